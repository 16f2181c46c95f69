"""Ctrl-C (SIGINT) and SIGTERM between steps: a signal that arrives during a step takes effect
once the step is done.

A KeyboardInterrupt raised wherever the signal lands (in the middle of an optimizer update or of
densification) would leave the model half-updated, and a checkpoint of it unresumable. SIGTERM is
how a batch scheduler ends a job at its time limit (Slurm, then SIGKILL 30 s later), as do
`timeout`, `kill` and `docker stop`: killed at once, a run lost the steps since its last
checkpoint (up to a minute) and said nothing. SIGHUP (the terminal closed: an ssh session that
dropped, a terminal window shut, the run not under nohup or tmux) likewise.
"""

from __future__ import annotations

import contextlib
import errno
import signal
import sys
import threading
from collections.abc import Callable, Iterator
from pathlib import Path


class Terminated(KeyboardInterrupt):
    """Work stopped by SIGTERM or SIGHUP (`signum`), as Ctrl-C stops it (the same clean-up;
    exit status 128 + signum)."""

    def __init__(self, signum: int = signal.SIGTERM):
        super().__init__()
        self.signum = signum


HANGUP = getattr(signal, "SIGHUP", None)  # None where the OS has none (Windows)
ENDING = tuple(s for s in (signal.SIGTERM, HANGUP) if s is not None)  # end a process unhandled
NAMES = {signal.SIGINT: "Ctrl-C", **{s: s.name for s in ENDING}}


def interruption(signum: int) -> KeyboardInterrupt:
    """The exception that stops work for signal `signum`: KeyboardInterrupt, or Terminated."""
    return Terminated(signum) if signum in ENDING else KeyboardInterrupt()


def raise_terminated(signum, frame) -> None:
    """A SIGTERM or SIGHUP handler that stops work as Ctrl-C does (`finally` blocks run); that
    signal is then ignored while it unwinds (a second SIGTERM landing in the clean-up printed
    'terminated' twice)."""
    signal.signal(signum, signal.SIG_IGN)
    raise Terminated(signum)


def say(message: str) -> OSError | None:
    """`message` on stderr; the error that kept it unsaid where stderr is gone (its terminal
    closed: EIO, with SIGHUP or not; its reader left: EPIPE; its file's disk full), where
    stopping must not fail on saying so, else None."""
    try:
        print(message, file=sys.stderr, flush=True)
    except OSError as err:
        if not output_gone(err):
            raise
        return err
    return None


def running_as_command() -> bool:
    """Whether this process is the `spikegs` command (its console script, spikegs-script.py
    where a Windows launcher runs one, or `python -m spikegs[.cli]`: runpy imports the package
    while sys.argv[0] is still "-m"), not a script, REPL or notebook that imports the package
    (`python plot.py -m spikegs`, an option's value, was taken for the command)."""
    return sys.argv[0] == "-m" or Path(sys.argv[0]).stem.removesuffix("-script") == "spikegs"


class ImportInterrupted:
    """A block of the package's imports (torch's and its core's: about 2 s at a command's start,
    before any handler of the `spikegs` command can be set, its console script importing the
    package first) whose Ctrl-C, left to the top level, says 'interrupted' as one later does,
    not a 30-60-line traceback through torch's import (the exit status stays Python's for an
    unhandled Ctrl-C). Where `armed` (the command: `running_as_command`; a script that catches
    the Ctrl-C would keep the hook for its own), it is `sys.excepthook` within the block, and
    after it while a Ctrl-C leaves it; once called, the hook it replaced is back, and gets any
    other exception."""

    def __init__(self, armed: bool):
        self.armed = armed

    def __enter__(self):
        self.previous = sys.excepthook
        if self.armed:
            sys.excepthook = self

    def __exit__(self, kind, value, traceback) -> None:
        if kind is None or not issubclass(kind, KeyboardInterrupt):
            self._restore()

    def __call__(self, kind, value, traceback) -> None:
        self._restore()
        if issubclass(kind, KeyboardInterrupt):
            say("interrupted")
        else:
            self.previous(kind, value, traceback)

    def _restore(self) -> None:
        """Put back the hook replaced, unless another replaced this one since."""
        if sys.excepthook is self:
            sys.excepthook = self.previous


# an output's file whose disk or quota is full (a batch job's log): it takes no more, as a gone
# one; taken for the work's error, it stopped a run mid-step with no word and no checkpoint (500
# steps lost) where the run's own disk had room
FULL = tuple(getattr(errno, name) for name in ("ENOSPC", "EDQUOT", "EFBIG") if hasattr(errno, name))


def output_gone(err: OSError) -> bool:
    """Whether `err` says that an output stream is gone: its reader left (EPIPE), its terminal
    closed (EIO), its file's disk or quota is full (FULL)."""
    return err.errno in (errno.EPIPE, errno.EIO, *FULL)


def progress_lost(show: Callable[[], None], bar) -> OSError | None:
    """Call `show` (a step's progress: its line, its tqdm `bar`); the error it raised where the
    output is gone (`output_gone`), the bar then off (its close would write again) and out of
    tqdm's list of bars (a later bar in the process would be drawn below it), else None: the
    caller stops once its step is done, as a signal stops it."""
    try:
        show()
    except OSError as err:
        if not output_gone(err):
            raise
        if not bar.disable:  # (a bar made off was never listed)
            bar.disable = True
            type(bar)._decr_instances(bar)  # what close does before it writes
        return err
    return None


@contextlib.contextmanager
def quiet_close(bar) -> Iterator:
    """`bar` for the block, closed at its end without raising where its output is gone."""
    try:
        yield bar
    finally:
        progress_lost(bar.close, bar)


def _takes_over(signum: int) -> bool:
    """Whether a deferred block handles `signum`: SIGINT unless ignored; SIGTERM and SIGHUP
    where the handler is the default or the `spikegs` command's (a library user's own, or
    nohup's SIG_IGN, stays)."""
    handler = signal.getsignal(signum)
    if signum in ENDING:
        return handler in (signal.SIG_DFL, raise_terminated)
    return handler is not signal.SIG_IGN


@contextlib.contextmanager
def deferred_interrupt(message: str, again: str = "") -> Iterator[Callable[[], int]]:
    """Within the block the first SIGINT, SIGTERM or SIGHUP prints `message` (its `{signal}` the
    signal's name), then `again` but for a hangup, and is recorded; the yielded callable returns
    the signal number (0 before any), and `interruption` of it is the exception to raise once
    the step is done. A second one raises at once, but a second SIGHUP (a hangup comes twice:
    the shell's, then the kernel's as the shell exits), which stays ignored after the block
    too. Outside the main thread (where no signal is delivered) nothing changes, nor for a
    signal ignored (SIGINT in a background job, SIGHUP under nohup) or a SIGTERM or SIGHUP
    handler of the caller's (`_takes_over`)."""
    if threading.current_thread() is not threading.main_thread():
        yield lambda: 0
        return
    handled = [s for s in NAMES if _takes_over(s)]
    hits: list[int] = []
    hung_up = []

    def handler(signum, frame):
        if signum == HANGUP:
            hung_up.append(signum)
            if hits:
                return
        hits.append(signum)
        if len(hits) > 1:
            raise interruption(signum)
        said = message + ("" if signum == HANGUP else again)
        say(said.format(signal=NAMES[signum]))  # (raising here would tear the step)

    previous = {s: signal.signal(s, handler) for s in handled}
    try:
        yield lambda: hits[0] if hits else 0
    finally:
        for s, before in previous.items():
            restored = signal.SIG_IGN if s == HANGUP and hung_up else before
            signal.signal(s, restored if restored is not None else signal.SIG_DFL)
