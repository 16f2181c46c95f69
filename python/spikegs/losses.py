"""The SpikeGS losses (paper eqs. 7, 10, 16) and an optional differentiable D-SSIM term."""

from __future__ import annotations

import contextlib
import math

import numpy as np
import torch
import torch.nn.functional as F

from .number_checks import is_int, is_number


def _smooth_l1(render: torch.Tensor, target: torch.Tensor, quantum: float | None) -> torch.Tensor:
    """L1 with a quadratic zone one `quantum` wide (the target's step, one spike of its TFP
    window): over views its optimum is the mean of quantised counts, as L2's, with L1's gradient
    wherever the residual exceeds a spike."""
    if not (is_number(quantum) and 0 <= quantum < math.inf):  # torch: "negative values for beta"
        raise ValueError(
            f"smooth_l1 expected the target's quantum, a finite number >= 0 (one spike of its TFP "
            f"window), got {quantum!r}"
        )
    return F.smooth_l1_loss(render, target, beta=quantum)


# norm name -> loss(render, target, quantum): l1 the paper's, whose optimum over views is the
# median of a quantised TFP (biased by up to half a spike); l2 and smooth_l1 the mean
NORMS = {
    "l1": lambda render, target, quantum: F.l1_loss(render, target),
    "l2": lambda render, target, quantum: F.mse_loss(render, target),
    "smooth_l1": _smooth_l1,
}

# SIM's self-supervised loss against TFP (paper eq. 15: l1; l2 the mean, the default)
SIM_LOSSES = {"l1": F.l1_loss, "l2": F.mse_loss}


def check_images(render, target, what: str) -> None:
    """ValueError unless `render` and `target` are floating-point torch tensors of one shape
    [H, W, C]: torch broadcast a mono target [H, W] (SpikeStream.tfp's) against a square [H, W,
    1] render to [H, W, W] and returned a wrong loss with a warning."""
    for name, image in (("render", render), ("target", target)):
        if not isinstance(image, torch.Tensor):
            raise ValueError(
                f"{what}: {name} expected a torch tensor, got {type(image).__name__} "
                f"(torch.from_numpy converts an array)"
            )
        if not image.is_floating_point():
            raise ValueError(f"{what}: {name} expected floating point, got {image.dtype}")
    if render.dim() != 3 or render.shape != target.shape:
        mono = " (a mono target [H, W] needs its channel axis: target[..., None])"
        hint = mono if target.dim() == 2 else ""
        raise ValueError(
            f"{what}: render {list(render.shape)} and target {list(target.shape)} expected one "
            f"shape [H, W, C]{hint}"
        )


def _norm(norm: str):
    """NORMS[norm]; ValueError naming the known norms."""
    if norm not in NORMS:
        raise ValueError(f"unknown norm {norm!r}: one of {', '.join(NORMS)}")
    return NORMS[norm]


def instant_loss(
    render: torch.Tensor, target: torch.Tensor, norm: str = "l1", quantum: float | None = None
) -> torch.Tensor:
    """L_instant = |render(t) - Ī(t)|₁ (or another of NORMS), mean over pixels; [H, W, C];
    `quantum`: the target's step, one spike of its window (smooth_l1's quadratic zone)."""
    check_images(render, target, "instant_loss")
    return _norm(norm)(render, target, quantum)


def exposure_times(t: float, window: int, poses: int) -> np.ndarray:
    """The K = `poses` readout times whose renders average to the exposure of the `window`
    readouts centred on t: the midpoints of K equal parts of [t - window/2, t + window/2] (the
    midpoint rule for paper eq. 8; K samples from end to end would spread the blur wider)."""
    if not (is_int(poses) and poses >= 1 and is_number(window) and window > 0):
        raise ValueError(
            f"exposure_times: expected an integer number of poses >= 1 and a window > 0, got "
            f"poses {poses!r}, window {window!r}"
        )
    step = window / poses
    return t - window / 2 + step * (np.arange(poses) + 0.5)  # [K]


def exposure_loss(
    renders: list[torch.Tensor] | torch.Tensor,
    target: torch.Tensor,
    norm: str = "l1",
    quantum: float | None = None,
) -> torch.Tensor:
    """L_exposure = |mean_k render(t_k) - TFP over Γ(t)|₁ (or another of NORMS); renders
    K x [H, W, C] (a list, or stacked [K, H, W, C]), target [H, W, C]; `quantum`: one spike of
    the TFP window in target units."""
    if isinstance(renders, torch.Tensor) and renders.dim() != 4:
        raise ValueError(
            f"exposure_loss: renders expected stacked [K, H, W, C] or a list of [H, W, C], got "
            f"a tensor {list(renders.shape)}"
        )
    if not len(renders):
        raise ValueError("exposure_loss: expected one render or more")
    for render in renders:
        check_images(render, target, "exposure_loss")
    stacked = renders if isinstance(renders, torch.Tensor) else torch.stack(list(renders))
    return _norm(norm)(stacked.mean(dim=0), target, quantum)


# a blur wider than this many pixels (σ) is made in Fourier space: the convolution's cost grows
# with its taps, forward and backward 251 against 7.7 ms for σ = 16 at 512², 20 against 2.6 ms
# for σ = 8 at 256²; at σ = 4 at 128², 0.63 against 0.80 ms (BENCHMARKS.md, "eval
# --align-poses: blurred first")
LONG_BLUR = 2.0


def _gaussian_taps(sigma: float) -> torch.Tensor:
    """The normalised 1-D Gaussian of width `sigma` (pixels) over ±3σ, rounded up: [2⌈3σ⌉ + 1]
    taps (11 for SSIM's σ = 1.5; its 2-D window is the outer product)."""
    r = math.ceil(3 * sigma)
    x = torch.arange(-r, r + 1, dtype=torch.float32)
    g = torch.exp(-(x**2) / (2 * sigma**2))
    return g / g.sum()


def gaussian_blur(maps: torch.Tensor, sigma: float = 1.5) -> torch.Tensor:
    """Each of `maps` [1, n, H, W] blurred by a Gaussian of width `sigma` (pixels; SSIM's window
    by default) over ±3σ, zero padding. Up to LONG_BLUR pixels wide, as two 1-D passes of one
    grouped convolution each: the 11x11 window in one convolution a map took 20x as long (79
    against 3.6 ms forward and backward at 128², one map's own convolution is no depthwise kernel
    in oneDNN); wider, as products in Fourier space, whose cost the width does not set."""
    g = _gaussian_taps(sigma).to(maps)
    if sigma > LONG_BLUR:
        return _fourier_blur(_fourier_blur(maps, g, 3), g, 2)
    n, r = maps.shape[1], g.numel() // 2
    rows = F.conv2d(maps, g.view(1, 1, 1, -1).expand(n, 1, 1, -1), padding=(0, r), groups=n)
    return F.conv2d(rows, g.view(1, 1, -1, 1).expand(n, 1, -1, 1), padding=(r, 0), groups=n)


def _fourier_blur(maps: torch.Tensor, taps: torch.Tensor, dim: int) -> torch.Tensor:
    """`maps` convolved along `dim` with the symmetric `taps` [2r + 1], zero padding: a circular
    convolution over the axis padded by r zeros (2r + 1 in all at least), which the wrap then
    reads in place of the zeros beyond either end."""
    n, r = maps.shape[dim], taps.numel() // 2
    m = max(n + r, 2 * r + 1)
    kernel = maps.new_zeros(m)  # the taps centred on index 0, wrapped
    kernel[: r + 1], kernel[m - r :] = taps[r:], taps[:r]
    shape = [1] * maps.dim()
    shape[dim] = m // 2 + 1
    spectrum = torch.fft.rfft(maps, n=m, dim=dim) * torch.fft.rfft(kernel).view(shape)
    return torch.fft.irfft(spectrum, n=m, dim=dim).narrow(dim, 0, n)


def _has_autocast(device: str) -> bool:
    """Whether torch.autocast takes `device` (torch before 2.4 has no is_autocast_available and
    autocasts CPU and CUDA alone)."""
    available = getattr(torch.amp, "is_autocast_available", None)
    return available(device) if available else device in ("cpu", "cuda")


def dssim(render: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """(1 - SSIM) / 2 with the usual 11x11 Gaussian window (σ = 1.5); images [H, W, C] in [0, 1]
    (floating point: integer images blurred by integer taps gave 0 for any pair). Computed in
    float32 at least, torch.autocast or not: the variances (E[x²] - E[x]²) cancel, and bfloat16
    blurs scored a render 0.005 off its target 0 (in float32 6.8e-4)."""
    check_images(render, target, "dssim")
    c = render.shape[-1]
    dtype = torch.promote_types(torch.promote_types(render.dtype, target.dtype), torch.float32)
    x, y = (t.to(dtype).permute(2, 0, 1)[None] for t in (render, target))  # [1, C, H, W]
    device = render.device.type  # (a meta tensor has no autocast to turn off)
    with (
        torch.autocast(device, enabled=False) if _has_autocast(device) else contextlib.nullcontext()
    ):
        # the five local moments' means, blurred together: [1, 5C, H, W] -> 5 x [1, C, H, W]
        blurred = gaussian_blur(torch.cat([x, y, x * x, y * y, x * y], 1))
    mx, my, xx, yy, xy = blurred.split(c, 1)
    vx, vy, cxy = xx - mx**2, yy - my**2, xy - mx * my
    c1, c2 = 0.01**2, 0.03**2
    s = ((2 * mx * my + c1) * (2 * cxy + c2)) / ((mx**2 + my**2 + c1) * (vx + vy + c2))
    return (1 - s.mean()) / 2
