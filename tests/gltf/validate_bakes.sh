#!/usr/bin/env bash
# Bakes the shared data with the CLI and runs the Khronos glTF-Validator on
# every result: 0 errors wanted (and 0 warnings, which we check too).
#   validate_bakes.sh CLI DATA_DIR NODE_MODULES OUT_DIR
set -euo pipefail
cli=$1 data=$2 modules=$3 out=$4
if [ ! -f "$modules/gltf-validator/package.json" ]; then
  echo "gltf-validator is not installed in $modules (scripts/test.sh installs it)"
  exit 77
fi
if [ ! -d "$data" ]; then
  echo "no shared data at $data"
  exit 77
fi
mkdir -p "$out"
hand=$data/xr_tools_hand
"$cli" bake "$hand/hand_l.gltf" "$hand/example/hand_l.cnrig.json" -o "$out/hand.glb" --clip "$hand/hand_l_poses.glb" >/dev/null
"$cli" bake "$hand/hand_l_quads.obj" "$hand/example/hand_l.cnrig.json" -o "$out/hand_quads_zup.glb" --up z --max-influences 8 >/dev/null
"$cli" starter "$data/cesium_man/CesiumMan.glb" -o "$out/cesium.cnrig.json" >/dev/null
"$cli" bake "$data/cesium_man/CesiumMan.glb" "$out/cesium.cnrig.json" -o "$out/cesium.glb" --clip "$data/cesium_man/CesiumMan.glb" >/dev/null
# The rig goes onto the 326-triangle variant as a rig goes onto another
# tessellation: by transfer (its curves lie off the coarse surface).
"$cli" transfer "$out/cesium.cnrig.json" --from "$data/cesium_man/CesiumMan.glb" \
  --to "$data/cesium_man/variants/cesium_man_e_decimated_326.obj" -o "$out/cesium_326.cnrig.json" >/dev/null
"$cli" bake "$data/cesium_man/variants/cesium_man_e_decimated_326.obj" "$out/cesium_326.cnrig.json" \
  --skeleton "$data/cesium_man/CesiumMan.glb" -o "$out/cesium_326.glb" --clip "$data/cesium_man/CesiumMan.glb" >/dev/null
# Helper joints (bake --helpers): nodes under the rig's joints, keyed in every
# clip, with extras naming their two joints; eight influences (JOINTS_1).
"$cli" starter "$data/quaternius/Trex.glb" -o "$out/trex.cnrig.json" >/dev/null
"$cli" bake "$data/quaternius/Trex.glb" "$out/trex.cnrig.json" -o "$out/trex_helpers.glb" --weights fitted \
  --helpers 16 --max-influences 8 --clip "$data/quaternius/Trex.glb" >/dev/null
dir=$(cd "$(dirname "$0")" && pwd)
report=$(node "$dir/validate.js" "$modules" "$out"/*.glb)
echo "$report"
if echo "$report" | grep -q " [1-9][0-9]* warnings"; then
  echo "warnings found"
  exit 1
fi
