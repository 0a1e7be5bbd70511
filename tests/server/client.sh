#!/usr/bin/env bash
# The CLI's job-server client end to end: `obscura submit`, `jobs`, `job`, `fetch`, `cancel`,
# `comparisons` and `compare` against obscurad.
# usage: client.sh OBSCURA_CLI OBSCURAD SOURCE_ROOT WORK_DIR
set -u
cli=$1 daemon=$2 root=$3 out=$4
source "$(dirname "$0")/client_lib.sh"

rm -rf "$out" && mkdir -p "$out"
pids=()
cleanup() { for p in "${pids[@]}"; do kill -9 "$p" 2>/dev/null; done; }
trap cleanup EXIT

# start_daemon NAME [obscurad options...]: starts obscurad on an ephemeral loopback port with its
# own directory; sets $url and $pid, or fails the whole test.
start_daemon() {
  local name=$1
  shift
  mkdir -p "$out/$name"
  "$daemon" --listen 127.0.0.1 --port 0 --db "$out/$name/obscura.db" --data-dir "$out/$name/data" \
    --scenes-dir "$root/scenes" --web-dir "$root/web" --workers 1 --no-vulkan "$@" \
    >"$out/$name/log" 2>&1 &
  pid=$!
  pids+=("$pid")
  local port="" i
  for ((i = 0; i < 300 * slow; i++)); do
    port=$(sed -n 's|.*listening on http://127\.0\.0\.1:\([0-9]*\).*|\1|p' "$out/$name/log" \
      2>/dev/null | head -1)
    [ -n "$port" ] && break
    kill -0 "$pid" 2>/dev/null || break
    sleep 0.1
  done
  if [ -z "$port" ]; then
    echo "FAIL: obscurad ($name) did not report its port:"
    cat "$out/$name/log"
    exit 1
  fi
  url=http://127.0.0.1:$port
}

# stop_daemon PID: SIGTERM and wait, so its log is complete (sanitizer reports come at exit).
stop_daemon() {
  kill "$1" 2>/dev/null
  wait "$1" 2>/dev/null
}

# njobs URL: the number of jobs the server lists (through the client itself).
njobs() {
  "$cli" jobs --server "$1" --limit 100000 --json |
    node -e 'let s = "";
      process.stdin.on("data", d => s += d).on("end", () => console.log(JSON.parse(s).jobs.length));'
}

scene=$root/scenes/sphere_on_plane.json
small=(--set /image/width=40 --set /image/height=30 --set /technique/params/samples=8)

start_daemon plain
plain_url=$url plain_pid=$pid
unset OBSCURA_TOKEN

# --- submit --wait -o: outputs downloaded, identical to a local render --------------------------
"$cli" submit "$scene" --server "$url" "${small[@]}" --label "client test" --priority 70 \
  --wait -o "$out/remote" >"$out/submit.out" 2>"$out/submit.err"
check "submit --wait -o exits 0" test $? -eq 0
check "submit prints the job id and its dashboard page" \
  grep -Eq "^job [0-9]+ queued: $url/#/jobs/[0-9]+$" "$out/submit.out"
id=$(sed -n 's/^job \([0-9]*\) queued.*/\1/p' "$out/submit.out")
check "submit reports success" grep -q "^job $id succeeded: rt_ao/cpu 40x30" "$out/submit.out"
check "plain progress lines (no TTY)" grep -q "^job $id: succeeded$" "$out/submit.err"
for f in ao.exr ao.png summary.json; do
  check "$f downloaded" test -s "$out/remote/$f"
done
check "no temporary files left in -o DIR" bash -c "! ls -A '$out/remote' | grep -q '^\\.'"
"$cli" render "$scene" "${small[@]}" -o "$out/local" --quiet
check "local render exits 0" test $? -eq 0
check "ao.exr identical to the local render" cmp "$out/remote/ao.exr" "$out/local/ao.exr"
check "ao.png identical to the local render" cmp "$out/remote/ao.png" "$out/local/ao.png"
check "summary.json describes the same render" node -e "
  const fs = require('fs');
  const a = JSON.parse(fs.readFileSync('$out/remote/summary.json'));
  const b = JSON.parse(fs.readFileSync('$out/local/summary.json'));
  const same = ['technique', 'backend', 'width', 'height', 'samples', 'rays', 'nan_count']
    .every(k => JSON.stringify(a[k]) === JSON.stringify(b[k]));
  process.exit(same && JSON.stringify(a.ao) === JSON.stringify(b.ao) ? 0 : 1);"

# --- jobs ---------------------------------------------------------------------------------------
"$cli" jobs --server "$url" >"$out/jobs.txt" 2>"$out/jobs.err"
check "jobs exits 0" test $? -eq 0
check "jobs table has the header" \
  grep -Eq "^ID +STATE +PROGRESS +TECHNIQUE +BACKEND +SCENE +TIME +PRIORITY +CREATED +LABEL$" \
  "$out/jobs.txt"
check "jobs lists the job with its scene and render time" \
  grep -Eq "^$id +succeeded +100% +rt_ao +cpu +sphere_on_plane\.json +[0-9.]+ m?s +70 +[0-9T:.-]+Z +client test$" \
  "$out/jobs.txt"
# --- job, fetch, cancel of a finished job ------------------------------------------------------
"$cli" job "$id" --server "$url" >"$out/job.txt" 2>"$out/job.err"
check "job exits 0" test $? -eq 0
check "job shows the state" grep -q "^job $id: succeeded 100%$" "$out/job.txt"
check "job shows technique, scene and image" bash -c "grep -Eq '^  technique +rt_ao on cpu' '$out/job.txt' &&
  grep -Eq '^  scene +sphere_on_plane\.json$' '$out/job.txt' &&
  grep -Eq '^  image +40x30, 1 pixel sample \(image\.spp\)$' '$out/job.txt'"
check "job shows the AO mean and the outputs" bash -c "grep -Eq '^  AO mean +0\.[0-9]{4}$' '$out/job.txt' &&
  grep -Eq '^  outputs +ao\.exr \([0-9]+ bytes\)$' '$out/job.txt'"
check "job shows the dashboard page" grep -q "^  page .*$url/#/jobs/$id$" "$out/job.txt"
"$cli" job "$id" --server "$url" --json >"$out/job.json"
check "job --json is the API's job" node -e "
  const j = JSON.parse(require('fs').readFileSync('$out/job.json'));
  process.exit(j.id === $id && j.state === 'succeeded' && j.scene_name === 'sphere_on_plane.json' ? 0 : 1);"
"$cli" job 999999 --server "$url" >/dev/null 2>"$out/job-404.err"
rc=$?
check "job of a missing id exits 2 with the server's answer" \
  bash -c "[ $rc -eq 2 ] && grep -q 'answered 404' '$out/job-404.err'"
"$cli" job abc --server "$url" >/dev/null 2>"$out/job-bad.err"
check "job with a bad id exits 2" test $? -eq 2
check "a specific error is followed by the hint, not the usage" bash -c "
  grep -q 'a job id is a positive integer (got abc)' '$out/job-bad.err' &&
  grep -qx \"obscura: 'obscura help job' shows its options\" '$out/job-bad.err' &&
  ! grep -q 'usage' '$out/job-bad.err'"
"$cli" fetch "$id" --server "$url" -o "$out/fetched" >"$out/fetch.out" 2>"$out/fetch.err"
check "fetch exits 0" test $? -eq 0
check "fetch downloads every output" test "$(ls "$out/fetched" | wc -l)" -eq "$(ls "$out/remote" | wc -l)"
check "fetch gives the same bytes as submit -o" cmp "$out/fetched/ao.exr" "$out/remote/ao.exr"
"$cli" fetch "$id" --server "$url" >/dev/null 2>"$out/fetch-no-o.err"
rc=$?
check "fetch without -o exits 2 and says so" \
  bash -c "[ $rc -eq 2 ] && grep -q 'missing -o DIR' '$out/fetch-no-o.err'"
"$cli" cancel "$id" --server "$url" >/dev/null 2>"$out/cancel-done.err"
check "cancel of a finished job exits 2" test $? -eq 2
check "cancel of a finished job shows the 409" grep -q "answered 409" "$out/cancel-done.err"
# The server from $OBSCURA_SERVER when --server is not given.
OBSCURA_SERVER=$url "$cli" jobs >"$out/jobs-env.txt" 2>&1
check "jobs uses OBSCURA_SERVER" grep -Eq "^$id +succeeded" "$out/jobs-env.txt"
# Neither: the default (scripts/run's address); whatever answers there, the client goes there.
(unset OBSCURA_SERVER; "$cli" jobs --limit 1 >/dev/null 2>"$out/jobs-default.err")
check "jobs defaults to http://127.0.0.1:8080" \
  bash -c "[ ! -s '$out/jobs-default.err' ] || grep -q 'http://127.0.0.1:8080/' '$out/jobs-default.err'"

"$cli" jobs --server "$url" --state succeeded --technique rt_ao --backend cpu --json \
  >"$out/jobs.json" 2>>"$out/jobs.err"
check "jobs --json with filters lists the job" node -e "
  const l = JSON.parse(require('fs').readFileSync('$out/jobs.json'));
  process.exit(l.jobs.length === 1 && l.jobs[0].id === $id && l.jobs[0].label === 'client test'
    && l.next === null ? 0 : 1);"
"$cli" jobs --server "$url" --state queued --json >"$out/jobs-q.json"
check "jobs --state queued is empty" node -e "
  const l = JSON.parse(require('fs').readFileSync('$out/jobs-q.json'));
  process.exit(l.jobs.length === 0 ? 0 : 1);"
"$cli" jobs --server "$url" --state bogus >/dev/null 2>"$out/jobs-bad.err"
check "jobs with a bad filter exits 2" test $? -eq 2
check "jobs with a bad filter shows the server's problem" grep -q "state" "$out/jobs-bad.err"

# --- compare: a request file followed to its end ------------------------------------------------
cat >"$out/cmp.json" <<JSON
{"scene_file": "sphere_on_plane.json", "label": "cli compare", "repeats": 1,
 "set": {"/image/width": 16, "/image/height": 12},
 "reference": {"samples": 256},
 "candidates": [{"technique": "rt_ao", "backend": "cpu", "params": {"samples": [2, 8]}},
                {"technique": "ssao", "backend": "cpu"}]}
JSON
"$cli" compare "$out/cmp.json" --server "$url" >"$out/cmp.out" 2>"$out/cmp.err"
check "compare exits 0 when the comparison succeeds" test $? -eq 0
check "compare prints the comparison's dashboard page" \
  grep -Eq "^comparison [0-9]+ queued: $url/#/comparisons/[0-9]+$" "$out/cmp.out"
cmpid=$(sed -n 's/^comparison \([0-9]*\) queued.*/\1/p' "$out/cmp.out")
check "compare reports progress" grep -q "^comparison $cmpid: 3/3 candidate(s) done$" "$out/cmp.err"
check "compare prints a row per candidate with time and every metric of the table" \
  test "$(grep -Ec '^ +[0-9]+[* ] +(rt_ao|ssao) +cpu +[0-9.]+( +-?[0-9.e-]+){6}( |$)' "$out/cmp.out")" -eq 3
check "compare's metric columns are the table's" \
  grep -Eq '^ +# +TECHNIQUE +BACKEND +TIME_MS +RMSE +BIAS +MAX_ABS +PSNR +SSIM +FLIP +PARAMS$' "$out/cmp.out"
check "compare names the parameter that varies" grep -Eq "rt_ao .* samples=2$" "$out/cmp.out"
check "compare leaves out the parameters that do not vary" bash -c "! grep -q falloff '$out/cmp.out'"
check "compare prints the Pareto set" grep -Eq "^pareto \(\* above, fastest first\):( [0-9]+)+$" "$out/cmp.out"
check "compare prints the outcome" grep -q "^comparison $cmpid succeeded$" "$out/cmp.out"
check "the starred rows are the Pareto set" node -e "
  const t = require('fs').readFileSync('$out/cmp.out', 'utf8');
  const starred = [...t.matchAll(/^ +([0-9]+)\* /gm)].map(m => +m[1]);
  const listed = t.match(/^pareto[^:]*:(.*)$/m)[1].trim().split(' ').map(Number);
  process.exit(starred.length > 0 && JSON.stringify([...starred].sort()) === JSON.stringify([...listed].sort()) ? 0 : 1);"
"$cli" comparisons --server "$url" >"$out/cmps.txt" 2>&1
check "comparisons lists the comparison with its state and candidates done" \
  grep -Eq "^$cmpid +succeeded +3/3 +[0-9T:.-]+Z +sphere_on_plane\.json +cli compare$" "$out/cmps.txt"
"$cli" comparisons --server "$url" --json >"$out/cmps.json"
check "comparisons --json is the API's list" node -e "
  const l = JSON.parse(require('fs').readFileSync('$out/cmps.json'));
  process.exit(l.comparisons.some(c => c.id === $cmpid && c.done === 3) ? 0 : 1);"
# A reference with 2 samples against candidates with 256: their RMSEs measure its noise.
printf '{"scene_file": "sphere_on_plane.json", "repeats": 1, "set": {"/image/width": 16, "/image/height": 12}, "reference": {"samples": 2}, "candidates": [{"technique": "rt_ao", "backend": "cpu", "params": {"samples": [256, 512]}}]}' \
  >"$out/cmp-noisy.json"
"$cli" compare "$out/cmp-noisy.json" --server "$url" >"$out/cmp-noisy.out" 2>"$out/cmp-noisy.err"
check "compare prints the ranking warning of a noisy reference" \
  grep -q "^obscura: warning: the reference is too noisy to rank the candidates" "$out/cmp-noisy.err"
check "compare prints no ranking warning when the reference can rank" \
  bash -c "! grep -q 'too noisy' '$out/cmp.err'"
"$cli" compare - --server "$url" --no-wait <"$out/cmp.json" >"$out/cmp2.out" 2>&1
check "compare - --no-wait reads stdin and returns at once" \
  bash -c "[ \$? -eq 0 ] && grep -Eq '^comparison [0-9]+ queued: ' '$out/cmp2.out' && ! grep -q '^pareto' '$out/cmp2.out'"
printf '{"scene_file": "sphere_on_plane.json", "repeats": 1, "set": {"/image/width": 8, "/image/height": 8}, "reference": {"samples": 2}, "candidates": [{"technique": "hbao", "backend": "cpu"}]}' \
  | "$cli" compare - --server "$url" --no-wait >/dev/null 2>"$out/cmp-notes.err"
check "compare says which values the server derived from the scene's size" \
  grep -Eq "^obscura: note: hbao radius = [0-9.e+-]+ derived from the scene's size" "$out/cmp-notes.err"
"$cli" compare "$out/cmp.json" --server "$url" --json >"$out/cmp3.json" 2>/dev/null
check "compare --json prints the finished comparison" node -e "
  const c = JSON.parse(require('fs').readFileSync('$out/cmp3.json'));
  process.exit(c.state === 'succeeded' && c.candidates.length === 3 && Array.isArray(c.pareto) ? 0 : 1);"
printf '{"scene_file": "sphere_on_plane.json", "candidates": [{"technique": "nope"}]}' >"$out/cmp-bad.json"
"$cli" compare "$out/cmp-bad.json" --server "$url" >/dev/null 2>"$out/cmp-bad.err"
check "compare of a bad request exits 2" test $? -eq 2
check "compare of a bad request shows the server's problem" grep -q "/candidates/0/technique" "$out/cmp-bad.err"
"$cli" compare "$out/no-such.json" --server "$url" >/dev/null 2>"$out/cmp-missing.err"
check "compare of a missing file exits 2" test $? -eq 2
check "compare of a missing file says why" grep -q "No such file or directory" "$out/cmp-missing.err"

# --- bad input is refused locally, nothing is sent ----------------------------------------------
before=$(njobs "$url")
"$cli" submit "$scene" --server "$url" --set /technique/params/samples=0 >"$out/bad.out" \
  2>"$out/bad.err"
check "bad --set exits 2" test $? -eq 2
check "bad --set names the pointer" grep -q "/technique/params/samples: must be >= 1" "$out/bad.err"
"$cli" submit "$scene" --server "$url" --technique nope >/dev/null 2>"$out/bad-t.err"
check "unknown technique exits 2" test $? -eq 2
"$cli" submit "$scene" --server "$url" --priority 101 >/dev/null 2>"$out/bad-p.err"
check "--priority out of range exits 2" test $? -eq 2
"$cli" submit "$out/missing.json" --server "$url" >/dev/null 2>&1
check "missing scene file exits 2" test $? -eq 2
"$cli" submit "$scene" --server "not a url" >/dev/null 2>&1
check "bad --server exits 2" test $? -eq 2
touch "$out/a-file"
"$cli" submit "$scene" --server "$url" "${small[@]}" -o "$out/a-file/sub" >/dev/null \
  2>"$out/bad-o.err"
check "unusable -o DIR exits 2" test $? -eq 2
check "nothing was submitted" test "$(njobs "$url")" = "$before"

# --- the server's own 4xx: exit 2 with its message and problems ---------------------------------
# The local loader accepts 200x200; the daemon's --max-pixels (set low below) does not.
# (--no-estimate-render-time: the job below must fail by the limit during the render, not be refused.)
start_daemon limited --max-pixels 10000 --max-render-seconds 1 --no-estimate-render-time
"$cli" submit "$scene" --server "$url" --set /image/width=200 --set /image/height=200 \
  >/dev/null 2>"$out/limit.err"
check "server 422 exits 2" test $? -eq 2
check "server 422 shows the server's message" grep -q "answered 422" "$out/limit.err"
check "server 422 names the limit" grep -q "max-pixels" "$out/limit.err"

# --- --wait on a job that fails exits 1 with the server's error ---------------------------------
"$cli" submit "$scene" --server "$url" --set /image/width=100 --set /image/height=100 \
  --set /technique/params/samples=65536 --wait -o "$out/failed" >"$out/failed.out" \
  2>"$out/failed.err"
check "--wait on a failed job exits 1" test $? -eq 1
check "--wait prints the job's error" grep -q "^obscura: job [0-9]* failed: .*time limit" \
  "$out/failed.err"
check "nothing downloaded for a failed job" test -z "$(ls -A "$out/failed")"
# A comparison whose reference fails (the time limit) ends failed: exit 1, the reason shown.
printf '{"scene_file": "sphere_on_plane.json", "repeats": 1, "set": {"/image/width": 100, "/image/height": 100}, "reference": {"samples": 65536}, "candidates": [{"technique": "ssao", "backend": "cpu"}]}' \
  >"$out/cmp-fail.json"
OBSCURA_SERVER=$url "$cli" compare "$out/cmp-fail.json" >"$out/cmp-fail.out" 2>"$out/cmp-fail.err"
check "compare of a comparison that fails exits 1" test $? -eq 1
check "compare of a comparison that fails says so" grep -q "^comparison [0-9]* failed$" "$out/cmp-fail.out"
check "compare shows why a candidate got no metrics" \
  grep -Eq "^ +0  +ssao .* error: reference job [0-9]+ failed$" "$out/cmp-fail.out"
stop_daemon "$pid"

# --- pagination: jobs follows the next cursor up to --limit -------------------------------------
start_daemon paged
for i in $(seq 1 104); do
  "$cli" submit "$scene" --server "$url" --set /image/width=4 --set /image/height=4 \
    --set /technique/params/samples=1 --label "p$i" >/dev/null 2>&1 || echo "submit $i failed"
done
"$cli" jobs --server "$url" --limit 1000 --json >"$out/paged.json"
check "jobs follows the cursor past one page" node -e "
  const l = JSON.parse(require('fs').readFileSync('$out/paged.json'));
  const ids = l.jobs.map(j => j.id);
  process.exit(ids.length === 104 && new Set(ids).size === 104 && l.next === null ? 0 : 1);"
"$cli" jobs --server "$url" --limit 102 --json >"$out/paged2.json"
check "jobs stops at --limit" node -e "
  const l = JSON.parse(require('fs').readFileSync('$out/paged2.json'));
  process.exit(l.jobs.length === 102 && l.next !== null ? 0 : 1);"
"$cli" jobs --server "$url" --limit 5 | tail -n +2 | wc -l >"$out/paged3.txt"
check "jobs table has --limit rows" test "$(cat "$out/paged3.txt")" -eq 5
stop_daemon "$pid"

# --- --wait on a job that ends cancelled exits 1 with the server's error ------------------------
"$cli" submit "$scene" --server "$plain_url" --set /technique/params/samples=65536 --wait \
  >"$out/cancel.out" 2>"$out/cancel.err" &
waiter=$!
cid=""
for ((i = 0; i < 200 * slow; i++)); do
  cid=$(sed -n 's/^job \([0-9]*\) queued.*/\1/p' "$out/cancel.out" 2>/dev/null)
  [ -n "$cid" ] && grep -q "^job $cid: running" "$out/cancel.err" && break
  sleep 0.05
done
"$cli" cancel "$cid" --server "$plain_url" >"$out/cancel-cmd.out" 2>&1
check "cancel of a running job exits 0" test $? -eq 0
check "cancel says the render stops" grep -q "^job $cid: cancel requested" "$out/cancel-cmd.out"
wait "$waiter"
check "--wait on a cancelled job exits 1" test $? -eq 1
check "--wait prints the server's error" grep -q "^obscura: job $cid cancelled: " "$out/cancel.err"

# --- token ----------------------------------------------------------------------------------------
printf 's3cret-token\n' >"$out/token.txt"
start_daemon token --token-file "$out/token.txt"
OBSCURA_TOKEN=wrong "$cli" submit "$scene" --server "$url" "${small[@]}" >/dev/null \
  2>"$out/token.err"
check "wrong token exits 2" test $? -eq 2
check "wrong token shows the 401" grep -q "answered 401" "$out/token.err"
"$cli" jobs --server "$url" >/dev/null 2>"$out/notoken.err"
check "missing token exits 2" test $? -eq 2
OBSCURA_TOKEN=s3cret-token "$cli" submit "$scene" --server "$url" "${small[@]}" --wait \
  >"$out/token.out" 2>&1
check "right token: submit --wait exits 0" test $? -eq 0
OBSCURA_TOKEN=s3cret-token "$cli" jobs --server "$url" >"$out/token-jobs.txt" 2>&1
check "right token: jobs lists the job" grep -Eq "^1 +succeeded" "$out/token-jobs.txt"
stop_daemon "$pid"

# --- unreachable server -------------------------------------------------------------------------
stop_daemon "$plain_pid"
"$cli" submit "$scene" --server "$plain_url" "${small[@]}" >/dev/null 2>"$out/down.err"
check "unreachable server exits 1" test $? -eq 1
check "unreachable server message names the URL" grep -q "cannot reach the server at $plain_url/" \
  "$out/down.err"
"$cli" jobs --server "$plain_url" >/dev/null 2>&1
check "jobs on an unreachable server exits 1" test $? -eq 1

for d in plain limited paged token; do
  if grep -Eq "ERROR: (Address|Leak)Sanitizer|runtime error:" "$out/$d/log"; then
    fail=$((fail + 1))
    echo "FAIL: sanitizer report in obscurad log ($d)"
  fi
done
echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
