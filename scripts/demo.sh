#!/usr/bin/env bash
# Installs the dependencies, builds xgauge, and renders a radiograph of
# Prism A (PARTS.md) on the replica 4096^2 machine: out/prism_a.tif and a PNG
# preview out/prism_a.png.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release
cmake --build build --parallel "$(nproc)" --target xgauge
mkdir -p out
build/apps/xgauge/xgauge render parts/prism_jaw.json \
  --machine examples/machine_4096.json --material examples/aluminium_60kev.json \
  --pose examples/prism_a_pose.json --samples 2 --format u16 \
  -o out/prism_a.tif --png out/prism_a.png
