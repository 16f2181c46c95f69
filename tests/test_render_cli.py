"""The orbit of `spikegs render` (render_cli.py): its radius, elevation and frames, the up of
cameras rolled every way, directions that are not finite, and the frames' 8-bit values."""

import argparse
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from spikegs import evaluate
from spikegs.data.trajectory import Trajectory, look_at, orbit_eye
from spikegs.image_io import srgb_to_linear
from spikegs.render_cli import dataset_orbit, direction, orbit_frames, orbit_viewmats, world_up

CENTER = np.array([1.0, -2.0, 0.5])


def _cameras(distances, elevation_deg=30.0):
    """Upright cameras looking at CENTER from `distances` at azimuths 0, 40, 80, ... degrees and
    one elevation (+z up)."""
    eyes = [orbit_eye(CENTER, d, 40.0 * i, elevation_deg) for i, d in enumerate(distances)]
    viewmats = np.stack([look_at(eye, CENTER) for eye in eyes])
    return Trajectory(np.arange(len(eyes), dtype=np.float64), viewmats)


def _eyes(viewmats):
    return np.linalg.inv(viewmats)[:, :3, 3]  # [F, 3] camera centres


def test_the_orbit_keeps_the_cameras_mean_distance_and_elevation():
    """Cameras at 3 and 5 units (mean 4), 30 degrees up: every orbit eye is 4 from the centre,
    2 = 4 sin 30 above it, and the first lies at the first camera's azimuth."""
    orbit = orbit_viewmats(_cameras([3.0, 5.0, 3.0, 5.0]), CENTER, 6)
    offsets = _eyes(orbit) - CENTER  # [6, 3]
    np.testing.assert_allclose(np.linalg.norm(offsets, axis=1), 4.0, rtol=1e-9)
    np.testing.assert_allclose(offsets[:, 2], 4.0 * np.sin(np.radians(30.0)), rtol=1e-9)
    np.testing.assert_allclose(offsets[0], orbit_eye((0, 0, 0), 4.0, 0.0, 30.0), atol=1e-9)


def test_the_orbit_frames_are_evenly_spaced_around_the_whole_circle():
    """F frames 360/F degrees apart, turning counter-clockwise about up (right-handed, as the
    azimuth of `orbit_eye`): the last is one step before the first, not on it (a looping video
    would show the first view twice)."""
    frames = 8
    offsets = _eyes(orbit_viewmats(_cameras([4.0, 4.0, 4.0]), CENTER, frames)) - CENTER
    azimuths = np.degrees(np.arctan2(offsets[:, 1], offsets[:, 0]))  # [F]
    steps = np.diff(np.concatenate([azimuths, azimuths[:1] + 360.0])) % 360.0
    np.testing.assert_allclose(steps, 360.0 / frames, atol=1e-9)


def test_cameras_rolled_every_way_leave_the_world_up_to_the_default():
    """Cameras whose right axes point every way span no level direction: the world's up is
    +z (WORLD_UP), not a NaN orbit."""
    rotations = Rotation.random(12, random_state=0).as_matrix()  # camera to world [12, 3, 3]
    c2w = np.tile(np.eye(4), (12, 1, 1))
    c2w[:, :3, :3] = rotations
    c2w[:, :3, 3] = np.random.default_rng(0).normal(size=(12, 3))
    np.testing.assert_array_equal(world_up(c2w), [0.0, 0.0, 1.0])


@pytest.mark.parametrize("text", ["inf,0,0", "0,-inf,1"])
def test_a_direction_that_is_not_finite_is_refused(text):
    with pytest.raises(argparse.ArgumentTypeError, match="non-zero direction"):
        direction(text)


def test_orbit_frames_round_to_the_nearest_8_bit_value(monkeypatch):
    """Each frame is the render sRGB-encoded and rounded to 8 bits (not truncated), a mono render
    repeated on R, G and B: renders of sRGB 100.7/255 and 100.3/255 give 101 and 100."""
    values = np.array([100.7, 100.3]) / 255.0
    mono = np.empty((2, 3, 1))
    mono[0], mono[1] = srgb_to_linear(values[0]), srgb_to_linear(values[1])  # rows: [2, 3, 1]
    monkeypatch.setattr(evaluate, "render_view", lambda model, viewmat, dataset: mono)
    dataset = SimpleNamespace(trajectory=_cameras([4.0, 4.0]), scene_center=CENTER, meta={})
    frames = orbit_frames(None, dataset, dataset_orbit(dataset, 2))
    assert frames.dtype == np.uint8 and frames.shape == (2, 2, 3, 3)
    assert (frames[:, 0] == 101).all() and (frames[:, 1] == 100).all()


def test_orbit_frames_turn_about_the_up_the_dataset_was_simulated_with(monkeypatch):
    """meta.json's `up` (simulate --up) is the orbit's axis where --up is not given, the
    cameras' up where it is null or absent; --up wins over both."""
    eyes = []
    monkeypatch.setattr(
        evaluate,
        "render_view",
        lambda model, viewmat, dataset: (
            eyes.append(np.linalg.inv(viewmat)[:3, 3]) or np.zeros((1, 1, 1))
        ),
    )

    def axis(meta, up=None):
        """The orbit's axis: the normal of the plane its eyes lie in."""
        eyes.clear()
        dataset = SimpleNamespace(trajectory=_cameras([4.0] * 5), scene_center=CENTER, meta=meta)
        orbit_frames(None, dataset, dataset_orbit(dataset, 8, up))
        normal = np.linalg.svd(np.stack(eyes) - np.mean(eyes, axis=0))[2][-1]
        return normal * np.sign(normal @ [1.0, 1.0, 1.0])

    np.testing.assert_allclose(axis({"up": [0.0, 2.0, 0.0]}), [0.0, 1.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(axis({"up": None}), [0.0, 0.0, 1.0], atol=1e-9)
    np.testing.assert_allclose(axis({}), [0.0, 0.0, 1.0], atol=1e-9)
    np.testing.assert_allclose(axis({"up": [0, 2, 0]}, np.array([1.0, 0, 0])), [1, 0, 0], atol=1e-9)
    with pytest.raises(ValueError, match="meta.json's up: expected a non-zero direction"):
        axis({"up": [0, 0, 0]})
