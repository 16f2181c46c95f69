"""Benchmarks that assert something: the stiff cases stay finite and float32 close to float64,
SIM's timed training step computes the literal network's gradients, and the training benchmark's
schedule is the demo's (CI also runs `spikegs bench all --quick`)."""

from __future__ import annotations

import dataclasses
import json
import math
import shutil
import tempfile
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import torch

pytest.importorskip("spikegs._C")

from spikegs import _C  # noqa: E402
from spikegs.bench import rasterizer, sim, spikes, stiff, train  # noqa: E402
from spikegs.data import load_dataset  # noqa: E402
from spikegs.data.scenes import SCENES  # noqa: E402
from spikegs.demo import DEMO_OVERRIDES  # noqa: E402
from spikegs.sim import SIM  # noqa: E402
from spikegs.spikes import SimParams, simulate_spikes  # noqa: E402


def test_stiff_cases_are_finite_and_float32_is_close(tmp_path):
    rows = stiff.run(quick=True, out=tmp_path)["cases"]
    assert len(rows) == len(stiff.CASES)
    for row in rows:
        assert row["non_finite"] == "none", row["case"]
        assert row["zero_grad"] in ("yes", "-"), row["case"]
        assert row["image_err"] < stiff.FLOAT_ERROR_BOUND, row["case"]
        assert row["ref_err"] < stiff.REFERENCE_ERROR_BOUND and row["ref_culls"] == "same"
    written = json.loads((tmp_path / "stiff.json").read_text())
    machine = written["machine"]
    assert machine["build"]["cpu_features"] == " ".join(_C.compiled_cpu_features)  # its build
    assert len(written["load_average"]) == 3  # every bench's (spikes, sim, poses had none)
    assert written["quick"] is True  # (a quick run's figures read as a measurement's)


@pytest.mark.parametrize("max_interval", [1, 3, 40, 1024])
def test_bench_spikes_numpy_tfi_is_the_cores(tmp_path, max_interval):
    """The TFI alternative `bench spikes` times and measures the core against: sparse spikes (a
    pixel's nearest several chunks away, or beyond reach), every readout from the first to the
    last, short and long reaches."""
    from spikegs.spikes import SpikeStream, save_dat

    rng = np.random.default_rng(3)
    bits = rng.random((90, 4, 16)) < np.linspace(0.002, 0.3, 16)  # [T, H, W] rates by column
    path = save_dat(tmp_path / "s.dat", bits.astype(np.uint8), flip=True)
    stream = SpikeStream.open(path, 4, 16)
    frames = np.memmap(path, np.uint8, "r").reshape(90, 4, 2)
    for k in range(90):
        ours = stream.tfi(k, max_interval)
        np.testing.assert_array_equal(spikes._numpy_tfi(frames, k, max_interval), ours)


def test_bench_spikes_tfp_error_looks_past_the_streams_start(tmp_path, monkeypatch):
    """bench spikes' TFP max |diff| compared the 8 earliest of the sorted timestamps it timed
    (readouts 10 to 192 of 20,000): a TFP wrong past readout 1000 reported 0."""
    from spikegs.spikes import SpikeStream

    readouts = 600
    path = tmp_path / "s.dat"
    spikes._write_random_stream(path, readouts)
    stream = SpikeStream.open(path, spikes.HEIGHT, spikes.WIDTH)
    frames = np.memmap(path, np.uint8, "r").reshape(readouts, spikes.HEIGHT, spikes.WIDTH // 8)
    right = SpikeStream.tfp

    def wrong_late(self, k, w):  # [H, W] or [B, H, W]: 1 too bright past the stream's middle
        return right(self, k, w) + (np.asarray(k) >= readouts // 2)[..., None, None]

    monkeypatch.setattr(SpikeStream, "tfp", wrong_late)
    row = spikes._bench_tfp(stream, frames, 33, 40, 2, np.random.default_rng(0))
    assert row["max |diff|"] == 1.0


def test_bench_spikes_numpy_simulator_is_the_cores():
    """The simulator alternative of `bench spikes`: without noise it fires the core's spikes
    (interpolated light, a pixel saturated, one dark); at the default noise as many spikes as the
    core within the noise."""
    light = np.random.default_rng(2).random((3, 6, 16), dtype=np.float32) * 1.5
    light[:, 0, :2] = [0.0, 1.0]  # dark; exactly 1
    light[:, 1, 0] = [8.0, 0.0, 0.0]  # saturated, then dark: no charge banked
    times = np.array([0.0, 70.0, 399.0])
    ours = simulate_spikes(light, 400, frame_times=times, params=spikes.NOISE_FREE)
    theirs = spikes._numpy_simulate(light, times, 400, spikes.NOISE_FREE)
    np.testing.assert_array_equal(theirs, ours)
    noisy = simulate_spikes(light, 400, frame_times=times)
    count = spikes._spike_count(noisy)
    numpy_count = spikes._spike_count(spikes._numpy_simulate(light, times, 400, SimParams()))
    assert abs(numpy_count - count) < 4 * math.sqrt(count), (numpy_count, count)


def test_bench_spikes_numpy_simulator_reads_the_last_frame_as_the_core():
    """The core reads a readout at the last frame's time as that frame (5baf63f), where the numpy
    model kept frames[F-2] + 1 · (frames[F-1] - frames[F-2]), which rounds in float32: `bench
    spikes` times the core against it with the last readout at the last frame's time, and counted
    pixels a voltage within a rounding of the threshold tips as "spikes differing". Light built
    so (as test_a_chunk_ending_on_a_frame_time_reads_that_frame): 14 of 4096 differed."""
    p = 4096
    s = np.random.default_rng(0).uniform(0.2, 3.9, p).astype(np.float32)
    kept = np.float32(97.5) + np.float32(25) * s - np.float32(100)  # v after readout 1
    light = np.zeros((3, 1, p), np.float32)  # a frame each readout, the last at readout 2
    light[0], light[1] = 7.9, s
    light[2] = ((100.0 - kept.astype(np.float64)) / 25.0).astype(np.float32)
    times = np.array([0.0, 1.0, 2.0])
    ours = simulate_spikes(light, 3, frame_times=times, params=spikes.NOISE_FREE)
    np.testing.assert_array_equal(spikes._numpy_simulate(light, times, 3, spikes.NOISE_FREE), ours)


def test_bench_data_lies_in_a_named_temporary_folder_removed_after(tmp_path, monkeypatch):
    """A bench part's temporary data (a 250 MB stream for `bench spikes`) lies in
    $TMPDIR/spikegs-bench-PART-*, so that one a killed process left says whose it is, and is
    removed when the part stops, on an error too."""
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    folders = []

    def stop(path, *args):  # the stream written: where is it?
        folders.append(path.parent)
        raise RuntimeError("stopped")

    monkeypatch.setattr(spikes, "_bench_stream", stop)
    with pytest.raises(RuntimeError, match="stopped"):
        spikes.run(quick=True, out=tmp_path / "out")
    assert folders[0].parent == tmp_path and folders[0].name.startswith("spikegs-bench-spikes-")
    assert not folders[0].exists()


def test_bench_spikes_simulator_times_are_medians(monkeypatch):
    """TFP's and TFI's times against numpy are medians of 3; the simulator's were one call each,
    which the machine's load moved (BENCHMARKS.md's two rows of the same core work, 2,318 and
    3,638 readouts/s). Three calls a side now, their median: a call slowed by another job does
    not move it."""
    import time

    clock = [0.0]
    took = iter([1.0, 9.0, 2.0, 40.0, 20.0, 90.0] * 2)  # ours, then numpy's, per noise

    def call(*args, **kwargs):
        clock[0] += next(took)
        return np.zeros((4, 2, 1), np.uint8)

    monkeypatch.setattr(time, "perf_counter", lambda: clock[0])
    monkeypatch.setattr(spikes, "simulate_spikes", call)
    monkeypatch.setattr(spikes, "_numpy_simulate", call)
    rows = spikes._simulator_vs_numpy(np.zeros((3, 2, 8), np.float32), 4)
    assert [(r["readouts/s"], r["numpy readouts/s"]) for r in rows] == [(2.0, 0.1)] * 2
    assert rows[0]["vs numpy"] == 20.0
    # spikes that differ are counted without noise alone (with it the draws differ)
    assert [r["noise"] for r in rows] == ["default", "none"] and "spikes differing" not in rows[0]
    assert rows[1]["spikes differing"] == 0


def _spike_statistics(packed: np.ndarray, width: int) -> tuple[float, float, float]:
    """The mean readout of each pixel's first spike, the spread (standard deviation) of the
    intervals between a pixel's spikes and that of the pixels' spike counts, of packed readouts
    [T, H, ceil(W/8)]."""
    bits = np.unpackbits(packed, axis=-1, bitorder="little")[..., :width]
    bits = bits.reshape(len(packed), -1)  # [T, pixels]
    pixel, readout = np.nonzero(bits.T)  # by pixel, then readout
    intervals = np.diff(readout)[pixel[1:] == pixel[:-1]]
    return float(bits.argmax(axis=0).mean()), float(intervals.std()), float(bits.sum(0).std())


@pytest.mark.parametrize(
    "params",
    [
        dataclasses.replace(spikes.NOISE_FREE, shot_noise=True),
        dataclasses.replace(spikes.NOISE_FREE, temporal_sigma=0.1),
        dataclasses.replace(spikes.NOISE_FREE, random_init=True),
        dataclasses.replace(spikes.NOISE_FREE, fpn_sigma=0.03),
        dataclasses.replace(spikes.NOISE_FREE, dark_rate=0.05),  # its spread: dark_sigma 0.5
        SimParams(),
    ],
    ids=["shot", "threshold", "start", "thresholds", "dark", "default"],
)
def test_bench_spikes_numpy_simulator_draws_the_cores_noise(params):
    """The numpy simulator `bench spikes` times the core against draws its noise too: spike counts
    alone agreed with a numpy model that had dropped the shot noise, the threshold noise or the
    random start (a spike a pixel in 300 readouts: within the noise), which does less work. Each
    noise on its own, then the default's: the first spikes' mean readout (a random start halves
    it), the spread of the intervals between spikes and that of the pixels' counts (both 0
    without noise, at constant light)."""
    light = np.full((3, 32, 32), 0.4, np.float32)  # 0.1 spikes a readout: intervals of ~10
    times = np.array([0.0, 150.0, 299.0])
    ours = _spike_statistics(simulate_spikes(light, 300, frame_times=times, params=params), 32)
    theirs = _spike_statistics(spikes._numpy_simulate(light, times, 300, params), 32)
    assert abs(theirs[0] - ours[0]) < 0.6, (theirs, ours)  # ±0.1 for 1024 uniform starts
    assert theirs[1] == pytest.approx(ours[1], rel=0.05, abs=0.02), (theirs, ours)
    assert theirs[2] == pytest.approx(ours[2], rel=0.15, abs=0.05), (theirs, ours)  # ±2 % each


def test_a_stiff_case_that_fails_fails_the_bench(tmp_path, monkeypatch, capsys):
    """`spikegs bench stiff` printed its table and exited 0 whatever it showed (CI runs `bench
    all --quick`: only a crash failed it); a row beyond a bound now exits 1, naming it."""
    from spikegs.cli import main

    assert main(["bench", "stiff", "--out", str(tmp_path / "ok")]) == 0
    assert json.loads((tmp_path / "ok" / "stiff.json").read_text())["failures"] == []
    monkeypatch.setattr(stiff, "GRAD_ERROR_BOUND", 1e-7)  # the needles' gradients exceed it
    capsys.readouterr()
    assert main(["bench", "stiff", "--out", str(tmp_path / "tight")]) == 1
    assert "FAILED bench stiff: needles 0.2 x 1e2..1e4 px: rel_means " in capsys.readouterr().err


def test_a_core_wrong_in_both_precisions_fails_bench_stiff(tmp_path, monkeypatch):
    """bench stiff compared the core's float32 with its own float64: a core that drew nothing, or
    half the image, in both passed every check (a helper's mutations). The float64 reference
    shows it."""
    core = stiff.rasterize

    def halved(*args, **kwargs):
        out = core(*args, **kwargs)
        return out._replace(image=0.5 * out.image)

    monkeypatch.setattr(stiff, "rasterize", halved)
    failures = stiff.run(quick=True, out=tmp_path)["failures"]
    assert len(failures) == len(stiff.CASES)  # every case (the empty one: its background)
    assert "scales 1e-6..1e3: ref_err 0.501 > 1e-06" in failures


def test_a_nan_in_the_references_alpha_fails_bench_stiff(tmp_path, monkeypatch):
    """ref_err was Python's max over the image's, alpha's and gradients' errors, which drops a
    NaN that is not first: a NaN in the reference's alpha (or a gradient) passed every check."""
    drawn = stiff.reference.rasterize

    def nan_alpha(*args, **kwargs):
        out = drawn(*args, **kwargs)
        return out._replace(
            alpha=out.alpha
            + torch.nn.functional.pad(
                torch.full((1, 1), float("nan"), dtype=out.alpha.dtype),
                (0, out.alpha.shape[1] - 1, 0, out.alpha.shape[0] - 1),
            )
        )

    monkeypatch.setattr(stiff.reference, "rasterize", nan_alpha)
    failures = stiff.run(quick=True, out=tmp_path)["failures"]
    assert len(failures) == len(stiff.CASES)
    assert all(failure.endswith(": ref_err nan > 1e-06") for failure in failures), failures


def test_a_gradient_to_a_culled_gaussian_fails_bench_stiff(tmp_path, monkeypatch):
    """A core whose image is right but whose gradient reaches every Gaussian, those behind the
    camera too: the cases that name Gaussians without a gradient fail on them."""
    core = stiff.rasterize

    def leaking(means, *args, **kwargs):
        out = core(means, *args, **kwargs)
        leak = 1e-3 * (means.sum() - means.sum().detach())  # 0, with a gradient to every mean
        return out._replace(image=out.image + leak)

    monkeypatch.setattr(stiff, "rasterize", leaking)
    failures = stiff.run(quick=True, out=tmp_path)["failures"]
    assert "near plane and behind camera: zero_grad NO" in failures


def test_bench_stiff_names_each_check_a_row_fails():
    """Each of a row's checks, failed alone, is named with its value and bound: two of them
    (the float32 image's error, culls unlike the reference's) no case's run fails."""
    good = {"ref_err": 0.0, "ref_culls": "same", "image_err": 0.0, "rel_means": 0.0}
    good.update(non_finite="none", zero_grad="yes")
    assert stiff.failed_checks(good) == []
    failing = {
        "ref_err": 2 * stiff.REFERENCE_ERROR_BOUND,
        "ref_culls": "NO",
        "image_err": 3 * stiff.FLOAT_ERROR_BOUND,
        "rel_means": 4 * stiff.GRAD_ERROR_BOUND,
        "non_finite": "image",
        "zero_grad": "NO",
    }
    named = [
        f"ref_err {2 * stiff.REFERENCE_ERROR_BOUND:.3g} > {stiff.REFERENCE_ERROR_BOUND:g}",
        "ref_culls NO",
        f"image_err {3 * stiff.FLOAT_ERROR_BOUND:.3g} > {stiff.FLOAT_ERROR_BOUND:g}",
        f"rel_means {4 * stiff.GRAD_ERROR_BOUND:.3g} > {stiff.GRAD_ERROR_BOUND:g}",
        "non-finite image",
        "zero_grad NO",
    ]
    for (key, value), problem in zip(failing.items(), named):
        assert stiff.failed_checks({**good, key: value}) == [problem]
    # a NaN error (the reference's image NaN) passed every bound: NaN > bound is false (the
    # bench trial)
    for key, bound in (
        ("ref_err", stiff.REFERENCE_ERROR_BOUND),
        ("image_err", stiff.FLOAT_ERROR_BOUND),
        ("rel_means", stiff.GRAD_ERROR_BOUND),
    ):
        assert stiff.failed_checks({**good, key: math.nan}) == [f"{key} nan > {bound:g}"]


def test_the_pairs_are_the_cores_count_else_each_visible_boxs_pixels(monkeypatch):
    """A row's pairs are the core's own count; an output without the core's context (the
    reference's) is estimated from each visible Gaussian's box, clipped to the image."""
    monkeypatch.setattr(rasterizer, "_peak_rss_mb", lambda *args: None)
    row = rasterizer.measure(100, 16, 16, 1, repeats=1)
    assert row["pairs_source"] == "core" and row["pairs"] > 0
    out = SimpleNamespace(
        image=torch.zeros(16, 16, 1),
        radii=torch.tensor([2, 0, 3]),  # a 4x4 box, a culled one, one cut by the left edge
        means2d=torch.tensor([[8.0, 8.0], [5.0, 5.0], [-1.0, 8.0]]),
    )
    assert rasterizer._pairs(out, 16, 16) == (4 * 4 + 2 * 6, "box estimate")


def test_the_reference_rasterizer_is_timed_after_its_first_calls(monkeypatch):
    """bench rasterizer timed the pure-torch reference's very first call, 15-20 % slower than
    later ones (torch's first calls; a benchmark audit): a render of 10 Gaussians goes first."""
    reference_rasterize, sizes = rasterizer.reference.rasterize, []

    def recorded(means, *args, **kwargs):
        sizes.append(len(means))
        return reference_rasterize(means, *args, **kwargs)

    monkeypatch.setattr(rasterizer.reference, "rasterize", recorded)
    monkeypatch.setattr(rasterizer, "_peak_rss_mb", lambda *args: None)  # (a fresh process)
    rasterizer.measure(100, 16, 16, 1, repeats=1)
    assert sizes == [rasterizer.WARMUP_N, 100, 100]


def test_bench_rasterizer_times_the_antialiased_filter_beside_the_plain(monkeypatch):
    """A row's aa_* columns are the antialiased filter's: its timed renders and its float32 and
    float64 ones are drawn with it, its cost is its time over the plain filter's (pairs timed in
    turn), its float32 error is small."""
    core, filters = rasterizer.rasterize, []

    def recorded(*args, antialiased=False, **kwargs):
        filters.append(antialiased)
        return core(*args, antialiased=antialiased, **kwargs)

    monkeypatch.setattr(rasterizer, "rasterize", recorded)
    monkeypatch.setattr(rasterizer, "_peak_rss_mb", lambda *args: None)  # (a fresh process)
    monkeypatch.setattr(rasterizer, "REFERENCE_MAX_N", 0)  # (its timing is another test's)
    row = rasterizer.measure(100, 16, 16, 1, repeats=1)
    assert filters.count(True) >= 3 and filters[-2:] == [True, True] and False in filters
    # its cost: the antialiased render over the plain one, timed in turn (`median_ratio`); a
    # ratio of microseconds timed once, which a descheduling under load took to 38.7 (a CI run
    # beside other work): positive and finite, its size the benchmark's to say
    assert "APAP" in "".join("A" if aa else "P" for aa in filters)
    assert 0 < row["aa_cost"] < math.inf
    assert 0 <= row["aa_err_image_f32"] < 1e-4


def test_bench_sim_draws_its_bar_only_on_a_terminal_and_never_with_no_progress(
    tmp_path, monkeypatch
):
    """bench sim drew SIM's training bar on a terminal with no way to turn it off (every other
    command has --no-progress); off the terminal it draws none."""
    from spikegs.cli import main

    asked = []
    monkeypatch.setattr(sim, "run", lambda quick, out, progress: asked.append(progress) or {})
    for terminal, argv in [(True, []), (True, ["--no-progress"]), (False, [])]:
        bars = lambda off, terminal=terminal: terminal and not off  # noqa: E731 (show_bars's rule)
        monkeypatch.setattr("spikegs.bench.cli.show_bars", bars)
        assert main(["bench", "sim", "--quick", *argv, "--out", str(tmp_path)]) == 0
    assert asked == [True, False, False]


def test_train_schedule_is_the_demo_one_stretched():
    demo = DEMO_OVERRIDES["train"]["iterations"]
    assert train.schedule(demo, quick=False)["densify"] == DEMO_OVERRIDES["densify"]
    half = train.schedule(demo // 2, quick=False)
    assert half["densify"]["stop"] == round(DEMO_OVERRIDES["densify"]["stop"] / 2)
    evals = math.ceil(half["train"]["iterations"] / half["train"]["eval_every"])
    assert evals == train.POINTS  # the last evaluation is at the end
    # --grad-threshold replaces the threshold alone, the stretched schedule kept
    dense = train.schedule(demo // 2, quick=False, grad_threshold=1e-4)
    assert dense["densify"] == {**half["densify"], "grad_threshold": 1e-4}


def test_sim_train_step_rows_time_the_same_gradients():
    rows = sim._train_step_rows(SIM(), batch=2, crop=16, repeats=1)
    assert [r["variant"] for r in rows] == [
        "train step rotated pairs (literal), channels-first",
        "train step per-branch, channels-first",
        "train step per-branch, channels-last",
    ]
    for row in rows:
        assert row["seconds"] > 0 and row["grad_err"] < 1e-4, row


def _run(psnr: float, **extra) -> dict:
    keys = ("ssim", "ssim_3dgs", "train_seconds", "sim_seconds", "gaussians", "wall_seconds")
    return {"psnr": psnr, **{k: 1.0 for k in keys}, "uses_sim": False, "curve": [], **extra}


def test_train_seeds_average_and_gains_pair_seed_by_seed():
    methods = {
        "tfp33": train.over_seeds([_run(25.0), _run(27.0)]),
        "spikegs": train.over_seeds([_run(26.0, curve=["seed 0"]), _run(28.4)]),
        "only_instant": train.over_seeds([_run(25.5), _run(27.5)]),
        "only_exposure": train.over_seeds([_run(25.8), _run(27.6)]),
    }
    spikegs = methods["spikegs"]
    assert spikegs["psnr"] == pytest.approx(27.2) and spikegs["curve"] == ["seed 0"]
    assert spikegs["psnr_std"] == pytest.approx(math.sqrt(2) * 1.2)
    assert [s["psnr"] for s in spikegs["seeds"]] == [26.0, 28.4]
    gain = train.paired_gains(methods)["spikegs"]  # +1.0 and +1.4: paired, not pooled
    assert gain["mean"] == pytest.approx(1.2) and gain["std"] == pytest.approx(math.sqrt(2) * 0.2)
    assert train.ablation_order(methods) == "spikegs > only_exposure > only_instant"
    methods["only_instant"] = train.over_seeds([_run(26.0), _run(27.8)])
    assert train.ablation_order(methods) == "holds"
    assert train.ablation_order({"tfp33": methods["tfp33"]}) is None
    row = {r["method"]: r for r in train._table(methods, train.paired_gains(methods))}["spikegs"]
    assert row["PSNR"] == "27.20 ± 1.70" and row["gain over tfp33 (dB)"] == "1.20 ± 0.28"
    # the plots draw seed 0's curve: its time axis starts at seed 0's SIM, not the mean's
    one = {"tfp33": train.over_seeds([_run(25.0)]), "spikegs": train.over_seeds([_run(26.5)])}
    assert one["spikegs"]["psnr_std"] is None  # one seed: no spread measured (0.0 read as agreed)
    assert train.paired_gains(one)["spikegs"] == {"mean": 1.5, "std": None}
    timed = train.over_seeds([_run(26.0, sim_seconds=30.0), _run(27.0, sim_seconds=50.0)])
    assert timed["sim_seconds"] == 40.0 and timed["curve_sim_seconds"] == 30.0
    # times are medians over the seeds: one run slowed by another job does not move them
    slowed = [_run(26.0, sim_seconds=s) for s in (30.0, 31.0, 90.0)]
    assert train.over_seeds(slowed)["sim_seconds"] == 31.0
    assert [s["sim_seconds"] for s in train.over_seeds(slowed)["seeds"]] == [30.0, 31.0, 90.0]
    assert isinstance(row["Gaussians"], int)


def test_ablation_order_holds_only_where_each_method_scores_strictly_higher():
    """Tied means are not an order: 'holds' says both losses > only instant > only exposure."""
    methods = {
        "spikegs": train.over_seeds([_run(27.0)]),
        "only_instant": train.over_seeds([_run(27.0)]),
        "only_exposure": train.over_seeds([_run(26.0)]),
    }
    assert train.ablation_order(methods) == "spikegs = only_instant > only_exposure"
    methods["only_exposure"] = train.over_seeds([_run(27.0)])
    assert train.ablation_order(methods) == "spikegs = only_instant = only_exposure"
    methods["only_instant"] = train.over_seeds([_run(26.0)])
    assert train.ablation_order(methods) == "spikegs = only_exposure > only_instant"
    methods["only_exposure"] = train.over_seeds([_run(25.0)])
    assert train.ablation_order(methods) == "holds"
    methods["only_exposure"] = train.over_seeds([_run(26.0)])  # the paper's order, the last tied
    assert train.ablation_order(methods) == "spikegs > only_instant = only_exposure"


def test_ablation_order_says_on_how_many_seeds_it_holds():
    """'holds' judges the means: the line and the JSON say on how many seeds the order held
    (the means can follow it where one seed of two does not)."""
    methods = {
        "spikegs": train.over_seeds([_run(27.0), _run(28.0)]),
        "only_instant": train.over_seeds([_run(26.0), _run(28.2)]),
        "only_exposure": train.over_seeds([_run(25.0), _run(27.5)]),
    }
    assert train.ablation_order(methods) == "holds"
    assert train.ablation_seeds(methods) == 1
    for tie, psnr in (("only_instant", 27.0), ("only_exposure", 26.0)):  # seed 0: 27 > 26 > 25
        tied = {**methods, tie: train.over_seeds([_run(psnr), *methods[tie]["seeds"][1:]])}
        assert train.ablation_seeds(tied) == 0  # either lead tied: no order on that seed
    assert train.ablation_line(methods) == (
        "paper's ablation order (both > only instant > only exposure): holds in the mean "
        "over 2 seeds, on 1 of them"
    )
    exposure_ahead = {**methods, "only_exposure": train.over_seeds([_run(26.0), _run(28.5)])}
    assert train.ablation_line(exposure_ahead).endswith(
        ": spikegs > only_exposure > only_instant (means over 2 seeds)"
    )
    one = {name: train.over_seeds(r["seeds"][:1]) for name, r in methods.items()}
    assert train.ablation_seeds(one) == 1
    assert train.ablation_line(one).endswith(": holds (one seed)")
    assert train.ablation_seeds({"spikegs": methods["spikegs"]}) is None
    assert train.ablation_line({"spikegs": methods["spikegs"]}) is None


def test_bench_writes_into_the_documented_folder_without_out(tmp_path, monkeypatch):
    """Without --out: bench-results, or bench-results-quick with --quick (the README's)."""
    from spikegs.cli import main

    monkeypatch.chdir(tmp_path)
    outs = []
    monkeypatch.setattr(stiff, "run", lambda quick, out: outs.append(out) or {"failures": []})
    assert main(["bench", "stiff", "--quick"]) == 0 and main(["bench", "stiff"]) == 0
    assert outs == [Path("bench-results-quick"), Path("bench-results")]


@pytest.mark.parametrize(
    "name, held", [("train.json", "a spikegs run (train.json)"), ("meta.json", "a dataset (meta")]
)
def test_bench_refuses_an_out_that_holds_a_run_or_a_dataset(
    name, held, tmp_path, monkeypatch, capsys
):
    """`bench train --out RUN` wrote its train.json over the run's (eval then refused the run),
    and its datasets, runs and figures among the run's or a dataset's files."""
    from spikegs.cli import main

    monkeypatch.setattr(stiff, "run", lambda quick, out: pytest.fail("worked"))
    (tmp_path / name).write_text("{}")
    assert main(["bench", "stiff", "--quick", "--out", str(tmp_path)]) == 2
    said = capsys.readouterr().err
    assert f"--out {tmp_path} holds {held}" in said
    # stiff writes no datasets or runs, as it said it would (bench train does)
    assert "spikegs bench stiff would write its own files (figures, JSON)" in said
    assert [p.name for p in tmp_path.iterdir()] == [name]
    monkeypatch.setattr(train, "run", lambda *args, **kwargs: pytest.fail("worked"))
    for scenes, data in (("solids", "its dataset"), ("solids,wires", "datasets")):
        argv = ["bench", "train", "--quick", "--scenes", scenes, "--out", str(tmp_path)]
        assert main(argv) == 2
        assert f"own files ({data} in {tmp_path / 'data'}, its runs in {tmp_path / 'runs'}" in (
            capsys.readouterr().err
        )


def test_bench_runs_again_where_bench_train_wrote_its_results(tmp_path, monkeypatch):
    """bench train's own OUT/train.json (a run's summary's name) refused every later bench into
    its folder, bench-results-quick too, as a run's; a run's train.json still is (above)."""
    from spikegs.bench.common import write_results
    from spikegs.cli import main

    write_results(tmp_path, "train", {"data": {}}, quick=True)
    ran = []
    monkeypatch.setattr(stiff, "run", lambda quick, out: ran.append(out) or {"failures": []})
    assert main(["bench", "stiff", "--quick", "--out", str(tmp_path)]) == 0 and ran == [tmp_path]


@pytest.mark.parametrize(
    "argv, message",
    [
        (["bench", "train", "--methods", ","], "--methods ',': expected comma-separated names"),
        (["bench", "spikes", "--seeds", "3"], "--seeds: options of bench train, not of bench"),
        (["bench", "rasterizer", "--seeds", "1"], "--seeds: options of bench train"),
        (["bench", "sim", "--methods", "tfi"], "--methods: options of bench train"),
        (["bench", "rasterizer", "--grad-threshold", "1e-4"], "--grad-threshold: options of"),
        (["bench", "spikes", "--spp", "16"], "--spp: options of bench train, not of bench"),
    ],
)
def test_bench_options_that_would_do_nothing_are_refused(argv, message, capsys):
    """`--methods ,` ran the default methods; train's options were ignored by the other parts."""
    from spikegs.cli import main

    assert main(argv) == 2
    assert message in capsys.readouterr().err


@pytest.mark.parametrize(
    "spp, message",
    [
        ("2", "spp (--spp): a built-in scene samples each"),
        (str(16384**2), "spp (--spp) 268435456: 64x64 frames would be drawn at 1048576x1048576"),
        (str(8192**2), "frames would be drawn at 524288x524288, 4096.0 GiB a frame, over half"),
    ],
)
def test_bench_all_refuses_an_spp_it_cannot_draw_before_any_part(spp, message, tmp_path, capsys):
    """`bench all --spp 2` (not a square) or an spp whose frames pass the rasterizer's side or
    the memory (the quick scenes' 64² at 8192² spp: 4 TiB a frame) is refused before the
    rasterizer, spikes and sim parts run (a check left to bench train ran them first)."""
    from spikegs.cli import main

    assert main(["bench", "all", "--quick", "--spp", spp, "--out", str(tmp_path / "b")]) == 2
    said = capsys.readouterr()
    assert message in said.err
    assert "==" not in said.out and not (tmp_path / "b" / "rasterizer.json").exists()


def test_train_selection_names_what_is_unknown():
    """Each name refused is told with its option ("unknown nope, tfp99; scenes: ...; methods:
    ..." named neither, the CLI-help trial)."""
    assert train.selection(quick=True) == ([train.HEADLINE_SCENE], list(train.QUICK_METHODS))
    with pytest.raises(ValueError) as refused:
        train.selection(False, ["solids", "nope"], ["tfp99", "tfi"])
    assert str(refused.value) == (
        "bench train --scenes nope: unknown; known: solids, wires, fine-texture; --methods "
        f"tfp99: unknown; known: {', '.join([*train.METHODS, 'sim17'])}"
    )
    with pytest.raises(ValueError, match=r"^bench train --methods bogus: unknown; known: spikeg"):
        train.selection(False, None, ["bogus"])
    with pytest.raises(ValueError, match=r"^bench train --seeds: expected >= 1, found 0$"):
        train.selection(False, seeds=0)


def test_train_selection_accepts_every_method_of_configs():
    """`--methods sim17` was refused as unknown although configs/sim17.yaml exists."""
    from spikegs.config import available_methods

    methods = available_methods()
    assert "sim17" in methods
    assert train.selection(False, ["solids"], methods) == (["solids"], methods)


def test_train_selection_runs_a_repeated_name_once():
    """`--scenes solids,solids` trained and wrote solids twice."""
    chosen = train.selection(False, ["wires", "solids", "wires"], ["tfi", "tfp33", "tfi"])
    assert chosen == (["wires", "solids"], ["tfi", "tfp33"])


def test_train_runs_every_seed(tmp_path):
    result = train.run(quick=True, out=tmp_path, seeds=2, methods=["tfp33"])
    tfp33 = result["scenes"][train.HEADLINE_SCENE]["methods"]["tfp33"]
    assert len(tfp33["seeds"]) == 2 and result["seeds"] == 2
    demo_threshold = DEMO_OVERRIDES["densify"]["grad_threshold"]
    assert result["schedule"]["densify"]["grad_threshold"] == demo_threshold  # the default
    assert tfp33["seeds"][0]["psnr"] != tfp33["seeds"][1]["psnr"]  # two runs, not one twice
    assert (tmp_path / "runs" / train.HEADLINE_SCENE / "tfp33-seed1" / "train.json").exists()


def test_train_simulates_its_scenes_at_spp_and_reuses_only_a_dataset_made_so(
    tmp_path, capsys, monkeypatch
):
    """`bench train --spp 4`: the scenes as a camera sees them (each pixel its box's mean light),
    said in the table's heading and recorded; a dataset cached at another spp, or with its
    training views spaced otherwise, is simulated again, one made so reused."""
    result = train.run(quick=True, out=tmp_path, methods=["tfp33"], spp=4)
    assert result["data"]["spp"] == 4
    assert "64x64 at 4 spp, 4 test views" in capsys.readouterr().out
    root = tmp_path / "data" / train.HEADLINE_SCENE
    dataset = load_dataset(root)
    assert dataset.meta["spp"] == 4
    made_so = {**train.QUICK_DATA, "spp": 4}
    assert train._matches(dataset, train.HEADLINE_SCENE, made_so)
    assert not train._matches(dataset, train.HEADLINE_SCENE, {**train.QUICK_DATA, "spp": 1})
    assert train.dataset_for(train.HEADLINE_SCENE, root, made_so)[1] == 0.0  # reused
    # of its size but simulated otherwise, or posed by SfM: `spikegs simulate --color --threshold
    # 10 --seed 7` into its folder was taken for its data (the bench trial)
    threshold = {**dataset.meta["sim"], "threshold": 10.0}
    others = [("seed", 7), ("channels", 3), ("sim", threshold), ("degrees_per_readout", 0.3)]
    for key, value in [*others, ("frame_every", 4), ("up", [0, 1, 0]), ("poses_from", "sfm")]:
        meta = {**dataset.meta, key: value}
        other = SimpleNamespace(meta=meta, test_views=dataset.test_views)
        other.train_timestamps = dataset.train_timestamps
        assert not train._matches(other, train.HEADLINE_SCENE, made_so), key
    every = train.default_train_every(made_so["readouts"])
    monkeypatch.setattr(train, "default_train_every", lambda readouts: every + 1)
    assert not train._matches(dataset, train.HEADLINE_SCENE, made_so)  # other training views


def test_median_ratio_times_its_pairs_in_turn(monkeypatch):
    """The anti-aliasing cost, two medians timed apart, measured 0.35 to 2.08 for about 1 on a
    loaded machine: timed in turn, a pair at a time, a load that grows 10 % a call moves a cost
    of 2 to 1.82 (timed apart: 1.24)."""
    from spikegs.bench import common

    clock, calls = [0.0], []

    def costing(seconds: float, name: str):
        def call():
            calls.append(name)
            clock[0] += seconds * 1.1 ** len(calls)

        return call

    monkeypatch.setattr(common.time, "perf_counter", lambda: clock[0])
    ratio = common.median_ratio(costing(2.0, "aa"), costing(1.0, "plain"), repeats=5)
    assert calls == ["aa", "plain"] * 6 and ratio == pytest.approx(2 / 1.1)


def test_points_per_run_counts_a_short_runs_evaluations():
    """points_per_run said 8 for a run of 1 iteration (1 point) or 10 (5: every 2nd)."""
    counts = {n: train.evaluations(n) for n in (1, 3, 8, 10, 100, 1800)}
    assert counts == {1: 1, 3: 3, 8: 8, 10: 5, 100: 8, 1800: 8}


def test_bench_without_a_part_names_the_word_its_usage_shows(capsys):
    """`spikegs bench` alone said "required: part", a word its usage (which showed the parts'
    set) never did (the CLI-help trial); the help lists every part."""
    from spikegs.cli import build_parser

    with pytest.raises(SystemExit) as exit_info:
        build_parser().parse_args(["bench"])
    err = capsys.readouterr().err
    assert exit_info.value.code == 2 and err.rstrip().endswith("arguments are required: part")
    assert " part\n" in err.split("spikegs bench: error")[0]  # the usage's last word
    with pytest.raises(SystemExit):
        build_parser().parse_args(["bench", "--help"])
    said = " ".join(capsys.readouterr().out.split())
    assert "rasterizer, spikes, sim, train, stiff, poses, or all" in said


@pytest.mark.parametrize("text", ["0", "-0.0001", "nan", "inf", "x"])
def test_bench_grad_threshold_is_checked_while_parsing(text, capsys):
    from spikegs.cli import build_parser

    with pytest.raises(SystemExit) as exit_info:
        build_parser().parse_args(["bench", "train", "--grad-threshold", text])
    assert exit_info.value.code == 2
    assert f"expected a finite number > 0, found '{text}'" in capsys.readouterr().err


def test_train_grad_threshold_reaches_every_run(tmp_path, capsys):
    """`spikegs bench train --grad-threshold X` trains every method at X (a SIM method and a
    baseline here), records it and says so in its table's heading."""
    from spikegs.cli import main
    from spikegs.config import load_config

    argv = ["bench", "train", "--quick", "--methods", "spikegs,tfp33", "--grad-threshold", "5e-4"]
    assert main([*argv, "--out", str(tmp_path)]) == 0
    assert "100 iterations, densify threshold 0.0005, 1 seed" in capsys.readouterr().out
    result = json.loads((tmp_path / "train.json").read_text())
    assert result["schedule"]["densify"]["grad_threshold"] == 0.0005
    methods = result["scenes"][train.HEADLINE_SCENE]["methods"]
    assert {m: r["uses_sim"] for m, r in methods.items()} == {"spikegs": True, "tfp33": False}
    for scores in methods.values():
        # both SSIMs at the end (3DGS's, the papers', beside scikit-image's), the curve one
        assert 0 < scores["ssim_3dgs"] <= 1 and scores["ssim_3dgs"] != scores["ssim"]
        assert [("ssim_3dgs" in p) for p in scores["curve"]][-2:] == [False, True]
        assert len(scores["curve"]) == result["points_per_run"] == 8
    assert result["quick"] is True
    for method in ("spikegs", "tfp33"):
        run = tmp_path / "runs" / train.HEADLINE_SCENE / method
        saved = load_config(run / "config.yaml", saved_run=True)
        assert saved.densify.grad_threshold == 0.0005


def test_train_draws_the_headline_only_with_spikegs_or_a_baseline(tmp_path, capsys):
    """`--methods oracle` drew an empty headline.png, with matplotlib's 'No artists with labels'
    warning; a baseline alone draws it."""
    from spikegs.cli import main

    for methods, drawn in (("oracle", False), ("tfp33", True)):
        out = tmp_path / methods
        argv = ["bench", "train", "--quick", "--scenes", "solids", "--methods", methods]
        assert main([*argv, "--out", str(out)]) == 0
        assert (out / "headline.png").exists() == drawn
        assert "legend" not in capsys.readouterr().err
    # a re-run into that folder with other scenes or no headline method left the earlier run's
    # figures beside a train.json they no longer describe (the bench trial)
    out = tmp_path / "tfp33"
    (out / "train_wires.png").write_bytes((out / "train_solids.png").read_bytes())
    argv = ["bench", "train", "--quick", "--scenes", "solids", "--methods", "oracle"]
    assert main([*argv, "--out", str(out)]) == 0
    assert not (out / "headline.png").exists() and not (out / "train_wires.png").exists()
    assert (out / "train_solids.png").exists()
    said = "removed an earlier run's train_wires.png, headline.png, of scenes or methods not run"
    assert said in capsys.readouterr().out


def test_train_refuses_a_users_files_in_its_run_folders_before_any_work(tmp_path, monkeypatch):
    """bench train deleted OUT/runs/SCENE/METHOD with the user's notes in it."""
    mine = tmp_path / "runs" / "solids" / "tfp33" / "notes.txt"
    mine.parent.mkdir(parents=True)
    mine.write_text("mine")
    monkeypatch.setattr(train, "dataset_for", lambda *a: pytest.fail("worked"))
    with pytest.raises(FileExistsError, match="notes.txt"):
        train.run(True, tmp_path, scenes=["solids"], methods=["tfp33"])
    assert mine.read_text() == "mine"


def test_a_data_folder_holding_its_lock_alone_is_simulated_into_as_an_empty_one(
    tmp_path, monkeypatch, capsys
):
    """A bench stopped as it began simulating leaves OUT/data/SCENE holding its .lock alone: the
    next one said of it "not this benchmark's dataset (other settings, or incomplete);
    replaced"."""
    root = tmp_path / "solids"
    root.mkdir()
    (root / ".lock").touch()
    monkeypatch.setattr(train, "simulate_dataset", lambda *args, **kwargs: "simulated")
    assert train.dataset_for("solids", root, {})[0] == "simulated"
    assert capsys.readouterr().out == ""
    (root / "meta.json").write_text("{}")  # an incomplete dataset is said to be replaced
    train.dataset_for("solids", root, {})
    assert "solids: a dataset simulated at other settings" in capsys.readouterr().out


def test_bench_all_refuses_a_users_files_in_its_data_folders_before_any_part(tmp_path, capsys):
    """OUT/data/SCENE holding a user's file was found by bench train, after the rasterizer,
    spikes and SIM parts had run (~70 s); stiff and poses then never ran."""
    from spikegs.cli import main

    mine = tmp_path / "data" / "solids" / "notes.txt"
    mine.parent.mkdir(parents=True)
    mine.write_text("mine")
    assert main(["bench", "all", "--quick", "--out", str(tmp_path)]) == 2
    printed = capsys.readouterr()
    assert "notes.txt" in printed.err and "== rasterizer" not in printed.out
    assert mine.read_text() == "mine"


@pytest.mark.parametrize("part", ["stiff", "all"])
def test_a_users_file_or_a_folder_at_a_parts_results_is_refused_before_any_part(
    tmp_path, capsys, part
):
    """A user's poses.json (or any PART.json) in --out was replaced by the bench's unsaid; a
    folder in its place ended the part once its work was done ("[Errno 21] Is a directory");
    a file named data in OUT ended bench all at its train part, after three others had run."""
    from spikegs.cli import main

    (tmp_path / "poses.json").write_text('{"mine": 1}')
    assert main(["bench", part, "--quick", "--out", str(tmp_path)]) == (0 if part == "stiff" else 2)
    printed = capsys.readouterr()
    if part == "all":
        assert "poses.json: not spikegs bench poses's results, where bench poses writes them" in (
            printed.err
        )
        assert "== " not in printed.out and (tmp_path / "poses.json").read_text() == '{"mine": 1}'
    (tmp_path / "poses.json").unlink()
    (tmp_path / "stiff.json").unlink(missing_ok=True)  # (its own results: replaced)
    (tmp_path / "stiff.json").mkdir()
    assert main(["bench", part, "--quick", "--out", str(tmp_path)]) == 2
    printed = capsys.readouterr()
    assert (
        "stiff.json: a folder, where bench stiff writes them; move it, or give anot" in printed.err
    )
    assert "== " not in printed.out
    (tmp_path / "stiff.json").rmdir()
    if part == "stiff":  # its own results replaced, run after run; another part's, or none, not
        assert main(["bench", "stiff", "--quick", "--out", str(tmp_path)]) == 0
        assert main(["bench", "stiff", "--quick", "--out", str(tmp_path)]) == 0
        for mine in ('{"benchmark": "poses"}', "[1]"):
            (tmp_path / "stiff.json").write_text(mine)
            assert main(["bench", "stiff", "--quick", "--out", str(tmp_path)]) == 2
            assert "stiff.json: not spikegs bench stiff's results" in capsys.readouterr().err
        (tmp_path / "stiff.json").unlink()
    (tmp_path / "data").write_text("mine")
    assert main(["bench", "all", "--quick", "--out", str(tmp_path)]) == 2
    printed = capsys.readouterr()
    assert "data is a file, where the benchmark writes its data" in printed.err
    assert "== " not in printed.out


def test_train_equal_time_gives_each_baseline_spikegs_seconds(tmp_path, monkeypatch, capsys):
    """The margins are at equal iterations, where SpikeGS renders K poses a step and trains SIM
    first (a helper's audit: ~6 times a baseline's seconds in the demo); `--equal-time` trains
    each baseline again with its schedule stretched to SpikeGS's seconds, SIM's included."""
    from spikegs.cli import main

    trained = []

    def fake_train(dataset, config, run_dir):  # seconds: spikegs 0.5 a step + SIM 30, tfp 0.1
        n, sim = config.train.iterations, config.instant_target() == "sim"
        trained.append((run_dir.name, n, config.densify.stop))
        point = {"iteration": n, "train_seconds": 0.1 * n, "psnr": 20.0, "ssim": 0.5}
        return {
            **_run(30.0 if sim else 25.0 + n / 1000, uses_sim=sim, iterations=n, curve=[point]),
            "train_seconds": (0.5 if sim else 0.1) * n,
            "sim_seconds": 30.0 if sim else 0.0,
        }

    dataset = SimpleNamespace(width=64, height=64, test_views=[0, 1])
    monkeypatch.setattr(train, "dataset_for", lambda *a: (dataset, 0.0))
    monkeypatch.setattr(train, "train_method", fake_train)
    argv = ["bench", "train", "--quick", "--methods", "spikegs,tfp33,only_instant", "--equal-time"]
    assert main([*argv, "--out", str(tmp_path)]) == 0
    # SpikeGS 50 + 30 s = 80 s; tfp33 10 s for 100 iterations: 800 at its pace, stretched
    assert [t[:2] for t in trained] == [
        ("spikegs", 100),
        ("tfp33", 100),
        ("only_instant", 100),
        ("tfp33-equal-time", 800),
    ]
    assert trained[3][2] == 8 * trained[1][2] > 0  # its densification stretched with it
    scene = json.loads((tmp_path / "train.json").read_text())["scenes"][train.HEADLINE_SCENE]
    assert scene["methods"]["tfp33-equal-time"]["train_seconds"] == 80.0
    # the table and plot titled '100 iterations' beside its 800: each says the runs' iterations
    printed = capsys.readouterr().out.splitlines()
    assert any("100 iterations, BASELINE-equal-time as many as SpikeGS's" in p for p in printed)
    header = next(p.split() for p in printed if p.split()[:2] == ["method", "iterations"])
    row = next(p.split() for p in printed if p.split()[:1] == ["tfp33-equal-time"])
    assert row[header.index("iterations")] == "800"
    # SpikeGS's margins at equal iterations and at equal time, printed and written (the table's
    # 'gain over tfp33' of the equal-time run left them to be subtracted by hand)
    margins = scene["spikegs_margin_db"]
    assert margins["tfp33"]["mean"] == pytest.approx(4.9)
    assert margins["tfp33-equal-time"]["mean"] == pytest.approx(4.2)
    assert (
        "SpikeGS's margin over tfp33: +4.90 dB at equal iterations, +4.20 dB at equal time "
        "(tfp33-equal-time: 800 iterations in 80.0 s, SpikeGS 80.0 s with SIM's training)"
    ) in printed
    titles = []
    monkeypatch.setattr(train, "save_curves", lambda path, runs, keys, title: titles.append(title))
    main([*argv, "--out", str(tmp_path / "again")])
    assert "100 iterations per method, BASELINE-equal-time as many" in titles[0]
    with pytest.raises(ValueError, match="expected spikegs and a baseline"):
        train.selection(True, None, ["spikegs", "only_instant"], equal_time=True)
    # a baseline slower than SpikeGS keeps its iterations (the bench's), never fewer
    runs = {"spikegs": _run(30.0, train_seconds=5.0, sim_seconds=1.0), "tfp33": _run(25.0)}
    runs["tfp33"]["train_seconds"] = 12.0
    assert train.equal_time_iterations(runs, "tfp33", 100) == 100
    assert main(["bench", "spikes", "--equal-time"]) == 2
    assert "--equal-time: options of bench train, not of bench spikes" in capsys.readouterr().err


def test_the_timing_figures_name_the_threads_the_core_ran_on(tmp_path, monkeypatch):
    """rasterizer.png and spikes.png said "2 cores" (the CPUs) where OMP_NUM_THREADS=1 ran the
    core on one thread, as their tables said; spikes.png's numpy runs on one; poses.png names
    its method as the other figures do; each figure's titles lie within it (spikes.png's ran past
    its right edge, "numpy on 1" cut off)."""
    import matplotlib.pyplot as plt
    from spikegs.bench import poses

    figures = []
    for part in (rasterizer, spikes, poses):
        monkeypatch.setattr(part, "save_figure", lambda fig, path: figures.append(fig))
    monkeypatch.setattr(_C, "max_threads", lambda: 1)
    row = {"size": "16x16", "C": 1, "N": 10, "fwd_ms": 1.0, "fwd_bwd_ms": 2.0}
    rasterizer._plot([row], 3, tmp_path / "r.png")
    spikes._plot([{"w": 33, "GB/s": 2.0, "numpy GB/s": 0.5}], tmp_path / "s.png")
    setup = {"size": 64, "method": "tfp33", "iterations": 10, "repeats": 1}
    rows = [{"condition": c, "psnr": 20.0} for c in ("true poses", "noisy poses", "refined")]
    errors = {
        f"{k}_{when}": np.ones(3)
        for k in ("rotation_deg", "centre")
        for when in ("before", "after")
    }
    poses._plot(rows, errors, setup, tmp_path / "p.png")
    raster, tfp, pose = figures
    assert "1 thread)" in raster.texts[0].get_text() and "cores" not in raster.texts[0].get_text()
    assert "spikegs on 1 thread, numpy on 1" in tfp.axes[0].get_title()
    assert "TFP(33)+3DGS (10 iterations)" in pose.texts[0].get_text()
    for fig in figures:
        fig.canvas.draw()
        renderer = fig.canvas.get_renderer()
        for title in [*fig.texts, *(ax.title for ax in fig.axes)]:
            box = title.get_window_extent(renderer)
            assert fig.bbox.x0 <= box.x0 and box.x1 <= fig.bbox.x1, title.get_text()
        plt.close(fig)


def test_rasterizer_figure_tells_every_size_apart_and_hides_no_line(tmp_path, monkeypatch):
    """rasterizer.png drew each size and C in matplotlib's colours (red beside green) with one
    marker, the same in grey, under a legend over the C++ lines' largest N: each size and C has
    a colour and marker of its own, the legend lies off the panels."""
    import matplotlib.pyplot as plt

    figures = []
    monkeypatch.setattr(rasterizer, "save_figure", lambda fig, path: figures.append(fig))
    rows = [
        {"size": size, "C": c, "N": n, "fwd_ms": n / 1e3, "fwd_bwd_ms": n / 4e2}
        for size in ("256x256", "400x250")
        for c in (1, 3)
        for n in (1_000, 100_000)
    ]
    rasterizer._plot(rows, 3, tmp_path / "rasterizer.png")
    (fig,) = figures
    try:
        fig.canvas.draw()
        renderer = fig.canvas.get_renderer()
        styles = {(line.get_color(), line.get_marker()) for line in fig.axes[0].lines}
        assert len({colour for colour, _ in styles}) == len({m for _, m in styles}) == 4
        legend = fig.axes[1].get_legend().get_window_extent(renderer)
        assert not any(legend.overlaps(ax.get_window_extent(renderer)) for ax in fig.axes)
    finally:
        plt.close(fig)


def test_bench_poses_trains_the_true_poses_once_and_measures_the_noise_it_added(
    tmp_path, monkeypatch, capsys
):
    """bench poses' logic in-process (CI's `bench all --quick` runs it whole in a child, its
    figures unchecked): over two noise seeds the true poses train once and each noisy
    condition twice; its training views lie on the perturbed keyframes, so their error before
    refinement is the noise it added, exactly; the rows are the runs' medians and the share
    recovered follows from them."""
    from spikegs.bench import poses

    setup = {"size": 24, "readouts": 330, "iterations": 30, "method": "tfp33", "repeats": 2}
    monkeypatch.setattr(poses, "QUICK", setup)
    errors, measure = [], poses.refined_pose_errors  # each seed's errors of each training view

    def measured(*args):  # the views' errors after refinement set: 7 of 10 better, 3 worse
        error = measure(*args)
        before = error["rotation_deg_before"]
        better = np.arange(len(before)) < round(0.7 * len(before))
        error["rotation_deg_after"] = np.where(better, before / 2, before * 2)
        errors.append(error)
        return error

    monkeypatch.setattr(poses, "refined_pose_errors", measured)
    results = poses.run(True, tmp_path)
    runs, rows = results["runs"], results["rows"]
    assert [len(runs[c]) for c in poses.CONDITIONS] == [1, 2, 2]
    for run, error in zip(runs[poses.CONDITIONS[2]], errors):
        assert run["rotation_deg_after"] == np.median(error["rotation_deg_after"])
        # set, not trained: a share other than 0.5, which its complement is not (training's own
        # was exactly 5 of 10 on one CPU, where this asked for another share of it)
        improved = np.mean(error["rotation_deg_after"] < error["rotation_deg_before"])
        assert run["views_improved"] == improved == pytest.approx(0.7, abs=0.05)
    refined = rows[2]
    assert refined["rotation_deg_before"] == pytest.approx(poses.NOISE_DEG, rel=1e-6)
    assert refined["centre_before"] == pytest.approx(poses.NOISE_TRANSLATION, rel=1e-6)
    assert "rotation_deg_before" not in rows[1]
    for row, condition in zip(rows, poses.CONDITIONS):
        assert row["condition"] == condition
        assert row["psnr"] == np.median([r["psnr"] for r in runs[condition]])
    psnr = [r["psnr"] for r in rows]
    assert results["psnr_recovered_fraction"] == pytest.approx(
        (psnr[2] - psnr[1]) / (psnr[0] - psnr[1])
    )
    assert json.loads((tmp_path / "poses.json").read_text())["rows"] == rows
    assert (tmp_path / "poses.png").stat().st_size > 0
    assert "median of 2 noise seeds" in capsys.readouterr().out


def test_bench_sim_scores_each_method_once_and_times_variants_of_one_network(tmp_path, capsys):
    """bench sim's logic in-process (CI's `bench all --quick` runs it whole in a child, its
    figures unchecked): one row per method and scene, SIM's in both precisions and the others
    once; each timed variant computes the float32 network's output (the straightforward one, its
    padded border aside, their baseline) and each training step its gradients; the gain is
    SIM's over TFP(33)."""
    results = sim.run(True, tmp_path)
    methods = [r["method"] for r in results["quality"]]
    assert sorted(methods) == sorted({*methods}) and {"SIM float32", "SIM bfloat16"} < {*methods}
    assert {"TFP(33)", "TFP(65)"} < {*methods}
    psnr = {r["method"]: r["psnr"] for r in results["quality"]}
    [(scene, gain)] = results["psnr_gain_over_tfp33_db"].items()
    assert gain == psnr["SIM bfloat16"] - psnr["TFP(33)"] and scene == list(SCENES)[0]
    inference = results["inference"]
    assert (inference["height"], inference["width"]) == (64, 96)
    fps = inference["rows"]
    assert fps[0]["speedup"] == 1  # its error: where its square's zero padding leaks in
    assert all(r["max_abs_err"] < (1e-2 if "bfloat16" in r["variant"] else 1e-6) for r in fps[1:])
    steps = results["train_step"]
    assert steps[0]["speedup"] == 1 and all(r["grad_err"] < 1e-4 for r in steps)
    assert {(r["batch"], r["crop"]) for r in steps} == {(8, 32)}
    assert [(t["height"], t["width"], t["steps"]) for t in results["training"]] == [(64, 96, 30)]
    assert "these scores check the run only" in capsys.readouterr().out
    assert json.loads((tmp_path / "sim.json").read_text())["train_step"] == steps


@pytest.mark.timeout(30)
def test_bench_train_refuses_a_users_files_in_the_run_folders_it_would_delete(tmp_path):
    """A user's file in a run folder that the benchmark replaces is refused before any work, for
    each seed it runs and not for another; --seeds 2**63 - 1 checked each of its names, for ever
    (it hung before any output)."""
    runs = tmp_path / "runs" / "solids"
    for name in ("tfp33-seed1", "tfp33-seed01", "tfp65"):
        (runs / name).mkdir(parents=True)
        (runs / name / "notes.txt").write_text("the user's")
    train.check_outputs(tmp_path, ["solids"], ["tfp33"], 1)  # seed 1 is not run
    for seeds in (2, 2**63 - 1):
        with pytest.raises(FileExistsError, match=r"tfp33-seed1 holds files that are not a run's"):
            train.check_outputs(tmp_path, ["solids"], ["tfp33"], seeds)
    with pytest.raises(FileExistsError, match=r"solids/tfp65 holds files"):
        train.check_outputs(tmp_path, ["solids"], ["tfp65"], 1)
    (runs / "tfp33-seed1" / "notes.txt").unlink()
    train.check_outputs(tmp_path, ["solids"], ["tfp33"], 2**63 - 1)  # nothing of the user's
    (runs / "x-seed2").mkdir()  # a method of that name: its seed 0's folder
    (runs / "x-seed2" / "notes.txt").write_text("the user's")
    with pytest.raises(FileExistsError, match=r"solids/x-seed2 holds files"):
        train.check_outputs(tmp_path, ["solids"], ["x-seed2"], 1)
    # a file in a run's place: refused once the scene was simulated; a user's file in a scene's
    # data folder, with the remedy of a folder the user never named (the bench trial)
    (runs / "tfp50").write_text("the user's")
    with pytest.raises(FileExistsError, match=r"solids/tfp50 is a file, where the benchmark wr"):
        train.check_outputs(tmp_path, ["solids"], ["tfp50"], 1)
    (tmp_path / "data" / "wires").mkdir(parents=True)
    (tmp_path / "data" / "wires" / "mine.txt").write_text("the user's")
    with pytest.raises(
        FileExistsError,
        match=r"\(mine.txt\); the benchmark simulates its scene there: give another --out$",
    ):
        train.check_outputs(tmp_path, ["wires"], ["tfp33"], 1)
    # a file where the scene's runs folder goes, or OUT/runs: "[Errno 20] Not a directory" once
    # the scene was simulated
    shutil.rmtree(tmp_path / "data" / "wires")
    (tmp_path / "runs" / "wires").write_text("the user's")
    with pytest.raises(FileExistsError, match=r"runs/wires is a file, where the benchmark writes"):
        train.check_outputs(tmp_path, ["wires"], ["tfp33"], 1)
    shutil.rmtree(tmp_path / "runs")
    (tmp_path / "runs").write_text("the user's")
    with pytest.raises(
        FileExistsError, match=r"/runs is a file, where the benchmark writes its runs; give anoth"
    ):
        train.check_outputs(tmp_path, ["wires"], ["tfp33"], 1)
    # a file named data in OUT: its scene's folder neither existed nor was a folder, and the
    # check passed; the bench failed with "[Errno 20] Not a directory" after the parts before
    (tmp_path / "runs").unlink()
    shutil.rmtree(tmp_path / "data")
    (tmp_path / "data").write_text("the user's")
    with pytest.raises(FileExistsError, match=r"/data is a file, where the benchmark writes its d"):
        train.check_outputs(tmp_path, ["wires"], ["tfp33"], 1)
