"""Shared benchmark helpers: median timing and JSON results (with the machine's record)."""

from __future__ import annotations

import os
import statistics
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from .. import strict_json
from ..atomic_save import write_text_atomically
from ..provenance import environment


def uniform(gen, lo: float, hi: float, *shape: int):
    """float64 draws [*shape] uniform in [lo, hi) from the torch Generator `gen`."""
    import torch

    return lo + (hi - lo) * torch.rand(*shape, generator=gen, dtype=torch.float64)


def scratch_folder(part: str) -> tempfile.TemporaryDirectory:
    """A temporary folder for the benchmark `part`'s data, removed at the block's end (Ctrl-C
    included); named `spikegs-bench-PART-*` in $TMPDIR, so that one a killed process left (up to
    ~250 MB for `bench spikes`) says whose it is."""
    return tempfile.TemporaryDirectory(prefix=f"spikegs-bench-{part}-")


def core_threads() -> str:
    """The C++ core's OpenMP threads as a figure names them ("1 thread", "2 threads"): what it ran
    on, which OMP_NUM_THREADS sets below the CPUs (the figures said "2 cores" for 1 thread)."""
    from .. import _C

    n = _C.max_threads()
    return f"{n} thread{'s' * (n != 1)}"


def median_seconds(fn: Callable[[], Any], repeats: int = 5, warmup: int = 1) -> float:
    """Median wall-clock seconds of `fn()` over `repeats` runs after `warmup` untimed runs."""
    for _ in range(warmup):
        fn()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def median_ratio(
    numerator: Callable[[], Any], denominator: Callable[[], Any], repeats: int = 5
) -> float:
    """Median over `repeats` pairs, timed in turn after one untimed call of each, of
    `numerator()`'s seconds over `denominator()`'s: a ratio the machine's load moves less than
    two medians timed apart do (an anti-aliasing cost of about 1 measured 0.35 to 2.08 so)."""
    numerator(), denominator()
    ratios = []
    for _ in range(repeats):
        top = median_seconds(numerator, repeats=1, warmup=0)
        ratios.append(top / median_seconds(denominator, repeats=1, warmup=0))
    return statistics.median(ratios)


def write_results(out_dir: Path, name: str, results: dict[str, Any], quick: bool) -> Path:
    """Write `results` (plus the machine description, and whether `quick`: a check that the
    bench runs, whose figures are no measurement) to `out_dir/name.json`."""
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / f"{name}.json"
    # the load at the end, the bench's own threads included (a snapshot, where a bench has none)
    payload = {
        "benchmark": name,
        "quick": quick,
        "machine": environment(),
        "load_average": os.getloadavg(),
        **results,
    }
    write_text_atomically(path, strict_json.dumps(payload, indent=2))
    return path
