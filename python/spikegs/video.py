"""Videos of rendered frames: an .mp4 through PyAV's own FFmpeg or a .gif through Pillow, written
whole or not at all."""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from pathlib import Path

import numpy as np

from .atomic_save import write_atomically
from .output_paths import check_file_output

MAX_FPS = 1000  # frames a second of a video (no player shows more)
GIF_MAX_FPS = 50  # GIF delays are hundredths of a second; most viewers slow those under 2
MP4_CODECS = ("libx264", "mpeg4")  # H.264 where PyAV's FFmpeg has it, else MPEG-4 part 2
# near-lossless for both: x264's constant quality 18, without B-frames (choosing them, x264
# reads stack memory it never wrote: the same frames made other files where other work ran
# between two of them, as a render does; -0.7 to +1.1 % bytes without); MPEG-4 at quantiser 2
# (global_quality is in lambda units, FF_QP2LAMBDA = 118 a quantiser step)
MP4_QUALITY = {
    "libx264": {"crf": "18", "bf": "0"},
    "mpeg4": {"flags": "+qscale", "global_quality": "236"},
}
# x264's assembly held to AVX2 where the CPU has AVX-512: x264's AVX-512 code (core 165, PyAV
# 18's) read heap memory it never wrote (the same frames made 6 files in 20 encodes after other
# allocations, and a test's file once in CI), its AVX2 code one file (as a machine's with AVX2
# and without AVX-512); 30 frames of 540x960 in 1.10 s against 1.03 (BENCHMARKS.md)
X264_WITHOUT_AVX512 = {"x264-params": "asm=AVX2"}


def check_video_output(path: Path, fps: int) -> None:
    """ValueError, before any rendering, unless `path` can take a video at `fps`: a .gif (at most
    GIF_MAX_FPS) or an .mp4, not an existing directory."""
    suffix = path.suffix.lower()
    if path.name.lower() in (".gif", ".mp4"):  # (a hidden file's name, whose suffix is none)
        raise ValueError(f"--out: '{path.name}' names no file before its suffix: NAME{path.name}")
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


# FFmpeg's AVColorSpace (the matrix), AVColorPrimaries, AVColorTransferCharacteristic, AVColorRange
BT601_MATRIX, BT709_PRIMARIES, SRGB_TRANSFER, LIMITED_RANGE = 6, 1, 13, 1


def _even(frame: np.ndarray) -> np.ndarray:
    """A uint8 frame [H, W, 3] with an edge-replicated row and column added where H or W is odd
    (yuv420p's chroma needs an even size)."""
    h, w = frame.shape[:2]
    return np.pad(frame, ((0, h % 2), (0, w % 2), (0, 0)), mode="edge")


def checked_frames(
    path: Path, frames: Iterable[np.ndarray], count: int | None = None
) -> Iterator[np.ndarray]:
    """`frames`, each checked as it comes: uint8 [H, W, 3], all of the first's size (an .mp4's
    encoder rescaled another size unsaid), `count` of them where given (a GIF's delays are
    counted before its frames); ValueError naming the video and the frame otherwise, or where
    there is none."""
    first, n = None, 0
    for n, frame in enumerate(frames, 1):
        frame = np.asarray(frame)
        if frame.dtype != np.uint8 or frame.ndim != 3 or frame.shape[2] != 3:
            raise ValueError(
                f"{path}: frame {n}: expected uint8 [H, W, 3], got {frame.dtype} "
                f"{list(frame.shape)}"
            )
        first = frame.shape if first is None else first
        if frame.shape != first:
            raise ValueError(
                f"{path}: frame {n} is {frame.shape[0]}x{frame.shape[1]}, the first "
                f"{first[0]}x{first[1]}: a video's frames share one size"
            )
        if count is not None and n > count:
            raise ValueError(f"{path}: more frames than the {count} stated")
        yield frame
    if n == 0:
        raise ValueError(f"{path}: no frames to write")
    if count is not None and n < count:
        raise ValueError(f"{path}: {n} frames, {count} stated")


def mp4_options(codec: str) -> dict[str, str]:
    """The encoder options of `codec` (one of MP4_CODECS): MP4_QUALITY's, and x264's assembly
    without AVX-512 on a CPU that has it (X264_WITHOUT_AVX512)."""
    from . import _C

    avx512 = codec == "libx264" and _C.cpu_features.get("avx512f", False)
    return {**MP4_QUALITY[codec], **(X264_WITHOUT_AVX512 if avx512 else {})}


def write_mp4(path: Path, frames: Iterable[np.ndarray], fps: int, count: int | None = None) -> None:
    """uint8 frames [H, W, 3] (an array [F, H, W, 3], or any iterable: each is encoded as it
    comes, and only it is held) as an .mp4 through PyAV's own FFmpeg (no ffmpeg on PATH needed),
    in yuv420p, which every player reads; its chroma needs an even size, so an odd height or
    width gains one edge-replicated row or column; `count`: as `checked_frames`."""
    import av

    codec = mp4_codec()
    options = mp4_options(codec)

    def write(tmp: Path) -> None:
        # a file of ours, not a name: FFmpeg read a relative '2024-05-01T10:30.mp4' as the
        # protocol '2024-05-01T10', and kept a file open whose write failed (a full disk)
        with open(tmp, "wb") as file, av.open(file, "w", format="mp4") as container:
            stream = None
            for frame in map(_even, checked_frames(path, frames, count)):
                if stream is None:  # the first frame's size is the video's
                    stream = container.add_stream(codec, rate=fps, options=options)
                    stream.height, stream.width = frame.shape[:2]
                    stream.pix_fmt = "yuv420p"
                    # stated so that players do not guess: the BT.601 (SMPTE 170M) matrix and
                    # limited range that swscale's rgb24 -> yuv420p conversion uses, and the
                    # frames' own sRGB primaries (BT.709's; SMPTE 170M's, stated before, shifted
                    # a colour-managed player's gamut) and transfer
                    context = stream.codec_context
                    context.colorspace, context.color_primaries = BT601_MATRIX, BT709_PRIMARIES
                    context.color_trc, context.color_range = SRGB_TRANSFER, LIMITED_RANGE
                container.mux(stream.encode(av.VideoFrame.from_ndarray(frame, format="rgb24")))
            container.mux(stream.encode())  # flush the encoder's delayed frames

    write_atomically(path, write)  # no half-written video at `path`


def gif_delays_ms(count: int, fps: int) -> list[int]:
    """Per-frame delays (ms) of `count` GIF frames at `fps`: a GIF stores whole hundredths of a
    second, so a rate like 40 fps alternates 20 and 30 ms, each frame ending within 5 ms of
    its time at the exact rate (one delay of 1000 // fps played 40 fps at 50)."""
    ends = np.round(np.arange(count + 1) * 100.0 / fps)  # [count + 1] centiseconds
    return [10 * int(d) for d in np.diff(ends)]


def write_video(
    path: Path, frames: Iterable[np.ndarray], fps: int, count: int | None = None
) -> None:
    """uint8 frames [H, W, 3] as a GIF (Pillow) or MP4 (`write_mp4`); `check_video_output`
    first. `frames`: an array [F, H, W, 3], or any iterable of `count` frames (a generator
    rendering them: each is written as it comes, where holding them all took 2-3 times the
    video's frames in memory)."""
    check_video_output(path, fps)
    if path.suffix.lower() == ".gif":
        from PIL import Image

        count = len(frames) if count is None else count

        def write(tmp: Path) -> None:
            # each as Pillow takes it; the first (which checked_frames finds or refuses) saves,
            # into a file of ours, closed whatever stops it (Pillow's own stayed open where a
            # render's Ctrl-C, no Exception, stopped the frames)
            images = (Image.fromarray(frame) for frame in checked_frames(path, frames, count))
            with open(tmp, "wb") as file:
                next(images).save(
                    file,
                    format="GIF",
                    save_all=True,
                    append_images=images,
                    duration=gif_delays_ms(count, fps),
                    loop=0,
                )

        write_atomically(path, write)  # no truncated animation at `path`
    else:
        write_mp4(path, frames, fps, count)
