"""Text drawn into images (Pillow's default font, white on black, in linear light): the titles
over the panels of a side-by-side, the labels beside its rows."""

from __future__ import annotations

import numpy as np

TITLE_HEIGHT = 16  # pixels of a header of titles at scale 1


def title_scale(height: int) -> int:
    """The scale of the titles over panels `height` pixels high: 1 up to 511, one more for each
    256 pixels (Pillow's default font, 11 pixels high, is 1 % of a 1080p panel)."""
    return max(1, height // 256)


def column_titles(titles: list[str], width: int, scale: int = 1) -> np.ndarray:
    """A header [TITLE_HEIGHT * scale, len(titles) * width, 1] of white titles on black, each
    centred over its column of `width` pixels, `scale` times the default font's size, or, where
    that is wider than the column less two pixels either side, shrunk to fit it (cut, they ran
    together: "FP pseudo trutnder, 23.46 d" over 64-pixel panels), in linear light."""
    from PIL import Image, ImageDraw

    from .image_io import srgb_to_linear

    columns, small = [], max(1, round(width / scale))  # a column's width at the font's size
    for title in titles:
        left, top, right, bottom = ImageDraw.Draw(Image.new("L", (1, 1))).textbbox((0, 0), title)
        wide = right - left + 4 > small  # wider than its column less two pixels either side
        room = right - left + 2 if wide else small  # (a pixel either side for its antialiasing)
        column = Image.new("L", (room, TITLE_HEIGHT))
        draw = ImageDraw.Draw(column)
        draw.text(((room - right - left) / 2, (TITLE_HEIGHT - bottom - top) / 2), title, fill=255)
        if wide:  # shrunk within those pixels, centred in the header's height
            fit = max(1, small - 4)
            rows = max(1, round(TITLE_HEIGHT * fit / room))
            shrunk = column.resize((fit, rows), Image.Resampling.LANCZOS)
            column = Image.new("L", (small, TITLE_HEIGHT))
            column.paste(shrunk, (2, (TITLE_HEIGHT - rows) // 2))
        column = column.resize((width, TITLE_HEIGHT * scale), Image.Resampling.BILINEAR)
        columns.append(np.asarray(column, np.float64) / 255)  # sRGB values, antialiased
    return srgb_to_linear(np.concatenate(columns, axis=1))[..., None]


def row_labels(lines: list[str], width: int, height: int) -> np.ndarray:
    """A label [height, width, 1] of white `lines` on black, left-aligned from the top (cut to
    it), in linear light."""
    from PIL import Image, ImageDraw

    from .image_io import srgb_to_linear

    label = Image.new("L", (width, height))
    ImageDraw.Draw(label).multiline_text((3, 2), "\n".join(lines), fill=255, spacing=2)
    return srgb_to_linear(np.asarray(label, np.float64) / 255)[..., None]
