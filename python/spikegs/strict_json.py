"""Strict JSON, both ways. Written so that any parser reads it: Python's json writes inf and NaN
as the non-standard Infinity and NaN tokens (JavaScript's JSON.parse, jq and serde refuse them);
here they are null (a PSNR is infinite only for a render identical to its ground truth). Read
refusing what json lets through: a key given twice (json keeps the last)."""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path

from .regular_file import NotText, read_text


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


def json_text(value) -> str:
    """A value read from a JSON file as a message shows it, as the file spells it: null, true,
    "32", [0, 0] (Python's repr said None, True, '32')."""
    return json.dumps(value, ensure_ascii=False, default=repr)


class _RepeatedKeys(ValueError):
    """A JSON object gives a key twice."""


def _unique_keys(pairs: list) -> dict:
    """A JSON object's {key: value}; _RepeatedKeys naming a key given twice (json keeps the
    last)."""
    doc = dict(pairs)
    if len(doc) < len(pairs):
        keys = [k for k, _ in pairs]
        raise _RepeatedKeys(sorted({k for k in keys if keys.count(k) > 1}))
    return doc


def read_json(path: Path, object_hook: Callable[[dict], dict] | None = None) -> dict:
    """The JSON object in the file at `path`; ValueError naming the file where it is malformed,
    gives a key twice in an object (which of the two was meant?) or holds something else than an
    object. `object_hook`: applied to each object (a dict) as it is parsed, innermost first."""
    pairs_hook = (
        _unique_keys if object_hook is None else lambda pairs: object_hook(_unique_keys(pairs))
    )
    try:
        # JSON is UTF-8 whatever the locale (a C or Windows locale's codec misread "données"); a
        # byte-order mark, which editors on Windows write, is skipped
        text = read_text(path, encoding="utf-8-sig")
        doc = json.loads(text, object_pairs_hook=pairs_hook)
    except _RepeatedKeys as err:
        raise ValueError(f"{path}: keys given twice in an object, which is meant? {err}") from None
    except NotText as err:  # (the file named once)
        raise ValueError(f"{path}: not valid JSON ({err.detail})") from None
    except json.JSONDecodeError as err:
        raise ValueError(f"{path}: not valid JSON ({err})") from None
    except RecursionError:  # Python's parser recurses per level: ~1000 deep was a traceback
        raise ValueError(f"{path}: not valid JSON for spikegs (nested too deeply)") from None
    if not isinstance(doc, dict):
        raise ValueError(f"{path}: expected a JSON object {{...}}, found {type(doc).__name__}")
    return doc
