"""Whether spikes match their views' sharp images better upside down: the `flip` of the file
that reads them is likely wrong, and the scene would train upside down (real.py's layouts, whose
flip is in spikegs.json, and meta.json's, whose flip is its own); or with each byte's bits read
in the other order (`other_bit_order`)."""

from __future__ import annotations

import warnings
from collections.abc import Iterable

import numpy as np

from .correlation import correlation

FLIP_MARGIN = 0.2  # correlation by which the other orientation must match better, to warn


def orientation_pairs(views: Iterable[tuple[np.ndarray, np.ndarray]]) -> list[tuple[float, float]]:
    """(correlation as read, upside down) of each view's TFP [H, W] with its sharp image [H, W, C]
    (its channels' mean)."""
    return [
        (correlation(tfp, image.mean(-1)), correlation(tfp, image.mean(-1)[::-1]))
        for tfp, image in views
    ]


def warn_if_upside_down(
    pairs: list[tuple[float, float]], flip: bool, source: str, settings: str, stacklevel: int
) -> None:
    """A UserWarning when most views' `pairs` (`orientation_pairs`) match better upside down, by
    FLIP_MARGIN: `flip`, stated in `settings`, is likely wrong."""
    better = [flipped - kept > FLIP_MARGIN for kept, flipped in pairs]
    if pairs and sum(better) > len(pairs) / 2:
        kept, flipped = np.median(np.asarray(pairs), axis=0)
        warnings.warn(
            f"{source}: the spikes match their views' sharp images better upside down (median "
            f"correlation {flipped:.2f} flipped against {kept:.2f} as read, over {len(pairs)} "
            f"views): flip ({flip}, in {settings}) is likely wrong",
            stacklevel=stacklevel + 1,
        )


def other_bit_order(image: np.ndarray, flip: bool) -> np.ndarray:
    """`image` [H, W], per-pixel figures of a .dat read least significant bit first (TFP, spike
    counts), as read most significant bit first: each byte's 8 pixels, in the file's order (rows
    bottom-up where `flip`), in reverse; a frame's last byte, where H·W leaves it partial, as it
    is. For frames of `width` pixels a stored row (no raw_width, col_offset)."""
    stored = (image[::-1] if flip else image).ravel()
    whole = np.arange(stored.size // 8 * 8)
    reordered = stored.copy()
    reordered[whole] = stored[whole - whole % 8 + 7 - whole % 8]
    reordered = reordered.reshape(image.shape)
    return reordered[::-1] if flip else reordered
