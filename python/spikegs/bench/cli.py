"""`spikegs bench PART`: run one benchmark part (or all) and write JSON, plots and a table."""

from __future__ import annotations

import argparse
import importlib
from pathlib import Path

# part -> module with `run(quick: bool, out: Path) -> dict`
PARTS = {
    "rasterizer": "spikegs.bench.rasterizer",
    "spikes": "spikegs.bench.spikes",
    "sim": "spikegs.bench.sim",
    "train": "spikegs.bench.train",
}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("part", choices=[*PARTS, "all"], help="which benchmark to run")
    parser.add_argument("--quick", action="store_true", help="small sizes: checks the suite runs")
    parser.add_argument("--out", type=Path, default=Path("bench-results"), help="output folder")


def run(args: argparse.Namespace) -> int:
    parts = list(PARTS) if args.part == "all" else [args.part]
    for part in parts:
        try:
            module = importlib.import_module(PARTS[part])
        except ModuleNotFoundError as err:
            if err.name != PARTS[part]:
                raise
            print(f"== {part}: not part of this build, skipped")
            continue
        print(f"== {part}")
        module.run(quick=args.quick, out=args.out)
    return 0
