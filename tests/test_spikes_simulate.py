"""simulate_spikes: firing statistics, calibration, determinism, streaming and bad input."""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest
import torch
from spikegs import _C, SimParams, SpikeStream, simulate_spikes
from spikegs.spikes import simulate
from spikegs.spikes.simulate import (
    fpn_gain,
    sample_times,
    simulate_channels,
    warn_unread_frames,
)


def rates(packed: np.ndarray, width: int) -> np.ndarray:
    """Mean spikes per readout per pixel: [H, W]."""
    return SpikeStream.from_packed(packed, packed.shape[1], width).tfp(
        len(packed) // 2, len(packed)
    )


def linear_fit(params: SimParams) -> tuple[float, float, float]:
    """Slope, intercept and max deviation from the line of the mean rate at 40 levels in [0, 1]
    (one per row, 64 pixels each) over 4000 readouts."""
    levels = np.linspace(0.0, 1.0, 40, dtype=np.float32)
    frames = np.repeat(levels[None, :, None], 64, axis=2)  # [1, 40, 64]
    rate = rates(simulate_spikes(frames, 4000, seed=1, params=params), 64).mean(1)  # [40]
    slope, intercept = np.polyfit(levels, rate, 1)
    return slope, intercept, np.abs(rate - (slope * levels + intercept)).max()


def test_rate_is_linear_in_intensity():
    # Shot, temporal-threshold and dark noise on; no fixed pattern: within 0.3% of full scale
    # (measured 0.06-0.11%: the resolution of 64 pixels x 4000 readouts).
    params = SimParams(fpn_sigma=0.0)
    slope, intercept, deviation = linear_fit(params)
    assert slope == pytest.approx(params.rate_at_one, rel=0.005)
    assert intercept == pytest.approx(params.dark_rate, abs=1e-4)
    assert deviation < 0.003 * params.rate_at_one
    # Default 3% threshold mismatch: each pixel's gain is θ/θ_i, so a level's mean over 64 pixels
    # scatters by ~0.4%; the long-run slope is rate_at_one · E[θ/θ_i] ≈ rate_at_one · (1 + 0.03²).
    params = SimParams()
    slope, intercept, deviation = linear_fit(params)
    assert slope == pytest.approx(params.rate_at_one, rel=0.01)
    assert deviation < 0.015 * params.rate_at_one


@pytest.mark.parametrize("threshold", [10.0, 100.0])
def test_shot_noise_scales_with_the_threshold(threshold):
    """Integrate-and-fire on Poisson photo-electrons: intervals Gamma(θ), so a long window's
    spike count has variance / mean = 1/θ (the Fano factor of the renewal process); a threshold
    ignored (always the default 100) failed only the range checks. Measured 0.1005 and 0.0104
    (+4 %: a count is an integer, its phase in the window adds ~1/6 to the variance)."""
    params = SimParams(threshold=threshold, fpn_sigma=0.0, dark_rate=0.0, temporal_sigma=0.0)
    packed = simulate_spikes(np.ones((1, 64, 64), np.float32), 3000, seed=2, params=params)
    counts = SpikeStream.from_packed(packed, 64, 64).tfp(2000, 2000) * 2000  # [64, 64]
    assert counts.mean() == pytest.approx(2000 * params.rate_at_one, rel=0.01)
    assert counts.var() / counts.mean() == pytest.approx(1 / threshold, rel=0.1)


def test_calibration_knob():
    frames = np.ones((1, 8, 64), np.float32)
    params = SimParams(rate_at_one=0.1, dark_rate=0.0)
    assert rates(simulate_spikes(frames, 3000, params=params), 64).mean() == pytest.approx(
        0.1, rel=0.01
    )


def test_dark_pixels_fire_at_dark_rate():
    dark = np.zeros((1, 64, 64), np.float32)
    uniform = SimParams(dark_rate=0.01, dark_sigma=0.0, fpn_sigma=0.0)
    r = rates(simulate_spikes(dark, 8000, params=uniform), 64)
    assert r.mean() == pytest.approx(0.01, rel=0.02)
    assert np.abs(r - 0.01).max() < 0.004  # every pixel, not just the mean
    spread = rates(simulate_spikes(dark, 8000, params=SimParams(dark_rate=0.01)), 64)
    assert spread.mean() == pytest.approx(0.01, rel=0.03)  # log-normal spread keeps the mean
    assert spread.std() > 2 * r.std()


def test_threshold_noise_never_fires_without_charge():
    """The per-readout threshold θ_i·(1 + temporal_sigma·z) is floored at 0.1·θ_i, like the
    per-pixel one: at temporal_sigma 0.5 it went below 0 and dark pixels without dark current
    fired (1130 spikes in 4000 readouts of 32²)."""
    for sigma in (0.5, 3.0):
        p = SimParams(temporal_sigma=sigma, dark_rate=0.0, shot_noise=False, random_init=False)
        assert not simulate_spikes(np.zeros((1, 32, 32), np.float32), 4000, params=p).any()


def test_an_overexposed_pixel_banks_no_charge():
    """v = min(v - θ_i, θ_i): light 10 spikes' worth a readout for 100 readouts, then dark, fires
    at most once more. Uncapped, the banked charge fired every one of the 300 dark readouts (an
    after-image of every bright flash); constant light cannot tell the two apart."""
    frames = np.zeros((4, 8, 16), np.float32)
    frames[:2] = 40.0  # 40 x rate_at_one 0.25 = 10 spikes a readout, readouts [0, 100)
    times = np.array([0.0, 99.0, 100.0, 399.0])
    packed = simulate_spikes(frames, 400, frame_times=times, params=SimParams(dark_rate=0.0))
    s = SpikeStream.from_packed(packed, 8, 16)
    assert (s.counts(50, 100) == 100).all()  # saturated: a spike every readout of [0, 100)
    assert s.counts(250, 300).max() <= 1  # readouts [100, 400): no light, no dark current


def test_fixed_pattern_noise_spreads_and_is_floored_and_independent_of_the_dark_current():
    """θ_i = θ·max(1 + fpn_sigma·z, 0.1) sets a pixel's rate to rate·θ/θ_i, so with no other noise
    the rates' relative spread is ~fpn_sigma (0.105 at 0.1; fpn_sigma was once unused, unseen);
    at fpn_sigma 3 the floor caps a pixel at 10x its rate (0.25 at light 0.1; 1.0 without it);
    and the dark current's draw is not the threshold's (correlation 0.93 when it was)."""
    quiet = dict(dark_rate=0.0, temporal_sigma=0.0, shot_noise=False)
    light = np.ones((1, 32, 32), np.float32)
    for sigma, lo, hi in ((0.1, 0.08, 0.12), (0.0, 0.0, 0.01)):
        r = rates(simulate_spikes(light, 3000, params=SimParams(fpn_sigma=sigma, **quiet)), 32)
        assert lo <= r.std() / r.mean() <= hi, sigma
    with pytest.warns(UserWarning, match="fpn_sigma 3: .* fire 4.32 times"):  # (said)
        floored = SimParams(fpn_sigma=3.0, **quiet)
    assert rates(simulate_spikes(0.1 * light, 2000, params=floored), 32).max() <= 0.26
    # the same seed's thresholds: a lit run gives θ/θ_i, a dark one dark_i·θ/θ_i
    mismatch = dict(quiet, fpn_sigma=0.2)
    lit = rates(simulate_spikes(light, 2000, seed=5, params=SimParams(**mismatch)), 32)
    dark = dict(mismatch, dark_rate=0.05)
    unlit = rates(simulate_spikes(0 * light, 4000, seed=5, params=SimParams(**dark)), 32)
    assert abs(np.corrcoef(1 / lit.ravel(), (unlit / lit).ravel())[0, 1]) < 0.15


def test_a_threshold_past_floats_range_is_never_reached():
    """A fixed-pattern spread whose threshold overflowed float (θ_i = inf) fired at readout 0 in
    the dark (the initial voltage u·inf reached it), then never again (inf - inf: a NaN voltage):
    146 of 256 dark pixels spiked once (the core trial). Float's largest is never reached."""
    quiet = dict(dark_rate=0.0, temporal_sigma=0.0)
    dark = np.zeros((1, 4, 64), np.float32)
    with pytest.warns(UserWarning, match="fpn_sigma"):  # (its gain is said)
        params = [
            SimParams(fpn_sigma=1e40, **quiet),
            SimParams(threshold=1e30, fpn_sigma=1e9, **quiet),
        ]
    for p in params:
        assert np.unpackbits(simulate_spikes(dark, 200, params=p)).sum() == 0, p
    lit = simulate_spikes(np.ones((1, 4, 64), np.float32), 200, params=params[0])
    assert np.unpackbits(lit).sum() > 0  # (the pixels floored at 0.1 θ still fire)


def test_never_more_than_one_spike_per_readout():
    # 4.0 = one spike per readout; up to float32's largest, whose charge overflows float32
    levels = np.array([2.0, 4.0, 8.0, 1e3, 1e30, 1e38, np.finfo(np.float32).max], np.float32)
    frames = np.repeat(levels[None, :, None], 16, axis=2)  # [1, 7, 16]
    with pytest.warns(UserWarning, match="86% of the light is at or above 1/rate_at_one = 4,"):
        r = rates(simulate_spikes(frames, 2000), 16).mean(1)
    assert r[0] == pytest.approx(0.5, rel=0.02)
    assert (r <= 1).all() and (r[2:] == 1).all()


def test_light_is_interpolated_in_time():
    ramp = np.stack([np.zeros((4, 32)), np.ones((4, 32))]).astype(np.float32)  # 0 -> 1
    packed = simulate_spikes(ramp, 4001, params=SimParams(dark_rate=0.0))
    s = SpikeStream.from_packed(packed, 4, 32)
    # Mean light over readouts [1000, 2000) is 0.375, over [3000, 4000) 0.875.
    assert s.tfp(1500, 1000).mean() == pytest.approx(0.25 * 0.375, rel=0.03)
    assert s.tfp(3500, 1000).mean() == pytest.approx(0.25 * 0.875, rel=0.03)


def test_deterministic_for_a_seed_and_chunking():
    frames = np.random.default_rng(0).random((3, 5, 21), dtype=np.float32)
    a = simulate_spikes(frames, 300, seed=7)
    np.testing.assert_array_equal(a, simulate_spikes(frames, 300, seed=7, chunk=13))
    assert (a != simulate_spikes(frames, 300, seed=8)).any()


def test_a_chunk_ending_on_a_frame_time_reads_that_frame():
    """A chunk's last readout at a frame's time (every chunk, with a frame each readout) read the
    light as frames[f-1] + 1 · (frames[f] - frames[f-1]), which rounds (1 + (0.1 - 1) is not 0.1
    in float), where one chunk across it reads frames[f] itself: the spikes differed with the
    chunk size. Here a bright readout 0 leaves v = 97.5 photo-electrons, readout 1 (light s, the
    end of a 2-readout chunk) fires and keeps 25 s - 2.5, and readout 2's light brings v to the
    threshold of 100 within a rounding: 509 of 4096 pixels fired otherwise there."""
    p = 4096
    s = np.random.default_rng(0).uniform(0.2, 3.9, p).astype(np.float32)
    kept = np.float32(97.5) + np.float32(25) * s - np.float32(100)  # v after readout 1
    frames = np.zeros((4, 1, p), np.float32)  # a frame each readout
    frames[0], frames[1] = 7.9, s
    frames[2] = ((100.0 - kept.astype(np.float64)) / 25.0).astype(np.float32)
    params = SimParams(
        shot_noise=False, temporal_sigma=0.0, fpn_sigma=0.0, dark_rate=0.0, random_init=False
    )
    whole = simulate_spikes(frames, 4, params=params, chunk=4)
    for chunk in (1, 2, 3):
        np.testing.assert_array_equal(simulate_spikes(frames, 4, params=params, chunk=chunk), whole)


def test_callable_source_matches_frames():
    frames = np.random.default_rng(1).random((4, 6, 10), dtype=np.float32)
    times = np.array([0.0, 100.0, 200.0, 299.0])

    def light(t: float) -> np.ndarray:
        i = min(int(np.searchsorted(times, t, side="right")) - 1, 2)
        a = (t - times[i]) / (times[i + 1] - times[i])
        return (1 - a) * frames[i] + a * frames[i + 1]

    want = simulate_spikes(frames, 300, frame_times=times, seed=3)
    np.testing.assert_array_equal(simulate_spikes(light, 300, frame_every=100, seed=3), want)


def test_a_callable_is_sampled_at_the_frame_times_given():
    """A callable with frame_times is sampled there (they were ignored: it was sampled every
    frame_every readouts), each time once."""
    frames = np.random.default_rng(5).random((3, 4, 9), dtype=np.float32)
    times = np.array([0.0, 37.5, 119.0])
    calls = []
    light = lambda t: calls.append(t) or frames[list(times).index(t)]  # noqa: E731
    got = simulate_spikes(light, 120, frame_times=times, seed=6, chunk=16)
    np.testing.assert_array_equal(got, simulate_spikes(frames, 120, frame_times=times, seed=6))
    assert calls == list(times)
    with pytest.raises(ValueError, match="frame_every expected a finite number > 0"):
        simulate_spikes(light, 120, frame_times=times, frame_every=0)  # unread, still checked
    with pytest.raises(ValueError, match="frame at t=1234567 expected finite"):  # not 1.23457e+06
        nan_later = lambda t: frames[0] * (np.nan if t else 1)  # noqa: E731
        simulate_spikes(nan_later, 1234568, frame_times=[0.0, 1234567.0], chunk=10**6)
    with pytest.raises(ValueError, match=r"frame_times expected \[F\] with F >= 1, found \[0\]"):
        simulate_spikes(light, 120, frame_times=[])
    with pytest.raises(ValueError, match=r'^frame_times: expected numbers, found "ab"'):
        simulate_spikes(light, 120, frame_times="ab")  # (it named no argument)
    with pytest.raises(ValueError, match=r"covering readouts \[0, 119\]"):
        simulate_spikes(light, 120, frame_times=[0.0, 100.0])


def test_frames_between_readouts_are_said_unread():
    """Frames packed more densely than readouts (ten a readout, evenly over the stream) were
    simulated from the two around each readout alone, unsaid: the light between, here all of
    it, fired nothing. Frames a readout or more apart are read, each."""
    frames = np.full((100, 4, 8), 2.0, np.float32)
    frames[::11] = 0.0  # the frames at readouts 0 to 9, the only ones read
    with pytest.warns(UserWarning, match=r"^90 of 100 light frames lie between two readouts and "):
        dark = np.unpackbits(simulate_spikes(frames, 10)).mean()  # ~0.45 where read
    assert dark < 0.02  # (a first readout's spike of the random initial charge)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        simulate_spikes(frames[:10], 10)  # a frame a readout
        simulate_spikes(frames[:3], 10, frame_times=[0.0, 4.5, 9.0])
    # 20 frames over 7 readouts: 8 are neither the frame at or before a readout nor the next
    # (none where the readout falls on a frame); 13 half a readout apart leave 6; 10 none
    for count, unread in ((20, 8), (13, 6)):
        said = f"{unread} of {count} light frames lie between two .*each of the 7 readouts"
        with pytest.warns(UserWarning, match=said):
            warn_unread_frames(np.linspace(0, 6, count), 7)
    # frames before the first readout or past the last (frame times cover the readouts): those
    # no readout reads are counted (readouts that do not exist were counted as reading them)
    for times, readouts, unread in (([-2.5, -1.5, 0.5, 3.0], 4, 1), ([0.0, 0.5, 1e9], 1, 2)):
        with pytest.warns(UserWarning, match=f"^{unread} of {len(times)} light frames lie"):
            warn_unread_frames(np.array(times), readouts)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        warn_unread_frames(np.linspace(0, 6, 10), 7)


def test_a_chunk_holds_its_frames_light_up_to_a_cap(tmp_path, monkeypatch, alive_arrays):
    """Large frames shorten a chunk so that the frames it holds stay under CHUNK_LIGHT_BYTES: a
    256-readout chunk held 129 frames of light rendered every 2 readouts, 1.1 GB at 1080x1920
    (simulate's peak RSS 2575 MB there, 987 with the cap). Colour frames of 6x11 (792 bytes in
    float32) and a cap of four: at most 4 rendered frames alive (101 before), each rendered once,
    and the spikes those of uncapped chunks."""
    rng = np.random.default_rng(5)
    frames = {t: rng.random((6, 11, 3), dtype=np.float32) for t in sample_times(200, 2.0)}
    calls = []

    def light(t: float) -> np.ndarray:  # [H, W, C] float32: held as it is returned
        calls.append(t)
        return alive_arrays.track(frames[t].copy())

    def spikes(name: str) -> list[np.ndarray]:
        outs = [tmp_path / f"{name}{c}.dat" for c in range(3)]
        simulate_channels(light, 200, outs, [1, 2, 3], frame_every=2.0, flip=False)
        return [SpikeStream.open(out, 6, 11, flip=False).packed() for out in outs]

    monkeypatch.setattr(simulate, "CHUNK_LIGHT_BYTES", 4 * 6 * 11 * 3 * 4, raising=False)
    capped = spikes("capped")
    assert alive_arrays.most <= 4, alive_arrays.most
    assert calls == sorted(frames)  # each once, in order
    monkeypatch.setattr(simulate, "CHUNK_LIGHT_BYTES", 1 << 30, raising=False)
    for got, want in zip(capped, spikes("whole")):
        np.testing.assert_array_equal(got, want)
    # uncapped, one chunk held every frame: the count counts
    assert alive_arrays.most >= len(frames)


def test_channels_are_each_simulated_as_alone(tmp_path):
    """simulate_channels writes each channel's .dat as simulate_spikes writes that channel alone
    with its seed, rendering each frame once, whatever the chunk; an error part way through
    leaves no file."""
    frames = np.random.default_rng(3).random((5, 6, 11, 3), dtype=np.float32)  # [F, H, W, C]
    times = np.array([0.0, 40.0, 90.0, 150.0, 199.0])
    seeds, outs = [4, 9, 2**64 - 1], [tmp_path / f"c{c}.dat" for c in range(3)]
    calls = []
    light = lambda t: calls.append(t) or frames[list(times).index(t)]  # noqa: E731
    simulate_channels(light, 200, outs, seeds, frame_times=times, flip=False, chunk=7)
    assert calls == list(times)
    for c in range(3):
        want = simulate_spikes(frames[..., c], 200, frame_times=times, seed=seeds[c])
        np.testing.assert_array_equal(SpikeStream.open(outs[c], 6, 11, flip=False).packed(), want)
    simulate_channels(frames, 200, outs, seeds, frame_times=times, flip=False)  # an array too
    np.testing.assert_array_equal(SpikeStream.open(outs[2], 6, 11, flip=False).packed(), want)

    fails = lambda t: frames[0] * (np.nan if t > 100 else 1)  # noqa: E731
    new = [tmp_path / f"new{c}.dat" for c in range(3)]
    with pytest.raises(ValueError, match="frame at t=150 expected finite intensities"):
        simulate_channels(fails, 200, new, seeds, frame_times=times)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(p.name for p in outs)
    # (the frames were blamed where the outputs and seeds fell short of their channels)
    with pytest.raises(ValueError, match=r"frames of 2 channels \(\[6, 11, 2\] each\) for 3 out"):
        simulate_channels(frames[..., :2], 200, outs, seeds, frame_times=times)
    with pytest.raises(ValueError, match="of 3 channels .* for 1 outputs: expected an output"):
        simulate_channels(frames, 200, outs[:1], seeds[:1], frame_times=times)
    with pytest.raises(ValueError, match="1 or more outputs, found 3 outputs and 2 seeds"):
        simulate_channels(frames, 200, outs, seeds[:2], frame_times=times)
    with pytest.raises(ValueError, match="found 0 outputs and 0 seeds"):
        simulate_channels(frames, 200, [], [], frame_times=times)
    with pytest.raises(ValueError, match="outs: expected a file for each channel"):
        simulate_channels(frames, 200, [outs[0], outs[1], outs[0]], seeds, frame_times=times)


def test_frame_every_that_rounds_onto_the_last_readout():
    """np.arange(0, 21, 0.7) ends at 21.0 by rounding: the last readout was listed twice and
    refused as not strictly increasing."""
    light = lambda t: np.full((4, 4), 0.5, np.float32)  # noqa: E731
    assert simulate_spikes(light, 22, frame_every=0.7).shape[0] == 22
    for bad in (0, -1.0, float("nan"), float("inf")):  # NaN reached numpy's arange
        with pytest.raises(ValueError, match="frame_every expected a finite number > 0"):
            simulate_spikes(light, 22, frame_every=bad)
    # sampled far more often than once a readout, only the frames around each readout are read
    # (a frame every 1e-7 readouts stacked 10**7 frames a chunk)
    calls = []
    ramp = lambda t: calls.append(t) or np.full((4, 4), 0.1 * t, np.float32)  # noqa: E731
    with pytest.warns(UserWarning, match="4999995 of 5000001 light frames lie between two"):
        spikes = simulate_spikes(ramp, 6, frame_every=1e-6, seed=2)
    assert len(calls) <= 2 * 6
    np.testing.assert_array_equal(spikes, simulate_spikes(ramp, 6, frame_every=1, seed=2))
    with pytest.raises(ValueError, match="samples the light .* times, over 1e\\+08"):
        simulate_spikes(ramp, 300, frame_every=1e-7)  # 3e9 times: 24 GB before any frame
    for n in range(1, 400):
        for every in (0.3, 0.7, 1.1, 2.9):
            times = sample_times(n, every)
            assert times[0] == 0 and times[-1] == n - 1
            assert (np.diff(times) > 0).all() and (np.diff(times) <= every + 1e-9).all()


def test_light_beyond_float32_is_saturated_light():
    """Finite float64 light above float32's largest value fires every readout, as float32's
    largest does (it became inf and was refused as not finite, naming the frames' minimum)."""
    light = np.zeros((2, 4, 4))
    light[1] = 1e39
    saturated = light.clip(max=np.finfo(np.float32).max).astype(np.float32)
    np.testing.assert_array_equal(simulate_spikes(light, 20), simulate_spikes(saturated, 20))


def test_torch_tensors_are_light_too():
    frames = torch.full((1, 4, 8), 0.5, requires_grad=True)
    expected = simulate_spikes(frames.detach().numpy(), 50)
    np.testing.assert_array_equal(simulate_spikes(frames, 50), expected)
    np.testing.assert_array_equal(simulate_spikes(lambda t: frames[0], 50), expected)
    # half-precision light is exact in float32: bfloat16 (no numpy type) raised a TypeError,
    # float16 an overflow warning while capping it at float32's largest value
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for half in (torch.bfloat16, torch.float16):
            light = frames.detach().to(half)
            assert np.array_equal(simulate_spikes(light, 50), expected)
        assert np.array_equal(simulate_spikes(light.numpy(), 50), expected)


def test_streams_to_dat(tmp_path):
    frames = np.random.default_rng(2).random((2, 5, 13), dtype=np.float32)
    want = simulate_spikes(frames, 100, seed=4)
    s = simulate_spikes(frames, 100, seed=4, out=tmp_path / "sim.dat", chunk=30)
    assert isinstance(s, SpikeStream) and (len(s), s.height, s.width) == (100, 5, 13)
    np.testing.assert_array_equal(s.packed(), want)
    np.testing.assert_array_equal(
        SpikeStream.open(tmp_path / "sim.dat", 5, 13, flip=False).window(50, 100),
        s.window(50, 100)[:, ::-1],
    )


def test_bad_input_refused():
    frames = np.ones((2, 4, 4), np.float32)
    with pytest.raises(ValueError, match="finite intensities >= 0"):
        simulate_spikes(-frames, 10)
    with pytest.raises(ValueError, match=r"covering readouts \[0, 9\]"):
        simulate_spikes(frames, 10, frame_times=[0.0, 5.0])
    with pytest.raises(ValueError, match=r"frame_times expected \[2\]"):
        simulate_spikes(frames, 10, frame_times=[0.0, 5.0, 9.0])
    with pytest.raises(ValueError, match=r"expected shape \[4, 4\]"):
        simulate_spikes(lambda t: np.ones((4, 4 + int(t > 0))), 10, frame_every=5)
    with pytest.raises(ValueError, match="rate_at_one"):
        simulate_spikes(frames, 10, params=SimParams(rate_at_one=2.0))
    with pytest.raises(ValueError, match="params expected a SimParams or None, found dict"):
        simulate_spikes(frames, 10, params={"rate_at_one": 0.2})  # was an AttributeError
    for n in (0, True, 10.0, float("nan")):
        with pytest.raises(ValueError, match="num_readouts"):
            simulate_spikes(frames, n)
    with pytest.raises(ValueError, match="2 frames spread over 1 readout"):
        simulate_spikes(frames, 1)  # was: frame times not increasing, found [0.0, 0.0]
    with pytest.raises(ValueError, match="expected numbers"):
        simulate_spikes(frames, 10, frame_times=["0", "9"])
    with pytest.raises(ValueError, match="expected real intensities"):
        simulate_spikes(frames.astype(np.complex64), 10)
    for codes in (np.uint8, np.uint16):  # an image file's 255 fired every readout, unsaid
        with pytest.raises(ValueError, match=f"found {np.dtype(codes).name} codes: convert"):
            simulate_spikes((frames * 255).astype(codes), 10)
        with pytest.raises(ValueError, match="frame at t=0 expected intensities"):
            simulate_spikes(lambda t, c=codes: (frames[0] * 255).astype(c), 10)
    for shape in ((4, 4), (0, 4, 4)):  # one frame without its axis; no frame
        with pytest.raises(ValueError, match=r"frames expected \[F, H, W\] with F >= 1, found"):
            simulate_spikes(np.ones(shape, np.float32), 10)
    with pytest.raises(ValueError, match="height and width expected >= 1, found 4x0"):
        simulate_spikes(frames[:, :, :0], 10)  # (numpy's reshape error in the NaN check, before)
    simulate_spikes(frames > 0.5, 10)  # bool and signed integers: intensities at face value
    simulate_spikes(np.ones((1, 4, 5), np.int64), 10)
    with pytest.raises(ValueError, match=r"found nan at \[1, 2, 3\]"):
        nan = frames.copy()
        nan[1, 2, 3] = np.nan
        simulate_spikes(nan, 10)
    with pytest.raises(ValueError, match=r"found -1.0 at \[1, 3, 2\]"):  # checked in parts
        negative = frames.copy()
        negative[1, 3, 2] = -1
        with pytest.MonkeyPatch.context() as patch:
            patch.setattr("spikegs.spikes.simulate._CHECKED_VALUES", 7)  # a row at a time
            simulate_spikes(negative, 10)
    for seed in (1.5, -1, 2**64):  # 1.5 was read as 1, -1 and 2**64 wrapped to 2**64 - 1 and 0
        with pytest.raises(ValueError, match="seed"):
            simulate_spikes(frames, 10, seed=seed)
    for chunk in (0, -1, 2.5):
        with pytest.raises(ValueError, match="chunk"):
            simulate_spikes(frames, 10, chunk=chunk)


def test_the_core_simulator_refuses_light_that_is_not_finite_or_negative():
    """A direct caller of the core's simulator (simulate_spikes checks first) passed NaN light: the
    pixel's voltage became NaN and it never fired again, in that run or any later one; so did
    light over FLT_MAX / (θ · rate_at_one), 1.4e37 at the defaults, whose charge overflowed: the
    core takes up to saturated_light, which simulate_spikes caps at."""
    params = SimParams().to_core()
    sim = _C.SpikeSimulator(2, 3, params, 0)
    most = np.float32(params.saturated_light)
    assert most == 1e6 / params.rate_at_one
    for bad in (np.nan, np.inf, -1.0, np.nextafter(most, np.inf), np.finfo(np.float32).max):
        frames = np.ones((2, 2, 3), np.float32)
        frames[1, 1, 1] = bad
        with pytest.raises(
            ValueError, match=r"intensities in \[0, 4e\+06\] .*, found .* at frame 1, pixel 4"
        ):
            sim.run(frames, np.array([0.0, 9.0]), 10)
    lit = _C.SpikeSimulator(2, 3, params, 0).run(np.full((2, 2, 3), most), np.array([0.0, 9.0]), 10)
    assert (lit == 0b111).all()  # the most fires every readout
    assert sim.run(np.ones((2, 2, 3), np.float32), np.array([0.0, 9.0]), 10).shape == (10, 2, 1)


def test_the_core_simulator_refuses_frames_and_times_of_other_shapes():
    """A direct caller of the core's simulator (simulate_spikes checks first): frames not
    [F, H, W] of its H and W, or times not [F], are refused and named (the core reads F·H·W
    intensities and F times), and so is a negative count of readouts."""
    sim = _C.SpikeSimulator(2, 3, SimParams().to_core(), 0)
    times = np.array([0.0, 9.0])
    for frames in (np.ones((2, 1, 3), np.float32), np.ones((2, 2, 4)), np.ones((2, 6))):
        shape = ", ".join(map(str, frames.shape))
        with pytest.raises(ValueError, match=rf"frames expected \[F, 2, 3\], found \[{shape}\]"):
            sim.run(frames, times, 10)
    frames = np.ones((2, 2, 3), np.float32)
    for bad_times in (np.array([0.0, 4.0, 9.0]), times[:, None]):
        shape = ", ".join(map(str, bad_times.shape))
        with pytest.raises(ValueError, match=rf"times expected \[2\], found \[{shape}\]"):
            sim.run(frames, bad_times, 10)
    with pytest.raises(ValueError, match="readouts expected >= 0, found -1"):
        sim.run(frames, times, -1)
    assert sim.run(frames, times, 10).shape == (10, 2, 1)


def test_sim_params_of_the_wrong_type_are_named():
    for fields, message in (
        ({"threshold": "100"}, "threshold: expected a number, found '100'"),
        ({"dark_rate": None}, "dark_rate: expected a number, found None"),
        ({"rate_at_one": True}, "rate_at_one: expected a number, found True"),
        ({"shot_noise": "yes"}, "shot_noise: expected True or False, found 'yes'"),
    ):
        with pytest.raises(ValueError, match=message):
            SimParams(**fields)
    with pytest.raises(ValueError, match="rate_at_one expected in"):  # ranges at construction
        SimParams(rate_at_one=0.0)
    for name in ("threshold", "dark_sigma", "fpn_sigma", "temporal_sigma"):  # not inf either
        with pytest.raises(ValueError, match=f"{name} expected (finite|in)"):
            SimParams(**{name: float("inf")})
    params = SimParams(threshold=np.int64(50), shot_noise=np.bool_(False))  # numpy scalars: fine
    assert (params.threshold, params.shot_noise) == (50.0, False)
    assert type(params.threshold) is float and type(params.shot_noise) is bool
    # a field set afterwards skipped every check ("0.5" reached the core as a string): frozen,
    # and another value checked through dataclasses.replace
    with pytest.raises(dataclasses.FrozenInstanceError):
        params.rate_at_one = "0.5"
    with pytest.raises(ValueError, match="rate_at_one: expected a number, found '0.5'"):
        dataclasses.replace(params, rate_at_one="0.5")
    assert dataclasses.replace(params, rate_at_one=0.5).rate_at_one == 0.5


def test_a_tiny_rate_at_one_saturates_without_overflow():
    """rate_at_one under ~3e-33 overflowed float32 where the light that saturates is capped (a
    RuntimeWarning, an error under np.errstate(all="raise")); the spikes were right."""
    with np.errstate(all="raise"), pytest.warns(UserWarning, match="100% of the light"):
        packed = simulate_spikes(np.full((1, 2, 8), 3e38), 5, params=SimParams(rate_at_one=1e-38))
    assert (packed == 255).all()  # every pixel fires every readout


def test_a_threshold_of_a_few_photo_electrons_warns():
    """Under 2 photo-electrons a spike the normal form of shot noise loses charge (the rate falls
    below rate_at_one·I at I = 1, rises above it in dim light): said, with the errors measured
    at this threshold (the same two figures were quoted whatever the threshold)."""
    with pytest.warns(UserWarning, match=r"under 2 .*measured -1% at I = 1, \+2% at I = 0\.05"):
        SimParams(threshold=1.0)
    with pytest.warns(UserWarning, match=r"measured -72% at I = 1, \+56% at I = 0\.05"):
        SimParams(threshold=0.01)  # (an audit measured -71.5 % and +51 % on a flat field)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        SimParams(threshold=2.0)
        SimParams(threshold=0.5, shot_noise=False)
    for threshold in (1e38, 1e-46, 1e-4):  # float voltages overflowed, or the threshold was 0:
        with pytest.raises(ValueError, match="threshold expected in \\[0.001, 1e30\\]"):
            SimParams(threshold=threshold)  # every readout fired
    with pytest.raises(ValueError, match="SimParams threshold: .* a 401-digit integer, beyond"):
        SimParams(threshold=10**400)  # float()'s OverflowError named no field


def test_a_fixed_pattern_spread_that_moves_the_mean_rate_warns():
    """fpn_sigma 5 was taken in silence, the spikes then 4.6 times the test images' units (a
    units warning blamed the images); the gain said is the simulated one."""
    with pytest.warns(UserWarning, match=r"fpn_sigma 5: .* fire 4.62 times rate_at_one·I"):
        SimParams(fpn_sigma=5.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        SimParams(fpn_sigma=0.2)  # +4.6 %
    with pytest.warns(UserWarning, match=r"fpn_sigma 0.5: .* fire 1.62 times"):
        params = SimParams(fpn_sigma=0.5, dark_rate=0.0, shot_noise=False, temporal_sigma=0.0)
    light = np.full((1, 64, 64), 0.4, np.float32)  # 0.1 spikes a readout at gain 1
    spikes = simulate_spikes(light, 2000, params=params)
    rate = np.unpackbits(spikes, axis=-1).mean()  # 64 columns: whole bytes
    assert rate / (0.4 * params.rate_at_one) == pytest.approx(fpn_gain(0.5), rel=0.03)


def test_a_dark_current_spread_that_empties_most_pixels_warns():
    """dark_sigma 1e308 (or 1000) was taken in silence, its dark current none at all (the
    mean rate that of dark_rate 0); a spread whose 64x64 pixels fire well under dark_rate is said,
    with the mean over 20,000 pixels' draws, and the simulated frame's mean is as low."""
    with pytest.warns(UserWarning, match=r"dark_sigma 1e\+308: .* fire 0 times dark_rate's"):
        SimParams(dark_sigma=1e308)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        SimParams(dark_sigma=2.5)  # -2.7 %
        SimParams(dark_sigma=1000.0, dark_rate=0.0)  # no dark current to spread
    with pytest.warns(UserWarning, match=r"dark_sigma 5: .* fire 0.251 times"):
        params = SimParams(dark_sigma=5.0, dark_rate=0.01, shot_noise=False, temporal_sigma=0.0)
    spikes = simulate_spikes(np.zeros((1, 64, 64), np.float32), 2000, params=params)
    assert np.unpackbits(spikes, axis=-1).mean() < 0.5 * params.dark_rate  # most pixels: none


def test_frames_without_times_span_readouts_0_to_the_last():
    """Frames without frame_times are spread evenly over readouts [0, T - 1]: the same spikes,
    bit for bit, as frame_times [0, T - 1] given (spread over [0, T] the ramp reached 1 a readout
    late: 346 of the 800 packed bytes differ here)."""
    ramp = np.stack([np.zeros((8, 16)), np.ones((8, 16))]).astype(np.float32)
    params = SimParams(dark_rate=0.0)
    got = simulate_spikes(ramp, 50, seed=4, params=params)
    want = simulate_spikes(ramp, 50, frame_times=[0.0, 49.0], seed=4, params=params)
    np.testing.assert_array_equal(got, want)


def test_slightly_negative_light_is_refused():
    """Light is >= 0: -0.25 (not only -1) is refused, naming the value and where."""
    frames = np.ones((2, 4, 4), np.float32)
    frames[1, 2, 3] = -0.25
    with pytest.raises(ValueError, match=r"finite intensities >= 0, found -0.25 at \[1, 2, 3\]"):
        simulate_spikes(frames, 10)


def test_frame_times_must_start_at_readout_0():
    """Frames from readout 1 on leave readout 0 unlit: refused as frames ending early are."""
    frames = np.ones((2, 4, 4), np.float32)
    with pytest.raises(ValueError, match=r"covering readouts \[0, 9\], found 2 times in \[1"):
        simulate_spikes(frames, 10, frame_times=[1.0, 9.0])


def test_frame_times_refused_name_what_is_wrong():
    """One NaN time was told "found 2 times in [nan, nan]" (the C++-core trial)."""
    frames = np.ones((4, 4, 4), np.float32)
    cases = {
        (0.0, float("nan"), 9.0): r"found a time that is not finite, nan at index 1",
        (0.0, 5.0, 5.0, 9.0): r"found 5\.0 at index 2 after 5\.0",
        (0.0, 3.0): r"covering readouts \[0, 9\], found 2 times in \[0\.0, 3\.0\]",
    }
    for times, says in cases.items():
        with pytest.raises(ValueError, match=says):
            simulate_spikes(frames[: len(times)], 10, frame_times=list(times))


def test_light_beyond_float32_fires_every_readout_without_a_warning():
    """float64 light past float32's range is taken at float32's largest value (then capped where
    a pixel fires every readout): every readout fires, and no overflow warning (the light's
    saturation is)."""
    frames = np.full((1, 2, 8), 1e300, np.float64)
    with warnings.catch_warnings(), pytest.warns(UserWarning, match="100% of the light"):
        warnings.simplefilter("error", RuntimeWarning)
        packed = simulate_spikes(frames, 20)
    assert (packed == 0xFF).all()


def test_a_callable_is_sampled_at_most_max_light_times(monkeypatch):
    """(num_readouts - 1) / frame_every sampling times over MAX_LIGHT_TIMES (here 100) are
    refused before any frame is asked for; exactly MAX_LIGHT_TIMES are not."""
    monkeypatch.setattr(simulate, "MAX_LIGHT_TIMES", 100)
    light = lambda t: np.ones((2, 8), np.float32)  # noqa: E731
    with pytest.raises(ValueError, match="frame_every 0.05 samples the light 10 / 0.05 times"):
        simulate_spikes(light, 11, frame_every=0.05)  # 200 times
    with pytest.warns(UserWarning, match="70 of 81 light frames lie between two readouts"):
        assert simulate_spikes(light, 11, frame_every=0.125).shape[0] == 11  # 80 times


def test_light_in_other_units_and_a_channel_last_image_are_warned_of():
    """8-bit codes as floats fired 98 % of a random image's pixels every readout, and an [H, W, 1]
    image was simulated as H frames of W×1 pixels, both unsaid: each is warned of; light in
    range, frames of a few channels' width given their own times, and a bright scene's few
    saturated pixels are not."""
    codes = np.random.default_rng(0).random((1, 16, 16), np.float32) * 255
    with pytest.warns(UserWarning, match=r"9\d% of the light is at or above 1/rate_at_one = 4,"):
        simulate_spikes(codes, 50)
    with pytest.warns(UserWarning, match=r"frames \[16, 16, 1\] read as 16 frames of 16x1 pix"):
        simulate_spikes(np.full((16, 16, 1), 0.5, np.float32), 50)
    bright = np.full((1, 16, 16), 0.5, np.float32)
    bright[0, :4] = 10.0  # a quarter of the light saturates
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        simulate_spikes(bright, 50)
        simulate_spikes(codes / 255, 50)
        simulate_spikes(np.full((2, 16, 3), 0.5, np.float32), 50, frame_times=[0, 49])
