"""cpu_quota.py and thread_count.py: a container's CPU quota (cgroup v1 and v2, its own or an
ancestor's) chooses the threads OpenMP and torch start with, unless the user chose."""

import types

import pytest
from spikegs import _C, cpu_quota, thread_count
from spikegs.cgroup_files import cgroup_files
from spikegs.cpu_quota import cpu_quota as quota_of
from spikegs.cpu_quota import quota_threads
from spikegs.thread_count import default_threads, set_loaded_threads


def _file(path, text):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)


def test_the_lowest_quota_of_the_group_and_its_ancestors(tmp_path):
    """v2: `cpu.max` "QUOTA PERIOD" ("max" for none), a pod's limit on its parent; v1: the cpu
    controller's cfs_quota_us (-1 for none) over cfs_period_us."""
    root, membership = tmp_path / "cgroup", tmp_path / "self_cgroup"
    _file(membership, "0::/kubepods/pod_7/ctr\n")
    _file(root / "kubepods/pod_7/ctr/cpu.max", "max 100000\n")
    _file(root / "kubepods/pod_7/cpu.max", "150000 100000\n")
    _file(root / "kubepods/cpu.max", "800000 100000\n")
    assert quota_of(membership, root) == 1.5
    _file(membership, "4:cpu,cpuacct:/docker/abc\n3:memory:/\n0::/\n")
    v1 = root / "cpu,cpuacct"  # mounted by its controllers' names
    _file(v1 / "docker/abc/cpu.cfs_quota_us", "25000\n")
    _file(v1 / "docker/abc/cpu.cfs_period_us", "50000\n")
    _file(v1 / "cpu.cfs_quota_us", "-1\n")
    _file(v1 / "cpu.cfs_period_us", "100000\n")
    assert quota_of(membership, root) == 0.5
    _file(v1 / "docker/abc/cpu.cfs_quota_us", "-1\n")
    assert quota_of(membership, root) is None
    _file(root / "cpu/docker/abc/cpu.cfs_quota_us", "200000\n")  # mounted as 'cpu' alone
    _file(root / "cpu/docker/abc/cpu.cfs_period_us", "100000\n")
    assert quota_of(membership, root) == 2.0
    assert quota_of(tmp_path / "none", root) is None  # no /proc/self/cgroup


def test_threads_round_the_quota_up_below_the_usable_cpus(tmp_path, monkeypatch):
    root, membership = tmp_path / "cgroup", tmp_path / "self_cgroup"
    _file(membership, "0::/job\n")
    monkeypatch.setattr(cpu_quota, "usable_cpus", lambda: 64)
    for quota, threads in ((50000, 1), (150000, 2), (200000, 2), (6400000, None), (9e6, None)):
        _file(root / "job/cpu.max", f"{int(quota)} 100000\n")
        assert quota_threads(membership, root) == threads, quota
    _file(root / "job/cpu.max", "max 100000\n")
    assert quota_threads(membership, root) is None


def test_the_usable_cpus_are_this_processs_affinity_else_the_machines(monkeypatch):
    """A cpuset's CPUs (this process's affinity, pid 0); where the OS keeps none (macOS) the
    machine's count, 1 where even that is unknown."""
    monkeypatch.setattr(cpu_quota.os, "sched_getaffinity", lambda pid: {3} if pid == 0 else {})
    monkeypatch.setattr(cpu_quota.os, "cpu_count", lambda: 8)
    assert cpu_quota.usable_cpus() == 1
    monkeypatch.delattr(cpu_quota.os, "sched_getaffinity")
    assert cpu_quota.usable_cpus() == 8
    monkeypatch.setattr(cpu_quota.os, "cpu_count", lambda: None)
    assert cpu_quota.usable_cpus() == 1


def test_the_users_thread_count_stands():
    environ = {}
    assert default_threads(environ, 2) == 2 and environ == {"OMP_NUM_THREADS": "2"}
    environ = {"OMP_NUM_THREADS": "8"}
    assert default_threads(environ, 2) is None and environ == {"OMP_NUM_THREADS": "8"}
    assert default_threads({}, None) is None


def test_torch_loaded_first_takes_the_quotas_count(monkeypatch):
    """A script that imported torch before spikegs: torch counted its threads already (one a
    CPU); unless the user set a count, the quota's is set in torch and in the core."""
    calls = []
    fake_torch = types.SimpleNamespace(
        get_num_threads=lambda: 64, set_num_threads=lambda n: calls.append(("torch", n))
    )
    core = types.SimpleNamespace(set_max_threads=lambda n: calls.append(("core", n)))
    monkeypatch.setattr(thread_count, "usable_cpus", lambda: 64)
    monkeypatch.setattr(thread_count, "QUOTA_THREADS", 2)
    monkeypatch.setattr(thread_count, "TORCH_FIRST", False)
    set_loaded_threads(fake_torch, core)
    assert calls == []  # loaded after: OMP_NUM_THREADS did it
    monkeypatch.setattr(thread_count, "TORCH_FIRST", True)
    set_loaded_threads(fake_torch, core)
    assert calls == [("torch", 2), ("core", 2)]
    fake_torch.get_num_threads = lambda: 3  # the user's own count
    set_loaded_threads(fake_torch, core)
    assert len(calls) == 2


def test_the_cores_thread_count_is_at_least_one():
    """The core's set_max_threads took 0 or a negative count and acted as 1, unsaid."""
    for n in (0, -5):
        with pytest.raises(ValueError, match=f"n expected >= 1, found {n}"):
            _C.set_max_threads(n)


def test_a_groups_limit_files_run_from_its_own_to_the_roots(tmp_path):
    """Each group's file, then its ancestors' up to the root, for a v1 controller mounted under
    its controllers' names and its own, and the v2 hierarchy; a colon in a group's name is the
    name's."""
    root, membership = tmp_path / "cgroup", tmp_path / "self_cgroup"
    _file(membership, "4:cpu,cpuacct:/a:b/c\n0::/x/y\n")
    v1 = [root / "cpu,cpuacct", root / "cpu"]
    assert cgroup_files("cpu", "q", "max", membership, root) == [
        *(base / p for base in v1 for p in ("a:b/c/q", "a:b/q", "q")),
        *(root / p for p in ("x/y/max", "x/max", "max")),
    ]


def test_a_quota_at_the_root_of_a_namespaced_group_counts(tmp_path, monkeypatch):
    """A container with its own cgroup namespace sees itself at the root ("0::/") and `docker run
    --cpus=2.4` writes cpu.max there: 2.4 CPUs (the root's own file was left out: no quota),
    3 threads (rounded up, not to the nearest); a period of 0 (a torn file) is no quota, not a
    ZeroDivisionError as the package loads."""
    root, membership = tmp_path / "cgroup", tmp_path / "self_cgroup"
    _file(membership, "0::/\n")
    _file(root / "cpu.max", "240000 100000\n")
    monkeypatch.setattr(cpu_quota, "usable_cpus", lambda: 64)
    assert quota_of(membership, root) == 2.4 and quota_threads(membership, root) == 3
    _file(root / "cpu.max", "50000 0\n")
    assert quota_of(membership, root) is None
