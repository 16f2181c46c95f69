"""Test-time pose alignment: a test view's pose optimised against its image with the scene frozen,
as pose-free NeRF and 3DGS papers score a scene trained from estimated poses. A dataset run
through `spikegs poses` trains in SfM's frame, which SfM's slowly drifting error warps a little;
each test view at its true pose sees that warp, and its PSNR understates the scene by 7-9 dB on
128² `solids` (BENCHMARKS.md, "Training from SfM poses — pose refinement")."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from .gaussians import GaussianModel, frame_origin, near_plane
from .losses import gaussian_blur
from .pose_refine import PoseRefiner

# Adam's step on the twist (radians, scene radii), held until the pose settles, then
# cosine-annealed to LR_END over ANNEAL_STEPS. A pose turned 10° off slides back along a shallow
# valley (a turn traded against a sideways shift): from 10° off a fixed 300 steps left 4 of 8
# views 2.0-2.4° off (up to 1.4 dB short) and lost 3; settling took 350-1200 (BENCHMARKS.md,
# "eval --align-poses until the pose settles"), 500-1850 with the blurred start below
LR, LR_END = 2e-3, 5e-5
CHECK_EVERY = 50  # steps between looks at how far the pose moved
# settled: its mean over CHECK_EVERY steps moved less than this from the last's (degrees; its
# centre as many radians of the scene's radius)
SETTLED_DEG = 0.02
ANNEAL_STEPS = 100
# a view's at most: one 20° off wanders without settling; with the blurred start below, views
# 10° off a 256² `wires` settled back at 2350-2600 steps, and lost ones at 128² still wandered
# at 3000
MAX_STEPS = 3000
# coarse to fine: fine, repeated structure (a checker, a grid of wires) gives the sharp images'
# L1 other optima a few degrees off the pose (L2 settles in the same ones); the pose first
# settles against both images blurred by a Gaussian this fraction of the image's larger side
# wide (4 px at 128²), then against the sharp ones. On 128² `fine-texture` and `wires`, 10° off:
# 7 of 8 views back against 4 and 3, in 1.7x the steps (BENCHMARKS.md, "eval --align-poses:
# blurred first")
BLUR_WIDTH = 1 / 32


def blur_sigmas(width: int, height: int) -> list[float]:
    """The Gaussian widths (pixels) that a `width` x `height` view's alignment settles against,
    in turn, before its sharp images: [4.0] at 128², none under a pixel (below 32²)."""
    sigma = BLUR_WIDTH * max(width, height)
    return [sigma] if sigma >= 1 else []


@dataclass
class Alignment:
    viewmat: np.ndarray  # [4, 4] float64 world-to-camera, aligned
    steps: int  # Adam steps taken
    settled: bool  # the pose stopped moving against the sharp images before `max_steps`


def aligned_pose(
    model: GaussianModel,
    viewmat: np.ndarray,
    image: np.ndarray,
    dataset,
    max_steps: int = MAX_STEPS,
) -> Alignment:
    """The world-to-camera viewmat [4, 4] (float64) near `viewmat` [4, 4] from which `model`
    renders `image` [H, W, C] (the render's units) best: Adam steps on a twist applied on the
    camera side (L1, as training's loss), against both images blurred (`blur_sigmas`) and then
    sharp, each until the pose settles (or `max_steps` in all), in the dataset's camera and the
    frame training renders in (`frame_origin`); `model` itself is left as it is.
    ValueError for a `max_steps` below one look at the pose and the annealing."""
    if max_steps < CHECK_EVERY + ANNEAL_STEPS:  # else it took ANNEAL_STEPS, unlooked at
        raise ValueError(
            f"max_steps: expected at least {CHECK_EVERY + ANNEAL_STEPS} ({CHECK_EVERY} steps "
            f"before the pose is looked at, {ANNEAL_STEPS} annealed), got {max_steps}"
        )
    origin = frame_origin(dataset.scene_center, dataset.scene_radius)
    frozen = GaussianModel.from_state_dict(model.centred_at(origin).state_dict())
    for p in frozen.params.values():
        p.requires_grad_(False)
    base = frozen.view_of(viewmat)  # [4, 4] float32, the model's frame
    K = torch.as_tensor(dataset.K, dtype=torch.float32)
    near = near_plane(dataset.scene_radius)
    twist = PoseRefiner(1, float(dataset.scene_radius))  # (radians, scene radii), as training's
    target = torch.as_tensor(np.asarray(image, np.float32))
    optimizer = torch.optim.Adam(twist.parameters(), lr=LR)

    def step(sigma: float):
        render = frozen.render(twist(base, 0), K, dataset.width, dataset.height, near)
        error = render.image - target  # [H, W, C]
        if sigma:
            error = gaussian_blur(error.permute(2, 0, 1)[None], sigma)
        loss = error.abs().mean()
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()

    # the twist's mean over each CHECK_EVERY steps against the last's: Adam's L1 steps jitter
    # about an optimum by ~LR, a drift along the valley moves the mean
    steps, settled = 0, False
    for sigma in [*blur_sigmas(dataset.width, dataset.height), 0.0]:
        settled, before = False, None  # (a first look compares with nothing: no settling)
        while not settled and steps + CHECK_EVERY + ANNEAL_STEPS <= max_steps:
            now = torch.zeros(6)
            for _ in range(CHECK_EVERY):
                step(sigma)
                now += twist.corrections.detach()[0] / CHECK_EVERY
            if before is not None:
                moved = (now - before).view(2, 3).norm(dim=1)  # [2]: turn (rad), centre (radii)
                settled = bool(moved.max() < np.radians(SETTLED_DEG))
            steps, before = steps + CHECK_EVERY, now
    schedule = torch.optim.lr_scheduler.CosineAnnealingLR(optimizer, ANNEAL_STEPS, LR_END)
    for _ in range(ANNEAL_STEPS):
        step(0.0)
        schedule.step()
    # on the camera side, the correction is the same in the world's frame: E @ view_of(V) is
    # view_of(E @ V)
    with torch.no_grad():
        correction = twist(torch.eye(4), 0).double().numpy()  # [4, 4]
    return Alignment(correction @ np.asarray(viewmat, np.float64), steps + ANNEAL_STEPS, settled)
