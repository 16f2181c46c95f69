"""Initial intensities of the Gaussians, from the data and the same for every method.

A random Gaussian takes the median TFP(33) intensity at its projections into up to 31 training
views; one that no view sees, and the background, take the median intensity of those images: the
constant image that fits them best in L1. The first render then resembles the views (a Gaussian on
a surface takes its colour, one in empty space the background's) instead of a grey fog: a grey 0.5
start fades the Gaussians on darker structures before their colour can follow, and pruning removes
them (BENCHMARKS.md, "Initial intensity").
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import torch

from .data.trajectory import pixels_in_view, point_parts
from .targets import tfp_sample


@dataclass
class ViewSample:
    """TFP(33) images at up to 31 training timestamps spread over the stream, read once for both
    initial intensities."""

    timestamps: np.ndarray  # [M] readouts
    rates: np.ndarray  # [M, H, W, C] firing rates
    scale: float  # firing rate of intensity 1.0 (targets.intensity_scale)

    @classmethod
    def of(cls, dataset, scale: float) -> ViewSample:
        return cls(*tfp_sample(dataset), scale)

    @cached_property
    def median(self) -> np.ndarray:
        """Median intensity [C] of each channel: the constant image that fits the views best in
        L1, whatever the method's target (computed once: the unseen-Gaussian fallback and the
        background both take it)."""
        return np.median(self.rates.reshape(-1, self.rates.shape[-1]), axis=0) / self.scale


def projected_intensity(dataset, sample: ViewSample, means: torch.Tensor) -> torch.Tensor:
    """Median intensity [N, C] of `sample`'s views at the projections of `means` [N, 3] (pixel
    centres at +0.5), the sample's median intensity where no view sees a point; a part of the
    points at a time (all at once, 5e5 took 0.55 GB)."""
    images = sample.rates / sample.scale  # [M, H, W, C]
    viewmats = dataset.trajectory.pose_at(sample.timestamps)  # [M, 4, 4] world to camera
    size = dataset.width, dataset.height
    medians = []
    for points in point_parts(means.detach().double().numpy()):  # [P, 3]
        u, v, inside = pixels_in_view(points, viewmats, dataset.K, *size)  # [M, P]
        seen = np.full((*u.shape, images.shape[-1]), np.nan, np.float32)  # [M, P, C]
        view = np.nonzero(inside)[0]
        seen[inside] = images[view, v[inside].astype(int), u[inside].astype(int)]
        never = np.isnan(seen).all(axis=0)  # [P, C]
        median = np.nanmedian(np.where(never[None], 0.0, seen), axis=0)
        medians.append(np.where(never, sample.median, median))
    return torch.from_numpy(np.concatenate(medians)).float()
