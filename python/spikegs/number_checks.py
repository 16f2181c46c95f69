"""Checks of numbers read from files (JSON, YAML): true and false are not numbers there."""

from __future__ import annotations

import math
import numbers


def is_int(value) -> bool:
    """Whether `value` is an integer (not a bool)."""
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def is_number(value) -> bool:
    """Whether `value` is a finite real number (not a bool)."""
    return (
        isinstance(value, numbers.Real)
        and not isinstance(value, bool)
        and math.isfinite(float(value))
    )
