"""JSON written strictly: no inf or NaN tokens that other readers refuse (strict_json.py)."""

from spikegs.strict_json import dumps


def test_dumps_nulls_non_finite_numbers_in_lists_too():
    """dumps writes inf and NaN as null inside lists and tuples too (a list of per-view scores
    raised ValueError with allow_nan off)."""
    assert (
        dumps({"psnr": [float("inf"), 31.5, (float("nan"),)]}) == '{"psnr": [null, 31.5, [null]]}'
    )
