"""`spikegs render RUN --out video.gif|mp4`: a novel-view orbit of a trained scene."""

from __future__ import annotations

import argparse
import warnings
from pathlib import Path

import numpy as np

from .cli import direction, output_file, positive_int
from .data.trajectory import WORLD_UP, look_at, orbit_eye, unit_vector, up_rotation
from .video import GIF_MAX_FPS, MAX_FPS, check_video_output, write_video

# directions that the cameras' right axes span with less than this fraction of their main spread
# count as level (roll noise of SfM poses stays below it)
LEVEL_SPAN = 0.05


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("run", type=Path, help="run folder (spikegs train --out)")
    parser.add_argument("--out", type=output_file, required=True, help="video file: .gif or .mp4")
    parser.add_argument("--dataset", type=Path, help="dataset folder (default: the run's own)")
    parser.add_argument("--frames", type=positive_int, default=60, help="frames in one orbit")
    parser.add_argument(
        "--fps",
        type=int,
        default=20,
        help=f"frames a second, 1 to {MAX_FPS} (a .gif {GIF_MAX_FPS} at most)",
    )
    parser.add_argument(
        "--up",
        type=direction,
        help="the world's up as X,Y,Z, the orbit's axis (default: the up a dataset was simulated "
        "with, meta.json's `up`, else as the cameras show it, `world_up`; a top-down or "
        "forward-facing capture leaves it open)",
    )


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


def orbit_viewmats(trajectory, center, frames: int, up: np.ndarray | None = None) -> np.ndarray:
    """Viewmats [F, 4, 4] on a level orbit around `center` at the cameras' mean distance and
    elevation, starting at the first camera's azimuth, about unit `up` [3] (default: their
    `world_up`: real data (SfM, LLFF) has no fixed world up, so +z would tilt or flip the orbit)."""
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
    elevation = np.arcsin(np.clip(offsets[away] @ up / distance[away], -1, 1)).mean()
    first = offsets[0] - (offsets[0] @ up) * up  # the first camera's direction in the orbit plane
    if np.linalg.norm(first) <= 1e-6 * distance.max():  # above the centre, or at it: any way
        first = np.cross(up, [1.0, 0.0, 0.0] if abs(up[0]) < 0.9 else [0.0, 1.0, 0.0])
    axes = up_rotation(up)  # [3, 3]: columns orbit_eye's x and y (azimuths 0° and 90°), and up
    start = np.degrees(np.arctan2(first @ axes[:, 1], first @ axes[:, 0]))  # the first camera's
    azimuths = start + 360.0 * np.arange(frames) / frames  # [F]
    eyes = orbit_eye(center, distance.mean(), azimuths, np.degrees(elevation), up)  # [F, 3]
    return np.stack([look_at(eye, center, up) for eye in eyes])


def orbit_frames(model, dataset, frames: int, up: np.ndarray | None = None) -> np.ndarray:
    """uint8 [F, H, W, 3] renders on `orbit_viewmats`' orbit, sRGB-encoded (as players show), about
    `up`, else the up the dataset was simulated with (meta.json's `up`), else the cameras'."""
    from .evaluate import render_view
    from .image_io import linear_to_srgb

    if up is None and dataset.meta.get("up") is not None:
        up = unit_vector("meta.json's up", dataset.meta["up"])
    path = orbit_viewmats(dataset.trajectory, dataset.scene_center, frames, up)
    out = []
    for viewmat in path:
        image = render_view(model, viewmat, dataset)  # [H, W, C]
        image = np.repeat(image, 3, axis=2) if image.shape[2] == 1 else image[..., :3]
        out.append((linear_to_srgb(image) * 255 + 0.5).astype(np.uint8))  # sRGB, as shown
    return np.stack(out)


def run(args: argparse.Namespace) -> int:
    from .data import load_dataset
    from .data.dataset import GuessedUnitsWarning
    from .eval_cli import run_dataset
    from .evaluate import other_data
    from .ply import load_ply
    from .run_summary import trained_scene

    check_video_output(args.out, args.fps)
    ply = trained_scene(args.run)
    with warnings.catch_warnings():  # the test images' units matter to scores, not to an orbit
        warnings.simplefilter("ignore", GuessedUnitsWarning)
        dataset = load_dataset(run_dataset(args.run, args.dataset))
    mismatch = other_data(args.run, dataset)
    if mismatch:  # eval scores such a dataset as another; an orbit took its cameras unsaid
        warnings.warn(
            f"{mismatch}: the orbit follows that dataset's cameras, scene centre and image size",
            stacklevel=2,
        )
    frames = orbit_frames(load_ply(ply), dataset, args.frames, args.up)
    write_video(args.out, frames, args.fps)
    print(f"{len(frames)} frames -> {args.out}")
    return 0
