"""Adaptive density control: clone, split, prune, opacity reset and the cap, each with the Adam
moments that go with the Gaussians."""

from __future__ import annotations

import math

import pytest
import torch
from spikegs.densify import Densifier, DensifyConfig
from spikegs.gaussians import PARAMETER_NAMES, GaussianModel

RULES = dict(start=7, every=7, stop=50, grad_threshold=0.5, percent_dense=0.1, min_opacity=0.005)


def _model(scales, opacities):
    """Isotropic Gaussians of `scales` and `opacities`, each with its own means, colour and Adam
    moments (one Adam step, at a zero rate, on a loss whose gradient differs for every entry)."""
    n = len(scales)
    params = {
        "means": torch.arange(3.0 * n).reshape(n, 3),
        "log_scales": torch.log(torch.tensor(scales)).unsqueeze(1).repeat(1, 3),
        "quats": torch.tensor([1.0, 0.0, 0.0, 0.0]).repeat(n, 1),
        "opacity_logits": torch.logit(torch.tensor(opacities)),
        "sh_dc": torch.arange(float(n)).reshape(n, 1, 1),
        "sh_rest": torch.zeros(n, 0, 1),
    }
    model = GaussianModel(params, torch.zeros(1), sh_degree=0)
    groups = [{"params": [model.params[k]], "name": k} for k in PARAMETER_NAMES]
    optimizer = torch.optim.Adam(groups, lr=0.0)  # moments recorded, parameters left as set
    weights = {
        k: 1 + torch.arange(float(p.numel())).reshape(p.shape) for k, p in model.params.items()
    }
    sum((p * weights[k]).sum() for k, p in model.params.items()).backward()
    optimizer.step()
    return model, optimizer


def _moments(model, optimizer, name):
    return optimizer.state[model.params[name]]["exp_avg"]


def _densifier(gradients, **rules) -> Densifier:
    """A Densifier that has seen one render with these screen-space gradient norms [N]."""
    densifier = Densifier(DensifyConfig(**{**RULES, **rules}), scene_radius=1.0, iterations=100)
    grads = torch.tensor(gradients)
    screen = torch.stack([grads, torch.zeros_like(grads)], 1)  # [N, 2] pixels
    densifier.observe(torch.ones(len(grads)), screen, width=2, height=2)  # NDC = pixels here
    return densifier


def test_small_gaussians_are_cloned_large_ones_split():
    model, optimizer = _model([0.05, 0.5, 0.05], [0.5, 0.5, 0.5])
    before = {k: v.detach().clone() for k, v in model.params.items()}
    means_moments = _moments(model, optimizer, "means").clone()
    torch.manual_seed(0)  # the split's offsets come from torch's global generator
    _densifier([1.0, 1.0, 0.1]).step(model, optimizer, 7)
    # kept 0 and 2, then the clone of 0, then the two halves of 1 (removed)
    assert len(model) == 5
    for name in PARAMETER_NAMES:
        assert torch.equal(model.params[name][:3], before[name][[0, 2, 0]]), name
        assert (
            optimizer.param_groups[PARAMETER_NAMES.index(name)]["params"][0] is model.params[name]
        )
    halves = model.params["log_scales"][3:]
    assert torch.allclose(halves, before["log_scales"][1] - math.log(1.6))
    assert (model.params["means"][3:] - before["means"][1]).norm(dim=1).max() < 5 * 0.5
    assert torch.equal(model.params["sh_dc"][3:], before["sh_dc"][[1, 1]])
    moments = _moments(model, optimizer, "means")
    assert torch.equal(moments[:2], means_moments[[0, 2]]) and not moments[2:].any()


def test_gradients_under_the_threshold_change_nothing():
    model, optimizer = _model([0.05, 0.5], [0.5, 0.5])
    before = {k: v.detach().clone() for k, v in model.params.items()}
    _densifier([0.49, 0.0]).step(model, optimizer, 7)
    assert all(torch.equal(model.params[k], before[k]) for k in PARAMETER_NAMES)


def test_faint_gaussians_are_pruned_with_their_moments():
    model, optimizer = _model([0.05, 0.05, 0.05], [0.5, 0.004, 0.9])
    moments = _moments(model, optimizer, "sh_dc").clone()
    _densifier([0.0, 0.0, 0.0]).step(model, optimizer, 7)
    assert model.params["sh_dc"].flatten().tolist() == [0.0, 2.0]
    assert torch.equal(_moments(model, optimizer, "sh_dc"), moments[[0, 2]])


def test_the_cap_keeps_the_strongest_gradients():
    model, optimizer = _model([0.05, 0.05, 0.05], [0.5, 0.5, 0.5])
    _densifier([0.6, 2.0, 1.0], max_gaussians=4).step(model, optimizer, 7)
    assert len(model) == 4 and model.params["sh_dc"][3].item() == 1.0  # the clone of 1 alone
    _densifier([5.0, 5.0, 5.0, 5.0], max_gaussians=4).step(model, optimizer, 14)
    assert len(model) == 4  # full: nothing grows


def test_opacity_reset_caps_opacities_and_forgets_their_moments():
    model, optimizer = _model([0.05, 0.05], [0.9, 0.004])
    means, means_moments = (
        model.params["means"].detach().clone(),
        _moments(model, optimizer, "means"),
    )
    means_moments = means_moments.clone()
    _densifier([0.0, 0.0], opacity_reset_every=20).step(model, optimizer, 20)  # no densify at 20
    assert model.opacities.tolist() == pytest.approx([0.01, 0.004])
    assert not _moments(model, optimizer, "opacity_logits").any()
    assert torch.equal(model.params["means"], means)
    assert torch.equal(_moments(model, optimizer, "means"), means_moments)


def test_large_gaussians_are_pruned_only_after_the_first_reset():
    rules = dict(opacity_reset_every=20, max_world_size=0.5)
    model, optimizer = _model([0.05, 0.8], [0.5, 0.5])
    _densifier([0.0, 0.0], **rules).step(model, optimizer, 14)  # before the reset at 20
    assert len(model) == 2
    _densifier([0.0, 0.0], **rules).step(model, optimizer, 28)
    assert len(model) == 1 and model.scales.max().item() == pytest.approx(0.05)
    model, optimizer = _model([0.05, 0.8], [0.5, 0.5])
    _densifier([0.0, 0.0], max_world_size=0.5, opacity_reset_every=0).step(model, optimizer, 28)
    assert len(model) == 2  # no reset in the run: never pruned by size


def test_observe_averages_over_the_steps_a_gaussian_was_seen_in_ndc_units():
    """Counting every step (not the visible ones) and swapping width and height both passed
    every test: the tests called observe once, all visible, on a 2x2 image."""
    densifier = Densifier(DensifyConfig(), scene_radius=1.0, iterations=100)
    pixels = torch.tensor([[1.0, 0.0], [0.0, 1.0]])  # [2, 2] screen gradients (per pixel)
    densifier.observe(torch.tensor([3, 2]), pixels, width=8, height=4)
    densifier.observe(torch.tensor([5, 0]), 3 * pixels, width=8, height=4)  # the second hidden
    # NDC = pixels x (width/2, height/2): (1, 0) -> 4, (0, 1) -> 2; (3, 0) -> 12
    torch.testing.assert_close(densifier.grad_sum, torch.tensor([4.0 + 12.0, 2.0]))
    torch.testing.assert_close(densifier.count, torch.tensor([2.0, 1.0]))
    torch.testing.assert_close(densifier.max_radii, torch.tensor([5.0, 2.0]))
