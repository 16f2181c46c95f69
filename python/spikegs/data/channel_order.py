"""Whether a colour dataset's channel files match their sharp images' channels as named: one
file stored upside down beside the others, or the files in another order (a Bayer mosaic split
with its red and blue swapped). Both trained 3 to 7 dB low unsaid (a 48x48 colour `solids`:
17.9 dB swapped, 21.4 with blue upside down, 24.8 right): the channels' mean, which
`check_orientation` judges, hid them."""

from __future__ import annotations

import warnings

import numpy as np

from .correlation import correlation
from .orientation import FLIP_MARGIN


def channel_correlations(tfps: list[np.ndarray], image: np.ndarray) -> np.ndarray:
    """[C, C + 1]: row c, image channel c's correlation with each file's TFP [H, W] as read
    (columns 0..C-1) and with its own file's upside down (column C)."""
    rows = []
    for c in range(image.shape[-1]):
        channel = image[..., c]
        rows.append([correlation(t, channel) for t in tfps] + [correlation(tfps[c][::-1], channel)])
    return np.array(rows)


def check_channels(
    views: list[tuple[list[np.ndarray], np.ndarray]], files: list[str], settings: str
) -> None:
    """UserWarnings where, in most `views` (each: the channels' TFPs [C] of [H, W] and a sharp
    image [H, W, C], not flat), an image channel matches another file's spikes, or its own file's
    upside down, better than its own file's as read, by FLIP_MARGIN: `files` [C], named in
    `settings`, are likely in another order, or such a file stored the other way up (unless all
    are: the dataset's `flip`, which `check_orientation` names)."""
    scores = [channel_correlations(tfps, image) for tfps, image in views if np.ptp(image) > 0]
    if not scores:
        return
    scores = np.array(scores)  # [V, C, C + 1]
    channels = len(files)
    own = scores[:, np.arange(channels), np.arange(channels)]  # [V, C]
    others, upside = [], []  # (channel, the file it matches better); channels better flipped
    for c in range(channels):
        best = int(np.bincount(scores[:, c].argmax(-1), minlength=channels + 1).argmax())
        ahead = scores[:, c, best] - own[:, c] > FLIP_MARGIN  # [V]
        if best != c and ahead.sum() > len(scores) / 2:
            (upside if best == channels else others).append((c, best))
    if others:
        said = "; ".join(
            f"channel {c}'s images match {files[s]} (median correlation "
            f"{np.median(scores[:, c, s]):.2f}) better than {files[c]} "
            f"({np.median(own[:, c]):.2f})"
            for c, s in others
        )
        warnings.warn(
            f"{settings}: over {len(scores)} views, {said}: spike_files are likely in another "
            f"order than the images' channels (R, G, B; a colour filter mosaic split with its "
            f"pattern read wrong?)",
            stacklevel=3,
        )
    if upside and len(upside) < channels:
        flipped = [c for c, _ in upside]
        names = ", ".join(files[c] for c in flipped)
        warnings.warn(
            f"{settings}: over {len(scores)} views, the spikes of {names} match their channel "
            f"of the images better upside down (median correlation "
            f"{np.median(scores[:, flipped, channels]):.2f} against "
            f"{np.median(own[:, flipped]):.2f} as read), the other files' as read: "
            f"{'they are' if len(flipped) > 1 else 'it is'} likely stored the other way up "
            f"(rows top-down where flip says bottom-up, or the reverse)",
            stacklevel=3,
        )
