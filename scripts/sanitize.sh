#!/usr/bin/env bash
# Builds with AddressSanitizer + UndefinedBehaviorSanitizer (PCDP_SANITIZE) and runs the unit and
# end-to-end tests under them. Leak detection is off: GDAL, PCL and OctoMap keep process-lifetime
# allocations that LeakSanitizer reports; memory errors and undefined behaviour still fail.
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD_DIR=build-asan BUILD_TYPE=RelWithDebInfo CMAKE_ARGS="-DPCDP_SANITIZE=ON -DPCDP_BUILD_BENCHMARKS=OFF" ./scripts/setup.sh
cd build-asan
ASAN_OPTIONS=detect_leaks=0:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 ctest --output-on-failure -j "$(nproc)" "$@"
