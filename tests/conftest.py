"""Fixtures shared by the test files."""

from __future__ import annotations

import collections
import dataclasses
import os
import shutil
import signal
import sys
import weakref

import numpy as np
import pytest
import torch


@pytest.fixture(autouse=True)
def fresh_findings():
    """Each test searches its recordings afresh: `found_once` keeps what a search of the spikes
    found for the process, and a test may patch the search."""
    from spikegs.found_once import forget

    forget()


@pytest.fixture
def ctrl_c():
    """Ctrl-C raising KeyboardInterrupt, as in a terminal, for the test's duration: a process
    started in the background by a non-interactive shell (`cmd &`) inherits SIGINT ignored, and
    the trainer rightly keeps it ignored (test_an_ignored_sigint_stays_ignored)."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)


@pytest.fixture
def console_signals():
    """SIGINT, SIGTERM and SIGHUP as the test found them, after `console()` (which sets them to
    be ignored once a command is stopped, and SIGTERM and SIGHUP to raise Terminated); SIGTERM
    and SIGHUP at their defaults for the test and the commands it starts, as in a fresh process
    (a suite run under nohup passes SIGHUP on ignored, and a command rightly keeps it so)."""
    from spikegs.interrupt import ENDING

    previous = {s: signal.getsignal(s) for s in (signal.SIGINT, *ENDING)}
    for s in ENDING:
        signal.signal(s, signal.SIG_DFL)
    yield previous
    for s, handler in previous.items():
        signal.signal(s, handler)


@pytest.fixture
def as_llff():
    """`as_llff(dataset, root, spikes=None)`: `root`, made to hold `dataset`'s spikes (or the
    .dat file `spikes`) in the LLFF layout, one stream with a pose every 50 readouts (every 8th
    held out without a sharp image: scored against a pseudo ground truth)."""
    from spikegs.data.llff import to_poses_bounds

    def write(dataset, root, spikes=None):
        readouts = np.arange(0, len(dataset.stream), 50)  # [P]
        viewmats = dataset.trajectory.pose_at(readouts)  # [P, 4, 4]
        centres = np.linalg.inv(viewmats)[:, :3, 3]  # [P, 3]
        distance = np.linalg.norm(centres - dataset.scene_center, axis=1)
        bounds = distance[:, None] + [-1.5 * dataset.scene_radius, 1.5 * dataset.scene_radius]
        hwf = (dataset.stream.height, dataset.stream.width, dataset.K[0, 0])
        root.mkdir(parents=True)
        np.save(root / "poses_bounds.npy", to_poses_bounds(viewmats, hwf, bounds))
        np.savetxt(root / "readouts.txt", readouts, fmt="%d")
        shutil.copy(spikes or dataset.root / "spikes.dat", root / "spikes.dat")
        return root

    return write


@pytest.fixture
def moved_world():
    """`moved_world(dataset, offset, scale=1)`: `dataset` with its world scaled by `scale` about
    the origin, then moved by `offset` [3] (poses, test views, scene centre and radius), as if
    captured there (UTM or GPS coordinates) in other units."""
    from spikegs.data.dataset import Dataset
    from spikegs.data.trajectory import Trajectory

    def moved(dataset, offset, scale: float = 1.0) -> Dataset:
        offset = np.asarray(offset, np.float64)

        def move(viewmats):  # world-to-camera [..., 4, 4]: scale·t - R·offset
            out = np.array(viewmats, np.float64)
            out[..., :3, 3] = scale * out[..., :3, 3] - out[..., :3, :3] @ offset
            return out

        trajectory = Trajectory(dataset.trajectory.readouts, move(dataset.trajectory.viewmats))
        views = [dataclasses.replace(v, viewmat=move(v.viewmat)) for v in dataset.test_views]
        meta = {
            **dataset.meta,
            "scene_center": list(scale * dataset.scene_center + offset),
            "scene_radius": scale * dataset.scene_radius,
        }
        timestamps = dataset.train_timestamps
        return Dataset(dataset.root, meta, dataset.streams, trajectory, timestamps, views)

    return moved


@pytest.fixture(scope="module")
def one_torch_thread():
    """One torch thread for a module's tests: their tensors are tiny, and one thread beats OpenMP
    hand-offs, most of all on a busy machine."""
    import torch

    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


class _GoneStderr:
    """A stderr whose writes raise `error` once `gone` is set."""

    def __init__(self, error: OSError):
        self.error, self.gone = error, False

    def write(self, text: str) -> int:
        if self.gone:
            raise self.error
        return len(text)

    def flush(self) -> None:
        if self.gone:
            raise self.error


@pytest.fixture
def gone_stderr(monkeypatch):
    """`gone_stderr(error)`: sys.stderr, for the test, a stream whose writes raise `error` (its
    reader left: EPIPE; its terminal closed: EIO) once its `gone` is set."""

    def install(error: OSError) -> _GoneStderr:
        stream = _GoneStderr(error)
        monkeypatch.setattr(sys, "stderr", stream)
        return stream

    return install


class AliveArrays:
    """The arrays handed to `track` that are not yet freed (`len`), and the most alive at once
    (`most`): for tests that data is held one piece at a time, not all together."""

    def __init__(self):
        self._ids: set[int] = set()
        self.most = 0

    def __len__(self) -> int:
        return len(self._ids)

    def track(self, array):
        """`array`, counted until it is freed."""
        self._ids.add(id(array))
        weakref.finalize(array, self._ids.discard, id(array))
        self.most = max(self.most, len(self._ids))
        return array


@pytest.fixture
def alive_arrays() -> AliveArrays:
    return AliveArrays()


@pytest.fixture
def listed_folders(monkeypatch) -> collections.Counter:
    """How often each folder (its path as text) is listed by os.listdir during the test."""
    listed, listdir = collections.Counter(), os.listdir

    def counted(path="."):
        listed[str(path)] += 1
        return listdir(path)

    monkeypatch.setattr(os, "listdir", counted)
    return listed


@pytest.fixture
def longest_pause():
    """`longest_pause(call)`: `call()` run in another thread while this one runs Python, the
    longest time this one ran none during it, as a fraction of the call's time: about 1 where the
    call holds the GIL throughout (a C++ kernel that keeps it), near 0 where it releases it. The
    least of 3 calls: a busy machine that deschedules this thread for a while makes one call's
    share large, not three calls' (a kernel that keeps the GIL makes each ~1)."""
    import threading
    import time

    def least(call) -> float:
        return min(measure(call) for _ in range(3))

    def measure(call) -> float:
        bounds, errors = [], []

        def work():
            start = time.perf_counter()
            try:
                call()
            except BaseException as err:  # raised here, in the test's thread
                errors.append(err)
            bounds.extend([start, time.perf_counter()])

        worker, ran = threading.Thread(target=work), [time.perf_counter()]
        worker.start()
        while worker.is_alive():
            now = time.perf_counter()
            if now - ran[-1] > 1e-4:  # a time every 0.1 ms at most (not ~10 MB a second)
                ran.append(now)
        worker.join()
        if errors:
            raise errors[0]
        start, end = bounds
        times = [start, *(t for t in ran if start < t < end), end]
        return max(b - a for a, b in zip(times, times[1:])) / (end - start)

    return least


@pytest.fixture
def float64_default():
    """torch's default dtype float64 for the test, as a script may set it (restored after)."""
    previous = torch.get_default_dtype()
    torch.set_default_dtype(torch.float64)
    yield
    torch.set_default_dtype(previous)
