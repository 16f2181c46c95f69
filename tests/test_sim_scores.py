"""SIM's scores on a dataset (sim_scores.evaluate_dataset): a colour camera's views are scored
with their channels together, as `spikegs eval` scores them, and a method whose image a view's
pseudo ground truth is, is left out of that view."""

from __future__ import annotations

import warnings
from types import SimpleNamespace

import numpy as np
import pytest
from spikegs.metrics import psnr, ssim
from spikegs.sim import SIM
from spikegs.sim_scores import evaluate_dataset
from spikegs.spikes.stream import SpikeStream

pytestmark = pytest.mark.usefixtures("one_torch_thread")


def _colour_dataset(tmp_path, pseudo: bool = False):
    """Two channels of Bernoulli spikes (rates 0.1 and 0.4 a readout over a ramp), two on-path
    views at readouts 40 and 60 with each channel's rates as ground truth, one off-path view;
    `pseudo`: the on-path views' ground truth is TFP(65) of their own spikes, doubled instead
    (a pseudo ground truth that differs from TFP(65): a flicker divided out)."""
    h, w, length = 10, 12, 100
    ramp = np.linspace(0.5, 1.0, w, dtype=np.float32)[None, :] * np.ones((h, 1), np.float32)
    rates = [0.2 * ramp, 0.8 * ramp]  # [H, W] per channel
    rng = np.random.default_rng(0)
    streams = [SpikeStream.from_bits(rng.random((length, h, w)) < r) for r in rates]
    views = []
    for name, readout in (("view_000", 40.0), ("view_001", 60.0), ("view_002", None)):
        window = 65 if pseudo and readout is not None else None
        channels = [2 * s.tfp(int(readout), 65) if window else r for s, r in zip(streams, rates)]
        image = np.stack(channels, -1)  # [H, W, C]
        views.append(SimpleNamespace(name=name, image=image, readout=readout, window=window))
    return SimpleNamespace(root=tmp_path, streams=streams, test_views=views)


def test_a_colour_datasets_scores_pool_the_channels_as_eval_does(tmp_path):
    """Each view's channels are scored together (`metrics.psnr` and `ssim` on [H, W, C], as
    `spikegs eval` scores a colour render), not channel by channel and averaged: the mean of
    the channels' PSNRs lies above the pooled one wherever their errors differ."""
    dataset, model = _colour_dataset(tmp_path), SIM(window=33)
    views = dataset.test_views[:2]  # on the path, at readouts 40 and 60
    scores = evaluate_dataset(model, dataset)
    assert set(scores) == {"SIM", "TFP(33)", "TFP(65)", "TFI"}
    for name, images in (
        ("TFP(33)", [np.stack([s.tfp(k, 33) for s in dataset.streams], -1) for k in (40, 60)]),
        ("TFI", [np.stack([s.tfi(k) for s in dataset.streams], -1) for k in (40, 60)]),
    ):
        for m, metric in (("psnr", psnr), ("ssim", ssim)):
            want = np.mean([metric(p, v.image) for p, v in zip(images, views)])
            assert scores[name][m] == pytest.approx(want, rel=1e-12), (name, m)
        channels_mean = np.mean(
            [psnr(p[..., c], v.image[..., c]) for p, v in zip(images, views) for c in (0, 1)]
        )
        assert channels_mean > scores[name]["psnr"] + 0.1, name


def test_a_pseudo_ground_truths_own_method_is_left_out(tmp_path):
    """Every on-path view's ground truth is TFP(65) of its own spikes (a pseudo ground truth, no
    longer equal to TFP(65)'s image: it was scored where it differed): TFP(65) has no view left
    and is left out, the others kept."""
    dataset, model = _colour_dataset(tmp_path, pseudo=True), SIM(window=33)
    with np.errstate(divide="raise"):
        scores = evaluate_dataset(model, dataset)
    assert set(scores) == {"SIM", "TFP(33)", "TFI"}


def test_a_view_between_readouts_is_scored_at_the_nearest_one(tmp_path):
    """On-path views at readouts 39.7 and 60.2 score as at 40 and 60, the nearest readouts
    (truncation, 39, passed every test, whose views lay on whole readouts)."""
    dataset, model = _colour_dataset(tmp_path), SIM(window=33)
    whole = evaluate_dataset(model, dataset)
    for view, readout in zip(dataset.test_views, (39.7, 60.2)):
        view.readout = readout
    assert evaluate_dataset(model, dataset) == whole


def test_a_view_whose_windows_reach_past_the_stream_is_left_out(tmp_path):
    """An on-path view 20 readouts from the stream's start (a real recording's; the loaders
    keep training timestamps away from it, not the stream's ends): TFP(65)'s window reaches
    past the stream, and sim-train failed there once SIM had trained. Left out, said; every
    view so: refused, naming them."""
    dataset, model = _colour_dataset(tmp_path), SIM(window=33)
    dataset.test_views[0].readout = 20.0
    with pytest.warns(UserWarning, match=r"within 32 readouts .* left out .*: view_000 \(readou"):
        scores = evaluate_dataset(model, dataset)
    dataset.test_views[0].readout = 32.0  # 32 readouts before it: TFP(65)'s window fits
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        both = evaluate_dataset(model, dataset)
    dataset.test_views[0].readout = 31.0
    with pytest.warns(UserWarning, match=r"within 32 readouts .*: view_000 \(readout 31\)"):
        evaluate_dataset(model, dataset)
    # SIM's own window, where it is the widest: a view within its half of an end left out
    dataset.test_views[0].readout = 32.0
    with pytest.warns(UserWarning, match=r"within 33 readouts .*67-readout window"):
        evaluate_dataset(SIM(window=67), dataset)
    dataset.test_views = dataset.test_views[1:]  # view_001 alone
    assert scores == evaluate_dataset(model, dataset) != both
    dataset.test_views[0].readout = 90.0
    with pytest.raises(ValueError, match=r"every held-out view .* view_001 \(readout 90\); none"):
        evaluate_dataset(model, dataset)
