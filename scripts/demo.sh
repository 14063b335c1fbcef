#!/usr/bin/env bash
# xgauge's main job on generated data: install the dependencies, build,
# simulate the replica Prism A session at 1024^2 (datasets/prism_a_small.json),
# fit the material to the lab's transmission table, then measure Prism A from
# two radiographs (t00 and t03, 30 mm apart) and print the dimensions against
# the truth. Results: out/prism_a_small/ (result.json, simulated and
# difference images, measure.log).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release
cmake --build build --parallel "$(nproc)" --target xgauge
xgauge=build/apps/xgauge/xgauge
[ -f data/prism_a_small/truth.json ] || "$xgauge" simulate datasets/prism_a_small.json -o data/prism_a_small
"$xgauge" material --from-truth data/prism_a_small/truth.json -o data/prism_a_small/material.json
"$xgauge" measure examples/prism_a_small_job.json -o out/prism_a_small --truth data/prism_a_small/truth.json
