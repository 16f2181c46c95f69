"""The user's cache folder for spikegs: $XDG_CACHE_HOME/spikegs, else ~/.cache/spikegs."""

from __future__ import annotations

import os
from pathlib import Path


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
