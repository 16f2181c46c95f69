"""Supervision images for training, computed once per training timestamp, in intensity units.

Each image is computed the first time a run samples its timestamp and kept from then on: n
steps over M timestamps visit about M·(1 − exp(−n/M)) of them (3000 steps: ~1,990 of 3,400), and
SIM inference at the others (0.2-0.3 s a 256² frame in float32) would be wasted. What a run keeps
is capped at a quarter of the memory the process may use (`ImageBudget`: 50,000 timestamps of
250×400 would hold 20 GB per target); past it, images are computed at each visit.

Spike images (TFP, TFI, SIM) are firing rates, spikes per readout; dividing by the rate that
intensity 1.0 fires (the simulator's calibration, or for real data a high percentile of TFP)
puts targets, renders and ground truth on a [0, 1]-like scale where the 3DGS defaults hold.
"""

from __future__ import annotations

import math
import sys
import warnings
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import torch

from .config import Config, SimConfig
from .flicker import MAX_DEPTH, cached_flicker
from .machine_memory import machine_memory
from .number_checks import is_number
from .pixel_defects import defect_maps, sensor_defects
from .sim_train import (
    fast_inference_model,
    meta_seconds,
    predict,
    recorded_meta,
    train_or_load,
    weights_digest,
)

# readouts from a timestamp k to the time TFI(k) shows: its inter-spike interval straddles
# readouts k and k + 1 (a time ramp measures +0.50), so its pose is rendered there
TFI_TIME = 0.5
# of the image's larger side: the scene moving further within a target's window of readouts is
# warned of. The default orbit's sphere moves 8 % of it in 33 readouts; simulate warns of a turn
# of 15° in 33, where it moves 23 %. spikegs on a 64² `solids` at 600 iterations: 29.62 dB at
# the default speed (8 %), 26.98 at 0.5° a readout (25 %), 25.31 at 1.5° (70 %), 2026-12-07
BLUR_SHARE = 0.2


class ImageBudget:
    """Bytes that a run's target images may keep, shared by its instant and exposure images
    (default: a quarter of the memory this process may use, `machine_memory`); past it, images
    are computed at each visit, said once."""

    def __init__(self, limit: int | None = None):
        self.limit = machine_memory() // 4 if limit is None else limit
        self.used = self.kept = 0  # bytes, images
        self.full = False

    def take(self, nbytes: int) -> bool:
        """Whether an image of `nbytes` fits (then counted as kept)."""
        if self.used + nbytes <= self.limit:
            self.used += nbytes
            self.kept += 1
            return True
        if not self.full:
            self.full = True
            warnings.warn(
                f"training images: {self.kept} kept fill {self.used / 2**30:.2f} GiB of "
                f"{self.limit / 2**30:.2f}, a quarter of the memory this process may use; "
                f"images of further timestamps are computed at each visit (SIM's inference each "
                f"step: slower). Fewer training timestamps keep them all: a larger "
                f"`simulate --train-every`, spikegs.json's train_every (an LLFF layout's one "
                f"stream), or fewer lines in a meta.json dataset's train_timestamps.txt",
                stacklevel=3,
            )
        return False

    def give_back(self, nbytes: int, images: int) -> None:
        """Count `images` kept images of `nbytes` in all as dropped."""
        self.used -= nbytes
        self.kept -= images


class TargetImages:
    """Images [H, W, C] in intensity units at a run's training timestamps, indexed like them;
    each computed on first access (`image_fn` of that one readout) and kept while `budget`
    lasts. `quantum`: one spike of the TFP window that they count or estimate, in intensity
    units (smooth L1's zone). `time_offset`: readouts from a timestamp to the time its image
    shows (TFI's: +0.5), where the trainer renders the instant pose. `valid`: the pixels [H, W,
    C] a loss may compare (None: all; `pixel_defects`)."""

    def __init__(
        self,
        timestamps: np.ndarray,
        image_fn: Callable,
        scale: float,
        quantum: float,
        time_offset: float = 0.0,
        budget: ImageBudget | None = None,
        valid: torch.Tensor | None = None,
    ):
        self.timestamps = timestamps  # [M] readouts
        self.valid = valid
        self.time_offset = time_offset
        self._image_fn = image_fn  # readouts [n] -> firing rates [n, H, W, C]
        self._scale = scale  # firing rate of intensity 1.0
        self.quantum = quantum
        self._cache: dict[int, torch.Tensor] = {}
        self._budget = ImageBudget() if budget is None else budget
        self._kept: set[int] = set()  # the indices whose images were kept, released or not

    def __len__(self) -> int:
        return len(self.timestamps)

    def __getitem__(self, index: int) -> torch.Tensor:
        image = self._cache.get(index)
        if image is None:
            rates = self._image_fn(self.timestamps[index : index + 1])[0]  # [H, W, C]
            image = torch.from_numpy(rates / np.float32(self._scale))
            if self._budget.take(image.nbytes):
                self._cache[index] = image
                self._kept.add(index)
        return image

    @property
    def computed(self) -> int:
        """How many timestamps' images have been computed and kept so far (all computed while
        the budget lasts), also once `release`d."""
        return len(self._kept)

    @property
    def nbytes(self) -> int:
        """The bytes of the images held now."""
        return sum(image.nbytes for image in self._cache.values())

    def release(self) -> None:
        """Drop the images held (a run's, once it stops: a Trainer kept in a notebook held them,
        up to a quarter of the memory, run after run), their bytes back to the budget; an image
        asked for again is computed again."""
        self._budget.give_back(self.nbytes, len(self._cache))
        self._cache.clear()


@dataclass
class Targets:
    timestamps: np.ndarray  # [M] readouts
    instant: TargetImages | None  # M images [H, W, C], or None
    exposure: TargetImages | None  # M images [H, W, C], or None
    sim_seconds: float = 0.0  # SIM's training time (loaded from its cache: the time it recorded)
    # the instant targets' SIM: its file ("path"), weights' "digest", the "threads" and "bf16"
    # it trained with (as its file records them) and the dtype it infers in ("inference")
    sim: dict | None = None
    # what the spikes showed that the targets leave out (train.json's `found_in_spikes`): the
    # light's flicker (None: none found, or not looked for) and the defect pixels masked
    found: dict = field(default_factory=dict)

    def release(self) -> None:
        """Drop the images both hold (`TargetImages.release`)."""
        for images in (self.instant, self.exposure):
            if images is not None:
                images.release()


def sample_timestamps(dataset) -> np.ndarray:
    """Every (M // 16)-th of the M training timestamps: all of them where M < 32, else 16 to 24."""
    return np.asarray(dataset.train_timestamps[:: max(1, len(dataset.train_timestamps) // 16)])


def tfp_sample(dataset) -> tuple[np.ndarray, np.ndarray]:
    """`sample_timestamps` and their TFP(33) firing rates [S, H, W, C]."""
    ts = sample_timestamps(dataset)
    return ts, _per_channel(dataset.streams, lambda s: s.tfp(ts, 33))


def intensity_scale(dataset) -> float:
    """Firing rate of intensity 1.0: the simulator's calibration (rate_at_one) or meta.json's
    image_scale (which must agree), else TFP(33)'s 99.5 percentile over the pixels that are not
    sensor defects (`pixel_defects`)."""
    from .data.dataset import stated_scales  # data.real imports this module

    stated = stated_scales(dataset.meta)
    for key, rate in stated.items():
        if not (is_number(rate) and 0 < rate <= 1):  # a pixel fires at most once a readout
            raise ValueError(
                f"{dataset.root}: {key} (firing rate of intensity 1: meta.json, or "
                f"spikegs.json's rate_at_one for a real layout) expected a number in (0, 1], "
                f"spikes a readout; found {rate!r}"
            )
    if len(stated) == 2 and abs(stated["rate_at_one"] - stated["image_scale"]) > 1e-6:
        raise ValueError(
            f"{dataset.root}: rate_at_one {stated['rate_at_one']!r} and image_scale "
            f"{stated['image_scale']!r}: both state the firing rate of intensity 1, and differ"
        )
    if stated:
        return float(next(iter(stated.values())))
    ts, rates = tfp_sample(dataset)  # [S, H, W, C]
    # not at the hot or stuck pixels found (0.6 % of them, the top of a sensor's usual share,
    # guessed 1.0 for 0.18, scoring 14 dB higher, unsaid), which the losses leave out too
    defects = np.moveaxis(defect_maps(dataset.streams), 0, -1)  # [H, W, C]
    guess = float(np.percentile(rates[:, ~defects] if not defects.all() else rates, 99.5))
    if guess == 0:
        warnings.warn(
            f"{dataset.root}: TFP(33) is 0 at 99.5 % or more of the pixels of {len(ts)} training "
            f"windows spread over the stream: the intensity scale (the firing rate of intensity "
            f"1) is taken as 1; state it (meta.json's image_scale, or spikegs.json's "
            f"rate_at_one: the camera's TFP over a white patch divided by that patch's "
            f"intensity, docs/training.md)",
            stacklevel=1,  # here: said once, however many callers ask
        )
        return 1.0
    return guess


def _per_channel(streams, image_fn) -> np.ndarray:
    """`image_fn(stream)` [M, H, W] (or [M, H, W, 1]) of each channel's stream -> [M, H, W, C]."""
    images = [np.asarray(image_fn(s), dtype=np.float32) for s in streams]
    return np.concatenate([i if i.ndim == 4 else i[..., None] for i in images], axis=-1)


def sim_crop(dataset, sim: SimConfig) -> int:
    """The crop that SIM's training takes: `sim.crop`, at most the frames' larger side."""
    return min(sim.crop, max(dataset.height, dataset.width))


def sim_path(dataset, sim: SimConfig, seed: int, repaired: bool = True) -> Path:
    """Where a dataset's trained SIM is cached, shared by the methods with the same SIM settings
    and spikes: the sensor's defects `repaired` in them (supervision.mask_defects), or not
    (`_raw`: runs of each, sharing a name, retrained over each other's SIM as on other spikes)."""
    depth = "" if sim.shift_layers == SimConfig.shift_layers else f"_m{sim.shift_layers}"
    crop = sim_crop(dataset, sim)
    name = (
        f"sim_w{sim.window}_t{sim.target_readouts()}_it{sim.iterations}_b{sim.batch}"
        f"_c{crop}_{sim.loss}{depth}{'' if repaired else '_raw'}_seed{seed}.pt"
    )
    return Path(dataset.root) / "sim" / name


def trained_sim(
    dataset,
    sim: SimConfig,
    seed: int,
    *,
    path: Path | None = None,
    force: bool = False,
    progress: bool = True,
    streams: list | None = None,
    repaired: bool = True,
):
    """(SIM, seconds spent training it, path): the one cached for `sim`'s settings (at `path`, by
    default `sim_path`; `train_or_load` may cache elsewhere; a SIM trained otherwise at a `path`
    given is refused, not replaced, unless `force`), else trained on every channel's stream
    (`streams`, by default the dataset's; the sensor's defects `repaired` in them or not) at the
    training timestamps. The other of the repaired and raw spikes' caches serves where it holds
    a SIM of the same spikes (a dataset without defects: `_raw` trained a copy, bit for bit)."""
    other = [] if path is not None else [sim_path(dataset, sim, seed, not repaired)]
    model, seconds, path = train_or_load(
        path or sim_path(dataset, sim, seed, repaired),
        streams or dataset.streams,  # a colour camera's channels share one SIM
        dataset.train_timestamps,
        sim.window,
        force=force,
        keep=path is not None,
        alternates=other,
        steps=sim.iterations,
        batch_size=sim.batch,
        crop=sim_crop(dataset, sim),  # as the cache's name has it
        loss=sim.loss,
        target_window=sim.target_readouts(),
        seed=seed,
        progress=progress,
        shift_layers=sim.shift_layers,
    )
    return model, seconds, path


def clean_images(dataset, quantum: float, budget: ImageBudget | None = None) -> TargetImages:
    """The noise-free instant images at the training timestamps, rendered by the source that a
    built-in scene's dataset was simulated from at the poses it was simulated from (already in
    intensity units; poses estimated since do not move them); `quantum`: the smooth-L1 zone they
    are compared within (they count no spikes); `budget`: what they may keep."""
    from .data.simulate import clean_source, simulated_trajectory  # the data package imports us

    source, poses = clean_source(dataset), simulated_trajectory(dataset)
    ts = np.asarray(dataset.train_timestamps)
    render = lambda readouts: np.stack(  # noqa: E731
        [source.image_at(poses, float(t)) for t in readouts]
    ).astype(np.float32)
    return TargetImages(ts, render, 1.0, quantum, budget=budget)


def check_targets(dataset, config: Config) -> None:
    """ValueError, before any work (SIM training, target images, a run folder), where `config`'s
    targets cannot be made from `dataset`: a window that, centred on a training timestamp, would
    reach past the stream (naming the setting), or clean images of a dataset that no built-in
    scene rendered."""
    from .data.dataset import TIMESTAMPS  # (the data package imports us)
    from .data.view_stream import ViewStreams

    s, ts = config.supervision, np.asarray(dataset.train_timestamps, dtype=np.int64)
    instant = config.instant_target()
    windows = {"sim.window": config.sim.window} if instant == "sim" else {}
    if instant == "tfp":
        windows["supervision.instant_window"] = s.instant_window
    if s.exposure_weight > 0:
        windows["supervision.exposure_window"] = s.exposure_window
    stream = dataset.streams[0]
    room = int(readouts_beside(stream, ts).min())
    for name, w in windows.items():
        if w // 2 > room:
            if isinstance(stream, ViewStreams):  # a window stays in its timestamp's view
                first, end = stream.bounds(ts)
                sizes = ", ".join(map(str, sorted(set(end - first))))
                where, ends = f"each in its view of {sizes} readouts", "their views'"
            else:
                where, ends = f"{ts.min()}..{ts.max()} of {len(stream)} readouts", "the stream's"
            listed = Path(dataset.root, TIMESTAMPS)
            listed = f" (listed in {listed})" if listed.is_file() else ""
            raise ValueError(
                f"{config.set_by(name)}: {name} = {w} readouts does not fit around the training "
                f"timestamps of {dataset.root} ({where}): at most {2 * room + 1}; a shorter "
                f"window, or training timestamps {w // 2} readouts or more inside {ends} ends"
                f"{listed}"
            )
    # the exposure's renders lie within the window's readouts (exposure_poses <= its length),
    # TFI's half a readout after its timestamp: poses there, where they do not cover the stream's
    # ends (a real recording's pose log, or a Dataset built in Python)
    reach = s.exposure_window // 2 if s.exposure_weight > 0 else 0
    late = max(reach, TFI_TIME if instant == "tfi" else 0)
    trajectory = dataset.trajectory
    early = ts.min() - reach < trajectory.start
    if early or ts.max() + late > trajectory.end:
        what = (
            f"{config.set_by('supervision.exposure_window')}: supervision.exposure_window = "
            f"{s.exposure_window} readouts around the training timestamps reaches"
            if reach
            else f"TFI's images, {TFI_TIME} readouts after the training timestamps, lie"
            if late and not early
            else "the training timestamps lie"
        )
        raise ValueError(
            f"{what} past the poses of {dataset.root} (timestamps {ts.min()}..{ts.max()}, poses "
            f"over readouts {trajectory.start:g}..{trajectory.end:g}): "
            f"{'a shorter window, or ' if reach else ''}poses over more of the stream"
        )
    if instant == "clean":
        from .data.simulate import clean_source, simulated_trajectory  # (imports us)

        clean_source(dataset)
        simulated_trajectory(dataset)


def blurring_spans(config: Config) -> list[tuple[str, int, str]]:
    """(the setting that sets it, readouts, what they are) of each span of readouts that one
    image of `config`'s targets or renders stands for: the instant image's (SIM's target window,
    or the instant TFP's), and each of the exposure loss's renders' (its window over its poses:
    the motion across the window itself is modelled by them)."""
    s, instant, spans = config.supervision, config.instant_target(), []
    if instant == "sim":
        name = "sim.target_window" if config.sim.target_window else "sim.window"
        readouts = config.sim.target_readouts()
        spans.append((name, readouts, f"{name} = {readouts} readouts"))
    if instant == "tfp":
        spans.append(
            ("supervision.instant_window", s.instant_window, f"supervision.instant_window = "
             f"{s.instant_window} readouts")
        )  # fmt: skip
    if s.exposure_weight > 0:
        each = math.ceil(s.exposure_window / s.exposure_poses)
        spans.append(
            ("supervision.exposure_poses", each, f"the {each} readouts each of the exposure "
             f"loss's {s.exposure_poses} renders stands for (supervision.exposure_window "
             f"{s.exposure_window} / exposure_poses {s.exposure_poses})")
        )  # fmt: skip
    return spans


def warn_if_blurred(dataset, config: Config) -> None:
    """A UserWarning where the scene sphere's points move over BLUR_SHARE of the image's larger
    side within a span of readouts that one image of `config`'s targets or renders stands for
    (`blurring_spans`), by the dataset's poses: the images made from those spikes are motion-
    blurred (a pose log as fast as `simulate --speed 60`'s trained a near-constant image,
    unsaid). The span that moves most is named."""
    from .data.sphere_motion import window_motion  # (the data package imports us)

    side, ts = max(dataset.width, dataset.height), dataset.train_timestamps
    moves = [
        (window_motion(dataset, dataset.trajectory, ts, readouts), name, what)
        for name, readouts, what in blurring_spans(config)
    ]
    motion, name, what = max(moves, default=(0.0, "", ""))
    if motion > BLUR_SHARE * side:
        remedy = "more poses" if name == "supervision.exposure_poses" else "a shorter window"
        warnings.warn(
            f"{dataset.root}: by its poses, the scene moves up to {motion:.0f} pixels "
            f"({motion / side:.0%} of the image's {side}) within {what} around a training "
            f"timestamp: the images made from them are motion-blurred, and a run learns the "
            f"scene smeared; {remedy} ({name}, {config.set_by(name)}), or a recording whose "
            f"camera moves slower against the readout rate",
            stacklevel=3,
        )


def readouts_beside(stream, ts: np.ndarray) -> np.ndarray:
    """The readouts [N] of `stream` on both sides of each readout `ts` [N] (within its own view,
    of a stream per view): a window of 2 x that + 1 readouts around it fits."""
    from .data.view_stream import ViewStreams  # (the data package imports us)

    first, end = stream.bounds(ts) if isinstance(stream, ViewStreams) else (0, len(stream))
    return np.minimum(ts - first, end - 1 - ts)


def build_targets(
    dataset, config: Config, progress: bool = True, instant_left: bool = True
) -> Targets:
    """Instant and exposure targets of `config`'s method at the dataset's training timestamps
    (SIM trained, or loaded from its cache, now; the images themselves on first use); no
    instant ones where none is `instant_left` to train (a run resumed past their last step: SIM
    was trained again, 100 s, where its cache was gone)."""
    s = config.supervision
    ts = np.asarray(dataset.train_timestamps)
    check_targets(dataset, config)
    scale = intensity_scale(dataset)
    streams = dataset.streams  # [C] SpikeStreams, one per channel

    def spike(window: int) -> float:
        """One spike of a `window`-readout TFP, in intensity units."""
        return 1.0 / (window * scale)

    budget = ImageBudget()  # the instant and exposure images' together
    # (clean images, the oracle's, are the simulator's light: no flicker to look for or divide)
    from_spikes = config.instant_target() not in ("none", "clean") or s.exposure_weight > 0
    flicker = cached_flicker(streams, progress) if s.deflicker and from_spikes else None
    found = None
    if flicker is not None:
        deep = flicker.depth >= MAX_DEPTH  # dividing would make targets negative or infinite
        done = (
            f"too deep for a sinusoid (under {MAX_DEPTH:g}: a light switched on and off?), so "
            f"the targets are left as the spikes show them"
            if deep
            else "each training target is divided by the flicker over its readouts"
        )
        warnings.warn(
            f"{dataset.root}: the light flickers with a period of {flicker.period:.1f} readouts, "
            f"depth {flicker.depth:.2f} (lamps on mains power?): {done} (docs/datasets.md, "
            f"'Lighting flicker')",
            stacklevel=2,
        )
        found = {**asdict(flicker), "divided": not deep}
        flicker = None if deep else flicker

    def images(
        stream_fn, window: int, time_offset: float = 0.0, span: int = 0, sources=None
    ) -> TargetImages:
        """`stream_fn(stream, readouts)` on each channel's stream of `sources` (default
        `streams`), stacked on the channel axis; images that count or estimate the spikes of
        `window` readouts, and show the light of `span` readouts from k - span // 2 +
        time_offset (default `window`), over any flicker there."""
        span = span or window

        def per_channel(k):  # readouts [n] -> [n, H, W, C]
            rates = _per_channel(sources or streams, lambda st: stream_fn(st, k))
            return rates if flicker is None else flicker.divided(rates, k, span, time_offset)

        return TargetImages(ts, per_channel, scale, spike(window), time_offset, budget, valid)

    # a sensor's hot, stuck and dead pixels: left out of every loss against the spikes, and
    # repaired in the spikes SIM reads (it reads a defect's spikes into its neighbours)
    defects = sensor_defects(streams, dataset.root, s.mask_defects and from_spikes)
    valid = defects.valid

    instant, sim_seconds, sim = None, 0.0, None
    if config.instant_target() != "none" and instant_left:
        if s.instant == "sim":
            model, sim_seconds, path = trained_sim(
                dataset,
                config.sim,
                config.train.seed,
                progress=progress,
                streams=defects.streams,
                repaired=s.mask_defects,
            )
            trained = recorded_meta(path)  # (read once: its time, threads and precision)
            if sim_seconds == 0.0:  # loaded from its cache: its training cost this run all the same
                sim_seconds = meta_seconds(trained)
                took = f"trained in {sim_seconds:.0f} s" if sim_seconds else "no time recorded"
                print(f"SIM: loaded {path} ({took})", file=sys.stderr)
            fast = fast_inference_model(model)
            # how it trained (another thread count or precision is another SIM) and infers
            # (another precision gives other targets)
            sim = {
                "path": str(path),
                "digest": weights_digest(model),
                "threads": trained.get("threads"),
                "bf16": trained.get("bf16"),
                "inference": str(next(fast.parameters()).dtype).removeprefix("torch."),
            }
            # SIM estimates the TFP of its target window (17 readouts for sim17)
            window = config.sim.target_readouts()
            infer = lambda st, k: predict(fast, st.window(k, fast.window))  # noqa: E731
            instant = images(infer, window, sources=defects.streams)
        elif s.instant == "clean":
            instant = clean_images(dataset, spike(s.instant_window), budget)
        elif s.instant == "tfp":
            instant = images(lambda st, k: st.tfp(k, s.instant_window), s.instant_window)
        else:  # TFI counts no window: instant_window only sets smooth L1's zone
            instant = images(lambda st, k: st.tfi(k), s.instant_window, TFI_TIME, span=1)
    exposure = None
    if s.exposure_weight > 0:
        exposure = images(lambda st, k: st.tfp(k, s.exposure_window), s.exposure_window)
    left_out = {"flicker": found, "defect_pixels": defects.pixels}
    return Targets(ts, instant, exposure, sim_seconds, sim, left_out)
