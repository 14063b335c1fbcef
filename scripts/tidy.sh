#!/usr/bin/env bash
# Runs clang-tidy (.clang-tidy) over every xgauge source of a configured build
# (default: build/, which writes compile_commands.json). Exits non-zero on any
# finding. Usage: scripts/tidy.sh [build folder] [jobs]
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
jobs=${2:-$(nproc)}
[ -f "$build/compile_commands.json" ] || { echo "tidy: configure $build first" >&2; exit 2; }
command -v run-clang-tidy >/dev/null || { echo "tidy: install clang-tidy" >&2; exit 2; }
files=$(git ls-files '*.cpp' | grep -v '^tests/consumer/')
# shellcheck disable=SC2086
# The compile commands are GCC's: clang would stop at its unknown warning
# flags and turn its own stricter warnings into errors (-Werror); the compiler
# already checks warnings, tidy checks what .clang-tidy lists.
run-clang-tidy -quiet -p "$build" -j "$jobs" -extra-arg=-Wno-unknown-warning-option \
  -extra-arg=-Wno-error $files
