"""A Dataset from real spike data: per-view streams or one stream, held-out views, meta.

A held-out view without a sharp image gets a pseudo ground truth: TFP over a long window of its own
spikes (by default the whole view for per-view streams, 65 readouts around its pose for one
stream). Its name starts with `pseudo_` and meta["test_ground_truth"] says so, so evaluation
output does too. A sharp image (intensity, [0, 1]) is stored times the trainer's intensity scale.
"""

from __future__ import annotations

import dataclasses
import math
import os
import warnings
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path

import numpy as np

from ..flicker import cached_flicker, divisible
from ..pixel_defects import defect_maps, repaired
from ..spikes import SpikeStream
from ..spikes.stream import centred_range
from ..targets import intensity_scale
from .dataset import (
    FORMAT_VERSION,
    GUESSED_SCALE,
    PSEUDO_PREFIX,
    READOUT_PERIOD_S,
    WINDOW_MARGIN,
    Dataset,
    GuessedUnitsWarning,
    TestView,
    check_test_views,
    intrinsics_keys,
    microseconds_hint,
    repeated,
    stated_scales,
    warn_about_test_units,
)
from .orientation import check_orientation
from .real_options import OPTIONS_FILE, Options
from .simulate import default_train_every, train_timestamps
from .trajectory import Trajectory, readout_number
from .view_stream import ViewStreams

# what a real layout's sharp images are in (firing rates once scaled): test images in firing-rate
# units with rate_at_one stated scored 16.5 dB where 26.9 was due, unsaid (the real-layout trial)
# an integer image's values are read as sRGB unless its file says linear (a PNG's gAMA 1.0)
LINEAR_UNTAGGED = "linear values in an 8- or 16-bit image not tagged linear, read as sRGB"
SHARP_UNITS = (
    "sharp images are expected in linear intensity, 1 for white (8- and 16-bit ones "
    f"sRGB-encoded unless tagged linear), which rate_at_one in {OPTIONS_FILE} turns into firing "
    "rates"
)
NEEDED_WINDOW = 2 * WINDOW_MARGIN + 1  # the longest window training reads: TFP(65)
HOLDOUT_EVERY = 8  # LLFF's convention: views 0, 8, 16, ... are held out
PSEUDO_NOTE = "TFP of the held-out view's own spikes, not a sharp image: views named pseudo_*"


def pseudo_views_note(names) -> str | None:
    """The line to print under scores over held-out views `names` where some are pseudo ground
    truths (TFP of their own spikes, which flatters TFP-like methods); None where none is."""
    pseudo = [name for name in names if name.startswith(PSEUDO_PREFIX)]
    if not pseudo:
        return None
    return f"note: {len(pseudo)} views without a sharp image, scored against TFP ({PSEUDO_PREFIX}*)"


@dataclasses.dataclass
class HeldOut:
    """A test view before its image is final."""

    name: str
    viewmat: np.ndarray  # [4, 4] world-to-camera, OpenCV
    readout: float | None  # on the stream's readout axis; None: no spikes of this view
    image: np.ndarray | None  # [H, W, C] sharp intensity, or None for a pseudo ground truth
    window: int = NEEDED_WINDOW  # readouts of the pseudo ground truth's TFP


def camera_meta(
    layout: str, root: Path, K: np.ndarray, height: int, width: int, options: Options, **extra
) -> dict:
    """meta.json-like keys of a real dataset (docs/datasets.md); `extra` are added as they are."""
    meta = {
        "format_version": FORMAT_VERSION,
        "layout": layout,
        "scene": root.resolve().name,
        "height": height,
        "width": width,
        "channels": 1,
        "readout_period_s": READOUT_PERIOD_S,
        "flip": options.flip,
        "raw_width": options.raw_width or width,
        "col_offset": options.col_offset,
        **intrinsics_keys(K),
        **extra,
    }
    if options.rate_at_one is not None:
        meta["rate_at_one"] = float(options.rate_at_one)
    return meta


def ground_truth_note(sharp: int, pseudo: int) -> dict:
    """meta["test_ground_truth"]: how many test views have a sharp image, how many a pseudo one."""
    note = {"sharp_images": sharp, "pseudo": pseudo}
    return {**note, "pseudo_method": PSEUDO_NOTE} if pseudo else note


def pseudo_truth(streams, progress: bool = False) -> tuple[Callable, dict]:
    """A held-out view's pseudo ground truth from `streams` (one a channel), `truth(k, window)`
    [H, W, C]: TFP over the window centred on readout k, each sensor's hot, stuck or dead pixel
    given its neighbours' median (the losses leave them out) and divided by the light's flicker
    there (the light's, not the scene's: as training's targets are); and what
    meta["test_ground_truth"] adds of them (`pseudo_flicker`, `pseudo_defects`). `progress`: the
    flicker search's bar."""
    flicker = divisible(cached_flicker(streams, progress))
    defects = defect_maps(streams)  # [C, H, W]

    def truth(k: int, window: int) -> np.ndarray:
        images = [s.tfp(k, window) for s in streams]  # C x [H, W]
        image = np.stack([repaired(i, d) if d.any() else i for i, d in zip(images, defects)], -1)
        return image if flicker is None else flicker.divided(image[None], [k], window)[0]

    notes, defective = {}, int(defects.any(0).sum())  # (pixels, in any channel)
    if flicker is not None:
        notes["pseudo_flicker"] = (
            f"divided by the light's flicker: period {flicker.period:.1f} readouts, depth "
            f"{flicker.depth:.2f}"
        )
    if defective:
        notes["pseudo_defects"] = (
            f"{defective} hot, stuck or dead pixels of the sensor replaced by the median of their "
            f"neighbours"
        )
    return truth, notes


# readouts a held-out pose keeps free of training timestamps: one between two such poses lies
# over 2·WINDOW_MARGIN from each
HOLD_OUT_GAP = 4 * WINDOW_MARGIN + 1
# the default held-out poses (every HOLDOUT_EVERY-th) give way to spaced ones (_spaced_hold_out)
# where they keep under 1 / FEW_KEPT of the training timestamps the spaced ones keep. Measured on
# 1500 readouts of 64x96: a pose every 17 readouts kept 33 timestamps where spaced ones keep 653,
# every 20 135 of 644 (both replaced); every 24, as in an audit's LLFF stream, 241 with 7
# held-out poses (not replaced)
FEW_KEPT = 4


def _pose_step(readouts: np.ndarray) -> float:
    """The median readouts between consecutive poses of a stream's pose log (readouts [P],
    strictly increasing, P >= 2: `stream_dataset` refuses poses spanning less than a training
    window)."""
    return float(np.median(np.diff(readouts)))


def _spaced_hold_out(readouts: np.ndarray, every: int, clearances: int = HOLDOUT_EVERY) -> int:
    """Every how many poses of a stream's pose log (readouts [P]) to hold one out so that the
    held-out poses lie `clearances` clearances apart (HOLD_OUT_GAP and a train_every `every`):
    HOLDOUT_EVERY of them lose about 1 in HOLDOUT_EVERY training timestamps, as every
    HOLDOUT_EVERY-th view of LLFF's sparse views loses; 1 leaves a timestamp between two; at
    least HOLDOUT_EVERY."""
    step = _pose_step(readouts)
    return max(HOLDOUT_EVERY, math.ceil(clearances * (HOLD_OUT_GAP + every) / step))


def timestamps_clear_of(
    num: int, held: np.ndarray, every: int, first: float, last: float
) -> np.ndarray:
    """Training timestamps [M] every `every` readouts of a `num`-readout stream, clear of the
    held-out readouts `held`, whose 65-readout windows lie within [first, last] (the poses')."""
    ks = train_timestamps(num, held, every)  # [M]
    return ks[(ks - WINDOW_MARGIN >= first) & (ks + WINDOW_MARGIN <= last)]


def spaced_instead(
    readouts: np.ndarray, fits: np.ndarray, every: int, kept: int, clear_of
) -> tuple[np.ndarray, np.ndarray, int] | None:
    """Where the default held-out poses of a dense pose log (readouts [P], every HOLDOUT_EVERY-th
    of those that `fits`) keep `kept` training timestamps and spaced ones (`_spaced_hold_out`,
    `_spaced_mask`) FEW_KEPT times as many (`clear_of(mask)`: the timestamps a mask keeps):
    (their mask [P], their timestamps, every how many); else None."""
    nth = _spaced_hold_out(readouts, every)
    if nth <= HOLDOUT_EVERY:
        return None
    spaced = _spaced_mask(fits, nth)
    spaced_ks = clear_of(spaced)
    return (spaced, spaced_ks, nth) if spaced.any() and kept * FEW_KEPT < len(spaced_ks) else None


def _strided(fits: np.ndarray, nth: int) -> np.ndarray:
    """The indices of every `nth` of those that `fits` [P], from half that on."""
    return np.flatnonzero(fits)[nth // 2 :: nth]


def _spaced_mask(fits: np.ndarray, nth: int) -> np.ndarray:
    """Mask [P] of every `nth` pose from half that on, of those that `fits` [P] (their pseudo
    ground truth's window fits in the stream); the middle one of them where they are fewer."""
    candidates, picked = np.flatnonzero(fits), _strided(fits, nth)
    if not len(picked) and len(candidates):
        picked = candidates[len(candidates) // 2 :][:1]
    mask = np.zeros(len(fits), bool)
    mask[picked] = True
    return mask


def spaced_words(nth: int, fits: np.ndarray) -> str:
    """How `_spaced_mask(fits, nth)` chose its views: every `nth` of those that `fits` [P] from
    half that on, or, where none lies there, the middle one of them."""
    room = "of those with room for the pseudo ground truth's window"
    if not len(_strided(fits, nth)):  # (pose 111 of 7-133 was called "the middle one")
        return f"the middle one {room}"
    return f"every {ordinal(nth)} {room}, from the {ordinal(nth // 2 + 1)}"


def ordinal(n: int) -> str:
    """'1st', '2nd', '3rd', '4th', '11th', '131st'."""
    last = "th" if n % 100 in (11, 12, 13) else {1: "st", 2: "nd", 3: "rd"}.get(n % 10, "th")
    return f"{n}{last}"


def held_out_mask(count: int, options: Options, source: str) -> np.ndarray:
    """Mask [count] of the test views: the options' test_views, or every HOLDOUT_EVERY-th from
    0; `source`, the file of the views, is in the dataset's folder."""
    given = options.test_views
    indices = list(range(0, count, HOLDOUT_EVERY)) if given is None else list(given)
    bad = [i for i in indices if not 0 <= i < count]
    if bad:  # (named `source` alone until 2026-12-06, whose views were right)
        raise ValueError(
            f"{options.origin('test_views', Path(source).parent)} {bad} outside the {count} "
            f"views [0, {count}) of {source}"
        )
    mask = np.zeros(count, bool)
    mask[indices] = True
    return mask


def scene_sphere(options: Options, center, radius: float) -> dict:
    """scene_center, scene_radius: the options' where given, else the computed ones."""
    center = options.scene_center if options.scene_center is not None else center
    radius = options.scene_radius if options.scene_radius is not None else radius
    return {"scene_center": [float(c) for c in center], "scene_radius": float(radius)}


def _finish(
    root: Path, meta: dict, stream, trajectory, timestamps, held_out, progress: bool = False
) -> Dataset:
    """The Dataset with test images in firing-rate units (sharp x intensity scale, or TFP);
    `progress`: a bar where the search for a flicker takes long (`flicker.PROGRESS_AFTER`)."""
    meta["num_readouts"] = len(stream)
    if not len(timestamps):
        per_view = isinstance(stream, ViewStreams)
        raise ValueError(  # (the options and the fix were not named: the layouts trial)
            f"{root}: no training timestamp left once the test views are held out ({len(held_out)} "
            f"of them): fewer held-out views (test_views in {OPTIONS_FILE}; every "
            f"{HOLDOUT_EVERY}th view by default, the first included), or "
            + ("more views (each trains at one timestamp)" if per_view else "more readouts")
        )
    dataset = Dataset(root, meta, [stream], trajectory, np.asarray(timestamps, np.int64), [])
    sharp = [h for h in held_out if h.image is not None]
    scale = intensity_scale(dataset) if sharp else 1.0
    stated = stated_scales(meta)  # (before image_scale is set to the scale taken)
    if sharp and not stated:
        warnings.warn(
            f"{root}: the test views' sharp images are put in firing-rate units by a guess, "
            f"TFP(33)'s 99.5th percentile ({scale:.4g} spikes a readout for intensity 1), and "
            f"their PSNR depends on it: set rate_at_one in {OPTIONS_FILE} (the camera's firing "
            f"rate of intensity 1), or give training views sharp images to calibrate it",
            GuessedUnitsWarning,
            stacklevel=3,
        )
    pseudo = len(held_out) - len(sharp)
    if sharp and pseudo:  # (a test image missing or misnamed: its view scored so, unsaid)
        names = ", ".join(h.name for h in held_out if h.image is None)
        warnings.warn(
            f"{root}: {pseudo} of the {len(held_out)} held-out views have no sharp image "
            f"({names}): scored against TFP of their own spikes (named {PSEUDO_PREFIX}*), the "
            f"{len(sharp)} others against their images (an image missing?)",
            stacklevel=3,
        )
    truth, notes = pseudo_truth([stream], progress) if pseudo else (None, {})
    for h in held_out:
        if h.image is None:
            image = truth(round(h.readout), h.window)  # [H, W, 1]
            pseudo_view = TestView(PSEUDO_PREFIX + h.name, h.viewmat, image, h.readout, h.window)
            dataset.test_views.append(pseudo_view)
        else:
            image = (np.asarray(h.image) * scale).astype(np.float32)  # [H, W, 1]
            dataset.test_views.append(TestView(h.name, h.viewmat, image, h.readout))
    meta["test_ground_truth"] = {**ground_truth_note(len(sharp), pseudo), **notes}
    if sharp:
        meta["image_scale"] = scale
        meta[GUESSED_SCALE] = not stated
    check_test_views(dataset.test_views, root)
    if sharp and stated:  # (a guessed scale is warned of above)
        named = {h.name for h in sharp}  # their images in firing-rate units, against their TFP
        views = [v for v in dataset.test_views if v.name in named]
        warn_about_test_units([stream], views, root, 0.0, SHARP_UNITS)
    return dataset


def _longest_odd(length: int) -> int:
    """The longest odd window in `length` readouts: it fits centred on the middle one."""
    return length - 1 + length % 2


def view_tfps(views: Iterable[tuple[SpikeStream, np.ndarray]]) -> Iterator[tuple[np.ndarray, ...]]:
    """Each view's TFP over its whole stream [H, W] with its sharp image [H, W, C], computed as
    it is asked for (a list of every training view's held as many TFPs as images)."""
    return ((s.tfp(len(s) // 2, _longest_odd(len(s))), image) for s, image in views)


def rate_from_images(views: Iterable[tuple[np.ndarray, np.ndarray]], source: str) -> float:
    """The firing rate of intensity 1.0 from training views' TFPs over the whole view [H, W]
    and sharp images [H, W, 1] (`view_tfps`): the median over views of a view's mean firing
    rate over its image's mean intensity. Means, so that motion blur within a view and small
    misalignments cancel; the median, so that a wrong image (black, another view's) does not
    move it. Black images are left out; ValueError when all are, and where the rate is over 1
    (a camera fires once a readout at most: images darker than their spikes' light)."""
    ratios = [tfp.mean() / np.mean(image) for tfp, image in views if np.mean(image) > 0]
    rate = float(np.median(ratios)) if ratios else 0.0
    if not rate > 0:
        raise ValueError(
            f"{source}: the training views' sharp images are all black or their spikes too few "
            f"to calibrate intensity; set rate_at_one in {OPTIONS_FILE}"
        )
    if rate > 1:  # (refused later as if a file had stated it: the user had stated nothing)
        raise ValueError(
            f"{source}: rate_at_one calibrated from {len(ratios)} training views' sharp images "
            f"is {rate:.3g}, over 1 spike a readout: the images are darker than the light their "
            f"spikes record (another exposure, or {LINEAR_UNTAGGED}); set rate_at_one in "
            f"{OPTIONS_FILE}"
        )
    return rate


ORIENTATION_VIEWS = 8  # sharp images read for the check: training views' where none calibrates,
# and held-out views' with spikes


def views_dataset(
    root: Path,
    meta: dict,
    names: list[str],
    viewmats: np.ndarray,
    streams: list[SpikeStream | None],
    images: list[np.ndarray | None],
    test: np.ndarray,
    options: Options,
    source: str,
) -> Dataset:
    """One spike stream per view [V] (None: a test view known only by its sharp image): views
    joined on one readout axis, a training timestamp at each training view's centre."""
    pseudo_window = options.pseudo_gt_window
    if options.train_every is not None:
        warnings.warn(
            f"{options.origin('train_every', root)} is not used with a spike stream per view "
            f"(each training view of {source} is one timestamp, at its centre); it spaces the "
            f"timestamps of one continuous stream",
            stacklevel=3,
        )
    twice = repeated(names)
    if twice:
        raise ValueError(
            f"{source}: view names (file paths without extension) expected unique, found twice: "
            f"{twice}"
        )
    for name, stream, image, held in zip(names, streams, images, test):
        if stream is not None and len(stream) < NEEDED_WINDOW:
            raise ValueError(
                f"{stream.path}: view '{name}' has {len(stream)} readouts; a view needs at least "
                f"{NEEDED_WINDOW}, the longest window training reads (or its frames are not "
                f"{stream.height}x{stream.width}, the size the layout states: check it)"
            )
        # the pseudo ground truth scores a held-out view that has no sharp image
        scored = held and image is None
        if stream is not None and scored and pseudo_window and len(stream) < pseudo_window:
            raise ValueError(
                f"{stream.path}: held-out view '{name}' (no sharp image: scored against the TFP "
                f"of its spikes) has {len(stream)} readouts, fewer than pseudo_gt_window "
                f"{pseudo_window}"
            )
    present = [i for i, s in enumerate(streams) if s is not None]
    joined = ViewStreams([streams[i] for i in present], [names[i] for i in present])
    trajectory = joined.held_trajectory(np.asarray(viewmats)[present], source)
    centers = dict(zip(present, joined.centers().tolist()))
    lengths = dict(zip(present, np.diff(joined.offsets).tolist()))
    held_out = [
        HeldOut(
            names[i],
            viewmats[i],
            float(centers[i]) if i in centers else None,
            images[i],
            pseudo_window or _longest_odd(lengths.get(i, 1)),
        )
        for i in np.flatnonzero(test)
    ]
    timestamps = [centers[i] for i in present if not test[i]]
    # training views with a sharp image: their TFPs [H, W] and images, a view at a time; the
    # orientation checked on held-out ones with spikes too (the images scored against: a wrong
    # flip trained 4.9 dB low unsaid where only they had images)
    sharp = [i for i in present if not test[i] and images[i] is not None]
    held = [i for i in present if test[i] and images[i] is not None][:ORIENTATION_VIEWS]
    checked = view_tfps((streams[i], images[i]) for i in sharp + held)
    check_orientation(
        checked,
        options.flip,
        source,
        options.frame_settings(),
        options.raw_width,
        options.col_offset,
    )
    if sharp and "rate_at_one" not in meta:
        tfps = view_tfps((streams[i], images[i]) for i in sharp)
        meta["rate_at_one"] = rate_from_images(tfps, source)
        meta["rate_at_one_from"] = f"{len(sharp)} training views' sharp images"
    meta["spike_files"] = [os.path.relpath(streams[i].path, root) for i in present]
    meta["view_readouts"] = {
        names[i]: [int(joined.offsets[j]), int(joined.offsets[j + 1])]
        for j, i in enumerate(present)
    }
    return _finish(root, meta, joined, trajectory, timestamps, held_out)


GAP_FACTOR = 4  # poses further apart than this many median spacings leave a gap


def first_of(items: list[str], shown: int = 5) -> str:
    """The first `shown` of `items` joined by commas, then how many more there are, for a
    message."""
    more = len(items) - shown
    return ", ".join(items[:shown]) + (f" and {more} more" if more > 0 else "")


def warn_pose_gaps(
    readouts: np.ndarray, timestamps: np.ndarray, source: str, fix: str = "check the pose log"
) -> None:
    """A UserWarning naming the gaps in a pose log (readouts [P], sorted) wider than GAP_FACTOR
    median spacings and than a training window, that training timestamps [M] fall into: their
    poses are interpolated across the gap (a motion-capture dropout), which a curved path does
    not follow; `fix`, what to do."""
    spacing = np.diff(readouts)  # [P - 1], P >= 2 (`_pose_step`)
    wide = (spacing > GAP_FACTOR * np.median(spacing)) & (spacing > NEEDED_WINDOW)
    gaps = []
    for i in np.flatnonzero(wide):
        inside = int(np.sum((timestamps > readouts[i]) & (timestamps < readouts[i + 1])))
        if inside:
            a, b = readout_number(readouts[i]), readout_number(readouts[i + 1])
            gaps.append(f"[{a}, {b}] ({inside})")
    if gaps:
        warnings.warn(
            f"{source}: training timestamps in gaps of the poses (readouts, timestamps inside) "
            f"{first_of(gaps)}, against a median spacing of "
            f"{readout_number(np.median(spacing))} readouts: their poses are interpolated across "
            f"each gap; {fix}",
            stacklevel=3,
        )


def _warn_if_stretches_untrained(
    ks: np.ndarray, start: float, end: float, every: int, source: str
) -> None:
    """A UserWarning naming the stretches of the poses' readouts [start, end] that the default
    held-out poses leave without a training timestamp (ks [M], sorted) over more than two
    clearances: every 8th pose there lies within a clearance and a timestamp step of the next
    (a denser stretch of an uneven pose log; or a uniform one whose train_every steps over the
    strips between clearances)."""
    edges = np.concatenate([[start + WINDOW_MARGIN], ks, [end - WINDOW_MARGIN]])  # [M + 2]
    wide = np.flatnonzero(np.diff(edges) > 2 * (HOLD_OUT_GAP + every))
    if len(wide):
        stretches = [f"{readout_number(edges[i])}-{readout_number(edges[i + 1])}" for i in wide]
        smaller = f"a train_every under {every}, or " if every > 1 else ""
        warnings.warn(
            f"{source}: no training timestamp between readouts {first_of(stretches)}: the "
            f"default held-out views, every {HOLDOUT_EVERY}th pose, lie there within "
            f"{HOLD_OUT_GAP + every} readouts of one another (each keeps {2 * WINDOW_MARGIN} "
            f"clear either side; timestamps fall every {every}, train_every), and what the "
            f"cameras saw there trains from the neighbouring readouts only; {smaller}test_views "
            f"in spikegs.json further apart",
            stacklevel=3,
        )


def light_span(num_readouts: int) -> tuple[float, float]:
    """The readouts' interval whose light a stream of `num_readouts` records: readout k shows the
    light of (k - 0.5, k + 0.5], so a pose stamped at the start of the first readout's
    integration or at the end of the last's lies half a readout outside [0, num_readouts - 1]."""
    return -0.5, num_readouts - 0.5


def stream_dataset(
    root: Path,
    meta: dict,
    stream: SpikeStream,
    readouts: np.ndarray,
    viewmats: np.ndarray,
    test: np.ndarray,
    options: Options,
    source: str,
    progress: bool = False,
    readouts_file: Path | None = None,
) -> Dataset:
    """One continuous stream with a pose [P, 4, 4] (from `source`) at each readout [P] (from
    `readouts_file`, else `source` too): training timestamps every `train_every` readouts
    (default: ~1024 over the readouts the poses span) clear of the held-out poses; a held-out
    pose whose pseudo-ground-truth window does not fit in the stream is not evaluated.
    `progress`: as `_finish`'s."""
    trajectory = Trajectory(readouts, viewmats, source=source)
    readouts_file = source if readouts_file is None else readouts_file
    first, last = light_span(len(stream))
    if trajectory.start < first or trajectory.end > last:
        raise ValueError(
            f"{readouts_file}: pose readouts span [{trajectory.start:g}, {trajectory.end:g}], "
            f"outside [{first:g}, {last:g}], the light the stream's {len(stream)} readouts record "
            f"({stream.path}).{microseconds_hint(trajectory.end, len(stream))}"
        )
    if trajectory.end - trajectory.start < 2 * WINDOW_MARGIN:
        cause = (
            f"readouts are indices, {READOUT_PERIOD_S * 1e6:g} µs apart (not seconds?)"
            if len(readouts) > 1
            else "one pose spans none (poses along the recording are needed)"
        )
        raise ValueError(
            f"{readouts_file}: the poses span readouts [{trajectory.start:g}, "
            f"{trajectory.end:g}] of the stream's {len(stream)}, less than the "
            f"{2 * WINDOW_MARGIN + 1} readouts a training window needs: {cause}"
        )
    # by default ~1024 timestamps over the readouts the poses span, not the whole recording's
    every = options.train_every or default_train_every(trajectory.end - trajectory.start + 1)

    def clear_of(test: np.ndarray) -> np.ndarray:  # training timestamps [M] clear of `test`
        return timestamps_clear_of(
            len(stream), readouts[test], every, trajectory.start, trajectory.end
        )

    window = options.pseudo_gt_window or NEEDED_WINDOW
    lo, hi = centred_range(len(stream), window)  # readouts whose window fits
    fits = (lo <= np.round(readouts)) & (np.round(readouts) <= hi)  # [P] poses that can be scored
    ks = clear_of(test)
    default = options.test_views is None  # the default held-out poses, on a dense pose log
    instead = spaced_instead(readouts, fits, every, len(ks), clear_of) if default else None
    if instead is not None:
        spaced, spaced_ks, nth = instead
        picked = np.flatnonzero(spaced).tolist()
        warnings.warn(
            f"{source}: every {HOLDOUT_EVERY}th pose, the default held-out views, leaves "
            f"{len(ks)} training timestamps (each keeps {2 * WINDOW_MARGIN} readouts clear of "
            f"a held-out pose): held out pose{'s' if len(picked) > 1 else ''} "
            f"{', '.join(map(str, picked[:5]))}{', ...' if len(picked) > 5 else ''} instead "
            f"({len(picked)} of {len(readouts)}, {spaced_words(nth, fits)}), which "
            f"leave{'s' if len(picked) == 1 else ''} {len(spaced_ks)}; test_views in "
            f"spikegs.json chooses others",
            stacklevel=3,
        )
        test, ks = spaced, spaced_ks
    if not len(ks):
        held = readouts[test]
        spacing = float(np.median(np.diff(held))) if len(held) > 1 else math.inf
        which = "" if options.test_views else f", every {HOLDOUT_EVERY}th pose by default"
        apart = f", which lie {spacing:g} readouts apart" if len(held) > 1 else ""
        smaller = "a smaller train_every, or " if every > 1 and spacing > HOLD_OUT_GAP else ""
        least = _spaced_hold_out(readouts, every, clearances=1)  # the closest that leave one
        poses = f"each of the {held.size} held-out poses" if held.size > 1 else "the held-out pose"
        raise ValueError(
            f"{source}: no training timestamp left: timestamps every {every} readouts "
            f"(train_every) of the stream, {WINDOW_MARGIN} or more inside the poses' readouts "
            f"[{trajectory.start:g}, {trajectory.end:g}], keep {2 * WINDOW_MARGIN} readouts "
            f"clear of {poses}{which}{apart}; {smaller}fewer "
            f"held-out poses further apart (test_views, pose indices, e.g. every "
            f"{ordinal(least)}: {readout_number(least * _pose_step(readouts))} readouts apart), "
            f"in spikegs.json"
        )
    warn_pose_gaps(readouts, ks, source)
    if options.test_views is None:  # (held-out poses of the user's own: as chosen)
        _warn_if_stretches_untrained(ks, trajectory.start, trajectory.end, every, source)
    held_out = [
        HeldOut(f"view_{i:03d}", viewmats[i], float(readouts[i]), None, window)
        for i in np.flatnonzero(test & fits)
    ]
    held = np.flatnonzero(test)
    unscored = np.flatnonzero(test & ~fits)
    # held-out poses the user chose that cannot be scored (the view count fell in silence; the
    # default's pose 0, at readout 0 in every LLFF log, is not: docs/datasets.md says so)
    if options.test_views is not None and held_out and unscored.size:
        named = ", ".join(f"{i} (readout {readouts[i]:g})" for i in unscored[:5])
        at = np.round(readouts[unscored]).astype(np.int64)
        room = int(np.minimum(at, len(stream) - 1 - at).min())  # readouts beside the closest
        shorter = f", or a pseudo_gt_window of {2 * room + 1} or less," if room else ""
        warnings.warn(
            f"{source}: held-out pose{'s' if unscored.size > 1 else ''} {named}"
            f"{', ...' if unscored.size > 5 else ''} within {window // 2} readouts of the "
            f"stream's ends, where a {window}-readout pseudo ground truth does not fit, "
            f"{'are' if unscored.size > 1 else 'is'} not scored ({len(held_out)} of {held.size} "
            f"held-out poses are; training stays clear of {'them' if unscored.size > 1 else 'it'}"
            f" all the same): test_views in spikegs.json with room around them{shorter} scores "
            f"them",
            stacklevel=3,
        )
    if held.size and not held_out:
        raise ValueError(
            f"{source}: none of the {held.size} held-out poses (test_views {held.tolist()}) can "
            f"be scored: a pseudo_gt_window of {window} readouts centred on its pose does not fit "
            f"in the stream's {len(stream)} readouts; set a shorter pseudo_gt_window in "
            f"spikegs.json, or test_views with room around them"
        )
    meta["spike_files"] = [os.path.relpath(stream.path, root)]
    meta["train_every"] = every
    return _finish(root, meta, stream, trajectory, ks, held_out, progress)
