"""The user's cache folder for spikegs: $XDG_CACHE_HOME/spikegs, else ~/.cache/spikegs."""

from __future__ import annotations

import os
from pathlib import Path

from .atomic_save import write_text_atomically

# what is worked out from spikes of this many bytes or more (a recording's digest, its flicker)
# is kept in the user's cache: 250x400 from 21,475 readouts, a digest of ~0.3 s and a flicker
# search of ~0.8 s, under a file's every later command
CACHED_FROM = 256 << 20


def cache_home() -> Path | None:
    """$XDG_CACHE_HOME/spikegs (an absolute path, as the XDG spec has it), else
    ~/.cache/spikegs; None where neither is known (no home directory)."""
    base = Path(os.environ.get("XDG_CACHE_HOME") or ".")
    if not base.is_absolute():
        try:
            base = Path.home() / ".cache"
        except RuntimeError:  # no $HOME and no passwd entry
            return None
    return base / "spikegs"


def write_cached(path: Path, text: str) -> None:
    """Write `text` at `path` in the user's cache (its folders made, the write atomic), where the
    cache can be written; else nothing: a read-only home computes it again next time."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        write_text_atomically(path, text)
    except OSError:
        pass
