"""Continuous camera trajectories: poses recorded at readouts, slerp/linear in between.

Poses are OpenCV cameras (x right, y down, z forward). In memory a pose is the world-to-camera
`viewmat` [4, 4]; on disk (`save_json`) it is the camera-to-world `transform_matrix`, in the
nerfstudio-like layout with a `readout` per frame and `"convention": "opencv"` stated.
"""

from __future__ import annotations

import json
import math
import os
import warnings
from collections.abc import Iterable
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from ..atomic_save import write_atomically
from ..number_checks import holds_bool, is_number, number_array
from ..strict_json import json_text, read_json

PathLike = str | os.PathLike
CONVENTION = "opencv"
FRAME_KEYS = ("readout", "transform_matrix")  # what every frame of a trajectory file holds
WORLD_UP = np.array([0.0, 0.0, 1.0])  # the spiral ascends along +z


def look_at(eye, target, up=WORLD_UP) -> np.ndarray:
    """World-to-camera viewmat [4, 4] of an OpenCV camera at `eye` looking at `target`."""
    eye, target = np.asarray(eye, np.float64), np.asarray(target, np.float64)
    forward = target - eye
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, up)
    norm = np.linalg.norm(right)
    if norm < 1e-9:
        raise ValueError(f"look_at: the view direction {forward} is parallel to up {up}")
    right /= norm
    down = np.cross(forward, right)
    c2w = np.eye(4)
    c2w[:3, :3] = np.stack([right, down, forward], axis=1)
    c2w[:3, 3] = eye
    return np.linalg.inv(c2w)


def unit_vector(name: str, value) -> np.ndarray:
    """`value` as a unit vector [3]; ValueError naming `name` unless it is a finite, non-zero
    vector of 3 numbers."""
    try:
        v = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        v = np.zeros(0)
    largest = float(np.abs(v).max()) if v.shape == (3,) else 0.0
    if not (math.isfinite(largest) and largest > 0):
        raise ValueError(f"{name}: expected a non-zero direction [x, y, z], found {value!r}")
    v = v / largest  # (1e308 components: their norm overflowed)
    return v / np.linalg.norm(v)


def up_rotation(up) -> np.ndarray:
    """The rotation [3, 3] that turns +z into the direction `up` [3] by the shortest arc (the
    identity, exactly, for +z; a half turn about x for -z)."""
    up = unit_vector("up", up)
    if np.array_equal(up, WORLD_UP):
        return np.eye(3)
    cross = np.cross(WORLD_UP, up)  # sin times the unit axis
    sin = float(np.linalg.norm(cross))
    axis = cross / sin if sin > 0 else np.array([1.0, 0.0, 0.0])  # -z: about x
    angle = math.atan2(sin, float(up @ WORLD_UP))  # accurate near -z too, unlike 1 / (1 + cos)
    return Rotation.from_rotvec(angle * axis).as_matrix()


def orbit_eye(center, radius: float, azimuth_deg, elevation_deg, up=WORLD_UP) -> np.ndarray:
    """Camera centres [..., 3] on a sphere of `radius` around `center`, at `elevation_deg` above
    the plane normal to unit `up` [3] (+z: azimuth from +x towards +y; another up turns that
    frame by `up_rotation`)."""
    az, el = np.broadcast_arrays(np.radians(azimuth_deg), np.radians(elevation_deg))
    offset = np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], axis=-1)
    if not np.array_equal(up, WORLD_UP):
        offset = offset @ up_rotation(up).T
    return np.asarray(center, np.float64) + radius * offset


RIGID_TOLERANCE = 1e-3  # of |R R^T - I|: accepts poses rounded to 4 decimals


def project_points(points, viewmats, K) -> tuple[np.ndarray, np.ndarray]:
    """Pixel positions [F, P, 2] (OpenCV: pixel centres at +0.5) and depths [F, P] of world points
    [P, 3] in the cameras `viewmats` [F, 4, 4] with intrinsics K [3, 3]; NaN positions for points
    at or behind a camera's centre (depth <= 0)."""
    points = np.asarray(points, np.float64)
    viewmats = np.asarray(viewmats, np.float64)
    cam = np.einsum("fij,pj->fpi", viewmats[:, :3, :3], points) + viewmats[:, None, :3, 3]
    z = cam[..., 2:]  # [F, P, 1]
    focal, centre = np.diag(K)[:2].astype(np.float64), np.asarray(K, np.float64)[:2, 2]
    pixels = cam[..., :2] * focal / np.where(z > 0, z, np.nan) + centre
    return pixels, z[..., 0]


def pixel_rays(u, v, K) -> np.ndarray:
    """Camera-space directions [..., 3] (z = 1) through pixel positions `u`, `v` [...] (OpenCV,
    as `project_points` gives them) of intrinsics K [3, 3]: the inverse of its projection."""
    u, v = np.asarray(u, np.float64), np.asarray(v, np.float64)
    return np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], np.ones_like(u)], -1)


def point_parts(points: np.ndarray, size: int = 65536) -> list[np.ndarray]:
    """Points [P, 3] in consecutive parts of at most `size`: projected into F views, a part's
    temporaries are [F, size, 3] float64 (31 views: 49 MB), the whole cloud's could be GBs."""
    return np.array_split(points, max(1, -(-len(points) // size)))


def pixels_in_view(points, viewmats, K, width: int, height: int):
    """Pixel columns u and rows v [F, P] (whole numbers as floats; NaN behind a camera) of world
    points [P, 3] in the cameras `viewmats` [F, 4, 4], and whether each lands in front of the
    camera inside its width x height image [F, P] bool."""
    pixels, z = project_points(points, viewmats, K)
    u, v = np.floor(pixels[..., 0]), np.floor(pixels[..., 1])
    inside = (z > 0) & (u >= 0) & (u < width) & (v >= 0) & (v < height)  # any unit: no 1e-6
    return u, v, inside


def rigid_c2w(matrices: np.ndarray, source: str, item: str = "view") -> np.ndarray:
    """`matrices` [N, 4, 4] or [4, 4] (camera-to-world or world-to-camera) with each rotation
    replaced by the nearest rotation (SVD), translation kept, when within RIGID_TOLERANCE of one
    (rounded poses); else ValueError naming `source`, the worst `item` index and its deviation.
    The one rigidity rule of every loader: check here before inverting."""
    matrices = np.asarray(matrices, np.float64)
    flat = matrices.reshape(-1, 4, 4)  # [N, 4, 4]
    rot = flat[:, :3, :3]
    with np.errstate(invalid="ignore"):
        deviation = np.abs(rot @ rot.transpose(0, 2, 1) - np.eye(3)).max(axis=(1, 2))  # [N]
        deviation = np.maximum(deviation, np.abs(flat[:, 3] - [0, 0, 0, 1]).max(axis=1))
    deviation[~np.isfinite(flat).all(axis=(1, 2))] = np.inf  # NaN/inf
    det = np.linalg.det(np.where(np.isfinite(rot), rot, 0.0))  # [N]
    bad = np.flatnonzero((deviation > RIGID_TOLERANCE) | (det <= 0))
    if bad.size:
        i = bad[np.argmax(deviation[bad])]
        batch = matrices.ndim == 3
        detail = (
            "non-finite values (NaN/inf)"
            if np.isinf(deviation[i])
            else f"max |R R^T - I| (and bottom row vs [0, 0, 0, 1]) = {deviation[i]:.3g} "
            f"(tolerance {RIGID_TOLERANCE}), det R = {det[i]:.4g}"
        )
        others = f"; every {item} refused: {bad[:10].tolist()}{' ...' if bad.size > 10 else ''}"
        raise ValueError(
            f"{source}: the pose{f' of {item} {i}' if batch else ''} is not rigid (a rotation and "
            f"translation): {detail}{others if batch and bad.size > 1 else ''}"
        )
    u, _, vt = np.linalg.svd(rot)
    out = flat.copy()
    out[:, :3, :3] = u @ vt
    out[:, 3] = [0.0, 0.0, 0.0, 1.0]
    return out.reshape(matrices.shape)


def check_rigid(matrices: np.ndarray, source: str, item: str = "view") -> None:
    """ValueError as `rigid_c2w`'s unless every matrix [..., 4, 4] is within RIGID_TOLERANCE of
    rigid."""
    rigid_c2w(matrices, source, item)


class Trajectory:
    """Camera poses at increasing readouts [P]; `pose_at(t)` interpolates between them."""

    def __init__(self, readouts: np.ndarray, viewmats: np.ndarray, *, source: str = "poses"):
        readouts = np.asarray(readouts, np.float64).reshape(-1)  # [P]
        viewmats = np.asarray(viewmats, np.float64)  # [P, 4, 4]
        if viewmats.shape != (len(readouts), 4, 4) or len(readouts) == 0:
            raise ValueError(
                f"{source}: expected readouts [P] and viewmats [P, 4, 4] with P >= 1, found "
                f"{list(readouts.shape)} and {list(viewmats.shape)}"
            )
        if not np.isfinite(readouts).all():
            raise ValueError(f"{source}: non-finite readouts (NaN/inf)")
        if (np.diff(readouts) <= 0).any():
            raise ValueError(f"{source}: readouts expected strictly increasing")
        check_rigid(viewmats, source, "index")  # loaders project rounded poses; these stay as given
        c2w = np.linalg.inv(viewmats)  # [P, 4, 4]
        rot = c2w[:, :3, :3]
        self.readouts = readouts
        self.viewmats = viewmats
        self._rotations = Rotation.from_matrix(rot)  # camera-to-world [P]
        self._centers = c2w[:, :3, 3]  # [P, 3]

    def __len__(self) -> int:
        return len(self.readouts)

    @property
    def start(self) -> float:
        return float(self.readouts[0])

    @property
    def end(self) -> float:
        return float(self.readouts[-1])

    def recorded_span(self) -> tuple[float, float]:
        """The first and last readouts between which the poses change: the start and end but
        where the first (last) pose is held, repeated, to it (`Reconstruction.trajectory` holds
        SfM's first and last registered poses to the stream's ends)."""
        held = np.isclose(self.viewmats[1:], self.viewmats[:-1], rtol=0, atol=1e-9)
        held = held.all(axis=(1, 2))  # [P - 1] pose k+1 is pose k
        first, last = 0, len(self) - 1
        while first < last and held[first]:
            first += 1
        while last > first and held[last - 1]:
            last -= 1
        return float(self.readouts[first]), float(self.readouts[last])

    @property
    def centers(self) -> np.ndarray:
        """Camera centres [P, 3] in world coordinates."""
        return self._centers

    def turns(self) -> np.ndarray:
        """Each pose's rotation from the first [P], radians."""
        return (self._rotations[0].inv() * self._rotations).magnitude()

    def pose_at(self, t) -> np.ndarray:
        """Viewmat [4, 4] (or [B, 4, 4] for t [B]) at readout time t: camera-to-world rotation
        slerped and camera centre interpolated linearly between the two bracketing poses."""
        ts = np.asarray(t, np.float64)
        flat = ts.reshape(-1)  # [B]
        bad = ~((flat >= self.start) & (flat <= self.end))
        if bad.any():
            raise ValueError(
                f"pose_at: t={flat[bad][0]} outside the trajectory's readouts "
                f"[{self.start}, {self.end}]"
            )
        i = np.clip(np.searchsorted(self.readouts, flat, side="right") - 1, 0, len(self) - 1)
        j = np.minimum(i + 1, len(self) - 1)
        span = self.readouts[j] - self.readouts[i]
        u = np.where(span > 0, (flat - self.readouts[i]) / np.where(span > 0, span, 1.0), 0.0)
        r0, r1 = self._rotations[i], self._rotations[j]
        rot = r0 * Rotation.from_rotvec((r0.inv() * r1).as_rotvec() * u[:, None])  # slerp
        c2w = np.tile(np.eye(4), (len(flat), 1, 1))  # [B, 4, 4]
        c2w[:, :3, :3] = rot.as_matrix()
        c2w[:, :3, 3] = (1 - u)[:, None] * self._centers[i] + u[:, None] * self._centers[j]
        out = np.linalg.inv(c2w)
        return out[0] if ts.ndim == 0 else out

    @classmethod
    def spiral(
        cls,
        num_readouts: int,
        *,
        radius: float,
        start_elevation_deg: float,
        end_elevation_deg: float,
        degrees_per_readout: float,
        look_at: tuple = (0.0, 0.0, 0.0),
        start_azimuth_deg: float = 0.0,
        every: int = 1,
        up=WORLD_UP,
    ) -> Trajectory:
        """A spiral around `look_at`, ascending along unit `up` [3]: azimuth grows by
        `degrees_per_readout`, elevation linearly from start to end; poses at readouts 0, every,
        2·every, … and the last one."""
        if num_readouts < 2 or every < 1:
            raise ValueError(
                f"spiral: num_readouts >= 2 and every >= 1 expected, found {num_readouts}, {every}"
            )
        last = num_readouts - 1
        readouts = np.unique(np.append(np.arange(0, last, every), last)).astype(np.float64)  # [P]
        frac = readouts / last
        azimuth = start_azimuth_deg + degrees_per_readout * readouts  # [P]
        elevation = start_elevation_deg + (end_elevation_deg - start_elevation_deg) * frac  # [P]
        eyes = orbit_eye(look_at, radius, azimuth, elevation, up)  # [P, 3]
        viewmats = np.stack([_look_at(eye, look_at, up) for eye in eyes])  # [P, 4, 4]
        return cls(readouts, viewmats, source="spiral")

    def save_json(self, path: PathLike, **extra) -> None:
        """Write the nerfstudio-like trajectory JSON (camera-to-world, OpenCV); `extra` keys
        (e.g. intrinsics fl_x, fl_y, cx, cy, w, h) go to the top level."""
        frames = (
            {"readout": readout_number(k), "transform_matrix": c2w.tolist()}
            for k, c2w in zip(self.readouts, np.linalg.inv(self.viewmats))
        )
        write_camera_doc(Path(path), frames, **extra)

    @classmethod
    def load_json(cls, path: PathLike, camera: dict | None = None) -> Trajectory:
        """Read `save_json`'s file; ValueError naming the file when it is malformed (a warning
        where it states another camera than `camera`: `read_camera_doc`)."""
        path = Path(path)
        if not path.is_file():
            raise FileNotFoundError(f"trajectory file not found: {path}")
        frames = read_camera_doc(path, camera, _compact_matrix)
        if not frames:
            raise ValueError(f"{path}: no frames (poses)")
        for i, frame in enumerate(frames):  # (a KeyError said "malformed frames ('readout')")
            missing = [key for key in FRAME_KEYS if key not in frame]
            if missing:
                raise ValueError(
                    f"{path}: frame {i} has no {' or '.join(missing)} (each frame needs "
                    f"readout, the readout index of its pose, and transform_matrix, "
                    f"camera-to-world 4x4); found the keys {sorted(frame)}"
                )
            _check_matrix(path, i, frame)
        try:
            readouts = number_array([f["readout"] for f in frames])  # [P]
            matrices = [f["transform_matrix"] for f in frames]  # [P] of [4, 4]
            if not all(isinstance(m, np.ndarray) for m in matrices):  # as written: its error
                matrices = [m.tolist() if isinstance(m, np.ndarray) else m for m in matrices]
            c2w = number_array(matrices)  # [P, 4, 4]
        except (KeyError, TypeError, ValueError) as err:
            raise ValueError(f"{path}: malformed frames ({err})") from err
        if c2w.shape[1:] != (4, 4):
            raise ValueError(f"{path}: transform_matrix expected 4x4, found {list(c2w.shape[1:])}")
        c2w = rigid_c2w(c2w, str(path), "frame")  # rounded poses made rigid, before inverting
        return cls(readouts, np.linalg.inv(c2w), source=str(path))


def write_camera_doc(path: Path, frames: Iterable[dict], **extra) -> None:
    """Write a camera file (trajectory.json, test_views.json) atomically: a JSON object of
    OpenCV cameras, `extra` keys at the top level, then `frames`, a frame a line, each encoded as
    it is written (a pose a readout of a long recording is never held whole as Python objects
    and text: 160k readouts took 0.6 GB and 4.4 s, indented a number a line); numpy values in
    `extra` (a Dataset's float32 K[0, 0]) as Python's."""
    plain = {
        k: v.tolist() if isinstance(v, (np.ndarray, np.generic)) else v for k, v in extra.items()
    }
    top = {"camera_model": "OPENCV", "convention": CONVENTION, **plain}

    def write(tmp: Path) -> None:
        with open(tmp, "w", encoding="utf-8") as file:
            file.write(
                "{\n" + "".join(f" {json.dumps(k)}: {json.dumps(v)},\n" for k, v in top.items())
            )
            file.write(' "frames": [')
            for i, frame in enumerate(frames):
                file.write(("," if i else "") + "\n  " + json.dumps(frame))
            file.write("\n ]\n}\n")

    write_atomically(path, write)


def _check_matrix(path: Path, i: int, frame: dict) -> None:
    """ValueError naming frame `i` of the file at `path` where its transform_matrix is not 4 rows
    of 4 numbers (numpy's 'inhomogeneous shape after 1 dimensions' named no frame)."""
    matrix = frame["transform_matrix"]
    if not (isinstance(matrix, np.ndarray) and matrix.shape == (4, 4)):  # (`_compact_matrix`'s)
        four_by_four(f"{path}: frame {i} (readout {json_text(frame['readout'])})", matrix)


def four_by_four(where: str, matrix) -> np.ndarray:
    """A JSON transform_matrix as float64 [4, 4]; ValueError saying `where` it is not 4 rows of
    4 numbers, as written, or which value is no number (a true or false, a string, a null)."""
    rows = isinstance(matrix, list) and len(matrix) == 4
    if not (rows and all(isinstance(row, list) and len(row) == 4 for row in matrix)):
        raise ValueError(
            f"{where}: transform_matrix expected 4 rows of 4 numbers, found {json_text(matrix)}"
        )
    try:
        return number_array(matrix)
    except ValueError as err:
        raise ValueError(f"{where}: transform_matrix {err}") from None


def _compact_matrix(frame: dict) -> dict:
    """A JSON object as it is parsed with its `transform_matrix`, where it is a frame (it has a
    readout: another object stays as written, for a message) and that is 4x4 numbers, as an
    array [4, 4] (int or float as the numbers are; `Trajectory.load_json` makes them float64):
    the lists and floats of a pose a readout held 0.3 GB for 200k readouts (the arrays 0.16,
    with the file's text). A true or false among a pose's numbers, which numpy reads as 1 or 0
    (a translation of 1 is as rigid as any), leaves it as written, for `number_array`'s error."""
    matrix = frame.get("transform_matrix")
    if "readout" in frame and isinstance(matrix, list):
        try:
            array = np.asarray(matrix)
        except ValueError:  # ragged: left as it is, for `load_json`'s error
            return frame
        if (
            array.dtype.kind in "iuf"
            and array.shape == (4, 4)  # 4 lists of 4 numbers
            and not holds_bool(matrix)
        ):
            frame["transform_matrix"] = array
    return frame


def read_camera_doc(path: Path, camera: dict | None = None, object_hook=None) -> list:
    """The frames [P] of `write_camera_doc`'s file; ValueError naming it unless it is an object
    in our convention whose frames are a list of objects. Given `camera` (nerfstudio keys: the
    camera training uses), a warning for each of its keys that the file states otherwise;
    `object_hook`: `read_json`'s."""
    doc = read_json(path, object_hook)
    for key, value in (camera or {}).items():
        stated = doc.get(key, value)
        # rounding (175.8 for 175.77) is not the edit of the wrong file this catches
        if not (is_number(stated) and abs(stated - value) <= 1e-3 * max(1.0, abs(value))):
            warnings.warn(
                f"{path}: {key} {json_text(stated)}, the dataset's camera has "
                f"{json_text(value)}: meta.json states the camera training uses, and this "
                f"file's copy is not read",
                stacklevel=3,
            )
    convention = doc.get("convention")  # unstated: NeRF exports are OpenGL, ours OpenCV
    if not (isinstance(convention, str) and convention.lower() == CONVENTION):
        found = (
            f"convention {json_text(doc['convention'])}" if "convention" in doc else "no convention"
        )
        raise ValueError(
            f'{path}: {found}; expected "convention": "{CONVENTION}" (camera-to-world '
            f"matrices with x right, y down, z forward). NeRF/Blender (OpenGL: y up, z back) "
            f"matrices become OpenCV's right-multiplied by diag(1, -1, -1, 1); or keep them in "
            f"the NeRF layout (transforms.json), which reads OpenGL (docs/datasets.md)"
        )
    frames = doc.get("frames", [])
    if not isinstance(frames, list) or not all(isinstance(f, dict) for f in frames):
        raise ValueError(f"{path}: 'frames' expected a list of objects")
    return frames


_look_at = look_at  # `spiral` has a parameter of the same name


def readout_number(k: float):
    """An integral readout as int (cleaner JSON and messages: `:g` printed 1000001 as 1e+06),
    else float."""
    return int(k) if float(k).is_integer() else float(k)
