"""A run rendered at other sizes than its training images, against Mitsuba's box-filtered ground
truth at those sizes (BENCHMARKS.md, "Renders at another size"); Mitsuba 3 (`pip install
".[mitsuba]"`).

    python scripts/renders_at_other_sizes.py RUN SCENE.xml SIDE [SIDE ...] [--spp N]

RUN: a run of `spikegs train` on a dataset simulated from SCENE.xml (`spikegs simulate --scene
SCENE.xml`); SIDE: the frames' larger side in pixels. At each size, the test views' PSNR / SSIM
(linear intensity, as `spikegs eval`) and milliseconds a frame (median) of three ways to make the
frame: `render_size.render_scaled` (what `spikegs render --scale` draws), the rasterizer at that
size as it is, and the training size's render resized (torch's bicubic larger, area smaller).
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F
from spikegs.data import load_dataset
from spikegs.data.simulate import make_source
from spikegs.evaluate import render_view, view_metrics
from spikegs.ply import load_ply
from spikegs.render_size import render_scaled, scaled_camera
from spikegs.run_summary import trained_scene
from spikegs.targets import intensity_scale

WAYS = ("render_scaled", "as it is", "resized")  # how a frame is made, `_frame`'s names


def _resized(image: np.ndarray, width: int, height: int) -> np.ndarray:
    """An image [H, W, C] resized to `width`×`height`: bicubic larger, the pixels' mean smaller."""
    larger = width > image.shape[1]
    pixels = torch.from_numpy(image).permute(2, 0, 1)[None]  # [1, C, H, W]
    mode = {"mode": "bicubic", "align_corners": False} if larger else {"mode": "area"}
    return F.interpolate(pixels, size=(height, width), **mode)[0].permute(1, 2, 0).numpy()


def _frame(way: str, model, viewmat: np.ndarray, dataset, scale: float) -> np.ndarray:
    """The frame [h, w, C] `scale` times the dataset's size from `viewmat` [4, 4], made `way`."""
    camera = scaled_camera(dataset, scale, 1)
    if way == "render_scaled":
        return render_scaled(model, viewmat, dataset, scale)
    if way == "as it is":
        return render_view(model, viewmat, camera)
    return _resized(render_view(model, viewmat, dataset), camera.width, camera.height)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("run", type=Path)
    parser.add_argument("scene", type=Path)
    parser.add_argument("sides", type=int, nargs="+")
    parser.add_argument("--spp", type=int, default=256, help="ground truth's samples a pixel")
    args = parser.parse_args()
    train = json.loads((args.run / "train.json").read_text())
    dataset = load_dataset(Path(train["dataset"]))
    model = load_ply(trained_scene(args.run))
    # the scene's intensity 1 in the render's units: the dataset's (test images') over the run's
    units = dataset.meta["image_scale"] / (train.get("intensity_scale") or intensity_scale(dataset))
    print("side  scale  " + "  ".join(f"{way}: PSNR / SSIM, ms a frame" for way in WAYS))
    for side in args.sides:
        scale = side / max(dataset.width, dataset.height)
        camera = scaled_camera(dataset, scale, 1)
        truth = make_source(args.scene, camera.width, camera.height, dataset.channels, spp=args.spp)
        scores, seconds = {}, {}
        # the ground truth first: a render timed just after Mitsuba's took 1.5-2x as long
        truths = [truth.render(view.viewmat) * units for view in dataset.test_views]  # [h, w, C]
        for view, gt in zip(dataset.test_views, truths):
            for way in WAYS:
                start = time.perf_counter()
                image = _frame(way, model, view.viewmat, dataset, scale)
                seconds.setdefault(way, []).append(time.perf_counter() - start)
                scores.setdefault(way, []).append(view_metrics(image, gt, ("ssim",)))
        cells = [
            f"{np.mean([s['psnr'] for s in scores[n]]):.2f} / "
            f"{np.mean([s['ssim'] for s in scores[n]]):.4f}, "
            f"{1000 * statistics.median(seconds[n]):.1f}"
            for n in WAYS
        ]
        print(f"{side:4d}  {scale:5.3g}  " + "  ".join(cells), flush=True)


if __name__ == "__main__":
    main()
