"""`spikegs bench PART`: run one benchmark part (or all) and write JSON, plots and a table."""

from __future__ import annotations

import argparse
import importlib
import sys
import time
from pathlib import Path

from ..cli import add_no_progress, file_path, positive_float, positive_int, show_bars
from ..demo import DEMO_OVERRIDES
from ..file_lock import exclusive_lock
from ..output_paths import check_folder_output
from ..run_folder import is_bench_results, refuse_dataset_or_run
from ..run_summary import LOCK
from .train import (
    FULL_ITERATIONS,
    HEADLINE_SCENE,
    QUICK_ITERATIONS,
    QUICK_METHODS,
    VARIANTS,
)

# part -> module with `run(quick: bool, out: Path) -> dict`
PARTS = {
    "rasterizer": "spikegs.bench.rasterizer",
    "spikes": "spikegs.bench.spikes",
    "sim": "spikegs.bench.sim",
    "train": "spikegs.bench.train",
    "stiff": "spikegs.bench.stiff",
    "poses": "spikegs.bench.poses",
}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(  # (metavar: the name a missing part's error says, as usage shows it)
        "part",
        choices=[*PARTS, "all"],
        metavar="part",
        help=f"which benchmark to run: {', '.join(PARTS)}, or all (each in turn)",
    )
    parser.add_argument("--quick", action="store_true", help="small sizes: checks the suite runs")
    parser.add_argument(
        "--out",
        type=file_path,
        default=None,
        help="output folder (default bench-results, or bench-results-quick with --quick, so "
        "that a quick run leaves a full one's files in the default folder alone; given, a part "
        "run into it replaces its own files there, quick or not)",
    )
    add_no_progress(parser, " in bench sim's SIM training")
    parser.add_argument(
        "--iterations",
        type=positive_int,
        help=f"training iterations per run (bench train; default {FULL_ITERATIONS}, "
        f"{QUICK_ITERATIONS} with --quick)",
    )
    parser.add_argument(
        "--seeds",
        type=positive_int,
        help="bench train: runs per method and scene (seeds 0..N-1; default 1)",
    )
    parser.add_argument(
        "--scenes",
        help=f"bench train: comma-separated scenes (default: all, {HEADLINE_SCENE} with --quick)",
    )
    parser.add_argument(
        "--methods",
        help=f"bench train: comma-separated methods (default: every method but "
        f"{', '.join(VARIANTS)}; with --quick, {','.join(QUICK_METHODS)})",
    )
    parser.add_argument(
        "--equal-time",
        action="store_true",
        help="bench train: train each baseline again for SpikeGS's seconds, SIM's training "
        "included (its schedule stretched to as many iterations): the margins at equal time "
        "beside those at equal iterations",
    )
    parser.add_argument(
        "--grad-threshold",
        type=positive_float,
        help="bench train: densification threshold for every method (default: the demo's "
        f"{DEMO_OVERRIDES['densify']['grad_threshold']})",
    )
    parser.add_argument(
        "--spp",
        type=positive_int,
        help="bench train: samples per pixel of the simulated scenes, on an s×s grid (a square: "
        "each pixel its box's mean light, as a camera's; default 1, the pixel centres)",
    )


def _train_options(args: argparse.Namespace) -> dict:
    """bench train's keyword arguments from the command line."""
    options = {"equal_time": True} if args.equal_time else {}
    for name in ("seeds", "iterations", "grad_threshold", "spp"):
        if getattr(args, name) is not None:
            options[name] = getattr(args, name)
    for name in ("scenes", "methods"):
        text = getattr(args, name)
        if text is not None:
            options[name] = [v.strip() for v in text.split(",") if v.strip()]
            if not options[name]:  # "," or "": the defaults would run instead
                raise ValueError(f"--{name} {text!r}: expected comma-separated names")
    return options


def bench_lock(out: Path):
    """An exclusive lock on OUT/.lock (OUT made) for a `with` block: one bench writes into OUT at
    a time (a second one deleted the first one's runs as they trained, and replaced its dataset);
    Busy while another holds it."""
    out.mkdir(parents=True, exist_ok=True)
    return exclusive_lock(
        out / LOCK,
        busy=f"{out} is being written by another spikegs bench; wait for it to end or give "
        f"another --out",
    )


def run(args: argparse.Namespace) -> int:
    args.out = args.out or Path("bench-results-quick" if args.quick else "bench-results")
    parts = list(PARTS) if args.part == "all" else [args.part]
    train_options = _train_options(args)
    given = [f"--{k.replace('_', '-')}" for k in train_options]  # the options of bench train's
    if given and "train" not in parts:
        raise ValueError(f"{', '.join(given)}: options of bench train, not of bench {args.part}")
    check_folder_output(args.out, images=True)  # its figures, its runs' eval images
    scenes = []  # those whose datasets and runs bench train writes
    if "train" in parts:  # a bad scene, method, seed count, spp or output fails before any part
        from .train import check_outputs, data_settings, run_names, selection

        data_settings(args.quick, train_options.get("spp", 1))
        seeds, equal_time = train_options.get("seeds", 1), args.equal_time
        scenes, methods = selection(
            args.quick,
            train_options.get("scenes"),
            train_options.get("methods"),
            seeds,
            equal_time,
        )
        check_outputs(Path(args.out), scenes, run_names(methods, equal_time), seeds)
    # (bench stiff said it would write datasets and runs, which only bench train writes there)
    refuse_dataset_or_run(Path(args.out), f"spikegs bench {args.part}", len(scenes))
    for part in parts:  # (written once the part's work was done: minutes lost, or a file)
        results = Path(args.out) / f"{part}.json"
        if results.exists() and not is_bench_results(results, part):  # (a folder is not)
            what = "a folder" if results.is_dir() else f"not spikegs bench {part}'s results"
            raise FileExistsError(
                f"{results}: {what}, where bench {part} writes them; move it, or give another --out"
            )
    failures = []
    with bench_lock(Path(args.out)):
        for part in parts:
            module = importlib.import_module(PARTS[part])
            print(f"== {part}")
            options = train_options if part == "train" else {}
            if part == "sim":  # (a bar's carriage returns garble a log: none in a batch job's)
                options = {"progress": show_bars(args.no_progress)}
            start = time.perf_counter()
            results = module.run(quick=args.quick, out=args.out, **options)
            print(f"== {part}: {time.perf_counter() - start:.1f} s")
            failures += [f"bench {part}: {f}" for f in results.get("failures", [])]
    for failure in failures:  # (a check that fails: a script, CI, must see it)
        print(f"FAILED {failure}", file=sys.stderr)
    return 1 if failures else 0
