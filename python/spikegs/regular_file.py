"""Files, not devices: a shared run or dataset folder (untrusted) may hold a link to a device
(/dev/zero, read without end until memory runs out; written atomically, replaced by a file) or a
FIFO (whose read waits forever for a writer)."""

from __future__ import annotations

import os
import stat
from pathlib import Path


def is_special(path: Path) -> bool:
    """Whether `path` is (or links to) a device, a FIFO or a socket: neither a file nor a folder
    (False where it cannot be found). stat, not open: a FIFO's open waits for a writer."""
    try:
        mode = Path(path).stat().st_mode
    except OSError:  # missing, or a link loop
        return False
    return not (stat.S_ISREG(mode) or stat.S_ISDIR(mode))


def is_given(path: Path) -> bool:
    """Whether a dataset's file `path`, which may be left out, is there: a file or a link to one;
    ValueError naming it where its name holds something else (a folder, a link to nothing or a
    loop, a device or FIFO), which read as left out dropped that file's settings unsaid."""
    path = Path(path)
    if path.is_file() and not is_special(path):
        return True
    if not os.path.lexists(path):
        return False
    if path.is_dir():
        what = "a folder"
    elif path.is_symlink() and not path.exists():
        what = "a link to nothing (or a loop of links)"
    else:
        what = "a device, FIFO or socket"
    raise ValueError(f"{path}: {what}, not a file")


class NotText(UnicodeDecodeError):
    """A file read as text that is not (a UnicodeDecodeError, whose message named no file: a
    run's config.yaml or log.jsonl of random bytes said only "'utf-8' codec can't decode")."""

    def __init__(self, path: Path, err: UnicodeDecodeError):
        super().__init__(err.encoding, err.object, err.start, err.end, err.reason)
        self.path = path

    def __reduce__(self):  # (copied or pickled: args are UnicodeDecodeError's five)
        return type(self), (self.path, UnicodeDecodeError(*self.args))

    @property
    def detail(self) -> str:
        """The message without the file's name, for one that names it."""
        return f"not UTF-8 text ({super().__str__()})"

    def __str__(self) -> str:
        return f"{self.path}: {self.detail}"


def read_text(path: Path, encoding: str = "utf-8") -> str:
    """`path.read_text(encoding)`; ValueError naming `path` where it `is_special`, NotText where
    it cannot be decoded. A missing file or a folder raises read_text's OSError."""
    path = Path(path)
    if is_special(path):
        raise ValueError(f"{path}: a device, FIFO or socket, not a file; spikegs reads files only")
    try:
        return path.read_text(encoding=encoding)
    except UnicodeDecodeError as err:
        raise NotText(path, err) from None


def is_blank(path: Path) -> bool:
    """Whether the file `path` holds nothing but white space (`read_text`'s errors where it
    cannot be read)."""
    return not read_text(path).strip()
