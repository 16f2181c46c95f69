"""Error-against-time curves (curves.py): what log.jsonl gives, and where each method's curve
lies on the time axis (a SIM method's after SIM's training)."""

import json
import os
import subprocess
import sys
from types import SimpleNamespace

import numpy as np
import pytest
from spikegs import curves
from spikegs.curves import (
    LEGEND_WRAP,
    _plot_curves,
    curves_figure,
    logged_curve,
    save_logged_curves,
)
from spikegs.method_titles import method_title


def _log(run_dir, records):
    run_dir.mkdir(parents=True, exist_ok=True)
    (run_dir / "log.jsonl").write_text("".join(json.dumps(r) + "\n" for r in records))
    return run_dir


LOG = [  # a training step's record has no psnr; an evaluation's has
    {"iteration": 10, "seconds": 0.5, "loss": 0.3},
    {"iteration": 50, "seconds": 2.25, "loss": 0.1, "psnr": 21.0},
    {"iteration": 60, "seconds": 2.75, "loss": 0.1},
    {"iteration": 80, "seconds": 3.5, "psnr": 22.5},
]


def test_logged_curve_is_the_evaluations_with_their_training_seconds(tmp_path):
    assert logged_curve(_log(tmp_path / "run", LOG)) == [
        {"iteration": 50, "train_seconds": 2.25, "psnr": 21.0},
        {"iteration": 80, "train_seconds": 3.5, "psnr": 22.5},
    ]


def test_the_curve_is_the_mean_over_the_test_views_where_every_evaluation_logged_it(
    tmp_path, monkeypatch
):
    """curve.png showed the first test view's PSNR (~1 dB from eval.json's mean over the views):
    the mean where each evaluation logged it (psnr_mean), else (an earlier version's log, in part
    or whole) the first view's, and the title says which."""
    means = [dict(r, psnr_mean=r["psnr"] + 1.0) if "psnr" in r else r for r in LOG]
    assert [p["psnr"] for p in logged_curve(_log(tmp_path / "new", means))] == [22.0, 23.5]
    resumed = [*LOG[:2], *means[2:]]  # an older version's evaluation, then the new one's
    assert [p["psnr"] for p in logged_curve(_log(tmp_path / "old", resumed))] == [21.0, 22.5]
    titles, drawn = [], []

    def save(path, methods, metrics, title):
        titles.append(title)
        drawn.append({name: [p["psnr"] for p in m["curve"]] for name, m in methods.items()})

    monkeypatch.setattr(curves, "save_curves", save)
    views = [SimpleNamespace(name=f"view_{i}") for i in range(3)]
    dataset = SimpleNamespace(meta={"scene": "solids"}, root=tmp_path, test_views=views)
    save_logged_curves(tmp_path / "a.png", {"spikegs": (tmp_path / "new", 1.0)}, dataset)
    save_logged_curves(tmp_path / "b.png", {"tfp33": (tmp_path / "old", 0.0)}, dataset)
    both = {"spikegs": (tmp_path / "new", 1.0), "tfp33": (tmp_path / "old", 0.0)}
    save_logged_curves(tmp_path / "c.png", both, dataset)  # (a demo resumed across versions)
    assert titles[0].startswith("solids: PSNR over the 3 test views during training")
    assert titles[1].startswith("solids: PSNR of the test view view_0 during training")
    assert titles[2].split("\n")[0] == titles[1]  # (tfp33 alone: no note on SIM's time)
    assert drawn[2] == {"spikegs": [21.0, 22.5], "tfp33": [21.0, 22.5]}


def test_the_title_says_where_views_are_scored_against_a_pseudo_ground_truth(tmp_path, monkeypatch):
    """A recording's pseudo_* views are scored against TFP of their own spikes, not the truth:
    curve.png's title said "PSNR over the 3 test views" alone; it says so now, and how many
    where some are."""
    titles = []
    monkeypatch.setattr(curves, "save_curves", lambda path, methods, m, title: titles.append(title))
    run = {"tfp33": (_log(tmp_path / "run", [dict(LOG[1], psnr_mean=21.0)]), 0.0)}
    # an earlier log scores the first view alone: the note reads that view only (the first two
    # read passed)
    old = {"tfp33": (_log(tmp_path / "old", [LOG[1]]), 0.0)}
    for log, names in (
        (run, ["pseudo_008", "pseudo_016"]),
        (run, ["on_000", "pseudo_016"]),
        (run, ["on_000"]),
        (old, ["on_000", "pseudo_016"]),
    ):
        views = [SimpleNamespace(name=name) for name in names]
        dataset = SimpleNamespace(meta={"scene": "llff"}, root=tmp_path, test_views=views)
        save_logged_curves(tmp_path / "curve.png", log, dataset)
    assert [t.split("\n")[0] for t in titles] == [
        "llff: PSNR over the 2 test views during training, against TFP pseudo ground truth",
        "llff: PSNR over the 2 test views during training, against TFP pseudo ground truth "
        "(1 of them)",
        "llff: PSNR over the 1 test views during training",
        "llff: PSNR of the test view on_000 during training",
    ]


def test_a_method_without_sim_is_drawn_as_one(tmp_path, monkeypatch):
    """save_logged_curves: a run with 0 s of SIM is no SIM method (drawn from 0 s, dashed, without
    "from SIM"); one with SIM seconds is, and keeps them."""
    drawn = {}
    monkeypatch.setattr(curves, "save_curves", lambda path, methods, *a: drawn.update(methods))
    runs = {"tfp33": (_log(tmp_path / "a", LOG), 0.0), "spikegs": (_log(tmp_path / "b", LOG), 12.0)}
    dataset = SimpleNamespace(
        meta={"scene": "solids"}, root=tmp_path, test_views=[SimpleNamespace(name="view_000")]
    )
    save_logged_curves(tmp_path / "curves.png", runs, dataset)
    assert drawn["tfp33"]["uses_sim"] is False and drawn["tfp33"]["sim_seconds"] == 0.0
    assert drawn["spikegs"]["uses_sim"] is True and drawn["spikegs"]["sim_seconds"] == 12.0


def test_a_figure_without_a_sim_method_says_nothing_of_sim():
    """A baseline's curve.png (tfp33 trains no SIM) was titled "(a SIM method's curve starts after
    SIM's training)" over "seconds (SIM + training)", and so were `bench train`'s figures of
    baselines alone: both only where a SIM method is drawn."""
    import matplotlib.pyplot as plt

    for uses_sim, label in ((False, "seconds (training)"), (True, "seconds (SIM + training)")):
        fig, _ = _drawn({"m": _at([1.0, 2.0], uses_sim)})
        try:
            assert fig.axes[0].get_xlabel() == label
            said = "(a SIM method's curve starts after SIM's training)" in fig._suptitle.get_text()
            assert said == uses_sim
        finally:
            plt.close(fig)


def test_a_sim_methods_curve_starts_after_sims_training():
    """Each point at SIM's seconds + its training seconds; a curve of its own offset
    (`curve_sim_seconds`: seed 0's SIM in `bench train`) takes that one, not `sim_seconds`; each
    labelled with its method's title."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    curve = [{"train_seconds": 1.0, "psnr": 20.0}, {"train_seconds": 3.0, "psnr": 21.0}]
    methods = {
        "tfp33": {"curve": curve, "sim_seconds": 0.0, "uses_sim": False},
        "spikegs": {"curve": curve, "sim_seconds": 10.0, "uses_sim": True},
        "bench": {"curve": curve, "sim_seconds": 40.0, "curve_sim_seconds": 30.0, "uses_sim": True},
    }
    fig, ax = plt.subplots()
    try:
        _plot_curves([ax], methods, ("psnr",))
        lines = {line.get_label(): list(line.get_xdata()) for line in ax.lines}
    finally:
        plt.close(fig)
    assert lines == {  # the paper's names for its methods, a config's own for others
        "TFP(33)+3DGS": [1.0, 3.0],
        "SpikeGS (from SIM 10 s)": [11.0, 13.0],
        "bench (from SIM 30 s)": [31.0, 33.0],
    }


def test_every_benchmarked_method_is_drawn_in_a_style_of_its_own():
    """Curves cycled 8 styles by position: of `bench train`'s 10 methods, k13 was drawn as
    SpikeGS and oracle as TFP(33)+3DGS. Each line differs from every other in its colour and
    marker, and in its colour and line style."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from spikegs.bench.train import METHODS, VARIANTS

    curve = [{"train_seconds": 1.0, "psnr": 20.0}, {"train_seconds": 3.0, "psnr": 21.0}]
    methods = {m: {"curve": curve, "sim_seconds": 1.0, "uses_sim": True} for m in METHODS}
    methods.update({m: {"curve": curve, "sim_seconds": 0.0, "uses_sim": False} for m in "abcde"})
    methods.update({m: {"curve": curve, "sim_seconds": 1.0, "uses_sim": True} for m in VARIANTS})
    fig, ax = plt.subplots()
    try:
        _plot_curves([ax], methods, ("psnr",))
        styles = [(line.get_color(), line.get_marker(), line.get_linestyle()) for line in ax.lines]
    finally:
        plt.close(fig)
    assert len(styles) == len(methods)
    assert len({(colour, marker) for colour, marker, _ in styles}) == len(styles)
    assert len({(colour, line) for colour, _, line in styles}) == len(styles)


def test_the_time_axis_names_several_seconds_whatever_its_span():
    """A log axis labelled at 1, 2, 5 × 10^k named two seconds over 170-500 s (a run's
    curve.png at 250x400) and none over 170-190 s: under a factor 3 the axis is linear, within
    a decade every 1-9 × 10^k is named; over decades 1, 2, 5 × 10^k as before."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    def named(seconds: list[float]) -> tuple[str, list[str]]:
        """The axis's scale and the tick labels it draws within the seconds plotted."""
        curve = [{"train_seconds": s, "psnr": 20.0} for s in seconds]
        fig, ax = plt.subplots()
        try:
            _plot_curves([ax], {"tfp33": {"curve": curve, "sim_seconds": 0.0, "uses_sim": False}},
                         ("psnr",))  # fmt: skip
            fig.canvas.draw()
            ticks = [t for t in ax.get_xticklabels() if min(seconds) <= t.get_position()[0]]
            labels = [t.get_text() for t in ticks if t.get_position()[0] <= max(seconds)]
            return ax.get_xscale(), [label for label in labels if label]
        finally:
            plt.close(fig)

    assert named([150.0, 300.0, 600.0]) == ("log", ["200", "300", "400", "500", "600"])
    scale, labels = named([170.0, 180.0, 190.0])
    assert scale == "linear" and len(labels) >= 3
    assert named([3.0, 300.0, 3000.0]) == ("log", ["5", "10", "20", "50", "100", "200", "500",
                                                   "1000", "2000"])  # fmt: skip


def _drawn(methods: dict, metrics: tuple[str, ...] = ("psnr",)):
    """`curves_figure` of `methods`, drawn: (figure, renderer); close the figure after."""
    fig = curves_figure(methods, metrics, "a scene")
    fig.canvas.draw()
    return fig, fig.canvas.get_renderer()


def _at(seconds: list[float], uses_sim: bool = False) -> dict:
    """A method's record whose evaluations lie at `seconds`."""
    curve = [{"train_seconds": s, "psnr": 20.0 + i, "ssim": 0.5} for i, s in enumerate(seconds)]
    return {"curve": curve, "sim_seconds": 0.0, "uses_sim": uses_sim}


@pytest.mark.parametrize("span", [(100.0, 900.0), (150.0, 1000.0), (12.0, 95.0), (2.0, 5000.0)])
@pytest.mark.parametrize("metrics", [("psnr",), ("psnr", "ssim")])
def test_no_two_time_labels_touch_whatever_the_span(span, metrics):
    """A log axis named every 1-9 x 10^k within a decade printed 800, 900 and 1000 over one
    another over 100-900 s (a run of 250x400), 1, 2, 5 x 10^k 1000 and 2000 over 2-5000 s: the
    densest naming whose labels stand apart, three at least."""
    import matplotlib.pyplot as plt

    fig, renderer = _drawn({"tfp33": _at(list(np.geomspace(*span, 5)))}, metrics)
    try:
        for ax in fig.axes:
            low, high = ax.get_xlim()
            labels = [t for t in ax.get_xticklabels() if low <= t.get_position()[0] <= high]
            named = [t.get_window_extent(renderer) for t in labels if t.get_text()]
            boxes = sorted(named, key=lambda b: b.x0)
            assert ax.get_xscale() == "log" and len(boxes) >= 3
            texts = [t.get_text() for t in labels]
            assert all(a.x1 < b.x0 for a, b in zip(boxes, boxes[1:])), texts
    finally:
        plt.close(fig)


def test_the_legend_hides_no_curve():
    """The legend lay over the curves: the headline's over SpikeGS's rise, `bench train`'s 15
    entries over half the SSIM panel, a config's long name over the tick labels. It lies right of
    the panels, within the figure, its long names wrapped."""
    import matplotlib.pyplot as plt
    from spikegs.bench.train import METHODS, VARIANTS

    names = [*METHODS, *VARIANTS, "tfp33-equal-time", "lambda_2_k9_no_densify_opacity_reset_v3"]
    methods = {m: _at([1.0 + i, 5.0 + i, 40.0 + i], m == "spikegs") for i, m in enumerate(names)}
    fig, renderer = _drawn(methods, ("psnr", "ssim"))
    try:
        legend = fig.axes[-1].get_legend().get_window_extent(renderer)
        assert not any(legend.overlaps(ax.get_window_extent(renderer)) for ax in fig.axes)
        assert fig.bbox.contains(legend.x0, legend.y0) and fig.bbox.contains(legend.x1, legend.y1)
        texts = [t.get_text() for t in fig.axes[-1].get_legend().get_texts()]
        assert max(len(line) for text in texts for line in text.split("\n")) <= LEGEND_WRAP
    finally:
        plt.close(fig)


def test_a_baselines_run_at_spikegs_time_is_titled_as_its_method():
    """`bench train --equal-time`'s runs were labelled "tfp33-equal-time" beside "TFP(33)+3DGS";
    a name of a user's own ending so is kept."""
    assert method_title("tfp33-equal-time") == "TFP(33)+3DGS at SpikeGS's time"
    assert method_title("tfi-equal-time") == "TFI+3DGS at SpikeGS's time"
    assert method_title("mine-equal-time") == "mine-equal-time"


def test_a_backend_matplotlib_does_not_know_leaves_the_figure_drawn(tmp_path):
    """MPLBACKEND=inline (meant for Jupyter) made `import matplotlib` raise ValueError: a run
    that had trained lost its curve.png and exited 2; the figures are files, drawn with Agg."""
    script = (
        "import sys\n"
        "from spikegs.curves import save_curves\n"
        "curve = [{'train_seconds': 1.0, 'psnr': 20.0}, {'train_seconds': 2.0, 'psnr': 21.0}]\n"
        "methods = {'tfp33': {'curve': curve, 'sim_seconds': 0.0, 'uses_sim': False}}\n"
        "save_curves(sys.argv[1], methods, ('psnr',), 'title')\n"
    )
    figure = tmp_path / "curve.png"
    env = {**os.environ, "MPLBACKEND": "inline"}
    done = subprocess.run([sys.executable, "-c", script, str(figure)], env=env, capture_output=True)
    assert done.returncode == 0 and figure.read_bytes().startswith(b"\x89PNG"), done.stderr
