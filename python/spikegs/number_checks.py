"""Checks of numbers read from files (JSON, YAML: true and false are not numbers there), of
seeds, of flags and of images (values that are not finite)."""

from __future__ import annotations

import math
import numbers
from itertools import chain

import numpy as np

from .strict_json import json_text


def is_int(value) -> bool:
    """Whether `value` is an integer (not a bool)."""
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def is_count(value) -> bool:
    """Whether `value` is a whole number of steps or things, 1..2**63 - 1 (2**63 iterations were
    trained on, a step at a time)."""
    return is_int(value) and 1 <= value < 2**63


def past_float(value: int) -> str:
    """An integer a float cannot hold as a message names it ("a 401-digit integer, beyond a
    float's range": its own digits would fill the message)."""
    return f"a {len(str(abs(value)))}-digit integer, beyond a float's range"


def shown_past(value: float, bound: float) -> str:
    """`value` with the digits that show it past `bound` (170.3 beyond 170 was shown as 170)."""
    for digits in range(3, 17):
        text = f"{value:.{digits}g}"
        if float(text) != bound:
            return text
    return repr(value)


def as_flag(name: str, value) -> bool:
    """`value` as a bool; ValueError unless it is one (a string "false" would read as True)."""
    if not isinstance(value, (bool, np.bool_)):
        raise ValueError(f"{name}: expected True or False, found {value!r}")
    return bool(value)


SEED_MAX = 2**64 - 1  # torch.manual_seed's range, and the simulator's


def is_seed(value) -> bool:
    """Whether `value` is an integer seed in 0..SEED_MAX (one outside would wrap around)."""
    return is_int(value) and 0 <= value <= SEED_MAX


def non_finite_pixels(image: np.ndarray) -> tuple[int, tuple[int, ...]] | None:
    """(how many pixels of `image` [H, W] or [H, W, C] hold a NaN or inf, the index of the first
    such value, row-major), or None where every value is finite."""
    bad = ~np.isfinite(image)
    if not bad.any():
        return None
    pixels = bad.any(axis=2) if bad.ndim == 3 else bad  # [H, W]
    return int(pixels.sum()), tuple(map(int, np.argwhere(bad)[0]))


def is_real(value) -> bool:
    """Whether `value` is a real number (not a bool), finite or not."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def is_number(value) -> bool:
    """Whether `value` is a finite real number (not a bool) that a float holds (an int past
    1.8e308, which JSON and YAML read from 309 digits, is not: float() raised OverflowError)."""
    if not is_real(value):
        return False
    try:
        return math.isfinite(float(value))
    except OverflowError:
        return False


def whole_numbers(**values) -> list[int]:
    """`values` as Python ints, in the order given (numpy integers converted); ValueError naming
    every one that is not an integer (a whole float too: 16.0 pixels is a slip, not a size) or
    lies outside int64's range (the core's: a raw_width of 10**30 was pybind11's TypeError)."""
    bad = [
        f"{k}: expected an int{' within ±2^63' * is_int(v)}, found {v!r}"
        for k, v in values.items()
        if not (is_int(v) and -(2**63) <= v < 2**63)
    ]
    if bad:
        raise ValueError("; ".join(bad))
    return [int(v) for v in values.values()]


def finite_numbers(**values) -> list[float]:
    """`values` as Python floats, in the order given; ValueError naming every one that is not a
    finite real number."""
    bad = [f"{k}={v!r}" for k, v in values.items() if not is_number(v)]
    if bad:
        raise ValueError(f"expected finite numbers, found {', '.join(bad)}")
    return [float(v) for v in values.values()]


_NESTED = (list, tuple)  # what `holds_bool` looks into


def number_array(value) -> np.ndarray:
    """Nested lists of numbers as a float64 array; ValueError for strings, booleans, nulls,
    integers past a float's range or ragged lists, naming the first value that is not a number
    and where (np.asarray(value, float) would read '1.0' and True as numbers, and np.asarray
    reads a True among numbers as 1)."""
    array = np.asarray(value)  # ragged: ValueError
    if array.dtype.kind not in "iuf":  # (an integer past int64 among numbers: an object array)
        given = np.asarray(value, dtype=object).reshape(-1)  # (as given: not made text like "x")
        flat = [v.item() if isinstance(v, np.generic) else v for v in given]
        i = next((i for i, v in enumerate(flat) if not _float_holds(v)), None)
        if i is not None:  # the first value that is not a number, as JSON spells it
            where = [int(n) for n in np.unravel_index(i, array.shape)]
            found = json_text(flat[i]) if not is_int(flat[i]) else "an integer past 1.8e308"
            raise ValueError(f"expected numbers, found {found} at {where}")
    if holds_bool(value):
        raise ValueError("expected numbers, found true or false among them")
    return array.astype(np.float64)


def _float_holds(value) -> bool:
    """Whether `value` is a real number (not a bool) that a float holds, finite or not."""
    return is_real(value) and (is_number(value) or not is_int(value))


def holds_bool(value) -> bool:
    """Whether nested lists or tuples, as JSON and YAML give them, hold a bool anywhere, a level
    at a time, each level's types gathered at once (100k 4x4 poses: 0.10 s; by recursion, a list
    at a time, 0.17; element by element, half again a pose log's load). Not looked
    into: a level's lists where it holds only subclasses of list, and arrays (a numpy bool array
    among lists of numbers reads as 1 and 0: the package passes none, and looking into the pose
    log's arrays of numbers would cost its load)."""
    level = list(value) if isinstance(value, _NESTED) else [value]
    while True:
        kinds = set(map(type, level))
        if not kinds.isdisjoint((bool, np.bool_)):
            return True
        if kinds.isdisjoint(_NESTED):
            return False
        nested = level if kinds <= set(_NESTED) else [v for v in level if isinstance(v, _NESTED)]
        level = list(chain.from_iterable(nested))
