"""Checks, before any work, that the files a command will write can be written."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path


def writable_folder(folder: Path) -> bool:
    """Whether files can be made in `folder`, or in its nearest existing ancestor where it does
    not exist yet (a read-only mount counts as not writable, for root too)."""
    folder = Path(folder).absolute()
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    if not (folder.is_dir() and os.access(folder, os.W_OK | os.X_OK)):
        return False
    try:  # os.access passes for root where the file system refuses (/proc, a read-only mount)
        with tempfile.TemporaryFile(dir=folder):
            return True
    except OSError:
        return False


def utf8_name(path: str | Path) -> str | None:
    """`path` as OpenImageIO takes names, its bytes on disk read as UTF-8; None where they are
    not (a Latin-1 folder's name, read through the surrogate escapes of os.fsdecode). The bytes,
    not the string: the C locale without UTF-8 mode (PYTHONUTF8=0) reads a UTF-8 name's bytes
    as ASCII's surrogate escapes too."""
    try:
        return os.fsencode(path).decode("utf-8")
    except UnicodeError:
        return None


def _check_no_file_on_path(path: Path, flag: str, folders) -> None:
    """ValueError where one of `folders` on `path`'s way is a file, or a symbolic link to
    nothing (a scratch disk's folder not made yet: 'File exists' once the work was done)."""
    for folder in folders:
        if folder.is_symlink() and not folder.exists():
            raise ValueError(
                f"{flag} {path}: {folder} is a symbolic link to {os.readlink(folder)}, which does "
                f"not exist; make that folder first"
            )
        if folder.exists() and not folder.is_dir():
            raise ValueError(f"{flag} {path}: a folder on its path is a file")


def check_file_output(path: Path, flag: str = "--out") -> None:
    """ValueError unless a file can be written at `path`: not a directory, no file on its folder
    path, its folder writable, and, where it is a symbolic link to nothing, its target's folder
    there (written through the link, it was made, wherever the link pointed)."""
    path = Path(path)
    if path.is_dir():
        raise ValueError(f"{flag} {path}: is a folder; give a file name")
    _check_no_file_on_path(path, flag, path.parents)
    if not writable_folder(path.parent):
        raise ValueError(f"{flag} {path}: its folder is not writable")
    target = Path(os.path.realpath(path))
    if path.is_symlink() and not path.exists() and not target.parent.is_dir():
        raise ValueError(
            f"{flag} {path}: a symbolic link to {os.readlink(path)}, whose folder does not "
            f"exist; make that folder first, or remove the link"
        )


def check_utf8_name(path: Path, flag: str, why: str) -> None:
    """ValueError where `path` (absolute) is not a UTF-8 name (`utf8_name`), saying `why` it
    must be one."""
    if utf8_name(Path(path).absolute()) is None:
        raise ValueError(f"{flag} {path}: not a UTF-8 name, which {why}; rename it")


def check_folder_output(folder: Path, flag: str = "--out", images: bool = False) -> None:
    """ValueError unless files can be written into `folder` (made where missing): not a file,
    no file or link to nothing on its path, its nearest existing ancestor writable, and its name
    UTF-8 where it takes `images` (OpenImageIO's)."""
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise ValueError(f"{flag} {folder}: is a file; give a folder")
    _check_no_file_on_path(folder, flag, [folder, *folder.parents])
    if not writable_folder(folder):
        raise ValueError(f"{flag} {folder}: not writable")
    if images:
        check_utf8_name(folder, flag, "OpenImageIO (spikegs's image files) cannot open")


def record_beside(path: Path) -> Path:
    """The JSON record of the file at `path`, beside it: its whole name with ".json" appended
    (orbit.mp4.json, sim.pt.json; with_suffix wrote a w.json's record over it)."""
    path = Path(path)
    return path.with_name(path.name + ".json")
