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

import math
import warnings
from abc import ABC, abstractmethod
from pathlib import Path

import numpy as np
import skimage.transform
import torch

from ..image_io import read_stored_image, srgb_to_linear
from ..missing_dependency import MissingDependencyError
from ..number_checks import is_number, number_array
from ..rasterize import rasterize
from ..spikes.simulate import sample_times
from .dataset import check_intrinsics, check_meta_values, intrinsics_keys
from .scenes import GaussianScene
from .trajectory import Trajectory, look_at, orbit_eye, read_json, rigid_c2w

LUMA_709 = np.array([0.2126, 0.7152, 0.0722])
IMAGE_EXTENSIONS = (
    ".png",
    ".exr",
    ".jpg",
    ".jpeg",
    ".tif",
    ".tiff",
)  # tried in turn after an extensionless path
OPENGL_TO_OPENCV = np.diag([1.0, -1.0, -1.0, 1.0])  # camera axes: y up, z back -> y down, z forward
CONVERGING = 0.03  # smallest eigenvalue of mean(I - d d^T) over view directions d: inward-facing
# the least spread whose nearest point of the axes a scene sphere is taken from where no depth
# bounds give another (NeRF layout, simulate): below it (directions within ~2°, forward-facing
# or parallel) that point is set by the poses' noise. A 30° inward arc, a ring seen from 82°
# elevation spread 0.02-0.07, forward-facing views jittered by 1° ~3e-4
AXES_SPREAD_MIN = 1e-3
SPHERE_FIX = "pass center and radius (the scene sphere) to FrameSequenceSource"
SIMULATE_ASPECT_FIX = "simulate spikes of that aspect ratio (height, width; --height, --width)"
CAMERA_KEYS = ("camera_angle_x", "fl_x", "fl_y", "cx", "cy", "w", "h")
DISTORTION_KEYS = ("k1", "k2", "k3", "k4", "p1", "p2")
# nerfstudio's camera models that are a pinhole (with distortion, warned of where not zero); the
# others (fisheye, equirectangular, ...) a pinhole rasterizer cannot render
PINHOLE_MODELS = ("PINHOLE", "SIMPLE_PINHOLE", "OPENCV", "FULL_OPENCV", "SIMPLE_RADIAL", "RADIAL")
CAMERA_RANGES = {  # key: (in range, what is expected)
    "camera_angle_x": (lambda v: 0 < v < math.pi, "in (0, pi) radians"),
    "fl_x": (lambda v: v > 0, "> 0 (pixels)"),
    "fl_y": (lambda v: v > 0, "> 0 (pixels)"),
    "w": (lambda v: v > 0 and v.is_integer(), "a positive integer (pixels)"),
    "h": (lambda v: v > 0 and v.is_integer(), "a positive integer (pixels)"),
}


def to_channels(rgb: np.ndarray, channels: int) -> np.ndarray:
    """Linear RGB [..., 3] -> [..., channels]: Rec. 709 luma for 1, unchanged for 3."""
    if channels == 3:
        return rgb
    if channels == 1:
        return rgb @ LUMA_709[:, None]
    raise ValueError(f"channels expected 1 (mono) or 3 (colour), found {channels}")


def intrinsics(width: int, height: int, fov_x_deg: float) -> np.ndarray:
    """K [3, 3] of a pinhole with horizontal field of view `fov_x_deg`, square pixels, centred."""
    f = width / 2 / np.tan(np.radians(fov_x_deg) / 2)
    return np.array([[f, 0.0, width / 2], [0.0, f, height / 2], [0.0, 0.0, 1.0]])


class Source(ABC):
    """Ground truth for a dataset of `width` × `height` pixels, `channels` 1 (mono) or 3."""

    name: str
    kind: str

    def __init__(self, width: int, height: int, channels: int, K: np.ndarray, center, radius):
        if channels not in (1, 3):
            raise ValueError(f"channels expected 1 (mono) or 3 (colour), found {channels}")
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
    """A source that renders any pose: an ascending spiral around the scene, off-path views on
    a wider circle at mid elevation."""

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
    ):
        super().__init__(
            width, height, channels, intrinsics(width, height, fov_deg), center, radius
        )
        self.distance = distance * self.scene_radius  # camera to scene centre
        self.elevation_deg = elevation_deg

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
        )

    def image_at(self, trajectory: Trajectory, t: float) -> np.ndarray:
        return self.render(trajectory.pose_at(t))

    def light_times(self, num_readouts: int, frame_every: float) -> np.ndarray:
        return sample_times(num_readouts, frame_every)

    def on_path_times(self, num_readouts: int, count: int, margin: int) -> np.ndarray:
        return np.round(np.linspace(margin, num_readouts - 1 - margin, count + 2)[1:-1])

    def off_path_views(self, count: int) -> list[tuple[str, np.ndarray, np.ndarray]]:
        views = []
        elevation = float(np.mean(self.elevation_deg))
        for i in range(count):
            eye = orbit_eye(
                self.scene_center, 1.2 * self.distance, 360 * (i + 0.5) / count, elevation
            )
            viewmat = look_at(eye, self.scene_center)
            views.append((f"off_{i:03d}", viewmat, self.render(viewmat)))
        return views


class ProceduralSource(RenderSource):
    """A built-in Gaussian scene rendered by the project's rasterizer."""

    kind = "procedural"

    def __init__(self, name: str, scene: GaussianScene, width: int, height: int, channels: int = 1):
        super().__init__(width, height, channels, scene.center, scene.radius)
        self.name = name
        tensor = lambda a: torch.as_tensor(np.asarray(a), dtype=torch.float32)  # noqa: E731
        self._gaussians = [
            tensor(a) for a in (scene.means, scene.quats, scene.scales, scene.opacities)
        ]
        self._colors = tensor(to_channels(scene.colors, channels))  # [N, C]
        self._background = tensor(to_channels(scene.background, channels))  # [C]
        self._K = tensor(self.K)

    def render(self, viewmat: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            out = rasterize(
                *self._gaussians,
                self._colors,
                torch.as_tensor(viewmat, dtype=torch.float32),
                self._K,
                self.width,
                self.height,
                background=self._background,
            )
        return out.image.numpy()


def import_mitsuba():
    """Mitsuba 3 with the `scalar_rgb` variant set (the llvm_* variants fail with Debian's LLVM)."""
    try:
        import mitsuba as mi
    except ImportError as err:
        raise MissingDependencyError(
            "a Mitsuba scene needs Mitsuba 3, which is not installed: "
            "pip install 'spikegs[mitsuba]' (or pip install mitsuba)"
        ) from err
    mi.set_variant("scalar_rgb")
    return mi


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
    ):
        mi = import_mitsuba()
        if not isinstance(scene, dict) and not Path(scene).is_file():
            raise FileNotFoundError(f"Mitsuba scene file not found: {scene}")
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
        super().__init__(width, height, channels, center, radius, fov_deg=fov_deg)
        self._mi, self._spp = mi, int(spp)
        self._sensor = mi.load_dict(
            {
                "type": "perspective",
                "fov": fov_deg,
                "fov_axis": "x",
                "film": {
                    "type": "hdrfilm",
                    "width": self.width,
                    "height": self.height,
                    "rfilter": {"type": "box"},
                    "pixel_format": "rgb",
                },
                "sampler": {"type": "independent", "sample_count": self._spp},
            }
        )
        self._params = mi.traverse(self._sensor)
        self._negative_warned = False

    def render(self, viewmat: np.ndarray) -> np.ndarray:
        c2w = np.linalg.inv(viewmat) @ np.diag([-1.0, -1.0, 1.0, 1.0])  # OpenCV -> Mitsuba axes
        self._params["to_world"] = self._mi.ScalarTransform4f(c2w.tolist())
        self._params.update()
        rgb = np.array(self._mi.render(self._scene, sensor=self._sensor, spp=self._spp, seed=0))
        if not self._negative_warned and (rgb < 0).any():  # a negative emitter's radiance
            self._negative_warned = True
            warnings.warn(
                f"Mitsuba scene '{self.name}' renders {int((rgb < 0).sum())} values below 0 in a "
                f"frame (the lowest {float(rgb.min()):.3g}; a negative emitter?), set to 0: light "
                f"is not negative (said once)",
                stacklevel=2,
            )
        return to_channels(np.maximum(rgb, 0.0), self.channels).astype(np.float32)


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
        frames = np.asarray(frames, np.float32)  # [F, H, W, C]
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
        transforms_test.json. 8-bit images are sRGB (decoded); alpha composited on `background`.
        The scene sphere: `center`, `radius`, else the file's scene_center and scene_radius, else
        `view_sphere`'s."""
        path = Path(path)
        frames, viewmats, K, doc = _read_transforms(path, width, height, channels, background)
        check_meta_values(doc, path, [k for k in ("scene_center", "scene_radius") if k in doc])
        fix = f"add scene_center [x, y, z] and scene_radius to {path.name}"
        center, radius = view_sphere(
            viewmats,
            path,
            fix,
            center=doc.get("scene_center") if center is None else center,
            radius=doc.get("scene_radius") if radius is None else radius,
        )
        sibling = path.with_name("transforms_test.json")
        test_path = test_path or (sibling if sibling.is_file() and sibling != path else None)
        tests = []
        if test_path:
            images, poses, test_K, _ = _read_transforms(
                Path(test_path), width, height, channels, background
            )
            if not np.allclose(test_K, K, rtol=1e-6, atol=0):  # both at width × height
                raise ValueError(
                    f"{test_path}: its camera (fx, fy, cx, cy at {width}x{height}: "
                    f"{_intrinsics_text(test_K)}) differs from {path}'s "
                    f"({_intrinsics_text(K)}); one camera expected"
                )
            tests = [(f"off_{i:03d}", v, im) for i, (v, im) in enumerate(zip(poses, images))]
        return cls(
            path.parent.name or path.stem,
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
        return self._test_views[:count]


def optical_axes(viewmats: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Camera centres [F, 3], view directions [F, 3] and the projections I - d d^T [F, 3, 3]
    across each optical axis, of world-to-camera viewmats [F, 4, 4]."""
    c2w = np.linalg.inv(viewmats)  # [F, 4, 4]
    eyes, dirs = c2w[:, :3, 3], c2w[:, :3, 2]  # [F, 3] each
    return eyes, dirs, np.eye(3) - dirs[:, :, None] * dirs[:, None, :]


def centre_of_view(viewmats: np.ndarray) -> tuple[np.ndarray, float]:
    """The point [3] nearest to all optical axes, and the mean camera distance to it / 2.5
    (the scene radius that the spiral sources see from their distance of 2.5 radii)."""
    eyes, _, proj = optical_axes(viewmats)
    center = np.linalg.lstsq(proj.sum(0), np.einsum("fij,fj->i", proj, eyes), rcond=None)[0]
    return center, float(np.linalg.norm(eyes - center, axis=1).mean() / 2.5)


def converging_centre(
    viewmats: np.ndarray, min_spread: float = CONVERGING
) -> tuple[np.ndarray, float] | None:
    """`centre_of_view` of viewmats [F, 4, 4] when their optical axes converge in front of every
    camera: view directions spread (`min_spread`; CONVERGING, about ±20°, for LLFF, which has depth
    bounds to fall back on) and the point ahead of each; else None (forward-facing views: the
    nearest point is set by noise, often behind them)."""
    eyes, dirs, proj = optical_axes(viewmats)  # [F, 3], [F, 3], [F, 3, 3]
    center, radius = centre_of_view(viewmats)
    ahead = np.einsum("fi,fi->f", center - eyes, dirs) > 0  # [F]
    spread = np.linalg.eigvalsh(proj.mean(0))[0] >= min_spread
    return (center, radius) if spread and ahead.all() else None


def view_sphere(
    viewmats: np.ndarray, source, fix: str, *, center=None, radius: float | None = None
) -> tuple[np.ndarray, float]:
    """The scene sphere's centre [3] and radius: `center`, `radius` where given (a centre needs
    its radius; a radius alone keeps the computed centre), else `converging_centre`'s; ValueError
    naming `source` and how to `fix` it when one is needed and the optical axes of viewmats
    [F, 4, 4] do not converge in front of the cameras."""
    if radius is not None and not (is_number(radius) and radius > 0):
        raise ValueError(f"{source}: scene radius expected a finite number > 0, found {radius!r}")
    if center is not None:
        try:
            given = number_array(center)
        except ValueError:  # text, booleans, ragged lists
            given = np.full(1, np.nan)
        if given.shape != (3,) or not np.isfinite(given).all():
            raise ValueError(f"{source}: scene centre expected 3 finite numbers, found {center!r}")
    if center is not None and radius is not None:
        return given, float(radius)
    if center is not None:
        raise ValueError(
            f"{source}: a scene centre needs its radius (the radius computed from the views is "
            f"about the centre computed with it); {fix}"
        )
    converged = converging_centre(viewmats, AXES_SPREAD_MIN)
    if converged is None:
        eyes, dirs, _ = optical_axes(viewmats)  # [F, 3], [F, 3]
        position, direction = (
            (np.round(v, 3) + 0.0).tolist()  # + 0.0: no -0.0
            for v in (eyes.mean(0), dirs.mean(0) / np.linalg.norm(dirs.mean(0)))
        )
        raise ValueError(
            f"{source}: the cameras' optical axes do not converge in front of them (forward-facing "
            f"or parallel views, directions within about ±2°, or axes whose nearest point lies "
            f"behind a camera), so the scene's centre and size are unknown; {fix} (the "
            f"cameras' mean position is {position}, their mean viewing direction {direction}: a "
            f"scene D ahead of them is centred at position + D * direction)"
        )
    return converged[0], converged[1] if radius is None else float(radius)


TRANSFORMS = ("transforms_train.json", "transforms_test.json", "transforms.json")  # NeRF layout


def warn_unread_transforms(root: Path, read: list[Path]) -> None:
    """A UserWarning naming the TRANSFORMS files in `root` that are not among `read` (the files
    taken: transforms_train.json + transforms_test.json, else one file)."""
    unread = [name for name in TRANSFORMS if (root / name).is_file() and root / name not in read]
    if unread:
        taken = ", ".join(p.name for p in read if p.is_file())
        warnings.warn(
            f"{root}: reading {taken}; {', '.join(unread)} not read (the layout takes "
            f"transforms_train.json + transforms_test.json, else one file)",
            stacklevel=3,
        )


def read_transforms_doc(path: Path) -> dict:
    """A transforms JSON (NeRF / nerfstudio); FileNotFoundError, or ValueError naming `path`
    unless it is an object with a non-empty list of frames, each with a file_path (text) and a
    transform_matrix."""
    if not path.is_file():
        raise FileNotFoundError(f"transforms file not found: {path}")
    doc = read_json(path)
    if not isinstance(doc.get("frames", []), list):
        raise ValueError(f"{path}: expected a JSON object with a list of frames")
    for i, frame in enumerate(doc.get("frames") or []):
        if not (
            isinstance(frame, dict)
            and isinstance(frame.get("file_path"), str)
            and "transform_matrix" in frame
        ):
            raise ValueError(f"{path}: frame {i} needs a file_path (text) and a transform_matrix")
    if not doc.get("frames"):
        raise ValueError(f"{path}: no frames")
    return doc


def _transform_matrix(path: Path, i: int, frame: dict) -> np.ndarray:
    """Frame i's transform_matrix [4, 4]; ValueError naming the frame if it is not 4x4 numbers."""
    try:
        matrix = number_array(frame["transform_matrix"])
    except (ValueError, TypeError):
        matrix = None
    if matrix is None or matrix.shape != (4, 4):
        raise ValueError(
            f"{path}: frame {i} ('{frame['file_path']}'): transform_matrix expected 4 rows of 4 "
            f"numbers, found {frame['transform_matrix']!r}"[:300]
        )
    return matrix


def transforms_viewmats(path: Path, doc: dict) -> np.ndarray:
    """OpenCV world-to-camera viewmats [F, 4, 4] of a transforms document's frames (`path` names
    it in errors); rounded rotations made exactly rigid, other ones refused."""
    c2w = np.stack([_transform_matrix(path, i, f) for i, f in enumerate(doc["frames"])])
    bad = np.flatnonzero(~np.isfinite(c2w).all(axis=(1, 2)))  # c2w [F, 4, 4]
    if bad.size:
        raise ValueError(f"{path}: non-finite (NaN/inf) transform_matrix in frames {bad.tolist()}")
    if is_opengl(path, doc):
        c2w = c2w @ OPENGL_TO_OPENCV
    return np.linalg.inv(rigid_c2w(c2w, str(path), "frame"))


def _intrinsics_text(K: np.ndarray) -> str:
    """fx, fy, cx, cy of a camera matrix [3, 3], for a message."""
    return ", ".join(f"{v:.6g}" for v in intrinsics_keys(K).values())


def _camera_text(camera: dict) -> str:
    """A transforms file's camera keys and their numbers, for a message: 'w 48, fl_x 40.5'."""
    return ", ".join(f"{key} {value:.6g}" for key, value in camera.items())


def _read_transforms(path: Path, width: int, height: int, channels: int, background: float):
    """Frames [F, height, width, C], viewmats [F, 4, 4] (OpenCV), K [3, 3] and the document of a
    transforms JSON."""
    doc = read_transforms_doc(path)
    frames = doc["frames"]
    viewmats = transforms_viewmats(path, doc)  # [F, 4, 4]
    camera = read_camera([doc] * len(frames), frames, [path] * len(frames))
    src, what = stated_size(path, camera, "its first frame")
    images, negative = [], []  # negative: (file, values below 0, the lowest) of each frame
    for f in frames:
        image = read_frame(path.parent / f["file_path"], background)  # [h, w, 3]
        if (image < 0).any():  # a renderer's or denoiser's round-off in float images (EXR)
            negative.append((f["file_path"], int((image < 0).sum()), float(image.min())))
            image = np.maximum(image, 0.0)
        src = src or image.shape[:2]  # the camera's w, h, else the first frame's size
        if not images:  # the aspect ratio checked before any frame is resized (no crop here)
            frame_columns(path, what, src, (height, width), SIMULATE_ASPECT_FIX)
        image = fitted(image, src, (height, width), f"{path.parent / f['file_path']}")
        images.append(to_channels(image, channels))
    if negative:
        warnings.warn(
            f"{path}: {len(negative)} frame(s) hold {sum(n for _, n, _ in negative)} values below "
            f"0 (the lowest {min(low for *_, low in negative):.3g}, first in "
            f"{negative[0][0]}), set to 0: light is not negative",
            stacklevel=3,
        )
    K = camera_matrix(path, camera, src, (height, width))
    return np.stack(images).astype(np.float32), viewmats, K, doc


def camera_number(path: Path, key: str, value) -> float:
    """A transforms file's camera value as a finite float, in CAMERA_RANGES for its key;
    ValueError naming `key` otherwise (camera_angle_x over pi: degrees, not radians?)."""
    number = float(value) if is_number(value) else math.nan  # "0.4" is text, true no number
    if not math.isfinite(number):
        raise ValueError(f"{path}: {key} expected a finite number, found {value!r}")
    in_range, expected = CAMERA_RANGES.get(key, (lambda v: True, ""))
    if not in_range(number):
        degrees = key == "camera_angle_x" and number >= math.pi
        hint = f" ({number:g} degrees would be {math.radians(number):.6g})" if degrees else ""
        raise ValueError(f"{path}: {key} expected {expected}, found {value!r}{hint}")
    return number


def is_opengl(path: Path, doc: dict) -> bool:
    """Whether a transforms file's camera-to-world matrices are OpenGL's (y up, z back: the
    default) or OpenCV's ("convention": "opencv"); ValueError naming the file for another value."""
    convention = doc.get("convention", "opengl")
    if not isinstance(convention, str) or convention.lower() not in ("opengl", "opencv"):
        raise ValueError(f"{path}: convention {convention!r}, expected 'opengl' or 'opencv'")
    return convention.lower() == "opengl"


def fitted(image: np.ndarray, src: tuple, size: tuple, name: str) -> np.ndarray:
    """`image` [h, w, C] resized to (h, w) `size` if need be; ValueError naming it (`name`) unless
    it has the aspect ratio of the camera's (h, w) `src` (its width within a pixel or 1 % of the
    camera's aspect at its height): another aspect ratio is another crop of the view, which
    resizing would stretch."""
    (h, w), (src_h, src_w) = image.shape[:2], src
    if abs(w - h * src_w / src_h) > max(1.0, 0.01 * w):
        raise ValueError(
            f"{name}: image {w}x{h} (aspect {w / h:.3f}), the camera's images are {src_w}x"
            f"{src_h} (aspect {src_w / src_h:.3f}): an image of another aspect ratio shows "
            f"another crop of the view; crop or pad it to the camera's"
        )
    if (h, w) == tuple(size):
        return image
    return skimage.transform.resize(image, size, anti_aliasing=True)


def read_camera(docs: list, frames: list, sources: list) -> dict:
    """The one camera {key: number} of frames [F] (CAMERA_KEYS, DISTORTION_KEYS): the first frame's
    file's keys (docs [F], each frame's file's JSON; sources [F], its path), the frame's own file's,
    then the frame's (nerfstudio), each checked (`camera_number`); ValueError naming two frames that
    differ or a camera_model that is not a pinhole; a warning for non-zero distortion, which the
    pinhole rasterizer does not model."""
    for doc, frame, source in zip(docs, frames, sources):
        model = {**docs[0], **doc, **frame}.get("camera_model", "PINHOLE")
        if model not in PINHOLE_MODELS:
            raise ValueError(
                f"{source}: camera_model {model!r} of frame '{frame['file_path']}': the "
                f"rasterizer renders pinhole cameras ({', '.join(PINHOLE_MODELS)}); rectify the "
                f"frames to one"
            )
    keys = CAMERA_KEYS + DISTORTION_KEYS
    merged = [
        {k: v for d in (docs[0], doc, frame) for k, v in d.items() if k in keys}
        for doc, frame in zip(docs, frames)
    ]
    cameras = [
        {k: camera_number(src, k, v) for k, v in c.items()} for c, src in zip(merged, sources)
    ]
    for i, camera in enumerate(cameras):
        if camera.keys() != cameras[0].keys() or not np.allclose(
            [camera[k] for k in camera], [cameras[0][k] for k in camera], rtol=1e-6
        ):
            raise ValueError(
                f"{sources[i]}: frame '{frames[i]['file_path']}' has intrinsics "
                f"{_camera_text(camera)}, frame '{frames[0]['file_path']}' of {sources[0]} "
                f"{_camera_text(cameras[0])}: one camera expected"
            )
    distortion = {k: cameras[0][k] for k in DISTORTION_KEYS if cameras[0].get(k, 0) != 0}
    if distortion:
        warnings.warn(
            f"{sources[0]}: distortion {distortion} ignored: the rasterizer assumes a pinhole "
            f"camera (undistort the spikes' frames to model it)",
            stacklevel=3,
        )
    return cameras[0]


def stated_size(path: Path, camera: dict, image: str) -> tuple[tuple[int, int] | None, str]:
    """(h, w) of the images a camera's intrinsics are for, from its w and h (None without them,
    the size of `image` then), and what gives it (for `frame_columns`); ValueError naming `path`
    when the camera gives one of w, h alone."""
    if ("w" in camera) != ("h" in camera):
        raise ValueError(f"{path}: w and h expected together (the intrinsics' image size)")
    if "w" not in camera:
        return None, f"the camera (sized as {image})"
    return (int(camera["h"]), int(camera["w"])), "the camera (its w, h)"


def frame_columns(
    source, what: str, src: tuple, size: tuple, fix: str, raw_width=None, col_offset: int = 0
) -> tuple[int, int]:
    """(width, first column) of frames of `size` (h, w) within images of `src` (h, w) resized to
    their height: (w, 0), or (raw_width, col_offset) for a raw-row crop (src's width at that height
    within a pixel of raw_width's, not of w's); a crop keeps the focal. ValueError naming `source`
    and `what` src is, saying how to `fix` it, when neither is within a pixel: another aspect
    ratio, the focal would differ in x and y (non-square pixels)."""
    (src_h, src_w), (height, width) = src, size
    scaled = src_w * height / src_h  # the images' width at the frames' height
    crop = raw_width is not None and raw_width != width and abs(scaled - raw_width) <= 1
    frame, shift = (raw_width, col_offset) if crop else (width, 0)
    if abs(scaled - frame) > 1:
        stored = f" (or the {raw_width} stored pixels of a row, raw_width)" if raw_width else ""
        raise ValueError(
            f"{source}: {what} is for {src_h:g}x{src_w:g} images (height x width), of another "
            f"aspect ratio than the {height}x{width} spikes{stored}: {src_w / src_h:.4g} vs "
            f"{width / height:.4g}, the focal would differ in x and y (non-square pixels); {fix}"
        )
    return frame, shift


def camera_matrix(
    path: Path, camera: dict, src: tuple, size: tuple, shift: float = 0
) -> np.ndarray:
    """K [3, 3] of a transforms file's `camera` (`read_camera`'s keys: fl_x, fl_y, cx, cy, or
    camera_angle_x) for images of `src` (h, w), scaled to `size` (h, w) and moved `shift` columns
    left (a crop, `frame_columns`); cx, cy default to the image centre."""
    (src_h, src_w), (height, width) = src, size
    get = lambda key, default: camera_number(path, key, camera.get(key, default))  # noqa: E731
    from_angle = None  # the focal (px) of camera_angle_x at the images' width
    if "camera_angle_x" in camera:
        from_angle = src_w / 2 / np.tan(get("camera_angle_x", None) / 2)
    if "fl_x" in camera or "fl_y" in camera:  # one focal given: square pixels
        fx = get("fl_x", camera.get("fl_y"))
        fy = get("fl_y", fx)
        if from_angle is not None and abs(from_angle - fx) > 0.01 * fx:
            warnings.warn(
                f"{path}: fl_x {fx:g} and camera_angle_x (a focal of {from_angle:.6g} px at "
                f"width {src_w:g}) disagree; fl_x is used",
                stacklevel=2,
            )
    elif from_angle is not None:
        fx = fy = from_angle
    else:
        raise ValueError(
            f"{path}: intrinsics expected (camera_angle_x, or fl_x/fl_y/cx/cy, in the file or "
            f"in every frame)"
        )
    cx, cy = get("cx", src_w / 2), get("cy", src_h / 2)
    sx, sy = width / src_w, height / src_h
    K = np.array([[fx * sx, 0.0, cx * sx - shift], [0.0, fy * sy, cy * sy], [0.0, 0.0, 1.0]])
    check_intrinsics(K, height, width, path)
    return K


def read_frame(base: Path, background: float) -> np.ndarray:
    """Linear RGB [h, w, 3] of an image file (extension optional, as in NeRF synthetic), an alpha
    channel composited over `background` in linear light, colour read as the file's metadata
    says: sRGB or linear, associated with alpha (EXR) or not (PNG)."""
    candidates = [base] + [base.with_name(base.name + ext) for ext in IMAGE_EXTENSIONS]
    files = [p for p in candidates if p.is_file()]
    if not files:
        raise FileNotFoundError(
            f"frame image not found: {base} (tried {', '.join(IMAGE_EXTENSIONS)})"
        )
    found = files[0]
    if len(files) > 1 and found != base:  # one message per folder, not per frame
        warnings.warn(
            f"{base.parent}: frame images in several formats "
            f"({', '.join(p.suffix for p in files)}): {found.suffix} is read, the first of "
            f"{', '.join(IMAGE_EXTENSIONS)}",
            stacklevel=2,
        )
    stored = read_stored_image(found)
    colour = np.broadcast_to(stored.colour, (*stored.colour.shape[:2], 3)).astype(np.float64)
    alpha = None if stored.alpha is None else stored.alpha.astype(np.float64)  # [h, w, 1]
    if stored.srgb:
        if stored.premultiplied and alpha is not None:  # sRGB units of colour * alpha
            colour = np.divide(colour, alpha, out=np.zeros_like(colour), where=alpha > 0)
        colour = srgb_to_linear(colour)
    if alpha is not None:
        associated = stored.premultiplied and not stored.srgb
        colour = (colour if associated else colour * alpha) + background * (1 - alpha)
    return colour  # [h, w, 3]
