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

# The deformation modes side by side with the skins (docs/deform.md).
cmake --build build --target deform_quality
tmp=$(mktemp -d)
render() { blender -b --factory-startup --python-exit-code 1 --python scripts/render_deform_quality.py -- "$@"; }
build/bin/deform_quality --ply "$tmp/bend" "cylinder bend 135" > /dev/null
render docs/images/quality_bend_135.png "$tmp/bend" rest LBS DQS "dq:dq (default)" harmonic gradient \
  --view 0 0 1 --up 0 1 0 --focus 0.2 2 0 2.2 --panel 300 420
build/bin/deform_quality --ply "$tmp/twist" "cylinder twist 180" > /dev/null
render docs/images/quality_twist_180.png "$tmp/twist" rest LBS DQS "dq:dq (default)" harmonic gradient \
  "gradient_without_sections:gradient, old" --view 0 0 1 --up 0 1 0 --focus 0 2 0 2.2 --panel 260 420
build/bin/deform_quality --ply "$tmp/fist" "hand fist grip" > /dev/null
render docs/images/quality_fist.png "$tmp/fist" LBS DQS "dq:dq (default)" harmonic gradient \
  --view 1 0.3 0.3 --up 0 1 0 --focus 0.01 0.01 -0.07 0.075 --panel 320 360
build/bin/deform_quality --ply "$tmp/flex" "hand flex" > /dev/null
render docs/images/quality_flex.png "$tmp/flex" rest LBS DQS "dq:dq (default)" harmonic gradient \
  --view 0 1 0 --up 1 0 0 --focus -0.02 0 -0.11 0.05 --panel 300 300
# CesiumMan's walk through the starter net with and without its middle nodes (docs/starter.md).
build/bin/deform_quality --ply "$tmp/cesium" "cesium man walk" > /dev/null
CURVENET_MIDDLE_NODES=0 build/bin/deform_quality --ply "$tmp/cesium_whole" "cesium man walk" > /dev/null
cp "$tmp/cesium_whole/dq.ply" "$tmp/cesium/dq_whole.ply"
render docs/images/starter_middle_nodes.png "$tmp/cesium" LBS DQS "dq_whole:dq, no middle nodes" \
  "dq:dq, middle nodes" --view 0 -1 0.2 --up 0 0 1 --focus 0 -0.05 0.45 0.55 --panel 300 420
rm -rf "$tmp"
