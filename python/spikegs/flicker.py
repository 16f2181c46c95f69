"""Lighting flicker: mains lighting modulates the light at 100 or 120 Hz (twice 50 or 60 Hz), a
period of 167-400 readouts at a 20-40 kHz readout. Found as a sinusoid in a stream's spikes per
frame, it is taken out of the training targets (each divided by the modulation over its readouts),
out of a pseudo ground truth made from the spikes and out of the images sim-train scores: left in,
the views' brightness follows the flicker's phase along the path and 3DGS fits it as geometry
(BENCHMARKS.md, "Lighting flicker").
"""

from __future__ import annotations

import functools
import hashlib
import json
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import scipy
from tqdm.auto import tqdm

from . import _C
from .cache_home import CACHED_FROM, cache_home, write_cached
from .found_once import found_once
from .interrupt import progress_lost, quiet_close
from .number_checks import is_number
from .spikes.stream import SpikeStream

PERIODS = (80.0, 420.0)  # readouts searched: 100-120 Hz at 20-40 kHz, and 240 Hz (a harmonic)
BEYOND = 1.1  # a peak within this factor past PERIODS is a flicker outside them, not one in them
EDGE = 1.01  # but for one within this factor, the spread of a peak's refinement at the edge
# a sinusoid of a depth (relative amplitude) below MIN_DEPTH, or under PEAK times the median of
# the periodogram over PERIODS, is no flicker: on the built-in scenes the camera's motion gives
# depths up to 0.01 there (BENCHMARKS.md, "Lighting flicker")
MIN_DEPTH, PEAK = 0.03, 8.0
# nor is one that fewer than IN_PHASE of the lit ones of GRID x GRID regions of the frame share
# (in phase): a light's flicker brightens the whole frame at once, an orbit's repeating view
# (solids at 0.6° a readout: 180° every 299 readouts, depth 0.075) brightens some regions as it
# darkens others (9 of 16 in phase, against 16 of 16 for a flicker of depth 0.1)
GRID, IN_PHASE, LIT = 4, 0.9, 0.1  # lit: spikes over LIT times the regions' mean
# a sinusoid this deep or deeper takes the light to none or below: not the model, so not divided
# out (a light switched on and off, as by an LED's PWM dimming, fits 1.26 at half on, 1.69 at 30 %)
MAX_DEPTH = 1.0
MIN_PERIODS = 4  # a recording shorter than this many of the longest periods is not judged
BINS_A_PERIOD = 16  # spikes are summed over bins of 1/16 of the shortest period
# the periodogram's FFT is zero-padded to PAD times the bins or more (a peak's top is then within
# 3 % of the sampled one's: the median test's), and the peak's frequency found around it to
# PHASE_STEP radians of phase over the recording
PAD, PHASE_STEP = 4, 0.1
BIN_CHUNK = 64  # bins counted at a time ([64, H, W] int32: 26 MB at 250x400)
# a progress bar shows once the counting has taken this long (seconds): 250x400 counts ~26,000
# readouts a second, 128² solids' 4000 readouts take 0.01-0.08 s
PROGRESS_AFTER = 1.0


@dataclass(frozen=True)
class Flicker:
    """Light × (1 + depth·sin(2π·t / period + phase)) at readout time t."""

    depth: float
    period: float  # readouts
    phase: float  # radians at readout 0

    def __post_init__(self):
        """ValueError for what `find_flicker` cannot find (a cache file edited or of another
        tool: its gain divided every target by it, NaN or a string failing deep in training)."""
        numbers = all(is_number(v) for v in asdict(self).values())  # (not bool: true read as 1)
        if not (numbers and self.depth >= 0 and self.period > 0):
            raise ValueError(f"not a flicker: {self}")

    def gain(self, first, span: int) -> np.ndarray:
        """The mean modulation [B] over `span` readouts from each of `first` [B] (a readout time:
        TFI's k + 0.5 with span 1)."""
        t = np.asarray(first, np.float64)[:, None] + np.arange(span)  # [B, span]
        return (1 + self.depth * np.sin(2 * np.pi * t / self.period + self.phase)).mean(axis=1)

    def divided(self, images: np.ndarray, k, span: int, time_offset: float = 0.0) -> np.ndarray:
        """`images` [B, ...] (float32) that show the light of `span` readouts from each
        k - span // 2 + `time_offset` (`k` [B]: a window centred on k), each divided by the
        flicker's mean there: the light's steady brightness."""
        gain = self.gain(np.asarray(k) - span // 2 + time_offset, span).astype(np.float32)
        return images / gain.reshape(-1, *[1] * (images.ndim - 1))


def divisible(flicker: Flicker | None) -> Flicker | None:
    """`flicker` where it can be divided out, None where none was found or it is too deep (a
    sinusoid of MAX_DEPTH or more takes the light to none or below)."""
    return None if flicker is None or flicker.depth >= MAX_DEPTH else flicker


def _region_totals(streams, progress: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Bin centres [n] (readout times) and the spikes of every channel in each bin of readouts
    in each of GRID x GRID regions of the frame [n, R] (fewer on a frame under GRID pixels high
    or wide: a region a row or column); `progress`: a bar over the readouts counted, once that
    takes PROGRESS_AFTER seconds."""
    step = max(1, int(PERIODS[0] // BINS_A_PERIOD))
    starts = np.arange(0, len(streams[0]) - step + 1, step)  # [n] first readouts
    h, w = streams[0].height, streams[0].width
    # each region's first row and column, once (reduceat sums a repeated start's row again)
    rows, cols = (np.unique(np.linspace(0, size, GRID + 1).astype(int)[:-1]) for size in (h, w))
    totals = np.zeros((len(starts), len(rows) * len(cols)))
    bar = tqdm(
        total=len(streams) * len(starts) * step,
        desc="flicker",
        unit="readout",
        unit_scale=True,
        disable=not progress,
        delay=PROGRESS_AFTER,
        dynamic_ncols=True,
    )
    with quiet_close(bar):
        for s in streams:
            for i in range(0, len(starts), BIN_CHUNK):
                ks = starts[i : i + BIN_CHUNK] + step // 2  # the window of `step` from each start
                counts = s.counts(ks, step)  # [b, H, W] int32
                regions = np.add.reduceat(np.add.reduceat(counts, rows, axis=1), cols, axis=2)
                totals[i : i + BIN_CHUNK] += regions.reshape(len(ks), -1)
                # (output gone: the bar off; training's own bar then stops the run)
                progress_lost(functools.partial(bar.update, len(ks) * step), bar)
    return starts + (step - 1) / 2, totals


def _detrended(t: np.ndarray, x: np.ndarray) -> np.ndarray:
    """`x` [n] at times `t` [n], a straight line (the camera's slow change of view, in part)
    taken out."""
    return x - np.polyval(np.polyfit(t, x, 1), t)


def _fft_size(bins: int, per_bin: float) -> int:
    """The power of two of at least `per_bin` x `bins` points."""
    return int(2 ** np.ceil(np.log2(per_bin * bins)))


def periodogram(
    t: np.ndarray, x: np.ndarray, band: tuple[float, float] = PERIODS
) -> tuple[np.ndarray, np.ndarray]:
    """The periods [F] (readouts) within `band` and the amplitudes [F] of relative rates `x` [n]
    of evenly spaced bins at times `t` [n] (zero-padded to PAD times the bins or more)."""
    size = _fft_size(len(x), PAD)
    amp = 2 * np.abs(np.fft.rfft(x, size)) / len(x)  # [size / 2 + 1]
    with np.errstate(divide="ignore"):
        period = (t[1] - t[0]) / np.fft.rfftfreq(size)  # readouts
    kept = (period >= band[0]) & (period <= band[1])
    return period[kept], amp[kept]


def _peak(
    t: np.ndarray, x: np.ndarray, near: float, band: tuple[float, float] = PERIODS
) -> tuple[float, float]:
    """(period in readouts, amplitude) of the highest amplitude of `x` [n] at times `t` [n] on
    frequencies PHASE_STEP radians of phase over the recording apart (the grid a periodogram
    padded to that would have), within `band` and a periodogram's step of period `near`: a
    chirp-z transform of a few dozen frequencies, memory as the bins'."""
    from scipy.signal import czt  # (0.1-0.5 s to import: only where a peak is sought)

    step, size = t[1] - t[0], _fft_size(len(x), 2 * np.pi / PHASE_STEP)
    reach = size // _fft_size(len(x), PAD)  # fine frequencies to a periodogram's step
    centre = round(size * step / near)
    index = np.arange(centre - reach, centre + reach + 1)  # [m] frequencies, of `size`
    period = step / (index / size)  # readouts
    index = index[(period >= band[0]) & (period <= band[1])]
    turn = np.exp(-2j * np.pi / size)  # a step along the grid
    start = np.exp(2j * np.pi * index[0] / size)
    amp = 2 * np.abs(czt(x, len(index), turn, start)) / len(x)  # [m]
    return float(step / (index[np.argmax(amp)] / size)), float(amp.max())


def _judged(streams) -> bool:
    """Whether `streams` [C] are one recording (not per-view streams: each view its own phase)
    of MIN_PERIODS of the longest period or more."""
    one = all(isinstance(s, SpikeStream) for s in streams)
    return one and len(streams[0]) >= MIN_PERIODS * PERIODS[1]


@functools.cache
def _detector() -> bytes:
    """A digest of the search: this module's code (its constants), the spike counting's (the
    core) and numpy's and scipy's versions."""
    digest = hashlib.sha256(f"{np.__version__}|{scipy.__version__}".encode())
    for code in (__file__, _C.__file__):
        digest.update(Path(code).read_bytes())
    return digest.digest()


def _settings() -> tuple:
    """The search's settings as they are now (a notebook may tune them after a first search)."""
    judged = (MIN_DEPTH, PEAK, MAX_DEPTH, GRID, IN_PHASE, LIT, MIN_PERIODS)
    return (PERIODS, BEYOND, EDGE, *judged, BINS_A_PERIOD, PAD, PHASE_STEP)


def cached_flicker(streams, progress: bool = False) -> Flicker | None:
    """`find_flicker`'s finding, under the spikes' digests and the search's (`_detector`, and
    `_settings` as they are now): kept for the process (`found_once`: a recording's loading, its
    targets and a bench's every method search it once) and, for a recording of CACHED_FROM bytes
    or more, in the user's cache (`cache_home()/flicker`, never the dataset's folder, which may be
    read-only: a run's start and its resume search it once). A changed recording or search
    searches again; streams not judged (`_judged`) are None at once, no digest read."""
    if not _judged(streams):
        return None
    key = hashlib.sha256(_detector() + repr(_settings()).encode())
    for s in streams:
        key.update(s.digest())
    return found_once(key.digest(), lambda: _kept_flicker(streams, key.hexdigest()[:32], progress))


def _kept_flicker(streams, name: str, progress: bool) -> Flicker | None:
    """`find_flicker`'s finding, kept under `name` in the user's cache for a recording of
    CACHED_FROM bytes or more; searched where no cache is known, readable or writable."""
    home = cache_home()
    size = sum(len(s) * s.height * ((s.width + 7) // 8) for s in streams)
    if home is None or size < CACHED_FROM:
        return find_flicker(streams, progress)
    path = home / "flicker" / f"{name}.json"
    try:
        kept = json.loads(path.read_text())["flicker"]
        return None if kept is None else Flicker(**kept)
    except (OSError, ValueError, KeyError, TypeError):  # none yet, or not one of ours
        pass
    found = find_flicker(streams, progress)
    write_cached(path, json.dumps({"flicker": None if found is None else asdict(found)}))
    return found


def find_flicker(streams, progress: bool = False) -> Flicker | None:
    """The flicker of the light that `streams` [C] (one recording, a stream per channel) saw, or
    None: none (`MIN_DEPTH`, `PEAK`, `IN_PHASE`), a recording under MIN_PERIODS of the longest
    period, or per-view streams (each its own phase); `progress`: a bar where the search takes
    over PROGRESS_AFTER seconds."""
    if not _judged(streams):
        return None
    t, totals = _region_totals(streams, progress)
    frame = totals.sum(axis=1)  # [n]
    frame = _detrended(t, frame / max(frame.mean(), 1e-12) - 1)  # relative rates
    # the highest peak within BEYOND of PERIODS, refined: one outside them (but for EDGE, its
    # refinement's spread) is no flicker of theirs (one of 450 or 500 readouts was found at
    # 419.6, its peak's flank, at a fraction of its depth, and divided out wrongly)
    wide = (PERIODS[0] / BEYOND, PERIODS[1] * BEYOND)
    periods, amp = periodogram(t, frame, wide)  # [F]
    best, top = _peak(t, frame, periods[np.argmax(amp)], wide)
    if not PERIODS[0] / EDGE <= best <= PERIODS[1] * EDGE:
        return None
    amp = amp[(periods >= PERIODS[0]) & (periods <= PERIODS[1])]  # (its median: PEAK's)
    w = 2 * np.pi / best  # radians a readout
    basis = np.stack([np.ones_like(t), t, np.sin(w * t), np.cos(w * t)], axis=1)  # [n, 4]
    _, _, a, b = np.linalg.lstsq(basis, frame, rcond=None)[0]
    depth, phase = float(np.hypot(a, b)), float(np.arctan2(b, a))  # a sin + b cos
    if depth < MIN_DEPTH or top < PEAK * np.median(amp):
        return None
    lit = totals.mean(axis=0) > LIT * totals.mean()  # [R]
    # a region's detrended relative rate against the sinusoid: its spikes against the sinusoid
    # detrended (a projection is symmetric), over its mean spikes (> 0: the sign is the same)
    in_phase = (_detrended(t, np.sin(w * t + phase)) @ totals)[lit]  # [lit regions]
    if np.mean(in_phase > 0) < IN_PHASE:
        return None
    return Flicker(depth, best, phase)
