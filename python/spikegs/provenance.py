"""What a result was computed with (train.json's, eval.json's and the demo's "environment",
bench's "machine"): the package's version and build, the libraries, the machine and its threads.
A `-march=native` build rounds as its CPU does, and SIM's convolutions as their thread count
does, so two records that differ here explain scores that differ in the last decimals."""

from __future__ import annotations

import os
import platform
from typing import Any

from .cpu_quota import cpu_quota, usable_cpus


def _first_cpu(cpuinfo: str) -> dict[str, str]:
    """The first CPU's fields in `cpuinfo`, Linux's /proc/cpuinfo ({} where there is none to
    read)."""
    fields: dict[str, str] = {}
    try:
        with open(cpuinfo, encoding="utf-8", errors="replace") as f:
            for line in f:
                key, _, value = line.partition(":")
                if not key.strip():  # the first CPU's block ends
                    break
                fields.setdefault(key.strip(), value.strip())
    except OSError:
        pass
    return fields


def cpu_record(cpuinfo: str = "/proc/cpuinfo") -> dict[str, Any]:
    """The CPU's model name (else the platform's word for it); on x86 its family, model and
    stepping (a virtual machine's model name may be a vendor's word alone) and whether it
    computes bfloat16 natively (SIM's bf16 inference); read from `cpuinfo`'s first block."""
    fields = _first_cpu(cpuinfo)
    record: dict[str, Any] = {"cpu": fields.get("model name") or platform.processor() or "unknown"}
    if "cpu family" in fields:
        flags = fields.get("flags", "").split()
        record["cpu_id"] = (
            f"family {fields['cpu family']} model {fields.get('model', '?')} stepping "
            f"{fields.get('stepping', '?')}"
        )
        record["native_bf16"] = "avx512_bf16" in flags or "amx_bf16" in flags
    return record


def environment() -> dict[str, Any]:
    """The record: spikegs's version, the source and options its core was built from
    (`spikegs._C.build`: the git commit at the build's configuration, "-dirty" with changes not
    committed), the extensions it was compiled for, library versions, the CPU and threads (torch's
    and the core's as this thread starts them)."""
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
        **cpu_record(),
        "cores": usable_cpus(),
        "cpu_quota": cpu_quota(),  # CPUs' worth of time (a container's --cpus), or None
        "torch_threads": torch.get_num_threads(),
        "core_threads": _C.max_threads() if hasattr(_C, "max_threads") else None,
        "omp_num_threads": os.environ.get("OMP_NUM_THREADS"),  # as the user set it, or None
    }
