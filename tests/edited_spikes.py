"""A dataset's spikes written again with some pixels changed: the tests' sensor defects."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
from spikegs.spikes import DatWriter


def write_edited_spikes(dataset, dat: Path, edit: Callable[[np.ndarray], None]) -> None:
    """`dataset`'s (mono) spikes [T, H, W] bool, changed in place by `edit`, written to the .dat
    file `dat` in the dataset's frame size and row order (meta.json's flip)."""
    bits = np.unpackbits(dataset.stream.packed(), axis=2, bitorder="little")
    bits = bits[..., : dataset.width] > 0  # [T, H, W]
    edit(bits)
    with DatWriter(dat, dataset.height, dataset.width, dataset.meta["flip"]) as writer:
        writer.write_bits(bits)
