"""The files of this process's cgroup (a batch job's, a container's) and of its ancestors, where
the kernel states the limits that the machine's totals do not show."""

from __future__ import annotations

from pathlib import Path

MEMBERSHIP = Path("/proc/self/cgroup")
ROOT = Path("/sys/fs/cgroup")


def cgroup_files(
    v1_controller: str,
    v1_name: str,
    v2_name: str,
    membership: Path = MEMBERSHIP,
    root: Path = ROOT,
) -> list[Path]:
    """The limit files of this process's groups, each group's own first, then its ancestors':
    `v2_name` in the v2 hierarchy under `root`, `v1_name` under `root`/`v1_controller` in the v1
    one, as `membership` lists the groups; none where it cannot be read. The files may not
    exist."""
    try:
        lines = membership.read_text().splitlines()
    except OSError:
        return []
    files = []
    for line in lines:
        fields = line.split(":", 2)  # hierarchy-ID:controllers:path
        if len(fields) != 3:
            continue
        _, controllers, group = fields
        if controllers == "":  # the v2 hierarchy
            bases, name = [root], v2_name
        elif v1_controller in controllers.split(","):  # mounted by its controllers' names, or
            # by the controller's ('cpu,cpuacct', and 'cpu' a link to it on systemd's hosts)
            bases, name = list(dict.fromkeys([root / controllers, root / v1_controller])), v1_name
        else:
            continue
        parts = [p for p in group.split("/") if p]
        for base in bases:
            files += [base.joinpath(*parts[:n], name) for n in range(len(parts), -1, -1)]
    return files
