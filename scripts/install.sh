#!/usr/bin/env bash
# Installs SpikeGS and everything it needs: `bash scripts/install.sh` then `spikegs demo`.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
echo "install: building the C++ core and installing spikegs (pip; 1-2 minutes on 2 cores)" >&2
python -m pip install -q --no-build-isolation "${1:-.}"
echo "install: done" >&2
