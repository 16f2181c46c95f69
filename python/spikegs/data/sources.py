"""Ground-truth sources behind one interface: a camera path and clean instantaneous images.

Three kinds:
- `ProceduralSource`: a built-in Gaussian scene (scenes.py) rendered by `spikegs.rasterize`;
- `MitsubaSource`: a Mitsuba 3 scene file or dict, rendered with the `scalar_rgb` variant;
- `FrameSequenceSource`: rendered frames with poses (e.g. a NeRF-synthetic transforms.json,
  OpenGL poses converted to OpenCV), spread evenly over the readouts and interpolated linearly.

Images are linear light, intensity 1.0 = white, [H, W, C]. A mono camera (C = 1) sees the Rec. 709
luma of linear RGB, Y = 0.2126 R + 0.7152 G + 0.0722 B (relative luminance); colour keeps C = 3.
"""

from __future__ import annotations

import itertools
import math
import os
import re
import warnings
from abc import ABC, abstractmethod
from pathlib import Path

import numpy as np
import torch

from ..box_filter import block_means
from ..image_io import to_channels
from ..machine_memory import machine_memory
from ..missing_dependency import MissingDependencyError
from ..number_checks import is_int
from ..rasterize import MAX_SIZE, rasterize
from ..spikes.simulate import not_codes, sample_times
from .dataset import check_meta_values, field_of_view_deg
from .scenes import GaussianScene
from .trajectory import WORLD_UP, Trajectory, look_at, orbit_eye, unit_vector
from .transforms_file import other_convention_fix, read_transforms
from .view_geometry import optical_axes, view_sphere

SPHERE_FIX = "pass center and radius (the scene sphere) to FrameSequenceSource"


# the widest view across a frame's longer side that `intrinsics` gives (a wide-angle lens's): a
# strip or a line of pixels (1x1000) sees 120° along its length, where 40° across its one pixel
# made it ~180° (refused)
MAX_LONG_FOV_DEG = 120.0


def intrinsics(width: int, height: int, fov_deg: float) -> np.ndarray:
    """K [3, 3] of a pinhole with field of view `fov_deg` across the frame's shorter side (a wide
    frame sees more at the sides, the scene framed as in a square one), up to MAX_LONG_FOV_DEG
    across its longer side (frames over 4.76:1 at 40°), square pixels, centred."""
    short, long = sorted((width, height))
    f = max(
        short / 2 / np.tan(np.radians(fov_deg) / 2),
        long / 2 / np.tan(np.radians(MAX_LONG_FOV_DEG) / 2),
    )
    return np.array([[f, 0.0, width / 2], [0.0, f, height / 2], [0.0, 0.0, 1.0]])


def horizontal_fov_deg(K: np.ndarray, width: int) -> float:
    """The field of view across the width of a centred pinhole K [3, 3] (Mitsuba's `fov`)."""
    return round(field_of_view_deg(width, K[0, 0]), 9)  # 40.0, not 1 ulp off


class Source(ABC):
    """Ground truth for a dataset of `width` × `height` pixels, `channels` 1 (mono) or 3.

    A subclass of the user's own is named after its class unless it sets `name` first; its
    `kind`, "custom", is treated as a rendered scene's (its light sampled at `light_times`
    every frame_every readouts), where a frame sequence's ("frames") keeps its frames' own
    spacing (simulate_dataset read both, an AttributeError where unset)."""

    name: str
    kind = "custom"

    def __init__(self, width: int, height: int, channels: int, K: np.ndarray, center, radius):
        if channels not in (1, 3):
            raise ValueError(f"channels expected 1 (mono) or 3 (colour), found {channels}")
        if "name" not in vars(self) and not hasattr(type(self), "name"):  # (a property's kept)
            self.name = type(self).__name__
        self.width, self.height, self.channels = int(width), int(height), int(channels)
        self.K = np.asarray(K, np.float64)  # [3, 3]
        self.scene_center = np.asarray(center, np.float64)  # [3]
        self.scene_radius = float(radius)

    @abstractmethod
    def trajectory(self, num_readouts: int, degrees_per_readout: float) -> Trajectory:
        """The camera path over readouts [0, num_readouts - 1]."""

    @abstractmethod
    def image_at(self, trajectory: Trajectory, t: float) -> np.ndarray:
        """The clean instantaneous image [H, W, C] on the path at readout t."""

    @abstractmethod
    def light_times(self, num_readouts: int, frame_every: float) -> np.ndarray:
        """Readouts [F] at which the simulator samples the light (linear in between)."""

    @abstractmethod
    def on_path_times(self, num_readouts: int, count: int, margin: int) -> np.ndarray:
        """`count` readouts [count] within [margin, num_readouts - 1 - margin] for held-out views
        whose clean image is exact."""

    @abstractmethod
    def off_path_views(self, count: int) -> list[tuple[str, np.ndarray, np.ndarray]]:
        """Up to `count` views off the path: (name, viewmat [4, 4], image [H, W, C])."""


class RenderSource(Source):
    """A source that renders any pose: a spiral around the scene ascending along `up` (the
    scene's up, unit [3]: +z by default, +y for a y-up scene), off-path views on a wider circle
    at mid elevation."""

    def __init__(
        self,
        width: int,
        height: int,
        channels: int,
        center,
        radius: float,
        *,
        fov_deg: float = 40.0,
        distance: float = 2.5,
        elevation_deg: tuple[float, float] = (10.0, 50.0),
        up=WORLD_UP,
        K: np.ndarray | None = None,
    ):
        """`K` [3, 3], a camera of its own (a dataset's as simulated), else `intrinsics` of
        `fov_deg`."""
        K = intrinsics(width, height, fov_deg) if K is None else K
        super().__init__(width, height, channels, K, center, radius)
        self.distance = distance * self.scene_radius  # camera to scene centre
        self.elevation_deg = elevation_deg
        self.up = unit_vector("up", up)

    @abstractmethod
    def render(self, viewmat: np.ndarray) -> np.ndarray:
        """The clean image [H, W, C] seen from `viewmat` [4, 4] (world-to-camera, OpenCV)."""

    def trajectory(self, num_readouts: int, degrees_per_readout: float) -> Trajectory:
        return Trajectory.spiral(
            num_readouts,
            radius=self.distance,
            start_elevation_deg=self.elevation_deg[0],
            end_elevation_deg=self.elevation_deg[1],
            degrees_per_readout=degrees_per_readout,
            look_at=tuple(self.scene_center),
            up=self.up,
        )

    def image_at(self, trajectory: Trajectory, t: float) -> np.ndarray:
        return self.render(trajectory.pose_at(t))

    def light_times(self, num_readouts: int, frame_every: float) -> np.ndarray:
        return sample_times(num_readouts, frame_every)

    def on_path_times(self, num_readouts: int, count: int, margin: int) -> np.ndarray:
        return np.round(np.linspace(margin, num_readouts - 1 - margin, count + 2)[1:-1])

    def off_path_views(
        self, count: int, arc_deg: float = 360.0
    ) -> list[tuple[str, np.ndarray, np.ndarray]]:
        """Evenly over the azimuths the path turns through, `arc_deg` (`trajectory`'s speed
        times its readouts less one; around the scene where it turns 360° or more): a 20° path
        (--speed 0.005) sees one side; views around it scored 17-22 dB where its own scored 44.
        Views a degree or more apart: a path that turns under 2° gets one (copies of it scored
        the same view again). They follow the orbit `trajectory` spirals on (its centre, up and
        azimuths from 0; its mean elevation, 1.2 times its distance): a subclass with a path of
        its own overrides both."""
        views = []
        elevation = float(np.mean(self.elevation_deg))
        arc = 360.0 if abs(arc_deg) >= 360 else arc_deg
        count = min(count, max(1, math.floor(abs(arc))))
        for i in range(count):
            eye = orbit_eye(
                self.scene_center, 1.2 * self.distance, arc * (i + 0.5) / count, elevation, self.up
            )
            viewmat = look_at(eye, self.scene_center, self.up)
            views.append((f"off_{i:03d}", viewmat, self.render(viewmat)))
        return views


class ProceduralSource(RenderSource):
    """A built-in Gaussian scene rendered by the project's rasterizer.

    `spp` samples per pixel on an s×s grid (a square: 1, 4, 9, ...): the frame is drawn s times
    larger and each s×s block averaged, a camera pixel's box (the mean of its area's light, as
    Mitsuba's box filter gives it); 1 samples each pixel's centre."""

    kind = "procedural"

    def __init__(
        self,
        name: str,
        scene: GaussianScene,
        width: int,
        height: int,
        channels: int = 1,
        up=WORLD_UP,
        K: np.ndarray | None = None,
        spp: int = 1,
    ):
        super().__init__(width, height, channels, scene.center, scene.radius, up=up, K=K)
        self.name = name
        self._grid = drawn_side(spp, width, height, channels)
        self.spp = self._grid**2
        tensor = lambda a: torch.as_tensor(np.asarray(a), dtype=torch.float32)  # noqa: E731
        self._gaussians = [
            tensor(a) for a in (scene.means, scene.quats, scene.scales, scene.opacities)
        ]
        self._colors = tensor(to_channels(scene.colors, channels))  # [N, C]
        self._background = tensor(to_channels(scene.background, channels))  # [C]
        # pixel centres at +0.5: pixel i's box [i, i + 1) is fine pixels s·i .. s·i + s - 1
        self._K = tensor(self.K * np.array([[self._grid], [self._grid], [1.0]]))

    def render(self, viewmat: np.ndarray) -> np.ndarray:
        s = self._grid
        with torch.no_grad():
            out = rasterize(
                *self._gaussians,
                self._colors,
                torch.as_tensor(viewmat, dtype=torch.float32),
                self._K,
                self.width * s,
                self.height * s,
                background=self._background,
            )
        return block_means(out.image.numpy(), s)  # [sH, sW, C] → [H, W, C]


def drawn_side(spp, width: int, height: int, channels: int = 1) -> int:
    """s, the side of the s×s grid on which a built-in scene's `width`×`height` frames of
    `channels` take `spp` samples a pixel (`grid_side`); ValueError where the frame drawn s times
    larger passes the rasterizer's side or half the memory this process may use."""
    s = grid_side(spp)
    # (one sample a pixel, the least: the frames' size alone, named as such, not spp)
    drawn = (
        f"height, width (--height, --width) {height}, {width}: frames drawn at their size"
        if s == 1
        else f"spp (--spp) {spp}: {width}x{height} frames would be drawn at "
        f"{width * s}x{height * s}"
    )
    remedy = "smaller frames" if s == 1 else "a smaller spp, or smaller frames"
    if max(width, height) * s > MAX_SIZE:
        raise ValueError(f"{drawn}, over the rasterizer's {MAX_SIZE} a side: {remedy}")
    # (C + 3) floats a fine pixel: its image, its alpha and the core's buffers (measured 23
    # bytes a pixel in colour)
    frame_bytes, memory = width * s * height * s * (channels + 3) * 4, machine_memory()
    if frame_bytes > memory // 2:
        raise ValueError(
            f"{drawn}, {frame_bytes / 2**30:.1f} GiB a frame, over half the {memory / 2**30:.1f} "
            f"GiB this process may use: {remedy}"
        )
    return s


def grid_side(spp) -> int:
    """s for `spp` = s² samples per pixel; ValueError where `spp` is not the square of a whole
    number >= 1."""
    side = math.isqrt(spp) if is_int(spp) and spp >= 1 else 0
    if side * side != spp or side == 0:
        raise ValueError(
            f"spp (--spp): a built-in scene samples each pixel on an s×s grid, so expected a "
            f"square (1, 4, 9, 16, ...), found {spp!r}"
        )
    return side


def import_mitsuba():
    """Mitsuba 3 with the `scalar_rgb` variant set (the llvm_* variants fail with Debian's LLVM)."""
    try:
        import mitsuba as mi
    except ImportError as err:
        raise MissingDependencyError(
            "a Mitsuba scene needs Mitsuba 3, which is not installed: "
            "pip install mitsuba (or, in a checkout of spikegs, pip install '.[mitsuba]')"
        ) from err
    mi.set_variant("scalar_rgb")
    return mi


CLIP_MARGIN = 2.0  # Mitsuba's far clip over the camera's distance to the bounding box's far corner
NEAR_OVER_FAR = 1e-6  # its near clip over its far (Mitsuba's defaults' ratio)


class MitsubaSource(RenderSource):
    """A Mitsuba 3 scene (a .xml file or a scene dict) rendered on the CPU (`scalar_rgb`).

    The scene's own sensors are ignored: one perspective sensor with a box filter is moved with
    `mi.traverse` (Mitsuba cameras look along +z with x left, y up: OpenCV with x, y flipped).
    The sampler seed is the same for every frame, so Monte Carlo noise does not flicker.
    """

    kind = "mitsuba"

    def __init__(
        self,
        scene: str | Path | dict,
        width: int,
        height: int,
        channels: int = 1,
        *,
        spp: int = 16,
        fov_deg: float = 40.0,
        center=None,
        radius: float | None = None,
        up=WORLD_UP,
    ):
        if not isinstance(scene, dict) and not Path(scene).is_file():  # (a typo's path asked
            raise FileNotFoundError(f"Mitsuba scene file not found: {scene}")  # for Mitsuba)
        mi = import_mitsuba()
        self.name = "mitsuba-dict" if isinstance(scene, dict) else Path(scene).stem
        try:  # Mitsuba's parse errors are plain Exceptions
            self._scene = (
                mi.load_dict(scene) if isinstance(scene, dict) else mi.load_file(str(scene))
            )
        except Exception as err:
            raise ValueError(f"Mitsuba scene '{self.name}' does not load: {err}") from err
        if self._scene.integrator() is None:  # Mitsuba would refuse at the first frame
            raise ValueError(
                f"Mitsuba scene '{self.name}' has no integrator: add one, e.g. "
                f'<integrator type="path"/>'
            )
        box = self._scene.bbox()
        lo, hi = np.array(box.min, np.float64), np.array(box.max, np.float64)
        if not (np.isfinite(lo).all() and np.isfinite(hi).all() and (hi >= lo).all()):
            raise ValueError(
                f"Mitsuba scene '{self.name}' has no shapes (an empty bounding box): nothing to "
                f"orbit"
            )
        center = (lo + hi) / 2 if center is None else center
        radius = np.linalg.norm(hi - lo) / 2 if radius is None else radius
        super().__init__(width, height, channels, center, radius, fov_deg=fov_deg, up=up)
        self._corners = np.array(list(itertools.product(*zip(lo, hi))))  # [8, 3], for the clips
        self._mi, self.spp = mi, int(spp)
        self._sensor = mi.load_dict(
            {
                "type": "perspective",
                "fov": horizontal_fov_deg(self.K, self.width),  # as `intrinsics` frames it
                "fov_axis": "x",
                "film": {
                    "type": "hdrfilm",
                    "width": self.width,
                    "height": self.height,
                    "rfilter": {"type": "box"},
                    "pixel_format": "rgb",
                },
                "sampler": {"type": "independent", "sample_count": self.spp},
            }
        )
        self._params = mi.traverse(self._sensor)
        self._negative_warned = False

    def render(self, viewmat: np.ndarray) -> np.ndarray:
        c2w = np.linalg.inv(viewmat) @ np.diag([-1.0, -1.0, 1.0, 1.0])  # OpenCV -> Mitsuba axes
        self._params["to_world"] = self._mi.ScalarTransform4f(c2w.tolist())
        # clip planes about the scene, in its units: Mitsuba's own, 0.01 and 10⁴, drew a scene in
        # millimetres (radius 2·10⁴) or of radius 10⁻³ as its background alone, unsaid
        far = CLIP_MARGIN * float(np.linalg.norm(self._corners - c2w[:3, 3], axis=1).max())
        self._params["far_clip"], self._params["near_clip"] = far, far * NEAR_OVER_FAR
        self._params.update()
        rgb = np.array(self._mi.render(self._scene, sensor=self._sensor, spp=self.spp, seed=0))
        if not self._negative_warned and (rgb < 0).any():  # a negative emitter's radiance
            self._negative_warned = True
            warnings.warn(
                f"Mitsuba scene '{self.name}' renders {int((rgb < 0).sum())} values below 0 in a "
                f"frame (the lowest {float(rgb.min()):.3g}; a negative emitter?), set to 0: light "
                f"is not negative (said once)",
                stacklevel=2,
            )
        return to_channels(np.maximum(rgb, 0.0), self.channels).astype(np.float32)


def _natural_key(name: str) -> list:
    """`name` split into text and numbers, for sorting r_2 before r_10."""
    return [int(part) if part.isdigit() else part for part in re.split(r"(\d+)", name)]


def warn_if_names_order_the_path(path: Path, names: list[str], viewmats: np.ndarray) -> None:
    """A UserWarning where frames [F] (file names, viewmats [F, 4, 4]) listed in this order make
    a camera path over twice as long as in their names' order: a frame sequence's list is its
    time (the simulated camera runs through it), and a list in another order (COLMAP's, which
    nerfstudio sorts by name on loading) made a camera that jumps between far views."""
    centres = optical_axes(viewmats)[0]  # [F, 3]
    order = sorted(range(len(names)), key=lambda i: _natural_key(names[i]))

    def length(points: np.ndarray) -> float:
        return float(np.linalg.norm(np.diff(points, axis=0), axis=1).sum())

    listed, by_name = length(centres), length(centres[order])
    if listed > 2 * by_name:
        warnings.warn(
            f"{path}: its frames, taken in the listed order as the camera's time, make a path "
            f"{listed / by_name:.1f} times as long as in their file names' order (a list sorted "
            f"otherwise, as COLMAP's is?); sort the frames by name if that is their time order",
            stacklevel=3,
        )


FRAME_TIME_KEYS = ("time", "timestamp")  # a frame's time in other tools' files (D-NeRF's)


def warn_if_frames_timed(path: Path, frames: list[dict]) -> None:
    """A UserWarning where the frames [F] of a transforms file state times of their own (D-NeRF's
    `time`): a frame sequence spreads its frames evenly over the readouts in the listed order,
    and such times were ignored unsaid."""
    keys = sorted({key for frame in frames for key in FRAME_TIME_KEYS if key in frame})
    if keys:
        warnings.warn(
            f"{path}: its frames state {' and '.join(keys)}, which is not read: the frames are "
            f"spread evenly over the readouts in the order listed (resample them to even "
            f"times, in time order, if they are not)",
            stacklevel=3,
        )


class FrameSequenceSource(Source):
    """Rendered frames [F, H, W, C] with poses [F, 4, 4] (world-to-camera, OpenCV), spread evenly
    over the readouts; the light in between is the linear interpolation of the two frames.
    Off-path views are optional test frames with their poses. The scene sphere is `center`,
    `radius` where given, else `view_sphere`'s (views converging on the scene)."""

    kind = "frames"

    def __init__(
        self,
        name: str,
        frames: np.ndarray,
        viewmats: np.ndarray,
        K: np.ndarray,
        *,
        test_views: list[tuple[str, np.ndarray, np.ndarray]] = (),
        center=None,
        radius: float | None = None,
    ):
        frames = not_codes(np.asarray(frames), f"frame sequence '{name}': frames")  # [F, H, W, C]
        frames = frames.astype(np.float32, copy=False)
        viewmats = np.asarray(viewmats, np.float64)  # [F, 4, 4]
        if frames.ndim != 4 or len(frames) < 2:
            raise ValueError(
                f"frames expected [F, H, W, C] with F >= 2, found {list(frames.shape)}"
            )
        if len(viewmats) != len(frames):
            raise ValueError(
                f"frame sequence '{name}': {len(frames)} frames but {len(viewmats)} poses; "
                f"expected one pose per frame"
            )
        Trajectory(np.arange(len(frames)), viewmats, source=name)  # validates the poses now
        height, width, channels = frames.shape[1:]
        center, radius = view_sphere(
            viewmats, f"frame sequence '{name}'", SPHERE_FIX, center=center, radius=radius
        )
        super().__init__(width, height, channels, K, center, radius)
        self.name, self.frames, self.viewmats = name, frames, viewmats
        self._test_views = list(test_views)

    @classmethod
    def from_transforms(
        cls,
        path: str | Path,
        width: int,
        height: int,
        channels: int = 1,
        *,
        background: float = 1.0,
        test_path: str | Path | None = None,
        center=None,
        radius: float | None = None,
    ) -> FrameSequenceSource:
        """Read a NeRF-style transforms JSON (OpenGL camera-to-world unless `"convention":
        "opencv"`), resize the frames to width × height; test frames from `test_path` or a sibling
        transforms_test.json. Integer images are sRGB (decoded) unless tagged linear; alpha
        composited on `background`.
        The scene sphere: `center`, `radius`, else the file's scene_center and scene_radius, else
        `view_sphere`'s."""
        path = Path(path)
        sibling = path.with_name("transforms_test.json")
        test_path = test_path or (sibling if sibling.is_file() and sibling != path else None)
        paths = [path] + ([Path(test_path)] if test_path else [])
        images, poses, K, doc = read_transforms(paths, width, height, channels, background)
        frames, viewmats = images[0], poses[0]
        if len(frames) < 2:  # (said not to converge, then a stack of 1 refused naming no file)
            raise ValueError(
                f"{path}: {len(frames)} frame; a frame sequence needs 2 or more along the "
                f"camera's path (the light between two is interpolated)"
            )
        warn_if_names_order_the_path(path, [f["file_path"] for f in doc["frames"]], viewmats)
        warn_if_frames_timed(path, doc["frames"])
        check_meta_values(doc, path, [k for k in ("scene_center", "scene_radius") if k in doc])
        fix = f"add scene_center [x, y, z] and scene_radius to {path.name}"
        center, radius = view_sphere(
            viewmats,
            path,
            fix,
            center=doc.get("scene_center") if center is None else center,
            radius=doc.get("scene_radius") if radius is None else radius,
            axes_fix=other_convention_fix(path),
        )
        tests = []
        if len(paths) == 2:
            tests = [(f"off_{i:03d}", v, im) for i, (v, im) in enumerate(zip(poses[1], images[1]))]
        return cls(
            # (`--scene .` or `..`: the folder's name; a link's own, not its target's)
            Path(os.path.abspath(path)).parent.name or path.stem,
            frames,
            viewmats,
            K,
            test_views=tests,
            center=center,
            radius=radius,
        )

    def frame_readouts(self, num_readouts: int) -> np.ndarray:
        """Readout [F] of each frame: evenly over [0, num_readouts - 1]."""
        return np.linspace(0.0, num_readouts - 1, len(self.frames))

    def trajectory(self, num_readouts: int, degrees_per_readout: float) -> Trajectory:
        """The frames' own poses (`degrees_per_readout` does not apply)."""
        return Trajectory(self.frame_readouts(num_readouts), self.viewmats, source=self.name)

    def image_at(self, trajectory: Trajectory, t: float) -> np.ndarray:
        u = (t - trajectory.start) / (trajectory.end - trajectory.start) * (len(self.frames) - 1)
        i = min(int(np.floor(u)), len(self.frames) - 2)
        w = u - i
        return (1 - w) * self.frames[i] + w * self.frames[i + 1]

    def light_times(self, num_readouts: int, frame_every: float) -> np.ndarray:
        return self.frame_readouts(num_readouts)

    def on_path_times(self, num_readouts: int, count: int, margin: int) -> np.ndarray:
        readouts = self.frame_readouts(num_readouts)
        inside = readouts[(readouts >= margin) & (readouts <= num_readouts - 1 - margin)]
        if count >= len(inside):
            return inside
        pick = np.unique(np.round(np.linspace(0, len(inside) - 1, count + 2)[1:-1]).astype(int))
        if len(pick) < count:  # picks between the ends repeat: spread over them all instead
            pick = np.round(np.linspace(0, len(inside) - 1, count)).astype(int)
        return inside[pick]

    def off_path_views(self, count: int) -> list[tuple[str, np.ndarray, np.ndarray]]:
        """Up to `count` of the test file's frames (wherever the path goes), evenly over its
        list, each named by its place there (off_NNN): its first `count` saw 126° of a ring of 20
        listed in order (the scene-sources trial)."""
        listed = len(self._test_views)
        pick = np.round(np.linspace(0, listed - 1, min(count, listed))).astype(int)
        return [self._test_views[i] for i in np.unique(pick)]
