#!/usr/bin/env bash
# The production line end to end, timed: simulate a lot, inspect it into an
# SQLite store, SPC with the first 100 parts as phase I, export. Prints the
# figures issue 47's acceptance asks for (the rule and part that flag the
# drift, alarms before it, Cpk of the stable phase against the truth's,
# parts per minute). Usage:
#   bench/production/lot_bench.sh [RECIPE] [WORK_FOLDER]
# Default: bench/production/cuboid_lot.json (200 cuboids at 256 x 224, a
# few minutes on 2 cores); datasets/prism_a_lot.json is the acceptance lot at
# 1024^2 (hours on 2 cores), measured with examples/prism_a_lot_plan.json's job.
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
recipe=${1:-$root/bench/production/cuboid_lot.json}
work=${2:-$root/out/lot_bench}
x=${XGAUGE:-$root/build/apps/xgauge/xgauge}
rm -rf "$work" && mkdir -p "$work"
t0=$(date +%s.%N)
"$x" simulate "$recipe" -o "$work/lot" -q
t1=$(date +%s.%N)
"$x" material --from-truth "$work/lot/truth/p0001.json" -o "$work/material.json" -q
lot=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['lot'])" "$work/lot/truth.json")
python3 "$root/bench/production/make_plan.py" "$recipe" "$work" "$lot" > "$work/plan.json"
t2=$(date +%s.%N)
"$x" inspect "$work/plan.json" "$work/lot/parts" --store "$work/results.sqlite" -o "$work/out" \
  --no-report -q > "$work/inspect.txt"
t3=$(date +%s.%N)
"$x" spc "$work/results.sqlite" -o "$work/spc" --baseline 100 -q > "$work/alarms.txt"
"$x" export "$work/results.sqlite" --lot "$lot" --dfq "$work/lot.dfq" --csv "$work/lot.csv" -q
python3 "$root/bench/production/figures.py" "$work" "$t0" "$t1" "$t2" "$t3"
