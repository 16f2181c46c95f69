"""What a result was computed with (train.json's, eval.json's and the demo's "environment",
bench's "machine"): the package's version and build, the libraries, the machine and its threads.
A `-march=native` build rounds as its CPU does, and SIM's convolutions as their thread count
does, so two records that differ here explain scores that differ in the last decimals."""

from __future__ import annotations

import platform
from typing import Any

from .cpu_quota import cpu_quota, usable_cpus


def cpu_model() -> str:
    """The CPU's model name (/proc/cpuinfo), else the platform's word for it."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def environment() -> dict[str, Any]:
    """The record: spikegs's version, the source and options its core was built from
    (`spikegs._C.build`: the git commit at the build's configuration, "-dirty" with changes not
    committed), the extensions it was compiled for, library versions, the CPU and threads."""
    import numpy
    import torch

    from . import _C, __version__

    return {
        "spikegs": __version__,
        # (an extension built before its record: rebuilt, it names its own)
        "build": {
            **getattr(_C, "build", {"source": "unknown (an extension older than this record)"}),
            "cpu_features": " ".join(_C.compiled_cpu_features),
        },
        "python": platform.python_version(),
        "torch": str(torch.__version__),  # (a TorchVersion, which a checkpoint cannot hold)
        "numpy": numpy.__version__,
        "cpu": cpu_model(),
        "cores": usable_cpus(),
        "cpu_quota": cpu_quota(),  # CPUs' worth of time (a container's --cpus), or None
        "torch_threads": torch.get_num_threads(),
    }
