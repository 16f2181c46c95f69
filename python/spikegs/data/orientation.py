"""Whether spikes match their views' sharp images better upside down: the `flip` of the file
that reads them is likely wrong, and the scene would train upside down (real.py's layouts, whose
flip is in spikegs.json, and meta.json's, whose flip is its own); or with each byte's bits read
in the other order (`other_bit_order`)."""

from __future__ import annotations

import warnings
from collections.abc import Iterable

import numpy as np

from .correlation import correlation
from .crop_offset import warn_if_shifted

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
            f"views): flip is likely wrong (read with flip {flip}; it is set in {settings})",
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


MATCH_MIN = 0.5  # a median correlation of the spikes with their sharp images under this is warned
# of (0.99 for a well-read view; 0.25 to 0.57 for a .dat packed most significant bit first, which
# the other bit order's reading names)


def check_orientation(
    views: Iterable[tuple[np.ndarray, np.ndarray]],
    flip: bool,
    source: str,
    settings: str,
    raw_width: int | None = None,
    col_offset: int = 0,
    judge_match: bool = True,
) -> None:
    """A UserWarning when the views' TFPs [H, W] match their sharp images [H, W, C] better with
    each byte's bits in the other order (`other_bit_order`, where the stored rows are the
    frame's: no `raw_width` other than its width, no `col_offset`), from another first column
    of a camera's wider rows (`warn_if_shifted`), or upside down (`warn_if_upside_down`), than
    as read, by FLIP_MARGIN in most views: the .dat's bit order, `col_offset` or `flip` (stated
    in `settings`) is likely wrong and the scene would train scrambled, shifted or upside down;
    and, where `judge_match`, when they match neither way (median correlation under
    MATCH_MIN): the spikes are not read as the images show them. Flat images (a black view)
    are left out."""
    pairs, reordered = [], []  # per view: (as read, upside down); the other bit order's best
    kept = []  # the views not flat: (TFP, image)
    for tfp, image in views:
        if np.ptp(image) == 0:  # a flat image (black) matches no way up
            continue
        kept.append((tfp, image))
        pairs += orientation_pairs([(tfp, image)])
        if raw_width in (None, tfp.shape[1]) and col_offset == 0:
            (other,) = orientation_pairs([(other_bit_order(tfp, flip), image)])
            reordered.append(max(other))  # the better way up
    better = [other - max(pair) > FLIP_MARGIN for other, pair in zip(reordered, pairs)]
    if better and sum(better) > len(better) / 2:
        warnings.warn(
            f"{source}: the spikes match their views' sharp images better with each byte's bits "
            f"read in the other order (median correlation {np.median(reordered):.2f} against "
            f"{np.median([max(pair) for pair in pairs]):.2f} as read, over {len(pairs)} views): "
            f"the .dat files are likely written most significant bit first (np.packbits' "
            f"default), where the least significant bit comes first (np.packbits(..., "
            f"bitorder='little'))",
            stacklevel=3,
        )
        return
    if raw_width is not None and warn_if_shifted(
        kept, raw_width, col_offset, source, settings, stacklevel=3
    ):
        return
    best = float(np.median([max(pair) for pair in pairs])) if pairs else 1.0
    if best < MATCH_MIN and judge_match:
        warnings.warn(
            f"{source}: the spikes hardly match their views' sharp images (median correlation "
            f"{best:.2f} over {len(pairs)} views, either way up): a .dat written in another bit "
            f"order (least significant bit first expected) or pixel order, the wrong frame size "
            f"(height, width, raw_width, col_offset in {settings}), or images of other views?",
            stacklevel=3,
        )
        return
    warn_if_upside_down(pairs, flip, source, settings, stacklevel=3)
