"""Initial intensities (initial_intensity.py): the views' median is an intensity, not a rate."""

from types import SimpleNamespace

import numpy as np
import torch
from spikegs.data.trajectory import Trajectory, look_at
from spikegs.initial_intensity import ViewSample, projected_intensity


def test_the_views_median_is_in_intensity_units():
    """ViewSample.median: the median firing rate of each channel divided by the rate of intensity
    1 (`scale`): rates 0.1, 0.3, 0.3, 0.5 (red) and 0.2, 0.2, 0.4, 0.4 (green) at scale 0.5 are
    intensities 0.6 and 0.6 (numpy's median of an even count: the mean of the middle two)."""
    red = np.array([0.1, 0.3, 0.3, 0.5], np.float32)
    green = np.array([0.2, 0.2, 0.4, 0.4], np.float32)
    rates = np.stack([red, green], -1).reshape(2, 1, 2, 2)  # [M=2, H=1, W=2, C=2]
    sample = ViewSample(np.array([0.0, 1.0]), rates, scale=0.5)
    np.testing.assert_allclose(sample.median, [0.6, 0.6], rtol=1e-6)


def test_a_gaussian_no_view_sees_starts_at_the_median_intensity():
    """A point behind the camera takes the views' median intensity (rate / scale), as a point
    that a view sees takes its pixel's intensity."""
    viewmat = look_at((0.0, -5.0, 0.0), (0.0, 0.0, 0.0))
    camera = SimpleNamespace(
        trajectory=Trajectory(np.array([0.0, 1.0]), np.stack([viewmat, viewmat])),
        K=np.array([[5.0, 0.0, 4.0], [0.0, 5.0, 2.0], [0.0, 0.0, 1.0]]),
        width=8,
        height=4,
    )
    rates = np.full((1, 4, 8, 1), 0.2, np.float32)  # intensity 0.2 / 0.25 = 0.8
    sample = ViewSample(np.array([0.0]), rates, scale=0.25)
    means = torch.tensor([[0.0, 0.0, 0.0], [0.0, -10.0, 0.0]])  # seen; behind the camera
    np.testing.assert_allclose(projected_intensity(camera, sample, means)[:, 0], [0.8, 0.8])
