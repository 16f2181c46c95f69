"""Built-in procedural ground-truth scenes: thousands of small Gaussians on surfaces and rods,
coloured from the sample images that ship inside scikit-image (no download, no extra dependency).

Colours are linear RGB in [0, 1] (the 8-bit sRGB samples are decoded). Every builder is
deterministic: it takes a `seed` for its jitter and returns the same scene for the same seed.

| name           | difficulty                                                             |
| -------------- | ---------------------------------------------------------------------- |
| `solids`       | easy: a sphere (astronaut) and a cube (coffee, chelsea, rocket, brick)  |
| `wires`        | thin structures: a wire-frame cube, rings and a helix of thin rods     |
| `fine-texture` | fine high-contrast texture: a cube of checkers, text, camera, gravel   |
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np
import skimage.data
from scipy.spatial.transform import Rotation

from ..image_io import srgb_to_linear


@dataclasses.dataclass
class GaussianScene:
    """Gaussians in the rasterizer's parametrisation (scales = std devs, opacities in [0, 1])."""

    means: np.ndarray  # [N, 3]
    quats: np.ndarray  # [N, 4] (w, x, y, z)
    scales: np.ndarray  # [N, 3]
    opacities: np.ndarray  # [N]
    colors: np.ndarray  # [N, 3] linear RGB
    background: np.ndarray  # [3] linear RGB

    @property
    def center(self) -> np.ndarray:
        """Centre [3] of the bounding box of the means."""
        return (self.means.min(0) + self.means.max(0)) / 2

    @property
    def radius(self) -> float:
        """Distance from `center` to the farthest mean."""
        return float(np.linalg.norm(self.means - self.center, axis=1).max())

    @staticmethod
    def concat(parts: list[GaussianScene], background) -> GaussianScene:
        fields = ("means", "quats", "scales", "opacities", "colors")
        arrays = {f: np.concatenate([getattr(p, f) for p in parts]) for f in fields}
        return GaussianScene(**arrays, background=np.asarray(background, np.float64))


def texture(name: str, white: float = 0.95) -> np.ndarray:
    """A scikit-image sample image as linear RGB float [h, w, 3], exposed so that its 99th
    percentile is `white` (decoded sRGB photos are dark in linear light)."""
    image = np.asarray(getattr(skimage.data, name)(), np.float64)
    image = image / 255.0 if image.max() > 1 else image
    if image.ndim == 2:
        image = np.repeat(image[..., None], 3, axis=2)
    image = srgb_to_linear(image[..., :3])
    return np.clip(image * white / max(np.percentile(image, 99), 1e-6), 0.0, 1.0)


def checker(cells: int, size: int = 256) -> np.ndarray:
    """A black/white checkerboard of cells × cells squares, linear RGB [size, size, 3]."""
    idx = np.arange(size) * cells // size
    board = ((idx[:, None] + idx[None, :]) % 2).astype(np.float64)
    return np.repeat(board[..., None], 3, axis=2) * 0.95 + 0.02


def sample(tex: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Nearest texel colours [N, 3] at uv [N, 2] in [0, 1] (u right, v down)."""
    h, w = tex.shape[:2]
    col = np.clip((uv[:, 0] * w).astype(int), 0, w - 1)
    row = np.clip((uv[:, 1] * h).astype(int), 0, h - 1)
    return tex[row, col]


def _quats(frames: np.ndarray) -> np.ndarray:
    """(w, x, y, z) quaternions [N, 4] of rotation matrices [N, 3, 3]."""
    xyzw = Rotation.from_matrix(frames).as_quat()
    return np.concatenate([xyzw[:, 3:], xyzw[:, :3]], axis=1)


def _frames_from(axis: np.ndarray) -> np.ndarray:
    """Right-handed orthonormal frames [N, 3, 3] whose third column is `axis` [N, 3]."""
    axis = axis / np.linalg.norm(axis, axis=1, keepdims=True)
    helper = np.where(np.abs(axis[:, 2:3]) < 0.9, [[0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0]])
    t1 = np.cross(helper, axis)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(axis, t1)
    return np.stack([t1, t2, axis], axis=2)


def surfels(points, normals, colors, spacing: float, rng, opacity: float = 0.95) -> GaussianScene:
    """Flat Gaussians on a surface: tangent std `spacing`·0.6 (overlapping), thin along normals."""
    n = len(points)
    sigma = spacing * 0.6 * rng.uniform(0.9, 1.1, n)  # [N]
    scales = np.stack([sigma, sigma, np.full(n, spacing * 0.05)], axis=1)  # [N, 3]
    return GaussianScene(
        means=np.asarray(points, np.float64),
        quats=_quats(_frames_from(np.asarray(normals, np.float64))),
        scales=scales,
        opacities=np.full(n, opacity),
        colors=np.asarray(colors, np.float64),
        background=np.zeros(3),
    )


def rod(start, end, thickness: float, colors_fn, spacing: float) -> GaussianScene:
    """A thin rod from `start` to `end`: needle Gaussians along it, colours colors_fn(s [N])."""
    start, end = np.asarray(start, np.float64), np.asarray(end, np.float64)
    length = np.linalg.norm(end - start)
    n = max(int(np.ceil(length / spacing)), 1)
    s = (np.arange(n) + 0.5) / n  # [N] along the rod
    axis = np.tile((end - start) / length, (n, 1))  # [N, 3]
    scales = np.tile([thickness, thickness, 0.6 * length / n], (n, 1))  # [N, 3]
    return GaussianScene(
        means=start + s[:, None] * (end - start),
        quats=_quats(_frames_from(axis)),
        scales=scales,
        opacities=np.full(n, 0.97),
        colors=colors_fn(s),
        background=np.zeros(3),
    )


def polyline(points: np.ndarray, thickness: float, colors_fn, spacing: float) -> GaussianScene:
    """Rods through consecutive `points` [P, 3], colours colors_fn(s), s along the whole line."""
    parts = []
    for i in range(len(points) - 1):
        lo, hi = i / (len(points) - 1), (i + 1) / (len(points) - 1)
        fn = lambda s, lo=lo, hi=hi: colors_fn(lo + (hi - lo) * s)  # noqa: E731
        parts.append(rod(points[i], points[i + 1], thickness, fn, spacing))
    return GaussianScene.concat(parts, np.zeros(3))


def sphere(center, radius: float, tex: np.ndarray, count: int, rng) -> GaussianScene:
    """A sphere of `count` surfels (Fibonacci lattice), equirectangular texture."""
    i = np.arange(count) + 0.5
    z = 1 - 2 * i / count  # [N]
    phi = np.pi * (1 + 5**0.5) * i
    normals = np.stack([np.sqrt(1 - z**2) * np.cos(phi), np.sqrt(1 - z**2) * np.sin(phi), z], 1)
    uv = np.stack([(phi / (2 * np.pi)) % 1.0, np.arccos(z) / np.pi], axis=1)  # [N, 2]
    spacing = radius * np.sqrt(4 * np.pi / count)
    points = np.asarray(center) + radius * normals
    return surfels(points, normals, sample(tex, uv), spacing, rng)


def cube(center, size: float, textures: list[np.ndarray], per_side: int, rng) -> GaussianScene:
    """An axis-aligned cube, `per_side`² surfels a face, face f textured with textures[f % len]."""
    g = (np.arange(per_side) + 0.5) / per_side  # [n]
    u, v = (a.reshape(-1) for a in np.meshgrid(g, g))  # [n²] each
    uv = np.stack([u, v], axis=1)
    parts = []
    for f, normal in enumerate(np.concatenate([np.eye(3), -np.eye(3)])):
        up = np.array([0.0, 1.0, 0.0]) if normal[2] else np.array([0.0, 0.0, 1.0])
        right = np.cross(up, normal)  # texture upright and unmirrored seen from outside
        points = (
            np.asarray(center, np.float64)
            + normal * size / 2
            + np.outer(u - 0.5, right) * size
            + np.outer(0.5 - v, up) * size
        )  # [n², 3]
        colors = sample(textures[f % len(textures)], uv)
        parts.append(surfels(points, np.tile(normal, (len(u), 1)), colors, size / per_side, rng))
    return GaussianScene.concat(parts, np.zeros(3))


def solids(seed: int = 0) -> GaussianScene:
    """Easy: a textured sphere next to a textured cube (~12k Gaussians)."""
    rng = np.random.default_rng(seed)
    tex = [texture(n) for n in ("coffee", "chelsea", "rocket", "brick")]
    parts = [
        sphere((-0.45, -0.1, 0.05), 0.55, texture("astronaut"), 6000, rng),
        cube((0.5, 0.25, -0.05), 0.75, tex, 32, rng),
    ]
    return GaussianScene.concat(parts, background=(0.1, 0.1, 0.12))


def wires(seed: int = 0) -> GaussianScene:
    """Thin structures: a wire-frame cube, three rings and a helix of 1-2 px rods (~1.9k)."""
    rng = np.random.default_rng(seed)
    thick, step = 0.008, 0.02
    rocket, coffee = texture("rocket"), texture("coffee")

    def along(tex, row: float):
        return lambda s: sample(tex, np.stack([s, np.full_like(s, row)], axis=1))

    corners = np.array([[x, y, z] for x in (-0.6, 0.6) for y in (-0.6, 0.6) for z in (-0.6, 0.6)])
    edges = [
        (i, j) for i in range(8) for j in range(i + 1, 8) if np.sum(corners[i] != corners[j]) == 1
    ]
    parts = [
        rod(corners[i], corners[j], thick, along(rocket, rng.uniform(0.2, 0.8)), step)
        for i, j in edges
    ]
    ring = np.linspace(0, 2 * np.pi, 97)  # [P]
    for k, (tilt, r) in enumerate(((0.0, 0.75), (np.pi / 3, 0.5), (-np.pi / 3, 0.5))):
        pts = np.stack(
            [r * np.cos(ring), r * np.sin(ring) * np.cos(tilt), r * np.sin(ring) * np.sin(tilt)], 1
        )
        parts.append(polyline(pts, thick, along(coffee, 0.3 + 0.2 * k), step))
    turns = np.linspace(0, 6 * np.pi, 241)
    helix = np.stack([0.25 * np.cos(turns), 0.25 * np.sin(turns), np.linspace(-0.55, 0.55, 241)], 1)
    parts.append(polyline(helix, thick * 1.5, along(rocket, 0.5), step))
    return GaussianScene.concat(parts, background=(0.25, 0.25, 0.27))


def fine_texture(seed: int = 0) -> GaussianScene:
    """Fine high-contrast texture: a cube of checkers, text, camera, gravel (~14k, ~1 px each)."""
    rng = np.random.default_rng(seed)
    tex = [
        checker(16),
        texture("text"),
        texture("camera"),
        checker(24),
        texture("gravel"),
        texture("page"),
    ]
    return GaussianScene.concat([cube((0, 0, 0), 1.1, tex, 48, rng)], background=(0.5, 0.5, 0.5))


SCENES: dict[str, Callable[..., GaussianScene]] = {
    "solids": solids,
    "wires": wires,
    "fine-texture": fine_texture,
}
