"""SpikeGS: 3D Gaussian Splatting trained from spike-camera streams."""

import importlib.util
import os

from .interrupt import ImportInterrupted, running_as_command

try:  # torch's oneMKL ends the process where it is gone, with a broken install's message
    os.getcwd()
except FileNotFoundError:
    raise FileNotFoundError(
        "the working folder is gone (deleted while the shell was in it), where torch cannot "
        "load ('Intel oneMKL FATAL ERROR: Cannot load libtorch_cpu.so'): cd to one that exists"
    ) from None

with ImportInterrupted(running_as_command()):  # a command's Ctrl-C as torch loads: no traceback
    from . import thread_count  # a CPU quota's threads in OMP_NUM_THREADS, before torch loads

    # torch and spikegs._C may each bring an OpenMP runtime (a torch wheel whose libgomp has
    # another name; torch 2.13's CPU wheel and _C share one libgomp.so.1); threads of one
    # spinning after a parallel region starve the other on a small machine (fwd+bwd 2.6x slower
    # measured on 2 cores). Set before torch is imported only: a script that imports torch
    # first keeps torch's policy.
    os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

    import torch

    try:
        from . import _C
    except ImportError:
        if importlib.util.find_spec(f"{__name__}._C") is not None:  # built, and failed loading
            raise  # (for another CPU: its own message)
        raise ImportError(  # (Python's said "cannot import name '_C' ... circular import")
            f"spikegs's C++ extension (spikegs._C) is not built in {os.path.dirname(__file__)}: "
            f"install the package (`pip install .` in its checkout), or build it in place for "
            f"PYTHONPATH=python (-DSPIKEGS_PYTHON=ON -DSPIKEGS_INPLACE=ON: docs/install.md); a "
            f"checkout's python/ folder on the path hides an installed copy"
        ) from None
    from .rasterize import RasterizeResult, rasterize
    from .sim import SIM
    from .spikes import SimParams, SpikeStream, save_dat, simulate_spikes


def _one_thread_after_fork() -> None:
    """A forked child's first OpenMP team of more than one thread waits forever for the parent's
    pool threads, which fork did not copy, once any parallel region (ours or torch's) ran before
    the fork (GNU libgomp): a render in a multiprocessing fork pool hung. The child runs one
    thread, as torch's DataLoader workers do (torch's runtime and the core's, where they differ)."""
    torch.set_num_threads(1)
    _C.set_max_threads(1)


os.register_at_fork(after_in_child=_one_thread_after_fork)
thread_count.set_loaded_threads(torch, _C)

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
