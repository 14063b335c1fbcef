#!/usr/bin/env bash
# xgauge's main job on generated data: install the dependencies, build,
# simulate the replica wedge and Prism A sessions at 1024^2
# (datasets/wedge_small.json, with its detector characterisation shots, and
# datasets/prism_a_small.json), characterise the detector from its dark and
# flat series, edge, crosstalk and lag shots, calibrate the material from
# the wedge's calibration shot on that characterised detector, then measure
# Prism A from two radiographs (t00 and t03, 30 mm apart) and print the
# dimensions against the truth. Results: out/detector_small/ (detector.json,
# bad_pixels.json), out/calibration_wedge_small/ (material.json,
# calibration.json, report.html) and out/prism_a_small/ (report.html, the
# inspection report to open in a browser; result.json, simulated and
# difference images, measure.log).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release
cmake --build build --parallel "$(nproc)" --target xgauge
xgauge=build/apps/xgauge/xgauge
# A wedge session simulated before the characterisation shots were added has
# no characterization/ folder: simulate it again.
[ -f data/wedge_small/characterization/characterize.json ] ||
    "$xgauge" simulate datasets/wedge_small.json -o data/wedge_small
[ -f data/prism_a_small/truth.json ] || "$xgauge" simulate datasets/prism_a_small.json -o data/prism_a_small
# The machine file examples/machine_1024_characterized.json names the
# detector file this writes.
"$xgauge" characterize data/wedge_small/characterization/characterize.json -o out/detector_small
"$xgauge" calibrate wedge examples/calibrate_wedge_small_characterized.json -o out/calibration_wedge_small \
    --truth data/wedge_small/truth.json
"$xgauge" measure examples/prism_a_small_job.json -o out/prism_a_small --truth data/prism_a_small/truth.json

echo "demo: open out/prism_a_small/report.html and out/calibration_wedge_small/report.html in a browser"
