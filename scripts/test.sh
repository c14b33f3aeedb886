#!/usr/bin/env bash
# Installs what is missing, builds curvenet and runs the whole test suite:
# once in Release, once under AddressSanitizer and UndefinedBehaviorSanitizer.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
jobs=$(nproc)
# The Khronos glTF-Validator, for the baked skins (from the npm registry).
validator=2.0.0-dev.3.10
if ! grep -qs "\"version\": \"$validator\"" build-tools/node_modules/gltf-validator/package.json; then
  npm install --no-audit --no-fund --silent --prefix build-tools "gltf-validator@$validator"
fi
# three.js, the engine that poses the baked skins in tests/engine (pinned).
three=0.170.0
if ! grep -qs "\"version\": \"$three\"" build-tools/node_modules/three/package.json; then
  npm install --no-audit --no-fund --silent --prefix build-tools "three@$three"
fi

cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release
cmake --build build -j "$jobs"
ctest --test-dir build --output-on-failure -j "$jobs"

if [ "${CURVENET_SKIP_SANITIZERS:-0}" != "1" ]; then
  cmake -S . -B build-asan -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCURVENET_SANITIZE=ON
  cmake --build build-asan -j "$jobs"
  # The fuzzer (tests/fuzz_test.cpp) runs longer under the sanitizers.
  ASAN_OPTIONS=detect_leaks=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
    CURVENET_FUZZ_ITERATIONS=15000 CURVENET_FUZZ_SECONDS=120 \
    ctest --test-dir build-asan --output-on-failure -j "$jobs"
fi

