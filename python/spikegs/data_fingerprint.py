"""The identity of training data: digests of the spikes (a SIM's cache key) and of what a run reads
from a dataset, to tell a moved dataset from another one."""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from pathlib import Path

import numpy as np


def spikes_fingerprint(stream, timestamps: Sequence[int], sampled: bool = False) -> str:
    """A digest of training data: the timestamps and each stream's `digest()`, of every readout
    (`stream`: one or a list). `sampled`: the digest of SIMs and runs saved before 2026-11-28,
    of each stream's size and 16 of its readouts (which missed spikes edited between them), by
    which those are still recognised."""
    streams = stream if isinstance(stream, (list, tuple)) else [stream]
    digest = hashlib.sha256(np.asarray(timestamps, np.int64).tobytes())
    for s in streams:
        digest.update(_sampled_readouts(s) if sampled else s.digest())
    return digest.hexdigest()


def _sampled_readouts(stream) -> bytes:
    """A stream's size and 16 of its readouts spread over it, as bytes."""
    parts = [np.asarray([len(stream), stream.height, stream.width], np.int64).tobytes()]
    for k in np.linspace(0, len(stream) - 1, 16).astype(np.int64) if len(stream) else []:
        parts.append(np.ascontiguousarray(stream.window(int(k), 1)).tobytes())
    return b"".join(parts)


def file_digest(path) -> str:
    """The SHA-256 of the file at `path`, hex."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def data_fingerprint(dataset, scale: float, sampled: bool = False) -> str:
    """A digest of what training reads from `dataset`: its spikes (`spikes_fingerprint`, with
    `sampled` as there), the poses at its training timestamps, its intrinsics and the intensity
    `scale` (not its path: a moved dataset is the same data)."""
    timestamps = np.asarray(dataset.train_timestamps, np.float64)
    spikes = spikes_fingerprint(dataset.streams, timestamps, sampled)
    digest = hashlib.sha256(spikes.encode())
    # rounded: the last bits of interpolated poses and of a calibrated scale may differ between
    # machines (BLAS, libm), and the same data moved there must still resume
    poses = np.round(dataset.trajectory.pose_at(timestamps), 6) + 0.0  # + 0.0: no -0.0
    digest.update(np.ascontiguousarray(poses, np.float64).data)
    digest.update(np.asarray([*np.round(np.ravel(dataset.K), 6), float(f"{scale:.6g}")]).tobytes())
    return digest.hexdigest()


def same_data(saved: str, dataset, scale: float, current: str | None = None) -> bool:
    """Whether a run's fingerprint `saved` is `dataset`'s: today's (`current` where known), or
    the sampled one of runs trained before 2026-11-28."""
    current = data_fingerprint(dataset, scale) if current is None else current
    return saved == current or saved == data_fingerprint(dataset, scale, sampled=True)
