"""`spikegs poses DATASET`: camera poses from the spikes themselves, for a camera with no pose log.

Spike images (TFP, or the dataset's cached SIM) at chosen readouts go through structure from
motion (pycolmap); the registered poses become DATASET/trajectory.json (an existing one is kept as
trajectory.json.bak) and the sparse points DATASET/points3d.ply, which the trainer uses to place
its initial Gaussians. SfM poses are known up to a similarity: with a known trajectory they are
aligned to it and their error is reported; without one they stay in SfM's own frame.

A raw recording (a meta.json and the spikes, no train_timestamps.txt or test_views.json) gets
those too: every 8th registered image held out with TFP(65) of its own spikes as ground truth (as
the real-data loaders do), training timestamps between the registered images, clear of them.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
from pathlib import Path

import numpy as np

from .atomic_save import write_text_atomically
from .cli import file_path
from .config import SupervisionConfig
from .data.dataset import (
    INTRINSICS_FROM_SFM,
    LOCK,
    META,
    POINTS,
    POINTS_BACKUP,
    POSES_FROM_SFM,
    TEST_DIR,
    TEST_VIEWS,
    TIMESTAMPS,
    TIMESTAMPS_BACKUP,
    TRAJECTORY,
    TRAJECTORY_BACKUP,
    WINDOW_MARGIN,
    TestView,
    camera_keys,
    check_dataset_folder,
    check_meta_values,
    check_stream_image,
    check_trajectory_covers,
    field_of_view_deg,
    intrinsics_keys,
    intrinsics_matrix,
    open_streams,
    read_timestamps,
    run_folder_note,
    spike_files,
    takes_lock,
    warn_rows_out_of_line,
    warn_unknown_meta_keys,
    write_parts,
    writing_dataset,
)
from .data.real import (
    HOLDOUT_EVERY,
    NEEDED_WINDOW,
    PSEUDO_PREFIX,
    ground_truth_note,
    pseudo_truth,
    spaced_instead,
    spaced_words,
    timestamps_clear_of,
)
from .data.simulate import default_train_every
from .data.trajectory import Trajectory
from .data.view_geometry import CONVERGING, axes_meeting
from .data_fingerprint import file_digest
from .interrupt import deferred_interrupt, interruption
from .number_checks import is_int
from .output_paths import writable_folder
from .pixel_defects import defect_maps, repaired_spikes
from .point_cloud import write_points
from .pose_refine import pose_errors
from .sfm import (
    Reconstruction,
    align,
    compared,
    import_pycolmap,
    reconstruct,
    spike_images,
    unmirrored,
)
from .shell_words import shell_path
from .spikes import SpikeStream
from .spikes.stream import centred_range
from .strict_json import json_text, read_json

MIN_IMAGES = 8
MEMORY_SIZES = "a lower --count, or a higher --every"  # (`cli.MEMORY_SIZES`)
DEFAULT_WINDOW = 33  # readouts of an SfM image's TFP
DEFAULT_COUNT = 40  # images spread evenly over the stream
DEFAULT_MIN_REGISTERED = 0.5  # the fraction of images SfM must register
SLOW_PAIRS = 20_000  # exhaustive matching beyond ~200 images: minutes on 2 cores
FOV_PLAUSIBLE = (10, 140)  # degrees: an estimated focal outside this is flagged
HELD_OUT_BY = "spikegs poses"  # meta.json's held_out_by: the held-out views are this command's
# the keys of sfm/report.json that record the files a run wrote, by name
DIGESTS = {
    TRAJECTORY: "trajectory_sha256",
    POINTS: "points_sha256",
    TIMESTAMPS: "timestamps_sha256",
}
MADE_EVERY = "train_every_made"  # the train_every a run wrote to meta.json, none being stated
BACKUP_DIGEST = "reference_sha256"  # the .bak aligned to, as the run that wrote the report read it
# a median rotation error (degrees) past this after the alignment: the reference or SfM is wrong
# (SfM's worst measured: 11.3° on `wires` from TFP; a pose log of world-to-camera matrices 48.6°,
# of OpenGL's axes read as OpenCV's 78.4°)
SUSPECT_ROTATION_DEG = 20.0
WORK_DIR = "sfm"  # DATASET/sfm: images, COLMAP database, sparse model and report.json


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "dataset",
        type=file_path,
        help="dataset folder (meta.json and spikes), written in place: trajectory.json (an "
        "earlier one kept as trajectory.json.bak), points3d.ply, meta.json's camera and the "
        "training timestamps; SfM's work in DATASET/sfm",
    )
    parser.add_argument(
        "--window",
        type=int,
        help=f"TFP window, odd (default {DEFAULT_WINDOW}; with --sim, the SIM's own)",
    )
    when = parser.add_mutually_exclusive_group()
    when.add_argument("--every", type=int, help="an image every N readouts")
    when.add_argument("--count", type=int, default=DEFAULT_COUNT, help="images spread evenly")
    parser.add_argument(
        "--sim", action="store_true", help="images from the cached SIM (DATASET/sim/*.pt), not TFP"
    )
    parser.add_argument(
        "--min-registered",
        type=float,
        default=DEFAULT_MIN_REGISTERED,
        help="fail below this fraction of registered images",
    )


def run(args: argparse.Namespace) -> int:
    report = estimate_poses(
        args.dataset, args.window, args.every, args.count, args.sim, args.min_registered
    )
    print(report["summary"])
    return 0


def _image_readouts(
    num_readouts: int, window: int, every: int | None, count: int, option: str = "--window"
) -> np.ndarray:
    """Readouts [N] whose `window` fits in the stream: every `every`, else `count` evenly;
    `option`: what sets the window, for the error where it does not fit."""
    first, last = centred_range(num_readouts, window)
    if first > last:
        raise ValueError(f"{option} {window}: longer than the stream's {num_readouts} readouts")
    if every is not None:
        return np.arange(first, last + 1, every)
    count = min(count, last - first + 1)  # (2**63 - 1 evenly: numpy's IndexError)
    return np.unique(np.round(np.linspace(first, last, count)).astype(np.int64))


def _saved_sims(root: Path) -> list[Path]:
    """The dataset's trained SIMs (DATASET/sim/*.pt; other files there are passed over), the
    latest trained or reused last."""
    from .sim_train import is_sim_file

    saved = [p for p in (root / "sim").glob("*.pt") if is_sim_file(p)]
    return sorted(saved, key=lambda p: p.stat().st_mtime)


def _cached_sim(root: Path, posed: bool):
    """The dataset's most recently trained SIM (`_saved_sims`), said which; `posed`: whether
    the recording has poses already (SIM trains on a dataset with them)."""
    from .sim_train import load_sim

    cached = _saved_sims(root)
    if not cached:
        where = shell_path(root)
        first = "" if posed else f"`spikegs poses {where}` (SfM on TFP images) first, then "
        raise ValueError(
            f"--sim: no trained SIM in {root / 'sim'}; run {first}`spikegs sim-train {where}`, "
            f"then --sim"
        )
    print(
        f"--sim: the latest of {len(cached)} trained SIM(s), {cached[-1].name} (its name gives "
        f"its window, steps, ...; `spikegs sim-train`, training or reusing one, makes it the "
        f"latest)",
        file=sys.stderr,
    )
    return load_sim(cached[-1])


SFM_REFERENCE, LOG_REFERENCE = "first spikegs poses run", "pose log"  # meta's pose_reference


def _reference_is_sfm(meta: dict, backed_up: bool, ours: bool, report: str | None) -> bool:
    """Whether the trajectory the poses are aligned to is an earlier run's SfM, not a pose log:
    trajectory.json where no .bak is (`backed_up`), as meta.json's poses_from says; else the
    .bak, as meta.json's pose_reference recorded when it was made, or, a dataset posed before
    that record, the last run's `report` (sfm/report.json's text) where it named a pose log;
    else by whether this command made its split (`ours`), which took a recording's pose log,
    backed up by the first run, for its first run's SfM (the reviews)."""
    if not backed_up:
        return meta.get("poses_from") == POSES_FROM_SFM
    recorded = meta.get("pose_reference")
    if recorded in (SFM_REFERENCE, LOG_REFERENCE):
        return recorded == SFM_REFERENCE
    if _reported(report).get("pose_reference") == LOG_REFERENCE:
        return False
    return ours


def _reported(report: str | None) -> dict:
    """The last run's report (sfm/report.json's text) as a dict; {} where there is none or it is
    torn."""
    try:
        reported = json.loads(report or "null")
    except ValueError:
        return {}
    return reported if isinstance(reported, dict) else {}


def _written_over(path: Path, report: str | None, key: str | None = None) -> bool | None:
    """Whether the file at `path` is another than the last run wrote (or, `key`
    BACKUP_DIGEST, aligned to) there, as its `report` (sfm/report.json's text) recorded it under
    `key` (default `DIGESTS`'): a pose log or another tool's points put in its place, a pose log
    moved over an SfM .bak; False where there is none, None where the report records none."""
    if not path.is_file():
        return False
    written = _reported(report).get(key or DIGESTS[path.name])
    return None if written is None else file_digest(path) != written


def _backup_placed(backup: Path, report: str | None) -> bool:
    """Whether the .bak at `backup` is a file put there since the last run, which wrote the
    `report` (sfm/report.json's text): another than the one it aligned to, or one where it
    aligned to none (its report records its files' digests, not the .bak's)."""
    written_over = _written_over(backup, report, BACKUP_DIGEST)
    if written_over is None:  # none recorded: placed since, unless the report predates digests
        return DIGESTS[TRAJECTORY] in _reported(report)
    return written_over


def _image_window(window: int | None, sim_model) -> int:
    """The readouts an image reads: `window` (DEFAULT_WINDOW where None), or a SIM's own, which
    a `window` given otherwise would not change (it moved the images' centres alone, unsaid)."""
    if sim_model is None:
        return DEFAULT_WINDOW if window is None else window
    if window is not None and window != sim_model.window:
        raise ValueError(
            f"--window {window} with --sim: SIM reads the {sim_model.window}-readout windows it "
            f"was trained on; leave --window out, or train a SIM of {window} readouts "
            f"(`spikegs sim-train --window {window}`), the latest then read"
        )
    return sim_model.window


def _recording(root: Path, meta: dict) -> list[SpikeStream]:
    """The spike streams that meta.json describes; ValueError naming meta.json where a key is
    missing or of the wrong type, or where the files do not match it."""
    where = root / META
    required = ("height", "width", "channels", "num_readouts", "flip")
    missing = [k for k in required if k not in meta]
    if missing:
        raise ValueError(f"{where}: missing keys {missing} (docs/datasets.md, spikegs poses)")
    intrinsics = [k for k in ("fx", "fy", "cx", "cy") if k in meta]
    if meta.get("intrinsics_from") != INTRINSICS_FROM_SFM and 0 < len(intrinsics) < 4:
        raise ValueError(
            f"{where}: states {intrinsics} of the intrinsics fx, fy, cx, cy: state all four (held "
            f"fixed) or none (structure from motion estimates them)"
        )
    optional = ("scene_center", "scene_radius", "raw_width", "col_offset", "scene", "source")
    stated = [k for k in (*intrinsics, *optional) if k in meta]
    # as training reads them later, in its words: sizes > 0 (a 0 was refused by the stream
    # without naming meta.json), channels 1 or 3, flip a JSON boolean
    check_meta_values(meta, where, [*required, *stated])
    # (a misspelt col_offset: SfM failed); said of estimate_poses' caller
    warn_unknown_meta_keys(meta, where, stacklevel=4)
    streams = open_streams(root, spike_files(meta["channels"]), meta)
    for stream in streams:  # a dark or saturated file: said before SfM, not after it
        check_stream_image(stream, META)
    warn_rows_out_of_line(streams[0], META)
    return streams


SPHERE_KEYS = ("scene_center", "scene_radius")


def _complete_meta(
    meta: dict, recon: Reconstruction, estimated: bool, again: bool, report: dict
) -> list[str]:
    """Fill in what meta.json did not know from SfM: the intrinsics when SfM `estimated` them
    (recorded as intrinsics_from: sfm, so that a later run estimates them again), the scene centre
    and radius when missing or `again` where they are the last run's estimate
    (`_is_last_estimate`), in its frame (a pose log aligned to since kept SfM's sphere: no
    training view saw the scene), recording the estimate in this run's `report`."""
    messages = []
    if estimated:
        K = recon.K
        meta.update(intrinsics_keys(K), intrinsics_from=INTRINSICS_FROM_SFM)
        messages.append(
            f"the intrinsics were not stated: SfM's estimate fx = fy = {K[0, 0]:.2f}, "
            f"cx = {K[0, 2]:.2f}, cy = {K[1, 2]:.2f} written to {META} (intrinsics_from: "
            f"{INTRINSICS_FROM_SFM}; state fx, fy, cx, cy without it to hold a calibration fixed)"
        )
        fov = field_of_view_deg(meta["width"], K[0, 0])
        if not FOV_PLAUSIBLE[0] <= fov <= FOV_PLAUSIBLE[1]:
            messages.append(
                f"warning: that focal length gives a {fov:.1f}° horizontal field of view, outside "
                f"{FOV_PLAUSIBLE[0]}-{FOV_PLAUSIBLE[1]}°: a poor estimate (few registered images, "
                f"little parallax?); state the camera's intrinsics in {META} if they are known"
            )
    if any(key not in meta for key in SPHERE_KEYS) or again:
        centre = np.median(recon.points, axis=0)  # [3]
        distances = np.linalg.norm(recon.points - centre, axis=1)  # [P]
        meta.update(scene_center=centre.tolist(), scene_radius=float(np.percentile(distances, 95)))
        report["scene_sphere"] = {key: meta[key] for key in SPHERE_KEYS}  # (the next run's)
        messages.append(
            f"scene_center and scene_radius estimated from the points ({META})"
            + (" again: the last run's estimate was in its own poses' frame" if again else "")
        )
    return messages


def _is_last_estimate(meta: dict, last_sphere: dict | None) -> bool:
    """Whether meta's scene centre and radius are those the last run estimated (`last_sphere`),
    not the user's."""
    return isinstance(last_sphere, dict) and all(
        key in meta and meta[key] == last_sphere.get(key) for key in SPHERE_KEYS
    )


def _stated_train_every(meta: dict, meta_path: Path) -> int | None:
    """meta.json's `train_every` (a positive integer, else ValueError), None where unstated."""
    every = meta.get("train_every")
    if every is not None and not (is_int(every) and every > 0):
        raise ValueError(
            f"{meta_path}: train_every expected a positive integer, found {json_text(every)}"
        )
    return None if every is None else int(every)


def _made_every(root: Path, meta: dict, report: str | None) -> int | None:
    """The train_every the last run made for its split and wrote to meta.json, none being
    stated: its `report`'s (sfm/report.json's text) record; a report from before that record
    (2026-12-07), of a split this command made: ceil(R / 1024) of the R readouts its poses span
    (trajectory.json's recorded span); else None."""
    reported = _reported(report)
    if MADE_EVERY in reported:
        return reported[MADE_EVERY]
    if not reported or meta.get("held_out_by") != HELD_OUT_BY or not (root / TRAJECTORY).is_file():
        return None
    first, last = Trajectory.load_json(root / TRAJECTORY).recorded_span()
    return default_train_every(int(last - first) + 1)


def _registered_timestamps(root: Path, registered: np.ndarray):
    """The dataset's training timestamps [M], those before any poses run dropped some (its .bak,
    where there is one: a run registering a narrower span narrowed them for good), and which [M]
    have the exposure loss's default window (t ± 16) between the first and last registered
    readouts (outside them the poses are held constant: wrong by as much as the camera turns
    there); None where all do and none was dropped. ValueError where none does, or where the
    file is malformed."""
    backup = root / TIMESTAMPS_BACKUP
    ks = read_timestamps(backup if backup.is_file() else root / TIMESTAMPS)  # [M]
    reach = SupervisionConfig.exposure_window // 2
    inside = (ks - reach >= registered[0]) & (ks + reach <= registered[-1])
    if inside.all() and not backup.is_file():
        return None
    if not inside.any():
        raise ValueError(
            f"{root / TIMESTAMPS}: no training timestamp has its window within the registered "
            f"readouts [{registered[0]:g}, {registered[-1]:g}], where the poses are known: more "
            f"images (--count), a longer --window or --sim; or remove {TIMESTAMPS} and "
            f"{TEST_VIEWS} to have a split made from the registered images"
        )
    return ks, inside


def _keep_timestamps(root: Path, ks: np.ndarray, inside: np.ndarray, registered) -> str:
    """Rewrite the training timestamps to those `inside` (the list before kept once, as a .bak:
    the original); the line that says so."""
    backup = root / TIMESTAMPS_BACKUP
    if not backup.exists():
        shutil.copy2(root / TIMESTAMPS, backup)
    write_text_atomically(root / TIMESTAMPS, "".join(f"{k}\n" for k in ks[inside]))
    return (
        f"kept {inside.sum()} of {len(ks)} training timestamps in {TIMESTAMPS}, those whose "
        f"windows lie within the registered readouts [{registered[0]:g}, {registered[-1]:g}] "
        f"(the poses are held constant outside them); the original list is {backup.name}"
    )


def _held_out_split(
    streams, trajectory: Trajectory, registered: np.ndarray, train_every: int, truth
) -> tuple[list[TestView], np.ndarray, str | None]:
    """A raw recording's held-out views and training timestamps [M]: every HOLDOUT_EVERY-th
    `registered` readout whose TFP(65) fits in the stream is held out, `truth(k, 65)` [H, W, C]
    its ground truth (`pseudo_truth`: TFP with the sensor's defects repaired and a flicker of the
    light divided, as the real-data loaders make it); timestamps every `train_every` readouts
    whose 65-readout windows lie between the first and last registered readouts (the trajectory
    is held constant outside) and clear of the held-out views'. Images dense in readouts (a high
    --count: 8 of 160 timestamps trained, unsaid) hold out spaced ones instead where those keep
    FEW_KEPT times as many timestamps, as a pose log's stream does (`real.spaced_instead`),
    and the line that says so; else None. ValueError when either comes out empty."""
    num = len(streams[0])
    lo, hi = centred_range(num, NEEDED_WINDOW)  # readouts whose ground-truth window fits
    fits = (lo <= registered) & (registered <= hi)  # [R]
    every_nth = np.zeros(len(registered), bool)
    every_nth[::HOLDOUT_EVERY] = True
    if not (every_nth & fits).any():
        raise ValueError(
            f"no held-out view: none of the registered images at readouts "
            f"{registered[::HOLDOUT_EVERY].tolist()} has room for a {NEEDED_WINDOW}-readout "
            f"ground truth in the {num}-readout stream"
        )

    def clear_of(test: np.ndarray) -> np.ndarray:  # timestamps [M] clear of registered[test]
        first, last = registered[0], registered[-1]
        return timestamps_clear_of(num, registered[test], train_every, first, last)

    test, note = every_nth & fits, None
    ks = clear_of(test)
    instead = spaced_instead(registered, fits, train_every, len(ks), clear_of)
    if instead is not None:
        spaced, spaced_ks, nth = instead
        picked = registered[spaced].tolist()
        note = (
            f"every {HOLDOUT_EVERY}th registered image, the default held-out views, leaves "
            f"{len(ks)} training timestamps (each keeps {2 * WINDOW_MARGIN} readouts clear "
            f"of a held-out view): held out the image{'s' if len(picked) > 1 else ''} at "
            f"readout{'s' if len(picked) > 1 else ''} {', '.join(map(str, picked[:5]))}"
            f"{', ...' if len(picked) > 5 else ''} instead ({len(picked)} of {len(registered)}, "
            f"{spaced_words(nth, fits)}), which leave{'s' if len(picked) == 1 else ''} "
            f"{len(spaced_ks)}"
        )
        test, ks = spaced, spaced_ks
    held = [int(k) for k in registered[test]]
    if not len(ks):
        raise ValueError(
            f"no training timestamp: the registered readouts [{registered[0]}, {registered[-1]}] "
            f"leave no {NEEDED_WINDOW}-readout window clear of the held-out views {held} (every "
            f"{HOLDOUT_EVERY}th image): lower --count (fewer held-out views) or record longer"
        )
    views = [
        TestView(
            f"{PSEUDO_PREFIX}{k:06d}",
            trajectory.pose_at(float(k)),
            truth(k, NEEDED_WINDOW),  # [H, W, C]
            float(k),
            NEEDED_WINDOW,
        )
        for k in held
    ]
    return views, ks, note


def _pose_report(recon: Reconstruction, reference: Trajectory, radius: float) -> dict:
    """Rotation (degrees) and centre (scene radii) errors of aligned poses against `reference`,
    at the registered readouts `compared` with it (their number: `compared`)."""
    inside = compared(recon.readouts, reference)  # [R]
    readouts = recon.readouts[inside]
    rotation, centre = pose_errors(recon.viewmats[inside], reference.pose_at(readouts))
    centre = centre / radius
    return {
        "compared": int(inside.sum()),
        "rotation_error_deg_median": float(np.median(rotation)),
        "rotation_error_deg_max": float(rotation.max()),
        "centre_error_median": float(np.median(centre)),
        "centre_error_max": float(centre.max()),
    }


def _upside_down_note(
    recon: Reconstruction, reference: Trajectory, off: float, name: str, meta: dict
) -> str | None:
    """The warning, where `recon`, aligned to `reference` (the file `name`), is `off` (its median
    rotation error, degrees) by over SUSPECT_ROTATION_DEG but its cameras read upside down
    (`unmirrored`) are within that: meta.json's `flip` is likely wrong (a wrong flip was 35 deg
    off, blamed on the pose log or SfM); else None. Only where the cameras' view directions
    spread (CONVERGING): forward-facing ones in a log of OpenGL's axes, or rolled 180 deg, fit
    as well upside down (10.5 and 17.8 deg: the review)."""
    if off <= SUSPECT_ROTATION_DEG or axes_meeting(recon.viewmats).spread < CONVERGING:
        return None
    try:
        flipped = align(unmirrored(recon), reference)
    except ValueError:  # (no similarity fits them either: not this)
        return None
    turned = _pose_report(flipped, reference, 1.0)["rotation_error_deg_median"]
    if turned > SUSPECT_ROTATION_DEG:
        return None
    return (
        f"warning: the cameras fit {name} mirrored, median rotation error {off:.2f} deg as read "
        f"and {turned:.2f} with the images upside down: the spikes are likely read upside down, "
        f"{META}'s flip ({json_text(meta['flip'])}) wrong; set it to "
        f"{json_text(not meta['flip'])} and run again (the poses written are aligned as read)"
    )


def _reprojection_report(recon: Reconstruction) -> dict:
    """SfM's reprojection error in pixels: the mean over every observation of a point, the worst
    registered image's mean, and each image's mean by its readout (null where it observes none)."""
    errors = recon.image_errors  # [R]
    return {
        "reprojection_error_px": recon.reprojection_error,
        "reprojection_error_px_max": float(np.nanmax(errors)),
        "image_reprojection_error_px": {
            str(int(k)): None if np.isnan(e) else float(e) for k, e in zip(recon.readouts, errors)
        },
    }


def estimate_poses(
    root: str | Path,
    window: int | None = None,
    every: int | None = None,
    count: int = DEFAULT_COUNT,
    sim: bool = False,
    min_registered: float = DEFAULT_MIN_REGISTERED,
) -> dict:
    """Run SfM on the dataset at `root` and write its poses and points there; returns the report
    (also written to DATASET/sfm/report.json). Busy while another process writes the dataset or
    trains from it."""
    args = (window, every, count, sim, min_registered)
    if Path(root).is_dir() and not writable_folder(Path(root)):  # (its lock's EROFS, or all the
        raise ValueError(  # images' work, then sfm/'s "File exists", said no more)
            f"{root}: not writable, where spikegs poses writes the poses, points and split (and "
            f"its work in {WORK_DIR}/); copy the dataset to a writable folder"
        )
    # refused as a dataset without meta.json, nothing made: a folder holding neither a lock nor
    # meta.json is no dataset a spikegs process writes (an LLFF layout's spikes.dat: it was
    # left a lock file, though refused)
    unlocked = not (Path(root) / LOCK).exists() and not (Path(root) / META).is_file()
    if unlocked or not takes_lock(Path(root)):
        return _estimate_poses(Path(root), *args)
    with writing_dataset(root):  # its poses and split, read as they change: one process at a time
        return _estimate_poses(Path(root), *args)


def _estimate_poses(
    root: Path, window: int | None, every: int | None, count: int, sim: bool, min_registered: float
) -> dict:
    """`estimate_poses`, its dataset locked."""
    root = Path(root)
    check_dataset_folder(root)
    meta_path = root / META
    if not meta_path.is_file():
        raise FileNotFoundError(
            run_folder_note(root)
            or f"dataset file not found: {meta_path} (spikegs poses reads a recording's meta.json "
            f"and spike files; an LLFF or NeRF layout brings its own poses: docs/datasets.md)"
        )
    meta = read_json(meta_path)
    if window is not None and (window < 1 or window % 2 == 0):
        raise ValueError(f"--window: expected an odd window >= 1, got {window}")
    if every is not None and every < 1:
        raise ValueError(f"--every: expected >= 1 readout, got {every}")
    if every is None and count < 1:
        raise ValueError(f"--count: expected >= 1 image, got {count}")
    if not 0 < min_registered <= 1:
        raise ValueError(f"--min-registered: expected a fraction in (0, 1], got {min_registered}")
    streams = _recording(root, meta)  # every check before any work or any write
    backup = root / TRAJECTORY_BACKUP
    report_path = root / WORK_DIR / "report.json"  # the live poses' (SfM's folder is replaced)
    live_report = report_path.read_text() if report_path.is_file() else None
    replaced = bool(_written_over(root / TRAJECTORY, live_report))
    # another tool's points; where no digest is recorded, there while no spikegs poses ran (a
    # report, or poses_from: an older run's cloud was kept as another tool's)
    others_points = _written_over(root / POINTS, live_report)
    if others_points is None:
        others_points = live_report is None and meta.get("poses_from") != POSES_FROM_SFM
    if others_points and (root / POINTS_BACKUP).exists():  # (written over, lost unsaid)
        raise ValueError(
            f"{root / POINTS}: another tool's point cloud (not the last spikegs poses run's), "
            f"which a run would write over, and {POINTS_BACKUP} holds an earlier one: move one "
            f"of them elsewhere"
        )
    if replaced and backup.exists():  # (aligned to the .bak, and written over: lost unsaid)
        raise ValueError(
            f"{root / TRAJECTORY}: another file than the last spikegs poses run wrote (a pose "
            f"log put back?), where a run aligns to {backup.name}, the pose log kept then, and "
            f"writes its poses over {TRAJECTORY}: to align to the new file, move it to "
            f"{backup.name}; to align to {backup.name} again, remove {TRAJECTORY}"
        )
    reference_path = backup if backup.exists() else root / TRAJECTORY  # the original pose log
    reference = Trajectory.load_json(reference_path) if reference_path.exists() else None
    num = len(streams[0])
    if reference is not None:  # (a partial one failed after SfM, in its alignment)
        check_trajectory_covers(reference, num, reference_path)
    # a raw recording (or one this command completed before) gets held-out views and timestamps
    present = [name for name in (TIMESTAMPS, TEST_VIEWS) if (root / name).exists()]
    if len(present) == 1:
        raise ValueError(
            f"{root}: {present[0]} without {({TIMESTAMPS, TEST_VIEWS} - set(present)).pop()}: a "
            f"dataset's split needs both (remove {present[0]} to have them made from the "
            f"registered images)"
        )
    split = bool(present)
    ours = meta.get("held_out_by") == HELD_OUT_BY  # an earlier run of this made the split
    if reference is None and split and not ours:  # (trained and scored in two frames, unsaid)
        raise ValueError(
            f"{root}: {TEST_VIEWS} and {TIMESTAMPS} without {TRAJECTORY}: the held-out views' "
            f"poses are in the frame of a pose log that is not there, which SfM's poses, in a "
            f"frame of their own, cannot be aligned to: put the pose log back as {TRAJECTORY} "
            f"to align to it, or remove {TEST_VIEWS} and {TIMESTAMPS} to have a split made from "
            f"the registered images"
        )
    raw = ours or not split
    # a list edited since the last run, which filters the .bak's and writes them over it (a split
    # this command made, `raw`, is made afresh); one equal to the .bak is the .bak's
    listed, backup_list = root / TIMESTAMPS, root / TIMESTAMPS_BACKUP
    if (
        not raw
        and backup_list.exists()
        and _written_over(listed, live_report)
        and listed.read_bytes() != backup_list.read_bytes()
    ):
        raise ValueError(
            f"{listed}: another list than the last spikegs poses run wrote (edited since?), "
            f"where a run writes those of {TIMESTAMPS_BACKUP}, the list before any run, that its "
            f"poses cover: to have the new list's kept, copy it over {TIMESTAMPS_BACKUP}; to go "
            f"back to {TIMESTAMPS_BACKUP}'s, copy that over {TIMESTAMPS}"
        )
    stated_every = _stated_train_every(meta, meta_path) if raw else None
    if stated_every is not None and stated_every == _made_every(root, meta, live_report):
        stated_every = None  # the last run's, for its span
    import_pycolmap()  # not installed: refused before announcing SfM, the images unmade
    posed = reference is not None
    sim_model = _cached_sim(root, posed) if sim else None  # none cached: refused before SfM
    window = _image_window(window, sim_model)
    # (with --sim, --window is refused: SIM's own is set by sim-train's, the review)
    option = "--window" if sim_model is None else "SIM's window (spikegs sim-train --window N)"
    readouts = _image_readouts(num, window, every, count, option)
    if len(readouts) < MIN_IMAGES:
        first, last = centred_range(num, window)  # the readouts the window fits around
        centres = last - first + 1
        fix = f"a shorter {option}" if centres < MIN_IMAGES else "raise --count or lower --every"
        raise ValueError(  # (a window leaving 2 centres was told to raise --count)
            f"too few images for structure from motion: {len(readouts)} (at least {MIN_IMAGES}); "
            f"{num} readouts with a {window}-readout window: {fix}"
        )
    if every is None and len(readouts) < count:
        print(
            f"--count {count}: the stream has {len(readouts)} readouts to centre a "
            f"{window}-readout window on; using them all",
            file=sys.stderr,
        )
    pairs = len(readouts) * (len(readouts) - 1) // 2
    print(
        f"SfM: {len(readouts)} images, {pairs} pairs matched exhaustively"
        + (" (slow: --count 40 to 100 suffices for an orbit)" if pairs > SLOW_PAIRS else ""),
        file=sys.stderr,
    )
    # the sensor's hot, stuck and dead pixels: a dot at one place in every image, a feature that
    # does not move with the camera, and they set the 99.5th percentile that scales the images;
    # SIM reads them repaired as its training did (it reads a defect's spikes into its neighbours)
    defects = defect_maps(streams)  # [C, H, W]
    sources = repaired_spikes(streams) if sim_model is not None else streams
    images = spike_images(sources, readouts, window, sim_model, defects)
    # intrinsics stated in meta.json are held fixed; those an earlier run estimated are not
    K = None
    if meta.get("intrinsics_from") != INTRINSICS_FROM_SFM and all(
        k in meta for k in ("fx", "fy", "cx", "cy")
    ):
        K = intrinsics_matrix(meta)
    try:
        recon = reconstruct(  # a SIM trains on a dataset with poses: not a raw recording's first
            images,
            readouts,
            root / WORK_DIR,
            K,
            min_registered,
            from_sim=sim_model is not None,
            can_sim=(root / TRAJECTORY).is_file(),
        )
    except BaseException:  # failed or stopped: the poses still in use keep their report
        if live_report is not None and not report_path.is_file():
            report_path.parent.mkdir(parents=True, exist_ok=True)
            write_text_atomically(report_path, live_report)
        raise
    defective = int(defects.any(0).sum())  # pixels, in any channel
    # meta's sphere the last run estimated (in its poses' frame: estimated again, below)
    sphere_again = _is_last_estimate(meta, _reported(live_report).get("scene_sphere"))
    report = {
        "images": recon.num_images,
        "registered": len(recon.readouts),
        "points": len(recon.points),
        "defects": defective,
        **_reprojection_report(recon),
    }
    messages = [
        f"SfM: {len(recon.readouts)} of {recon.num_images} images registered "
        f"({len(recon.readouts) / recon.num_images:.0%}), {len(recon.points)} points, mean "
        f"reprojection error {recon.reprojection_error:.2f} px (worst image "
        f"{report['reprojection_error_px_max']:.2f} px)"
    ]
    pairs, parallax = recon.pair_counts
    if pairs and not parallax:  # (no longer refused before mapping: small images' orbits)
        messages.append(
            f"warning: none of the {pairs} matched image pairs showed parallax to COLMAP's "
            f"verification (most of each pair's matches explained by a homography within 4 "
            f"px, as in most pairs of small images): check these poses; where the camera "
            f"barely moved or only turned they are fitted to noise"
        )
    if sim_model is None and len(streams) == 1:  # (a colour camera's mean is as clean)
        how = (
            "--sim reads the SIM trained on them"
            if _saved_sims(root)
            else f"`spikegs sim-train {shell_path(root)}`, then --sim"
        )
        messages.append(
            f"SfM read TFP({window}) images of the spikes; SIM's are cleaner, and put simulated "
            f"mono scenes' poses 2.5 to 7 times closer: {how} (docs/datasets.md, 'spikegs poses')"
        )
    if defective:
        messages.append(
            f"{defective} hot, stuck or dead pixels of the sensor (found in the spikes) showed "
            f"the median of their 8 neighbours in the SfM images (docs/datasets.md, 'Sensor "
            f"defects')"
        )
    if reference is None:
        messages.append(
            "no trajectory to align to: the poses are in SfM's own frame, known up to a "
            "similarity (arbitrary rotation, translation and scale)"
        )
        framed = [k for k in ("scene_center", "scene_radius", "up") if k in meta]
        framed = [k for k in framed if not (sphere_again and k in SPHERE_KEYS)]
        if framed:  # (`up`: an orbit's axis, which `spikegs render` tilted unsaid)
            messages.append(
                f"warning: {' / '.join(framed)} in {META} are kept, but they cannot be in SfM's "
                f"frame; remove them to have them estimated (the scene sphere from the points, "
                f"an orbit's up from the cameras)"
            )
    else:
        recon = align(recon, reference)
    messages += _complete_meta(meta, recon, K is None, sphere_again, report)
    if reference is not None:
        report.update(_pose_report(recon, reference, float(meta["scene_radius"])))
        # a raw recording's reference is the first run's SfM where it had no pose log: a
        # difference, not an error
        # (a pose log put in place of an earlier run's SfM is a pose log)
        # (a pose log moved over an SfM .bak, as a refusal tells, was called the first run's;
        # one put there where the last run kept none, as docs/datasets.md tells, too)
        logged = replaced or _backup_placed(backup, live_report)
        sfm = not logged and _reference_is_sfm(meta, backup.exists(), ours, live_report)
        report["pose_reference"] = meta["pose_reference"] = SFM_REFERENCE if sfm else LOG_REFERENCE
        word = "difference" if sfm else "error"
        first, last = reference.recorded_span()
        within = (
            f" of the {report['compared']} of {len(recon.readouts)} registered images within "
            f"its poses' span (readouts {first:g}..{last:g}; its first and last poses are held "
            f"constant outside it)"
            if report["compared"] < len(recon.readouts)
            else ""
        )
        messages.append(
            f"aligned to {reference_path.name} by a similarity on the camera centres and "
            f"orientations{within}: rotation "
            f"{word} median {report['rotation_error_deg_median']:.2f} deg (max "
            f"{report['rotation_error_deg_max']:.2f}), centre {word} median "
            f"{report['centre_error_median']:.2%} of the scene radius "
            f"(max {report['centre_error_max']:.2%})"
            + (" — against the first spikegs poses run's poses, not a pose log" if sfm else "")
        )
        off = report["rotation_error_deg_median"]
        upside_down = (  # (against an earlier run's SfM, the flip it read with: unjudged)
            None if sfm else _upside_down_note(recon, reference, off, reference_path.name, meta)
        )
        if upside_down:
            messages.append(upside_down)
        elif off > SUSPECT_ROTATION_DEG:  # (written unsaid)
            messages.append(
                f"warning: a median rotation {word} over {SUSPECT_ROTATION_DEG:.0f} deg: "
                + (
                    "this run's SfM or the first one's went wrong"
                    if sfm
                    else "a pose log in another convention (world-to-camera matrices, or "
                    "OpenGL's axes where OpenCV's are read: docs/datasets.md, 'Poses'), or "
                    "SfM gone wrong"
                )
                + f"; the poses written are aligned to {reference_path.name}, as wrong as it"
            )
        if not backup.exists():
            messages.append(f"the previous trajectory is kept as {backup.name}")
    trajectory = recon.trajectory(num)
    meta["poses_from"] = POSES_FROM_SFM  # (a gap between registered images: said as SfM's)
    kept = None if raw else _registered_timestamps(root, recon.readouts)  # checked before writes
    if raw:  # held-out views and training timestamps too, so that the recording trains
        span = recon.readouts[-1] - recon.readouts[0] + 1  # the readouts the poses cover
        train_every = stated_every or default_train_every(span)
        # (a re-run took it for stated: 1275 timestamps over 1468); null: stated
        report[MADE_EVERY] = train_every if stated_every is None else None
        truth, notes = pseudo_truth(streams)
        views, ks, spaced = _held_out_split(streams, trajectory, recon.readouts, train_every, truth)
        note = {**ground_truth_note(0, len(views)), **notes}
        meta.update(train_every=train_every, test_ground_truth=note, held_out_by=HELD_OUT_BY)
        where = f"every {HOLDOUT_EVERY}th registered image" if spaced is None else "spaced: below"
        messages.append(
            f"wrote {TRAJECTORY}, {POINTS}, {META}, {TIMESTAMPS} ({len(ks)} training timestamps) "
            f"and {TEST_VIEWS}: {len(views)} held-out view{'s' if len(views) > 1 else ''} "
            f"({where}), their ground truth TFP({NEEDED_WINDOW}) of their own spikes (named "
            f"{PSEUDO_PREFIX}*)"
        )
        messages += [spaced] if spaced else []
    else:
        messages.append(f"wrote {TRAJECTORY}, {POINTS} and {META}")
    if others_points:
        messages.append(f"the previous {POINTS}, another tool's, is kept as {POINTS_BACKUP}")
    # written whole, not torn by a stop: one between the trajectory and meta.json left SfM's
    # poses, which the next run aligned to as a pose log ("error 0.00 deg") and kept as its .bak
    stop = "\n{signal}: stopping once the poses and points are written"
    with deferred_interrupt(stop) as interrupted:
        if reference is not None and not backup.exists():
            shutil.copy2(reference_path, backup)
        if raw:
            for old in (root / TEST_DIR).glob(f"{PSEUDO_PREFIX}*"):  # a previous run's held-out
                old.unlink()  # images (the folder's other files are not this command's)
            write_parts(root, meta, trajectory, ks, views)
        else:
            trajectory.save_json(root / TRAJECTORY, **camera_keys(meta))
            write_text_atomically(meta_path, json.dumps(meta, indent=1))
            if kept is not None:
                messages.append(_keep_timestamps(root, *kept, recon.readouts))
        if others_points:
            shutil.copy2(root / POINTS, root / POINTS_BACKUP)
        write_points(root / POINTS, recon.points, recon.colors)
        report["summary"] = "\n".join(messages)
        # what this run wrote: a pose log or another tool's points put in their place is told
        report.update({key: file_digest(root / name) for name, key in DIGESTS.items()})
        if backup.exists():
            report[BACKUP_DIGEST] = file_digest(backup)
        write_text_atomically(report_path, json.dumps(report, indent=1))
    if interrupted():
        raise interruption(interrupted())
    return report
