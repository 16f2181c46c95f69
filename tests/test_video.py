"""Videos (video.py): the frame-rate bounds of a GIF and the codec an .mp4 prefers."""

import pytest
from spikegs import video
from spikegs.video import GIF_MAX_FPS, check_video_output, gif_delays_ms


def test_a_gif_takes_up_to_50_fps(tmp_path):
    """50 fps (a delay of 2 hundredths, which viewers play as written) is a GIF's most; 51 is
    refused, naming .mp4."""
    assert GIF_MAX_FPS == 50
    check_video_output(tmp_path / "a.gif", 50)
    assert gif_delays_ms(3, 50) == [20, 20, 20]
    with pytest.raises(ValueError, match="--fps 51: a GIF holds at most 50"):
        check_video_output(tmp_path / "a.gif", 51)


def test_mp4_prefers_h264_and_falls_back_to_mpeg4(monkeypatch, tmp_path):
    """H.264 where PyAV's FFmpeg has it (smaller and sharper), MPEG-4 part 2 only without."""
    monkeypatch.setattr(video, "can_encode", lambda codec: True)
    assert video.mp4_codec() == "libx264"
    monkeypatch.setattr(video, "can_encode", lambda codec: codec == "mpeg4")
    assert video.mp4_codec() == "mpeg4"
    monkeypatch.setattr(video, "can_encode", lambda codec: False)
    with pytest.raises(ValueError, match="none of the encoders libx264, mpeg4"):
        check_video_output(tmp_path / "v.mp4", 20)
