"""The threads a CPU quota pays for: a container's (`docker run --cpus=2`) or a Kubernetes pod's
CPU limit lets a process use a share of the machine's time, while OpenMP and torch start a thread
on every CPU they may run on (a 64-core host: 64 threads on 2 CPUs' worth of time, each parallel
region's wake-ups and stalls paid from the quota; measured on 2 cores, 16 threads under half a
CPU trained 1.6x slower than 1 thread)."""

from __future__ import annotations

import math
import os
from pathlib import Path

from .cgroup_files import MEMBERSHIP, ROOT, cgroup_files


def cpu_quota(membership: Path = MEMBERSHIP, root: Path = ROOT) -> float | None:
    """The lowest CPU quota over this process's cgroup and its ancestors, in CPUs (v2 `cpu.max`
    "QUOTA PERIOD", v1 `cpu.cfs_quota_us` over `cpu.cfs_period_us`); None where none is set
    ("max", -1) or none can be read."""
    quotas = []
    for path in cgroup_files("cpu", "cpu.cfs_quota_us", "cpu.max", membership, root):
        try:
            fields = path.read_text().split()
            if path.name == "cpu.cfs_quota_us":
                fields += path.with_name("cpu.cfs_period_us").read_text().split()
        except OSError:
            continue
        if len(fields) == 2 and fields[0].isdigit() and fields[1].isdigit() and int(fields[1]):
            quotas.append(int(fields[0]) / int(fields[1]))
    return min(quotas) if quotas else None


def usable_cpus() -> int:
    """The CPUs this process may run on (its affinity, which a cpuset limits)."""
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


def quota_threads(membership: Path = MEMBERSHIP, root: Path = ROOT) -> int | None:
    """The threads a CPU quota pays for where it is below the usable CPUs (its CPUs rounded up,
    at least 1); None where no quota is set or it covers them all."""
    quota = cpu_quota(membership, root)
    if quota is None:
        return None
    threads = max(1, math.ceil(quota))  # (whole microseconds: 150000/100000 is 1.5 exactly)
    return threads if threads < usable_cpus() else None
