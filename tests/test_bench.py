"""Benchmarks that assert something: the stiff cases stay finite and float32 close to float64,
SIM's timed training step computes the literal network's gradients, and the training benchmark's
schedule is the demo's (CI also runs `spikegs bench all --quick`)."""

from __future__ import annotations

import math

import pytest

pytest.importorskip("spikegs._C")

from spikegs.bench import sim, stiff, train  # noqa: E402
from spikegs.demo import DEMO_OVERRIDES  # noqa: E402
from spikegs.sim import SIM  # noqa: E402


def test_stiff_cases_are_finite_and_float32_is_close(tmp_path):
    rows = stiff.run(quick=True, out=tmp_path)["cases"]
    assert len(rows) == len(stiff.CASES)
    for row in rows:
        assert row["non_finite"] == "none", row["case"]
        assert row["zero_grad"] in ("yes", "-"), row["case"]
        assert row["image_err"] < stiff.FLOAT_ERROR_BOUND, row["case"]
    assert (tmp_path / "stiff.json").exists()


def test_train_schedule_is_the_demo_one_stretched():
    demo = DEMO_OVERRIDES["train"]["iterations"]
    assert train.schedule(demo, quick=False)["densify"] == DEMO_OVERRIDES["densify"]
    half = train.schedule(demo // 2, quick=False)
    assert half["densify"]["stop"] == round(DEMO_OVERRIDES["densify"]["stop"] / 2)
    evals = math.ceil(half["train"]["iterations"] / half["train"]["eval_every"])
    assert evals == train.POINTS  # the last evaluation is at the end


def test_sim_train_step_rows_time_the_same_gradients():
    rows = sim._train_step_rows(SIM(), batch=2, crop=16, repeats=1)
    assert [r["variant"] for r in rows] == [
        "train step rotated pairs (literal)",
        "train step canvas",
    ]
    for row in rows:
        assert row["seconds"] > 0 and row["grad_err"] < 1e-4, row
