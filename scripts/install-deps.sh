#!/usr/bin/env bash
# Installs what building SpikeGS needs and a fresh machine may lack: a C++17 compiler (g++, where
# apt-get is), GLM (system package), torch 2.13.0 (pinned: on this project's machines a local CPU
# build, where an unpinned torch pulls a multi-GB CUDA build; elsewhere see the README), and the
# build backend.
set -euo pipefail
# Python 3.10 or newer (pyproject.toml's requires-python): torch 2.13.0, pinned below, has no
# wheel for 3.9 (torch's last for 3.9 is 2.8.0), where pip's "No matching distribution found for
# torch==2.13.0" would be the only word
python -c 'import sys; sys.exit(0 if sys.version_info >= (3, 10) else
  "SpikeGS needs Python 3.10 or newer (torch 2.13.0 has no wheel for Python %d.%d): %s"
  % (sys.version_info[0], sys.version_info[1], sys.executable))'
has_glm() {  # where CMake looks too: the prefixes in CMAKE_PREFIX_PATH (a cluster's modules)
  local dir prefixes
  IFS=: read -r -a prefixes <<<"${CMAKE_PREFIX_PATH:-}"
  # (an empty array's "${prefixes[@]}" is unbound under set -u in macOS's bash 3.2)
  for dir in /usr /usr/local /opt/homebrew "${CONDA_PREFIX:-/nonexistent}" ${prefixes[@]+"${prefixes[@]}"}; do
    [ -n "$dir" ] && [ -f "$dir/include/glm/glm.hpp" ] && return 0
  done
  return 1
}
has_compiler() {  # CXX, as CMake takes it (conda's compilers are named x86_64-conda-linux-gnu-c++)
  if [ -n "${CXX:-}" ]; then
    command -v "${CXX%% *}" >/dev/null
  else
    command -v c++ >/dev/null || command -v g++ >/dev/null || command -v clang++ >/dev/null
  fi
}
apt_install() {  # Debian/Ubuntu packages, with sudo unless root
  local sudo=""
  [ "$(id -u)" -ne 0 ] && sudo="sudo"
  $sudo apt-get update -qq && $sudo apt-get install -y -qq "$@"
}
if ! has_compiler; then
  if [ -z "${CXX:-}" ] && command -v apt-get >/dev/null; then  # a bare image: no C++17 compiler
    apt_install g++
  elif [ -n "${CXX:-}" ]; then
    echo "no C++ compiler at CXX=$CXX: set CXX to one, or unset it to use g++ or clang++" >&2
    exit 1
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
    echo "GLM is missing: install it with your package manager (conda install glm), or name the" \
      "prefix it is installed under in CMAKE_PREFIX_PATH (vcpkg's: docs/install.md)" >&2
    exit 1
  fi
fi
echo "install-deps: torch 2.13.0, scikit-build-core, pybind11, cmake, ninja (pip)" >&2
python -m pip install -q "torch==2.13.0" "scikit-build-core>=0.10" "pybind11>=2.12" cmake ninja
