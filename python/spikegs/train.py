"""The trainer: one loop for SpikeGS, its baselines and ablations (a method is a supervision).

A run directory holds config.yaml, log.jsonl (error against time), checkpoints/last.pt and, at the
end, scene.ply and train.json. Training resumes from the last checkpoint with `resume=True`.
"""

from __future__ import annotations

import copy
import functools
import json
import math
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import torch
from tqdm.auto import tqdm

from . import strict_json
from .atomic_save import save_atomically, sweep_temporaries, write_text_if_changed
from .config import (
    MIN_GAUSSIANS,
    SCHEDULE_KEYS,
    Config,
    available_methods,
    differences,
    warn_if_nothing_learns,
    warn_if_schedule_unscaled,
    with_defaults,
)
from .curves import logged_curve
from .data.dataset import (
    FEW_TIMESTAMPS,
    POINTS,
    camera_keys,
    check_dataset,
    check_edited_dataset,
    reading_dataset,
    scale_guessed,
)
from .data_fingerprint import data_fingerprint, file_digest, same_data
from .densify import Densifier
from .evaluate import score_view
from .filter_3d import filter_widths
from .fit_brightness import FitBrightness, biased_fit
from .gaussians import PARAMETER_NAMES, GaussianModel, frame_origin, near_plane
from .grad_mode import refuse_inference_mode
from .initial_intensity import ViewSample, projected_intensity
from .interrupt import deferred_interrupt, interruption, progress_lost, say
from .losses import dssim, exposure_loss, exposure_times, instant_loss
from .number_checks import as_flag, is_int
from .pixel_defects import hide
from .ply import load_ply, save_ply
from .point_cloud import (
    ball_points,
    distinct_points,
    gaussians_from_points,
    in_training_views,
    read_points,
    seen_points,
    view_coverage,
)
from .pose_refine import PoseRefiner, make_refiner
from .provenance import environment
from .psnr_fall import psnr_fall
from .regular_file import NotText, read_text
from .run_folder import FolderWatch, check_fresh_run_dir, run_lock
from .run_summary import CONFIG, FOUND, LOG, SCENE, SUMMARY, last_checkpoint, resume_command
from .sim_train import SAVED_EVERY
from .targets import build_targets, check_targets, intensity_scale, warn_if_blurred
from .yaml_files import dump_yaml

SPHERE_PROBES = 1000  # points spread through the scene sphere: half the views must see one
# the share of the median training view the scene sphere must cover, not to be warned of: a
# right sphere covers 53-100 % of its median view (72 datasets here, 8x6 to 128²); poses in
# units 10x the sphere's covered 0.8 % and trained 10.8 dB below the right sphere, a radius 0.3x
# the right one 9.4 % and 7.5 dB (BENCHMARKS.md, "The scene sphere's coverage, exact")
MIN_SPHERE_COVERAGE = 0.15
# the 3D filter's widths are recomputed this often as the Gaussians move (Mip-Splatting's 100),
# and after every densification round, from at most FILTER_3D_VIEWS training views spread evenly
# over the stream (a continuous path's neighbours differ little in depth: 256 of 726 moved a
# trained model's widths by 0.6 % at most; 50,000 Gaussians took 0.37 s against 1.3, one thread)
FILTER_3D_EVERY, FILTER_3D_VIEWS = 100, 256
CHECKPOINT_S = 60.0  # a checkpoint at least this often (seconds), whatever checkpoint_every says
# train.json's and a checkpoint's record of the point cloud the Gaussians started at (None: random
# points), and its value for a run from a checkpoint saved before it was recorded (2026-12-07)
START_POINTS, UNRECORDED = "start_points", "unrecorded"
# the bar while densification rounds remain, which slow the steps as they add Gaussians: its
# time left marked "+" (a 30000-iteration run's was 0.4-0.75x the time it then took)
GROWING_BAR = "{l_bar}{bar}| {n_fmt}/{total_fmt} [{elapsed}<{remaining}+, {rate_fmt}{postfix}]"


def _sim_text(sim: dict) -> str:
    """A SIM's record (`Targets.sim`) as a message shows it."""
    trained = {True: "bfloat16", False: "float32"}.get(sim.get("bf16"), "an unrecorded precision")
    threads = f"{sim['threads']} threads" if sim.get("threads") else "an unrecorded thread count"
    return (
        f"weights {str(sim.get('digest'))[:12]}, trained at {threads} in {trained}, inferring in "
        f"{sim.get('inference')}"
    )


def _sphere_text(sphere: list[float]) -> str:
    """A scene sphere [4] as a message shows it."""
    return f"centre [{', '.join(f'{c:.6g}' for c in sphere[:3])}], radius {sphere[3]:.6g}"


def _cut_log(path: Path, iteration: int) -> None:
    """Keep `path`'s records up to `iteration` (those of steps that a resumed run repeats, or all
    of a run that never checkpointed, are dropped)."""
    kept = []
    fix = "move it away to resume without the records before the checkpoint"
    if iteration > 0 and path.exists():
        try:
            lines = [line for line in read_text(path).splitlines() if line.strip()]
        except NotText as err:
            raise ValueError(f"{err}; {fix}") from None
        for number, line in enumerate(lines, start=1):
            try:
                record = json.loads(line)
            except ValueError as err:
                if number == len(lines):  # a last line cut short by a kill mid-write
                    break
                raise ValueError(
                    f"{path}: line {number} is not a log record ({err}); {fix}"
                ) from None
            step = record.get("iteration") if isinstance(record, dict) else None
            if not is_int(step):  # ("50": a TypeError at the comparison below)
                what = "iteration" if step is None else f"iteration {strict_json.json_text(step)}"
                raise ValueError(
                    f"{path}: line {number} is not a log record (no integer {what}); {fix}"
                )
            if step <= iteration:
                kept.append(line)
    write_text_if_changed(path, "".join(line + "\n" for line in kept))  # a kill keeps them all


def _optimizer(
    model: GaussianModel, config: Config, scene_radius: float, poses: PoseRefiner | None = None
) -> torch.optim.Adam:
    lr = config.lr
    groups = [
        {"params": [model.params[name]], "name": name, "lr": getattr(lr, name)}
        for name in PARAMETER_NAMES
    ]
    groups[0]["lr"] = lr.means * scene_radius
    groups.append({"params": [model.background], "name": "background", "lr": lr.background})
    if poses is not None:
        groups.append({"params": [poses.corrections], "name": "poses", "lr": config.pose_refine.lr})
    return torch.optim.Adam(groups, lr=0.0, eps=1e-15)


def _means_lr(config: Config, iteration: int, scene_radius: float) -> float:
    """Exponential decay from lr.means to lr.means_final over the run, times the scene radius."""
    frac = min(iteration / max(config.train.iterations, 1), 1.0)
    lr0, lr1 = config.lr.means, config.lr.means_final  # lr1 > 0 where lr0 > 0 (validated)
    if lr0 == 0:
        return 0.0
    return math.exp(math.log(lr0) * (1 - frac) + math.log(lr1) * frac) * scene_radius


def _finite_nonnegative(values: torch.Tensor | None) -> bool:
    """Whether a tensor of values >= 0 where finite (None or empty: yes) is all finite: its max
    carries NaN and inf, one reduction (a tenth of isfinite(...).all()'s time)."""
    return values is None or values.numel() == 0 or bool(torch.isfinite(values.max()))


class Trainer:
    """Trains a GaussianModel on `dataset` with the supervision of `config`, in `run_dir`."""

    def __init__(
        self,
        dataset,
        config: Config,
        run_dir: str | Path,
        progress: bool = True,
        settings_file: Path | None = None,
        resumable: bool = True,
        command_line: tuple[str, ...] = (),
    ):
        check_dataset(dataset, "Trainer")
        check_edited_dataset(dataset, "Trainer")  # (before its scale is taken from TFP)
        progress = as_flag("Trainer: progress", progress)  # ("no" drew the bar)
        # False where the caller trains the run afresh each time (the benchmarks): a Ctrl-C's
        # message then promises no --resume, which they have not
        self.resumable = as_flag("Trainer: resumable", resumable)
        if not isinstance(config, Config):  # (a dict: "'dict' object has no attribute 'validate'")
            raise TypeError(
                f"Trainer: config expected a Config (spikegs.config.load_config(METHOD, "
                f"overrides) makes one), found {type(config).__name__} {config!r:.80}"
            )
        # copies: a sweep that edits one Config between constructing its trainers (or after one
        # trained, before resuming it) trained every run with the last settings; validated, as
        # load_config validates: a value edited out of range (densify.every = 0, a float
        # train.iterations, an unknown supervision.instant) crashed mid-run or trained unsaid.
        # The dataset's timestamps edited so trained each run on the last, its train.json the
        # data it was built with (the API trial)
        self.dataset, self.config, self.progress = (
            dataset.copy(),
            copy.deepcopy(config).validate(),
            progress,
        )
        # absolute: a notebook's chdir during training took the folder for moved, and stopped
        self.run_dir = Path(run_dir).absolute()
        dataset = self.dataset
        self.scale = intensity_scale(dataset)
        self.K = torch.as_tensor(dataset.K, dtype=torch.float32)
        self.radius = float(dataset.scene_radius)
        self.near = near_plane(self.radius)
        # where the model's means are measured from (the scene's centre, for a scene far from
        # the world's origin)
        self.origin = frame_origin(dataset.scene_center, self.radius)
        self.checkpoint_path = last_checkpoint(self.run_dir)
        # the file `config` was read from where a resume takes the run's own (RUN/config.yaml),
        # and the settings the command line set over it (train.iterations, train.seed): a
        # checkpoint's other settings are then that file's edits
        self.settings_file, self.command_line = settings_file, command_line
        self.data = data_fingerprint(dataset, self.scale)
        self.sim_seconds = 0.0  # SIM's training time for this run, set when training starts
        self.sim = None  # the instant targets' SIM's record (`Targets.sim`), kept in checkpoints
        self.iteration, self.train_seconds = 0, 0.0  # a fresh state's or a checkpoint's, then
        self.brightness = FitBrightness()  # of the steps this process takes
        self.targets = None  # a training's target images (`build_targets`), released after it
        self.found = None  # what they leave out (`Targets.found`), kept in the checkpoint
        self.summary = None  # train.json's object once this process has written it
        self.saved_iteration = None  # the iteration of the last checkpoint this process saved
        self._watch = None  # the run folder, while this process trains in it (`FolderWatch`)

    # -- state ---------------------------------------------------------------------------------
    @functools.cached_property
    def cloud_points(self) -> np.ndarray | None:
        """The distinct points [P, 3] of the dataset's sparse point cloud (DATASET/points3d.ply,
        e.g. from `spikegs poses`) that the Gaussians start at; None where it has none, or fewer
        than a run may start with, or with fewer inside the training views (warned: they start
        at random points in the scene bounds); warned where most lie in no training view."""
        cloud = Path(self.dataset.root) / POINTS
        if not cloud.exists():
            return None
        # its digest as it is read (`start_points`): fresh state follows minutes of SIM training
        self._cloud_digest = file_digest(cloud)
        points = distinct_points(read_points(cloud))
        instead = "the Gaussians start at random points in the scene bounds instead"
        if len(points) < MIN_GAUSSIANS:
            warnings.warn(
                f"{cloud}: {len(points)} distinct point(s), fewer than {MIN_GAUSSIANS}: {instead}",
                stacklevel=2,
            )
            return None
        seen = int(seen_points(points, self.dataset).sum())
        unseen = (
            f"{cloud}: {len(points) - seen} of its {len(points)} distinct points lie in none of "
            f"the training views sampled along the stream (a cloud in another frame or unit than "
            f"the poses?)"
        )
        if seen < MIN_GAUSSIANS:
            warnings.warn(f"{unseen}: {instead}", stacklevel=2)
            return None
        if seen < len(points) / 2:
            warnings.warn(f"{unseen}: Gaussians started there get no gradient", stacklevel=2)
        return points

    def _check_scene_in_view(self) -> None:
        """ValueError where under half of the training views sampled along the stream see any
        of SPHERE_PROBES points spread through the scene sphere (each sees most of it in a
        capture of the scene): Gaussians start there, and poses given as world-to-camera
        matrices, or in the other axis convention, trained the background alone unsaid. A
        warning where the sphere covers under MIN_SPHERE_COVERAGE of the median view: a sphere
        too small for the poses' units, which trained unsaid."""
        d = self.dataset
        probes = ball_points(d.scene_center, self.radius, SPHERE_PROBES)  # [P, 3]
        seeing = in_training_views(probes, d).any(axis=1)  # [M]
        center = ", ".join(f"{c:.4g}" for c in d.scene_center)
        sphere = f"the scene sphere (centre [{center}], radius {self.radius:.4g})"
        if seeing.mean() < 0.5:
            raise ValueError(
                f"{d.root}: {seeing.sum()} of {len(seeing)} training views (sampled along the "
                f"stream) see any of {sphere} where the Gaussians start: check that the poses "
                f"are camera-to-world (not world-to-camera) in the convention the layout states "
                f"(OpenCV: x right, y down, z forward; OpenGL: y up, z back), and the scene "
                f"sphere (docs/datasets.md)"
            )
        coverage = self._sphere_coverage()
        if coverage >= MIN_SPHERE_COVERAGE:
            self._warn_of_test_views_elsewhere()
        else:
            warnings.warn(
                f"{d.root}: {sphere} covers {100 * coverage:.1f} % of the median training view "
                f"(a right one covers 53-100 % of views the scene fills): the Gaussians start "
                f"in it, and the means' learning rate, the near plane and the sizes "
                f"densification works with scale with its radius; a sphere too small for the "
                f"scene (a radius 0.3x the right one, or translations in units 10x its own) "
                f"trained 7.5-10.8 dB low. Check scene_center and scene_radius against the "
                f"poses (docs/datasets.md); where they are right, the scene is that small in "
                f"the views (cameras far from it: 100 radii away, a 40° view showed it a pixel "
                f"across, and a run learnt a constant)",
                stacklevel=2,
            )

    def _warn_if_few_timestamps(self) -> None:
        """A UserWarning where the dataset has one training timestamp (a real layout's one
        training view: loaded unsaid, where `spikegs simulate` warns of one), or where both
        losses train with the dense views' settings on fewer than FEW_TIMESTAMPS: the sparse
        views' scored higher there."""
        s, n = self.config.supervision, len(self.dataset.train_timestamps)
        if n == 1:
            warnings.warn(
                f"{self.dataset.root}: one training timestamp (readout "
                f"{self.dataset.train_timestamps[0]:g}): every step trains on one view, which "
                f"cannot place the scene in depth; the test views' scores say little",
                stacklevel=3,
            )
            return
        both = s.instant != "none" and s.instant_weight > 0 and s.exposure_weight > 0
        dense = s.exposure_weight > s.instant_weight or s.instant_until == "densify"
        if both and dense and n < FEW_TIMESTAMPS:
            # (a file of the line alone starts from the dataclass's defaults, L1 norms: base)
            method = self.config.method
            line = f"supervision: {{exposure_weight: {s.instant_weight:g}, instant_until: run}}"
            advice = (
                f"a config file of base: {method} and {line}"
                if method in available_methods()
                else f"{line} added to the method's config file"
            )
            warnings.warn(
                f"{self.dataset.root}: {n} training timestamps, and supervision's exposure_weight "
                f"{s.exposure_weight:g} against instant_weight {s.instant_weight:g}, "
                f"instant_until {s.instant_until}, the settings for many views: with few, "
                f"{advice} scored 0.9-1.4 dB higher at 9 timestamps of each built-in scene "
                f"(docs/datasets.md)",
                stacklevel=3,
            )

    def _warn_of_test_views_elsewhere(self) -> None:
        """A UserWarning naming the off-path test views whose image the scene sphere covers
        under MIN_SPHERE_COVERAGE of and under half of what the least-covered training view
        sampled along the stream has: a test file's poses in another convention, unit or
        direction than the training views' (nothing checked them: a frame sequence's
        transforms_test.json in OpenCV axes unsaid scored its views 4.4 dB low, their renders
        flat grey; such views see 0 %). On-path views are the path's own poses."""
        d = self.dataset
        off = [v for v in d.test_views if v.readout is None]
        if not off:
            return
        viewmats = np.stack([np.asarray(v.viewmat, np.float64) for v in off])
        covered = view_coverage(d.scene_center, self.radius, d, viewmats=viewmats)  # [V]
        least = float(view_coverage(d.scene_center, self.radius, d).min())  # a training view's
        bound = min(MIN_SPHERE_COVERAGE, least / 2)
        away = [(v.name, c) for v, c in zip(off, covered) if c < bound]
        if away:
            named = ", ".join(f"{name} {100 * c:.1f} %" for name, c in away[:5])
            more = f" and {len(away) - 5} more" if len(away) > 5 else ""
            warnings.warn(
                f"{d.root}: the scene sphere covers {len(away)} of the {len(covered)} off-path "
                f"test views' images little or not at all ({named}{more}; every training view "
                f"sampled along the stream {100 * least:.1f} % or more): their poses in another "
                f"convention, unit or direction than the training views' (camera-to-world, in "
                f"the layout's axes)? Their renders would show little or none of the scene",
                stacklevel=3,
            )

    def _sphere_coverage(self) -> float:
        """The share of the median training view that the scene sphere covers."""
        d = self.dataset
        return float(np.median(view_coverage(d.scene_center, self.radius, d)))

    def _sphere_first(self) -> str:
        """What an end-of-run warning adds where the scene sphere is too small (warned of as the
        run started): the Gaussians' sizes and learning rates were off, so densification grew
        none and the renders missed the targets' brightness; a lower threshold or smooth L1,
        their advice, did not help (32², translations 10x: 18.85 and 19.13 dB against 18.87),
        the right sphere did (22.99)."""
        coverage = self._sphere_coverage()
        if coverage >= MIN_SPHERE_COVERAGE:
            return ""
        return (
            f" (first, the scene sphere: it covers {100 * coverage:.1f} % of the median training "
            f"view, warned of as the run started, and this follows from it)"
        )

    def _fresh_state(self) -> None:
        t = self.config.train
        self.environments: list[dict] = []  # what trained the run (`_record_environment`)
        # the run's own generators: torch's global RNG is the caller's (a run that reseeded it
        # made every run of a sweep leave it in the same state, and a callback drawing from it
        # changed the run); the densifier's draws what the global one, seeded so, drew before
        self.split_rng = torch.Generator().manual_seed(t.seed)
        gen = torch.Generator().manual_seed(t.seed)
        # intensities from the data (initial_intensity.py): Gaussians take what the views show
        # where they project (a point cloud gives positions only), the background the views'
        # median intensity
        sample = ViewSample.of(self.dataset, self.scale)
        origin = self.origin
        colors_of = lambda means: projected_intensity(  # noqa: E731
            self.dataset, sample, means.double() + torch.from_numpy(origin)
        )
        # no larger than the size that densification prunes (after the first opacity reset):
        # fewer than ~4200 random Gaussians, or a sparse cloud, started above it and were all
        # deleted there
        cap = self.config.densify.max_world_size * self.radius
        max_scale = 0.99 * cap if cap else math.inf
        self.start_points = None  # random points in the scene bounds
        if self.cloud_points is not None:
            self.model = gaussians_from_points(
                self.cloud_points - origin, t.init_gaussians, t.sh_degree, gen, colors_of, max_scale
            )
            cloud = Path(self.dataset.root, POINTS).resolve()
            count = len(self.cloud_points)
            self.start_points = {"file": str(cloud), "points": count, "sha256": self._cloud_digest}
            # (a cloud whose points lay within 1e-7 started Gaussians that small, unsaid)
            size = math.exp(float(self.model.params["log_scales"][0, 0].detach())) / self.radius
            print(  # (it moves a run's scores by dB, and the dataset's other files look the same)
                f"{cloud}: the {len(self.model)} initial Gaussians start at its points ({count} "
                f"distinct), {size:.2g} of the scene radius wide (their median spacing, at most "
                f"the size densification prunes; delete it to start at random points in the "
                f"scene bounds)",
                file=sys.stderr,
            )
        else:
            self.model = GaussianModel.random(
                t.init_gaussians,
                self.dataset.scene_center - origin,
                self.radius,
                self.dataset.channels,
                t.sh_degree,
                gen,
                colors_of,
                max_scale,
            )
        self.model.origin = origin
        self.model.antialiased, self.model.dilation = t.antialiased, t.dilation
        with torch.no_grad():
            self.model.background.copy_(torch.from_numpy(sample.median))
        self._start_optimisation()
        self._filter_3d()  # (with the pose refiner's corrections, zero at the start)
        self.rng = np.random.default_rng(t.seed)
        self.iteration, self.train_seconds = 0, 0.0

    def _start_optimisation(self) -> None:
        """A fresh pose refiner (None unless configured), optimiser and densifier of the model."""
        self.poses = make_refiner(
            self.config.pose_refine, len(self.dataset.train_timestamps), self.radius
        )
        self.optimizer = _optimizer(self.model, self.config, self.radius, self.poses)
        self.densifier = Densifier(
            self.config.densify, self.radius, self.config.train.iterations, self.split_rng
        )

    def _record_environment(self) -> None:
        """This process's environment (provenance.py) in the run's record, from the iteration it
        trains from, where it differs from the previous process's: a run resumed elsewhere (another
        build, version or thread count) names each; an earlier version's checkpoint kept none."""
        now = environment()
        last = self.environments[-1] if self.environments else {}
        if {k: v for k, v in last.items() if k != "from_iteration"} != now:
            self.environments.append({"from_iteration": self.iteration, **now})

    def save_checkpoint(self) -> None:
        self._check_in_place()
        state = {
            "iteration": self.iteration,
            "train_seconds": self.train_seconds,
            "sim_seconds": self.sim_seconds,
            "sim": self.sim,
            "model": self.model.state_dict(),
            "optimizer": self.optimizer.state_dict(),
            "densifier": self.densifier.state_dict(),
            "poses": None if self.poses is None else self.poses.state_dict(),
            "rng": self.rng.bit_generator.state,
            "torch_rng": self.split_rng.get_state(),  # (a checkpoint before: the global one's)
            "config": self.config.to_dict(),
            "data": self.data,
            START_POINTS: self.start_points,
            "scene_sphere": self._scene_sphere(),
            "dataset": str(Path(self.dataset.root).resolve()),
            "environments": self.environments,
            FOUND: self.found,
        }
        save_atomically(state, self.checkpoint_path)  # a kill mid-save keeps the previous one
        self.saved_iteration = self.iteration

    def _check_in_place(self) -> None:
        """FileNotFoundError where the run's folder, as this training locked it, was moved,
        renamed or deleted since: its checkpoints and scene made a new folder at the old path,
        unlocked, apart from its log (and a second process resumed there beside this one)."""
        if self._watch is None or not self._watch.moved():
            return
        now = self._watch.now()
        went = "" if now is None else f" (to {now}: {resume_command(now, self.dataset.root)})"
        raise FileNotFoundError(
            f"{self.run_dir}: the run's folder was moved or deleted while it trained{went}; "
            f"stopped at iteration {self.iteration}, the steps since its last checkpoint lost, "
            f"writing nothing at the old path"
        )

    def _read_checkpoint(self) -> dict:
        """The last checkpoint's state; ValueError naming every setting that differs from this
        trainer's configuration, or when it was trained on other data (a run resumes only with
        its own settings and data)."""
        unusable = f"{self.checkpoint_path}: cannot be resumed (train afresh into another --out):"
        try:
            state = torch.load(self.checkpoint_path, map_location="cpu", weights_only=True)
        except Exception as err:  # torch, pickle and zip raise their own kinds for a torn file
            raise ValueError(f"{unusable} unreadable ({type(err).__name__}: {err})") from None
        keys = ("config", "iteration", "model", "optimizer")  # (a saved SIM has a config)
        if not (isinstance(state, dict) and all(key in state for key in keys)):
            raise ValueError(f"{unusable} not a checkpoint of spikegs train")
        changed = differences(
            with_defaults(state["config"]), self.config.to_dict(), ("in the run", "now")
        )
        if changed:
            longer = any(c.startswith("train.iterations") for c in changed)
            same = "the same method and settings"
            # what --iterations and --seed changed (the schedule scaled with the length)
            given = tuple(f"{key}:" for key in self.command_line)
            if "train.iterations" in self.command_line:
                given += tuple(f"densify.{key}:" for key in SCHEDULE_KEYS)
            if self.settings_file is not None and any(not c.startswith(given) for c in changed):
                # (it named no settings: the run's own file was edited)
                same = f"the settings it trained with: put them back in {self.settings_file}"
            elif all(c.startswith("method:") for c in changed):  # a copy of the run's file
                same = (  # (named after its stem: staged as $TMPDIR/config.yaml, refused)
                    f"its method's name: a config file is named after its file unless it sets "
                    f"`method: {state['config'].get('method')}`; or leave out --config and "
                    f"--method, to resume with the run's own settings"
                )
            raise ValueError(
                f"{self.checkpoint_path}: the run was trained with other settings; resume with "
                f"{same} (or train into another --out). Differing: "
                + "; ".join(changed)
                + (
                    " (a run's length sets its schedule, densification, learning-rate decay and "
                    "the instant loss's end scaled with it: a run of another length is a new run)"
                    if longer
                    else ""
                )
            )
        saved = state.get("data", self.data)  # checkpoints before fingerprints have none
        if not same_data(saved, self.dataset, self.scale, self.data):
            raise ValueError(
                f"{self.checkpoint_path}: the run was trained on other data than "
                f"{self.dataset.root} (other spikes, training timestamps, poses, intrinsics or "
                f"intensity scale; it was "
                f"{state.get('dataset')}); resume it on its own dataset or train into another --out"
            )
        sphere = state.get("scene_sphere")  # (checkpoints before 2026-12-07 have none)
        now = self._scene_sphere()
        if sphere is not None and not np.allclose(sphere, now, rtol=1e-6, atol=1e-6 * now[3]):
            raise ValueError(
                f"{self.checkpoint_path}: the run was trained about another scene sphere than "
                f"{self.dataset.root}'s (the run's {_sphere_text(sphere)}, now "
                f"{_sphere_text(now)}: the means' learning rate and densification's sizes scale "
                f"with it); resume it with its own, or train into another --out"
            )
        return state

    def _scene_sphere(self) -> list[float]:
        """The dataset's scene centre and radius [4], which training's scales follow."""
        return [*map(float, self.dataset.scene_center), float(self.dataset.scene_radius)]

    def _sim_record(self, state: dict | None) -> dict | None:
        """The record of the targets' SIM (`Targets.sim`), warning where a resumed run's
        checkpoint recorded another SIM, or inference in another precision: its SIM, retrained
        since (the dataset's sim/ deleted, at another thread count) or swapped, was taken in
        silence, the run going on against other instant targets."""
        sim = self.targets.sim
        before = state and state.get("sim")  # (an earlier version's checkpoint: none)
        same = ("digest", "inference")
        if sim and before and any(sim[key] != before.get(key) for key in same):
            warnings.warn(
                f"{self.checkpoint_path}: the run trained against another SIM's instant targets "
                f"than {sim['path']} gives: {_sim_text(before)} then, {_sim_text(sim)} now (SIM "
                f"trained again at another thread count or precision is another, every weight; "
                f"inference in another precision gives other images); it goes on against these, "
                f"no longer as the uninterrupted run would (put the run's SIM file back, or "
                f"train into another --out)",
                stacklevel=3,
            )
        return sim or before  # (none built past the instant loss's end: the run's)

    def _load_checkpoint(self, state: dict) -> None:
        self.split_rng = torch.Generator()
        self.split_rng.set_state(state["torch_rng"])  # an older checkpoint's global state: the same
        self.model = GaussianModel.from_state_dict(state["model"])
        if "origin" not in state["model"]:  # saved before origins: world means, moved about the
            # origin a fresh run takes (Adam's moments do not depend on it)
            self.model = self.model.centred_at(self.origin)
        self._start_optimisation()
        if self.poses is not None:
            self.poses.load_state_dict(state["poses"])  # in place: the optimiser's parameters
        self.optimizer.load_state_dict(state["optimizer"])
        self.densifier.load_state_dict(state["densifier"])
        self.rng = np.random.default_rng()
        self.rng.bit_generator.state = state["rng"]
        self.iteration, self.train_seconds = state["iteration"], state["train_seconds"]
        self.environments = state.get("environments", [])
        self.start_points = state.get(START_POINTS, UNRECORDED)

    # -- one step ------------------------------------------------------------------------------
    def _poses(self, readouts: list[float], view: int) -> list[torch.Tensor]:
        """Viewmats [4, 4] at `readouts` (one trajectory lookup), with training view `view`'s
        correction when refining."""
        viewmats = self.model.view_of(self.dataset.trajectory.pose_at(np.asarray(readouts)))
        return [v if self.poses is None else self.poses(v, view) for v in viewmats]

    def _diverged(self, what: str) -> FloatingPointError:
        """The error that stops a diverged run: `what` happened, where the run can go on from."""
        kept = (
            f"its last checkpoint ({self.checkpoint_path}) is kept"
            if self.checkpoint_path.exists()
            else "no checkpoint was written yet"
        )
        return FloatingPointError(
            f"iteration {self.iteration}: {what}; stopped, {kept}. Lower the learning rates or "
            f"loss weights"
        )

    def _check_parameters(self) -> None:
        """FloatingPointError naming the parameters that an update made non-finite (the
        rasterizer culls such Gaussians, so the loss alone would not show it), or whose Adam
        second moments overflowed (squared gradients past float32's range: those parameters
        would stop moving for good)."""
        named = {**self.model.params, "background": self.model.background}
        # a non-finite entry makes the sum non-finite: one reduction a step (counting the rows
        # took ~0.7 ms); a sum that overflows is counted and found clean
        suspect = {k: p.detach() for k, p in named.items() if not torch.isfinite(p.detach().sum())}
        bad = {  # name: rows (Gaussians; background: channels) with a non-finite entry
            k: (int((~torch.isfinite(p)).reshape(len(p), -1).any(1).sum()), len(p))
            for k, p in suspect.items()
        }
        listed = ", ".join(f"{k} ({n} of {rows})" for k, (n, rows) in bad.items() if n)
        if listed:
            raise self._diverged(f"the update made parameters non-finite: {listed}")
        overflowed = [
            group["name"]
            for group in self.optimizer.param_groups
            for p in group["params"]
            if not _finite_nonnegative(self.optimizer.state.get(p, {}).get("exp_avg_sq"))
        ]
        if overflowed:
            raise self._diverged(
                f"gradients too large for float32 (Adam's squared-gradient averages of "
                f"{', '.join(overflowed)} overflowed)"
            )

    def step(self) -> float:
        """One iteration, as the loop runs it without evaluation: `update`, then `densify`;
        returns the loss."""
        loss = self.update()
        self.densify()
        return loss

    def update(self) -> float:
        """One optimisation step on a random training timestamp; returns the loss."""
        s, targets = self.config.supervision, self.targets
        self.iteration += 1
        for group in self.optimizer.param_groups:
            if group["name"] == "means":
                group["lr"] = _means_lr(self.config, self.iteration, self.radius)
        index = int(self.rng.integers(len(targets.timestamps)))
        t = float(targets.timestamps[index])
        h, w = self.dataset.height, self.dataset.width
        densifying = self.iteration <= self.densifier.stop
        # the instant loss trains every step, or (instant_until: densify) until densification ends
        last_instant = self.config.last_instant_iteration()
        instant_trains = targets.instant is not None and self.iteration <= last_instant
        # this step's densification signal [N, 2], while the model densifies: AbsGS's absolute
        # per-pixel sums, which each render's backward adds to, or the plain gradient of a zero
        # tap on the 2D means
        absgrad = self.config.densify.absgrad
        screen = torch.zeros(len(self.model), 2, dtype=self.model.dtype, requires_grad=not absgrad)
        tap = {"screen_abs" if absgrad else "screen_points": screen} if densifying else {}
        radii = torch.zeros(len(self.model), dtype=torch.int32)
        # densify.instant_only: the exposure's renders (but for one it shares with the instant
        # pose, an odd K's centre, whose loss weight there is `shared`) give the signal nothing
        instant_only = self.config.densify.instant_only and instant_trains
        exposure_tap = {} if instant_only else tap
        loss, instant, shared = torch.zeros((), dtype=self.model.dtype), None, 0.0
        terms = {}  # the step's unweighted loss terms by name
        # the instant pose (at the time its target shows: TFI's is half a readout on), then the
        # exposure's
        offset = targets.instant.time_offset if targets.instant is not None else 0.0
        times = [t + offset]
        if targets.exposure is not None:
            times += [float(tk) for tk in exposure_times(t, s.exposure_window, s.exposure_poses)]
        viewmats = self._poses(times, index)
        if instant_trains:
            instant = self.model.render(viewmats[0], self.K, w, h, self.near, **tap)
            radii = torch.maximum(radii, instant.radii)
            target = targets.instant[index]
            shown = hide(instant.image, target, targets.instant.valid)  # defects: no residual
            terms["instant"] = instant_loss(shown, target, s.instant_norm, targets.instant.quantum)
            loss = loss + s.instant_weight * terms["instant"]
            self.brightness.observe("instant", [shown], target)  # (as the loss sees it)
            if s.dssim_weight:
                terms["dssim"] = dssim(shown, target)
                loss = loss + s.dssim_weight * terms["dssim"]
        if targets.exposure is not None:
            renders = []
            for k, viewmat in enumerate(viewmats[1:]):
                if instant is not None and not offset and 2 * k + 1 == s.exposure_poses:
                    renders.append(instant.image)  # an odd K's centre pose is t: render it once
                    shared = s.exposure_weight / s.exposure_poses  # λ/K
                    continue
                r = self.model.render(viewmat, self.K, w, h, self.near, **exposure_tap)
                radii = torch.maximum(radii, r.radii)
                renders.append(r.image)
            target = targets.exposure[index]
            shown = [hide(r, target, targets.exposure.valid) for r in renders]
            terms["exposure"] = exposure_loss(
                shown, target, s.exposure_norm, targets.exposure.quantum
            )
            self.brightness.observe("exposure", shown, target)
            loss = loss + s.exposure_weight * terms["exposure"]
        if not torch.isfinite(loss):
            raise self._diverged(f"the loss is {loss.item()}, before the update")
        loss.backward()
        self.optimizer.step()
        self.optimizer.zero_grad(set_to_none=True)
        self._check_parameters()
        self.loss_terms = {name: term.item() for name, term in terms.items()}
        if densifying:
            # the screen-space gradient of a unit-weight loss, as in 3DGS, whatever the weights;
            # with instant_only, over the instant losses' weight or a shared centre's λ/K, the
            # larger: at the default λ = 4, K = 5 the instant's, beyond λ/K's, so the signal
            # stops growing with λ (BENCHMARKS.md, "The exposure loss in the densification
            # signal")
            screen_grad = screen if absgrad else screen.grad
            instant_weight = max(s.instant_total_weight(), shared)
            weight = instant_weight if instant_only else s.total_weight()
            self.densifier.observe(radii, screen_grad / weight, w, h)
        return loss.item()

    def densify(self) -> None:
        """The densification, pruning and opacity reset due after this iteration's update, and
        the 3D filter's widths recomputed after it (where the model has the filter) when a round
        touched the Gaussians, or every FILTER_3D_EVERY iterations as they move; not at the
        run's last, whose evaluation is taken before it."""
        means = self.model.params["means"]
        self.densifier.step(self.model, self.optimizer, self.iteration)
        # (a round replaces every parameter, the means too: its clones and prunings may keep
        # the count and move the rows; an opacity reset replaces them too, harmlessly)
        changed = self.model.params["means"] is not means
        due = changed or self.iteration % FILTER_3D_EVERY == 0
        if due and self.iteration < self.config.train.iterations:
            self._filter_3d()
        if len(self.model) == 0:
            d = self.config.densify
            biased = biased_fit(self.brightness, self.config.supervision)
            # the settings that pruned this round, each named (max_screen_size's pruning was
            # reported as min_opacity's or max_world_size's, 0.0 the latter's where it was off)
            why = {
                "min_opacity": f"below densify.min_opacity {d.min_opacity}",
                "max_world_size": f"larger than densify.max_world_size {d.max_world_size} of "
                f"the scene radius, a size Gaussians leave by splitting, which "
                f"densify.max_gaussians {d.max_gaussians} may leave no room for",
                "max_screen_size": f"wider than densify.max_screen_size {d.max_screen_size} "
                f"pixels in a view",
            }
            causes = "; ".join(f"{n:,} {why[name]}" for name, n in self.densifier.pruned.items())
            # a fit gone wrong first (dim data's L1 fit to black): the pruning took what it left,
            # and "prune less" led the message on faint light (the stiff-scenes trial)
            remedy = (
                f"a fit gone wrong first: {biased}"
                if biased
                else "prune less, or give the run more room"
            )
            raise ValueError(
                f"iteration {self.iteration}: pruning removed every Gaussian ({causes}); {remedy}"
            )

    def _filter_3d(self) -> None:
        """The model's 3D smoothing filter (`train.filter_3d`, none where 0) of its Gaussians
        now, in the training views (the poses of FILTER_3D_VIEWS training timestamps at most,
        each with its learnt correction when refining poses)."""
        variance = self.config.train.filter_3d
        if not variance:
            return
        d, count = self.dataset, len(self.dataset.train_timestamps)
        indices = np.linspace(0, count - 1, min(count, FILTER_3D_VIEWS)).round().astype(int)
        times = np.asarray(d.train_timestamps)[indices]
        views = self.model.view_of(d.trajectory.pose_at(times))  # [M, 4, 4]
        if self.poses is not None:
            with torch.no_grad():
                views = torch.stack([self.poses(v, int(i)) for v, i in zip(views, indices)])
        self.model.filter_3d = filter_widths(
            self.model.params["means"], views, self.K, d.width, d.height, self.near, variance
        )

    # -- the loop ------------------------------------------------------------------------------
    def densifies_from(self, iteration: int) -> bool:
        """Whether a densification round is due at `iteration` (after its evaluation) or later
        (`DensifyConfig.last_round`)."""
        last = self.config.densify.last_round(self.config.train.iterations)
        return last > 0 and last >= iteration

    def test_psnrs(self) -> list[float]:
        """Each test view's PSNR, as `spikegs eval` scores it (without its SSIMs)."""
        return [
            score_view(self.model, v, self.dataset, self.scale, ssims=())["psnr"]
            for v in self.dataset.test_views
        ]

    def _after_step(self, loss: float, log, bar, on_eval) -> OSError | None:
        """Evaluation (into `test_psnr` and `first_view_psnr`), log record and progress due
        after a step; the error the progress output raised where it is gone (`progress_lost`)."""
        t, it = self.config.train, self.iteration
        # a run of eval_every iterations or fewer is evaluated after its first step too: at its
        # end alone, its curve.png was one point
        first = it == 1 and t.iterations <= t.eval_every
        evaluate = it % t.eval_every == 0 or it == t.iterations or first
        if evaluate:
            psnrs = self.test_psnrs()
            self.first_view_psnr, self.test_psnr = psnrs[0], float(np.mean(psnrs))
            if self._paced is not None:  # the pace of the steps since the previous evaluation
                paced_from, seconds = self._paced
                pace = (self.train_seconds - seconds) / max(it - paced_from, 1)
                self.seconds_left = (t.iterations - it) * pace
            self._paced = (it, self.train_seconds)
        if it % t.log_every == 0 or evaluate:
            record = {
                "iteration": it,
                "seconds": round(self.train_seconds, 3),
                "loss": loss,
                **{f"loss_{name}": term for name, term in self.loss_terms.items()},
                "gaussians": len(self.model),
            }
            if evaluate:  # the first test view's, and the mean over all (eval.json's psnr)
                name = self.dataset.test_views[0].name
                record.update(psnr=self.first_view_psnr, psnr_view=name, psnr_mean=self.test_psnr)
            log.write(strict_json.dumps(record) + "\n")
            log.flush()

        def show() -> None:
            if evaluate and on_eval is not None:
                on_eval(self)
            if it % t.log_every == 0 or evaluate:
                bar.set_postfix(
                    loss=f"{loss:.4f}",
                    psnr=f"{self.test_psnr:.2f}" if np.isfinite(self.test_psnr) else "-",
                    n=len(self.model),
                    s=f"{self.train_seconds:.0f}",
                )
            if not bar.disable and bar.bar_format and not self.densifies_from(it):
                bar.bar_format = None  # a step's time settles: the plain estimate
            bar.update(1)

        return progress_lost(show, bar)

    def train(self, resume: bool = False, on_eval=None) -> dict:
        """Run (or resume) training to `config.train.iterations`; returns the run summary.

        `on_eval(trainer)`, if given, is called every `eval_every` iterations and at the end
        (and after the first step where the run is no longer than `eval_every`),
        outside the timed steps (its time is not in `train_seconds`), `trainer.first_view_psnr`
        then the first test view's PSNR, `trainer.test_psnr` the mean over every test view and
        `trainer.seconds_left` the training seconds the remaining steps take at the pace of
        those since the previous evaluation (NaN at the first; more while it `densifies_from`
        the iteration).
        Gradients are on for it whatever the caller's mode (a notebook's `torch.no_grad()` left
        around the call failed in torch at the first backward); not under `inference_mode`."""
        # (a callback given first was taken for resume=True, and never called)
        resume = as_flag("Trainer.train: resume", resume)
        if on_eval is not None and not callable(on_eval):
            raise TypeError(f"Trainer.train: on_eval expected a callable, found {on_eval!r:.80}")
        refuse_inference_mode("Trainer.train")  # (an internal argument, screen_abs, was named)
        with torch.enable_grad():
            return self._train(resume, on_eval)

    def _train(self, resume: bool, on_eval) -> dict:
        """`train` with its arguments checked and gradients on."""
        # a config that cannot train on this dataset is refused before the run folder is touched
        check_targets(self.dataset, self.config)
        if not self._from_checkpoint(resume):
            # poses, or a point cloud, that cannot train are refused before any work
            self._check_scene_in_view()
            self.cloud_points  # noqa: B018
            warn_if_nothing_learns(self.config)
            warn_if_schedule_unscaled(self.config)
            self._warn_if_few_timestamps()
            warn_if_blurred(self.dataset, self.config)
        self.run_dir.mkdir(parents=True, exist_ok=True)
        # one process trains in a run directory at a time; the checks again under the lock, so
        # that they see the state that this process will train from (another may have trained
        # here since), before any work
        # the dataset is not rewritten under the training (`spikegs simulate --overwrite`,
        # `spikegs poses`: Busy meanwhile, and the training Busy while one of them writes it)
        with (
            reading_dataset(self.dataset.root),
            run_lock(self.run_dir),
            FolderWatch(self.run_dir) as self._watch,
        ):
            # one process trains here: a temporary file is a killed process's, half-written
            for folder in (self.run_dir, self.checkpoint_path.parent):
                sweep_temporaries(folder)
            from_checkpoint = self._from_checkpoint(resume)
            if resume and not from_checkpoint:  # stderr: stdout is `spikegs train`'s summary
                started = (self.run_dir / CONFIG).exists()  # (a mistyped --out: not)
                what = "no checkpoint yet" if started else "no run to continue, nothing written"
                print(f"{self.run_dir}: {what}; training from the start", file=sys.stderr)
            if not resume and self.checkpoint_path.exists():
                how = (  # --resume said "nothing to train" of a finished run
                    "a finished one (train.json): eval or render it, or train into"
                    if (self.run_dir / SUMMARY).is_file()
                    else "pass --resume to continue it, or"
                )
                raise FileExistsError(f"{self.run_dir} already holds a run; {how} another --out")
            state = self._read_checkpoint() if from_checkpoint else None
            if state is not None:  # said: a resumed run printed nothing before its next line
                it, iterations = state["iteration"], self.config.train.iterations
                print(
                    f"{self.run_dir}: "
                    + (
                        f"finished at iteration {it}; nothing to train"
                        if it >= iterations
                        else f"resuming at iteration {it} of {iterations}"
                    ),
                    file=sys.stderr,
                )
            elif not self.progress:  # a log heard of the run first at its first evaluation
                count = self.config.train.iterations
                print(
                    f"{self.config.method}: training {count} iteration{'s' if count > 1 else ''} "
                    f"into {self.run_dir}",
                    file=sys.stderr,
                    flush=True,
                )
            try:
                return self._run(state, on_eval)
            finally:  # the run's target images go with it (a Trainer kept held them)
                self._watch = None
                if self.targets is not None:
                    self.targets.release()

    def _scene_readable(self) -> bool:
        """Whether a finished run's scene.ply is there and loads (kept as it is then: another
        tool's edit too); one that does not is said, and written again (--resume left a damaged
        one as it was, and eval named it with no way out)."""
        path = self.run_dir / SCENE
        if not path.exists():
            return False
        try:
            with warnings.catch_warnings():  # (what it holds is the user's: eval says it)
                warnings.simplefilter("ignore")
                load_ply(path)
        except ValueError as err:
            print(f"{err}: written again from the checkpoint", file=sys.stderr)
            return False
        return True

    def _from_checkpoint(self, resume: bool) -> bool:
        """Whether training goes on from RUN's checkpoint (else from the start); --resume of a run
        stopped before its first checkpoint (in SIM's training, say: SIM resumes itself), or
        before it wrote anything, starts it again. FileExistsError where a fresh run would mix
        with files in RUN (`check_fresh_run_dir`)."""
        restart = resume and not self.checkpoint_path.exists()
        if not resume or restart:
            check_fresh_run_dir(self.run_dir, self.checkpoint_path)
        return resume and not restart

    def _run(self, state: dict | None, on_eval) -> dict:
        """`train` once its checks have passed: fresh when `state` is None, else resumed."""
        t = self.config.train
        # --resume of a finished run rewrote each of its files as it was: now only what changed
        # (train.json's dataset, moved) or what a kill after the last checkpoint left missing
        finished = state is not None and state["iteration"] >= t.iterations
        config = dump_yaml(self.config.to_dict())  # `--resume` reads it back
        write_text_if_changed(self.run_dir / CONFIG, config)
        # the log is checked (and cut to the checkpoint) before minutes of SIM training
        _cut_log(self.run_dir / LOG, state["iteration"] if state else 0)
        # a finished run needs no targets; SIM's training time for this run: trained now or
        # loaded from the dataset's cache (its recorded time), a resumed run's its checkpoint's
        if not finished:
            left = state is None or state["iteration"] < self.config.last_instant_iteration()
            try:
                self.targets = build_targets(self.dataset, self.config, self.progress, left)
            except KeyboardInterrupt:  # (it said "interrupted" alone)
                if left and self.config.instant_target() == "sim":
                    say(
                        f"\nSIM's training, if it had begun, goes on from its last saved state "
                        f"when this run is trained again ({SAVED_EVERY})"
                    )
                raise
        # (an earlier version's checkpoint of a cached SIM kept 0: the cache's time stands in)
        saved = state.get("sim_seconds", 0.0) if state else 0.0
        self.sim_seconds = saved if finished or saved else self.targets.sim_seconds
        # what the targets leave out (a finished run built none: its checkpoint's, if it has it)
        self.found = state.get(FOUND) if finished else self.targets.found
        self.sim = state.get("sim") if finished else self._sim_record(state)
        if state is not None:
            self._load_checkpoint(state)
        else:
            self._fresh_state()
        if not finished:
            self._record_environment()
        log = (self.run_dir / LOG).open("a")
        saved_at = time.perf_counter()
        bar = tqdm(
            total=t.iterations,
            initial=self.iteration,
            disable=not self.progress,
            desc=self.config.method,
            dynamic_ncols=True,
            bar_format=GROWING_BAR if self.densifies_from(self.iteration + 1) else None,
        )
        self.first_view_psnr = self.test_psnr = float("nan")  # none before the first evaluation
        # none before a second evaluation: the steps up to the first compute most timestamps'
        # targets, which later ones find kept (on solids, 10000 iterations: 4x the time left)
        self.seconds_left = float("nan")
        self._paced = None  # (iteration, train_seconds) at the previous evaluation
        self.loss_terms: dict[str, float] = {}  # the last step's unweighted terms, for the log
        stop_message = "\n{signal}: stopping after this step" + (
            ", with a checkpoint to --resume from" if self.resumable else ""
        )
        again = " ({signal} again stops at once" + (
            ", keeping the last checkpoint)" if self.resumable else ")"
        )
        gone = None  # the progress output's loss (its reader left, its terminal closed)
        with deferred_interrupt(stop_message, again) as interrupted:
            try:
                while self.iteration < t.iterations and gone is None:
                    start = time.perf_counter()
                    loss = self.update()
                    self.train_seconds += time.perf_counter() - start
                    # the model the step trained, as 3DGS evaluates it: an opacity reset due now
                    # (at 1000 of the default 3000 iterations) logged a held-out PSNR ~10 dB low,
                    # a dip a user could read as divergence
                    gone = self._after_step(loss, log, bar, on_eval)
                    start = time.perf_counter()
                    self.densify()
                    self.train_seconds += time.perf_counter() - start
                    if interrupted() and self.iteration < t.iterations:
                        self.save_checkpoint()  # between steps: a consistent state
                        raise interruption(interrupted())  # (the last step: finished first)
                    if (
                        self.iteration % t.checkpoint_every == 0
                        or time.perf_counter() - saved_at > CHECKPOINT_S
                    ):
                        self.save_checkpoint()
                        saved_at = time.perf_counter()
            finally:
                closed = progress_lost(bar.close, bar)  # the run done: it finishes, then stops
                log.close()
            gone = gone or closed
            if gone is not None and self.iteration < t.iterations:
                self.save_checkpoint()  # nothing to show the rest to: stopped, as `| head` stops it
                raise gone
            # the run's last files written with a stop deferred too: one there left no scene.ply,
            # no train.json and the checkpoint before, and said no --resume (the kill trial)
            summary = self._finish(finished)
            stopped = interrupted()  # in the last step: the run finishes, then stops (a demo
            # went on to its next method, which the scheduler's SIGKILL then cut)
        if stopped:
            raise interruption(stopped)
        if gone is not None:
            raise gone
        return summary

    def _finish(self, finished: bool) -> dict:
        """The run's last checkpoint (unless `finished` before), scene.ply and train.json, and
        what the run leaves to say; returns the summary."""
        if not finished:
            self.save_checkpoint()
        if not (finished and self._scene_readable()):
            save_ply(self.model, self.run_dir / SCENE)
        # densification that grew nothing and renders off the targets' brightness follow from a
        # scene sphere too small, where there is one: said with it
        followers = [
            self.densifier.unreached(self.iteration),
            biased_fit(self.brightness, self.config.supervision),
        ]
        sphere = self._sphere_first() if any(followers) else ""
        others = [psnr_fall(logged_curve(self.run_dir)), self.densifier.capped_note()]
        summary = {
            "method": self.config.method,
            "dataset": str(Path(self.dataset.root).resolve()),
            "scene": self.dataset.meta.get("scene"),
            "camera": camera_keys(self.dataset.meta),  # eval tells coarser test pixels by it
            "iterations": self.iteration,
            "seed": self.config.train.seed,
            "train_seconds": self.train_seconds,
            "sim_seconds": self.sim_seconds,
            "gaussians": len(self.model),
            "intensity_scale": self.scale,
            "intensity_scale_guessed": scale_guessed(self.dataset.meta),  # eval on other data
            "data": self.data,  # `spikegs eval` knows the run's own data, moved, by it
            START_POINTS: self.start_points,  # (the cloud is no part of `data`: nor of a SIM's)
            "environment": self.environments,  # what trained it, from which iteration
        }
        if self.found is not None:  # (none in a checkpoint from before the key)
            summary[FOUND] = self.found
        write_text_if_changed(self.run_dir / SUMMARY, strict_json.dumps(summary, indent=2))
        self.summary = summary
        # said once the run is whole: warnings made errors (-W error, a test's filter) left it
        # without train.json, and its resume raised them again before writing it
        for said in others + [f and f + sphere for f in followers]:
            if said:
                warnings.warn(f"{self.run_dir}: {said}", stacklevel=3)
        return summary
