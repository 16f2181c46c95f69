"""The dataset layout on disk (docs/datasets.md): writing its parts and loading it, checked.

DIR/meta.json              sizes, readout period, flip, simulator parameters + seed, K, scene
DIR/spikes.dat             mono; a colour dataset has spikes_r.dat, spikes_g.dat, spikes_b.dat
DIR/trajectory.json        camera-to-world poses (OpenCV) at recorded readouts
DIR/train_timestamps.txt   readouts at which training samples are taken, one per line
DIR/test_views.json        held-out views: name, readout (null off the path), pose, image file
DIR/test/NAME.exr          their clean instantaneous images, float, firing-rate units

`load_dataset` also opens the real-data layouts (llff.py, nerf_layout.py) by what DIR holds.
"""

from __future__ import annotations

import collections
import contextlib
import copy
import dataclasses
import functools
import json
import math
import os
import shutil
import threading
import warnings
from pathlib import Path

import numpy as np

from .. import _C
from ..atomic_save import NAME_MAX, is_temporary, target_name, write_text_atomically
from ..file_lock import exclusive_lock, refuse_if_held, shared_lock
from ..image_io import read_stored_image, srgb_to_linear, write_image
from ..number_checks import is_int, is_number, shown_past
from ..rasterize import MAX_SIZE
from ..regular_file import is_given, read_text
from ..run_summary import CONFIG, SUMMARY, read_summary
from ..shell_words import shell_path
from ..spikes import SpikeStream
from ..strict_json import json_text, read_json
from .channel_order import check_channels
from .correlation import correlation
from .orientation import check_orientation
from .trajectory import (
    PathLike,
    Trajectory,
    four_by_four,
    read_camera_doc,
    rigid_c2w,
    write_camera_doc,
)

META, TRAJECTORY, TIMESTAMPS, TEST_VIEWS = (
    "meta.json",
    "trajectory.json",
    "train_timestamps.txt",
    "test_views.json",
)
TEST_DIR = "test"
READOUT_PERIOD_S = 25e-6
WINDOW_MARGIN = 32  # a 65-readout window centred on a training timestamp fits in the stream
# fewer training timestamps than this: a simulation that keeps fewer than half its stride's
# says why, and both losses with the dense views' settings (λ over the instant weight, or the
# instant loss ending with densification) are warned of: at 9 (128²,
# 3 seeds) equal weights and the instant loss to the end scored higher on every built-in scene
# (solids +1.35 ± 0.39, wires +0.95 ± 0.12, fine-texture +1.14 ± 0.12 dB); at 15 the defaults
# led on wires (+0.80 ± 0.28), the two were level on solids (+0.04 ± 0.06) and the sparse ones
# still led on fine-texture (+0.80 ± 0.03), the defaults again at 29 (+0.24 ± 0.25): each scene
# turns at its own count, and below 12 the advice held on all (BENCHMARKS.md, "Few training
# timestamps at the seventy-fifth session's code", "... on wires and fine-texture" and "Where
# the sparse-view settings stop leading")
FEW_TIMESTAMPS = 12
FORMAT_VERSION = 1
MAX_OFF_AXIS_DEG = 60  # the image centre's angle off the optical axis: a crop's, not a typo's
MAX_FIELD_DEG = 170  # a pinhole's field of view across the image (fx 1e-9: 180°, trained unsaid)
# and the least (fx 1e300 was inf in float32, and training blamed the poses): a 1200 mm lens on a
# full frame sees 2°
MIN_FIELD_DEG = 1e-3
# camera centres and the scene centre farther from the origin (in any unit) are refused: float64
# keeps a pose there to ~1e-4 units (the Earth's centred coordinates in mm: 6e9), and translations
# of 1e300 loaded, then training stopped on an infinite view matrix naming no file
MAX_COORDINATE = 1e12
PSEUDO_PREFIX = "pseudo_"  # a test view scored against TFP of its own spikes, no sharp image
INTRINSICS_FROM_SFM = "sfm"  # meta.json's intrinsics_from where `spikegs poses` estimated them
POSES_FROM_SFM = "sfm"  # meta.json's poses_from where `spikegs poses` wrote trajectory.json


def stated_scales(meta: dict) -> dict:
    """The firing rate of intensity 1 (the test images' units) as `meta` states it: {key: value}
    of rate_at_one (top level, as the real layouts' options put it, or under sim, as the
    simulator does) and image_scale, those present."""
    sim = meta.get("sim")
    rate = meta.get("rate_at_one", sim.get("rate_at_one") if isinstance(sim, dict) else None)
    stated = {"rate_at_one": rate, "image_scale": meta.get("image_scale")}
    return {k: v for k, v in stated.items() if v is not None}


# a real layout's meta key: whether its image_scale is the trainer's guess
GUESSED_SCALE = "image_scale_guessed"


def scale_guessed(meta: dict) -> bool:
    """Whether the firing rate of intensity 1 of a dataset of `meta` is guessed (TFP(33)'s 99.5th
    percentile: `targets.intensity_scale`), not stated or calibrated."""
    return not stated_scales(meta) or meta.get(GUESSED_SCALE) is True


class GuessedUnitsWarning(UserWarning):
    """The test images' units (firing rate of intensity 1) are guessed: their PSNR depends on it."""


class DarkSpikesWarning(UserWarning):
    """A simulated stream's light adds no more spikes than its dark current (simulate says so
    as it makes one)."""


class FaintLightWarning(UserWarning):
    """A stream's lit pixels fire under FAINTEST_MEASURED (simulate says so as it makes one)."""


# the faintest light measured (lit pixels' spikes a readout): SpikeGS saw solids at rate_at_one
# 0.08, 32.3 dB (BENCHMARKS.md, "Scenes not tuned on"); fainter is unmeasured: at rate_at_one
# 0.01 (lit pixels 0.0017) a 64² solids rendered its learnt background alone, at 0.05 (0.009) a
# 32² one's held-out PSNR fell 3 dB as training fitted shot noise, warned of as learning rates
# too high (the stiff-scenes trial)
FAINTEST_MEASURED = 0.012
LIT_SHARE = 0.01  # pixels firing over this share of the 99.9th percentile's rate are lit,
LIT_SPIKES = 3  # with this many spikes or more (a dark pixel's spike is no light),
HOT_RATE = 0.9  # and under this rate (a hot pixel's is no scene's light)


def intrinsics_matrix(meta: dict) -> np.ndarray:
    """K [3, 3] float64 of meta.json's fx, fy, cx, cy."""
    return np.array([[meta["fx"], 0, meta["cx"]], [0, meta["fy"], meta["cy"]], [0, 0, 1]], float)


def field_of_view_deg(pixels: float, focal: float) -> float:
    """The angle in degrees that `pixels` centred on a pinhole's axis span at focal length
    `focal` (pixels)."""
    return float(2 * np.degrees(np.arctan(pixels / 2 / focal)))


def intrinsics_keys(K: np.ndarray) -> dict:
    """meta.json's fx, fy, cx, cy (floats) of K [3, 3]."""
    return {"fx": float(K[0, 0]), "fy": float(K[1, 1]), "cx": float(K[0, 2]), "cy": float(K[1, 2])}


def check_intrinsics(K: np.ndarray, height: int, width: int, source) -> None:
    """ValueError naming `source` where K [3, 3] of a height x width frame gives a field of view
    or an image centre off the optical axis that meta.json's fx, fy, cx, cy are refused for."""
    keys = {**intrinsics_keys(K), "height": height, "width": width}
    check_meta_values(keys, source, ("fx", "fy", "cx", "cy"))


def spike_files(channels: int) -> list[str]:
    """The .dat file of each channel: spikes.dat (mono) or spikes_r/g/b.dat (colour)."""
    return ["spikes.dat"] if channels == 1 else [f"spikes_{c}.dat" for c in "rgb"]


@dataclasses.dataclass
class TestView:
    """A held-out view; `image` [H, W, C] float32 in firing-rate units (intensity × rate_at_one)."""

    name: str
    viewmat: np.ndarray  # [4, 4] world-to-camera, OpenCV
    image: np.ndarray  # [H, W, C]
    readout: float | None  # on-path readout time, None off the path
    window: int | None = None  # a pseudo ground truth's: TFP of this many of the view's readouts


FLOAT32_ROUNDING_PX = 0.1  # Dataset: a scene far from the origin rounds by more: warned
# Dataset: a scene radius over this many times the cameras' median distance from the scene
# centre, or under its inverse, is warned of (Gaussians start in that ball, the near plane and
# the means' learning rate follow it; 1e4 against cameras 3 units away trained unsaid)
SCENE_SIZE_RATIO = 100.0
# Dataset: camera centres all within this share of their distance from the scene centre of one
# point while the views turn by TURN_DEG or more are warned of (world-to-camera matrices read as
# camera-to-world put an orbit's cameras within 2 % of one point; a turn on the spot has no
# parallax either)
ONE_POINT_SHARE, TURN_DEG = 0.05, 10.0


class Dataset:
    """A loaded dataset. `stream` is the SpikeStream of a mono dataset and the list [r, g, b] of a
    colour one; `streams` is always the list, one SpikeStream per channel. `root` is kept
    absolute: a relative one, after a chdir, lost its points3d.ply and SIM cache unsaid."""

    def __init__(self, root: Path, meta: dict, streams, trajectory, train_timestamps, test_views):
        self.root = Path(root).absolute()  # (a later chdir does not move it, as for streams)
        self.meta = meta
        self.height, self.width = int(meta["height"]), int(meta["width"])
        self.channels = int(meta["channels"])
        self.K = intrinsics_matrix(meta).astype(np.float32)
        self.streams: list[SpikeStream] = streams
        self.stream = streams[0] if self.channels == 1 else streams
        self.trajectory: Trajectory = trajectory
        self.train_timestamps: np.ndarray = train_timestamps  # [M] int64
        self.test_views: list[TestView] = test_views
        self.scene_center = np.asarray(meta["scene_center"], np.float64)  # [3]
        self.scene_radius = float(meta["scene_radius"])
        self._check_coordinates()
        self._warn_about_float32_rounding()
        self._warn_about_scene_size()
        self._warn_about_one_viewpoint()

    def copy(self) -> Dataset:
        """A copy whose training timestamps, test view list, meta, intrinsics and scene centre are
        its own (its streams and trajectory shared): what a Trainer keeps."""
        twin = copy.copy(self)
        twin.train_timestamps = np.array(self.train_timestamps)
        twin.test_views, twin.meta = list(self.test_views), copy.deepcopy(self.meta)
        twin.K, twin.scene_center = self.K.copy(), self.scene_center.copy()
        return twin

    def _check_coordinates(self) -> None:
        """ValueError where a camera centre or the scene centre lies MAX_COORDINATE or farther
        from the origin: poses in other units, or corrupt."""
        far = max(float(np.abs(self.trajectory.centers).max()), *np.abs(self.scene_center))
        if not far < MAX_COORDINATE:
            raise ValueError(
                f"{self.root}: camera centres or the scene centre lie {far:.3g} units from the "
                f"origin: expected under {MAX_COORDINATE:.0e} (float64 poses keep no detail "
                f"there): check the poses and their units"
            )

    def _camera_distance(self) -> float:
        """The cameras' median distance from the scene centre; 0 where it is rounding alone
        (cameras on the centre: ~1e-17, which the scale checks divided by)."""
        centers = self.trajectory.centers  # [P, 3]
        distance = float(np.median(np.linalg.norm(centers - self.scene_center, axis=1)))
        size = max(1.0, float(np.abs(centers).max()), float(np.abs(self.scene_center).max()))
        return distance if distance > 1e-12 * size else 0.0

    def _warn_about_scene_size(self) -> None:
        """A UserWarning where scene_radius is over SCENE_SIZE_RATIO times the cameras' median
        distance from scene_center, or under its inverse: a radius in other units or a typo."""
        distance = self._camera_distance()
        if not distance > 0:  # cameras at the centre (a turn on the spot): no scale to judge by
            return
        ratio = self.scene_radius / distance
        if not 1 / SCENE_SIZE_RATIO <= ratio <= SCENE_SIZE_RATIO:
            where = (  # a real layout's sphere: computed from its views, or set in spikegs.json
                "meta.json's scene_radius"
                if "layout" not in self.meta
                else "the scene sphere: set scene_center and scene_radius in spikegs.json"
            )
            warnings.warn(
                f"{self.root}: scene_radius {self.scene_radius:.3g} is {ratio:.3g} times the "
                f"cameras' median distance from scene_center ({distance:.3g}): Gaussians start "
                f"in that ball and the near plane and the means' learning rate follow it; "
                f"check {where} (expected within {SCENE_SIZE_RATIO:g}x either way of that "
                f"distance)",
                stacklevel=3,
            )

    def _warn_about_one_viewpoint(self) -> None:
        """A UserWarning where every camera centre lies within ONE_POINT_SHARE of their median
        distance from the scene centre (of the scene radius where they sit on the centre) of
        their mean while the cameras turn TURN_DEG or more (their rotations; an orbit's
        matrices inverted keep one optical axis)."""
        distance = self._camera_distance()
        scale = distance if distance > 0 else self.scene_radius  # 0: cameras on the centre
        centers = self.trajectory.centers  # [P, 3]
        spread = float(np.linalg.norm(centers - centers.mean(0), axis=1).max())
        turn = float(np.degrees(self.trajectory.turns().max()))
        if spread <= ONE_POINT_SHARE * scale and turn >= TURN_DEG:
            warnings.warn(
                f"{self.root}: every camera centre lies within {spread:.3g} of one point "
                f"({distance:.3g} from the scene centre) while the cameras turn {turn:.0f}°: "
                f"world-to-camera matrices given where camera-to-world ones belong put an "
                f"orbit's cameras at one point (and a camera turning on the spot shows no "
                f"parallax to place Gaussians in depth)",
                stacklevel=3,
            )

    def _warn_about_float32_rounding(self) -> None:
        """A UserWarning where the scene lies so far from the origin (UTM or GPS coordinates)
        that float32 world positions round by more than FLOAT32_ROUNDING_PX pixels there: runs
        work about the scene's centre (gaussians.frame_origin) and their scene.ply holds
        positions about it, which another tool must offset to place the scene in the world."""
        offset = float(np.linalg.norm(self.scene_center))
        distance = self._camera_distance()
        if not distance > 0:  # cameras at the centre (a turn on the spot): no scale to judge by
            return
        pixels = float(self.K[:2, :2].max()) * offset * 2.0**-24 / float(distance)  # fx or fy
        if pixels > FLOAT32_ROUNDING_PX:
            warnings.warn(
                f"{self.root}: the scene's centre lies {offset:.3g} units from the origin, where "
                f"float32 positions round by ~{pixels:.2g} pixels in these views: a run trains "
                f"about the centre, and its scene.ply holds positions about it (its comment "
                f"'spikegs origin X Y Z' is the offset to add for another tool)",
                stacklevel=3,
            )

    @property
    def num_readouts(self) -> int:
        return int(self.meta["num_readouts"])

    def __repr__(self) -> str:
        return (
            f"Dataset('{self.root}', scene={self.meta.get('scene')!r}, {self.height}x{self.width}"
            f"x{self.channels}, readouts={self.num_readouts}, train={len(self.train_timestamps)}, "
            f"test={len(self.test_views)})"
        )


OLD_LIGHT = ".light.npy"  # a simulation before 2026-11-29 rendered its light here (GBs)
# the folder inside --out that a simulation writes its dataset into, moved into --out once it loads
STAGING = ".simulating"
# any of these (or its temporary file) marks a dataset, or what an interrupted simulation left
PARTS = (META, TRAJECTORY, TEST_VIEWS, *spike_files(1), *spike_files(3), OLD_LIGHT, STAGING)
TRAJECTORY_BACKUP = f"{TRAJECTORY}.bak"  # the pose log that `spikegs poses` replaced
TIMESTAMPS_BACKUP = f"{TIMESTAMPS}.bak"  # the training timestamps before poses dropped any
# held by a process writing the dataset (simulate, poses), shared by those reading it (train,
# sim-train, eval, render); it stays behind, empty
LOCK = ".lock"
POINTS = "points3d.ply"  # a sparse point cloud the Gaussians start at (spikegs poses writes one)
POINTS_BACKUP = f"{POINTS}.bak"  # another tool's point cloud that `spikegs poses` replaced
# what a dataset directory holds besides its parts: test images, cached SIMs, `spikegs poses`
DERIVED = (
    TEST_DIR,
    "sim",
    "sfm",
    POINTS,
    POINTS_BACKUP,
    TRAJECTORY_BACKUP,
    TIMESTAMPS,
    TIMESTAMPS_BACKUP,
    LOCK,
)
SIM_SUFFIXES = (".pt", ".pt.json", ".pt.lock", ".pt.partial")  # what DATASET/sim holds: SIMs,
# their scores, locks and interrupted trainings' states
WRITERS = "spikegs simulate or poses"
READERS = "train, sim-train, eval or render"


def check_dataset(dataset, where: str) -> None:
    """TypeError unless `dataset` is a loaded Dataset (a path given to the Trainer or
    evaluate_run failed on "'str' object has no attribute 'meta'")."""
    if not isinstance(dataset, Dataset):
        raise TypeError(
            f"{where}: dataset expected a Dataset (spikegs.data.load_dataset(PATH) opens one), "
            f"found {type(dataset).__name__} {dataset!r:.80}"
        )


def check_edited_dataset(dataset, where: str) -> None:
    """ValueError, for `where` (the Trainer, evaluate_run), where a Dataset edited in memory
    holds no test view, or one whose name is no file name, (`check_test_views`: with none,
    evaluate_run replaced a run's scores with none and a run trained until its first evaluation
    failed), or training timestamps that are not one or more finite whole readout numbers (floats
    were cast to int unsaid; none, or a guessed scale's TFP, failed in numpy)."""
    views = dataset.test_views
    check_test_views(
        list(views) if isinstance(views, (list, tuple)) else [], f"{where}: {dataset.root}"
    )
    given = np.asarray(dataset.train_timestamps)
    real = np.issubdtype(given.dtype, np.integer) or np.issubdtype(given.dtype, np.floating)
    listed = given.ndim == 1 and len(given) > 0 and real
    if not (listed and np.isfinite(given).all() and np.array_equal(given, np.round(given))):
        odd = given[~np.isfinite(given) | (given != np.round(given))] if listed else []
        raise ValueError(
            f"{where}: {dataset.root}: train_timestamps expected a 1-D array of one or more "
            f"finite whole readout numbers, found {given.dtype} of shape {list(given.shape)}"
            + (f" ({float(odd[0]):g} first)" if len(odd) else "")
        )
    count = len(dataset.streams[0])  # (one past the stream was said as "at most -201" readouts)
    if given.min() < 0 or given.max() >= count:
        raise ValueError(
            f"{where}: {dataset.root}: train_timestamps {given.min():g}..{given.max():g} reach "
            f"past the stream's readouts 0..{count - 1}"
        )


def _in_use(root: Path, remedy: str) -> str:
    return (
        f"{root} is in use by another process ({WRITERS} writing it, or {READERS} reading it); "
        f"wait for it to end{remedy}"
    )


def writing_dataset(root: PathLike, remedy: str = ""):
    """An exclusive lock on ROOT/.lock (ROOT made where missing) for a `with` block that writes
    the dataset at `root`: Busy while another process writes it or reads it (`reading_dataset`);
    `remedy` follows "wait for it to end" in the message."""
    root = Path(root)
    root.mkdir(parents=True, exist_ok=True)
    return exclusive_lock(root / LOCK, busy=_in_use(root, remedy))


def refuse_if_in_use(root: PathLike, remedy: str = "") -> None:
    """Busy, before any work, where another process holds the dataset at `root`'s lock (writing
    or reading it); `writing_dataset` makes sure of it later."""
    refuse_if_held(Path(root) / LOCK, _in_use(Path(root), remedy))


# the dataset locks this process holds shared (`reading_dataset`), by the lock file's real path:
# [the open lock, the blocks holding it], changed under _READING_GUARD (a block per thread)
_READING: dict[str, list] = {}
_READING_GUARD = threading.Lock()


def reading_dataset(root: PathLike):
    """A shared lock on ROOT/.lock for a `with` block that reads the dataset at `root` (loads it,
    trains from it): processes reading it run together; Busy while one writes it
    (`writing_dataset`), and a process that would write it is refused meanwhile. No lock where
    `root` takes none (`takes_lock`), or is a folder without the lock that this process cannot
    write. A process takes it once (`spikegs train`'s, then its Trainer's; trainings in threads),
    held until its last block ends: where flock is emulated by POSIX locks (NFS) the close of any
    descriptor of the file releases the process's lock, and a filesystem without locks is said
    once."""
    root = Path(root)
    if not takes_lock(root):
        return contextlib.nullcontext()
    return _held_shared(root)


@contextlib.contextmanager
def _held_shared(root: Path):
    """`reading_dataset`'s lock, shared by this process's blocks in _READING."""
    path = os.path.realpath(root / LOCK)
    with _READING_GUARD:
        held = _READING.get(path)
        if held is None:
            busy = f"{root} is being written by another process ({WRITERS}); wait for it to end"
            lock = contextlib.ExitStack()
            lock.enter_context(shared_lock(root / LOCK, busy))
            held = _READING[path] = [lock, 0]
        held[1] += 1
    try:
        yield
    finally:
        with _READING_GUARD:
            held[1] -= 1
            if not held[1]:
                del _READING[path]
                held[0].close()


def takes_lock(root: Path) -> bool:
    """Whether a command using the folder `root` as a dataset locks it: where it holds a lock or
    (a part of) a dataset. A folder holding neither is left without a lock file: it has nothing
    to read (an empty or mistyped one; a simulation starting there makes the lock before any
    part), or no spikegs process writes it (an LLFF or NeRF layout). A run folder given for a
    dataset takes none: its lock is its training's, which made it "being written by spikegs
    simulate or poses; wait", and load_dataset names it as a run folder."""
    if run_folder_note(root) is not None and not holds_dataset(root):
        return False
    return (root / LOCK).exists() or holds_dataset(root)


def holds_dataset(out: Path) -> bool:
    """Whether the directory `out` holds (a part of) a dataset, or a part's temporary file
    (`.spikes.dat.W.tmp`, which a simulation killed while writing it leaves)."""
    return out.is_dir() and any(target_name(p.name) in PARTS for p in out.iterdir())


def near_held_out(timestamps: np.ndarray, held_out: np.ndarray) -> np.ndarray:
    """[M] whether each training timestamp's 65-readout window reaches an on-path held-out
    view's (readouts `held_out` [V]): its spikes would be trained on."""
    gaps = np.abs(np.asarray(timestamps)[:, None] - np.asarray(held_out)[None, :])  # [M, V]
    return (gaps <= 2 * WINDOW_MARGIN).any(axis=1)


def check_output(
    out: PathLike, overwrite: bool, remedy: str = "give an empty or new folder"
) -> Path:
    """FileExistsError if `out` is a file, holds a dataset and not `overwrite`, or holds anything
    that is not a dataset's (a replaced dataset's directory is deleted whole), saying `remedy`
    for those."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise FileExistsError(f"{out} is a file, not a dataset folder")
    if out.is_dir() and holds_dataset(out) and not overwrite:
        raise FileExistsError(
            f"{out} already holds a dataset (or what an interrupted simulation left); pass "
            f"--overwrite to replace it"
        )
    names = [p.name for p in out.iterdir()] if out.is_dir() else []
    others = sorted(n for n in names if target_name(n) not in PARTS and n not in DERIVED)
    # SIMs of the old spikes, and its held-out views' images (VIEW.exr), deleted with them:
    # nothing else (a user's notes in test/ were deleted by `spikegs demo --overwrite`)
    for folder, written in (("sim", SIM_SUFFIXES), (TEST_DIR, (".exr",))):
        if (out / folder).is_dir():
            others += sorted(
                f"{folder}/{p.name}"
                for p in (out / folder).iterdir()
                if not (is_temporary(p.name) or p.name.endswith(written))
            )
    if others:
        raise FileExistsError(
            f"{out} holds files that are not a dataset's ({', '.join(others[:5])}"
            f"{', ...' if len(others) > 5 else ''}); {remedy}"
        )
    return out


def move_in(out: Path) -> None:
    """Replace the dataset at `out` (checked by `check_output`) by the one written into
    OUT/STAGING: what `out` held is deleted (caches derived from the old spikes included) but its
    lock (`writing_dataset`'s, held by the caller: a new file would be another lock, which a
    second process could take), then the new one's entries moved in, within the folder."""
    staging = out / STAGING
    # entry by entry: the lock stays, and a link (a dataset on another disk) keeps its target;
    # meta.json goes first and comes in last, as it is written last (a kill between, in the
    # directory's order, left a meta.json beside a part of the files: a dataset missing one)
    for entry in reversed(_meta_last(out)):  # (rmtree refuses a link)
        if entry.name in (LOCK, STAGING):
            continue
        if entry.is_dir() and not entry.is_symlink():
            shutil.rmtree(entry)
        else:
            entry.unlink()
    for entry in _meta_last(staging):
        entry.rename(out / entry.name)
    staging.rmdir()


def _meta_last(folder: Path) -> list[Path]:
    """The entries of `folder`, meta.json last."""
    return sorted(folder.iterdir(), key=lambda entry: entry.name == META)


def camera_keys(meta: dict) -> dict:
    """The camera of meta.json as trajectory.json and test_views.json state it (nerfstudio keys)."""
    camera = {"fl_x": meta["fx"], "fl_y": meta["fy"], "cx": meta["cx"], "cy": meta["cy"]}
    return {**camera, "w": meta["width"], "h": meta["height"]}


def write_parts(
    out: Path,
    meta: dict,
    trajectory: Trajectory,
    train_timestamps: np.ndarray,
    test_views: list[TestView],
) -> None:
    """Write everything but the spikes; meta.json last, so a dataset without it is incomplete."""
    camera = camera_keys(meta)
    trajectory.save_json(out / TRAJECTORY, **camera)
    write_text_atomically(out / TIMESTAMPS, "".join(f"{int(k)}\n" for k in train_timestamps))
    frames = []
    for view in test_views:
        file_path = f"{TEST_DIR}/{view.name}.exr"
        write_image(out / file_path, view.image)
        frames.append(
            {
                "name": view.name,
                "readout": view.readout,
                "file_path": file_path,
                "transform_matrix": np.linalg.inv(view.viewmat).tolist(),
                **({} if view.window is None else {"pseudo_window": view.window}),
            }
        )
    # whole files only (`spikegs poses` rewrites a dataset's: a kill there left it unloadable)
    write_camera_doc(out / TEST_VIEWS, frames, **camera)
    write_text_atomically(out / META, json.dumps(meta, indent=1))


def existing_file(root: Path, name: str, what: str = "") -> Path:
    """ROOT/name; FileNotFoundError naming it (and `what` it is, where given) when it is missing,
    ValueError when its name holds something else than a file (`is_given`: a folder was said to
    be missing)."""
    path = root / name
    if not is_given(path):
        raise FileNotFoundError(f"dataset file not found: {path}{f' ({what})' if what else ''}")
    return path


# what a missing split file is, and the ways to one (a pose log of one's own, in this layout,
# was told the file missing alone)
SPLIT = (
    f"{TIMESTAMPS} and {TEST_VIEWS}, the readouts training samples and the held-out views, are "
    f"the dataset's split: write them (docs/datasets.md), or keep a pose log of your own, with "
    f"near and far depth bounds, in the LLFF layout (spikes.dat, poses_bounds.npy, readouts.txt "
    f"in a folder without {META}), which makes its own split; `spikegs poses` makes them too, "
    f"replacing the poses with SfM's aligned to them"
)


def open_streams(root: Path, names: list[str], meta: dict) -> list[SpikeStream]:
    """The spike files ROOT/names, memory-mapped as `meta` (meta.json) describes them (height,
    width, flip, num_readouts; raw_width and col_offset for a camera's wider rows);
    FileNotFoundError naming a missing one, ValueError naming one that does not hold the
    readouts meta.json says; a UserWarning names the other kind of camera's files beside them,
    which are not read."""
    num = int(meta["num_readouts"])
    other = spike_files(1 if len(names) == 3 else 3)  # the other kind of camera's files
    kind = "colour" if len(other) == 3 else "mono"
    missing = [n for n in names if not (root / n).is_file()]
    unread = [n for n in other if (root / n).is_file()]
    if missing and unread == other:
        raise FileNotFoundError(
            f"dataset file not found: {root / missing[0]}; {root} holds {', '.join(other)}, a "
            f"{kind} camera's: {META}'s channels {meta['channels']} should be {len(other)}"
        )
    if unread and not missing:
        warnings.warn(
            f"{root}: {', '.join(unread)} not read: {META}'s channels {meta['channels']} reads "
            f"{', '.join(names)} (a {kind} camera's files beside them: another recording's?)",
            stacklevel=3,
        )
    streams = [
        SpikeStream.open(
            existing_file(root, n),
            int(meta["height"]),
            int(meta["width"]),
            meta["flip"],
            meta.get("raw_width"),
            meta.get("col_offset", 0),
        )
        for n in names
    ]
    for name, stream in zip(names, streams):
        if len(stream) != num:
            wider = None if meta.get("raw_width") else _wider_rows(stream, num)
            hint = (  # (a camera's 72-pixel rows of a 64-pixel image named no raw_width)
                f"; it holds {num} readouts of {stream.height}x{wider}: rows wider than the "
                f"image? raw_width {wider} and col_offset in {META}"
                if wider
                else ""
            )
            raise ValueError(
                f"{root / name}: {len(stream)} readouts of {meta['height']}x{meta['width']}, "
                f"{META} says {num} (or its height and width are wrong{hint})"
            )
    return streams


def _frame_bytes(height: int, row: int) -> int:
    """Bytes of a .dat frame of `height` rows of `row` bits: ceil(height·row / 8), its last byte
    padded."""
    return -(-height * row // 8)


def _wider_rows(stream: SpikeStream, num: int) -> int | None:
    """The row width, over the stream's and at most 4 times it, at which its file holds `num`
    whole frames of its height; None where none does."""
    size = stream.path.stat().st_size
    if num < 1 or size % num:
        return None
    frame = size // num  # bytes
    for width in range(stream.width + 1, 4 * stream.width + 1):
        if _frame_bytes(stream.height, width) == frame:
            return width
    return None


SILENT_SHARE = 0.01  # check_stream_image: a stream with fewer pixels that ever fire (or never
# stop firing) than this share holds no image (a hot or a dead pixel does not make one)
SWAPPED_MIN, SWAPPED_GAP = 0.5, 0.05  # neighbouring rows' correlation read swapped, over it
# and this much over the rows as read: the frame size is likely swapped. Measured (medians over
# STRUCTURE_WINDOWS of the counts' ranks), the built-in scenes read right against read swapped:
# 0.69-0.87 against -0.08-0.01 at 24x32, 0.34-0.56 against -0.05-0.05 at 12x8 (motion blur),
# and where swapped rows are true rows two apart (2:1 frames) 0.58-0.75 against 0.38-0.61 (the
# gap 0.07 at the least: 64x32); 685 datasets of earlier audits read right: none warned of
STRUCTURE_WINDOWS = (7, 401)  # images of 401 readouts at 7 places (short: little motion blur)
WIDER_GAP = 0.2  # a reading with wider stored rows this much more coherent than the rows as
# given (and SWAPPED_MIN or more): raw_width is likely missing or wrong. Measured: 64x96 with 16
# more columns a row read without raw_width 0.15, with 0.74; the camera's 416-pixel rows read as
# 400 -0.05, as 416 0.97; 504 streams read as their meta.json says (54 under SWAPPED_MIN, so
# searched; no raw rows among them): none warned of
WIDER_MIN_SIZE = 16  # rows and columns a frame needs to be read wider: random frames of 2-12 x
# 2-16 pixels, the best of many widths' noisy scores, were told to set raw_width in 14 of 330 (a
# review's) and 11 of 165 (seeded); none with the floor
ROW_MULTIPLES = range(2, 9)  # stored rows of these many times the width are tried too: frames
# given at 1/2 .. 1/8 of their size (a downsampled image's: LLFF's hwf for images_2 .. images_8)
# A frame size that reads a more coherent image must also read frames that follow one another as
# an integrate-and-fire camera's readouts do (`_in_turn`): rows alike alone named right files of
# horizontal stripes, whose rows read at 1/m of the size are pieces of one row, alike as much.
# Measured (scripts/frame_size_audit.py's streams, 512 readouts): files given at m times their
# size, read at their own, -0.165 to -0.046 (3 % hot pixels too); right files read at 1/m, -0.005
# to 0.007. IN_TURN_MIN: the least anticorrelation taken for a camera's, over 3 standard errors
# of a 16x16 frame's
IN_TURN_MIN, IN_TURN_READOUTS, IN_TURN_PIXELS = 0.01, 512, 1 << 14


def check_stream_image(
    stream: SpikeStream, settings: str, sim_rate: float | None = None
) -> np.ndarray:
    """The stream's firing rates [H, W] (spikes a readout, each pixel's over the whole stream,
    one pass, which `warn_if_faint` takes too); ValueError naming its file when
    under SILENT_SHARE of its pixels ever fire, or all but that share fire at every readout: no
    image in it (one pass over the spikes); `settings` names the file of its frame size,
    `sim_rate` a simulated stream's rate_at_one (its light at fault, not its file)."""
    n = len(stream)
    counts = stream.counts(n // 2, n)  # [H, W] spikes per pixel over the whole stream
    firing, saturated = float((counts > 0).mean()), float((counts == n).mean())
    if firing >= SILENT_SHARE and saturated <= 1 - SILENT_SHARE:
        return counts / n
    dark = firing < SILENT_SHARE
    if dark:
        what = "no spikes" if firing == 0 else f"spikes at {firing:.2%} of the pixels only"
    else:
        every = "every pixel" if saturated == 1 else f"{saturated:.2%} of the pixels"
        what = f"{every} firing at every readout"
    kind = "dark" if dark else "saturated"
    if sim_rate is None:
        cause = (
            f"a {kind} recording, a wrong file or a wrong frame size: height, width, raw_width, "
            f"col_offset in {settings}"
        )
    else:
        light = "more light or a higher" if dark else "less light or a lower"
        cause = (
            f"a {kind} simulation, rate_at_one {sim_rate:g} in {settings}: simulate it again "
            f"with {light} --rate-at-one{', at most 1' if dark else ''}; or a wrong file"
        )
    raise ValueError(
        f"{stream.path}: {what} in its {n} readouts of {stream.height}x{stream.width}: nothing "
        f"to learn from ({cause})"
    )


def warn_if_faint(
    rates: list[np.ndarray], readouts: int, source: Path, settings: str, dark_rate: float = 0.0
) -> None:
    """A FaintLightWarning where the brightest channel's lit pixels fire under FAINTEST_MEASURED
    spikes a readout: `rates` [C] of [H, W], each channel's over its `readouts`
    (`check_stream_image`), less `dark_rate` (stated in `settings`); lit, pixels over LIT_SHARE
    of the 99.9th percentile's rate and of LIT_SPIKES or more spikes (a dark pixel's spike or two
    in a short stream is no light), hot ones (HOT_RATE or more) left out of both. A recording's
    faint light was said nowhere; `source` names its file."""
    light = brightest = 0.0  # (the brightest 0.1 %'s rate, said where no pixel is lit)
    for channel in rates:
        usable = channel[channel < HOT_RATE]
        if usable.size:
            light_rates = usable - dark_rate
            top = float(np.percentile(light_rates, 99.9))
            spikes = np.rint(usable * readouts)  # (3 / 1070 * 1070 is under 3)
            lit = (light_rates > LIT_SHARE * top) & (spikes >= LIT_SPIKES)
            light = max(light, float(light_rates[lit].mean()) if lit.any() else 0.0)
            brightest = max(brightest, top)
    if light < FAINTEST_MEASURED:
        dark = f", less {settings}'s dark_rate {dark_rate:g}" if dark_rate else ""
        lit = (  # (none: "fire 0 spikes a readout" was said of a light of 0.00047)
            f"its lit pixels fire {light:.3g} spikes a readout on average{dark}"
            if light
            else f"no pixel fires {LIT_SPIKES} spikes in its {readouts} readouts (the brightest "
            f"0.1 % fire {brightest:.2g} spikes a readout{dark})"
        )
        light = light or brightest
        warnings.warn(
            f"{source}: {lit}, "
            f"fainter than any light SpikeGS was measured on ({FAINTEST_MEASURED:g}; a "
            f"33-readout TFP counts {33 * light:.2g} spikes): training fits shot noise, or "
            f"learns the background alone, and a held-out PSNR that falls is the light's, not "
            f"the learning rates'",
            FaintLightWarning,
            stacklevel=3,
        )


def _rows_alike(stream: SpikeStream) -> float:
    """How alike neighbouring rows of the stream's images are: the median over
    STRUCTURE_WINDOWS of the correlation of their counts' ranks (which a camera's hot pixels do
    not decorrelate)."""
    from scipy.stats import rankdata

    places, length = STRUCTURE_WINDOWS
    w = min(length, len(stream))
    ks = np.unique(np.linspace(w // 2, len(stream) - w + w // 2, places).astype(np.int64))
    alike = []
    for counts in stream.counts(ks, w):  # [H, W] each
        image = rankdata(counts).reshape(counts.shape)
        alike.append(correlation(image[1:], image[:-1]))
    return float(np.median(alike))


def _next_readout_alike(stream: SpikeStream, period: int) -> float:
    """The correlation of the pixels' spikes with their next readout's, pooled over (at most
    IN_TURN_PIXELS of) the pixels at IN_TURN_READOUTS readouts mid-stream, each pixel's mean at
    each phase of `period` readouts removed (a frame size 1/m of the file's cycles each pixel
    through m² of its pixels: means, not spikes, that differ). An integrate-and-fire pixel seldom
    fires twice running below 1/2 a readout (nor misses twice above): -r/(1 - r) for a regular
    one at rate r; spikes read from other pixels at the next 'readout', 0."""
    n = min(IN_TURN_READOUTS, len(stream)) // period * period
    if n < 2 * period:
        return 0.0
    spikes = stream.window(len(stream) // 2, n).reshape(n, -1)  # [n, H·W] 0/1
    step = -(-spikes.shape[1] // IN_TURN_PIXELS)
    x = spikes[:, ::step].astype(np.float32).reshape(n // period, period, -1)
    x = (x - x.mean(axis=0)).reshape(n, -1)  # [n, P]
    spread = float((x * x).sum())
    return float((x[1:] * x[:-1]).sum()) / spread if spread else 0.0


def _in_turn(other: SpikeStream, stream: SpikeStream) -> bool:
    """Whether the frames of `other` (the file read at another frame size) follow one another as
    a camera's readouts do (`_next_readout_alike` IN_TURN_MIN or more below 0), more clearly than
    the frames of `stream`, the file read as given: at least half as much where `other`'s frames
    are smaller (read wrong, each pixel's next frame is another pixel's: 0), and IN_TURN_MIN more
    where they hold whole frames of `stream` (read wrong, each pixel's next frame is its own k
    readouts on, anticorrelated too). Each reading's pixels cycle through the other's as far as
    the two frame sizes' bytes share no factor: those means are removed."""
    mine, theirs = other.layout.frame_bytes, stream.layout.frame_bytes
    common = math.gcd(mine, theirs)
    turn = _next_readout_alike(other, theirs // common)
    given = _next_readout_alike(stream, mine // common)
    if mine % theirs == 0:
        return turn <= min(given, 0.0) - IN_TURN_MIN
    return turn <= -IN_TURN_MIN and turn <= min(given, 0.0) / 2


def warn_rows_out_of_line(stream: SpikeStream, settings: str) -> None:
    """UserWarnings when a .dat stream's frames read another way give a clearly more coherent
    image (neighbouring rows alike) than as given: with height and width swapped (frames of as
    many bytes, each row then starting at another place of the scene), or, where the image as
    given has no such structure, with stored rows a few pixels wider (`_rows_wider`: a
    camera's extra columns without raw_width); read wrong, training learns noise unsaid. Rows
    wider than they are read, whose swapped reading is alike too (72-pixel rows of a 48x64
    image, their extra columns noise: 0.66 swapped, 0.76 as 72), are named by the more alike
    reading. A line of pixels or spikes in memory are not judged; a square frame or a camera's
    raw rows (raw_width, col_offset) are not read swapped; `settings` names the file of the
    size."""
    if stream.path is None or min(stream.height, stream.width) < 2:  # a line has no rows
        return
    as_read = _rows_alike(stream)
    # the wider rows' reading, scored once where it is asked for (every width opened: not where
    # a swapped reading fails on its own)
    wider = functools.cache(lambda: _rows_wider(stream, as_read) if as_read < SWAPPED_MIN else None)
    layout = stream.layout
    simple = layout.row_bits == stream.width and layout.col_offset == 0
    if simple and stream.height != stream.width:
        swapped = SpikeStream.open(stream.path, stream.width, stream.height, layout.flip)
        other = _rows_alike(swapped)
        alike = other >= SWAPPED_MIN and other - as_read >= SWAPPED_GAP
        if alike and (wider() is None or other >= wider()[1]):  # (the more alike reading)
            warnings.warn(
                f"{stream.path}: its frames read as {stream.height}x{stream.width} give an "
                f"image whose neighbouring rows correlate at {as_read:.2f}, read as "
                f"{stream.width}x{stream.height} at {other:.2f}: height and width are likely "
                f"swapped (set them in {settings}); read so, training learns noise",
                stacklevel=3,
            )
            return
    if simple and _warned_if_frames_smaller(stream, as_read, settings):
        return
    if wider() is not None:
        _warn_rows_wider(stream, as_read, *wider(), settings)


def _warned_if_frames_smaller(stream: SpikeStream, as_read: float, settings: str) -> bool:
    """Whether a UserWarning was given that the stream's file read as frames of 1/m the height
    and width (m in ROW_MULTIPLES, frames of WIDER_MIN_SIZE or more rows and columns, whole ones
    in the file) gives an image whose neighbouring rows correlate at SWAPPED_MIN or more and
    SWAPPED_GAP over `as_read`: a size stated m times the spikes' (the full-size images' of LLFF's
    hwf or a transforms file's w, h) reads m² readouts as one frame, each row m true rows side by
    side, and loaded without a word (its rows, true rows m apart, still alike). Read at 1/m of
    its size, a right file's rows are pieces of one row: measured -0.68 to 0.06, but as alike as
    true neighbours where its rows are uniform (horizontal stripes): the frames read so must
    follow one another as readouts too (`_in_turn`)."""
    size = stream.path.stat().st_size
    readings, scores = {}, {}  # the file read at 1/m of its size, and how alike its rows are
    for m in ROW_MULTIPLES:
        height, width = stream.height // m, stream.width // m
        whole = stream.height % m == 0 and stream.width % m == 0
        if not whole or min(height, width) < WIDER_MIN_SIZE or size % _frame_bytes(height, width):
            continue
        readings[m] = SpikeStream.open(stream.path, height, width, stream.layout.flip)
        scores[m] = _rows_alike(readings[m])
    m = max(scores, key=scores.get, default=None)
    if m is None or scores[m] < SWAPPED_MIN or scores[m] - as_read < SWAPPED_GAP:
        return False
    if not _in_turn(readings[m], stream):
        return False
    smaller = f"{stream.height // m}x{stream.width // m}"
    warnings.warn(
        f"{stream.path}: its frames read as {stream.height}x{stream.width} give an image whose "
        f"neighbouring rows correlate at {as_read:.2f}, read as {smaller} at {scores[m]:.2f}: "
        f"the frames are likely {smaller}, 1/{m} of the size given (the full-size images' size? "
        f"set height and width in {settings}); read so, each frame holds {m * m} readouts side "
        f"by side and training learns noise",
        stacklevel=4,
    )
    return True


def _rows_wider(stream: SpikeStream, as_read: float) -> tuple[int, float, bool] | None:
    """The stored row width R, its reading's score and whether the height is as far off,
    where the stream's file (frames of WIDER_MIN_SIZE or more rows and columns)
    read with stored rows of another width R (width <= R < 2 width, or a whole multiple of the
    width in ROW_MULTIPLES; whole frames of height·R bits in the file) gives an image whose
    neighbouring rows correlate at SWAPPED_MIN or more and WIDER_GAP over `as_read`, the rows as
    given: rows of R pixels read as fewer start each a few pixels further along the scene (a
    camera's extra columns), or each row of a frame given at 1/m of its size is 1/m of a true
    row, and frames of the wrong size blur the images of many readouts into noise. Read with
    rows m times its own, a right file's rows are true rows m apart: less alike, not more (but
    pieces of one row where its rows are uniform: a width whose frames do not follow one another
    as readouts, `_in_turn`, is not named)."""
    layout = stream.layout
    if min(stream.height, stream.width) < WIDER_MIN_SIZE:
        return None
    size = stream.path.stat().st_size
    wider, scores = {}, {}  # the file read with rows of R pixels, and how alike they are
    multiples = (m * stream.width for m in ROW_MULTIPLES)
    for row in (*range(stream.width, 2 * stream.width), *multiples):
        frame_bytes = _frame_bytes(stream.height, row)
        if row == layout.row_bits or size % frame_bytes:
            continue
        wider[row] = SpikeStream.open(stream.path, stream.height, stream.width, layout.flip, row)
        scores[row] = _rows_alike(wider[row])
    if not scores:
        return None
    row = max(scores, key=scores.get)
    if scores[row] < SWAPPED_MIN or scores[row] - as_read < WIDER_GAP:
        return None
    m = row // stream.width
    larger = row % stream.width == 0 and size % _frame_bytes(m * stream.height, row) == 0
    readings = [wider[row]]
    if larger:  # the height as far off too: frames of m² readouts read as one
        readings.append(SpikeStream.open(stream.path, m * stream.height, row, layout.flip))
    if not any(_in_turn(other, stream) for other in readings):
        return None
    return row, scores[row], larger


def _warn_rows_wider(
    stream: SpikeStream, as_read: float, row: int, score: float, larger: bool, settings: str
) -> None:
    """A UserWarning that the stream's file likely stores rows of `row` pixels (a camera's extra
    columns), or frames `row` / width times the size given where `larger` (`_rows_wider`, whose
    reading scores `score` against `as_read`)."""
    m, given = row // stream.width, f"{stream.height}x{stream.width}"
    if larger:
        warnings.warn(
            f"{stream.path}: its frames read as {given} give an image whose neighbouring rows "
            f"correlate at {as_read:.2f}, read with rows of {row} pixels at {score:.2f}: "
            f"the frames are likely {row} pixels wide, {m} times the width given ("
            f"{m * stream.height}x{row} if the height is as far off: a downsampled image's size? "
            f"set height and width in {settings}); read so, training learns noise",
            stacklevel=4,
        )
    else:
        lay = stream.layout  # (meta.json states the readouts: a second refusal named them)
        wide = _C.SpikeLayout.dat(lay.height, lay.width, lay.flip, row, 0).frame_bytes
        readouts = len(stream) * lay.frame_bytes // wide
        counted = f"num_readouts {readouts}" if settings == META else f"{readouts} readouts so"
        warnings.warn(
            f"{stream.path}: its frames read as {given} with rows of "
            f"{stream.layout.row_bits} pixels give an image whose neighbouring rows correlate at "
            f"{as_read:.2f}, read with rows of {row} pixels at {score:.2f}: the file likely "
            f"stores {row} pixels a row (a camera's extra columns: set raw_width {row}, and "
            f"col_offset, the first stored column kept, in {settings}; {counted}); "
            f"read so, training learns noise",
            stacklevel=4,
        )


def repeated(names) -> list[str]:
    """The names that occur more than once in `names`, sorted."""
    return sorted(name for name, count in collections.Counter(names).items() if count > 1)


VIEW_NAME_MAX = NAME_MAX - len(".png")  # bytes (UTF-8)


def is_view_name(name) -> bool:
    """Whether `name` can name a test view: a file name (RUN/eval/NAME.png), not a path."""
    return (
        isinstance(name, str)
        and name not in ("", ".", "..")
        and not {"/", "\\"} & set(name)
        and len(os.fsencode(name)) <= VIEW_NAME_MAX
    )


def check_test_views(views: list[TestView], where) -> None:
    """ValueError unless there is at least one held-out view and their names are unique file names
    (each names its scores and images in an evaluation); `where`: the file or scene they come
    from."""
    if not views:
        raise ValueError(f"{where}: no held-out test view; evaluation and training need one")
    for view in views:  # a name names the view's files: RUN/eval/NAME.png
        if not is_view_name(view.name):
            raise ValueError(
                f"{where}: test view name {view.name!r} expected a file name (no / or \\, at "
                f"most {VIEW_NAME_MAX} bytes)"
            )
    twice = repeated(v.name for v in views)
    if twice:
        raise ValueError(f"{where}: test view names expected unique, found twice: {twice}")


def _read_test_views(root: Path, shape: tuple, camera: dict | None) -> list[TestView]:
    from .transforms_file import frame_file  # (it imports this module)

    path = existing_file(root, TEST_VIEWS, SPLIT)
    views, listings = [], {}  # each image folder listed once (`frame_files`)
    readers: dict[Path, list[str]] = collections.defaultdict(list)  # image file -> its views
    for i, frame in enumerate(read_camera_doc(path, camera)):
        missing = [k for k in ("name", "transform_matrix", "file_path") if k not in frame]
        if missing:
            raise ValueError(f"{path}: frame {i} has no {', '.join(missing)}")
        where = f"{path}: view {frame['name']!r}"
        c2w = four_by_four(where, frame["transform_matrix"])  # [4, 4]
        readout, window = frame.get("readout"), frame.get("pseudo_window")
        path_given = isinstance(frame["file_path"], str) and frame["file_path"].strip()
        if not path_given or not (readout is None or is_number(readout)):  # ("": the folder)
            raise ValueError(
                f"{where}: file_path expected a path and readout a finite number, found "
                f"{json_text(frame['file_path'])} and {json_text(readout)}"
            )
        if window is not None and not (is_int(window) and window >= 1 and readout is not None):
            raise ValueError(
                f"{where}: pseudo_window expected a whole number of readouts >= 1 "
                f"on the path (a readout), found {window!r}"
            )
        c2w = rigid_c2w(c2w, where)  # rounded poses made rigid, before inverting
        file = frame_file(root / frame["file_path"], listings)  # as a transforms file's frame
        readers[file.resolve()].append(frame["name"])
        stored = read_stored_image(file)
        if stored.alpha is not None:
            raise ValueError(
                f"{file}: a test view with an alpha channel; expected {shape[2]} channel(s) of "
                f"firing rate"
            )
        # 8-bit files hold sRGB (write_image encodes them so): back to linear units
        image = srgb_to_linear(stored.colour) if stored.srgb else stored.colour  # [H, W, C]
        if image.shape != shape:
            swapped = image.shape == (shape[1], shape[0], shape[2]) != shape
            raise ValueError(
                f"{file}: expected an image of shape {list(shape)} (height, width, channels of "
                f"{META}), found {list(image.shape)}"
                + (f": height and width swapped in {META}?" if swapped else "")
            )
        views.append(
            TestView(
                frame["name"],
                np.linalg.inv(c2w),
                image,
                None if readout is None else float(readout),
                window,
            )
        )
    check_test_views(views, path)
    shared = [f"{names} read {file}" for file, names in readers.items() if len(names) > 1]
    if shared:  # (unsaid until 2026-12-06)
        warnings.warn(
            f"{path}: test views {'; '.join(shared[:3])}: each is scored against that one image "
            f"(a frame copied without its file_path changed?)",
            stacklevel=3,
        )
    return views


def check_dataset_folder(root: Path) -> None:
    """FileNotFoundError where the dataset folder `root` does not exist (NotADirectoryError: it is
    a file)."""
    if root.exists() and not root.is_dir():
        raise NotADirectoryError(f"{root} is a file, not a dataset folder")
    if not root.is_dir():
        raise FileNotFoundError(f"dataset folder not found: {root}")


def layout_files(root: Path) -> list[str]:
    """The files in `root` that mark a dataset: meta.json, LLFF's poses_bounds.npy, the NeRF
    layout's transforms files."""
    from .llff import POSES_BOUNDS
    from .nerf_layout import TRANSFORMS

    return [name for name in (META, POSES_BOUNDS, *TRANSFORMS) if (root / name).is_file()]


def run_folder_note(root: Path) -> str | None:
    """'ROOT: a run folder (its config.yaml, ...), not a dataset; the run's dataset is D' where
    `root` holds a run's settings or summary (spikegs train's --out, given where a dataset goes);
    None where it holds neither."""
    held = [name for name in (CONFIG, SUMMARY) if (root / name).is_file()]
    if not held:
        return None
    try:
        own = read_summary(root).get("dataset")
    except ValueError:  # (a torn train.json: the run folder is named all the same)
        own = None
    note = f"{root}: a run folder (its {', '.join(held)}), not a dataset"
    return note + (f"; the run's dataset is {own}" if own else "")


def check_trajectory_covers(trajectory: Trajectory, num: int, path: Path) -> None:
    """ValueError where the poses of `path` leave out some of a `num`-readout stream's readouts
    (poses for part of a recording, which its layout does not hold)."""
    if trajectory.start > 0 or trajectory.end < num - 1:
        raise ValueError(
            f"{path}: poses cover readouts [{trajectory.start}, {trajectory.end}], expected "
            f"[0, {num - 1}] (poses for part of a recording: the LLFF layout, one spikes.dat "
            f"with readouts.txt; docs/datasets.md)"
        )


def load_dataset(path: PathLike, progress: bool = False) -> Dataset:
    """Open a dataset directory, checking every file before returning (FileNotFoundError names a
    missing file, ValueError a malformed one); the spikes are memory-mapped, not read. Without a
    meta.json, an LLFF (poses_bounds.npy) or NeRF (transforms*.json) layout is opened instead.
    `progress`: a bar where a recording without sharp test images searches long for a flicker of
    the light (its pseudo ground truth's; docs/datasets.md)."""
    root = Path(path)
    check_dataset_folder(root)
    from .llff import POSES_BOUNDS, load_llff
    from .nerf_layout import TRANSFORMS, load_nerf_layout

    others = [name for name in layout_files(root) if name != META]
    if not is_given(root / META):
        if is_given(root / POSES_BOUNDS):
            if len(others) > 1:
                unread = ", ".join(name for name in others if name != POSES_BOUNDS)
                warnings.warn(
                    f"{root}: {unread} not read: with {POSES_BOUNDS} here the LLFF layout is "
                    f"taken (docs/datasets.md)",
                    stacklevel=2,
                )
            return load_llff(root, progress=progress)
        if others:
            return load_nerf_layout(root)
        run = run_folder_note(root)
        if run is not None:
            raise FileNotFoundError(run)
        partial = " (its spikes without a meta.json: an interrupted simulation?)"
        within = f"; {root / 'data'} holds one (a demo's folder?)"
        raise FileNotFoundError(
            f"{root}: no dataset found: none of {META} (simulated or spikegs poses), "
            f"{POSES_BOUNDS} (LLFF) or {' / '.join(TRANSFORMS)} (NeRF layout)"
            f"{partial if holds_dataset(root) else ''}"
            f"{within if layout_files(root / 'data') else ''}; docs/datasets.md"
        )
    # a meta.json marks spikegs's own layout; another layout's files beside it are not read
    not_read = (
        f"{', '.join(others)} here belong to the LLFF / NeRF layouts, read only where there is "
        f"no {META} (move {META} away, e.g. a camera's own, to read them)"
    )
    meta_path = existing_file(root, META)
    if not (root / TRAJECTORY).is_file():
        raise FileNotFoundError(
            f"dataset file not found: {root / TRAJECTORY} (the camera poses; a raw recording gets "
            f"them, and what else it lacks, from `spikegs poses {shell_path(root)}`)"
            + (f"; {not_read}" if others else "")
        )
    meta = read_json(meta_path)
    _check_meta(meta, meta_path)
    num = int(meta["num_readouts"])
    names = spike_files(int(meta["channels"]))
    streams = open_streams(root, names, meta)
    sim = meta.get("sim") if isinstance(meta.get("sim"), dict) else {}  # the simulator's
    sim_rate = sim.get("rate_at_one") if is_number(sim.get("rate_at_one")) else None
    rates = [check_stream_image(s, META, sim_rate) for s in streams]  # [C] of [H, W]
    rate = float(np.mean([r.mean() for r in rates]))  # spikes a readout
    warn_rows_out_of_line(streams[0], META)  # (the channels share a frame size)
    if (root / "spikegs.json").is_file():
        warnings.warn(_options_not_read(root / "spikegs.json"), stacklevel=2)
    if others:
        warnings.warn(f"{root}: {not_read}", stacklevel=2)
    # the files' copies of the camera predate intrinsics that `spikegs poses` estimated
    camera = None if meta.get("intrinsics_from") == INTRINSICS_FROM_SFM else camera_keys(meta)
    trajectory = Trajectory.load_json(existing_file(root, TRAJECTORY), camera)
    check_trajectory_covers(trajectory, num, root / TRAJECTORY)
    in_us = microseconds_hint(trajectory.end, num)
    if in_us:  # (as a pose log that ran on, it trained the stream on its first 1/25 unsaid)
        raise ValueError(
            f"{root / TRAJECTORY}: poses cover readouts [{trajectory.start:g}, "
            f"{trajectory.end:g}], the stream holds {num}.{in_us} Else, a pose log that ran on "
            f"far after the recording: remove its poses past readout {num - 1}."
        )
    if trajectory.end > num - 1:  # a pose log that ran on, or a stream cut short: said
        warnings.warn(
            f"{root / TRAJECTORY}: poses cover readouts [{trajectory.start:g}, "
            f"{trajectory.end:g}], the stream holds {num}: those past readout {num - 1} are not "
            f"used (a pose log that ran on after the recording, or a recording cut short?)",
            stacklevel=2,
        )
    timestamps = read_timestamps(existing_file(root, TIMESTAMPS, SPLIT))  # [M]
    lo, hi = WINDOW_MARGIN, num - 1 - WINDOW_MARGIN
    if len(timestamps) == 0:
        raise ValueError(f"{root / TIMESTAMPS}: no training timestamps (one readout per line)")
    outside = timestamps[(timestamps < lo) | (timestamps > hi)]
    if outside.size:
        raise ValueError(
            f"{root / TIMESTAMPS}: expected timestamps within [{lo}, {hi}] (a "
            f"{2 * WINDOW_MARGIN + 1}-readout window around each inside the stream's {num}), "
            f"found {outside[:5].tolist()}.{microseconds_hint(timestamps.max(), num)}"
        )
    from .real import warn_pose_gaps  # (real.py reads this module's names)

    fix = (  # (SfM's were told to "check the pose log")
        "SfM registered no image there: `spikegs poses` with more images (--count) or --sim"
        if meta.get("poses_from") == POSES_FROM_SFM
        else "check the pose log"
    )
    warn_pose_gaps(trajectory.readouts, timestamps, str(root / TRAJECTORY), fix)
    shape = (int(meta["height"]), int(meta["width"]), int(meta["channels"]))
    test_views = _read_test_views(root, shape, camera)
    _check_held_out(test_views, timestamps, num, root)
    dark = sim.get("dark_rate", 0.0)
    drowned = is_number(dark) and 0 < dark and rate <= 2 * dark  # light adds no more than dark
    if drowned:
        warnings.warn(
            f"{root / names[0]}: its spikes fire {rate:.3g} a pixel a readout, {META}'s "
            f"sim.dark_rate {dark:g} of them: the light adds {max(rate - dark, 0):.3g}, no more "
            f"than the dark current (a black scene, or light far dimmer than the simulated "
            f"noise); every method learns little but noise, and black test views score how "
            f"black a render is",
            DarkSpikesWarning,
            stacklevel=2,
        )
    warn_about_test_units(streams, test_views, root / TEST_VIEWS, dark if is_number(dark) else 0.0)
    sharp = [v for v in test_views if not v.name.startswith(PSEUDO_PREFIX)]
    if not drowned:  # (its spikes match their images no way up: said above)
        warn_if_faint(rates, num, streams[0].path, META, dark if is_number(dark) else 0.0)
        _check_orientation(streams, sharp, meta_path, meta)
    if sharp and not stated_scales(meta):
        warnings.warn(
            f"{meta_path}: neither image_scale nor sim.rate_at_one (the firing rate of intensity "
            f"1, the test images' units): the trainer guesses it from TFP(33)'s 99.5th "
            f"percentile, and the test views' PSNR depends on it",
            GuessedUnitsWarning,
            stacklevel=2,
        )
    return Dataset(root, meta, streams, trajectory, timestamps, test_views)


UNITS_RATIO = 2.0  # on-path test images whose mean is over this factor from their spikes' are
# warned of: test images are firing rates (intensity 1 at rate_at_one; intensities in [0, 1] read
# as rates scored 5.6 dB where 18.7 was due, unsaid)
UNITS_MIN_SPIKES = 1000  # spikes (per channel) those views' TFP must count to judge by
UNITS_WINDOW = 33  # readouts of the TFP that the test images are compared with
# spikes a pixel the TFP must count, on average, to check the orientation by: a simulation at a
# rate_at_one of 1e-4 (0.002) 'hardly matched' its images; a 24x32 `solids` counts 1.25
ORIENTATION_MIN_COUNT = 1.0


def _on_path(views: list[TestView], length: int) -> list[tuple[TestView, int]]:
    """The test views whose TFP(UNITS_WINDOW) lies within a stream of `length` readouts, each
    with its readout."""
    half = UNITS_WINDOW // 2
    readouts = [None if v.readout is None else round(v.readout) for v in views]
    return [(v, k) for v, k in zip(views, readouts) if k is not None and half <= k < length - half]


FIRING_RATE_UNITS = "test images are expected in firing-rate units (intensity x image_scale)"


def warn_about_test_units(
    streams: list[SpikeStream],
    views: list[TestView],
    path: Path,
    dark_rate: float,
    expected: str = FIRING_RATE_UNITS,
) -> None:
    """A UserWarning where the on-path test views' images [H, W, C] average over UNITS_RATIO
    times more, or less, than the firing rate of their spikes' light (TFP(33) at their readouts,
    each channel its stream's, less the stated `dark_rate`, which the images leave out): images
    in intensity or 8-bit units, not spikes a readout (`expected`: the units the file's images
    are to be in, and how they become firing rates). Pixels whose spikes fire every readout are
    left out: light past the sensor's saturation shows brighter in its image than in any spikes
    (a lamp saturating 3.6 % of a view was told "6.65 times": the extreme-scenes trial)."""
    image_sum = rate_sum = pixels = 0.0
    for view, k in _on_path(views, len(streams[0])):
        tfp = np.stack([s.tfp(k, UNITS_WINDOW) for s in streams], -1)  # [H, W, C]
        below = tfp < 1.0  # [H, W, C] not saturated
        count = int(below.sum())
        image_sum += float(view.image[below].sum())
        rate_sum += float(tfp[below].sum()) - dark_rate * count
        pixels += count
    if rate_sum * UNITS_WINDOW / len(streams) < UNITS_MIN_SPIKES:  # too faint to tell units
        return  # from shot noise (the light's spikes, a channel)
    ratio = image_sum / rate_sum
    if not 1 / UNITS_RATIO <= ratio <= UNITS_RATIO:
        warnings.warn(
            f"{path}: the on-path test images average {ratio:.3g} times their spikes' firing "
            f"rate (TFP(33) at their readouts: {rate_sum / pixels:.3g} spikes a readout, the "
            f"images {image_sum / pixels:.3g}): {expected}, and PSNR against images in other "
            f"units means nothing (or the spikes are not the images': dark current, another "
            f"recording)",
            stacklevel=3,
        )


def _check_orientation(
    streams: list[SpikeStream], sharp: list[TestView], path: Path, meta: dict
) -> None:
    """`check_orientation` over the on-path sharp test views: TFP(UNITS_WINDOW) at each's readout
    (the channels' mean) against its image [H, W, C]. A meta.json's flip stated wrong read every
    frame upside down unsaid, where the LLFF and NeRF layouts warned; a .dat packed most
    significant bit first, read scrambled, trained 4.3 dB low unsaid (a 48x64 `solids`). Views
    whose TFP counts under ORIENTATION_MIN_COUNT spikes a pixel are left out: light that faint
    matches its image no way up (said apart, by the simulation's checks). A colour dataset's
    files are checked each against its channel too (`check_channels`)."""
    views, channels = [], []  # (the channels' mean TFP, image); (each's TFP [C], image)
    for view, k in _on_path(sharp, len(streams[0])):
        tfps = [s.tfp(k, UNITS_WINDOW) for s in streams]  # [C] of [H, W]
        tfp = np.mean(tfps, axis=0)  # [H, W]
        if tfp.mean() * UNITS_WINDOW >= ORIENTATION_MIN_COUNT:
            views.append((tfp, view.image))
            channels.append((tfps, view.image))
    raw = (meta.get("raw_width"), meta.get("col_offset", 0))
    # a simulation's noise alone keeps TFP under MATCH_MIN (a 24x32 fine-texture at rate_at_one
    # 0.1 and threshold noise 5: 0.48): the two readings are compared there, not judged alone
    judge = "sim" not in meta
    check_orientation(views, meta["flip"], str(path), META, *raw, judge_match=judge)
    if len(streams) > 1:
        check_channels(channels, [s.path.name for s in streams], str(path))


# the real layouts' options of their split, which a meta.json dataset's own files list
SPLIT_OPTIONS = ("test_views", "train_every", "pseudo_gt_window")


def _options_not_read(path: Path) -> str:
    """What is said of the LLFF and NeRF layouts' spikegs.json at `path` beside a meta.json:
    not read, its camera's options stated in meta.json, and its split's in no place there
    (train_every moved to meta.json as told was read by `spikegs poses` alone)."""
    try:
        doc = read_json(path)
    except (OSError, ValueError):
        doc = {}
    split = [key for key in SPLIT_OPTIONS if isinstance(doc, dict) and key in doc]
    return (
        f"{path} is not read: it holds the options of the LLFF and NeRF layouts; a {META} "
        f"dataset states its own (rate_at_one, raw_width, col_offset, ...) in {META}"
        + (
            f", and {TIMESTAMPS} and {TEST_VIEWS} list its training timestamps and held-out "
            f"views, each pseudo view with its window ({', '.join(split)} in {path.name})"
            if split
            else ""
        )
    )


# every key a meta.json may hold: what `spikegs simulate` and `spikegs poses` write, a recording's
# optional ones (docs/datasets.md), and a real layout's in-memory ones
META_KEYS = (
    *("format_version", "scene", "source", "height", "width", "channels", "num_readouts"),
    *("readout_period_s", "flip", "raw_width", "col_offset", "spike_files", "seed", "sim"),
    *("fx", "fy", "cx", "cy", "scene_center", "scene_radius", "degrees_per_readout"),
    *("frame_every", "up", "luma", "image_scale", "train_every", "spp", "rate_at_one"),
    *("intrinsics_from", "poses_from", "pose_reference", "held_out_by", "test_ground_truth"),
    *("rate_at_one_from", "layout", "near", "far", "view_readouts", GUESSED_SCALE),
)


def _check_meta(meta: dict, path: Path) -> None:
    """ValueError naming `path` (meta.json) and the key unless every value training reads is
    there and of its type and range; a UserWarning naming keys not in META_KEYS, which nothing
    reads (a `"bayer_pattern": "RGGB"` beside a mosaic's one .dat loaded unsaid, as a mono
    camera's; a misspelt optional key, `"rate_at_1"`, left the rate guessed)."""
    required = ("height", "width", "channels", "num_readouts", "flip", "fx", "fy", "cx", "cy")
    missing = [k for k in (*required, "scene_center", "scene_radius") if k not in meta]
    # what `spikegs poses` estimates (removed as its warning tells): the scene sphere, and the
    # intrinsics where all four are unstated (some of them stated it refuses)
    intrinsics, sphere = {"fx", "fy", "cx", "cy"}, {"scene_center", "scene_radius"}
    lost = set(missing)
    estimated = lost <= intrinsics | sphere and (lost >= intrinsics or not lost & intrinsics)
    if missing:
        poses = f" (`spikegs poses {shell_path(path.parent)}` estimates them)" * estimated
        raise ValueError(f"{path}: missing keys {missing}{poses}")
    warn_unknown_meta_keys(meta, path, stacklevel=3)  # (load_dataset's caller)
    version = meta.get("format_version", FORMAT_VERSION)
    if version != FORMAT_VERSION or isinstance(version, (bool, str)):  # 1.0 is 1
        raise ValueError(
            f"{path}: format_version {json_text(version)}, this SpikeGS reads {FORMAT_VERSION} "
            f"(an integer)"
        )
    optional = [k for k in ("raw_width", "col_offset", "scene", "source", "spp") if k in meta]
    check_meta_values(meta, path, [*required, "scene_center", "scene_radius", *optional])


def warn_unknown_meta_keys(meta: dict, path: Path, stacklevel: int) -> None:
    """A UserWarning naming the keys of `meta` (read from `path`, a meta.json) not in META_KEYS,
    which nothing reads, to `stacklevel` (as `warnings.warn`'s, from the caller)."""
    unknown = sorted(set(meta) - set(META_KEYS))
    if unknown:
        warnings.warn(
            f"{path}: {', '.join(unknown)}: not {META}'s keys, not read (a misspelling? the keys "
            f"read are in docs/datasets.md, `meta.json`; spikegs demosaics nothing)",
            stacklevel=stacklevel + 1,
        )


def check_meta_values(meta: dict, path: Path, keys) -> None:
    """ValueError naming `path` (meta.json) and the key unless each of `keys` (present in `meta`)
    holds a value of its type and range."""

    def number(key: str, low: float = -np.inf, integer: bool = False, high=None) -> None:
        value = meta[key]
        if not (
            (is_int if integer else is_number)(value)
            and value > low
            and (high is None or value <= high)
        ):
            what = ("an integer" if integer else "a finite number") + (
                f" > {low}" if low > -np.inf else ""
            )
            what += "" if high is None else f" and at most {high}"
            raise ValueError(f"{path}: {key} expected {what}, found {json_text(value)}")

    for key in keys:
        if key in ("height", "width"):
            number(key, 0, integer=True, high=MAX_SIZE)  # the rasterizer's
        elif key == "num_readouts" or (key == "spp" and meta[key] is not None):  # null: frames
            number(key, 0, integer=True)
        elif key == "channels" and (meta[key] not in (1, 3) or isinstance(meta[key], bool)):
            raise ValueError(
                f"{path}: channels expected 1 (mono) or 3 (RGB), found {json_text(meta[key])}"
            )
        elif key == "scene_radius":
            number(key, 0)
        elif key in ("fx", "fy"):
            number(key, 0)
            size = meta.get("width" if key == "fx" else "height")
            field = field_of_view_deg(size, meta[key]) if is_number(size) else 0
            if not MIN_FIELD_DEG <= field <= MAX_FIELD_DEG and is_number(size):
                bound = MIN_FIELD_DEG if field < MIN_FIELD_DEG else MAX_FIELD_DEG
                raise ValueError(
                    f"{path}: {key} {meta[key]!r} gives a {shown_past(field, bound)}° field of "
                    f"view across {size} pixels; a pinhole camera's focal length in pixels "
                    f"expected, {MIN_FIELD_DEG:g}° to {MAX_FIELD_DEG}° of view"
                )
        elif key in ("cx", "cy"):
            number(key)
            size, focal = (
                meta.get(k) for k in (("width", "fx") if key == "cx" else ("height", "fy"))
            )
            if is_number(size) and is_number(focal) and focal > 0:  # a crop is off-axis, not off
                angle = np.degrees(np.arctan(abs(meta[key] - size / 2) / focal))
                if angle > MAX_OFF_AXIS_DEG:  # a principal point 30 widths away trained nothing
                    raise ValueError(
                        f"{path}: {key} {meta[key]!r} puts the image centre "
                        f"{shown_past(angle, MAX_OFF_AXIS_DEG)}° off the "
                        f"optical axis (|{key} - {size}/2| over the focal length {focal}); "
                        f"expected under {MAX_OFF_AXIS_DEG}°"
                    )
        elif key == "flip" and not isinstance(meta[key], bool):
            raise ValueError(f"{path}: flip expected true or false, found {json_text(meta[key])}")
        elif key == "raw_width":
            offset = meta.get("col_offset", 0)
            need = int(meta.get("width", 1)) + (offset if is_int(offset) else 0)
            if not (is_int(meta[key]) and meta[key] >= need):
                raise ValueError(
                    f"{path}: raw_width (pixels stored per .dat row) expected an integer >= "
                    f"width + col_offset = {need}, found {json_text(meta[key])}"
                )
        elif key == "col_offset" and not (is_int(meta[key]) and meta[key] >= 0):
            raise ValueError(
                f"{path}: col_offset expected an integer >= 0, found {json_text(meta[key])}"
            )
        elif key in ("scene", "source") and isinstance(meta[key], (list, dict)):
            raise ValueError(
                f"{path}: {key} expected a name or number, found {json_text(meta[key])}"
            )
        elif key == "scene_center":
            center = meta[key]
            if not (isinstance(center, list) and len(center) == 3 and all(map(is_number, center))):
                raise ValueError(
                    f"{path}: scene_center expected 3 finite numbers, found {json_text(center)}"
                )
    names = spike_files(meta["channels"]) if "channels" in keys else None
    if names and meta.get("spike_files", names) != names:  # the files are found by these names
        raise ValueError(
            f"{path}: spike_files {json_text(meta['spike_files'])}, but {meta['channels']} "
            f"channel(s) are read from {json_text(names)} (a list of file names; rename the "
            f"files, or remove the key)"
        )


def read_column(path: Path, what: str) -> np.ndarray:
    """The numbers [P] of a text file of one `what` a line (blank lines and # comments skipped);
    ValueError naming the file and the first line that is not one number."""
    try:
        lines = read_text(path, encoding="utf-8-sig").splitlines()  # a byte-order mark skipped
    except UnicodeDecodeError:
        raise ValueError(f"{path}: expected text, one {what} a line; found binary data") from None
    values = []
    for number, line in enumerate(lines, 1):
        text = line.split("#")[0].strip()
        if not text:
            continue
        try:
            if "_" in text:  # (Python's float took 9_0 for 90: a typo read as another number)
                raise ValueError
            values.append(float(text))
        except ValueError:
            fields = len(text.replace(",", " ").split())
            raise ValueError(
                f"{path}: line {number}: expected one {what} a line (a number), found {text!r}"
                f"{f' ({fields} fields)' if fields > 1 else ''}"
            ) from None
    return np.array(values, np.float64)


def read_timestamps(path: Path) -> np.ndarray:
    """The integer readouts [M] of a train_timestamps.txt; ValueError naming the file."""
    values = read_column(path, "integer readout")  # [M]
    whole = np.isfinite(values) & (values == np.round(values)) & (np.abs(values) < 2.0**62)
    bad = values[~whole]  # NaN, inf and 30-digit ones too (int64 printed them as -2^63)
    if bad.size:
        raise ValueError(f"{path}: expected integer readouts, found {bad[:5].tolist()}")
    unique, counts = np.unique(values, return_counts=True)
    if (counts > 1).any():  # sampled twice as often, silently
        twice = unique[counts > 1][:5].astype(np.int64).tolist()
        raise ValueError(f"{path}: readouts listed twice: {twice}")
    return values.astype(np.int64)


def microseconds_hint(last: float, num_readouts: int) -> str:
    """Where readouts that reach `last` run past a stream of `num_readouts` as far as a clock in
    µs would (read as µs, from half the stream to half as far past it: a µs log that ran on a
    little), a sentence saying so; else "". A pose log or timestamps in µs trained on the first
    1/25 of the poses, said to be 'a pose log that ran on after the recording'."""
    period_us = READOUT_PERIOD_S * 1e6
    as_us = last / period_us  # [half the stream, 1.5 times it], where as readouts it is past it
    if not (num_readouts - 1) / 2 <= as_us <= 1.5 * num_readouts or last <= num_readouts - 0.5:
        return ""
    return (
        f" Readouts in µs? They are readout indices, {period_us:g} µs apart: divided by "
        f"{period_us:g}, the last ({last:.10g}) is readout {last / period_us:.6g} of the "
        f"stream's {num_readouts}."
    )


def _check_held_out(views: list[TestView], timestamps: np.ndarray, num: int, root: Path) -> None:
    """ValueError if an on-path view lies outside the stream, or if a training timestamp's
    65-readout window reaches an on-path view's: its spikes would be trained on."""
    for view in views:
        if view.readout is None:
            continue
        if not 0 <= view.readout <= num - 1:
            raise ValueError(
                f"{root / TEST_VIEWS}: view '{view.name}' at readout {view.readout}, outside the "
                f"stream's [0, {num - 1}]"
            )
        near = timestamps[near_held_out(timestamps, [view.readout])]
        if near.size:
            raise ValueError(
                f"{root / TIMESTAMPS}: training readouts {near[:5].tolist()} lie within "
                f"{2 * WINDOW_MARGIN} readouts of held-out view '{view.name}' (readout "
                f"{view.readout}): their windows would train on its spikes"
            )
