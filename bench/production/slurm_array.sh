#!/usr/bin/env bash
# docs/production.md's Slurm job array, run for real (issue 61): starts a
# single-node Slurm on this machine (Debian's slurm-wlm: slurmctld and slurmd
# with a throw-away config in WORKDIR) and a throw-away PostgreSQL server
# (tests/production/postgres_fixture.sh), simulates a small Prism A lot
# (datasets/prism_a_lot.json with PARTS parts, default 24, at 1024^2),
# submits bench/production/inspect_array.sbatch (the text docs/production.md
# shows, checked here) from the lot's folder, waits for its 8 tasks, checks
# in the store that every part of the lot is there exactly once, measured,
# and prints the figures. Everything it started is stopped on exit, whatever
# the exit. Usage, as root (slurmd starts jobs as their user; SlurmUser=root):
#   bash bench/production/slurm_array.sh WORKDIR [PARTS]
# WORKDIR is created, or emptied if an earlier run of this script made it.
# SLURM_ARRAY_TIMEOUT_S (default 1800) bounds the wait for the array.
# Needs scripts/install-deps.sh's packages (slurm-wlm, postgresql) and the
# built build/apps/xgauge/xgauge (or XGAUGE=path).
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
x=${XGAUGE:-$root/build/apps/xgauge/xgauge}
sbatch_file=$root/bench/production/inspect_array.sbatch
timeout_s=${SLURM_ARRAY_TIMEOUT_S:-1800}

die() {
  echo "slurm_array: error: $*" >&2
  exit 1
}

if [ $# -lt 1 ] || [ $# -gt 2 ]; then die "usage: bash $0 WORKDIR [PARTS]"; fi
parts=${2:-24}
[[ $parts =~ ^[1-9][0-9]*$ ]] || die "PARTS must be a positive whole number, not '$parts'"
[ "$(id -u)" -eq 0 ] || die "run as root: the throw-away Slurm runs its daemons and jobs as root (SlurmUser=root)"
for tool in slurmctld slurmd sbatch squeue scontrol scancel sinfo psql python3; do
  command -v "$tool" > /dev/null || die "'$tool' not found: run scripts/install-deps.sh (slurm-wlm, postgresql)"
done
[ -x "$x" ] || die "no xgauge at $x: build it first (cmake --build build), or set XGAUGE"
cpus=$(nproc)
[ "$cpus" -ge 2 ] || die "the array asks 2 CPUs per task and this machine has $cpus"

# The array's text is the docs' text: refuse to measure anything else.
python3 - "$sbatch_file" "$root/docs/production.md" <<'PY' || die "docs/production.md does not show bench/production/inspect_array.sbatch verbatim (in a sh block): make them the same"
import sys
script, docs = (open(f).read() for f in sys.argv[1:3])
sys.exit(0 if "```sh\n" + script + "```\n" in docs else 1)
PY
tasks=$(sed -n 's/^#SBATCH --array=1-\([0-9]*\)$/\1/p' "$sbatch_file")
[ -n "$tasks" ] || die "$sbatch_file has no '#SBATCH --array=1-N' line"

work=$1
case "$work" in *[[:space:]]*) die "WORKDIR must not contain white space (slurm.conf): '$work'" ;; esac
marker=.slurm_array_bench
if [ -e "$work" ] && [ -n "$(ls -A "$work" 2> /dev/null)" ] && [ ! -e "$work/$marker" ]; then
  die "$work exists, is not empty and was not made by this script: give a new folder"
fi
rm -rf "$work"
mkdir -p "$work"
work=$(cd "$work" && pwd)
touch "$work/$marker"
# The tasks run a copy: a rebuild of the tree during the run cannot pull the
# binary from under a task (xgauge links its own libraries statically).
mkdir "$work/bin"
cp "$x" "$work/bin/xgauge" || die "cannot copy $x"
x=$work/bin/xgauge

# ---- stop everything on exit ------------------------------------------------
ctld_pid="" slurmd_pid="" pg_started="" array=""
alive() { [ -n "$1" ] && kill -0 "$1" 2> /dev/null; }
stop_pid() {  # stop_pid PID NAME: it was asked to stop; wait, then TERM, then KILL
  local pid=$1 name=$2 i
  for i in $(seq 1 40); do alive "$pid" || break; sleep 0.5; done
  if alive "$pid"; then echo "slurm_array: $name did not stop: SIGTERM" >&2; kill -TERM "$pid" 2> /dev/null; sleep 3; fi
  if alive "$pid"; then echo "slurm_array: $name did not stop: SIGKILL" >&2; kill -KILL "$pid" 2> /dev/null; fi
  wait "$pid" 2> /dev/null || true
}
cleanup() {
  local rc=$? i
  set +e
  trap - EXIT INT TERM
  if [ -n "$array" ] && alive "$ctld_pid"; then
    if [ -n "$(squeue -h -r -j "$array" 2> /dev/null)" ]; then
      echo "slurm_array: cancelling job array $array" >&2
      scancel "$array"
      for i in $(seq 1 30); do [ -z "$(squeue -h -r -j "$array" 2> /dev/null)" ] && break; sleep 1; done
    fi
  fi
  if alive "$ctld_pid"; then scontrol shutdown > /dev/null 2>&1; fi  # stops slurmctld and slurmd
  [ -n "$slurmd_pid" ] && stop_pid "$slurmd_pid" slurmd
  [ -n "$ctld_pid" ] && stop_pid "$ctld_pid" slurmctld
  [ -n "$pg_started" ] && bash "$root/tests/production/postgres_fixture.sh" stop "$work/pg"
  exit "$rc"
}
trap cleanup EXIT
trap 'exit 130' INT
trap 'exit 143' TERM

# ---- PostgreSQL: the store --------------------------------------------------
pg_started=1
bash "$root/tests/production/postgres_fixture.sh" start "$work/pg"
[ ! -f "$work/pg/skip" ] || die "no PostgreSQL server: $(cat "$work/pg/skip")"
url=$(cat "$work/pg/url")
echo "slurm_array: PostgreSQL store $url"

# ---- Slurm: one node, this machine ------------------------------------------
node=$(hostname -s)
read -r ctld_port slurmd_port < <(python3 -c '
import socket
ss = [socket.socket() for _ in range(2)]
for s in ss: s.bind(("127.0.0.1", 0))
print(*(s.getsockname()[1] for s in ss))')
s=$work/slurm
mkdir -p "$s/state" "$s/spool"
# A throw-away cluster on localhost: no munge (auth/none: every client is this
# machine's root), no accounting, no cgroups (processes tracked via /proc).
cat > "$s/slurm.conf" <<EOF
ClusterName=xgauge_bench
SlurmctldHost=$node(127.0.0.1)
SlurmUser=root
SlurmdUser=root
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
AuthType=auth/none
CredType=cred/none
StateSaveLocation=$s/state
SlurmdSpoolDir=$s/spool
SlurmctldPidFile=$s/slurmctld.pid
SlurmdPidFile=$s/slurmd.pid
SlurmctldLogFile=$s/slurmctld.log
SlurmdLogFile=$s/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
SchedulerType=sched/backfill
MpiDefault=none
MailProg=/bin/true
AccountingStorageType=accounting_storage/none
JobAcctGatherType=jobacct_gather/none
JobCompType=jobcomp/none
ReturnToService=2
MinJobAge=86400
KillWait=10
NodeName=$node NodeAddr=127.0.0.1 CPUs=$cpus State=UNKNOWN
PartitionName=bench Nodes=$node Default=YES MaxTime=INFINITE State=UP
EOF
export SLURM_CONF=$s/slurm.conf
slurmctld -D -f "$SLURM_CONF" > "$s/slurmctld.out" 2>&1 &
ctld_pid=$!
slurmd -D -f "$SLURM_CONF" -N "$node" > "$s/slurmd.out" 2>&1 &
slurmd_pid=$!
for i in $(seq 1 60); do
  alive "$ctld_pid" || die "slurmctld exited: $(tail -n 5 "$s/slurmctld.out")"
  alive "$slurmd_pid" || die "slurmd exited: $(tail -n 5 "$s/slurmd.out")"
  [ "$(sinfo -h -n "$node" -o %T 2> /dev/null)" = idle ] && break
  [ "$i" -lt 60 ] || die "node $node not idle after 60 s: $(sinfo -h -n "$node" -o '%T %E' 2>&1); see $s/*.log"
  sleep 1
done
echo "slurm_array: Slurm $(sinfo -V | cut -d' ' -f2): node $node, $cpus CPUs, partition bench (config $SLURM_CONF)"

# ---- the lot ----------------------------------------------------------------
python3 - "$root/datasets/prism_a_lot.json" "$work/recipe.json" "$parts" <<'PY'
import json, os, sys
src, dst, parts = sys.argv[1], sys.argv[2], int(sys.argv[3])
here = os.path.dirname(os.path.abspath(src))
r = json.load(open(src))
r["description"] = f"slurm_array.sh: {os.path.basename(src)} with {parts} parts. " + r["description"]
r["machine"] = os.path.normpath(os.path.join(here, r["machine"]))
r["part"]["model"] = os.path.normpath(os.path.join(here, r["part"]["model"]))
r["lot"]["parts"] = parts
for process in r["lot"]["process"].values():  # a drift that starts after the last part
    if process.get("drift", {}).get("from_part", 0) > parts:
        del process["drift"]
json.dump(r, open(dst, "w"), indent=2)
PY
t0=$(date +%s.%N)
"$x" simulate "$work/recipe.json" -o "$work/lot" -q
t1=$(date +%s.%N)
"$x" material --from-truth "$work/lot/truth/p0001.json" -o "$work/material.json" -q
lot=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['lot'])" "$work/lot/truth.json")
python3 "$root/bench/production/make_plan.py" "$work/recipe.json" "$work" "$lot" > "$work/lot/plan.json"
cp "$sbatch_file" "$work/lot/inspect_array.sbatch"
echo "slurm_array: lot $lot, $parts parts simulated in $(python3 -c "print(f'{$t1 - $t0:.0f}')") s into $work/lot"

# ---- the array --------------------------------------------------------------
t2=$(date +%s.%N)
array=$(cd "$work/lot" && PATH="$(dirname "$x"):$PATH" XGAUGE_STORE=$url sbatch --parsable inspect_array.sbatch) \
  || die "sbatch refused the array (see $s/slurmctld.log)"
array=${array%%;*}
echo "slurm_array: submitted job array $array ($tasks tasks), waiting up to $timeout_s s"
deadline=$((SECONDS + timeout_s))
while [ -n "$(squeue -h -r -j "$array" 2> /dev/null)" ]; do
  alive "$ctld_pid" || die "slurmctld exited during the array: $(tail -n 5 "$s/slurmctld.log")"
  alive "$slurmd_pid" || die "slurmd exited during the array: $(tail -n 5 "$s/slurmd.log")"
  [ "$SECONDS" -lt "$deadline" ] || die "job array $array not done after $timeout_s s: $(squeue -h -r -j "$array" -o '%i %T %M' | tr '\n' ';')"
  sleep 2
done
t3=$(date +%s.%N)
scontrol show job "$array" -o > "$work/tasks.txt" || die "scontrol cannot show job array $array"
python3 - "$work/tasks.txt" "$tasks" "$work/lot" <<'PY' || die "the array's tasks did not all complete"
import glob, re, sys
lines = [l for l in open(sys.argv[1]) if l.strip()]
tasks, lot = int(sys.argv[2]), sys.argv[3]
seen, bad = set(), []
for l in lines:
    f = dict(re.findall(r"(\w+)=(\S*)", l))
    seen.add(f.get("ArrayTaskId"))
    if f.get("JobState") != "COMPLETED" or f.get("ExitCode") != "0:0":
        bad.append(f"task {f.get('ArrayTaskId')}: {f.get('JobState')} exit {f.get('ExitCode')}")
missing = {str(i) for i in range(1, tasks + 1)} - seen
if missing:
    bad.append(f"tasks {sorted(missing, key=int)} not found")
for b in bad:
    print("slurm_array:", b, file=sys.stderr)
if bad:
    for out in sorted(glob.glob(f"{lot}/slurm-*.out")):
        text = open(out).read().strip()
        if text:
            print(f"--- {out}\n{text[-2000:]}", file=sys.stderr)
    sys.exit(1)
PY

# ---- the store: every part once ---------------------------------------------
psql "$url" -v ON_ERROR_STOP=1 -q -At -F ' ' -c "
  SELECT p.name, count(m.id), count(m.id) FILTER (WHERE m.status = 'measured'), coalesce(sum(m.seconds), 0)
  FROM parts p JOIN lots l ON l.id = p.lot_id LEFT JOIN measurements m ON m.part_id = p.id
  WHERE l.name = '$lot' GROUP BY p.name ORDER BY p.name" > "$work/store_parts.txt" \
  || die "cannot read the store $url"
claims=$(psql "$url" -v ON_ERROR_STOP=1 -q -At -c "SELECT count(*) FROM claims") || die "cannot read the store's claims"
python3 - "$work" "$parts" "$claims" "$t2" "$t3" "$tasks" "$*" <<'PY'
import os, sys
work, parts, claims, t2, t3, tasks, args = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), float(sys.argv[4]), float(sys.argv[5]), int(sys.argv[6]), sys.argv[7]
folders = sorted(d for d in os.listdir(os.path.join(work, "lot", "parts")))
rows = {}
for line in open(os.path.join(work, "store_parts.txt")):
    name, n, measured, seconds = line.split()
    rows[name] = (int(n), int(measured), float(seconds))
once = [p for p in folders if rows.get(p, (0,))[0] == 1]
twice = [p for p in folders if rows.get(p, (0,))[0] > 1]
missing = [p for p in folders if rows.get(p, (0,))[0] == 0]
extra = [p for p in rows if p not in folders]
measured = sum(1 for p in once if rows[p][1] == 1)
wall = t3 - t2
seconds = sum(r[2] for r in rows.values())
print(f"slurm_array: command: bash bench/production/slurm_array.sh {args}")
print(f"slurm_array: {tasks} array tasks, {len(folders)} part folders, {len(rows)} parts in the store")
print(f"slurm_array: parts once: {len(once)} of {len(folders)} (measured {measured}; twice or more: {len(twice)}; missing: {len(missing)}; not in the lot: {len(extra)}; claims left: {claims})")
print(f"slurm_array: array wall time {wall:.1f} s from sbatch to the last task's end: {len(once) / wall * 60:.1f} parts per minute")
print(f"slurm_array: measuring time in the store {seconds:.1f} s, {seconds / max(len(rows), 1):.2f} s per part")
ok = len(once) == len(folders) == parts and measured == parts and not twice and not missing and not extra and claims == 0
print("slurm_array: PASS: every part in the store exactly once" if ok else
      f"slurm_array: FAIL: twice {twice[:5]} missing {missing[:5]} extra {extra[:5]}")
sys.exit(0 if ok else 1)
PY
