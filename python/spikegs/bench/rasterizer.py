"""`spikegs bench rasterizer`: C++ rasterizer time, work and memory against the torch reference.

For each N (Gaussians), image size and channel count C, on the standard scene: forward and
forward+backward medians (ms), evaluated (pixel, Gaussian) pairs and ns per pair, peak memory, the
float32 error against float64, and the ratio against `spikegs.reference` (pure torch) timed once in
the same run where it is affordable (N <= 1e4); the antialiased filter's forward+backward
(`aa_*`): its time, its cost against the plain filter's and its float32 error. Peak memory is the
resident-set high-water mark (VmHWM in /proc/self/status) after resetting it (`echo 5 >
/proc/self/clear_refs`), minus the resident set before the run: the C++ core's allocations are
invisible to tracemalloc and torch's allocator counters, and ru_maxrss cannot be reset. It is
measured in a fresh process, because an allocator that already holds memory from earlier runs
shows no growth.
"""

from __future__ import annotations

import contextlib
import functools
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import torch

from .. import _C, reference
from ..atomic_save import save_figure
from ..curves import COLOURS, MARKERS
from ..pyplot_agg import pyplot
from ..rasterize import rasterize
from ..text_table import print_table
from .common import core_threads, median_ratio, median_seconds, uniform, write_results

REFERENCE_MAX_N = 10_000  # the torch reference is timed (once) up to this N
WARMUP_N = 10  # Gaussians of the reference's untimed first render
# The reference is a Python loop of small ops: one torch thread is its fastest setting (threads
# only add synchronisation, badly so on a loaded machine).
REFERENCE_THREADS = 1
LOSS = "mean((image - 0.5)^2) + mean(alpha)"


def standard_scene(n: int, width: int, height: int, channels: int, seed: int = 0) -> dict:
    """N Gaussians uniform in a unit cube 2 units in front of an identity camera, fx = fy = 256,
    principal point at the image centre; scales in [0.01, 0.05], random unit quaternions,
    opacities in [0.05, 0.95], random direct colours. float64 tensors."""
    gen = torch.Generator().manual_seed(seed)

    quats = torch.randn(n, 4, generator=gen, dtype=torch.float64)
    return {
        "means": uniform(gen, -0.5, 0.5, n, 3) + torch.tensor([0.0, 0.0, 2.0], dtype=torch.float64),
        "quats": quats / quats.norm(dim=-1, keepdim=True),
        "scales": uniform(gen, 0.01, 0.05, n, 3),
        "opacities": uniform(gen, 0.05, 0.95, n),
        "colors": uniform(gen, 0.0, 1.0, n, channels),
        "viewmat": torch.eye(4, dtype=torch.float64),
        "K": torch.tensor(
            [[256.0, 0.0, width / 2], [0.0, 256.0, height / 2], [0.0, 0.0, 1.0]],
            dtype=torch.float64,
        ),
    }


def _render(fn: Callable, scene: dict, width: int, height: int, grad: bool):
    """Render with `fn` (and with `grad`, backpropagate the benchmark loss): (out, leaves)."""
    leaves = {k: v.detach().requires_grad_(grad and k != "K") for k, v in scene.items()}
    with torch.set_grad_enabled(grad):
        out = fn(*leaves.values(), width, height)
        if grad:
            loss = ((out.image - 0.5) ** 2).mean() + out.alpha.mean()
            loss.backward()
    return out, leaves


def _status_mb(field: str) -> float:
    """A memory field of /proc/self/status (VmRSS, VmHWM) in MiB."""
    with open("/proc/self/status") as f:
        line = next(line for line in f if line.startswith(field + ":"))
    return float(line.split()[1]) / 1024  # kB -> MiB


def peak_in_this_process(n: int, width: int, height: int, channels: int) -> float:
    """Resident-set high-water mark of one float32 forward+backward above the resident set before
    it (MiB); meant for a fresh process, whose allocator holds no memory from earlier runs."""
    scene = {k: v.float() for k, v in standard_scene(n, width, height, channels).items()}
    with open("/proc/self/clear_refs", "w") as f:
        f.write("5")  # resets VmHWM to the current resident set
    before = _status_mb("VmRSS")
    _render(rasterize, scene, width, height, True)
    return _status_mb("VmHWM") - before


def _peak_rss_mb(n: int, width: int, height: int, channels: int) -> float:
    """`peak_in_this_process` run in a fresh Python process; NaN where /proc cannot do it."""
    # this package, first on the child's path (through PYTHONPATH, a folder holding ':' split in
    # two, and the child imported another install's spikegs without a word)
    package_root = str(Path(__file__).resolve().parents[2])
    code = (
        f"import sys; sys.path.insert(0, {package_root!r}); "
        "from spikegs.bench.rasterizer import peak_in_this_process as f; "
        f"print(f({n}, {width}, {height}, {channels}))"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    try:
        return float(done.stdout.split()[-1])
    except (IndexError, ValueError):
        return float("nan")


@contextlib.contextmanager
def _torch_threads(count: int):
    """Run the block with `count` torch intra-op threads."""
    saved = torch.get_num_threads()
    torch.set_num_threads(count)
    try:
        yield
    finally:
        torch.set_num_threads(saved)


def _pairs(out, width: int, height: int) -> tuple[int, str]:
    """(pixel, Gaussian) pairs the forward evaluated: the C++ count where the autograd node holds
    the core's context, else the pixels of each visible Gaussian's box inside the image."""
    count = getattr(getattr(out.image.grad_fn, "raster", None), "pairs", None)
    if count is not None:
        return int(count), "core"
    r = out.radii.double()
    mx, my = out.means2d.detach().double().unbind(-1)
    w = (torch.minimum(mx + r, torch.tensor(width)) - torch.clamp(mx - r, min=0)).clamp(min=0)
    h = (torch.minimum(my + r, torch.tensor(height)) - torch.clamp(my - r, min=0)).clamp(min=0)
    return int((w * h)[out.radii > 0].sum().item()), "box estimate"


def _max_error(a: torch.Tensor, b: torch.Tensor) -> float:
    return (a.detach().double() - b.detach().double()).abs().max().item()


def measure(n: int, width: int, height: int, channels: int, repeats: int) -> dict[str, Any]:
    """One row of the benchmark: timings, work, memory and errors for one configuration."""
    scene64 = standard_scene(n, width, height, channels)
    scene = {k: v.float() for k, v in scene64.items()}
    forward_s = median_seconds(lambda: _render(rasterize, scene, width, height, False), repeats)
    both_s = median_seconds(lambda: _render(rasterize, scene, width, height, True), repeats)
    peak_mb = _peak_rss_mb(n, width, height, channels)
    out, leaves = _render(rasterize, scene, width, height, True)
    out64, leaves64 = _render(rasterize, scene64, width, height, True)
    pairs, pairs_source = _pairs(out, width, height)
    grad_scale = max(leaves64["means"].grad.abs().max().item(), 1e-300)
    # the antialiased 2D filter (each opacity times sqrt(det Σ / det(Σ + 0.3 px²))): its cost
    # against the plain filter's, in the same process, and its float32 error
    antialiased = functools.partial(rasterize, antialiased=True)
    aa_s = median_seconds(lambda: _render(antialiased, scene, width, height, True), repeats)
    aa_cost = median_ratio(
        lambda: _render(antialiased, scene, width, height, True),
        lambda: _render(rasterize, scene, width, height, True),
        repeats,
    )
    out_aa, _ = _render(antialiased, scene, width, height, True)
    out64_aa, _ = _render(antialiased, scene64, width, height, True)
    row = {
        "N": n,
        "size": f"{width}x{height}",
        "C": channels,
        "fwd_ms": 1e3 * forward_s,
        "fwd_bwd_ms": 1e3 * both_s,
        "pairs": pairs,
        "pairs_source": pairs_source,
        "ns_per_pair": 1e9 * forward_s / max(pairs, 1),
        "peak_mb": peak_mb,
        "err_image_f32": _max_error(out.image, out64.image),
        "err_grad_means_f32_rel": _max_error(leaves["means"].grad, leaves64["means"].grad)
        / grad_scale,
        "aa_fwd_bwd_ms": 1e3 * aa_s,
        "aa_cost": aa_cost,
        "aa_err_image_f32": _max_error(out_aa.image, out64_aa.image),
    }
    if n <= REFERENCE_MAX_N:
        with _torch_threads(REFERENCE_THREADS):
            # a small scene first: torch's first calls (15-20 % of a 1e4 forward) go untimed
            small = {k: v if k in ("viewmat", "K") else v[:WARMUP_N] for k, v in scene.items()}
            _render(reference.rasterize, small, width, height, True)
            start = time.perf_counter()
            ref, _ = _render(reference.rasterize, scene, width, height, False)
            ref_forward_s = time.perf_counter() - start
            start = time.perf_counter()
            _render(reference.rasterize, scene, width, height, True)
            ref_both_s = time.perf_counter() - start
        row.update(
            ref_fwd_ms=1e3 * ref_forward_s,
            ref_fwd_bwd_ms=1e3 * ref_both_s,
            ref_err_image_f32=_max_error(ref.image, out64.image),
            speedup_fwd=ref_forward_s / forward_s,
            speedup_fwd_bwd=ref_both_s / both_s,
        )
    return row


def _plot(rows: list[dict[str, Any]], repeats: int, path: Path) -> None:
    """Time against N, log-log: C++ (solid, filled markers), torch reference (dashed, open), a
    colour and marker per size and C (the curves' colour-blind-safe ones, told apart in grey
    too; matplotlib's cycle drew red beside green, every size and C with the same marker); the
    legend right of the panels (inside, it lay over the C++ lines' largest N)."""
    plt = pyplot()

    fig, axes = plt.subplots(1, 2, figsize=(13, 4.2), sharey=True)
    configs = sorted({(r["size"], r["C"]) for r in rows})
    for ax, key, title in zip(axes, ("fwd_ms", "fwd_bwd_ms"), ("forward", "forward + backward")):
        for i, (size, channels) in enumerate(configs):
            sel = [r for r in rows if (r["size"], r["C"]) == (size, channels)]
            style = {"color": COLOURS[i % len(COLOURS)], "marker": MARKERS[i % len(MARKERS)]}
            label = f"{size.replace('x', '×')}, C = {channels}"
            ax.loglog(
                [r["N"] for r in sel], [r[key] for r in sel], "-", label=f"C++ {label}", **style
            )
            ref = [r for r in sel if "ref_" + key in r]
            if ref:
                ax.loglog(
                    [r["N"] for r in ref],
                    [r["ref_" + key] for r in ref],
                    "--",
                    markerfacecolor="none",
                    label=f"torch reference {label}",
                    **style,
                )
        ax.set_title(title)
        ax.set_xlabel("Gaussians N")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].set_ylabel("time (ms)")
    axes[1].legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.03, 1.0), borderaxespad=0)
    fig.suptitle(
        f"spikegs.rasterize (C++, median of {repeats} after a warm-up, "
        f"{core_threads()}) vs spikegs.reference (torch, timed once, 1 thread), "
        f"float32; C: channels, size W×H pixels",
        fontsize=10,
    )
    fig.tight_layout()
    save_figure(fig, path)


def run(quick: bool, out: Path) -> dict:
    """Run the benchmark, print the table, write rasterizer.json and rasterizer.png under `out`."""
    if quick:
        ns, sizes, channel_counts, repeats = [1_000, 10_000], [(256, 256)], [3], 2
    else:
        ns, sizes, channel_counts, repeats = (
            [1_000, 10_000, 100_000],
            [(256, 256), (400, 250)],
            [1, 3],
            5,
        )
    rows = []
    for width, height in sizes:
        for channels in channel_counts:
            for n in ns:
                rows.append(measure(n, width, height, channels, repeats))
                fwd_bwd = rows[-1]["fwd_bwd_ms"]
                print(f"  N={n} {width}x{height} C={channels}: forward+backward {fwd_bwd:.1f} ms")
    columns = [c for c in dict.fromkeys(k for row in rows for k in row) if c != "pairs_source"]
    print_table(rows, columns)
    print(
        f"speedup_*: the core on {_C.max_threads()} thread(s), median of {repeats} after a "
        f"warm-up, against the pure-torch reference on {REFERENCE_THREADS} thread, timed once "
        f"after an untimed render of {WARMUP_N} Gaussians"
    )
    results = {
        "scene": "means uniform in a unit cube 2 units in front, fx = fy = 256, cx, cy = centre, "
        "identity viewmat, scales U[0.01, 0.05], unit quaternions, opacities U[0.05, 0.95], "
        "direct colours U[0, 1]; float32 (errors against the float64 core)",
        "loss": LOSS,
        "alternative": "spikegs.reference.rasterize (pure torch, autograd), timed once after an "
        f"untimed render of {WARMUP_N} Gaussians, "
        f"{REFERENCE_THREADS} torch thread(s), against the core on its threads (machine's "
        "core_threads), a median of repeats after a warm-up: speed-ups per process, not per "
        "thread",
        "peak_memory": "one forward+backward in a fresh process: VmHWM after "
        "`5 > /proc/self/clear_refs`, minus VmRSS before (MiB)",
        "repeats": repeats,
        "rows": rows,
    }
    write_results(out, "rasterizer", results, quick)
    _plot(rows, repeats, out / "rasterizer.png")
    return results
