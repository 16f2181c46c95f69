"""`spikegs bench spikes`: TFP, TFI and the simulator against numpy doing the same work.

TFP(w) for many timestamps on a memory-mapped 250x400 .dat stream, in GB/s of packed input read
(timestamps · w · frame bytes / time), with the ratio against numpy (unpackbits + mean over the
same windows) and the largest difference between the two, measured in the same run. The peak of
the allocations made during a batch is measured for two stream lengths (it should not grow with
the stream). TFI of a batch of timestamps against numpy searching each pixel's spikes around
them, with the largest difference. Simulator throughput in readouts/s at 250x400 at the default
noise, and without noise against numpy's integrate-and-fire of the same light, with the spikes
that differ between the two.
"""

from __future__ import annotations

import tracemalloc
from pathlib import Path
from typing import Any

import numpy as np

from ..atomic_save import save_figure
from ..pyplot_agg import pyplot
from ..spikes import TFI_DEFAULT_MAX_INTERVAL, SimParams, SpikeStream, simulate_spikes
from ..text_table import print_table
from .common import core_threads, median_seconds, scratch_folder, write_results

HEIGHT, WIDTH = 250, 400
BATCH = 25  # timestamps per call: bounds the output held at once ([25, H, W] float32)
TFI_CHUNK = 16  # readouts numpy unpacks at a time while it searches for a pixel's spikes
NOISE_FREE = SimParams(
    dark_rate=0.0, fpn_sigma=0.0, temporal_sigma=0.0, shot_noise=False, random_init=False
)


def _write_random_stream(path: Path, readouts: int, seed: int = 0) -> None:
    """A .dat file of `readouts` random frames (spike probability 1/4), written in chunks."""
    rng = np.random.default_rng(seed)
    frame_bytes = HEIGHT * WIDTH // 8
    with open(path, "wb") as f:
        for t in range(0, readouts, 1000):
            n = min(1000, readouts - t)
            a, b = rng.integers(0, 256, (2, n * frame_bytes), dtype=np.uint8)
            f.write((a & b).tobytes())


def _ours(stream: SpikeStream, ks: np.ndarray, w: int) -> None:
    for i in range(0, len(ks), BATCH):
        stream.tfp(ks[i : i + BATCH], w)


def _numpy_tfp(frames: np.ndarray, k: int, w: int) -> np.ndarray:
    """The numpy way: unpack the window to a byte per pixel, flip rows, mean over time. [H, W]"""
    window = frames[k - w // 2 : k - w // 2 + w]  # [w, H, W/8] packed
    return np.unpackbits(window, axis=-1, bitorder="little")[:, ::-1].mean(0, dtype=np.float32)


def _numpy(frames: np.ndarray, ks: np.ndarray, w: int) -> None:
    for k in ks:
        _numpy_tfp(frames, int(k), w)


def _spike_distance(frames: np.ndarray, origin: int, step: int, reach: int) -> np.ndarray:
    """Readouts from `origin` to each pixel's nearest spike walking by `step` (+1 or -1), origin
    included (0: a spike there), unpacking TFI_CHUNK readouts at a time until every pixel has
    one; `reach` where none lies within `reach` readouts or before the stream's end. frames:
    the packed, row-flipped file [T, H, W/8]; returns int64 [H, W]"""
    distance = np.full((frames.shape[1], frames.shape[2] * 8), reach, np.int64)
    for near in range(0, reach, TFI_CHUNK):
        readouts = origin + step * np.arange(near, min(near + TFI_CHUNK, reach))
        readouts = readouts[(readouts >= 0) & (readouts < len(frames))]
        if readouts.size == 0 or (distance < reach).all():
            break
        bits = np.unpackbits(frames[readouts], axis=-1, bitorder="little")[:, ::-1]
        fresh = (distance == reach) & bits.any(axis=0)
        distance[fresh] = near + np.argmax(bits, axis=0)[fresh]
    return distance


def _numpy_tfi(frames: np.ndarray, k: int, max_interval: int) -> np.ndarray:
    """TFI(k) the numpy way: 1 / min(t_next - t_prev, max_interval) from each pixel's last spike
    at or before k and first after it. [H, W] float32"""
    back = _spike_distance(frames, k, -1, max_interval)  # k - t_prev
    ahead = _spike_distance(frames, k + 1, 1, max_interval)  # t_next - (k + 1)
    return (1.0 / np.minimum(back + ahead + 1, max_interval)).astype(np.float32)


def _peak_alloc_mb(stream: SpikeStream, ks: np.ndarray, w: int) -> float:
    """Peak traced allocation (MB) during one batch of TFP."""
    tracemalloc.start()
    stream.tfp(ks[:BATCH], w)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return peak / 1e6


def _bench_tfp(stream: SpikeStream, frames: np.ndarray, w: int, count: int, np_count: int, rng):
    """One row: GB/s of ours and of numpy for TFP(w), their ratio and max difference."""
    ks = np.sort(rng.integers(w // 2, len(stream) - w + w // 2 + 1, count))
    frame_bytes = stream.layout.frame_bytes
    t_ours = median_seconds(lambda: _ours(stream, ks, w), repeats=3)
    t_np = median_seconds(lambda: _numpy(frames, ks[:np_count], w), repeats=3, warmup=0)
    # timestamps spread over those timed (the first 8, sorted, lay in the stream's first 1 %)
    check = ks[np.linspace(0, len(ks) - 1, min(8, len(ks))).astype(int)]
    err = float(
        np.max([np.abs(stream.tfp(int(k), w) - _numpy_tfp(frames, int(k), w)).max() for k in check])
    )
    gbs = count * w * frame_bytes / t_ours / 1e9
    gbs_np = np_count * w * frame_bytes / t_np / 1e9
    return {
        "w": w,
        "timestamps": count,
        "seconds": t_ours,
        "GB/s": gbs,
        "numpy GB/s": gbs_np,
        "vs numpy": gbs / gbs_np,
        "max |diff|": err,
    }


def _numpy_simulate(light: np.ndarray, times: np.ndarray, readouts: int, params: SimParams):
    """The simulator's model (spike_simulator.hpp) the numpy way, one readout at a time over
    every pixel, its normals drawn by numpy's generator (as many as the core draws, noise or
    not): light [F, H, W] shown at readouts `times` [F], linearly interpolated in between.
    Packed uint8 [readouts, H, ceil(W/8)], as simulate_spikes returns."""
    f32, p = np.float32, params
    rng = np.random.default_rng(0)
    z = rng.standard_normal((2, *light.shape[1:]), f32)  # [2, H, W] the pixels' constants
    theta = (p.threshold * np.maximum(1 + p.fpn_sigma * z[0], 0.1)).astype(f32)  # θ_i
    ds = p.dark_sigma
    dark = (p.threshold * p.dark_rate * np.exp(ds * z[1] - ds * ds / 2)).astype(f32)
    voltage = rng.random(theta.shape, f32) * theta * f32(p.random_init)  # [H, W]
    gain, shot, tsig = f32(p.threshold * p.rate_at_one), f32(p.shot_noise), f32(p.temporal_sigma)
    out = np.empty((readouts, light.shape[1], (light.shape[2] + 7) // 8), np.uint8)
    for t in range(readouts):
        f = max(int(np.searchsorted(times, t, side="right")) - 1, 0)
        # a readout at (or past) the last frame's time reads that frame alone, as the core does:
        # frames[F-2] + 1 · (frames[F-1] - frames[F-2]) rounds in float32
        nxt = min(f + 1, len(times) - 1)
        a = f32(np.clip((t - times[f]) / (times[nxt] - times[f]), 0.0, 1.0)) if nxt > f else f32(0)
        z = rng.standard_normal((2, *theta.shape), f32)
        mu = gain * np.maximum(light[f] + a * (light[nxt] - light[f]), 0) + dark
        voltage += mu + shot * np.sqrt(mu) * z[0]
        fire = voltage >= theta * np.maximum(1 + tsig * z[1], f32(0.1))
        voltage = np.where(fire, np.minimum(voltage - theta, theta), voltage)
        out[t] = np.packbits(fire, axis=-1, bitorder="little")
    return out


def _spike_count(packed: np.ndarray) -> int:
    """Spikes in packed readouts [T, H, ceil(W/8)] (their rows' padding bits are 0)."""
    return int(np.unpackbits(packed).sum())


def _timed(fn, *args, repeats: int = 1, **kwargs) -> tuple[float, Any]:
    """The median seconds of `repeats` calls of `fn(*args, **kwargs)` and the last's result."""
    results = []
    seconds = median_seconds(lambda: results.append(fn(*args, **kwargs)), repeats, warmup=0)
    return seconds, results[-1]


def _simulator_vs_numpy(light: np.ndarray, readouts: int) -> list[dict]:
    """Ours against numpy's same model over `readouts`, at the default noise (their spike counts
    agree within the noise; the draws differ) and without noise (the spikes that differ: float32
    either side, the core's fused and reordered sums can tip a pixel at its threshold); each
    time a median of 3, as TFP's and TFI's (one call moved with the machine's load)."""
    times = np.linspace(0.0, readouts - 1.0, len(light))  # [F]
    rows = []
    for noise, params in (("default", SimParams()), ("none", NOISE_FREE)):
        ours_seconds, ours_spikes = _timed(
            simulate_spikes, light, readouts, frame_times=times, params=params, repeats=3
        )
        numpy_seconds, numpy_spikes = _timed(
            _numpy_simulate, light, times, readouts, params, repeats=3
        )
        row = {
            "noise": noise,
            "readouts": readouts,
            "readouts/s": readouts / ours_seconds,
            "numpy readouts/s": readouts / numpy_seconds,
            "vs numpy": numpy_seconds / ours_seconds,
            "spikes": _spike_count(ours_spikes),
            "numpy spikes": _spike_count(numpy_spikes),
        }
        if noise == "none":  # the same spikes expected
            row["spikes differing"] = _spike_count(ours_spikes ^ numpy_spikes)
        rows.append(row)
    return rows


def _bench_simulator(light: np.ndarray, readouts: int) -> dict:
    """Throughput at the default noise over `readouts` of `light` [F, H, W]."""
    simulate_spikes(light, 64)  # warm up
    seconds, packed = _timed(simulate_spikes, light, readouts, params=SimParams())
    bits = np.unpackbits(packed[:200], axis=-1, bitorder="little")[..., :WIDTH]  # [200, H, W]
    return {
        "readouts": readouts,
        "seconds": seconds,
        "readouts/s": readouts / seconds,
        "mean rate": float(bits.mean()),
    }


def _plot(rows: list[dict], path: Path) -> None:
    plt = pyplot()
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter, NullLocator

    ws = [r["w"] for r in rows]
    fig, ax = plt.subplots(figsize=(5.5, 3.5))
    ax.plot(ws, [r["GB/s"] for r in rows], "o-", label="spikegs (packed bits, C++)")
    ax.plot(ws, [r["numpy GB/s"] for r in rows], "s--", label="numpy unpackbits + mean")
    ax.set_xscale("log", base=2)
    ax.set_xticks(ws, [str(w) for w in ws])  # the windows measured (not 8, 16, 32, ...)
    ax.xaxis.set_minor_locator(NullLocator())
    ax.set_yscale("log")  # GB/s labelled 0.2, 0.5, 1, 2, 5, 10, ...
    ax.yaxis.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
    ax.yaxis.set_major_formatter(FuncFormatter(lambda y, _: f"{y:g}"))
    ax.yaxis.set_minor_formatter(NullFormatter())
    ax.set_xlabel("window w (readouts)")
    ax.set_ylabel("GB/s (w frames of packed bits a TFP)")
    # two lines: on one it ran 11 pixels past the figure's edge, which cut "on 1" off
    ax.set_title(f"TFP on a {HEIGHT}×{WIDTH} stream\nspikegs on {core_threads()}, numpy on 1")
    ax.legend()
    fig.tight_layout()
    save_figure(fig, path)


def _bench_stream(path: Path, readouts: int, count: int, np_count: int) -> tuple:
    """TFP rows for several windows, the memory figures and TFI's against numpy on the file at
    `path`."""
    rng = np.random.default_rng(0)
    stream = SpikeStream.open(path, HEIGHT, WIDTH)
    frames = np.memmap(path, np.uint8, "r").reshape(readouts, HEIGHT, WIDTH // 8)
    rows = [
        _bench_tfp(stream, frames, w, count, np_count if w == 33 else count // 10, rng)
        for w in (9, 33, 65, 129)
    ]
    fb = stream.layout.frame_bytes
    short = SpikeStream(np.memmap(path, np.uint8, "r")[: 1000 * fb], stream.layout)
    ks = np.arange(16, 16 + BATCH)
    memory = {
        f"peak MB, stream of {len(short)}": _peak_alloc_mb(short, ks, 33),
        f"peak MB, stream of {len(stream)}": _peak_alloc_mb(stream, ks, 33),
        "output MB per batch": BATCH * HEIGHT * WIDTH * 4 / 1e6,
    }
    max_interval = TFI_DEFAULT_MAX_INTERVAL
    tfi_seconds = median_seconds(lambda: stream.tfi(ks), repeats=3)
    numpy_seconds = median_seconds(
        lambda: [_numpy_tfi(frames, int(k), max_interval) for k in ks], repeats=3, warmup=0
    )
    error = max(
        float(np.abs(stream.tfi(int(k)) - _numpy_tfi(frames, int(k), max_interval)).max())
        for k in ks
    )
    tfi = {
        "tfi_seconds": tfi_seconds,
        "tfi_timestamps": BATCH,
        "tfi_numpy_seconds": numpy_seconds,
        "tfi_vs_numpy": numpy_seconds / tfi_seconds,
        "tfi_max_diff": error,
    }
    return rows, memory, tfi


def run(quick: bool, out: Path) -> dict:
    """Run the benchmark, print a table, write spikes.json and spikes.png under `out`."""
    readouts = 2000 if quick else 20000
    count, np_count = (100, 20) if quick else (1000, 1000)
    with scratch_folder("spikes") as tmp:
        path = Path(tmp) / "stream.dat"
        _write_random_stream(path, readouts)
        rows, memory, tfi = _bench_stream(path, readouts, count, np_count)
    light = np.random.default_rng(1).random((3, HEIGHT, WIDTH), dtype=np.float32)  # [F, H, W]
    sim = _bench_simulator(light, 300 if quick else 3000)
    sim_rows = _simulator_vs_numpy(light, 50 if quick else 300)

    print(f"TFP on a memory-mapped {HEIGHT}x{WIDTH} stream of {readouts} readouts")
    print_table(rows)
    print(f"memory (traced allocations during one batch of {BATCH} TFP(33)): {memory}")
    print(
        f"TFI for {BATCH} timestamps: {tfi['tfi_seconds'] * 1e3:.1f} ms, numpy "
        f"{tfi['tfi_numpy_seconds'] * 1e3:.1f} ms ({tfi['tfi_vs_numpy']:.1f}x), max |diff| "
        f"{tfi['tfi_max_diff']:.2g}"
    )
    print(
        f"simulator at {HEIGHT}x{WIDTH}: {sim['readouts/s']:.0f} readouts/s (one call of "
        f"{sim['readouts']} readouts); against numpy (median of 3 calls each):"
    )
    print_table(sim_rows, columns=list(sim_rows[-1]))
    results = {
        "stream": {"height": HEIGHT, "width": WIDTH, "readouts": readouts},
        "tfp": rows,
        "memory": memory,
        **tfi,
        "simulator": sim,
        "simulator_vs_numpy": sim_rows,
    }
    write_results(out, "spikes", results, quick)
    _plot(rows, out / "spikes.png")
    return results
