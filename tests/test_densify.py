"""Adaptive density control: clone, split, prune, opacity reset and the cap, each with the Adam
moments that go with the Gaussians."""

from __future__ import annotations

import math

import pytest
import torch
from spikegs.densify import Densifier, DensifyConfig
from spikegs.gaussians import PARAMETER_NAMES, GaussianModel

RULES = dict(start=7, every=7, stop=50, grad_threshold=0.5, percent_dense=0.1, min_opacity=0.005)


def _model(scales, opacities, quats=None, means=None):
    """Gaussians of `scales` ([N] isotropic, or [N, 3] along their axes), `opacities`, `quats`
    (default: unrotated) and `means` (default: each its own), each with its own colour and Adam
    moments (one Adam step, at a zero rate, on a loss whose gradient differs for every entry)."""
    n = len(scales)
    scales = torch.tensor(scales, dtype=torch.float32)
    params = {
        "means": torch.arange(3.0 * n).reshape(n, 3) if means is None else means,
        "log_scales": torch.log(scales if scales.dim() == 2 else scales[:, None].repeat(1, 3)),
        "quats": torch.tensor([1.0, 0.0, 0.0, 0.0]).repeat(n, 1) if quats is None else quats,
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


def _densifier(gradients, radius: float = 1.0, **rules) -> Densifier:
    """A Densifier for a scene of `radius` that has seen one render with these screen-space
    gradient norms [N]."""
    densifier = Densifier(DensifyConfig(**{**RULES, **rules}), scene_radius=radius, iterations=100)
    _observe(densifier, gradients)
    return densifier


def _observe(densifier: Densifier, gradients, times: int = 1) -> None:
    """`times` renders in which every Gaussian is seen with these screen gradient norms [N]."""
    grads = torch.tensor(gradients)
    screen = torch.stack([grads, torch.zeros_like(grads)], 1)  # [N, 2] pixels
    for _ in range(times):
        densifier.observe(torch.ones(len(grads)), screen, width=2, height=2)  # NDC = pixels


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


def test_the_threshold_applies_to_the_mean_gradient_over_the_steps_seen():
    """Three steps at 0.3: the mean (0.3) is under the 0.5 threshold, the sum (0.9) over it; then
    each round averages only its own steps (0.6 clones). A summed gradient, and statistics kept
    over a round, passed every test, which observed once a round."""
    model, optimizer = _model([0.05, 0.05], [0.5, 0.5])
    densifier = _densifier([0.3, 0.3])
    _observe(densifier, [0.3, 0.3], times=2)
    densifier.step(model, optimizer, 7)
    assert len(model) == 2
    _observe(densifier, [0.0, 0.6])
    densifier.step(model, optimizer, 14)
    assert len(model) == 3  # the second one cloned


def test_clone_or_split_and_size_pruning_are_in_units_of_the_scene_radius():
    """percent_dense 0.1 of a scene of radius 10: scale 0.5 is cloned, 2.0 split (its halves 2/1.6);
    max_world_size 0.5 of radius 4: scale 1.0 stays, 3.0 goes. Every test's radius was 1."""
    model, optimizer = _model([0.5, 2.0], [0.5, 0.5])
    _densifier([1.0, 1.0], radius=10.0).step(model, optimizer, 7)
    assert len(model) == 4  # kept 0, its clone, the two halves of 1
    assert torch.allclose(model.scales[:2], torch.full((2, 3), 0.5))
    assert torch.allclose(model.scales[2:], torch.full((2, 3), 2.0 / 1.6))
    model, optimizer = _model([1.0, 3.0], [0.5, 0.5])
    rules = dict(opacity_reset_every=20, max_world_size=0.5)
    _densifier([0.0, 0.0], radius=4.0, **rules).step(model, optimizer, 28)
    assert len(model) == 1 and model.scales.max().item() == pytest.approx(1.0)


def test_split_halves_are_samples_of_the_gaussian_along_its_axes():
    """The halves of a split are drawn from N(mean, Σ): 400 splits of scale 0.5 at the origin
    spread 0.5 per axis (both halves at the mean passed every test), and a needle (1, 0.01, 0.01)
    turned 90 degrees about z spreads along world y (offsets left unrotated passed too)."""
    torch.manual_seed(0)  # the split's offsets come from torch's global generator
    model, optimizer = _model([0.5] * 400, [0.5] * 400, means=torch.zeros(400, 3))
    _densifier([1.0] * 400).step(model, optimizer, 7)
    std = model.params["means"].detach().std(dim=0)  # [3]
    assert len(model) == 800 and torch.allclose(std, torch.full((3,), 0.5), rtol=0.15), std
    turned = torch.tensor([math.sqrt(0.5), 0.0, 0.0, math.sqrt(0.5)]).repeat(200, 1)
    model, optimizer = _model([[1.0, 0.01, 0.01]] * 200, [0.5] * 200, turned, torch.zeros(200, 3))
    _densifier([1.0] * 200).step(model, optimizer, 7)
    std = model.params["means"].detach().std(dim=0)
    assert std[1] > 0.8 and std[0] < 0.05 and std[2] < 0.05, std


def test_size_pruning_waits_for_the_round_after_the_reset():
    """step() densifies before it resets: the round at the reset's own iteration prunes nothing
    by size, the next one does (pruning already there passed every test)."""
    rules = dict(every=10, opacity_reset_every=20, max_world_size=0.5)
    model, optimizer = _model([0.05, 0.8], [0.5, 0.5])
    densifier = _densifier([0.0, 0.0], **rules)
    densifier.step(model, optimizer, 20)  # a round, then the first reset
    assert len(model) == 2
    _observe(densifier, [0.0, 0.0])
    densifier.step(model, optimizer, 30)
    assert len(model) == 1


def test_screen_size_pruning_removes_the_gaussians_larger_than_the_cap():
    """densify.max_screen_size 3 px, after the first reset: of radii 2, 5 and 3 px the 5 goes (no
    test set it; a flipped comparison passed them all, and >= for > passed a cap no radius met)."""
    rules = dict(RULES, opacity_reset_every=20, max_world_size=0.0, max_screen_size=3.0)
    model, optimizer = _model([0.05, 0.05, 0.05], [0.5, 0.5, 0.5])
    densifier = Densifier(DensifyConfig(**rules), scene_radius=1.0, iterations=100)
    # radii are whole pixels: one of exactly the cap is not larger than it, and stays (3DGS: >)
    densifier.observe(torch.tensor([2, 5, 3]), torch.zeros(3, 2), width=2, height=2)
    densifier.step(model, optimizer, 28)
    assert model.params["sh_dc"].flatten().tolist() == [0.0, 2.0]


def test_the_last_round_is_never_the_runs_last_iteration():
    """A stop at or past the run's end: the last round falls before the last iteration (which
    `step` never densifies at), 90 of 100 every 10; the run's end itself (100) passed every test,
    and `Trainer.densifies_from` would then mark steps 91..100 as densifying."""
    assert DensifyConfig(start=10, every=10, stop=100).last_round(100) == 90
    assert DensifyConfig(start=10, every=10, stop=500).last_round(100) == 90
    assert DensifyConfig(start=10, every=10, stop=95).last_round(100) == 90
    assert DensifyConfig(start=10, every=10, stop=0).last_round(100) == 50
    assert DensifyConfig(start=60, every=10, stop=0).last_round(100) == 0  # none: 60 > 50


def test_a_run_whose_rounds_never_reach_the_threshold_is_told_so():
    model, optimizer = _model([0.05, 0.05], [0.5, 0.5])
    densifier = _densifier([0.3, 0.1])
    for iteration in range(7, 50, 7):  # every round, the last at 49
        densifier.step(model, optimizer, iteration)
        assert (densifier.unreached(iteration) is None) == (iteration < 49)  # not before it
        _observe(densifier, [0.3, 0.1])
    said = densifier.unreached(49)
    assert "saw, 0.3, " in said and "densify.grad_threshold 0.5" in said and len(model) == 2
    restored = _densifier([])
    restored.load_state_dict(densifier.state_dict())
    assert restored.unreached(100) == said
    earlier = {k: v for k, v in densifier.state_dict().items() if k != "strongest"}
    restored.load_state_dict(earlier)  # a checkpoint from before the check: unknown, not said
    assert restored.unreached(100) is None
    _observe(densifier, [0.9, 0.1])  # with the round's 0.3: a mean of 0.6
    densifier.step(model, optimizer, 49)  # one round reached it: said of no run that densified
    assert len(model) == 3 and densifier.unreached(49) is None


def test_a_round_that_reached_the_threshold_is_not_forgotten_by_weaker_ones():
    """The largest gradient is over every round: a run whose first round grew a clone and whose
    later ones, to the last, stayed under the threshold is not told that it grew none."""
    model, optimizer = _model([0.05, 0.05], [0.5, 0.5])
    densifier = _densifier([0.9, 0.1])  # round 7: 0.9 reaches 0.5
    for iteration in range(7, 50, 7):
        densifier.step(model, optimizer, iteration)
        _observe(densifier, [0.3] * len(model))
    assert len(model) == 3 and densifier.unreached(49) is None


def test_the_runs_last_iteration_never_densifies_even_within_the_window():
    """A stop past the run's end (50 of a 49-iteration run; accepted): its last iteration, 49, a
    round's by `every` 7, densifies nothing (its clones would be saved untrained)."""
    model, optimizer = _model([0.05, 0.05], [0.5, 0.5])
    densifier = Densifier(DensifyConfig(**RULES), scene_radius=1.0, iterations=49)
    _observe(densifier, [0.9, 0.1])
    densifier.step(model, optimizer, 49)
    assert len(model) == 2
    densifier.step(model, optimizer, 42)  # the round before it does
    assert len(model) == 3


def test_a_fresh_densifier_has_seen_no_gradient():
    """Gradients of 1e-4 under the default threshold, 2e-4, are told as the largest seen: its
    record starts at 0 (one at 0.1 said nothing of any run at the default)."""
    model, optimizer = _model([0.05, 0.05], [0.5, 0.5])
    densifier = _densifier([1e-4, 1e-5], grad_threshold=2e-4)
    for iteration in range(7, 50, 7):
        densifier.step(model, optimizer, iteration)
        _observe(densifier, [1e-4, 1e-5])
    assert "saw, 0.0001, " in densifier.unreached(49)
