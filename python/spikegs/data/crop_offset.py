"""Whether spikes read from a camera's wider rows (`raw_width`) match their views' sharp images
better from another first column: `col_offset` is likely wrong, and the scene would train on a
crop beside the images' (a 48x64 `solids` of 72-pixel rows whose image starts 4 columns in,
read from column 0: 20.3 dB trained where 26.9 was due, unsaid)."""

from __future__ import annotations

import collections
import warnings

import numpy as np
from scipy.stats import rankdata

from .correlation import correlation

SHIFT_MARGIN = 0.1  # correlation by which another first column must match better, to warn
# (4 columns off on that `solids`: 0.06-0.24 as read, 0.91-0.96 shifted; the right column's
# neighbours lie 0.06-0.12 under it: the values' correlation; the ranks', 0.34 against 0.79)


def shifted_correlation(tfp: np.ndarray, image: np.ndarray, shift: int) -> float:
    """Correlation of `tfp` [H, W] read `shift` columns further along its stored rows with
    `image` [H, W], over the columns both hold: image[:, j] against tfp[:, j + shift]. Pass
    ranks (`warn_if_shifted`): a hot column, firing every readout, weighs as a bright one."""
    width = tfp.shape[1]
    return correlation(
        tfp[:, max(shift, 0) : width + min(shift, 0)],
        image[:, max(-shift, 0) : width - max(shift, 0)],
    )


def warn_if_shifted(
    views: list[tuple[np.ndarray, np.ndarray]],
    raw_width: int,
    col_offset: int,
    source: str,
    settings: str,
    stacklevel: int,
) -> bool:
    """A UserWarning, and True, when most views' TFPs [H, W] match their sharp images [H, W, C]
    better, by SHIFT_MARGIN, read from another first column of the stored rows of `raw_width`
    pixels (one that `col_offset`, stated in `settings`, can name, leaving half the width or
    more in common) than from `col_offset`, the same one in most."""
    if not views:
        return False
    width = views[0][0].shape[1]
    reach = width // 2
    shifts = range(max(-col_offset, -reach), min(raw_width - width - col_offset, reach) + 1)
    found = []  # per view: (best shift, its correlation, as read)
    for tfp, image in views:  # ranks: a hot edge column, which shifts drop, named one
        tfp, image = rankdata(tfp).reshape(tfp.shape), rankdata(image.mean(-1)).reshape(tfp.shape)
        scores = {s: shifted_correlation(tfp, image, s) for s in shifts}
        best = max(scores, key=scores.get)
        found.append((best, scores[best], scores[0]))
    moved = [s for s, top, kept in found if s != 0 and top - kept > SHIFT_MARGIN]
    shift, count = collections.Counter(moved).most_common(1)[0] if moved else (0, 0)
    if count <= len(found) / 2:  # (shifts that disagree name no one column)
        return False
    top, kept = np.median([(t, k) for s, t, k in found if s == shift], axis=0)
    warnings.warn(
        f"{source}: the spikes match their views' sharp images better read {abs(shift)} "
        f"column{'s' * (abs(shift) != 1)} {'further along' if shift > 0 else 'back'} their "
        f"stored rows (median correlation {top:.2f} against {kept:.2f} as read, over {count} of "
        f"{len(found)} views): col_offset is likely {col_offset + shift}, the first stored "
        f"column of the image (read with col_offset {col_offset}; it is set in {settings})",
        stacklevel=stacklevel + 1,
    )
    return True
