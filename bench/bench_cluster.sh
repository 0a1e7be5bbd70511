#!/usr/bin/env bash
# Several obscurad sharing one PostgreSQL store: the same comparison (118 rt_ao candidates and
# their 2 references, 120 jobs) run on 1, 2 and 3 daemons on PostgreSQL and on one daemon on SQLite;
# jobs per minute, the 2-daemon/1-daemon throughput ratio, the claim statement's latency as the
# PostgreSQL server logged it (log_min_duration_statement = 0: bind + execute of each claim, p50
# and p99), whether any job ran twice (attempts, rows in runs), and the latency of the dashboard's
# job-list request with 10,000 jobs stored, on both stores.
# Goals (docs/cluster.md): 2 daemons >= 1.8x one daemon's throughput; claim p99 <= 20 ms.
#
# Each daemon has one CPU lane and, unless --no-pin, is pinned to one core (daemon i to core
# i mod cores), as if each were a one-core host; PostgreSQL runs unpinned. A throwaway PostgreSQL
# is started with tests/pg/pg.sh, each run on its own fresh database. See bench/README.md.
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)

build=$ROOT/build size=96 history=10000 requests=200 pin=1 daemons="1 2 3" sqlite=1
usage() {
  cat <<EOF
usage: bench/bench_cluster.sh [options]
  --build DIR       build directory holding obscurad (default build, a Release build)
  --size N          image width and height of every job (default $size)
  --daemons "LIST"  daemon counts to run on PostgreSQL (default "$daemons")
  --no-sqlite       skip the one-daemon SQLite run
  --history N       jobs stored for the list latency (default $history; 0 skips)
  --requests N      list requests timed per query (default $requests)
  --no-pin          leave the daemons unpinned
EOF
}
while [ $# -gt 0 ]; do
  case $1 in
    --build) build=$(cd "$2" && pwd); shift 2 ;;
    --size) size=$2; shift 2 ;;
    --daemons) daemons=$2; shift 2 ;;
    --no-sqlite) sqlite=0; shift ;;
    --history) history=$2; shift 2 ;;
    --requests) requests=$2; shift 2 ;;
    --no-pin) pin=0; shift ;;
    -h | --help) usage; exit 0 ;;
    *) usage >&2; exit 2 ;;
  esac
done
PG_BIN=${OBSCURA_PG_BIN:-/usr/lib/postgresql/15/bin}
export OBSCURA_PG_BIN=$PG_BIN
for tool in curl node psql sqlite3 taskset; do
  command -v $tool >/dev/null || { echo "bench_cluster: $tool is not installed" >&2; exit 1; }
done
[ -x "$PG_BIN/initdb" ] || { echo "bench_cluster: no $PG_BIN/initdb (postgresql-15)" >&2; exit 1; }
bin=$build/obscurad
[ -x "$bin" ] || { echo "bench_cluster: no $bin (cmake --build $build --target obscurad)" >&2; exit 1; }
if grep -q 'OBSCURA_SANITIZE:BOOL=ON' "$build/CMakeCache.txt" 2>/dev/null; then
  echo "bench_cluster: warning: $build is a sanitizer build" >&2
fi

work=$(mktemp -d "${TMPDIR:-/tmp}/bench-cluster.XXXXXX")
chmod 755 "$work" # the PostgreSQL server runs as postgres under root
pids=()
cleanup() {
  for p in "${pids[@]}"; do kill -9 "$p" 2>/dev/null || true; done
  sh "$ROOT/tests/pg/pg.sh" stop "$work/pg" >/dev/null 2>&1 || true
  rm -rf "$work"
}
trap cleanup EXIT

ncpu=$(nproc)
model=$(sed -n 's/^model name[[:space:]]*: //p' /proc/cpuinfo | head -1)
echo "obscurad ($(git -C "$ROOT" describe --always --dirty 2>/dev/null || echo '?')) on $ncpu cores ($model);" \
     "PostgreSQL $("$PG_BIN/postgres" --version | awk '{print $3}'); daemons $([ $pin = 1 ] && echo "pinned one core each" || echo unpinned)"

pgport=$(node -e 'const s=require("net").createServer().listen(0,"127.0.0.1",()=>{console.log(s.address().port);s.close()})')
admin=$(sh "$ROOT/tests/pg/pg.sh" start "$work/pg" "$pgport" | tail -1)
admin=${admin%/obscura}/postgres
pglog=$work/pg/server.log
psql -X -q -d "$admin" -c "ALTER SYSTEM SET log_min_duration_statement = 0" \
  -c "ALTER SYSTEM SET log_parameter_max_length = 0" -c "SELECT pg_reload_conf()" >/dev/null

# start_daemon NAME STORE CORE: starts obscurad, appends its pid to pids and its URL to urls.
urls=()
start_daemon() {
  local name=$1 store=$2 core=$3 dir=$work/$1 port= pre=()
  mkdir -p "$dir"
  [ $pin = 1 ] && pre=(taskset -c "$core")
  local where=(--db "$store")
  case $store in postgresql://*) where=(--store "$store" --node-name "$name") ;; esac
  "${pre[@]}" "$bin" --listen 127.0.0.1 --port 0 "${where[@]}" --data-dir "$dir/data" \
    --scenes-dir "$ROOT/scenes" --web-dir "$ROOT/web" --workers 1 --no-vulkan --quiet \
    2>"$dir/log" &
  pids+=($!)
  disown $!
  for _ in $(seq 1 300); do
    port=$(sed -n 's|^obscurad: listening on http://127\.0\.0\.1:\([0-9]*\)$|\1|p' "$dir/log")
    [ -n "$port" ] && break
    sleep 0.1
  done
  [ -n "$port" ] || { echo "bench_cluster: $name did not start:" >&2; cat "$dir/log" >&2; exit 1; }
  urls+=("http://127.0.0.1:$port")
}
stop_daemons() {
  for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
  for p in "${pids[@]}"; do
    for _ in $(seq 1 200); do kill -0 "$p" 2>/dev/null || break; sleep 0.1; done
  done
  pids=() urls=()
}

# The comparison: 118 rt_ao candidates (samples 32..90 at two ray lengths) and their two
# references, one timed run each after the warm-up.
request=$(node -e "console.log(JSON.stringify({scene_file: 'sphere_on_plane.json', label: 'bench cluster',
  set: {'/image/width': $size, '/image/height': $size}, repeats: 1, reference: {samples: 256},
  candidates: [{technique: 'rt_ao', backend: 'cpu', params: {samples: Array.from({length: 59}, (_, i) => 32 + i),
                                                              max_distance: [1, 4]}}]}))")

# sweep URL: posts the comparison and polls it (in one process, so that the polling costs little
# CPU) until it ends; prints "seconds state".
sweep() {
  REQUEST=$request node -e '
    const url = process.argv[1], t0 = process.hrtime.bigint();
    (async () => {
      const r = await fetch(`${url}/api/v1/comparisons`, {method: "POST", body: process.env.REQUEST,
                                                         headers: {"content-type": "application/json"}});
      if (r.status !== 201) throw new Error(`POST /api/v1/comparisons: ${r.status} ${await r.text()}`);
      const {id} = await r.json();
      for (;;) {
        const c = await (await fetch(`${url}/api/v1/comparisons/${id}`)).json();
        if (c.state !== "running") {
          console.log((Number(process.hrtime.bigint() - t0) / 1e9).toFixed(2), c.state);
          return;
        }
        await new Promise((res) => setTimeout(res, 50));
      }
    })().catch((e) => { console.error(`bench_cluster: ${e.message}`); process.exit(1); });' "$1"
}

# daemon_cpu: CPU seconds (user + system) the running daemons used so far.
daemon_cpu() {
  local t=0 p
  for p in "${pids[@]}"; do t=$((t + $(awk '{print $14 + $15}' "/proc/$p/stat"))); done
  awk -v t=$t -v hz="$(getconf CLK_TCK)" 'BEGIN { printf "%.1f", t / hz }'
}
# Other processes' load while a run went: the 1-minute load average at its end.
load1() { cut -d' ' -f1 /proc/loadavg; }

# percentiles: reads numbers, prints "p50 p99 n".
percentiles() {
  sort -n | awk '{ v[NR] = $1 } END {
    if (!NR) { print "- - 0"; exit }
    m = NR % 2 ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2
    i = int(NR * 0.99 + 0.999999); if (i > NR) i = NR
    printf "%.3f %.3f %d\n", m, v[i], NR }'
}

# claim_ms FROM: the claim statements' bind + execute durations the server logged past byte FROM.
claim_ms() {
  tail -c +$(($1 + 1)) "$pglog" | awk '
    match($0, /\[[0-9]+\]/) { pid = substr($0, RSTART, RLENGTH) }
    /duration: [0-9.]+ ms  (bind|execute) [^:]*: WITH c AS MATERIALIZED \(SELECT id FROM jobs/ {
      d = $0; sub(/.*duration: /, "", d); d += 0
      if ($0 ~ /ms  bind /) bind[pid] = d
      else { print d + bind[pid]; bind[pid] = 0 }
    }'
}

# list_latency URL: p50/p99 of the dashboard's first page, unfiltered and by state.
list_latency() {
  local q out=""
  for q in 'limit=50' 'state=succeeded&limit=50'; do
    for _ in $(seq 1 "$requests"); do
      curl -s -o /dev/null -w '%{time_total}\n' "$1/api/v1/jobs?$q"
    done | awk '{ print $1 * 1000 }' | percentiles >"$work/lat"
    read -r p50 p99 n <"$work/lat"
    out+="${out:+; }?$q p50 $p50 ms p99 $p99 ms"
  done
  echo "$out"
}

# The columns both stores' jobs tables have, for copying a finished job as history.
COLS="state, priority, label, scene, doc, technique, backend_requested, lane, backend, width, height, spp,
      attempts, created_ms, started_ms, finished_ms, summary, progress, notes, ranks, stored_bytes, node"

declare -A jpm
summary=()
for n in $daemons; do
  echo "== $n daemon(s) on PostgreSQL"
  psql -X -q -d "$admin" -c "CREATE DATABASE bench$n" >/dev/null
  url=${admin%/postgres}/bench$n
  for i in $(seq 1 "$n"); do start_daemon "node$i" "$url" $(((i - 1) % ncpu)); done
  from=$(stat -c %s "$pglog")
  read -r secs st < <(sweep "${urls[0]}")
  jpm[$n]=$(awk -v s="$secs" 'BEGIN { printf "%.1f", 120 / s * 60 }')
  cpu=$(daemon_cpu) load=$(load1)
  read -r c50 c99 cn < <(claim_ms "$from" | percentiles)
  twice=$(psql -X -A -t -d "$url" -c "SELECT count(*) FROM jobs WHERE attempts <> 1 OR state <> 'succeeded'")
  extra=$(psql -X -A -t -d "$url" -c "SELECT count(*) FROM (SELECT j.id FROM jobs j LEFT JOIN runs r ON r.job = j.id
                                        GROUP BY j.id, j.repeats HAVING count(r.job) <> j.repeats) x")
  spread=$(psql -X -A -t -F ' ' -d "$url" -c "SELECT node || ':' || count(*) FROM jobs GROUP BY node ORDER BY node" | paste -sd ' ')
  line="PostgreSQL, $n daemon(s): 120 jobs in $secs s ($st) = ${jpm[$n]} jobs/min (daemons' CPU $cpu s, load average $load); claim p50 $c50 ms p99 $c99 ms (n = $cn); jobs per node: $spread; not once: $twice, runs off: $extra"
  echo "$line"
  summary+=("$line")
  if [ "$n" = "$(echo $daemons | awk '{print $NF}')" ] && [ "$history" -gt 0 ]; then
    psql -X -q -d "$url" -c "INSERT INTO jobs ($COLS) SELECT $COLS FROM jobs, generate_series(1, $history)
                             WHERE id = (SELECT min(id) FROM jobs)" >/dev/null
    stored=$(psql -X -A -t -d "$url" -c "SELECT count(*) FROM jobs")
    line="PostgreSQL list latency with $stored jobs stored: $(list_latency "${urls[0]}")"
    echo "$line"
    summary+=("$line")
  fi
  stop_daemons
done

if [ $sqlite = 1 ]; then
  echo "== 1 daemon on SQLite"
  db=$work/sqlite.db
  start_daemon sqlite "$db" 0
  read -r secs st < <(sweep "${urls[0]}")
  jpm[sqlite]=$(awk -v s="$secs" 'BEGIN { printf "%.1f", 120 / s * 60 }')
  cpu=$(daemon_cpu) load=$(load1)
  twice=$(sqlite3 -readonly "$db" "SELECT count(*) FROM jobs WHERE attempts <> 1 OR state <> 'succeeded'")
  extra=$(sqlite3 -readonly "$db" "SELECT count(*) FROM (SELECT j.id FROM jobs j LEFT JOIN runs r ON r.job = j.id
                                    GROUP BY j.id, j.repeats HAVING count(r.job) <> j.repeats)")
  line="SQLite, 1 daemon: 120 jobs in $secs s ($st) = ${jpm[sqlite]} jobs/min (daemon's CPU $cpu s, load average $load); not once: $twice, runs off: $extra"
  echo "$line"
  summary+=("$line")
  if [ "$history" -gt 0 ]; then
    sqlite3 "$db" >/dev/null "PRAGMA busy_timeout = 10000; INSERT INTO jobs ($COLS) SELECT $COLS FROM jobs,
                   (WITH RECURSIVE s(x) AS (SELECT 1 UNION ALL SELECT x + 1 FROM s WHERE x < $history) SELECT x FROM s)
                   WHERE id = (SELECT min(id) FROM jobs)"
    stored=$(sqlite3 -readonly "$db" "SELECT count(*) FROM jobs")
    line="SQLite list latency with $stored jobs stored: $(list_latency "${urls[0]}")"
    echo "$line"
    summary+=("$line")
  fi
  stop_daemons
fi

echo "== summary"
printf '%s\n' "${summary[@]}"
if [ -n "${jpm[1]:-}" ] && [ -n "${jpm[2]:-}" ]; then
  awk -v a="${jpm[1]}" -v b="${jpm[2]}" 'BEGIN { r = b / a
    printf "2 daemons / 1 daemon: %.2fx (goal >= 1.8x: %s)\n", r, (r >= 1.8 ? "met" : "missed") }'
fi
