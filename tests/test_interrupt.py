"""interrupt.py: which signals stop work, as what, and the deferred stop's handlers."""

import os
import signal
import threading

import pytest
from spikegs.interrupt import ENDING, NAMES, Terminated, deferred_interrupt, interruption

pytestmark = pytest.mark.skipif(not hasattr(signal, "SIGHUP"), reason="a POSIX system's signals")


def test_sigterm_and_sighup_terminate_and_ctrl_c_interrupts():
    assert ENDING == (signal.SIGTERM, signal.SIGHUP)
    assert NAMES == {signal.SIGINT: "Ctrl-C", signal.SIGTERM: "SIGTERM", signal.SIGHUP: "SIGHUP"}
    for signum in ENDING:
        stop = interruption(signum)
        assert isinstance(stop, Terminated) and stop.signum == signum
    assert type(interruption(signal.SIGINT)) is KeyboardInterrupt


def test_off_the_main_thread_nothing_is_deferred():
    """No signal reaches a worker thread: its block records none and leaves the handlers."""
    seen = []

    def work():
        with deferred_interrupt("stopping") as interrupted:
            seen.append((interrupted(), signal.getsignal(signal.SIGTERM)))

    thread = threading.Thread(target=work)
    thread.start()
    thread.join()
    assert seen == [(0, signal.getsignal(signal.SIGTERM))]


def test_the_handlers_come_back_and_a_hangup_stays_ignored(capsys):
    """A block without a signal restores every handler; one with a SIGHUP says `message` alone
    (no `again`: nobody is left to press Ctrl-C) and leaves SIGHUP ignored (the kernel's second
    hangup), the others restored."""
    before = {s: signal.getsignal(s) for s in NAMES}
    try:
        for s in ENDING:
            signal.signal(s, signal.SIG_DFL)
        with deferred_interrupt("stopping") as interrupted:
            assert interrupted() == 0
        assert [signal.getsignal(s) for s in ENDING] == [signal.SIG_DFL] * 2
        assert signal.getsignal(signal.SIGINT) == before[signal.SIGINT]
        with deferred_interrupt("stopping on {signal}", again=", again to stop now") as interrupted:
            os.kill(os.getpid(), signal.SIGHUP)
            assert interrupted() == signal.SIGHUP
        assert signal.getsignal(signal.SIGHUP) == signal.SIG_IGN
        assert signal.getsignal(signal.SIGTERM) == signal.SIG_DFL
        assert signal.getsignal(signal.SIGINT) == before[signal.SIGINT]
        assert capsys.readouterr().err == "stopping on SIGHUP\n"
    finally:
        for s, handler in before.items():
            signal.signal(s, handler)
