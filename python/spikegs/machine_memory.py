"""The memory this process may use: the machine's, or less where its cgroup (a batch job's, a
container's) is limited, which the machine's total does not show."""

from __future__ import annotations

import os
from pathlib import Path


def machine_memory() -> int:
    """Bytes of memory this process may use: the machine's physical memory, or its cgroup's
    limit where lower; 16 GiB where the system says neither."""
    try:
        total = os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (AttributeError, ValueError, OSError):  # not POSIX, or a name it lacks
        total = 16 << 30
    limit = cgroup_limit()
    return total if limit is None else min(total, limit)


def cgroup_limit(
    membership: Path = Path("/proc/self/cgroup"), root: Path = Path("/sys/fs/cgroup")
) -> int | None:
    """The lowest memory limit over this process's cgroup and its ancestors (v2 `memory.max`
    under `root`, v1 `memory.limit_in_bytes` under `root`/memory), as `membership` lists the
    groups; None where none is set ("max") or none can be read."""
    try:
        lines = membership.read_text().splitlines()
    except OSError:
        return None
    files = []
    for line in lines:
        fields = line.split(":", 2)  # hierarchy-ID:controllers:path
        if len(fields) != 3:
            continue
        _, controllers, group = fields
        if controllers == "":  # the v2 hierarchy
            base, name = root, "memory.max"
        elif "memory" in controllers.split(","):
            base, name = root / "memory", "memory.limit_in_bytes"
        else:
            continue
        parts = [p for p in group.split("/") if p]
        files += [base.joinpath(*parts[:n], name) for n in range(len(parts), -1, -1)]
    limits = []
    for path in files:
        try:
            text = path.read_text().strip()
        except OSError:
            continue
        if text.isdigit() and int(text) < 1 << 62:  # v1 writes ~2^63 for none
            limits.append(int(text))
    return min(limits) if limits else None
