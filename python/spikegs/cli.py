"""The `spikegs` command line: one sub-command per module, each with `add_arguments` and `run`."""

from __future__ import annotations

import argparse
import codecs
import contextlib
import errno
import importlib
import io
import itertools
import math
import os
import re
import signal
import sys
import warnings
from pathlib import Path

from .file_lock import BUSY, Busy
from .interrupt import ENDING, FULL, NAMES, Terminated, raise_terminated, say
from .missing_dependency import MissingDependencyError

# what an out-of-memory error asks to make smaller, unless a command's module names its own
# options (MEMORY_SIZES: sim-train's named the dataset's sizes for a --batch-size of 10^9)
MEMORY_SIZES = "height, width, readouts, spp, Gaussians"
# sub-command -> (module implementing it, one-line help)
COMMANDS = {
    "demo": (
        "spikegs.demo",
        "simulate, train SIM, SpikeGS and TFP(33)+3DGS, evaluate: the main job",
    ),
    "simulate": ("spikegs.data.simulate_cli", "make a synthetic spike dataset"),
    "sim-train": ("spikegs.sim_cli", "train the SIM blind-spot network on a dataset"),
    "train": ("spikegs.train_cli", "train a Gaussian scene from a spike dataset"),
    "eval": ("spikegs.eval_cli", "evaluate a training run on its test views"),
    "render": ("spikegs.render_cli", "render a novel-view orbit video of a run"),
    "poses": ("spikegs.poses_cli", "camera poses and a point cloud from the spikes (SfM)"),
    "bench": ("spikegs.bench.cli", "benchmarks: error against run time"),
}


def positive_int(text: str) -> int:
    """An argparse type: a whole number in 1..2**63 - 1, refused while parsing (before any work
    starts: 2**63 iterations trained on, 2**63 frames or crops stopped on numpy's messages)."""
    from .number_checks import is_count  # (numpy: not at every spikegs start)

    try:
        value = int(text)
    except ValueError:
        value = 0
    if not is_count(value):
        raise argparse.ArgumentTypeError(f"expected a positive integer below 2^63, found '{text}'")
    return value


def _number(text: str) -> float:
    """float(text), NaN where it is no number (which the types below refuse)."""
    try:
        return float(text)
    except ValueError:
        return math.nan


def finite_float(text: str) -> float:
    """An argparse type: a finite number, refused while parsing (float() reads nan and inf)."""
    value = _number(text)
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"expected a finite number, found '{text}'")
    return value


def positive_float(text: str) -> float:
    """An argparse type: a finite number > 0, refused while parsing (before any work starts)."""
    value = _number(text)
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"expected a finite number > 0, found '{text}'")
    return value


def seed(text: str) -> int:
    """An argparse type: a seed, a whole number in 0..2**64 - 1 (torch's and the simulator's
    range, where one outside would wrap around), refused while parsing in one wording for every
    command (each worded its own check after parsing)."""
    from .number_checks import is_seed  # (numpy: not at every spikegs start)

    try:
        value = int(text)
    except ValueError:
        value = -1
    if not is_seed(value):
        raise argparse.ArgumentTypeError(f"expected an integer in 0..2**64 - 1, found '{text}'")
    return value


def direction(text: str):
    """An argparse type: 'X,Y,Z', a non-zero finite vector, as a unit vector [3] (numpy)."""
    from .data.trajectory import unit_vector  # (numpy: not at every spikegs start, --help too)

    try:
        return unit_vector("", [float(x) for x in text.split(",")])
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected a non-zero direction X,Y,Z, found '{text}'"
        ) from None


def file_path(text: str) -> Path:
    """An argparse type: a path, refused while parsing when empty (Path('') is the current
    directory)."""
    if not text.strip():
        raise argparse.ArgumentTypeError("expected a path, found ''")
    return Path(text)


def output_file(text: str) -> Path:
    """An argparse type: a file to write, refused while parsing when its name ends in a path
    separator (a folder's: Path drops the separator, and the file would be written)."""
    path = file_path(text)
    last = text.replace(os.altsep or os.sep, os.sep).rsplit(os.sep, 1)[-1]  # its last part
    if last in ("", ".", ".."):
        raise argparse.ArgumentTypeError(f"expected a file name, found the folder name '{text}'")
    return path


# what `spikegs --help` says above the commands: the path through them
USAGE = """3D Gaussian Splatting trained from spike-camera streams.

  spikegs demo --out DIR                     the main job, a few minutes on 2 cores
  spikegs simulate --out DATASET             a synthetic dataset (or bring a recording;
  spikegs poses DATASET                        poses from its spikes where it has none)
  spikegs train DATASET --method spikegs --out RUN
  spikegs eval RUN                           PSNR/SSIM on the test views, side-by-sides
  spikegs render RUN --out orbit.mp4         a novel-view orbit

`spikegs COMMAND --help` for each command's options."""


# the options `spikegs` takes before a command's name (argparse's help, and `--version`)
TOP_OPTIONS = ("-h", "--help", "--version")
# options whose value is X,Y,Z (`direction`), and a value of them starting with a minus sign
VECTOR_OPTIONS = ("--up",)
NEGATIVE_VECTOR = re.compile(r"-[\d.]")


def joined_vectors(words: list[str]) -> list[str]:
    """`words` with `--up -1,0,0` as `--up=-1,0,0`: argparse takes a word starting with a minus
    sign for an option unless it is a plain negative number ("--up: expected one argument")."""
    joined = []
    for word in words:
        if joined and joined[-1] in VECTOR_OPTIONS and NEGATIVE_VECTOR.match(word):
            joined[-1] = f"{joined[-1]}={word}"
        else:
            joined.append(word)
    return joined


class _DefaultsFormatter(argparse.HelpFormatter):
    """Help that ends an option's text with its default, where it has one (not None or off) and
    the text does not already say it."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        none = action.default is None or action.default is False
        if none or action.default is argparse.SUPPRESS or not action.option_strings:
            return text
        return text if "default" in text else f"{text} (default: %(default)s)"


def add_no_progress(parser: argparse.ArgumentParser, instead: str = "", *aliases: str) -> None:
    """--no-progress (and `aliases`), read by `show_bars`: no progress bars, `instead` what the
    command prints in their place; the default where stderr is not a terminal."""
    parser.add_argument(
        "--no-progress",
        *aliases,
        dest="no_progress",
        action="store_true",
        help=f"no progress bars{instead} (the default where stderr is not a terminal: a batch "
        f"job's log)",
    )


def show_bars(off: bool) -> bool:
    """Whether a command draws progress bars: not where `off` (--no-progress, --quiet), nor where
    stderr is no terminal (a batch job's log, which bars' carriage returns garble) or one that
    reports no width (a pseudo-terminal given no size: `script` under cron, some containers),
    where tqdm drew empty bars and the run printed nothing until its end, or no height (`stty
    cols 80` alone in `script`), where tqdm drew nothing."""
    if off or not sys.stderr.isatty():
        return False
    try:
        size = os.get_terminal_size(sys.stderr.fileno())
        return size.columns > 0 and size.lines > 0
    except (OSError, ValueError):  # no file descriptor: a stream that only says it is a terminal
        return False


def build_parser() -> argparse.ArgumentParser:
    """The parser of every command; options are never abbreviated (a script's `--iter` would
    turn ambiguous, or mean another option, when one is added)."""
    from . import __version__

    parser = argparse.ArgumentParser(
        prog="spikegs",
        description=USAGE,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        allow_abbrev=False,
    )
    parser.add_argument("--version", action="version", version=f"spikegs {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name, (module_name, help_text) in COMMANDS.items():
        module = importlib.import_module(module_name)
        command = sub.add_parser(
            name,
            help=help_text,
            description=help_text,
            formatter_class=_DefaultsFormatter,
            allow_abbrev=False,
        )
        module.add_arguments(command)
        sizes = getattr(module, "MEMORY_SIZES", MEMORY_SIZES)  # (a command's own, if it has)
        command.set_defaults(_run=module.run, _parser=command, _sizes=sizes)
    return parser


def _warning_printer(command: str, default):
    """A `warnings.showwarning` that prints our warnings (UserWarning) as `spikegs COMMAND:
    warning: MESSAGE`, without the source line they were raised at; others as `default` does."""

    def show(message, category, filename, lineno, file=None, line=None):
        if not issubclass(category, UserWarning):
            return default(message, category, filename, lineno, file, line)
        print(f"spikegs {command}: warning: {message}", file=file or sys.stderr)

    return show


INTERRUPTED = 130  # the exit status of a command stopped by Ctrl-C (128 + SIGINT), as shells'
# stopped by SIGTERM or SIGHUP: 128 + the signal's number (143, 129)
BROKEN_PIPE = 141  # its output's reader gone (128 + SIGPIPE)
HUNG_UP = 129  # an error it could not say, its terminal gone (EIO): as SIGHUP ends (128 + 1)
# (one it could not say to stderr's reader gone: BROKEN_PIPE)


ESCAPE = "spikegs.escape"  # the codec error handler `_escape`


def _escape(err: UnicodeError) -> tuple[str | bytes, int]:
    """Surrogateescape's bytes where it applies (a file name's undecodable bytes print as they
    are), else backslashreplace's escape."""
    try:
        return codecs.lookup_error("surrogateescape")(err)
    except UnicodeError:
        return codecs.backslashreplace_errors(err)


def _escaping_outputs() -> None:
    """stdout and stderr print a character their codec lacks escaped: strict ones (a Latin-1
    or ASCII locale, PYTHONIOENCODING) as backslashreplace does, surrogateescape ones (the C
    locale's ASCII stdout without UTF-8 mode, PYTHONUTF8=0, which raised at a µ or an é; UTF-8
    mode's) as `_escape` does."""
    codecs.register_error(ESCAPE, _escape)
    escapes = {"strict": "backslashreplace", "surrogateescape": ESCAPE}
    for stream in (sys.stdout, sys.stderr):
        if isinstance(stream, io.TextIOWrapper) and stream.errors in escapes:
            with contextlib.suppress(OSError):  # its flush, where its reader left: said at exit
                stream.reconfigure(errors=escapes[stream.errors])


def _closed_streams_to_devnull() -> None:
    """stdin, stdout or stderr closed as the command started (`spikegs ... 2>&-`) is /dev/null
    instead: Python set a closed one to None, whose first use stopped train (exit 1, nothing
    said), and the next file opened took its descriptor, which C and C++ code writes messages
    to. Filled in order, each gets the lowest descriptor free: its own."""
    for fd, name in enumerate(("stdin", "stdout", "stderr")):
        try:
            os.fstat(fd)
        except OSError:
            os.open(os.devnull, os.O_RDWR)
            setattr(sys, name, open(fd, "r" if fd == 0 else "w", closefd=False))


def console() -> None:
    """The `spikegs` command: `main`, then exit with its status. SIGTERM stops a command as
    Ctrl-C does (a batch scheduler's time limit: training checkpoints after its step, temporary
    files are removed), unless it was ignored; SIGHUP likewise (the terminal closed; nohup
    ignores it). Once stopped, further signals are ignored while the interpreter exits (a
    second Ctrl-C, pressed as people do, printed 'Exception ignored in atexit callback ...
    KeyboardInterrupt' from its clean-up). A Ctrl-C while the command's modules import says
    'interrupted' too, not a traceback (as one during the package's own import, torch's, before
    this runs: `ImportInterrupted`). A command that finished ignores them too: a
    signal landing in the interpreter's exit (about a second, torch's teardown) replaced the
    status it earned (0) with a kill. A character the output's codec lacks (θ, µ or — through a
    Latin-1 or ASCII stdout) prints escaped (as Python's stderr does), not as a
    UnicodeEncodeError after the work."""
    _closed_streams_to_devnull()
    _escaping_outputs()
    for signum in ENDING:
        if signal.getsignal(signum) is signal.SIG_DFL:
            signal.signal(signum, raise_terminated)
    try:
        status = main()
    except KeyboardInterrupt as stop:
        status = _stopped(stop)
    except BrokenPipeError:  # the reader left (`| head`): quiet, as a tool SIGPIPE ends
        status = BROKEN_PIPE
    lost = _drop_unflushable_outputs().get("stdout")
    if lost is not None and status == 0:  # its results, printed, are lost: no success
        status = _lost_output_status(lost)
        _drop_unflushable_outputs()  # (what that said, to a stderr whose disk is full too)
    for signum in NAMES:  # the status is decided: nothing left to stop
        signal.signal(signum, signal.SIG_IGN)
    _forget_unhandled_interrupt()
    sys.exit(status)


def _forget_unhandled_interrupt() -> None:
    """Clear CPython's mark of a KeyboardInterrupt left unhandled, which one leaving code run
    from a string sets though `console` handled it (a Ctrl-C in a dataclass's generated
    __init__ or a namedtuple's __new__, which modules imported mid-command define): `python -m
    spikegs` then killed itself with SIGINT at exit, not exiting with its status. Evaluating
    any string clears it as it starts."""
    eval("None")


def _drop_unflushable_outputs() -> dict[str, OSError]:
    """Send stdout or stderr to /dev/null where what it still holds cannot be flushed (its
    reader or terminal gone, its disk full): exit's flush would fail on it and exit 120 with
    Python's 'Exception ignored'; the error of each so sent ("stdout", "stderr"). An output that
    flushes is left as it is (a log file a hung-up command wrote to keeps its last lines)."""
    dropped = {}
    for name, stream in (("stdout", sys.stdout), ("stderr", sys.stderr)):
        try:
            stream.flush()
        except (AttributeError, ValueError):  # None (its descriptor closed as Python started)
            continue  # or closed: exit's flush passes it by too
        except OSError as err:
            devnull = os.open(os.devnull, os.O_WRONLY)
            with contextlib.suppress(OSError, ValueError):  # (a stream without a file)
                os.dup2(devnull, stream.fileno())
            os.close(devnull)
            dropped[name] = err
    return dropped


def _lost_output_status(err: OSError) -> int:
    """The status of a command whose printed results `err` kept from stdout: its reader gone
    (141), its terminal (129), else (its disk full: 2) said on stderr where it can be."""
    if isinstance(err, BrokenPipeError):
        return BROKEN_PIPE
    if err.errno == errno.EIO:
        return HUNG_UP
    say(f"spikegs: error: stdout: {err.strerror or err}: {PRINTED_LOST}")
    return 2


PRINTED_LOST = "what the command printed is lost"  # (its files are written as it says)
STDOUT = "<stdout>"  # the file name of stdout's write errors (`_NamedStdout`)


class _NamedStdout:
    """stdout, its full-disk write errors naming it (a command's results printed into `>
    /dev/full` were said as a bare "[Errno 28] No space left on device", read as its files
    failing, which are written); all else stdout's own."""

    def __init__(self, stream):
        self._stream = stream

    def _named(self, call, *args):
        try:
            return call(*args)
        except OSError as err:
            if err.errno not in FULL or err.filename is not None:
                raise
            raise OSError(err.errno, err.strerror, STDOUT) from err

    def write(self, text: str) -> int:
        return self._named(self._stream.write, text)

    def flush(self) -> None:
        return self._named(self._stream.flush)

    def __getattr__(self, name: str):
        return getattr(self._stream, name)


def _stopped(stop: KeyboardInterrupt) -> int:
    """Say that a signal stopped the command (unless stderr is gone); its exit status."""
    if isinstance(stop, Terminated):
        say("terminated" if stop.signum == signal.SIGTERM else "hung up")
        return 128 + stop.signum
    say("interrupted")
    return INTERRUPTED


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    words = sys.argv[1:] if argv is None else argv
    # an option before the command's name that the top level does not take: argparse said
    # "the following arguments are required: COMMAND" for `spikegs --vers`, and the command's
    # missing arguments for `spikegs --vers train`
    before = itertools.takewhile(lambda word: word.startswith("-") and word != "--", words)
    unknown = [word for word in before if word not in TOP_OPTIONS]
    if unknown:
        parser.error(f"unrecognized arguments: {' '.join(unknown)}")
    args, unknown = parser.parse_known_args(joined_vectors(words))
    if unknown:  # with the command's usage (the top level's named no option of it)
        args._parser.error(f"unrecognized arguments: {' '.join(unknown)}")
    with warnings.catch_warnings():
        warnings.showwarning = _warning_printer(args.command, warnings.showwarning)
        return _run(args)


def _run(args: argparse.Namespace) -> int:
    """Run the parsed command; its errors as messages and exit codes."""
    stdout = sys.stdout
    if stdout is not None:  # (None: a closed stdout, which print passes by)
        sys.stdout = _NamedStdout(stdout)
    try:
        return int(args._run(args) or 0)
    except KeyboardInterrupt as stop:
        return _stopped(stop)
    except BrokenPipeError:  # the output's reader left: not the command's error (`console`)
        raise
    except Busy as err:  # another process holds the run: a retry may succeed
        print(f"spikegs {args.command}: busy: {err}", file=sys.stderr)
        return BUSY
    # bad input, missing or unwritable files, an extra not installed (pip install '.[..]'),
    # a warning that PYTHONWARNINGS=error or -W error made an exception (a traceback before)
    except (ValueError, OSError, MissingDependencyError, Warning) as err:
        if isinstance(err, OSError) and err.filename == STDOUT:
            err = f"stdout: {err.strerror}: {PRINTED_LOST}"
        warned = isinstance(err, Warning)
        note = " (a warning, which PYTHONWARNINGS or -W makes an error)" if warned else ""
        # (a closed terminal's EIO, stdout's or stderr's, once more as this is said: quiet)
        unsaid = say(f"spikegs {args.command}: error: {err}{note}")
        if unsaid is None or unsaid.errno in FULL:  # (a full stderr's: the error's own status)
            return 2
        return BROKEN_PIPE if isinstance(unsaid, BrokenPipeError) else HUNG_UP
    except FloatingPointError as err:  # training diverged: the message says where and why
        print(f"spikegs {args.command}: stopped: {err}", file=sys.stderr)
        return 1
    except MemoryError as err:  # numpy's names the size (a 100000² simulation: 37 GiB)
        print(
            f"spikegs {args.command}: out of memory: {err or 'an allocation failed'}; smaller "
            f"sizes ({args._sizes})",
            file=sys.stderr,
        )
        return 1
    finally:
        sys.stdout = stdout


if __name__ == "__main__":
    console()
