"""The audit behind docs/datasets.md's figures for frames read at the wrong size: spike files
given at 1/m of their frame size (LLFF's hwf of downsampled images) or at m times it (the
full-size images' hwf), which `warn_rows_out_of_line` should name, and files read right under
fast motion, hot pixels or few spikes, which it should not. Simulates the built-in scenes at
several sizes, speeds and seeds into OUT (minutes on two cores) and prints the counts;
OUT/audit.json holds each stream's row.

    python scripts/frame_size_audit.py OUT
"""

from __future__ import annotations

import argparse
import itertools
import json
import warnings
from pathlib import Path

import numpy as np
from spikegs.data import simulate_dataset
from spikegs.data.dataset import WIDER_MIN_SIZE, _rows_alike, warn_rows_out_of_line
from spikegs.data.scenes import SCENES
from spikegs.spikes.stream import SpikeStream, save_dat

# (frame sizes, speeds in degrees a readout: None the default) of each part
FRACTIONS = ([(16, 16), (16, 24), (24, 32), (32, 48), (48, 64)], [None, 2.0])
RIGHT = ([(16, 16), (16, 32), (24, 24), (32, 32), (40, 24), (32, 48), (48, 64)], [3.0, 8.0])
SCALES = (-4, -2, 1, 2, 4)  # the size given: -m is 1/m of the frames' own, m is m times it
# what the warning says of a file given at 1/m of its size, and at m times it
NAMED = {False: "times the width", True: "of the size given"}
SEEDS = (0, 1, 2)


def warned(stream: SpikeStream) -> str:
    """The first warning `warn_rows_out_of_line` gives on `stream`, or ""."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        warn_rows_out_of_line(stream, "x")
    return str(caught[0].message) if caught else ""


def simulated(out: Path, scene: str, size: tuple, speed, seed: int, readouts: int):
    """A dataset of `scene` simulated into OUT, and its spikes [T, H, W], 0/1 uint8."""
    h, w = size
    data = simulate_dataset(
        scene,
        out / f"{scene}_{h}x{w}_{speed}_{seed}",
        height=h,
        width=w,
        readouts=readouts,
        speed=speed,
        seed=seed,
        test_on_path=1,
        test_off_path=1,
        progress=False,
        overwrite=True,
    )
    n = len(data.stream)
    return data, data.stream.window(n // 2, n)


def fractions(out: Path) -> list[dict]:
    """Streams given at 1/m of their size and at m times it (SCALES; 1 read right), with and
    without 3 % hot pixels."""
    rows = []
    sizes, speeds = FRACTIONS
    for scene, size, speed, seed in itertools.product(SCENES, sizes, speeds, SEEDS[:2]):
        data, bits = simulated(out, scene, size, speed, seed, 800)
        bits[:, np.random.default_rng(seed).random(size) < 0.03] = 1
        save_dat(data.root / "hot.dat", bits)
        for path, m in itertools.product((data.stream.path, data.root / "hot.dat"), SCALES):
            if m < 0 and (size[0] % m or size[1] % m):
                continue
            given = [n * m if m > 0 else n // -m for n in size]
            stream = SpikeStream.open(path, *given)
            said = warned(stream)
            judged = min(size if m > 0 else given) >= WIDER_MIN_SIZE
            rows.append(
                dict(
                    stream=f"{data.root.name}/{path.name}",
                    m=m,
                    judged=judged,
                    as_read=round(_rows_alike(stream), 2),
                    named=NAMED[m > 0] in said,
                    warned=bool(said),
                )
            )
    return rows


def right(out: Path) -> list[dict]:
    """Streams read right under fast motion, with 10 % hot pixels or thinned to 15 % of their
    spikes and 2 % hot."""
    rows = []
    sizes, speeds = RIGHT
    for scene, size, speed, seed in itertools.product(SCENES, sizes, speeds, SEEDS):
        data, bits = simulated(out, scene, size, speed, seed, 600)
        rng = np.random.default_rng(seed)
        for name, hot, kept in (("hot", 0.1, 1.0), ("dim", 0.02, 0.15)):
            spikes = bits & (rng.random(bits.shape) < kept)
            spikes[:, rng.random(size) < hot] = 1
            save_dat(data.root / f"{name}.dat", spikes)
            stream = SpikeStream.open(data.root / f"{name}.dat", *size)
            rows.append(
                dict(
                    stream=f"{data.root.name}/{name}.dat",
                    m=1,
                    judged=True,
                    as_read=round(_rows_alike(stream), 2),
                    named=False,
                    warned=bool(warned(stream)),
                )
            )
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path, help="folder for the simulated datasets")
    out = parser.parse_args().out
    out.mkdir(parents=True, exist_ok=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the simulator's on fast motion
        given, read = fractions(out), right(out)
    (out / "audit.json").write_text(json.dumps({"fractions": given, "right": read}, indent=1))
    for larger in (False, True):
        wrong = [r for r in given if (r["m"] > 1 if larger else r["m"] < 0) and r["judged"]]
        print(
            f"given at {'m times' if larger else '1/m of'} their size, judged (frames of 16 rows "
            f"and columns or more): {len(wrong)}, named {sum(r['named'] for r in wrong)}"
        )
    ok = [r for r in given if r["m"] == 1] + read
    print(
        f"read right: {len(ok)} ({sum(r['as_read'] < 0.5 for r in ok)} under 0.5, searched), "
        f"warned {sum(r['warned'] for r in ok)}"
    )


if __name__ == "__main__":
    main()
