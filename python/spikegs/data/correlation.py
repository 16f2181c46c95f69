"""Pearson's correlation of two images' pixels: how well spikes decoded one way match another
image (real.py's orientation check) or themselves shifted by a row (dataset.py's frame size)."""

from __future__ import annotations

import numpy as np


def correlation(a: np.ndarray, b: np.ndarray) -> float:
    """Pearson's r of the values of `a` and `b` (arrays of one shape, not empty); 0 where either
    is flat; ValueError where the shapes differ (numpy would broadcast them)."""
    if np.shape(a) != np.shape(b):
        raise ValueError(f"correlation of arrays of shapes {np.shape(a)} and {np.shape(b)}")
    a = np.asarray(a, np.float64) - np.mean(a)
    b = np.asarray(b, np.float64) - np.mean(b)
    norm = np.sqrt((a * a).sum() * (b * b).sum())
    return float((a * b).sum() / norm) if norm > 0 else 0.0
