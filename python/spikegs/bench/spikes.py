"""`spikegs bench spikes`: TFP from packed bits against numpy unpackbits + mean, and the simulator.

TFP(w) for many timestamps on a memory-mapped 250x400 .dat stream, in GB/s of packed input read
(timestamps · w · frame bytes / time), with the ratio against numpy (unpackbits + mean over the
same windows) and the largest difference between the two, measured in the same run. The peak of
the allocations made during a batch is measured for two stream lengths (it should not grow with
the stream). Simulator throughput in readouts/s at 250x400.
"""

from __future__ import annotations

import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np

from ..atomic_save import save_figure
from ..cpu_quota import usable_cpus
from ..spikes import SimParams, SpikeStream, simulate_spikes
from ..text_table import print_table
from .common import median_seconds, write_results

HEIGHT, WIDTH = 250, 400
BATCH = 25  # timestamps per call: bounds the output held at once ([25, H, W] float32)


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
    check = ks[:8]
    err = max(
        float(np.abs(stream.tfp(int(k), w) - _numpy_tfp(frames, int(k), w)).max()) for k in check
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


def _bench_simulator(readouts: int) -> dict:
    frames = np.random.default_rng(1).random((3, HEIGHT, WIDTH), dtype=np.float32)
    simulate_spikes(frames, 64)  # warm up
    start = time.perf_counter()
    packed = simulate_spikes(frames, readouts, params=SimParams())
    seconds = time.perf_counter() - start
    bits = np.unpackbits(packed[:200], axis=-1, bitorder="little")[..., :WIDTH]  # [200, H, W]
    return {
        "readouts": readouts,
        "seconds": seconds,
        "readouts/s": readouts / seconds,
        "mean rate": float(bits.mean()),
    }


def _plot(rows: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
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
    ax.set_title(f"TFP on a {HEIGHT}×{WIDTH} stream, {usable_cpus()} cores")
    ax.legend()
    fig.tight_layout()
    save_figure(fig, path)


def _bench_stream(path: Path, readouts: int, count: int, np_count: int) -> tuple:
    """TFP rows for several windows, the memory figures and the TFI time on the file at `path`."""
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
    tfi_seconds = median_seconds(lambda: stream.tfi(ks), repeats=3)
    return rows, memory, tfi_seconds


def run(quick: bool, out: Path) -> dict:
    """Run the benchmark, print a table, write spikes.json and spikes.png under `out`."""
    readouts = 2000 if quick else 20000
    count, np_count = (100, 20) if quick else (1000, 1000)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "stream.dat"
        _write_random_stream(path, readouts)
        rows, memory, tfi_seconds = _bench_stream(path, readouts, count, np_count)
    sim = _bench_simulator(300 if quick else 3000)

    print(f"TFP on a memory-mapped {HEIGHT}x{WIDTH} stream of {readouts} readouts")
    print_table(rows)
    print(f"memory (traced allocations during one batch of {BATCH} TFP(33)): {memory}")
    print(f"TFI for {BATCH} timestamps: {tfi_seconds * 1e3:.1f} ms")
    print(f"simulator at {HEIGHT}x{WIDTH}: {sim['readouts/s']:.0f} readouts/s")
    results = {
        "stream": {"height": HEIGHT, "width": WIDTH, "readouts": readouts},
        "tfp": rows,
        "memory": memory,
        "tfi_seconds": tfi_seconds,
        "tfi_timestamps": BATCH,
        "simulator": sim,
    }
    write_results(out, "spikes", results)
    _plot(rows, out / "spikes.png")
    return results
