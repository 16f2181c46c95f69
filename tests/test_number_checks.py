"""Booleans found among numbers as JSON and YAML give them (number_checks.holds_bool), and
arrays of numbers read from them (number_checks.number_array)."""

import re

import numpy as np
import pytest
from spikegs.number_checks import holds_bool, number_array, shown_past


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


def test_number_array_names_what_is_not_a_number_and_where():
    """number_array refuses booleans (true, false in a JSON file are not 1 and 0) and a null,
    saying where, as JSON spells them; reads nested lists and arrays, and an integer past int64
    as a float."""
    with pytest.raises(ValueError, match=re.escape("expected numbers, found true at [0]")):
        number_array([True, False])
    # a null in a pose log's matrix: named as JSON spells it, and where (was "object values")
    with pytest.raises(ValueError, match=re.escape("expected numbers, found null at [1, 0]")):
        number_array([[0, 1], [None, 2]])
    for mixed in ([1.0, True], [[0, 1], (2, np.False_)]):  # numpy made these 1.0 and 0
        with pytest.raises(ValueError, match="found true or false among them"):
            number_array(mixed)
    assert number_array([np.zeros(2), [1, 2]]).tolist() == [[0, 0], [1, 2]]
    # an integer past int64 (JSON reads 1e30 written out as one) made an object array, where the
    # search for what is not a number found none: StopIteration's traceback, not a message
    assert number_array([[0, 10**30], [1, 2]]).tolist() == [[0, 1e30], [1, 2]]
    with pytest.raises(ValueError, match=re.escape("found an integer past 1.8e308 at [1]")):
        number_array([0, 10**400])


def test_a_value_past_its_bound_is_shown_past_it():
    """170.3 beyond a bound of 170 was shown as 170 (the geometry trial); three digits where they
    tell it apart, more where they do not."""
    assert shown_past(175.46, 170) == "175"
    assert shown_past(170.3, 170) == "170.3"
    assert shown_past(60.0004, 60) == "60.0004"
    assert shown_past(0.00099, 0.001) == "0.00099"
