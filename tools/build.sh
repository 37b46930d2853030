#!/usr/bin/env bash
# Shared by tools/run and tools/test: installs missing Debian packages, then configures and builds Release
# into build/ (library, CLI, tests and benchmarks). Sourced, not run directly.
set -euo pipefail

HNS_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
HNS_PACKAGES=(build-essential cmake pkg-config libode-dev libeigen3-dev libxsimd-dev libtbb-dev
              libgtest-dev libgmock-dev libbenchmark-dev libcli11-dev nlohmann-json3-dev
              python3 git valgrind python3-dev pybind11-dev python3-numpy python3-pytest
              libopenmpi-dev openmpi-bin libgd-dev
              libmujoco-dev)  # test-only: the physics parity suite runs the original's engine (MuJoCo)
# Optional test-only packages: headless Chromium for the replay page tests, PyTorch for the PyTorch PPO
# example's test. If they cannot be installed
# (no network, no root), the tests that need them report themselves skipped; the build goes on.
HNS_TEST_PACKAGES=(chromium python3-torch)

# hns_apt_install required|optional PACKAGE...: installs the packages that are missing. A failure is fatal
# for required packages and a warning for optional ones.
hns_apt_install() {
  local need="$1"
  shift
  local missing=()
  for p in "$@"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  [ ${#missing[@]} -eq 0 ] && return 0
  echo "hns: installing missing $need packages: ${missing[*]}"
  local sudo=""
  if [ "$(id -u)" -ne 0 ]; then
    if ! command -v sudo >/dev/null; then
      echo "hns: need root or sudo to install: ${missing[*]}" >&2
      [ "$need" = optional ] && return 0
      exit 1
    fi
    sudo="sudo"
  fi
  if ! { $sudo env DEBIAN_FRONTEND=noninteractive apt-get update -qq &&
         $sudo env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing[@]}"; }; then
    if [ "$need" = optional ]; then
      echo "hns: warning: could not install ${missing[*]}; the tests that need them will be skipped" >&2
      return 0
    fi
    echo "hns: could not install ${missing[*]}" >&2
    exit 1
  fi
}

hns_install_packages() { hns_apt_install required "${HNS_PACKAGES[@]}"; }
hns_install_test_packages() { hns_apt_install optional "${HNS_TEST_PACKAGES[@]}"; }

# The build folder: build/, or build-<sanitizers>/ for a sanitizer build (HNS_SANITIZE=address,undefined).
hns_build_dir() {
  if [ -n "${HNS_SANITIZE:-}" ]; then echo "$HNS_ROOT/build-${HNS_SANITIZE//,/-}"; else echo "$HNS_ROOT/build"; fi
}

# The instruction set for HNS_ISA: $HNS_ISA if set, else avx512 where this machine has every AVX-512 part
# of x86-64-v4 (F, BW, CD, DQ, VL), else the portable avx2. A -DHNS_ISA in HNS_CMAKE_ARGS still wins.
hns_isa() {
  if [ -n "${HNS_ISA:-}" ]; then echo "$HNS_ISA"; return; fi
  local flags
  flags="$(grep -m1 '^flags' /proc/cpuinfo 2>/dev/null || true)"
  for f in avx512f avx512bw avx512cd avx512dq avx512vl; do
    [[ " $flags " == *" $f "* ]] || { echo avx2; return; }
  done
  echo avx512
}

hns_build() {
  local jobs dir isa
  jobs="${HNS_JOBS:-$(nproc)}"
  dir="$(hns_build_dir)"
  isa="$(hns_isa)"
  if [ -n "${HNS_SANITIZE:-}" ]; then
    # Sanitizer trees are built with clang (libFuzzer's compiler: an address/undefined tree also holds the
    # fuzz targets, so CI builds one tree for both); optimised, with line tables for readable reports (the
    # file and line of every frame; full debug info took about 15 % longer to compile, for nothing a report
    # shows).
    hns_apt_install required clang libclang-rt-14-dev
    local fuzz=OFF
    [[ "$HNS_SANITIZE" == *thread* ]] || fuzz=ON
    if [ -f "$dir/CMakeCache.txt" ] && ! grep -q "CMAKE_CXX_COMPILER:.*clang" "$dir/CMakeCache.txt"; then
      rm -rf "$dir"  # a tree configured with another compiler cannot be switched in place
    fi
    CC=clang CXX=clang++ cmake -S "$HNS_ROOT" -B "$dir" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
      -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O2 -gline-tables-only -DNDEBUG" \
      -DCMAKE_C_FLAGS_RELWITHDEBINFO="-O2 -gline-tables-only -DNDEBUG" -DHNS_SANITIZE="$HNS_SANITIZE" \
      -DHNS_FUZZ="$fuzz" -DHNS_BUILD_BENCH=OFF -DHNS_ISA="$isa" ${HNS_CMAKE_ARGS:-}
  else
    cmake -S "$HNS_ROOT" -B "$dir" -DCMAKE_BUILD_TYPE=Release -DHNS_ISA="$isa" ${HNS_CMAKE_ARGS:-}
  fi
  cmake --build "$dir" -j "$jobs"
}
