#!/usr/bin/env bash
# obscurad under load on loopback: `wrk` on GET /api/v1/jobs/{id} while a CPU render keeps the
# worker busy -- as fast as it goes, then at a fixed offered rate -- (requests/s, p50, p99), then the
# latency of sequential job submissions (median, p99).
# Goal: >= 5000 requests/s with p99 <= 5 ms on 2 cores. See bench/README.md.
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)

duration=30 threads=2 connections=32 submissions=200 build=$ROOT/build render=1 target=running
rate=5500
extra=()
usage() {
  cat <<EOF
usage: bench/bench_server.sh [options] [-- obscurad options...]
  --duration S      wrk run length in seconds (default $duration)
  --threads N       wrk threads (default $threads)
  --connections N   wrk connections (default $connections)
  --rate R          then the same at about R requests/s offered (wrk Lua delay: each connection
                    waits connections/R s after a response, so a little less is served; default
                    $rate, which serves >= 5000 here; 0 skips)
  --submissions N   sequential POST /api/v1/jobs to time (default $submissions; 0 skips)
  --build DIR       build directory holding obscurad (default build, a Release build)
  --target running|finished
                    GET the busy running job (live progress, the default) or a finished one
  --no-render       no background render (the daemon idles apart from HTTP)
Options after -- go to obscurad (e.g. -- --quiet, -- --http-threads 4).
EOF
}
while [ $# -gt 0 ]; do
  case $1 in
    --duration) duration=$2; shift 2 ;;
    --threads) threads=$2; shift 2 ;;
    --connections) connections=$2; shift 2 ;;
    --submissions) submissions=$2; shift 2 ;;
    --rate) rate=$2; shift 2 ;;
    --build) build=$(cd "$2" && pwd); shift 2 ;;
    --target) target=$2; shift 2 ;;
    --no-render) render=0; shift ;;
    -h | --help) usage; exit 0 ;;
    --) shift; extra=("$@"); break ;;
    *) usage >&2; exit 2 ;;
  esac
done
case $target in running | finished) ;; *) usage >&2; exit 2 ;; esac
for tool in wrk curl node; do
  command -v $tool >/dev/null || { echo "bench_server: $tool is not installed (apt-get install $tool)" >&2; exit 1; }
done
bin=$build/obscurad
[ -x "$bin" ] || { echo "bench_server: no $bin (cmake --build $build --target obscurad)" >&2; exit 1; }
if grep -q 'OBSCURA_SANITIZE:BOOL=ON' "$build/CMakeCache.txt" 2>/dev/null; then
  echo "bench_server: warning: $build is a sanitizer build" >&2
fi

work=$(mktemp -d "${TMPDIR:-/tmp}/bench-server.XXXXXX")
pid=
cleanup() {
  [ -n "$pid" ] && kill -9 "$pid" 2>/dev/null
  rm -rf "$work"
}
trap cleanup EXIT

"$bin" --listen 127.0.0.1 --port 0 --db "$work/obscura.db" --data-dir "$work/data" \
  --scenes-dir "$ROOT/scenes" --web-dir "$ROOT/web" --workers 1 --no-vulkan "${extra[@]}" \
  2>"$work/log" &
pid=$!
disown "$pid" # no "Killed" message at the end
port=
for _ in $(seq 1 300); do
  port=$(sed -n 's|^obscurad: listening on http://127\.0\.0\.1:\([0-9]*\)$|\1|p' "$work/log")
  [ -n "$port" ] && break
  kill -0 "$pid" 2>/dev/null || break
  sleep 0.1
done
[ -n "$port" ] || { echo "bench_server: obscurad did not start:" >&2; cat "$work/log" >&2; exit 1; }
url=http://127.0.0.1:$port

# post BODY: prints the new job id.
post() {
  curl -sf -X POST -H 'Content-Type: application/json' --data-binary "$1" "$url/api/v1/jobs" |
    node -e 'let s="";process.stdin.on("data",d=>s+=d).on("end",()=>console.log(JSON.parse(s).id))'
}
state() {
  curl -sf "$url/api/v1/jobs/$1" |
    node -e 'let s="";process.stdin.on("data",d=>s+=d).on("end",()=>console.log(JSON.parse(s).state))'
}
wait_state() { # id state...
  local id=$1 s
  shift
  for _ in $(seq 1 600); do
    s=$(state "$id")
    for want in "$@"; do [ "$s" = "$want" ] && return 0; done
    sleep 0.1
  done
  echo "bench_server: job $id stayed $s" >&2
  exit 1
}

tiny='{"scene_file": "sphere_on_plane.json", "set": {"/image/width": 16, "/image/height": 16, "/technique/params/samples": 4}, "label": "bench"}'
finished=$(post "$tiny")
wait_state "$finished" succeeded
busy=
if [ "$render" = 1 ]; then
  # About 2.1e9 occlusion rays on the 1M-triangle displaced sphere: minutes of work for both cores.
  busy=$(post '{"scene_file": "displaced_sphere.json", "technique": {"name": "rt_ao", "backend": "cpu", "params": {"samples": 8192, "max_distance": 0.5}}, "label": "bench load"}')
  wait_state "$busy" running
fi
id=$finished
[ "$target" = running ] && [ -n "$busy" ] && id=$busy

nproc=$(nproc)
model=$(sed -n 's/^model name[[:space:]]*: //p' /proc/cpuinfo | head -1)
echo "obscurad ($(git -C "$ROOT" describe --always --dirty 2>/dev/null || echo '?')) on $nproc cores" \
     "($model); background render: $([ -n "$busy" ] && echo "job $busy" || echo none)"

# CPU ticks (USER_HZ) busy on the whole machine, and used by one process.
busy_ticks() { awk '/^cpu / {print $2 + $3 + $4 + $7 + $8 + $9}' /proc/stat; }
proc_ticks() { awk '{print $14 + $15}' "/proc/$1/stat"; }
hz=$(getconf CLK_TCK)
to_ms() { # wrk latency like 812.00us, 1.23ms, 2.00s -> ms
  awk -v v="$1" 'BEGIN { n = v + 0; if (v ~ /us$/) n /= 1000; else if (v ~ /[0-9]s$/ && v !~ /ms$/) n *= 1000; printf "%.3f", n }'
}
# run_wrk NAME [wrk options...]: runs wrk on the job, prints its output and sets $rps $p50 $p99
# $other (share of all cores that other processes used meanwhile, %).
run_wrk() {
  local name=$1
  shift
  echo "== $name: wrk -t$threads -c$connections -d${duration}s --latency${*:+ $*} GET /api/v1/jobs/$id ($target job)"
  local b0 d0 t0 b1 d1 t1 wt
  b0=$(busy_ticks) d0=$(proc_ticks "$pid") t0=$(date +%s%N)
  (wrk -t"$threads" -c"$connections" -d"${duration}s" --latency "$@" "$url/api/v1/jobs/$id" >"$work/wrk.txt"
   times >"$work/times.txt")
  b1=$(busy_ticks) d1=$(proc_ticks "$pid") t1=$(date +%s%N)
  cat "$work/wrk.txt"
  # `times` line 2: children's user and system time, e.g. "0m3.210s 0m5.020s".
  wt=$(awk 'NR == 2 { split($1, u, /[ms]/); split($2, s, /[ms]/); print (u[1] * 60 + u[2] + s[1] * 60 + s[2]) }' "$work/times.txt")
  other=$(awk -v b=$((b1 - b0)) -v d=$((d1 - d0)) -v w="$wt" -v hz="$hz" -v ns=$((t1 - t0)) -v n="$nproc" \
    'BEGIN { o = (b - d - w * hz) / (ns / 1e9 * hz * n) * 100; if (o < 0) o = 0; printf "%.1f", o }')
  rps=$(awk '/^Requests\/sec:/ {print $2}' "$work/wrk.txt")
  p50=$(to_ms "$(awk '$1 == "50%" {print $2}' "$work/wrk.txt")")
  p99=$(to_ms "$(awk '$1 == "99%" {print $2}' "$work/wrk.txt")")
  local errs
  errs=$(awk '/Non-2xx|Socket errors/' "$work/wrk.txt")
  [ -z "$errs" ] || echo "bench_server: warning: wrk: $errs" >&2
  echo "other processes used $other % of the CPU meanwhile"
}
goal() { awk -v r="$1" -v p="$2" 'BEGIN { print (r >= 5000 && p <= 5) ? "met" : "missed" }'; }

run_wrk "closed loop, as fast as it goes"
sat_line="GET /api/v1/jobs/{id}, as fast as it goes: $rps requests/s, p50 $p50 ms, p99 $p99 ms (wrk $threads threads, $connections connections, $duration s; other load $other %)"
sat_goal=$(goal "$rps" "$p99")
rate_line="" rate_goal=""
if [ "$rate" != 0 ]; then
  # Each connection waits connections/rate seconds after a response before its next request (wrk
  # truncates the delay to whole milliseconds: 5.8 ms becomes 5).
  awk -v c="$connections" -v r="$rate" 'BEGIN { printf "local d = %.4f\nfunction delay() return d end\n", c * 1000 / r }' >"$work/rate.lua"
  run_wrk "offered $rate requests/s" -s "$work/rate.lua"
  rate_line="GET /api/v1/jobs/{id}, $rate requests/s offered: $rps requests/s served, p50 $p50 ms, p99 $p99 ms (other load $other %)"
  rate_goal=$(goal "$rps" "$p99")
fi
if [ -n "$busy" ]; then
  bs=$(state "$busy")
  [ "$bs" = running ] || echo "bench_server: warning: the background render is $bs, not running, after wrk" >&2
fi

sub_line="submission latency: skipped"
if [ "$submissions" -gt 0 ]; then
  echo "== $submissions sequential POST /api/v1/jobs (tiny bundled-scene job, a new connection each)"
  printf '%s' "$tiny" >"$work/tiny.json"
  for _ in $(seq 1 "$submissions"); do
    curl -s -o /dev/null -w '%{http_code} %{time_total}\n' -X POST -H 'Content-Type: application/json' \
      --data-binary @"$work/tiny.json" "$url/api/v1/jobs"
  done >"$work/sub.txt"
  bad=$(awk '$1 != 201' "$work/sub.txt" | wc -l)
  [ "$bad" -eq 0 ] || echo "bench_server: warning: $bad submissions were not answered 201" >&2
  sub_line=$(awk '{print $2 * 1000}' "$work/sub.txt" | sort -n | awk '
    { v[NR] = $1 }
    END {
      med = NR % 2 ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2
      i = int(NR * 0.99 + 0.999999); if (i < 1) i = 1; if (i > NR) i = NR
      printf "submission latency: median %.2f ms, p99 %.2f ms, max %.2f ms (n = %d)", med, v[i], v[NR], NR
    }')
fi
[ -n "$busy" ] && curl -sf -o /dev/null -X POST "$url/api/v1/jobs/$busy/cancel" || true

echo "== summary"
echo "$sat_line"
[ -n "$rate_line" ] && echo "$rate_line"
echo "$sub_line"
echo "goal (>= 5000 requests/s with p99 <= 5 ms): as fast as it goes: $sat_goal${rate_goal:+; at $rate requests/s offered: $rate_goal}"
