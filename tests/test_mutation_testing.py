"""scripts/mutation_testing.py, the tool behind BENCHMARKS.md's mutation-testing figures, on a toy
package whose mutants' fates are known."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

SCRIPT = Path(__file__).parents[1] / "scripts" / "mutation_testing.py"
CALC = '''"""A toy module."""


def clamp(x, lo, hi):
    if lo > hi:
        raise ValueError(f"empty range {lo}..{hi}", 2)
    if x < lo:
        return lo
    return min(x, hi)


def unused(x):
    return x > 0
'''
TESTS = """import pytest
from toy.calc import clamp


def test_clamp():
    assert clamp(-1, 0, 5) == 0
    assert clamp(3, 0, 5) == 3
    with pytest.raises(ValueError):
        clamp(0, 1, 0)


def test_nothing_of_calc():
    assert True
"""
# line: the mutants there, and whether test_clamp kills each (the equivalent two survive: they
# differ only at lo == hi and x == lo, which the test never passes)
EXPECTED = {
    5: {"Gt->LtE": "killed", "Gt->GtE": "survived", "negate": "killed"},
    7: {"Lt->GtE": "killed", "Lt->LtE": "survived", "negate": "killed"},
    13: {"Gt->LtE": "uncovered", "Gt->GtE": "uncovered", "0->1": "uncovered"},
}


def expected(*lines: int) -> dict:
    """{(line, change): status} of EXPECTED's mutants on `lines` (all of them by default)."""
    return {
        (line, what): status
        for line in lines or EXPECTED
        for what, status in EXPECTED[line].items()
    }


@pytest.fixture
def toy(tmp_path):
    """tmp_path holding the package `toy` (importable: src/ on PYTHONPATH) and its test file."""
    (tmp_path / "src" / "toy").mkdir(parents=True)
    (tmp_path / "src" / "toy" / "__init__.py").write_text("")
    (tmp_path / "src" / "toy" / "calc.py").write_text(CALC)
    (tmp_path / "test_toy.py").write_text(TESTS)
    return tmp_path


def tool(root: Path, *args: str) -> str:
    env = {**os.environ, "PYTHONPATH": str(root / "src")}
    common = ["--package", "toy", "--sources", "src/toy", "--work", "work"]
    if args[0] not in ("cover", "run"):
        common = []
    done = subprocess.run([sys.executable, SCRIPT, *args[:1], *common, *args[1:]], cwd=root,
                          env=env, capture_output=True, text=True)  # fmt: skip
    assert done.returncode == 0, done.stderr
    return done.stdout


def results(path: Path) -> dict:
    """{(line, change): status} of a results file."""
    rows = [json.loads(line) for line in path.read_text().splitlines()]
    return {(r["line"], r["what"]): r["status"] for r in rows}


def test_generate_leaves_out_messages_and_writes_each_mutant(toy):
    assert "9 mutants" in tool(toy, "generate", "src/toy/calc.py", "mutants")
    index = [row.split("\t") for row in (toy / "mutants" / "index.tsv").read_text().splitlines()]
    # nothing on line 6: a raise's number is its message
    assert sorted((int(line), what) for _, line, what in index) == sorted(expected())
    mid = next(mid for mid, line, what in index if (line, what) == ("7", "Lt->LtE"))
    assert "if x <= lo:" in (toy / "mutants" / f"{mid}.py").read_text()


def test_run_kills_what_the_tests_pin_down_and_resumes(toy):
    tool(toy, "generate", "src/toy/calc.py", "mutants")
    out = toy / "calc.jsonl"
    run = ("run", "toy/calc.py", "mutants", "--out", str(out), "--workers", "2")
    tool(toy, *run, "--ids", "0000,0001,0002,0003,0004,0005", "--", "test_toy.py")
    assert results(out) == expected(5, 7)
    assert (toy / "src" / "toy" / "calc.py").read_text() == CALC  # the sources untouched
    assert (toy / "work" / "worker0" / "toy" / "calc.py").read_text() == CALC  # restored
    tool(toy, *run, "--", "test_toy.py")  # resumed: only the three not yet run
    assert len(out.read_text().splitlines()) == 9
    assert "'killed': 4" in tool(toy, "summary", str(out))


def test_cover_maps_each_line_to_the_tests_that_ran_it(toy):
    tool(toy, "generate", "src/toy/calc.py", "mutants")
    tool(toy, "cover", "toy/calc.py", "--out", "cover.json", "--", "test_toy.py")
    lines = json.loads((toy / "cover.json").read_text())["toy/calc.py"]
    assert lines["7"] == ["test_toy.py::test_clamp"]
    assert lines.get("13", []) == [] and lines["4"] == []  # never run; run only at import
    out = toy / "calc.jsonl"
    tool(toy, "run", "toy/calc.py", "mutants", "--out", str(out), "--cover", "cover.json")
    assert results(out) == expected()
