"""The thread count that OpenMP and torch start with: a CPU quota's where one binds (a
container's `--cpus`, `cpu_quota`), unless the user chose one (OMP_NUM_THREADS). Imported by the
package before torch: OpenMP and torch read OMP_NUM_THREADS as they load."""

from __future__ import annotations

import os
import sys
from collections.abc import MutableMapping

from .cpu_quota import quota_threads, usable_cpus


def default_threads(environ: MutableMapping[str, str], quota: int | None) -> int | None:
    """`quota` threads (`quota_threads`) as `environ`'s OMP_NUM_THREADS, unless the user set
    one there; the count set, or None."""
    if quota is None or "OMP_NUM_THREADS" in environ:
        return None
    environ["OMP_NUM_THREADS"] = str(quota)
    return quota


TORCH_FIRST = "torch" in sys.modules  # loaded before spikegs: its count is set already
QUOTA_THREADS = default_threads(os.environ, quota_threads())


def set_loaded_threads(torch, core) -> None:
    """Where torch loaded before spikegs with one thread a CPU (the user set none), the quota's
    count for this thread, in torch and in the core's OpenMP runtime."""
    if QUOTA_THREADS is not None and TORCH_FIRST and torch.get_num_threads() == usable_cpus():
        torch.set_num_threads(QUOTA_THREADS)
        core.set_max_threads(QUOTA_THREADS)
