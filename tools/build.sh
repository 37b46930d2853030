#!/usr/bin/env bash
# Shared by tools/run and tools/test: installs missing Debian packages, then configures and
# builds Release into build/ (library, CLI, tests and benchmarks). Sourced, not run directly.
set -euo pipefail

HNS_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
HNS_PACKAGES=(build-essential cmake pkg-config libode-dev libeigen3-dev libxsimd-dev libtbb-dev
              libgtest-dev libgmock-dev libbenchmark-dev libcli11-dev nlohmann-json3-dev
              python3 git)

hns_install_packages() {
  local missing=()
  for p in "${HNS_PACKAGES[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  [ ${#missing[@]} -eq 0 ] && return 0
  echo "hns: installing missing packages: ${missing[*]}"
  local sudo=""
  if [ "$(id -u)" -ne 0 ]; then
    command -v sudo >/dev/null || { echo "hns: need root or sudo to install: ${missing[*]}" >&2; exit 1; }
    sudo="sudo"
  fi
  $sudo env DEBIAN_FRONTEND=noninteractive apt-get update -qq
  $sudo env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing[@]}"
}

hns_build() {
  local jobs
  jobs="${HNS_JOBS:-$(nproc)}"
  cmake -S "$HNS_ROOT" -B "$HNS_ROOT/build" -DCMAKE_BUILD_TYPE=Release ${HNS_CMAKE_ARGS:-}
  cmake --build "$HNS_ROOT/build" -j "$jobs"
}
