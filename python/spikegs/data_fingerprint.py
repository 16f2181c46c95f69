"""The identity of a run's data: a digest of what training reads from a dataset, to tell a moved
dataset from another one."""

from __future__ import annotations

import hashlib

import numpy as np

from .sim_train import spikes_fingerprint


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
