"""JSON that any parser reads: Python's json writes inf and NaN as the non-standard Infinity and
NaN tokens (JavaScript's JSON.parse, jq and serde refuse them). Here they are null; a PSNR is
infinite only for a render identical to its ground truth."""

from __future__ import annotations

import json
import math


def _finite_or_none(value):
    """`value` with every non-finite float in it, at any depth, replaced by None."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _finite_or_none(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite_or_none(v) for v in value]
    return value


def dumps(value, **kwargs) -> str:
    """json.dumps(value) with non-finite floats written as null."""
    return json.dumps(_finite_or_none(value), allow_nan=False, **kwargs)
