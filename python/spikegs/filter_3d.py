"""Mip-Splatting's 3D smoothing filter: no Gaussian finer than the training views sample it.

A point at depth z in a view of focal length f (pixels) is sampled there every z/f world units;
the finest sampling among the training views that see a Gaussian bounds the detail they can
teach it. Mip-Splatting (Yu et al., CVPR 2024) convolves each Gaussian with an isotropic 3D
Gaussian of variance `variance`·(z/f)² at that finest sampling (0.2 px² in the paper): its scales
become sqrt(s² + w²) and its opacity is multiplied by sqrt(det S² / det(S² + w²)), which keeps
its integral, so that a render at a finer sampling than training's (nearer, or larger) shows no
detail finer than the views taught. The widths w are not learnt: a trainer recomputes them as the
Gaussians move and densify (`train.filter_3d`).
"""

from __future__ import annotations

import math

import torch

from .float32 import F32

# Mip-Splatting's: a view counts a Gaussian whose centre projects up to 15 % of the image's side
# outside it (its footprint reaches in)
MARGIN = 0.15
VIEWS_AT_ONCE = 64  # views projected together: [N, 64, 3] temporaries


def filter_widths(
    means: torch.Tensor,
    viewmats: torch.Tensor,
    K: torch.Tensor,
    width: int,
    height: int,
    near: float,
    variance: float,
) -> torch.Tensor:
    """The filter's standard deviation [N] (world units, the means' dtype) of Gaussians at
    `means` [N, 3], seen from `viewmats` [M, 4, 4] (world-to-camera, of the means' frame) with
    intrinsics `K` [3, 3] in width × height images: sqrt(variance) · z / max(fx, fy) at the
    nearest depth z of the views whose image (MARGIN wider) holds the centre in front of the near
    plane; a Gaussian that no view holds takes the widest of those that one does (Mip-
    Splatting's choice), and every one 0 where none does."""
    if not (math.isfinite(variance) and variance >= 0):
        raise ValueError(f"filter_widths: variance expected >= 0 px², not {variance!r}")
    if len(viewmats) == 0:
        return torch.zeros(len(means), dtype=means.dtype)
    K = torch.as_tensor(K, dtype=torch.float32)
    pixel = 1 / float(max(K[0, 0], K[1, 1]))  # world units a pixel at depth 1, finest axis
    # homogeneous points [N, 4] and each view's projection K·[R | t] [M, 3, 4]: one product gives
    # (u·z, v·z, z), compared with the image's bounds times z (z > near > 0: no division)
    points = torch.cat([means.detach().float(), torch.ones(len(means), 1, **F32)], dim=1)
    projections = K @ torch.as_tensor(viewmats, dtype=torch.float32)[:, :3]
    finest = torch.full((len(means),), math.inf, **F32)  # [N]: z of the nearest view that holds it
    for part in projections.split(VIEWS_AT_ONCE):
        uvz = (points @ part.reshape(-1, 4).T).reshape(len(means), len(part), 3)  # [N, B, 3]
        z = uvz[..., 2]
        inside = (z > near) & (uvz[..., 0] >= -MARGIN * width * z)
        inside &= uvz[..., 0] <= (1 + MARGIN) * width * z
        inside &= (uvz[..., 1] >= -MARGIN * height * z) & (uvz[..., 1] <= (1 + MARGIN) * height * z)
        finest = torch.minimum(finest, torch.where(inside, z, math.inf).amin(dim=1))
    seen = torch.isfinite(finest)
    widest = finest[seen].max() if seen.any() else torch.zeros((), **F32)
    finest = torch.where(seen, finest, widest)
    return (math.sqrt(variance) * pixel * finest).to(means.dtype)


def smoothed(
    scales: torch.Tensor, opacities: torch.Tensor, widths: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor]:
    """Scales [N, 3] and opacities [N] convolved with isotropic Gaussians of standard deviation
    `widths` [N]: sqrt(s² + w²) and o · Π s / sqrt(s² + w²), the product of the axes' ratios
    (each in [0, 1]: det S² itself underflows float32 for scales under 3e-8); differentiable
    in the scales and opacities. By hypot, which neither overflows nor underflows (s² did from
    1e19 in float32); a scale of 0 is taken as the dtype's least normal number, so that a width
    of 0 beside it keeps the Gaussian as it is, not 0/0."""
    scales = scales.clamp_min(torch.finfo(scales.dtype).tiny)
    wide = torch.hypot(scales, widths[:, None])  # [N, 3]
    return wide, opacities * (scales / wide).prod(dim=1)
