#!/usr/bin/env bash
# Builds the libFuzzer targets with clang and fuzzes each for SECONDS (default 20) on a copy of
# the committed corpus (tests/fuzz/corpus). Exits non-zero if a target crashes; the crashing input
# is left as tests/fuzz/crash-* to become a corpus case.
set -euo pipefail
cd "$(dirname "$0")/.."
SECONDS_EACH="${1:-20}"
missing=()
for p in clang libclang-rt-14-dev; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi
./scripts/setup.sh >/dev/null  # the other Debian packages
CC=clang CXX=clang++ cmake -S . -B build-fuzz -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DPCDP_FUZZ=ON \
  -DPCDP_BUILD_TESTS=OFF -DPCDP_BUILD_TOOLS=OFF -DPCDP_BUILD_BENCHMARKS=OFF >/dev/null
cmake --build build-fuzz -j "$(nproc)" --target fuzz_pcd fuzz_pose_csv fuzz_pipeline_yaml fuzz_geotiff fuzz_grid_metadata fuzz_rosbag2_cdr fuzz_carmen fuzz_las
status=0
for t in pcd pose_csv pipeline_yaml geotiff grid_metadata rosbag2_cdr carmen las; do
  work="build-fuzz/corpus-$t"
  rm -rf "$work" && mkdir -p "$work" && cp tests/fuzz/corpus/$t/* "$work"/
  if build-fuzz/tests/fuzz/fuzz_$t -max_total_time="$SECONDS_EACH" -rss_limit_mb=2048 -print_final_stats=1 -artifact_prefix=tests/fuzz/crash-$t- \
      "$work" > "build-fuzz/fuzz_$t.log" 2>&1; then
    echo "fuzz $t: $(grep -o 'stat::number_of_executed_units: [0-9]*' build-fuzz/fuzz_$t.log || tail -1 build-fuzz/fuzz_$t.log) in ${SECONDS_EACH} s, no crash"
  else
    echo "fuzz $t: CRASH (see build-fuzz/fuzz_$t.log and tests/fuzz/crash-$t-*)"; tail -30 "build-fuzz/fuzz_$t.log"; status=1
  fi
done
exit $status
