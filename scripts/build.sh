#!/usr/bin/env bash
# Installs the Debian packages mbdae needs (only those missing), then configures and
# builds into build/. Run as root on Debian 12 (or with sudo available).
set -euo pipefail
cd "$(dirname "$0")/.."

packages=(build-essential cmake pkg-config
  libsundials-dev libsuitesparse-dev libeigen3-dev libhdf5-dev libyaml-cpp-dev
  libgtest-dev libbenchmark-dev
  coinor-libipopt-dev liburdfdom-dev
  python3 python3-numpy python3-scipy python3-sympy python3-yaml python3-h5py
  python3-matplotlib python3-pytest python3-pandas python3-dask python3-distributed
  libjs-three chromium python3-pil)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "Installing: ${missing[*]}" >&2
  SUDO=""
  [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

jobs=$(nproc 2>/dev/null || echo 2)
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release -DMBDAE_PYTHON=/usr/bin/python3 >/dev/null
cmake --build build -j "$jobs"
