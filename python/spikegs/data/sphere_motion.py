"""How far the scene moves across the image as the camera moves: the scene sphere's poles and
centre projected into the cameras along a trajectory (the simulator's light frames, a training
target's window of readouts)."""

from __future__ import annotations

import numpy as np

from .trajectory import Trajectory, project_points

# at most this many poses a window is sampled at (a readout apart below it), and at most this
# many windows, spread evenly over the timestamps (50,000 windows' poses took 23 s)
WINDOW_SAMPLES, WINDOWS = 65, 256


def sphere_track(scene, viewmats: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pixel positions [F, 7, 2] of the scene sphere's six poles and centre in the cameras
    `viewmats` [F, 4, 4], and whether each lies ahead of its camera [F, 7] (by 1% of the radius:
    a point near a camera's plane projects anywhere). `scene`: anything with scene_center,
    scene_radius and K (a Dataset, a simulator's Source)."""
    offsets = np.concatenate([np.eye(3), -np.eye(3), np.zeros((1, 3))])  # [7, 3]
    points = np.asarray(scene.scene_center) + scene.scene_radius * offsets
    pixels, z = project_points(points, viewmats, scene.K)
    return pixels, z > 0.01 * scene.scene_radius


def track_steps(pixels: np.ndarray, ahead: np.ndarray) -> np.ndarray:
    """Each point's motion in pixels between consecutive poses [..., F - 1, 7] of `sphere_track`'s
    [..., F, 7, 2] and [..., F, 7]; 0 where it lies behind either camera of the pair."""
    steps = np.linalg.norm(np.diff(pixels, axis=-3), axis=-1)
    return np.where(ahead[..., 1:, :] & ahead[..., :-1, :], steps, 0.0)


def window_motion(scene, trajectory: Trajectory, timestamps, window: int) -> float:
    """The longest path in pixels that a pole or the centre of the scene sphere traces across the
    image within `window` readouts centred on a readout of `timestamps` [N] (at most WINDOWS of
    them, evenly spread: a short fast stretch of a long pose log between them is not seen; the
    poses at every readout of a window, at most WINDOW_SAMPLES evenly, clipped to the
    trajectory's readouts): the motion blur of an image made from those readouts' spikes. Only
    steps whose ends both project within half the image's size of it count: a pole near a
    camera's plane (a camera in or near the sphere) moved thousands of pixels off the image as
    the image itself barely moved. `scene` as `sphere_track`'s, with the image's width and
    height."""
    ts = np.sort(np.asarray(timestamps, np.float64))  # [N]
    ts = ts[np.unique(np.linspace(0, len(ts) - 1, min(len(ts), WINDOWS)).round().astype(int))]
    offsets = np.linspace(-(window // 2), window // 2, min(window, WINDOW_SAMPLES))  # [S]
    times = np.clip(ts[:, None] + offsets, trajectory.start, trajectory.end)  # [N', S]
    pixels, ahead = sphere_track(scene, trajectory.pose_at(times.ravel()))
    size = np.array([scene.width, scene.height], np.float64)
    near = ahead & np.all((pixels > -size / 2) & (pixels < 1.5 * size), axis=-1)  # [F, 7]
    steps = track_steps(pixels.reshape(*times.shape, 7, 2), near.reshape(*times.shape, 7))
    return float(steps.sum(axis=-2).max()) if steps.size else 0.0
