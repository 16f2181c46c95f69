"""Files written atomically: a kill mid-write leaves the previous file (or none), never a truncated
one."""

from __future__ import annotations

import contextlib
import glob
import hashlib
import os
import re
from collections.abc import Callable, Iterator
from pathlib import Path

from .regular_file import is_special

NAME_MAX = 255  # bytes in a file name (Linux's and macOS's file systems)
STEM_MAX = 200  # bytes of a name that a temporary's name holds: room for a writer and .tmp


def short_name(name: str, limit: int) -> str:
    """`name` where it fits in `limit` bytes (UTF-8), else its first whole characters and a hash
    of all of it (`~` and 12 hex digits), `limit` bytes at most: distinct names stay distinct."""
    raw = os.fsencode(name)
    if len(raw) <= limit:
        return name
    digest = hashlib.sha1(raw).hexdigest()[:12]
    return raw[: limit - 13].decode("utf-8", "ignore") + "~" + digest


def temporary_name(path: Path, writer: str) -> str:
    """The name of writer `writer`'s temporary file beside `path`: hidden, ending .tmp (a
    process id for `write_atomically`, a random one for a streaming DatWriter); a name past
    STEM_MAX bytes shortened (a 246-byte video's temporary passed NAME_MAX, and its write
    failed after the rendering)."""
    return _temporary(short_name(path.name, STEM_MAX), writer)


def _temporary(stem: str, writer: str) -> str:
    return f".{stem}.{writer}.tmp"


_TEMPORARY = re.compile(r"^\..+\.([^.]+)\.tmp$")  # `temporary_name`'s


def is_temporary(name: str) -> bool:
    """Whether a file name is a temporary file's of ours (`.NAME.WRITER.tmp`); a user's
    `notes.tmp` is not."""
    return _TEMPORARY.match(name) is not None


def target_name(name: str) -> str:
    """The name of the file that a temporary file of ours is written for (`.NAME.WRITER.tmp`:
    NAME, shortened where it is long); any other name as it is."""
    match = _TEMPORARY.match(name)
    return name[1 : match.start(1) - 1] if match else name


def _writer_alive(name: str) -> bool:
    """Whether the writer of temporary file `name` is a live process (its WRITER a process id:
    `write_atomically`'s)."""
    writer = _TEMPORARY.match(name).group(1)
    if not writer.isdigit() or int(writer) == 0:  # (0 would signal our process group)
        return False
    try:
        os.kill(int(writer), 0)  # signal 0: only whether it exists
    except (ProcessLookupError, OverflowError):
        return False
    except PermissionError:  # another user's live process
        pass
    return True


def sweep_temporaries(folder: Path) -> None:
    """Remove the temporary files of ours in `folder` whose writers are dead (killed mid-write);
    a live process's (`spikegs eval` writing into a run that a resumed training sweeps) stays."""
    for stale in Path(folder).iterdir() if Path(folder).is_dir() else ():
        if is_temporary(stale.name) and not _writer_alive(stale.name):
            stale.unlink(missing_ok=True)


def written_path(path: Path) -> Path:
    """Where a write of `path` lands: `path`, or the target of a symbolic link (the link stays);
    a link to a device, FIFO or socket is replaced, not followed (a run folder's eval.json linked
    to /dev/zero: root's write replaced the device with the scores)."""
    path = Path(path)  # (realpath, not resolve: a link loop is the path itself, not an error)
    return Path(os.path.realpath(path)) if path.is_symlink() and not is_special(path) else path


def _temporaries_of(path: Path, writer: str = "*") -> Iterator[Path]:
    """The files beside `path` named as its temporaries, of writers matching the glob `writer`
    (a longer name's may match too: `target_name` tells)."""
    return path.parent.glob(_temporary(glob.escape(short_name(path.name, STEM_MAX)), writer))


def sweep_killed_writes(path: Path) -> None:
    """Remove the temporary files that writers of `path` killed mid-write left beside it (beside
    its target, for a symbolic link); call it where no other process can be writing `path` (under
    the lock that its writers hold)."""
    for stale in _temporaries_of(written_path(path)):
        stale.unlink(missing_ok=True)


def sweep_dead_writes(path: Path) -> None:
    """Remove the temporaries of `path` that `write_atomically` calls of dead processes left
    beside it (a kill mid-write: `spikegs eval`'s images, a video, the demo's figures, which no
    run folder's sweep reaches); a live writer's, and a streaming writer's (no process id),
    stay."""
    stem = short_name(path.name, STEM_MAX)
    for stale in _temporaries_of(path, "[0-9]*"):
        ours = target_name(stale.name) == stem
        writer = _TEMPORARY.match(stale.name).group(1)
        if ours and writer.isdigit() and not _writer_alive(stale.name):
            with contextlib.suppress(OSError):
                stale.unlink(missing_ok=True)


def naming(err: OSError, path: Path, written=None) -> OSError:
    """`err` naming `path` where it names no file (a write's error: a full disk said only "[Errno
    28] No space left on device") or names `written`, the temporary written for it; else `err`.
    A new error of its errno's kind: PyAV's `av.error.OSError` has no settable filename."""
    if err.errno is None or err.filename not in (None, str(written), written):
        return err
    named = OSError(err.errno, err.strerror, str(path))
    named.__cause__ = err  # as `raise named from err`
    return named


def write_atomically(path: Path, write: Callable[[Path], None]) -> None:
    """`write(tmp)` to a temporary file of this process beside `path` (processes may share
    `path`, as trainers share a SIM cache), then rename it onto `path`; makes `path`'s folder.
    Where `path` is a symbolic link, its target is written and the link stays. The temporary file
    is removed when writing fails; a killed process's stays until swept (`sweep_dead_writes` as
    `path` is written again, `sweep_temporaries` in a run folder when training or scoring starts
    and in a demo's, `sweep_killed_writes` in SIM's cache)."""
    tmp, target = staged_write(path, write)
    try:
        tmp.replace(target)
    except OSError as err:  # named by the file asked for, not the hidden temporary one
        raise naming(err, target, tmp)  # noqa: B904 (its cause set, where it is another)
    finally:  # (an error of its own would replace the rename's)
        with contextlib.suppress(OSError):
            tmp.unlink(missing_ok=True)


def staged_write(path: Path, write: Callable[[Path], None]) -> tuple[Path, Path]:
    """`write_atomically` but for its rename: (the temporary file written, where it is to land),
    for the caller to rename when the files written with it are all whole (`spikegs eval`'s
    images, published with their scores); the temporary is removed where `write` fails."""
    target = written_path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    sweep_dead_writes(target)  # a killed writer's temporary of `path` (eval's images, a video)
    tmp = target.with_name(temporary_name(target, str(os.getpid())))
    try:
        write(tmp)
    except BaseException as err:  # (Ctrl-C mid-write too)
        with contextlib.suppress(OSError):
            tmp.unlink(missing_ok=True)
        if isinstance(err, OSError):  # named by the file asked for, not the hidden temporary
            raise naming(err, target, tmp)  # noqa: B904 (its cause set, where it is another)
        raise
    return tmp, target


def write_text_atomically(path: Path, text: str) -> None:
    """`path.write_text(text)` in UTF-8 (the locale's codec may have no "é") through
    `write_atomically`."""
    write_atomically(path, lambda tmp: tmp.write_text(text, encoding="utf-8"))


def write_text_if_changed(path: Path, text: str) -> None:
    """`write_text_atomically` unless the file holds `text` already (left as it is: a finished
    run's files, resumed)."""
    if not (path.is_file() and path.read_bytes() == text.encode("utf-8")):
        write_text_atomically(path, text)


def save_atomically(obj, path: Path) -> None:
    """torch.save `obj` to `path` through `write_atomically`, into a file object (serialised in
    memory first, a checkpoint of 1e6 colour Gaussians took 0.7 GB more). A disk that fills up
    mid-write raises its OSError: torch's zip writer, closing, raised "RuntimeError: [enforce
    fail at inline_container.cc] unexpected pos" over it, which no caller takes for an
    OSError."""
    import torch

    def write(tmp: Path) -> None:
        with open(tmp, "wb") as file:
            try:
                torch.save(obj, file)
            except RuntimeError as err:
                if isinstance(err.__context__, OSError):  # the write's own error
                    raise err.__context__ from None
                raise

    write_atomically(path, write)


def save_figure(fig, path: Path) -> None:
    """Save matplotlib figure `fig` to `path` through `write_atomically` (savefig straight to a
    curve.png left it torn on a full disk), in the format of its suffix (PNG without one: the
    temporary's name has none), at 120 dpi; the figure is closed."""
    import matplotlib.pyplot as plt

    kind = Path(path).suffix[1:] or "png"
    try:
        write_atomically(Path(path), lambda tmp: fig.savefig(tmp, dpi=120, format=kind))
    finally:
        plt.close(fig)
