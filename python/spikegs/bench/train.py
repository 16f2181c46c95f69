"""`spikegs bench train`: PSNR and SSIM against wall-clock training time, every method and scene.

Each built-in scene is simulated once (cached under OUT/data/SCENE) and every method is trained on
it with the demo's schedule (DEMO_OVERRIDES, stretched to the chosen iterations; `grad_threshold`
replaces its densification threshold for every method). PSNR and SSIM
over all test views are measured at regular iterations through the trainer's `on_eval` hook,
outside the timed steps. SIM is trained once per scene (cached with the dataset) and shared by
the methods that use it; its training time is reported separately and counts for those methods:
their curves start at their SIM time. `oracle` (config oracle.yaml) trains on the simulator's clean
instant images: its gain over TFP(33) is the most that any instant target can give at this
schedule. Writes OUT/train.json, OUT/train_SCENE.png, OUT/headline.png (SpikeGS and the baselines
on solids, where any of them ran). By default it trains
METHODS (QUICK_METHODS when quick); `methods` may name any method of configs/ (VARIANTS, the
variant sim17, are not in the default set).

With `seeds` > 1 every run is repeated with train.seed = 0 .. seeds-1 (SIM retrained for each:
its training is part of a method's randomness): scores are means over the seeds, with their
standard deviations and the gains over TFP(33) paired seed by seed, times medians over the seeds
(a run slowed by another job on the machine moves a mean); the plots show seed 0.

The methods' margins are at equal iterations: a SpikeGS step renders K poses and SIM trains first.
With `equal_time` each baseline (BASELINES) is trained again as BASELINE-equal-time, its schedule
stretched to the iterations that take SpikeGS's median seconds, SIM's training included, at the
baseline's own median seconds an iteration (a step's cost grows with the Gaussians, so the time
reached is near SpikeGS's, not equal: the table shows it).
"""

from __future__ import annotations

import copy
import dataclasses
import json
import math
import shutil
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..config import Config, available_methods, load_config
from ..curves import save_curves
from ..data import load_dataset, simulate_dataset
from ..data.dataset import check_output
from ..data.scenes import SCENES
from ..data.simulate import (
    DEFAULT_FRAME_EVERY,
    DEFAULT_SEED,
    DEFAULT_SPEED,
    default_train_every,
    simulated_spp,
)
from ..data.sources import drawn_side
from ..data.trajectory import WORLD_UP
from ..demo import DEMO_OVERRIDES, holds_files
from ..evaluate import SSIMS, score_view
from ..method_titles import EQUAL_TIME  # a baseline's run given SpikeGS's seconds: name, folder
from ..run_folder import refuse_foreign_files
from ..spikes import SimParams
from ..text_table import print_table
from ..train import Trainer
from .common import write_results

BASELINES = ("tfp33", "tfp65", "tfi", "tfp33_smooth_l1")  # the last: TFP(33)+3DGS at our norm
CEILING = "oracle"  # clean instant targets: what perfect supervision gives this trainer
METHODS = ("spikegs", *BASELINES, "only_instant", "only_exposure", "k9", "k13", CEILING)
VARIANTS = ("sim17",)  # the methods of configs/ that METHODS leaves out (`methods` names them)
QUICK_METHODS = ("spikegs", "tfp33")
ABLATION_ORDER = ("spikegs", "only_instant", "only_exposure")  # the paper's Table 3, best first
HEADLINE_SCENE = "solids"  # the default scene; the headline plot shows SpikeGS and BASELINES
POINTS = 8  # evaluations per run
# per run: 600 (the demo has 1500): the full benchmark trains METHODS on every built-in scene
FULL_ITERATIONS = 600
QUICK_ITERATIONS = 100
FULL_DATA = {"height": 128, "width": 128, "readouts": 4000, "test_on_path": 8, "test_off_path": 8}
QUICK_DATA = {"height": 64, "width": 64, "readouts": 600, "test_on_path": 2, "test_off_path": 2}
QUICK_SIM_ITERATIONS = 20


def evaluations(iterations: int) -> int:
    """The evaluations of a run of `iterations` on `schedule`'s: every ⌈iterations / POINTS⌉
    iterations and the last (POINTS, or fewer for a run of fewer iterations: 3 of 3)."""
    return math.ceil(iterations / math.ceil(iterations / POINTS))


def schedule(iterations: int, quick: bool, grad_threshold: float | None = None) -> dict:
    """Config overrides: the demo's schedule with its densification stretched to `iterations`,
    evaluated at POINTS regular iterations, one checkpoint at the end; `grad_threshold` replaces
    the demo's densification threshold (every method alike)."""
    overrides = copy.deepcopy(DEMO_OVERRIDES)
    overrides["train"].update(
        iterations=iterations,
        eval_every=math.ceil(iterations / POINTS),
        checkpoint_every=iterations,
    )
    stretched = load_config(None, DEMO_OVERRIDES).with_iterations(iterations).densify
    overrides["densify"] = {k: getattr(stretched, k) for k in DEMO_OVERRIDES["densify"]}
    if grad_threshold is not None:
        overrides["densify"]["grad_threshold"] = grad_threshold
    if quick:
        overrides["sim"]["iterations"] = QUICK_SIM_ITERATIONS
    return overrides


def _matches(dataset, scene: str, settings: dict) -> bool:
    """Whether a loaded dataset was simulated from `scene` with `settings`, and otherwise as the
    benchmark simulates (`SIMULATED`: a `spikegs simulate --color --threshold 10 --seed 7` of its
    size was its data, unsaid), its poses not replaced by `spikegs poses`."""
    meta, views = dataset.meta, dataset.test_views
    if any(meta.get(key) != value for key, value in SIMULATED.items()) or "poses_from" in meta:
        return False
    on_path = sum(v.readout is not None for v in views)
    ts = np.asarray(dataset.train_timestamps)
    want_every = default_train_every(settings["readouts"])
    every = int(np.diff(ts).min()) if len(ts) > 1 else want_every
    spp = simulated_spp(meta)
    found = (meta["scene"], meta["height"], meta["width"], meta["num_readouts"], every, spp)
    want = (scene, *(settings[k] for k in ("height", "width", "readouts")), want_every)
    want += (settings["spp"],)
    views_wanted = (settings["test_on_path"], settings["test_off_path"])
    return found == want and (on_path, len(views) - on_path) == views_wanted


# meta.json's records of what `simulate_dataset` takes at its defaults, as JSON reads them back
SIMULATED = json.loads(
    json.dumps(
        {
            "channels": 1,
            "flip": True,
            "seed": DEFAULT_SEED,
            "sim": dataclasses.asdict(SimParams()),
            "degrees_per_readout": DEFAULT_SPEED,
            "frame_every": DEFAULT_FRAME_EVERY,
            "up": WORLD_UP.tolist(),
        }
    )
)


def dataset_for(scene: str, root: Path, settings: dict) -> tuple:
    """(dataset, seconds simulating): the one cached at `root` when it matches, else simulated."""
    try:
        dataset = load_dataset(root)
        if _matches(dataset, scene, settings):
            return dataset, 0.0
    except (FileNotFoundError, ValueError, KeyError):
        pass
    if holds_files(root):  # (a folder holding its lock alone is an empty one)
        print(
            f"{root}: a dataset simulated at other settings (a full run's and a --quick one's "
            f"differ, as do two --spp), or incomplete; replaced"
        )
    start = time.perf_counter()
    dataset = simulate_dataset(scene, root, overwrite=True, progress=False, **settings)
    return dataset, time.perf_counter() - start


def uses_sim(config: Config) -> bool:
    return config.instant_target() == "sim"


def held_out_scores(trainer: Trainer, ssims: tuple[str, ...] = ("ssim",)) -> dict[str, float]:
    """Mean PSNR and the `ssims` (evaluate.SSIMS; the tables' is scikit-image's "ssim") of the
    trainer's model over every test view of its dataset."""
    ds = trainer.dataset
    scores = [score_view(trainer.model, view, ds, trainer.scale, ssims) for view in ds.test_views]
    return {k: float(np.mean([s[k] for s in scores])) for k in ("psnr", *ssims)}


def run_name(method: str, seed: int) -> str:
    """The folder of `method`'s run with `seed` in OUT/runs/SCENE (seed 0: the method's name)."""
    return method if seed == 0 else f"{method}-seed{seed}"


def train_method(dataset, config: Config, run_dir: Path) -> dict:
    """Train one method afresh in `run_dir`; its curve, final scores and times."""
    shutil.rmtree(run_dir, ignore_errors=True)
    start = time.perf_counter()
    curve = []

    def record(trainer: Trainer) -> None:
        point = {"iteration": trainer.iteration, "train_seconds": trainer.train_seconds}
        # the final scores with 3DGS's SSIM too (the papers'), the curve's points without
        final = trainer.iteration == config.train.iterations
        scores = held_out_scores(trainer, tuple(SSIMS) if final else ("ssim",))
        curve.append({**point, **scores, "gaussians": len(trainer.model)})

    trainer = Trainer(dataset, config, run_dir, progress=False, resumable=False)
    summary = trainer.train(on_eval=record)
    return {
        "psnr": curve[-1]["psnr"],
        "ssim": curve[-1]["ssim"],
        "ssim_3dgs": curve[-1]["ssim_3dgs"],
        "train_seconds": summary["train_seconds"],
        "sim_seconds": summary["sim_seconds"],  # trained now, or the cached SIM's recorded time
        "uses_sim": uses_sim(config),
        "gaussians": summary["gaussians"],
        "iterations": summary["iterations"],
        "wall_seconds": time.perf_counter() - start,  # with targets, SIM and evaluations
        "curve": curve,  # time axis of the plots: sim_seconds + train_seconds
    }


def _seeds(dataset, config: Config, seeds: int, root: Path, name: str) -> dict:
    """`config` trained with seeds 0 .. `seeds` - 1 in root/run_name(name, seed), each run's
    line printed; `over_seeds` of them."""
    per_seed = []
    for seed in range(seeds):
        r = train_method(dataset, seeded(config, seed), root / run_name(name, seed))
        per_seed.append(r)
        print(
            f"  {root.name} {name} seed {seed}: {r['psnr']:.2f} dB ({r['iterations']} "
            f"iterations); {r['train_seconds']:.1f} s training, {r['wall_seconds']:.1f} s in all"
        )
    return over_seeds(per_seed)


def seeded(config: Config, seed: int) -> Config:
    """`config` with train.seed = `seed` (which also seeds its SIM)."""
    config = copy.deepcopy(config)
    config.train.seed = seed
    return config


def _mean_and_std(values: list[float]) -> tuple[float, float | None]:
    """Mean and sample standard deviation (None for a single value: no spread measured, where
    0.0 read as seeds that agreed)."""
    return float(np.mean(values)), float(np.std(values, ddof=1)) if len(values) > 1 else None


SCORES = ("psnr", "ssim", "ssim_3dgs", "gaussians")  # averaged over the seeds
TIMES = ("train_seconds", "sim_seconds", "wall_seconds")  # their medians over the seeds


def over_seeds(runs: list[dict]) -> dict:
    """One method's runs on one scene, one per seed -> seed 0's run (its curve, for the plots)
    with the scores replaced by their means and standard deviations, the times by their
    medians, and every seed's of both."""
    merged = dict(runs[0])
    merged["curve_sim_seconds"] = runs[0]["sim_seconds"]  # the curve's own offset: seed 0's SIM
    for key in SCORES:
        mean, std = _mean_and_std([r[key] for r in runs])
        merged[key] = mean
        if key in ("psnr", "ssim"):
            merged[f"{key}_std"] = std
    for key in TIMES:
        merged[key] = float(np.median([r[key] for r in runs]))
    merged["seeds"] = [{k: r[k] for k in (*SCORES, *TIMES)} for r in runs]
    return merged


def paired_gains(methods: dict, base: str = "tfp33") -> dict[str, dict]:
    """PSNR gain of each method over `base`, seed by seed: name -> {"mean", "std"} (its sample
    standard deviation, None for one seed)."""
    if base not in methods:
        return {}
    reference = [s["psnr"] for s in methods[base]["seeds"]]
    gains = {
        name: _mean_and_std([s["psnr"] - b for s, b in zip(r["seeds"], reference)])
        for name, r in methods.items()
    }
    return {name: {"mean": mean, "std": std} for name, (mean, std) in gains.items()}


def ablation_order(methods: dict) -> str | None:
    """'holds' when the mean PSNRs follow the paper's ablation strictly (both losses > only
    instant > only exposure), else the order found, equal means joined by '=' (a tie is no
    lead: sorted, it would have read as the paper's order); None when a method of it was not
    run."""
    if not all(m in methods for m in ABLATION_ORDER):
        return None
    found = sorted(ABLATION_ORDER, key=lambda m: -methods[m]["psnr"])
    psnr = [methods[m]["psnr"] for m in found]
    if tuple(found) == ABLATION_ORDER and psnr[0] > psnr[1] > psnr[2]:
        return "holds"
    order = found[0]
    for name, higher, lower in zip(found[1:], psnr, psnr[1:]):
        order += f" {'=' if lower == higher else '>'} {name}"
    return order


def ablation_seeds(methods: dict) -> int | None:
    """On how many seeds the paper's ablation order held strictly, run by run (the seeds pair
    as the gains do); None when a method of it was not run."""
    if not all(m in methods for m in ABLATION_ORDER):
        return None
    per_seed = zip(*(methods[m]["seeds"] for m in ABLATION_ORDER))
    return sum(
        both["psnr"] > instant["psnr"] > exposure["psnr"] for both, instant, exposure in per_seed
    )


def ablation_line(methods: dict) -> str | None:
    """The printed verdict on the paper's ablation order: `ablation_order` of the means, and,
    where it holds over several seeds, on how many of them (a mean can hold where a seed
    does not); None when a method of it was not run."""
    order = ablation_order(methods)
    if order is None:
        return None
    seeds = len(methods[ABLATION_ORDER[0]]["seeds"])
    if seeds == 1:
        order += " (one seed)"
    elif order == "holds":
        order = f"holds in the mean over {seeds} seeds, on {ablation_seeds(methods)} of them"
    else:
        order += f" (means over {seeds} seeds)"
    return f"paper's ablation order (both > only instant > only exposure): {order}"


def equal_time_margins(methods: dict) -> dict[str, dict]:
    """SpikeGS's PSNR margin, seed by seed (`paired_gains`), over each baseline that has an
    equal-time run, at equal iterations (its own run) and at equal time (that run): name ->
    {"mean", "std"}; {} where none was trained."""
    names = [m for b in BASELINES if b + EQUAL_TIME in methods for m in (b, b + EQUAL_TIME)]
    return {name: paired_gains(methods, name)["spikegs"] for name in names}


def equal_time_lines(methods: dict, margins: dict[str, dict]) -> list[str]:
    """The printed margins of `equal_time_margins`: each baseline's at equal iterations and at
    equal time, with the seconds that time reached against SpikeGS's budget (medians)."""
    lines = []
    for name in [m for m in margins if m.endswith(EQUAL_TIME)]:
        budget = methods["spikegs"]["train_seconds"] + methods["spikegs"]["sim_seconds"]
        base = name.removesuffix(EQUAL_TIME)
        at = {m: f"{margins[m]['mean']:+.2f}" for m in (base, name)}
        lines.append(
            f"SpikeGS's margin over {base}: {at[base]} dB at equal iterations, {at[name]} dB at "
            f"equal time ({name}: {methods[name]['iterations']} iterations in "
            f"{methods[name]['train_seconds']:.1f} s, SpikeGS {budget:.1f} s with SIM's training)"
        )
    return lines


def _table(methods: dict, gains: dict[str, dict], iterations: bool = False) -> list[dict]:
    """The paper's Tables 1-3 analogue for one scene: scores, times, `gains` over TFP(33)
    (`paired_gains`; means over the seeds, ± their standard deviations when there are several);
    with `iterations` each method's (seed 0's: the -equal-time runs train more)."""

    def spread(mean: float, std: float | None, digits: int) -> str | float:
        return mean if std is None else f"{mean:.{digits}f} ± {std:.{digits}f}"

    return [
        {
            "method": name,
            **({"iterations": r["iterations"]} if iterations else {}),
            "PSNR": spread(r["psnr"], r["psnr_std"], 2),
            "SSIM": spread(r["ssim"], r["ssim_std"], 3),
            "train s": r["train_seconds"],
            "SIM s": r["sim_seconds"] if r["uses_sim"] else "-",
            "Gaussians": int(round(r["gaussians"])),
            "gain over tfp33 (dB)": spread(**gains[name], digits=2) if name in gains else "-",
        }
        for name, r in methods.items()
    ]


def selection(
    quick: bool,
    scenes: Sequence[str] | None = None,
    methods: Sequence[str] | None = None,
    seeds: int = 1,
    equal_time: bool = False,
) -> tuple[list[str], list[str]]:
    """The scenes and methods a run trains (defaults filled in: METHODS, or QUICK_METHODS when
    quick; any method of configs/ may be named, e.g. the variant sim17); ValueError naming what
    is unknown, with the known ones, before any work starts. A name given twice runs once.
    `equal_time` needs spikegs and a baseline among the methods."""
    scenes = list(dict.fromkeys(scenes or ([HEADLINE_SCENE] if quick else SCENES)))
    methods = list(dict.fromkeys(methods or (QUICK_METHODS if quick else METHODS)))
    known = [*METHODS, *(m for m in available_methods() if m not in METHODS)]
    refused = [
        f"--{option} {', '.join(unknown)}: unknown; known: {', '.join(names)}"
        for option, given, names in (("scenes", scenes, SCENES), ("methods", methods, known))
        if (unknown := [name for name in given if name not in names])
    ]
    if seeds < 1:
        refused.append(f"--seeds: expected >= 1, found {seeds}")
    if refused:
        raise ValueError(f"bench train {'; '.join(refused)}")
    if equal_time and ("spikegs" not in methods or not equal_time_methods(methods)):
        raise ValueError(
            f"bench train --equal-time: expected spikegs and a baseline ({', '.join(BASELINES)}) "
            f"among the methods, found {', '.join(methods)}"
        )
    return scenes, methods


def run_names(methods: Sequence[str], equal_time: bool) -> list[str]:
    """Every run's method name: `methods`, and with `equal_time` their baselines' at SpikeGS's
    time."""
    return [*methods, *(m + EQUAL_TIME for m in equal_time_methods(methods) if equal_time)]


def equal_time_methods(methods: Sequence[str]) -> list[str]:
    """The baselines among `methods`, each trained again at SpikeGS's time with `equal_time`."""
    return [m for m in methods if m in BASELINES]


def equal_time_iterations(runs: dict, method: str, iterations: int) -> int:
    """The iterations that give `method` SpikeGS's median seconds, SIM's training included:
    `iterations` scaled by the ratio of the two methods' median times (runs: over_seeds's)."""
    budget = runs["spikegs"]["train_seconds"] + runs["spikegs"]["sim_seconds"]
    return max(iterations, round(iterations * budget / max(runs[method]["train_seconds"], 1e-9)))


def _refuse_file(folder: Path, what: str) -> None:
    """FileExistsError where a file stands at `folder`, where the benchmark writes its `what`: it
    failed late, "[Errno 20] Not a directory", after the parts before train (OUT/data passed
    check_output, its scene's folder neither existing nor a folder)."""
    if folder.exists() and not folder.is_dir():
        raise FileExistsError(
            f"{folder} is a file, where the benchmark writes its {what}; give another --out"
        )


def check_outputs(out: Path, scenes: Sequence[str], methods: Sequence[str], seeds: int) -> None:
    """Refuse, before any work, a user's files where the benchmark writes: each run is trained
    afresh, its folder deleted first, and a scene's dataset folder replaced unless it matches."""
    for top in ("data", "runs"):
        _refuse_file(Path(out) / top, top)
    for scene in scenes:
        # (the remedy was "give an empty or new folder": one --out sets)
        check_output(
            Path(out) / "data" / scene,
            True,
            "the benchmark simulates its scene there: give another --out",
        )
        # the run folders there that a run would delete (every name of --seeds 2**63 - 1 was
        # checked, for ever)
        runs = Path(out) / "runs" / scene
        _refuse_file(runs, "runs")
        for folder in sorted(runs.iterdir()) if runs.is_dir() else []:
            method, _, seed = folder.name.rpartition("-seed")
            seeded = seed.isdecimal() and method in methods and int(seed) < seeds
            if folder.name in methods or (seeded and folder.name == run_name(method, int(seed))):
                if not folder.is_dir():  # (refused once the scene was simulated, tens of seconds)
                    raise FileExistsError(
                        f"{folder} is a file, where the benchmark writes a run; give another --out"
                    )
                refuse_foreign_files(
                    folder, ", which the benchmark would delete with its run; give another --out"
                )


def data_settings(quick: bool, spp) -> dict:
    """The scenes' simulation settings (QUICK_DATA or FULL_DATA) at `spp` samples a pixel;
    ValueError, before any work, where the frames cannot be drawn at it (`drawn_side`: not a
    square, past the rasterizer's side or half the memory)."""
    data = QUICK_DATA if quick else FULL_DATA
    drawn_side(spp, data["width"], data["height"])
    return {**data, "spp": int(spp)}


def run(
    quick: bool,
    out: Path,
    iterations: int | None = None,
    seeds: int = 1,
    scenes: Sequence[str] | None = None,
    methods: Sequence[str] | None = None,
    grad_threshold: float | None = None,
    equal_time: bool = False,
    spp: int = 1,
) -> dict:
    """Train `methods` (default: METHODS, QUICK_METHODS when quick) on `scenes` (default: every
    built-in one, HEADLINE_SCENE when quick) with `seeds` seeds each, densifying at the demo's
    threshold or `grad_threshold`, and with `equal_time` each baseline again at SpikeGS's time;
    the scenes simulated at `spp` samples a pixel (ProceduralSource: a square, 1 the centres);
    print a table per scene, write JSON and plots."""
    iterations = iterations or (QUICK_ITERATIONS if quick else FULL_ITERATIONS)
    scenes, methods = selection(quick, scenes, methods, seeds, equal_time)
    settings = data_settings(quick, spp)
    overrides = schedule(iterations, quick, grad_threshold)
    length = f"{iterations} iterations"  # the tables' and plots' schedule, as given
    if grad_threshold is not None:
        length += f", densify threshold {grad_threshold:g}"
    # the -equal-time runs train more: the scene's table and plot say so
    stretched = f", BASELINE{EQUAL_TIME} as many as SpikeGS's seconds take" if equal_time else ""
    configs = {m: load_config(m, overrides) for m in methods}
    check_outputs(out, scenes, run_names(methods, equal_time), seeds)
    start = time.perf_counter()
    results = {}
    for scene in scenes:
        scene_start = time.perf_counter()
        dataset, simulate_s = dataset_for(scene, out / "data" / scene, settings)
        runs = {}
        for method, config in configs.items():
            runs[method] = _seeds(dataset, config, seeds, out / "runs" / scene, method)
        for method in equal_time_methods(methods) if equal_time else ():
            n = equal_time_iterations(runs, method, iterations)
            config = load_config(method, schedule(n, quick, grad_threshold))
            name = method + EQUAL_TIME
            runs[name] = _seeds(dataset, config, seeds, out / "runs" / scene, name)
        wall = time.perf_counter() - scene_start
        order = ablation_order(runs)
        results[scene] = {
            "simulate_seconds": simulate_s,
            "wall_seconds": wall,
            "methods": runs,
            "gain_over_tfp33_db": paired_gains(runs),
            "spikegs_margin_db": equal_time_margins(runs),
            "ablation_order": order,
            "ablation_order_seeds": ablation_seeds(runs),
        }
        size = f"{dataset.width}x{dataset.height}" + (f" at {spp} spp" if spp > 1 else "")
        print(
            f"{scene} ({size}, {len(dataset.test_views)} test views, {length}{stretched}, "
            f"{seeds} seed{'s' if seeds > 1 else ''})"
        )
        print_table(_table(runs, results[scene]["gain_over_tfp33_db"], equal_time))
        if CEILING in runs:
            print(
                f"{CEILING}: trained on the clean instant images (one render a step): the "
                "ceiling of instant targets; the exposure loss renders K poses a step"
            )
        if order is not None:
            print(ablation_line(runs))
        for line in equal_time_lines(runs, results[scene]["spikegs_margin_db"]):
            print(line)
        views = f"mean over the {len(dataset.test_views)} test views, seed 0's run"
        title = f"{scene} {size}, {length} per method{stretched}; {views}"
        save_curves(out / f"train_{scene}.png", runs, ("psnr", "ssim"), title)
    headline = results.get(HEADLINE_SCENE, {}).get("methods", {})
    shown = {m: r for m, r in headline.items() if m in ("spikegs", *BASELINES)}
    if shown:  # (an ablation or the oracle alone has no headline: an empty plot, before)
        title = f"{HEADLINE_SCENE} {size}: SpikeGS vs baselines, {length}; {views}"
        save_curves(out / "headline.png", shown, ("psnr",), title)
    payload = {
        "data": {**settings, "train_every": default_train_every(settings["readouts"])},
        "iterations": iterations,
        "equal_time": equal_time,
        "seeds": seeds,
        "schedule": overrides,
        "points_per_run": evaluations(iterations),
        "time_axis": "SIM methods: sim_seconds + train_seconds; others: train_seconds "
        "(the steps: updates, densification and each timestamp's targets made at its first visit; "
        "evaluations, checkpoints and SIM's training excluded)",
        "scores": "mean PSNR (dB, data range 1) and SSIM over every test view; ssim: "
        "scikit-image's (7x7 uniform window), ssim_3dgs: 3DGS's evaluation's (11x11 Gaussian, "
        "the final scores only)",
        "total_seconds": time.perf_counter() - start,
        "scenes": results,
    }
    write_results(out, "train", payload, quick)
    stale = [f"train_{s}.png" for s in SCENES if s not in scenes]
    _remove_stale_figures(out, stale + ([] if shown else ["headline.png"]))
    return payload


def _remove_stale_figures(out: Path, names: list[str]) -> None:
    """Delete an earlier run's figures `names` in OUT, which the train.json just written does
    not describe (a re-run with other scenes, or with no headline method, left them beside it),
    said in a line."""
    removed = [name for name in names if (out / name).is_file()]
    for name in removed:
        (out / name).unlink()
    if removed:
        print(f"removed an earlier run's {', '.join(removed)}, of scenes or methods not run now")
