"""The C++ rasterizer (`spikegs.rasterize`) against the pure-torch reference, plus checks of the
reference itself (docs/rasterizer.md is the specification of both)."""

from __future__ import annotations

import decimal
import functools
import math
import os
import subprocess
import sys
import tracemalloc
from pathlib import Path

import numpy as np
import pytest
import spikegs
import torch
from spikegs import reference
from spikegs import sh as sh_module
from spikegs.sh import num_coeffs, sh_basis

try:
    from spikegs import _C  # noqa: F401

    HAVE_CPP = True
except ImportError:
    HAVE_CPP = False
needs_cpp = pytest.mark.skipif(not HAVE_CPP, reason="the C++ extension spikegs._C is not built")

ARGS = ("means", "quats", "scales", "opacities", "colors", "viewmat", "K")  # positional tensors
# differentiable inputs; screen_points [N, 2] (zeros) receives the gradient of the 2D means
PARAMS = (
    "means",
    "quats",
    "scales",
    "opacities",
    "colors",
    "viewmat",
    "background",
    "screen_points",
)
DIFFERENTIABLE = ("image", "alpha", "means2d", "depths")  # the outputs with a gradient
SIZES = [(13, 9), (33, 17), (64, 48)]  # (width, height), none a multiple of the tile size
COLOR_MODES = [None, 0, 1, 2, 3]  # None: direct colours, else the SH degree


def random_rotation(gen: torch.Generator, dtype: torch.dtype) -> torch.Tensor:
    """A random 3x3 rotation matrix."""
    q, r = torch.linalg.qr(torch.randn(3, 3, generator=gen, dtype=dtype))
    q = q * torch.sign(torch.diagonal(r))
    return q if torch.det(q) > 0 else -q


def make_scene(
    seed: int,
    n: int,
    width: int,
    height: int,
    channels: int = 3,
    sh_degree: int | None = None,
    dtype: torch.dtype = torch.float64,
    opacity: tuple[float, float] = (0.05, 0.95),
    sigma_px: tuple[float, float] = (0.3, 6.0),
) -> dict:
    """A random scene seen by a rotated, translated camera: Gaussians spread over the view and
    beyond it (where the Jacobian clamp acts); footprints of `sigma_px` pixels; a background."""
    gen = torch.Generator().manual_seed(seed)

    def uniform(lo: float, hi: float, *shape: int) -> torch.Tensor:
        return lo + (hi - lo) * torch.rand(*shape, generator=gen, dtype=torch.float64)

    f = 0.9 * max(width, height)
    K = torch.tensor([[f, 0, 0.5 * width + 0.3], [0, f, 0.5 * height - 0.2], [0, 0, 1]])
    viewmat = torch.eye(4, dtype=torch.float64)
    viewmat[:3, :3] = random_rotation(gen, torch.float64)
    viewmat[:3, 3] = uniform(-1, 1, 3)
    z = uniform(1.5, 4.0, n)
    px = torch.stack([uniform(-0.3, 1.3, n) * width, uniform(-0.3, 1.3, n) * height], -1)
    cam = torch.cat([(px - K[:2, 2]) / f * z[:, None], z[:, None]], -1)  # [N, 3]
    means = (cam - viewmat[:3, 3]) @ viewmat[:3, :3]  # [N, 3] = W^T (p - t)
    scales = uniform(*sigma_px, n, 3) * z[:, None] / f
    if sh_degree is None:
        colors = uniform(0, 1, n, channels)
    else:
        colors = 0.4 * torch.randn(
            n, num_coeffs(sh_degree), channels, generator=gen, dtype=torch.float64
        )
    scene = {
        "means": means,
        "quats": torch.randn(n, 4, generator=gen, dtype=torch.float64),
        "scales": scales,
        "opacities": uniform(*opacity, n),
        "colors": colors,
        "viewmat": viewmat,
        "K": K,
        "background": uniform(0, 1, channels),
        "screen_points": torch.zeros(n, 2, dtype=torch.float64),
    }
    scene = {k: v.to(dtype) for k, v in scene.items()}
    scene.update(width=width, height=height, sh_degree=sh_degree)
    return scene


def project(scene: dict) -> reference._Splats:
    """The reference's projection of a scene with direct colours, nothing culled upfront."""
    inputs = (*(scene[k] for k in ARGS), scene["width"], scene["height"])
    keep = torch.ones(scene["means"].shape[0], dtype=torch.bool)
    return reference._project(inputs, None, 0.01, 1e10, False, reference.DILATION, keep)


def render(fn, scene: dict, **overrides) -> spikegs.RasterizeResult:
    """Call a rasterizer (`spikegs.rasterize` or `reference.rasterize`) on a scene dict."""
    s = {**scene, **overrides}
    return fn(
        *(s[k] for k in ARGS),
        s["width"],
        s["height"],
        sh_degree=s["sh_degree"],
        background=s["background"],
        screen_points=s["screen_points"],
        **{k: s[k] for k in ("screen_abs", "near", "far", "antialiased", "dilation") if k in s},
    )


def forward_backward(fn, scene: dict, dtype: torch.dtype, seed: int = 1):
    """Outputs and gradients of (image, alpha, means2d, depths) . (random upstream gradients)
    w.r.t. PARAMS."""
    leaves = {k: scene[k].detach().to(dtype).requires_grad_() for k in PARAMS}
    out = render(fn, scene, K=scene["K"].to(dtype), **leaves)
    gen = torch.Generator().manual_seed(seed)
    loss = 0
    for name in DIFFERENTIABLE:
        x = getattr(out, name)
        loss = loss + (x * torch.randn(x.shape, generator=gen, dtype=torch.float64).to(dtype)).sum()
    grads = torch.autograd.grad(loss, list(leaves.values()), allow_unused=True)
    grads = {k: torch.zeros_like(v) if g is None else g for (k, v), g in zip(leaves.items(), grads)}
    return out, grads


def assert_near(actual: torch.Tensor, expected: torch.Tensor, rtol: float, what: str) -> None:
    """|actual - expected| <= rtol * max(|expected|, 1) elementwise (both finite), in float64."""
    actual, expected = actual.detach().double(), expected.detach().double()
    assert actual.shape == expected.shape, what
    assert torch.isfinite(actual).all(), f"{what}: non-finite values"
    scale = max(expected.abs().max().item() if expected.numel() else 0.0, 1.0)
    err = (actual - expected).abs().max().item() if expected.numel() else 0.0
    assert err <= rtol * scale, f"{what}: max abs error {err:.3g} > {rtol:.1g} * {scale:.3g}"


def check_finite_and_culled(out, grads) -> None:
    """Finite outputs and gradients; zero 2D means, depths and gradients for culled Gaussians."""
    for name in ("image", "alpha", "means2d", "depths"):
        assert torch.isfinite(getattr(out, name)).all(), name
    culled = out.radii == 0
    assert torch.all(out.means2d[culled] == 0) and torch.all(out.depths[culled] == 0)
    for name, g in grads.items():
        assert torch.isfinite(g).all(), f"grad {name}"
        if name not in ("viewmat", "background"):  # per-Gaussian gradients
            assert torch.all(g[culled] == 0), f"grad {name} of a culled Gaussian"


def compare_to_reference(scene: dict, dtype: torch.dtype, rtol: float) -> None:
    """C++ in `dtype` against the float64 reference on the same inputs: outputs and gradients."""
    scene = {k: v.to(dtype) if torch.is_tensor(v) else v for k, v in scene.items()}
    out, grads = forward_backward(spikegs.rasterize, scene, dtype)
    ref, ref_grads = forward_backward(reference.rasterize, scene, torch.float64)
    assert out.radii.dtype == torch.int32
    assert torch.equal(out.radii, ref.radii), "radii"
    for name in ("image", "alpha", "means2d", "depths"):
        assert getattr(out, name).dtype == dtype, name
        assert_near(getattr(out, name), getattr(ref, name), rtol, name)
    check_finite_and_culled(out, grads)
    for name in PARAMS:
        assert_near(grads[name], ref_grads[name], rtol, f"grad {name}")


# ---- the reference on its own ---------------------------------------------------------------


def test_sh_basis_is_orthonormal():
    """The 16 basis functions integrate to the identity over the sphere (Fibonacci quadrature)."""
    m = 20000
    i = torch.arange(m, dtype=torch.float64) + 0.5
    z = 1 - 2 * i / m
    phi = math.pi * (1 + 5**0.5) * i
    r = torch.sqrt(1 - z * z)
    dirs = torch.stack([r * torch.cos(phi), r * torch.sin(phi), z], -1)
    Y = sh_basis(dirs, 3)  # [M, 16]
    gram = Y.T @ Y * (4 * math.pi / m)
    assert torch.allclose(gram, torch.eye(16, dtype=torch.float64), atol=1e-4)
    assert sh_basis(dirs[:2], 0).shape == (2, 1)
    for degree in (-1, 4):  # the rasterizer's degrees are 0..3
        with pytest.raises(ValueError, match=f"sh degree must be in 0..3, got {degree}"):
            sh_basis(dirs[:2], degree)


def test_reference_single_gaussian_mass():
    """alpha of one Gaussian integrates to o * 2 pi sqrt(det Sigma2) * (1 - 1/(255 o)): the 1/255
    cut removes the mass outside the level set o G = 1/255."""
    o = 0.5
    scene = make_scene(0, 1, 64, 48, opacity=(o, o), sigma_px=(4.0, 6.0))
    scene["means"] = (
        (torch.tensor([0.1, -0.05, 3.0]) - scene["viewmat"][:3, 3]) @ scene["viewmat"][:3, :3]
    )[None]
    out = render(reference.rasterize, scene)
    splats = project(scene)
    A, B, C = splats.conics[0].tolist()
    mass = o * 2 * math.pi / math.sqrt(A * C - B * B) * (1 - reference.ALPHA_MIN / o)
    assert out.radii.item() > 0
    assert abs(out.alpha.sum().item() - mass) < 2e-3 * mass
    color = out.image - (1 - out.alpha)[..., None] * scene["background"]
    assert torch.allclose(color.sum((0, 1)) / out.alpha.sum(), scene["colors"][0])


def brute_force_image(splats: reference._Splats, width: int, height: int) -> torch.Tensor:
    """docs/rasterizer.md's per-pixel loop written literally with Python floats (no background)."""
    visible = [i for i in range(len(splats.visible)) if splats.visible[i]]
    order = sorted(visible, key=lambda i: (splats.depths[i].item(), i))
    image = torch.zeros(height, width, splats.colors.shape[1], dtype=torch.float64)
    for py in range(height):
        for px in range(width):
            T = 1.0
            for i in order:
                mx, my = splats.means2d[i].tolist()
                A, B, C = splats.conics[i].tolist()
                dx, dy = px + 0.5 - mx, py + 0.5 - my
                power = -0.5 * (A * dx * dx + C * dy * dy) - B * dx * dy
                if power > 0:
                    continue
                alpha = min(reference.ALPHA_MAX, splats.opacities[i].item() * math.exp(power))
                if alpha < reference.ALPHA_MIN:
                    continue
                if T * (1 - alpha) < reference.T_MIN:
                    break
                image[py, px] += alpha * T * splats.colors[i]
                T *= 1 - alpha
    return image


def test_reference_compositing_matches_the_literal_loop():
    scene = make_scene(3, 40, 13, 9, opacity=(0.5, 0.99), sigma_px=(1.0, 5.0))
    scene["background"] = torch.zeros(3, dtype=torch.float64)
    out = render(reference.rasterize, scene)
    splats = project(scene)
    assert (out.alpha > 1 - 1e-3).any(), "the scene should exercise the transmittance stop"
    assert torch.allclose(out.image, brute_force_image(splats, 13, 9), rtol=0, atol=1e-12)


# ---- C++ against the reference ---------------------------------------------------------------


@needs_cpp
@pytest.mark.parametrize("size", SIZES, ids=lambda s: f"{s[0]}x{s[1]}")
@pytest.mark.parametrize(
    "color_mode", COLOR_MODES, ids=lambda d: "direct" if d is None else f"sh{d}"
)
@pytest.mark.parametrize("channels", [1, 3])
@pytest.mark.parametrize(
    "dtype, rtol", [(torch.float64, 1e-9), (torch.float32, 1e-4)], ids=["float64", "float32"]
)
def test_matches_reference(size, color_mode, channels, dtype, rtol):
    width, height = size
    seed = 1000 * SIZES.index(size) + 10 * COLOR_MODES.index(color_mode) + channels
    n = 1 + seed % 50
    scene = make_scene(seed, n, width, height, channels, color_mode)
    compare_to_reference(scene, dtype, rtol)


@needs_cpp
@pytest.mark.parametrize("sh_degree", [0, 1, 2])
@pytest.mark.parametrize("channels", [1, 3])
def test_a_degree_below_the_coefficients_matches_reference(sh_degree, channels):
    """Degree-3 coefficients [N, 16, C] rendered at a lower degree (a GaussianModel's sh_rest may
    hold more than its degree reads): the core strides by 16 and reads the first (d+1)²; the
    unread ones get exactly zero gradient. The other tests render K = (d+1)² only."""
    scene = make_scene(300 + 10 * sh_degree + channels, 12, 21, 14, channels, sh_degree=3)
    scene["sh_degree"] = sh_degree
    compare_to_reference(scene, torch.float64, 1e-9)
    _, grads = forward_backward(spikegs.rasterize, scene, torch.float64)
    assert grads["colors"][:, : num_coeffs(sh_degree)].abs().sum() > 0
    assert torch.all(grads["colors"][:, num_coeffs(sh_degree) :] == 0)


@needs_cpp
def test_degree_0_of_16_channels_matches_reference_given_its_degree():
    """[N, 1, 16], refused without sh_degree (a mono scene's [N, C, K] reads the same), renders
    16 channels of degree 0 where sh_degree=0 says so."""
    compare_to_reference(make_scene(360, 12, 21, 14, 16, sh_degree=0), torch.float64, 1e-9)


@needs_cpp
@pytest.mark.parametrize("seed", range(3))
def test_elongated_splats_across_tiles_match_reference(seed):
    """Long, thin splats at every angle crossing tile edges and corners: the core composites only
    the rows of a tile within a pixel of a splat's ellipse, so a wrong chord there shows here."""
    scene = make_scene(7000 + seed, 40, 70, 52, sigma_px=(0.3, 12.0))
    scene["scales"][:, 0] *= 6.0  # one axis 6x longer: ellipses far from their boxes' rows
    compare_to_reference(scene, torch.float64, 1e-9)
    compare_to_reference(scene, torch.float32, 1e-4)


@pytest.mark.parametrize(
    "antialiased, dilation",
    [(False, 0.3), (True, 0.3), (True, 0.1)],
    ids=["plain", "antialiased", "mip-splatting"],
)
@pytest.mark.parametrize("sh_degree", [None, 1])
@pytest.mark.parametrize("impl", ["reference", pytest.param("cpp", marks=needs_cpp)])
def test_gradcheck(impl, sh_degree, antialiased, dilation):
    """Finite differences in float64: opacities in [0.1, 0.7] and a few Gaussians keep every alpha
    away from the 0.99 clamp and the transmittance stop. screen_points is left out: it is a
    gradient tap whose value the C++ op does not read (its gradient is compared with the reference's
    in test_matches_reference)."""
    fn = spikegs.rasterize if impl == "cpp" else reference.rasterize
    scene = make_scene(5, 4, 17, 11, sh_degree=sh_degree, opacity=(0.1, 0.7), sigma_px=(1.5, 3.0))
    scene["antialiased"], scene["dilation"] = antialiased, dilation
    if sh_degree is not None:
        scene["colors"] *= 0.25  # colours stay well above the clamp at 0
    names = [k for k in PARAMS if k != "screen_points"]
    leaves = [scene[k].clone().requires_grad_() for k in names]

    def outputs(*args):
        out = render(fn, scene, **dict(zip(names, args)))
        return tuple(getattr(out, name) for name in DIFFERENTIABLE)

    # the reference is slow: random projections of the Jacobian (fast mode) suffice to check it
    assert torch.autograd.gradcheck(
        outputs, leaves, eps=1e-6, atol=1e-6, rtol=1e-4, fast_mode=impl == "reference"
    )


@needs_cpp
@pytest.mark.parametrize(
    "dtype, rtol", [(torch.float64, 1e-9), (torch.float32, 1e-4)], ids=["float64", "float32"]
)
@pytest.mark.parametrize("case", ["sh2", "needles", "sub-pixel", "direct-mono"])
def test_antialiased_matches_reference(case, dtype, rtol):
    """The antialiased filter (each opacity times sqrt(det Σ / det(Σ + 0.3 I))) against the
    reference's, forward and every gradient: SH colours, needles across tiles (Σ nearly flat,
    the compensation near 0), splats under a pixel and direct mono colours."""
    if case == "needles":
        scene = make_scene(7100, 40, 70, 52, sigma_px=(0.3, 12.0))
        scene["scales"][:, 0] *= 6.0
    elif case == "sub-pixel":
        scene = make_scene(7200, 30, 33, 17, opacity=(0.3, 1.0), sigma_px=(0.05, 0.8))
    elif case == "sh2":
        scene = make_scene(7300, 30, 33, 17, sh_degree=2)
    else:
        scene = make_scene(7400, 25, 64, 48, channels=1)
    scene["antialiased"] = True
    compare_to_reference(scene, dtype, rtol)
    plain = render(spikegs.rasterize, scene, antialiased=False)
    drawn = render(spikegs.rasterize, scene)
    assert (drawn.radii <= plain.radii).all(), "a compensated splat reaches no farther"
    assert drawn.alpha.sum() < plain.alpha.sum(), "the compensation takes opacity away"


@needs_cpp
@pytest.mark.parametrize(
    "dtype, rtol", [(torch.float64, 1e-9), (torch.float32, 1e-4)], ids=["float64", "float32"]
)
@pytest.mark.parametrize("antialiased", [False, True], ids=["plain", "antialiased"])
@pytest.mark.parametrize("dilation", [0.01, 0.1, 10.0])
def test_another_dilation_matches_reference(dilation, antialiased, dtype, rtol):
    """A dilation other than 3DGS's 0.3 px² (Mip-Splatting's 0.1, and the range's two ends)
    against the reference's, forward and every gradient, on needles across tiles and splats
    under a pixel (at 0.01 px² their conics reach 100 px⁻²); the image is another than at 0.3."""
    scene = make_scene(7600, 40, 70, 52, opacity=(0.2, 0.95), sigma_px=(0.05, 6.0))
    scene["scales"][:10, 0] *= 8.0  # needles
    scene["antialiased"], scene["dilation"] = antialiased, dilation
    compare_to_reference(scene, dtype, rtol)
    default = render(spikegs.rasterize, scene, dilation=0.3)
    assert (render(spikegs.rasterize, scene).image - default.image).abs().max() > 0.01


def _round_splat(op, angle: float, o: float, K, size: int, **options) -> spikegs.RasterizeResult:
    """One round splat of opacity `o` and colour 1 on the optical axis at depth 2, as wide as
    `angle` (its σ over its depth: σ·f pixels at focal length f), drawn by `op` (either
    rasterizer, float64) through K [3, 3] in a `size` × `size` image with `options`."""
    return op(
        torch.tensor([[0.0, 0.0, 2.0]], dtype=torch.float64),
        torch.tensor([[1.0, 0.0, 0.0, 0.0]], dtype=torch.float64),
        torch.full((1, 3), 2.0 * angle, dtype=torch.float64),
        torch.tensor([o], dtype=torch.float64),
        torch.ones(1, 1, dtype=torch.float64),
        torch.eye(4, dtype=torch.float64),
        K,
        size,
        size,
        **options,
    )


@needs_cpp
@pytest.mark.parametrize("op", [spikegs.rasterize, reference.rasterize], ids=["core", "reference"])
def test_a_splat_is_as_wide_as_its_variance_and_dilation(op):
    """Independent of either rasterizer's maths: a round splat of variance σ² px² centred on a
    pixel, drawn with dilation d, has its alpha at the next pixel exp(-1 / (2 (σ² + d))) times
    the centre's; the centre's is o plain and o σ² / (σ² + d) antialiased (the integral kept)."""
    o, size, f = 0.95, 9, 20.0
    K = torch.tensor([[f, 0, 4.5], [0, f, 4.5], [0, 0, 1]], dtype=torch.float64)  # centre (4, 4)
    for antialiased, variance in ((False, 1e-8), (True, 0.25)):
        for d in (0.1, 0.3, 2.0, 10.0):
            out = _round_splat(
                op, math.sqrt(variance) / f, o, K, size, antialiased=antialiased, dilation=d
            )
            centre = o * variance / (variance + d) if antialiased else o
            assert out.alpha[4, 4].item() == pytest.approx(centre, rel=1e-6), (antialiased, d)
            ratio = math.exp(-1 / (2 * (variance + d)))
            for pixel in ((4, 5), (5, 4), (3, 4), (4, 3)):
                assert out.alpha[pixel].item() == pytest.approx(centre * ratio, rel=1e-6), d


@needs_cpp
@pytest.mark.parametrize("dtype", [torch.float64, torch.float32], ids=["float64", "float32"])
def test_an_antialiased_line_or_point_is_culled(dtype):
    """A Gaussian of two (or three) zero scales projects to a line (a point): det(V Vᵀ) = 0, so
    its antialiased opacity is 0 and it is culled, with zero gradients, where the plain filter
    draws it 0.3 px² wide; a needle beside them keeps finite gradients."""
    scene = make_scene(7500, 3, 33, 17, opacity=(0.8, 0.9), sigma_px=(2.0, 3.0))
    scene["scales"][0, 1:] = 0.0  # a line
    scene["scales"][1] = 0.0  # a point
    scene["scales"][2, 1] = 1e-7 * scene["scales"][2, 0]  # a needle, nearly flat
    scene["means"][:] = scene["means"][2]  # all in view
    scene = {k: v.to(dtype) if torch.is_tensor(v) else v for k, v in scene.items()}
    plain, _ = forward_backward(spikegs.rasterize, scene, dtype)
    out, grads = forward_backward(spikegs.rasterize, {**scene, "antialiased": True}, dtype)
    assert (plain.radii[:2] > 0).all() and (out.radii[:2] == 0).all()
    check_finite_and_culled(out, grads)
    if dtype == torch.float64:
        compare_to_reference({**scene, "antialiased": True}, dtype, 1e-9)


@needs_cpp
@pytest.mark.parametrize("op", [spikegs.rasterize, reference.rasterize], ids=["core", "reference"])
def test_an_antialiased_splat_keeps_its_mass_at_any_resolution(op):
    """Independent of the reference's maths: one round splat of σ = 0.25 px, drawn at 1, 2 and 4
    times the resolution. Antialiased, its alpha integrates to o 2π σ² in pixels of the first
    size at each (the dilation keeps the integral; less the mass below 1/255, o_eff G < 1/255);
    plain, the dilation adds 0.3 px² of the size drawn: 4.5 times the mass at the first size
    as at the last."""
    o, sigma = 0.9, 0.25  # sigma in pixels at scale 1
    masses = {}
    for antialiased in (False, True):
        for scale in (1, 2, 4):
            size = 16 * scale
            f = 20.0 * scale
            K = torch.tensor([[f, 0, size / 2 + 0.13], [0, f, size / 2 - 0.21], [0, 0, 1]])
            out = _round_splat(op, sigma / 20.0, o, K.double(), size, antialiased=antialiased)
            masses[antialiased, scale] = out.alpha.sum().item() / scale**2
            if antialiased:
                var = (sigma * scale) ** 2  # the undilated variance, pixels² of this size
                o_eff = o * var / (var + reference.DILATION)
                expected = o * 2 * math.pi * sigma**2 * (1 - reference.ALPHA_MIN / o_eff)
                assert masses[True, scale] == pytest.approx(expected, rel=0.01), scale
    assert masses[False, 1] > 4 * masses[False, 4]  # (0.0625 + 0.3) / (0.0625 + 0.3 / 16)
    assert masses[False, 4] > 1.1 * masses[True, 4]


def anisotropic(scene: dict, kx: float, ky: float, cx: float, cy: float) -> dict:
    """`scene` seen through other intrinsics: its focal lengths times `kx`, `ky` (fx != fy: a
    non-square pixel or a resampled image), the principal point at (`cx`, `cy`) of the image."""
    K = scene["K"].clone()
    K[0, 0], K[1, 1] = K[0, 0] * kx, K[1, 1] * ky
    K[0, 2], K[1, 2] = cx * scene["width"], cy * scene["height"]
    return {**scene, "K": K}


@needs_cpp
@pytest.mark.parametrize(
    "kx, ky, cx, cy",
    [(1.7, 1.0, 0.1, 0.5), (1.0, 2.5, 0.9, 0.05), (0.08, 0.08, 0.5, 0.5), (40.0, 40.0, 0.5, 0.5)],
    ids=["fx-wide", "fy-wide-corner", "fisheye-wide", "telephoto"],
)
def test_anisotropic_and_extreme_intrinsics_match_the_reference(kx, ky, cx, cy):
    """Every other case has fx = fy and the principal point near the centre: the op against
    the reference with fx != fy, the principal point near an edge, a ~160° and a ~1.6° view
    (the Jacobian's clamp at 1.3 tan of the half-field acting on each axis apart)."""
    scene = anisotropic(make_scene(40, 3, 33, 17), kx, ky, cx, cy)
    compare_to_reference(scene, torch.float64, 1e-9)
    compare_to_reference(scene, torch.float32, 1e-4)


@needs_cpp
def test_anisotropic_gradients_match_finite_differences():
    """The op's gradients (the viewmat's and K-dependent ones included) in float64 with fx = 0.3
    fy against finite differences, as test_gradcheck does for fx = fy."""
    scene = anisotropic(
        make_scene(5, 4, 17, 11, sh_degree=1, opacity=(0.1, 0.7)), 0.3, 1.6, 0.4, 0.6
    )
    scene["colors"] *= 0.25  # colours stay well above the clamp at 0
    names = [k for k in PARAMS if k != "screen_points"]
    leaves = [scene[k].clone().requires_grad_() for k in names]

    def outputs(*args):
        out = render(spikegs.rasterize, scene, **dict(zip(names, args)))
        return tuple(getattr(out, name) for name in DIFFERENTIABLE)

    assert torch.autograd.gradcheck(outputs, leaves, eps=1e-6, atol=1e-6, rtol=1e-4)


@needs_cpp
def test_a_small_gaussian_lands_where_the_intrinsics_project_it():
    """Independent of the reference (which shares the op's maths): one small Gaussian's alpha
    centroid lies at (fx x/z + cx, fy y/z + cy) with pixel centres at +0.5, for fx != fy and an
    off-centre principal point."""
    f64 = dict(dtype=torch.float64)
    K = torch.tensor([[90.0, 0, 20.3], [0, 30.0, 30.7], [0, 0, 1]], **f64)
    mean = torch.tensor([[0.1, -0.2, 3.0]], **f64)
    alpha = spikegs.rasterize(
        mean,
        torch.tensor([[1.0, 0, 0, 0]], **f64),
        torch.full((1, 3), 0.02, **f64),
        torch.tensor([0.9], **f64),
        torch.ones(1, 1, **f64),
        torch.eye(4, **f64),
        K,
        64,
        48,
    ).alpha  # [48, 64]
    ys, xs = torch.meshgrid(
        torch.arange(48, **f64) + 0.5, torch.arange(64, **f64) + 0.5, indexing="ij"
    )
    centroid = torch.stack([(alpha * xs).sum(), (alpha * ys).sum()]) / alpha.sum()
    expected = torch.tensor([90 * 0.1 / 3 + 20.3, 30 * -0.2 / 3 + 30.7], **f64)
    assert (centroid - expected).abs().max() < 0.02, (centroid, expected)


@needs_cpp
@pytest.mark.parametrize("channels", [1, 3, 4])
@pytest.mark.parametrize(
    "dtype, rtol", [(torch.float64, 1e-9), (torch.float32, 1e-4)], ids=["float64", "float32"]
)
def test_screen_abs_sums_the_reference_per_pixel_shares(channels, dtype, rtol):
    """screen_abs (AbsGS) against the float64 reference: the Jacobian of each pixel's loss (image
    and alpha, random weights) w.r.t. the 2D means, summed over pixels in absolute value. Each
    backward adds to it: two renders give the sum of their two."""
    scene = make_scene(31 + channels, 12, 21, 14, channels)
    gen = torch.Generator().manual_seed(channels)
    w_img = torch.randn(14, 21, channels, generator=gen, dtype=torch.float64)
    w_alpha = torch.randn(14, 21, generator=gen, dtype=torch.float64)

    def per_pixel(screen_points):  # [H * W] each pixel's loss
        out = render(reference.rasterize, scene, screen_points=screen_points)
        return ((out.image * w_img).sum(-1) + out.alpha * w_alpha).flatten()

    jac = torch.autograd.functional.jacobian(per_pixel, scene["screen_points"])  # [H*W, N, 2]
    expected = jac.abs().sum(0)
    assert (expected - jac.sum(0).abs()).max() > 0.1 * expected.max(), "no shares cancel"

    s = {k: v.to(dtype) if torch.is_tensor(v) else v for k, v in scene.items()}
    screen_abs = torch.zeros(12, 2, dtype=dtype)
    for _ in range(2):
        leaves = {k: s[k].clone().requires_grad_() for k in ("means", "colors")}
        out = render(spikegs.rasterize, s, screen_abs=screen_abs, **leaves)
        loss = (out.image * w_img.to(dtype)).sum() + (out.alpha * w_alpha.to(dtype)).sum()
        loss.backward()
    assert_near(screen_abs, 2 * expected, rtol, "screen_abs after two backwards")
    with pytest.raises(ValueError, match=r"screen_abs: expected shape \[12, 2\]"):
        render(spikegs.rasterize, s, screen_abs=torch.zeros(11, 2, dtype=dtype))


@needs_cpp
def test_equal_depths_keep_index_order():
    """Overlapping Gaussians at exactly the same depth are composited in index order."""
    scene = make_scene(9, 6, 33, 17, opacity=(0.6, 0.9), sigma_px=(3.0, 5.0))
    scene["viewmat"] = torch.eye(4, dtype=torch.float64)  # depth = means[:, 2] exactly
    scene["means"] = torch.tensor([[0.02 * i - 0.05, 0.01 * i, 2.0] for i in range(6)]).double()
    out = render(spikegs.rasterize, scene)
    assert torch.all(out.depths == 2.0)
    assert torch.allclose(out.image, render(reference.rasterize, scene).image, rtol=0, atol=1e-12)
    flipped = render(
        spikegs.rasterize, {k: v.flip(0) if k in PARAMS[:5] else v for k, v in scene.items()}
    )
    assert not torch.allclose(out.image, flipped.image, atol=1e-3), "the order should matter here"


@needs_cpp
def test_result_type():
    out = render(spikegs.rasterize, make_scene(6, 5, 13, 9))
    assert isinstance(out, spikegs.RasterizeResult)
    assert out._fields == ("image", "alpha", "radii", "means2d", "depths")
    assert out.image.shape == (9, 13, 3) and out.alpha.shape == (9, 13)
    assert out.radii.shape == (5,) and out.means2d.shape == (5, 2) and out.depths.shape == (5,)


@needs_cpp
def test_non_contiguous_inputs():
    """Transposed and strided views give what their contiguous copies give: the same outputs and
    gradients, bitwise."""
    scene = make_scene(7, 20, 33, 17, sh_degree=2)
    views = {k: torch.stack([scene[k], scene[k]], -1)[..., 1] for k in ARGS + ("background",)}
    views["means"] = scene["means"].T.contiguous().T
    views["colors"] = scene["colors"].permute(2, 0, 1).contiguous().permute(1, 2, 0)
    assert not any(v.is_contiguous() for v in views.values())
    out, grads = forward_backward(spikegs.rasterize, scene, torch.float64)
    out_v, grads_v = forward_backward(spikegs.rasterize, {**scene, **views}, torch.float64)
    for a, b in zip(out, out_v):
        assert torch.equal(a, b)
    for name in PARAMS:
        assert torch.equal(grads_v[name], grads[name]), name


@needs_cpp
def test_inputs_and_outputs_cross_the_binding_without_a_copy():
    """Contiguous CPU tensors reach the core as numpy views of their memory, and its arrays come
    back as tensors over them: while the op runs numpy allocates its outputs and gradients and
    nothing else (tracemalloc traces numpy's memory, not the core's or torch's), so a copy of any
    input, 4 bytes a Gaussian at least, shows; and the forward's outputs are numpy's memory still
    (copied into torch tensors, the arrays were freed)."""
    n, slack = 100_000, 64 << 10  # Python's own objects: a few kB
    scene = make_scene(2, n, 16, 12, channels=1, dtype=torch.float32)
    leaves = {k: scene[k].requires_grad_() for k in PARAMS[:5]}
    render(spikegs.rasterize, scene, **leaves)  # the first call's imports and caches
    tracemalloc.start()
    try:
        out = render(spikegs.rasterize, scene, **leaves)
        held, peak = tracemalloc.get_traced_memory()
        outputs = sum(t.nbytes for t in out)  # image, alpha, radii, means2d, depths
        assert (out.radii > 0).sum() > n // 2
        assert outputs <= held and peak <= outputs + slack, (held, peak, outputs)
        tracemalloc.reset_peak()
        out.image.sum().backward()
        # a gradient per input value, of the view matrix and background, of means2d and AbsGS's
        grads = sum(v.nbytes for v in leaves.values()) + (16 + 1 + 4 * n) * 4
        assert tracemalloc.get_traced_memory()[1] <= held + grads + slack
    finally:
        tracemalloc.stop()


@needs_cpp
def test_forward_and_backward_release_the_gil(longest_pause, monkeypatch):
    """The core runs without the GIL, forward and backward: Python's other threads run meanwhile
    (a data loader, a viewer). The binding's calls of a render are timed alone, with the
    arguments spikegs.rasterize gave them (the wrapper's own Python holds the GIL, as it must:
    around them, the forward kept it 45 % of a render's time): 40,000 Gaussians 20-40 px wide on
    512², ~0.2 s each way."""
    scene = make_scene(
        3,
        40_000,
        512,
        512,
        channels=1,
        dtype=torch.float32,
        opacity=(0.01, 0.05),
        sigma_px=(20, 40),
    )
    calls, cores = {}, {}
    for way in ("forward", "backward"):
        cores[way] = core = getattr(spikegs._C, f"rasterize_{way}_float32")

        def record(*args, way=way, core=core):
            calls[way] = args
            return core(*args)

        monkeypatch.setattr(spikegs._C, f"rasterize_{way}_float32", record)
    leaves = {k: scene[k].requires_grad_() for k in PARAMS[:5]}
    render(spikegs.rasterize, scene, **leaves).image.sum().backward()
    for way, core in cores.items():
        assert longest_pause(functools.partial(core, *calls[way])) < 0.5, way


# ---- input validation ------------------------------------------------------------------------


def _bad_inputs():
    """Cases (id, overrides of the scene, argument the error must name) and the float32 scene."""
    s = make_scene(8, 6, 13, 9, sh_degree=1, dtype=torch.float32)
    return (
        [
            ("means-shape", {"means": s["means"][:, :2]}, "means"),
            ("quats-shape", {"quats": s["quats"][:, :3]}, "quats"),
            ("scales-shape", {"scales": s["scales"][:, :1]}, "scales"),
            ("opacities-shape", {"opacities": s["opacities"][:, None]}, "opacities"),
            ("colors-shape", {"colors": s["colors"][:, 0, 0]}, "colors"),
            ("viewmat-shape", {"viewmat": s["viewmat"][:3]}, "viewmat"),
            ("K-shape", {"K": s["K"][:2]}, "K"),
            ("background-shape", {"background": s["background"][:2]}, "background"),
            ("means-int", {"means": s["means"].long()}, "means"),
            ("means-float16", {"means": s["means"].half()}, r"means.*pass means\.float\(\)"),
            # a layer's output under torch.autocast: said what to do
            (
                "colors-bfloat16",
                {"colors": s["colors"].bfloat16()},
                r"colors: .* no half-precision path: pass colors\.float\(\)",
            ),
            ("scales-mixed", {"scales": s["scales"].double()}, "scales"),
            ("colors-mixed", {"colors": s["colors"].double()}, "colors"),
            ("viewmat-mixed", {"viewmat": s["viewmat"].double()}, "viewmat"),
            ("means-meta", {"means": s["means"].to("meta")}, "means"),
            ("opacities-meta", {"opacities": s["opacities"].to("meta")}, "opacities"),
            ("scales-n", {"scales": torch.cat([s["scales"], s["scales"][:1]])}, "scales"),
            ("colors-n", {"colors": s["colors"][:-1]}, "colors"),
            (
                "opacity-above-1",
                {"opacities": s["opacities"] + 1},
                r"opacities: expected .* \[0, 1\]",
            ),
            (
                "opacity-negative",
                {"opacities": -s["opacities"]},
                r"opacities: expected .* \[0, 1\]",
            ),
            ("width-0", {"width": 0}, "width"),
            ("height-neg", {"height": -3}, "height"),
            ("width-huge", {"width": 2**31}, "width"),
            ("width-float", {"width": 13.0}, "width"),
            ("viewmat-nan", {"viewmat": s["viewmat"].clone().fill_(float("nan"))}, "viewmat"),
            ("K-inf", {"K": s["K"] * float("inf")}, "K"),
            ("K-fx-0", {"K": s["K"] * torch.tensor([0.0, 1, 1])[:, None]}, "K: expected focal"),
            ("K-fy-neg", {"K": s["K"] * torch.tensor([1.0, -1, 1])[:, None]}, "K: expected focal"),
            ("K-skew", {"K": s["K"] + torch.tensor([[0.0, 0.5, 0], [0, 0, 0], [0, 0, 0]])}, "skew"),
            ("K-last-row", {"K": s["K"] * 2}, "skew"),
            ("background-nan", {"background": s["background"] * float("nan")}, "background"),
            ("scales-log", {"scales": s["scales"].log()}, "scales: expected activated"),
            # read by the reference, ignored by the op: images that differed silently
            ("screen-points-non-zero", {"screen_points": torch.ones(6, 2)}, "expected zeros"),
            ("near-str", {"near": "0.1"}, "near, far: expected"),  # TypeErrors
            ("far-none", {"far": None}, "near, far: expected"),
            ("near-float32-zero", {"near": 1e-300}, "round to 0.0, .* in torch.float32"),
            ("far-float32-inf", {"near": 1e39, "far": 1e40}, "round to inf, inf"),
            ("far-int-overflow", {"far": 10**400}, "overflow a float"),  # an OverflowError
            ("near-decimal", {"near": decimal.Decimal("0.01")}, "near, far: expected real"),
            (
                "quats-list",
                {"quats": s["quats"].tolist()},
                "quats: expected a torch.Tensor, got list",
            ),
            (
                "colors-0-channels",
                {"colors": s["colors"][..., :0]},
                "colors: expected at least one",
            ),
            ("means-sparse", {"means": s["means"].to_sparse()}, "means: expected a dense"),
            ("K-sparse", {"K": s["K"].to_sparse()}, "K: expected a dense"),  # NotImplementedError
            # rendered, and K.grad stayed None after the backward
            ("K-requires-grad", {"K": s["K"].clone().requires_grad_()}, "K: the intrinsics get no"),
            # taken as numbers, their gradient none, unsaid
            (
                "dilation-requires-grad",
                {"dilation": torch.tensor(0.3, requires_grad=True)},
                "dilation: gets no gradient",
            ),
            (
                "near-requires-grad",
                {"near": torch.tensor(0.01, requires_grad=True)},
                "near: gets no gradient",
            ),
            # failed only in the backward's in-place sum, with torch's message
            ("screen-abs-expanded", {"screen_abs": torch.zeros(1, 2).expand(6, 2)}, "expanded"),
            ("sh-degree-bool", {"sh_degree": True}, "sh_degree"),
            ("antialiased-str", {"antialiased": "yes"}, "antialiased: expected True or False"),
            ("antialiased-int", {"antialiased": 1}, "antialiased: expected True or False"),
            ("dilation-small", {"dilation": 0.009}, r"dilation: expected pixels² in 0.01..10"),
            ("dilation-large", {"dilation": 10.5}, r"dilation: expected pixels² in 0.01..10"),
            ("dilation-nan", {"dilation": float("nan")}, "dilation: expected pixels²"),
            ("dilation-bool", {"dilation": True}, "dilation: expected pixels²"),
            ("dilation-str", {"dilation": "0.1"}, "dilation: expected pixels²"),
            (
                "sh-degree-float",
                {"sh_degree": 1.0},
                "sh_degree: expected an int",
            ),  # a pybind TypeError
            ("sh-degree-str", {"sh_degree": "1"}, "sh_degree: expected an int"),
            ("sh-k-small", {"sh_degree": 2}, "colors|sh_degree"),
            # a degree for direct colours [N, C], and colours of 4 dimensions
            (
                "sh-degree-of-direct",
                {"colors": s["colors"][:, 0], "sh_degree": 1},
                r"colors: sh_degree=1 needs SH coefficients \[N, K, C\], got \[6, 3\]",
            ),
            (
                "sh-4d",
                {"colors": s["colors"][..., None]},
                r"expected shape \[N, C\] or \[N, K, C\]",
            ),
            # a degree out of range with direct colours: was told it needs SH coefficients
            ("sh-degree-negative", {"colors": s["colors"][:, 0], "sh_degree": -1}, "expected 0..3"),
            ("sh-degree-5", {"sh_degree": 5}, r"sh_degree: expected 0..3, got 5"),
            # was "sh_degree: expected 0..3, got -1", a degree the caller never passed
            ("sh-k-zero", {"colors": s["colors"][:, :0], "sh_degree": None}, "at least 1 SH"),
            (
                "sh-k-not-square",
                {"colors": s["colors"][:, :3], "sh_degree": None},
                "colors|sh_degree",
            ),
            # was "sh_degree: expected 0..3, got 4", a degree the caller never passed
            (
                "sh-k-25",
                {"colors": s["colors"].repeat(1, 7, 1)[:, :25], "sh_degree": None},
                "up to 3",
            ),
            # [N, C, K] (as some codebases store them): said "pass sh_degree", which fails too
            (
                "sh-channels-first",
                {"colors": s["colors"].mT, "sh_degree": None, "background": None},
                "transpose",
            ),
            # a mono scene's [N, C, K]: rendered as degree 0 of 4 channels, unsaid
            (
                "sh-mono-channels-first",
                {"colors": s["colors"][..., :1].mT, "sh_degree": None, "background": None},
                r"\[6, 1, 4\] is SH degree 0 of 4 channels .* colors\.transpose\(1, 2\)",
            ),
            (
                "sh-degree-4",
                {"colors": s["colors"].repeat(1, 7, 1)[:, :25], "sh_degree": 4},
                "colors|sh_degree",
            ),
        ],
        s,
    )


_BAD, _BAD_SCENE = _bad_inputs()


@needs_cpp
@pytest.mark.parametrize("overrides, name", [c[1:] for c in _BAD], ids=[c[0] for c in _BAD])
def test_bad_input_raises(overrides, name):
    with pytest.raises(ValueError, match=name):
        render(spikegs.rasterize, _BAD_SCENE, **overrides)


@needs_cpp
def test_the_core_has_the_documented_constants():
    """The reference writes docs/rasterizer.md's constants; it read them from the core, so a
    changed clamp margin (0.3 -> 1.0) passed every test."""
    documented = {
        "alpha_max": reference.ALPHA_MAX,
        "alpha_min": reference.ALPHA_MIN,
        "transmittance_min": reference.T_MIN,
        "dilation": reference.DILATION,
        "min_dilation": reference.MIN_DILATION,
        "max_dilation": reference.MAX_DILATION,
        "clamp_margin": reference.CLAMP_MARGIN,
        "tile_size": 16,
        "near": reference.NEAR,
        "far": reference.FAR,
        "max_mean2d": reference.MAX_MEAN2D,
        "max_sh_degree": 3,
        "max_image_size": 2**20,
    }
    core = spikegs._C.constants
    assert {k: core[k] for k in documented} == pytest.approx(documented, rel=1e-7)


def test_reference_refuses_what_the_op_refuses():
    """Both rasterizers check colours and SH degrees with one function (sh.degree_of)."""
    for overrides, name in [c[1:] for c in _BAD if c[0].startswith("sh-")]:
        with pytest.raises(ValueError, match=name):
            render(reference.rasterize, _BAD_SCENE, **overrides)
    assert sh_module.MAX_DEGREE == spikegs._C.constants["max_sh_degree"]


@needs_cpp
@pytest.mark.parametrize("dtype", [torch.float64, torch.float32])
def test_far_plane_culls_as_the_reference_does(dtype):
    """Gaussians at depth >= far are culled (radius 0, no gradient): a core that ignored `far`
    passed every other test, whose scenes lie well within it (12 of these drawn, the image 0.56
    off)."""
    scene = {**make_scene(21, 30, 33, 17), "far": 2.5}  # depths 1.5-4: about half beyond
    ref = render(reference.rasterize, scene)
    assert ((ref.radii == 0) & (ref.depths == 0)).sum() >= 5
    compare_to_reference(scene, dtype, 1e-9 if dtype == torch.float64 else 1e-4)


@needs_cpp
@pytest.mark.parametrize("dtype", [torch.float64, torch.float32], ids=["float64", "float32"])
def test_a_quaternion_whose_norm_squared_is_subnormal_culls_as_in_the_reference(dtype):
    """|q|² below the dtype's smallest normal number culls in both rasterizers; just above it,
    both draw the rotation of q / |q|: -ffast-math's reciprocal square root made -inf of a
    subnormal float32 |q|² (|q| < 1.1e-19), where the core culled what the reference drew."""
    scene = make_scene(3, 20, 33, 17, dtype=dtype)
    unit = scene["quats"] / scene["quats"].norm(dim=-1, keepdim=True)  # [N, 4]
    root_tiny = math.sqrt(torch.finfo(dtype).tiny)
    subnormal = torch.arange(20) % 2 == 0  # [N]: |q|² a quarter of the smallest normal
    small = {**scene, "quats": unit * torch.where(subnormal, 0.5, 2.0)[:, None] * root_tiny}
    out, ref = render(spikegs.rasterize, small), render(reference.rasterize, small)
    assert torch.equal(out.radii, ref.radii), "radii"
    drawn = render(spikegs.rasterize, {**scene, "quats": unit}).radii > 0
    assert drawn.sum() >= 5 and torch.equal(out.radii > 0, drawn & ~subnormal)
    rtol = 1e-9 if dtype == torch.float64 else 1e-4
    for name in ("image", "alpha", "means2d", "depths"):
        assert_near(getattr(out, name), getattr(ref, name), rtol, name)
    check_finite_and_culled(*forward_backward(spikegs.rasterize, small, dtype))


@pytest.mark.parametrize("channels", [1, 3, 4])
def test_a_clamped_alpha_passes_no_gradient_for_any_channel_count(channels):
    """alpha = min(0.99, o·G) has no gradient where clamped; the backward has one loop for 1 and
    3 channels and another for the rest, which only 1-channel clamped scenes tested (4 channels
    with the clamp's gradient let through: 0.27 off). An opaque Gaussian ~40 px wide over most of
    the image and a few others, against the reference."""
    scene = make_scene(5, 4, 17, 11, channels=channels, opacity=(0.3, 0.6), sigma_px=(1.5, 3.0))
    scene["opacities"][0] = 1.0
    scene["scales"][0] *= 20.0
    assert (render(reference.rasterize, scene).alpha >= 0.99).sum() > 20  # clamped there
    compare_to_reference(scene, torch.float64, 1e-9)


@pytest.mark.parametrize("dtype", [torch.float64, torch.float32])
def test_an_alpha_exactly_at_the_clamp_passes_no_gradient(dtype):
    """o·G equal to the clamp (o = 0.99 rounded down in the dtype, centred on a pixel: G = 1) is
    clamped, no gradient, in both rasterizers (the reference's torch.minimum gave half, 0.5)."""
    t = lambda x: torch.tensor(x, dtype=dtype)  # noqa: E731
    alpha_max = reference._alpha_max(dtype).item()  # float32: 0.98999995
    for fn in (spikegs.rasterize, reference.rasterize):
        o = t([alpha_max]).requires_grad_()
        out = fn(
            t([[0.0, 0.0, 2.0]]),
            t([[1.0, 0.0, 0.0, 0.0]]),
            t([[0.3, 0.3, 0.3]]),
            o,
            t([[1.0]]),
            torch.eye(4, dtype=dtype),
            t([[8.0, 0.0, 4.5], [0.0, 8.0, 4.5], [0.0, 0.0, 1.0]]),
            9,
            9,
        )
        out.alpha[4, 4].backward()
        assert out.alpha[4, 4].item() == pytest.approx(0.99, abs=1e-7), fn
        assert o.grad.item() == 0.0, fn


@pytest.mark.parametrize("number", [torch.tensor, np.float64, np.float32], ids=["0-d", "f8", "f4"])
def test_number_arguments_as_numpy_scalars_or_scalar_tensors(number):
    """near, far and dilation alike (a 0-d tensor's dilation was refused, its near taken)."""
    values = {"near": 0.05, "far": 50, "dilation": 0.1}
    plain = render(spikegs.rasterize, _BAD_SCENE, **values)
    given = render(spikegs.rasterize, _BAD_SCENE, **{k: number(v) for k, v in values.items()})
    assert torch.equal(plain.image, given.image)


def test_antialiased_as_a_numpy_bool():
    """np.bool_ (a numpy comparison's result) is a bool: it was refused."""
    plain = render(spikegs.rasterize, _BAD_SCENE, antialiased=True)
    given = render(spikegs.rasterize, _BAD_SCENE, antialiased=np.bool_(True))
    assert torch.equal(plain.image, given.image)


@needs_cpp
@pytest.mark.parametrize("output", ["alpha", "depths"])
def test_a_loss_on_one_output_alone(output):
    """Outputs the loss leaves out reach the backward as None (the image's too)."""
    scene = make_scene(4, 6, 13, 9)
    grads = []
    for fn in (spikegs.rasterize, reference.rasterize):
        means = scene["means"].clone().requires_grad_()
        (grad,) = torch.autograd.grad(getattr(render(fn, scene, means=means), output).sum(), means)
        grads.append(grad)
    assert grads[1].abs().max() > 0
    assert_near(grads[0], grads[1], 1e-9, f"grad means of {output}")


def _render_and_grads(scene: dict, fn=None) -> list[torch.Tensor]:
    """A float32 scene's outputs and the gradients of every input of a loss on all of them,
    computed by `fn(leaves) -> RasterizeResult` (default: the op)."""
    names = [k for k in PARAMS if k != "screen_points"]
    leaves = {k: scene[k].clone().requires_grad_() for k in names}
    out = fn(leaves) if fn else render(spikegs.rasterize, scene, **leaves)
    loss = (out.image - 0.5).square().mean() + out.alpha.mean() + out.means2d.mean()
    loss.backward()
    return [*out, loss.detach()] + [leaves[k].grad for k in names]


@needs_cpp
def test_autocast_and_grad_modes_leave_the_op_as_it_is():
    """docs/rasterizer.md, "Under the rest of torch": the op is not autocast (float32 in, float32
    numbers out, the same gradients), and renders alike under no_grad and inference_mode."""
    scene = make_scene(5, 6, 17, 11, sh_degree=1, dtype=torch.float32)
    expected = _render_and_grads(scene)
    with torch.autocast("cpu", dtype=torch.bfloat16):
        got = _render_and_grads(scene)
    assert all(a.dtype == b.dtype and torch.equal(a, b) for a, b in zip(got, expected))
    for mode in (torch.no_grad, torch.inference_mode):
        with mode():
            out = render(spikegs.rasterize, scene)
        assert not out.image.requires_grad
        assert all(torch.equal(a, b) for a, b in zip(out, expected))


@needs_cpp
@pytest.mark.skipif(
    not torch._dynamo.is_dynamo_supported(), reason="torch.compile is not supported on this Python"
)
def test_torch_compile_runs_the_op_as_eager_does():
    """A researcher's compiled step: graph breaks around the op (a C++ call), the same numbers and
    gradients, and no recompilation on a second call."""
    import warnings

    graphs = []

    def backend(gm, example_inputs):  # torch's eager backend, counting the graphs it is given
        graphs.append(gm)
        return gm.forward

    scene = make_scene(5, 6, 17, 11, sh_degree=1, dtype=torch.float32)
    expected = _render_and_grads(scene)
    compiled = torch.compile(
        lambda leaves: render(spikegs.rasterize, scene, **leaves), backend=backend
    )
    with warnings.catch_warnings():  # torch's "Dynamo does not know how to trace" the core
        warnings.simplefilter("ignore")
        counts = []
        for _ in range(2):
            got = _render_and_grads(scene, compiled)
            assert all(torch.equal(a, b) for a, b in zip(got, expected))
            counts.append(len(graphs))
    assert counts[0] > 0 and counts[1] == counts[0]  # compiled once
    torch._dynamo.reset()


@needs_cpp
def test_double_backward_is_refused_clearly():
    """A gradient penalty, and a Hessian-vector product (its zeros came back silently)."""
    scene = make_scene(3, 4, 13, 9)
    means = scene["means"].clone().requires_grad_()
    out = render(spikegs.rasterize, scene, means=means)
    with pytest.raises(RuntimeError, match="differentiable once"):
        torch.autograd.grad((out.image**2).sum(), means, create_graph=True)

    def loss(m):
        return render(spikegs.rasterize, scene, means=m).image.square().mean()

    with pytest.raises(RuntimeError, match="differentiable once"):
        torch.autograd.functional.hvp(loss, means.detach(), torch.ones_like(means))
    out = render(spikegs.rasterize, scene, means=means)  # a plain backward still works
    out.image.sum().backward()
    assert means.grad.abs().sum() > 0


@needs_cpp
def test_a_batch_of_gradients_is_refused_clearly():
    """Rows of a Jacobian at once (torch said only "Batching rule not implemented for
    aten::detach"); one row at a time works."""
    scene = make_scene(5, 4, 17, 11)
    means = scene["means"].clone().requires_grad_()
    alpha = render(spikegs.rasterize, scene, means=means).alpha
    rows = torch.eye(alpha.numel(), dtype=alpha.dtype)[:3].view(3, *alpha.shape)
    with pytest.raises(RuntimeError, match="one gradient of its outputs at a time.*batched"):
        torch.autograd.grad(alpha, means, rows, is_grads_batched=True, retain_graph=True)
    row = torch.autograd.grad(alpha, means, rows[1])[0]
    assert row.abs().sum() > 0


@needs_cpp
def test_torch_func_transforms_are_refused_clearly():
    """torch.func.grad, vmap and jacrev said only that the Function "must override the
    setup_context staticmethod"; the reference runs under them."""
    scene = make_scene(5, 4, 17, 11)

    def loss(fn, m):
        return render(fn, scene, means=m).image.sum()

    for transform in (torch.func.grad, torch.func.jacrev):
        with pytest.raises(RuntimeError, match="does not run under torch.func's transforms"):
            transform(lambda m: loss(spikegs.rasterize, m))(scene["means"])
    with pytest.raises(RuntimeError, match="does not run under torch.func's transforms"):
        torch.func.vmap(lambda m: loss(spikegs.rasterize, m))(scene["means"][None])
    by_func = torch.func.grad(lambda m: loss(reference.rasterize, m))(scene["means"])
    means = scene["means"].clone().requires_grad_()
    loss(spikegs.rasterize, means).backward()
    torch.testing.assert_close(by_func, means.grad, rtol=1e-9, atol=1e-12)


def test_only_a_batch_of_gradients_is_said_to_be_one():
    """_grad_array turns torch's "Batching rule" error alone into the batch's message; another
    tensor numpy cannot take (one requiring grad, which the create_graph check keeps out of a
    backward; a contiguous view with torch's negative bit) keeps torch's own, which says how to
    mend it."""
    from spikegs.rasterize import _grad_array

    with pytest.raises(RuntimeError, match="requires grad. Use tensor.detach") as err:
        _grad_array(torch.ones(2, requires_grad=True))
    assert "one gradient of its outputs at a time" not in str(err.value)


@needs_cpp
def test_numpy_integer_sizes_accepted():
    a = render(spikegs.rasterize, _BAD_SCENE)
    b = render(spikegs.rasterize, _BAD_SCENE, width=np.int64(13), height=np.int32(9))
    assert torch.equal(a.image, b.image)


# ---- stiff and extreme cases ------------------------------------------------------------------

EXTREME = {  # name -> (N, (width, height))
    "wide-scales": (12, (33, 17)),
    "ill-conditioned": (10, (33, 17)),
    "near-plane": (12, (33, 17)),
    "opacity-logits": (8, (33, 17)),
    "stacked": (300, (33, 17)),
    "sub-and-screen": (10, (33, 17)),
    "bad-quats": (8, (33, 17)),
    "bad-values": (10, (33, 17)),
    "empty": (0, (33, 17)),
    "huge-extent": (4, (33, 17)),
    "float32-needle": (4, (16, 16)),
    "alpha-min-opacity": (6, (33, 17)),
    "capped-radius": (3, (16, 12)),
    "scaled-viewmat": (3, (33, 17)),
    "width-1": (10, (1, 17)),
    "height-1": (10, (23, 1)),
    "one-pixel": (10, (1, 1)),
}


def _extreme(name: str) -> dict:
    """One stiff or extreme scene by name (float64)."""
    nan, inf = float("nan"), float("inf")
    n, (width, height) = EXTREME[name]
    s = make_scene(list(EXTREME).index(name), n, width, height, sh_degree=1)
    W, t = s["viewmat"][:3, :3], s["viewmat"][:3, 3]

    def at_camera(points) -> torch.Tensor:  # camera-space points -> world means
        return (torch.as_tensor(points, dtype=torch.float64) - t) @ W

    f = s["K"][0, 0].item()
    if name == "wide-scales":
        s["scales"] = torch.logspace(-6, 3, n * 3, dtype=torch.float64).reshape(3, n).T
    elif name == "ill-conditioned":  # covariance condition numbers up to 1e8
        ratio = torch.logspace(0, 4, n, dtype=torch.float64)
        s["scales"] = torch.stack([0.05 * ratio, 0.05 * ratio, 0.05 * torch.ones(n)], -1) * 0.1
    elif name == "near-plane":  # means around and behind z = near, large enough to straddle it
        z = torch.tensor(
            [-2.0, -0.1, 0.0, 0.005, 0.01, 0.0100001, 0.011, 0.02, 0.05, 0.1, 0.3, 1.0]
        )
        s["means"] = at_camera(torch.stack([0.02 * z, -0.01 * z, z], -1))
        s["scales"] = torch.full((n, 3), 0.2, dtype=torch.float64)
    elif name == "opacity-logits":
        s["opacities"] = torch.sigmoid(torch.tensor([30.0, -30.0] * (n // 2), dtype=torch.float64))
        s["means"] = at_camera([[0.1 * i - 0.3, 0.0, 2.0 + 0.01 * i] for i in range(n)])
        s["scales"] = torch.full((n, 3), 0.1, dtype=torch.float64)
    elif name == "stacked":  # hundreds of Gaussians on one pixel: the transmittance stop
        gen = torch.Generator().manual_seed(0)
        s["means"] = at_camera([[0.0, 0.0, 2.0]]) + 1e-4 * torch.randn(
            n, 3, generator=gen, dtype=torch.float64
        )
        s["opacities"] = 0.3 + 0.6 * torch.rand(n, generator=gen, dtype=torch.float64)
    elif name == "sub-and-screen":  # sub-pixel footprints and ones covering the whole image
        s["scales"][: n // 2] = 1e-4 / f
        s["scales"][n // 2 :] = 50.0
    elif name == "huge-extent":  # splats 1e9 px tall: their rows overflow a 32-bit int
        s["means"] = at_camera([[0.1 * i - 0.15, 0.0, 2.0 + 0.1 * i] for i in range(n)])
        s["scales"] = torch.tensor([[0.05, 1e8, 0.05]] * n, dtype=torch.float64)
        s["quats"] = torch.tensor([[1.0, 0.0, 0.0, 0.0]] * n, dtype=torch.float64)
    elif name == "float32-needle":  # 1e18-1e19 px long, 0.03 px wide: rendered in float32,
        # whose backward made NaN of 1/det^2 (an underflow) and of the conic's terms (overflows)
        s["viewmat"] = torch.eye(4, dtype=torch.float64)  # the needle across the view
        s["means"] = torch.tensor([[0.1 * i - 0.15, 0.0, 2.0] for i in range(n)]).double()
        s["scales"] = torch.full((n, 3), 1e-3 * 2.0 / f, dtype=torch.float64)
        s["scales"][:, 0] = torch.tensor([3e18, 6e18, 1e19, 1.5e19]) * 2.0 / f
        c, si = math.cos(0.3), math.sin(0.3)
        s["quats"] = torch.tensor([[c, 0.0, 0.0, si]] * n, dtype=torch.float64)
    elif name == "capped-radius":  # radii over the 2^30 px cap about centres 1e11 px off the
        # image, whose tails still cover it: the reference composited the capped box (nothing, or
        # torch.arange's inverted or int64-overflowing range) where the core renders the tails
        s["K"] = torch.tensor([[1e12, 0, 8.0], [0, 1e12, 6.0], [0, 0, 1]], dtype=torch.float64)
        s["means"] = at_camera([[0.42, 0.145, 3.15], [-0.3, 0.2, 2.5], [0.0, 0.0, 3.0]])
        s["scales"] = torch.full((n, 3), 0.15, dtype=torch.float64)
        s["opacities"] = torch.full((n,), 0.9, dtype=torch.float64)
    elif name == "alpha-min-opacity":  # o at 1/255 (alpha reaches 1/255 at most on the centre)
        s["means"] = at_camera([[0.1 * i - 0.25, 0.0, 2.0] for i in range(n)])
        s["opacities"] = torch.tensor([1 / 255, 1 / 255 + 1e-12, 1 / 255 - 1e-12] * 2).double()
    elif name == "scaled-viewmat":  # not rigid: a mean at -W^T t, in view, has no SH direction
        s["viewmat"] = torch.diag(torch.tensor([2.0, 2.0, 2.0, 1.0], dtype=torch.float64))
        s["viewmat"][2, 3] = -1.0  # W = 2 I: -W^T t = (0, 0, 2), at camera z 3, exactly
        means = [[0.0, 0.0, 2.0], [0.01, 0.0, 2.0], [0.0, -0.02, 2.1]]
        s["means"] = torch.tensor(means, dtype=torch.float64)
    elif name == "bad-quats":
        s["quats"][0] = 0.0
        s["quats"][1, 2] = nan
        s["quats"][2] = 1e-30  # tiny but not zero: a valid rotation
        s["quats"][3, 0] = inf
        s["quats"][4] = 1e160  # |q|^2 overflows: culled (the reference rendered it)
        s["quats"][5] = 1e-170  # |q|^2 underflows to 0: culled
    elif name == "bad-values":
        s["means"][0, 0] = nan
        s["means"][1, 2] = inf
        s["means"][2, 1] = -inf
        s["scales"][3, 1] = nan
        s["opacities"][4] = nan
        s["colors"][5, 2, 0] = inf
        s["scales"][6, 0] = 1e200  # finite, but its covariance overflows
    return s


@pytest.mark.parametrize("name", EXTREME)
def test_extreme_reference(name):
    scene = _extreme(name)
    out, grads = forward_backward(reference.rasterize, scene, torch.float64)
    check_finite_and_culled(out, grads)
    assert out.alpha.numel() == 0 or out.alpha.max().item() <= 1 - reference.T_MIN


@needs_cpp
@pytest.mark.parametrize("antialiased", [False, True], ids=["plain", "antialiased"])
@pytest.mark.parametrize("dtype", [torch.float64, torch.float32], ids=["float64", "float32"])
@pytest.mark.parametrize("name", EXTREME)
def test_extreme_cpp(name, dtype, antialiased):
    scene = {k: v.to(dtype) if torch.is_tensor(v) else v for k, v in _extreme(name).items()}
    scene["antialiased"] = antialiased
    out, grads = forward_backward(spikegs.rasterize, scene, dtype)
    check_finite_and_culled(out, grads)
    if dtype == torch.float64:
        compare_to_reference(scene, dtype, 1e-9)


@pytest.mark.parametrize(
    "op, dtype",
    [
        pytest.param(spikegs.rasterize, torch.float32, marks=needs_cpp, id="cpp-float32"),
        pytest.param(spikegs.rasterize, torch.float64, marks=needs_cpp, id="cpp-float64"),
        (reference.rasterize, torch.float32),
        (reference.rasterize, torch.float64),
    ],
)
def test_the_second_of_two_clamped_gaussians_counts(op, dtype):
    """Two opaque Gaussians (alpha clamped to 0.99) on one pixel leave T = 0.01² = 1e-4, not below
    the stop: the second counts. float32's 0.99 rounds up (0.99000001) and stopped the pixel
    before it, unless the clamp takes the float below."""
    t = lambda x: torch.tensor(x, dtype=dtype)  # noqa: E731
    background = t([0.5]).requires_grad_()
    out = op(
        t([[0.0, 0.0, 2.0], [0.0, 0.0, 3.0]]),
        t([[1.0, 0, 0, 0]] * 2),
        t([[5.0, 5.0, 5.0]] * 2),
        t([1.0, 1.0]),
        t([[1.0], [0.0]]),  # the front one white, the back one black
        torch.eye(4, dtype=dtype),
        t([[8.0, 0, 4], [0, 8.0, 4], [0, 0, 1]]),
        8,
        8,
        background=background,
    )
    out.image[4, 4, 0].backward()
    tol = dict(rtol=1e-5, atol=1e-7)
    torch.testing.assert_close(
        out.alpha[4, 4].double(), torch.tensor(1 - 1e-4, dtype=torch.float64), **tol
    )
    torch.testing.assert_close(
        out.image[4, 4, 0].double(), torch.tensor(0.99 + 0.5e-4, dtype=torch.float64), **tol
    )
    torch.testing.assert_close(
        background.grad.double(), torch.tensor([1e-4], dtype=torch.float64), **tol
    )


@needs_cpp
@pytest.mark.parametrize("length_px", [100, 1000, 10000])
def test_needle_gradients_in_float32(length_px):
    """A needle (0.2 px wide, up to 1e4 px long, turned off the axes): the float32 core's
    gradients match the float64 reference to float32 precision. Through the inverse (dΣ = −QGQ)
    they lost accuracy with the square of the length (5 % at 1000 px)."""
    f, z = 64.0, 2.0
    s = make_scene(0, 1, 64, 64, channels=1)
    s["viewmat"] = torch.eye(4, dtype=torch.float64)
    s["K"] = torch.tensor([[f, 0, 32.3], [0, f, 31.8], [0, 0, 1]], dtype=torch.float64)
    s["means"] = torch.tensor([[0.05, -0.03, z]], dtype=torch.float64)
    s["quats"] = torch.tensor([[math.cos(0.15), 0.1, 0.2, math.sin(0.15)]], dtype=torch.float64)
    s["scales"] = torch.tensor([[0.2, length_px, 0.3]], dtype=torch.float64) * z / f
    s["opacities"] = torch.tensor([0.8], dtype=torch.float64)
    ref, ref_grads = forward_backward(reference.rasterize, s, torch.float64)
    s32 = {k: v.float() if torch.is_tensor(v) else v for k, v in s.items()}
    out, grads = forward_backward(spikegs.rasterize, s32, torch.float32)
    assert torch.equal(out.radii, ref.radii)
    for name in PARAMS:
        g, r = grads[name].double(), ref_grads[name]
        err = ((g - r).norm() / r.norm().clamp_min(1e-30)).item()
        assert err < 2e-3, f"grad {name}: relative error {err:.2g}"


def needles(count: int, length_px: float, seed: int) -> list[dict]:
    """Scenes of one needle each (0.2 px wide, `length_px` long, turned in the image plane by a
    random angle, its centre off the pixel grid), the first at an angle whose axis passes through
    a pixel centre, where float32 rounds its power above 0."""
    gen = torch.Generator().manual_seed(seed)
    angles = torch.cat([torch.tensor([0.38461539149284363]), torch.rand(count - 1, generator=gen)])
    f, z, scenes = 64.0, 2.0, []
    for i, angle in enumerate(angles.tolist()):
        offset = [0.013, -0.007] if i == 0 else (torch.rand(2, generator=gen) - 0.5).tolist()
        scenes.append(
            dict(
                means=torch.tensor([[*[0.1 * o for o in offset], z]]),
                quats=torch.tensor([[math.cos(angle / 2), 0, 0, math.sin(angle / 2)]]),
                scales=torch.tensor([[length_px, 0.2, 0.2]]) * z / f,
                opacities=torch.tensor([0.9]),
                colors=torch.ones(1, 1),
                viewmat=torch.eye(4),
                K=torch.tensor([[f, 0, 32], [0, f, 32], [0, 0, 1]]),
                width=64,
                height=64,
            )
        )
    return scenes


@pytest.mark.parametrize("op", [spikegs.rasterize, reference.rasterize], ids=["core", "reference"])
def test_needle_axis_has_no_holes_in_float32(op):
    """On the axis of a needle 1e4 px long the true power is ~0 and float32 rounds it either way:
    a power > 0 counts as 0 (alpha = opacity) in the reference (the core's, a sum of squares, is
    never positive), where skipping it, as 3DGS does, left pixels of alpha 0 between pixels of
    ~0.7 (the first needle; 3 in 150 random ones)."""
    for scene in needles(40, 1e4, seed=1):
        args = dict(scene)
        dims = (args.pop("width"), args.pop("height"))
        alpha32 = op(*args.values(), *dims).alpha.double()
        alpha64 = spikegs.rasterize(*(v.double() for v in args.values()), *dims).alpha
        assert (alpha32 - alpha64).abs().max() < 1e-3
        # never above the opacity: exp of the rounded power gave up to +1.1e-4 (core)
        assert alpha32.max() <= scene["opacities"][0].double()


@needs_cpp
@pytest.mark.parametrize("dilation", [0.01, 0.1, 0.3])
def test_a_needle_centred_on_the_image_is_drawn_in_float32_as_in_float64(dilation):
    """The conic's form -(A dx² + C dy²)/2 - B dx dy cancels along a long, thin splat, the more
    the lower the dilation (its entries reach 1/dilation): a needle centred on a 256² image, 300
    px long, was 0.037 off in alpha at dilation 0.01 (101 pixels over 1/255; 0.0083 at 0.1, 0.0031
    at 0.3) and its quaternion's gradient 7 % (47 % at 0.1; the rasterizer trial). Taken as a sum
    of squares through the conic's Cholesky factor: 0.0023, 0.0017, 0.0010 (the conic's own
    rounding), the gradient 0.5 % and 1.2 %."""
    angle = math.pi / 4
    values = (
        [[0.0013, -0.0007, 1.0]],
        [[math.cos(angle / 2), 0, 0, math.sin(angle / 2)]],
        [[1e-7, 300 / 256, 1e-7]],
        [0.9],
        [[1.0, 1.0, 1.0]],
    )
    K = [[256.0, 0, 128], [0, 256, 128], [0, 0, 1]]
    alpha, grad = {}, {}
    for dtype in (torch.float32, torch.float64):
        params = [torch.tensor(v, dtype=dtype, requires_grad=True) for v in values]
        out = spikegs.rasterize(
            *params,
            torch.eye(4, dtype=dtype),
            torch.tensor(K, dtype=dtype),
            256,
            256,
            dilation=dilation,
        )
        out.alpha.sum().backward()
        alpha[dtype], grad[dtype] = out.alpha.double(), params[1].grad.double()
    assert (alpha[torch.float32] - alpha[torch.float64]).abs().max() < 0.003
    assert alpha[torch.float64].max() > 0.3  # (drawn)
    error = (grad[torch.float32] - grad[torch.float64]).norm() / grad[torch.float64].norm()
    assert error < 0.02 or dilation > 0.1  # (0.49 of a gradient of ~1 at 0.3: was 6.8)


@pytest.mark.parametrize(
    "op",
    [pytest.param(spikegs.rasterize, marks=needs_cpp, id="core"), reference.rasterize],
)
def test_a_needle_whose_backward_would_overflow_is_culled(op):
    """A float32 needle ~1e18 long (0.03 and 0.17 across) projected finite and drew nothing, but
    its backward's 2 |V|³ terms overflowed: 0 · inf gave NaN gradients, and through their sum the
    view matrix's too, ruining a second, ordinary Gaussian's pose refinement. Now culled there."""
    t = lambda x: torch.tensor(x, dtype=torch.float32)  # noqa: E731
    for length in (9.8e17, 1e18, 1.03e18):
        viewmat = torch.eye(4, requires_grad=True)
        params = [
            t([[0.672, 1.1756, 1.517], [0.0, 0.0, 2.0]]),
            t([[-0.6839, -0.3240, 0.0051, -1.1001], [1.0, 0.0, 0.0, 0.0]]),
            t([[0.0305, length, 0.172], [0.1, 0.1, 0.1]]),
            t([0.544, 0.9]),
            t([[1.0, 0.5], [0.2, 0.4]]),
        ]
        params = [p.requires_grad_() for p in params]
        K = t([[20.0, 0, 2], [0, 20.0, 3], [0, 0, 1]])
        out = op(*params, viewmat, K, 4, 6)
        out.image.sum().backward()
        assert out.radii[0] == 0 and out.radii[1] > 0
        for grad in [p.grad for p in params] + [viewmat.grad]:
            assert torch.isfinite(grad).all()
        assert viewmat.grad.abs().sum() > 0


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64], ids=["float32", "float64"])
@pytest.mark.parametrize(
    "op",
    [pytest.param(spikegs.rasterize, marks=needs_cpp, id="core"), reference.rasterize],
)
def test_a_splat_centred_past_max_mean2d_is_culled(op, dtype):
    """A needle centred 2e19 px off the image whose ellipse reached it: float32's power was
    inf - inf, a NaN that reached exp's integer conversion (undefined). Splats centred farther
    than 2^40 px (in x or y) are culled; one centred 20 px off still renders."""
    c, s = math.cos(math.pi / 8), math.sin(math.pi / 8)
    t = lambda x: torch.tensor(x, dtype=dtype)  # noqa: E731
    K = t([[100.0, 0, 8], [0, 100.0, 8], [0, 0, 1]])
    for centre, length, culled in ((2e17, 1e17, True), (0.2, 0.1, False)):
        out = op(
            t([[centre, centre, 1.0]]),
            t([[c, 0, 0, s]]),
            t([[length, 1e-3, 1e-3]]),
            t([1.0]),
            t([[1.0]]),
            torch.eye(4, dtype=dtype),
            K,
            16,
            16,
        )
        assert (out.radii[0] == 0) == culled
        assert torch.isfinite(out.image).all() and (out.alpha.max() > 0) != culled


OUT_OF_MEMORY = """
import resource, torch
from pathlib import Path
from spikegs.rasterize import rasterize

def limit(extra):  # address space: what the process maps now, plus `extra` bytes
    status = Path("/proc/self/status").read_text().splitlines()
    size = next(int(l.split()[1]) for l in status if l.startswith("VmSize:"))
    resource.setrlimit(resource.RLIMIT_AS, (size * 1024 + extra, resource.RLIM_INFINITY))

C = 1 << 18  # a tile's accumulators: 256 C floats = 256 MiB a thread, 2 threads
colors = torch.rand(1, C, requires_grad=True)
viewmat = torch.eye(4)
viewmat[2, 3] = 3.0  # the Gaussian 3 units in front of the camera
args = (torch.zeros(1, 3), torch.tensor([[1.0, 0, 0, 0]]), torch.full((1, 3), 0.1),
        torch.tensor([0.5]), colors, viewmat, torch.tensor([[10.0, 0, 1], [0, 10, 1], [0, 0, 1]]),
        2, 2)
for stage in ("forward", "backward"):
    image = rasterize(*args).image if stage == "backward" else None
    limit(1 << 28)  # less than two threads' accumulators
    try:
        (rasterize(*args).image if image is None else image).sum().backward()
        print(stage, "ran")
    except MemoryError as err:  # named with the work (it said "std::bad_alloc")
        print(stage, "MemoryError", str(err).startswith(f"rasterize {stage}: out of memory with "
              "1 Gaussians, 2x2 pixels, 262144 channel(s)"))
    resource.setrlimit(resource.RLIMIT_AS, (resource.RLIM_INFINITY,) * 2)
print("after", rasterize(*args[:4], colors[:, :3].detach(), *args[5:]).image.shape)
"""


@needs_cpp
@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="needs Linux's /proc")
def test_out_of_memory_is_a_memory_error():
    """Buffers too large for memory (a tile's accumulators, 256 floats a channel and thread) raise
    MemoryError in the forward and in the backward, and the process goes on; allocated inside
    the OpenMP region, std::bad_alloc aborted the process. The address space is limited in a
    subprocess, so that the test does not depend on the machine's memory."""
    env = {**os.environ, "OMP_NUM_THREADS": "2"}
    done = subprocess.run(
        [sys.executable, "-c", OUT_OF_MEMORY], capture_output=True, text=True, env=env
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.split("\n")[:3] == [
        "forward MemoryError True",
        "backward MemoryError True",
        "after torch.Size([2, 2, 3])",
    ], done.stdout


@needs_cpp
def test_the_core_binding_checks_what_the_core_assumes():
    """Direct `_C` callers (spikegs.rasterize checks all of this first): a backward on inputs that
    are not the forward's read an unset projection (valgrind: uninitialised values in the
    gradients), and a short background past its end; a negative near, an opacity above 1, a zero
    focal length broke the binning's order, the alpha cut-off, the projection."""
    s = {k: v.numpy() if torch.is_tensor(v) else v for k, v in make_scene(7, 6, 13, 9).items()}
    arrays = [s[k] for k in ("means", "quats", "scales", "opacities", "colors")]

    def forward(**changes):
        a = {"viewmat": s["viewmat"], "K": s["K"], "near": 0.01, "opacities": s["opacities"]}
        a.update(changes)
        inputs = [*arrays[:3], a["opacities"], arrays[4], a["viewmat"], a["K"]]
        return spikegs._C.rasterize_forward_float64(
            *inputs, 13, 9, -1, 1, 3, s["background"], a["near"], 1e10
        )

    for changes, message in (
        ({"near": -0.5}, "0 < near < far"),
        ({"opacities": s["opacities"] * 3}, "opacities in \\[0, 1\\]"),
        ({"K": s["K"] * np.array([0.0, 1, 1])[:, None]}, "focal lengths"),
    ):
        with pytest.raises(ValueError, match=message):
            forward(**changes)
    *out, ctx = forward()
    assert (out[2] > 0).any()
    W, t = s["viewmat"][:3, :3], s["viewmat"][:3, 3]
    camera = arrays[0] @ W.T + t  # [N, 3] camera-space means, z > 0
    behind = (-camera - t) @ W  # [N, 3] world means at -camera: behind the camera
    backward = spikegs._C.rasterize_backward_float64
    image_grad = np.ones((9, 13, 3))
    grads = backward(ctx, behind, *arrays[1:], s["background"], image_grad, None, None, None)
    for g in grads[:5]:  # every Gaussian culled there: no gradient, not garbage
        assert np.isfinite(g).all() and not g.any()
    with pytest.raises(ValueError, match="background must have C entries"):
        backward(ctx, *arrays, np.zeros(1), image_grad, None, None, None)


@needs_cpp
def test_the_core_binding_refuses_sizes_it_would_read_past():
    """Direct `_C` callers: arrays shorter than N, C, the SH degree, the image or a 4x4 view
    matrix say, and SH settings out of range, are refused before the core reads past their ends
    (spikegs.rasterize checks all of this first, with messages of its own)."""
    s = {k: v.numpy() if torch.is_tensor(v) else v for k, v in make_scene(8, 6, 13, 9).items()}
    a = {k: s[k] for k in ("means", "quats", "scales", "opacities", "colors", "viewmat", "K")}
    settings = {"width": 13, "height": 9, "sh_degree": -1, "sh_coeffs": 1, "channels": 3}

    def forward(**changes):
        args = {**a, **settings, "background": s["background"], "near": 0.01, "far": 1e10}
        return spikegs._C.rasterize_forward_float64(**{**args, **changes})

    for changes, message in (
        ({"channels": 0}, "sh_degree in -1..3"),
        ({"sh_degree": 4, "sh_coeffs": 25}, "sh_degree in -1..3"),
        ({"sh_degree": 1, "sh_coeffs": 3}, r"sh_coeffs >= \(degree \+ 1\)\^2"),
        ({"means": s["means"][:, :2]}, "input sizes do not match N = 6"),
        ({"quats": s["quats"][:, :3]}, "input sizes do not match N = 6"),
        ({"scales": s["scales"][:5]}, "input sizes do not match N = 6"),
        ({"opacities": s["opacities"][:5]}, "input sizes do not match N = 6"),
        ({"colors": s["colors"][:, :2]}, "input sizes do not match N = 6"),
        ({"viewmat": s["viewmat"][:3]}, "viewmat must be 4x4, K 3x3"),
        ({"K": s["K"][:2, :2]}, "viewmat must be 4x4, K 3x3"),
        ({"width": 0}, r"width and height in 1\.\.2\^20"),
        ({"height": 2**20 + 1}, r"width and height in 1\.\.2\^20"),
        ({"dilation": 0.005}, r"dilation in min_dilation\.\.max_dilation"),
        ({"dilation": float("inf")}, r"dilation in min_dilation\.\.max_dilation"),
        ({"dilation": float("nan")}, r"dilation in min_dilation\.\.max_dilation"),
    ):
        with pytest.raises(ValueError, match=message):
            forward(**changes)
    *_, ctx = forward()
    arrays = [a[k] for k in ("means", "quats", "scales", "opacities", "colors")]
    image_grad, alpha_grad = np.ones((9, 13, 3)), np.ones((9, 13))

    def backward(inputs=arrays, image=image_grad, alpha=None, means2d=None, depths=None):
        return spikegs._C.rasterize_backward_float64(
            ctx, *inputs, s["background"], image, alpha, means2d, depths
        )

    assert len(backward(alpha=alpha_grad, means2d=np.ones((6, 2)), depths=np.ones(6))) == 9
    with pytest.raises(ValueError, match="the forward's context holds 6 Gaussians, not 5"):
        backward(inputs=[x[:5] for x in arrays])
    for grads in ({"image": image_grad[:8]}, {"alpha": alpha_grad[:, :12]}):
        with pytest.raises(ValueError, match="gradient shapes do not match the image"):
            backward(**grads)
    for grads in ({"means2d": np.ones((5, 2))}, {"depths": np.ones(7)}):
        with pytest.raises(ValueError, match="gradient shapes do not match the Gaussians"):
            backward(**grads)


FORKED_RENDER = """
import multiprocessing, torch
from spikegs import rasterize

def render(_=None):
    means = torch.tensor([[0.0, 0, 3], [0.2, 0.1, 4]])
    K = torch.tensor([[20.0, 0, 8], [0, 20, 8], [0, 0, 1]])
    return rasterize(means, torch.tensor([[1.0, 0, 0, 0]] * 2), torch.full((2, 3), 0.2),
                     torch.tensor([0.5, 0.7]), torch.rand(2, 3, generator=torch.Generator()
                     .manual_seed(0)), torch.eye(4), K, 16, 16).image.sum().item()

torch.set_num_threads(2)
first = render()  # the parent's team of two threads: libgomp keeps them in a pool
with multiprocessing.get_context("fork").Pool(1) as pool:
    try:
        print("child", pool.apply_async(render).get(timeout=30) == first)
    except multiprocessing.TimeoutError:
        print("child hung")
"""


@needs_cpp
@pytest.mark.skipif(not hasattr(os, "fork"), reason="fork: POSIX only")
def test_a_forked_child_renders_after_the_parent_did():
    """A fork pool's worker renders what the parent rendered before it forked: its first team of
    two threads waited forever for the parent's pool threads (GNU libgomp), until spikegs set one
    thread in forked children. In a subprocess, so that the test forks no pytest process."""
    done = subprocess.run(
        [sys.executable, "-c", FORKED_RENDER], capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.split("\n")[0] == "child True", done.stdout


@needs_cpp
@pytest.mark.parametrize(
    "dtype, depth, drawn",
    [(torch.float32, 1e20, False), (torch.float32, 1e-19, False), (torch.float64, 1e20, True)],
)
def test_a_depth_whose_square_leaves_the_normal_range_is_culled(dtype, depth, drawn):
    """A Gaussian 1e20 away in float32 (z² overflows), or 1e-19 near (z² underflows), was drawn
    with NaN and infinite gradients of its mean and of the view matrix (the core trial): culled,
    zero gradients; float64 draws it, its gradients those of a 1e20-fold scene (1/z)."""
    scene = make_scene(2, 2, 37, 23, dtype=dtype)
    scene["viewmat"] = torch.eye(4, dtype=dtype)
    scene["means"] = torch.tensor([[0.3, 0.1, 1.0], [0.0, 0.0, 1.0]], dtype=dtype)
    scene["scales"] = torch.full((2, 3), 0.01, dtype=dtype)
    scene["K"] = torch.tensor([[30.0, 0, 18.5], [0, 30.0, 11.5], [0, 0, 1]], dtype=dtype)
    scene.update(near=1e-35, far=3e38)
    out, grads = forward_backward(spikegs.rasterize, scene, dtype)
    scene["means"][0] *= depth
    scene["scales"][0] *= depth
    far, far_grads = forward_backward(spikegs.rasterize, scene, dtype)
    assert far.radii.tolist() == [out.radii[0] if drawn else 0, out.radii[1]]
    check_finite_and_culled(far, far_grads)
    if drawn:  # (x and y: the depth output's own gradient is 1 at any depth)
        torch.testing.assert_close(far_grads["means"][0, :2] * depth, grads["means"][0, :2])


@needs_cpp
def test_a_float32_splat_whose_determinant_overflows_is_culled():
    """DESIGN §4: a Gaussian whose 2D determinant is not finite is culled. A round splat ~1e10 px
    wide in float32: its covariance entries (~1e20) and the backward's largest terms (~1e30) are
    finite, its determinant (~1e40) is not; with that guard dropped it was rendered (conic 0)."""
    scene = make_scene(3, 2, 16, 12, dtype=torch.float32)
    scene["viewmat"] = torch.eye(4, dtype=torch.float32)
    scene["means"] = torch.tensor([[0.0, 0.0, 2.0], [0.05, 0.0, 2.0]])
    scene["scales"][0] = 1e10 * 2.0 / scene["K"][0, 0]
    out, grads = forward_backward(spikegs.rasterize, scene, torch.float32)
    assert out.radii.tolist()[0] == 0 and out.radii.tolist()[1] > 0
    check_finite_and_culled(out, grads)


@needs_cpp
@pytest.mark.parametrize("dtype, far", [(torch.float32, 1.35e19), (torch.float64, 1e154)])
def test_sh_colour_of_a_gaussian_whose_squared_distance_overflows(dtype, far):
    """rasterizer.md step 9: the view direction is d/|d| whatever its size. |d|² overflowed at
    distances past 1.8e19 (float32) and 1.3e154 (float64): float32 rendered black with NaN
    gradients (means, SH, the viewmat's), float64 band 0 alone (the C++-core trial)."""

    def rendered(dtype, distance):
        leaves = {
            "means": torch.tensor([[distance, 0.0, distance]], dtype=dtype),
            "quats": torch.tensor([[1.0, 0.0, 0.0, 0.0]], dtype=dtype),
            "scales": torch.ones(1, 3, dtype=dtype),
            "opacities": torch.tensor([0.8], dtype=dtype),
            "colors": torch.tensor([[[0.1], [0.3], [-0.2], [0.25]]], dtype=dtype),  # degree 1
            "viewmat": torch.eye(4, dtype=dtype),
        }
        leaves = {name: t.requires_grad_() for name, t in leaves.items()}
        K = torch.tensor([[1.0, 0, 7.0], [0, 1.0, 8.0], [0, 0, 1]], dtype=dtype)  # at (8, 8)
        out = spikegs.rasterize(*leaves.values(), K, 16, 16, far=3 * distance)
        out.image.sum().backward()
        return out.image.double(), {name: t.grad.double() for name, t in leaves.items()}

    image, grads = rendered(dtype, far)
    near_image, near_grads = rendered(torch.float64, 1e3)  # the same direction, (1, 0, 1)/√2
    assert image.sum() > 0.5
    torch.testing.assert_close(image, near_image, rtol=1e-5, atol=1e-6)
    torch.testing.assert_close(grads["colors"], near_grads["colors"], rtol=1e-5, atol=1e-6)
    assert all(g.isfinite().all() for g in grads.values())
    # the direction's slope falls as 1/|d|: the means' gradient is the near one's x 1e3 / far
    torch.testing.assert_close(grads["means"] * far / 1e3, near_grads["means"], rtol=1e-3, atol=0)
