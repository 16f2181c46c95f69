"""A run folder's files (run_folder.py): another dataset's evaluations (eval-DATASET*) are a run's
own, not foreign files that block training into it; a run folder and a dataset given for each
other are named for what they are."""

import errno
import json
import re

import pytest
from spikegs.cli import main
from spikegs.data.dataset import reading_dataset
from spikegs.run_folder import (
    FolderWatch,
    check_fresh_run_dir,
    foreign_files,
    refuse_foreign_files,
    run_lock,
)
from spikegs.run_summary import read_summary, resume_command, trained_scene


def test_evaluations_of_other_datasets_are_a_runs_files(tmp_path):
    """`spikegs eval RUN --dataset OTHER` writes RUN/eval-OTHER.json and RUN/eval-OTHER/: not
    foreign (a resumed or retrained run may keep them); a user's notes.txt is."""
    run = tmp_path / "run"
    (run / "eval-other").mkdir(parents=True)
    (run / "eval-other.json").write_text("{}")
    (run / "eval-other-2.json").write_text("{}")
    (run / "config.yaml").write_text("")
    assert foreign_files(run) == []
    refuse_foreign_files(run, "")  # nothing to refuse
    (run / "notes.txt").write_text("mine")
    assert foreign_files(run) == ["notes.txt"]


def test_a_users_files_inside_a_runs_folders_are_not_a_runs(tmp_path):
    """`spikegs demo --overwrite`, which says it refuses files no spikegs run wrote, deleted a
    user's notes in eval/, checkpoints/ and an eval-notes.txt (named as another dataset's
    scores), looking at the run folder's own names alone (the demo trial)."""
    run = tmp_path / "run"
    for folder in ("checkpoints", "eval", "eval-other"):
        (run / folder).mkdir(parents=True)
    written = ["checkpoints/last.pt", "eval/on_000.png", "eval-other/off_001.png", "eval.json"]
    for name in [*written, "eval-other.json", "checkpoints/.last.pt.123.tmp"]:
        (run / name).write_text("")
    assert foreign_files(run) == []
    mine = ["checkpoints/mine.pt", "eval-notes.txt", "eval-other/notes.txt", "eval/notes.txt"]
    for name in mine:
        (run / name).write_text("mine")
    assert foreign_files(run) == mine
    with pytest.raises(FileExistsError, match=r"not a run's \(checkpoints/mine.pt, eval-notes"):
        refuse_foreign_files(run, "")


def test_a_started_run_without_a_checkpoint_may_be_trained_over(tmp_path):
    """A run stopped before its first checkpoint (config.yaml, log.jsonl, .lock, checkpoints/)
    is no finished run: a fresh one starts there."""
    run = tmp_path / "run"
    (run / "checkpoints").mkdir(parents=True)
    for name in ("config.yaml", "log.jsonl", ".lock"):
        (run / name).write_text("")
    check_fresh_run_dir(run, run / "checkpoints" / "last.pt")


def test_a_finished_runs_files_and_files_not_a_runs_are_refused_each_by_name(tmp_path):
    """A fresh run refuses a finished run's files (its checkpoint gone) naming those alone, and
    a user's notes as files that are not a run's."""
    run = tmp_path / "run"
    run.mkdir()
    for name in ("notes.txt", "scene.ply", "train.json"):
        (run / name).write_text("")
    checkpoint = run / "checkpoints" / "last.pt"
    with pytest.raises(FileExistsError, match=r"holds a finished run \(scene.ply, train.json\) "):
        check_fresh_run_dir(run, checkpoint)
    (run / "scene.ply").unlink()
    (run / "train.json").unlink()
    with pytest.raises(FileExistsError, match=r"holds files that are not a run's \(notes.txt\)"):
        check_fresh_run_dir(run, checkpoint)


def test_a_stopped_run_in_a_folder_not_writable_says_how_to_finish_it(tmp_path, monkeypatch):
    """`spikegs eval` on a stopped run in a folder this process cannot write (a colleague's, a
    read-only copy): its .lock cannot be opened to ask whether a process trains the run, which is
    then not known to be busy; the message says how to finish it, not 'Permission denied'."""
    run = tmp_path / "run"
    (run / "checkpoints").mkdir(parents=True)
    (run / "checkpoints" / "last.pt").write_bytes(b"")
    (run / ".lock").write_text("")

    def refused(path, busy):
        raise PermissionError(errno.EACCES, "Permission denied", str(path))

    monkeypatch.setattr("spikegs.run_summary.exclusive_lock", refused)
    with pytest.raises(FileNotFoundError, match="stopped before its end; finish it with spikegs"):
        trained_scene(run)


def test_a_folder_watch_tells_a_folder_made_again_at_the_path_from_the_one_it_watches(tmp_path):
    """A run's folder moved and another made at its path (a second --resume there) is not the
    folder its training locked: its own name is not its identity."""
    run = tmp_path / "run"
    run.mkdir()
    with FolderWatch(run) as watch:
        assert not watch.moved() and watch.now() in (run, None)
        run.rename(tmp_path / "new")
        run.mkdir()
        assert watch.moved() and watch.now() in (tmp_path / "new", None)


def test_the_resume_command_of_a_run_whose_dataset_moved_asks_where_it_went(tmp_path):
    """A stopped run whose dataset was moved since was told to finish with `spikegs train OLD
    --out RUN --resume`, which failed: "dataset folder not found"."""
    import torch

    run, data = tmp_path / "run", tmp_path / "data"
    (run / "checkpoints").mkdir(parents=True)
    torch.save({"dataset": str(data)}, run / "checkpoints" / "last.pt")
    assert resume_command(run) == (
        f"spikegs train DATASET --out {run} --resume (DATASET where {data} went)"
    )
    (data / "sim").mkdir(parents=True)  # a folder a process made at the old path, after the move
    assert resume_command(run).endswith(f"--resume (DATASET where {data} went)")
    (data / "meta.json").write_text("{}")
    assert resume_command(run) == f"spikegs train {data} --out {run} --resume"


def test_a_dataset_and_a_run_folder_given_for_each_other_are_named(tmp_path, capsys):
    """`spikegs eval DATASET` said "scene.ply not found: train the run first", and `spikegs train
    RUN` "no dataset found: none of meta.json, ...": each folder is named for what it is."""
    data, run = tmp_path / "data", tmp_path / "run"
    data.mkdir()
    (data / "meta.json").write_text("{}")
    run.mkdir()
    (run / "config.yaml").write_text("method: tfp33\n")
    (run / "train.json").write_text(json.dumps({"dataset": str(data)}))
    for argv in (["eval", str(data)], ["render", str(data), "--out", str(tmp_path / "o.gif")]):
        assert main(argv) == 2
        assert "data: a dataset (its meta.json), not a run folder" in capsys.readouterr().err
        with reading_dataset(data):  # a training reads it: named all the same (said busy, 75)
            assert main(argv) == 2
        assert "data: a dataset (its meta.json), not a run folder" in capsys.readouterr().err
    for argv in (["train", str(run), "--out", str(tmp_path / "new")], ["poses", str(run)]):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert "run: a run folder (its config.yaml, train.json), not a dataset" in err
        assert f"the run's dataset is {data}" in err
    # while a training holds the run's lock: named so, not "being written by another process
    # (spikegs simulate or poses); wait for it to end", then this after the wait (the eval trial)
    with run_lock(run):
        for argv in (["train", str(run), "--out", str(tmp_path / "new")], ["poses", str(run)]):
            assert main(argv) == 2
            assert "run: a run folder (its config.yaml, train.json)" in capsys.readouterr().err
    (run / "train.json").write_text('{"dataset": ')  # torn: the folder is named all the same
    assert main(["train", str(run), "--out", str(tmp_path / "new")]) == 2
    err = capsys.readouterr().err
    assert "run: a run folder (its config.yaml, train.json), not a dataset" in err
    assert "the run's dataset" not in err


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("intensity_scale", 0, "intensity_scale expected a finite number > 0, found 0"),
        ("intensity_scale", -1.5, "intensity_scale expected a finite number > 0, found -1.5"),
        ("intensity_scale", "2", 'intensity_scale expected a finite number > 0, found "2"'),
        ("camera", {"fl_x": 40, "fl_y": 0}, "camera expected fl_x and fl_y, finite numbers > 0"),
        ("camera", {"fl_x": -40, "fl_y": 40}, "camera expected fl_x and fl_y"),
        ("camera", {"fl_x": 40}, "camera expected fl_x and fl_y"),
        ("camera", {"fl_x": "40", "fl_y": 40}, "camera expected fl_x and fl_y"),
        ("camera", [40, 40], "camera expected fl_x and fl_y"),
    ],
)
def test_a_train_json_edited_by_hand_is_refused_by_field(tmp_path, field, value, message):
    """An intensity scale or focal length of 0, negative or text is named; a run from before
    both fields reads as it is."""
    (tmp_path / "train.json").write_text(json.dumps({"dataset": "data"}))
    assert read_summary(tmp_path) == {"dataset": "data"}
    (tmp_path / "train.json").write_text(json.dumps({"dataset": "data", field: value}))
    with pytest.raises(ValueError, match=re.escape(message)):
        read_summary(tmp_path)
