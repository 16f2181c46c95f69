"""`spikegs demo`: the main job on the built-in default scene, in a few minutes on a laptop CPU.

Simulates the small default scene, trains SIM, trains SpikeGS and the TFP(33)+3DGS baseline with
the same number of iterations (not the same time: SpikeGS renders K poses a step and trains SIM
first, ~6 times the baseline's seconds), evaluates both on held-out views, prints a table and
writes DIR/results.json and DIR/comparison.png (ground truth | TFP(33)+3DGS | SpikeGS on each test
view, stacked) and DIR/curves.png (both methods' test PSNR over every test view against training
seconds, SpikeGS's from the end of SIM's training).
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import time
from pathlib import Path

import numpy as np

from . import strict_json
from .atomic_save import sweep_temporaries, write_text_atomically
from .cli import add_no_progress, file_path, positive_int, show_bars
from .config import load_config, load_saved_run
from .curves import save_logged_curves
from .data.scenes import SCENES
from .image_labels import column_titles, row_labels
from .interrupt import say
from .method_titles import method_title
from .provenance import environment
from .regular_file import is_blank, read_text
from .run_folder import refuse_dataset_or_run, refuse_foreign_files, run_lock
from .run_summary import CONFIG, EVAL, LOCK, last_checkpoint
from .text_table import print_table

METHODS = ("spikegs", "tfp33")
DEFAULT_SCENE = "solids"
# The demo's shortened schedule: the same iterations and settings for both methods (equal
# iterations, not equal time: `gain_line` says both methods' seconds), sized for the
# 5-minute budget on 2 cores of the slower (AVX2, no native bfloat16) machine (BENCHMARKS.md,
# "Training"): 1500 iterations, the densification of 1800 scaled to them (1800 took 6 min 35-55 s
# there with SIM's batch of 8). AbsGS's threshold at 0.0003, not the default 0.0002: 0.0002 grew
# a quarter more Gaussians. SIM trains 300 steps on batches of 2 crops: as good a SIM as 8 crops
# (on-path views, seeds 0-2: 41.60 dB against 41.66 for 8, seeds 0-1) in a quarter of the time.
DEMO_OVERRIDES = {
    "train": {"iterations": 1500, "eval_every": 300, "checkpoint_every": 300},
    "densify": {
        "start": 250,
        "stop": 1125,
        "every": 125,
        "opacity_reset_every": 0,
        "grad_threshold": 0.0003,
    },
    "sim": {"iterations": 300, "batch": 2},
}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", type=file_path, default=Path("spikegs-demo"), help="output folder")
    parser.add_argument(
        "--scene",
        choices=sorted(SCENES),
        help=f"built-in scene (default: {DEFAULT_SCENE}; on --resume, the demo's own)",
    )
    parser.add_argument(
        "--iterations",
        type=positive_int,
        help="training iterations per method, densification scaled with them (default: "
        f"{DEMO_OVERRIDES['train']['iterations']}; on --resume, those the demo started with)",
    )
    fresh_or_not = parser.add_mutually_exclusive_group()  # (--overwrite deleted what resumes)
    fresh_or_not.add_argument(
        "--resume",
        action="store_true",
        help="continue an interrupted demo in --out: its dataset, SIM's saved training state and "
        "each run's last checkpoint (the same results as a demo never interrupted); where --out "
        "holds no demo, one starts (said on stderr), so a script may always pass it",
    )
    fresh_or_not.add_argument(
        "--overwrite",
        action="store_true",
        help="start afresh where --out holds an earlier demo, deleting its dataset, runs and "
        "results (refused otherwise: --resume continues it, a finished one printed again)",
    )
    parser.add_argument(
        "--color",
        action="store_true",
        help="a colour spike camera, a stream per channel (on --resume, the demo's own camera)",
    )
    add_no_progress(parser, ": a line as each run starts and at each evaluation instead")


def demo_dataset(scene: str, data: Path, resume: bool, progress: bool, color: bool = False):
    """The demo's dataset: simulated into `data` (`color`: an RGB camera), or, on `resume`, the
    one a demo already simulated there (meta.json is written last: a folder without it is
    simulated again), of `scene` and that camera (`_check_resumed_scene` refused another)."""
    from .data import load_dataset, simulate_dataset

    if resume and (data / "meta.json").exists():
        dataset = load_dataset(data)
        print(f"[1/3] resuming with the spike dataset in {data}", file=sys.stderr)
        return dataset
    print(f"[1/3] simulating the spike dataset -> {data}", file=sys.stderr)
    return simulate_dataset(scene, data, overwrite=True, progress=progress, color=color)


SECONDS_FILE = ".demo_seconds"  # wall-clock seconds of the demo's interrupted processes
STARTED_FILE = ".demo_started.json"  # what a demo began with: {"scene", "iterations", "color"}
RESULTS = "results.json"
COMPARISON, CURVES = "comparison.png", "curves.png"  # the demo's figures
LABEL_WIDTH = 88  # pixels of comparison.png's row labels: the view, each method's PSNR there


def earlier_seconds(out: Path, finished: dict | None) -> float:
    """The seconds that earlier processes of the demo in `out` spent: those of its interrupted
    processes, or the total_seconds of `finished`, its results.json (`finished_results`:
    resumed, it has nothing left to train); 0 where none recorded."""
    try:
        return float(read_text(out / SECONDS_FILE))
    except (FileNotFoundError, ValueError):
        return 0.0 if finished is None else float(finished["total_seconds"])


def _started(out: Path) -> dict:
    """What the demo in `out` recorded as it started (STARTED_FILE); {} where none."""
    try:
        started = json.loads(read_text(out / STARTED_FILE))
    except (FileNotFoundError, ValueError):
        return {}
    return started if isinstance(started, dict) else {}


def finished_results(out: Path) -> dict | None:
    """OUT/results.json where a demo wrote it (its "methods" hold the demo's methods and its
    "total_seconds" a number), else None: a file of that name no demo wrote is not a demo's."""
    try:
        results = json.loads(read_text(out / RESULTS))
    except (FileNotFoundError, ValueError):
        return None
    ours = (
        isinstance(results, dict)
        and isinstance(results.get("methods"), dict)
        and set(METHODS) <= set(results["methods"])
        and isinstance(results.get("total_seconds"), (int, float))
    )
    return results if ours else None


def held_demo(out: Path, finished: dict | None) -> str | None:
    """What demo `out` holds: "a finished demo" (`finished`, its `finished_results`), "an
    interrupted demo" (STARTED_FILE without them), None for none."""
    if finished is not None:
        return "a finished demo"
    return "an interrupted demo" if (out / STARTED_FILE).is_file() else None


def started_iterations(out: Path) -> int | None:
    """The iterations an interrupted demo in `out` was started with (its first run's
    config.yaml, as `saved_settings` gives it, else what it recorded when it started), None for
    the default; ValueError naming a run's config.yaml that is empty without a checkpoint or not
    a run's settings."""
    for method in METHODS:
        run_dir = out / "runs" / method
        if (run_dir / CONFIG).is_file():
            return load_saved_run(saved_settings(run_dir)).train.iterations
    iterations = _started(out).get("iterations")
    return iterations if isinstance(iterations, int) and iterations > 0 else None


def saved_settings(run_dir: Path) -> Path:
    """A demo run's config.yaml, written again from its checkpoint's settings where emptied, as
    `spikegs train --resume` does (it was refused, and so was the demo without --resume,
    holding the finished runs); ValueError where it is empty without a checkpoint."""
    from .train_cli import restore_run_settings  # (it imports torch's training machinery)

    saved = run_dir / CONFIG
    if is_blank(saved):
        if not last_checkpoint(run_dir).is_file():
            raise ValueError(
                f"--resume: {saved} is empty: the run's settings are lost; start the demo "
                f"afresh (without --resume)"
            )
        restore_run_settings(str(run_dir), saved)
    return saved


def _dataset_meta(out: Path) -> dict | None:
    """The meta.json of the demo's dataset in `out`; None where there is none (or not an
    object)."""
    try:
        meta = json.loads(read_text(out / "data" / "meta.json"))
    except (FileNotFoundError, ValueError):
        return None
    return meta if isinstance(meta, dict) else None


def _own_scene(out: Path) -> str | None:
    """The scene of the demo in `out` as written: its dataset's, else what it recorded when it
    started; None where neither names one."""
    meta = _dataset_meta(out)
    scene = _started(out).get("scene") if meta is None else meta.get("scene")
    return scene if isinstance(scene, str) else None


def started_scene(out: Path) -> str | None:
    """The scene of the demo in `out` (`_own_scene`), None where it is no built-in one."""
    scene = _own_scene(out)
    return scene if scene in SCENES else None


def started_color(out: Path) -> bool:
    """Whether the demo in `out` is a colour camera's (its dataset's channels, else what it
    recorded when it started)."""
    meta = _dataset_meta(out)
    return _started(out).get("color") is True if meta is None else meta.get("channels") == 3


def holds_files(folder: Path) -> bool:
    """Whether `folder` exists and holds anything but a lock (which stays behind, empty)."""
    return folder.is_dir() and any(p.name != LOCK for p in folder.iterdir())


def check_fresh_out(out: Path, overwrite: bool, finished: dict | None) -> None:
    """FileExistsError, before any work, where a fresh demo in `out` would delete what is not an
    earlier demo's: OUT/data or OUT/runs/METHOD holding files that are not a dataset's or a
    spikegs run's (a user's own run there keeps its notes, renders, ...), or, where no demo ran
    in OUT (`held_demo`: `finished`, its `finished_results`, a demo's results.json, which demos
    before 2026-11-25 left alone, or STARTED_FILE), holding anything, or a results.json or
    figure of the demo's names (`--out` naming a project's folder, whose runs/spikegs, data and
    results are its own; a results.json of any content was taken for a demo's); and, without
    `overwrite`, where an earlier demo is there (its results were deleted unasked)."""
    from .data.dataset import check_output

    # (its remedy was "give an empty or new folder", of a folder --out sets)
    check_output(out / "data", True, "move them out, or give the demo another --out")
    check_run_dirs(out, resume=False)
    held = held_demo(out, finished)
    if held is not None and not overwrite:
        again = " (printed again)" if held == "a finished demo" else ""
        raise FileExistsError(
            f"--out {out} holds {held}: --resume continues it{again}, --overwrite starts "
            f"afresh, deleting its dataset, runs and results; or give another --out"
        )
    if held is None:
        named = [name for name in (RESULTS, COMPARISON, CURVES) if (out / name).exists()]
        for part in (out / "data", *(out / "runs" / m for m in METHODS)):
            if holds_files(part):
                named.append(str(part.relative_to(out)))
        if named:
            raise FileExistsError(
                f"{out} holds {', '.join(named)}, which no demo wrote (it holds neither a "
                f"demo's {RESULTS} nor {STARTED_FILE}) and a demo would replace; give it another "
                f"--out"
            )


def check_run_dirs(out: Path, resume: bool) -> None:
    """FileExistsError, before any work, where OUT/runs/METHOD holds files that are not a spikegs
    run's (a fresh demo would delete them, a resumed one, on `resume`, refuse them after its
    first stages)."""
    remedy = (  # (a resumed demo was told to take another --out, losing its progress)
        ": move them out, then --resume again"
        if resume
        else ", which a demo would delete with its run; move them out, or give it another --out"
    )
    for method in METHODS:
        run_dir = out / "runs" / method
        if run_dir.exists() and not run_dir.is_dir():
            raise FileExistsError(f"{run_dir} is a file; give the demo another --out")
        refuse_foreign_files(run_dir, remedy)


def train_and_evaluate(
    dataset, configs: dict, out: Path, resume: bool, progress: bool
) -> tuple[dict, dict]:
    """{method: scores} and {method: {view: PSNR}}: each method of `configs` trained into
    OUT/runs/METHOD (resumed from its last checkpoint on `resume`, where it had started) and
    evaluated on the test views."""
    from .evaluate import evaluate_run
    from .train import Trainer
    from .train_cli import print_evaluation

    results, view_psnrs = {}, {}
    for i, method in enumerate(configs, start=2):
        print(f"[{i}/3] training {method}", file=sys.stderr)
        run_dir = out / "runs" / method
        started = resume and (run_dir / CONFIG).exists()
        # a checkpointed run goes on with its own settings: an earlier version's, whose defaults
        # today's differ from, was refused as trained with other settings
        config = configs[method]
        if started and last_checkpoint(run_dir).is_file():  # (at the length asked for: another
            # is refused, as before)
            config = load_saved_run(saved_settings(run_dir), iterations=config.train.iterations)
        trainer = Trainer(dataset, config, run_dir, progress=progress)
        summary = trainer.train(started, on_eval=None if progress else print_evaluation)
        ev = evaluate_run(run_dir, dataset)
        results[method] = {
            "psnr": ev["psnr"],
            "ssim": ev["ssim"],  # scikit-image's; 3DGS's evaluation's, the papers':
            "ssim_3dgs": ev["ssim_3dgs"],
            "train_seconds": summary["train_seconds"],
            "sim_seconds": summary["sim_seconds"],
            "gaussians": summary["gaussians"],
            "iterations": summary["iterations"],
        }
        view_psnrs[method] = {name: v["psnr"] for name, v in ev["views"].items()}
    return results, view_psnrs


def write_figures(out: Path, dataset, results: dict, view_psnrs: dict) -> None:
    """OUT/comparison.png (ground truth | TFP(33)+3DGS | SpikeGS on each test view, from the
    runs' evaluation images, under those titles, each row labelled with its view and the
    methods' PSNR there, `view_psnrs` {method: {view: PSNR}}) and OUT/curves.png
    (`save_logged_curves`)."""
    from .image_io import read_image, srgb_to_linear, write_image

    rows, h = [], dataset.height
    for view in dataset.test_views:  # each eval image is GT | render | error under their titles:
        panels = [  # GT once, the renders; back to linear light (write_image encodes it again)
            srgb_to_linear(read_image(out / "runs" / m / EVAL / f"{view.name}.png")[-h:])
            for m in METHODS
        ]
        w, c = panels[0].shape[1] // 3, panels[0].shape[2]
        psnrs = [
            f"{method_title(m).split('+')[0]} {view_psnrs[m][view.name]:.2f}" for m in METHODS[::-1]
        ]
        label = row_labels([view.name, *psnrs], LABEL_WIDTH, h)
        label = np.broadcast_to(label, (h, LABEL_WIDTH, c))
        renders = [p[:, w : 2 * w] for p in panels[::-1]]
        rows.append(np.concatenate([label, panels[0][:, :w], *renders], 1))
    titles = column_titles(["ground truth", *(method_title(m) for m in METHODS[::-1])], w)
    header = np.concatenate([column_titles(["view, PSNR (dB)"], LABEL_WIDTH), titles], axis=1)
    header = np.broadcast_to(header, (*header.shape[:2], rows[0].shape[2]))
    write_image(out / COMPARISON, np.concatenate([header, *rows], axis=0))
    runs = {m: (out / "runs" / m, r["sim_seconds"]) for m, r in results.items()}
    save_logged_curves(out / CURVES, runs, dataset)


def run(args: argparse.Namespace) -> int:
    from .output_paths import check_folder_output

    out = Path(args.out)
    check_folder_output(out, images=True)
    refuse_dataset_or_run(out, "a demo", datasets=1)
    out.mkdir(parents=True, exist_ok=True)
    with run_lock(out):  # one demo per OUT: a second one would delete the first one's files
        return _demo(args, out)


def _demo(args: argparse.Namespace, out: Path) -> int:
    """`run` once OUT is locked."""
    start = time.perf_counter()
    sweep_temporaries(out)  # one demo here: a figure or results.json a killed one half-wrote
    finished = finished_results(out)  # read once, with OUT locked
    # a demo writes STARTED_FILE as it starts: a folder without it (or a demo's results) holds
    # none, even where it holds other files (they went on as a demo without its start record)
    nothing_to_resume = args.resume and held_demo(out, finished) is None
    if nothing_to_resume:  # a fresh demo, as started (said once OUT is found fit for one)
        args = argparse.Namespace(**{**vars(args), "resume": False})
    progress = show_bars(args.no_progress)  # else a line at each evaluation
    earlier = earlier_seconds(out, finished) if args.resume else 0.0
    # --resume without --scene or --iterations goes on with those the demo was started with
    scene = args.scene or (started_scene(out) if args.resume else None) or DEFAULT_SCENE
    configs = {m: load_config(m, DEMO_OVERRIDES) for m in METHODS}
    started = started_iterations(out) if args.resume else None
    iterations = args.iterations or started
    color = args.color or (started_color(out) if args.resume else False)
    if iterations is not None:
        configs = {m: c.with_iterations(iterations) for m, c in configs.items()}
    if args.resume:  # other iterations refused in the demo's words (train's came after SIM)
        started = started or DEMO_OVERRIDES["train"]["iterations"]
        if args.iterations is not None and args.iterations != started:
            raise ValueError(
                f"--resume: the demo in {out} was started with {started} iterations, not "
                f"{args.iterations}; leave out --iterations to continue it, or give another --out"
            )
        _check_resumed_scene(out, scene, color)
        printable = _printable(finished, scene, color)
        if printable is not None:  # nothing to train: evaluated and timed again before
            print(f"--resume: {out} holds a finished demo; its results:", file=sys.stderr)
            return _print_results(printable, out)
    if not args.resume:
        check_fresh_out(out, args.overwrite, finished)
        if nothing_to_resume:
            print(f"--resume: {out} holds no demo to continue; starting one", file=sys.stderr)
        # an earlier demo's dataset is simulated again: a stop before the new one's meta.json
        # (written last) left the old one's, which --resume then continued, the scene and
        # camera this demo started with aside
        (out / "data" / "meta.json").unlink(missing_ok=True)
        # an earlier demo's, all at once: a fresh demo stopped before its last method left that
        # method's finished run, which --resume then refused as trained with other settings
        for method in METHODS:
            shutil.rmtree(out / "runs" / method, ignore_errors=True)
        for stale in (RESULTS, SECONDS_FILE, COMPARISON, CURVES):
            (out / stale).unlink(missing_ok=True)
        # what --resume goes on with, should this demo stop before its dataset and first run
        started = {"scene": scene, "iterations": iterations, "color": color}
        write_text_atomically(out / STARTED_FILE, json.dumps(started))
    else:
        check_run_dirs(out, resume=True)
    try:  # the figures too: stopped while writing them, it says how to go on as well
        dataset = demo_dataset(scene, out / "data", args.resume, progress, color)
        results, view_psnrs = train_and_evaluate(dataset, configs, out, args.resume, progress)
        write_figures(out, dataset, results, view_psnrs)
    except (KeyboardInterrupt, OSError, MemoryError) as stop:
        try:  # a full disk may refuse this too: the time then stays as it was
            seconds = repr(earlier + time.perf_counter() - start)
            write_text_atomically(out / SECONDS_FILE, seconds)  # (write_text emptied it first)
        except OSError:
            pass
        mend = "" if isinstance(stop, KeyboardInterrupt) else "once that is mended, "
        say(f"\n{mend}the same command with --resume continues from here")  # (stderr may be gone)
        raise
    total = earlier + time.perf_counter() - start  # with the interrupted processes' time
    (out / SECONDS_FILE).unlink(missing_ok=True)
    payload = {
        "methods": results,
        "scene": dataset.meta.get("scene"),
        "height": dataset.height,
        "width": dataset.width,
        "channels": dataset.channels,
        "test_views": len(dataset.test_views),  # the scores' means are over these
        "total_seconds": total,
        "resumed": args.resume,  # finished by more than one process
        "environment": environment(),  # this process's; each run's train.json names its own
    }
    write_text_atomically(out / RESULTS, strict_json.dumps(payload, indent=2))
    return _print_results(payload, out)


def _check_resumed_scene(out: Path, scene: str, color: bool) -> None:
    """ValueError where the scene (`scene`) or camera (`color`) a resumed demo would train is not
    the demo's own (`_own_scene`, `started_color`): its dataset's, or, stopped before that
    existed, what it recorded as it started (a --scene or --color given to --resume went on
    with the one named, unsaid). The one check of both, dataset or record."""
    own = _own_scene(out)
    if own is not None and scene != own:
        raise ValueError(
            f"--resume: the demo in {out} was started with scene '{own}', not '{scene}'; leave "
            f"out --scene to continue it, or give another --out"
        )
    if color and not started_color(out):
        raise ValueError(
            f"--resume: the demo in {out} was started with a mono camera; leave out --color to "
            f"continue it, or give another --out"
        )


def _printable(finished: dict | None, scene: str, color: bool) -> dict | None:
    """A finished demo's results.json (`finished_results`) of `scene` and camera, holding what
    `_print_results` prints (an older demo's may lack its iterations); else None."""
    if finished is None or finished.get("scene") != scene:
        return None
    printed = {"psnr", "ssim", "train_seconds", "gaussians", "sim_seconds", "iterations"}
    runs = [finished["methods"][m] for m in METHODS]
    whole = all(isinstance(r, dict) and printed <= set(r) for r in runs)
    return finished if whole and finished.get("channels") == (3 if color else 1) else None


def _print_results(payload: dict, out: Path) -> int:
    """The demo's table and headline from its results.json `payload`; 0."""
    results = payload["methods"]
    print()
    print_table(
        [
            {"method": m, **{k: r[k] for k in ("psnr", "ssim", "train_seconds", "gaussians")}}
            for m, r in results.items()
        ]
    )
    print(f"\n{gain_line(results)}; total {payload['total_seconds']:.0f} s; results in {out}")
    return 0


def gain_line(results: dict) -> str:
    """The demo's headline: SpikeGS's lead over TFP(33)+3DGS with the budget it is measured at,
    equal iterations, and what that budget costs each (SpikeGS renders K poses a step and trains
    SIM first: the lead is not an equal-time one, BENCHMARKS.md, "The baselines at SpikeGS's
    time"). `results`: results.json's "methods"."""
    ours, base = results["spikegs"], results["tfp33"]
    # the difference of the table's figures (18.99 and 18.50 were said to differ by 0.50); no
    # -0.00
    gain = round(round(ours["psnr"], 2) - round(base["psnr"], 2), 2) + 0.0
    ours_s = ours["train_seconds"] + ours["sim_seconds"]
    times = f", {ours_s / base['train_seconds']:.1f}x" if base["train_seconds"] > 0 else ","
    return (
        f"SpikeGS - TFP(33)+3DGS: {gain:+.2f} dB at equal iterations ({ours['iterations']} each; "
        f"SpikeGS {_seconds(ours_s)} s with SIM's training{times} the baseline's "
        f"{_seconds(base['train_seconds'])} s)"
    )


def _seconds(seconds: float) -> str:
    """Seconds in whole ones, under 10 to 2 significant digits (a baseline's 0.5 s read "0 s"
    beside a ratio of 149.6)."""
    return f"{seconds:.0f}" if seconds >= 9.5 else f"{seconds:.2g}"
