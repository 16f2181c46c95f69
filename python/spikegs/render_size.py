"""Renders at a size other than the training images': drawn no finer than training saw the scene.

The rasterizer widens every splat by its dilation, px² of the image it draws (3DGS's low-pass
filter, 0.3 unless `train.dilation` says otherwise), and training fitted the Gaussians with that
filter at the training images' size. Drawn S times larger, a splat keeps only 1/S² of it and thin
Gaussians thin further; drawn smaller, every pixel takes one sample of a scene fitted to finer
pixels and aliases. So a larger frame widens each Gaussian in 3D by the filter its finer pixels miss
at its depth in the view, and a smaller one averages m×m pixels of a render at least the training
images' size (BENCHMARKS.md, "Renders at another size": against a box-filtered ground truth of a
textured scene, 4x larger 24.13 dB against 23.07 drawn as it is, 1/4 the size 33.15 dB against
20.03; on the Cornell box's broad walls the widening cost 0.14-0.25 dB at 1.5-2x and gained 0.15 at
4x). A model trained with the antialiased filter (`train.antialiased`) keeps each splat's mass in
any pixels: it is averaged the same way smaller, and drawn as it is larger (widened, its splats
gained mass). So is one with the 3D smoothing filter (`train.filter_3d`), which already keeps each
Gaussian no finer than the training views sampled it (widened too, TFP(33)+3DGS's plain model with
the filter scored 0.42 and 0.83 dB lower at 4x on the textured scene and the Cornell box:
BENCHMARKS.md, "Mip-Splatting's 3D smoothing filter").
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import torch

from .box_filter import block_means
from .data.dataset import camera_keys
from .gaussians import GaussianModel

MAX_SIDE = 8192  # pixels a side of a scaled frame (8192² colour: 0.8 GB a render)


@dataclasses.dataclass(frozen=True)
class Camera:
    """What `evaluate.render_view` draws with, a dataset's alike: intrinsics K [3, 3] (pixels),
    the image's size, the scene's sphere (its near plane and the training frame's origin)."""

    K: np.ndarray
    width: int
    height: int
    scene_center: np.ndarray
    scene_radius: float


def scaled_size(width: int, height: int, scale: float) -> tuple[int, int]:
    """(width, height) `scale` times a `width`×`height` image's, each rounded half up (round()'s
    half to even made 5x7 at 0.5 render 2x4, a 3 and a 5 both 2, and 64x1 refused as 32x0);
    ValueError where a side would be under 1 or over MAX_SIDE pixels."""
    # (1e308: inf, which rounding raised on)
    size = [
        math.floor(side + 0.5) if math.isfinite(side) else side
        for side in (width * scale, height * scale)
    ]
    if not all(1 <= side <= MAX_SIDE for side in size):
        raise ValueError(
            f"scale (--scale) {scale:g}: {width}x{height} images would render at "
            f"{size[0]}x{size[1]}; a side from 1 to {MAX_SIDE} pixels"
        )
    return size[0], size[1]


def scaled_keys(keys: dict, scale: float, supersample: int = 1) -> dict:
    """Camera `keys` as `dataset.camera_keys` states them (fl_x, fl_y, cx, cy, w, h) for images
    `scale` times as large (`scaled_size`), each pixel split into `supersample`²: focal lengths
    and centre scaled as the sides (pixel centres at +0.5)."""
    width, height = scaled_size(keys["w"], keys["h"], scale)
    width, height = width * supersample, height * supersample
    sx, sy = width / keys["w"], height / keys["h"]
    return {
        "fl_x": keys["fl_x"] * sx,
        "fl_y": keys["fl_y"] * sy,
        "cx": keys["cx"] * sx,
        "cy": keys["cy"] * sy,
        "w": width,
        "h": height,
    }


def scaled_camera(dataset, scale: float, supersample: int) -> Camera:
    """The dataset's camera with its images `scaled_keys`' size, each pixel split into
    `supersample`²."""
    keys = scaled_keys(camera_keys(dataset.meta), scale, supersample)
    K = np.array([[keys["fl_x"], 0, keys["cx"]], [0, keys["fl_y"], keys["cy"]], [0, 0, 1]])
    return Camera(K, keys["w"], keys["h"], dataset.scene_center, dataset.scene_radius)


def supersampling(dataset, scale: float, trained: dict | None = None) -> int:
    """The m whose m×m pixels a frame `scale` times the dataset's size averages: the least that
    makes them as fine as the training camera's (`trained`: its keys as `scaled_keys` reads
    them; default the dataset's) or finer (1 where the frame's already are)."""
    trained = camera_keys(dataset.meta) if trained is None else trained
    frame = scaled_keys(camera_keys(dataset.meta), scale)
    coarser = max(trained["fl_x"] / frame["fl_x"], trained["fl_y"] / frame["fl_y"])
    return max(1, math.ceil(coarser - 1e-9))  # (a whole ratio's float rounding: not one more)


def widened(
    model: GaussianModel, viewmat: np.ndarray, trained: dict, camera: Camera
) -> GaussianModel:
    """The model with each Gaussian's covariance grown by k·I (world units²), k the low-pass
    filter that `camera`'s pixels, finer than the training camera's (`trained`: fl_x, fl_y),
    miss at its depth z in world-to-camera `viewmat` [4, 4]: dilation · z² · (1/(fx₀·fy₀) −
    1/(fx·fy)), as wide in the image as training drew it (the model itself where they are no
    finer). Growing the covariance by a multiple of I keeps its axes: the scales s become
    sqrt(s² + k)."""
    finer = 1 / (trained["fl_x"] * trained["fl_y"]) - 1 / (camera.K[0, 0] * camera.K[1, 1])
    if finer <= 0:
        return model
    viewmat = np.asarray(viewmat, np.float64)
    depth = model.world_means() @ torch.from_numpy(viewmat[2, :3]) + viewmat[2, 3]  # [N]
    k = model.dilation * depth.square() * float(finer)  # [N], float64: 1/px² → world
    state = model.state_dict()
    log_scales = state["params"]["log_scales"]  # [N, 3]
    variances = (2 * log_scales.double()).exp()  # float64: no underflow
    state["params"]["log_scales"] = (0.5 * torch.log(variances + k[:, None])).to(log_scales.dtype)
    return GaussianModel.from_state_dict(state)


def render_scaled(
    model: GaussianModel, viewmat: np.ndarray, dataset, scale: float, trained: dict | None = None
) -> np.ndarray:
    """The model's image [h, w, C] (intensity units) from world-to-camera `viewmat` [4, 4] in the
    dataset's camera with its images `scale` times as large, drawn no finer than the training
    camera (`trained`: train.json's `camera`; default the dataset's) drew it: each Gaussian
    `widened` where the frame's pixels are finer, the mean of `supersampling`'s m×m pixels where
    they are coarser; `evaluate.render_view`'s image, bit for bit, in the training camera. An
    antialiased model (`train.antialiased`) is drawn as it is in finer pixels: its filter keeps
    each splat's mass, which widening would add to; so is one with the 3D smoothing filter
    (`train.filter_3d`), whose Gaussians are no finer than training sampled them."""
    from .evaluate import render_view

    if scale == 1 and trained is None:  # (the dataset's camera is the training camera)
        return render_view(model, viewmat, dataset)
    trained = camera_keys(dataset.meta) if trained is None else trained
    m = supersampling(dataset, scale, trained)
    camera = scaled_camera(dataset, scale, m)
    # an antialiased model's splats keep their mass at any size (widened, they gained some), a
    # 3D-filtered model's Gaussians are as wide as training's sampling (widened, they blurred)
    if not model.antialiased and model.filter_3d is None:
        model = widened(model, viewmat, trained, camera)
    return block_means(render_view(model, viewmat, camera), m)  # [m·h, m·w, C] → [h, w, C]
