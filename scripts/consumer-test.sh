#!/usr/bin/env bash
# Installs a built xgauge into a temporary prefix, builds tests/consumer (a
# separate CMake project: find_package(xgauge CONFIG REQUIRED)) against it
# with warnings as errors, and runs it on parts/cuboid.json. Checks that the
# installed headers, static libraries and CMake package work on their own.
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
"$tmp/build/xgauge_consumer" parts/cuboid.json
"$tmp/prefix/bin/xgauge" --version
echo "consumer-test: passed"
