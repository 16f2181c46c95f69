"""Spike camera simulator: intensity frames (or a renderer callable) to packed spikes.

The model (C++, csrc/core/spike_simulator.hpp): integrate-and-fire per pixel at the readout rate
(τ = 25 µs), light linearly interpolated in time between two frames, threshold θ, reset by
subtraction, at most one spike per readout, with photon shot noise, dark current, fixed-pattern
and temporal threshold noise and a random initial voltage. Intensity 1.0 fires `rate_at_one`
spikes per readout; the long-run rate is linear in intensity up to saturation at 1 per readout
(a large temporal threshold noise bends it down near saturation: at 0.75 spikes a readout,
temporal_sigma 0.01, the default, 0.0 %, 0.5 −2.5 %, 1 −8 %; at 0.25, none; and the shot
noise, against the cap on the charge carried over, where a spike is few photo-electrons:
without temporal noise, θ = 10 −0.6 % at 0.75, −5.3 % at 0.99; θ = 100, the default, −0.5 %
at 0.99 only). Deterministic for a seed, whatever the thread count or chunk size.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import numbers
import os
import warnings
from collections.abc import Callable

import numpy as np
from scipy.special import ndtri

from .. import _C
from ..number_checks import as_flag, is_int, is_number, is_seed, number_array, past_float
from .stream import DatWriter, PathLike, SpikeStream, check_chunk

_CORE_DEFAULTS = _C.SimParams()
Source = np.ndarray | Callable[[float], np.ndarray]


MAX_LIGHT_TIMES = 1e8  # a callable's sampling times: 0.8 GB (a frame every 1e-7 readouts: 24 GB)

# the smallest threshold (photo-electrons a spike) at which the normal form of shot noise keeps
# the firing rate within 0.5% of rate_at_one·I at the default rate_at_one (I up to 1.5)
MIN_SHOT_THRESHOLD = 2.0
# under it, the rates' error is measured at these intensities over so many pixels and readouts
# (12,800 spikes at I = 0.05 and the default rate_at_one: ~1 % statistical error)
BIAS_INTENSITIES, BIAS_PIXELS, BIAS_READOUTS = (1.0, 0.05), 256, 4000
# a fixed-pattern spread whose mean gain over the pixels, θ/θ_i, is off 1 by more than this
# (fpn_sigma 0.2: +4.6 %, 0.25: +8.1 %, 5: x4.6) is warned of: the rates leave rate_at_one·I;
# so is a dark current's spread whose pixels' mean is (`dark_gain`)
FPN_GAIN_TOLERANCE = 0.05


def _param(name: str, meaning: str):
    """A SimParams field: the core's default, and what it means (the CLI's help)."""
    return dataclasses.field(default=getattr(_CORE_DEFAULTS, name), metadata={"help": meaning})


@dataclasses.dataclass(frozen=True)
class SimParams:
    """Simulator parameters; the defaults are the C++ core's (spike_simulator.hpp). Frozen, so
    that every value is checked: `dataclasses.replace(params, rate_at_one=0.5)` for another
    (a field set afterwards skipped the checks: "0.5" reached the core as a string)."""

    threshold: float = _param("threshold", "photo-electrons a spike θ (shot noise ~ 1/√θ)")
    rate_at_one: float = _param("rate_at_one", "spikes a readout at intensity 1.0")
    dark_rate: float = _param("dark_rate", "mean dark spikes a readout (5e-4 = 20 Hz)")
    dark_sigma: float = _param("dark_sigma", "log-normal spread of the dark current over pixels")
    fpn_sigma: float = _param("fpn_sigma", "fixed-pattern threshold mismatch, relative std")
    temporal_sigma: float = _param("temporal_sigma", "threshold noise a readout, relative std")
    shot_noise: bool = _param("shot_noise", "photon shot noise on the charge")
    random_init: bool = _param("random_init", "initial voltage uniform in [0, θ_i), else 0")

    def __post_init__(self):
        """ValueError naming a field of the wrong type or out of range (the core's ranges, checked
        here so that an error comes before any work)."""
        for field in dataclasses.fields(self):
            value, flag = getattr(self, field.name), field.type in (bool, "bool")
            if flag:
                value = as_flag(f"SimParams {field.name}", value)
            else:
                if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
                    raise ValueError(f"SimParams {field.name}: expected a number, found {value!r}")
                try:
                    value = float(value)
                except OverflowError:  # (10**400: float()'s message named no field)
                    raise ValueError(
                        f"SimParams {field.name}: expected a number, found {past_float(value)}"
                    ) from None
            object.__setattr__(self, field.name, value)  # (frozen)
        _C.SpikeSimulator(1, 1, self.to_core(), 0)  # validates the ranges
        if self.shot_noise and self.threshold < MIN_SHOT_THRESHOLD:
            errors = ", ".join(
                f"{error:+.0%} at I = {i:g}" for i, error in zip(BIAS_INTENSITIES, rate_bias(self))
            )
            warnings.warn(
                f"SimParams threshold {self.threshold:g}: under {MIN_SHOT_THRESHOLD:g} "
                f"photo-electrons a spike, the simulator's normal form of shot noise (which can "
                f"take charge away, or add more than a spike's) distorts the firing rates: "
                f"measured {errors} against rate_at_one·I (the dark current's rate likewise)",
                stacklevel=3,
            )

        gain = fpn_gain(self.fpn_sigma)
        if abs(gain - 1) > FPN_GAIN_TOLERANCE:
            warnings.warn(
                f"SimParams fpn_sigma {self.fpn_sigma:g}: pixels whose thresholds spread as "
                f"θ·max(1 + fpn_sigma·z, 0.1) fire {gain:.3g} times rate_at_one·I on average "
                f"(their mean θ/θ_i), so the spikes leave the test images' units; a spread "
                f"under ~0.2 keeps that within {FPN_GAIN_TOLERANCE:.0%}",
                stacklevel=3,
            )

        gain = dark_gain(self.dark_sigma)
        if self.dark_rate > 0 and abs(gain - 1) > FPN_GAIN_TOLERANCE:  # (1e308: none, unsaid)
            warnings.warn(
                f"SimParams dark_sigma {self.dark_sigma:g}: a dark current spread so widely "
                f"over the pixels lies in the few of its far tail, and 20,000 pixels fire "
                f"{gain:.3g} times dark_rate's dark spikes on average (most pixels none); a "
                f"spread under ~2.7 keeps that within {FPN_GAIN_TOLERANCE:.0%}",
                stacklevel=3,
            )

    def to_core(self) -> _C.SimParams:
        core = _C.SimParams()
        for field in dataclasses.fields(self):
            setattr(core, field.name, getattr(self, field.name))
        return core


@functools.cache
def _normal_quantiles() -> np.ndarray:
    """The standard normal's quantiles [20000] at the midpoints of 20,000 equal probability bins:
    a mean over them is a mean over that many pixels' draws, without their sampling noise."""
    z = ndtri((np.arange(20000) + 0.5) / 20000)
    z.flags.writeable = False  # (one array for every caller)
    return z


def fpn_gain(fpn_sigma: float) -> float:
    """The pixels' mean firing-rate gain θ/θ_i under fixed-pattern threshold mismatch,
    θ_i = θ·max(1 + fpn_sigma·z, 0.1) with z standard normal (`_normal_quantiles`' mean)."""
    return float(np.mean(1 / np.maximum(1 + fpn_sigma * _normal_quantiles(), 0.1)))


def dark_gain(dark_sigma: float) -> float:
    """The pixels' mean dark current over dark_rate, dark_i = dark_rate·exp(dark_sigma·z -
    dark_sigma²/2) (`_normal_quantiles`' mean): 1 in expectation, but a wide spread puts it in
    the few pixels of the far tail, and 20,000 pixels' mean falls short (2.5: 0.97, 3: 0.92,
    5: 0.25)."""
    with np.errstate(over="ignore"):  # (1e308: -inf, a gain of 0)
        return float(np.mean(np.exp(dark_sigma * (_normal_quantiles() - dark_sigma / 2))))


def rate_bias(params: SimParams) -> list[float]:
    """The simulated firing rate's relative error against rate_at_one·I at each of
    BIAS_INTENSITIES under `params`, the shot noise's alone (no dark current, fixed-pattern or
    temporal noise), over BIAS_PIXELS pixels and BIAS_READOUTS readouts."""
    core = params.to_core()
    core.dark_rate = core.fpn_sigma = core.temporal_sigma = 0.0
    light = np.repeat(np.float32(BIAS_INTENSITIES)[:, None], BIAS_PIXELS, axis=1)  # [I, P]
    sim = _C.SpikeSimulator(len(BIAS_INTENSITIES), BIAS_PIXELS, core, 0)
    packed = sim.run(light[None], np.zeros(1), BIAS_READOUTS)  # [T, I, P / 8]: whole bytes
    rates = np.unpackbits(packed, axis=-1).mean(axis=(0, 2))  # [I] spikes a readout
    expected = np.minimum(params.rate_at_one * np.asarray(BIAS_INTENSITIES), 1.0)
    return (rates / expected - 1).tolist()


FLOAT32_MAX = float(np.finfo(np.float32).max)


_CHECKED_VALUES = 16 << 20  # light values checked at a time by _checked_frame
# the frames a chunk of readouts may hold, in bytes of float32 light: fewer readouts a chunk where
# the frames are large (1080x1920 rendered every 2 readouts: 129 frames a 256-readout chunk, 1.1 GB
# mono, 3.2 GB colour, and one channel's stack of them as much again); a chunk holds 2 at least
CHUNK_LIGHT_BYTES = 256 << 20
# more of the light than this share at or above 1/rate_at_one, where a pixel fires every readout,
# is warned of: intensities in other units (8-bit codes as floats: 98 % of a random image's
# pixels saturated at the default rate_at_one, unsaid) by simulate_spikes; a bright scene's
# saturated pixels are the simulate command's to judge (its held-out views' 1 %)
SATURATED_SHARE = 0.5
SATURATED_SAMPLE = 4096  # values of a frame judged, at most: evenly strided (the whole light of
# a frame a readout, 128², took 10 % more time)
CHANNEL_LAST_SIZES = (1, 3, 4)  # an [H, W, C] image's last axis, read as [F, H, W] frames


def not_codes(light: np.ndarray, what: str) -> np.ndarray:
    """`light`; ValueError where `what` holds an image file's uint8 or uint16 codes, not light
    (255 taken as 255 times white)."""
    if light.dtype in (np.uint8, np.uint16):
        raise ValueError(
            f"{what} expected intensities (1.0 fires rate_at_one a readout), found "
            f"{light.dtype.name} codes: convert them to float and linear light first (an 8-bit "
            f"sRGB image: spikegs.image_io.srgb_to_linear(image / 255))"
        )
    return light


def _checked_frame(frame, shape: tuple | None, what: str) -> np.ndarray:
    """`frame` (an array or a torch tensor) as float32, ValueError unless real, of `shape` (if
    given), finite and >= 0. Light beyond float32's range (from float64) is taken at its largest
    value: the simulator caps it far below, where a pixel fires every readout."""
    if hasattr(frame, "detach"):  # a tensor, perhaps requiring grad or on another device
        frame = frame.detach().cpu()
        if frame.is_floating_point() and frame.dtype.itemsize < 4:  # bfloat16: none in numpy
            frame = frame.float()
        frame = frame.numpy()
    frame = np.asarray(frame)
    if frame.dtype.kind not in "biuf":
        raise ValueError(f"{what} expected real intensities, found {frame.dtype.name} values")
    not_codes(frame, what)
    if shape is not None and frame.shape != shape:
        raise ValueError(f"{what} expected shape {list(shape)}, found {list(frame.shape)}")
    flat = frame.ndim < 2 or frame.size == 0  # (a width of 0: reshape(-1, 0) is no shape)
    rows = frame.reshape(1, -1) if flat else frame.reshape(-1, frame.shape[-1])
    step = max(1, _CHECKED_VALUES // max(1, rows.shape[1]))  # rows a check (not the whole light
    for start in range(0, len(rows), step):  # at once: 2 bytes of masks a value, GBs of them)
        part = rows[start : start + step]
        bad = ~(np.isfinite(part) & (part >= 0)) if frame.dtype.kind == "f" else part < 0
        if bad.any():
            row, col = np.argwhere(bad)[0]
            where = np.unravel_index((start + row) * rows.shape[1] + col, frame.shape)
            raise ValueError(
                f"{what} expected finite intensities >= 0, found {part[row, col]} at "
                f"{list(map(int, where))}"
            )
    if frame.dtype.kind == "f" and frame.dtype.itemsize < 4:  # float16: exact in float32 (its
        frame = frame.astype(np.float32)  # minimum with FLOAT32_MAX overflowed, with a warning)
    if frame.dtype != np.float32:
        frame = np.minimum(frame, FLOAT32_MAX).astype(np.float32)
    return frame


def sample_times(num_readouts: int, frame_every: float) -> np.ndarray:
    """Readouts [F] at which the light is rendered: 0, frame_every, … below the last readout, and
    the last (a multiple that rounds onto it is not repeated)."""
    last = num_readouts - 1
    times = np.arange(0.0, last, frame_every)
    return np.append(times[times < last], float(last))


def checked_times(frame_times, count: int | None, last: int) -> np.ndarray:
    """`frame_times` as floats [F] (F = `count`, or any F >= 1 where None); ValueError unless
    finite, strictly increasing and covering readouts [0, last]."""
    try:
        times = number_array(frame_times)
    except ValueError as err:  # (it named no argument: 'expected numbers, found "ab" at []')
        raise ValueError(f"frame_times: {err}") from None
    if times.ndim != 1 or len(times) != (count or len(times)) or not len(times):
        expected = f"[{count}]" if count else "[F] with F >= 1"
        raise ValueError(f"frame_times expected {expected}, found {list(times.shape)}")
    if len(times) == 1:
        return times
    expected = f"frame times expected finite, strictly increasing and covering readouts [0, {last}]"
    if not np.isfinite(times).all():
        i = int(np.flatnonzero(~np.isfinite(times))[0])
        raise ValueError(f"{expected}, found a time that is not finite, {times[i]} at index {i}")
    if not (np.diff(times) > 0).all():
        i = int(np.flatnonzero(np.diff(times) <= 0)[0]) + 1
        raise ValueError(f"{expected}, found {times[i]} at index {i} after {times[i - 1]}")
    if not times[0] <= 0 <= last <= times[-1]:
        raise ValueError(f"{expected}, found {len(times)} times in [{times[0]}, {times[-1]}]")
    return times


def warn_unread_frames(times: np.ndarray, num_readouts: int) -> None:
    """A UserWarning where some of the frames at readouts `times` [F] (increasing) lie between
    two readouts and are never read: each readout interpolates the frame at or before it and the
    next (frames packed more densely than readouts were dropped unsaid by simulate_spikes)."""
    # frame i is the one at or before a readout r in [t_i, t_i+1), or the next of one in
    # (t_i-1, t_i), r in [0, num_readouts): counted over the frames, not the readouts (frame
    # times cover the readouts, the first at or before 0 and the last at or after the last)
    last = num_readouts - 1
    ends = np.append(times[1:], np.inf)  # [F]
    first = np.maximum(np.ceil(times), 0)  # [F] the first readout at or after each frame
    before = np.minimum(np.ceil(ends) - 1, last) >= first  # [F]
    after = np.minimum(np.ceil(times[1:]) - 1, last) >= np.maximum(np.floor(times[:-1]) + 1, 0)
    unread = int((~(before | np.append(False, after))).sum())
    if unread:
        warnings.warn(
            f"{unread} of {len(times)} light frames lie between two readouts "
            f"and are never read (each of the {num_readouts} readouts interpolates the frame "
            f"at or before it and the next): more readouts, or fewer frames",
            stacklevel=4,
        )


class _Frames:
    """The light: frames [F, H, W, C] at readout times [F], read lazily from an array or a
    callable (frames [F, H, W] and a callable's [H, W] given a channel axis when `channels` is
    None), so that each frame is read (rendered) once and only those lighting a chunk are held."""

    def __init__(
        self, source: Source, num_readouts: int, frame_times, frame_every: float, channels
    ):
        last = num_readouts - 1
        self._cache: dict[int, np.ndarray | None] = {}
        frame_ndim = 2 if channels is None else 3
        if callable(source):
            if not (is_number(frame_every) and frame_every > 0):
                raise ValueError(f"frame_every expected a finite number > 0, found {frame_every}")
            if frame_times is None:
                if (num_readouts - 1) / frame_every > MAX_LIGHT_TIMES:  # 8 bytes a time
                    raise ValueError(
                        f"frame_every {frame_every:g} samples the light {num_readouts - 1:.0f} "
                        f"/ {frame_every:g} times, over {MAX_LIGHT_TIMES:.0e}: a larger "
                        f"frame_every (each readout interpolates the two frames around it)"
                    )
                frame_times = sample_times(num_readouts, frame_every)
            self.times = checked_times(frame_times, None, last)  # [F]

            def render(i: int, shape=None) -> np.ndarray:
                t = float(self.times[i])
                return _checked_frame(source(t), shape, f"frame at t={t:.10g}")

            first = render(0)  # its shape: every frame's
            shape, read = first.shape, functools.partial(render, shape=first.shape)
        else:
            frames = _checked_frame(source, None, "frames")
            if frames.ndim != 1 + frame_ndim or len(frames) == 0:
                axes = "[F, H, W]" if channels is None else "[F, H, W, C]"
                raise ValueError(f"frames expected {axes} with F >= 1, found {list(frames.shape)}")
            # an image's rows outnumber its channels, and come without times
            image = frame_times is None and len(frames) > frames.shape[-1]
            if channels is None and frames.shape[-1] in CHANNEL_LAST_SIZES and image:
                count, height, width = frames.shape
                warnings.warn(
                    f"frames {list(frames.shape)} read as {count} frames of {height}x{width} "
                    f"pixels: an [H, W, C] image? One frame of one channel is image[None, ..., "
                    f"0] (a colour one: simulate_channels)",
                    stacklevel=3,
                )
            shape, read = frames.shape[1:], frames.__getitem__
            if frame_times is None:
                if len(frames) > 1 and last == 0:
                    raise ValueError(
                        f"{len(frames)} frames spread over 1 readout: give one frame, or "
                        f"frame_times"
                    )
                frame_times = np.linspace(0.0, last, len(frames)) if len(frames) > 1 else [0.0]
            self.times = checked_times(frame_times, len(frames), last)  # [F]
        if len(shape) != frame_ndim:
            axes = "[H, W]" if channels is None else f"[H, W, {channels}]"
            raise ValueError(f"frames expected {axes} each, found {list(shape)}")
        if channels is not None and shape[-1] != channels:  # (the frames were blamed)
            raise ValueError(
                f"frames of {shape[-1]} channels ({list(shape)} each) for {channels} outputs: "
                f"expected an output file and a seed for each channel"
            )
        warn_unread_frames(self.times, num_readouts)
        self.shape = shape if channels is not None else (*shape, 1)  # [H, W, C]
        self._get = read if channels is not None else lambda i: read(i)[..., None]
        if callable(source):  # its first frame rendered once: covering() finds it cached
            self._cache[0] = first if channels is not None else first[..., None]

    def _needed(self, t0: int, t1: int) -> np.ndarray:
        """The indices [f] of the frames that light readouts [t0, t1): the two around each
        readout, which it interpolates (with frames sampled more often than once a readout, those
        between are not read: a millionth of a readout apart, they filled the memory)."""
        i0 = max(int(np.searchsorted(self.times, t0, side="right")) - 1, 0)
        i1 = min(int(np.searchsorted(self.times, t1 - 1, side="left")), len(self.times) - 1)
        before = np.searchsorted(self.times, np.arange(t0, t1), side="right") - 1  # [t1 - t0]
        return np.unique(np.clip(np.concatenate([before, before + 1]), i0, i1))  # [f]

    def end_within(self, t0: int, t1: int, most: int) -> int:
        """The largest end t in (t0, t1] whose readouts [t0, t) are lit by at most `most` frames
        (`most` >= 2: one readout's two, t0 + 1 at least)."""
        if len(self._needed(t0, t1)) <= most:
            return t1
        lo, hi = t0 + 1, t1  # the frames of [t0, lo) fit, those of [t0, hi) do not
        while hi - lo > 1:
            mid = (lo + hi) // 2
            lo, hi = (mid, hi) if len(self._needed(t0, mid)) <= most else (lo, mid)
        return lo

    def covering(self, t0: int, t1: int) -> tuple[list[np.ndarray], np.ndarray]:
        """The f frames [H, W, C] and their times [f] that light readouts [t0, t1) (`_needed`)."""
        needed = self._needed(t0, t1)  # [f]
        self._cache = {int(i): self._cache.get(int(i)) for i in needed}
        for i, frame in self._cache.items():
            if frame is None:
                self._cache[i] = self._get(i)
        return list(self._cache.values()), self.times[needed]


def _checked_run(num_readouts, seeds: list, params, chunk) -> tuple[int, SimParams]:
    """`num_readouts` as an int and `params` (None: the defaults); ValueError naming a bad
    readout count, seed, params or chunk."""
    if not (is_int(num_readouts) and num_readouts >= 1):
        raise ValueError(f"num_readouts expected a positive int, found {num_readouts!r}")
    for seed in seeds:
        if not is_seed(seed):
            raise ValueError(f"seed expected an integer in 0..2**64 - 1, found {seed}")
    check_chunk(chunk)
    params = SimParams() if params is None else params
    if not isinstance(params, SimParams):
        raise ValueError(f"params expected a SimParams or None, found {type(params).__name__}")
    return int(num_readouts), params


def _spike_chunks(
    frames: _Frames,
    num_readouts: int,
    seeds: list,
    params: SimParams,
    chunk: int,
    warn_saturated: bool = False,
):
    """Yield (t0, t1, spikes) for each `chunk` readouts [t0, t1), fewer where their frames would
    hold more than CHUNK_LIGHT_BYTES: spikes [C] packed uint8 [t1 - t0, H, ceil(W/8)], channel c
    simulated with seed `seeds[c]` (the same spikes whatever the chunks). `warn_saturated`: a
    UserWarning at the end where over SATURATED_SHARE of the light fires every readout."""
    height, width, channels = frames.shape
    sims = [_C.SpikeSimulator(height, width, params.to_core(), int(s)) for s in seeds]
    saturated = np.float32(params.to_core().saturated_light)  # the most light the core takes
    most = max(2, CHUNK_LIGHT_BYTES // max(1, 4 * height * width * channels))  # frames a chunk
    every_readout = np.float32(1 / params.rate_at_one) if params.rate_at_one > 0 else np.inf
    above, values = 0, 0  # the held frames' sampled values at or above it, and all
    t0 = 0
    while t0 < num_readouts:
        t1 = frames.end_within(t0, min(t0 + chunk, num_readouts), most)
        held, times = frames.covering(t0, t1)
        for frame in held if warn_saturated else ():  # (one lighting several chunks: each)
            found, judged = _at_or_above(frame, every_readout)
            above, values = above + found, values + judged
        spikes = _chunk_spikes(sims, held, times, t1 - t0, saturated)
        del held  # (the next chunk's frames are read without this one's held here)
        yield t0, t1, spikes
        t0 = t1
    if values and above / values > SATURATED_SHARE:  # (counted where warn_saturated)
        warnings.warn(
            f"{above / values:.0%} of the light is at or above 1/rate_at_one = "
            f"{every_readout:.3g}, where a pixel fires every readout: intensities in other units? "
            f"(1.0 fires rate_at_one = {params.rate_at_one:g} a readout; an 8-bit image's codes "
            f"as floats: spikegs.image_io.srgb_to_linear(image / 255))",
            stacklevel=3,
        )


def _at_or_above(frame: np.ndarray, level) -> tuple[int, int]:
    """How many of `frame`'s values, about SATURATED_SAMPLE evenly strided (all of a smaller
    frame), are at or above `level`, and of how many."""
    sample = frame.reshape(-1)[:: max(1, frame.size // SATURATED_SAMPLE)]
    return int(np.count_nonzero(sample >= level)), sample.size


def _chunk_spikes(sims: list, held: list, times: np.ndarray, n: int, saturated) -> list:
    """Spikes [C] packed uint8 [n, H, ceil(W/8)]: `n` readouts of each channel's simulator
    `sims` [C] lit by frames `held` [f] of [H, W, C] at `times` [f] (capped at `saturated`)."""
    spikes = []
    for c, sim in enumerate(sims):  # a channel's light at a time: [f, H, W], a new array
        light = np.stack([frame[..., c] for frame in held])
        np.minimum(light, saturated, out=light)
        spikes.append(sim.run(light, times, n))
    return spikes


def simulate_spikes(
    source: Source,
    num_readouts: int,
    *,
    frame_times=None,
    frame_every: float = 1,
    out: PathLike | None = None,
    flip: bool = True,
    seed: int = 0,
    params: SimParams | None = None,
    chunk: int = 256,
) -> np.ndarray | SpikeStream:
    """Simulate `num_readouts` readouts of a spike camera.

    source: intensity frames [F, H, W] (1.0 fires `rate_at_one` per readout) shown at readouts
    `frame_times` [F] (default evenly over [0, num_readouts - 1]; one frame = constant light), or
    a callable t -> [H, W] sampled at `frame_times` if given, else at t = 0, frame_every,
    2·frame_every, ... and the last readout, each time once, as the simulation reaches it.
    The light between two frames is interpolated linearly per readout. Works `chunk` readouts at
    a time (fewer where their frames would hold over CHUNK_LIGHT_BYTES). With `out` a path,
    streams to a .dat file (rows flipped if `flip`) and returns `SpikeStream.open(out, ...)`;
    else returns packed uint8 [T, H, ceil(W/8)] (rows unflipped), which
    `SpikeStream.from_packed(packed, width=W)` reads. Intensities are floats (or bool and
    signed integers, at face value); uint8 and uint16, an image file's codes, are refused.
    """
    num_readouts, params = _checked_run(num_readouts, [seed], params, chunk)
    frames = _Frames(source, num_readouts, frame_times, frame_every, None)
    height, width, _ = frames.shape
    writer = DatWriter(out, height, width, flip) if out is not None else None
    packed = None if writer else np.empty((num_readouts, height, (width + 7) // 8), np.uint8)
    with writer or contextlib.nullcontext():
        chunks = _spike_chunks(frames, num_readouts, [seed], params, chunk, warn_saturated=True)
        for t0, t1, (spikes,) in chunks:
            if writer:
                writer.write_packed(spikes)
            else:
                packed[t0:t1] = spikes
    return SpikeStream.open(out, height, width, flip=flip) if writer else packed


def simulate_channels(
    source: Source,
    num_readouts: int,
    outs: list[PathLike],
    seeds: list[int],
    *,
    frame_times=None,
    frame_every: float = 1,
    flip: bool = True,
    params: SimParams | None = None,
    chunk: int = 256,
) -> None:
    """Simulate the C channels of a light, frames [F, H, W, C] or a callable t -> [H, W, C]
    (`simulate_spikes`'s times), into one .dat file each, `outs` [C], channel c with seed
    `seeds[c]`: each file the spikes `simulate_spikes` writes of that channel alone. Each frame
    is read (a callable's rendered) once, and only those lighting `chunk` readouts are held (fewer
    readouts where they would hold over CHUNK_LIGHT_BYTES): no light of the whole recording in
    memory or on disk."""
    if not outs or len(outs) != len(seeds):
        raise ValueError(
            f"expected a seed for each of 1 or more outputs, found {len(outs)} outputs and "
            f"{len(seeds)} seeds"
        )
    if len({os.path.realpath(out) for out in outs}) < len(outs):  # the last would win
        raise ValueError(f"outs: expected a file for each channel, found {list(map(str, outs))}")
    num_readouts, params = _checked_run(num_readouts, seeds, params, chunk)
    frames = _Frames(source, num_readouts, frame_times, frame_every, len(outs))
    height, width, _ = frames.shape
    with contextlib.ExitStack() as stack:  # an error discards every file written so far
        writers = [stack.enter_context(DatWriter(out, height, width, flip)) for out in outs]
        for _, _, spikes in _spike_chunks(frames, num_readouts, seeds, params, chunk):
            for writer, channel in zip(writers, spikes):
                writer.write_packed(channel)
