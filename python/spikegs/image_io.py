"""Image files through OpenImageIO: float [H, W, C] arrays in and out (EXR exact, PNG 8-bit)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import OpenImageIO as oiio


def write_image(path: str | Path, image: np.ndarray) -> None:
    """Write float `image` [H, W] or [H, W, C]; PNG/JPEG are clipped to [0, 1] and quantised."""
    image = np.asarray(image, dtype=np.float32)
    if image.ndim == 2:
        image = image[..., None]  # OpenImageIO needs (H, W, 1) for one channel
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    spec = oiio.ImageSpec(image.shape[1], image.shape[0], image.shape[2], oiio.FLOAT)
    if path.suffix.lower() in (".png", ".jpg", ".jpeg"):
        image = np.clip(image, 0.0, 1.0)
        spec.set_format(oiio.UINT8)
    out = oiio.ImageOutput.create(str(path))
    if out is None or not out.open(str(path), spec):
        raise OSError(f"cannot write {path}: {oiio.geterror()}")
    ok = out.write_image(np.ascontiguousarray(image))
    out.close()
    if not ok:
        raise OSError(f"cannot write {path}: {out.geterror()}")


def read_image(path: str | Path, unassociated_alpha: bool = False) -> np.ndarray:
    """Read an image as float32 [H, W, C] (8-bit files scaled to [0, 1]); FileNotFoundError when
    there is no such file, ValueError when there is one that is not a readable image.

    OpenImageIO premultiplies colour by an alpha that a file stores unassociated (PNG);
    `unassociated_alpha` keeps the file's colour as it is."""
    config = oiio.ImageSpec()
    config.attribute("oiio:UnassociatedAlpha", int(unassociated_alpha))
    inp = oiio.ImageInput.open(str(path), config)
    if inp is None:
        missing = not Path(path).is_file()
        raise (FileNotFoundError if missing else ValueError)(
            f"cannot read {path}: {oiio.geterror()}"
        )
    try:
        image = inp.read_image(oiio.FLOAT)
    finally:
        inp.close()
    if image is None:
        raise ValueError(f"cannot read {path}: {oiio.geterror()}")
    return np.asarray(image, dtype=np.float32).reshape(inp.spec().height, inp.spec().width, -1)
