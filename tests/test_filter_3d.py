"""Mip-Splatting's 3D smoothing filter (filter_3d.py, `train.filter_3d`): the widths from the
training views' finest sampling, the convolution of each Gaussian with them, a model that draws
with them, and their .ply property."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from plyfile import PlyData
from spikegs import reference
from spikegs.filter_3d import MARGIN, filter_widths, smoothed
from spikegs.gaussians import GaussianModel
from spikegs.ply import FILTER_3D, load_ply, save_ply

FOCAL, SIDE = 50.0, 40
K = torch.tensor([[FOCAL, 0.0, SIDE / 2], [0.0, FOCAL, SIDE / 2], [0.0, 0.0, 1.0]])


def _view(distance: float) -> torch.Tensor:
    """A world-to-camera viewmat [4, 4]: looking down +z at the world's origin from `distance`."""
    viewmat = torch.eye(4)
    viewmat[2, 3] = distance
    return viewmat


def _widths(points, views, variance: float = 0.2, k: torch.Tensor = K) -> torch.Tensor:
    return filter_widths(torch.tensor(points), torch.stack(views), k, SIDE, SIDE, 0.01, variance)


def test_the_width_is_the_finest_sampling_among_the_views_that_see_a_gaussian():
    """sqrt(variance)·z/f of the nearest view that holds the centre (the larger focal of an
    anisotropic camera); a view that does not hold it (behind, or past the margin) is not
    counted, and a Gaussian no view holds takes the widest width of those one does."""
    near, far = _view(2.0), _view(5.0)
    behind = torch.diag(torch.tensor([-1.0, 1.0, -1.0, 1.0]))  # looking away, 1 unit off
    behind[2, 3] = -1.0
    widths = _widths([[0.0, 0.0, 0.0], [0.0, 0.0, 3.0]], [far, near, behind])
    # the origin: 2 units ahead of `near`; the second point 5 ahead of `near`, 1 behind `behind`
    np.testing.assert_allclose(widths, [math.sqrt(0.2) * 2 / FOCAL, math.sqrt(0.2) * 5 / FOCAL])
    # half the image and MARGIN of its side off the centre at depth 2, in and out of the margin
    edge = (0.5 + MARGIN) * SIDE * 2 / FOCAL
    points = [[0.0, 0.0, 3.0], [0.99 * edge, 0.0, 0.0], [1.01 * edge, 0.0, 0.0]]
    widths = _widths(points, [near, far])
    assert widths[1] == pytest.approx(math.sqrt(0.2) * 2 / FOCAL)  # in `near`'s margin
    assert widths[2] == pytest.approx(math.sqrt(0.2) * 5 / FOCAL)  # in `far`'s only
    unseen = _widths([[0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [50.0, 0.0, 0.0]], [near])
    assert unseen[2] == unseen.max() == pytest.approx(math.sqrt(0.2) * 3 / FOCAL)
    stretched = K.clone()
    stretched[1, 1] = 2 * FOCAL  # finer rows: the finer sampling bounds the detail
    assert _widths([[0.0, 0.0, 0.0]], [near], k=stretched)[0] == pytest.approx(
        math.sqrt(0.2) * 2 / (2 * FOCAL)
    )
    assert not _widths([[0.0, 0.0, 0.0]], [behind]).any()  # no view holds any: none
    none = torch.zeros(0, 4, 4)  # no view at all: none
    assert not filter_widths(torch.zeros(1, 3), none, K, SIDE, SIDE, 0.01, 0.2).any()
    # the near plane, not 0: a point 0.005 ahead of a camera whose near is 0.01 is not held
    close = filter_widths(
        torch.tensor([[0.0, 0.0, 0.0]]), _view(0.005)[None], K, SIDE, SIDE, 0.01, 0.2
    )
    assert close[0] == 0
    assert _widths([[0.0, 0.0, 0.0]], [near], variance=0.0)[0] == 0
    with pytest.raises(ValueError, match="variance expected >= 0"):
        _widths([[0.0, 0.0, 0.0]], [near], variance=-0.1)


def test_the_margin_holds_on_every_side_of_a_wide_image_across_many_views():
    """A 60×20 image (width and height not swapped): a centre MARGIN of a side outside each edge
    is held, one a little further is not; the nearest view is found among more views than one
    batch projects at once (the minimum kept across batches)."""
    width, height, depth = 60, 20, 2.0
    k = torch.tensor([[FOCAL, 0.0, width / 2], [0.0, FOCAL, height / 2], [0.0, 0.0, 1.0]])
    edges = {
        "x": (0.5 + MARGIN) * width * depth / FOCAL,
        "y": (0.5 + MARGIN) * height * depth / FOCAL,
    }
    for axis, edge in edges.items():
        for sign in (1.0, -1.0):
            for inside in (True, False):
                point = [0.0, 0.0, 0.0]
                point["xy".index(axis)] = sign * edge * (0.99 if inside else 1.01)
                alone = filter_widths(
                    torch.tensor([point]), _view(depth)[None], k, width, height, 0.01, 0.2
                )  # held: its width; not: no view holds any Gaussian, 0
                assert (alone[0] > 0) == inside, (axis, sign, inside)
    views = [_view(10.0 + i) for i in range(150)] + [_view(3.0)]  # the nearest in the last batch
    views.insert(5, _view(2.5))  # and a nearer one in the first
    widths = _widths([[0.0, 0.0, 0.0]], views)
    assert widths[0] == pytest.approx(math.sqrt(0.2) * 2.5 / FOCAL)


def test_smoothing_keeps_each_gaussians_integral_and_differentiates():
    """sqrt(s² + w²) and o·Π s/sqrt(s² + w²): o·det S kept (the Gaussian's integral); width 0
    the Gaussian itself; torch's gradcheck in float64."""
    gen = torch.Generator().manual_seed(0)
    scales = torch.rand(20, 3, generator=gen, dtype=torch.float64) * 0.1 + 1e-3
    opacities = torch.rand(20, generator=gen, dtype=torch.float64)
    widths = torch.rand(20, generator=gen, dtype=torch.float64) * 0.05
    wide, faded = smoothed(scales, opacities, widths)
    np.testing.assert_allclose(wide.square(), scales.square() + widths.square()[:, None])
    np.testing.assert_allclose(faded * wide.prod(1), opacities * scales.prod(1), rtol=1e-12)
    same = smoothed(scales, opacities, torch.zeros(20, dtype=torch.float64))
    np.testing.assert_allclose(same[0], scales, rtol=1e-15)
    np.testing.assert_allclose(same[1], opacities, rtol=1e-15)
    arguments = (scales.requires_grad_(), opacities.requires_grad_())
    assert torch.autograd.gradcheck(lambda s, o: smoothed(s, o, widths), arguments)


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_smoothing_extremes_stay_finite(dtype):
    """DESIGN §4's extremes: scales that underflow (1e-30, 0), huge ones (1e30, whose square
    overflows float32), a width of 0 beside a scale of 0: finite scales, opacities in [0, 1] and
    finite gradients; a width of 0 keeps a Gaussian as it is; a needle far under its width
    fades by its two thin axes' ratios."""
    scales = torch.tensor(
        [[1e-30, 1e-30, 1e-30], [0.0, 0.0, 0.0], [1e30, 1e30, 1e30], [1e-4, 1.0, 1.0]],
        dtype=dtype,
    ).requires_grad_()
    opacities = torch.full((4,), 0.9, dtype=dtype).requires_grad_()
    widths = torch.tensor([1e-2, 0.0, 1e-2, 1e-2], dtype=dtype)
    wide, faded = smoothed(scales, opacities, widths)
    (wide.sum() + faded.sum()).backward()
    for tensor in (wide, faded, scales.grad, opacities.grad):
        assert tensor.isfinite().all()
    assert ((faded >= 0) & (faded <= 0.9)).all()
    faded = faded.detach()
    assert faded[1] == pytest.approx(0.9) and faded[2] == pytest.approx(0.9)
    assert faded[0] < 1e-20
    assert faded[3] == pytest.approx(0.9 * 1e-4 / math.hypot(1e-4, 1e-2), rel=1e-4)


def _model(n: int = 30, seed: int = 0) -> GaussianModel:
    gen = torch.Generator().manual_seed(seed)
    model = GaussianModel.random(n, (0.0, 0.0, 0.0), 0.5, 1, 0, gen)
    model.params["log_scales"].data -= 2.0  # small Gaussians: the filter matters
    return model


def test_a_model_with_the_filter_draws_its_smoothed_gaussians():
    """`render` with `filter_3d` is the rasterizer's image of the smoothed scales and opacities:
    the C++ op against the pure-torch reference of the same maths, image and gradients, in
    float64; without it, the Gaussians as they are."""
    model = _model()
    state = model.state_dict()
    state["params"] = {k: v.double() for k, v in state["params"].items()}
    model = GaussianModel.from_state_dict({**state, "background": state["background"].double()})
    views = torch.stack([_view(2.0), _view(3.0)])
    model.filter_3d = filter_widths(model.params["means"], views, K, SIDE, SIDE, 0.01, 0.2)
    assert model.filter_3d.dtype == torch.float64 and (model.filter_3d > 0).all()
    out = model.render(_view(2.0).double(), K.double(), SIDE, SIDE, 0.01)
    (out.image.square().sum()).backward()
    got = {k: model.params[k].grad.clone() for k in ("means", "log_scales", "opacity_logits")}

    p = {k: v.detach().clone().requires_grad_() for k, v in model.params.items()}
    scales, opacities = smoothed(
        p["log_scales"].exp(), torch.sigmoid(p["opacity_logits"]), model.filter_3d
    )
    sh = torch.cat([p["sh_dc"], p["sh_rest"]], dim=1)
    expected = reference.rasterize(
        p["means"],
        p["quats"],
        scales,
        opacities,
        sh,
        _view(2.0).double(),
        K.double(),
        SIDE,
        SIDE,
        sh_degree=0,
        background=model.background.detach(),
        near=0.01,
        far=1e30,
    )
    torch.testing.assert_close(out.image.detach(), expected.image.detach(), rtol=1e-9, atol=1e-12)
    expected.image.square().sum().backward()
    for name, grad in got.items():
        torch.testing.assert_close(grad, p[name].grad, rtol=1e-8, atol=1e-12, msg=name)
    plain = GaussianModel.from_state_dict({**model.state_dict(), "filter_3d": None})
    unsmoothed = plain.render(_view(2.0).double(), K.double(), SIDE, SIDE, 0.01).image
    assert (unsmoothed - out.image.detach()).abs().max() > 0.01


def _seen_variance(variance: float, opacity: float) -> float:
    """The second moment along x (px²) of an isotropic splat of `variance` (px²) and opacity
    over black as the rasterizer draws it, its alpha cut below 1/255: r²/2σ² ~ Exp(1) truncated
    at L = ln(255·opacity), so σ²·(1 − L·e^−L / (1 − e^−L))."""
    cut = math.log(255 * opacity)
    return variance * (1 - cut * math.exp(-cut) / (1 - math.exp(-cut)))


def test_a_finer_render_shows_nothing_finer_than_the_training_views_sampled():
    """The filter's purpose: a Gaussian 0.3 training pixels wide, drawn with 4 times the training
    focal length (the antialiased 2D filter on), is as wide as (0.3² + 0.2)·4² px², and as faint
    as the filter's compensation makes it (its alpha cut at 1/255 as `_seen_variance` says);
    without the 3D filter, 0.3²·4² px²; both beside the 2D filter's 0.3."""
    depth, opacity = 2.0, 1 / (1 + math.exp(-3.0))
    model = GaussianModel.from_points(torch.zeros(1, 3), torch.ones(1, 1), 0.3 * depth / FOCAL)
    model.params["opacity_logits"].data.fill_(3.0)
    model.antialiased = True
    model.filter_3d = filter_widths(
        model.params["means"], _view(depth)[None], K, SIDE, SIDE, 0.01, 0.2
    )
    finer = K.clone()
    finer[:2] *= 4

    def variance_x(m: GaussianModel) -> float:
        image = m.render(_view(depth), finer, 4 * SIDE, 4 * SIDE, 0.01).image.detach()
        weights = image[..., 0].sum(dim=0).double()  # [W]
        x = torch.arange(len(weights), dtype=torch.float64) + 0.5
        mean = (weights * x).sum() / weights.sum()
        return float((weights * (x - mean).square()).sum() / weights.sum())

    for width2 in (0.2, 0.0):  # the 3D filter's variance in training pixels², then none
        splat = (0.3**2 + width2) * 16  # px² at 4x
        faded = opacity * (0.3**2 / (0.3**2 + width2)) ** 1.5  # 3D filter's compensation
        faded *= math.sqrt(splat / (splat + 0.3))  # the antialiased 2D filter's
        expected = _seen_variance(splat + 0.3, faded)
        assert variance_x(model) == pytest.approx(expected, rel=0.02), width2
        model.filter_3d = None


def test_the_filter_is_checked_kept_and_written_as_mip_splattings_property(tmp_path):
    """Widths of another length, negative or not finite are refused; the state dict keeps them;
    the .ply holds them as Mip-Splatting's `filter_3D` property (the scales and opacities
    unfiltered), read back exactly, from a file without our comments too (Mip-Splatting's own);
    a file's negative width is refused naming the property; a
    model without the filter writes no such property."""
    model = _model()
    for bad, said in (
        (torch.zeros(3), r"filter_3d \[30\] expected, not \[3\]"),
        (torch.full((30,), -1.0), "finite widths >= 0"),
        (torch.full((30,), math.nan), "finite widths >= 0"),
    ):
        with pytest.raises(ValueError, match=said):
            model.filter_3d = bad
    widths = torch.linspace(0.0, 0.01, 30)
    model.filter_3d = widths
    copy = GaussianModel.from_state_dict(model.state_dict())
    assert torch.equal(copy.filter_3d, widths)
    assert torch.equal(model.centred_at([1.0, 2.0, 3.0]).filter_3d, widths)
    path = tmp_path / "scene.ply"
    save_ply(model, path)
    vertex = PlyData.read(str(path))["vertex"].data
    np.testing.assert_array_equal(vertex[FILTER_3D], widths.numpy())
    np.testing.assert_array_equal(vertex["opacity"], model.params["opacity_logits"].detach())
    loaded = load_ply(path)
    assert torch.equal(loaded.filter_3d, widths)
    image = model.render(_view(2.0), K, SIDE, SIDE, 0.01).image
    assert torch.equal(loaded.render(_view(2.0), K, SIDE, SIDE, 0.01).image, image)
    ply = PlyData.read(str(path))
    ply["vertex"].comments = []  # as Mip-Splatting writes it: no spikegs comments
    ply.write(str(tmp_path / "mip.ply"))
    with pytest.warns(UserWarning, match="no 'spikegs background' comment"):
        assert torch.equal(load_ply(tmp_path / "mip.ply").filter_3d, widths)
    ply["vertex"].data[FILTER_3D][4] = -0.5
    ply.write(str(tmp_path / "negative.ply"))
    with pytest.raises(ValueError, match="vertex property filter_3D: expected finite widths"):
        with pytest.warns(UserWarning, match="no 'spikegs background' comment"):
            load_ply(tmp_path / "negative.ply")
    # fused: the filter folded into the scales and opacities, the renders the same, and a file
    # of 62 values a Gaussian, which SIBR reads (the filter_3D property shifted its records)
    fused = loaded.fused()
    assert fused.filter_3d is None and loaded.filter_3d is not None and fused.fused() is fused
    torch.testing.assert_close(
        fused.render(_view(2.0), K, SIDE, SIDE, 0.01).image, image, rtol=0, atol=1e-6
    )
    unfiltered = GaussianModel.from_state_dict({**loaded.state_dict(), "filter_3d": None})
    assert (unfiltered.render(_view(2.0), K, SIDE, SIDE, 0.01).image - image).abs().max() > 1e-3
    save_ply(fused, tmp_path / "fused.ply")
    assert len(PlyData.read(str(tmp_path / "fused.ply"))["vertex"].data.dtype.names) == 62
    # opaque Gaussians (logits 20 and 40 round to an opacity of 1) kept finite, to their logit
    # where the width is 0 (inf was written: the second review); widths of another count named
    opaque = _model(4)
    opaque.params["opacity_logits"].data = torch.tensor([20.0, 40.0, 0.0, -30.0])
    opaque.filter_3d = torch.tensor([0.0, 1e-6, 0.0, 0.01])
    logits = opaque.fused().params["opacity_logits"].detach()
    assert logits.isfinite().all() and logits[0] == 20.0 and logits[2] == 0.0, logits
    _, factors = smoothed(opaque.scales.double(), torch.ones(4, dtype=torch.float64),
                          opaque.filter_3d.double())  # fmt: skip
    torch.testing.assert_close(  # 1 - o for the opaque ones: o itself rounds to 1
        torch.sigmoid(-logits.double()),
        1 - torch.sigmoid(torch.tensor([20.0, 40.0, 0.0, -30.0], dtype=torch.float64)) * factors,
        rtol=1e-5,  # (the float32 logit's rounding)
        atol=0,
    )
    opaque.params = {k: v[:3] for k, v in opaque.params.items()}  # densified since: stale
    with pytest.raises(ValueError, match="filter_3d holds 4 widths for 3 Gaussians"):
        opaque.fused()
    model.filter_3d = None
    save_ply(model, tmp_path / "plain.ply")
    assert FILTER_3D not in PlyData.read(str(tmp_path / "plain.ply"))["vertex"].data.dtype.names
    assert load_ply(tmp_path / "plain.ply").filter_3d is None


def test_a_densified_model_refuses_to_draw_with_stale_widths():
    """Widths computed before the Gaussians changed in number are refused by `render`, naming
    the fix, not drawn against the wrong Gaussians."""
    model = _model()
    model.filter_3d = torch.full((30,), 0.01)
    model.params["means"] = torch.nn.Parameter(model.params["means"].detach()[:20])
    for name in ("log_scales", "quats", "opacity_logits", "sh_dc", "sh_rest"):
        model.params[name] = torch.nn.Parameter(model.params[name].detach()[:20])
    with pytest.raises(ValueError, match="30 widths for 20 Gaussians: recompute it"):
        model.render(_view(2.0), K, SIDE, SIDE, 0.01)
