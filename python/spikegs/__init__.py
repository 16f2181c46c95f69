"""SpikeGS: 3D Gaussian Splatting trained from spike-camera streams."""

import os

# torch and spikegs._C each bring an OpenMP runtime; threads of one spinning after a parallel
# region starve the other on a small machine (fwd+bwd 2.6x slower measured on 2 cores).
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

from .rasterize import RasterizeResult, rasterize
from .sim import SIM
from .spikes import SimParams, SpikeStream, save_dat, simulate_spikes

__all__ = [
    "RasterizeResult",
    "rasterize",
    "SimParams",
    "SpikeStream",
    "save_dat",
    "simulate_spikes",
    "SIM",
]
__version__ = "0.1.0"
