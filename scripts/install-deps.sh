#!/usr/bin/env bash
# Installs what building SpikeGS needs and a fresh machine may lack: GLM (system package), torch
# 2.13.0 (pinned: on this project's machines a local CPU build, where an unpinned torch pulls a
# multi-GB CUDA build; elsewhere see the README), and the build backend.
set -euo pipefail
has_glm() {
  local dir
  for dir in /usr/include /usr/local/include /opt/homebrew/include "${CONDA_PREFIX:-/nonexistent}/include"; do
    [ -f "$dir/glm/glm.hpp" ] && return 0
  done
  return 1
}
if ! has_glm; then
  if command -v apt-get >/dev/null; then
    SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
    $SUDO apt-get update -qq && $SUDO apt-get install -y -qq libglm-dev
  elif command -v brew >/dev/null; then
    brew install glm
  else
    echo "GLM is missing: install it with your package manager (conda install glm, vcpkg glm)" >&2
    exit 1
  fi
fi
python -m pip install -q "torch==2.13.0" "scikit-build-core>=0.10" "pybind11>=2.12" cmake ninja
