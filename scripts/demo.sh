#!/usr/bin/env bash
# Installs what is missing, builds curvenet, and runs the demo pipeline into out/demo/.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release
cmake --build build --target curvenet_cli
build/bin/curvenet demo --out out/demo
