"""A run folder's files by name, and RUN/train.json, the summary `spikegs train` writes at the end
of a run, read back checked."""

from __future__ import annotations

from pathlib import Path

from .file_lock import Busy, exclusive_lock
from .number_checks import is_number
from .shell_words import shell_path
from .strict_json import json_text, read_json

CONFIG = "config.yaml"  # the run's settings, which --resume keeps
LOG = "log.jsonl"  # loss, its terms, Gaussians, held-out PSNR against seconds: a JSON line each
LOCK = ".lock"  # held by the process training in the folder
CHECKPOINTS = "checkpoints"  # folder of last.pt
SCENE = "scene.ply"  # the trained scene, written when the run finishes
SUMMARY = "train.json"
FOUND = "found_in_spikes"  # train.json's: the flicker and defect pixels the targets left out
CURVE = "curve.png"  # `spikegs train`'s plot of the PSNR it logged against seconds
EVAL = "eval"  # `spikegs eval`'s: RUN/eval.json its scores, RUN/eval/ its side-by-side images


def last_checkpoint(run_dir: Path) -> Path:
    """RUN/checkpoints/last.pt, the checkpoint that `--resume` continues from."""
    return Path(run_dir) / CHECKPOINTS / "last.pt"


def resume_command(run_dir: Path, dataset: Path | None = None) -> str:
    """`spikegs train DATASET --out RUN --resume`, which finishes a run stopped with a checkpoint:
    DATASET `dataset`, else the one its checkpoint names (the word DATASET where that cannot be
    read: a torn file, a checkpoint from before the key; or where it is gone, said)."""
    gone = ""
    if dataset is None:
        import torch

        try:  # (mapped: a large scene's parameters are not read for a message)
            state = torch.load(last_checkpoint(run_dir), "cpu", mmap=True, weights_only=True)
            dataset = state.get("dataset") if isinstance(state, dict) else None
        except Exception:  # torch, pickle and zip raise their own kinds for a torn file
            dataset = None
        if isinstance(dataset, str) and not dataset_there(Path(dataset)):  # (moved: it failed)
            dataset, gone = None, f" (DATASET where {shell_path(dataset)} went)"
    where = "DATASET" if not isinstance(dataset, (str, Path)) else shell_path(dataset)
    return f"spikegs train {where} --out {shell_path(run_dir)} --resume{gone}"


def dataset_there(folder: Path) -> bool:
    """Whether `folder` holds a dataset (not gone, nor a folder a process made at its old path
    since it moved, as eval tells)."""
    from .data.dataset import layout_files  # (the data package imports this module)

    return folder.is_dir() and bool(layout_files(folder))


def read_summary(run_dir: Path) -> dict:
    """RUN/train.json's object ({} where there is none); ValueError naming the file where it is
    not JSON, not an object, or holds a dataset that is not a path, a scale that is not a finite
    number > 0, or a camera whose focal lengths are not."""
    path = Path(run_dir) / SUMMARY
    if not path.exists():
        return {}
    summary = read_json(path)
    if not isinstance(summary.get("dataset", ""), str):
        raise ValueError(f"{path}: dataset expected a path, found {json_text(summary['dataset'])}")
    scale = summary.get("intensity_scale", 1.0)
    if not (is_number(scale) and scale > 0):
        raise ValueError(
            f"{path}: intensity_scale expected a finite number > 0, found {json_text(scale)}"
        )
    camera = summary.get("camera", {"fl_x": 1, "fl_y": 1})  # (absent: a run from before it)
    focal = [camera.get(k) for k in ("fl_x", "fl_y")] if isinstance(camera, dict) else []
    if not (len(focal) == 2 and all(is_number(f) and f > 0 for f in focal)):
        raise ValueError(
            f"{path}: camera expected fl_x and fl_y, finite numbers > 0, found {json_text(camera)}"
        )
    return summary


def trained_scene(run_dir: Path) -> Path:
    """RUN/scene.ply, written when a run finishes; FileNotFoundError saying how to get it where
    the run has not finished (stopped with a checkpoint: --resume) or not started, or that
    `run_dir` is a dataset; Busy while another process trains it."""
    ply = Path(run_dir) / SCENE
    if ply.exists():
        return ply
    from .data.dataset import layout_files  # (the data package imports this module)

    marks = layout_files(Path(run_dir))
    if marks:  # a dataset given where a run goes (before its lock, which a training reads by)
        raise FileNotFoundError(
            f"{run_dir}: a dataset (its {', '.join(marks)}), not a run folder (spikegs train "
            f"{shell_path(run_dir)} --out RUN trains one)"
        )
    lock = Path(run_dir) / LOCK
    if lock.is_file():  # a run being trained holds it (`spikegs train`): --resume would fail
        busy = f"{ply} not found yet: {run_dir} is being trained by another process"
        try:
            with exclusive_lock(lock, busy):
                pass
        except Busy:
            raise Busy(f"{busy}; try again once it has finished") from None
        except OSError:  # a folder this process cannot write: not known to be busy
            pass
    if last_checkpoint(run_dir).exists():
        raise FileNotFoundError(
            f"{ply} not found: the run stopped before its end; finish it with "
            f"{resume_command(run_dir)}"
        )
    if not Path(run_dir).is_dir():
        what = "a file, not a run folder" if Path(run_dir).exists() else "no such run folder"
        raise FileNotFoundError(f"{run_dir}: {what} (spikegs train ... --out RUN)")
    runs = sorted(  # a folder of one's runs (it was told to train), a demo's or a bench's
        p.parent.relative_to(run_dir).as_posix()
        for pattern in (f"*/{CONFIG}", f"runs/*/{CONFIG}", f"runs/*/*/{CONFIG}")
        for p in Path(run_dir).glob(pattern)
        if (p.parent / LOG).is_file()  # a run's (another tool's config.yaml alone: not)
    )
    if runs:
        shown = ", ".join(runs[:4]) + (f" and {len(runs) - 4} more" if len(runs) > 4 else "")
        whose = ": a demo's or a bench's" if any(r.startswith("runs/") for r in runs) else ""
        raise FileNotFoundError(
            f"{run_dir}: a folder of runs ({shown}{whose}), not a run; give one of them, e.g. "
            f"{shell_path(Path(run_dir) / runs[0])}"
        )
    raise FileNotFoundError(f"{ply} not found: train the run first (spikegs train)")


def trained_model(run_dir: Path):
    """The GaussianModel of `trained_scene`; its ValueError where scene.ply cannot be read, saying
    that --resume writes it again where the run has its checkpoint (a damaged scene.ply was named
    without a way out)."""
    from .ply import load_ply  # (torch's: commands that read train.json alone need none)

    ply = trained_scene(run_dir)
    try:
        return load_ply(ply)
    except ValueError as err:
        if not last_checkpoint(run_dir).is_file():
            raise
        raise ValueError(
            f"{err}; {resume_command(run_dir)} writes it again from the run's checkpoint"
        ) from None
