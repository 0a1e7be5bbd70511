#!/usr/bin/env bash
# obscurad end to end, quickly: start on an ephemeral loopback port with a fresh database, submit a
# tiny inline scene, poll it to success, fetch its PNG (and a 304), check a 404, a 422, the
# dashboard and /metrics, then stop it with SIGTERM and expect a clean exit.
set -u
bin=$1 root=$2 work=$3
pass=0 fail=0
check() { # description, command...
  local d=$1; shift
  if "$@"; then pass=$((pass + 1)); echo "ok: $d"; else fail=$((fail + 1)); echo "FAIL: $d"; fi
}
rm -rf "$work" && mkdir -p "$work"
"$bin" --port 0 --data-dir "$work/var" --scenes-dir "$root/scenes" --web-dir "$root/web" \
  --vendor-dir "$root/node_modules" --workers 1 2>"$work/log" &
pid=$!
trap 'kill -9 $pid 2>/dev/null' EXIT
port=
for _ in $(seq 1 600); do
  port=$(sed -n 's|^obscurad: listening on http://127.0.0.1:\([0-9]*\)$|\1|p' "$work/log")
  [ -n "$port" ] && break
  kill -0 $pid 2>/dev/null || break
  sleep 0.1
done
if [ -z "$port" ]; then
  echo "FAIL: obscurad did not start"; cat "$work/log"; exit 1
fi
base=http://127.0.0.1:$port
echo "obscurad on $base"

# curl wrapper: prints the status code; body into $work/body, headers into $work/headers.
req() { curl -s -o "$work/body" -D "$work/headers" -w '%{http_code}' "$@"; }
json() { node -e "const b=JSON.parse(require('fs').readFileSync('$work/body'));process.stdout.write(String($1))"; }

check "health is 200" test "$(req "$base/api/v1/health")" = 200
node -e "
  const d = JSON.parse(require('fs').readFileSync('$root/scenes/sphere_on_plane.json'));
  d.image.width = 40; d.image.height = 30; d.technique.params.samples = 8; d.label = 'smoke';
  process.stdout.write(JSON.stringify(d));" >"$work/job.json"
code=$(req -X POST -H 'Content-Type: application/json' --data-binary @"$work/job.json" \
  "$base/api/v1/jobs")
check "submit is 201" test "$code" = 201
id=$(json b.id)
check "201 body has id, state queued and links" \
  test "$(json "b.state + ' ' + b.links.self")" = "queued /api/v1/jobs/$id"
state=
for _ in $(seq 1 1200); do
  req "$base/api/v1/jobs/$id" >/dev/null
  state=$(json b.state)
  case $state in succeeded|failed|cancelled) break ;; esac
  sleep 0.1
done
check "job succeeded" test "$state" = succeeded
check "job has timings, rays, stats, outputs" node -e "
  const j = JSON.parse(require('fs').readFileSync('$work/body'));
  const ok = j.progress === 1 && j.attempts === 1 && j.label === 'smoke' &&
    j.backend.actual === 'cpu' && j.timings_ms.total > 0 && j.rays > 0 &&
    j.stats.nan_count === 0 && j.outputs.length >= 4 && j.links.outputs['ao.png'] &&
    j.links.outputs['depth.png'];
  process.exit(ok ? 0 : 1);"
code=$(req "$base/api/v1/jobs/$id/outputs/ao.png")
check "ao.png is 200" test "$code" = 200
check "ao.png is a PNG" bash -c "head -c 8 '$work/body' | od -An -tx1 | grep -q '89 50 4e 47'"
check "ao.png has image/png and an immutable cache header" \
  bash -c "grep -qi '^content-type: image/png' '$work/headers' &&
           grep -qi '^cache-control: public, max-age=31536000, immutable' '$work/headers'"
etag=$(sed -n 's/^[Ee][Tt][Aa][Gg]: *\(.*\)\r$/\1/p' "$work/headers")
check "If-None-Match gives 304" \
  test "$(req -H "If-None-Match: $etag" "$base/api/v1/jobs/$id/outputs/ao.png")" = 304
check "unknown job is 404" test "$(req "$base/api/v1/jobs/999999")" = 404
check "404 has the error shape" test "$(json "typeof b.error + Array.isArray(b.problems)")" = stringtrue
check "unknown output is 404" test "$(req "$base/api/v1/jobs/$id/outputs/..%2Fobscura.db")" = 404
code=$(req -X POST -H 'Content-Type: application/json' \
  -d '{"scene_file":"sphere_on_plane.json","set":{"/image/width":0},"priority":101}' \
  "$base/api/v1/jobs")
check "invalid job is 422" test "$code" = 422
check "422 lists every problem with its pointer" node -e "
  const b = JSON.parse(require('fs').readFileSync('$work/body'));
  const p = b.problems.join('\n');
  process.exit(p.includes('request: /priority') && p.includes('/image/width') ? 0 : 1);"
check "malformed JSON is 400" test "$(req -X POST -H 'Content-Type: application/json' -d '{"a":' \
  "$base/api/v1/jobs")" = 400
check "dashboard is served with a CSP" bash -c "
  test \"\$(curl -s -o /dev/null -D '$work/h2' -w '%{http_code}' '$base/')\" = 200 &&
  grep -qi \"^content-security-policy: default-src 'self'\" '$work/h2'"
check "the chart library is served from --vendor-dir" \
  test "$(req "$base/vendor/uplot/uPlot.iife.min.js")" = 200
check "nothing else of --vendor-dir is" bash -c "
  test \"\$(curl -s -o /dev/null -w '%{http_code}' '$base/vendor/uplot/package.json')\" = 404 &&
  test \"\$(curl -s -o /dev/null -w '%{http_code}' --path-as-is '$base/vendor/../package.json')\" = 404"
check "metrics count jobs by state" bash -c "curl -s '$base/metrics' |
  grep -q '^obscura_jobs{state=\"succeeded\"} 1$'"
kill -TERM $pid
wait $pid
rc=$?
trap - EXIT
check "SIGTERM stops it cleanly (exit 0)" test $rc -eq 0
check "no database error was logged" bash -c "! grep -qE 'database error|database: ' '$work/log'"
echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ] || { echo "--- daemon log"; cat "$work/log"; }
[ "$fail" -eq 0 ]
