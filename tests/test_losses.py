"""The SpikeGS losses: exposure sampling times, L1/L2 optima on quantised targets, D-SSIM, and
the Gaussian blur D-SSIM and pose alignment read."""

import numpy as np
import pytest
import torch
from skimage.metrics import structural_similarity
from spikegs.losses import (
    LONG_BLUR,
    dssim,
    exposure_loss,
    exposure_times,
    gaussian_blur,
    instant_loss,
)


@pytest.mark.parametrize("window, poses", [(33, 5), (33, 9), (65, 13), (9, 2)])
def test_exposure_times_spread_like_the_window(window, poses):
    """Midpoints of K equal parts: centred on t, inside the window, and spread like a uniform
    exposure (variance window²/12 up to the midpoint rule's 1/K², not end to end's ~K/(K-1))."""
    times = exposure_times(100.0, window, poses)  # [K]
    assert len(times) == poses and np.all(np.diff(times) > 0)
    assert times.mean() == pytest.approx(100.0)
    assert times.min() > 100 - window / 2 and times.max() < 100 + window / 2
    exposure_var = window**2 / 12
    assert abs(times.var() / exposure_var - 1) <= 1 / poses**2 + 1e-9
    if poses % 2:
        assert times[poses // 2] == pytest.approx(100.0)  # the instant pose is one of them


def test_one_exposure_pose_is_the_instant():
    """K = 1: the one midpoint of the window is t itself (K >= 2 alone was tested, where refusing
    K = 1 passed every test)."""
    assert exposure_times(100.0, 33, 1).tolist() == [100.0]


def _fit_constant(norm: str, targets: torch.Tensor) -> float:
    """The constant image that minimises the exposure loss over `targets` [M, H, W, 1]."""
    x = torch.zeros(1, requires_grad=True)
    opt = torch.optim.Adam([x], lr=0.01)
    for _ in range(1500):
        opt.zero_grad()
        loss = sum(exposure_loss([x.expand(4, 4, 1)] * 3, t, norm, 1 / 33) for t in targets)
        loss.backward()
        opt.step()
    return float(x.detach())


@pytest.mark.parametrize("counts", [[3] * 7 + [4] * 3, [3] * 4 + [4] * 6, [5] * 2 + [6] * 3])
def test_l2_and_smooth_l1_exposure_learn_the_mean_of_quantised_tfp_where_l1_learns_the_median(
    counts,
):
    """TFP of 33 readouts is a whole number of spikes / 33 (at 0.1 spikes/readout 3/33 or 4/33):
    L1 ends at the median count, L2 and smooth L1 with a one-spike quadratic zone at the mean."""
    counts = torch.tensor(counts, dtype=torch.float32)
    targets = (counts / 33)[:, None, None, None].expand(-1, 4, 4, 1)
    assert _fit_constant("l1", targets) == pytest.approx(float(counts.median()) / 33, abs=2e-3)
    for norm in ("l2", "smooth_l1"):
        assert _fit_constant(norm, targets) == pytest.approx(float(counts.mean()) / 33, abs=1e-3)


def test_instant_loss_norms():
    render, target = torch.full((2, 3, 1), 0.5), torch.full((2, 3, 1), 0.2)
    assert float(instant_loss(render, target)) == pytest.approx(0.3)
    assert float(instant_loss(render, target, "l2")) == pytest.approx(0.09)
    # smooth L1: |r| - quantum/2 beyond one quantum, r²/(2·quantum) within it
    assert float(instant_loss(render, target, "smooth_l1", 0.1)) == pytest.approx(0.25)
    assert float(instant_loss(render, target, "smooth_l1", 0.6)) == pytest.approx(0.075)
    with pytest.raises(ValueError, match="quantum"):  # its zone has no default unit
        instant_loss(render, target, "smooth_l1")
    for quantum in (float("nan"), -0.1, float("inf"), "0.1"):  # torch: "negative values for beta"
        with pytest.raises(ValueError, match=f"a finite number >= 0 .*got {quantum!r}"):
            instant_loss(render, target, "smooth_l1", quantum)
    assert float(instant_loss(render, target, "smooth_l1", 0.0)) == pytest.approx(0.3)  # L1
    assert float(exposure_loss([render, target], target)) == pytest.approx(0.15)


def test_dssim_matches_scikit_image():
    """Same SSIM as scikit-image's Gaussian-window variant, to float32 rounding (3e-8): the images
    have a black frame 12 pixels wide, so our zero padding and scikit-image's reflection see the
    same beyond the edge and the full maps agree. (Compared within 5 % over a border that
    differed, C1 x100, C2 x11, sigma 2.5 and no padding all passed.)"""
    rng = np.random.default_rng(0)
    a, b = np.zeros((2, 64, 64), np.float32)
    a[12:-12, 12:-12] = rng.random((40, 40))
    b[12:-12, 12:-12] = np.clip(a[12:-12, 12:-12] + 0.1 * rng.standard_normal((40, 40)), 0, 1)
    ours = float(dssim(torch.from_numpy(a[..., None]), torch.from_numpy(b[..., None])))
    _, full = structural_similarity(
        a,
        b,
        data_range=1.0,
        gaussian_weights=True,
        sigma=1.5,
        use_sample_covariance=False,
        full=True,
    )
    assert abs(ours - (1 - full.mean()) / 2) < 1e-5, (ours, (1 - full.mean()) / 2)


def test_dssim_of_colour_is_the_mean_of_its_channels_and_its_gradient_checks():
    """The channels' moments are blurred together: each channel's map must come from its own
    moments (a mix-up of the stacked maps scores other numbers), and the gradient is autograd's
    through the two 1-D passes (float64 finite differences)."""
    gen = torch.Generator().manual_seed(0)
    a, b = torch.rand(2, 20, 24, 3, generator=gen, dtype=torch.float64)
    per_channel = torch.stack([dssim(a[..., i : i + 1], b[..., i : i + 1]) for i in range(3)])
    assert float(dssim(a, b)) == pytest.approx(float(per_channel.mean()), abs=1e-12)
    assert len(set(per_channel.tolist())) == 3
    x = a[:9, :10].clone().requires_grad_()
    assert torch.autograd.gradcheck(lambda x: dssim(x, b[:9, :10]), (x,))


def test_dssim_under_bfloat16_autocast_is_its_float32_value():
    """A researcher's training step under torch.autocast("cpu", dtype=torch.bfloat16): the blurs
    (convolutions, which autocast lowers) ran in bfloat16, where the variances E[x²] - E[x]²
    cancel: a render 0.005 off its target scored D-SSIM 0 (float32: 6.8e-4) and the gradient
    pointed elsewhere (cosine 0.87; 0.36 at 0.001 off)."""
    gen = torch.Generator().manual_seed(0)
    target = 0.4 + 0.3 * torch.rand(64, 64, 3, generator=gen)
    render = (target + 0.005 * torch.randn(64, 64, 3, generator=gen)).requires_grad_()
    expected = dssim(render, target)
    (grad,) = torch.autograd.grad(expected, render)
    with torch.autocast("cpu", dtype=torch.bfloat16):
        value = dssim(render, target)
    assert value.dtype == torch.float32 and expected.item() > 5e-4
    assert torch.equal(value, expected)
    assert torch.equal(torch.autograd.grad(value, render)[0], grad)
    half = dssim(render.detach().bfloat16(), target.bfloat16())  # bfloat16 images: float32 too
    assert half.dtype == torch.float32 and float(half) == pytest.approx(expected.item(), rel=0.1)


@pytest.mark.parametrize(
    "shape, sigma",
    [((1, 5, 30, 30), 1.5), ((1, 3, 40, 57), LONG_BLUR + 2), ((1, 1, 9, 7), 5.0)],
)
def test_gaussian_blur_is_the_zero_padded_2d_convolution(shape, sigma):
    """`gaussian_blur` against one 2-D convolution with the outer product of a Gaussian's taps over
    ±⌈3σ⌉, zero padding, in double: the short blur's convolutions and the long one's Fourier
    products (whose circular wrap must read zeros, also where the taps outreach the map)."""
    import torch.nn.functional as F

    maps = torch.rand(*shape, dtype=torch.float64, generator=torch.Generator().manual_seed(0))
    r = int(np.ceil(3 * sigma))
    x = torch.arange(-r, r + 1, dtype=torch.float64)
    taps = torch.exp(-(x**2) / (2 * sigma**2))
    window = torch.outer(taps, taps) / taps.sum() ** 2  # [2r + 1, 2r + 1]
    n = shape[1]
    wanted = F.conv2d(maps, window.expand(n, 1, -1, -1).contiguous(), padding=r, groups=n)
    torch.testing.assert_close(gaussian_blur(maps, sigma), wanted, rtol=0, atol=1e-6)


def test_images_of_other_shapes_or_types_than_the_render_are_refused():
    """A mono target [H, W] (SpikeStream.tfp's) broadcast against a square render [H, W, 1] to
    [H, W, W]: a wrong loss with torch's warning only; integer images gave D-SSIM 0 for any pair
    (the window's taps cast to integers); a numpy target or an unknown norm failed obscurely."""
    gen = torch.Generator().manual_seed(0)
    render, target = torch.rand(8, 8, 1, generator=gen), torch.rand(8, 8, 1, generator=gen)
    mono = "a mono target \\[H, W\\] needs its channel axis"
    for loss in (instant_loss, lambda r, t: exposure_loss([r, r], t)):
        with pytest.raises(ValueError, match=r"render \[8, 8, 1\] and target \[8, 8\] .*" + mono):
            loss(render, target[..., 0])
        with pytest.raises(ValueError, match="target expected a torch tensor, got ndarray"):
            loss(render, target.numpy())
        assert float(loss(render, target)) == pytest.approx(float((render - target).abs().mean()))
    with pytest.raises(ValueError, match="render expected floating point, got torch.uint8"):
        dssim((render * 255).to(torch.uint8), (target * 255).to(torch.uint8))
    with pytest.raises(ValueError, match=r"dssim: render \[8, 8\] and target \[8, 8\]"):
        dssim(render[..., 0], target[..., 0])
    with pytest.raises(ValueError, match="unknown norm 'L1': one of l1, l2, smooth_l1"):
        instant_loss(render, target, "L1")
    with pytest.raises(ValueError, match="expected one render or more"):
        exposure_loss([], target)
    stacked = torch.stack([render, target])  # [K, H, W, C]: torch.stack refused a tensor
    assert float(exposure_loss(stacked, target)) == float(exposure_loss([render, target], target))
    with pytest.raises(ValueError, match=r"stacked \[K, H, W, C\] .* got a tensor \[8, 8, 1\]"):
        exposure_loss(render, target)  # one render, not a list of it
    for poses in (0, 2.5):
        with pytest.raises(ValueError, match=f"integer number of poses >= 1 .* poses {poses}"):
            exposure_times(100.0, 33, poses)
