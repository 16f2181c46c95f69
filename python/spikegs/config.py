"""Experiment configuration: defaults in dataclasses, one YAML file per method in configs/.

A YAML file overrides only what differs from what it starts from, section by section: `base: NAME`
starts from another method's file, `base: FILE.yaml` from another file (a relative path is taken
from the directory of the file that names it); without `base`, from the dataclass defaults (the
paper's losses, eqs. 7 and 10: L1 norms, lambda = 1, which the paper leaves unstated; but SIM's loss
is L2, where the paper's eq. 15 has L1: `sim: {loss: l1}`; `--method spikegs` is
configs/spikegs.yaml, smooth-L1 norms and lambda = 4). A file that sets no `method` is named after
itself, whatever its base: an empty my_run.yaml trains the dataclass defaults as method `my_run`,
and lam2.yaml (`base: spikegs`, another lambda) trains as `lam2`, never under another method's name
and settings (a file named like a built-in method must start from it, and is then that method, or
name itself; a file whose `method` names a built-in one must keep its supervision and SIM settings).
No file at all is the default method, DEFAULT_METHOD. The densification schedule's defaults are for
the default train.iterations: a config that sets another gets each schedule key it does not set
scaled to it, as `--iterations` does; a key a file (or its base) sets is for that file's length, and
scales from it to the run's. Unknown sections or keys, a key given twice, values of the wrong type
or range and non-finite numbers are refused with a message that names the key and what is allowed
(an unknown key or a wrong type with the file that sets it, a base file too).
"""

from __future__ import annotations

import contextlib
import copy
import dataclasses
import functools
import math
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from .densify import DensifyConfig
from .losses import NORMS, SIM_LOSSES
from .number_checks import SEED_MAX, is_count, is_int, is_number, is_seed, past_float
from .pose_refine import PoseRefineConfig
from .rasterize import CONSTANTS, DILATION_EXPECTED, is_dilation
from .regular_file import NotText
from .yaml_files import read_yaml, yaml_text

# installed: spikegs/configs (CMake installs the repository's configs/ there); in-tree: configs/
_PACKAGE_DIR = Path(__file__).resolve().parent
CONFIG_DIR = next(
    (p for p in (_PACKAGE_DIR / "configs", _PACKAGE_DIR.parents[1] / "configs") if p.is_dir()),
    _PACKAGE_DIR / "configs",
)
DEFAULT_METHOD = "spikegs"  # the configuration when no method or file is named
# supervision.instant_until: every step, or until densification ends
INSTANT_UNTIL = ("run", "densify")
INSTANT_TARGETS = ("sim", "tfp", "tfi", "clean", "none")
# the text settings of a fixed set of words, each 'section.key' with its words
CHOICES = {
    "supervision.instant": INSTANT_TARGETS,
    "supervision.instant_until": INSTANT_UNTIL,
    "supervision.instant_norm": tuple(NORMS),
    "supervision.exposure_norm": tuple(NORMS),
    "sim.loss": tuple(SIM_LOSSES),
}
MAX_LR = 1.0  # learning rates above it move parameters by more than their own scale a step
# supervision's loss weights: only their ratios matter (Adam's steps do not see the loss's scale,
# and densification divides the weights out), and a term weighted 2**24 (1.7e7) times another
# drowns it in float32's rounding of their sum. Far above, Adam's squared gradients overflow
# float32 (|gradient| 1.8e19): a weight's gradient is up to ~its size (the background's, a mean
# over pixels; 0.59 at most over 1500 steps of tfp33 on 128² solids), and 1e21-1e22 stopped such a
# run within 9 steps, after SIM where it trains (BENCHMARKS.md, "Loss weights' bound"). Far
# below, the gradients fall under Adam's eps (1e-15): 32² solids' tfp33 trained as at 1 down to
# 1e-8, 2.7 dB worse at 1e-10, and not at all from 1e-14; a weight is 0 (off) or at least MIN_WEIGHT
MAX_WEIGHT, MIN_WEIGHT = 1e6, 1e-6
# train.filter_3d's variances (pixels²): a standard deviation over 3 pixels in the nearest view
# blurs each Gaussian past what any training view shows; one of 0.03 pixels changes nothing a
# render shows, yet `render --scale` would stop widening the run
MIN_FILTER_3D, MAX_FILTER_3D = 1e-3, 10.0
# train.init_gaussians: fewer is no scene. With the default densification schedule (scaled to 150
# steps, 32² solids) 1 and 2 random Gaussians were all pruned by the opacity reset (an empty
# model), 4 kept 29; the demo starts from 5000
MIN_GAUSSIANS = 16
COUNTS = "a whole number >= 1 (and below 2^63)"  # what a count of steps or things expects
# densify keys counted in iterations: their defaults are for TrainConfig.iterations, and a run of
# another length scales them (0 stays: stop = half the run, no opacity reset)
SCHEDULE_KEYS = ("start", "stop", "every", "opacity_reset_every")


@dataclass
class SupervisionConfig:
    # sim | tfp | tfi | none: the image compared with render(t); clean: the simulator's noise-free
    # image (built-in synthetic scenes only): the ceiling of perfect instant targets, not a method
    instant: str = "sim"
    # TFP window of the instant target when instant = tfp (SIM's: sim.target_window)
    instant_window: int = 33
    instant_weight: float = 1.0
    exposure_weight: float = 1.0  # lambda: weight of L_exposure (0: off)
    # how long L_instant (and its D-SSIM term) trains: "run", every step (the paper), or
    # "densify", until densification's window ends (densify.stop, or half the run where stop is
    # 0, whether or not a round falls in it), after which L_exposure alone, free of SIM's
    # blind-spot bias, finishes the run (needs the exposure loss)
    instant_until: str = "run"
    exposure_window: int = 33  # readouts of the virtual exposure around t
    exposure_poses: int = 5  # K renders averaged over the window
    # optional D-SSIM term on the instant loss, (1 - SSIM) / 2: 3DGS's 0.8 L1 + 0.2 (1 - SSIM) is
    # instant_weight 0.8, dssim_weight 0.4
    dssim_weight: float = 0.0
    # l1 (the paper's eqs. 7 and 10; over views it fits the median of a quantised TFP) | l2 |
    # smooth_l1 (quadratic within one spike of the TFP window): both fit the mean
    instant_norm: str = "l1"
    exposure_norm: str = "l1"
    # divide a light's flicker found in the spikes out of every target (spikegs.flicker; false:
    # the targets as the spikes show them)
    deflicker: bool = True
    # leave a sensor's hot, stuck and dead pixels found in the spikes out of every loss against a
    # target made from them (spikegs.pixel_defects; false: every pixel)
    mask_defects: bool = True

    def instant_total_weight(self) -> float:
        """The weight of the losses on the instant render: L_instant's and D-SSIM's, the latter
        in units of 1 - SSIM, as 3DGS weighs it (its 0.8 L1 + 0.2 (1 - SSIM) is ours at 0.8 and
        0.4 of (1 - SSIM) / 2: a unit weight, whose densification signal is 3DGS's; counted at
        0.4 it was 1/1.2 of it); 0 without an instant target."""
        return self.instant_weight + self.dssim_weight / 2 if self.instant != "none" else 0.0

    def total_weight(self) -> float:
        """The sum of the weights of the losses in use (> 0 in a valid config; D-SSIM's only with
        an instant target, as validation requires)."""
        return self.instant_total_weight() + self.exposure_weight


@dataclass
class LearningRates:
    # times the scene radius, decayed exponentially to means_final. 3DGS's 1.6e-4 (and gsplat's)
    # is per unit of the *camera* extent, 1.1x the cameras' farthest distance from their centroid:
    # ~3 scene radii on our orbits (cameras at ~2.5-3 radii), so 3x that per scene radius.
    # Forward-facing views (LLFF) spread little: 3DGS's rate there is a fraction of a radius's,
    # ours stays per scene radius (untuned on such data).
    # At 1.6e-4 per radius (until 2026-11-28, with percent_dense 0.01) the demo's schedule scored
    # lower: SpikeGS by 0.42 / 0.70 dB on solids and 0.61 on fine-texture, TFI+3DGS by 0.65-1.13
    # (BENCHMARKS.md, "The position learning rate's unit")
    means: float = 4.8e-4
    means_final: float = 4.8e-6
    log_scales: float = 5e-3
    quats: float = 1e-3
    opacity_logits: float = 5e-2
    sh_dc: float = 2.5e-3
    sh_rest: float = 1.25e-4
    background: float = 1e-3


@dataclass
class TrainConfig:
    iterations: int = 3000
    seed: int = 0
    init_gaussians: int = 5000
    sh_degree: int = 0  # 0 suits a mono camera: leave out what the scene does not need
    # the rasterizer's antialiased 2D filter (Mip-Splatting's; gsplat's "antialiased" mode):
    # each opacity times sqrt(det Σ / det(Σ + dilation)), so that a splat keeps its integral at
    # any resolution; eval and render draw the run's scene.ply as it trained
    antialiased: bool = False
    # the variance (px²) that the rasterizer's 2D filter adds to each splat's 2D covariance:
    # 3DGS's 0.3, Mip-Splatting's 0.1 (beside its 3D filter's 0.2)
    dilation: float = CONSTANTS["dilation"]
    # Mip-Splatting's 3D smoothing filter: each Gaussian convolved with an isotropic one of this
    # variance in pixels² of the finest training view that sees it (the paper's 0.2), so that
    # nothing finer than the training views sample is learnt or drawn nearer or larger; 0: off
    # (filter_3d.py)
    filter_3d: float = 0.0
    eval_every: int = 500
    checkpoint_every: int = 500
    log_every: int = 25


@dataclass
class SimConfig:
    window: int = 33  # readouts SIM sees
    target_window: int = 0  # readouts at the window's centre whose TFP SIM learns (0: window)
    # SIM's quality follows its number of steps more than its batch: at 256², 1000 steps of 2
    # crops score 0.1-0.3 dB a frame above 500 steps of 8 (the default until 2026-11-28) in half
    # the time, ~100 s against ~200 on 2 cores (BENCHMARKS.md, "SIM's steps and batch at 256²").
    # 1500 steps of 8 lifted its bias (a still view's mean over windows) from 30.8 dB at 300 steps
    # to 35.4 ("SIM's training length"); with the output layer starting at zero, 300 steps reach
    # 33.1-33.9 ("What decides a 300-step SIM")
    iterations: int = 1000
    crop: int = 64
    batch: int = 2
    loss: str = "l2"  # l2: conditional mean (Noise2Void); l1: the paper's eq. 15, biased when dim
    # shift convolutions per branch m: the blind spot sees a (2m+1)-wide block on each side. 5
    # costs ~1.4x the training; at 300 steps it moved SIM's bias by less than the seeds' spread
    # (BENCHMARKS.md, "SIM's depth")
    shift_layers: int = 3

    def target_readouts(self) -> int:
        """The readouts whose TFP SIM learns: `target_window`, or the whole window when 0."""
        return self.target_window or self.window


@dataclass
class Config:
    method: str = "spikegs"
    supervision: SupervisionConfig = field(default_factory=SupervisionConfig)
    train: TrainConfig = field(default_factory=TrainConfig)
    lr: LearningRates = field(default_factory=LearningRates)
    densify: DensifyConfig = field(default_factory=DensifyConfig)
    sim: SimConfig = field(default_factory=SimConfig)
    pose_refine: PoseRefineConfig = field(default_factory=PoseRefineConfig)
    # the train.iterations its densification schedule is for (`load_config` and `with_iterations`
    # set it; the defaults' is the default length): a script's `config.train.iterations = 300`
    # after them leaves the schedule as it was (`warn_if_schedule_unscaled`)
    _schedule_length = TrainConfig.iterations
    # 'section.key' -> (the config file that set it, the value it gave), as `load_config` read
    # them (`set_by`; a file's, not a built-in method's); replaced, never changed in place
    _set_in = {}

    def set_by(self, name: str) -> str:
        """The config file that set the setting `name` ('section.key') to the value it holds,
        else "config" (a default, a built-in method's, a value set in Python since)."""
        path, value = self._set_in.get(name, (None, None))
        return str(path) if path is not None and self.setting(name) == value else "config"

    def setting(self, name: str) -> Any:
        """The value of the setting `name` ('section.key')."""
        return functools.reduce(getattr, name.split("."), self)

    def validate(self) -> Config:
        s, t, d, sim = self.supervision, self.train, self.densify, self.sim
        _check_types(self)
        _require(
            isinstance(self.method, str)
            and self.method.strip() == self.method != ""
            and not set(self.method) & set("/\\")
            and self.method.isprintable(),
            "method",
            self.method,
            "a name: printable, without / or \\ or surrounding spaces",
        )
        for name, value in _numbers(self):
            _require(math.isfinite(value), name, value, "a finite number")
        # the weights' range before the checks that read them (-1 was named as instant_until's)
        for name in ("instant_weight", "exposure_weight", "dssim_weight"):
            _require(
                getattr(s, name) == 0 or MIN_WEIGHT <= getattr(s, name) <= MAX_WEIGHT,
                f"supervision.{name}",
                getattr(s, name),
                f"0 (off) or {MIN_WEIGHT:g}..{MAX_WEIGHT:,.0f} (only the weights' ratios matter "
                f"within it: Adam's steps and densification do not see their scale; near 1e20 "
                f"Adam's squared gradients overflow float32, and under 1e-9 its eps swamps them)",
            )
        _require(
            s.instant in INSTANT_TARGETS,
            "supervision.instant",
            s.instant,
            f"one of {', '.join(INSTANT_TARGETS)}",
        )
        for name in ("instant_window", "exposure_window"):
            value = getattr(s, name)
            _require(
                value >= 1 and value % 2 == 1, f"supervision.{name}", value, "an odd window >= 1"
            )
        _require(
            s.instant_until in INSTANT_UNTIL,
            "supervision.instant_until",
            s.instant_until,
            " or ".join(INSTANT_UNTIL),
        )
        _require(
            s.instant_until == "run" or s.exposure_weight > 0 or s.instant == "none",
            "supervision.instant_until",
            s.instant_until,
            "run without the exposure loss (densify leaves the steps after densification "
            "without a loss: exposure_weight > 0 finishes the run)",
            also=("supervision.exposure_weight", "supervision.instant"),
        )
        for name in ("instant_norm", "exposure_norm"):
            value = getattr(s, name)
            _require(value in NORMS, f"supervision.{name}", value, " or ".join(NORMS))
        if s.exposure_weight > 0:  # (a method without the exposure loss leaves them unread)
            _require(
                s.exposure_window >= 3,
                "supervision.exposure_window",
                s.exposure_window,
                ">= 3 with the exposure loss (it averages >= 2 renders, one a readout at most)",
            )
            _require(
                2 <= s.exposure_poses <= s.exposure_window,
                "supervision.exposure_poses",
                s.exposure_poses,
                f">= 2 and at most supervision.exposure_window ({s.exposure_window}): one render "
                f"a readout at most (more would reach past the window)",
                also=("supervision.exposure_window",),
            )
        _require(
            s.dssim_weight == 0 or (s.instant != "none" and s.instant_weight > 0),
            "supervision.dssim_weight",
            s.dssim_weight,
            "0 without an instant target (the D-SSIM term compares the instant render with it: "
            "supervision.instant and instant_weight > 0)",
        )
        _require(
            s.instant not in ("sim", "none")
            or s.instant_window == SupervisionConfig.instant_window,
            "supervision.instant_window",
            s.instant_window,
            f"{SupervisionConfig.instant_window} (the default) with instant {s.instant}: it is the "
            f"TFP window, and the smooth-L1 zone's spike for tfi and clean (SIM's is "
            f"sim.target_window, or sim.window when 0)",
            also=("supervision.instant",),
        )
        _require(
            s.instant_weight > 0 or s.exposure_weight > 0,
            "supervision",
            "no loss",
            "instant_weight or exposure_weight > 0",
        )
        _require(
            s.instant != "none" or s.instant_weight == 0 or s.exposure_weight > 0,
            "supervision.instant",
            "none",
            "exposure_weight > 0 when there is no instant target",
        )
        _require(is_count(t.iterations), "train.iterations", t.iterations, COUNTS)
        _require(is_seed(t.seed), "train.seed", t.seed, f"0..{SEED_MAX} (2**64 - 1)")
        _require(0 <= t.sh_degree <= 3, "train.sh_degree", t.sh_degree, "0..3")
        _require(
            t.init_gaussians >= MIN_GAUSSIANS,
            "train.init_gaussians",
            t.init_gaussians,
            f">= {MIN_GAUSSIANS} (fewer were pruned to an empty scene)",
        )
        _require(
            t.filter_3d == 0 or MIN_FILTER_3D <= t.filter_3d <= MAX_FILTER_3D,
            "train.filter_3d",
            t.filter_3d,
            f"0 (off) or a variance in pixels² of {MIN_FILTER_3D:g}..{MAX_FILTER_3D:g} "
            f"(Mip-Splatting's 0.2; at {MAX_FILTER_3D:g} each Gaussian is wider than 3 pixels in "
            f"its nearest view, under {MIN_FILTER_3D:g} it smooths nothing a render shows)",
        )
        _require(is_dilation(t.dilation), "train.dilation", t.dilation, DILATION_EXPECTED)
        for name in ("eval_every", "checkpoint_every", "log_every"):
            _require(is_count(getattr(t, name)), f"train.{name}", getattr(t, name), COUNTS)
        for f in dataclasses.fields(self.lr):
            _require(
                0 <= getattr(self.lr, f.name) <= MAX_LR,
                f"lr.{f.name}",
                getattr(self.lr, f.name),
                f"0..{MAX_LR} (Adam moves a parameter by about its rate a step; 3DGS's are "
                f"1e-4..5e-2)",
            )
        _require(
            self.lr.means == 0 or self.lr.means_final > 0,
            "lr.means_final",
            self.lr.means_final,
            "> 0 (the means' rate decays exponentially, never to 0: take a small value)",
        )
        _require(d.start >= 0, "densify.start", d.start, ">= 0")
        _require(d.stop >= 0, "densify.stop", d.stop, ">= 0 (0: half the run)")
        _require(d.every >= 1, "densify.every", d.every, ">= 1")
        _require(
            d.opacity_reset_every >= 0,
            "densify.opacity_reset_every",
            d.opacity_reset_every,
            ">= 0 (0: never)",
        )
        last = d.last_iteration(t.iterations)
        _require(
            d.start >= t.iterations or d.start <= last,
            "densify.start",
            d.start,
            f"<= the last densifying iteration {last} (densify.stop, or half of train.iterations "
            f"when 0), or >= train.iterations ({t.iterations}) for a run without densification",
            also=("densify.stop", "train.iterations"),
        )
        # rounds fall on the multiples of every in start..stop, never at the run's last iteration
        # (`Densifier.step`): a stop past the run ends them at iterations - 1 (start 50, stop 1000,
        # every 100 in 60 iterations was accepted, and the run never densified)
        first, end = d.first_iteration(), min(last, t.iterations - 1)
        _require(
            d.start >= t.iterations or first <= end,
            "densify.every",
            d.every,
            f"a period with a multiple in densify.start..stop = {d.start}..{end} (densification "
            f"runs at the multiples of every, before the run's last iteration {t.iterations}: "
            f"none there, the run would never densify), or densify.start >= train.iterations "
            f"({t.iterations}) for a run without densification, as such a schedule trains",
            also=("densify.start", "densify.stop", "train.iterations"),
        )
        _require(
            d.grad_threshold > 0,
            "densify.grad_threshold",
            d.grad_threshold,
            "> 0 (at 0 every Gaussian is cloned or split each round, up to max_gaussians)",
        )
        for name in ("percent_dense", "max_world_size"):
            _require(getattr(d, name) >= 0, f"densify.{name}", getattr(d, name), ">= 0")
        _require(  # a visible Gaussian's radius is a whole pixel or more: one round pruned 6.7k
            d.max_screen_size == 0 or d.max_screen_size >= 1,  # of 6.8k at 0.5, unsaid
            "densify.max_screen_size",
            d.max_screen_size,
            "0 (never) or >= 1 pixel (a visible Gaussian's radius is 1 pixel or more: under 1 "
            "prunes every one)",
        )
        _require(
            0 <= d.min_opacity < 1,
            "densify.min_opacity",
            d.min_opacity,
            "0 <= min_opacity < 1 (an opacity is below 1: 1 prunes every Gaussian)",
        )
        _require(
            d.max_gaussians >= t.init_gaussians,
            "densify.max_gaussians",
            d.max_gaussians,
            f">= train.init_gaussians ({t.init_gaussians:,}): raise the cap, or start with fewer",
            also=("train.init_gaussians",),
        )
        _require(sim.window >= 1 and sim.window % 2 == 1, "sim.window", sim.window, "odd, >= 1")
        _require(
            sim.target_window == 0
            or (1 <= sim.target_window <= sim.window and sim.target_window % 2),
            "sim.target_window",
            sim.target_window,
            "0 (the whole window) or an odd number of readouts <= sim.window",
        )
        for name in ("iterations", "crop", "batch", "shift_layers"):
            _require(is_count(getattr(sim, name)), f"sim.{name}", getattr(sim, name), COUNTS)
        _require(sim.loss in SIM_LOSSES, "sim.loss", sim.loss, " or ".join(SIM_LOSSES))
        _require(
            0 <= self.pose_refine.lr <= MAX_LR,
            "pose_refine.lr",
            self.pose_refine.lr,
            f"0..{MAX_LR}",
        )
        return self

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    def last_instant_iteration(self) -> int:
        """The last iteration that trains L_instant: the run's last, or (instant_until: densify)
        the end of densification's window, `DensifyConfig.last_iteration` (0 in a run of one
        iteration: L_instant never trains)."""
        t = self.train
        if self.supervision.instant_until == "run":
            return t.iterations
        return self.densify.last_iteration(t.iterations)

    def instant_target(self) -> str:
        """The instant target the run reads: supervision.instant, or "none" where its weight is 0
        or it trains on no iteration (`last_instant_iteration` 0)."""
        s = self.supervision
        return s.instant if s.instant_weight > 0 and self.last_instant_iteration() >= 1 else "none"

    def with_iterations(self, iterations: int) -> Config:
        """A copy that trains for `iterations` steps, its densification schedule (start, stop,
        every, opacity reset) scaled by iterations / train.iterations so that a shorter or longer
        run keeps about its number of densification rounds (each key rounded on its own: 16 at
        44 iterations, 8 at 45); 0 (stop: half the run, reset: never) stays."""
        _require(is_count(iterations), "train.iterations", iterations, COUNTS)
        config = copy.deepcopy(self)
        factor = iterations / config.train.iterations
        _scale_schedule(config.densify, SCHEDULE_KEYS, factor)
        config.train.iterations = iterations
        # the schedule's own length scaled alike: a train.iterations set by hand before, which
        # left the schedule as it was, still warned of (`warn_if_schedule_unscaled`)
        config._schedule_length = max(1, round(self._schedule_length * factor))
        if factor != 1:
            _keep_a_round(config.densify, iterations)
        return _validated_scaled(config, dict.fromkeys(SCHEDULE_KEYS, factor), {})


def _validated_scaled(config: Config, factors: dict[str, float], set_in: dict[str, Path]) -> Config:
    """`config.validate()`, where the setting refused is named with the file that set it (`set_in`:
    'section.key' → the file; through a base chain the key's file was not said) and, where it is a
    densification value scaled to the run's length (by `factors`, per schedule key), saying so:
    the value named is not the one written."""
    try:
        return config.validate()
    except ConfigError as err:
        key = err.name.removeprefix("densify.")
        scaled = factors.get(key, 1) != 1
        # a rule weighing the setting against another that a file set, where it set none: that
        # file named, and the setting (densify.start's default refused against a stop written
        # was said of "config:")
        named = next((k for k in (err.name, *err.also) if k in set_in), None)
        if named is None and not scaled:
            raise
        expected = err.expected + (
            f"; scaled to train.iterations = {config.train.iterations} from the run length it "
            f"was set for, the default {TrainConfig.iterations} where unset (densify.{key} x "
            f"{factors[key]:.3g})"
            if scaled
            else ""
        )
        if named not in (None, err.name):
            expected += f"; {named} is set in this file"
        where = str(set_in.get(named, "config"))
        raise ConfigError(err.name, err.value, expected, where, err.also) from None


def _scale_schedule(densify: DensifyConfig, keys, factor: float) -> None:
    """Scale the iteration counts `keys` of `densify` by `factor` (at least 1; 0 stays 0 and a
    negative value stays, for `Config.validate` to name)."""
    for key in keys:
        value = getattr(densify, key)
        setattr(densify, key, max(1, round(value * factor)) if value > 0 else value)


def _keep_a_round(densify: DensifyConfig, iterations: int) -> None:
    """A scaled schedule whose rounding left no multiple of `every` in start..stop (start = stop
    = 1000 every 100 at 500 of 3000 iterations: 167..167 every 17), or, with stop 0, a start past
    half the run (1500 at 1003: 502 > 501), densifies once: start no later than the last
    densifying iteration, stop at the first multiple of every from start. One whose first
    multiple of every from start falls at or past the run's last iteration, where no round falls
    (`Densifier.step`; 2700..3400 every 700, a round at 2800 of 3000, is 10..12 every 3 at 11),
    starts at the last multiple of every before the run's end (9) instead."""
    d = densify
    if d.every < 1 or not 0 <= d.start < iterations or d.stop < 0:
        return  # for validate to name
    last = d.last_iteration(iterations)
    if not d.stop and d.start == last + 1:  # round(start·f) against floor(iterations / 2)
        d.start = last
    first = d.first_iteration()
    end = min(last, iterations - 1)  # the last iteration a round may fall at
    if d.start <= last < first < iterations:
        d.stop = first
    elif d.start <= end < first and end >= d.every:  # (a multiple of every within 1..end)
        d.start = end // d.every * d.every


class ConfigError(ValueError):
    """A setting refused by `Config.validate`: `name` is its 'section.key', `where` the file that
    set it ('config' where none did), `also` the other settings the rule weighs it against."""

    def __init__(self, name: str, value, expected: str, where: str = "config", also=()):
        super().__init__(f"{where}: {name} = {value!r}, expected {expected}")
        self.name, self.value, self.expected, self.also = name, value, expected, tuple(also)


def _require(ok: bool, name: str, value, expected: str, also=()) -> None:
    if not ok:
        raise ConfigError(name, value, expected, also=also)


def _numbers(section, where: str = ""):
    """('section.key', value) of every float setting of dataclass `section`, nested ones too."""
    for f in dataclasses.fields(section):
        value = getattr(section, f.name)
        if dataclasses.is_dataclass(value):
            yield from _numbers(value, f"{where}{f.name}.")
        elif isinstance(value, float):
            yield f"{where}{f.name}", value


def _check_types(section, where: str = "") -> None:
    """ValueError for a setting of dataclass `section` (nested ones too) whose type is not its
    default's (an int where a float is expected is made a float): set as attributes or through
    load_config's `iterations`, a float count ran a fraction of a step and saved a config that
    could not be read back."""
    defaults = type(section)()
    for f in dataclasses.fields(section):
        value, default = getattr(section, f.name), getattr(defaults, f.name)
        if dataclasses.is_dataclass(value):
            _check_types(value, f"{where}{f.name}.")
        elif isinstance(default, float) and is_number(value) and type(value) is not float:
            setattr(section, f.name, float(value))  # an int or a numpy float
        elif isinstance(default, int) and not isinstance(default, bool) and is_int(value):
            setattr(section, f.name, int(value))  # a numpy integer
        elif type(value) is not type(default):
            raise ValueError(
                f"config: '{where}{f.name}' = {value!r} is a {type(value).__name__}, expected "
                f"{type(default).__name__}"
            )


# a config value's kind in words, for the messages that name what a key expects and what it holds
KIND_WORDS = {
    bool: "true or false",
    int: "an integer",
    float: "a number",
    str: "text",
    list: "a list",
    dict: "a section",
    type(None): "empty",
}


def _wrong_kind(key: str, value, expected: str) -> ValueError:
    """ValueError: config key `key` holds `value`, as YAML spells it (null, true, '20'), and its
    kind (a value of another type than KIND_WORDS' in Python's words), where `expected` goes."""
    kind = KIND_WORDS.get(type(value), type(value).__name__)
    found = yaml_text(value) + ("" if isinstance(value, bool) else f" ({kind})")  # (true says it)
    quote = ""
    if isinstance(value, bool) and expected == KIND_WORDS[str]:
        quote = " (YAML reads an unquoted yes, no, on or off as true or false: quote the text)"
    return ValueError(f"config: '{key}' = {found}, expected {expected}{quote}")


def _apply(target, overrides: dict, where: str, file_keys: tuple[str, ...] = ()) -> None:
    """Set the fields of dataclass `target` from `overrides`, section by section, checking types;
    `file_keys`: the keys a YAML file takes beside the fields (`base`), named among the known."""
    known = {f.name: f for f in dataclasses.fields(target)}
    for key, value in overrides.items():
        if key not in known:
            names = ", ".join([*known, *file_keys])
            raise ValueError(f"config: unknown key '{where}{key}'; known keys: {names}")
        current = getattr(target, key)
        if dataclasses.is_dataclass(current):
            if not isinstance(value, dict):
                raise _wrong_kind(f"{where}{key}", value, "a section (its keys, indented below it)")
            _apply(current, value, f"{where}{key}.")
            continue
        if isinstance(value, np.generic):  # a sweep's np.linspace value: yaml_text raised on it
            value = value.item()
        kind = type(current)
        if kind is float and is_int(value):
            if not is_number(value):  # float() raised OverflowError
                raise ValueError(f"config: '{where}{key}' = {past_float(value)}")
            value = float(value)
        if type(value) is not kind:
            words = CHOICES.get(f"{where}{key}")  # (then no word of the YAML's true is one)
            expected = f"one of {', '.join(words)}" if words else KIND_WORDS[kind]
            raise _wrong_kind(f"{where}{key}", value, expected)
        setattr(target, key, value)


def available_methods() -> list[str]:
    return sorted(p.stem for p in CONFIG_DIR.glob("*.yaml"))


def load_config(
    name_or_path: str | Path | None = None,
    overrides: dict | None = None,
    iterations: int | None = None,
    *,
    saved_run: bool = False,
) -> Config:
    """The configuration of a method name (configs/NAME.yaml) or a YAML file (None: the default
    method, DEFAULT_METHOD), with `overrides` (nested dicts) applied, validated. `iterations`
    (`--iterations`) sets the run's length as `Config.with_iterations` does, in one rounding with
    the scaling of the schedule keys (SCHEDULE_KEYS): each from the length it was given for, the
    train.iterations set beside it in its file or in `overrides`, else the one its base (the
    file, for `overrides`) sets, else the default length (`{"densify": {"start": 100}}` at
    iterations=20 starts at 1). `saved_run`: the file is a
    run's own config.yaml, which keeps its method's name with that method's settings of the day."""
    config = Config()
    name = DEFAULT_METHOD if name_or_path is None else name_or_path
    read = _read(name, set(), saved_run=saved_run)
    if overrides:
        _layer(read, copy.deepcopy(overrides))
        # a key the overrides set is theirs, not the file's (a refusal named the file)
        set_in = read.get(SET_IN, {})
        for section, values in overrides.items():
            for key in values if isinstance(values, dict) else ():
                set_in.pop(f"{section}.{key}", None)
    lengths = read.get(LENGTHS, {})  # what each schedule key set was given for
    _apply(config, _settings(read), "")
    if iterations is not None:
        _require(is_count(iterations), "train.iterations", iterations, COUNTS)
        if not is_count(config.train.iterations):  # the file's, replaced: refused all the same
            where = str(read.get(SET_IN, {}).get("train.iterations", "config"))
            raise ConfigError("train.iterations", config.train.iterations, COUNTS, where)
        config.train.iterations = iterations
    factors = {}
    for key in SCHEDULE_KEYS:  # unset keys are for the default length; each scaled once
        factors[key] = config.train.iterations / lengths.get(key, TrainConfig.iterations)
        _scale_schedule(config.densify, [key], factors[key])
    if any(factors[k] != 1 for k in ("start", "stop", "every")):  # a schedule as written stays
        _keep_a_round(config.densify, config.train.iterations)
    config._schedule_length = config.train.iterations
    config._set_in = {
        name: (path, config.setting(name)) for name, path in read.get(SET_IN, {}).items()
    }
    config = _validated_scaled(config, factors, read.get(SET_IN, {}))
    if not saved_run:  # (a run's config.yaml sets every key)
        warn_if_unread(config, read.get(SET_IN, {}))
    return config


def unread_settings(config: Config) -> dict[str, str]:
    """{'section.key': why} of the settings that a run of `config` never reads: SIM's without
    SIM targets, the exposure loss's at exposure_weight 0, the instant loss's without an instant
    target (and TFI's and clean targets' window but as smooth L1's zone), deflicker and
    mask_defects where no target is made from the spikes, pose refinement's with it off (those
    it refuses unless at their defaults, as
    instant_window beside SIM targets, are left to `Config.validate`)."""
    s, instant = config.supervision, config.instant_target()
    unread = {}
    if instant != "sim":
        why = f"the instant target is {instant}: no SIM is trained"
        unread |= {f"sim.{f.name}": why for f in dataclasses.fields(SimConfig)}
    if s.exposure_weight == 0:
        why = "supervision.exposure_weight is 0: no exposure loss"
        keys = ("exposure_window", "exposure_poses", "exposure_norm")
        unread |= {f"supervision.{key}": why for key in keys}
    if s.instant == "none" or s.instant_weight == 0:  # (not where instant_until ends it at once)
        why = "no instant target"
        keys = ("instant_window", "instant_norm", "instant_until")
        unread |= {f"supervision.{key}": why for key in keys}
    elif s.instant in ("tfi", "clean") and s.instant_norm != "smooth_l1":  # (TFI counts none)
        unread["supervision.instant_window"] = (
            f"the instant target {s.instant} counts no window: it sets smooth_l1's zone alone, "
            f"and supervision.instant_norm is {s.instant_norm}"
        )
    if instant in ("none", "clean") and s.exposure_weight == 0:  # (targets.build_targets)
        why = f"no target is made from the spikes (instant target {instant}, no exposure loss)"
        unread |= {f"supervision.{key}": why for key in ("deflicker", "mask_defects")}
    if s.exposure_weight == 0 or s.instant == "none" or s.instant_weight == 0:
        why = "one loss alone: its renders give the densification signal"
        unread["densify.instant_only"] = why
    if not config.pose_refine.enabled:
        unread["pose_refine.lr"] = "pose_refine.enabled is false"
    elif config.pose_refine.lr == 0:  # (enabled, no pose moved: unsaid)
        unread["pose_refine.enabled"] = "pose_refine.lr is 0: no pose is refined"
    if config.train.sh_degree == 0:
        unread["lr.sh_rest"] = "train.sh_degree is 0: no coefficients beyond the DC's"
    if config.lr.means == 0:  # (`train._means_lr`)
        unread["lr.means_final"] = "lr.means is 0: the means do not move, nothing decays"
    return unread | _unread_densify(config.densify, config.train.iterations)


RESET_KEY = "densify.opacity_reset_every"  # unread where no reset falls: as 0, which it changes


def _unread_densify(d: DensifyConfig, iterations: int) -> dict[str, str]:
    """{'densify.key': why} of the densification settings that a run of `iterations` never
    reads: the rounds' where none falls in the run, opacity_reset_every where no reset does (the
    first, at that iteration, at or past densification's end or within a period of the run's
    end: `Densifier._resets_opacity`), and max_screen_size where no round follows a reset
    (`Densifier._after_first_reset`)."""
    unread, stop, last = {}, d.last_iteration(iterations), d.last_round(iterations)
    if not last:
        why = (
            f"no densification round falls in the run's {iterations} iterations (densify.start "
            f"{d.start}, every {d.every}, to {stop})"
        )
        keys = ("grad_threshold", "percent_dense", "min_opacity", "max_gaussians", "absgrad")
        unread |= {f"densify.{key}": why for key in (*keys, "instant_only", "max_screen_size")}
    every = d.opacity_reset_every
    if every and not (every < stop and 2 * every <= iterations):
        unread[RESET_KEY] = (
            f"no opacity reset falls in the run: the first, at iteration {every}, must come "
            f"before densification's end ({stop}) with a period of the run's {iterations} "
            f"iterations left after it; so it trains as 0 does, resets off, removing the base's "
            f"where they fall in the run"
        )
    # (max_world_size prunes there too, and caps the initial Gaussians' size: read)
    if last and (not every or RESET_KEY in unread or last <= every):
        unread["densify.max_screen_size"] = (
            "size pruning is done by the densification rounds after the first opacity reset, "
            "and none follows one"
        )
    return unread


def warn_if_unread(config: Config, set_in: dict[str, Path]) -> None:
    """A UserWarning naming the settings that a config file changes from what it starts from
    (`set_in`: 'section.key' → the file) and a run of `config` never reads (`unread_settings`),
    with why: they were accepted and written to the run's config.yaml as if they had trained it
    (sim: keys beside `base: tfp33`)."""
    unread = unread_settings(config)
    found = {key: path for key, path in set_in.items() if key in unread}
    if not found:
        return
    reasons = {}
    for key in sorted(found):
        reasons.setdefault(unread[key], []).append(key)
    files = ", ".join(sorted({str(path) for path in found.values()}))
    # (a reset period no reset of which falls in the run is unread as 0 is: it can change what
    # the base trained, the others nothing: "they change nothing" was said of it, the stability
    # trial's run losing the default's reset and 4.1 dB)
    unchanged = "They change nothing" if RESET_KEY not in found else "The others change nothing"
    warnings.warn(
        f"config file {files} sets what method '{config.method}' never reads: "
        + "; ".join(f"{', '.join(keys)} ({why})" for why, keys in reasons.items())
        + (f". {unchanged}" if set(found) != {RESET_KEY} else ""),
        stacklevel=3,
    )


def warn_if_schedule_unscaled(config: Config) -> None:
    """A UserWarning, to the caller's caller, where train.iterations was set after the
    densification schedule (a script's `config.train.iterations = 300` on a config `load_config`
    made for 3000) and no round of it falls in the run: such a run trained without
    densification, unsaid (`--iterations`, `load_config(iterations=)` and `with_iterations`
    scale the schedule to the length)."""
    d, iterations, length = config.densify, config.train.iterations, config._schedule_length
    if iterations == length or d.last_round(iterations):
        return
    warnings.warn(
        f"train.iterations = {iterations} was set after the densification schedule, which is "
        f"for {length} iterations (densify.start {d.start}, every {d.every}): no round of it "
        f"falls in the run, which trains without densification. load_config(..., "
        f"iterations={iterations}), or config.with_iterations({iterations}) in place of setting "
        f"train.iterations, scales the schedule to the run's length (a run meant to train "
        f"without densification: densify.start set to train.iterations or more after that)",
        stacklevel=3,
    )


def warn_if_nothing_learns(config: Config) -> None:
    """A UserWarning, to the caller's caller, where the learning rate of every parameter a run of
    `config` updates is 0 (sh_rest's counts only at sh_degree > 0, pose_refine's only where it
    is enabled; means_final only decays lr.means): such a run trained to its end unsaid, no step
    moving anything."""
    rates = {f"lr.{f.name}": getattr(config.lr, f.name) for f in dataclasses.fields(config.lr)}
    del rates["lr.means_final"]
    if config.train.sh_degree == 0:  # no coefficients beyond the DC's
        del rates["lr.sh_rest"]
    if config.pose_refine.enabled:
        rates["pose_refine.lr"] = config.pose_refine.lr
    if not any(rates.values()):
        warnings.warn(
            f"{', '.join(rates)}: every learning rate is 0, so no step changes a parameter "
            f"(densification alone clones, splits and prunes the Gaussians, and its opacity "
            f"resets lower their opacities); 3DGS's are "
            f"1e-4..5e-2",
            stacklevel=3,
        )


def _own_name(path: Path, inherited: str | None, given: str | Path) -> str:
    """The method name of a file that names none: its stem as `given` (a link's own: the file it
    points to named the method), `path` the file itself; a built-in method's name only for a
    file that starts from that method (`inherited`: its base's method), else it would train under
    a name whose settings it lacks."""
    stem = Path(given).stem
    builtin = CONFIG_DIR / f"{stem}.yaml"
    if builtin.exists() and builtin.resolve() != path.resolve() and inherited != stem:
        raise ValueError(
            f"config file {path} is named like the built-in method '{stem}' but does not "
            f"start from it: add 'base: {stem}' to change that method's other settings (not "
            f"its supervision or SIM settings, which make it that method), or 'method: NAME' "
            f"to name yours"
        )
    return stem


def differences(first: dict, second: dict, labels: tuple[str, str], prefix: str = "") -> list[str]:
    """'key: first LABEL0, second LABEL1' for every setting of two nested config dicts that
    differs."""
    out = []
    for key in sorted(set(first) | set(second)):
        a, b = first.get(key), second.get(key)
        if isinstance(a, dict) and isinstance(b, dict):
            out += differences(a, b, labels, f"{prefix}{key}.")
        elif a != b:
            out.append(f"{prefix}{key}: {a!r} {labels[0]}, {b!r} {labels[1]}")
    return out


def _check_named(path: Path, read: dict) -> None:
    """ValueError where a file's method (its own `method: NAME`, or its name: `read` is the file
    with its base chain) is a built-in method whose supervision (and SIM, where it uses one) it
    does not have: it would train under that name without that method's settings. (A copy of
    the method's file and a file with `base: NAME` and another length or learning rate keep the
    name.)"""
    name = read["method"]
    builtin = CONFIG_DIR / f"{name}.yaml" if isinstance(name, str) and name else None
    if builtin is None or not builtin.is_file() or builtin.resolve() == path.resolve():
        return
    mine, theirs = Config(), Config()
    _apply(mine, _settings(read), "")
    _apply(theirs, _settings(_read(builtin, set())), "")
    uses_sim = mine.supervision.instant == "sim"
    sections = ("supervision", "sim") if uses_sim else ("supervision",)
    changed = differences(
        {k: dataclasses.asdict(getattr(mine, k)) for k in sections},
        {k: dataclasses.asdict(getattr(theirs, k)) for k in sections},
        ("in the file", f"in {name}"),
    )
    if changed:
        raise ValueError(
            f"config file {path}: method '{name}' is a built-in method, whose supervision and "
            f"SIM settings the file changes ({'; '.join(changed)}): start from it ('base: "
            f"{name}') without changing them, or name yours otherwise"
        )


def _read(
    name_or_path: str | Path, seen: set, relative_to: Path | None = None, saved_run: bool = False
) -> dict:
    """The overrides of a config file, with its `base` chain resolved (base first); a relative
    file path is taken from `relative_to` (the including file's directory), else from the
    current directory. `saved_run` as in `load_config`."""
    path = _config_path(name_or_path, relative_to)
    if path in seen:
        raise ValueError(f"config: 'base' chain loops at {path}")
    try:
        data = read_yaml(path) or {}
    except NotText as err:  # (the file named once)
        raise ValueError(f"{path}: not readable as YAML: {err.detail}") from None
    except yaml.YAMLError as err:
        raise ValueError(f"{path}: not readable as YAML: {err}") from None
    if not isinstance(data, dict):
        raise ValueError(f"{path}: expected a mapping at the top level")
    has_base = "base" in data  # an empty `base:` trained the defaults under the file's name
    base = data.pop("base", None)
    if has_base and (not isinstance(base, str) or not base.strip()):
        unset = " (without a base, leave the key out: the dataclass defaults)" * (base is None)
        raise ValueError(
            f"{path}: base = {yaml_text(base)}, expected a method name or a YAML file{unset}"
        )
    try:  # each file's keys and types where it sets them: a typo in a base named with its file
        _apply(Config(), data, "", file_keys=("base",))
    except ValueError as err:
        raise ValueError(f"{path}: {str(err).removeprefix('config: ')}") from None
    merged = {}
    if base:
        try:
            base_path = _config_path(base, path.parent)
        except (ValueError, FileNotFoundError) as err:  # it named the base, not the file naming it
            raise type(err)(f"{path}: base: {err}") from None
        merged = _read(base_path, seen | {path})
    if not seen and "method" not in data:  # the file given names no method: its own name
        data["method"] = _own_name(path, merged.get("method"), name_or_path)
    if path.parent != CONFIG_DIR.resolve():  # a user's file: what it changes, for warn_if_unread
        inherited = Config()
        _apply(inherited, _settings(merged), "")
        length = _length(data) or _length(merged) or TrainConfig.iterations  # its keys' (`_layer`)
        lengths = merged.get(LENGTHS, {})

        def changes(section: str, key: str, value) -> bool:
            """Whether the file's `value` changes what `inherited` trains: a schedule key by the
            fraction of its run (opacity_reset_every: 1000 beside iterations: 60 turned off the
            base's resets, unsaid, where 999 was warned of)."""
            was = getattr(getattr(inherited, section), key)
            if section == "densify" and key in SCHEDULE_KEYS:
                return value * lengths.get(key, TrainConfig.iterations) != was * length
            return value != was

        merged.setdefault(SET_IN, {}).update(
            {
                f"{section}.{key}": path
                for section, values in data.items()
                if isinstance(values, dict)
                for key, value in values.items()
                if changes(section, key, value)
            }
        )
    _layer(merged, data)
    if not seen and not saved_run:  # named, or named after itself like a built-in method
        _check_named(path, merged)
    return merged


def _config_path(name_or_path: str | Path, relative_to: Path | None) -> Path:
    """The resolved path of a config file (`~` its user's home; relative to `relative_to`, else
    to the current directory) or a built-in method's name; ValueError or FileNotFoundError
    naming it."""
    path = Path(name_or_path)
    if path.suffix.lower() not in (".yaml", ".yml"):  # (MINE.YAML too)
        if len(path.parts) > 1 or path.suffix:  # a file's path, not a method's name
            raise ValueError(f"config file {path}: expected a .yaml or .yml file")
        path = CONFIG_DIR / f"{name_or_path}.yaml"
        if not path.exists():
            raise ValueError(
                f"unknown method '{name_or_path}'; known methods: {', '.join(available_methods())}"
            )
    else:
        with contextlib.suppress(RuntimeError):  # ~/FILE.yaml: the home's (where one is known)
            path = path.expanduser()
        if relative_to is not None and not path.is_absolute():
            path = relative_to / path
    if not path.exists():
        raise FileNotFoundError(f"config file not found: {path}")
    if not path.is_file():
        raise ValueError(f"config file {path}: not a file")
    return path.resolve()


# Keys added with a default unlike the behaviour before them: a run's config saved without one
# was trained with this value (densify.absgrad: the plain gradient, before AbsGS, 2026-11-24;
# densify.instant_only: the whole step's signal, before 2026-11-25; supervision.instant_until:
# both losses to the end, before 2026-11-29, as the dataclass default still is but spikegs not;
# supervision.deflicker: the targets as the spikes showed them, before 2026-12-01;
# supervision.mask_defects: every pixel in the losses, before 2026-12-01, fifty-second session).
LEGACY_VALUES = {
    "densify": {"absgrad": False, "instant_only": False},
    "supervision": {"instant_until": "run", "deflicker": False, "mask_defects": False},
}


def legacy_overrides(saved: dict | Path) -> dict:
    """The LEGACY_VALUES of the keys that a saved run config (a dict, or its YAML file) lacks."""
    if isinstance(saved, Path):
        saved = _read(saved, set(), saved_run=True)
    return {  # a section that is not one (null, a number) is left to load_config, which says so
        section: missing
        for section, values in LEGACY_VALUES.items()
        if isinstance(saved.get(section, {}), dict)
        and (missing := {k: v for k, v in values.items() if k not in saved.get(section, {})})
    }


# the share of the config's keys a file sets to be taken for a run's config.yaml: today's sets
# them all, an earlier version's all but those added since (LEGACY_VALUES' and others)
SAVED_RUN_SHARE = 0.75


def older_run_keys(doc: dict) -> dict:
    """{"section.key": value} of the LEGACY_VALUES keys that a config file's dict lacks where it
    sets most keys of the config (SAVED_RUN_SHARE), as an earlier version's run config.yaml
    does: that run trained with those values, while a config file takes today's defaults."""
    keys = {
        name: {f.name for f in dataclasses.fields(part)}
        for name, part in vars(Config()).items()
        if dataclasses.is_dataclass(part)
    }
    sections = {name: doc[name] for name in keys if isinstance(doc.get(name), dict)}
    given = sum(len(keys[name] & set(values)) for name, values in sections.items())
    if given < SAVED_RUN_SHARE * sum(map(len, keys.values())):
        return {}
    return {
        f"{name}.{key}": value
        for name, legacy in LEGACY_VALUES.items()
        if name in sections
        for key, value in sorted(legacy.items())
        if key not in sections[name]
    }


def load_saved_run(path: Path, overrides: dict | None = None, iterations: int | None = None):
    """A run's own config.yaml (`path`) as the run trained: the keys added since it was saved at
    the values that kept its behaviour (LEGACY_VALUES), then `overrides` and `iterations` as in
    `load_config`; ValueError naming the file where its own settings are refused now (a
    schedule that never densified, which an earlier spikegs accepted), else the error of
    `overrides` or `iterations`."""
    legacy = legacy_overrides(path)
    try:
        return load_config(path, {**legacy, **(overrides or {})}, iterations, saved_run=True)
    except ValueError as err:  # (a never-densifying schedule, accepted before 2026-12-01)
        try:
            load_config(path, legacy, saved_run=True)
        except ValueError:
            pass
        else:
            raise  # the run's settings load: the caller's overrides are refused
        raise ValueError(
            f"{path}: the run's own settings, of the spikegs that trained it, are refused now: "
            f"{err}. A run resumes from its checkpoint with the settings it trained with alone: "
            f"train afresh into another --out, with settings accepted now"
        ) from None


def with_defaults(saved: dict) -> dict:
    """A config dict saved by an earlier version, with the keys added since filled in: by the
    value that kept its behaviour (LEGACY_VALUES), else by their defaults (which keep it)."""
    full = Config().to_dict()
    _merge(full, legacy_overrides(saved))
    _merge(full, saved)
    return full


# a merged config dict's record of the train.iterations each schedule key it sets was given for
LENGTHS = "_schedule_lengths"
# its record of the file (not a built-in method's) that sets each 'section.key', where one does
SET_IN = "_set_in"


def _length(layer: dict) -> int | None:
    """The train.iterations a config layer sets, where it is a valid one."""
    train = layer.get("train")
    value = train.get("iterations") if isinstance(train, dict) else None
    return value if is_int(value) and value >= 1 else None


def _layer(into: dict, layer: dict) -> None:
    """Merge a config layer (a file over its base chain, overrides over a file) into `into`,
    recording under LENGTHS the length its schedule keys are for: its own train.iterations, else
    the one it inherits (load_config scales each key from there to the run's, once)."""
    own = layer.get("densify") if isinstance(layer.get("densify"), dict) else {}
    length = _length(layer) or _length(into) or TrainConfig.iterations
    lengths = into.setdefault(LENGTHS, {})
    lengths.update({key: length for key in SCHEDULE_KEYS if key in own})
    _merge(into, layer)


def _settings(merged: dict) -> dict:
    """A merged config dict without its LENGTHS and SET_IN records."""
    return {k: v for k, v in merged.items() if k not in (LENGTHS, SET_IN)}


def _merge(into: dict, update: dict) -> None:
    for key, value in update.items():
        if isinstance(value, dict) and isinstance(into.get(key), dict):
            _merge(into[key], value)
        else:
            into[key] = value
