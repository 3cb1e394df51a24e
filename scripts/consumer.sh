#!/usr/bin/env bash
# Installs the library into build/install and builds and runs examples/consumer against the
# installed package (find_package(pcd_pipeline), pcdp::pcdp).
set -euo pipefail
cd "$(dirname "$0")/.."
cmake --install build --prefix build/install >/dev/null
cmake -S examples/consumer -B build/consumer -G Ninja -DCMAKE_PREFIX_PATH="$PWD/build/install" >/dev/null
cmake --build build/consumer
./build/consumer/consumer
