"""Test-time pose alignment: a test view's pose optimised against its image with the scene frozen,
as pose-free NeRF and 3DGS papers score a scene trained from estimated poses. A dataset run
through `spikegs poses` trains in SfM's frame, which SfM's slowly drifting error warps a little;
each test view at its true pose sees that warp, and its PSNR understates the scene by 7-9 dB on
128² `solids` (BENCHMARKS.md, "Training from SfM poses — pose refinement")."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch

from .gaussians import GaussianModel, frame_origin, near_plane
from .losses import gaussian_blur
from .pose_refine import se3_exp

# Levenberg-Marquardt on a twist (radians, scene radii) applied on the camera side of the pose,
# minimising the squared error: a step renders the view at the pose and at six poses a twist of
# FD_STEP away along each axis (the residual's Jacobian by forward differences), solves the
# damped normal equations, and takes the step where it lowers the error (then damps less), else
# damps more and solves again. Against Adam's steps on the L1 error (until 2026-12-02): the same
# scores in a fifth of the time (16 views of 128² `fine-texture`, 29 s against 152 s) and as far a
# reach (BENCHMARKS.md, "eval --align-poses: Levenberg-Marquardt")
FD_STEP = 1e-3
DAMPING, DAMPING_MIN = 1e-3, 1e-7  # of the normal equations' diagonal
# the diagonal's least, of its largest (or of one: the image's units² per radian²)
NORMAL_FLOOR = 1e-12
MAX_TURN = np.radians(1.0)  # a step's longest turn (radians), and centre shift (as many radii)
# a phase has settled when the step that lowers the error (damped further while none does) would
# turn the camera less than this (degrees) and shift its centre less than as many radians of the
# scene's radius
SETTLED_DEG = 1e-3
MAX_STEPS = 200  # steps in all phases; views back from 5-20° off took at most 144 at 128²
# coarse to fine: fine, repeated structure (a checker, a grid of wires) gives the sharp images'
# error other optima a few degrees off the pose; the pose first settles against both images
# blurred by Gaussians these fractions of the image's larger side wide, widest first (16, 8 and
# 4 px at 256²), then against the sharp ones. Against the widest blur the camera only turns: free
# to shift, on 256² `wires` it slid 0.8 scene radii along the valley where a turn is traded for a
# shift, and settled 20-30° off
BLUR_WIDTHS = (1 / 16, 1 / 32, 1 / 64)


def blur_sigmas(width: int, height: int) -> list[float]:
    """The Gaussian widths (pixels) that a `width` x `height` view's alignment settles against,
    in turn, before its sharp images: [8.0, 4.0, 2.0] at 128², none under a pixel."""
    sigmas = [fraction * max(width, height) for fraction in BLUR_WIDTHS]
    return [sigma for sigma in sigmas if sigma >= 1]


@dataclass
class Alignment:
    viewmat: np.ndarray  # [4, 4] float64 world-to-camera, aligned
    steps: int  # Levenberg-Marquardt steps taken, over all phases
    settled: bool  # the pose settled against the sharp images within `max_steps`
    # the share of the image's coarse structure that the aligned render leaves unexplained:
    # |blur(render - image)|² / |blur(image - its mean)|² at the widest blur (none below 16 px);
    # nan for an image without any. A view settled off its pose often leaves several times what the
    # others do (BENCHMARKS.md, "eval --align-poses: Levenberg-Marquardt")
    unexplained: float


def aligned_pose(
    model: GaussianModel,
    viewmat: np.ndarray,
    image: np.ndarray,
    dataset,
    max_steps: int = MAX_STEPS,
) -> Alignment:
    """The world-to-camera viewmat [4, 4] (float64) near `viewmat` [4, 4] from which `model`
    renders `image` [H, W, C] (the render's units) best in the squared error: Levenberg-Marquardt
    steps on a twist applied on the camera side, against both images blurred (`blur_sigmas`) and
    then sharp, each until the pose settles (or `max_steps` in all), in the dataset's camera and
    the frame training renders in (`frame_origin`); `model` itself is left as it is. Stopped,
    unsettled, where the image or the render holds a NaN. ValueError for a `max_steps` below one."""
    if max_steps < 1:
        raise ValueError(f"max_steps: expected at least 1, got {max_steps}")
    model = model.centred_at(frame_origin(dataset.scene_center, dataset.scene_radius))
    start = model.view_of(viewmat).double()  # [4, 4], the model's frame
    K = torch.as_tensor(dataset.K, dtype=model.dtype)
    near = near_plane(dataset.scene_radius)
    radius = float(dataset.scene_radius)
    unit = torch.tensor([1.0, 1, 1, radius, radius, radius], dtype=torch.float64)
    target = torch.as_tensor(np.asarray(image, np.float32))

    def residual(pose: torch.Tensor, sigma: float) -> torch.Tensor:
        """The render at `pose` [4, 4] less the image, blurred by `sigma` px: [P], in the model's
        dtype (float32 as trained)."""
        with torch.no_grad():
            render = model.render(
                pose.to(model.dtype), K, dataset.width, dataset.height, near
            ).image
            return _blurred(render - target, sigma)

    def moved(twist: torch.Tensor, pose: torch.Tensor) -> torch.Tensor:
        return se3_exp(twist * unit) @ pose

    pose, steps, settled = start, 0, False
    sigmas = blur_sigmas(dataset.width, dataset.height)
    for sigma in [*sigmas, 0.0]:
        axes = 3 if sigmas and sigma == sigmas[0] else 6  # the widest blur: turns only
        error = residual(pose, sigma)
        cost, damping, settled = _squared_sum(error), DAMPING, False
        while not settled and steps < max_steps:
            steps += 1
            # [P, axes]: float32 differences, held in float64 for the sums over P (no copy)
            J = torch.empty(error.numel(), axes, dtype=torch.float64)
            for axis in range(axes):
                twist = torch.zeros(6, dtype=torch.float64)
                twist[axis] = FD_STEP
                J[:, axis] = (residual(moved(twist, pose), sigma) - error) / FD_STEP
            normal, gradient = J.T @ J, J.T @ error.double()  # [axes, axes], [axes]
            # floored: an axis along which the render does not change (nothing in view) takes
            # no step rather than make the equations singular
            floor = NORMAL_FLOOR * max(float(normal.diagonal().max()), 1.0)
            diagonal = normal.diagonal().clamp_min(floor)
            while True:  # damped until a step lowers the error, or is too short to matter
                damped = normal + damping * torch.diag(diagonal)
                twist = torch.zeros(6, dtype=torch.float64)
                twist[:axes] = -torch.linalg.solve(damped, gradient)
                longest = float(twist.view(2, 3).norm(dim=1).max())
                if not np.isfinite(longest):  # a NaN in the image or the render: unsettled
                    return _aligned(pose, start, viewmat, steps, False, math.nan)
                settled = bool(longest < np.radians(SETTLED_DEG))
                if settled:
                    break
                candidate = moved(twist * min(1.0, MAX_TURN / longest), pose)
                tried = residual(candidate, sigma)
                tried_cost = _squared_sum(tried)
                if tried_cost < cost:
                    pose, error, cost = candidate, tried, tried_cost
                    damping = max(damping / 3, DAMPING_MIN)
                    break
                damping *= 4
    widest = sigmas[0] if sigmas else 0.0
    # the mean summed in float64: a flat image's is its value, its structure none (float32's
    # left 1e-8 a pixel, 1e14 of it unexplained)
    structure = _squared_sum(_blurred(target - target.double().mean((0, 1)).float(), widest))
    left = _squared_sum(residual(pose, widest))
    unexplained = left / structure if structure > 0 else math.nan
    return _aligned(pose, start, viewmat, steps, settled, unexplained)


def _blurred(image: torch.Tensor, sigma: float) -> torch.Tensor:
    """`image` [H, W, C] blurred by a Gaussian `sigma` px wide (none at 0), flattened: [P]."""
    if sigma:
        image = gaussian_blur(image.permute(2, 0, 1)[None], sigma)
    return image.reshape(-1)


def _squared_sum(error: torch.Tensor) -> float:
    """The sum of `error`'s squares, summed in float64."""
    return float(error.double().square().sum())


def _aligned(pose, start, viewmat, steps: int, settled: bool, unexplained: float) -> Alignment:
    """The Alignment of `viewmat` [4, 4] (the world's frame) corrected as `start` [4, 4] (the
    model's frame) was to `pose` [4, 4]."""
    # on the camera side, the correction is the same in the world's frame: E @ view_of(V) is
    # view_of(E @ V)
    correction = (pose @ torch.linalg.inv(start)).numpy()  # [4, 4]
    return Alignment(correction @ np.asarray(viewmat, np.float64), steps, settled, unexplained)
