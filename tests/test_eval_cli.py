"""`spikegs eval` (eval_cli.py): --no-images writes the scores only; pseudo ground truths noted;
--align-poses says how far the poses moved; eval and render load with a bar unless
--no-progress."""

import json

import pytest
from spikegs.cli import main
from spikegs.config import load_config
from spikegs.data import simulate_dataset
from spikegs.train import Trainer

FAST = {
    "train": {"iterations": 2, "init_gaussians": 800, "eval_every": 50, "checkpoint_every": 50},
    "densify": {"start": 40, "stop": 160, "every": 40, "opacity_reset_every": 0},
}
TINY = dict(height=32, width=32, readouts=600, test_on_path=1, test_off_path=1, progress=False)


def test_eval_no_images_writes_the_scores_only(tmp_path, capsys):
    data = simulate_dataset("solids", tmp_path / "data", **TINY)
    Trainer(data, load_config("tfp33", FAST), tmp_path / "run", progress=False).train()
    assert main(["eval", str(tmp_path / "run"), "--no-images"]) == 0
    assert len(json.loads((tmp_path / "run" / "eval.json").read_text())["views"]) == 2
    assert not (tmp_path / "run" / "eval").exists()
    assert "tfp33: PSNR" in capsys.readouterr().out
    assert main(["eval", str(tmp_path / "run")]) == 0  # with images: one per view
    assert len(list((tmp_path / "run" / "eval").glob("*.png"))) == 2


def test_eval_notes_views_scored_against_pseudo_ground_truth(tmp_path, monkeypatch, capsys):
    """A real recording's views without a sharp image are scored against TFP of their spikes:
    the scores say how many, under the line of PSNR and SSIM."""
    data = simulate_dataset("solids", tmp_path / "data", **TINY)
    views = {"pseudo_000": {}, "pseudo_008": {}, "view_004": {}}
    scored = {"method": "spikegs", "psnr": 30.0, "ssim": 0.9, "views": views, "file": "eval.json"}
    monkeypatch.setattr("spikegs.evaluate.evaluate_run", lambda *args, **kwargs: scored)
    assert main(["eval", str(tmp_path / "run"), "--dataset", str(data.root)]) == 0
    said = capsys.readouterr().out.splitlines()
    assert said[-1] == "note: 2 views without a sharp image, scored against TFP (pseudo_*)"


def test_eval_with_aligned_poses_says_how_far_the_median_view_and_the_furthest_moved(
    tmp_path, monkeypatch, capsys
):
    """`--align-poses`: under the scores, the median move and the view that moved most (a view
    settled off its pose moves far more than the others)."""
    data = simulate_dataset("solids", tmp_path / "data", **TINY)
    views = {
        name: {"aligned_rotation_deg": degrees}
        for name, degrees in (("on_000", 1.5), ("on_002", 31.25), ("off_000", 2.0))
    }
    moved = {"rotation_deg_median": 2.0, "centre_median": 0.05}
    scored = {"method": "tfp33", "psnr": 29.0, "ssim": 0.9, "views": views, "file": "eval.json"}
    scored["aligned_poses"] = moved
    given = []

    def evaluate_run(*args, **kwargs):
        given.append(kwargs["align_poses"])
        return scored

    monkeypatch.setattr("spikegs.evaluate.evaluate_run", evaluate_run)
    command = ["eval", str(tmp_path / "run"), "--dataset", str(data.root), "--align-poses"]
    assert main(command) == 0 and given == [True]
    said = capsys.readouterr().out.splitlines()
    assert said[-1] == (
        "(each view's pose aligned to its image first: moved a median 2.00 deg, at most 31.25 "
        "(on_002), its centre 5.00% of the scene radius)"
    )


class _Loaded(Exception):
    """Raised by a stub past the loading: the command has asked for its dataset."""


@pytest.mark.parametrize(
    "command, asked",
    [(["eval"], [True, True, False, False]), (["render", "--out", "ORBIT"], [True, False])],
)
def test_eval_and_render_load_with_a_bar_unless_told_not_to(tmp_path, monkeypatch, command, asked):
    """A recording without sharp test images searches its spikes for a flicker as it loads
    (seconds, longer on big ones): eval and render pass the loader a bar in a terminal, as train
    does, and none under --no-progress; so does eval to its scoring (which loads the run's own
    folder where --dataset names another)."""
    run = tmp_path / "run"
    run.mkdir()
    (run / "scene.ply").touch()
    given = []

    def load(root, progress=False):
        given.append(progress)
        return "the dataset"

    def past_loading(*args, progress=None, **kwargs):
        given.extend([] if progress is None else [progress])
        raise _Loaded

    monkeypatch.setattr("spikegs.data.load_dataset", load)
    monkeypatch.setattr("spikegs.evaluate.evaluate_run", past_loading)
    monkeypatch.setattr("spikegs.evaluate.other_data", past_loading)  # render's next step
    for module in ("eval_cli", "render_cli"):  # stderr a terminal
        monkeypatch.setattr(f"spikegs.{module}.show_bars", lambda off: not off)
    name, *options = [str(tmp_path / "orbit.gif") if word == "ORBIT" else word for word in command]
    for extra in ([], ["--no-progress"]):
        with pytest.raises(_Loaded):
            main([name, str(run), *options, "--dataset", str(tmp_path), *extra])
    assert given == asked
