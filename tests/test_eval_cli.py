"""`spikegs eval` (eval_cli.py): --no-images writes the scores only; pseudo ground truths noted."""

import json

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
