"""What a search of the spikes found, kept for the process under a digest of the spikes and of the
search: a recording's loading (its pseudo ground truth), its training targets and a bench's every
method search it once (a sensor's defects, ~0.3 s at 250x400 and 20,000 readouts; the light's
flicker ~1 s)."""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable
from typing import TypeVar

KEPT = 16  # findings kept, the least recently asked for dropped first

T = TypeVar("T")
_found: OrderedDict[bytes, object] = OrderedDict()


def found_once(key: bytes, search: Callable[[], T]) -> T:
    """What `search()` returns, searched once for each `key` (a digest of the spikes searched and
    of the search) while it stays among the KEPT latest asked for."""
    if key in _found:
        _found.move_to_end(key)
        return _found[key]
    found = _found[key] = search()
    while len(_found) > KEPT:
        _found.popitem(last=False)
    return found


def forget() -> None:
    """Drop every finding kept (a test's patched search then searches again)."""
    _found.clear()
