#!/usr/bin/env bash
# Installs SpikeGS and everything it needs: `bash scripts/install.sh` then `spikegs demo`.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
python -m pip install -q --no-build-isolation "${1:-.}"
