"""`spikegs.rasterize`: the C++ tile rasterizer as one differentiable torch op.

The maths is in docs/rasterizer.md.
"""

from __future__ import annotations

from typing import NamedTuple

import torch

from . import _C
from .number_checks import as_flag, is_int, is_real
from .sh import degree_of

CONSTANTS = _C.constants  # tile_size, alpha_max, alpha_min, transmittance_min, dilation, ...
MAX_SIZE = CONSTANTS["max_image_size"]  # image width and height (the core's 32-bit indices)


class RasterizeResult(NamedTuple):
    image: torch.Tensor  # [H, W, C]
    alpha: torch.Tensor  # [H, W] 1 - final transmittance
    radii: torch.Tensor  # [N] int32 pixels, 0 = culled (no gradient)
    means2d: torch.Tensor  # [N, 2] projected centres (pixels), 0 where culled
    depths: torch.Tensor  # [N] camera-space z, 0 where culled


def _half_hint(name: str, got: torch.dtype, want: torch.dtype = torch.float32) -> str:
    """What to do with a half-precision input (torch.autocast makes a layer's output bfloat16)."""
    if got not in (torch.float16, torch.bfloat16):
        return ""
    cast = "float()" if want == torch.float32 else "double()"
    return f"; the op has no half-precision path: pass {name}.{cast} (under torch.autocast too)"


def _check(name: str, t, shape: tuple, dtype: torch.dtype) -> torch.Tensor:
    """Raise ValueError naming `name` unless `t` is a CPU `dtype` tensor of `shape` (None: any)."""
    if not isinstance(t, torch.Tensor):
        raise ValueError(f"{name}: expected a torch.Tensor, got {type(t).__name__}")
    if t.device.type != "cpu":
        raise ValueError(f"{name}: expected a CPU tensor, got one on device '{t.device}'")
    if t.layout != torch.strided:
        raise ValueError(f"{name}: expected a dense tensor, got layout {t.layout}")
    if t.dtype != dtype:
        raise ValueError(
            f"{name}: expected dtype {dtype} (the dtype of means), got {t.dtype}"
            + _half_hint(name, t.dtype, dtype)
        )
    if t.dim() != len(shape) or any(s is not None and s != d for s, d in zip(shape, t.shape)):
        want = ", ".join("*" if s is None else str(s) for s in shape)
        raise ValueError(f"{name}: expected shape [{want}], got {list(t.shape)}")
    return t


def _check_intrinsics(K: torch.Tensor) -> None:
    """ValueError unless K is [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] with fx, fy > 0 (the op reads
    only fx, fy, cx, cy: a skew or another last row would be ignored)."""
    k = K.detach().double().tolist()  # Python floats: a tensor's indexing took ~30 us a render
    if not (k[0][0] > 0 and k[1][1] > 0):
        raise ValueError(f"K: expected focal lengths fx = K[0,0], fy = K[1,1] > 0, got {k}")
    if k[0][1] != 0 or k[1][0] != 0 or k[2] != [0.0, 0.0, 1.0]:
        raise ValueError(f"K: expected [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] (no skew), got {k}")


_LOW, _HIGH = CONSTANTS["min_dilation"], CONSTANTS["max_dilation"]
# what a dilation must be, for the errors of `check_dilation` and the config's `train.dilation`
DILATION_EXPECTED = (
    f"pixels² in {_LOW:g}..{_HIGH:g} (3DGS's 0.3, Mip-Splatting's 0.1; below {_LOW:g} a sub-pixel "
    f"splat falls between pixels)"
)


def _as_number(value):
    """A one-element tensor's value as a Python number (`.item()`), anything else as given: a
    number argument takes either."""
    return value.item() if isinstance(value, torch.Tensor) and value.numel() == 1 else value


def is_dilation(value) -> bool:
    """Whether `value` is a real number (or a one-element tensor holding one) in the core's
    range of dilations (px²)."""
    value = _as_number(value)
    return is_real(value) and _LOW <= value <= _HIGH


def check_dilation(dilation, name: str = "dilation") -> None:
    """Raise ValueError unless `dilation` is a real number in the core's range (px²)."""
    if not is_dilation(dilation):
        raise ValueError(f"{name}: expected {DILATION_EXPECTED}, got {dilation!r}")


def _sh_layout(colors: torch.Tensor, sh_degree: int | None) -> tuple[int, int]:
    """(sh_degree, coefficients per Gaussian) for `colors`; degree -1 means direct colours."""
    degree = degree_of(colors, sh_degree)
    return (-1, 1) if degree is None else (degree, colors.shape[1])


def _grad_array(grad: torch.Tensor):
    """An output's gradient as the core's array; RuntimeError naming the op for a batch of
    gradients at once (`is_grads_batched=True`, `jacobian(vectorize=True)`), whose batched
    tensor holds no array (torch said only "Batching rule not implemented for aten::detach")."""
    try:
        return grad.contiguous().numpy()
    except RuntimeError as err:
        if "Batching rule" not in str(err):
            raise
        raise RuntimeError(
            "spikegs.rasterize: its backward takes one gradient of its outputs at a time, not a "
            f"batch (is_grads_batched=True, jacobian(vectorize=True)); loop over them ({err})"
        ) from None


class _RasterizeFunction(torch.autograd.Function):
    @staticmethod
    def forward(
        ctx,
        means,
        quats,
        scales,
        opacities,
        colors,
        viewmat,
        background,
        screen_points,
        screen_abs,
        K,
        settings,
    ):
        core = "float64" if means.dtype == torch.float64 else "float32"
        arrays = [
            t.detach().contiguous().numpy() for t in (means, quats, scales, opacities, colors)
        ]
        bg = None if background is None else background.detach().contiguous().numpy()
        image, alpha, radii, means2d, depths, raster = getattr(_C, f"rasterize_forward_{core}")(
            *arrays,
            viewmat.detach().contiguous().numpy(),
            K.detach().contiguous().numpy(),
            settings["width"],
            settings["height"],
            settings["sh_degree"],
            settings["sh_coeffs"],
            settings["channels"],
            bg,
            settings["near"],
            settings["far"],
            settings["antialiased"],
            settings["dilation"],
        )
        ctx.raster, ctx.core, ctx.image_shape = raster, core, image.shape
        ctx.screen_abs = screen_abs
        ctx.set_materialize_grads(False)  # outputs the loss leaves out: None, not zero arrays
        ctx.save_for_backward(means, quats, scales, opacities, colors, background)
        outputs = tuple(torch.from_numpy(x) for x in (image, alpha, radii, means2d, depths))
        ctx.mark_non_differentiable(outputs[2])
        return outputs

    @staticmethod
    def backward(ctx, grad_image, grad_alpha, _grad_radii, grad_means2d, grad_depths):
        # grad mode is on in a backward only for create_graph=True: a Hessian, a gradient penalty
        # (torch's once_differentiable returned their second derivatives as silent zeros)
        if torch.is_grad_enabled():
            raise RuntimeError(
                "spikegs.rasterize is differentiable once: its backward cannot build a graph "
                "(create_graph=True); spikegs.reference.rasterize has second derivatives"
            )
        means, quats, scales, opacities, colors, background = ctx.saved_tensors
        if grad_image is None:
            grad_image = means.new_zeros(ctx.image_shape)
        grads_in = (grad_image, grad_alpha, grad_means2d, grad_depths)
        arrays = [
            t.detach().contiguous().numpy() for t in (means, quats, scales, opacities, colors)
        ]
        bg = None if background is None else background.detach().contiguous().numpy()
        grads = getattr(_C, f"rasterize_backward_{ctx.core}")(
            ctx.raster,
            *arrays,
            bg,
            *(None if g is None else _grad_array(g) for g in grads_in),
        )
        dmeans, dquats, dscales, dopac, dcolors, dviewmat, dbackground, dmeans2d, dabs = map(
            torch.from_numpy, grads
        )
        if ctx.screen_abs is not None:
            ctx.screen_abs += dabs
        dbackground = dbackground if ctx.needs_input_grad[6] else None
        dmeans2d = dmeans2d if ctx.needs_input_grad[7] else None
        grads = (dmeans, dquats, dscales, dopac, dcolors, dviewmat, dbackground, dmeans2d)
        return grads + (None, None, None)


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
    near: float = CONSTANTS["near"],
    far: float = CONSTANTS["far"],
    screen_points: torch.Tensor | None = None,
    screen_abs: torch.Tensor | None = None,
    antialiased: bool = False,
    dilation: float = CONSTANTS["dilation"],
) -> RasterizeResult:
    """Render N Gaussians into one [H, W, C] image of `width` × `height` pixels, differentiably.

    means [N, 3], quats [N, 4] (w, x, y, z, any norm), scales [N, 3] and opacities [N] (already
    activated), colors [N, C] (direct) or [N, K, C] (SH coefficients, degree `sh_degree` or
    sqrt(K) - 1; a mono scene's are [N, K, 1], and [N, 1, 4 | 9 | 16] needs `sh_degree`),
    viewmat [4, 4] world-to-camera (OpenCV; its top 3x4 rows read as an affine map, not checked
    for rigidity), K [3, 3] intrinsics (no gradient: one requiring grad is refused), background
    [C]. Pixel (u, v) has its centre at (u + 0.5, v + 0.5) in K's pixels.
    All float32 (the fast core) or all float64 (the double core, for gradcheck), on the CPU; one
    camera a call (no batch dimension). Returns RasterizeResult: image [H, W, C], alpha [H, W],
    radii [N] int32, means2d [N, 2] pixels, depths [N].
    `screen_points`, an optional [N, 2] tensor of zeros (refused otherwise) requiring grad,
    receives the gradient of the projected 2D means (as in 3DGS densification; the reference adds
    its values to them, this op ignores them): `means2d` is an output beside the image, so its
    `.retain_grad()` (gsplat's way) sees no gradient of the image. `screen_abs`, an optional
    [N, 2] tensor, has each backward add the compositing's per-pixel shares of that gradient
    summed in absolute value (AbsGS's densification signal: shares of opposite sign do not
    cancel). `dilation` (px², 0.01..10) is added to each splat's 2D covariance Σ's diagonal: 3DGS's
    low-pass filter, 0.3 by default, Mip-Splatting's 0.1. `antialiased` scales each opacity by
    sqrt(det Σ / det(Σ + dilation I)) (Mip-Splatting's 2D filter, gsplat's "antialiased" mode):
    the dilation then keeps a splat's integral instead of adding to it, so that a splat under a
    pixel carries the same light at any resolution. `near`, `far` and `dilation` take a number
    (numpy's too) or a one-element tensor. Culled Gaussians get radius 0 and zero gradient.
    Every output but `radii` is differentiable, once (docs/rasterizer.md).
    """
    if not isinstance(means, torch.Tensor) or means.dtype not in (torch.float32, torch.float64):
        got = means.dtype if isinstance(means, torch.Tensor) else type(means).__name__
        hint = _half_hint("means", got) if isinstance(got, torch.dtype) else ""
        raise ValueError(f"means: expected a float32 or float64 tensor, got {got}{hint}")
    dtype = means.dtype
    n = means.shape[0] if means.dim() == 2 else None
    _check("means", means, (n, 3), dtype)
    _check("quats", quats, (n, 4), dtype)
    _check("scales", scales, (n, 3), dtype)
    _check("opacities", opacities, (n,), dtype)
    # each range checked by a reduction first, and masked only where that fails (NaN, which the
    # reduction carries, may fail it; the mask lets NaN and inf through): the masks took ~70 us
    # a render at 11k Gaussians, and a SpikeGS step renders 5 poses
    s = scales.detach()
    if s.numel() and not bool(s.min() >= 0):
        negative = s[s < 0]
        if negative.numel():  # NaN/inf are culled per Gaussian, as documented
            raise ValueError(
                f"scales: expected activated values >= 0 (exp of the log-scales), got "
                f"{negative.numel()} negative, e.g. {negative[:3].tolist()}"
            )
    o = opacities.detach()
    if o.numel() and not (o.min() >= 0 and o.max() <= 1):
        outside = o[torch.isfinite(o) & ((o < 0) | (o > 1))]
        if outside.numel():  # NaN/inf are culled per Gaussian, as documented
            raise ValueError(
                f"opacities: expected activated values in [0, 1] (sigmoid of the logits), got "
                f"{outside.numel()} outside, e.g. {outside[:3].tolist()}"
            )
    if not isinstance(colors, torch.Tensor) or colors.dim() not in (2, 3):
        raise ValueError(
            f"colors: expected shape [N, C] or [N, K, C], got {getattr(colors, 'shape', colors)}"
        )
    _check("colors", colors, (n,) + (None,) * (colors.dim() - 1), dtype)
    channels = colors.shape[-1]
    if channels < 1:
        raise ValueError("colors: expected at least one channel")
    _check("viewmat", viewmat, (4, 4), dtype)
    _check("K", K, (3, 3), dtype)
    if K.requires_grad:
        raise ValueError(
            "K: the intrinsics get no gradient (a learnt K would stay as it is); pass K.detach()"
        )
    for name, camera in (("viewmat", viewmat), ("K", K)):
        if not torch.isfinite(camera).all():
            raise ValueError(f"{name}: expected finite values, got {camera.tolist()}")
    _check_intrinsics(K)
    if background is not None:
        _check("background", background, (channels,), dtype)
        if not torch.isfinite(background).all():
            raise ValueError(f"background: expected finite values, got {background.tolist()}")
    if screen_points is not None:
        _check("screen_points", screen_points, (n, 2), dtype)
        if screen_points.detach().any():  # the reference adds them to the 2D means
            raise ValueError(
                "screen_points: expected zeros, a tap that receives the 2D means' gradient (the "
                "op does not read its values)"
            )
    if screen_abs is not None:
        _check("screen_abs", screen_abs, (n, 2), dtype)
        overlapping = any(
            st == 0 and sz > 1 for st, sz in zip(screen_abs.stride(), screen_abs.shape)
        )
        if screen_abs.is_inference() or overlapping:
            raise ValueError(
                "screen_abs: expected a tensor the backward can add to in place, found "
                + ("an inference-mode tensor" if screen_abs.is_inference() else "an expanded view")
            )
    for name, value in (("width", width), ("height", height)):
        if not is_int(value):
            raise ValueError(f"{name}: expected a positive int, got {value!r}")
        if not 0 < value <= MAX_SIZE:
            raise ValueError(f"{name}: expected a positive int up to {MAX_SIZE}, got {value!r}")
    width, height = int(width), int(height)
    for name, value in (("near", near), ("far", far), ("dilation", dilation)):
        if isinstance(value, torch.Tensor) and value.requires_grad:  # (taken as a number, unsaid)
            raise ValueError(
                f"{name}: gets no gradient (a learnt {name} would stay as it is); pass a number "
                f"or {name}.detach()"
            )
    near, far = _as_number(near), _as_number(far)
    if not (is_real(near) and is_real(far) and 0 < near < far):
        raise ValueError(
            f"near, far: expected real numbers with 0 < near < far, got near={near!r}, far={far!r}"
        )
    try:  # an int beyond float's range: OverflowError
        near_t, far_t = torch.tensor([float(near), float(far)], dtype=dtype).tolist()  # the core's
    except OverflowError:
        raise ValueError(f"near, far: {near!r}, {far!r} overflow a float") from None
    if not 0 < near_t < far_t:
        raise ValueError(
            f"near, far: {near!r}, {far!r} round to {near_t!r}, {far_t!r} in {dtype}, the "
            "inputs' dtype; expected 0 < near < far there"
        )
    antialiased = as_flag("antialiased", antialiased)
    check_dilation(dilation)
    degree, coeffs = _sh_layout(colors, sh_degree)
    settings = dict(
        width=width,
        height=height,
        sh_degree=degree,
        sh_coeffs=coeffs,
        channels=channels,
        near=float(near),
        far=float(far),
        antialiased=antialiased,
        dilation=float(dilation),
    )
    scene = (means, quats, scales, opacities, colors, viewmat, background)
    try:
        outputs = _RasterizeFunction.apply(*scene, screen_points, screen_abs, K, settings)
    except RuntimeError as err:  # torch said only "... must override the setup_context ..."
        if "setup_context" not in str(err):
            raise
        raise RuntimeError(
            "spikegs.rasterize does not run under torch.func's transforms (grad, vmap, jacrev, "
            "...): its backward takes one gradient without a graph; use torch.autograd.grad or "
            f".backward() (spikegs.reference.rasterize runs under them) ({err})"
        ) from None
    return RasterizeResult(*outputs)
