"""SpikeGS: 3D Gaussian Splatting trained from spike-camera streams."""

import os

# torch and spikegs._C may each bring an OpenMP runtime (a torch wheel whose libgomp has another
# name; torch 2.13's CPU wheel and _C share one libgomp.so.1); threads of one spinning after a
# parallel region starve the other on a small machine (fwd+bwd 2.6x slower measured on 2 cores).
# Set before torch is imported only: a script that imports torch first keeps torch's policy.
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
