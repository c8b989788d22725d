#!/usr/bin/env bash
# Installs the Debian packages kintsugi needs to build, test and benchmark (clang and its
# libFuzzer runtime for scripts/test.sh's header check and fuzzing).
# Idempotent; quiet when everything is already present. Needs root (or sudo) to install.
set -euo pipefail

packages=(
  g++ cmake ninja-build ccache pkg-config python3
  libeigen3-dev libcgal-dev libgmp-dev libmpfr-dev libboost-graph-dev
  libnanoflann-dev libtbb-dev libcli11-dev doctest-dev libbenchmark-dev
  clang libclang-rt-14-dev
)

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done
[ ${#missing[@]} -eq 0 ] && exit 0

echo "setup: installing ${missing[*]}" >&2
SUDO=""
if [ "$(id -u)" -ne 0 ]; then
  command -v sudo >/dev/null || { echo "setup: need root or sudo to install: ${missing[*]}" >&2; exit 1; }
  SUDO="sudo"
fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
echo "setup: done" >&2
