"""`spikegs render RUN --out video.gif|mp4`: a novel-view orbit of a trained scene."""

from __future__ import annotations

import argparse
import shutil
from pathlib import Path

import numpy as np

GIF_MAX_FPS = 50  # GIF delays are hundredths of a second; most viewers slow those under 2


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("run", type=Path, help="run folder (spikegs train --out)")
    parser.add_argument(
        "--out", type=Path, required=True, help="video file: .gif, or .mp4 (ffmpeg)"
    )
    parser.add_argument("--dataset", type=Path, help="dataset folder (default: the run's own)")
    parser.add_argument("--frames", type=int, default=60, help="frames in one full orbit")
    parser.add_argument("--fps", type=int, default=20)


def orbit_frames(model, dataset, frames: int) -> np.ndarray:
    """uint8 [F, H, W, 3] renders on a level orbit at the cameras' mean radius and elevation."""
    import torch

    from .data import Trajectory
    from .evaluate import render_view

    center = np.asarray(dataset.scene_center, dtype=np.float64)
    offsets = dataset.trajectory.centers - center  # [P, 3]
    radius = float(np.linalg.norm(offsets, axis=1).mean())
    elevation = float(np.degrees(np.arcsin(offsets[:, 2] / np.linalg.norm(offsets, axis=1))).mean())
    path = Trajectory.spiral(
        frames + 1,
        radius=radius,
        start_elevation_deg=elevation,
        end_elevation_deg=elevation,
        degrees_per_readout=360.0 / frames,
        look_at=tuple(center),
    )
    K = torch.as_tensor(dataset.K, dtype=torch.float32)
    out = []
    for viewmat in path.viewmats[:frames]:
        view = argparse.Namespace(viewmat=viewmat)
        image = render_view(model, view, K, dataset.width, dataset.height)  # [H, W, C]
        image = np.repeat(image, 3, axis=2) if image.shape[2] == 1 else image[..., :3]
        out.append((np.clip(image, 0, 1) * 255 + 0.5).astype(np.uint8))
    return np.stack(out)


def check_video_output(path: Path, fps: int) -> None:
    """ValueError, before any rendering, unless `path` can take a video at `fps`: a .gif (at most
    GIF_MAX_FPS) or an .mp4 with ffmpeg on PATH, not an existing directory."""
    suffix = path.suffix.lower()
    if suffix not in (".gif", ".mp4"):
        raise ValueError(f"--out: expected a .gif or .mp4 file, got '{path.name}'")
    if path.is_dir():
        raise ValueError(f"--out {path}: is a directory")
    if fps < 1:
        raise ValueError(f"--fps: expected a positive number, got {fps}")
    if suffix == ".gif" and fps > GIF_MAX_FPS:
        raise ValueError(
            f"--fps {fps}: a GIF holds at most {GIF_MAX_FPS} (its frame delays are whole "
            f"hundredths of a second, and viewers slow delays under 2 of them); use .mp4"
        )
    if suffix == ".mp4" and shutil.which("ffmpeg") is None:
        raise ValueError(
            "--out .mp4 needs ffmpeg on PATH (apt-get install ffmpeg); .gif works without"
        )


def write_video(path: Path, frames: np.ndarray, fps: int) -> None:
    """GIF through Pillow; MP4 through matplotlib's ffmpeg writer (`check_video_output` first)."""
    check_video_output(path, fps)
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.suffix.lower() == ".gif":
        from PIL import Image

        images = [Image.fromarray(f) for f in frames]
        images[0].save(path, save_all=True, append_images=images[1:], duration=1000 // fps, loop=0)
    else:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        from matplotlib.animation import FFMpegWriter

        h, w = frames.shape[1:3]
        fig = plt.figure(figsize=(w / 100, h / 100), dpi=100)
        ax = fig.add_axes([0, 0, 1, 1])
        ax.axis("off")
        shown = ax.imshow(frames[0])
        writer = FFMpegWriter(fps=fps)
        with writer.saving(fig, str(path), dpi=100):
            for f in frames:
                shown.set_data(f)
                writer.grab_frame()
        plt.close(fig)


def run(args: argparse.Namespace) -> int:
    from .data import load_dataset
    from .eval_cli import run_dataset
    from .ply import load_ply

    check_video_output(args.out, args.fps)
    if args.frames < 1:
        raise ValueError(f"--frames: expected a positive number, got {args.frames}")
    ply = args.run / "scene.ply"
    if not ply.exists():
        raise FileNotFoundError(f"{ply} not found: train the run first (spikegs train)")
    dataset = load_dataset(run_dataset(args.run, args.dataset))
    frames = orbit_frames(load_ply(ply), dataset, args.frames)
    write_video(args.out, frames, args.fps)
    print(f"{len(frames)} frames -> {args.out}")
    return 0
