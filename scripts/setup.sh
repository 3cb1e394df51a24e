#!/usr/bin/env bash
# Idempotent set-up: installs the Debian packages the project needs (only those missing) and
# builds (Release by default; BUILD_TYPE=Debug ./scripts/setup.sh for a debug build).
#   BUILD_DIR   build folder (default: build)
#   CMAKE_ARGS  extra arguments for cmake's configure step
set -euo pipefail
cd "$(dirname "$0")/.."

PACKAGES=(
  cmake ninja-build g++ pkg-config
  libeigen3-dev libyaml-cpp-dev libcli11-dev nlohmann-json3-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libpcl-dev liboctomap-dev libpng-dev libdeflate-dev zlib1g-dev  # zlib: import carmen reads .log.gz
  libtiff-dev libgeotiff-dev libproj-dev  # elevation.tif: libtiff, its GeoKeys (libgeotiff), a WKT `crs` checked (PROJ)
  libsqlite3-dev  # import rosbag2: ROS 2 bags (sqlite3 storage)
  libssl-dev  # libcrypto: SHA-256 of report.json's inputs and outputs
  libgdal-dev gdal-bin  # the tests only: an independent reader of the GeoTIFFs we write (and gdalinfo)
)

missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing ${missing[*]}" >&2
  SUDO=""
  [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

BUILD_DIR="${BUILD_DIR:-build}"
cmake -S . -B "$BUILD_DIR" -G Ninja -DCMAKE_BUILD_TYPE="${BUILD_TYPE:-Release}" ${CMAKE_ARGS:-} >/dev/null
cmake --build "$BUILD_DIR" -j "$(nproc)"
