"""torch.save atomically: a kill mid-save leaves the previous file, never a truncated one."""

from __future__ import annotations

import os
from pathlib import Path

import torch


def save_atomically(obj, path: Path) -> None:
    """torch.save `obj` to a temporary file of this process beside `path` (processes may share
    `path`, as trainers share a SIM cache), then rename it onto `path`; makes `path`'s folder."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f"{path.name}.{os.getpid()}.tmp")
    torch.save(obj, tmp)
    tmp.replace(path)
