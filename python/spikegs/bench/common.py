"""Shared benchmark helpers: machine description, median timing and JSON results."""

from __future__ import annotations

import platform
import statistics
import time
from pathlib import Path
from typing import Any, Callable

from .. import strict_json
from ..atomic_save import write_text_atomically
from ..cpu_quota import cpu_quota, usable_cpus


def uniform(gen, lo: float, hi: float, *shape: int):
    """float64 draws [*shape] uniform in [lo, hi) from the torch Generator `gen`."""
    import torch

    return lo + (hi - lo) * torch.rand(*shape, generator=gen, dtype=torch.float64)


def machine_info() -> dict[str, Any]:
    """Cores, CPU model and library versions of the machine the figures come from."""
    import numpy
    import torch

    cpu = platform.processor() or "unknown"
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    return {
        "cpu": cpu,
        "cores": usable_cpus(),
        "cpu_quota": cpu_quota(),  # CPUs' worth of time (a container's --cpus), or None
        "torch_threads": torch.get_num_threads(),
        "python": platform.python_version(),
        "torch": torch.__version__,
        "numpy": numpy.__version__,
    }


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


def write_results(out_dir: Path, name: str, results: dict[str, Any]) -> Path:
    """Write `results` (plus the machine description) to `out_dir/name.json`."""
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / f"{name}.json"
    payload = {"benchmark": name, "machine": machine_info(), **results}
    write_text_atomically(path, strict_json.dumps(payload, indent=2))
    return path
