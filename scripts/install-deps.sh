#!/usr/bin/env bash
# Installs what building SpikeGS needs and a fresh machine may lack: a C++17 compiler (g++, where
# apt-get is), GLM (system package), torch 2.13.0 (pinned: on this project's machines a local CPU
# build, where an unpinned torch pulls a multi-GB CUDA build; elsewhere see the README), and the
# build backend.
set -euo pipefail
has_glm() {
  local dir
  for dir in /usr/include /usr/local/include /opt/homebrew/include "${CONDA_PREFIX:-/nonexistent}/include"; do
    [ -f "$dir/glm/glm.hpp" ] && return 0
  done
  return 1
}
apt_install() {  # Debian/Ubuntu packages, with sudo unless root
  local sudo=""
  [ "$(id -u)" -ne 0 ] && sudo="sudo"
  $sudo apt-get update -qq && $sudo apt-get install -y -qq "$@"
}
if ! command -v c++ >/dev/null && ! command -v g++ >/dev/null && ! command -v clang++ >/dev/null; then
  if command -v apt-get >/dev/null; then  # a bare image: no C++17 compiler
    apt_install g++
  else
    echo "no C++ compiler: install g++ or clang++ (C++17; on macOS, Xcode's command line tools)" >&2
    exit 1
  fi
fi
if ! has_glm; then
  if command -v apt-get >/dev/null; then
    apt_install libglm-dev
  elif command -v brew >/dev/null; then
    brew install glm
  else
    echo "GLM is missing: install it with your package manager (conda install glm, vcpkg glm)" >&2
    exit 1
  fi
fi
python -m pip install -q "torch==2.13.0" "scikit-build-core>=0.10" "pybind11>=2.12" cmake ninja
