#!/usr/bin/env bash
# Builds with ThreadSanitizer (PCDP_TSAN) and runs the tests that use threads: the 1- against
# 2-thread run, every shipped pipeline (run with one thread per core), the Kurt3D pipeline, and the
# line streaming API. A data race fails the run. tests/tsan.supp silences one report inside GDAL
# (a lock-order inversion between GDAL's own mutexes; only one of our threads ever calls GDAL).
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD_DIR=build-tsan BUILD_TYPE=RelWithDebInfo CMAKE_ARGS="-DPCDP_TSAN=ON -DPCDP_BUILD_BENCHMARKS=OFF" ./scripts/setup.sh
cd build-tsan
TSAN_OPTIONS="halt_on_error=1 suppressions=$PWD/../tests/tsan.supp" \
  ctest --output-on-failure -j "$(nproc)" -R 'Threads|Pipelines\.|Kurt3D|Stream' "$@"
