"""Hot, stuck and dead pixels found in the spikes themselves, left out of the losses.

A sensor's defect stays at one pixel of the frame. Where the camera moves, each view puts it on
another ray and 3DGS averages it away; where it barely moves (or views differ little), the
defect falls on nearly one ray in every view and is fitted as a point floating before the scene
(BENCHMARKS.md, "Sensor defects where the camera barely moves"). A pixel is taken as hot (or
stuck) where, in nearly every stretch of the recording (each view's stream of a per-view
capture), it fires well above all but one of its 8 neighbours: a bright point of the scene (a
highlight, a lamp) moves across the pixels as the camera does, and an edge or a thin line has a
neighbour as bright. Dead: far below all but one over the whole recording, and in nearly every
stretch no higher than they.
"""

from __future__ import annotations

import hashlib
import warnings
from typing import NamedTuple

import numpy as np
import torch

from .found_once import found_once
from .spikes import SpikeStream

STRETCHES = 16  # a recording's equal stretches (a per-view capture's: its views)
SHARE = 0.9  # of the stretches in which a defect must stand out
RATIO = 1.5  # how far from its neighbours' firing rate, as a factor
Z = 4.0  # and by how many of the neighbours' Poisson standard deviations beyond it


def stretches(stream):
    """Each stretch of `stream` (a SpikeStream: STRETCHES equal ones, at least a readout each; a
    ViewStreams: the longest odd window of each view), one at a time: its firing rates [H, W]
    and the readouts it counts."""
    if isinstance(stream, SpikeStream):
        window = max(len(stream) // STRETCHES, 1)
        starts = np.arange(min(len(stream) // window, STRETCHES)) * window
        centers, windows = starts + window // 2, np.full(len(starts), window)
    else:  # a ViewStreams
        centers, windows = stream.centers(), np.diff(stream.offsets)
        windows = windows - 1 + windows % 2  # [V] odd
    for k, w in zip(centers, windows):
        yield stream.tfp(int(k), int(w)), int(w)


def _ring(image: np.ndarray) -> np.ndarray:
    """Each pixel's 8 neighbours in `image` [H, W] [8, H, W], reflected about the frame's edges: a
    border pixel's neighbours in the frame, an edge's inner three twice and a corner's diagonal
    four times, as a scene's line crossing the edge goes on past it (edges repeated made a corner
    three of its own neighbours, and so its second brightest and darkest: a defect there was
    never found; left out, NaN, a still line's pixel at the edge was taken for a defect)."""
    h, w = image.shape
    pad = np.pad(image, 1, mode="reflect")
    ring = [(dy, dx) for dy in range(3) for dx in range(3) if (dy, dx) != (1, 1)]
    return np.stack([pad[y : y + h, x : x + w] for y, x in ring])


def _neighbours(image: np.ndarray) -> np.ndarray:
    """Each pixel's 8 neighbours in `image` [H, W] (reflected at the edges), darkest first [8, H,
    W]."""
    return np.sort(_ring(image), axis=0)


def _second(rates: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The second darkest and second brightest [H, W] of each pixel's 8 neighbours in rates [H,
    W] (reflected at the edges)."""
    around = _neighbours(rates)
    return around[1], around[-2]


def find_defects(stream) -> tuple[np.ndarray, np.ndarray]:
    """Hot (or stuck) and dead pixels of one channel's `stream`: two bool maps [H, W], read-only
    (a file's kept for the process under the spikes' digest and the search's settings:
    `found_once`)."""
    return _found(stream)[:2]


def _found(stream) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """`find_defects`' maps and each defect's stand-in (`_search`)."""
    views = getattr(stream, "streams", [stream])  # (a ViewStreams' views)
    if any(view.path is None for view in views):  # in memory: its digest, read each time it is
        return _search(stream)  # asked, costs 4x this search (2.1 / 0.5 s at 250x400 x 100,000)
    settings = f"pixel_defects|{STRETCHES}|{SHARE}|{RATIO}|{Z}|".encode()  # (tuned at run time)
    key = hashlib.sha256(settings + stream.digest()).digest()
    return found_once(key, lambda: _search(stream))


def _search(stream) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """`find_defects`' maps [H, W], found afresh, and each defect's (flat order) neighbour of the
    (upper) median rate over the recording: flat pixel indices [D]."""
    shape = (stream.height, stream.width)
    above, not_below, spikes = np.zeros(shape), np.zeros(shape), np.zeros(shape)  # [H, W] each
    count = readouts = 0
    for rates, n in stretches(stream):  # [H, W], readouts
        dark, bright = _second(rates)
        above += rates > RATIO * bright + Z * np.sqrt(np.maximum(bright, 1 / n) / n)
        not_below += rates <= dark
        spikes += rates * n
        readouts += n
        count += 1
    total = spikes / readouts  # [H, W] the whole recording's rate
    dark_total, _ = _second(total)
    deep = total < dark_total / RATIO - Z * np.sqrt(dark_total / readouts)
    hot, dead = above / count >= SHARE, deep & (not_below / count >= SHARE)
    # whole counts: neighbours of equal counts taken in ring order (float32 rates times
    # readouts rounded such ties apart, picking another stand-in, and so another SIM cache key)
    found = hot, dead, _stand_ins(np.rint(spikes), hot | dead)
    for kept in found:
        kept.flags.writeable = False  # (kept: a caller's edit would be the next one's finding)
    return found


def _stand_ins(spikes: np.ndarray, defects: np.ndarray) -> np.ndarray:
    """Each of `defects`' [H, W] (bool; flat order) neighbours whose count in `spikes` [H, W] is
    their (upper) median, as `repaired` takes it: flat pixel indices [D]."""
    index = np.arange(spikes.size).reshape(spikes.shape)  # [H, W] flat pixel indices
    median = np.argsort(_ring(spikes)[:, defects], axis=0, kind="stable")[4]  # [D]
    return _ring(index)[:, defects][median, np.arange(len(median))]


class SensorDefects(NamedTuple):
    """A recording's hot, stuck and dead pixels, as the losses and SIM take them."""

    valid: torch.Tensor | None  # [H, W, C] pixels a loss against the spikes compares (None: all)
    streams: list  # one a channel, the defects repaired (`RepairedSpikes`): what SIM reads
    pixels: int  # pixels with a defect in any channel


def sensor_defects(streams: list, root, search: bool = True) -> SensorDefects:
    """The defects of `streams` (one a channel) of the recording at `root`; a warning counts
    them. None found, or `search` false (nothing searched): `valid` None and `streams` as they
    are."""
    found = [_found(stream) for stream in streams] if search else []
    if not _any_found(found):
        return SensorDefects(None, streams, 0)
    hot, dead = (np.stack(maps, -1) for maps in list(zip(*found))[:2])  # [H, W, C] each
    defects = hot | dead
    where = "" if len(streams) == 1 else ", in any channel"  # (pixels counted once)
    warnings.warn(
        f"{root}: {int(hot.any(-1).sum())} hot or stuck pixels (firing far above their neighbours "
        f"throughout the recording) and {int(dead.any(-1).sum())} dead ones (far below them)"
        f"{where}, left out of every loss against a target made from the spikes "
        f"(supervision.mask_defects; "
        f"docs/datasets.md, 'Sensor defects')",
        stacklevel=3,
    )
    valid = torch.from_numpy(~defects)
    return SensorDefects(valid, _repaired_spikes(streams, found), int(defects.any(-1).sum()))


def defect_maps(streams: list) -> np.ndarray:
    """The hot, stuck and dead pixels of `streams` (one a channel): bool [C, H, W]."""
    return np.stack([np.logical_or(*find_defects(stream)) for stream in streams])


def repaired_spikes(streams: list) -> list:
    """`streams` (one a channel) with their defects repaired (`RepairedSpikes`), as SIM reads
    them; `streams` themselves where none is found."""
    found = [_found(stream) for stream in streams]
    return _repaired_spikes(streams, found) if _any_found(found) else streams


def _any_found(found: list) -> bool:
    """Whether any of `_found`'s findings `found` (one a channel) holds a defect."""
    return any(hot.any() or dead.any() for hot, dead, _ in found)


def _repaired_spikes(streams: list, found: list) -> list:
    """Each of `streams` a `RepairedSpikes` of its `_found` maps and stand-ins."""
    return [
        RepairedSpikes(stream, np.flatnonzero(hot | dead), stand_in)
        for stream, (hot, dead, stand_in) in zip(streams, found)
    ]


def repaired(image: np.ndarray, defects: np.ndarray) -> np.ndarray:
    """`image` [H, W] with each of its `defects` [H, W] (bool) replaced by the (upper) median of
    its 8 neighbours (reflected at the edges), as a camera's defect-pixel correction does."""
    return np.where(defects, _neighbours(image)[4], image)


class RepairedSpikes:
    """`stream` (a SpikeStream or ViewStreams) whose defects, at flat pixel indices `at` [D], fire
    as their neighbours `stand_in` [D] (each its neighbour of the (upper) median rate over the
    recording) do: what SIM, a blind-spot network that reads each pixel's neighbours, is trained
    on and reads (a hot pixel's spikes brightened its 8 neighbours and swamped its
    self-supervised loss; BENCHMARKS.md, "Sensor defects, leftovers"), and what sim-train scores
    the decoders on. Windows, TFP and TFI; the digest is the stream's and the defects'."""

    def __init__(self, stream, at: np.ndarray, stand_in: np.ndarray):
        self.stream, self.at, self.stand_in = stream, at, stand_in
        self.height, self.width = stream.height, stream.width

    def __len__(self) -> int:
        return len(self.stream)

    def window(self, k, w: int) -> np.ndarray:
        """`stream.window(k, w)` [w, H, W] ([B, w, H, W]), the defects repaired."""
        return self._repaired(self.stream.window(k, w))

    def tfp(self, k, w: int) -> np.ndarray:
        """`stream.tfp(k, w)` [H, W] ([B, H, W]), the defects repaired (a pixel's TFP is its own
        spikes', so the stand-ins' TFP)."""
        return self._repaired(self.stream.tfp(k, w))

    def tfi(self, k) -> np.ndarray:
        """`stream.tfi(k)` [H, W] ([B, H, W]), the defects repaired (the stand-ins' TFI)."""
        return self._repaired(self.stream.tfi(k))

    def _repaired(self, images: np.ndarray) -> np.ndarray:
        """`images` [..., H, W], a new array the stream made, with each defect its stand-in's."""
        flat = images.reshape(*images.shape[:-2], -1)  # [..., H * W], a view
        flat[..., self.at] = flat[..., self.stand_in]
        return images

    def digest(self) -> bytes:
        """SHA-256 of the stream's digest, the defects and the neighbours standing in."""
        parts = (self.stream.digest(), self.at.tobytes(), self.stand_in.tobytes())
        return hashlib.sha256(b"".join(parts)).digest()


def hide(render: torch.Tensor, target: torch.Tensor, valid: torch.Tensor | None) -> torch.Tensor:
    """`render` [H, W, C] showing `target` [H, W, C] where `valid` [H, W, C] is false: those
    pixels add no residual and no gradient to a loss (`valid` None: `render` itself)."""
    return render if valid is None else torch.where(valid, render, target)
