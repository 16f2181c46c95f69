"""Fixtures shared by the test files."""

from __future__ import annotations

import signal

import pytest


@pytest.fixture
def ctrl_c():
    """Ctrl-C raising KeyboardInterrupt, as in a terminal, for the test's duration: a process
    started in the background by a non-interactive shell (`cmd &`) inherits SIGINT ignored, and
    the trainer rightly keeps it ignored (test_an_ignored_sigint_stays_ignored)."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)
