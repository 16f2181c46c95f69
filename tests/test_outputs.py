"""What a researcher gets out of a run: times, evaluation files and images (an output audit)."""

from __future__ import annotations

import argparse
import errno
import functools
import io
import os
import re
import shutil
import signal
import subprocess
import sys
import warnings
from pathlib import Path

import pytest
import spikegs
from spikegs.cli import console, main
from spikegs.config import load_config
from spikegs.data import load_dataset, simulate_dataset
from spikegs.evaluate import evaluate_run
from spikegs.interrupt import HANGUP, progress_lost, raise_terminated, say
from spikegs.train import Trainer
from tqdm import tqdm

NO_HANGUP = pytest.mark.skipif(HANGUP is None, reason="no SIGHUP on this OS")

FAST = {
    "train": {"iterations": 2, "init_gaussians": 800, "eval_every": 50, "checkpoint_every": 50},
    "densify": {"start": 40, "stop": 160, "every": 40, "opacity_reset_every": 0},
}
TINY = dict(height=32, width=32, readouts=600, test_on_path=2, test_off_path=2, progress=False)


def test_a_run_on_a_cached_sim_counts_sims_training_time(tmp_path, capsys):
    """A second SIM method on a dataset loads SIM from DATASET/sim: its train.json said
    sim_seconds 0 and its curve.png drew it from 0 s as a method without SIM, where `bench
    train` counts the cached SIM's recorded time. It says which SIM it loaded (it said
    nothing)."""
    data = simulate_dataset("solids", tmp_path / "data", **TINY)
    config = load_config("spikegs", {**FAST, "sim": {"iterations": 3, "crop": 16, "batch": 1}})
    first = Trainer(data, config, tmp_path / "a", progress=False).train()
    assert "SIM: loaded" not in capsys.readouterr().err
    second = Trainer(data, config, tmp_path / "b", progress=False).train()
    assert first["sim_seconds"] > 0
    assert second["sim_seconds"] == first["sim_seconds"]
    (cached,) = (tmp_path / "data" / "sim").glob("*.pt")
    said = f"SIM: loaded {cached} (trained in {first['sim_seconds']:.0f} s)"
    assert said in capsys.readouterr().err


def test_eval_images_are_those_of_the_views_scored(tmp_path):
    """Scored again after its dataset was simulated again with fewer test views, eval-DATA/ kept
    the side-by-sides of the views no longer there next to the new ones."""
    data = simulate_dataset("solids", tmp_path / "data", **TINY)
    Trainer(data, load_config("tfp33", FAST), tmp_path / "run", progress=False).train()
    other = simulate_dataset("solids", tmp_path / "other" / "data", **TINY)
    evaluate_run(tmp_path / "run", other)
    fewer = {**TINY, "test_on_path": 1, "test_off_path": 1, "seed": 1}
    other = simulate_dataset("solids", tmp_path / "other" / "data", **fewer, overwrite=True)
    with pytest.warns(UserWarning, match=r"eval-data.json scored 4 test views; .* holds 2 now"):
        result = evaluate_run(tmp_path / "run", other)
    folder = tmp_path / "run" / "eval-data"
    assert sorted(p.stem for p in folder.glob("*.png")) == sorted(result["views"])


def test_eval_of_its_moved_dataset_writes_eval_json_where_another_took_its_place(tmp_path):
    """The run's dataset moved and another simulated into its old folder: scoring the moved one,
    the run's own data, wrote eval-moved.json, as if it were another dataset."""
    data = simulate_dataset("solids", tmp_path / "data", **TINY)
    Trainer(data, load_config("tfp33", FAST), tmp_path / "run", progress=False).train()
    moved = shutil.move(tmp_path / "data", tmp_path / "moved")
    simulate_dataset("solids", tmp_path / "data", **{**TINY, "seed": 1})
    result = evaluate_run(tmp_path / "run", load_dataset(moved), write_images=False)
    assert result["file"] == str((tmp_path / "run" / "eval.json").resolve())


def test_eval_json_names_where_it_lies_for_a_run_named_relative(tmp_path, monkeypatch):
    """`spikegs eval run` wrote "file": "run/eval.json" into eval.json, a path that means
    nothing read from another folder (its "dataset" was already absolute)."""
    data = simulate_dataset("solids", tmp_path / "data", **TINY)
    Trainer(data, load_config("tfp33", FAST), tmp_path / "run", progress=False).train()
    monkeypatch.chdir(tmp_path)
    result = evaluate_run("run", data, write_images=False)
    assert result["file"] == str(tmp_path.resolve() / "run" / "eval.json")


class _Stderr:
    """A stderr whose writes fail with `errno`."""

    def __init__(self, errno_: int):
        self.errno = errno_

    def write(self, text):
        raise OSError(self.errno, os.strerror(self.errno))

    def flush(self):
        pass


def test_saying_to_a_gone_or_full_stderr_returns_its_error_and_to_a_broken_one_raises(
    monkeypatch,
):
    """say(): a stderr whose reader left (EPIPE), whose terminal closed (EIO) or whose file's
    disk or quota is full (a batch log: it raised, and the command ended with exit 1 and no
    word) is gone, its error returned for the caller to stop quietly with; any other failure is
    not a gone output and is raised, not taken for one."""
    for gone in (errno.EPIPE, errno.EIO, errno.ENOSPC, errno.EDQUOT):
        monkeypatch.setattr(sys, "stderr", _Stderr(gone))
        assert say("stopped").errno == gone
    monkeypatch.setattr(sys, "stderr", _Stderr(errno.EBADF))
    with pytest.raises(OSError, match="Bad file descriptor"):
        say("stopped")
    monkeypatch.undo()
    assert say("said") is None


def test_a_second_ctrl_c_while_exiting_prints_no_traceback(monkeypatch, console_signals):
    """After 'interrupted', a second Ctrl-C (pressed twice, as people do) landed in the
    interpreter's exit and printed 'Exception ignored in atexit callback ... KeyboardInterrupt':
    the `spikegs` command ignores SIGINT once interrupted, until it has exited."""

    def interrupted(args):
        raise KeyboardInterrupt

    monkeypatch.setattr("spikegs.eval_cli.run", interrupted)
    monkeypatch.setattr(sys, "argv", ["spikegs", "eval", "RUN"])
    with pytest.raises(SystemExit) as exit:
        console()
    assert exit.value.code == 130
    assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
    signal.signal(signal.SIGINT, console_signals[signal.SIGINT])
    assert main(["eval", "RUN"]) == 130  # main, which tests call, leaves SIGINT alone
    assert signal.getsignal(signal.SIGINT) is console_signals[signal.SIGINT]


def test_a_finished_command_ignores_a_late_signal(monkeypatch, console_signals):
    """A signal landing in the interpreter's exit after a command finished (about a second,
    torch's teardown) killed it, its status 0 replaced (-2, -15, -1): once `main` returns, the
    `spikegs` command ignores SIGINT, SIGTERM and SIGHUP, whatever the status."""
    monkeypatch.setattr("spikegs.eval_cli.run", lambda args: 0)
    monkeypatch.setattr(sys, "argv", ["spikegs", "eval", "RUN"])
    with pytest.raises(SystemExit) as exit:
        console()
    assert exit.value.code == 0
    assert all(signal.getsignal(s) is signal.SIG_IGN for s in console_signals)


@pytest.mark.parametrize(
    "signum, status, said",
    [(signal.SIGTERM, 143, "terminated"), pytest.param(HANGUP, 129, "hung up", marks=NO_HANGUP)],
)
def test_sigterm_stops_a_command_as_ctrl_c_does(
    monkeypatch, capsys, console_signals, signum, status, said
):
    """SIGTERM (a batch scheduler's time limit, `timeout`, `docker stop`) killed any command at
    once, its clean-up (temporaries, the demo's time) undone: the `spikegs` command raises it as
    Terminated, a KeyboardInterrupt, says 'terminated', exits with 143 and ignores further
    signals while exiting. A SIGTERM ignored by the parent (`trap '' TERM`) stays ignored.
    SIGHUP (a closed terminal) likewise: 'hung up', 129; ignored under nohup."""
    handlers = []

    def terminated(args):
        handlers.append(signal.getsignal(signum))
        if handlers[-1] is raise_terminated:  # (else the test would end pytest)
            os.kill(os.getpid(), signum)
        return 0

    monkeypatch.setattr("spikegs.eval_cli.run", terminated)
    monkeypatch.setattr(sys, "argv", ["spikegs", "eval", "RUN"])
    with pytest.raises(SystemExit) as exit:
        console()
    assert exit.value.code == status and handlers == [raise_terminated]
    assert capsys.readouterr().err == f"{said}\n"
    assert all(signal.getsignal(s) is signal.SIG_IGN for s in console_signals)
    signal.signal(signum, signal.SIG_IGN)
    with pytest.raises(SystemExit) as exit:
        console()
    assert exit.value.code == 0 and handlers[-1] is signal.SIG_IGN


@NO_HANGUP
def test_a_stop_said_to_a_closed_terminal_still_stops(monkeypatch, console_signals):
    """Saying 'hung up' to the terminal whose closing sent SIGHUP raises EIO: the command still
    exits as stopped (129), with no traceback of the write."""

    class ClosedTerminal(io.StringIO):
        def write(self, text):
            raise OSError(errno.EIO, "Input/output error")

    def hung_up(args):
        os.kill(os.getpid(), HANGUP)

    monkeypatch.setattr("spikegs.eval_cli.run", hung_up)
    monkeypatch.setattr(sys, "argv", ["spikegs", "eval", "RUN"])
    monkeypatch.setattr(sys, "stderr", ClosedTerminal())
    with pytest.raises(SystemExit) as exit:
        console()
    assert exit.value.code == 129


@pytest.mark.parametrize(
    "stderr, status",
    [
        (None, 2),
        (OSError(errno.EIO, "Input/output error"), 129),
        (BrokenPipeError(errno.EPIPE, "Broken pipe"), 141),
        (OSError(errno.ENOSPC, "No space left on device"), 2),  # (exit 1, a traceback unsaid)
    ],
)
def test_an_error_it_cannot_say_ends_the_command_quietly(monkeypatch, gone_stderr, stderr, status):
    """A command whose terminal closed under it without a SIGHUP (a job left running by a shell
    that exited) failed writing there (EIO), then again saying so: a traceback, exit 1. An
    error it cannot say ends it quietly with 129, as SIGHUP would (141 where stderr's reader
    left; to a full disk its own, 2); one it can, with 2."""

    def run(args):
        raise OSError(errno.EIO, "Input/output error")

    monkeypatch.setattr("spikegs.eval_cli.run", run)
    gone_stderr(stderr).gone = stderr is not None
    assert main(["eval", "RUN"]) == status


def test_a_warning_made_an_error_is_said_as_one(monkeypatch, capsys):
    """Under PYTHONWARNINGS=error a command's warning (simulate's dim light, before any file
    was written) ended in a traceback: it is said as the command's error, exit 2."""

    def run(args):
        warnings.warn("the light is dim", stacklevel=1)

    monkeypatch.setattr("spikegs.eval_cli.run", run)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert main(["eval", "RUN"]) == 2
    assert capsys.readouterr().err == (
        "spikegs eval: error: the light is dim (a warning, which PYTHONWARNINGS or -W makes an "
        "error)\n"
    )


@pytest.mark.skipif(sys.platform != "linux", reason="a deleted working folder: Linux's")
def test_a_deleted_working_folder_is_named(tmp_path):
    """In a working folder deleted under the shell (`mkdir x; cd x; rmdir ../x`) every command
    ended at torch's import with 'Intel oneMKL FATAL ERROR: Cannot load libtorch_cpu.so', a
    broken install's message (oneMKL asks for the folder as it loads)."""
    gone = tmp_path / "x"
    gone.mkdir()
    done = subprocess.run(
        [sys.executable, "-c", "import spikegs"],
        cwd=gone,
        preexec_fn=gone.rmdir,  # (in the child, once in it)
        capture_output=True,
        text=True,
    )
    assert done.returncode == 1
    assert "FileNotFoundError: the working folder is gone" in done.stderr, done.stderr


def test_a_ctrl_c_before_the_command_runs_prints_no_traceback(monkeypatch, capsys, console_signals):
    """Ctrl-C in the first seconds, while Python imported torch for the command, printed a
    30-60-line traceback ending in KeyboardInterrupt."""

    def importing(*args):
        raise KeyboardInterrupt

    monkeypatch.setattr("spikegs.cli.build_parser", importing)
    monkeypatch.setattr(sys, "argv", ["spikegs", "train", "DATA", "--out", "RUN"])
    with pytest.raises(SystemExit) as exit:
        console()
    assert exit.value.code == 130 and capsys.readouterr().err == "interrupted\n"


_STOP_AT_TORCH = (  # sitecustomize: a Ctrl-C as the package imports torch
    "import sys\n"
    "class StopAtTorch:\n"
    "    def find_spec(self, name, path=None, target=None):\n"
    "        if name == 'torch':\n"
    "            raise KeyboardInterrupt\n"
    "sys.meta_path.insert(0, StopAtTorch())\n"
)


def _stopped_at_torch(tmp_path, *entry) -> subprocess.CompletedProcess:
    """`python ENTRY...`, a Ctrl-C landing as the package imports torch."""
    (tmp_path / "sitecustomize.py").write_text(_STOP_AT_TORCH)
    path = os.pathsep.join([str(tmp_path), *sys.path])
    env = {**os.environ, "PYTHONPATH": path}
    return subprocess.run([sys.executable, *entry], env=env, capture_output=True, text=True)


@pytest.mark.parametrize("entry", ["console script", "-m"])
def test_a_ctrl_c_while_the_package_imports_torch_says_interrupted(tmp_path, entry):
    """Ctrl-C in a command's first ~2 s, while the package imported torch (before `console` could
    set any handler: the console script imports the package first), printed Python's
    traceback through torch's import, a third time reported."""
    script = tmp_path / "bin" / "spikegs"  # as pip writes it
    script.parent.mkdir()
    script.write_text("from spikegs.cli import console\nconsole()\n")
    command = [str(script)] if entry == "console script" else ["-m", "spikegs"]
    done = _stopped_at_torch(tmp_path, *command, "--version")
    assert (done.returncode, done.stderr) == (-signal.SIGINT, "interrupted\n")


@pytest.mark.parametrize("options", [[], ["-m", "spikegs"]])
def test_a_script_that_imports_the_package_keeps_its_own_ctrl_c(tmp_path, options):
    """A script or REPL importing the package (not the command) keeps Python's hook: one that
    caught the Ctrl-C landing in that import printed 'interrupted' alone for its own later one,
    its traceback gone (the review); a script's own option `-m spikegs` (a method's name) is
    not the command (the second review)."""
    script = (
        "import sys\n"
        "try:\n"
        "    import spikegs\n"
        "except KeyboardInterrupt:\n"
        "    print(sys.excepthook is sys.__excepthook__)\n"
        "raise KeyboardInterrupt\n"
    )
    done = _stopped_at_torch(tmp_path, "-c", script, *options)
    assert done.stdout == "True\n" and done.stderr.startswith("Traceback"), done.stderr
    assert done.returncode == -signal.SIGINT


def test_the_import_hook_passes_other_errors_on_and_is_gone_once_loaded():
    """The package's import puts back the hook it replaced; one left by a Ctrl-C passes other
    errors to the hook it replaced."""
    from spikegs.interrupt import ImportInterrupted

    assert not isinstance(sys.excepthook, ImportInterrupted)
    before, seen = sys.excepthook, []
    sys.excepthook = lambda *error: seen.append(error[0])
    try:
        with pytest.raises(KeyboardInterrupt), ImportInterrupted(armed=True):
            raise KeyboardInterrupt
        hook = sys.excepthook
        assert isinstance(hook, ImportInterrupted)  # left for the top level to call
        hook(ValueError, ValueError("bad"), None)
        assert seen == [ValueError] and sys.excepthook is not hook
    finally:
        sys.excepthook = before


def test_a_ctrl_c_in_code_run_from_a_string_exits_130_under_python_m(tmp_path):
    """A Ctrl-C landing in code Python runs from a string (a dataclass's generated __init__, a
    namedtuple's __new__, which modules imported mid-command define) marks it unhandled for the
    interpreter, though the command handles it: `python -m spikegs train` said 'interrupted',
    then killed itself with SIGINT (-2 to its parent, where 130 was due; 3 of 80 Ctrl-Cs in the
    half second after 'SIM: loaded')."""
    (tmp_path / "stopped_in_exec.py").write_text(
        "import spikegs.cli as cli\n"
        "cli.main = lambda: exec('raise KeyboardInterrupt')\n"
        "cli.console()\n"
    )
    command = [sys.executable, "-m", "stopped_in_exec"]
    done = subprocess.run(command, cwd=tmp_path, capture_output=True, text=True)
    assert (done.returncode, done.stderr) == (130, "interrupted\n")


@pytest.mark.parametrize("errors", ["strict", "surrogateescape"])
def test_characters_the_output_codec_lacks_print_escaped(monkeypatch, console_signals, errors):
    """`spikegs simulate --help` through an ASCII or Latin-1 stdout (a legacy locale, a
    Windows code page, PYTHONIOENCODING; the C locale without UTF-8 mode, PYTHONUTF8=0, whose
    ASCII stdout's errors are surrogateescape) raised UnicodeEncodeError at its "µs"; messages
    with θ or — likewise, after the work: the command prints them escaped."""
    out = io.TextIOWrapper(io.BytesIO(), encoding="ascii", errors=errors)
    monkeypatch.setattr(sys, "stdout", out)
    monkeypatch.setattr(sys, "argv", ["spikegs", "simulate", "--help"])
    with pytest.raises(SystemExit) as exit:
        console()
    out.flush()
    assert exit.value.code == 0 and b"readouts (25 \\xb5s each)" in out.buffer.getvalue()


def test_undecodable_bytes_of_a_name_print_as_they_are(monkeypatch, console_signals):
    """Under the C locale without UTF-8 mode a folder's Latin-1 name (b"caf\\xe9") prints
    its own bytes, as Python's surrogateescape stdout does, beside an escaped µ."""
    out = io.TextIOWrapper(io.BytesIO(), encoding="ascii", errors="surrogateescape")
    monkeypatch.setattr(sys, "stdout", out)
    monkeypatch.setattr("spikegs.cli.main", lambda: print(os.fsdecode(b"caf\xe9"), "25 µs") or 0)
    with pytest.raises(SystemExit):
        console()
    out.flush()
    assert out.buffer.getvalue() == b"caf\xe9 25 \\xb5s\n"


def test_a_reader_that_leaves_ends_the_command_quietly(tmp_path):
    """`spikegs train ... --resume | head -1` of a finished run exited 2 with "error: [Errno 32]
    Broken pipe" (the demo's besides: "once that is mended, ... --resume continues"): a gone
    reader ends the command as SIGPIPE ends a Unix tool, quietly, exit status 141."""
    script = (
        "import sys, spikegs.cli as cli\n"
        "def run(args):\n"
        "    raise BrokenPipeError(32, 'Broken pipe')\n"
        "cli.main = lambda: cli._run(cli.argparse.Namespace(command='eval', _run=run))\n"
        "cli.console()\n"
    )
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    assert (done.returncode, done.stdout, done.stderr) == (141, "", "")


def test_stdout_is_named_in_its_full_disk_errors_alone_and_restored(capsys):
    """_NamedStdout names stdout in a full disk's error of its own, not another file's error nor
    another kind; and a command leaves sys.stdout as it found it, returned or raised."""
    from spikegs import cli

    class Failing:
        def __init__(self, err):
            self.err = err

        def write(self, text):
            raise self.err

        def flush(self):
            raise self.err

    for err, named in (
        (OSError(errno.ENOSPC, "No space left on device"), True),
        (OSError(errno.ENOSPC, "No space left on device", "other.json"), False),
        (OSError(errno.EPIPE, "Broken pipe"), False),
    ):
        stdout = cli._NamedStdout(Failing(err))
        for call in (functools.partial(stdout.write, "x"), stdout.flush):
            with pytest.raises(OSError) as raised:
                call()
            assert raised.value.filename == (cli.STDOUT if named else err.filename), err
            assert raised.value.errno == err.errno
    before = sys.stdout
    for run in (lambda args: None, lambda args: int("x")):  # (a ValueError: said, status 2)
        cli._run(argparse.Namespace(command="eval", _run=run))
        assert sys.stdout is before


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="no /dev/full (Linux's)")
def test_results_printed_into_a_full_disk_are_said_as_stdouts(tmp_path):
    """eval's, render's, sim-train's and the demo's results printed into `> /dev/full` (more than
    stdout's buffer: the print fails inside the command) were said as a bare "[Errno 28] No space
    left on device", read as their files failing, which are written; a file's error, stdout
    fine, is said as it is."""
    script = (
        "import argparse, errno, os, sys\n"
        "import spikegs.cli as cli\n"
        "def lost(args):\n"
        "    if sys.argv[1] == 'file':\n"
        "        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))\n"
        "    print('psnr 30.1 ' * 10**4)\n"
        "sys.exit(cli._run(argparse.Namespace(command='eval', _run=lost)))\n"
    )
    with open("/dev/full", "w") as disk:
        done = subprocess.run(
            [sys.executable, "-c", script, "stdout"], stdout=disk, stderr=subprocess.PIPE
        )
    assert done.returncode == 2
    said = "spikegs eval: error: stdout: No space left on device: what the command printed is lost"
    assert done.stderr.decode().splitlines() == [said]
    done = subprocess.run([sys.executable, "-c", script, "file"], capture_output=True)
    assert done.returncode == 2
    assert done.stderr.decode() == "spikegs eval: error: [Errno 28] No space left on device\n"


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="no /dev/full (Linux's)")
@pytest.mark.parametrize(
    "full, status, said",
    [
        (
            "stdout",
            2,
            "spikegs: error: stdout: No space left on device: what the command printed is lost\n",
        ),
        ("stderr", 0, None),  # (its results printed whole)
        ("both", 2, None),
        ("reader gone", 141, ""),  # (README's status for a reader that left)
    ],
)
def test_results_that_cannot_be_printed_are_no_success(tmp_path, full, status, said):
    """A command whose results could not be printed (stdout's file on a full disk, its reader
    gone before the exit's flush) exited 120 with Python's 'Exception ignored ... No space left
    on device' after a success: 2, said where stderr can say it (141 where the reader left); a
    full stderr alone loses no result."""
    script = (
        "import spikegs.cli as cli\n"
        "cli.main = lambda: print('psnr 30.1') or 0\n"  # (held: stdout is a file or a pipe)
        "cli.console()\n"
    )
    held = {k: v for k, v in os.environ.items() if k != "PYTHONUNBUFFERED"}
    read, write = os.pipe()
    if full == "reader gone":
        os.close(read)
    with open("/dev/full", "w") as disk:
        stdout = disk if full in ("stdout", "both") else write
        stderr = disk if full in ("stderr", "both") else subprocess.PIPE
        command = [sys.executable, "-c", script]
        done = subprocess.run(command, env=held, stdout=stdout, stderr=stderr)
    os.close(write)
    if full != "reader gone":
        printed = os.read(read, 100)
        os.close(read)
        assert printed == (b"psnr 30.1\n" if full == "stderr" else b"")
    assert done.returncode == status
    if said is not None:
        assert done.stderr.decode() == said


def test_an_error_to_a_reader_that_left_exits_141_with_output_pending():
    """An error it could not say, stderr's reader gone, returned 141, but what stdout still held
    for the same gone reader failed at exit, which then exited 120."""
    script = (
        "import spikegs.cli as cli\n"
        "print('pending')\n"  # (held: stdout is a pipe)
        "def run(args):\n"
        "    raise ValueError('bad input')\n"
        "cli.main = lambda: cli._run(cli.argparse.Namespace(command='eval', _run=run))\n"
        "cli.console()\n"
    )
    read, write = os.pipe()
    os.close(read)  # the reader left
    held = {k: v for k, v in os.environ.items() if k != "PYTHONUNBUFFERED"}
    try:
        done = subprocess.run([sys.executable, "-c", script], stdout=write, stderr=write, env=held)
    finally:
        os.close(write)
    assert done.returncode == 141


@NO_HANGUP
def test_a_hung_up_command_keeps_the_lines_its_log_file_holds(tmp_path, console_signals):
    """Stopped by SIGHUP, a command sent stdout and stderr to /dev/null before exiting (for a
    terminal gone, whose flush would fail): the last lines still held for a log file that
    works were lost, and a test runner's captured output with them."""
    script = (
        "import os, signal, spikegs.cli as cli\n"
        "print('last line')\n"  # (held: stdout is a file)
        "def run(args):\n"
        "    os.kill(os.getpid(), signal.SIGHUP)\n"
        "cli.main = lambda: cli._run(cli.argparse.Namespace(command='eval', _run=run))\n"
        "cli.console()\n"
    )
    held = {k: v for k, v in os.environ.items() if k != "PYTHONUNBUFFERED"}
    with open(tmp_path / "log", "w") as log:
        done = subprocess.run([sys.executable, "-c", script], stdout=log, stderr=log, env=held)
    assert done.returncode == 129
    assert sorted((tmp_path / "log").read_text().splitlines()) == ["hung up", "last line"]


@pytest.mark.parametrize("closed", [None, "closed"])
def test_a_closed_stdout_does_not_fail_a_command_whose_reader_left(
    monkeypatch, console_signals, closed
):
    """Ending on a reader gone, the command flushes its outputs to find those that cannot be:
    stdout None (`spikegs ... >&-`: Python's for a closed descriptor) or closed by a script
    raised there (exit's own flush passes them by)."""

    def reader_left(args):
        if closed:
            sys.stdout.close()
        raise BrokenPipeError(errno.EPIPE, "Broken pipe")

    monkeypatch.setattr("spikegs.eval_cli.run", reader_left)
    monkeypatch.setattr(sys, "argv", ["spikegs", "eval", "RUN"])
    monkeypatch.setattr(sys, "stdout", closed and io.TextIOWrapper(io.BytesIO()))
    with pytest.raises(SystemExit) as exit:
        console()
    assert exit.value.code == 141


@pytest.mark.skipif(not os.path.isdir("/proc/self/fd"), reason="reads /proc/self/fd")
@pytest.mark.parametrize("fd", [0, 1, 2])
def test_a_command_started_with_a_standard_stream_closed_runs_with_it_on_dev_null(tmp_path, fd):
    """`spikegs train ... 2>&-` stopped at its first look at stderr (Python's None for a closed
    descriptor: AttributeError, exit 1, nothing said or trained), and the next file it opened
    took descriptor 2, where C and C++ code's messages go: stderr is /dev/null instead, and so
    is a closed stdin (read: nothing) or stdout (written to)."""
    script = (
        "import os, sys, spikegs.cli as cli\n"
        "def run():\n"
        "    read = sys.stdin.read() if FD == 0 else ''\n"
        "    print('said'), print('said', file=sys.stderr)\n"
        "    link = os.readlink('/proc/self/fd/FD')\n"
        "    with open(os.environ['OUT'], 'w') as out:\n"
        "        out.write(f'{read!r} {cli.show_bars(False)} {link}')\n"
        "    return 0\n"
        "cli.main = run\n"
        "cli.console()\n"
    ).replace("FD", str(fd))
    out = tmp_path / "out"
    env = {**os.environ, "OUT": str(out)}
    done = subprocess.run(
        [sys.executable, "-c", script],
        env=env,
        capture_output=True,
        preexec_fn=lambda: os.close(fd),
    )
    assert done.returncode == 0 and out.read_text() == f"'' False {os.devnull}"


@pytest.mark.parametrize(
    "argv",
    [
        ["eval", "RUN", "--dataset", ""],
        ["eval", ""],
        ["render", "RUN", "--out", "v.gif", "--dataset", ""],
        ["render", "", "--out", "v.gif"],
        ["train", "", "--method", "tfp33", "--out", "RUN"],
        ["sim-train", ""],
        ["poses", ""],
        ["simulate", "--out", ""],
        ["demo", "--out", ""],
        ["bench", "stiff", "--out", ""],
    ],
)
def test_an_empty_path_is_refused_while_parsing(argv, capsys):
    """`eval RUN --dataset ""` said "./: no dataset found": an empty path was the current
    folder (Path('')), for every path argument but train's --out and --config."""
    with pytest.raises(SystemExit) as exit:
        main(argv)
    assert exit.value.code == 2 and "expected a path, found ''" in capsys.readouterr().err


def test_an_unknown_or_shortened_option_is_refused_with_the_commands_usage(capsys, monkeypatch):
    """An unknown option printed the top level's usage (`spikegs [-h] COMMAND ...`) under
    `spikegs: error:`, every other error the command's; a shortened one (`--iter 3`) was read
    as the option it begins, which a script's turns ambiguous, or another's, when options are
    added. `--version` names the package's."""
    for wrong in ("--quiet", "--iter"):
        with pytest.raises(SystemExit) as exit:
            main(["train", "DATA", "--out", "RUN", wrong, "3"])
        err = capsys.readouterr().err
        assert exit.value.code == 2 and err.startswith("usage: spikegs train ")
        assert f"spikegs train: error: unrecognized arguments: {wrong} 3" in err
    with pytest.raises(SystemExit) as exit:  # a word that is the command's name, after it
        main(["train", "DATA", "--out", "RUN", "train"])
    err = capsys.readouterr().err
    assert exit.value.code == 2 and "spikegs train: error: unrecognized arguments: train" in err
    for argv in (["--bogus", "train", "DATA", "--out", "RUN"], None):  # None: sys.argv's
        monkeypatch.setattr(sys, "argv", ["spikegs", "--bogus", "train", "DATA", "--out", "RUN"])
        with pytest.raises(SystemExit) as exit:  # an option before the command: the top level's
            main(argv)
        err = capsys.readouterr().err
        assert exit.value.code == 2 and "spikegs: error: unrecognized arguments: --bogus" in err
    # a shortened --version, alone or before a command: argparse said "the following arguments
    # are required: COMMAND", or the command's missing arguments
    for argv in (["--vers"], ["--vers", "train"]):
        with pytest.raises(SystemExit) as exit:
            main(argv)
        err = capsys.readouterr().err
        assert exit.value.code == 2 and f"spikegs: error: unrecognized arguments: {argv[0]}" in err
    with pytest.raises(SystemExit) as exit:
        main(["--version"])
    assert exit.value.code == 0 and capsys.readouterr().out == f"spikegs {spikegs.__version__}\n"


def test_the_version_is_the_one_the_package_is_built_with():
    """`__version__` and pyproject.toml's version are written apart: a bump of one alone made
    `spikegs --version` and pip's metadata disagree (the install trial)."""
    pyproject = (Path(__file__).parents[1] / "pyproject.toml").read_text(encoding="utf-8")
    (built,) = re.findall(r'(?m)^version = "([^"]+)"$', pyproject)
    assert spikegs.__version__ == built


def test_names_with_dollar_signs_are_plotted_as_written(tmp_path):
    """matplotlib reads $...$ as TeX: a config naming its method "lam$^$2" trained to the end,
    then failed at its curve.png with a parse error (exit status 2, the run complete)."""
    from spikegs.curves import save_curves

    curve = [{"train_seconds": s, "psnr": p} for s, p in ((1.0, 20.0), (2.0, 21.0))]
    methods = {
        "lam$^$2": {"curve": curve, "sim_seconds": 0.0, "uses_sim": False},
        "sim$": {"curve": curve, "sim_seconds": 3.0, "uses_sim": True},
    }
    save_curves(tmp_path / "curves.png", methods, ("psnr",), "scene $^$: view $a_{b$")
    assert (tmp_path / "curves.png").stat().st_size > 0


def test_a_folder_name_that_is_not_utf8_is_plotted(tmp_path):
    """A dataset in a Latin-1 folder (b"caf\\xe9", os.fsdecode's surrogate escape) trained to the
    end, then its curve.png failed in the font (TypeError, exit status 1, the run complete)."""
    from spikegs.curves import save_curves

    curve = [{"train_seconds": s, "psnr": p} for s, p in ((1.0, 20.0), (2.0, 21.0))]
    methods = {"tfp33": {"curve": curve, "sim_seconds": 0.0, "uses_sim": False}}
    save_curves(tmp_path / "curves.png", methods, ("psnr",), os.fsdecode(b"caf\xe9_llff"))
    assert (tmp_path / "curves.png").stat().st_size > 0
    # a lone surrogate that is no escaped byte (meta.json's "caf\\ud800", as JSON reads it)
    save_curves(tmp_path / "lone.png", methods, ("psnr",), "caf\ud800")
    assert (tmp_path / "lone.png").stat().st_size > 0


def test_a_bar_whose_output_is_gone_leaves_the_next_bar_its_line(gone_stderr):
    """A bar whose output went away was turned off but stayed in tqdm's list of bars (its close
    returns early when off), so a later bar in the same process was drawn on the line below it."""
    stderr = gone_stderr(BrokenPipeError(errno.EPIPE, "Broken pipe"))
    bar = tqdm(total=3, file=sys.stderr)
    stderr.gone = True
    assert isinstance(progress_lost(bar.refresh, bar), BrokenPipeError)
    quiet = tqdm(total=3, file=io.StringIO())
    assert quiet.pos == 0
    quiet.close()
