#!/usr/bin/env bash
# Installs SpikeGS with its test extras and runs every test: the C++ tests (ctest, built with
# AddressSanitizer and UBSan: a memory error fails them) and pytest.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install.sh ".[test,mitsuba,sfm]"
cmake -S . -B build/ctest -DSPIKEGS_PYTHON=OFF -DSPIKEGS_TESTS=ON -DSPIKEGS_SANITIZE=ON >/dev/null
cmake --build build/ctest -j"$(nproc)"
ctest --test-dir build/ctest --output-on-failure -j"$(nproc)"
python -m pytest -q tests
spikegs bench all --quick --out "${TMPDIR:-/tmp}/spikegs-bench-quick"
