"""Error against run time, plotted: held-out scores of training runs against their seconds, the
runs that train SIM first starting at SIM's training time (matplotlib)."""

from __future__ import annotations

import json
import textwrap
from pathlib import Path

from .atomic_save import save_figure
from .method_titles import method_title
from .run_summary import LOG


def _logged_evaluations(run_dir: str | Path) -> list[dict]:
    """RUN/log.jsonl's evaluation records, in order."""
    lines = (Path(run_dir) / LOG).read_text().splitlines()
    return [r for r in map(json.loads, lines) if "psnr" in r]


def _psnr_key(runs: list[list[dict]]) -> str:
    """The PSNR that every evaluation of `runs` holds: "psnr_mean" (over every test view, as
    eval.json's psnr) where each logged it, else "psnr" (the first test view's: a log of an
    earlier version, in part or whole)."""
    return "psnr_mean" if all("psnr_mean" in r for run in runs for r in run) else "psnr"


def _curve(evaluations: list[dict], key: str) -> list[dict]:
    """[{"iteration", "train_seconds", "psnr"}] of logged `evaluations`, the PSNR under `key`."""
    return [
        {"iteration": r["iteration"], "train_seconds": r["seconds"], "psnr": r[key]}
        for r in evaluations
    ]


def logged_curve(run_dir: str | Path) -> list[dict]:
    """RUN's logged test PSNR against its training seconds, [{"iteration", "train_seconds",
    "psnr"}] (over every test view, or an earlier log's first view: `_psnr_key`)."""
    evaluations = _logged_evaluations(run_dir)
    return _curve(evaluations, _psnr_key([evaluations]))


def save_logged_curves(path: Path, runs: dict[str, tuple[Path, float]], dataset) -> None:
    """Plot the logged PSNR of `runs` ({method: (RUN, SIM's training seconds)}, trained on
    `dataset`) to `path`, each curve starting after its SIM's training."""
    logs = {name: _logged_evaluations(run_dir) for name, (run_dir, _) in runs.items()}
    key = _psnr_key(list(logs.values()))  # one for every curve: the title names it
    methods = {
        name: {"curve": _curve(logs[name], key), "sim_seconds": sim, "uses_sim": sim > 0}
        for name, (_, sim) in runs.items()
    }
    scene = dataset.meta.get("scene") or Path(dataset.root).name
    views = dataset.test_views
    means = key == "psnr_mean"
    scored = f"over the {len(views)} test views" if means else f"of the test view {views[0].name}"
    title = (
        f"{scene}: PSNR {scored} during training\n"
        f"(a SIM method's curve starts after SIM's training)"
    )
    save_curves(path, methods, ("psnr",), title)


def _as_text(text: str) -> str:
    """`text` (a method, scene or view name) drawn as written: matplotlib reads $...$ as TeX and
    refused a method named "lam$^$2" at the end of its run."""
    return text.replace("$", r"\$")


# Okabe and Ito's colours, told apart with colour-blindness; each method a marker of its own too,
# for greyscale print (8 colours and 11 markers: the first 88 methods differ in one or both); past
# the eighth, methods take the colours again with dotted lines
COLOURS = ("#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00", "#56B4E9", "#000000", "#F0E442")
MARKERS = ("o", "s", "^", "v", "D", "P", "X", "*", "<", ">", "h")
LINES = {True: ("-", ":"), False: ("--", "-.")}  # a SIM method's, another's; by colour cycle
LABELS = {"psnr": "PSNR (dB)", "ssim": "SSIM (scikit-image, 7×7 window)"}


def _plot_curves(axes, methods: dict, metrics: tuple[str, ...]) -> None:
    """One line per method of each metric against seconds (SIM methods offset by their SIM time,
    solid or dotted; the others dashed or dash-dotted)."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    for i, (name, r) in enumerate(methods.items()):
        offset = r.get("curve_sim_seconds", r["sim_seconds"])  # the curve is seed 0's
        seconds = [offset + p["train_seconds"] for p in r["curve"]]
        sim = r["uses_sim"]
        label = method_title(name) + (f" (from SIM {offset:.0f} s)" if sim else "")
        style = {
            "color": COLOURS[i % len(COLOURS)],
            "marker": MARKERS[i % len(MARKERS)],
            "linestyle": LINES[sim][i // len(COLOURS) % 2],
        }
        for ax, metric in zip(axes, metrics):
            values = [p[metric] for p in r["curve"]]
            ax.plot(seconds, values, label=_as_text(label), **style)
    for ax, metric in zip(axes, metrics):
        low, high = ax.dataLim.intervalx  # the seconds plotted
        if high >= 3 * low:  # seconds labelled 1, 2, 5, 10, ... (matplotlib's 3x10^0 overlapped);
            ax.set_xscale("log")  # within a decade (150-600 s) every 100: 1, 2, 5 named two
            subs = range(1, 10) if high < 10 * low else (1.0, 2.0, 5.0)
            ax.xaxis.set_major_locator(LogLocator(base=10, subs=subs))
            ax.xaxis.set_major_formatter(FuncFormatter(lambda x, _: f"{x:g}"))
            ax.xaxis.set_minor_formatter(NullFormatter())
        # (under a factor 3, 170-190 s: a linear axis, which names its ticks; a log one named none)
        ax.set_xlabel("seconds (SIM + training)")
        ax.set_ylabel(LABELS.get(metric, metric))
        ax.grid(True, which="both", alpha=0.3)
    axes[-1].legend(fontsize=8)


def save_curves(path: Path, methods: dict, metrics: tuple[str, ...], title: str) -> None:
    """Plot `methods` ({name: {"curve": [{"train_seconds", METRIC, ...}], "sim_seconds",
    "uses_sim"}}) to `path`, one panel per metric."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    width = 5.5 * len(metrics)  # inches
    fig, axes = plt.subplots(1, len(metrics), figsize=(width, 4.2), squeeze=False)
    _plot_curves(axes[0], methods, metrics)
    lines = [textwrap.fill(line, int(13 * width)) for line in title.split("\n")]  # ~13 a inch
    fig.suptitle(_as_text("\n".join(lines)), fontsize=10)
    fig.tight_layout()
    save_figure(fig, path)
