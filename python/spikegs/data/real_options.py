"""Options of the real-data loaders: DIR/spikegs.json, overridden by keyword arguments.

Every key is optional (docs/datasets.md, "Real data layouts"):
  height, width          spike resolution; default: from the layout's intrinsics (each alone)
  flip                   .dat rows stored bottom-up (default true, as the camera writes them)
  raw_width, col_offset  pixels stored per .dat row and the first one kept (the raw 250x400
                         camera's rows carry extra columns); default: width, 0
  test_views             indices of the held-out poses (LLFF, or one transforms file; default
                         every 8th: 0, 8, 16, ...)
  train_every            readouts between training timestamps (LLFF single stream)
  pseudo_gt_window       readouts of the TFP standing in for a held-out view without a sharp image
  scene_center, scene_radius  the scene sphere, instead of the one computed from the poses (a
                         centre needs its radius; a radius alone is about the computed centre)
  rate_at_one            firing rate of intensity 1.0 when calibrated (else fitted to sharp
                         training images where there are some, else a TFP percentile)

Types and ranges are checked when read: a ValueError names spikegs.json, the key, what was expected
and what was found.
"""

from __future__ import annotations

import dataclasses
import warnings
from pathlib import Path

import numpy as np

from .. import _C
from ..number_checks import is_int, is_number
from ..regular_file import is_given
from ..spikes import SpikeStream
from ..strict_json import json_text, read_json
from .dataset import check_stream_image

OPTIONS_FILE = "spikegs.json"
# how to mend a camera whose images have another aspect ratio than the spikes (`frame_columns`)
ASPECT_FIX = (
    f"set height and width in {OPTIONS_FILE} to the spikes' size, at that aspect ratio; or, "
    f"where the .dat rows are those images' and the spikes some of their columns, raw_width and "
    f"col_offset"
)


FRAME_OPTIONS = ("flip", "height", "width", "raw_width", "col_offset")  # how a .dat is read


@dataclasses.dataclass
class Options:
    """The options of the module docstring; None: the layout's default."""

    height: int | None = None
    width: int | None = None
    flip: bool = True
    raw_width: int | None = None
    col_offset: int = 0
    test_views: list[int] | None = None
    train_every: int | None = None
    pseudo_gt_window: int | None = None
    scene_center: list[float] | None = None
    scene_radius: float | None = None
    rate_at_one: float | None = None
    keywords = frozenset()  # the options a loader's keyword arguments set (not a field)

    def origin(self, key: str, root: Path) -> str:
        """Where option `key` was set, to begin a message: a loader's keyword, else the
        dataset's ROOT/spikegs.json."""
        return (
            f"{root}: keyword option {key}"
            if key in self.keywords
            else f"{root / OPTIONS_FILE}: {key}"
        )

    def frame_settings(self) -> str:
        """Where the frame options (FRAME_OPTIONS) are set, for the checks' advice on how a .dat
        is read: spikegs.json, or the loader's keywords where they override it (the advice named
        spikegs.json for a flip given as a keyword)."""
        keyed = [key for key in FRAME_OPTIONS if key in self.keywords]
        given = (
            f" or the loader's keywords ({', '.join(keyed)}), which override it" if keyed else ""
        )
        return OPTIONS_FILE + given


def _positive_int(v) -> bool:
    return is_int(v) and v >= 1


# key: (check of a non-None value, what it expects)
CHECKS = {
    "height": (_positive_int, "a positive integer"),
    "width": (_positive_int, "a positive integer"),
    "flip": (lambda v: isinstance(v, bool), "true or false"),
    "raw_width": (_positive_int, "a positive integer"),
    "col_offset": (lambda v: is_int(v) and v >= 0, "an integer >= 0"),
    "test_views": (
        lambda v: (
            isinstance(v, (list, tuple)) and len(v) > 0 and all(is_int(i) and i >= 0 for i in v)
        ),
        "a non-empty list of view indices (integers >= 0; leave test_views out for the default, "
        "every 8th)",
    ),
    "train_every": (_positive_int, "a positive integer"),
    "pseudo_gt_window": (lambda v: _positive_int(v) and v % 2 == 1, "an odd positive integer"),
    "scene_center": (
        lambda v: isinstance(v, (list, tuple)) and len(v) == 3 and all(map(is_number, v)),
        "a list of 3 finite numbers",
    ),
    "scene_radius": (lambda v: is_number(v) and v > 0, "a finite number > 0"),
    "rate_at_one": (lambda v: is_number(v) and 0 < v <= 1, "a number in (0, 1]: spikes a readout"),
}


def read_options(root: Path, overrides: dict) -> Options:
    """ROOT/spikegs.json (if any) with `overrides` (a loader's keyword arguments) on top;
    ValueError naming an unknown key or a value of the wrong type or range, and where it was
    set: the file, or the keyword (the file was named for a keyword's, whether or not it held
    that key)."""
    path = root / OPTIONS_FILE
    values = read_json(path) if is_given(path) else {}
    given = {k: v for k, v in overrides.items() if v is not None}
    values.update(given)

    def where(keys) -> str:
        """Where options `keys` were set, to begin a message: the keywords, else the file."""
        keywords = [key for key in keys if key in given]
        return f"{root}: keyword option(s) {', '.join(keywords)}:" if keywords else f"{path}:"

    known = [f.name for f in dataclasses.fields(Options)]
    unknown = sorted(set(given) - set(known)) or sorted(set(values) - set(known))  # keywords'
    if unknown:
        raise ValueError(f"{where(unknown)} unknown options {unknown}; known: {', '.join(known)}")
    for key, value in values.items():
        check, expected = CHECKS[key]
        if value is not None and not check(value):
            raise ValueError(f"{where([key])} {key} expected {expected}, found {json_text(value)}")
    if values.get("scene_center") is not None and values.get("scene_radius") is None:
        raise ValueError(
            f"{where(['scene_center'])} scene_center needs scene_radius (the radius computed from "
            f"the poses is about the centre computed with it)"
        )
    views = values.get("test_views") or []
    twice = sorted({i for i in views if views.count(i) > 1})
    if twice:
        warnings.warn(
            f"{where(['test_views'])} test_views lists {twice} more than once", stacklevel=2
        )
    # null: the default, for every key (flip's and col_offset's None reached the reader)
    options = Options(**{key: value for key, value in values.items() if value is not None})
    options.keywords = frozenset(given)
    return options


def open_spikes(
    path: Path, height: int, width: int, options: Options, size_from: str
) -> tuple[SpikeStream, np.ndarray]:
    """Memory-map a .dat of `height` x `width` readouts with the options' flip and raw-row crop,
    with its firing rates [H, W] (`check_stream_image`'s pass); FileNotFoundError or ValueError
    naming the file (empty, not of the expected layout, or without information) and, where the
    options set no size, `size_from`, what the size was taken from (LLFF's hwf). Its callers
    found `path` a file."""
    num_bytes = path.stat().st_size
    if num_bytes == 0:
        raise ValueError(f"{path}: empty spike file (no readout)")
    try:
        stream = SpikeStream.open(
            path, height, width, options.flip, options.raw_width, options.col_offset
        )
    except ValueError as err:
        where = "" if str(path) in str(err) else f"{path}: "
        raw = options.raw_width or width
        given = options.height and options.width
        origin = "" if given else f", the size of {size_from}"
        smaller = "" if given or raw != width else _smaller_size(num_bytes, height, width, options)
        raise ValueError(
            f"{where}{err} (expected frames of {height}x{width} pixels{origin}, rows of {raw} "
            f"from column {options.col_offset}: set height, width, raw_width, col_offset in "
            f"{OPTIONS_FILE} if these are wrong{smaller})"
        ) from err
    return stream, check_stream_image(stream, OPTIONS_FILE)


def _smaller_size(num_bytes: int, height: int, width: int, options: Options) -> str:
    """What to say where `num_bytes` are whole frames of `height` x `width` divided by 2 to 8 (a
    stream at half its poses' images' size was advised to be truncated)."""
    for m in range(2, 9):
        if height % m == 0 and width % m == 0:
            size = (height // m, width // m)
            frame = _C.SpikeLayout.dat(*size, options.flip, 0, 0).frame_bytes
            if num_bytes % frame == 0:
                return (
                    f"; the file holds {num_bytes // frame} whole frames of {size[0]}x{size[1]}: "
                    f"spikes at 1/{m} of that size?"
                )
    return ""
