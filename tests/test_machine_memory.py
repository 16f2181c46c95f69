"""machine_memory.py: the memory limit of a process's cgroup, v1 and v2, its own or an
ancestor's, and none set."""

import os

from spikegs.machine_memory import cgroup_limit, machine_memory


def _file(path, text):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)


def test_the_lowest_limit_of_the_group_and_its_ancestors(tmp_path):
    """v2: a batch job limits its group (8 GiB), its step's group says "max": the job's counts;
    v1: the memory controller's group and the root's "unlimited" (2^63 - 4096)."""
    root, membership = tmp_path / "cgroup", tmp_path / "self_cgroup"
    _file(membership, "0::/slurm/job_7/step_0\n")
    _file(root / "slurm/job_7/step_0/memory.max", "max\n")
    _file(root / "slurm/job_7/memory.max", f"{8 << 30}\n")
    _file(root / "slurm/memory.max", f"{64 << 30}\n")
    assert cgroup_limit(membership, root) == 8 << 30
    _file(membership, "4:memory:/process_api/abc\n3:cpuset:/\n0::/\n")
    _file(root / "memory/process_api/abc/memory.limit_in_bytes", f"{3 << 30}\n")
    _file(root / "memory/memory.limit_in_bytes", "9223372036854771712\n")
    assert cgroup_limit(membership, root) == 3 << 30
    _file(root / "memory/process_api/abc/memory.limit_in_bytes", "9223372036854771712\n")
    assert cgroup_limit(membership, root) is None  # v1's "no limit"


def test_no_limit_set_or_readable(tmp_path):
    """ "max" everywhere, a group without files, or no /proc/self/cgroup: None, and the machine's
    memory stands."""
    root, membership = tmp_path / "cgroup", tmp_path / "self_cgroup"
    assert cgroup_limit(membership, root) is None  # no membership file
    _file(membership, "garbled\n0::/user.slice\n")
    assert cgroup_limit(membership, root) is None  # no memory.max
    _file(root / "user.slice/memory.max", "max\n")
    assert cgroup_limit(membership, root) is None
    assert machine_memory() > 0


def test_a_limit_above_the_machines_memory_leaves_the_machines(monkeypatch):
    """A cgroup limit larger than the physical memory (a job asking for more than the node has)
    does not raise what the process may use past the machine's; a lower one is the answer."""
    physical = os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    monkeypatch.setattr("spikegs.machine_memory.cgroup_limit", lambda: 4 * physical)
    assert machine_memory() == physical
    monkeypatch.setattr("spikegs.machine_memory.cgroup_limit", lambda: physical // 4)
    assert machine_memory() == physical // 4


def test_a_system_that_tells_no_memory_is_taken_for_16_gib(monkeypatch):
    """sysconf without the names (not POSIX): 16 GiB, or a lower cgroup limit."""

    def unknown(name):
        raise ValueError(f"unrecognized configuration name {name}")

    monkeypatch.setattr(os, "sysconf", unknown)
    monkeypatch.setattr("spikegs.machine_memory.cgroup_limit", lambda: None)
    assert machine_memory() == 16 << 30
    monkeypatch.setattr("spikegs.machine_memory.cgroup_limit", lambda: 2 << 30)
    assert machine_memory() == 2 << 30
