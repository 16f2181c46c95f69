"""`spikegs eval RUN`: PSNR/SSIM on the test views, written to RUN/eval.json with images."""

from __future__ import annotations

import argparse
from pathlib import Path

from .cli import add_no_progress, file_path, show_bars


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("run", type=file_path, help="run folder (spikegs train --out)")
    parser.add_argument("--dataset", type=file_path, help="dataset folder (default: the run's own)")
    parser.add_argument(
        "--no-images",
        action="store_true",
        help="write the scores only, no side-by-side images (an earlier scoring's images of views "
        "whose scores changed are removed)",
    )
    parser.add_argument(
        "--align-poses",
        action="store_true",
        help="score each test view from its pose aligned to its image first, the scene frozen "
        "(for a scene trained from estimated poses, e.g. spikegs poses'): into eval-aligned.json "
        "and eval-aligned/",
    )
    add_no_progress(parser)


def run_dataset(run_dir: Path, dataset: Path | None) -> Path:
    """The dataset a run was trained on, unless one is given."""
    if dataset is not None:
        return dataset
    from .file_lock import refuse_if_held
    from .run_summary import (
        LOCK,
        SUMMARY,
        dataset_there,
        last_checkpoint,
        read_summary,
        resume_command,
        trained_scene,
    )

    summary = read_summary(run_dir)
    if "dataset" not in summary:
        trained_scene(run_dir)  # a run stopped with a checkpoint: finish it with --resume
        if not (run_dir / SUMMARY).exists() and last_checkpoint(run_dir).exists():
            # its training may be writing them now (train.json follows scene.ply)
            refuse_if_held(
                run_dir / LOCK,
                f"{run_dir / SUMMARY} not found yet: {run_dir} is being trained by another "
                f"process, which is writing its results; try again once it has finished",
            )
            # killed between scene.ply and train.json, its last writes: --resume writes the rest
            raise FileNotFoundError(
                f"{run_dir / SUMMARY} not found: the run stopped while writing its results; "
                f"finish it with {resume_command(run_dir)}"
            )
        raise FileNotFoundError(
            f"{run_dir / SUMMARY} not found or without a dataset: is {run_dir} a finished run? "
            f"(a scene.ply from another tool is scored and rendered with --dataset DATASET)"
        )
    own = Path(summary["dataset"])
    if not dataset_there(own):  # (a folder a process made there, once the dataset moved
        # mid-run: "no dataset found", without the remedy)
        raise FileNotFoundError(f"the run's dataset {own} is gone: pass --dataset DATASET")
    return own


def run(args: argparse.Namespace) -> int:
    from .data import load_dataset
    from .data.dataset import reading_dataset
    from .data.real import pseudo_views_note
    from .evaluate import evaluate_run

    root = run_dataset(args.run, args.dataset)
    bars = show_bars(args.no_progress)  # (a recording's flicker search as it loads)
    with reading_dataset(root):  # not rewritten as it is read (Busy while it is)
        dataset = load_dataset(root, bars)
        result = evaluate_run(
            args.run, dataset, not args.no_images, progress=bars, align_poses=args.align_poses
        )
    method = result["method"] or args.run.name  # a scene folder of another tool names none
    print(
        f"{method}: PSNR {result['psnr']:.2f} dB, SSIM {result['ssim']:.4f} "
        f"over {len(result['views'])} test views -> {result['file']}"
    )
    if args.align_poses:  # the median move, and the view that moved most (an outlier: suspect)
        moved, views = result["aligned_poses"], result["views"]
        most = max(views, key=lambda name: views[name]["aligned_rotation_deg"])
        print(
            f"(each view's pose aligned to its image first: moved a median "
            f"{moved['rotation_deg_median']:.2f} deg, at most "
            f"{views[most]['aligned_rotation_deg']:.2f} ({most}), its centre "
            f"{moved['centre_median']:.2%} of the scene radius)"
        )
    note = pseudo_views_note(result["views"])
    if note:
        print(note)
    return 0
