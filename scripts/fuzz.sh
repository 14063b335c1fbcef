#!/usr/bin/env bash
# Fuzzes xgauge's parsers with libFuzzer + AddressSanitizer + UBSan
# (docs/fuzzing.md; the targets are in fuzz/).
#
#   scripts/fuzz.sh [SECONDS] [TARGET...]   fuzz each target SECONDS (default 60)
#   scripts/fuzz.sh --replay [TARGET...]    run each target once over its corpus
#                                           and fuzz/regressions/<target>/
#
# Targets: fuzz_tiff fuzz_raw fuzz_nxtomo fuzz_diconde fuzz_config fuzz_part_model fuzz_stl
# (default: all).
# Configures and builds build-fuzz/ (clang, RelWithDebInfo, -DXGAUGE_FUZZ=ON,
# no tests, benchmarks or install rules), building only the targets asked for
# with $FUZZ_BUILD_JOBS jobs (default 2). Then, per target:
#   build-fuzz/corpus/<target>/    working corpus, seeded from fuzz/corpus/<target>/
#                                  (new seeds are added, nothing is removed)
#   build-fuzz/findings/<target>/  crash-*, leak-*, oom-*, timeout-* inputs
#   build-fuzz/logs/<target>.log   libFuzzer's and the sanitizers' output
#                                  (<target>.replay.log for --replay)
# Limits, so that runaway allocations and hangs are findings too:
#   -rss_limit_mb=2048    the process may not grow beyond 2 GiB
#   -malloc_limit_mb=1088 no single allocation above the TIFF memory cap
#                         (1088 MiB: a 16384^2 float image and a 64 MiB strip)
#   -timeout=30           no input may take more than 30 s
# ASan and UBSan stop at the first error (halt_on_error=1, and every UB check
# is built with -fno-sanitize-recover); UBSan prints the stack. Your own
# ASAN_OPTIONS / UBSAN_OPTIONS are appended (so they win), and $FUZZ_ARGS is
# passed to every libFuzzer run (e.g. FUZZ_ARGS="-jobs=2 -workers=2").
#
# Prints per target the executions and whether it found a crash; exits 1 when
# any target did (or, with --replay, when any input crashes), 2 on bad usage.
set -euo pipefail
cd "$(dirname "$0")/.."

all_targets=(fuzz_tiff fuzz_raw fuzz_nxtomo fuzz_diconde fuzz_config fuzz_part_model fuzz_stl)
declare -A max_len=([fuzz_tiff]=65536 [fuzz_raw]=16384 [fuzz_nxtomo]=65536 [fuzz_diconde]=65536
                    [fuzz_config]=16384 [fuzz_part_model]=16384 [fuzz_stl]=65536)
# fuzz_nxtomo: libhdf5 checks what malloc returns, so a huge declared
# object fails there as an error when malloc may return null (as it does in
# a release build); the 56-byte leaks libhdf5's error paths leave are
# suppressed (fuzz/lsan.supp: libhdf5 frames only).
declare -A extra_asan=([fuzz_nxtomo]=allocator_may_return_null=1)
declare -A dict=([fuzz_tiff]=fuzz/tiff.dict [fuzz_raw]=fuzz/raw.dict [fuzz_nxtomo]=fuzz/nxtomo.dict
                 [fuzz_diconde]=fuzz/diconde.dict [fuzz_config]=fuzz/json.dict
                 [fuzz_part_model]=fuzz/json.dict [fuzz_stl]=fuzz/stl.dict)

usage() {
  sed -n '2,9p' "$0" | sed 's/^# \{0,1\}//' >&2
  exit 2
}

mode=fuzz
seconds=60
if [ $# -gt 0 ]; then
  case "$1" in
    --replay) mode=replay; shift ;;
    -h|--help) usage ;;
    *[!0-9]*|'') ;;  # not a number: a target name
    *) seconds=$1; shift ;;
  esac
fi
[ "$seconds" -gt 0 ] || usage
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=("${all_targets[@]}")
for t in "${targets[@]}"; do
  [ -n "${max_len[$t]:-}" ] || { echo "fuzz.sh: unknown target '$t' (known: ${all_targets[*]})" >&2; usage; }
done

# Build -------------------------------------------------------------------
build=build-fuzz
mkdir -p "$build"
CC=clang CXX=clang++ cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DXGAUGE_FUZZ=ON -DXGAUGE_BUILD_TESTS=OFF -DXGAUGE_BUILD_BENCH=OFF -DXGAUGE_INSTALL=OFF \
  > "$build/configure.log" 2>&1 || { cat "$build/configure.log" >&2; exit 1; }
cmake --build "$build" --parallel "${FUZZ_BUILD_JOBS:-2}" --target "${targets[@]}"

# Run ---------------------------------------------------------------------
export ASAN_OPTIONS="halt_on_error=1:detect_leaks=1:symbolize=1${ASAN_OPTIONS:+:$ASAN_OPTIONS}"
export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1:report_error_type=1${UBSAN_OPTIONS:+:$UBSAN_OPTIONS}"
# The targets write each input to a scratch file (fuzz/fuzz_common.h): keep
# those in one folder of ours, removed at the end even after a crash.
scratch=$(mktemp -d /dev/shm/xgauge-fuzz.XXXXXX 2>/dev/null || mktemp -d)
trap 'rm -rf "$scratch"' EXIT
export XGAUGE_FUZZ_TMP=$scratch
read -r -a extra_args <<< "${FUZZ_ARGS:-}"

mkdir -p "$build/logs"
log_suffix=
[ "$mode" = fuzz ] || log_suffix=.replay
failed=0
summary=()

# The report in a log: its first lines, and the first frames of the stack
# outside the sanitizer and libFuzzer runtimes and the standard library
report_excerpt() {
  grep -E -m 6 'ERROR: (AddressSanitizer|LeakSanitizer|libFuzzer)|runtime error:|SUMMARY:|terminate called|what\(\):|broken promise|internal error|Test unit written' "$1" \
    | cut -c1-300 | sed 's/^/    /' || true
  grep -E '^ +#[0-9]+ 0x[0-9a-f]+ in ' "$1" \
    | grep -v -E ' in (__sanitizer|__asan|__ubsan|__lsan|__interceptor|fuzzer::|operator new|__libc_start|_start|abort|raise|__pthread_kill|gsignal|std::terminate|__cxxabiv1|__cxa_|std::|__gnu_cxx::)' \
    | head -8 | sed -E 's/ \(BuildId: [0-9a-f]+\)//; s|/usr/bin/../lib/gcc/x86_64-linux-gnu/12/../../../../include/c\+\+/12/|<c++>/|' \
    | cut -c1-250 | sed 's/^/    /' || true
}

for t in "${targets[@]}"; do
  exe=$build/fuzz/$t
  findings=$build/findings/$t
  log=$build/logs/$t$log_suffix.log
  mkdir -p "$findings"
  common=(-rss_limit_mb=2048 -malloc_limit_mb=1088 -timeout=30 -max_len="${max_len[$t]}"
          -artifact_prefix="$findings/")

  if [ "$mode" = replay ]; then
    # Every input once: the working corpus, the seeds and the regressions.
    mapfile -d '' inputs < <(find "$build/corpus/$t" "fuzz/corpus/$t" "fuzz/regressions/$t" \
                               -type f ! -name .gitkeep -print0 2>/dev/null)
    echo "== $t: replaying ${#inputs[@]} inputs (log: $log)"
    rc=0
    if [ ${#inputs[@]} -gt 0 ]; then
      printf '%s\0' "${inputs[@]}" |
        ASAN_OPTIONS="$ASAN_OPTIONS${extra_asan[$t]:+:${extra_asan[$t]}}" \
        LSAN_OPTIONS="suppressions=$PWD/fuzz/lsan.supp${LSAN_OPTIONS:+:$LSAN_OPTIONS}" \
        xargs -0 "$exe" "${common[@]}" "${extra_args[@]}" > "$log" 2>&1 || rc=$?
    else
      : > "$log"
    fi
    if [ $rc -ne 0 ]; then
      failed=1
      crashed=$(grep -E -o '^Running: .*' "$log" | tail -1 | cut -d' ' -f2-)
      echo "   CRASH on ${crashed:-?}"
      report_excerpt "$log"
      summary+=("$(printf '%-16s %8s inputs  CRASH on %s' "$t" "${#inputs[@]}" "${crashed:-?}")")
    else
      summary+=("$(printf '%-16s %8s inputs  ok' "$t" "${#inputs[@]}")")
    fi
    continue
  fi

  corpus=$build/corpus/$t
  mkdir -p "$corpus"
  cp -n fuzz/corpus/"$t"/* "$corpus"/ 2>/dev/null || true
  stamp=$(mktemp "$scratch/stamp.XXXXXX")
  echo "== $t: fuzzing ${seconds} s (corpus: $corpus, log: $log)"
  rc=0
  ASAN_OPTIONS="$ASAN_OPTIONS${extra_asan[$t]:+:${extra_asan[$t]}}" \
  LSAN_OPTIONS="suppressions=$PWD/fuzz/lsan.supp${LSAN_OPTIONS:+:$LSAN_OPTIONS}" \
  "$exe" "$corpus" -dict="${dict[$t]}" -max_total_time="$seconds" -print_final_stats=1 \
    "${common[@]}" "${extra_args[@]}" > "$log" 2>&1 || rc=$?
  # Executions: the final stats, else the last status line (fork mode).
  execs=$(grep -E -o 'stat::number_of_executed_units: [0-9]+' "$log" | tail -1 | grep -E -o '[0-9]+$' ||
          grep -E -o '^#[0-9]+' "$log" | tail -1 | tr -d '#' || true)
  mapfile -t artifacts < <(find "$findings" -type f -newer "$stamp" \
                             \( -name 'crash-*' -o -name 'leak-*' -o -name 'oom-*' -o -name 'timeout-*' \) | sort)
  if [ $rc -ne 0 ] || [ ${#artifacts[@]} -gt 0 ]; then
    failed=1
    echo "   FINDING (exit status $rc) after ${execs:-?} executions:"
    for a in "${artifacts[@]}"; do echo "   input: $a"; done
    report_excerpt "$log"
    summary+=("$(printf '%-16s %12s execs  FINDING: %s' "$t" "${execs:-?}" "${artifacts[*]:-see $log}")")
  else
    summary+=("$(printf '%-16s %12s execs  no crash' "$t" "${execs:-?}")")
  fi
done

echo
echo "== summary ($mode)"
printf '%s\n' "${summary[@]}"
exit $failed
