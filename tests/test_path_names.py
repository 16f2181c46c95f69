"""File and folder names that researchers have (a paths audit): long names, a colon, non-UTF-8
names, symbolic links to other disks or to nothing."""

from __future__ import annotations

import errno
import hashlib
import os
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from spikegs.atomic_save import (
    NAME_MAX,
    is_temporary,
    save_figure,
    short_name,
    sweep_killed_writes,
    sweep_temporaries,
    temporary_name,
    write_atomically,
    write_text_atomically,
    write_text_if_changed,
)
from spikegs.data.dataset import STAGING, is_view_name, move_in
from spikegs.evaluate import _eval_name
from spikegs.image_io import read_image, write_image
from spikegs.output_paths import check_file_output, check_folder_output
from spikegs.run_summary import last_checkpoint, trained_scene
from spikegs.shell_words import shell_path
from spikegs.video import can_encode, check_video_output, write_video

LINUX = pytest.mark.skipif(sys.platform != "linux", reason="names as bytes: Linux file systems")


def test_names_up_to_name_max_are_written(tmp_path):
    """A 246-byte video or view image failed after the work: its temporary (`.NAME.PID.tmp`)
    passed NAME_MAX, and the failed clean-up's own error named that hidden file."""
    text = tmp_path / ("é" * 127)  # 254 bytes: a character cut in two would not be UTF-8
    write_text_atomically(text, "scores")
    assert text.read_text() == "scores" and os.listdir(tmp_path) == [text.name]
    image = tmp_path / ("v" * (NAME_MAX - 4) + ".png")
    write_image(image, np.full((4, 4), 0.5, np.float32))
    assert read_image(image).shape[:2] == (4, 4)
    # a killed writer's temporary of a long name is swept as a short one's is
    stale = tmp_path / temporary_name(text, "12345")
    stale.write_text("torn")
    sweep_killed_writes(text)
    assert not stale.exists() and text.exists()


@pytest.mark.parametrize("limit", [40, 200])
def test_short_names_fit_and_stay_distinct(limit):
    names = ["é" * 150 + "a", "é" * 150 + "b", "x" * 39]
    shortened = [short_name(n, limit) for n in names]
    assert all(len(os.fsencode(s)) <= limit for s in shortened)
    assert len(set(shortened)) == 3 and shortened[2] == names[2]  # one that fits: as it is
    assert all(s.encode("utf-8") for s in shortened)  # whole characters
    long = "x" * (
        limit + 1
    )  # one byte over: its first bytes, "~" and 12 hex digits, `limit` in all
    digest = hashlib.sha1(long.encode()).hexdigest()[:12]
    assert short_name(long, limit) == "x" * (limit - 13) + "~" + digest


def test_a_failed_clean_up_keeps_the_writes_error(tmp_path, monkeypatch):
    """The temporary's removal failing too (its name too long, a folder gone) replaced the
    write's error, named by the file asked for, with its own, naming the hidden temporary."""

    def refused(self, missing_ok=False):
        raise OSError(errno.ENAMETOOLONG, "File name too long", str(self))

    def full(tmp):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(Path, "unlink", refused)
    with pytest.raises(OSError, match="No space left on device: '.*scores.json'") as err:
        write_atomically(tmp_path / "scores.json", full)
    assert err.value.errno == errno.ENOSPC


def test_another_datasets_scores_fit_a_file_name(tmp_path):
    """`spikegs eval RUN --dataset D`, D's name 250 bytes: eval-D.json passed NAME_MAX and
    failed after the scoring."""
    dataset = SimpleNamespace(root=tmp_path / ("d" * 250))
    train = {"dataset": str(tmp_path / "own"), "intensity_scale": 1.0}  # its train.json
    name = _eval_name(tmp_path / "run", train, dataset)
    assert name.startswith("eval-ddd") and len(os.fsencode(f"{name}-99.json")) <= NAME_MAX


def test_view_names_fit_their_image():
    assert is_view_name("a" * (NAME_MAX - 4)) and not is_view_name("a" * (NAME_MAX - 3))


@pytest.mark.skipif(not can_encode("mpeg4"), reason="PyAV without an MP4 encoder")
def test_an_mp4_named_with_a_colon(tmp_path, monkeypatch):
    """FFmpeg took the relative '2024-05-01T10:30.mp4' for the protocol '2024-05-01T10' (a
    traceback, after the rendering)."""
    monkeypatch.chdir(tmp_path)
    write_video(Path("2024-05-01T10:30.mp4"), np.zeros((2, 16, 16, 3), np.uint8), 10)
    assert (tmp_path / "2024-05-01T10:30.mp4").stat().st_size > 0


def test_a_video_named_by_its_suffix_alone_is_refused_as_such(tmp_path):
    with pytest.raises(ValueError, match="'.mp4' names no file before its suffix"):
        check_video_output(tmp_path / ".mp4", 10)


@LINUX
def test_a_non_utf8_folder_is_refused_by_name(tmp_path, capfd):
    """OpenImageIO takes UTF-8 names only: a Latin-1 folder (café) was a TypeError traceback
    from its binding, after a simulation had written its spikes."""
    from spikegs.cli import main

    latin = tmp_path / os.fsdecode(b"caf\xe9")
    with pytest.raises(ValueError, match="not a UTF-8 name"):
        check_folder_output(latin, images=True)
    check_folder_output(latin)  # a folder of no OpenImageIO file (a SIM's)
    for command in (["train", "data", "--method", "tfp33"], ["bench", "stiff", "--quick"]):
        # a run's eval images go into RUN/eval: eval refused the run that train had made
        assert main([*command, "--out", str(latin)]) == 2
        assert "not a UTF-8 name" in capfd.readouterr().err and not latin.exists()
    latin.mkdir()
    with pytest.raises(ValueError, match="not a UTF-8 file name"):
        write_image(latin / "v.png", np.zeros((2, 2), np.float32))
    with pytest.raises(ValueError, match="not a UTF-8 file name"):
        read_image(latin / "v.png")


@LINUX
def test_a_utf8_folder_read_by_the_c_locale_takes_images(tmp_path):
    """Under the C locale without UTF-8 mode (LC_ALL=C PYTHONUTF8=0) Python reads a UTF-8 name's
    bytes (né) as ASCII's surrogate escapes, and its image files were refused as 'not a UTF-8
    file name': OpenImageIO is given the name's bytes as UTF-8."""
    folder = tmp_path / "né"
    folder.mkdir()
    as_c_locale = Path(os.fsencode(folder).decode("ascii", "surrogateescape"))
    check_folder_output(as_c_locale, images=True)
    write_image(as_c_locale / "v.png", np.ones((2, 2), np.float32))
    assert read_image(folder / "v.png").shape == (2, 2, 1)
    assert read_image(as_c_locale / "v.png").shape == (2, 2, 1)


def test_a_link_to_a_missing_folder_is_named(tmp_path):
    """An output that is a symbolic link to a scratch disk's folder not made yet failed with
    '[Errno 17] File exists', after rendering for a video."""
    link = tmp_path / "scratch"
    link.symlink_to(tmp_path / "not_yet")
    for check, path in ((check_folder_output, link), (check_file_output, link / "o.mp4")):
        with pytest.raises(ValueError, match="scratch is a symbolic link to .*not_yet, which"):
            check(path)


def test_an_output_on_a_read_only_disk_is_refused_by_name(tmp_path, monkeypatch, capsys):
    """A read-only mount (where root's os.access says yes) or a folder of another user's:
    `spikegs sim-train --out FILE` and `spikegs simulate --out FOLDER` stop before any work, the
    message naming the path asked for, not a traceback once the work is done."""
    from spikegs.cli import main

    monkeypatch.setattr("spikegs.output_paths.writable_folder", lambda folder: False)
    weights, data = tmp_path / "w.pt", tmp_path / "data"
    assert main(["sim-train", str(tmp_path / "no_dataset"), "--out", str(weights)]) == 2
    said = capsys.readouterr().err
    assert f"spikegs sim-train: error: --out {weights}: its folder is not writable" in said
    assert main(["simulate", "--out", str(data)]) == 2
    assert f"spikegs simulate: error: --out {data}: not writable" in capsys.readouterr().err
    assert os.listdir(tmp_path) == []


def test_a_dataset_replaced_through_a_link(tmp_path):
    """`spikegs simulate --out LINK --overwrite`, LINK a dataset on another disk: rmtree refused
    the link ('Cannot call rmtree on a symbolic link'); the target is emptied, the link kept."""
    target = tmp_path / "disk" / "data"
    (target / "test").mkdir(parents=True)
    (target / "meta.json").write_text("{}")
    (target / STAGING).mkdir()
    (target / STAGING / "meta.json").write_text('{"new": 1}')
    link = tmp_path / "data"
    link.symlink_to(target)
    move_in(link)
    assert link.is_symlink() and target.is_dir() and os.listdir(target) == ["meta.json"]
    assert (target / "meta.json").read_text() == '{"new": 1}'


def test_a_name_of_exactly_the_limit_is_kept_and_temporaries_are_ours_only():
    """A name of `limit` bytes fits as it is (shortened, its temporary's and sweep's name would
    differ from it needlessly); `.NAME.WRITER.tmp` is ours, a user's `notes.v2.tmp` not (its
    leading dot is part of the pattern)."""
    assert short_name("x" * 40, 40) == "x" * 40
    assert is_temporary(".notes.json.123.tmp") and not is_temporary("notes.v2.tmp")


def test_a_temporarys_writer_is_alive_unless_its_process_is_gone(tmp_path, monkeypatch):
    """Writer 0 is no process (os.kill(0, 0) signals our own group: its temporary was never
    swept); another user's live process (PermissionError) is alive, and its temporary stays
    (the error escaped the sweep)."""
    zero = tmp_path / ".scores.json.0.tmp"
    zero.write_text("torn")
    sweep_temporaries(tmp_path)
    assert not zero.exists()

    def not_ours(pid, signal):
        raise PermissionError(1, "Operation not permitted")

    monkeypatch.setattr(os, "kill", not_ours)
    theirs = tmp_path / ".scores.json.4242.tmp"
    theirs.write_text("being written")
    sweep_temporaries(tmp_path)
    assert theirs.exists()


def test_a_live_writers_temporary_stays_and_its_writer_is_only_asked(tmp_path):
    """A live process's temporary stays, the process untouched (signal 0 asks whether it
    exists, sends nothing); once it is gone, its temporary is swept."""
    writer = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        tmp = tmp_path / f".scores.json.{writer.pid}.tmp"
        tmp.write_text("being written")
        sweep_temporaries(tmp_path)
        assert tmp.exists()
        with pytest.raises(subprocess.TimeoutExpired):  # alive: a signal would end it by then
            writer.wait(timeout=0.5)
    finally:
        writer.kill()
        writer.wait()
    sweep_temporaries(tmp_path)
    assert not tmp.exists()


def test_text_is_written_only_where_the_file_holds_other_text(tmp_path):
    """A finished run's file holding the text already is left as it is (the same inode and
    time), one holding other text replaced."""
    path = tmp_path / "train.json"
    write_text_if_changed(path, "é")
    before = path.stat()
    write_text_if_changed(path, "é")
    after = path.stat()
    assert (after.st_ino, after.st_mtime_ns) == (before.st_ino, before.st_mtime_ns)
    write_text_if_changed(path, "e")
    assert path.read_text(encoding="utf-8") == "e"


def test_an_error_naming_another_file_keeps_its_name(tmp_path):
    """A write's error that names a file other than its temporary (an input it read) is raised
    as it is, not renamed to the file asked for."""
    other = str(tmp_path / "frames" / "0001.png")

    def reads(tmp):
        raise FileNotFoundError(2, "No such file or directory", other)

    with pytest.raises(FileNotFoundError) as raised:
        write_atomically(tmp_path / "video.json", reads)
    assert raised.value.filename == other


def test_a_figure_without_a_suffix_is_a_png(tmp_path):
    """save_figure writes the format of its suffix, PNG where there is none (matplotlib refused
    the empty format), at 120 dpi."""
    import matplotlib.pyplot as plt

    save_figure(plt.figure(figsize=(2, 1)), tmp_path / "curve")
    assert (tmp_path / "curve").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert read_image(tmp_path / "curve").shape[:2] == (120, 240)


def test_a_command_suggested_for_a_path_starting_with_a_dash_reads_it_as_a_path(
    tmp_path, monkeypatch
):
    """A run stopped before its end in ./-run was told 'finish it with spikegs train DATASET
    --out -run --resume', which argparse reads as an option without its value (pathlib drops
    the ./ typed): a relative path that starts with "-" is suggested with ./ before it."""
    monkeypatch.chdir(tmp_path)
    run = Path("./-run")
    last_checkpoint(run).parent.mkdir(parents=True)
    last_checkpoint(run).touch()
    with pytest.raises(FileNotFoundError, match=r"--out \./-run --resume"):
        trained_scene(run)
    assert (shell_path("-a b"), shell_path("/d/-a"), shell_path("a")) == ("'./-a b'", "/d/-a", "a")
