"""Files written atomically: a kill mid-write leaves the previous file (or none), never a truncated
one."""

from __future__ import annotations

import glob
import os
from collections.abc import Callable
from pathlib import Path


def _temporary_name(path: Path, writer: str) -> str:
    """The name of writer `writer`'s temporary file beside `path`: hidden, ending .tmp."""
    return f".{path.name}.{writer}.tmp"


def is_temporary(name: str) -> bool:
    """Whether a file name is a temporary file's of ours (`_temporary_name`, DatWriter's): hidden
    and ending .tmp; a user's `notes.tmp` is not."""
    return name.startswith(".") and name.endswith(".tmp")


def sweep_temporaries(folder: Path) -> None:
    """Remove every temporary file of ours in `folder`; call it where no other process can be
    writing there (a run folder, under the run's lock)."""
    for stale in Path(folder).glob(".*.tmp"):
        stale.unlink(missing_ok=True)


def sweep_killed_writes(path: Path) -> None:
    """Remove the temporary files that writers of `path` killed mid-write left beside it; call it
    where no other process can be writing `path` (under the lock that its writers hold)."""
    path = Path(path)
    for stale in path.parent.glob(_temporary_name(Path(glob.escape(path.name)), "*")):
        stale.unlink(missing_ok=True)


def write_atomically(path: Path, write: Callable[[Path], None]) -> None:
    """`write(tmp)` to a temporary file of this process beside `path` (processes may share
    `path`, as trainers share a SIM cache), then rename it onto `path`; makes `path`'s folder. The
    temporary file is removed when writing fails; a killed process's stays until
    `sweep_killed_writes` (the trainer sweeps a run folder's, SIM's cache its own)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(_temporary_name(path, str(os.getpid())))
    try:
        write(tmp)
        tmp.replace(path)
    finally:
        tmp.unlink(missing_ok=True)


def write_text_atomically(path: Path, text: str) -> None:
    """`path.write_text(text)` through `write_atomically`."""
    write_atomically(path, lambda tmp: tmp.write_text(text))


def save_atomically(obj, path: Path) -> None:
    """torch.save `obj` to `path` through `write_atomically`."""
    import torch

    write_atomically(path, lambda tmp: torch.save(obj, tmp))
