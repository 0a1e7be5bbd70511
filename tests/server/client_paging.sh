#!/usr/bin/env bash
# `obscura jobs` through a long history by its keyset: --limit N pages, --after ID continues below
# a listing's "next" with no job twice or missed, --all follows every page (more than one request's
# worth of jobs), the table says where older jobs continue, and a bad --after is refused.
# usage: client_paging.sh OBSCURA_CLI OBSCURAD SOURCE_ROOT WORK_DIR
set -u
cli=$1 daemon=$2 root=$3 out=$4
source "$(dirname "$0")/client_lib.sh"
rm -rf "$out" && mkdir -p "$out"
"$daemon" --listen 127.0.0.1 --port 0 --db "$out/obscura.db" --data-dir "$out/data" \
  --scenes-dir "$root/scenes" --web-dir "$root/web" --workers 1 --no-vulkan --quiet \
  >"$out/log" 2>&1 &
pid=$!
trap 'kill -9 $pid 2>/dev/null' EXIT
port=""
for ((i = 0; i < 300 * slow; i++)); do
  port=$(sed -n 's|.*listening on http://127\.0\.0\.1:\([0-9]*\).*|\1|p' "$out/log" | head -1)
  [ -n "$port" ] && break
  sleep 0.1
done
[ -n "$port" ] || { echo "FAIL: obscurad did not start"; cat "$out/log"; exit 1; }
url=http://127.0.0.1:$port

# 130 jobs (more than the client's 100 per request), held queued behind a long first job and
# cancelled: the listing does not care how they ended.
body='{"scene_file": "sphere_on_plane.json", "set": {"/image/width": 16, "/image/height": 16}}'
long='{"scene_file": "cornell_box.json", "priority": 100, "set": {"/image/width": 64, "/image/height": 48, "/technique/params/samples": 65536}}'
curl -sf -H 'Content-Type: application/json' -d "$long" "$url/api/v1/jobs" >/dev/null ||
  { echo "FAIL: submitting the long job"; exit 1; }
for ((i = 0; i < 129; i++)); do
  curl -sf -H 'Content-Type: application/json' -d "$body" "$url/api/v1/jobs" >/dev/null ||
    { echo "FAIL: submitting job $i"; exit 1; }
done
# Newest first, the long job last: the queued ones are cancelled while it still holds the worker
# (cancelled first, it would let them render on a fast machine).
for ((id = 130; id >= 1; id--)); do curl -sf -X POST "$url/api/v1/jobs/$id/cancel" >/dev/null; done

ids() { node -e 'let s = ""; process.stdin.on("data", (d) => s += d).on("end", () => {
  const l = JSON.parse(s); console.log(l.jobs.map((j) => j.id).join(" ") + " | " + l.next); });'; }
expect() { # from to: "from from-1 ... to"
  local s="" k
  for ((k = $1; k >= $2; k--)); do s+="$k "; done
  echo "${s% }"
}

"$cli" jobs --server "$url" --limit 3 --json | ids >"$out/p1"
check "--limit 3: the newest three and the cursor below them" \
  test "$(cat "$out/p1")" = "$(expect 130 128) | 128"
"$cli" jobs --server "$url" --limit 3 --after 128 --json | ids >"$out/p2"
check "--after continues below the cursor" test "$(cat "$out/p2")" = "$(expect 127 125) | 125"
"$cli" jobs --server "$url" --limit 5 --after 3 --json | ids >"$out/p3"
check "the last page ends with no cursor" test "$(cat "$out/p3")" = "2 1 | null"
"$cli" jobs --server "$url" --all --json | ids >"$out/all"
check "--all follows every page (130 jobs over two requests)" \
  test "$(cat "$out/all")" = "$(expect 130 1) | null"
"$cli" jobs --server "$url" --all --limit 2 --after 120 --json | ids >"$out/all-after"
check "--all from --after reads to the oldest, whatever --limit says" \
  test "$(cat "$out/all-after")" = "$(expect 119 1) | null"
# Some jobs may have rendered before their cancel: the filtered pages against the server's own
# filtered listing, read in one request.
curl -sf "$url/api/v1/jobs?state=cancelled&limit=500" | node -e 'let s = "";
  process.stdin.on("data", (d) => s += d).on("end", () => {
    const ids = JSON.parse(s).jobs.map((j) => j.id).filter((id) => id < 125);
    console.log(ids.slice(0, 110).join(" ") + " | " + (ids.length > 110 ? ids[109] : null)); });' \
  >"$out/f-want"
"$cli" jobs --server "$url" --state cancelled --limit 110 --after 125 --json | ids >"$out/f"
check "a filter stays with every page" test "$(cat "$out/f")" = "$(cat "$out/f-want")"
check "the filtered listing is long enough to need two requests" \
  test "$(wc -w <"$out/f-want")" -gt 102

"$cli" jobs --server "$url" --limit 2 >"$out/t.txt" 2>"$out/t.err"
check "the table exits 0" test $? -eq 0
check "the table says where older jobs continue" \
  grep -qx 'obscura: older jobs follow: obscura jobs --after 129' "$out/t.err"
check "the table holds the two newest" test "$(grep -Ec '^(130|129) ' "$out/t.txt")" -eq 2
"$cli" jobs --server "$url" --after 130 --limit 200 >/dev/null 2>"$out/last.err"
check "no hint after the last page" test ! -s "$out/last.err"

for bad in 0 -4 abc 012 ""; do
  "$cli" jobs --server "$url" --after "$bad" >/dev/null 2>"$out/bad.err"
  check "--after '$bad' exits 2" test $? -eq 2
  check "--after '$bad' is named" grep -q -- '--after must be a job id' "$out/bad.err"
done

kill "$pid"
wait "$pid" 2>/dev/null
echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
