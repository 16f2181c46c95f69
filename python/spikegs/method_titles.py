"""The names figures give the methods, as the paper and the README write them (a config's own
name where it has none: a user's config, an experiment)."""

from __future__ import annotations

TITLES = {
    "spikegs": "SpikeGS",
    "tfp33": "TFP(33)+3DGS",
    "tfp65": "TFP(65)+3DGS",
    "tfi": "TFI+3DGS",
    "tfp33_smooth_l1": "TFP(33)+3DGS, smooth L1",
    "only_instant": "only L_instant",
    "only_exposure": "only L_exposure",
    "k9": "SpikeGS, K = 9",
    "k13": "SpikeGS, K = 13",
    "sim17": "SpikeGS, SIM on 17 readouts",
    "oracle": "clean instant targets (ceiling)",
}
EQUAL_TIME = "-equal-time"  # `bench train --equal-time`: a baseline's run given SpikeGS's seconds


def method_title(name: str) -> str:
    """The figure title of method `name` (configs/NAME.yaml), of a method's BASE-equal-time run
    too (its legend entry read "tfp33-equal-time" beside "TFP(33)+3DGS"); `name` itself where
    none is set."""
    base = name.removesuffix(EQUAL_TIME)
    if base != name and base in TITLES:
        return f"{TITLES[base]} at SpikeGS's time"
    return TITLES.get(name, name)
