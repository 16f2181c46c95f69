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
from .pose_refine import PoseRefiner

# Adam's step on the twist (radians, scene radii), held until the pose settles, then
# cosine-annealed to LR_END over ANNEAL_STEPS. A pose turned 10° off slides back along a shallow
# valley (a turn traded against a sideways shift): from 10° off a fixed 300 steps left 4 of 8
# views 2.0-2.4° off (up to 1.4 dB short) and lost 3; settling takes 350-1200 (BENCHMARKS.md,
# "eval --align-poses until the pose settles")
LR, LR_END = 2e-3, 5e-5
CHECK_EVERY = 50  # steps between looks at how far the pose moved
# settled: its mean over CHECK_EVERY steps moved less than this from the last's (degrees; its
# centre as many radians of the scene's radius)
SETTLED_DEG = 0.02
ANNEAL_STEPS = 100
MAX_STEPS = 2000  # a view's at most: one 20° off wanders without settling


@dataclass
class Alignment:
    viewmat: np.ndarray  # [4, 4] float64 world-to-camera, aligned
    steps: int  # Adam steps taken
    settled: bool  # the pose stopped moving before `max_steps`


def aligned_pose(
    model: GaussianModel,
    viewmat: np.ndarray,
    image: np.ndarray,
    dataset,
    max_steps: int = MAX_STEPS,
) -> Alignment:
    """The world-to-camera viewmat [4, 4] (float64) near `viewmat` [4, 4] from which `model`
    renders `image` [H, W, C] (the render's units) best: Adam steps on a twist applied on the
    camera side (L1, as training's loss) until the pose settles (or `max_steps`), in the dataset's
    camera and the frame training renders in (`frame_origin`); `model` itself is left as it is.
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

    def step():
        render = frozen.render(twist(base, 0), K, dataset.width, dataset.height, near)
        loss = (render.image - target).abs().mean()
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()

    # the twist's mean over each CHECK_EVERY steps against the last's: Adam's L1 steps jitter
    # about an optimum by ~LR, a drift along the valley moves the mean
    steps, settled, before = 0, False, torch.zeros(6)
    while not settled and steps + CHECK_EVERY + ANNEAL_STEPS <= max_steps:
        now = torch.zeros(6)
        for _ in range(CHECK_EVERY):
            step()
            now += twist.corrections.detach()[0] / CHECK_EVERY
        moved = (now - before).view(2, 3).norm(dim=1)  # [2]: turn (radians), centre (radii)
        settled = steps > 0 and bool(moved.max() < np.radians(SETTLED_DEG))
        steps, before = steps + CHECK_EVERY, now
    schedule = torch.optim.lr_scheduler.CosineAnnealingLR(optimizer, ANNEAL_STEPS, LR_END)
    for _ in range(ANNEAL_STEPS):
        step()
        schedule.step()
    # on the camera side, the correction is the same in the world's frame: E @ view_of(V) is
    # view_of(E @ V)
    with torch.no_grad():
        correction = twist(torch.eye(4), 0).double().numpy()  # [4, 4]
    return Alignment(correction @ np.asarray(viewmat, np.float64), steps + ANNEAL_STEPS, settled)
