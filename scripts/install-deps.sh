#!/usr/bin/env bash
# Installs the Debian 12 packages Viscera builds with. Idempotent: packages already present are
# skipped, and apt-get runs only when something is missing.
set -euo pipefail

packages=(
  build-essential cmake ninja-build ccache pkg-config
  libeigen3-dev libsuitesparse-dev libopenblas0-serial libpugixml-dev nlohmann-json3-dev libcli11-dev libtbb-dev zlib1g-dev libnlopt-cxx-dev libboost-dev libopenmpi-dev openmpi-bin
  libexodusii-dev libnetcdf-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libtorch-dev
  libpcl-dev libopenmesh-dev tetgen
  gnuplot-nox
)
# Extra packages a target needs (e.g. `make fuzz` asks for clang).
packages+=("$@")

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  exit 0
fi

echo "install-deps: installing ${missing[*]}"
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
