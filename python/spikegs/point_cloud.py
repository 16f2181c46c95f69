"""A dataset's optional sparse point cloud, DIR/points3d.ply: written by `spikegs poses` (vertices
x y z, red green blue as uint8 for viewing), read by the trainer to place the initial Gaussians."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import torch
from plyfile import PlyData, PlyElement
from scipy.spatial import cKDTree

from .atomic_save import write_atomically
from .data.trajectory import pixel_rays, pixels_in_view, point_parts
from .gaussians import GaussianModel
from .ply import read_vertices
from .targets import sample_timestamps


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
    ply = PlyData([PlyElement.describe(vertex, "vertex")])
    write_atomically(Path(path), lambda tmp: ply.write(str(tmp)))


def read_points(path: str | Path) -> np.ndarray:
    """Points [P, 3] float64 (any colours the file has are left: their units are the camera's
    or photo's that made them, not the spikes'); ValueError naming the file for anything else."""
    vertex = read_vertices(path)["vertex"].data
    names = vertex.dtype.names
    if not {"x", "y", "z"} <= set(names):
        raise ValueError(f"{path}: expected vertex properties x, y, z; found {list(names)}")
    points = np.stack([vertex[a] for a in "xyz"], axis=1).astype(np.float64)  # [P, 3]
    # finite in float32 too, the Gaussians' precision (1e39 became inf there)
    finite = (np.abs(points) <= np.finfo(np.float32).max).all(axis=1)  # [P] (NaN: False)
    if not len(points) or not finite.all():
        bad = np.flatnonzero(~finite)
        found = (
            "none"
            if not len(points)
            else f"{len(bad)} of {len(points)} not finite, #{bad[0]} first"
        )
        raise ValueError(
            f"{path}: expected at least one point, all finite (in float32); found {found}"
        )
    return points


def in_training_views(points: np.ndarray, dataset) -> np.ndarray:
    """Whether each point [P, 3] lies inside each of the dataset's training views at
    `sample_timestamps` (up to 31 spread over the stream) [M, P] bool; a part at a time."""
    viewmats = dataset.trajectory.pose_at(sample_timestamps(dataset))  # [M, 4, 4]
    size = dataset.width, dataset.height
    return np.concatenate(
        [pixels_in_view(part, viewmats, dataset.K, *size)[2] for part in point_parts(points)],
        axis=1,
    )


def view_coverage(
    center, radius: float, dataset, cells: int = 16, viewmats: np.ndarray | None = None
) -> np.ndarray:
    """The share of each training view at `sample_timestamps` (or of each of `viewmats` [M, 4,
    4], in the dataset's camera) [M] that the ball (center, radius) covers: of its image cut
    into `cells` x `cells` parts, those whose middle's ray meets the ball in front of the camera
    (every part, from inside the ball). Exact: points spread through the ball and projected to
    whole pixels filled no more than `width` of the columns (8x6 images: under 19 % at most)
    and, around the cameras, a few parts of a view that the ball fills."""
    if viewmats is None:
        viewmats = dataset.trajectory.pose_at(sample_timestamps(dataset))  # [M, 4, 4]
    K = np.asarray(dataset.K, np.float64)
    middles = (np.arange(cells) + 0.5) / cells  # [cells] as shares of a side
    x, y = np.meshgrid(middles * dataset.width, middles * dataset.height)  # [cells, cells] pixels
    rays = pixel_rays(x, y, K).reshape(-1, 3)  # [cells², 3]
    rays /= np.linalg.norm(rays, axis=1, keepdims=True)
    centre = viewmats[:, :3, :3] @ np.asarray(center, np.float64) + viewmats[:, :3, 3]  # [M, 3]
    along = centre @ rays.T  # [M, cells²] the ray's nearest approach to the centre, its depth
    distance2 = (centre**2).sum(axis=1, keepdims=True)  # [M, 1] the camera's from the centre
    gap = distance2 - along**2  # [M, cells²] squared, the ray's from the centre
    around = distance2 <= radius**2  # [M, 1] camera in the ball
    return (around | ((along > 0) & (gap <= radius**2))).mean(axis=1)  # [M]


def seen_points(points: np.ndarray, dataset) -> np.ndarray:
    """Whether each point [P, 3] lies inside one or more of the dataset's training views at
    `sample_timestamps` [P] bool."""
    return in_training_views(points, dataset).any(axis=0)


def ball_points(center, radius: float, count: int) -> np.ndarray:
    """`count` points [count, 3] spread uniformly through the ball (center, radius), the same
    ones on every call (a fixed seed)."""
    rng = np.random.default_rng(0)
    directions = rng.normal(size=(count, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    return np.asarray(center, np.float64) + directions * radius * rng.random((count, 1)) ** (1 / 3)


def distinct_points(points: np.ndarray) -> np.ndarray:
    """The distinct points of a cloud [P, 3], in its order (a repeat would make the spacing 0)."""
    first = np.unique(points, axis=0, return_index=True)[1]
    return points[np.sort(first)]


def gaussians_from_points(
    points: np.ndarray,
    max_points: int,
    sh_degree: int,
    generator: torch.Generator,
    colors_of: Callable[[torch.Tensor], torch.Tensor],
    max_scale: float = math.inf,
) -> GaussianModel:
    """Gaussians at distinct points [P, 3] (`distinct_points`, P >= 2; a random subset of
    `max_points` when it has more), of the intensities `colors_of(points)` [P, C] (what the views
    show there), sized by the median distance between nearest neighbours, at most `max_scale`."""
    if len(points) < 2:
        raise ValueError(f"a point cloud of {len(points)} distinct point(s) has no spacing")
    if len(points) > max_points:
        points = points[torch.randperm(len(points), generator=generator)[:max_points].numpy()]
    means = torch.from_numpy(points)
    spacing = float(np.median(cKDTree(points).query(points, k=2)[0][:, 1]))
    return GaussianModel.from_points(means, colors_of(means), min(spacing, max_scale), sh_degree)
