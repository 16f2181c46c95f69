"""`spikegs render RUN --out video.gif|mp4`: a novel-view orbit of a trained scene."""

from __future__ import annotations

import argparse
import warnings
from pathlib import Path

import numpy as np

from .cli import output_file, positive_int
from .data.trajectory import WORLD_UP, look_at
from .output_paths import check_file_output

# directions that the cameras' right axes span with less than this fraction of their main spread
# count as level (roll noise of SfM poses stays below it)
LEVEL_SPAN = 0.05
MAX_FPS = 1000  # frames a second of a video (no player shows more)
GIF_MAX_FPS = 50  # GIF delays are hundredths of a second; most viewers slow those under 2
MP4_CODECS = ("libx264", "mpeg4")  # H.264 where PyAV's FFmpeg has it, else MPEG-4 part 2
# near-lossless for both: x264's constant quality 18; MPEG-4 at quantiser 2 (global_quality is
# in lambda units, FF_QP2LAMBDA = 118 a quantiser step)
MP4_QUALITY = {"libx264": {"crf": "18"}, "mpeg4": {"flags": "+qscale", "global_quality": "236"}}


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
        help="the world's up as X,Y,Z, the orbit's axis (default: as the cameras show it, "
        "`world_up`; a top-down or forward-facing capture leaves it open)",
    )


def direction(text: str) -> np.ndarray:
    """An argparse type: 'X,Y,Z', a non-zero finite vector, as a unit vector [3]."""
    try:
        v = np.array([float(x) for x in text.split(",")])
    except ValueError:
        v = np.zeros(0)
    norm = np.linalg.norm(v) if v.shape == (3,) else 0.0
    if not (np.isfinite(norm) and norm > 0):
        raise argparse.ArgumentTypeError(f"expected a non-zero direction X,Y,Z, found '{text}'")
    return v / norm


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
    e1 = first / np.linalg.norm(first)
    e2 = np.cross(up, e1)
    angles = 2 * np.pi * np.arange(frames) / frames  # [F]
    ring = np.cos(angles)[:, None] * e1 + np.sin(angles)[:, None] * e2  # [F, 3]
    eyes = center + distance.mean() * (np.cos(elevation) * ring + np.sin(elevation) * up)
    return np.stack([look_at(eye, center, up) for eye in eyes])


def orbit_frames(model, dataset, frames: int, up: np.ndarray | None = None) -> np.ndarray:
    """uint8 [F, H, W, 3] renders on `orbit_viewmats`' orbit, sRGB-encoded (as players show)."""
    from .evaluate import render_view
    from .image_io import linear_to_srgb

    path = orbit_viewmats(dataset.trajectory, dataset.scene_center, frames, up)
    out = []
    for viewmat in path:
        image = render_view(model, viewmat, dataset)  # [H, W, C]
        image = np.repeat(image, 3, axis=2) if image.shape[2] == 1 else image[..., :3]
        out.append((linear_to_srgb(image) * 255 + 0.5).astype(np.uint8))  # sRGB, as shown
    return np.stack(out)


def check_video_output(path: Path, fps: int) -> None:
    """ValueError, before any rendering, unless `path` can take a video at `fps`: a .gif (at most
    GIF_MAX_FPS) or an .mp4, not an existing directory."""
    suffix = path.suffix.lower()
    if suffix not in (".gif", ".mp4"):
        raise ValueError(f"--out: expected a .gif or .mp4 file, got '{path.name}'")
    check_file_output(path)
    if not 1 <= fps <= MAX_FPS:  # PyAV's frame rate is a 32-bit fraction
        raise ValueError(f"--fps: expected 1 to {MAX_FPS}, got {fps}")
    if suffix == ".gif" and fps > GIF_MAX_FPS:
        raise ValueError(
            f"--fps {fps}: a GIF holds at most {GIF_MAX_FPS} (its frame delays are whole "
            f"hundredths of a second, and viewers slow delays under 2 of them); use .mp4"
        )
    if suffix == ".mp4":
        mp4_codec()


def can_encode(codec: str) -> bool:
    """Whether PyAV's FFmpeg has an encoder named `codec` (`av.codecs_available` lists decoders
    too)."""
    import av

    try:
        av.Codec(codec, "w")
    except Exception:  # av.codec.codec.UnknownCodecError; its path moved between releases
        return False
    return True


def mp4_codec() -> str:
    """The first of MP4_CODECS that PyAV's FFmpeg can encode; ValueError if none."""
    codec = next((c for c in MP4_CODECS if can_encode(c)), None)
    if codec is None:
        raise ValueError(
            f"--out .mp4: this PyAV's FFmpeg has none of the encoders {', '.join(MP4_CODECS)}; "
            f"install PyAV's own wheel (pip install --force-reinstall av) or write a .gif"
        )
    return codec


BT601, SRGB_TRANSFER, LIMITED_RANGE = 6, 13, 1  # FFmpeg's AVColorSpace/Primaries, TRC, Range


def write_mp4(path: Path, frames: np.ndarray, fps: int) -> None:
    """uint8 frames [F, H, W, 3] as an .mp4 through PyAV's own FFmpeg (no ffmpeg on PATH needed),
    in yuv420p, which every player reads; its chroma needs an even size, so an odd height or
    width gains one edge-replicated row or column."""
    import av

    from .atomic_save import write_atomically

    h, w = frames.shape[1:3]
    frames = np.pad(frames, ((0, 0), (0, h % 2), (0, w % 2), (0, 0)), mode="edge")
    codec = mp4_codec()

    def write(tmp: Path) -> None:
        with av.open(str(tmp), "w", format="mp4") as container:
            stream = container.add_stream(codec, rate=fps, options=MP4_QUALITY[codec])
            stream.height, stream.width = frames.shape[1:3]
            stream.pix_fmt = "yuv420p"
            # what swscale's rgb24 -> yuv420p conversion makes, stated so that players do not
            # guess: BT.601 (SMPTE 170M) matrix and primaries, limited range, sRGB transfer
            context = stream.codec_context
            context.colorspace, context.color_primaries = BT601, BT601
            context.color_trc, context.color_range = SRGB_TRANSFER, LIMITED_RANGE
            for frame in frames:
                container.mux(stream.encode(av.VideoFrame.from_ndarray(frame, format="rgb24")))
            container.mux(stream.encode())  # flush the encoder's delayed frames

    write_atomically(path, write)  # no half-written video at `path`


def gif_delays_ms(count: int, fps: int) -> list[int]:
    """Per-frame delays (ms) of `count` GIF frames at `fps`: a GIF stores whole hundredths of a
    second, so a rate like 40 fps alternates 20 and 30 ms, each frame ending within 5 ms of
    its time at the exact rate (one delay of 1000 // fps played 40 fps at 50)."""
    ends = np.round(np.arange(count + 1) * 100.0 / fps)  # [count + 1] centiseconds
    return [10 * int(d) for d in np.diff(ends)]


def write_video(path: Path, frames: np.ndarray, fps: int) -> None:
    """uint8 frames [F, H, W, 3] as a GIF (Pillow) or MP4 (`write_mp4`); `check_video_output`
    first."""
    check_video_output(path, fps)
    if path.suffix.lower() == ".gif":
        from PIL import Image

        from .atomic_save import write_atomically

        images = [Image.fromarray(f) for f in frames]
        write_atomically(  # no truncated animation at `path`
            path,
            lambda tmp: images[0].save(
                tmp,
                format="GIF",
                save_all=True,
                append_images=images[1:],
                duration=gif_delays_ms(len(frames), fps),
                loop=0,
            ),
        )
    else:
        write_mp4(path, frames, fps)


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
