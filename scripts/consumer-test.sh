#!/usr/bin/env bash
# Installs a built xgauge into a temporary prefix, builds tests/consumer (a
# separate CMake project: find_package(xgauge CONFIG REQUIRED)) against it
# with warnings as errors, and runs it on the demo pair: the README demo's
# steps (scripts/demo.sh) with the installed executable in a scratch copy
# of examples/, then the consumer measures examples/prism_a_small_job.json
# through the front door (xgauge/xgauge.h). Checks that the installed
# package exposes only the front door and that it works on its own.
#
#   scripts/consumer-test.sh [BUILD_DIR]    (default: build, already built)
set -euo pipefail
cd "$(dirname "$0")/.."
build_dir="${1:-build}"
if [[ ! -f "$build_dir/CMakeCache.txt" ]]; then
  echo "consumer-test: $build_dir is not a configured build folder" >&2
  exit 2
fi
tmp="$(mktemp -d "${TMPDIR:-/tmp}/xgauge-consumer.XXXXXX")"
trap 'rm -rf "$tmp"' EXIT

cmake --install "$build_dir" --prefix "$tmp/prefix" >"$tmp/install.log" ||
  { cat "$tmp/install.log" >&2; exit 1; }
# Only the installed package, not the source or build tree, may be found.
cmake -S tests/consumer -B "$tmp/build" -G Ninja -DCMAKE_BUILD_TYPE=Release \
  -DCMAKE_PREFIX_PATH="$tmp/prefix" -DCMAKE_FIND_PACKAGE_NO_PACKAGE_REGISTRY=ON \
  -DCMAKE_COMPILE_WARNING_AS_ERROR=ON
cmake --build "$tmp/build"
# Only the front door's headers are installed (XGAUGE_PUBLIC_HEADERS).
headers=$(cd "$tmp/prefix/include" && find . -type f | sort | tr '\n' ' ')
expected="./xgauge/lab.h ./xgauge/part.h ./xgauge/production.h ./xgauge/radiographs.h ./xgauge/runtime.h "
expected+="./xgauge/version.h ./xgauge/xgauge.h "
[[ "$headers" == "$expected" ]] ||
  { echo "consumer-test: installed headers: $headers (expected the front door's only)" >&2; exit 1; }
# The demo's data and material, made by the installed executable.
x="$tmp/prefix/bin/xgauge"
"$x" --version
work="$tmp/work"
mkdir -p "$work"
cp -r examples "$work/examples"
ln -s "$PWD/parts" "$work/parts"
ln -s "$PWD/datasets" "$work/datasets"
(cd "$work" &&
  "$x" simulate datasets/wedge_small.json -o data/wedge_small -q &&
  "$x" simulate datasets/prism_a_small.json -o data/prism_a_small -q &&
  "$x" characterize data/wedge_small/characterization/characterize.json -o out/detector_small -q &&
  "$x" calibrate wedge examples/calibrate_wedge_small_characterized.json \
    -o out/calibration_wedge_small -q)
"$tmp/build/xgauge_consumer" "$work/examples/prism_a_small_job.json" \
  "$work/data/prism_a_small/truth.json" "$work/out/prism_a_small"
[[ -f "$work/out/prism_a_small/result.json" && -f "$work/out/prism_a_small/report.html" ]] ||
  { echo "consumer-test: the consumer's measurement wrote no result.json and report.html" >&2; exit 1; }
echo "consumer-test: passed"
