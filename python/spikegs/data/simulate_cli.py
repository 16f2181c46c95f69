"""`spikegs simulate`: make a synthetic spike dataset (docs/datasets.md)."""

from __future__ import annotations

import argparse
import dataclasses
import time
import warnings

from ..cli import add_no_progress, direction, file_path, finite_float, seed, show_bars
from ..output_paths import check_folder_output
from ..spikes import SimParams
from .scenes import SCENES
from .simulate import (
    DEFAULT_FRAME_EVERY,
    DEFAULT_READOUTS,
    DEFAULT_SEED,
    DEFAULT_SIZE,
    DEFAULT_SPEED,
    DEFAULT_TEST_VIEWS,
    FRAME_MOTION_PX,
    simulate_dataset,
)

MEMORY_SIZES = "--height, --width, --readouts, --spp"  # (`cli.MEMORY_SIZES`)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--scene",
        default="solids",
        help=f"built-in scene ({', '.join(SCENES)}), a Mitsuba .xml file, or a NeRF-style "
        "transforms JSON / a folder holding transforms_train.json or transforms.json (default: "
        "solids)",
    )
    parser.add_argument("--out", type=file_path, required=True, help="output dataset folder")
    parser.add_argument("--height", type=int, default=DEFAULT_SIZE, help="image rows, pixels")
    parser.add_argument("--width", type=int, default=DEFAULT_SIZE, help="image columns, pixels")
    parser.add_argument(
        "--readouts", type=int, default=DEFAULT_READOUTS, help="readouts (25 µs each)"
    )
    orbit = "a built-in or Mitsuba scene's orbit; a frame sequence's frames set it"
    parser.add_argument(
        "--speed",
        type=finite_float,
        help=f"degrees of orbit per readout (default {DEFAULT_SPEED}; {orbit})",
    )
    parser.add_argument(
        "--up",
        type=direction,
        help=f"the scene's up as X,Y,Z, the axis the orbit ascends along (default 0,0,1; 0,1,0 "
        f"for a y-up Mitsuba scene, such as its Cornell box; {orbit})",
    )
    parser.add_argument("--seed", type=seed, default=DEFAULT_SEED, help="simulator seed")
    parser.add_argument(
        "--frame-every",
        type=finite_float,
        help=f"readouts between rendered light frames, >= 1 (linear in between; default "
        f"{DEFAULT_FRAME_EVERY}, fewer where the scene would move over {FRAME_MOTION_PX:g} px "
        f"between two; a built-in or Mitsuba scene's)",
    )
    parser.add_argument("--color", action="store_true", help="colour camera: one .dat per channel")
    default = f"default {DEFAULT_TEST_VIEWS}, or as many as a frame sequence has"
    parser.add_argument(
        "--test-on-path",
        type=int,
        help=f"held-out on-path views ({default}; the default fewer, with a warning, where "
        f"--readouts leaves too little room for them)",
    )
    parser.add_argument("--test-off-path", type=int, help=f"off-path test views ({default})")
    parser.add_argument(
        "--train-every",
        type=int,
        help="readouts between training timestamps (default: at most 1024 timestamps)",
    )
    parser.add_argument(
        "--spp",
        type=int,
        help="samples per pixel: a Mitsuba scene's (default 16), or a built-in scene's on an s×s "
        "grid, each pixel its box's mean light as a camera's (a square; default 1, its centre)",
    )
    parser.add_argument("--no-flip", action="store_true", help="write .dat rows top-down")
    parser.add_argument("--overwrite", action="store_true", help="replace a dataset in --out")
    add_no_progress(parser, "", "--quiet")
    sim = parser.add_argument_group("simulator parameters (SimParams)")
    for field in dataclasses.fields(SimParams):
        flag = "--" + field.name.replace("_", "-")
        if field.type in (bool, "bool"):
            sim.add_argument(
                flag,
                action=argparse.BooleanOptionalAction,
                default=field.default,
                help=field.metadata["help"],
            )
        else:
            sim.add_argument(
                flag,
                type=_sim_param(field.name),
                default=field.default,
                help=field.metadata["help"],
            )


def _sim_param(name: str):
    """An argparse type for the SimParams field `name`: a finite number in the simulator's range,
    refused while parsing with its option named (the range's own message names the field)."""

    def parse(text: str) -> float:
        value = finite_float(text)
        try:
            with warnings.catch_warnings():  # (warned of once, as the dataset is simulated)
                warnings.simplefilter("ignore")
                SimParams(**{name: value})
        except ValueError as refused:
            raise argparse.ArgumentTypeError(str(refused)) from None
        return value

    return parse


def run(args: argparse.Namespace) -> int:
    check_folder_output(args.out, images=True)
    sim_params = {f.name: getattr(args, f.name) for f in dataclasses.fields(SimParams)}
    start = time.perf_counter()
    dataset = simulate_dataset(
        args.scene,
        args.out,
        height=args.height,
        width=args.width,
        readouts=args.readouts,
        speed=args.speed,
        seed=args.seed,
        overwrite=args.overwrite,
        color=args.color,
        frame_every=args.frame_every,
        up=args.up,
        test_on_path=args.test_on_path,
        test_off_path=args.test_off_path,
        train_every=args.train_every,
        spp=args.spp,
        flip=not args.no_flip,
        progress=show_bars(args.no_progress),
        **sim_params,
    )
    print(f"{dataset} in {time.perf_counter() - start:.1f} s")
    spacing = dataset.meta.get("frame_every")
    if args.frame_every is None and spacing not in (None, DEFAULT_FRAME_EVERY):  # (meta.json's)
        print(
            f"light rendered every {spacing:g} readouts, not {DEFAULT_FRAME_EVERY}: at this size "
            f"the scene would move over {FRAME_MOTION_PX:g} px between two frames"
        )
    return 0
