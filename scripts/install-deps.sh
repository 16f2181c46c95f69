#!/usr/bin/env bash
# Installs what building SpikeGS needs and a fresh machine may lack: GLM (system package), the CPU
# build of torch (pinned: an unpinned torch pulls a multi-GB CUDA build), and the build backend.
set -euo pipefail
if [ ! -f /usr/include/glm/glm.hpp ] && [ ! -f /usr/local/include/glm/glm.hpp ]; then
  if command -v apt-get >/dev/null; then
    SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
    $SUDO apt-get update -qq && $SUDO apt-get install -y -qq libglm-dev
  else
    echo "GLM is missing: install it with your package manager (brew install glm, conda install glm)" >&2
    exit 1
  fi
fi
python -m pip install -q "torch==2.13.0" "scikit-build-core>=0.10" "pybind11>=2.12" cmake ninja
