"""Error against run time, plotted: held-out scores of training runs against their seconds, the
runs that train SIM first starting at SIM's training time (matplotlib)."""

from __future__ import annotations

import json
import re
import textwrap
from pathlib import Path

from .atomic_save import save_figure
from .method_titles import method_title
from .pyplot_agg import pyplot
from .regular_file import read_text
from .run_summary import LOG


def _logged_evaluations(run_dir: str | Path) -> list[dict]:
    """RUN/log.jsonl's evaluation records, in order."""
    lines = read_text(Path(run_dir) / LOG).splitlines()
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
    against = _pseudo_note(views if means else views[:1])
    save_curves(path, methods, ("psnr",), f"{scene}: PSNR {scored} during training{against}")


def _pseudo_note(views) -> str:
    """The title's ', against TFP pseudo ground truth' where test `views` are scored against TFP
    of their own spikes (a recording's `pseudo_*` views, which flatter TFP-like methods: the
    title read as scored against the truth), with how many where some are not; '' where none."""
    from .data.dataset import PSEUDO_PREFIX

    pseudo = sum(view.name.startswith(PSEUDO_PREFIX) for view in views)
    if not pseudo:
        return ""
    some = "" if pseudo == len(views) else f" ({pseudo} of them)"
    return f", against TFP pseudo ground truth{some}"


def _as_text(text: str) -> str:
    """`text` (a method, scene or view name) drawn as written: matplotlib reads $...$ as TeX and
    refused a method named "lam$^$2" at the end of its run; a name's bytes that are not UTF-8 (a
    Latin-1 folder's, os.fsdecode's surrogate escapes) drawn as U+FFFD, where the font refused
    them (TypeError) at the end of the run; any other lone surrogate (JSON's "\\ud800") too."""
    return re.sub("[\ud800-\udfff]", "\ufffd", text).replace("$", r"\$")


# Okabe and Ito's colours, told apart with colour-blindness; each method a marker of its own too,
# for greyscale print (8 colours and 11 markers: the first 88 methods differ in one or both); past
# the eighth, methods take the colours again with dotted lines
COLOURS = ("#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00", "#56B4E9", "#000000", "#F0E442")
MARKERS = ("o", "s", "^", "v", "D", "P", "X", "*", "<", ">", "h")
LINES = {True: ("-", ":"), False: ("--", "-.")}  # a SIM method's, another's; by colour cycle
LABELS = {"psnr": "PSNR (dB)", "ssim": "SSIM (scikit-image, 7×7 window)"}
# a log time axis is named at the densest of these (× 10^k) whose labels stand apart as it is laid
# out: 1-9 named 800, 900 and 1000 over one another over 100-900 s, 1, 2, 5 1000 and 2000 over
# 2-5000 s
LOG_SUBS = (range(1, 10), (1.0, 2.0, 3.0, 5.0), (1.0, 2.0, 5.0), (1.0, 3.0), (1.0,))
LEGEND_WRAP = 32  # characters a line of a legend entry (a config's long name)


def _draws_sim(methods: dict) -> bool:
    """Whether a SIM method is among the curves of `methods` (`save_curves`')."""
    return any(r["uses_sim"] for r in methods.values())


def _plot_curves(axes, methods: dict, metrics: tuple[str, ...]) -> None:
    """One line per method of each metric against seconds (SIM methods offset by their SIM time,
    solid or dotted; the others dashed or dash-dotted); the legend right of the last axes, off
    the curves (inside, it hid the headline's SpikeGS curve and half the lines of `bench
    train`'s 15)."""
    from matplotlib.ticker import FuncFormatter, NullFormatter

    sim_drawn = _draws_sim(methods)  # the time axis holds SIM's seconds
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
            ax.plot(seconds, values, label=_as_text(textwrap.fill(label, LEGEND_WRAP)), **style)
    for ax, metric in zip(axes, metrics):
        low, high = ax.dataLim.intervalx  # the seconds plotted
        if high >= 3 * low:  # (under a factor 3, 170-190 s: a linear axis, which names its ticks;
            ax.set_xscale("log")  # a log one named none)
            ax.xaxis.set_major_formatter(FuncFormatter(lambda x, _: f"{x:g}"))
            ax.xaxis.set_minor_formatter(NullFormatter())
            _fit_log_ticks(ax)
        ax.set_xlabel(f"seconds ({'SIM + ' * sim_drawn}training)")
        ax.set_ylabel(LABELS.get(metric, metric))
        ax.grid(True, which="both", alpha=0.3)
    axes[-1].legend(loc="upper left", bbox_to_anchor=(1.03, 1.0), borderaxespad=0, fontsize=8)


def _fit_log_ticks(ax) -> None:
    """Name log axis `ax`'s seconds at the densest of LOG_SUBS whose labels, as `ax` is now
    laid out, stand at least half a character apart."""
    from matplotlib.ticker import LogLocator

    renderer = ax.figure.canvas.get_renderer()
    for subs in LOG_SUBS:
        ax.xaxis.set_major_locator(LogLocator(base=10, subs=subs))
        ax.xaxis.get_tightbbox(renderer)  # the ticks and their labels for the axis's limits
        low, high = ax.get_xlim()
        labels = [t.label1 for t in ax.xaxis.get_major_ticks() if low <= t.get_loc() <= high]
        boxes = sorted(
            (t.get_window_extent(renderer) for t in labels if t.get_text()), key=lambda b: b.x0
        )
        gap = labels[0].get_size() * ax.figure.dpi / 72 / 2 if labels else 0.0  # pixels
        if all(a.x1 + gap <= b.x0 for a, b in zip(boxes, boxes[1:])):
            return


def save_curves(path: Path, methods: dict, metrics: tuple[str, ...], title: str) -> None:
    """Plot `methods` ({name: {"curve": [{"train_seconds", METRIC, ...}], "sim_seconds",
    "uses_sim"}}) to `path`, one panel per metric (`curves_figure`)."""
    save_figure(curves_figure(methods, metrics, title), path)


def curves_figure(methods: dict, metrics: tuple[str, ...], title: str):
    """The matplotlib figure of `save_curves`: the panels 5.5 inches wide each, the figure wider
    by the legend; `title` and, where a SIM method is drawn, a line saying where its curve starts
    (a baseline's alone trains no SIM)."""
    plt = pyplot()
    if _draws_sim(methods):
        title += "\n(a SIM method's curve starts after SIM's training)"

    width = 5.5 * len(metrics)  # inches
    fig, axes = plt.subplots(1, len(metrics), figsize=(width, 4.2), squeeze=False)
    _plot_curves(axes[0], methods, metrics)
    legend = axes[0][-1].get_legend().get_window_extent(fig.canvas.get_renderer())
    fig.set_figwidth(width + legend.width / fig.dpi)
    lines = [textwrap.fill(line, int(13 * width)) for line in title.split("\n")]  # ~13 a inch
    fig.suptitle(_as_text("\n".join(lines)), fontsize=10)
    fig.tight_layout()
    for ax in axes[0]:
        if ax.get_xscale() == "log":
            _fit_log_ticks(ax)  # again, the axes as laid out
    return fig
