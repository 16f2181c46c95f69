"""A dataset's optional sparse point cloud, DIR/points3d.ply: written by `spikegs poses`, read by
the trainer to place the initial Gaussians (vertices x y z, optional red green blue as uint8)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import torch
from plyfile import PlyData, PlyElement
from scipy.spatial import cKDTree

from .gaussians import GaussianModel
from .ply import read_vertices

POINTS = "points3d.ply"


def write_points(path: str | Path, points: np.ndarray, colors: np.ndarray | None = None) -> None:
    """Write points [P, 3] (and uint8 colours [P, 3]) as a binary .ply."""
    fields = [("x", "f4"), ("y", "f4"), ("z", "f4")]
    if colors is not None:
        fields += [("red", "u1"), ("green", "u1"), ("blue", "u1")]
    vertex = np.empty(len(points), dtype=fields)
    for i, axis in enumerate("xyz"):
        vertex[axis] = points[:, i]
    if colors is not None:
        for i, name in enumerate(("red", "green", "blue")):
            vertex[name] = colors[:, i]
    PlyData([PlyElement.describe(vertex, "vertex")]).write(str(path))


def read_points(path: str | Path) -> tuple[np.ndarray, np.ndarray | None]:
    """Points [P, 3] float64 and colours [P, 3] in [0, 1] (None when the file has none): 8- or
    16-bit integers scaled by their range, floats taken as they are (0..1, as PLY writers store
    them); ValueError naming the file for anything else."""
    vertex = read_vertices(path)["vertex"].data
    names = vertex.dtype.names
    if not {"x", "y", "z"} <= set(names):
        raise ValueError(f"{path}: expected vertex properties x, y, z; found {list(names)}")
    points = np.stack([vertex[a] for a in "xyz"], axis=1).astype(np.float64)  # [P, 3]
    if not len(points) or not np.isfinite(points).all():
        raise ValueError(f"{path}: expected at least one point, all finite")
    if not {"red", "green", "blue"} <= set(names):
        return points, None
    colors = np.stack([vertex[c] for c in ("red", "green", "blue")], axis=1)  # [P, 3]
    if colors.dtype.kind == "f":
        scale = 1.0
    elif colors.dtype in (np.uint8, np.uint16):
        scale = float(np.iinfo(colors.dtype).max)
    else:
        raise ValueError(
            f"{path}: red, green, blue of type {colors.dtype}; expected uint8, uint16 or float"
        )
    colors = colors.astype(np.float64) / scale
    if not (np.isfinite(colors).all() and colors.min() >= 0 and colors.max() <= 1):
        raise ValueError(f"{path}: colours expected in [0, 1] (floats) or their integer range")
    return points, colors


def gaussians_from_points(
    path: str | Path,
    max_points: int,
    channels: int,
    sh_degree: int,
    generator: torch.Generator,
    colors_of: Callable[[torch.Tensor], torch.Tensor] | None = None,
) -> GaussianModel:
    """Gaussians at the cloud's points (a random subset of `max_points` when it has more), coloured
    by it (a mono camera takes the mean of r, g, b; a cloud without colours: `colors_of(points)`
    [P, C], default grey 0.5), sized by the median distance between nearest neighbours."""
    points, colors = read_points(path)
    if len(points) > max_points:
        keep = torch.randperm(len(points), generator=generator)[:max_points].numpy()
        points, colors = points[keep], None if colors is None else colors[keep]
    means = torch.from_numpy(points)
    if colors is None:
        rgb = torch.full((len(points), channels), 0.5) if colors_of is None else colors_of(means)
    else:
        rgb = torch.from_numpy(colors.mean(axis=1, keepdims=True) if channels == 1 else colors)
    spacing = np.median(cKDTree(points).query(points, k=2)[0][:, 1]) if len(points) > 1 else 0.0
    return GaussianModel.from_points(
        means,
        rgb,
        max(float(spacing), 1e-6),
        sh_degree,
    )
