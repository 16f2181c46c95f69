"""Advisory locks (flock) between spikegs processes: one trains in a run folder, one trains each
cached SIM, one writes a dataset (simulate, poses) while none reads it (train, sim-train, eval,
render)."""

from __future__ import annotations

import contextlib
import sys
import warnings
from pathlib import Path

from .regular_file import is_special

try:
    import fcntl
except ImportError:  # Windows
    fcntl = None


class Busy(FileExistsError):
    """Another process holds the lock: a later try may succeed (eval, render, --resume once it
    has finished; `spikegs` exits with BUSY, where a usage error or bad input exits 2)."""


BUSY = 75  # the exit status of a command refused for a lock another process holds (sysexits.h's
# EX_TEMPFAIL: a temporary failure, worth a retry)


@contextlib.contextmanager
def exclusive_lock(path: Path, busy: str | None):
    """Hold an exclusive lock on the file `path` for the block (released at its end or when the
    process dies, however). While another process holds it: Busy(`busy`), or, where
    `busy` is None, wait for it (saying so). No lock where the OS has no fcntl (Windows) or the
    filesystem no flock (some NFS, Lustre and FUSE mounts: a warning)."""
    if fcntl is None:
        yield
        return
    with _opened(Path(path)) as handle:
        _lock(handle, path, fcntl.LOCK_EX, busy)
        yield


@contextlib.contextmanager
def shared_lock(path: Path, busy: str):
    """Hold a shared lock on the file `path` for the block: processes holding it shared run
    together, and one asking for `exclusive_lock` is refused (Busy) meanwhile. Busy(`busy`) while
    another process holds it exclusive. No lock where the file can be neither made nor opened
    (a folder this process cannot write, holding none: no spikegs process writes it either)."""
    if fcntl is None:
        yield
        return
    try:
        handle = _opened(Path(path))
    except OSError:  # (the docstring's folder; or the lock unreadable: another user's, mode 600)
        yield
        return
    with handle:
        _lock(handle, path, fcntl.LOCK_SH, busy)
        yield


def _opened(path: Path):
    """The file `path` opened to lock it: for appending, made where missing ("w" would touch it:
    a finished run looked rewritten), else read-only, all that flock needs (a lock file of
    another user's in a shared folder; a read-only folder's); the append's OSError where neither
    opens; ValueError where it is a device, FIFO or socket (a shared dataset's FIFO .lock: the
    open waited forever for a reader) or a folder (whose open said "Is a directory" alone)."""
    if is_special(path) or path.is_dir():
        what = "a folder" if path.is_dir() else "a device, FIFO or socket"
        raise ValueError(f"{path}: {what}, not a lock file; remove it")
    try:
        return path.open("a")
    except OSError as err:
        try:
            return path.open("rb")
        except OSError:
            raise err from None


def _lock(handle, path: Path, kind: int, busy: str | None) -> None:
    """flock `handle` (the file `path`) `kind`: Busy(`busy`) while another process holds a lock
    that conflicts, or, where `busy` is None, wait for it (saying so); a warning where the
    filesystem cannot lock."""
    try:
        fcntl.flock(handle, kind | fcntl.LOCK_NB)
    except BlockingIOError:
        if busy is not None:
            raise Busy(busy) from None
        print(f"waiting for another process, which holds {path}", file=sys.stderr)
        fcntl.flock(handle, kind)
    except OSError as err:  # ENOLCK, ENOSYS, EOPNOTSUPP: the filesystem cannot lock
        warnings.warn(f"{path}: not locked ({err}); use it from one process only", stacklevel=4)


def refuse_if_held(path: Path, busy: str) -> None:
    """Busy(`busy`) where another process holds a lock on the file `path` (shared or exclusive);
    nothing where there is no such file or it cannot be opened: a check before any work, which
    the lock taken later makes sure of."""
    if not Path(path).is_file():
        return
    try:
        with warnings.catch_warnings():  # a filesystem that cannot lock: the later lock says so
            warnings.simplefilter("ignore")
            with exclusive_lock(path, busy):
                pass
    except Busy:
        raise
    except OSError:  # a folder this process cannot write: its writes fail later, saying so
        pass
