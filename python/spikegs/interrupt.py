"""Ctrl-C between steps: a SIGINT that arrives during a step takes effect once the step is done.

A KeyboardInterrupt raised wherever the signal lands (in the middle of an optimizer update or of
densification) would leave the model half-updated, and a checkpoint of it unresumable.
"""

from __future__ import annotations

import contextlib
import signal
import sys
import threading
from collections.abc import Callable, Iterator


@contextlib.contextmanager
def deferred_interrupt(message: str) -> Iterator[Callable[[], bool]]:
    """Within the block the first SIGINT prints `message` and sets a flag, which the yielded
    callable reads; a second one raises KeyboardInterrupt at once. Outside the main thread
    (where no signal is delivered), or where SIGINT is ignored (a background job), the flag stays
    False and the handling as it was."""
    ignored = signal.getsignal(signal.SIGINT) is signal.SIG_IGN
    if ignored or threading.current_thread() is not threading.main_thread():
        yield lambda: False
        return
    hits = []

    def handler(signum, frame):
        hits.append(signum)
        if len(hits) > 1:
            raise KeyboardInterrupt
        print(message, file=sys.stderr, flush=True)

    previous = signal.signal(signal.SIGINT, handler)
    try:
        yield lambda: bool(hits)
    finally:
        signal.signal(signal.SIGINT, previous if previous is not None else signal.SIG_DFL)
