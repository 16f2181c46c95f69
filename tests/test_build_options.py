"""What the build and its dependency script take: the options CMake refuses together, and the
compiler that scripts/install-deps.sh finds where CMake would."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_an_in_place_build_without_the_python_module_is_refused_at_configure(tmp_path):
    """-DSPIKEGS_INPLACE=ON alone (the extension's not-built message named it alone) configured,
    then built no module, unsaid: refused, naming the option it needs (the install trial)."""
    done = subprocess.run(
        [
            "cmake",
            "-S",
            str(ROOT),
            "-B",
            str(tmp_path),
            "-DSPIKEGS_INPLACE=ON",
            "-DSPIKEGS_PYTHON=OFF",
        ],
        capture_output=True,
        text=True,
    )
    assert done.returncode != 0
    assert "SPIKEGS_PYTHON=OFF does not build: add -DSPIKEGS_PYTHON=ON" in done.stderr, done.stderr


def _install_deps(tmp_path, **env) -> subprocess.CompletedProcess:
    """scripts/install-deps.sh on a PATH of `id` and a `python` that records its arguments in
    tmp_path/python.args (no c++, g++, clang++, apt-get or brew), with `env`; GLM found under a
    prefix of CMAKE_PREFIX_PATH, wherever the machine keeps its own (or has none)."""
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
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
    (tmp_path / "other").mkdir()
    missing = _install_deps(tmp_path / "other", CXX="/nonexistent/c++")
    assert missing.returncode == 1
    assert "no C++ compiler at CXX=/nonexistent/c++: set CXX to one" in missing.stderr
