"""Pure-torch reference rasterizer: docs/rasterizer.md step by step, autograd for the backward.

Slow and simple: the test oracle for `spikegs.rasterize` and the benchmark's named alternative.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import torch

from .rasterize import RasterizeResult
from .sh import degree_of, sh_basis

# docs/rasterizer.md's constants, written here, not read from the core: the reference checks the
# core's values too (a test compares them with spikegs._C.constants)
ALPHA_MAX = 0.99  # alpha clamp
ALPHA_MIN = 1.0 / 255.0  # a pair below is skipped
T_MIN = 1e-4  # a pixel stops below this transmittance
DILATION = 0.3  # the default added to the 2D covariance's diagonal (pixels²)
MIN_DILATION, MAX_DILATION = 0.01, 10.0  # the range the op takes it in
CLAMP_MARGIN = 0.3  # the Jacobian's clamp, beyond the image, in tan(fov/2) units
NEAR, FAR = 0.01, 1e10  # the default clipping planes (world units)
MAX_MEAN2D = 2.0**40  # a 2D mean farther from the image origin in x or y (pixels) is culled


class _Splats(NamedTuple):
    """Per-Gaussian projection results (all N rows; only rows with `visible` are meaningful)."""

    visible: torch.Tensor  # [N] bool
    radii: torch.Tensor  # [N] int32, capped at 2^30 as the core's output
    reach: torch.Tensor  # [N] the radius uncapped (float): the compositing box
    means2d: torch.Tensor  # [N, 2]
    conics: torch.Tensor  # [N, 3] (A, B, C)
    depths: torch.Tensor  # [N]
    opacities: torch.Tensor  # [N]
    colors: torch.Tensor  # [N, C]


def quat_to_rotation(q: torch.Tensor) -> torch.Tensor:
    """Rotation matrices [N, 3, 3] of unit quaternions q [N, 4] (w, x, y, z)."""
    w, x, y, z = q.unbind(-1)
    rows = (
        (1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)),
        (2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)),
        (2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)),
    )
    return torch.stack([torch.stack(row, -1) for row in rows], -2)


def _rows(mask: torch.Tensor, like: torch.Tensor) -> torch.Tensor:
    """`mask` [N] shaped to broadcast over the trailing dimensions of `like` [N, ...]."""
    return mask.view(-1, *([1] * (like.dim() - 1)))


def _project(scene: tuple, sh_degree, near, far, antialiased: bool, dilation, keep) -> _Splats:
    """Steps 1-10 of the projection of `scene` (means, quats, scales, opacities, colors, viewmat,
    K, width, height, as `rasterize` takes them) for the Gaussians in `keep` [N] bool.

    Rows outside `keep`, and rows culled on the way, are computed from safe stand-in values chosen
    with torch.where, so that their (unused) results and their zero gradients stay finite.
    """
    means, quats, scales, opacities, colors, viewmat, K, width, height = scene
    safe_quat = quats.new_tensor([1.0, 0.0, 0.0, 0.0])
    safe_point = means.new_tensor([0.0, 0.0, 1.0])
    means = torch.where(_rows(keep, means), means, 0.0)  # [N, 3]
    quats = torch.where(_rows(keep, quats), quats, safe_quat)  # [N, 4]
    scales = torch.where(_rows(keep, scales), scales, 1.0)  # [N, 3]
    opacities = torch.where(keep, opacities, 1.0)  # [N]
    colors = torch.where(_rows(keep, colors), colors, 0.0)  # [N, C] or [N, K, C]

    # 2-3: rotation and camera-space mean; near/far cull
    W, t = viewmat[:3, :3], viewmat[:3, 3]  # [3, 3], [3]
    p = means @ W.T + t  # [N, 3]
    keep = keep & (p[:, 2] > near) & (p[:, 2] < far)
    p = torch.where(_rows(keep, p), p, safe_point)
    x, y, z = p.unbind(-1)  # [N] each
    R = quat_to_rotation(quats / quats.norm(dim=-1, keepdim=True))  # [N, 3, 3]
    WM = W @ (R * scales[:, None, :])  # [N, 3, 3] = W R diag(s)

    # 4-6: clamped Jacobian, 2D covariance with dilation, determinant, conic
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    tan_x, tan_y = 0.5 * width / fx, 0.5 * height / fy
    u = torch.clamp(
        x / z, -(cx / fx + CLAMP_MARGIN * tan_x), (width - cx) / fx + CLAMP_MARGIN * tan_x
    )
    v = torch.clamp(
        y / z, -(cy / fy + CLAMP_MARGIN * tan_y), (height - cy) / fy + CLAMP_MARGIN * tan_y
    )
    zeros = torch.zeros_like(z)
    J0 = torch.stack([fx / z, zeros, -fx * (z * u) / (z * z)], -1)  # [N, 3]
    J1 = torch.stack([zeros, fy / z, -fy * (z * v) / (z * z)], -1)  # [N, 3]
    V0 = torch.einsum("ni,nij->nj", J0, WM)  # [N, 3] rows of V = J W M
    V1 = torch.einsum("ni,nij->nj", J1, WM)
    n0, n1, b = (V0 * V0).sum(-1), (V1 * V1).sum(-1), (V0 * V1).sum(-1)  # [N]
    a, c = n0 + dilation, n1 + dilation
    cross = torch.linalg.cross(V0, V1)  # [N, 3]
    det = (cross * cross).sum(-1) + dilation * (n0 + n1) + dilation * dilation  # [N]
    keep = keep & torch.isfinite(det) & (det > 0)
    n_max = torch.maximum(n0, n1)  # the backward's terms reach 2 |V|^3: culled where that overflows
    keep = keep & torch.isfinite(2 * n_max * torch.sqrt(n_max))
    conics = torch.stack([c / det, -b / det, a / det], -1)  # [N, 3]
    if antialiased:  # times sqrt(det(V V^T) / det): 0 (culled below) for a flat splat
        undilated = (cross * cross).sum(-1)  # [N] det(V V^T)
        root = torch.sqrt(torch.where(undilated > 0, undilated, 1.0)) * (undilated > 0)
        opacities = opacities * root / torch.sqrt(torch.where(keep, det, 1.0))

    # 7-8: 2D mean, opacity-aware radius, box cull
    means2d = torch.stack([fx * x / z + cx, fy * y / z + cy], -1)  # [N, 2]
    with torch.no_grad():
        keep = keep & (opacities >= ALPHA_MIN)
        mid = 0.5 * (a + c)
        lam = mid + torch.sqrt(torch.clamp(mid * mid - det, min=0.1))
        level = 2 * torch.log(opacities / ALPHA_MIN)  # alpha >= 1/255 where d^T conic d <= level
        r = torch.ceil(torch.sqrt(level * lam))
        mx, my = means2d.unbind(-1)

        def reaches_image(half_x: torch.Tensor, half_y: torch.Tensor) -> torch.Tensor:
            """[N] whether the box mean ± half-widths overlaps the image."""
            return (
                (mx + half_x > 0)
                & (mx - half_x < width)
                & (my + half_y > 0)
                & (my - half_y < height)
            )

        # the circle's box, then the ellipse's own x and y half-widths (+1 px), the box the C++
        # binning tiles: it can miss the image where the circle does not
        ex, ey = torch.sqrt(level * a) + 1, torch.sqrt(level * c) + 1
        keep = keep & (mx.abs() < MAX_MEAN2D) & (my.abs() < MAX_MEAN2D)
        keep = keep & (r >= 1) & reaches_image(r, r) & reaches_image(ex, ey)
        radii = torch.where(keep, torch.clamp(r, max=2.0**30), 0).to(torch.int32)

    # 9: colour
    if sh_degree is None:
        rgb = colors  # [N, C]
    else:
        d = means + t @ W  # [N, 3] mean - campos, campos = -W^T t
        d = torch.where(_rows(keep, d), d, safe_point)
        length = d.norm(dim=-1, keepdim=True)  # [N, 1]; 0 at -W^T t (a non-rigid viewmat's)
        dirs = torch.where(length > 0, d / torch.where(length > 0, length, 1.0), 0.0)  # [N, 3]
        basis = sh_basis(dirs, sh_degree)  # [N, (d+1)^2]
        rgb = torch.einsum("nk,nkc->nc", basis, colors[:, : basis.shape[1]]) + 0.5
        rgb = torch.clamp(rgb, min=0.0)  # [N, C]
    return _Splats(keep, radii, torch.where(keep, r, 0), means2d, conics, z, opacities, rgb)


def _alpha_max(dtype: torch.dtype) -> torch.Tensor:
    """ALPHA_MAX in `dtype`, rounded down where its nearest value lies above (float32's
    0.99000001): two clamped Gaussians leave T = T_MIN, which does not stop a pixel (docs)."""
    nearest = torch.tensor(ALPHA_MAX, dtype=dtype)
    return (
        torch.nextafter(nearest, nearest.new_zeros(())) if nearest.item() > ALPHA_MAX else nearest
    )


def _composite(splats: _Splats, width: int, height: int, background: torch.Tensor) -> tuple:
    """Front-to-back alpha compositing over flat pixels, one visible Gaussian at a time."""
    channels = splats.colors.shape[-1]
    transmittance = splats.depths.new_ones(height * width)  # [P]
    done = torch.zeros(height * width, dtype=torch.bool, device=transmittance.device)  # [P]
    pixels, contributions = [], []  # per Gaussian: [Q] pixel indices, [Q, C] alpha T c
    visible = torch.nonzero(splats.visible).flatten()
    order = visible[torch.sort(splats.depths[visible], stable=True).indices]
    alpha_max = _alpha_max(transmittance.dtype)
    boxes = torch.cat([splats.means2d.detach(), splats.reach[:, None].to(splats.means2d)], -1)
    for i, (mx, my, r) in zip(order.tolist(), boxes[order].tolist()):
        # The opacity-aware box (plus a pixel): outside it alpha < 1/255 (docs step 8); its
        # integer ends clamped to the image before torch sees them (a far centre's can exceed
        # int64)
        x0, x1 = max(0, math.floor(mx - r)), min(width - 1, math.ceil(mx + r))
        y0, y1 = max(0, math.floor(my - r)), min(height - 1, math.ceil(my + r))
        if x1 < x0 or y1 < y0:
            continue
        xs, ys = torch.arange(x0, x1 + 1), torch.arange(y0, y1 + 1)
        idx = (ys[:, None] * width + xs[None, :]).flatten()  # [Q]
        dx = (xs.to(transmittance) + 0.5 - splats.means2d[i, 0])[None, :]  # [1, X]
        dy = (ys.to(transmittance) + 0.5 - splats.means2d[i, 1])[:, None]  # [Y, 1]
        A, B, C = splats.conics[i]
        power = (-0.5 * (A * dx * dx + C * dy * dy) - B * dx * dy).flatten()  # [Q]
        # > 0 only by rounding (the conic is positive definite): counts as 0, gradient as below 0
        power = power - power.detach().clamp(min=0)
        raw = splats.opacities[i] * torch.exp(power)  # [Q]
        # min(raw, alpha_max) with no gradient at a tie (torch.minimum splits it: 0.5 there)
        alpha = torch.where(raw < alpha_max, raw, alpha_max)
        live = (alpha >= ALPHA_MIN) & ~done[idx]
        t = transmittance[idx]
        t_next = t * (1 - alpha)
        stop = live & (t_next < T_MIN)
        use = live & ~stop
        pixels.append(idx)
        contributions.append(torch.where(use, alpha * t, 0.0)[:, None] * splats.colors[i])
        transmittance = transmittance.index_copy(0, idx, torch.where(use, t_next, t))
        done[idx] |= stop
    color = transmittance.new_zeros(height * width, channels)  # [P, C]
    if pixels:
        color = color.index_add(0, torch.cat(pixels), torch.cat(contributions))
    image = color + transmittance[:, None] * background  # [P, C]
    return image.view(height, width, channels), (1 - transmittance).view(height, width)


def rasterize(
    means: torch.Tensor,
    quats: torch.Tensor,
    scales: torch.Tensor,
    opacities: torch.Tensor,
    colors: torch.Tensor,
    viewmat: torch.Tensor,
    K: torch.Tensor,
    width: int,
    height: int,
    *,
    sh_degree: int | None = None,
    background: torch.Tensor | None = None,
    near: float = NEAR,
    far: float = FAR,
    screen_points: torch.Tensor | None = None,
    antialiased: bool = False,
    dilation: float = DILATION,
) -> RasterizeResult:
    """Render N Gaussians exactly as docs/rasterizer.md says; differentiable through autograd.

    means [N, 3], quats [N, 4] (w, x, y, z), scales [N, 3], opacities [N], colors [N, C] (direct)
    or [N, K, C] (SH coefficients), viewmat [4, 4] world-to-camera, K [3, 3], background [C].
    `screen_points` [N, 2] (zeros) is added to the 2D means the compositing uses, so that its
    gradient is the screen-space gradient of the 2D means, as in `spikegs.rasterize`.
    `dilation` (px²) is added to each 2D covariance Σ's diagonal; `antialiased` scales each
    opacity by sqrt(det Σ / det(Σ + dilation)) (step 6).
    Culled Gaussians get radius 0, mean2d 0, depth 0 and exactly zero gradient.
    """
    sh_degree = degree_of(colors, sh_degree)
    n = means.shape[0]
    finite = torch.stack(
        [
            t.isfinite().reshape(n, math.prod(t.shape[1:])).all(-1)
            for t in (means, quats, scales, opacities, colors)
        ]
    ).all(0)
    qq = (quats * quats).sum(-1)  # [N]; as the core: |q|^2 that overflows or is subnormal culls
    keep = finite & (qq >= torch.finfo(qq.dtype).tiny) & qq.isfinite()  # [N]
    scene = (means, quats, scales, opacities, colors, viewmat, K, width, height)
    args = (scene, sh_degree, near, far, antialiased, dilation)
    # Pass 1 finds the visible set; pass 2 recomputes with every culled row on safe values, so no
    # NaN or inf of a culled Gaussian can reach a gradient.
    with torch.no_grad():
        visible = _project(*args, keep).visible
    splats = _project(*args, visible)
    if screen_points is not None:
        splats = splats._replace(means2d=splats.means2d + screen_points)
    if background is None:
        background = means.new_zeros(colors.shape[-1])
    image, alpha = _composite(splats, width, height, background)
    means2d = torch.where(splats.visible[:, None], splats.means2d, 0.0)
    depths = torch.where(splats.visible, splats.depths, 0.0)
    return RasterizeResult(image, alpha, splats.radii, means2d, depths)
