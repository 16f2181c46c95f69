"""Files written atomically: a kill mid-write leaves the previous file (or none), never a truncated
one."""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path


def write_atomically(path: Path, write: Callable[[Path], None]) -> None:
    """`write(tmp)` to a temporary file of this process beside `path` (processes may share
    `path`, as trainers share a SIM cache), then rename it onto `path`; makes `path`'s folder. The
    temporary file is removed when writing fails; a killed process's is swept by the trainer in a
    run folder, and elsewhere stays as a hidden .NAME.PID.tmp."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        write(tmp)
        tmp.replace(path)
    finally:
        tmp.unlink(missing_ok=True)


def save_atomically(obj, path: Path) -> None:
    """torch.save `obj` to `path` through `write_atomically`."""
    import torch

    write_atomically(path, lambda tmp: torch.save(obj, tmp))
