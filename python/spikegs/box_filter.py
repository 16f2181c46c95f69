"""A camera pixel's box filter: each pixel the mean of the m×m pixels of a render m times as large
(the built-in scenes' `--spp`, `spikegs render --scale` under 1)."""

from __future__ import annotations

import numpy as np


def block_means(image: np.ndarray, m: int) -> np.ndarray:
    """The mean of each m×m block of `image` [m·h, m·w, C] (float32): [h, w, C] float32; `image`
    itself where m is 1."""
    if m == 1:
        return image
    height, width, channels = image.shape
    return image.reshape(height // m, m, width // m, m, channels).mean(
        axis=(1, 3), dtype=np.float32
    )
