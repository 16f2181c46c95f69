"""Audit of 9efe204: the span loop's views must not repeat frame after frame (the commit's own
claim: 'a quarter step on so that no view shows twice running (a GIF merged them)'). The clip to
the cameras' extremes of an ellipse sqrt(3) standard deviations wide held few cameras (whose
spread is no uniform one) at their ends for several frames running."""

import numpy as np
import pytest
from spikegs.data.trajectory import Trajectory, look_at, orbit_eye
from spikegs.render_cli import orbit_viewmats

CENTER = np.array([1.0, -2.0, 0.5])


def _cameras(azimuths, elevations):
    eyes = [orbit_eye(CENTER, 4.0, a, e) for a, e in zip(azimuths, elevations)]
    return Trajectory(np.arange(float(len(eyes))), np.stack([look_at(e, CENTER) for e in eyes]))


@pytest.mark.parametrize(
    "azimuths, elevations",
    [
        ((0, 40), (20, 20)),  # two cameras
        ((0, 40, 80), (20, 20, 20)),  # three on an arc
        ((170, 250), (10, 40)),  # two, across +-180, rising
        (tuple(range(0, 61, 10)), tuple(10 + a / 2 for a in range(0, 61, 10))),  # a spiral's arc
    ],
)
def test_no_span_view_shows_twice_running(azimuths, elevations):
    frames = 24
    viewmats, path = orbit_viewmats(_cameras(azimuths, elevations), CENTER, frames)
    assert path == "span"
    steps = np.linalg.norm(np.diff(np.linalg.inv(viewmats)[:, :3, 3], axis=0), axis=1)  # [F-1]
    assert (steps > 1e-6).all(), f"{int((steps <= 1e-6).sum())} of {frames - 1} steps stand still"
