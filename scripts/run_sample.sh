#!/usr/bin/env bash
# Sets up (packages + build) and runs the main pipeline on sample_scans/.
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/setup.sh
./build/tools/pcd_pipeline run pipelines/nodding_terrain.yaml "$@"
