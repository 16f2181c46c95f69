"""A run folder's rules: one process trains in it (its lock), what a run writes there, and the
files that are not a run's, which no run overwrites."""

from __future__ import annotations

import os
from pathlib import Path

from .atomic_save import is_temporary
from .file_lock import exclusive_lock
from .run_summary import (
    CHECKPOINTS,
    CONFIG,
    CURVE,
    EVAL,
    LOCK,
    LOG,
    SCENE,
    SUMMARY,
    last_checkpoint,
)
from .strict_json import read_json


def run_lock(run_dir: Path):
    """An exclusive lock on RUN/.lock for a `with` block: Busy while another process trains in
    RUN (or scores it: `evaluate_run`)."""
    return exclusive_lock(
        run_dir / LOCK,
        busy=f"{run_dir} is being trained by another process (or scored by spikegs eval); wait "
        f"for it to end or train into another --out",
    )


def folder_identity(folder: Path) -> tuple[int, int] | None:
    """The (device, inode) of `folder`: the same folder wherever it is named from; None where
    nothing is there."""
    try:
        status = os.stat(folder)
    except FileNotFoundError:
        return None
    return status.st_dev, status.st_ino


class FolderWatch:
    """For a `with` block: whether `folder` is still the folder its path named as it began (not
    moved, renamed or deleted since), and where it went (on Linux, the folder held open)."""

    def __init__(self, folder: Path):
        self.folder = Path(folder)
        self._identity = folder_identity(self.folder)
        try:
            self._fd = os.open(self.folder, os.O_RDONLY)
        except OSError:  # (a folder cannot be opened on Windows: where it went is unknown)
            self._fd = None

    def __enter__(self) -> FolderWatch:
        return self

    def __exit__(self, *exc) -> None:
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None

    def moved(self) -> bool:
        """Whether the path names another folder now, or none."""
        return folder_identity(self.folder) != self._identity

    def now(self) -> Path | None:
        """Where the folder lies now; None where that is not known or it was deleted."""
        if self._fd is None:
            return None
        try:
            where = os.readlink(f"/proc/self/fd/{self._fd}")
        except OSError:  # (no /proc: another system)
            return None
        return None if where.endswith(" (deleted)") else Path(where)


# what a fresh run writes before its first checkpoint: it may start over a run stopped then
RUN_STARTED = frozenset({CONFIG, LOG, LOCK, CHECKPOINTS})
# what `spikegs train` and `spikegs eval` write in a run (and eval-DATASET*[.json] for others')
RUN_FILES = RUN_STARTED | {SCENE, SUMMARY, CURVE, EVAL, f"{EVAL}.json"}


def foreign_files(run_dir: Path) -> list[str]:
    """The names in `run_dir` that neither `spikegs train` nor `spikegs eval` wrote, sorted, and
    those in its folders as FOLDER/NAME: what is not the checkpoint in checkpoints/, not a
    side-by-side (VIEW.png) in eval/ and eval-DATASET*/ (a user's notes there were deleted with
    the run by `spikegs demo --overwrite`, which said it refuses them)."""
    foreign = []
    for path in sorted(run_dir.iterdir()) if run_dir.is_dir() else ():
        name = path.name  # temporary files: a killed process's, swept when a run starts
        other = name.startswith(f"{EVAL}-")  # another dataset's eval-DATASET*.json and folder
        if is_temporary(name) or (other and name.endswith(".json") and path.is_file()):
            continue
        if path.is_dir() and (name in (CHECKPOINTS, EVAL) or other):
            written = _checkpoint if name == CHECKPOINTS else _side_by_side
            inner = (p.name for p in sorted(path.iterdir()))
            foreign += [f"{name}/{n}" for n in inner if not (is_temporary(n) or written(n))]
        elif name not in RUN_FILES or other:
            foreign.append(name)
    return sorted(foreign)


def _checkpoint(name: str) -> bool:
    """Whether `name` is the file that training writes in RUN/checkpoints."""
    return name == last_checkpoint(Path()).name


def _side_by_side(name: str) -> bool:
    """Whether `name` is one of eval's side-by-side images (VIEW.png)."""
    return name.endswith(".png")


def refuse_foreign_files(run_dir: Path, remedy: str) -> None:
    """FileExistsError naming (five of) the files in `run_dir` that are not a run's
    (`foreign_files`), followed by `remedy`; nothing where there are none."""
    foreign = foreign_files(run_dir)
    if foreign:
        raise FileExistsError(
            f"{run_dir} holds files that are not a run's ({', '.join(foreign[:5])}"
            f"{', ...' if len(foreign) > 5 else ''}){remedy}"
        )


def check_fresh_run_dir(run_dir: Path, checkpoint: Path) -> None:
    """FileExistsError where a fresh run in `run_dir` would overwrite or mix with files that are
    not a run's: `run_dir` a file, or a directory holding anything but RUN_STARTED (a run with a
    `checkpoint` is refused under the run's lock, with its own message)."""
    if run_dir.exists() and not run_dir.is_dir():
        raise FileExistsError(f"{run_dir} is a file, not a run folder; give another --out")
    if not run_dir.is_dir() or checkpoint.exists():
        return
    # temporary files are a killed process's, swept when training starts
    names = sorted(p.name for p in run_dir.iterdir() if not is_temporary(p.name))
    foreign = foreign_files(run_dir)
    finished = [n for n in names if n not in RUN_STARTED and n not in foreign]
    if finished:
        raise FileExistsError(
            f"{run_dir} holds a finished run ({', '.join(finished)}) without its checkpoint "
            f"({checkpoint}): nothing to continue, and training afresh would mix with its "
            f"files; give another --out"
        )
    refuse_foreign_files(run_dir, "; give an empty or new --out")


def is_bench_results(path: Path, part: str) -> bool:
    """Whether `path` holds benchmark `part`'s results (`bench.common`'s object, its "benchmark"
    named): `bench train` writes OUT/train.json, a run's summary's name."""
    try:
        results = read_json(path)
    except (OSError, ValueError):
        return False
    return isinstance(results, dict) and results.get("benchmark") == part


def refuse_dataset_or_run(out: Path, writer: str, datasets: int) -> None:
    """FileExistsError, before any work, where OUT itself holds a dataset or a spikegs run
    (--out naming one, as simulate's or train's does): `writer` ("a demo", "spikegs bench")
    would write its own files in among its files (bench's train.json over a run's, which eval
    then refused): figures, JSON, and where it makes `datasets` (one, or more), they and its
    runs in OUT/data and OUT/runs."""
    from .data.dataset import holds_dataset, layout_files

    if not out.is_dir():
        return
    run = sorted(p.name for p in out.iterdir() if p.name in RUN_FILES - {LOCK})
    if run == [SUMMARY] and is_bench_results(
        out / SUMMARY, "train"
    ):  # `bench train`'s own, not a run's
        run = []
    marks = layout_files(out)
    if run:
        held = f"a spikegs run ({', '.join(run)})"
    elif marks or holds_dataset(out):
        held = f"a dataset ({', '.join(marks) or 'its spikes'})"
    else:
        return
    data = "its dataset" if datasets == 1 else "datasets"
    own = f"{data} in {out / 'data'}, its runs in {out / 'runs'}, " if datasets else ""
    raise FileExistsError(
        f"--out {out} holds {held}, among which {writer} would write its own files ({own}"
        f"figures, JSON); give it another --out"
    )
