"""The scripts BENCHMARKS.md cites for its figures (scripts/): each says its usage and writes
nothing when asked for it, and what they call of the package is still its API (no test ran them:
one crashed on a signature changed since, another rendered its scenes into a folder `--help`)."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import torch
from spikegs.evaluate import render_view
from spikegs.gaussians import GaussianModel

SCRIPTS = Path(__file__).parents[1] / "scripts"


@pytest.mark.parametrize(
    "script", sorted(p.relative_to(SCRIPTS).as_posix() for p in SCRIPTS.rglob("*.py"))
)
def test_a_script_asked_for_help_says_its_usage_and_writes_nothing(script, tmp_path):
    done = subprocess.run(
        [sys.executable, str(SCRIPTS / script), "--help"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0 and done.stdout.startswith("usage:"), done.stderr
    assert not list(tmp_path.iterdir())


def test_renders_at_other_sizes_makes_each_way_s_frame_at_the_scaled_size():
    """Its three ways of making a frame at 1.5x a 32² camera's size, through the package's
    render_scaled, scaled_camera and render_view: the same 48² frame, a Gaussian in its middle."""
    spec = importlib.util.spec_from_file_location("sizes", SCRIPTS / "renders_at_other_sizes.py")
    sizes = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(sizes)
    side, focal, depth = 32, 40.0, 4.0
    meta = {"fx": focal, "fy": focal, "cx": side / 2, "cy": side / 2, "width": side, "height": side}
    K = np.array([[focal, 0, side / 2], [0, focal, side / 2], [0, 0, 1]], np.float32)
    dataset = SimpleNamespace(
        K=K, width=side, height=side, scene_center=np.array([0, 0, depth]), scene_radius=1.0,
        meta=meta,
    )  # fmt: skip
    model = GaussianModel.from_points(torch.tensor([[0.0, 0.0, depth]]), torch.ones(1, 1), 0.2)
    frames = {way: sizes._frame(way, model, np.eye(4), dataset, 1.5) for way in sizes.WAYS}
    for way, frame in frames.items():
        assert frame.shape == (48, 48, 1), way
        assert frame[24, 24, 0] > 0.05 > 100 * frame[0, 0, 0], way
    at_one = sizes._frame("as it is", model, np.eye(4), dataset, 1.0)
    np.testing.assert_array_equal(at_one, render_view(model, np.eye(4), dataset))
