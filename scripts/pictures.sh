#!/usr/bin/env bash
# Regenerates the add-on pictures in docs/images/ (README.md, docs/blender.md):
# builds the module and the add-on, then renders with Blender headless from
# the shared data in ../shared/data.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release
cmake --build build --target curvenet_blender_addon
blender -b --factory-startup --python-exit-code 1 --python scripts/render_pictures.py -- \
  build "${CURVENET_DATA_DIR:-../shared/data}" docs/images
