#!/usr/bin/env bash
# Installs what is missing, builds everything (library, CLI, Python module,
# Blender add-on), and runs the demo into out/demo/: the CLI pipeline on
# generated tubes, then the same tube through the Python module and through
# the add-on in Blender (headless). It needs none of the shared data.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release
cmake --build build --target curvenet_cli curvenet_python curvenet_blender_addon
build/bin/curvenet demo --out out/demo
PYTHONPATH=build/python /usr/bin/python3 scripts/demo_python.py out/demo
if ! blender -b --factory-startup --python-exit-code 1 --python scripts/demo_blender.py -- build out/demo \
    > out/demo/blender.log 2>&1; then
  cat out/demo/blender.log
  exit 1
fi
grep '^blender:' out/demo/blender.log
echo "Python module: build/python (PYTHONPATH=build/python /usr/bin/python3 -c 'import curvenet')"
echo "Blender add-on: build/blender/curvenet_blender.zip (docs/blender.md)"
