"""Renders at another size than the training images' (render_size.py): a larger frame draws each
Gaussian as wide as training saw it, a smaller one averages a render at least the training size."""

from types import SimpleNamespace

import numpy as np
import pytest
import torch
from spikegs.evaluate import render_view
from spikegs.gaussians import GaussianModel
from spikegs.render_size import (
    MAX_SIDE,
    render_scaled,
    scaled_keys,
    scaled_size,
    supersampling,
    widened,
)

FOCAL, SIDE, DEPTH = 40.0, 32, 4.0
VIEWMAT = np.eye(4)  # the camera at the origin looking down +z (OpenCV)


def _camera(side: int = SIDE, cx: float | None = None) -> SimpleNamespace:
    """A dataset's camera alike: K, size, the scene's sphere and meta.json's numbers."""
    cx = side / 2 if cx is None else cx
    meta = {"fx": FOCAL, "fy": FOCAL, "cx": cx, "cy": side / 2, "width": side, "height": side}
    K = np.array([[FOCAL, 0, cx], [0, FOCAL, side / 2], [0, 0, 1]], np.float32)
    return SimpleNamespace(
        K=K,
        width=side,
        height=side,
        scene_center=np.array([0, 0, DEPTH]),
        scene_radius=1.0,
        meta=meta,
    )


def _splat(sigma_px: float, opacity: float = 0.5, x: float = 0.0) -> GaussianModel:
    """One isotropic white Gaussian DEPTH ahead, `sigma_px` pixels wide in the SIDE² image, on a
    black background."""
    model = GaussianModel.from_points(
        torch.tensor([[x, 0.0, DEPTH]]), torch.ones(1, 1), sigma_px * DEPTH / FOCAL
    )
    model.params["opacity_logits"].data.fill_(float(np.log(opacity / (1 - opacity))))
    return model


def _variance(image: np.ndarray) -> float:
    """The image's second moment about its centroid along x, in pixels²."""
    weights = image[..., 0].sum(axis=0)  # [W]
    x = np.arange(len(weights)) + 0.5
    mean = (weights * x).sum() / weights.sum()
    return float((weights * (x - mean) ** 2).sum() / weights.sum())


def test_at_scale_one_the_frame_is_the_training_sizes_render():
    model, dataset = _splat(1.5), _camera()
    np.testing.assert_array_equal(
        render_scaled(model, VIEWMAT, dataset, 1.0), render_view(model, VIEWMAT, dataset)
    )


@pytest.mark.parametrize("dilation", [0.3, 2.0])
@pytest.mark.parametrize("scale", [2.0, 4.0])
def test_a_larger_frame_draws_each_gaussian_as_wide_as_training_did(scale, dilation):
    """A splat σ = 1.5 px at the training size shows σ² + d px² (the rasterizer's filter, the
    model's dilation d); drawn `scale` times larger, it shows scale² times that in the frame's
    pixels, where drawn as it is it would show scale²·σ² + d (at 4x and d = 0.3: 2.27 against
    2.55 training's pixels²)."""
    model, dataset = _splat(1.5), _camera()
    model.dilation = dilation
    trained = _variance(render_view(model, VIEWMAT, dataset))
    larger = render_scaled(model, VIEWMAT, dataset, scale)
    assert larger.shape == (SIDE * scale, SIDE * scale, 1)
    assert _variance(larger) / scale**2 == pytest.approx(trained, rel=0.01)
    plain = render_view(model, VIEWMAT, _camera_scaled(dataset, scale))
    assert _variance(plain) / scale**2 < 0.97 * trained  # what the widening mends


def _camera_scaled(dataset, scale: float) -> SimpleNamespace:
    """The dataset's camera `scale` times as large (K, size and meta.json's numbers), nothing
    else changed."""
    K = dataset.K.copy()
    K[:2] *= scale
    side = round(dataset.width * scale)
    meta = {k: v * scale for k, v in dataset.meta.items()}  # fx, fy, cx, cy, width, height
    meta["width"] = meta["height"] = side
    return SimpleNamespace(**{**vars(dataset), "K": K, "width": side, "height": side, "meta": meta})


def test_widening_keeps_the_gaussians_axes_and_grows_with_depth():
    """Growing the covariance by k·I: a flat Gaussian's scales s become sqrt(s² + k), k ∝ its
    depth², its rotation, opacity and colour unchanged."""
    model = _splat(1.5)
    model.params["log_scales"].data = torch.tensor([[-3.0, -1.0, -6.0]])
    model.params["quats"].data = torch.tensor([[0.9, 0.1, -0.3, 0.2]])
    far = GaussianModel.from_state_dict(model.state_dict())
    far.params["means"].data[0, 2] = 2 * DEPTH
    camera, trained = SimpleNamespace(K=2 * np.eye(3) * FOCAL), {"fl_x": FOCAL, "fl_y": FOCAL}
    near_k, far_k = (
        (widened(m, VIEWMAT, trained, camera).scales ** 2 - m.scales**2)[0].detach()
        for m in (model, far)
    )
    k = 0.3 * DEPTH**2 * (1 / FOCAL**2 - 1 / (2 * FOCAL) ** 2)  # world units²
    np.testing.assert_allclose(near_k, [k] * 3, rtol=1e-4)
    np.testing.assert_allclose(far_k, [4 * k] * 3, rtol=1e-4)
    wide = widened(model, VIEWMAT, trained, camera)
    for name in ("means", "quats", "opacity_logits", "sh_dc"):
        assert torch.equal(wide.params[name], model.params[name])
    assert widened(model, VIEWMAT, trained, SimpleNamespace(K=np.eye(3) * FOCAL)) is model
    # a Gaussian whose variance underflows float32 (e^-120) takes k whole, not log(0)
    model.params["log_scales"].data.fill_(-60.0)
    thin = widened(model, VIEWMAT, trained, camera).scales.detach()
    np.testing.assert_allclose(thin**2, [[k] * 3], rtol=1e-5)
    state = model.state_dict()  # a float64 model stays float64
    state["params"] = {name: value.double() for name, value in state["params"].items()}
    double = GaussianModel.from_state_dict({**state, "background": state["background"].double()})
    assert widened(double, VIEWMAT, trained, camera).params["log_scales"].dtype == torch.float64


@pytest.mark.parametrize("scale", [4.0, 0.3])
def test_an_antialiased_model_keeps_each_splats_mass_at_any_size(scale):
    """An antialiased model's splat (`train.antialiased`) keeps its mass in any pixels: drawn 4x
    larger it is the rasterizer's frame at that size as it is, not widened (which added mass:
    the filter's compensation is taken from the widened covariance); 0.3 of the size averages a
    40 px render, unwidened too. Its light, in training pixels, stays the training size's."""
    model, dataset = _splat(0.6), _camera()
    model.antialiased = True
    full = render_view(model, VIEWMAT, dataset)
    frame = render_scaled(model, VIEWMAT, dataset, scale)
    if scale > 1:
        as_it_is = render_view(model, VIEWMAT, _camera_scaled(dataset, scale))
        np.testing.assert_array_equal(frame, as_it_is)
    side = frame.shape[1]
    assert frame.sum() * (SIDE / side) ** 2 == pytest.approx(full.sum(), rel=0.01)
    model.antialiased = False  # the same splat drawn plain: widened, it gains
    plain_full = render_view(model, VIEWMAT, dataset)
    model.antialiased = True
    assert plain_full.sum() > 1.2 * full.sum()


def test_a_3d_filtered_model_is_drawn_as_it_is_larger():
    """A model with the 3D smoothing filter (`train.filter_3d`) is drawn 4x larger as it is, its
    filter's widths kept: its Gaussians are already no finer than training sampled them, and
    widened they blurred (BENCHMARKS.md); without the filter, the same model is widened."""
    model, dataset = _splat(0.3), _camera()
    model.filter_3d = torch.full((1,), 0.45 * DEPTH / FOCAL)  # sqrt(0.2) px at the depth
    larger = _camera_scaled(dataset, 4.0)
    frame = render_scaled(model, VIEWMAT, dataset, 4.0)
    np.testing.assert_array_equal(frame, render_view(model, VIEWMAT, larger))
    unfiltered = GaussianModel.from_state_dict({**model.state_dict(), "filter_3d": None})
    thin = render_view(unfiltered, VIEWMAT, larger)
    assert _variance(frame) > 2 * _variance(thin)  # the filter's width drawn
    assert not np.array_equal(render_scaled(unfiltered, VIEWMAT, dataset, 4.0), thin)


def test_a_smaller_frame_is_the_mean_of_the_training_sizes_pixels():
    """Half the size: each pixel the mean of the 2x2 it covers at the training size, exactly;
    a sub-pixel splat keeps its light (its sum a quarter of the training size's), where drawn
    as it is at the smaller size it gains the filter's 0.3 px² of its own pixels."""
    model, dataset = _splat(0.3, x=0.37), _camera()
    full = render_view(model, VIEWMAT, dataset)  # [32, 32, 1]
    half = render_scaled(model, VIEWMAT, dataset, 0.5)
    np.testing.assert_allclose(half, full.reshape(16, 2, 16, 2, 1).mean(axis=(1, 3)), atol=1e-7)
    plain = render_view(model, VIEWMAT, _camera_scaled(dataset, 0.5))
    assert half.sum() == pytest.approx(full.sum() / 4, rel=1e-5)
    assert abs(plain.sum() - full.sum() / 4) > 0.05 * full.sum() / 4  # what the mean mends


def test_a_frame_of_no_whole_ratio_averages_a_render_at_least_the_training_size():
    """0.3 of 32 px: 10 px, each the mean of 4x4 of a 40 px render (widened from 32: its
    light per area as the training size's)."""
    model, dataset = _splat(2.0), _camera()
    assert supersampling(dataset, 0.3) == 4 and supersampling(dataset, 0.5) == 2
    assert supersampling(dataset, 1.0) == supersampling(dataset, 3.0) == 1
    nine = {"fx": 10.0, "fy": 10.0, "cx": 4.5, "cy": 4.5, "width": 9, "height": 9}
    assert supersampling(SimpleNamespace(meta=nine), 1 / 3) == 3  # 10 / (10 · 3/9): 3 + 4e-16
    small = render_scaled(model, VIEWMAT, dataset, 0.3)
    assert small.shape == (10, 10, 1)
    full = render_view(model, VIEWMAT, dataset)
    assert small.sum() * (SIDE / 10) ** 2 == pytest.approx(full.sum(), rel=0.01)


def test_a_run_trained_on_finer_pixels_is_drawn_no_finer_than_they_were():
    """A 16² dataset of a run trained at 32² (train.json's `camera`): at scale 1 each pixel is
    the mean of 2x2 of the 32² render (not the 16² one drawn as it is), at scale 2 the 32²
    render itself (no widening: its pixels are the training camera's)."""
    model, small, large = _splat(0.4, x=0.37), _camera_scaled(_camera(), 0.5), _camera()
    trained = {"fl_x": FOCAL, "fl_y": FOCAL}
    assert supersampling(small, 1.0, trained) == 2
    full = render_view(model, VIEWMAT, large)  # [32, 32, 1]
    np.testing.assert_allclose(
        render_scaled(model, VIEWMAT, small, 1.0, trained),
        full.reshape(16, 2, 16, 2, 1).mean(axis=(1, 3)),
        atol=1e-7,
    )
    np.testing.assert_array_equal(render_scaled(model, VIEWMAT, small, 2.0, trained), full)


def test_the_scaled_camera_scales_focal_lengths_and_centre_as_the_sides():
    keys = {"fl_x": 40.0, "fl_y": 50.0, "cx": 10.0, "cy": 12.5, "w": 32, "h": 24}
    assert scaled_keys(keys, 1.0) == keys
    assert scaled_keys(keys, 0.3) == {
        "fl_x": 40.0 * 10 / 32,
        "fl_y": 50.0 * 7 / 24,
        "cx": 10.0 * 10 / 32,
        "cy": 12.5 * 7 / 24,
        "w": 10,
        "h": 7,
    }
    assert scaled_keys(keys, 0.3, 4)["w"] == 40 and scaled_keys(keys, 0.3, 4)["fl_x"] == 50.0
    # an off-centre principal point scales about the image's corner (pixel centres at +0.5):
    # the splat under it stays under it
    dataset = _camera(cx=9.0)
    model = _splat(1.0, x=(11.0 - 9.0) * DEPTH / FOCAL)  # 2 px right of cx: at x = 11
    image = render_scaled(model, VIEWMAT, dataset, 2.0)
    centroid = (image[..., 0].sum(axis=0) * (np.arange(2 * SIDE) + 0.5)).sum() / image.sum()
    assert centroid == pytest.approx(22.0, abs=0.05)


@pytest.mark.parametrize("scale", [0.01, MAX_SIDE / SIDE + 0.1, 1e308])  # 1e308: OverflowError
def test_a_scale_leaving_a_side_under_one_or_over_the_most_pixels_is_refused(scale):
    with pytest.raises(ValueError, match=r"scale \(--scale\) .*a side from 1 to 8192 pixels"):
        scaled_size(SIDE, SIDE, scale)
    assert scaled_size(SIDE, 2 * SIDE, MAX_SIDE / (2 * SIDE)) == (MAX_SIDE // 2, MAX_SIDE)
    assert scaled_size(SIDE, 2 * SIDE, 1 / SIDE) == (1, 2)  # each end of the range is a side
    # halves round up, as both sides do: half to even made 5x7 at 0.5 render 2x4 (a 5 and a 3
    # both 2), and refused 64x1 as 32x0
    assert scaled_size(5, 7, 0.5) == (3, 4) and scaled_size(3, 3, 0.5) == (2, 2)
    assert scaled_size(64, 1, 0.5) == (32, 1)
