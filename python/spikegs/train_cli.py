"""`spikegs train DATASET --method NAME|--config FILE --out RUN [--resume]`."""

from __future__ import annotations

import argparse
import contextlib
import math
import sys
import warnings
from pathlib import Path

import torch
import yaml

from . import strict_json
from .atomic_save import write_text_if_changed
from .cli import add_no_progress, file_path, positive_int, seed, show_bars
from .config import (
    DEFAULT_METHOD,
    available_methods,
    differences,
    load_config,
    load_saved_run,
    older_run_keys,
)
from .curves import save_logged_curves
from .interrupt import FULL, say
from .output_paths import check_folder_output
from .regular_file import NotText, is_blank
from .run_summary import CONFIG, CURVE, SUMMARY, last_checkpoint, resume_command
from .yaml_files import dump_yaml, read_yaml


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "dataset", type=file_path, help="dataset folder (spikegs simulate writes one)"
    )
    which = parser.add_mutually_exclusive_group()
    which.add_argument(
        "--method",
        help=f"one of {', '.join(available_methods())} (default: {DEFAULT_METHOD}; with --resume, "
        f"the run's own settings, RUN/config.yaml)",
    )
    which.add_argument(
        "--config", type=file_path, help="a YAML config file instead of a method name"
    )
    parser.add_argument("--out", type=file_path, required=True, help="run folder")
    parser.add_argument(
        "--iterations",
        type=positive_int,
        help="override train.iterations (default: the method's, 3000 for the built-in ones); the "
        "densification schedule and the instant loss's end are scaled with it (30000 densifies "
        "from step 5000 every 1000, not as 3DGS: configs/spikegs.yaml's comment gives its "
        "schedule as a --config)",
    )
    parser.add_argument("--seed", type=seed, help="override train.seed (default: the method's, 0)")
    parser.add_argument(
        "--resume",
        action="store_true",
        help="continue from RUN's last checkpoint (a run stopped before its first one starts "
        "over, and one not begun starts where --method or --config names its settings: a batch "
        "script may pass them with --resume from its first submission)",
    )
    add_no_progress(parser, ": a line to stderr as it starts and at each evaluation instead")


def config_from_args(args: argparse.Namespace):
    """The validated config of --method/--config (neither: DEFAULT_METHOD, or on --resume the
    run's own RUN/config.yaml) with the command-line overrides applied."""
    overrides = {} if args.seed is None else {"train": {"seed": args.seed}}
    saved = Path(args.out) / CONFIG
    if args.config is not None and Path(args.config).suffix.lower() not in (".yaml", ".yml"):
        raise ValueError(
            f"--config {args.config}: expected a .yaml or .yml file (--method NAME names a method)"
        )
    given = args.config if args.config is not None else args.method  # "" is refused by name
    own = resumes_own_settings(args)
    try:  # an empty one: the defaults would stand in for the run's
        empty = own and is_blank(saved)
    except NotText as err:
        fix = (  # (`restore_run_settings`, which needs the checkpoint)
            "delete it, and --resume writes it again from the checkpoint's settings"
            if last_checkpoint(args.out).is_file()
            else "name the run's settings again with --method or --config"
        )
        raise ValueError(f"{err}; {fix}") from None
    if given is None and args.resume and not Path(args.out).exists():
        raise ValueError(
            f"--resume: {args.out} does not exist: nothing to resume (check the path; a new run "
            f"needs no --resume)"
        )
    if given is None and args.resume and (empty or not own):
        restore_run_settings(args.out, saved)
        own = True
    if not own:
        config = load_config(DEFAULT_METHOD if given is None else given, overrides, args.iterations)
        older = older_run_keys(read_yaml(args.config) or {}) if args.config is not None else {}
        if older:  # (a valid file: load_config read it)
            warnings.warn(
                f"--config {args.config} sets nearly every key but lacks {', '.join(older)}, as "
                f"an earlier spikegs's run config.yaml does: those take today's defaults, where "
                f"that run trained with "
                + ", ".join(f"{k} = {v!r}" for k, v in older.items())
                + "; write them in to train as it did (or --resume that run)",
                stacklevel=2,
            )
        return config
    config = load_saved_run(saved, overrides, args.iterations)  # keys added since keep its own
    if given is not None:  # at the run's length and seed: only what the method's settings differ in
        current = load_config(
            given, {"train": {"seed": config.train.seed}}, config.train.iterations
        )
        changed = differences(config.to_dict(), current.to_dict(), ("in the run", "now"))
        if changed:
            print(
                f"{args.out}: the run's own settings stand ({saved}), which differ from "
                f"{given}'s current ones: {'; '.join(changed)}",
                file=sys.stderr,
            )
    return config


def restore_run_settings(out: str, saved: Path) -> None:
    """Write a run's missing or empty config.yaml (`saved`) from the settings that its last
    checkpoint holds, said (the defaults stood in for them, refused by the checkpoint);
    ValueError where there is none to take them from."""
    checkpoint, settings = last_checkpoint(out), None
    if checkpoint.is_file():
        with contextlib.suppress(Exception):  # a torn or foreign file: as none (resume names it)
            settings = torch.load(checkpoint, map_location="cpu", weights_only=True)["config"]
    if not isinstance(settings, dict):
        from .data.dataset import layout_files  # (the data package is not needed otherwise)

        marks = layout_files(Path(out))
        if marks:  # (it said the dataset's config.yaml was missing)
            raise ValueError(
                f"--out {out}: a dataset (its {', '.join(marks)}), not a run folder: nothing "
                f"to resume (--out names the run's folder)"
            )
        raise ValueError(
            f"--resume: {saved} is missing or empty; name the run's settings again with --method "
            f"or --config (a checkpoint is checked against them; a run stopped before its first "
            f"one starts over)"
        )
    write_text_if_changed(saved, dump_yaml(settings))
    warnings.warn(
        f"{saved} was missing or empty: written again from the settings in {checkpoint}, "
        f"which the run resumes with",
        stacklevel=3,
    )


def resumes_own_settings(args: argparse.Namespace) -> bool:
    """Whether `spikegs train` resumes with the run's own settings, RUN/config.yaml: --resume
    where it exists, without --method or --config, or with --method naming a checkpointed run's
    own built-in method (a batch script's one command: after an upgrade that changed the
    method's defaults, the checkpoint was refused as trained with other settings)."""
    saved = Path(args.out) / CONFIG
    given = args.config if args.config is not None else args.method
    same_method = (
        args.config is None
        and given in available_methods()
        and last_checkpoint(args.out).is_file()
        and given == _saved_method(saved)
    )
    return args.resume and saved.is_file() and (given is None or same_method)


def _saved_method(saved: Path) -> str | None:
    """The method a run's config.yaml names; None where it cannot be read."""
    try:
        doc = read_yaml(saved)
    except (OSError, ValueError, yaml.YAMLError):  # (UnicodeDecodeError is a ValueError)
        return None
    return doc.get("method") if isinstance(doc, dict) else None


def print_evaluation(trainer) -> None:
    """Progress without a bar: one line to stderr at each evaluation (a bar garbles logs), with
    the training time left at the pace since the previous one, from the second to the last but
    one; "densifying" while densification rounds remain, which slow the steps as they add
    Gaussians."""
    views, it = trainer.dataset.test_views, trainer.iteration
    left = ""
    if it < trainer.config.train.iterations and math.isfinite(trainer.seconds_left):
        growing = " (densifying)" if trainer.densifies_from(it) else ""
        left = f", ~{trainer.seconds_left:.0f} s of training left{growing}"
    print(
        f"{trainer.config.method}: iteration {it}/{trainer.config.train.iterations}, held-out "
        f"PSNR {trainer.test_psnr:.2f} dB over {len(views)} views ({views[0].name} "
        f"{trainer.first_view_psnr:.2f}), {len(trainer.model):,} Gaussians, "
        f"{trainer.train_seconds:.0f} s{left}",
        file=sys.stderr,
        flush=True,
    )


def run(args: argparse.Namespace) -> int:
    from .data.dataset import reading_dataset

    config = config_from_args(args)  # bad method or config: refused before any work
    check_folder_output(args.out, images=True)  # eval's images go into RUN/eval
    # no simulation or `spikegs poses` rewrites the dataset under the training (Busy while one does)
    with reading_dataset(args.dataset):
        return _train(args, config)


def _train(args: argparse.Namespace, config) -> int:
    """`run` once the dataset is locked."""
    from .data import load_dataset
    from .train import Trainer

    bars = show_bars(args.no_progress)
    dataset = load_dataset(args.dataset, bars)
    settings = Path(args.out) / CONFIG if resumes_own_settings(args) else None
    given = {"train.iterations": args.iterations, "train.seed": args.seed}
    command_line = tuple(key for key, value in given.items() if value is not None)
    trainer = Trainer(
        dataset, config, args.out, bars, settings_file=settings, command_line=command_line
    )
    unprinted = trained = None  # the summary's printing's error; the training's own
    written = Path(args.out) / SUMMARY
    try:
        try:
            trainer.train(args.resume, on_eval=None if bars else print_evaluation)
        except OSError as err:
            trained = err
            raise
        except KeyboardInterrupt:  # (a stopped run said "interrupted" alone: where it stands)
            if trainer.iteration < config.train.iterations and last_checkpoint(args.out).is_file():
                at = trainer.saved_iteration
                say(
                    f"{resume_command(args.out, args.dataset)} continues from its last checkpoint"
                    + ("" if at is None else f", at iteration {at} of {config.train.iterations}")
                )
            raise
        finally:  # a run stopped in its last step finished all the same: its curve and summary
            if trainer.iteration >= config.train.iterations:
                runs = {config.method: (trainer.run_dir, trainer.sim_seconds)}
                save_logged_curves(Path(args.out) / CURVE, runs, dataset)
                # written before a stop is raised; an error before it leaves an earlier
                # finish's train.json, which is not this training's summary
                if trainer.summary is not None:  # (a script reads it from stdout)
                    try:
                        print(strict_json.dumps(trainer.summary, indent=2))
                    except OSError as err:  # a full stdout: the run is finished, no --resume
                        if err.errno not in FULL:
                            raise
                        unprinted = OSError(
                            err.errno,
                            f"{err.strerror}: stdout, where the summary was printed (the run is "
                            f"finished: {written} holds it)",
                        )
                        raise unprinted from err
    except OSError as err:  # a full disk (scene.ply at the end, a checkpoint): said how to go on
        if err is unprinted or err.errno not in FULL or not last_checkpoint(args.out).is_file():
            raise
        where = "" if err.filename is None else f": {err.filename}"
        if err is trained and trainer.summary is not None:  # its progress output's, at the end
            raise OSError(
                err.errno, f"{err.strerror}{where} (the run is finished: {written} holds it)"
            ) from err
        raise OSError(
            err.errno,
            f"{err.strerror}{where}; once there is room, "
            f"{resume_command(args.out, args.dataset)} finishes the run from its last checkpoint",
        ) from err
    return 0
