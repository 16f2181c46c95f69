"""Commands run at once on one dataset, run or benchmark folder: each works, or one is refused as
busy (exit 75, naming what to do); none deletes or mixes into another's files.

flock locks belong to an open file, not a process: a lock taken here on another open of the same
file stands for another process's, as a second process sees it."""

from __future__ import annotations

import fcntl
import json
import multiprocessing
import os
from pathlib import Path

import pytest
from spikegs.cli import main
from spikegs.data import simulate_dataset
from spikegs.file_lock import BUSY, Busy, exclusive_lock

SMALL = dict(height=16, width=16, readouts=400, test_on_path=2, test_off_path=2, progress=False)
BUSY_DATASET = "in use by another process"
# a command that waits for a lock it should refuse fails in a minute, not at the suite's timeout
pytestmark = pytest.mark.timeout(60)


@pytest.fixture(scope="module")
def simulated(tmp_path_factory):
    """A small simulated dataset's folder (for tests that do not change it)."""
    root = tmp_path_factory.mktemp("concurrent") / "data"
    simulate_dataset("solids", root, **SMALL)
    return root


def test_the_busy_exit_status_is_the_documented_one():
    """Scripts retry on the status the README and docs/datasets.md give: sysexits.h's
    EX_TEMPFAIL, 75."""
    root = Path(__file__).parents[1]
    readme = (root / "README.md").read_text(encoding="utf-8")
    datasets = (root / "docs" / "datasets.md").read_text(encoding="utf-8")
    assert f"{BUSY} where another process trains the run" in " ".join(readme.split())
    assert f"`busy:`, exit status {BUSY}, before any work" in datasets


def test_a_dataset_being_simulated_is_not_simulated_over(tmp_path):
    """Two `spikegs simulate --out D` at once: the second deleted the first one's files as it wrote
    them ("[Errno 2] No such file or directory: 'D/spikes.dat'"), or said that D held "what an
    interrupted simulation left" and to pass --overwrite, which deleted it; both could write, a
    dataset's parts from one and its spikes from the other."""
    out = tmp_path / "data"
    out.mkdir()
    with exclusive_lock(out / ".lock", busy="held"):  # as a simulation writing `out` holds it
        for overwrite in (False, True):
            with pytest.raises(Busy, match=f"{BUSY_DATASET}.*give another --out"):
                simulate_dataset("solids", out, overwrite=overwrite, **SMALL)
    assert os.listdir(out) == [".lock"]  # nothing written
    simulate_dataset("solids", out, **SMALL)  # a folder holding the lock alone is an empty one


def test_a_simulation_under_way_is_busy_not_an_interrupted_one(tmp_path):
    """A simulation writing `out` has its spikes' temporary there: a second one said that `out`
    held "what an interrupted simulation left" and to pass --overwrite (which would delete the
    first one's files). simulate checks the lock before that check, and before any work: busy.
    (With only the lock in `out`, as above, the lock taken before writing refuses it as well, so
    that test alone passes without the check before any work.)"""
    out = tmp_path / "data"
    out.mkdir()
    partial = out / ".spikes.dat.4242.tmp"  # the first simulation's spikes, being written
    partial.write_bytes(b"\0" * 64)
    with exclusive_lock(out / ".lock", busy="held"):
        with pytest.raises(Busy, match=f"{BUSY_DATASET}.*give another --out"):
            simulate_dataset("solids", out, **SMALL)
    assert sorted(os.listdir(out)) == [".lock", partial.name]  # nothing written or deleted


def test_a_dataset_being_trained_from_is_not_overwritten(tmp_path):
    """`spikegs simulate --overwrite` deleted a dataset that a training was reading, its SIM's
    lock with it (a second process then trained that SIM beside the first)."""
    out = tmp_path / "data"
    simulate_dataset("solids", out, **SMALL)
    meta = (out / "meta.json").read_text()
    with open(out / ".lock", "a") as reader:  # a training's lock on its dataset
        fcntl.flock(reader, fcntl.LOCK_SH)
        with pytest.raises(Busy, match=f"{BUSY_DATASET} .*train, sim-train, eval or render"):
            simulate_dataset("solids", out, overwrite=True, seed=3, **SMALL)
    assert (out / "meta.json").read_text() == meta
    # once it has ended: replaced, the lock file kept (the one a process may hold as it is)
    lock = (out / ".lock").stat().st_ino
    simulate_dataset("solids", out, overwrite=True, seed=3, **SMALL)
    assert json.loads((out / "meta.json").read_text())["seed"] == 3
    assert (out / ".lock").stat().st_ino == lock


def test_commands_reading_a_dataset_refuse_while_it_is_written(simulated, tmp_path):
    """train, sim-train, eval and render read a dataset that a simulation or `spikegs poses` was
    rewriting: a mix of its old and new files, or its spikes gone as a SIM trained on them."""
    run = tmp_path / "run"
    with exclusive_lock(simulated / ".lock", busy="held"):  # as `simulate --overwrite` holds it
        for argv in (
            ["train", str(simulated), "--out", str(run), "--iterations", "2"],
            ["sim-train", str(simulated), "--steps", "1", "--out", str(tmp_path / "sim.pt")],
            ["eval", str(run), "--dataset", str(simulated)],
        ):
            assert main([*argv, "--no-progress"] if argv[0] != "eval" else argv) == BUSY, argv
    assert not run.exists() and not (tmp_path / "sim.pt").exists()


def test_commands_pointed_at_a_folder_without_a_dataset_leave_no_lock_there(tmp_path, capsys):
    """train, sim-train, eval, render and poses on a folder holding no dataset (an empty or
    mistyped one; an LLFF or NeRF layout, which no spikegs process writes) left an empty .lock
    in it; a folder being simulated (its lock held, its parts not yet written) is busy still."""
    import numpy as np

    typo, llff, run = tmp_path / "typo", tmp_path / "llff", tmp_path / "run"
    typo.mkdir()
    llff.mkdir()
    np.save(llff / "poses_bounds.npy", np.zeros((2, 17)))  # (its bounds refused)
    commands = [
        ["train", str(typo), "--out", str(run)],
        ["sim-train", str(typo)],
        ["eval", str(run), "--dataset", str(typo)],
        ["poses", str(typo)],
    ]
    for argv in (*commands, ["train", str(llff), "--out", str(run)]):
        assert main(argv) == 2, argv
    assert os.listdir(typo) == [] and os.listdir(llff) == ["poses_bounds.npy"]
    assert "no dataset found" in capsys.readouterr().err
    with exclusive_lock(typo / ".lock", busy="held"):  # as a simulation starting there holds it
        for argv in commands:
            assert main(argv) == BUSY, argv
    assert not run.exists()


def test_training_from_a_dataset_shares_it(simulated, tmp_path):
    """Trainings from one dataset run together (a shared lock), and leave it as it was."""
    from spikegs.config import load_config
    from spikegs.data import load_dataset
    from spikegs.train import Trainer

    config = load_config("tfp33", {"train": {"iterations": 2, "eval_every": 2}})
    with open(simulated / ".lock", "a") as reader:  # another training's
        fcntl.flock(reader, fcntl.LOCK_SH)
        Trainer(load_dataset(simulated), config, tmp_path / "run", progress=False).train()
    assert (tmp_path / "run" / "scene.ply").is_file()


def _hold(path, held, release):  # another process holding the lock at `path`
    with exclusive_lock(path, busy="held"):
        held.set()
        release.wait(60)


@pytest.mark.skipif(not hasattr(os, "fork"), reason="flock is POSIX")
def test_a_second_bench_into_one_folder_is_refused(tmp_path, capsys):
    """Two `spikegs bench train --out B` at once: the second deleted each run folder that the
    first was training in (its lock with it) and trained there too, one's scene.ply ending in the
    other's run; each reported success."""
    out = tmp_path / "bench"
    out.mkdir()
    fork = multiprocessing.get_context("fork")
    held, release = fork.Event(), fork.Event()
    other = fork.Process(target=_hold, args=(out / ".lock", held, release))
    other.start()
    try:
        assert held.wait(60)
        argv = ["bench", "train", "--quick", "--out", str(out), "--methods", "tfp33"]
        assert main([*argv, "--iterations", "2", "--no-progress"]) == BUSY
    finally:
        release.set()
        other.join(60)
    assert "being written by another spikegs bench" in capsys.readouterr().err
    assert os.listdir(out) == [".lock"]


@pytest.mark.skipif(not hasattr(os, "fork"), reason="flock is POSIX")
def test_a_second_scoring_of_one_run_is_refused_busy(simulated, tmp_path, capsys):
    """Two `spikegs eval RUN --dataset D` of datasets in folders of one name, at once: both chose
    eval-data.json (the name free when each looked) and one's scores were lost, though both
    said they were written. A scoring holds the run's lock: with it held (by another process
    here), a scoring is refused, busy, and writes nothing."""
    from spikegs.config import load_config
    from spikegs.data import load_dataset
    from spikegs.train import Trainer

    run = tmp_path / "run"
    config = load_config("tfp33", {"train": {"iterations": 2, "eval_every": 2}})
    Trainer(load_dataset(simulated), config, run, progress=False).train()
    fork = multiprocessing.get_context("fork")
    held, release = fork.Event(), fork.Event()
    other = fork.Process(target=_hold, args=(run / ".lock", held, release))  # the first scoring
    other.start()
    try:
        assert held.wait(60)
        assert main(["eval", str(run), "--no-progress"]) == BUSY
    finally:
        release.set()
        other.join(60)
    assert "being scored or trained by another process" in capsys.readouterr().err
    assert not (run / "eval.json").exists()
    assert main(["eval", str(run), "--no-progress"]) == 0


def test_eval_of_a_run_finishing_says_it_is_busy(tmp_path):
    """`spikegs eval RUN` between the run's scene.ply and its train.json, the last two writes of a
    training still under way, said that the run had stopped and to finish it with --resume (which
    the running training refused)."""
    from spikegs.eval_cli import run_dataset
    from spikegs.run_folder import run_lock

    run = tmp_path / "run"
    (run / "checkpoints").mkdir(parents=True)
    (run / "checkpoints" / "last.pt").write_bytes(b"")
    (run / "scene.ply").write_bytes(b"")
    with run_lock(run), pytest.raises(Busy, match="being trained by another process"):
        run_dataset(run, None)
    with pytest.raises(FileNotFoundError, match="stopped while writing its results"):
        run_dataset(run, None)  # no process holds it: killed there


def test_a_lock_file_of_another_users_locks_read_only(tmp_path, monkeypatch):
    """simulate into a folder whose .lock another user made (a shared folder, the lock readable,
    not writable) ended on "error: [Errno 13] Permission denied: D/.lock" (exit 2): flock needs
    no write access, and the lock opened read-only works as any."""
    from pathlib import Path

    out = tmp_path / "data"
    out.mkdir()
    (out / ".lock").touch()
    opened = Path.open

    def theirs(self, mode="r", *args, **kwargs):  # as for a process of another user
        if self.name == ".lock" and mode != "rb":
            raise PermissionError(13, "Permission denied", str(self))
        return opened(self, mode, *args, **kwargs)

    monkeypatch.setattr(Path, "open", theirs)
    simulate_dataset("solids", out, **SMALL)
    with open(out / ".lock") as reader:  # a training's lock on its dataset
        fcntl.flock(reader, fcntl.LOCK_SH)
        with pytest.raises(Busy, match=BUSY_DATASET):
            simulate_dataset("solids", out, overwrite=True, **SMALL)


def test_a_lock_file_that_opens_neither_way_is_named_where_a_lock_is_needed(tmp_path, monkeypatch):
    """A .lock this process can open neither to append nor to read (another user's, mode 600):
    taking the lock raises the append's error, naming the file; the check before work
    (`refuse_if_held`) and a reader's shared lock go on without it (the folder's writes, or
    none, say the rest)."""
    from spikegs.file_lock import refuse_if_held, shared_lock

    lock = tmp_path / ".lock"
    lock.touch()
    opened = Path.open

    def unreadable(self, mode="r", *args, **kwargs):
        if self.name == ".lock" and mode == "a":
            raise PermissionError(13, "Permission denied", str(self))
        if self.name == ".lock":  # (the read's own error: not the one to name)
            raise OSError(5, "Input/output error", str(self))
        return opened(self, mode, *args, **kwargs)

    monkeypatch.setattr(Path, "open", unreadable)
    with pytest.raises(PermissionError) as raised, exclusive_lock(lock, "busy"):
        pass
    assert raised.value.filename == str(lock)
    refuse_if_held(lock, "busy")
    with shared_lock(lock, "busy"):
        pass


def test_without_flock_the_locks_are_none(tmp_path, monkeypatch):
    """Where the OS has no fcntl (Windows) each lock is no lock: the block runs, no file made."""
    from spikegs import file_lock

    monkeypatch.setattr(file_lock, "fcntl", None)
    with file_lock.exclusive_lock(tmp_path / ".lock", "busy"):
        with file_lock.shared_lock(tmp_path / ".lock", "busy"):
            pass
    assert list(tmp_path.iterdir()) == []


def test_a_filesystem_without_locks_is_said_once_by_simulate(tmp_path, monkeypatch):
    """simulate's check before any work and its lock around the writes each warned "not locked"
    where the filesystem cannot lock (ENOLCK): once is enough."""
    import errno
    import warnings

    out = tmp_path / "data"
    simulate_dataset("solids", out, **SMALL)  # its .lock there, as a second simulation finds it

    def no_flock(*args):
        raise OSError(errno.ENOLCK, "No locks available")

    monkeypatch.setattr("fcntl.flock", no_flock)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        simulate_dataset("solids", out, overwrite=True, **SMALL)
    said = [str(w.message) for w in caught if "not locked" in str(w.message)]
    assert len(said) == 1, said


def test_a_training_takes_its_datasets_lock_once(simulated, tmp_path, monkeypatch, capsys):
    """`spikegs train` took the dataset's lock twice in one process, the command's and then its
    Trainer's: harmless with flock, but where flock is emulated by POSIX locks (NFS) the inner
    lock's end released the outer, and where the filesystem cannot lock it said so twice."""
    import errno
    import warnings

    def no_flock(*args):
        raise OSError(errno.ENOLCK, "No locks available")

    monkeypatch.setattr("fcntl.flock", no_flock)
    out = tmp_path / "run"
    argv = ["train", str(simulated), "--method", "tfp33", "--iterations", "2", "--out", str(out)]
    with warnings.catch_warnings():  # (said, not raised)
        warnings.simplefilter("always")
        assert main([*argv, "--no-progress"]) == 0
    assert capsys.readouterr().err.count(f"{simulated / '.lock'}: not locked") == 1


def test_a_dataset_read_in_two_blocks_stays_locked_until_the_last_ends(simulated):
    """Blocks reading one dataset in one process (a training in each of two threads) share its
    lock, held until the last ends: the first one's end does not release it under the other."""
    from contextlib import ExitStack

    from spikegs.data.dataset import reading_dataset, refuse_if_in_use

    first, second = ExitStack(), ExitStack()
    first.enter_context(reading_dataset(simulated))
    second.enter_context(reading_dataset(simulated))
    first.close()
    with pytest.raises(Busy, match=BUSY_DATASET):  # a writer's check (another open of the file)
        refuse_if_in_use(simulated)
    second.close()
    refuse_if_in_use(simulated)
