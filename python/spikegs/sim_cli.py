"""`spikegs sim-train DATASET`: train SIM on a dataset's spikes (or reuse the cached weights), then
compare it with TFP(33), TFP(65) and TFI on the held-out on-path views."""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import sys
from dataclasses import asdict
from pathlib import Path

from . import strict_json
from .atomic_save import write_text_atomically
from .cli import add_no_progress, file_path, output_file, positive_int, seed, show_bars
from .config import Config, SimConfig, SupervisionConfig, TrainConfig
from .data.dataset import load_dataset, reading_dataset
from .data.real import pseudo_views_note
from .flicker import cached_flicker, divisible
from .interrupt import say
from .losses import SIM_LOSSES
from .output_paths import check_file_output, record_beside
from .pixel_defects import sensor_defects
from .provenance import environment
from .sim_scores import evaluate_dataset, on_path_views
from .sim_train import SAVED_EVERY, is_sim_file, recorded_seconds
from .targets import check_targets, intensity_scale, trained_sim
from .text_table import print_table

# the config keys that the options set, named in the config's messages
FLAGS = {
    "sim.window": "--window",
    "sim.target_window": "--target-window",
    "sim.iterations": "--steps",
    "sim.batch": "--batch-size",
    "sim.crop": "--crop",
    "train.seed": "--seed",
}

MEMORY_SIZES = "--batch-size, --crop, --window"  # (`cli.MEMORY_SIZES`)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sim = SimConfig()
    parser.add_argument(
        "dataset", type=file_path, help="dataset folder (spikegs simulate writes one)"
    )
    parser.add_argument(
        "--window", type=positive_int, default=sim.window, help="spike window, readouts"
    )
    parser.add_argument(
        "--target-window",
        type=int,
        default=sim.target_window,
        help="readouts at the window's centre whose TFP SIM learns (0: the whole window)",
    )
    parser.add_argument("--steps", type=positive_int, default=sim.iterations, help="training steps")
    parser.add_argument("--batch-size", type=positive_int, default=sim.batch, help="crops per step")
    parser.add_argument(
        "--crop",
        type=positive_int,
        default=sim.crop,
        help="crop side, pixels (at most a frame side)",
    )
    parser.add_argument(
        "--loss", choices=tuple(SIM_LOSSES), default=sim.loss, help="loss against TFP"
    )
    parser.add_argument(
        "--seed",
        type=seed,
        default=TrainConfig().seed,
        help="seed of SIM's training (a training run's train.seed picks the SIM of its seed)",
    )
    parser.add_argument(
        "--out",
        type=output_file,
        help="weights (default: the dataset's SIM cache, where spikegs train looks; the file name "
        "holds every setting, and train reuses a SIM made with its config's own)",
    )
    parser.add_argument(
        "--force",
        action="store_true",
        help="retrain even if the weights exist (a saved SIM's: another file at --out is never "
        "replaced)",
    )
    add_no_progress(parser)


def run(args: argparse.Namespace) -> int:
    # no simulation or `spikegs poses` rewrites the dataset under SIM (Busy while one does)
    with reading_dataset(args.dataset):
        return _run(args)


def _is_scores_record(path: Path) -> bool:
    """Whether the file at `path` holds a record of SIM's scores that this command wrote."""
    try:
        record = strict_json.read_json(path)
    except (ValueError, OSError):
        return False
    return {"sim", "dataset", "scores"} <= record.keys()


def _run(args: argparse.Namespace) -> int:
    """`run` once the dataset is locked."""
    sim = SimConfig(
        window=args.window,
        target_window=args.target_window,
        iterations=args.steps,
        crop=args.crop,
        batch=args.batch_size,
        loss=args.loss,
    )
    # SIM alone: no exposure loss, whose window would be checked too
    config = Config(
        sim=sim,
        train=TrainConfig(seed=args.seed),
        supervision=SupervisionConfig(instant="sim", exposure_weight=0.0),
    )
    if args.out is not None:
        check_file_output(args.out)
        if Path(args.out).exists() and not is_sim_file(Path(args.out)):
            raise ValueError(  # (a cache's torn file is retrained over; a file named is not)
                f"--out {args.out}: an existing file that is not a saved SIM, which sim-train "
                f"does not replace, --force or not; give another path (where it is a SIM's "
                f"file cut short, delete it first)"
            )
        record = record_beside(Path(args.out))
        if record.exists() and not _is_scores_record(record):  # (`--out DATASET/test_views`
            raise ValueError(  # wrote the scores over the dataset's test_views.json)
                f"--out {args.out}: its scores go to {record}, an existing file that is not "
                f"sim-train's record; give another path (SIM's weights are named *.pt)"
            )
    bars = show_bars(args.no_progress)
    try:  # the config's rules, and the window around the dataset's timestamps
        config.validate()
        dataset = load_dataset(args.dataset, bars)
        check_targets(dataset, config)
    except ValueError as err:
        key = next((k for k in FLAGS if f"{k} =" in str(err)), None)
        raise ValueError(f"{FLAGS[key]}: {err}" if key else str(err)) from None
    views = on_path_views(dataset, sim.window)  # what SIM is scored on, before it is trained
    # the spikes that training's SIM learns from (the sensor's defects repaired): the one made
    # here is the one it reuses, and every decoder is scored on them
    defects = sensor_defects(dataset.streams, dataset.root, config.supervision.mask_defects)
    try:
        model, seconds, out = trained_sim(
            dataset,
            sim,
            args.seed,
            path=args.out,
            force=args.force,
            progress=bars,
            streams=defects.streams,
        )
    except KeyboardInterrupt:  # (stderr may be gone: a closed terminal's SIGHUP)
        say(
            "\nthe same command (without --force) continues from SIM's last saved state, if "
            f"its training had begun ({SAVED_EVERY})"
        )
        raise
    done = f"trained in {seconds:.1f} s" if seconds else "reused"
    if not seconds:  # the latest SIM now, as `spikegs poses --sim` picks (by modification time)
        with contextlib.suppress(OSError):  # (a read-only dataset's reused SIM: it crashed)
            os.utime(out)
    print(f"SIM ({model.num_parameters()} parameters) {done}: {out}")
    # the light's flicker, divided out of every method's images as out of training's targets
    found = cached_flicker(dataset.streams, bars) if config.supervision.deflicker else None
    flicker = divisible(found)
    scores = evaluate_dataset(model, dataset, None, defects.streams, flicker, views)
    units = -20 * math.log10(intensity_scale(dataset))  # rates are intensity x that scale
    record = record_beside(out)  # the table for a script, beside the weights, never over them
    summary = {
        "sim": str(Path(out).resolve()),
        "dataset": str(Path(dataset.root).resolve()),
        "parameters": model.num_parameters(),
        "seconds": recorded_seconds(Path(out)),  # its training time, as it recorded it
        "trained_now": bool(seconds),
        "views": [v.name for v in views],  # on the camera's path: scored at their readouts
        "units": (
            f"firing rates, spikes a readout, data range 1 (PSNR {units:.1f} dB above eval's, "
            f"SSIM higher too)"
        ),
        "scores": scores,
        "defect_pixels": defects.pixels,  # repaired in the spikes scored
        "flicker": None if found is None else {**asdict(found), "divided": flicker is not None},
        "environment": environment(),
    }
    # written before the table is printed: a stdout on a full disk left it unwritten (the
    # environment trial); reused weights may lie where nothing is written: the table stands
    written = None
    try:
        write_text_atomically(record, strict_json.dumps(summary, indent=2))
        written = f"scores: {record}"
    except OSError as err:
        print(f"scores not written beside the weights: {err}", file=sys.stderr)
    print_table([{"method": name, **s} for name, s in scores.items()])
    print(
        f"(PSNR of firing rates, spikes a readout, over a data range of 1: {units:.1f} dB above "
        f"the same error in the intensity units of spikegs eval; SSIM higher too; the means over "
        f"the {len(views)} test views on the camera's path, at their readouts)"
    )
    if defects.pixels:
        print(
            f"({defects.pixels} hot, stuck or dead pixels of the sensor fire as a neighbour in "
            f"the spikes every method reads, as SIM's training reads them)"
        )
    if found is not None:
        done = "each method's images divided by it" if flicker else "too deep to divide out"
        print(
            f"(the light flickers with a period of {found.period:.1f} readouts, depth "
            f"{found.depth:.2f}: {done}, as training's targets are)"
        )
    if written:
        print(written)
    note = pseudo_views_note(v.name for v in views)
    if note:
        print(
            f"{note}: the TFP rows are scored against TFP of the same spikes (a method on the "
            f"views whose ground truth it is, left out)"
        )
    return 0
