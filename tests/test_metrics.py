"""metrics.py: what PSNR and the SSIMs accept."""

import numpy as np
import pytest
from spikegs.metrics import psnr, ssim, ssim_3dgs


@pytest.mark.parametrize("shape", [(20,), (2, 8, 8, 3), (0, 5, 3), (8, 0)])
@pytest.mark.parametrize("metric", [psnr, ssim, ssim_3dgs])
def test_metrics_refuse_what_is_not_an_image(metric, shape):
    """[H, W] or [H, W, C] only: a batch [N, H, W, C] (or a line of values) is refused, not scored
    as one image; an empty image too (PSNR and SSIM scored NaN, 3DGS's SSIM raised torch's
    kernel-size error)."""
    x = np.random.default_rng(0).random(shape)
    with pytest.raises(ValueError, match=r"expected two \[H, W\] or \[H, W, C\] images"):
        metric(x, x)


@pytest.mark.parametrize("metric", [psnr, ssim, ssim_3dgs])
def test_images_of_other_channel_counts_are_named_as_such(metric):
    """A colour model's render scored against a mono view was told "expected two [H, W] or [H, W,
    C] images, not empty", of two non-empty [H, W, C] images: the shapes differ, in channels."""
    rng = np.random.default_rng(0)
    with pytest.raises(
        ValueError, match=r"one shape.*\(8, 8, 3\) and \(8, 8, 1\): 3 channel\(s\) against 1"
    ):
        metric(rng.random((8, 8, 3)), rng.random((8, 8, 1)))
    with pytest.raises(ValueError, match=r"one shape, not empty, got \(8, 8\) and \(8, 9\)$"):
        metric(rng.random((8, 8)), rng.random((8, 9)))


@pytest.mark.parametrize("metric", [psnr, ssim, ssim_3dgs])
def test_metrics_refuse_codes_and_channels_first_and_take_tensors(metric):
    """8-bit codes (data range 1: 200 against 100 scored -40 dB) and a channels-first [3, H, W]
    image (scored as 3 rows with 32 channels) are refused; a torch tensor requiring grad (float32
    or float64) scores as its values do."""
    import torch

    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match="found uint8 values"):
        metric(np.full((8, 8), 200, np.uint8), np.full((8, 8), 100, np.uint8))
    for channels in (3, 4):  # RGB or RGBA first (RGBA's 4 passed with < in place of <=)
        chw = rng.random((channels, 32, 32))
        with pytest.raises(ValueError, match=rf"got \[{channels}, 32, 32\]: channels first"):
            metric(chw, chw * 0.9)
    a, b = rng.random((16, 16, 3)), rng.random((16, 16, 3))
    tensor = torch.from_numpy(a).float().requires_grad_()
    assert metric(tensor, torch.from_numpy(b)) == pytest.approx(metric(a.astype(np.float32), b))
    # float64 scored in float64: images 1e-9 apart score ~180 dB (float32 rounds them to 0 or a
    # float32 step apart: another score, which scoring a float32 copy of the tensor gave)
    near = a + 1e-9 * rng.standard_normal(a.shape)
    exact = metric(a, near)
    assert metric(torch.from_numpy(a), torch.from_numpy(near)) == pytest.approx(exact, abs=1e-9)
    half = torch.from_numpy(a).bfloat16()  # none in numpy: taken as its values
    assert metric(half, torch.from_numpy(b)) == pytest.approx(metric(half.double().numpy(), b))


def test_view_metrics_take_what_the_metrics_take_and_name_unknown_ssims():
    """evaluate.view_metrics, the call the README shows, clipped before the metrics saw their
    input: a tensor requiring grad raised "Can't call numpy() on Tensor that requires grad", a
    bfloat16 one "unsupported ScalarType"; ssims="ssim" was read a letter at a time (KeyError:
    's')."""
    import torch
    from spikegs.evaluate import view_metrics

    rng = np.random.default_rng(0)
    a, b = rng.random((16, 16, 1)), rng.random((16, 16, 1))
    expected = view_metrics(a, b)
    assert view_metrics(torch.from_numpy(a).requires_grad_(), b) == expected
    half = torch.from_numpy(a).bfloat16()
    assert view_metrics(half, b) == view_metrics(half.double().numpy(), b)
    assert view_metrics(a, b, "ssim") == {"psnr": expected["psnr"], "ssim": expected["ssim"]}
    with pytest.raises(ValueError, match="ssims: unknown .'SSIM'.; known: ssim, ssim_3dgs"):
        view_metrics(a, b, ["SSIM"])


def test_ssim_3dgs_is_3dgs_evaluations_ssim():
    """3DGS's evaluation's `ssim` written out as it computes it: one 11×11 window (the outer
    product of the normalised Gaussian, σ = 1.5) convolved per channel with 5 pixels of zero
    padding, the map's mean; on images with content up to their edges, where the padding counts
    (the test against scikit-image frames its images in black)."""
    import torch
    import torch.nn.functional as F

    rng = np.random.default_rng(1)
    a = rng.random((37, 50, 3))
    b = np.clip(a + 0.1 * rng.standard_normal(a.shape), 0, 1)
    x, y = (torch.from_numpy(i).permute(2, 0, 1)[None] for i in (a, b))  # [1, 3, H, W]
    g = torch.exp(-((torch.arange(11, dtype=torch.float64) - 5) ** 2) / (2 * 1.5**2))
    g = g / g.sum()
    window = (g[:, None] @ g[None, :]).expand(3, 1, 11, 11)

    def blur(t):
        return F.conv2d(t, window, padding=5, groups=3)

    mx, my = blur(x), blur(y)
    vx, vy, cxy = blur(x * x) - mx**2, blur(y * y) - my**2, blur(x * y) - mx * my
    c1, c2 = 0.01**2, 0.03**2
    ssim_map = ((2 * mx * my + c1) * (2 * cxy + c2)) / ((mx**2 + my**2 + c1) * (vx + vy + c2))
    assert ssim_3dgs(a, b) == pytest.approx(float(ssim_map.mean()), abs=1e-6)
    assert abs(ssim_3dgs(a, b) - ssim(a, b)) > 1e-3  # scikit-image's is another SSIM


@pytest.mark.parametrize("rows, window", [(4, 3), (6, 5)])
def test_ssim_of_an_even_short_side_takes_the_largest_odd_window_under_it(rows, window):
    """A side of 4 (6) pixels takes a 3 (5) window, the largest odd one that fits (two under the
    side passed every test, which had odd sides alone: 4 then gave 2, refused, 6 gave 4, which
    scikit-image refuses)."""
    from skimage.metrics import structural_similarity

    rng = np.random.default_rng(2)
    gt = rng.random((rows, 12))
    pred = np.clip(gt + 0.1 * rng.standard_normal(gt.shape), 0, 1)
    want = structural_similarity(gt, pred, data_range=1.0, win_size=window)
    assert ssim(pred, gt) == pytest.approx(want, abs=1e-12)


def test_ssim_of_a_line_image_is_1d_ssim_and_a_point_or_a_short_side_is_refused():
    """A side of one pixel is dropped: a row or a column, mono or colour, scores as 1-D SSIM of
    its values (untested before: keeping the side of 1 took a window of 1, refused); a single
    pixel, or a side of 2, leaves no window of 3 and is refused."""
    from skimage.metrics import structural_similarity

    rng = np.random.default_rng(3)
    gt = rng.random((20, 3))
    pred = np.clip(gt + 0.1 * rng.standard_normal(gt.shape), 0, 1)
    want = structural_similarity(gt, pred, data_range=1.0, win_size=7, channel_axis=-1)
    assert ssim(pred[None], gt[None]) == pytest.approx(want, abs=1e-12)  # a row [1, 20, 3]
    assert ssim(pred[:, None], gt[:, None]) == pytest.approx(want, abs=1e-12)  # a column
    mono = structural_similarity(gt[:, 0], pred[:, 0], data_range=1.0, win_size=7)
    assert ssim(pred[None, :, 0], gt[None, :, 0]) == pytest.approx(mono, abs=1e-12)  # [1, 20]
    for shape in ((1, 1), (1, 1, 3), (2, 8)):
        with pytest.raises(ValueError, match="SSIM needs sides of 1 or at least 3 pixels"):
            ssim(np.zeros(shape), np.zeros(shape))


def test_psnr_is_10_log10_of_one_over_the_mean_squared_error():
    """PSNR at data range 1 written out, mono and colour (a data range of 1.1 scored 0.83 dB
    higher and passed every test: each compared PSNR with PSNR)."""
    rng = np.random.default_rng(4)
    for shape in ((9, 11), (9, 11, 3)):
        gt = rng.random(shape)
        pred = np.clip(gt + 0.05 * rng.standard_normal(shape), 0, 1)
        want = 10 * np.log10(1 / np.mean((pred - gt) ** 2))
        assert psnr(pred, gt) == pytest.approx(want, abs=1e-10)
    assert psnr(gt, gt) == float("inf")


@pytest.mark.parametrize("metric", [psnr, ssim, ssim_3dgs])
def test_metrics_refuse_images_that_are_not_finite(metric):
    """A NaN or inf scored NaN (or -inf dB), unsaid: refused, naming the image, how many of its
    pixels and where the first lies."""
    gt = np.random.default_rng(5).random((9, 11, 3))
    pred = gt.copy()
    pred[2, 3, 1], pred[4, 5] = np.nan, np.inf
    with pytest.raises(ValueError, match=r"pred \(the render\): 2 of 99 pixels not finite .* "):
        metric(pred, gt)
    with pytest.raises(ValueError, match=r"gt \(the ground truth\): 2 of 99 .* row 2, column 3"):
        metric(gt, pred)
