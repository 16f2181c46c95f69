"""The places that list the built-in methods, scenes and command options by hand name each of
them: a method added to configs/ or a scene to SCENES passed every test while figures, the
benchmark and the docs left it out (a contributor's audit)."""

from __future__ import annotations

import argparse
import re
from pathlib import Path

from spikegs.bench.train import METHODS, VARIANTS
from spikegs.cli import build_parser
from spikegs.config import available_methods
from spikegs.data import scenes
from spikegs.method_titles import TITLES

ROOT = Path(__file__).parents[1]


def test_every_method_has_a_title_a_benchmark_role_and_a_readme_entry():
    """sim17's figures showed its file name (no title); the benchmark's sets and the README's
    table of methods (the paragraph that opens it and the table) are written by hand."""
    methods = set(available_methods())
    assert set(TITLES) == methods
    assert set(METHODS) | set(VARIANTS) == methods and not set(METHODS) & set(VARIANTS)
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    listed = "".join(readme[readme.index("Methods (`configs/*.yaml`") :].split("\n\n")[:2])
    assert {m for m in methods if f"`{m}`" not in listed} == set()


def test_every_scene_is_in_the_tables_of_scenes():
    """The scenes module's table, docs/datasets.md's and the README's `simulate --scene` row."""
    datasets = (ROOT / "docs" / "datasets.md").read_text(encoding="utf-8")
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    row = re.search(r"`spikegs simulate \[--scene ([^ \]]+)", readme).group(1).split("\\|")
    for name in scenes.SCENES:
        assert f"| `{name}`" in scenes.__doc__, name
        assert f"| `{name}` |" in datasets, name
        assert name in row, name


def test_the_readme_commands_name_every_option():
    """The README's table of commands is written by hand: train's row lacked --config,
    --iterations, --seed and --no-progress, poses' every option, bench's --out (the CLI trial).
    Each command's long options are in its rows' first cells (simulate's row sends to --help)."""
    parser = build_parser()
    (commands,) = (a.choices for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    for name, command in commands.items():
        cells = " ".join(re.findall(rf"^\| `spikegs {name}\b([^`]*)`", readme, re.MULTILINE))
        assert cells, name
        if name == "simulate":
            assert "every option: `spikegs simulate --help`" in readme
            continue
        options = {o for a in command._actions for o in a.option_strings if o.startswith("--")}
        assert {o for o in options - {"--help"} if o not in cells} == set(), name
