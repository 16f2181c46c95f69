"""`spikegs render RUN --out video.gif|mp4`: a novel-view orbit of a trained scene."""

from __future__ import annotations

import argparse
import warnings
from collections.abc import Iterator
from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from .cli import (
    add_no_progress,
    direction,
    file_path,
    output_file,
    positive_float,
    show_bars,
)
from .data.trajectory import WORLD_UP, look_at, orbit_eye, unit_vector, up_rotation
from .interrupt import deferred_interrupt, interruption, say
from .output_paths import check_file_output, check_utf8_name, record_beside
from .video import GIF_MAX_FPS, MAX_FPS, check_video_output, write_video

# directions that the cameras' right axes span with less than this fraction of their main spread
# count as level (roll noise of SfM poses stays below it)
LEVEL_SPAN = 0.05
# cameras whose azimuths about the scene centre leave no gap over this many degrees surround it:
# `spikegs render` circles them (three cameras 120° apart do); otherwise it loops over their span
SURROUND_GAP_DEG = 120.0
# the circle's elevation at most this far from the horizon: cameras straight above the centre
# (a top-down capture with --up along their view) circle just off the pole, the view turning
TOP_DEG = 89.0
PATH_TEXT = {  # what each path shows, as `spikegs render` says
    "circle": "a circle around the scene centre",
    "span": "a loop over the views the cameras span (--path circle for the whole circle)",
    "trajectory": "the cameras' recorded path",
}

MEMORY_SIZES = "--frames, --scale"  # (`cli.MEMORY_SIZES`)
# an orbit's frames at most: 9 hours at 30 frames a second (every camera is made before the first
# frame: 10^8 took 5.8 GB, and 2^63 - 1 numpy's IndexError)
MAX_FRAMES = 1_000_000


def frame_count(text: str) -> int:
    """An argparse type: a number of frames in 1..MAX_FRAMES, its range said when refused."""
    try:
        frames = int(text)
    except ValueError:
        frames = 0
    if not 1 <= frames <= MAX_FRAMES:
        raise argparse.ArgumentTypeError(
            f"expected 1 to {MAX_FRAMES:,} frames ({MAX_FRAMES:,}: over 9 hours at 30 a second), "
            f"found '{text}'"
        )
    return frames


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("run", type=file_path, help="run folder (spikegs train --out)")
    parser.add_argument("--out", type=output_file, required=True, help="video file: .gif or .mp4")
    parser.add_argument("--dataset", type=file_path, help="dataset folder (default: the run's own)")
    parser.add_argument(
        "--frames", type=frame_count, default=60, help=f"frames in one orbit, up to {MAX_FRAMES:,}"
    )
    parser.add_argument(
        "--fps",
        type=int,
        default=20,
        help=f"frames a second, 1 to {MAX_FPS} (a .gif {GIF_MAX_FPS} at most)",
    )
    parser.add_argument(
        "--scale",
        type=positive_float,
        default=1.0,
        help="frames this many times the dataset's width and height (default 1; 4: a 128x128 "
        "scene's orbit at 512x512), each Gaussian drawn as wide as the training images showed "
        "it (a run trained with train.antialiased or train.filter_3d: as it is); where the "
        "frame's pixels are coarser than theirs, each the mean of a render at their size or "
        "finer",
    )
    parser.add_argument(
        "--path",
        choices=("auto", *PATH_TEXT),
        default="auto",
        help="circle: the whole level circle at the cameras' mean elevation; span: a loop over "
        "the azimuths and elevations the cameras span (a forward-facing capture, a partial arc); "
        f"auto (default): a circle where no gap between the cameras' azimuths is over "
        f"{SURROUND_GAP_DEG:g} degrees, else a span; trajectory: the recorded path, the frames "
        "evenly over its readouts",
    )
    parser.add_argument(
        "--up",
        type=direction,
        help="the world's up as X,Y,Z, the orbit's axis (default: the up a dataset was simulated "
        "with, meta.json's `up`, else as the cameras show it, `world_up`; a top-down or "
        "forward-facing capture leaves it open); not with --path trajectory, whose cameras are "
        "the recorded ones",
    )
    add_no_progress(parser)


def world_up(c2w: np.ndarray) -> np.ndarray:
    """The world's up [3] as cameras c2w [P, 4, 4] (OpenCV) held without roll show it: the
    direction their right axes span least (a camera's right is level), signed and, where the
    rights leave it open (cameras all turned alike), completed by their mean up."""
    rights, ups = c2w[:, :3, 0], -c2w[:, :3, 1]  # OpenCV: y points down the image
    values, vectors = np.linalg.eigh(rights.T @ rights)  # ascending
    level = vectors[:, values < LEVEL_SPAN * values[-1]]  # [3, k]: directions no right spans
    up = level @ (level.T @ ups.mean(axis=0))  # the mean up, within those directions
    if np.linalg.norm(up) < 1e-6:
        return np.asarray(WORLD_UP, np.float64)
    return up / np.linalg.norm(up)


def _arc_of(azimuths: np.ndarray) -> tuple[float, float]:
    """(start, width) in degrees of the shortest arc holding every azimuth [P] (degrees): it starts
    after the largest gap between neighbours around the circle."""
    ordered = np.sort(azimuths % 360.0)
    gaps = np.diff(np.append(ordered, ordered[0] + 360.0))  # [P]: after each azimuth
    largest = int(np.argmax(gaps))
    return float(ordered[(largest + 1) % len(ordered)]), float(360.0 - gaps[largest])


def _span_loop(
    azimuths: np.ndarray, elevations: np.ndarray, turn: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Azimuths and elevations (degrees) [F] at angles `turn` [F] of an ellipse over cameras'
    azimuths (from the start of their arc) and elevations [P]: about their mean, along their
    principal directions, sqrt(3) standard deviations across (a uniform spread's half-width: a
    grid's inscribed ellipse, a line's length, travelled to and fro) or their nearer extreme
    from the mean along it, whichever is less, kept within their extremes."""
    points = np.stack([azimuths, elevations], axis=1)  # [P, 2]
    spread, directions = np.linalg.eigh(np.cov(points.T, bias=True).reshape(2, 2))  # ascending
    # (a clip alone held the path still at an end for frames running: few cameras, or a
    # non-uniform spread, reach less than sqrt(3) sigma)
    along = (points - points.mean(axis=0)) @ directions  # [P, 2]
    reach = np.minimum(-along.min(axis=0), along.max(axis=0))  # [2]
    radii = np.minimum(np.sqrt(3.0 * np.maximum(spread, 0.0)), reach)  # [2]
    loop = points.mean(axis=0) + (  # [F, 2]: the major axis first
        np.cos(turn)[:, None] * radii[1] * directions[:, 1]
        + np.sin(turn)[:, None] * radii[0] * directions[:, 0]
    )
    loop = np.clip(loop, points.min(axis=0), points.max(axis=0))
    return loop[:, 0], loop[:, 1]


def orbit_viewmats(
    trajectory, center, frames: int, up: np.ndarray | None = None, path: str = "auto"
) -> tuple[np.ndarray, str]:
    """Viewmats [F, 4, 4] looking at `center` from the cameras' mean distance, about unit `up`
    [3] (default: their `world_up`: real data (SfM, LLFF) has no fixed world up, so +z would tilt
    or flip the path), and the path taken: "circle", the whole level circle at their mean
    elevation (within TOP_DEG of the horizon) from the first camera's azimuth; "span", a loop
    over the azimuths and elevations the cameras span (a forward-facing capture, a partial arc: a
    circle would show mostly what no camera saw; cameras all above the centre have no azimuths
    to span: a circle); "auto", a circle where the cameras surround the centre (no gap between
    their azimuths over SURROUND_GAP_DEG) or span no views (one camera, a dolly), else a span."""
    center = np.asarray(center, np.float64)
    up = world_up(np.linalg.inv(trajectory.viewmats)) if up is None else np.asarray(up, float)
    offsets = trajectory.centers - center  # [P, 3]
    distance = np.linalg.norm(offsets, axis=1)  # [P]
    away = distance > 1e-9 * max(1.0, np.abs(center).max())  # [P] cameras off the centre
    if not away.any():
        raise ValueError(
            "render: every camera sits at the scene centre (a capture turning in place): an "
            "orbit around it has no radius"
        )
    ratio = offsets @ up / np.maximum(distance, np.finfo(float).tiny)  # [P] (0 at the centre)
    elevations = np.degrees(np.arcsin(np.clip(ratio, -1, 1)))  # [P]
    axes = up_rotation(up)  # [3, 3]: columns orbit_eye's x and y (azimuths 0° and 90°), and up
    level = offsets @ axes[:, :2]  # [P, 2]: in the orbit plane
    beside = np.linalg.norm(level, axis=1) > 1e-6 * distance.max()  # [P]: not above the centre
    azimuths = np.degrees(np.arctan2(level[:, 1], level[:, 0]))  # [P]
    start, width = _arc_of(azimuths[beside]) if beside.any() else (0.0, 0.0)
    if not beside.any():  # cameras all above or below the centre: no azimuths to span
        path = "circle"
    elif path == "auto":  # (1e-6: round-off) cameras at one azimuth and elevation span no views
        spread = width + np.ptp(elevations[beside])
        around = 360.0 - width <= SURROUND_GAP_DEG + 1e-6 or spread <= 1e-6
        path = "circle" if around else "span"
    turn = 2 * np.pi * np.arange(frames) / frames  # [F]
    if path == "circle":  # from the first camera's azimuth, where it has one
        azimuth = (azimuths[0] if beside[0] else start) + np.degrees(turn)  # [F]
        elevation = np.full(frames, np.clip(elevations[away].mean(), -TOP_DEG, TOP_DEG))
    else:  # a quarter step on: a to-and-fro line shows no view twice running (a GIF merges them)
        azimuth, elevation = _span_loop(
            (azimuths[beside] - start) % 360.0, elevations[beside], turn + np.pi / 2 / frames
        )
        azimuth += start
    eyes = orbit_eye(center, distance.mean(), azimuth, elevation, up)  # [F, 3]
    return np.stack([look_at(eye, center, up) for eye in eyes]), path


def dataset_orbit(
    dataset, frames: int, up: np.ndarray | None = None, path: str = "auto"
) -> tuple[np.ndarray, str, np.ndarray | None]:
    """Viewmats [F, 4, 4], the path taken and the readouts [F] of a "trajectory" path (else
    None): the dataset's poses at F readouts evenly over those its trajectory spans (the recorded
    path, interpolated as training reads it), else `orbit_viewmats`' about `up`, else the up the
    dataset was simulated with (meta.json's `up`), else the cameras'."""
    trajectory = dataset.trajectory
    if path == "trajectory":
        readouts = np.linspace(trajectory.start, trajectory.end, frames)  # [F]
        return trajectory.pose_at(readouts), path, readouts
    if up is None and dataset.meta.get("up") is not None:
        up = unit_vector("meta.json's up", dataset.meta["up"])
    return (*orbit_viewmats(trajectory, dataset.scene_center, frames, up, path), None)


def orbit_frames(
    model, dataset, path: np.ndarray, scale: float = 1.0, trained: dict | None = None
) -> Iterator[np.ndarray]:
    """uint8 [H, W, 3] renders at viewmats `path` [F, 4, 4], `scale` times the dataset's size
    and no finer than the training camera `trained` drew them (`render_size.render_scaled`),
    sRGB-encoded (as players show), one at a time as they are asked for: a video's frames all
    held at once, and stacked, took twice their memory (1080p: 6 MB a frame)."""
    from .image_io import linear_to_srgb
    from .render_size import render_scaled

    for viewmat in path:
        image = render_scaled(model, viewmat, dataset, scale, trained)  # [H, W, C]
        image = np.repeat(image, 3, axis=2) if image.shape[2] == 1 else image[..., :3]
        yield (linear_to_srgb(image) * 255 + 0.5).astype(np.uint8)  # sRGB, as shown


def run(args: argparse.Namespace) -> int:
    from .data import load_dataset
    from .data.dataset import GuessedUnitsWarning, reading_dataset
    from .eval_cli import run_dataset
    from .evaluate import other_data
    from .render_size import scaled_size
    from .run_summary import read_summary, trained_model, trained_scene

    check_video_output(args.out, args.fps)
    if args.up is not None and args.path == "trajectory":  # (ignored unsaid)
        raise ValueError(
            "--up sets the axis of an orbit (--path auto, circle or span); --path trajectory "
            "renders the recorded cameras as they were"
        )
    for path, flag in ((args.out, "--out"), (args.run, "RUN")):  # (as strict JSON holds them)
        check_utf8_name(path, flag, "the cameras' record beside the video names")
    # the cameras' record too (a folder of its name was said after the rendering, exit 0)
    check_file_output(record_beside(args.out), "--out's cameras, beside it:")
    trained_scene(args.run)  # (a run without one refused before its dataset loads)
    root = run_dataset(args.run, args.dataset)
    with reading_dataset(root), warnings.catch_warnings():  # (not rewritten as it is read)
        # the test images' units matter to scores, not to an orbit
        warnings.simplefilter("ignore", GuessedUnitsWarning)
        dataset = load_dataset(root, show_bars(args.no_progress))  # (its flicker search's bar)
        mismatch = other_data(args.run, dataset)  # (its spikes' digest)
    if mismatch:  # eval scores such a dataset as another; an orbit took its cameras unsaid
        warnings.warn(
            f"{mismatch}: the orbit follows that dataset's cameras, scene centre and image size",
            stacklevel=2,
        )
    scaled_size(dataset.width, dataset.height, args.scale)  # (refused before any rendering)
    viewmats, path, readouts = dataset_orbit(dataset, args.frames, args.up, args.path)
    trained = read_summary(args.run).get("camera")  # (a run from before it: the dataset's)
    model = trained_model(args.run)
    frames = tqdm(  # as written (3000 frames at --scale 4 printed nothing until they were)
        orbit_frames(model, dataset, viewmats, args.scale, trained),
        "rendering",
        total=len(viewmats),
        unit="frame",
        disable=not show_bars(args.no_progress),
    )
    cameras = record_beside(args.out)
    write_video(args.out, frames, args.fps, count=len(viewmats))
    # the video's cameras written with it, not left a previous video's by a stop between the two
    # (a SIGTERM as the new video landed kept the old 60 frames' cameras beside its 400)
    stop = "\n{signal}: stopping once the video's cameras are written"
    unwritten = None  # the cameras' error: the video stands, said after it (exit status 2)
    with deferred_interrupt(stop) as interrupted:
        try:
            save_orbit(
                cameras,
                viewmats,
                dataset,
                readouts,
                video=args.out,
                run=args.run,
                fps=args.fps,
                path=path,
                scale=args.scale,
            )
        except OSError as err:  # (an earlier video's, left, would describe this one)
            said = (
                f"{err.filename or cameras}: {err.strerror or err}: the cameras not written "
                f"beside the video {args.out}, which stands"
            )
            try:
                cameras.unlink(missing_ok=True)
            except OSError as kept:
                said += f"; {cameras}, an earlier video's, is left: {kept.strerror}"
            cameras, unwritten = None, OSError(err.errno, said)
    if interrupted():
        if unwritten is not None:  # (the stop's "terminated" alone implied they were written)
            say(unwritten.strerror)  # (a gone stderr must not replace the stop)
        raise interruption(interrupted())
    # said once both files are written (a full stdout's error left the video without its cameras)
    count = f"{len(viewmats)} frame{'s' if len(viewmats) != 1 else ''}"  # ("1 frames")
    print(f"{count}, {PATH_TEXT[path]} -> {args.out}")
    if unwritten is not None:  # an output not written: as a full disk's (a script's status 2)
        raise unwritten
    print(f"cameras: {cameras}")
    return 0


def save_orbit(
    file: Path,
    viewmats: np.ndarray,
    dataset,
    readouts: np.ndarray | None,
    *,
    video: Path,
    run: Path,
    fps: int,
    path: str,
    scale: float = 1.0,
):
    """Write the orbit's cameras, viewmats [F, 4, 4], in the layout of trajectory.json (OpenCV
    camera-to-world, the dataset's camera with its images `scale` times as large), a `frame`
    index per frame, and its `readout` on a trajectory path (`readouts` [F]), with what rendered
    them and the `path` taken: another method rendered at these poses shows the same views."""
    from .data.dataset import camera_keys
    from .data.trajectory import readout_number, write_camera_doc
    from .provenance import environment
    from .render_size import scaled_keys

    write_camera_doc(
        file,
        (
            {"frame": i}
            | ({} if readouts is None else {"readout": readout_number(readouts[i])})
            | {"transform_matrix": c2w.tolist()}
            for i, c2w in enumerate(np.linalg.inv(viewmats))
        ),
        **scaled_keys(camera_keys(dataset.meta), scale),  # meta.json's (dataset.K is float32)
        video=str(Path(video).resolve()),
        fps=fps,
        scale=scale,
        orbit=path,
        run=str(Path(run).resolve()),
        dataset=str(Path(dataset.root).resolve()),
        environment=environment(),
    )
