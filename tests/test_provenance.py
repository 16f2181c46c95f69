"""provenance.py: the CPU and threads a result's record names."""

import platform

import pytest
from spikegs import _C
from spikegs.provenance import cpu_record, environment

_EPYC = """processor\t: 0
vendor_id\t: AuthenticAMD
cpu family\t: 25
model\t\t: 17
model name\t: AMD EPYC 9454 48-Core Processor
stepping\t: 1
flags\t\t: fpu sse2 avx2 avx512f {bf16}

processor\t: 1
cpu family\t: 6
model\t\t: 85
model name\t: another CPU's
stepping\t: 7
flags\t\t: fpu sse2 avx512_bf16 amx_bf16
"""


@pytest.mark.parametrize(
    ("bf16", "native"), [("avx512_bf16", True), ("amx_bf16 amx_tile", True), ("avx512_vnni", False)]
)
def test_an_x86_cpus_record_is_its_first_blocks(tmp_path, bf16, native):
    """The first CPU's model name, family, model and stepping, and native bfloat16 where its
    flags hold AVX-512's or AMX's (the second CPU's block, with both, is not read)."""
    (tmp_path / "cpuinfo").write_text(_EPYC.format(bf16=bf16))
    assert cpu_record(str(tmp_path / "cpuinfo")) == {
        "cpu": "AMD EPYC 9454 48-Core Processor",
        "cpu_id": "family 25 model 17 stepping 1",
        "native_bf16": native,
    }


@pytest.mark.parametrize("processor", ["aarch64", ""])
def test_a_cpu_without_x86_fields_is_named_by_the_platform(tmp_path, monkeypatch, processor):
    """An ARM cpuinfo (no model name, no cpu family) or none at all: the platform's word for the
    CPU, else "unknown"; no family, model or bfloat16 claimed."""
    monkeypatch.setattr(platform, "processor", lambda: processor)
    (tmp_path / "cpuinfo").write_text("processor\t: 0\nBogoMIPS\t: 50.00\nCPU part\t: 0xd0c\n")
    for cpuinfo in (tmp_path / "cpuinfo", tmp_path / "none"):
        assert cpu_record(str(cpuinfo)) == {"cpu": processor or "unknown"}


def test_the_cores_threads_are_its_own_or_none_from_an_older_extension(monkeypatch):
    assert environment()["core_threads"] == _C.max_threads()
    monkeypatch.delattr(_C, "max_threads")
    assert environment()["core_threads"] is None
