"""Advisory exclusive locks (flock) between spikegs processes: one trains in a run folder, one
trains each cached SIM."""

from __future__ import annotations

import contextlib
import sys
import warnings
from pathlib import Path

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
    with Path(path).open("a") as handle:  # "w" would touch it: a finished run looked rewritten
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            if busy is not None:
                raise Busy(busy) from None
            print(f"waiting for another process, which holds {path}", file=sys.stderr)
            fcntl.flock(handle, fcntl.LOCK_EX)
        except OSError as err:  # ENOLCK, ENOSYS, EOPNOTSUPP: the filesystem cannot lock
            warnings.warn(f"{path}: not locked ({err}); use it from one process only", stacklevel=3)
        yield
