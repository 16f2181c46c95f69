"""`spikegs eval` (eval_cli.py): --no-images writes the scores only."""

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
