"""The Gaussian scene: raw parameters, their activations, initialisation and rendering."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import torch

from .filter_3d import smoothed
from .float32 import F32
from .number_checks import as_flag, is_int
from .rasterize import CONSTANTS, RasterizeResult, check_dilation, rasterize
from .sh import C0, MAX_DEGREE, num_coeffs

PARAMETER_NAMES = ("means", "log_scales", "quats", "opacity_logits", "sh_dc", "sh_rest")
RENDERED_DTYPES = (torch.float32, torch.float64)  # the rasterizer's variants
# the near plane: the rasterizer's 0.01 world units (gsplat's, and the znear of 3DGS's projection
# matrix; 3DGS's renderer itself culls at depth 0.2), lowered in proportion for a scene of
# radius under 1, whose units are small (at 0.01 every Gaussian of a scene a thousand times
# smaller, cameras 0.003 from its centre, was culled and training learnt the background alone);
# not raised for a larger one, whose content may lie far nearer a camera than its radius (a
# forward-facing capture's loose scene sphere)
NEAR_FRACTION = 0.01
FAR_PLANE = float(torch.finfo(torch.float32).max)  # none: any depth beyond `near` renders
# the lowest starting intensity: a colour of exactly 0 sits on the render's clamp at 0, where the
# rounding of its SH evaluation (the core's fused 0.5 + C0·dc: −7e-9) decides whether any
# gradient reaches it, and a black start (a dark pixel's TFP, a black point of a cloud) never
# learnt a colour; 1/255, an 8-bit image's step, is well clear of that rounding
MIN_START_INTENSITY = 1 / 255


def near_plane(scene_radius: float) -> float:
    """The near plane (world units) for a scene of radius `scene_radius`."""
    return NEAR_FRACTION * min(scene_radius, 1.0)


# a scene whose centre lies further than this many radii from the world's origin is trained and
# rendered about its centre (GaussianModel.origin): at 23,000 radii the float32 means' steps
# rounded to whole ulps (−0.65 dB, unsaid), at 230,000 none moved; within it float32 world
# coordinates lose under 1e-6 of the radius, and runs stay what they were
FAR_SCENE_RADII = 10.0


def frame_origin(scene_center, scene_radius: float) -> np.ndarray:
    """The origin [3] that training and evaluation measure a scene's means from: its centre
    where it lies over FAR_SCENE_RADII radii from the world's origin, else the world's."""
    center = np.asarray(scene_center, np.float64)
    far = np.linalg.norm(center) > FAR_SCENE_RADII * scene_radius
    return center.copy() if far else np.zeros(3)


class GaussianModel:
    """N Gaussians as raw (unconstrained) tensors; `scales`, `opacities` and `colors` activate them.

    means [N, 3], log_scales [N, 3], quats [N, 4] (w, x, y, z, unnormalised), opacity_logits [N],
    sh_dc [N, 1, C] and sh_rest [N, K - 1, C] with K = (sh_degree + 1)², plus a learnable
    background [C]. C = 1 for a mono spike camera. `filter_3d` [N] (world units, or None: off):
    the 3D smoothing filter's widths that `render` convolves each Gaussian with (`filter_3d.py`),
    not learnt. `antialiased` and `dilation` (px²) are the rasterizer's 2D filter it is drawn with.

    The means are measured from `origin` [3] (float64, world units; default the world's): a
    trainer puts it at the scene's centre, so that a scene far from the world's origin (UTM or
    GPS coordinates) keeps float32 positions that its steps can move and that render without
    cancellation. `render` takes viewmats of that frame, which `view_of` makes from world ones.
    """

    def __init__(
        self,
        params: dict[str, torch.Tensor],
        background: torch.Tensor,
        sh_degree: int,
        origin=None,
        antialiased: bool = False,
        filter_3d: torch.Tensor | None = None,
        dilation: float = CONSTANTS["dilation"],
    ):
        missing = set(PARAMETER_NAMES) - set(params)
        if missing:
            raise ValueError(f"GaussianModel: missing parameters {sorted(missing)}")
        if not is_int(sh_degree) or not 0 <= sh_degree <= MAX_DEGREE:
            raise ValueError(
                f"GaussianModel: sh_degree expected 0..{MAX_DEGREE}, not {sh_degree!r}"
            )
        rest = params["sh_rest"]  # [N, K - 1, C]: K the degree's coefficients at least
        if rest.dim() != 3 or rest.shape[1] < num_coeffs(sh_degree) - 1:
            raise ValueError(
                f"GaussianModel: sh_degree {sh_degree} needs sh_rest [N, "
                f"{num_coeffs(sh_degree) - 1}, C], got {list(rest.shape)}"
            )
        counts = [params[k].shape[0] if params[k].dim() else -1 for k in PARAMETER_NAMES]
        n, dc = max(counts, key=counts.count), params["sh_dc"]  # the odd one out is named
        c = dc.shape[-1] if dc.dim() == 3 else -1
        wanted = {"means": (n, 3), "log_scales": (n, 3), "quats": (n, 4)}
        wanted.update({"opacity_logits": (n,), "sh_dc": (n, 1, c), "background": (c,)})
        given = {**params, "background": background}
        wrong = [f"{k} {list(given[k].shape)}" for k, w in wanted.items() if given[k].shape != w]
        wrong += [f"sh_rest {list(rest.shape)}"] if (rest.shape[0], rest.shape[2]) != (n, c) else []
        dtypes = {k: given[k].dtype for k in wanted} | {"sh_rest": rest.dtype}
        if len(set(dtypes.values())) > 1 or given["means"].dtype not in RENDERED_DTYPES:
            # (a bfloat16 model failed on saving, a float16 one on rendering, each unnamed)
            found = ", ".join(f"{k} {str(d).removeprefix('torch.')}" for k, d in dtypes.items())
            raise ValueError(
                f"GaussianModel: parameters of one floating dtype expected; {found} (float32 or "
                f"float64: those the rasterizer renders)"
            )
        if wrong:  # unchecked, a background of 3 for 1 channel was saved and then refused
            raise ValueError(
                f"GaussianModel: means [N, 3], log_scales [N, 3], quats [N, 4], opacity_logits "
                f"[N], sh_dc [N, 1, C], sh_rest [N, K - 1, C] and background [C] expected, of "
                f"one N and C; found {', '.join(wrong)}"
            )
        self.params = {k: torch.nn.Parameter(params[k].detach().clone()) for k in PARAMETER_NAMES}
        self.background = torch.nn.Parameter(background.detach().clone())
        self._sh_degree = int(sh_degree)
        self.origin = np.zeros(3) if origin is None else np.array(origin, np.float64)  # [3]
        if self.origin.shape != (3,) or not np.isfinite(self.origin).all():
            raise ValueError(f"GaussianModel: origin expected 3 finite numbers, not {origin!r}")
        # drawn with the antialiased 2D filter (`spikegs.rasterize`'s `antialiased`): a model
        # trained so renders so
        self.antialiased = as_flag("GaussianModel: antialiased", antialiased)
        self.filter_3d = filter_3d  # (the setter checks it)
        self.dilation = dilation  # (so does this one)

    @property
    def dilation(self) -> float:
        """The 2D filter's variance (px²) added to each splat's 2D covariance in `render`."""
        return self._dilation

    @dilation.setter
    def dilation(self, dilation: float) -> None:
        check_dilation(dilation, "GaussianModel: dilation")
        self._dilation = float(dilation)

    @property
    def filter_3d(self) -> torch.Tensor | None:
        """The 3D smoothing filter's standard deviations [N] (world units), or None (off)."""
        return self._filter_3d

    @filter_3d.setter
    def filter_3d(self, widths: torch.Tensor | None) -> None:
        if widths is not None:
            means = self.params["means"]
            if not isinstance(widths, torch.Tensor) or widths.shape != (len(self),):
                found = list(widths.shape) if isinstance(widths, torch.Tensor) else widths
                raise ValueError(f"GaussianModel: filter_3d [{len(self)}] expected, not {found}")
            widths = widths.detach().to(means.dtype).clone()
            if not (widths.isfinite() & (widths >= 0)).all():
                raise ValueError("GaussianModel: filter_3d expected finite widths >= 0")
        self._filter_3d = widths

    @property
    def sh_degree(self) -> int:
        """The SH degree the model renders with (fixed: its sh_rest holds that many)."""
        return self._sh_degree

    @classmethod
    def random(
        cls,
        n: int,
        center,
        radius: float,
        channels: int,
        sh_degree: int = 0,
        generator: torch.Generator | None = None,
        colors: Callable[[torch.Tensor], torch.Tensor] | None = None,
        max_scale: float = math.inf,
    ) -> GaussianModel:
        """`n` Gaussians uniform in the ball (center, radius), semi-transparent, isotropic, of
        intensities `colors(means)` [N, C] (default grey 0.5), no larger than `max_scale`."""
        if not 0 < radius < math.inf:
            raise ValueError(f"radius expected a positive finite size, found {radius}")
        g = generator
        direction = torch.randn(n, 3, generator=g, dtype=torch.float32)  # [N, 3], unit below
        direction = direction / direction.norm(dim=1, keepdim=True).clamp_min(1e-12)
        r = radius * torch.rand(n, 1, generator=g, dtype=torch.float32) ** (1 / 3)  # [N, 1]
        means = torch.as_tensor(center, dtype=torch.float32) + direction * r  # [N, 3]
        # scale: about the mean distance between neighbours at this density
        spacing = radius * (4 / 3 * math.pi / max(n, 1)) ** (1 / 3)
        rgb = torch.full((n, channels), 0.5) if colors is None else colors(means)  # any dtype
        return cls.from_points(means, rgb, min(spacing, max_scale), sh_degree)

    @classmethod
    def from_points(
        cls, points: torch.Tensor, colors: torch.Tensor, scale: float, sh_degree: int = 0
    ) -> GaussianModel:
        """Gaussians at `points` [N, 3] with colours [N, C] (intensity units; those below
        MIN_START_INTENSITY start there) and one scale; float32 whatever torch's default dtype
        (float64 mixed the two, which `render` refused)."""
        if not 0 < scale < math.inf:
            raise ValueError(f"scale expected a positive finite size, found {scale}")
        if not (isinstance(points, torch.Tensor) and isinstance(colors, torch.Tensor)):
            kinds = f"{type(points).__name__} and {type(colors).__name__}"
            raise ValueError(f"points and colours expected torch tensors, got {kinds}")
        if colors.dim() != 2:
            raise ValueError(f"colours [N, C] expected, found {list(colors.shape)}")
        n, channels = colors.shape
        if points.shape != (n, 3):
            raise ValueError(
                f"points [N, 3] and colours [N, C] of one N expected, found {list(points.shape)} "
                f"and {list(colors.shape)}"
            )
        params = {
            "means": points.float(),
            "log_scales": torch.full((n, 3), math.log(scale), **F32),
            "quats": torch.tensor([1.0, 0.0, 0.0, 0.0], **F32).repeat(n, 1),
            "opacity_logits": torch.full((n,), math.log(0.1 / 0.9), **F32),
            "sh_dc": ((colors.float().clamp_min(MIN_START_INTENSITY) - 0.5) / C0).unsqueeze(1),
            "sh_rest": torch.zeros(n, num_coeffs(sh_degree) - 1, channels, **F32),
        }
        return cls(params, torch.zeros(channels, **F32), sh_degree)

    def __len__(self) -> int:
        return self.params["means"].shape[0]

    def view_of(self, viewmats) -> torch.Tensor:
        """World-to-camera `viewmats` [..., 4, 4] (world frame; float64 keeps a far one exact)
        as viewmats of this model's frame and dtype: t + R·origin, summed in float64; not
        differentiable (a tensor that requires grad is refused: apply a learnt correction to
        the result)."""
        if isinstance(viewmats, torch.Tensor) and viewmats.requires_grad:
            raise ValueError("view_of: viewmats that require grad (not differentiable: detach)")
        local = np.asarray(viewmats, np.float64).copy()  # np.array warned on a torch tensor
        local[..., :3, 3] += local[..., :3, :3] @ self.origin
        return torch.as_tensor(local, dtype=self.dtype)

    def world_means(self) -> torch.Tensor:
        """The means in the world frame, float64 [N, 3]."""
        return self.params["means"].detach().double() + torch.from_numpy(self.origin)

    def centred_at(self, origin) -> GaussianModel:
        """This model with its means measured from `origin` [3] (itself where it already is), of
        its dtype."""
        origin = np.asarray(origin, np.float64)
        if np.array_equal(origin, self.origin):
            return self
        state = self.state_dict()
        state["params"]["means"] = (self.world_means() - torch.from_numpy(origin)).to(self.dtype)
        state["origin"] = origin.tolist()
        return GaussianModel.from_state_dict(state)

    def _check_filter_3d(self) -> None:
        """ValueError where `filter_3d` holds another count of widths than Gaussians (densified
        since it was computed)."""
        if self.filter_3d.shape != (len(self),):
            raise ValueError(
                f"GaussianModel: filter_3d holds {len(self.filter_3d)} widths for "
                f"{len(self)} Gaussians: recompute it (filter_3d.filter_widths)"
            )

    def fused(self) -> GaussianModel:
        """This model with its 3D smoothing filter folded into its scales and opacities (itself
        where it has none): the same renders, and a .ply without Mip-Splatting's filter_3D
        property, which 3DGS's SIBR viewer cannot read (its fixed 62-value records)."""
        if self.filter_3d is None:
            return self
        self._check_filter_3d()
        state, dtype = self.state_dict(), self.params["log_scales"].dtype
        # in float64 and in logits: an opacity that rounds to 1 (a logit over ~17 in float32,
        # ~37 in float64) had a logit of inf, written to the .ply
        with torch.no_grad():
            logits = self.params["opacity_logits"].double()  # [N]
            scales = self.params["log_scales"].double().exp().clamp_min(torch.finfo(dtype).tiny)
            wide = torch.hypot(scales, self.filter_3d.double()[:, None])  # [N, 3], as smoothed
            log_f = (scales.log() - wide.log()).sum(dim=1)  # [N] log of the opacity's factor
            # logit(σ(l) f) = log(σ(l) f) - log(σ(-l) + σ(l) (1 - f))
            held = torch.sigmoid(-logits) - torch.sigmoid(logits) * torch.expm1(log_f)
            fused = log_f - torch.nn.functional.softplus(-logits) - held.log()
        state["params"]["log_scales"] = wide.log().to(dtype)
        state["params"]["opacity_logits"] = fused.to(dtype)
        state["filter_3d"] = None
        return GaussianModel.from_state_dict(state)

    @property
    def dtype(self) -> torch.dtype:
        """The parameters' dtype: float32 (trained, loaded) or float64."""
        return self.params["means"].dtype

    @property
    def channels(self) -> int:
        return self.params["sh_dc"].shape[-1]

    @property
    def scales(self) -> torch.Tensor:  # [N, 3]
        return self.params["log_scales"].exp()

    @property
    def opacities(self) -> torch.Tensor:  # [N]
        return torch.sigmoid(self.params["opacity_logits"])

    @property
    def sh(self) -> torch.Tensor:  # [N, K, C]
        return torch.cat([self.params["sh_dc"], self.params["sh_rest"]], dim=1)

    def render(
        self,
        viewmat: torch.Tensor,
        K: torch.Tensor,
        width: int,
        height: int,
        near: float,
        screen_points: torch.Tensor | None = None,
        screen_abs: torch.Tensor | None = None,
    ) -> RasterizeResult:
        """Render from `viewmat` [4, 4], camera from this model's frame (`view_of` of a world-to-
        camera viewmat), with intrinsics `K` [3, 3], culling what lies nearer than `near` (world
        units: `near_plane` of the scene's radius); each Gaussian convolved with its `filter_3d`
        width where the model has one."""
        scales, opacities = self.scales, self.opacities
        if self.filter_3d is not None:
            self._check_filter_3d()
            scales, opacities = smoothed(scales, opacities, self.filter_3d)
        return rasterize(
            self.params["means"],
            self.params["quats"],
            scales,
            opacities,
            self.sh,
            viewmat,
            K,
            width,
            height,
            sh_degree=self.sh_degree,
            background=self.background,
            near=near,
            # no far plane: the rasterizer's default (1e10) culled a whole scene whose units put
            # its cameras 3e10 away, which then trained to its background alone, unsaid (float's
            # largest, not inf, which a -ffast-math core may not compare)
            far=FAR_PLANE,
            screen_points=screen_points,
            screen_abs=screen_abs,
            antialiased=self.antialiased,
            dilation=self.dilation,
        )

    def state_dict(self) -> dict:
        return {
            "params": {k: v.detach().clone() for k, v in self.params.items()},
            "background": self.background.detach().clone(),
            "sh_degree": self.sh_degree,
            "origin": self.origin.tolist(),
            "antialiased": self.antialiased,
            "filter_3d": None if self.filter_3d is None else self.filter_3d.clone(),
            "dilation": self.dilation,
        }

    @classmethod
    def from_state_dict(cls, state: dict) -> GaussianModel:
        # a checkpoint from before origins holds world means, one from before the antialiased
        # or the 3D filter was drawn without them, one from before dilations at 0.3
        return cls(
            state["params"],
            state["background"],
            state["sh_degree"],
            state.get("origin"),
            state.get("antialiased", False),
            state.get("filter_3d"),
            state.get("dilation", CONSTANTS["dilation"]),
        )
