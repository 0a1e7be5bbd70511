#!/usr/bin/env bash
# Runs every libFuzzer target of fuzz/ for a fixed number of executions and prints, per target,
# the executions done, the wall time, exec/s and whether it found anything (a crash, a leak, a
# timeout or an out-of-memory). Each run starts from the committed seed corpus copied to a scratch
# directory (the source tree is never written) and uses the target's dictionary when it has one.
#
#   bash bench/bench_fuzz.sh [BUILD_DIR] [RUNS] [TARGET...]
#     BUILD_DIR  a configuration with -DOBSCURA_FUZZ=ON (CC=clang); default build-asan
#     RUNS       executions per target; default 1000000
#     TARGET     fuzz_<name> executables to run; default all in BUILD_DIR/fuzz
#
# Findings are written to BUILD_DIR/fuzz/bench-<target>-crash-<sha1> (or -leak-, -timeout-,
# -oom-); a target's full log is BUILD_DIR/fuzz/bench-<target>.log. Exit status 1 when any
# target found something.
set -u
root=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$root/build-asan}
runs=${2:-1000000}
shift $(($# > 2 ? 2 : $#))
fuzzdir=$build/fuzz
if [ ! -d "$fuzzdir" ]; then
  echo "bench_fuzz: no $fuzzdir: configure with CC=clang cmake -S . -B build-asan -DOBSCURA_FUZZ=ON" >&2
  exit 2
fi
targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then
  for f in "$fuzzdir"/fuzz_*; do
    [ -x "$f" ] && [ -f "$f" ] && targets+=("$(basename "$f")")
  done
fi
# The mesh-import target drives the worker program as obscurad does: the release build's worker
# (build/obscura-import, when built) runs about twice as fast as this build's sanitized one, and
# a 10 ms import limit cuts the inputs that make assimp loop (common) five times sooner than the
# target's default of 50 ms. Both only change the pace: the checks are the same.
if [ -z "${OBSCURA_IMPORT:-}" ]; then
  if [ -x "$root/build/obscura-import" ]; then OBSCURA_IMPORT=$root/build/obscura-import
  else OBSCURA_IMPORT=$build/obscura-import; fi
fi
export OBSCURA_IMPORT
export OBSCURA_FUZZ_IMPORT_SECONDS=${OBSCURA_FUZZ_IMPORT_SECONDS:-0.01}
scratch=$(mktemp -d "${TMPDIR:-/tmp}/bench-fuzz-XXXXXX")
trap 'rm -rf "$scratch"' EXIT
status=0
printf '%-20s %12s %10s %10s %8s  %s\n' target executions wall_s exec/s corpus result
for t in "${targets[@]}"; do
  bin=$fuzzdir/$t
  log=$fuzzdir/bench-$t.log
  mkdir -p "$scratch/$t"
  [ -d "$root/fuzz/corpus/$t" ] && cp "$root/fuzz/corpus/$t"/* "$scratch/$t"/ 2>/dev/null
  dict=()
  [ -f "$root/fuzz/$t.dict" ] && dict=(-dict="$root/fuzz/$t.dict")
  t0=$(date +%s.%N)
  # -timeout 20: one input taking longer is a hang; leaks are checked as in the suite.
  ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1} UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1} \
    "$bin" -runs="$runs" -timeout=20 -rss_limit_mb=2048 -print_final_stats=1 "${dict[@]}" \
    -artifact_prefix="$fuzzdir/bench-$t-" "$scratch/$t" >"$log" 2>&1
  rc=$?
  t1=$(date +%s.%N)
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  corpus=$(ls "$scratch/$t" | wc -l)
  wall=$(echo "$t1 - $t0" | bc)
  rate=$(echo "scale=0; ${execs:-0} / $wall" | bc)
  result=ok
  if [ $rc -ne 0 ]; then
    result="FOUND ($(grep -m1 -oE 'ERROR: [A-Za-z]+: [a-z -]+|fuzz_[a-z_]+: [^(]*|SUMMARY: [A-Za-z]+: [^ ]+' "$log" | head -1); see $log)"
    status=1
  fi
  printf '%-20s %12s %10.1f %10s %8s  %s\n' "$t" "${execs:-0}" "$wall" "$rate" "$corpus" "$result"
done
exit $status
