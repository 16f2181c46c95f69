"""Per-view spike streams on one readout axis, each view's pose held over its own readouts.

View i occupies readouts [offsets[i], offsets[i + 1]) of the virtual axis. A window or a TFI is
read from the one view that holds its centre; a window reaching into another view is a
ValueError, so no target ever mixes two views.
"""

from __future__ import annotations

import hashlib

import numpy as np

from ..spikes import TFI_DEFAULT_MAX_INTERVAL, SpikeStream
from ..spikes.stream import as_readouts
from .trajectory import Trajectory


class ViewStreams:
    """Streams [V] of one size as one stream (`len`, `height`, `width`, `window`, `tfp`, `tfi`)."""

    def __init__(self, streams: list[SpikeStream], names: list[str]):
        sizes = {(s.height, s.width) for s in streams}
        if len(sizes) != 1:
            raise ValueError(f"view streams of one size expected, found sizes {sorted(sizes)}")
        self.streams, self.names = list(streams), list(names)
        self.offsets = np.concatenate([[0], np.cumsum([len(s) for s in streams])])  # [V + 1]

    def __len__(self) -> int:
        return int(self.offsets[-1])

    @property
    def height(self) -> int:
        return self.streams[0].height

    @property
    def width(self) -> int:
        return self.streams[0].width

    def __repr__(self) -> str:
        size = f"{self.height}x{self.width}"
        return f"ViewStreams(views={len(self.streams)}, readouts={len(self)}, {size})"

    def digest(self) -> bytes:
        """SHA-256 of the views' digests in order (`SpikeStream.digest`)."""
        return hashlib.sha256(b"".join(s.digest() for s in self.streams)).digest()

    def centers(self) -> np.ndarray:
        """The centre readout [V] of each view: a 65-readout window there stays in the view."""
        return self.offsets[:-1] + (np.diff(self.offsets) - 1) // 2

    def view_of(self, k) -> np.ndarray:
        """Index [B] of the view holding each readout k [B]."""
        return np.searchsorted(self.offsets, k, side="right") - 1

    def bounds(self, k) -> tuple[np.ndarray, np.ndarray]:
        """The first readout [B] and the end [B] (one past the last) of the view holding each
        readout k [B] (of the first or last view for a k before or past the stream)."""
        views = self.view_of(k)
        return (
            self.offsets[np.clip(views, 0, len(self.streams) - 1)],
            self.offsets[np.clip(views + 1, 1, len(self.streams))],
        )

    def _split(self, k, w: int) -> tuple[np.ndarray, np.ndarray, bool]:
        """Views [B] and view-local readouts [B] of k; ValueError if a window of `w` readouts
        centred on k leaves the stream or its view."""
        ks, single = as_readouts(k)
        views = self.view_of(ks)
        starts = ks - w // 2
        inside = (ks >= 0) & (ks < len(self))
        lo, hi = self.bounds(ks)
        bad = np.flatnonzero(~inside | (starts < lo) | (starts + w > hi))
        if bad.size:
            i = bad[0]
            where = (
                f"view '{self.names[views[i]]}' at readouts [{lo[i]}, {hi[i]})"
                if inside[i]
                else f"the stream's [0, {len(self)})"
            )
            raise ValueError(
                f"window of {w} readouts centred on k={ks[i]} covers "
                f"[{starts[i]}, {starts[i] + w}), outside {where}: a window stays within one view"
            )
        return views, ks - self.offsets[views], single

    def _per_view(self, k, w: int, read) -> np.ndarray:
        """`read(stream, local_ks)` [b, ...] of each view, gathered in the order of k."""
        views, local, single = self._split(k, w)
        if not len(local):
            return read(self.streams[0], local)
        parts = {v: read(self.streams[v], local[views == v]) for v in np.unique(views)}
        first = next(iter(parts.values()))
        out = np.empty((len(local), *first.shape[1:]), first.dtype)
        for v, part in parts.items():
            out[views == v] = part
        return out[0] if single else out

    def window(self, k, w: int) -> np.ndarray:
        """Spikes uint8 [w, H, W] ([B, w, H, W]) of the window of `w` centred on k."""
        return self._per_view(k, w, lambda s, ks: s.window(ks, w))

    def tfp(self, k, w: int) -> np.ndarray:
        """TFP float32 [H, W] ([B, H, W]) of the window of `w` centred on k."""
        return self._per_view(k, w, lambda s, ks: s.tfp(ks, w))

    def tfi(self, k, max_interval: int = TFI_DEFAULT_MAX_INTERVAL) -> np.ndarray:
        """TFI float32 [H, W] ([B, H, W]) at k, from k's own view (its ends as the stream's)."""
        return self._per_view(k, 1, lambda s, ks: s.tfi(ks, max_interval))

    def held_trajectory(self, viewmats: np.ndarray, source: str) -> Trajectory:
        """Each view's pose [V, 4, 4] held over its readouts (first and last readout recorded)."""
        first, last = self.offsets[:-1], self.offsets[1:] - 1  # [V] each
        readouts = np.stack([first, last], axis=1).reshape(-1)  # [2V]
        poses = np.repeat(np.asarray(viewmats, np.float64), 2, axis=0)  # [2V, 4, 4]
        keep = np.concatenate([[True], np.diff(readouts) > 0])  # a one-readout view: one pose
        return Trajectory(readouts[keep], poses[keep], source=source)
