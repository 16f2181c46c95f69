"""spikegs._C refuses to load on a CPU without an instruction-set extension that its core was
compiled for (-march=native builds moved to another machine), naming them, instead of stopping
the process at "Illegal instruction"."""

from __future__ import annotations

import platform
import re
from pathlib import Path

import pytest

_C = pytest.importorskip("spikegs._C", reason="the C++ extension spikegs._C is not built")
X86 = platform.machine().lower() in ("x86_64", "amd64", "i386", "i686")
SOURCE = Path(__file__).resolve().parents[1] / "csrc" / "core" / "cpu_features.cpp"


def test_the_core_was_compiled_for_this_cpu():
    """The module loaded, so every extension it was compiled for is one this CPU has."""
    compiled = _C.compiled_cpu_features
    assert all(_C.cpu_features.get(name) for name in compiled), compiled
    assert _C.cpu_mismatch(" ".join(compiled), _C.cpu_features) == ""


@pytest.mark.skipif(not X86, reason="the extensions checked are x86's")
def test_every_extension_the_core_can_name_is_checked():
    """Each name core/cpu_features.cpp can report is one the bindings look up on the CPU (a name
    they do not know would refuse every CPU that the core was compiled for)."""
    named = set(re.findall(r'^\s*" ([a-z0-9.]+)"$', SOURCE.read_text(), re.M))
    assert len(named) >= 10, f"no extension names parsed from {SOURCE}"
    assert named == set(_C.cpu_features), named ^ set(_C.cpu_features)


def test_a_cpu_without_a_compiled_extension_is_refused():
    cpu = {"avx": True, "avx2": True, "avx512f": False, "avx512bw": False}
    why = _C.cpu_mismatch(" avx avx2 avx512f avx512bw", cpu)
    assert "compiled for a CPU with avx512f, avx512bw, which this CPU lacks" in why
    assert "Illegal instruction" in why and "SPIKEGS_NATIVE=OFF" in why
    assert "with avx2," in _C.cpu_mismatch("avx2", {})  # a name the CPU table lacks: refused
    assert _C.cpu_mismatch(" avx avx2", cpu) == ""
    assert _C.cpu_mismatch("", {}) == ""  # a portable build runs anywhere
