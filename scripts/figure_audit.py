"""What a researcher would see in a run's figures, measured (BENCHMARKS.md, "The figures, looked
at"): the render's alignment with the ground truth and tile seams in RUN/eval/*.png, and an orbit
video against the renders at its cameras.

    python scripts/figure_audit.py RUN [VIDEO]

RUN/eval/*.png: the mean squared error of the render panel shifted by -1, 0, +1 pixels against
the ground-truth panel (the best shift, and the sub-pixel one of a parabola through the three),
and each panel's mean step across the 16-pixel tile boundaries over that elsewhere (1: no seam).
VIDEO (an .mp4 or .gif of `spikegs render RUN`, its cameras in VIDEO.json): its frames decoded
(PyAV) against `orbit_frames` at those cameras, the coded luma against BT.601's of the renders,
and the frame-to-frame mean |difference| (a jump or a pop: a frame's far above the median).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

TILE = 16  # the rasterizer's tile side, pixels


def eval_panels(run: Path):
    """(ground truth, render) [H, W, C] of each RUN/eval/*.png, sRGB values in [0, 1]."""
    from spikegs.image_io import read_image
    from spikegs.image_labels import TITLE_HEIGHT, title_scale

    for path in sorted((run / "eval").glob("*.png")):
        image = read_image(path)
        w = image.shape[1] // 3
        h = next(h for h in range(image.shape[0], 0, -1)
                 if h + TITLE_HEIGHT * title_scale(h) == image.shape[0])  # fmt: skip
        yield image[-h:, :w], image[-h:, w : 2 * w]


def shifts(run: Path) -> dict:
    """Mean squared error over the views of the render shifted by (dy, dx) against the truth."""
    errors = {}
    for gt, render in eval_panels(run):
        h, w = gt.shape[:2]
        for dy in (-1, 0, 1):
            for dx in (-1, 0, 1):
                moved = render[1 + dy : h - 1 + dy, 1 + dx : w - 1 + dx]
                errors[dy, dx] = errors.get((dy, dx), 0.0) + np.mean((gt[1:-1, 1:-1] - moved) ** 2)
    return errors


def sub_pixel(minus: float, zero: float, plus: float) -> float:
    """The vertex of the parabola through errors at -1, 0, +1 pixels."""
    return 0.5 * (minus - plus) / (minus - 2 * zero + plus)


def seams(run: Path) -> dict:
    """{panel: (x, y)}: the mean |step| across tile boundaries over that across other pixel
    boundaries, columns and rows."""
    steps = {"truth": np.zeros((2, TILE)), "render": np.zeros((2, TILE))}
    for panels in eval_panels(run):
        for name, panel in zip(steps, panels):
            for axis in (0, 1):
                step = np.abs(np.diff(panel, axis=1 - axis)).mean(axis=(axis, 2))  # [side - 1]
                np.add.at(steps[name][axis], np.arange(1, len(step) + 1) % TILE, step)
    return {name: tuple(s[0] / s[1:].mean() for s in sums) for name, sums in steps.items()}


def video(run: Path, path: Path) -> dict:
    """The decoded frames of `path` against the renders at its cameras."""
    import av
    from PIL import Image
    from spikegs.data import load_dataset
    from spikegs.ply import load_ply
    from spikegs.render_cli import orbit_frames

    meta = json.loads(Path(f"{path}.json").read_text())
    viewmats = np.stack([np.linalg.inv(f["transform_matrix"]) for f in meta["frames"]])
    dataset = load_dataset(meta["dataset"])
    renders = np.stack(list(orbit_frames(load_ply(run / "scene.ply"), dataset, viewmats)))
    h, w = renders.shape[1:3]
    result = {}
    if path.suffix == ".mp4":
        with av.open(str(path)) as container:
            frames = list(container.decode(video=0))
        decoded = np.stack([f.to_ndarray(format="rgb24")[:h, :w] for f in frames])
        luma = np.stack([f.to_ndarray(format="yuv420p")[:h, :w] for f in frames])
        exact = 16 + 219 / 255 * (renders @ np.array([0.299, 0.587, 0.114]))  # BT.601, limited
        result["luma - BT.601 of the renders"] = float((luma - exact).mean())
    else:
        gif = Image.open(path)
        decoded = []
        for i in range(gif.n_frames):
            gif.seek(i)
            decoded.append(np.asarray(gif.convert("RGB")))
        decoded = np.stack(decoded)
    difference = decoded.astype(float) - renders
    steps = np.abs(np.diff(decoded.astype(float), axis=0)).mean(axis=(1, 2, 3))  # [F - 1]
    result.update(
        {
            "frames": len(decoded),
            "size": f"{w}x{h}",
            "decoded - render (8-bit steps), mean": float(difference.mean()),
            "mean |decoded - render|": float(np.abs(difference).mean()),
            "frame-to-frame mean |diff|: median, largest / median": (
                float(np.median(steps)),
                float(steps.max() / np.median(steps)),
            ),
        }
    )
    return result


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("run", type=Path, help="a run evaluated with its images (spikegs eval)")
    parser.add_argument("video", type=Path, nargs="?", help="spikegs render RUN's .mp4 or .gif")
    args = parser.parse_args()
    run = args.run
    errors = shifts(run)
    if not errors:
        sys.exit(f"{run / 'eval'}: no side-by-side images (spikegs eval without --no-images)")
    best = min(errors, key=errors.get)
    dy = sub_pixel(errors[-1, 0], errors[0, 0], errors[1, 0])
    dx = sub_pixel(errors[0, -1], errors[0, 0], errors[0, 1])
    print(f"{run}: best shift (dy, dx) {best}, sub-pixel ({dy:+.3f}, {dx:+.3f}) px")
    for name, (x, y) in seams(run).items():
        print(f"  {name}: step at a tile boundary / elsewhere: columns {x:.3f}, rows {y:.3f}")
    if args.video is not None:
        for key, value in video(run, args.video).items():
            print(f"  {key}: {value}")


if __name__ == "__main__":
    main()
