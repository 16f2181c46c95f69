"""Ctrl-C (SIGINT) and SIGTERM between steps: a signal that arrives during a step takes effect
once the step is done.

A KeyboardInterrupt raised wherever the signal lands (in the middle of an optimizer update or of
densification) would leave the model half-updated, and a checkpoint of it unresumable. SIGTERM is
how a batch scheduler ends a job at its time limit (Slurm, then SIGKILL 30 s later), as do
`timeout`, `kill` and `docker stop`: killed at once, a run lost the steps since its last
checkpoint (up to a minute) and said nothing.
"""

from __future__ import annotations

import contextlib
import signal
import sys
import threading
from collections.abc import Callable, Iterator


class Terminated(KeyboardInterrupt):
    """Work stopped by SIGTERM, as Ctrl-C stops it (the same clean-up; exit status 143)."""


NAMES = {signal.SIGINT: "Ctrl-C", signal.SIGTERM: "SIGTERM"}


def interruption(signum: int) -> KeyboardInterrupt:
    """The exception that stops work for signal `signum`: KeyboardInterrupt, or Terminated."""
    return Terminated() if signum == signal.SIGTERM else KeyboardInterrupt()


def raise_terminated(signum, frame) -> None:
    """A SIGTERM handler that stops work as Ctrl-C does (`finally` blocks run); further SIGTERMs
    are ignored while it unwinds (one landing in the clean-up printed 'terminated' twice)."""
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    raise Terminated


def _takes_over(signum: int) -> bool:
    """Whether a deferred block handles `signum`: SIGINT unless ignored; SIGTERM where its
    handler is the default or the `spikegs` command's (a library user's own stays theirs)."""
    handler = signal.getsignal(signum)
    if signum == signal.SIGTERM:
        return handler in (signal.SIG_DFL, raise_terminated)
    return handler is not signal.SIG_IGN


@contextlib.contextmanager
def deferred_interrupt(message: str) -> Iterator[Callable[[], int]]:
    """Within the block the first SIGINT or SIGTERM prints `message` (its `{signal}` the
    signal's name) and is recorded; the yielded callable returns the signal number (0 before
    any), and `interruption` of it is the exception to raise once the step is done. A second
    one raises at once. Outside the main thread (where no signal is delivered) nothing changes,
    nor for a signal ignored (SIGINT in a background job) or a SIGTERM handler of the caller's
    (`_takes_over`)."""
    if threading.current_thread() is not threading.main_thread():
        yield lambda: 0
        return
    handled = [s for s in NAMES if _takes_over(s)]
    hits: list[int] = []

    def handler(signum, frame):
        hits.append(signum)
        if len(hits) > 1:
            raise interruption(signum)
        print(message.format(signal=NAMES[signum]), file=sys.stderr, flush=True)

    previous = {s: signal.signal(s, handler) for s in handled}
    try:
        yield lambda: hits[0] if hits else 0
    finally:
        for s, before in previous.items():
            signal.signal(s, before if before is not None else signal.SIG_DFL)
