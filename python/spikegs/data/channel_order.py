"""Whether a colour dataset's channel files match their sharp images' channels as named: one
file stored upside down beside the others, or the files in another order (a Bayer mosaic split
with its red and blue swapped). Both trained 3 to 7 dB low unsaid (a 48x48 colour `solids`:
17.9 dB swapped, 21.4 with blue upside down, 24.8 right): the channels' mean, which
`check_orientation` judges, hid them."""

from __future__ import annotations

import itertools
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
    image [H, W, C], not flat), the image's channels match `files` [C] (named in `settings`)
    in another order, each channel it moves better by FLIP_MARGIN than its own file (the files
    likely listed in another order), or some files' spikes (not all: the dataset's `flip`,
    which `check_orientation` names) match their channel better upside down, by FLIP_MARGIN
    (stored the other way up), or files hold another channel than their own, the order aside
    (`_warn_of_files_holding_another_channel`). Orders, not channels alone: a dim channel
    matches a brighter file better than its own noisy one (blue at 30 % of red) where no other
    order fits."""
    scores = [channel_correlations(tfps, image) for tfps, image in views if np.ptp(image) > 0]
    if not scores:
        return
    scores = np.array(scores)  # [V, C, C + 1]
    channels = len(files)
    own = scores[:, np.arange(channels), np.arange(channels)]  # [V, C]
    best, gain = None, 0.0  # the other order most views fit in every channel it moves
    for order in itertools.permutations(range(channels)):
        moved = [c for c in range(channels) if order[c] != c]
        if not moved:
            continue
        ahead = scores[:, moved, [order[c] for c in moved]] - own[:, moved]  # [V, M]
        fits = (ahead > FLIP_MARGIN).all(axis=1)  # [V]
        if fits.sum() > len(scores) / 2 and np.median(ahead.sum(axis=1)) > gain:
            best, gain = order, float(np.median(ahead.sum(axis=1)))
    if best is not None:
        said = "; ".join(
            f"channel {c}'s images match {files[best[c]]} (median correlation "
            f"{np.median(scores[:, c, best[c]]):.2f}) better than {files[c]} "
            f"({np.median(own[:, c]):.2f})"
            for c in range(channels)
            if best[c] != c
        )
        warnings.warn(
            f"{settings}: over {len(scores)} views, {said}: spike_files are likely in another "
            f"order than the images' channels (R, G, B; a colour filter mosaic split with its "
            f"pattern read wrong?)",
            stacklevel=3,
        )
    named = {best[c] for c in range(channels) if best[c] != c} if best is not None else set()
    named |= _warn_of_files_holding_another_channel(scores, files, settings, named)
    flipped = scores[:, :, channels] - own > FLIP_MARGIN  # [V, C]
    # a file that matches its channel upside down, by FLIP_MARGIN at least (not merely less
    # unlike it: a file holding another channel, -0.01 against -0.26, was called stored the
    # other way up)
    upside = [
        c
        for c in range(channels)
        if flipped[:, c].sum() > len(scores) / 2
        and np.median(scores[:, c, channels]) >= FLIP_MARGIN
        and c not in named
    ]
    if upside and len(upside) < channels:
        names = ", ".join(files[c] for c in upside)
        warnings.warn(
            f"{settings}: over {len(scores)} views, the spikes of {names} match their channel "
            f"of the images better upside down (median correlation "
            f"{np.median(scores[:, upside, channels]):.2f} against "
            f"{np.median(own[:, upside]):.2f} as read), the other files' as read: "
            f"{'they are' if len(upside) > 1 else 'it is'} likely stored the other way up "
            f"(rows top-down where flip says bottom-up, or the reverse)",
            stacklevel=3,
        )


def _warn_of_files_holding_another_channel(
    scores: np.ndarray, files: list[str], settings: str, named: set[int]
) -> set[int]:
    """A UserWarning naming the files (not in `named`, the order's) whose spikes match another
    channel of the images better than their own, by FLIP_MARGIN in most views (`scores`
    [V, C, C + 1] of `check_channels`): a mosaic split with two files holding one channel (an
    RGGB sensor's stored rows read as GBRG give red's and blue's files green pixels) is no
    other order. A file's own noise lowers its every correlation alike: a dim channel's file
    is not named. Returns the files named."""
    channels = len(files)
    holding = {}  # file f: the channel c it matches best, other than its own
    for f in sorted(set(range(channels)) - named):
        # channel c over its own, read either way up (a file stored upside down is that, not
        # another channel's: its own as read near 0, any channel alike by 0.2 was named)
        own = np.maximum(scores[:, f, f], scores[:, f, channels])  # [V]
        ahead = scores[:, :channels, f] - own[:, None]  # [V, C]
        ahead[:, f] = -np.inf
        c = int(np.argmax(np.median(ahead, axis=0)))
        if (ahead[:, c] > FLIP_MARGIN).sum() > len(scores) / 2:
            holding[f] = c
    if holding:
        said = "; ".join(
            f"{files[f]} matches the images' channel {c} (median correlation "
            f"{np.median(scores[:, c, f]):.2f}) better than its own channel {f} "
            f"({np.median(scores[:, f, f]):.2f})"
            for f, c in holding.items()
        )
        warnings.warn(
            f"{settings}: over {len(scores)} views, {said}: the files likely hold other channels "
            f"than their names say (a colour filter mosaic split with its pattern read wrong: "
            f"an RGGB sensor's rows stored bottom-up read as GBRG)",
            stacklevel=4,
        )
    return set(holding)
