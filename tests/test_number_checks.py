"""Booleans found among numbers as JSON and YAML give them (number_checks.holds_bool)."""

import numpy as np
import pytest
from spikegs.number_checks import holds_bool


@pytest.mark.parametrize(
    "value, held",
    [
        (True, True),  # a value alone, not a list
        (np.True_, True),
        (2.5, False),
        ([1.0, [2.0, (3.0, False)]], True),  # numbers and lists in one level, a bool below
        ([1.0, [2.0, (3.0, 4.0)], 5], False),
        ([[[[0.0]]], [[[1.0, True]]]], True),  # four levels down
        ([], False),
    ],
)
def test_a_bool_is_found_at_any_depth_beside_numbers(value, held):
    assert holds_bool(value) is held
