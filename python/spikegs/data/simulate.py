"""Make a synthetic spike dataset: ground truth along a fast camera path, turned into spikes."""

from __future__ import annotations

import dataclasses
import errno
import inspect
import math
import shutil
import warnings
from pathlib import Path

import numpy as np
from tqdm import tqdm

from ..interrupt import deferred_interrupt, interruption
from ..number_checks import as_flag, finite_numbers, is_seed, whole_numbers
from ..spikes import SimParams
from ..spikes.simulate import checked_times, not_codes, simulate_channels
from .dataset import (
    FAINTEST_MEASURED,
    FEW_TIMESTAMPS,
    FORMAT_VERSION,
    LOCK,
    READOUT_PERIOD_S,
    STAGING,
    TRAJECTORY_BACKUP,
    WINDOW_MARGIN,
    DarkSpikesWarning,
    Dataset,
    FaintLightWarning,
    TestView,
    check_meta_values,
    check_output,
    check_test_views,
    holds_dataset,
    intrinsics_keys,
    intrinsics_matrix,
    load_dataset,
    move_in,
    near_held_out,
    refuse_if_in_use,
    spike_files,
    write_parts,
    writing_dataset,
)
from .scenes import SCENES
from .sources import FrameSequenceSource, MitsubaSource, ProceduralSource, RenderSource, Source
from .sphere_motion import sphere_track, track_steps
from .trajectory import WORLD_UP, Trajectory, unit_vector
from .transforms_file import TRANSFORMS, warn_unread_transforms

DEFAULT_SIZE = 128  # pixels a side
DEFAULT_READOUTS = 4000  # 0.1 s of spike camera
DEFAULT_SPEED = 0.15  # degrees of orbit per readout: 5° per 33 readouts, 600° in all
DEFAULT_SEED = 0  # the simulator's noise
# the light rendered every 8 readouts, or more often where the scene would move more than
# FRAME_MOTION_PX between frames (default_frame_every); cross-faded between
DEFAULT_FRAME_EVERY = 8
DEFAULT_TEST_VIEWS = 8  # held-out views on the path, and off it
MAX_DEFAULT_TIMESTAMPS = 1024  # one stream: train_every defaults to give at most this many
FEW_TRAINED = 0.25  # on-path views that leave training less of the path than this are warned of
# Data that defeats the methods, or their scores, gets a warning before simulating: more of the
# held-out views' pixels saturated than this fraction, dark spikes at this fraction of the light's
# mean rate, a TFP window of this many readouts turning the camera by more than this many degrees.
SATURATED_FRACTION = 0.01
LIT_INTENSITY = 0.01  # pixels brighter than this are the scene's, when judging its light
EMPTY_VIEW = 0.01  # a held-out view with fewer lit pixels than this fraction scores its black
DARK_FRACTION = 0.1
BLUR_WINDOW, BLUR_DEGREES = 33, 15.0
# a path turning less than this many degrees and moving less than this fraction of the scene
# radius sees the scene from one place (a camera that translates without turning is not still)
STILL_DEGREES, STILL_MOVE = 1.0, 0.01


def clean_source(dataset: Dataset) -> Source:
    """The noise-free source that `dataset` was simulated from; only a built-in scene can be
    rebuilt from meta.json, anything else is a ValueError."""
    scene, kind = dataset.meta.get("scene"), dataset.meta.get("source")
    if kind != "procedural" or scene not in SCENES:
        this = f"{kind} scene '{scene}'" if kind else "not simulated"
        raise ValueError(
            f"{dataset.root}: clean instant images (supervision.instant: clean) need a dataset "
            f"simulated from a built-in scene ({', '.join(SCENES)}); this one is {this}"
        )
    # with the camera it was simulated with (a wide frame's framing changed on 2026-11-30)
    K = intrinsics_matrix(dataset.meta)
    return ProceduralSource(
        scene,
        SCENES[scene](),
        dataset.width,
        dataset.height,
        dataset.channels,
        K=K,
        spp=simulated_spp(dataset.meta),
    )


def simulated_spp(meta: dict) -> int:
    """The samples per pixel a built-in scene's dataset was simulated at (meta.json's `spp`; 1, the
    pixel centres, in a dataset from before the key was written; null, a frame sequence's)."""
    spp = meta.get("spp")
    return 1 if spp is None else spp


def simulated_trajectory(dataset: Dataset) -> Trajectory:
    """The poses `dataset` was simulated from: its trajectory, or where `spikegs poses` replaced
    that with SfM's, the pose log it kept; ValueError where SfM's poses replaced no pose log (a
    recording's own frame, which the source's scene is not in)."""
    backup = Path(dataset.root) / TRAJECTORY_BACKUP
    if backup.exists():
        return Trajectory.load_json(backup)
    if dataset.meta.get("held_out_by"):
        raise ValueError(
            f"{dataset.root}: its poses are structure from motion's, in a frame of their own "
            f"(no {TRAJECTORY_BACKUP}): the scene's clean images cannot be rendered at them"
        )
    return dataset.trajectory


def camera_motion(trajectory: Trajectory) -> tuple[float, float]:
    """The largest angle, in degrees, between the first pose's optical axis and another's, and
    the largest distance of a camera centre from the first's."""
    axes = trajectory.viewmats[:, 2, :3]  # [P, 3] optical axes in world coordinates
    turn = float(np.degrees(np.arccos(np.clip(axes @ axes[0], -1.0, 1.0))).max())
    return turn, float(np.linalg.norm(trajectory.centers - trajectory.centers[0], axis=1).max())


def _lit_rates(views: list[TestView], threshold: float) -> np.ndarray:
    """The values [n] over `threshold` of the views' images, in their order (the images' own
    dtype, promoted as np.concatenate does), gathered a view at a time."""
    counts = [int(np.count_nonzero(v.image > threshold)) for v in views]
    lit = np.empty(sum(counts), np.result_type(*(v.image.dtype for v in views)))
    start = 0
    for view, count in zip(views, counts):
        lit[start : start + count] = view.image[view.image > threshold]
        start += count
    return lit


def warn_about_data(
    views: list[TestView], trajectory: Trajectory, params: SimParams, speed: float | None = None
) -> None:
    """UserWarnings where the data to be simulated would defeat the methods (light that saturates
    the camera, or too faint for a TFP window, dark spikes rivalling the light, a camera that
    turns so fast that a TFP window blurs), their scores (held-out views of almost nothing) or
    waste effort (a grey scene for a colour camera). `views`' images [H, W, C] are in firing-rate
    units (spikes per readout); `speed` the orbit's degrees per readout (None: no orbit's)."""
    if views[0].image.shape[-1] == 3 and all(
        np.array_equal(v.image[..., 0], v.image[..., c]) for v in views for c in (1, 2)
    ):
        warnings.warn(
            "the scene is grey (R = G = B in every held-out view): a colour camera records the "
            "same image three times over; simulate it mono or use a coloured scene",
            stacklevel=3,
        )
    # counted view by view, the lit pixels' rates gathered into one array: the views' images
    # concatenated, their masks and the lit ones copied took 2.2 times the images (16 views of
    # 1080x1920 colour: +851 MB over their 380, +401 now); the same numbers (np.mean's)
    total = max(sum(v.image.size for v in views), 1)
    saturated = sum(int(np.count_nonzero(v.image >= 1.0)) for v in views) / total
    if saturated > SATURATED_FRACTION:
        warnings.warn(
            f"{saturated:.0%} of the held-out views' pixels fire every readout (intensity >= "
            f"1/rate_at_one = {1 / params.rate_at_one:.3g}): the camera saturates and their "
            f"intensity is lost; lower rate_at_one",
            stacklevel=3,
        )
    else:  # brighter than white, recorded, but scored as white
        bright = sum(int(np.count_nonzero(v.image > params.rate_at_one)) for v in views) / total
        if bright > SATURATED_FRACTION:
            warnings.warn(
                f"{bright:.1%} of the held-out views' pixels are brighter than white (intensity "
                f"over 1, which fires rate_at_one = {params.rate_at_one:g} spikes per readout): "
                f"the camera records them, but spikegs eval scores intensities clipped to [0, 1] "
                f"(as 8-bit images are), so their detail is not scored; dim the scene's light "
                f"where it matters",
                stacklevel=3,
            )
    # a view of a wall's back or of the sky scores how black a render is: Mitsuba's one-sided
    # Cornell box, 9 of its 16 views black, TFP(33)+3DGS 59 dB in the mean, SpikeGS 46, though
    # SpikeGS leads by 2.3 dB over the 7 views of the box (BENCHMARKS.md, "Scenes not tuned on")
    threshold = LIT_INTENSITY * params.rate_at_one
    empty = [v.name for v in views if np.mean((v.image > threshold).any(-1)) < EMPTY_VIEW]
    if empty:
        warnings.warn(
            f"{len(empty)} of {len(views)} held-out views have under {EMPTY_VIEW:.0%} of their "
            f"pixels lit (above intensity {LIT_INTENSITY:g}: {', '.join(empty[:4])}"
            f"{', ...' if len(empty) > 4 else ''}): their PSNR measures mostly how black a render "
            f"is, tens of dB that outweigh the other views' in the mean; frame the scene in every "
            f"view (one-sided walls seen from behind render black)",
            stacklevel=3,
        )
    # the scene's own pixels: a small object on black (most of the frame) is not a dim scene
    lit = _lit_rates(views, threshold)
    lit_mean = float(lit.mean()) if lit.size else 0.0
    if lit_mean * BLUR_WINDOW < 1:
        fire = (
            f"lit pixels (intensity over {LIT_INTENSITY:g}) fire {lit_mean:.3g} spikes per "
            f"readout on average: a {BLUR_WINDOW}-readout TFP counts under one spike"
            if lit.size
            else f"pixels are all under intensity {LIT_INTENSITY:g}: black"
        )
        if lit_mean >= FAINTEST_MEASURED:
            effect = (
                "TFP images of such windows are scattered spikes: 3DGS with L1 on them (tfp33) "
                "learns the scene dark, the methods that fit the mean (spikegs, tfp33_smooth_l1) "
                "still see it; for TFP baselines raise rate_at_one or the light"
            )
        elif lit.size:
            effect = (
                f"fainter than any light measured (SpikeGS saw a scene at {FAINTEST_MEASURED:g} "
                f"spikes per readout); raise rate_at_one or the light"
            )
        else:
            effect = "too few to see the scene by; raise rate_at_one or the light"
        warnings.warn(f"the held-out views' {fire}; {effect}", stacklevel=3)
    if params.dark_rate > 0 and params.dark_rate >= DARK_FRACTION * lit_mean:
        warnings.warn(
            f"dark_rate {params.dark_rate:g} spikes per readout against a mean light rate of "
            f"{lit_mean:.3g} in the held-out views' lit pixels: dark spikes will bury the "
            f"scene's darker parts",
            stacklevel=3,
        )
    # the turn summed readout by readout over 16 windows along the path (a turn of more than
    # 180° between a window's ends would otherwise read as a small one)
    starts = np.linspace(
        trajectory.start, max(trajectory.end - BLUR_WINDOW + 1, trajectory.start), 16
    )
    times = np.minimum(starts[:, None] + np.arange(BLUR_WINDOW), trajectory.end)  # [16, w]
    rot = trajectory.pose_at(times.ravel())[:, :3, :3].reshape(*times.shape, 3, 3)
    cos = (np.einsum("nkij,nkij->nk", rot[:, 1:], rot[:, :-1]) - 1) / 2  # tr(Rb Ra^T) = 1+2cos
    degrees = float(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))).sum(1).max())
    if degrees > BLUR_DEGREES:
        # where the orbit's speed turns it less than half of that, the camera turns as the
        # spiral climbs from its first elevation to its last over the recording (a short one:
        # 16° in 33 of 80 readouts, at any speed): a lower speed would not mend it
        if speed is None:  # a frame sequence: its frames spread evenly over the readouts
            slower = "more readouts, over which the frames spread"
        elif abs(speed) * (BLUR_WINDOW - 1) < degrees / 2:
            slower = (
                "more readouts (the orbit turns mostly as it climbs its elevations, over the "
                "whole recording: a lower speed would not slow it)"
            )
        else:  # (more readouts at one speed turn it as fast: "or more readouts" was advised)
            slower = "a lower speed (--speed, degrees a readout)"
        warnings.warn(
            f"the camera turns up to {degrees:.1f}° in {BLUR_WINDOW} readouts: TFP and SIM "
            f"images will be motion-blurred and held-out views far from any training timestamp; "
            f"slow the camera: {slower}",
            stacklevel=3,
        )


# the scene sphere's largest motion between two light frames rendered every --frame-every
# readouts (its poles: the objects inside move less); the defaults' is 2.4 px at 128², 4.9 px at
# 256², and a larger frame renders more often by default (default_frame_every)
FRAME_MOTION_PX = 6.0


def frame_motion(source: Source, trajectory: Trajectory, times: np.ndarray) -> float:
    """The largest motion in pixels of the scene sphere's poles and centre between two light
    frames at readouts `times` [F] (points behind either camera of a pair not counted)."""
    # points in front of both cameras of a pair (a sphere around a camera has some behind it)
    steps = track_steps(*sphere_track(source, trajectory.pose_at(times)))  # [F - 1, 7]
    return float(steps.max()) if steps.size else 0.0


def default_frame_every(source: Source, trajectory: Trajectory, num_readouts: int) -> float:
    """DEFAULT_FRAME_EVERY, or the whole number of readouts below it (at least 1) at which the
    scene moves at most FRAME_MOTION_PX pixels between two light frames: a larger or nearer view
    renders more often rather than warning of ghosting at the defaults (512²: 4, 1080x1920: 2)."""
    every = DEFAULT_FRAME_EVERY
    while every > 1:  # motion is near proportional to the spacing: one or two tries
        motion = frame_motion(source, trajectory, source.light_times(num_readouts, every))
        if motion <= FRAME_MOTION_PX:
            break
        every = max(1, min(every - 1, math.floor(every * FRAME_MOTION_PX / motion)))
    return every


def warn_about_frames(source: Source, trajectory: Trajectory, times: np.ndarray) -> None:
    """A UserWarning where the scene sphere's points move more than FRAME_MOTION_PX pixels between
    two light frames at readouts `times` [F]: the simulator cross-fades them (ghosting) where the
    held-out views are sharp. Nothing for F < 2 (a built-in source's light times hold readout 0
    and the last; a Source of the user's own may give fewer, which the simulator then refuses by
    name, not an IndexError here)."""
    if len(times) < 2:
        return
    motion = frame_motion(source, trajectory, times)
    if motion > FRAME_MOTION_PX:
        # built-in, Mitsuba and a user's own scenes render a frame every frame_every readouts;
        # a frame sequence's spacing is its own
        rendered = source.kind != "frames"
        frames = "rendered light frames" if rendered else "frames of the sequence"
        remedy = (
            "a smaller frame_every (--frame-every)"
            if rendered and np.diff(times).max() > 1
            else "a slower camera (--speed), or one further from the scene (a frame every "
            "readout already: frame_every 1, the least)"
            if rendered
            else "a denser frame sequence, or its frames in order (a file listing frame_10 "
            "before frame_2, sorted as text, jumps back and forth)"
        )
        warnings.warn(
            f"the scene moves up to {motion:.1f} pixels between two {frames}: the simulator "
            f"cross-fades them (ghosting) where the held-out views are sharp; {remedy}",
            stacklevel=3,
        )


def make_source(
    scene: str | Path | dict | Source,
    width: int,
    height: int,
    channels: int,
    *,
    spp: int | None = None,
    up=WORLD_UP,
) -> Source:
    """The source of `scene`: a built-in name (SCENES), a Mitsuba .xml file or dict, a NeRF-style
    transforms JSON (or a directory holding transforms_train.json / transforms.json) or a Source.
    `up` [3]: the axis a built-in or Mitsuba scene's spiral ascends along (a unit vector); `spp`:
    samples per pixel of a built-in or Mitsuba scene (None: its own default, 1 or 16)."""
    if isinstance(scene, Source):
        return scene
    rendered = {"up": up} if spp is None else {"up": up, "spp": spp}
    if isinstance(scene, dict):
        return MitsubaSource(scene, width, height, channels, **rendered)
    if str(scene) in SCENES:
        return ProceduralSource(
            str(scene), SCENES[str(scene)](), width, height, channels, **rendered
        )
    expected = (
        f"expected a built-in scene ({', '.join(SCENES)}), a Mitsuba .xml file, or a transforms "
        f"JSON (or a folder holding transforms_train.json or transforms.json)"
    )
    if not str(scene).strip():  # (Path("") is the current folder: it was searched)
        raise ValueError(f"scene (--scene): empty; {expected}")
    path = Path(scene)
    if path.is_dir():  # a NeRF layout: its training frames, with transforms_test.json beside
        root = path
        train, test, single = (root / name for name in TRANSFORMS)
        path = train if train.is_file() else single if single.is_file() else root
        if path != root:
            warn_unread_transforms(root, [path, test])
    if path.suffix.lower() == ".xml":
        return MitsubaSource(path, width, height, channels, **rendered)
    if path.suffix.lower() == ".json":  # a missing file: from_transforms names it
        return FrameSequenceSource.from_transforms(path, width, height, channels)
    if path.is_dir():
        raise ValueError(f"scene folder {path} holds no {' or '.join(TRANSFORMS[::2])}; {expected}")
    if path.exists():
        raise ValueError(f"scene file {path} is neither .xml nor .json; {expected}")
    if len(path.parts) > 1:  # a path, not a name
        raise FileNotFoundError(f"scene {path} not found; {expected}")
    raise ValueError(f"unknown scene '{scene}': {expected}")


def default_train_every(num_readouts: int) -> int:
    """The stride giving at most MAX_DEFAULT_TIMESTAMPS training timestamps in a stream: a
    4000-readout stream gets one every 4 readouts (a view every 0.6° of the default orbit)."""
    return max(1, math.ceil(num_readouts / MAX_DEFAULT_TIMESTAMPS))


def train_timestamps(num_readouts: int, held_out: np.ndarray, every: int) -> np.ndarray:
    """Readouts [M] every `every` within [32, T - 33] (a 65-readout window fits), keeping 65-readout
    windows clear of each held-out on-path readout."""
    ks = np.arange(WINDOW_MARGIN, num_readouts - WINDOW_MARGIN, every)  # [M]
    return ks[~near_held_out(ks, held_out)].astype(np.int64)


def write_spikes(
    source: Source,
    trajectory: Trajectory,
    times: np.ndarray,
    out: Path,
    readouts: int,
    seed: int,
    params: SimParams,
    flip: bool,
    progress: bool,
) -> None:
    """Simulate each channel of the light, rendered at readouts `times` [F] as the simulation
    reaches them, into its .dat (mono: `seed`; colour: one seed per channel derived from it);
    `progress`: a bar over the frames rendered."""
    files = spike_files(source.channels)
    seeds = [seed] if len(files) == 1 else np.random.SeedSequence(seed).generate_state(3)
    with tqdm(total=len(times), desc="simulate", unit="frame", disable=not progress) as bar:

        def render(t: float) -> np.ndarray:  # [H, W, C]
            image = source.image_at(trajectory, t)
            bar.update()
            return image

        simulate_channels(
            render,
            readouts,
            [out / name for name in files],
            [int(s) for s in seeds],
            frame_times=times,
            flip=flip,
            params=params,
        )


OTHER_OUT = ", or give another --out"  # a busy dataset's remedy


def simulate_dataset(
    scene: str | Path | dict | Source,
    out: str | Path,
    *,
    height: int = DEFAULT_SIZE,
    width: int = DEFAULT_SIZE,
    readouts: int = DEFAULT_READOUTS,
    speed: float | None = None,
    seed: int = DEFAULT_SEED,
    overwrite: bool = False,
    color: bool = False,
    frame_every: float | None = None,
    test_on_path: int | None = None,
    test_off_path: int | None = None,
    train_every: int | None = None,
    spp: int | None = None,
    flip: bool = True,
    progress: bool = True,
    up=None,
    **sim_params,
) -> Dataset:
    """Simulate a dataset into `out` and return it loaded. `speed`: degrees of orbit per readout
    (default DEFAULT_SPEED), `up`: the unit axis [3] its spiral ascends along (default +z; +y for a
    y-up Mitsuba scene), `frame_every`: readouts between two rendered light frames (default
    `default_frame_every`; the simulator interpolates linearly), each for a built-in or Mitsuba
    scene (a frame sequence's frames and poses set them: given, they are warned of);
    `test_on_path`, `test_off_path`: held-out views on and off the path (default
    DEFAULT_TEST_VIEWS each, or as many as a frame sequence has; fewer than a count given are
    warned of); `train_every`: readouts between training timestamps (default
    `default_train_every`); `spp`: samples per pixel of a built-in scene (a square, s×s: each pixel
    its box's mean light; default 1, its centre) or a Mitsuba scene (default 16), recorded in
    meta.json; `sim_params`: SimParams fields (threshold, rate_at_one, ...)."""
    params = SimParams(**sim_params)
    asked = (test_on_path, test_off_path)
    motion = {"speed": speed, "frame_every": frame_every, "up": up}  # a frame sequence has its own
    speed = DEFAULT_SPEED if speed is None else speed
    frame_every = DEFAULT_FRAME_EVERY if frame_every is None else frame_every
    up = WORLD_UP if up is None else unit_vector("up", up)
    test_on_path = DEFAULT_TEST_VIEWS if test_on_path is None else test_on_path
    test_off_path = DEFAULT_TEST_VIEWS if test_off_path is None else test_off_path
    # numpy numbers and whole floats were written into meta.json (a TypeError after the
    # simulation, or a dataset that does not load): converted or refused before any work
    height, width, readouts, test_on_path, test_off_path = whole_numbers(
        height=height,
        width=width,
        readouts=readouts,
        test_on_path=test_on_path,
        test_off_path=test_off_path,
    )
    if train_every is not None:
        (train_every,) = whole_numbers(train_every=train_every)
    if spp is not None:
        (spp,) = whole_numbers(spp=spp)
    speed, frame_every = finite_numbers(speed=speed, frame_every=frame_every)
    if not math.isfinite(speed * readouts):  # (numpy's warnings, then "the pose ... not rigid")
        raise ValueError(
            f"speed (--speed): expected degrees a readout that turn the orbit by a finite "
            f"angle over the {readouts} readouts, found {speed:g} (at 180 or more a readout "
            f"the orbit aliases)"
        )
    flip, color = as_flag("flip", flip), as_flag("color", color)
    # (truthy words were taken: progress="no" drew bars, overwrite=1 replaced a dataset)
    progress, overwrite = as_flag("progress", progress), as_flag("overwrite", overwrite)
    if height < 1 or width < 1:
        raise ValueError(
            f"height, width (--height, --width): expected >= 1 pixel, found {height}, {width}"
        )
    if spp is not None and spp < 1:
        raise ValueError(f"spp (--spp): expected samples per pixel >= 1, found {spp}")
    if not is_seed(seed):
        raise ValueError(f"seed (--seed): expected an integer in 0..2**64 - 1, found {seed}")
    seed = int(seed)
    if test_on_path < 0 or test_off_path < 0:
        raise ValueError(
            f"test_on_path, test_off_path (--test-on-path, --test-off-path): expected counts "
            f">= 0, found {test_on_path}, {test_off_path}"
        )
    # the default's on-path views: their windows kept from training (4 WINDOW_MARGIN + 1
    # readouts each) cover at most half the readouts training could use (as many as fit left
    # training timestamps at the path's two ends alone: 1000 readouts held 7, 22 % of the path
    # trained, off-path views 20.6 dB where 2 views gave 25.9)
    held, usable = 4 * WINDOW_MARGIN + 1, readouts - 2 * WINDOW_MARGIN  # [32, T - 33]
    room = usable // (2 * held)
    fewer_views = None  # said once the scene is known
    if asked[0] is None and room < test_on_path:
        if room >= 0:  # (under none the stream is refused below)
            fewer_views = (
                f"{readouts} readouts hold {room} on-path held-out views of the default "
                f"{test_on_path} (each keeps the {held} readouts around it from training; the "
                f"default keeps at most half of the {usable} training could use: "
                f"{2 * held * test_on_path + 2 * WINDOW_MARGIN} readouts for {test_on_path}): add "
                f"readouts for more, or set test_on_path (--test-on-path)"
            )
        test_on_path = max(room, 0)
    min_readouts = 2 * WINDOW_MARGIN + 2 + held * test_on_path  # (128 a view: 194 gave one)
    if readouts < min_readouts and not test_on_path:  # (holding out fewer than none frees none)
        raise ValueError(
            f"readouts (--readouts): expected >= {min_readouts}, found {readouts}: two training "
            f"timestamps at the least, each with the {2 * WINDOW_MARGIN + 1}-readout window "
            f"around it in the stream"
        )
    if readouts < min_readouts:
        raise ValueError(  # (-1 was named as if the held-out views alone wanted more)
            f"readouts (--readouts): expected >= {min_readouts}, found {readouts}: "
            f"{2 * WINDOW_MARGIN + 2} for two training timestamps, each with the "
            f"{2 * WINDOW_MARGIN + 1}-readout window around it, and {held} for each of the "
            f"{test_on_path} on-path held-out views (test_on_path, --test-on-path): add "
            f"readouts or hold out fewer"
        )
    train_every = default_train_every(readouts) if train_every is None else train_every
    if train_every < 1:
        raise ValueError(f"train_every (--train-every): expected >= 1 readout, found {train_every}")
    if frame_every < 1:  # 1e-5 over 200 readouts: 2e7 poses, 3.6 GB, before any spike
        raise ValueError(
            f"frame_every (--frame-every): expected >= 1, found {frame_every:g}: each readout "
            f"reads the light from the two frames around it, so frames closer than a readout are "
            f"never read"
        )
    if 2 in (height, width) or (height, width) == (1, 1):
        raise ValueError(
            f"{height}x{width} images cannot be scored (SSIM, in spikegs eval, needs each side 1 "
            f"or at least 3 pixels, and not 1x1)"
        )
    # another simulation writing `out` (its spikes' temporary read as "what an interrupted
    # simulation left"), or a training reading it: refused as busy, before any work
    refuse_if_in_use(out, OTHER_OUT)
    check_output(out, overwrite)  # before any work
    channels = 3 if color else 1
    source = make_source(scene, width, height, channels, spp=spp, up=up)
    if fewer_views is not None:  # (an unknown scene was refused after it)
        warnings.warn(fewer_views, stacklevel=2)
    if isinstance(scene, RenderSource) and motion["up"] is not None:
        raise ValueError(f"up: the source '{source.name}' given sets its own (its up)")
    if isinstance(scene, Source) and source.kind != "frames" and spp is not None:  # (dropped)
        raise ValueError(f"spp: the source '{source.name}' given sets its own (its spp)")
    given = [name for name, value in motion.items() if value is not None]
    if source.kind == "frames" and given:  # (dropped in silence, before)
        warnings.warn(
            f"scene '{source.name}' is a frame sequence, whose frames and poses set the camera's "
            f"motion: {', '.join(given)} (a built-in or Mitsuba scene's orbit) ignored",
            stacklevel=2,
        )
    if source.kind == "frames" and spp is not None:
        warnings.warn(
            f"scene '{source.name}' is a frame sequence, whose frames are the light: spp (--spp, "
            f"a built-in or Mitsuba scene's samples per pixel) ignored",
            stacklevel=2,
        )
    if (source.height, source.width, source.channels) != (height, width, channels):
        raise ValueError(
            f"source '{source.name}' gives {source.height}x{source.width}x{source.channels} "
            f"images, expected {height}x{width}x{channels}"
        )
    # the camera as load_dataset will check it, before any work (a frame 40 times as tall as
    # wide, its focal length set by the width, was written whole and then refused; a source's
    # own camera can still give such a view)
    camera = {"height": height, "width": width, **intrinsics_keys(source.K)}
    try:
        check_meta_values(camera, f"scene '{source.name}'", ["fx", "fy", "cx", "cy"])
    except ValueError as err:
        raise ValueError(
            f"{err}: the camera scene '{source.name}' gives a {height}x{width} frame (another "
            f"size, a narrower field of view, or a principal point nearer the image's centre)"
        ) from None
    trajectory = source.trajectory(readouts, speed)
    rate = params.rate_at_one  # test images in firing-rate units, as TFP estimates them
    on_path = source.on_path_times(readouts, test_on_path, 2 * WINDOW_MARGIN)  # [n]
    views = [
        TestView(
            f"on_{i:03d}", trajectory.pose_at(t), source.image_at(trajectory, t) * rate, float(t)
        )
        for i, t in enumerate(on_path)
    ]
    # an orbit's over the arc its path turns, where its off_path_views takes one (RenderSource's:
    # a Source of the user's own, or a subclass of ProceduralSource overriding it, may take only
    # the count, Source's signature); the rendered images not kept beside their firing rates
    # (through the simulation: 8 views of 1080x1920 colour, 0.2 GB)
    takes_arc = "arc_deg" in inspect.signature(source.off_path_views).parameters
    arc = {"arc_deg": speed * (readouts - 1)} if takes_arc else {}
    codes = f"scene '{source.name}': test view"  # (8-bit codes were scored as light 255 x white)
    views += [
        TestView(name, viewmat, not_codes(np.asarray(image), f"{codes} {name!r}") * rate, None)
        for name, viewmat, image in source.off_path_views(test_off_path, **arc)
    ]
    off_path = len(views) - len(on_path)  # the views the source gives off the path
    where = f"scene '{source.name}'"
    # said with the ways to a view; none asked (0, 0): plainly, by check_test_views. The frames
    # were blamed for holding no on-path view where none was asked (the trial and the reviews)
    tests = "test frames: a transforms_test.json beside its file, FrameSequenceSource's test_views"
    if not views and source.kind == "frames" and asked != (0, 0):
        if asked[0] == 0:
            where += f" (no on-path view asked, and no {tests})"
        else:
            where += (
                f" (its frames within {2 * WINDOW_MARGIN} readouts of the recording's ends hold "
                f"no on-path view: more frames or readouts"
                + (f", or {tests})" if asked[1] != 0 else ")")
            )
    check_test_views(views, where)  # before any work
    # a frame sequence holds so many frames and test views: its defaults are as many as it has;
    # an orbit's are said where it gives fewer (a still camera's arc held one off-path view)
    wanted = asked if source.kind == "frames" else (test_on_path, test_off_path)
    if any(n is not None and got < n for n, got in zip(wanted, (len(on_path), off_path))):
        how = "asked" if wanted == asked else "asked or by default"
        warnings.warn(
            f"scene '{source.name}' gives {len(on_path)} on-path and {off_path} off-path "
            f"test views of the {test_on_path} and {test_off_path} {how} (an on-path view is a "
            f"frame {2 * WINDOW_MARGIN} readouts or more from the ends, distinct; an orbit's "
            f"off-path views lie a degree or more apart over the arc it turns)",
            stacklevel=2,
        )
    warn_about_data(views, trajectory, params, speed if source.kind != "frames" else None)
    if motion["frame_every"] is None and source.kind != "frames":  # (a frame sequence's own)
        frame_every = float(default_frame_every(source, trajectory, readouts))
    try:  # (a Source of one's own: the simulator named "frame times" alone, after the views)
        times = checked_times(source.light_times(readouts, frame_every), None, readouts - 1)  # [F]
    except ValueError as err:
        raise ValueError(f"scene '{source.name}': light_times: {err}") from None
    warn_about_frames(source, trajectory, times)
    if abs(speed) >= 180:  # the poses cannot show it: consecutive readouts look still or reversed
        warnings.warn(
            f"speed {speed:g}° a readout: the orbit is sampled at most twice a turn, so the "
            f"camera appears still or turning backwards (aliasing); a speed below 180°",
            stacklevel=2,
        )
    elif (motion := camera_motion(trajectory))[0] < STILL_DEGREES and motion[1] < (
        STILL_MOVE * source.scene_radius
    ):
        warnings.warn(
            f"the camera turns {motion[0]:.2g}° and moves {motion[1]:.2g} (scene radius "
            f"{source.scene_radius:.3g}) over the {readouts} readouts: every training view sees "
            f"the scene from one place, and the views off the path cannot be reconstructed "
            f"(poses that move around the scene can)",
            stacklevel=2,
        )
    held_out = [v.readout for v in views if v.readout is not None]
    timestamps = train_timestamps(readouts, np.array(held_out), train_every)
    clear = train_timestamps(readouts, np.array(held_out), 1)  # [N] the readouts to train at
    fewer = "more readouts, or fewer on-path held-out views (--test-on-path)"
    remedy = "a smaller train_every (--train-every)" if len(clear) > len(timestamps) else fewer
    # views asked for that keep most of the path from training (--test-on-path 7 over 1000
    # readouts: 16 % of it trained, off-path views 20.6 dB where 2 gave 25.9)
    if asked[0] is not None and len(clear) < FEW_TRAINED * usable:
        warnings.warn(
            f"the {len(held_out)} on-path held-out views keep {usable - len(clear)} of the "
            f"{usable} readouts training could use from it (each the {held} around it): it "
            f"trains on {100 * len(clear) / usable:.0f} % of the path, and the views off it are "
            f"reconstructed from that alone; {fewer}",
            stacklevel=2,
        )
    spaced = len(train_timestamps(readouts, np.array([]), train_every))  # none held out
    # (--train-every 150 over 1500 readouts kept 2 of 10, unsaid)
    if 2 <= len(timestamps) < min(spaced / 2, FEW_TIMESTAMPS):
        warnings.warn(
            f"{len(timestamps)} training timestamps of the {spaced} that train_every "
            f"{train_every} spaces over {readouts} readouts: the others lie within "
            f"{2 * WINDOW_MARGIN} readouts of the {len(held_out)} on-path held-out views (their "
            f"windows kept clear of the views' spikes); {remedy}",
            stacklevel=2,
        )
    if len(timestamps) < 2:
        if not len(timestamps):  # (was refused on loading, after the simulation)
            raise ValueError(
                f"no training timestamp: train_every {train_every} over {readouts} readouts, "
                f"around {len(held_out)} on-path held-out views; {remedy}"
            )
        warnings.warn(
            f"one training timestamp (readout {timestamps[0]}; train_every {train_every} over "
            f"{readouts} readouts): every step trains on one view, which cannot place the scene "
            f"in depth; {remedy}",
            stacklevel=2,
        )
    K = source.K
    meta = {
        "format_version": FORMAT_VERSION,
        "scene": source.name,
        "source": source.kind,
        "height": height,
        "width": width,
        "channels": channels,
        "num_readouts": readouts,
        "readout_period_s": READOUT_PERIOD_S,
        "flip": flip,
        "spike_files": spike_files(channels),
        "seed": seed,
        "sim": dataclasses.asdict(params),
        **intrinsics_keys(K),
        "scene_center": source.scene_center.tolist(),
        "scene_radius": source.scene_radius,
        "degrees_per_readout": speed if source.kind != "frames" else None,
        "frame_every": frame_every if source.kind != "frames" else None,
        "up": source.up.tolist() if isinstance(source, RenderSource) else None,  # the spiral's
        "luma": "rec709-linear" if channels == 1 else None,
        "image_scale": rate,
        "train_every": train_every,
        "spp": getattr(source, "spp", None),  # a rendered scene's samples per pixel
    }
    # one process writes `out`, none reading it (a training's SIM cache, its spikes): the checks
    # again under the lock, which --overwrite's deletion keeps
    made = not Path(out).exists()  # (removed again where the simulation fails)
    with writing_dataset(out, OTHER_OUT):
        out = check_output(out, overwrite)
        # and still empty but for the lock once it is held: another simulation into `out` may
        # have finished between the look and the lock (this one, --overwrite, then replaces it)
        made = made and all(entry.name == LOCK for entry in out.iterdir())
        # the new dataset is written into out/STAGING and loaded there, and replaces the old one
        # only then: a simulation whose light saturates the sensor (or leaves it dark), refused
        # on loading, or one that fails or is stopped, leaves no unloadable dataset and keeps
        # an old one
        staging = out / STAGING
        if staging.exists():  # what an interrupted simulation left (--overwrite was given)
            shutil.rmtree(staging)
        staging.mkdir()
        try:
            write_spikes(source, trajectory, times, staging, readouts, seed, params, flip, progress)
            write_parts(staging, meta, trajectory, timestamps, views)
            del views, source  # the test images (and a frame sequence's frames) not held twice
            with warnings.catch_warnings():  # (the load of `out` below says them)
                warnings.simplefilter("ignore")
                try:
                    load_dataset(staging)
                except ValueError as err:  # its files named as the dataset's, which it is not
                    said = str(err).replace(str(staging), str(out))
                    raise ValueError(f"{said}; the simulation is not kept") from None
        except BaseException as err:
            shutil.rmtree(out if made else staging, ignore_errors=True)
            if isinstance(err, OSError) and err.errno == errno.ENOSPC:  # named as `out`'s
                need = readouts * channels * height * ((width + 7) // 8)  # the spikes' bytes
                said = f"{err.strerror} for the new dataset (its spikes {need / 2**20:.1f} MiB)"
                if holds_dataset(out):
                    said += (
                        ", written beside the one it replaces, which stays until it loads: the "
                        "old dataset is kept; delete it first, or free room on the disk"
                    )
                raise OSError(
                    errno.ENOSPC, f"{said}; the simulation is not kept", str(out)
                ) from err
            raise
        # the old dataset's files deleted and the new one's moved in, not torn by a stop: a
        # Ctrl-C there left a folder of both (a new spikes.dat beside the old meta.json)
        stop = "\n{signal}: stopping once the new dataset has replaced the old one"
        with deferred_interrupt(stop) as interrupted:
            move_in(out)
        if interrupted():
            raise interruption(interrupted())
        with warnings.catch_warnings():  # (said above, before the work: warn_about_data)
            warnings.simplefilter("ignore", DarkSpikesWarning)
            warnings.simplefilter("ignore", FaintLightWarning)
            return load_dataset(out)
