"""JSON written strictly: no inf or NaN tokens that other readers refuse (strict_json.py)."""

import pytest
from spikegs.strict_json import dumps, read_json


def test_dumps_nulls_non_finite_numbers_in_lists_too():
    """dumps writes inf and NaN as null inside lists and tuples too (a list of per-view scores
    raised ValueError with allow_nan off)."""
    assert (
        dumps({"psnr": [float("inf"), 31.5, (float("nan"),)]}) == '{"psnr": [null, 31.5, [null]]}'
    )


def test_json_nested_past_the_parsers_depth_is_named(tmp_path):
    """A meta.json nested thousands deep (a fuzz's) was a RecursionError traceback from the CLI."""
    path = tmp_path / "meta.json"
    path.write_text('{"a": ' + "[" * 100_000 + "]" * 100_000 + "}")
    with pytest.raises(
        ValueError, match=r"meta.json: not valid JSON for spikegs \(nested too deep"
    ):
        read_json(path)
