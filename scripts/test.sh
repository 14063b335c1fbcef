#!/usr/bin/env bash
# Installs the dependencies, builds xgauge in Release with warnings as errors,
# runs the whole test suite (CTest + GoogleTest), then the consumer test of
# the installed library (scripts/consumer-test.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release -DXGAUGE_WARNINGS_AS_ERRORS=ON
cmake --build build --parallel "$(nproc)"
ctest --test-dir build --output-on-failure --parallel "$(nproc)" --timeout 900
# The installed library, used by a separate project through its CMake package.
bash scripts/consumer-test.sh build
