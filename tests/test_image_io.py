"""image_io.py: the colour conversions of linear light, a file's stored channels, and writes
that fail."""

import os

import numpy as np
import pytest
from spikegs.image_io import (
    linear_to_srgb,
    read_image,
    read_stored_image,
    srgb_to_linear,
    to_channels,
    write_image,
)


def test_srgb_decoding_matches_the_standards_values_on_each_side_of_its_knee():
    """IEC 61966-2-1's published values: 8-bit 10 on the linear segment, 11 (just above the knee
    at 0.04045) on the power curve, 128; encoding undoes decoding everywhere."""
    values = np.array([0, 10, 11, 128, 255]) / 255
    expected = [0.0, 0.0030353, 0.0033465, 0.2158605, 1.0]
    np.testing.assert_allclose(srgb_to_linear(values), expected, rtol=2e-5)
    grid = np.linspace(0.0, 1.0, 2001)
    np.testing.assert_allclose(linear_to_srgb(srgb_to_linear(grid)), grid, atol=1e-7)


def test_srgb_encoding_clips_light_outside_zero_to_one():
    """A highlight above 1 is shown white, a negative value black: never beyond either."""
    encoded = linear_to_srgb(np.array([-0.5, 0.0, 1.0, 1.5, 40.0]))
    np.testing.assert_allclose(encoded, [0, 0, 1, 1, 1], atol=1e-12)  # 1.055 - 0.055: 1 - 1e-16


def test_mono_is_rec709_luma_and_colour_is_unchanged():
    rgb = np.array([[0.3, 0.3, 0.3], [1, 0, 0], [0, 1, 0], [0, 0, 1]])  # [4, 3]
    np.testing.assert_allclose(to_channels(rgb, 1)[:, 0], [0.3, 0.2126, 0.7152, 0.0722])
    assert to_channels(rgb, 3) is rgb
    with pytest.raises(ValueError, match=r"channels expected 1 \(mono\) or 3 \(colour\), found 2"):
        to_channels(rgb, 2)


def _write_exr(path, names: tuple[str, ...]) -> None:
    """A 2x2 float EXR whose channel `names` hold 0.1, 0.2, ... in order; A, where named, is
    alpha."""
    import OpenImageIO as oiio

    spec = oiio.ImageSpec(2, 2, len(names), oiio.FLOAT)
    spec.channelnames = names
    spec.alpha_channel = names.index("A") if "A" in names else -1
    values = np.arange(1, len(names) + 1, dtype=np.float32) / 10
    out = oiio.ImageOutput.create(str(path))
    assert out.open(str(path), spec)
    out.write_image(np.ascontiguousarray(np.broadcast_to(values, (2, 2, len(names)))))
    out.close()


@pytest.mark.parametrize(
    ("names", "colour", "alpha"),
    [
        (("R", "G", "B", "A", "Z"), [0.1, 0.2, 0.3], [0.4]),  # a depth after alpha: neither
        (("Y", "A", "Z"), [0.1], [0.2]),
        (("Y", "Z"), [0.1], None),  # grey and a channel not called alpha: grey alone
    ],
)
def test_colour_is_three_channels_or_one_and_alpha_one(tmp_path, names, colour, alpha):
    _write_exr(tmp_path / "v.exr", names)
    stored = read_stored_image(tmp_path / "v.exr")
    np.testing.assert_allclose(stored.colour, np.broadcast_to(colour, (2, 2, len(colour))))
    if alpha is None:
        assert stored.alpha is None
    else:
        np.testing.assert_allclose(stored.alpha, np.full((2, 2, 1), alpha))


def test_an_image_of_alpha_alone_is_refused_as_a_mask(tmp_path):
    """An EXR whose one channel is A (a matte): OpenImageIO's alpha index is 0 there; its colour
    was an empty channel axis that broadcast obscurely downstream."""
    _write_exr(tmp_path / "matte.exr", ("A",))
    with pytest.raises(ValueError, match="matte.exr: no colour channel, alpha alone: a mask"):
        read_stored_image(tmp_path / "matte.exr")


class _FullDisk:
    """An OpenImageIO writer whose `step` ("write_image" or "close") fails as on a full disk,
    saying so through its geterror."""

    def __init__(self, out, step: str):
        self._out, self._step = out, step

    def __getattr__(self, name):
        return getattr(self._out, name)

    def write_image(self, pixels):
        return self._out.write_image(pixels) and self._step != "write_image"

    def close(self):
        return self._out.close() and self._step != "close"

    def geterror(self):
        return "No space left on device"


class _SilentlyTorn:
    """OpenImageIO's writer on a full disk as PNG's behaved: every call says it succeeded, and
    the file holds `kept` of its bytes."""

    def __init__(self, out, kept: float):
        self._out, self._kept, self._name = out, kept, None

    def open(self, name, spec):
        self._name = name
        return self._out.open(name, spec)

    def write_image(self, pixels):
        return self._out.write_image(pixels)

    def close(self):
        self._out.close()
        with open(self._name, "r+b") as file:
            file.truncate(int(self._kept * os.path.getsize(self._name)))
        return True


@pytest.mark.parametrize(
    ("failing", "reason"),
    [
        (lambda out: _FullDisk(out, "write_image"), "No space left on device"),
        (lambda out: _FullDisk(out, "close"), "No space left on device"),
        (lambda out: _SilentlyTorn(out, 0.0), "what was written reads back torn or empty"),
        (lambda out: _SilentlyTorn(out, 0.5), "what was written reads back torn or empty"),
    ],
    ids=["write fails", "close fails", "all said written, empty", "all said written, torn"],
)
def test_an_image_not_written_names_it_and_keeps_the_one_before(
    tmp_path, monkeypatch, failing, reason
):
    """OpenImageIO's writer failing (a full disk: writing or closing the file), or saying it
    succeeded over a file it left empty (one OpenImageIO cannot open) or torn (it opens, its
    pixels do not read): an OSError naming the image asked for, with the reason; the image
    written before stays and no temporary is left."""
    import OpenImageIO as oiio

    grey = np.full((16, 16, 3), 0.25, np.float32)
    path = tmp_path / "v.exr"
    write_image(path, grey)
    create = oiio.ImageOutput.create
    monkeypatch.setattr(oiio.ImageOutput, "create", lambda name: failing(create(name)))
    with pytest.raises(OSError, match=rf"cannot write .*v\.exr: {reason}"):
        write_image(path, 2 * grey)
    monkeypatch.undo()
    assert os.listdir(tmp_path) == ["v.exr"]
    np.testing.assert_array_equal(read_image(path), grey)


def test_an_image_of_no_known_format_is_refused_by_name(tmp_path):
    with pytest.raises(OSError, match=r"cannot write .*v\.xyz: OpenImageIO could not find a"):
        write_image(tmp_path / "v.xyz", np.zeros((2, 2, 3), np.float32))
    assert os.listdir(tmp_path) == []
