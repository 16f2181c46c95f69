"""A path as a word of a command that a message gives the user to paste into a shell."""

from __future__ import annotations

import shlex
from pathlib import Path


def shell_path(path: str | Path) -> str:
    """`path` quoted for a shell, with ./ before a relative one that starts with "-", which the
    command would read as an option (pathlib drops a ./ typed: Path("./-run") is "-run")."""
    text = str(path)
    return shlex.quote(f"./{text}" if text.startswith("-") else text)
