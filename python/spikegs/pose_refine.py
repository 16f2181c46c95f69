"""Pose refinement: per-view se(3) corrections of the camera poses, learnt through the rasterizer.

A correction is a twist xi = (omega, v) [6]: omega an axis-angle rotation (radians), v a translation
in units of the scene radius (so that one learning rate suits both). It acts on the camera side of
a world-to-camera viewmat, `viewmat' = exp(xi) @ viewmat`, starts at zero (the identity) and is
shared by every render of one training view (the instant pose at t and the K exposure poses).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from scipy.spatial.transform import Rotation

from .float32 import F32

# theta² below which the series expansions (to theta⁴: truncation < 3e-16) are used; above it the
# closed forms lose at most ~1e-11 to cancellation in float64
_SMALL = 1e-4


@dataclass
class PoseRefineConfig:
    enabled: bool = False  # off: the trajectory's poses are used as they are
    # Adam step (radians, scene radii); measured: 1e-4 to 3e-4 do equally well, 1e-3 makes the
    # poses worse (docs/datasets.md)
    lr: float = 3e-4


def hat(omega: torch.Tensor) -> torch.Tensor:
    """Skew-symmetric matrices [..., 3, 3] of vectors [..., 3]: hat(a) @ b = a × b."""
    x, y, z = omega.unbind(-1)
    zero = torch.zeros_like(x)
    rows = (zero, -z, y, z, zero, -x, -y, x, zero)
    return torch.stack(rows, dim=-1).reshape(*omega.shape[:-1], 3, 3)


def se3_exp(xi: torch.Tensor) -> torch.Tensor:
    """The exponential of twists xi [..., 6] (omega, v) as rigid transforms [..., 4, 4].

    R = I + a W + b W², t = (I + b W + c W²) v with W = hat(omega), theta = |omega| and
    a = sin θ / θ, b = (1 - cos θ) / θ², c = (θ - sin θ) / θ³; Taylor series near θ = 0 keep the
    value and the gradient finite at zero. Computed in float64 whatever xi's dtype: in float32
    1 - cos θ and θ - sin θ cancel to 0 for θ ~ 1e-4, where refinement starts.
    """
    dtype, xi = xi.dtype, xi.double()
    omega, v = xi[..., :3], xi[..., 3:]
    theta2 = (omega * omega).sum(-1, keepdim=True).unsqueeze(-1)  # [..., 1, 1]
    small = theta2 < _SMALL
    theta2_safe = torch.where(small, torch.ones_like(theta2), theta2)
    theta = theta2_safe.sqrt()
    t4 = theta2 * theta2
    a = torch.where(small, 1 - theta2 / 6 + t4 / 120, torch.sin(theta) / theta)
    b = torch.where(small, 0.5 - theta2 / 24 + t4 / 720, (1 - torch.cos(theta)) / theta2_safe)
    c = torch.where(
        small, 1 / 6 - theta2 / 120 + t4 / 5040, (theta - torch.sin(theta)) / (theta2_safe * theta)
    )
    W = hat(omega)
    WW = W @ W
    eye = torch.eye(3, dtype=xi.dtype).expand_as(W)
    rotation = eye + a * W + b * WW
    translation = ((eye + b * W + c * WW) @ v.unsqueeze(-1)).squeeze(-1)  # [..., 3]
    top = torch.cat([rotation, translation.unsqueeze(-1)], dim=-1)  # [..., 3, 4]
    bottom = torch.zeros(*top.shape[:-2], 1, 4, dtype=xi.dtype)
    bottom[..., 0, 3] = 1
    return torch.cat([top, bottom], dim=-2).to(dtype)


class PoseRefiner(torch.nn.Module):
    """Corrections [M, 6] of M training views, zero at start; `refiner(viewmat, view)` applies
    view `view`'s."""

    def __init__(self, num_views: int, scene_radius: float):
        super().__init__()
        # (float32, whatever torch's default dtype a caller set: float64 failed in se3_exp)
        self.corrections = torch.nn.Parameter(torch.zeros(num_views, 6, **F32))  # [M, 6]
        self.register_buffer(
            "unit", torch.tensor([1.0, 1, 1, scene_radius, scene_radius, scene_radius], **F32)
        )

    def forward(self, viewmat: torch.Tensor, view: int) -> torch.Tensor:
        """The corrected world-to-camera viewmat [4, 4] of training view `view`."""
        return se3_exp(self.corrections[view] * self.unit) @ viewmat


def make_refiner(config: PoseRefineConfig, num_views: int, scene_radius: float):
    """A PoseRefiner for `num_views` training views when `config.enabled`, else None."""
    return PoseRefiner(num_views, scene_radius) if config.enabled else None


def pose_errors(viewmats: np.ndarray, reference: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotation error (degrees) [P] and camera-centre distance [P] of world-to-camera `viewmats`
    [P, 4, 4] against `reference` [P, 4, 4]."""
    viewmats, reference = np.asarray(viewmats, np.float64), np.asarray(reference, np.float64)
    relative = viewmats[:, :3, :3] @ reference[:, :3, :3].transpose(0, 2, 1)  # [P, 3, 3]
    centres = np.linalg.inv(viewmats)[:, :3, 3] - np.linalg.inv(reference)[:, :3, 3]  # [P, 3]
    angles = Rotation.from_matrix(relative).magnitude()  # [P]
    return np.degrees(angles), np.linalg.norm(centres, axis=1)
