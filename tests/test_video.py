"""Videos (video.py): the frame-rate bounds of a GIF, the codec an .mp4 prefers, and frames
written as they come."""

import gc
import warnings

import numpy as np
import pytest
from spikegs import video
from spikegs.video import GIF_MAX_FPS, check_video_output, gif_delays_ms, write_video


def test_a_gif_takes_up_to_50_fps(tmp_path):
    """50 fps (a delay of 2 hundredths, which viewers play as written) is a GIF's most; 51 is
    refused, naming .mp4."""
    assert GIF_MAX_FPS == 50
    check_video_output(tmp_path / "a.gif", 50)
    assert gif_delays_ms(3, 50) == [20, 20, 20]
    with pytest.raises(ValueError, match="--fps 51: a GIF holds at most 50"):
        check_video_output(tmp_path / "a.gif", 51)


def test_a_video_takes_1_to_1000_fps(tmp_path):
    """Each end of the frame rate's range is a video's; 0 and 1001 are refused."""
    for name, fps in (("a.gif", 1), ("a.mp4", 1), ("a.mp4", 1000)):
        check_video_output(tmp_path / name, fps)
    for fps in (0, 1001):
        with pytest.raises(ValueError, match=f"--fps: expected 1 to 1000, got {fps}"):
            check_video_output(tmp_path / "a.mp4", fps)


def test_a_gif_loops_and_an_mp4_states_its_colours(tmp_path):
    """An orbit's GIF plays on a loop (Netscape's loop count 0: forever); an .mp4 states what
    swscale's conversion made, so that players do not guess: the BT.601 (SMPTE 170M, 6) matrix,
    limited range (1), and the frames' sRGB primaries (BT.709's, 1: SMPTE 170M's were stated, the
    eval trial) and transfer (13). MPEG-4 takes no x264 options."""
    import av
    from PIL import Image

    frames = gradient_noise()[:3]
    write_video(tmp_path / "v.gif", frames, 20)
    with Image.open(tmp_path / "v.gif") as gif:
        assert gif.info["loop"] == 0 and gif.n_frames == 3
    write_video(tmp_path / "v.mp4", frames, 20)
    with av.open(str(tmp_path / "v.mp4")) as container:
        context = container.streams.video[0].codec_context
        tags = context.colorspace, context.color_primaries, context.color_trc
        assert (*tags, context.color_range) == (6, 1, 13, 1)
    assert video.mp4_options("mpeg4") == video.MP4_QUALITY["mpeg4"]


def test_mp4_prefers_h264_and_falls_back_to_mpeg4(monkeypatch, tmp_path):
    """H.264 where PyAV's FFmpeg has it (smaller and sharper), MPEG-4 part 2 only without."""
    monkeypatch.setattr(video, "can_encode", lambda codec: True)
    assert video.mp4_codec() == "libx264"
    monkeypatch.setattr(video, "can_encode", lambda codec: codec == "mpeg4")
    assert video.mp4_codec() == "mpeg4"
    monkeypatch.setattr(video, "can_encode", lambda codec: False)
    with pytest.raises(ValueError, match="none of the encoders libx264, mpeg4"):
        check_video_output(tmp_path / "v.mp4", 20)


@pytest.mark.parametrize("error", [RuntimeError("render failed"), KeyboardInterrupt()])
@pytest.mark.parametrize("name", ["orbit.mp4", "orbit.gif"])
def test_frames_that_stop_coming_leave_the_previous_video(tmp_path, name, error):
    """`spikegs render` encodes each frame as it is rendered, inside the video's atomic write: a
    render that fails (or a Ctrl-C) after two frames raises its own error, and leaves the previous
    video whole, no temporary file and no file open (an error of any kind, not only a write's
    OSError)."""
    path = tmp_path / name
    path.write_bytes(b"previous")

    def frames():
        yield from np.zeros((2, 16, 16, 3), np.uint8)
        raise type(error)(*error.args)  # (the parameter's own would keep its traceback)

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with pytest.raises(type(error)):
            write_video(path, frames(), 10, count=3)
        gc.collect()  # (a file left open says so once collected: Pillow's GIF, on a Ctrl-C)
    assert path.read_bytes() == b"previous" and sorted(tmp_path.iterdir()) == [path]
    assert not [w for w in caught if w.category is ResourceWarning], [str(w) for w in caught]


@pytest.mark.parametrize("name", ["orbit.mp4", "orbit.gif"])
def test_a_video_of_no_frames_is_refused(tmp_path, name):
    """No frames: a ValueError naming the video, and no file (the encoder had no stream to flush,
    the GIF no first image)."""
    with pytest.raises(ValueError, match=f"{name}: no frames to write"):
        write_video(tmp_path / name, iter([]), 10, count=0)
    assert not list(tmp_path.iterdir())


def gradient_noise() -> np.ndarray:
    """24 frames [24, 34, 48, 3] uint8 of a gradient's noise: x264's files of them differed."""
    light = np.cumsum(np.random.default_rng(0).random((24, 34, 48, 3)), axis=1)
    return (light / light.max() * 255).astype(np.uint8)


@pytest.mark.parametrize("name", ["orbit.mp4", "orbit.gif"])
def test_frames_unlike_the_first_or_the_count_are_refused(tmp_path, name):
    """A frame of another size (an .mp4's encoder rescaled it unsaid), of floats or one channel,
    or frames other than the count stated (a GIF's delays are counted first: Pillow's IndexError):
    a ValueError naming the video and the frame, and no file."""
    path = tmp_path / name
    frame = np.zeros((16, 16, 3), np.uint8)
    cases = [
        ([frame, np.zeros((16, 18, 3), np.uint8)], None, "frame 2 is 16x18, the first 16x16"),
        (
            [frame, frame.astype(np.float32)],
            None,
            r"frame 2: expected uint8 \[H, W, 3\], got float32",
        ),
        ([frame[..., :1]], None, r"frame 1: expected uint8 \[H, W, 3\], got uint8 \[16, 16, 1\]"),
        ([frame] * 3, 2, "more frames than the 2 stated"),
        ([frame] * 2, 3, "2 frames, 3 stated"),
    ]
    for frames, count, said in cases:
        with pytest.raises(ValueError, match=f"{name}: {said}"):
            write_video(path, iter(frames), 10, count=count if count else len(frames))
        assert not list(tmp_path.iterdir())


def test_an_mp4_is_x264s_avx2_codes_file(tmp_path, monkeypatch):
    """x264's AVX-512 code read heap memory it never wrote (the same frames made 6 files in 20
    encodes after other allocations; this file's next test failed once in CI), its AVX2 code
    did not: an .mp4 is the AVX2 code's file, on a CPU with AVX-512 as on one with AVX2 alone
    (where x264 chooses that code itself). These frames' file from the AVX-512 code differs."""
    from spikegs import _C

    if not video.can_encode("libx264") or not _C.cpu_features.get("avx2", False):
        pytest.skip("no libx264 encoder in this PyAV's FFmpeg, or no AVX2 on this CPU")
    frames = gradient_noise()
    write_video(tmp_path / "v.mp4", frames, 20)
    avx2 = {**video.MP4_QUALITY["libx264"], "x264-params": "asm=AVX2"}
    monkeypatch.setattr(video, "mp4_options", lambda codec: avx2)
    write_video(tmp_path / "avx2.mp4", frames, 20)
    assert (tmp_path / "v.mp4").read_bytes() == (tmp_path / "avx2.mp4").read_bytes()


def test_an_mp4_is_the_same_file_whatever_runs_between_its_frames(tmp_path):
    """`spikegs render` renders each frame between two encodes; with B-frames, libx264 read stack
    memory it never wrote, and the same frames made another file where other work ran between
    them (3 files of 5 renders of one orbit). The same frames: one file, work between or not."""
    frames = gradient_noise()

    def rendered(seed: int):
        """`frames`, some of numpy's and LAPACK's work done before each, as a render's."""
        work = np.random.default_rng(seed)
        for frame in frames:
            np.linalg.svd(work.random((60, 60)))
            [work.integers(0, 255, work.integers(1000, 100000), np.uint8) for _ in range(10)]
            yield frame

    write_video(tmp_path / "alone.mp4", frames, 20)
    for seed in (1, 2):
        write_video(tmp_path / "rendered.mp4", rendered(seed), 20)
        assert (tmp_path / "rendered.mp4").read_bytes() == (tmp_path / "alone.mp4").read_bytes()
