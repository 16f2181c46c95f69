#!/usr/bin/env bash
# Installs SpikeGS with its test extras and runs every test: the house style (ruff, clang-format),
# the C++ tests (ctest, built with AddressSanitizer and UBSan: a memory error fails them; again
# without OpenMP) and pytest.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install.sh ".[dev,mitsuba,sfm]"
ruff check . && ruff format --check .
clang-format --dry-run --Werror csrc/*/*.cpp csrc/*/*.hpp cpp_tests/*.cpp cpp_tests/*.hpp
cmake -S . -B build/ctest -DSPIKEGS_PYTHON=OFF -DSPIKEGS_TESTS=ON -DSPIKEGS_SANITIZE=ON >/dev/null
cmake --build build/ctest -j"$(nproc)"
ctest --test-dir build/ctest --output-on-failure -j"$(nproc)"
# the core without OpenMP (Apple's clang has none): it must build and pass alone (~6 s); without
# -ffast-math, under which a NaN row bound of splat_rows read as no rows and hid a mutant; and
# portable (no -march=native): on an AVX-512 machine the native builds never compile the window
# counts' plain-C++ path, which every other CPU runs
cmake -S . -B build/ctest-serial -DSPIKEGS_PYTHON=OFF -DSPIKEGS_TESTS=ON \
  -DCMAKE_DISABLE_FIND_PACKAGE_OpenMP=ON -DSPIKEGS_FAST_MATH=OFF -DSPIKEGS_NATIVE=OFF \
  >build/ctest-serial.log 2>&1 ||
  { cat build/ctest-serial.log; exit 1; }  # its expected warning only on failure
cmake --build build/ctest-serial -j"$(nproc)" >/dev/null
ctest --test-dir build/ctest-serial --output-on-failure -j"$(nproc)"
python -m pytest -q tests
# the quick benchmarks into a folder of this run's own (a shared one mixed two runs' files)
bench_out="$(mktemp -d)"
trap 'rm -rf "$bench_out"' EXIT
spikegs bench all --quick --out "$bench_out"
