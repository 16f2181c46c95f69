"""Test-time pose alignment: a test view's pose optimised against its image with the scene frozen,
as pose-free NeRF and 3DGS papers score a scene trained from estimated poses. A dataset run
through `spikegs poses` trains in SfM's frame, which SfM's slowly drifting error warps a little;
each test view at its true pose sees that warp, and its PSNR understates the scene by 7-9 dB on
128² `solids` (BENCHMARKS.md, "Training from SfM poses — pose refinement")."""

from __future__ import annotations

import numpy as np
import torch

from .gaussians import GaussianModel, frame_origin, near_plane
from .pose_refine import PoseRefiner

STEPS = 300  # Adam steps a view
# Adam's step on the twist (radians, scene radii), cosine-annealed to LR_END over the steps:
# from SfM's poses (2.3° off) 300 steps scored 29.21 dB where the true poses score 29.28
LR, LR_END = 2e-3, 5e-5


def aligned_pose(
    model: GaussianModel, viewmat: np.ndarray, image: np.ndarray, dataset, steps: int = STEPS
) -> np.ndarray:
    """The world-to-camera viewmat [4, 4] (float64) near `viewmat` [4, 4] from which `model`
    renders `image` [H, W, C] (the render's units) best: `steps` Adam steps on a twist applied on
    the camera side (L1, as training's loss), in the dataset's camera and the frame training
    renders in (`frame_origin`); `model` itself is left as it is."""
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
    schedule = torch.optim.lr_scheduler.CosineAnnealingLR(optimizer, steps, eta_min=LR_END)
    for _ in range(steps):
        render = frozen.render(twist(base, 0), K, dataset.width, dataset.height, near)
        loss = (render.image - target).abs().mean()
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
        schedule.step()
    # on the camera side, the correction is the same in the world's frame: E @ view_of(V) is
    # view_of(E @ V)
    with torch.no_grad():
        correction = twist(torch.eye(4), 0).double().numpy()  # [4, 4]
    return correction @ np.asarray(viewmat, np.float64)
