"""`spikegs bench stiff`: the rasterizer's stiff and extreme cases through `spikegs.rasterize`.

The cases of cpp_tests/test_raster_stiff.cpp, rendered in float32 and float64 with a backward pass
of a fixed random upstream gradient: per case, the float64 core against the float64 pure-torch
reference (`spikegs.reference`: an error common to both of the core's precisions shows there),
the largest |float32 − float64| of the image and alpha, the relative error of each float32
gradient (max |g32 − g64| / max(max |g64|, 1)),
whether any output or gradient is non-finite in either precision, and whether the Gaussians that
must be culled (or are transparent or clamped) get exactly zero gradient.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import torch

from .. import reference
from ..rasterize import rasterize
from ..text_table import print_table
from .common import uniform, write_results

PER_GAUSSIAN = ("means", "quats", "scales", "opacities", "colors", "means2d")
GRADS = (*PER_GAUSSIAN, "background", "viewmat")
FLOAT_ERROR_BOUND = 1e-3  # |float32 - float64| of image and alpha the C++ tests assert
GRAD_ERROR_BOUND = 1e-2  # rel_X of every gradient (the needles' 1.6e-4 the worst, 2026-11-30)
REFERENCE_ERROR_BOUND = 1e-6  # float64 core against the float64 pure-torch reference (ref_err)
TINY = 1e-300  # ref_err's floor where every gradient is zero (the empty scene)
NAN, INF = float("nan"), float("inf")


@dataclass
class Case:
    name: str
    scene: dict  # float64 tensors (means, quats, scales, opacities, colors, background, viewmat, K)
    width: int
    height: int
    zero_grad: dict[str, list[int]] = field(default_factory=dict)  # gradient -> Gaussians


def random_scene(seed: int, n: int, width: int, height: int, channels: int = 3) -> dict:
    """N Gaussians 2-4 units ahead of a slightly rotated camera, inside its view, footprints of a
    few pixels, opacities in [0.1, 0.7], direct colours, a background (as cpp_tests)."""
    gen = torch.Generator().manual_seed(seed)

    f = 1.2 * max(width, height)
    K = torch.tensor(
        [[f * uniform(gen, 0.9, 1.1, 1).item(), 0, width * uniform(gen, 0.4, 0.6, 1).item()],
         [0, f * uniform(gen, 0.9, 1.1, 1).item(), height * uniform(gen, 0.4, 0.6, 1).item()],
         [0, 0, 1]],
        dtype=torch.float64,
    )  # fmt: skip
    w = 0.1 * torch.randn(3, generator=gen, dtype=torch.float64)  # small axis-angle
    skew = torch.zeros(3, 3, dtype=torch.float64)
    skew[0, 1], skew[0, 2], skew[1, 2] = -w[2], w[1], -w[0]
    viewmat = torch.eye(4, dtype=torch.float64)
    viewmat[:3, :3] = torch.linalg.matrix_exp(skew - skew.T)
    viewmat[:3, 3] = 0.1 * torch.randn(3, generator=gen, dtype=torch.float64)
    z = uniform(gen, 2, 4, n)
    cam = torch.stack([uniform(gen, -0.5, 0.5, n) * width, uniform(gen, -0.5, 0.5, n) * height], -1)
    cam = torch.cat([cam * z[:, None] / f, z[:, None]], -1)  # [N, 3] camera space
    return {
        "means": (cam - viewmat[:3, 3]) @ viewmat[:3, :3],  # [N, 3] = R^T (p - t)
        "quats": torch.randn(n, 4, generator=gen, dtype=torch.float64),
        "scales": (z / f * uniform(gen, 1, 4, n))[:, None] * uniform(gen, 0.5, 1.5, n, 3),
        "opacities": uniform(gen, 0.1, 0.7, n),
        "colors": uniform(gen, 0, 1, n, channels),
        "background": uniform(gen, 0, 1, channels),
        "viewmat": viewmat,
        "K": K,
    }


def _all(indices: list[int]) -> dict[str, list[int]]:
    """Every per-Gaussian gradient of `indices` must be zero."""
    return {name: indices for name in PER_GAUSSIAN}


def _scales() -> Case:
    s = random_scene(1, 40, 64, 48)
    s["scales"] = 10 ** (-6 + 9 * (torch.arange(120, dtype=torch.float64) % 10) / 9).reshape(40, 3)
    return Case("scales 1e-6..1e3", s, 64, 48)


def _condition() -> Case:
    s = random_scene(2, 30, 64, 48)
    s["scales"][:, 0], s["scales"][:, 1:] = 0.5, 0.5e-4
    return Case("covariance condition 1e8", s, 64, 48)


def _near_plane() -> Case:
    s = random_scene(3, 10, 33, 17)
    s["viewmat"] = torch.eye(4, dtype=torch.float64)
    z = torch.tensor([-2.0, -0.5, -0.01, 0.0, 0.005, 0.01, 0.0100001, 0.05, 0.5, 2.0])
    i = torch.arange(10, dtype=torch.float64)
    s["means"] = torch.stack([0.01 * (i - 5), 0.005 * i, z], -1)
    s["scales"] = torch.full((10, 3), 0.3, dtype=torch.float64)  # straddles z = near
    behind = [k for k in range(10) if z[k] <= 0.01]
    return Case("near plane and behind camera", s, 33, 17, _all(behind))


def _needles() -> Case:
    """Splats 0.2 px wide and 1e2..1e4 px long at random turns (float32 gradients through the
    conic's inverse lost accuracy with the square of the length)."""
    s = random_scene(12, 5, 64, 48, channels=1)
    z, f = s["means"] @ s["viewmat"][2, :3] + s["viewmat"][2, 3], s["K"][0, 0]  # [N] depth
    length = torch.logspace(2, 4, 5, dtype=torch.float64)  # pixels
    s["scales"] = torch.stack([0.2 * torch.ones(5), length, 0.3 * torch.ones(5)], -1)
    s["scales"] *= (z / f)[:, None]
    return Case("needles 0.2 x 1e2..1e4 px", s, 64, 48)


def _huge_extent() -> Case:
    """Splats ~1e9 px tall: their rows overflowed a 32-bit int and they drew nothing."""
    s = random_scene(13, 4, 33, 17)
    s["scales"][:, 1] = 1e8
    return Case("1e9 px tall", s, 33, 17)


def _opacity_logits() -> Case:
    s = random_scene(4, 20, 33, 17, channels=1)
    s["opacities"] = torch.sigmoid(torch.tensor([30.0, -30.0] * 10, dtype=torch.float64))
    return Case("opacity logits +-30", s, 33, 17, _all(list(range(1, 20, 2))))


def _stacked() -> Case:
    s = random_scene(5, 400, 13, 9)
    s["viewmat"] = torch.eye(4, dtype=torch.float64)
    s["means"] = torch.zeros(400, 3, dtype=torch.float64)
    s["means"][:, 2] = 2 + 1e-3 * torch.arange(400, dtype=torch.float64)
    s["scales"] = torch.full((400, 3), 0.05, dtype=torch.float64)
    s["opacities"] = torch.full((400,), 0.9, dtype=torch.float64)
    return Case("400 stacked on one pixel", s, 13, 9)


def _sub_and_screen() -> Case:
    s = random_scene(6, 6, 33, 17)
    s["scales"][:4] = torch.tensor([1e-5, 1e-7, 1e3, 50.0], dtype=torch.float64)[:, None]
    return Case("sub-pixel and screen-covering", s, 33, 17)


def _quaternions() -> Case:
    s = random_scene(7, 12, 33, 17)
    s["quats"][10] = 0.0
    s["quats"][11] = torch.tensor([0.5, 0.5, NAN, 0.5])
    return Case("zero and NaN quaternions", s, 33, 17, _all([10, 11]))


def _non_finite() -> Case:
    s = random_scene(8, 14, 33, 17)
    s["means"][10, 1], s["scales"][11, 2], s["opacities"][12], s["colors"][13, 0] = (
        NAN,
        INF,
        NAN,
        -INF,
    )
    return Case("non-finite parameters", s, 33, 17, _all([10, 11, 12, 13]))


def _empty() -> Case:
    return Case("empty scene", random_scene(9, 0, 33, 17), 33, 17)


def _thin(width: int, height: int) -> Callable[[], Case]:
    def case() -> Case:
        scene = random_scene(10, 25, width, height, channels=1)
        return Case(f"{width}x{height} image", scene, width, height)

    return case


def _clamped_alpha() -> Case:
    s = random_scene(11, 1, 13, 9, channels=1)
    s["scales"][:] = 1e3  # G ~ 1 on every pixel, so alpha = min(0.99, G) is clamped everywhere
    s["opacities"][:] = 1.0
    return Case("clamped alpha", s, 13, 9, {"opacities": [0], "means": [0], "scales": [0]})


CASES = (
    _scales,
    _condition,
    _needles,
    _huge_extent,
    _near_plane,
    _opacity_logits,
    _stacked,
    _sub_and_screen,
    _quaternions,
    _non_finite,
    _empty,
    *(_thin(w, h) for w, h in ((1, 1), (1, 37), (37, 1), (17, 16))),
    _clamped_alpha,
)


def forward_backward(case: Case, dtype: torch.dtype, op=None) -> tuple[dict, dict]:
    """Outputs (image, alpha, radii) and the gradients GRADS of (image, alpha) · (fixed random
    upstream gradient), in `dtype`, through `op` (the pure-torch reference; None: the core)."""
    leaves = {k: v.to(dtype).requires_grad_(k != "K") for k, v in case.scene.items()}
    screen = torch.zeros(len(leaves["means"]), 2, dtype=dtype, requires_grad=True)
    out = (op or rasterize)(
        *(leaves[k] for k in ("means", "quats", "scales", "opacities", "colors", "viewmat", "K")),
        case.width,
        case.height,
        background=leaves["background"],
        screen_points=screen,
    )
    gen = torch.Generator().manual_seed(7)
    g_image = torch.randn(out.image.shape, generator=gen, dtype=torch.float64).to(dtype)
    g_alpha = torch.randn(out.alpha.shape, generator=gen, dtype=torch.float64).to(dtype)
    loss = (out.image * g_image).sum() + (out.alpha * g_alpha).sum()
    inputs = {**{k: v for k, v in leaves.items() if k != "K"}, "means2d": screen}
    grads = torch.autograd.grad(loss, list(inputs.values()), allow_unused=True)
    grads = {k: torch.zeros_like(v) if g is None else g for (k, v), g in zip(inputs.items(), grads)}
    return {"image": out.image, "alpha": out.alpha, "radii": out.radii}, grads


def _max_abs(t: torch.Tensor) -> float:
    return t.abs().max().item() if t.numel() else 0.0


def _worst(errors: list[float]) -> float:
    """The largest of `errors`, NaN where one is (Python's max kept a NaN first alone: a NaN in
    the reference's alpha or gradients passed every check)."""
    return float("nan") if any(math.isnan(e) for e in errors) else max(errors)


def _relative_error(g32: torch.Tensor, g64: torch.Tensor) -> float:
    """max |g32 - g64| / max(max |g64|, 1): relative, absolute where the gradient is below 1 (one
    that vanishes analytically, as the quaternion gradient of an isotropic Gaussian, holds only
    rounding noise); the normalisation of tests/test_rasterize.py."""
    return _max_abs(g32.double() - g64) / max(_max_abs(g64), 1.0)


def measure(case: Case) -> dict:
    """One row of the table for `case`."""
    results = {dtype: forward_backward(case, dtype) for dtype in (torch.float32, torch.float64)}
    (out32, g32), (out64, g64) = results[torch.float32], results[torch.float64]
    out_ref, g_ref = forward_backward(case, torch.float64, reference.rasterize)
    # each gradient's error relative to its size, or to 1e-9 of the largest where it is smaller:
    # one that vanishes analytically (an isotropic Gaussian's quaternion) holds rounding alone
    floor = 1e-9 * max([_max_abs(g) for g in g_ref.values()] + [TINY])
    non_finite = [
        f"{str(dtype)[6:]} {kind}{name}"
        for dtype, (out, grads) in results.items()
        for kind, tensors in (("", out), ("grad ", grads))
        for name, t in tensors.items()
        if t.is_floating_point() and not torch.isfinite(t).all()
    ]
    zero_ok = all(
        torch.all(grads[name][indices] == 0).item()
        for _, grads in results.values()
        for name, indices in case.zero_grad.items()
    )
    row = {
        "case": case.name,
        "N": len(case.scene["means"]),
        "size": f"{case.width}x{case.height}",
        "visible": int((out64["radii"] > 0).sum()),
        "image_err": _worst([_max_abs(out32[k].double() - out64[k]) for k in ("image", "alpha")]),
        "ref_err": _worst(
            [_max_abs(out64[k] - out_ref[k]) for k in ("image", "alpha")]
            + [_max_abs(g64[k] - g_ref[k]) / max(_max_abs(g_ref[k]), floor) for k in GRADS]
        ),
        "ref_culls": "same" if torch.equal(out64["radii"] > 0, out_ref["radii"] > 0) else "NO",
    }
    row.update({f"rel_{name}": _relative_error(g32[name], g64[name]) for name in GRADS})
    row["non_finite"] = ", ".join(non_finite) or "none"
    row["zero_grad"] = ("yes" if zero_ok else "NO") if case.zero_grad else "-"
    return row


def failed_checks(row: dict) -> list[str]:
    """What a row of `measure` fails: float32 beyond the bounds of float64, a non-finite output
    or gradient, a culled, transparent or clamped Gaussian with a gradient. An error of NaN (a
    NaN in the reference's outputs, which `non_finite` does not look at) fails its bound."""
    problems = []
    if not row["ref_err"] <= REFERENCE_ERROR_BOUND:
        problems.append(f"ref_err {row['ref_err']:.3g} > {REFERENCE_ERROR_BOUND:g}")
    if row["ref_culls"] == "NO":
        problems.append("ref_culls NO")
    if not row["image_err"] <= FLOAT_ERROR_BOUND:
        problems.append(f"image_err {row['image_err']:.3g} > {FLOAT_ERROR_BOUND:g}")
    problems += [
        f"{k} {v:.3g} > {GRAD_ERROR_BOUND:g}"
        for k, v in row.items()
        if k.startswith("rel_") and not v <= GRAD_ERROR_BOUND
    ]
    if row["non_finite"] != "none":
        problems.append(f"non-finite {row['non_finite']}")
    if row["zero_grad"] == "NO":
        problems.append("zero_grad NO")
    return problems


def run(quick: bool, out: Path) -> dict:
    """Run every case (quick and full are the same: seconds); print the table, write stiff.json."""
    rows = [measure(case()) for case in CASES]
    print_table(rows)
    worst = _worst([r["image_err"] for r in rows])
    print(f"worst |float32 - float64| of image/alpha: {worst:.3g} (C++ tests: < 1e-3)")
    failures = [f"{r['case']}: {problem}" for r in rows for problem in failed_checks(r)]
    results = {
        "loss": "sum(image * g) + sum(alpha * h), g, h ~ N(0, 1) fixed (seed 7)",
        "columns": {
            "image_err": "max |float32 - float64| of image and alpha",
            "ref_err": "the float64 core against the float64 pure-torch reference: max |diff| of "
            "image and alpha, max |diff| / max |reference| of each gradient (at least 1e-9 of the "
            "largest gradient's)",
            "ref_culls": "the core and the reference cull the same Gaussians",
            "rel_X": "max |grad32 - grad64| / max(max |grad64|, 1) of gradient X "
            "(means2d: the screen points)",
            "non_finite": "outputs or gradients with a non-finite value, in either precision",
            "zero_grad": "the culled, transparent or clamped Gaussians get exactly zero gradient",
        },
        "float_error_bound": FLOAT_ERROR_BOUND,
        "grad_error_bound": GRAD_ERROR_BOUND,
        "reference_error_bound": REFERENCE_ERROR_BOUND,
        "cases": rows,
        "failures": failures,  # `spikegs bench` exits 1 where there are any
    }
    write_results(out, "stiff", results, quick)
    return results
