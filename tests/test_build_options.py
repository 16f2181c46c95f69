"""What the build and its dependency script take: the options CMake refuses together, and the
compiler that scripts/install-deps.sh finds where CMake would."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("inplace", [True, False])
def test_an_in_place_build_without_the_python_module_is_refused_at_configure(tmp_path, inplace):
    """-DSPIKEGS_INPLACE=ON alone (the extension's not-built message named it alone) configured,
    then built no module, unsaid: refused, naming the option it needs (the install trial); the
    C++ tests' build alone (PYTHON=OFF) is not."""
    options = ["-DSPIKEGS_PYTHON=OFF", "-DSPIKEGS_TESTS=OFF", f"-DSPIKEGS_INPLACE={inplace:d}"]
    done = subprocess.run(
        ["cmake", "-S", str(ROOT), "-B", str(tmp_path), *options], capture_output=True, text=True
    )
    refused = "SPIKEGS_PYTHON=OFF does not build: add -DSPIKEGS_PYTHON=ON" in done.stderr
    assert refused == inplace and (done.returncode != 0) == inplace, done.stderr


def test_a_missing_pybind11_says_how_to_install_it(tmp_path):
    """CMake's own message for a pybind11 it cannot find named pybind11_DIR and
    CMAKE_PREFIX_PATH, not the pip package (the install trial)."""
    options = ["-DSPIKEGS_PYTHON=ON", "-DSPIKEGS_TESTS=OFF", f"-Dpybind11_DIR={tmp_path / 'no'}"]
    done = subprocess.run(
        ["cmake", "-S", str(ROOT), "-B", str(tmp_path / "b"), *options],
        capture_output=True,
        text=True,
    )
    said = " ".join(done.stderr.split())  # (CMake wraps its messages)
    assert done.returncode != 0 and "pybind11 not found for " in said, done.stderr
    assert "pip install 'pybind11>=2.12' (or bash scripts/install-deps.sh)" in said, said


def test_a_missing_glm_says_how_to_install_it_and_pass_its_prefix_through_pip(tmp_path):
    """GLM found nowhere (the search rooted in an empty folder): the message says how to install
    it and how to pass its prefix, through pip too (-DCMAKE_PREFIX_PATH alone is CMake's, which
    `pip install .` takes as -C cmake.define...; the install trial)."""
    (tmp_path / "root").mkdir()
    options = [
        "-DSPIKEGS_PYTHON=OFF",
        "-DSPIKEGS_TESTS=OFF",
        f"-DCMAKE_FIND_ROOT_PATH={tmp_path / 'root'}",
        "-DCMAKE_FIND_ROOT_PATH_MODE_INCLUDE=ONLY",
        "-DCMAKE_FIND_ROOT_PATH_MODE_PACKAGE=ONLY",
    ]
    done = subprocess.run(
        ["cmake", "-S", str(ROOT), "-B", str(tmp_path / "b"), *options],
        capture_output=True,
        text=True,
    )
    said = " ".join(done.stderr.split())  # (CMake wraps its messages)
    assert done.returncode != 0 and "GLM not found: install it (Debian/Ubuntu: apt-get" in said
    assert "(through pip: -C cmake.define.CMAKE_PREFIX_PATH=<glm prefix>)" in said, said


def _install_deps(tmp_path, apt: bool = False, **env) -> subprocess.CompletedProcess:
    """scripts/install-deps.sh on a PATH of `id` and a `python` that records its arguments in
    tmp_path/python.args (no c++, g++, clang++ or brew; an `apt-get` recording its arguments in
    tmp_path/apt.args where `apt`), with `env`; GLM found under a prefix of CMAKE_PREFIX_PATH,
    wherever the machine keeps its own (or has none)."""
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    if apt:
        (bin_dir / "apt-get").write_text(f'#!/bin/sh\necho "$@" >> {tmp_path / "apt.args"}\n')
        (bin_dir / "apt-get").chmod(0o755)
    (tmp_path / "prefix" / "include" / "glm").mkdir(parents=True)
    (tmp_path / "prefix" / "include" / "glm" / "glm.hpp").write_text("")
    env = {"CMAKE_PREFIX_PATH": str(tmp_path / "prefix"), **env}
    (bin_dir / "id").symlink_to(shutil.which("id"))
    python = bin_dir / "python"
    python.write_text(f'#!/bin/sh\necho "$@" >> {tmp_path / "python.args"}\n')
    python.chmod(0o755)
    return subprocess.run(
        ["/bin/bash", str(ROOT / "scripts" / "install-deps.sh")],
        capture_output=True,
        text=True,
        env={"PATH": str(bin_dir), "HOME": str(tmp_path), **env},
    )


def test_install_deps_takes_the_compiler_cxx_names(tmp_path):
    """A compiler named by CXX alone (conda's x86_64-conda-linux-gnu-c++, no c++ on the PATH)
    was refused, "install g++ or clang++", though CMake would use it; a CXX that is no program is
    said as such."""
    compiler = tmp_path / "x86_64-conda-linux-gnu-c++"
    compiler.symlink_to(shutil.which("g++") or shutil.which("c++"))
    done = _install_deps(tmp_path, CXX=str(compiler))
    assert done.returncode == 0, done.stderr
    assert "pip install" in (tmp_path / "python.args").read_text()  # on to the build backend
    (tmp_path / "flags").mkdir()  # (CXX with its flags: the program is its first word)
    assert _install_deps(tmp_path / "flags", CXX=f"{compiler} -O2").returncode == 0
    # a CXX that is no program: said, and no g++ installed in its place (CMake would take CXX)
    (tmp_path / "other").mkdir()
    missing = _install_deps(tmp_path / "other", apt=True, CXX="/nonexistent/c++")
    assert missing.returncode == 1
    assert "no C++ compiler at CXX=/nonexistent/c++: set CXX to one" in missing.stderr
    assert not (tmp_path / "other" / "apt.args").exists()
