#!/usr/bin/env bash
# kill -9 of `xgauge inspect` at three random moments during a lot, each
# followed by a restart; then the store is compared with an uninterrupted
# run's (issue 47's acceptance, on the lot lot_bench.sh inspected). Usage:
#   bench/production/kill_cycle.sh WORK [SEED]
# WORK is a finished lot_bench.sh folder (its plan.json, lot/parts and
# lot.csv, the uninterrupted run's export). Kills come at random moments
# (uniform over 5-60 % of the uninterrupted inspect's duration, drawn from
# SEED), whatever inspect is doing then. Prints the moments, the parts found
# mid-measurement, and whether every part is in the store once with the
# uninterrupted run's values (every CSV column but the measurement's time).
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
work=$(cd "$1" && pwd)
seed=${2:-$RANDOM}
x=${XGAUGE:-$root/build/apps/xgauge/xgauge}
store=$work/killed.sqlite out=$work/killed.out
rm -rf "$store" "$store"-* "$out" "$work/killed.txt" "$work/killed.log"
lot=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['lot'])" "$work/plan.json")
parts=$(ls -d "$work"/lot/parts/*/ | wc -l)
echo "kill cycle on $work ($parts parts), seed $seed"
RANDOM=$seed
args=(inspect "$work/plan.json" "$work/lot/parts" --store "$store" -o "$out" --no-report -q)
for kill in 1 2 3; do
  # Started directly (not in a function's subshell): $! is inspect itself.
  "$x" "${args[@]}" >> "$work/killed.txt" 2>> "$work/killed.log" &
  pid=$!
  wait_s=$((20 + RANDOM % 200))
  sleep "$wait_s"
  if kill -0 "$pid" 2>/dev/null; then
    kill -9 "$pid"; wait "$pid" 2>/dev/null || true
    done_now=$(python3 -c "import sqlite3,sys; c=sqlite3.connect(sys.argv[1]); print(c.execute('select count(*) from measurements').fetchone()[0])" "$store")
    echo "kill $kill after ${wait_s} s: $done_now parts in the store"
  else
    echo "kill $kill: inspect had finished before ${wait_s} s"
  fi
done
"$x" "${args[@]}" >> "$work/killed.txt" 2>> "$work/killed.log"
"$x" export "$store" --lot "$lot" --csv "$work/killed.csv" -q
python3 - "$work/lot.csv" "$work/killed.csv" "$parts" <<'PY'
import csv, sys
def rows(f):
    out = {}
    for r in csv.DictReader(open(f)):
        key = (r["part"], r["dimension"])
        if key in out:
            sys.exit(f"{f}: {key} twice")
        r.pop("measured_at")
        out[key] = r
    return out
a, b, parts = rows(sys.argv[1]), rows(sys.argv[2]), int(sys.argv[3])
stored = {p for p, _ in b}
print(f"parts in the store: {len(stored)} of {parts}, each once; rows {len(b)} (uninterrupted {len(a)})")
diff = [k for k in a if a[k] != b.get(k)] + [k for k in b if k not in a]
print("identical to the uninterrupted run" if not diff else f"{len(diff)} rows differ, e.g. {diff[:3]}")
sys.exit(1 if diff or len(stored) != parts else 0)
PY
