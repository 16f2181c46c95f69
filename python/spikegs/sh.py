"""Real spherical harmonics of degrees 0-3, constants and signs as in the 3DGS reference code."""

from __future__ import annotations

import math

import torch

from .number_checks import is_int

MAX_DEGREE = 3
C0 = 0.28209479177387814
C1 = 0.4886025119029199
C2 = (
    1.0925484305920792,
    -1.0925484305920792,
    0.31539156525252005,
    -1.0925484305920792,
    0.5462742152960396,
)
C3 = (
    -0.5900435899266435,
    2.890611442640554,
    -0.4570457994644658,
    0.3731763325901154,
    -0.4570457994644658,
    1.445305721320277,
    -0.5900435899266435,
)


def num_coeffs(degree: int) -> int:
    """Number of SH coefficients up to `degree`: (degree + 1)²."""
    return (degree + 1) ** 2


def degree_of(colors: torch.Tensor, sh_degree: int | None) -> int | None:
    """The SH degree that renders `colors`: None for direct colours [N, C]; for coefficients
    [N, K, C], `sh_degree` or, where None, sqrt(K) - 1. ValueError naming what does not fit, and
    for [N, 1, 4 | 9 | 16] without `sh_degree`, which is degree 0 of that many channels or a
    mono scene's coefficients in the [N, C, K] layout."""
    if sh_degree is not None and not is_int(sh_degree):
        raise ValueError(f"sh_degree: expected an int, got {sh_degree!r}")
    if sh_degree is not None and not 0 <= sh_degree <= MAX_DEGREE:  # (said of the colours' shape)
        raise ValueError(f"sh_degree: expected 0..{MAX_DEGREE}, got {sh_degree}")
    if colors.dim() == 2:
        if sh_degree is not None:
            raise ValueError(
                f"colors: sh_degree={sh_degree} needs SH coefficients [N, K, C], "
                f"got {list(colors.shape)}"
            )
        return None
    if colors.dim() != 3:
        raise ValueError(f"colors: expected shape [N, C] or [N, K, C], got {list(colors.shape)}")
    k = colors.shape[1]
    if k < 1:
        raise ValueError(f"colors: expected at least 1 SH coefficient, got {list(colors.shape)}")
    if sh_degree is None:
        sh_degree = math.isqrt(k) - 1
        c = colors.shape[2]
        if k == 1 and c in (4, 9, 16):
            raise ValueError(
                f"colors: {list(colors.shape)} is SH degree 0 of {c} channels in the [N, K, C] "
                f"layout, or a mono scene's {c} coefficients in a [N, C, K] one: pass "
                f"sh_degree=0 for the first, colors.transpose(1, 2) for the second"
            )
        if num_coeffs(sh_degree) != k and c in (4, 9, 16) and k <= 4:
            raise ValueError(
                f"colors: expected SH coefficients [N, K, C], got {list(colors.shape)}, "
                f"{k} coefficients of {c} channels: a [N, C, K] layout? colors.transpose(1, 2)"
            )
        if num_coeffs(sh_degree) != k:
            raise ValueError(f"colors: {k} SH coefficients is not a square; pass sh_degree")
        if sh_degree > MAX_DEGREE:
            raise ValueError(
                f"colors: {k} SH coefficients are degree {sh_degree}, up to {MAX_DEGREE} "
                f"rendered: pass sh_degree={MAX_DEGREE} to use the first {num_coeffs(MAX_DEGREE)}"
            )
    if k < num_coeffs(sh_degree):
        raise ValueError(
            f"colors: sh_degree {sh_degree} needs {num_coeffs(sh_degree)} coefficients, got {k}"
        )
    return int(sh_degree)


def sh_basis(dirs: torch.Tensor, degree: int) -> torch.Tensor:
    """Basis values Y_k(dir) for unit directions `dirs` [N, 3]; returns [N, (degree + 1)²]."""
    if not 0 <= degree <= MAX_DEGREE:
        raise ValueError(f"sh degree must be in 0..{MAX_DEGREE}, got {degree}")
    x, y, z = dirs.unbind(-1)  # [N] each
    basis = [torch.full_like(x, C0)]
    if degree >= 1:
        basis += [-C1 * y, C1 * z, -C1 * x]
    if degree >= 2:
        xx, yy, zz = x * x, y * y, z * z
        basis += [
            C2[0] * x * y,
            C2[1] * y * z,
            C2[2] * (2 * zz - xx - yy),
            C2[3] * x * z,
            C2[4] * (xx - yy),
        ]
    if degree >= 3:
        basis += [
            C3[0] * y * (3 * xx - yy),
            C3[1] * x * y * z,
            C3[2] * y * (4 * zz - xx - yy),
            C3[3] * z * (2 * zz - 3 * xx - 3 * yy),
            C3[4] * x * (4 * zz - xx - yy),
            C3[5] * z * (xx - yy),
            C3[6] * x * (xx - 3 * yy),
        ]
    return torch.stack(basis, dim=-1)  # [N, (degree + 1)²]
