"""Image files through OpenImageIO: float [H, W, C] arrays in and out (EXR exact, PNG 8-bit); the
colour conversions of linear light (sRGB, Rec. 709 luma)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import OpenImageIO as oiio

from .atomic_save import staged_write, write_atomically
from .number_checks import non_finite_pixels
from .output_paths import utf8_name


def srgb_to_linear(c: np.ndarray) -> np.ndarray:
    """Decode sRGB values in [0, 1] to linear light."""
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(c: np.ndarray) -> np.ndarray:
    """Encode linear light in [0, 1] (clipped) as sRGB values in [0, 1]."""
    c = np.clip(c, 0.0, 1.0)
    return np.where(c <= 0.0031308, 12.92 * c, 1.055 * c ** (1 / 2.4) - 0.055)


LUMA_709 = np.array([0.2126, 0.7152, 0.0722])


def to_channels(rgb: np.ndarray, channels: int) -> np.ndarray:
    """Linear RGB [..., 3] -> [..., channels]: Rec. 709 luma for 1, unchanged for 3."""
    if channels == 3:
        return rgb
    if channels == 1:
        return rgb @ LUMA_709[:, None]
    raise ValueError(f"channels expected 1 (mono) or 3 (colour), found {channels}")


def _reason(error: str) -> str:
    """OpenImageIO's error message, which some failures leave empty (a truncated file, a folder
    that cannot be written); libpng prints its own line to stderr then, which the words allow."""
    return error.strip() or (
        "OpenImageIO returned no reason (a truncated file, or no permission? its image library "
        "may have printed one above)"
    )


def _name(path: str | Path) -> str:
    """`path` as OpenImageIO takes it; ValueError naming it where it is not UTF-8 (a Latin-1
    folder's name, read through os.fsdecode's surrogate escapes: the binding raised TypeError)."""
    name = utf8_name(path)
    if name is None:
        raise ValueError(
            f"{path}: not a UTF-8 file name, which OpenImageIO cannot open; rename it (or its "
            f"folder)"
        )
    return name


def write_image(path: str | Path, image: np.ndarray) -> None:
    """Write linear float `image` [H, W] or [H, W, C]: EXR/TIFF as they are; PNG/JPEG, which
    OpenImageIO tags as sRGB, sRGB-encoded (clipped to [0, 1]) and quantised to 8 bits, so that
    viewers show the intensities and `read_frame` decodes them back."""
    write_atomically(Path(path), _image_writer(Path(path), image))  # a kill keeps the previous


def stage_image(path: str | Path, image: np.ndarray) -> tuple[Path, Path]:
    """`write_image` but for the last rename: (the temporary file written, `path` or its link's
    target), for the caller to rename onto it (`atomic_save.staged_write`)."""
    return staged_write(Path(path), _image_writer(Path(path), image))


def _image_writer(path: Path, image: np.ndarray) -> Callable[[Path], None]:
    """A function writing `image` to a temporary file, in `path`'s format (`write_image`)."""
    image = np.asarray(image, dtype=np.float32)
    if image.ndim == 2:
        image = image[..., None]  # OpenImageIO needs (H, W, 1) for one channel
    spec = oiio.ImageSpec(image.shape[1], image.shape[0], image.shape[2], oiio.FLOAT)
    if path.suffix.lower() in (".png", ".jpg", ".jpeg"):
        image = linear_to_srgb(image).astype(np.float32)
        spec.set_format(oiio.UINT8)

    def write(tmp: Path) -> None:  # the format is `path`'s: the temporary name has no suffix
        out = oiio.ImageOutput.create(_name(path))
        if out is None or not out.open(_name(tmp), spec):
            raise OSError(f"cannot write {path}: {_reason(oiio.geterror())}")
        try:
            ok = out.write_image(np.ascontiguousarray(image))
        finally:
            closed = out.close()
        if not (ok and closed):
            raise OSError(f"cannot write {path}: {_reason(out.geterror())}")
        # on a full disk PNG's writer returned True from every call (an empty temporary then
        # replaced the image; its has_error, set there, is also set by a TIFF's harmless Exif
        # notice): what was written must read back whole
        check = oiio.ImageInput.open(_name(tmp))
        whole = check is not None and check.read_image() is not None
        if check is not None:
            check.close()
        if not whole:
            oiio.geterror()  # taken: OpenImageIO prints errors left unread when the process ends
            raise OSError(
                f"cannot write {path}: what was written reads back torn or empty (a full disk, or "
                f"a quota reached?)"
            )

    return write


@dataclass(frozen=True)
class StoredImage:
    """An image's colour and alpha as its file stores them, with how to read the colour."""

    colour: np.ndarray  # [H, W, 1 or 3] float32, grey or RGB (8/16-bit files scaled to [0, 1])
    alpha: np.ndarray | None  # [H, W, 1], or None where the file has no alpha channel
    premultiplied: bool  # colour associated with alpha (EXR, TIFF's associated alpha)
    srgb: bool  # colour sRGB-encoded (8/16-bit files), not linear (half/float files)


def _read(path: str | Path, unassociated_alpha: bool) -> tuple[np.ndarray, oiio.ImageSpec]:
    """Pixels [H, W, C] float32 and spec of an image file; see `read_image` for the errors."""
    config = oiio.ImageSpec()
    config.attribute("oiio:UnassociatedAlpha", int(unassociated_alpha))
    inp = oiio.ImageInput.open(_name(path), config)
    if inp is None:
        missing = not Path(path).is_file()
        raise (FileNotFoundError if missing else ValueError)(
            f"cannot read {path}: {_reason(oiio.geterror())}"
        )
    try:
        image = inp.read_image(oiio.FLOAT)
    finally:
        inp.close()
    if image is None:
        raise ValueError(f"cannot read {path}: {_reason(oiio.geterror())}")
    spec = inp.spec()
    return np.asarray(image, dtype=np.float32).reshape(spec.height, spec.width, -1), spec


def read_image(path: str | Path) -> np.ndarray:
    """Read an image as float32 [H, W, C] (8-bit files scaled to [0, 1]); FileNotFoundError when
    there is no such file, ValueError when there is one that is not a readable image."""
    return _read(path, unassociated_alpha=False)[0]


def read_stored_image(path: str | Path) -> StoredImage:
    """Read an image's colour as its file stores it: OpenImageIO would premultiply colour by an
    alpha that the file keeps unassociated (PNG, TIFF's unassociated alpha), in sRGB units.
    The file's metadata, not its extension, says which channel is alpha (an unspecified extra
    channel is not), whether colour is premultiplied, and whether it is sRGB (errors as
    `read_image`); ValueError where a value is not finite (a renderer's NaN firefly in an EXR
    made every score NaN) and where it holds alpha alone (a mask)."""
    pixels, spec = _read(path, unassociated_alpha=True)
    space = spec.get_string_attribute("oiio:ColorSpace").lower()
    floating = spec.format.basetype in (oiio.HALF, oiio.FLOAT, oiio.DOUBLE)
    srgb = "lin" not in space and ("srgb" in space or not floating)
    unassociated = spec.get_int_attribute("oiio:UnassociatedAlpha", 0) == 1
    a = spec.alpha_channel
    alpha = pixels[..., a : a + 1] if a >= 0 else None
    others = np.delete(pixels, a, axis=2) if a >= 0 else pixels  # [H, W, C - 1 or C]
    if others.shape[2] == 0:  # alpha alone (an EXR matte): no colour to composite or score
        raise ValueError(f"{path}: no colour channel, alpha alone: a mask, not a picture")
    colour = others[..., : 3 if others.shape[2] >= 3 else 1]
    for name, values in (("colour", colour), ("alpha", alpha)):  # a depth channel may be inf
        found = None if values is None else non_finite_pixels(values)
        if found is not None:
            count, (y, x, c) = found
            raise ValueError(
                f"{path}: {count} pixel(s) of {name} not finite, the first {values[y, x, c]} at "
                f"row {y}, column {x}: fix the image"
            )
    return StoredImage(colour, alpha, premultiplied=not unassociated, srgb=srgb)
