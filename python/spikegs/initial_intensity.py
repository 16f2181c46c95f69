"""Initial intensities of the Gaussians, from the data and the same for every method.

A random Gaussian takes the median TFP(33) intensity at its projections into ~16 training views;
one that no view sees, and the background, take the median intensity of those images: the
constant image that fits them best in L1. The first render then resembles the views (a Gaussian on
a surface takes its colour, one in empty space the background's) instead of a grey fog: a grey 0.5
start fades the Gaussians on darker structures before their colour can follow, and pruning removes
them (BENCHMARKS.md, "Initial intensity").
"""

from __future__ import annotations

import numpy as np
import torch

from .targets import intensity_scale, tfp_sample


def median_intensity(dataset) -> np.ndarray:
    """Median intensity [C] of each channel over TFP(33) images spread over the stream: the
    constant image that fits the views best in L1, whatever the method's target."""
    rates = tfp_sample(dataset)[1]  # [M, H, W, C]
    return np.median(rates.reshape(-1, rates.shape[-1]), axis=0) / intensity_scale(dataset)


def projected_intensity(dataset, means: torch.Tensor) -> torch.Tensor:
    """Median TFP(33) intensity [N, C] at the projections of `means` [N, 3] into ~16 training
    views (pixel centres at +0.5), the dataset's median intensity where no view sees a point."""
    timestamps, rates = tfp_sample(dataset)  # [M], [M, H, W, C]
    images = rates / intensity_scale(dataset)
    points = means.detach().double().numpy()  # [N, 3]
    K = dataset.K.astype(np.float64)
    seen = np.full((len(timestamps), len(points), images.shape[-1]), np.nan, np.float32)
    for i, t in enumerate(timestamps):
        viewmat = dataset.trajectory.pose_at(float(t))  # [4, 4] world to camera
        cam = points @ viewmat[:3, :3].T + viewmat[:3, 3]  # [N, 3]
        z = cam[:, 2]
        ahead = z > 1e-6
        z = np.where(ahead, z, 1.0)
        u = np.floor(K[0, 0] * cam[:, 0] / z + K[0, 2])
        v = np.floor(K[1, 1] * cam[:, 1] / z + K[1, 2])
        inside = ahead & (u >= 0) & (u < dataset.width) & (v >= 0) & (v < dataset.height)
        seen[i, inside] = images[i, v[inside].astype(int), u[inside].astype(int)]
    level = median_intensity(dataset)  # [C]
    never = np.isnan(seen).all(axis=0)  # [N, C]
    median = np.nanmedian(np.where(never[None], 0.0, seen), axis=0)
    return torch.from_numpy(np.where(never, level, median)).float()
