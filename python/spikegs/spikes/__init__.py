"""Spike streams: the .dat format, TFP/TFI kernels and the spike camera simulator."""

from .simulate import SimParams, simulate_spikes
from .stream import TFI_DEFAULT_MAX_INTERVAL, DatWriter, SpikeStream, save_dat

__all__ = [
    "TFI_DEFAULT_MAX_INTERVAL",
    "DatWriter",
    "SimParams",
    "SpikeStream",
    "save_dat",
    "simulate_spikes",
]
