"""The memory this process may use: the machine's, or less where its cgroup (a batch job's, a
container's) is limited, which the machine's total does not show."""

from __future__ import annotations

import os
from pathlib import Path

from .cgroup_files import MEMBERSHIP, ROOT, cgroup_files


def machine_memory() -> int:
    """Bytes of memory this process may use: the machine's physical memory, or its cgroup's
    limit where lower; 16 GiB where the system says neither."""
    try:
        total = os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (AttributeError, ValueError, OSError):  # not POSIX, or a name it lacks
        total = 16 << 30
    limit = cgroup_limit()
    return total if limit is None else min(total, limit)


def cgroup_limit(membership: Path = MEMBERSHIP, root: Path = ROOT) -> int | None:
    """The lowest memory limit over this process's cgroup and its ancestors (v2 `memory.max`,
    v1 `memory.limit_in_bytes`; `cgroup_files`); None where none is set ("max") or none can be
    read."""
    limits = []
    for path in cgroup_files("memory", "memory.limit_in_bytes", "memory.max", membership, root):
        try:
            text = path.read_text().strip()
        except OSError:
            continue
        if text.isdigit() and int(text) < 1 << 62:  # v1 writes ~2^63 for none
            limits.append(int(text))
    return min(limits) if limits else None
