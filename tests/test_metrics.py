"""metrics.py: what PSNR and the SSIMs accept."""

import numpy as np
import pytest
from spikegs.metrics import psnr, ssim, ssim_3dgs


@pytest.mark.parametrize("shape", [(20,), (2, 8, 8, 3)])
@pytest.mark.parametrize("metric", [psnr, ssim, ssim_3dgs])
def test_metrics_refuse_what_is_not_an_image(metric, shape):
    """[H, W] or [H, W, C] only: a batch [N, H, W, C] (or a line of values) is refused, not scored
    as one image."""
    x = np.random.default_rng(0).random(shape)
    with pytest.raises(ValueError, match=r"expected two \[H, W\] or \[H, W, C\] images"):
        metric(x, x)
