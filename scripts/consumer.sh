#!/usr/bin/env bash
# Installs the project into build/install and checks the installed package:
#  - examples/consumer, built against it (find_package(pcd_pipeline), pcdp::pcdp), runs;
#  - the installed CLI (P/bin/pcd_pipeline) runs from a folder outside the repository: `stages`,
#    the installed sample pipeline (P/share/pcd_pipeline, outputs into ./out/<name> of that
#    folder) and `bench`, whose defaults come from P/share/pcd_pipeline.
set -euo pipefail
cd "$(dirname "$0")/.."
P="$PWD/build/install"
cmake --install build --prefix "$P" >/dev/null
cmake -S examples/consumer -B build/consumer -G Ninja -DCMAKE_PREFIX_PATH="$P" >/dev/null
cmake --build build/consumer
./build/consumer/consumer

away="$(mktemp -d)"
trap 'rm -rf "$away"' EXIT
(
  cd "$away"
  "$P/bin/pcd_pipeline" stages | grep '^register' >/dev/null
  "$P/bin/pcd_pipeline" run "$P/share/pcd_pipeline/pipelines/nodding_terrain.yaml" -q
  test -s out/nodding_terrain/report.json
  test -s out/nodding_terrain/cloud.pcd
  "$P/bin/pcd_pipeline" bench --passes 1 --reps 1 --geometric | grep 'whole run on 2 threads' >/dev/null
)
echo "consumer: the installed library and $P/bin/pcd_pipeline work (from $away)"
