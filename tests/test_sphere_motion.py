"""The scene sphere's motion across the image: against a camera's motion worked by hand."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from spikegs.data.sphere_motion import WINDOW_SAMPLES, sphere_track, track_steps, window_motion
from spikegs.data.trajectory import Trajectory, look_at

K = np.array([[100.0, 0, 32], [0, 100.0, 32], [0, 0, 1]])
SCENE = SimpleNamespace(scene_center=np.zeros(3), scene_radius=1.0, K=K, width=64, height=64)


def looking_along_z(times, eyes) -> Trajectory:
    """Cameras at `eyes` [P, 3] at readouts `times` [P], looking along +z (x right, y down)."""
    eyes = np.asarray(eyes, np.float64)
    return Trajectory(times, np.stack([look_at(e, e + [0, 0, 1], up=[0, -1, 0]) for e in eyes]))


def sliding(speed: float, readouts: int = 400, across: float = 0.0) -> Trajectory:
    """A camera 5 units from the sphere's centre on -z, sliding along x at `speed` units a readout
    (and along y at `across`) and looking along +z, past x = 0 halfway: every point moves
    f · speed / depth pixels a readout along u."""
    half = np.array([speed, across, 0.0]) * (readouts - 1) / 2
    return looking_along_z([0.0, readouts - 1.0], [[0, 0, -5] - half, [0, 0, -5] + half])


@pytest.mark.parametrize("window", [1, 33, 2 * WINDOW_SAMPLES + 1])
def test_a_sliding_camera_moves_the_nearest_pole_by_focal_times_its_path_over_its_depth(window):
    """The nearest pole (depth 4) moves 100 · 0.01 / 4 px a readout: over a window's w - 1 readouts
    between its ends, 0.25 · (w - 1), sampled at every readout or WINDOW_SAMPLES of them."""
    motion = window_motion(SCENE, sliding(0.01), [200], window)
    assert motion == pytest.approx(0.25 * (window - 1), rel=1e-9)


def test_windows_past_the_trajectory_are_clipped_to_it_and_the_largest_is_taken():
    """A window around readout 0 reaches half its length before the poses: the motion is that of
    its readouts within them; of several timestamps, the largest."""
    trajectory = sliding(0.01)
    assert window_motion(SCENE, trajectory, [0], 33) == pytest.approx(0.25 * 16)
    assert window_motion(SCENE, trajectory, [0, 100, 399], 33) == pytest.approx(0.25 * 32)
    assert window_motion(SCENE, trajectory, [399], 33) == pytest.approx(0.25 * 16)  # (its end)


def test_points_behind_the_camera_add_no_motion():
    """A camera inside the sphere (a pole behind it projects anywhere): only the points ahead."""
    inside = SimpleNamespace(
        scene_center=np.array([0.0, 0, -5]), scene_radius=3.0, K=K, width=64, height=64
    )
    motion = window_motion(inside, sliding(0.01), [200], 33)
    # ahead: the +z pole at depth 3 moves 100 · 0.01 / 3 a readout; the centre, on the camera's
    # plane, and the -z pole behind it, none
    assert motion == pytest.approx(100 * 0.01 / 3 * 32)


def test_points_far_off_the_image_add_no_motion():
    """A camera orbiting slowly inside the sphere (0.3 radii from its centre, which it looks at):
    the poles beside it, near its plane, project far off the image and swept thousands of pixels
    as the image barely moved (302 % of a 24² image at 0.05° a readout: the review). Steps whose
    ends both lie within half the image's size of it count: here the far pole's, near the
    centre, 1 · sin(azimuth) off the view axis at depth ~1.3: f · cos(10°) · 1.6° / 1.3 = 2.1 px
    (the elevation's 10° adds a little)."""
    orbit = Trajectory.spiral(
        400, radius=0.3, start_elevation_deg=10, end_elevation_deg=10, degrees_per_readout=0.05
    )
    motion = window_motion(SCENE, orbit, [200], 33)
    assert 2.0 < motion < 2.5


def test_a_path_is_measured_in_euclidean_pixels_at_every_readout():
    """Sliding diagonally, the nearest pole's path is √2 · 0.25 px a readout; a camera shaking
    0.1 units back and forth every readout moves it 2.5 px at each (sampled at fewer readouts
    than a window's, the shake aliased away), through a window of WINDOW_SAMPLES readouts."""
    diagonal = window_motion(SCENE, sliding(0.01, across=0.01), [200], 33)
    assert diagonal == pytest.approx(np.sqrt(2) * 0.25 * 32)
    shaking = looking_along_z(np.arange(200.0), [[0.1 * (i % 2), 0, -5] for i in range(200)])
    for window in (33, WINDOW_SAMPLES):
        assert window_motion(SCENE, shaking, [100], window) == pytest.approx((window - 1) * 2.5)
    assert window_motion(SCENE, shaking, [], 33) == 0.0  # (no timestamp: no window)


def test_a_point_is_ahead_by_a_hundredth_of_the_radius_and_a_step_counts_with_both_ends():
    """A centre 0.005 radii before the camera projects anywhere (not ahead), 0.02 is ahead; a step
    counts where both its ends are ahead."""
    for depth, ahead in ((0.005, False), (0.02, True)):
        scene = SimpleNamespace(scene_center=np.array([0, 0, depth]), scene_radius=1.0, K=K)
        assert sphere_track(scene, np.eye(4)[None])[1][0, 6] == ahead
    pixels = np.array([[0.0, 0], [1, 0], [3, 0]])[:, None].repeat(7, 1)  # [3, 7, 2]
    ahead = np.array([False, True, True])[:, None].repeat(7, 1)  # [3, 7]
    assert track_steps(pixels, ahead)[:, 0].tolist() == [0.0, 2.0]
