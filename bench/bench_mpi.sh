#!/usr/bin/env bash
# Scaling of a render split across Open MPI ranks (docs/mpi.md): the same rt_ao image rendered by
# one process with one thread and by `mpirun -np RANKS` with one thread per rank, each REPEATS
# times, interleaved. Prints the median wall time of each (the whole command: MPI start-up, every
# rank's scene load and BVH build, the render, rank 0's writes), the median render time rank 0
# reports (its tile loop until the last rank's tile is in), and the parallel efficiency
# t1 / (RANKS x tRANKS) of both. For scale, one process with RANKS threads runs too: what the
# machine gives that many threads without MPI (on a machine shared with other work, the fairer
# reference). Checks that every run wrote the same EXR bytes.
#
#   bash bench/bench_mpi.sh [BUILD_DIR] [REPEATS] [RANKS]
#     BUILD_DIR  a build with the obscura CLI; default build
#     REPEATS    runs of each; default 3
#     RANKS      ranks of the split run; default 2
#   Environment: SCENE (default scenes/sphere_on_plane.json), TECHNIQUE (rt_ao; any per-pixel CPU
#   technique with a `samples` parameter, e.g. volume_ao on scenes/volume_engine.json), SIZE (512:
#   SIZE x SIZE pixels), SAMPLES (64, the technique's samples), MPIRUN_ARGS (extra mpirun options,
#   e.g. --oversubscribe), DATA (1: also the data-parallel render, `--distribute data`, of a volume
#   technique, timed the same way, with its image difference against one process: AO and final
#   RMSE and the fraction of pixels off by more than 1e-3, from the build's tests/metrics_tool),
#   EXTRA (more render options for every run, split at spaces, e.g.
#   "--set /technique/params/max_distance=0.15").
set -u
root=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$root/build}
repeats=${2:-3}
ranks=${3:-2}
scene=${SCENE:-$root/scenes/sphere_on_plane.json}
size=${SIZE:-512}
samples=${SAMPLES:-64}
technique=${TECHNIQUE:-rt_ao}
cli=$build/obscura
if [ ! -x "$cli" ]; then
  echo "bench_mpi: no $cli: build the obscura target first" >&2
  exit 2
fi
command -v mpirun >/dev/null || { echo "bench_mpi: mpirun not found (openmpi-bin)" >&2; exit 2; }
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
args=(render "$scene" --technique "$technique" --backend cpu --set "/image/width=$size"
      --set "/image/height=$size" --set "/technique/params/samples=$samples" --threads 1 --quiet)
# shellcheck disable=SC2206
[ -n "${EXTRA:-}" ] && args+=(${EXTRA})

now() { date +%s.%N; }
# Runs "$@" and appends "<wall s> <render ms>" (the render time from DIR/summary.json) to FILE.
timed() { # FILE DIR command...
  local file=$1 dir=$2 t0 t1
  shift 2
  t0=$(now)
  if ! "$@" -o "$dir" >"$dir.log" 2>&1; then
    cat "$dir.log" >&2
    echo "bench_mpi: run failed" >&2
    exit 1
  fi
  t1=$(now)
  node -e "const s = JSON.parse(require('fs').readFileSync('$dir/summary.json'));
    console.log(($t1 - $t0).toFixed(3), s.timings_ms.render.toFixed(1))" >>"$file"
}
median() {
  sort -n | awk '{v[NR] = $1}
    END {print NR % 2 ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2}'
}

for i in $(seq "$repeats"); do
  timed "$out/one.txt" "$out/one$i" "$cli" "${args[@]}"
  # shellcheck disable=SC2086
  timed "$out/split.txt" "$out/split$i" mpirun ${MPIRUN_ARGS:-} -np "$ranks" "$cli" "${args[@]}"
  timed "$out/threads.txt" "$out/threads$i" "$cli" "${args[@]}" --threads "$ranks"
  if [ "${DATA:-0}" = 1 ]; then
    # shellcheck disable=SC2086
    timed "$out/data.txt" "$out/data$i" mpirun ${MPIRUN_ARGS:-} -np "$ranks" "$cli" "${args[@]}" \
      --distribute data
  fi
  exr=$(cd "$out/one$i" && ls ./*.exr | head -1)
  for run in split threads; do
    cmp -s "$out/one$i/$exr" "$out/$run$i/$exr" ||
      { echo "bench_mpi: the $run render's $exr differs from one thread's" >&2; exit 1; }
  done
done
w1=$(cut -d' ' -f1 "$out/one.txt" | median) r1=$(cut -d' ' -f2 "$out/one.txt" | median)
wn=$(cut -d' ' -f1 "$out/split.txt" | median) rn=$(cut -d' ' -f2 "$out/split.txt" | median)
wt=$(cut -d' ' -f1 "$out/threads.txt" | median) rt=$(cut -d' ' -f2 "$out/threads.txt" | median)
echo "$technique ${size}x${size}, $samples samples, $(basename "$scene"), median of $repeats," \
  "$(nproc) cores"
printf '%-22s %10s %12s\n' "" "wall s" "render ms"
printf '%-22s %10s %12s\n' "1 rank x 1 thread" "$w1" "$r1"
printf '%-22s %10s %12s\n' "$ranks ranks x 1 thread" "$wn" "$rn"
printf '%-22s %10s %12s\n' "1 rank x $ranks threads" "$wt" "$rt"
awk -v w1="$w1" -v wn="$wn" -v wt="$wt" -v r1="$r1" -v rn="$rn" -v rt="$rt" -v n="$ranks" 'BEGIN {
  printf "%d ranks: speed-up    wall %.2f   render %.2f\n", n, w1 / wn, r1 / rn
  printf "%d ranks: efficiency  wall %.2f   render %.2f   (t1 / (%d x t%d))\n", n, w1 / (n * wn),
    r1 / (n * rn), n, n
  printf "%d threads: efficiency wall %.2f   render %.2f   (the same for threads)\n", n,
    w1 / (n * wt), r1 / (n * rt)
}'
echo "same EXR bytes in every run"
if [ "${DATA:-0}" = 1 ]; then
  wd=$(cut -d' ' -f1 "$out/data.txt" | median) rd=$(cut -d' ' -f2 "$out/data.txt" | median)
  printf '%-22s %10s %12s\n' "$ranks ranks, data" "$wd" "$rd"
  awk -v w1="$w1" -v wd="$wd" -v r1="$r1" -v rd="$rd" -v n="$ranks" 'BEGIN {
    printf "%d ranks, data-parallel: efficiency wall %.2f   render %.2f\n", n, w1 / (n * wd),
      r1 / (n * rd) }'
  if [ -x "$build/tests/metrics_tool" ]; then
    echo "data-parallel against one process (channel rmse max_abs differ>1e-3):"
    "$build/tests/metrics_tool" diff "$out/data1/$exr" "$out/one1/$exr" ao final.G alpha
  fi
fi
