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


@pytest.mark.parametrize("metric", [psnr, ssim, ssim_3dgs])
def test_metrics_refuse_codes_and_channels_first_and_take_tensors(metric):
    """8-bit codes (data range 1: 200 against 100 scored -40 dB) and a channels-first [3, H, W]
    image (scored as 3 rows with 32 channels) are refused; a torch tensor requiring grad (float32
    or float64) scores as its values do."""
    import torch

    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match="found uint8 values"):
        metric(np.full((8, 8), 200, np.uint8), np.full((8, 8), 100, np.uint8))
    chw = rng.random((3, 32, 32))
    with pytest.raises(ValueError, match=r"got \[3, 32, 32\]: channels first"):
        metric(chw, chw * 0.9)
    a, b = rng.random((16, 16, 3)), rng.random((16, 16, 3))
    tensor = torch.from_numpy(a).float().requires_grad_()
    assert metric(tensor, torch.from_numpy(b)) == pytest.approx(metric(a.astype(np.float32), b))
    half = torch.from_numpy(a).bfloat16()  # none in numpy: taken as its values
    assert metric(half, torch.from_numpy(b)) == pytest.approx(metric(half.double().numpy(), b))
