"""Options of the real-data loaders: DIR/spikegs.json, overridden by keyword arguments.

Every key is optional (docs/datasets.md, "Real data layouts"):
  height, width          spike resolution; default: from the layout's intrinsics
  flip                   .dat rows stored bottom-up (default true, as the camera writes them)
  raw_width, col_offset  pixels stored per .dat row and the first one kept (the raw 250x400
                         camera's rows carry extra columns); default: width, 0
  test_views             indices of the held-out poses (LLFF; default every 8th: 0, 8, 16, ...)
  train_every            readouts between training timestamps (LLFF single stream)
  pseudo_gt_window       readouts of the TFP standing in for a held-out view without a sharp image
  scene_center, scene_radius  the scene sphere, instead of the one computed from the poses
  rate_at_one            firing rate of intensity 1.0 when calibrated (else a TFP percentile)
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

from ..spikes import SpikeStream

OPTIONS_FILE = "spikegs.json"


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


def read_options(root: Path, overrides: dict) -> Options:
    """ROOT/spikegs.json (if any) with `overrides` on top; ValueError naming an unknown key."""
    path = root / OPTIONS_FILE
    values = json.loads(path.read_text()) if path.is_file() else {}
    if not isinstance(values, dict):
        raise ValueError(f"{path}: expected a JSON object of options")
    values.update({k: v for k, v in overrides.items() if v is not None})
    known = [f.name for f in dataclasses.fields(Options)]
    unknown = sorted(set(values) - set(known))
    if unknown:
        raise ValueError(f"{path}: unknown options {unknown}; known: {', '.join(known)}")
    options = Options(**values)
    window = options.pseudo_gt_window
    if window is not None and (window < 1 or window % 2 == 0):
        raise ValueError(
            f"{path}: pseudo_gt_window expected an odd positive number, found {window}"
        )
    return options


def open_spikes(path: Path, height: int, width: int, options: Options) -> SpikeStream:
    """Memory-map a .dat of `height` x `width` readouts with the options' flip and raw-row crop;
    FileNotFoundError or ValueError naming the file and the layout it was expected to have."""
    if not path.is_file():
        raise FileNotFoundError(f"spike file not found: {path}")
    try:
        return SpikeStream.open(
            path, height, width, options.flip, options.raw_width, options.col_offset
        )
    except ValueError as err:
        where = "" if str(path) in str(err) else f"{path}: "
        raw = options.raw_width or width
        raise ValueError(
            f"{where}{err} (expected {height}x{width} readouts, rows of {raw} pixels from column "
            f"{options.col_offset}: set height, width, raw_width, col_offset in {OPTIONS_FILE} "
            f"if these are wrong)"
        ) from err
