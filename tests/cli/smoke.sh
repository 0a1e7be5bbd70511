#!/usr/bin/env bash
# The CLI end to end: render, outputs and summary, exit codes for bad input, validate, techniques,
# warnings outside a technique's guaranteed range.
set -u
cli=$1 root=$2 out=$3
pass=0 fail=0
check() { # description, command...
  local d=$1; shift
  if "$@"; then pass=$((pass + 1)); echo "ok: $d"; else fail=$((fail + 1)); echo "FAIL: $d"; fi
}
rm -rf "$out" && mkdir -p "$out"
"$cli" render "$root/scenes/sphere_on_plane.json" -o "$out/r" --set /image/width=40 \
  --set /image/height=30 --set /technique/params/samples=8 --threads 2 >"$out/log" 2>&1
check "render exits 0" test $? -eq 0
check "ao.exr written" test -s "$out/r/ao.exr"
check "ao.png is a PNG" bash -c "head -c 8 '$out/r/ao.png' | od -An -tx1 | grep -q '89 50 4e 47'"
check "summary has the fields" node -e "
  const s = JSON.parse(require('fs').readFileSync('$out/r/summary.json'));
  const ok = s.technique === 'rt_ao' && s.backend === 'cpu' && s.width === 40 && s.height === 30 &&
    s.samples === 8 && s.rays > 0 && s.nan_count === 0 && s.ao.min >= 0 && s.ao.max <= 1 &&
    ['load','build','render','write','total'].every(k => typeof s.timings_ms[k] === 'number');
  process.exit(ok ? 0 : 1);"
"$cli" render "$root/scenes/sphere_on_plane.json" -o "$out/bad" --set /technique/params/samples=0 \
  >"$out/bad.log" 2>&1
check "bad --set exits 2" test $? -eq 2
check "bad --set names the pointer" grep -q "/technique/params/samples: must be >= 1" "$out/bad.log"
check "nothing written for bad input" test ! -e "$out/bad"
"$cli" render "$root/scenes/sphere_on_plane.json" -o "$out/v" --backend vulkan >"$out/v.log" 2>&1
check "missing backend exits 2" test $? -eq 2
check "missing backend lists available" grep -q 'available: "cpu"' "$out/v.log"
"$cli" render "$root/scenes/sphere_on_plane.json" --technique nope >"$out/t.log" 2>&1
check "unknown technique exits 2" test $? -eq 2
"$cli" render "$out/does-not-exist.json" >"$out/m.log" 2>&1
check "missing file exits 2" test $? -eq 2
"$cli" validate "$root/scenes/cornell_box.json" >/dev/null 2>&1
check "validate ok exits 0" test $? -eq 0
"$cli" techniques >"$out/tech.json"
check "techniques is JSON with rt_ao" node -e "
  const t = JSON.parse(require('fs').readFileSync('$out/tech.json'));
  process.exit(t.some(x => x.name === 'rt_ao' && x.backends.includes('cpu')) ? 0 : 1);"
check "techniques carry each backend's range" node -e "
  const t = JSON.parse(require('fs').readFileSync('$out/tech.json'));
  process.exit(t.every(x => x.backends.every(b => x.ranges[b] && x.ranges[b].size.length === 2)) ? 0 : 1);"
"$cli" techniques --bogus >/dev/null 2>&1
check "techniques with an unknown option exits 2" test $? -eq 2
# Outside the guaranteed range the render succeeds and warns, on stderr and in summary.json.
"$cli" render "$root/scenes/sphere_on_plane.json" -o "$out/wide" --set /camera/fov_y=175 \
  --set /image/width=16 --set /image/height=16 --set /technique/params/samples=4 --quiet \
  >"$out/wide.log" 2>&1
check "render outside the range exits 0" test $? -eq 0
check "render outside the range warns on stderr" \
  grep -q "warning: camera fov_y 175 degrees is outside \[.*\] degrees where rt_ao on cpu" \
  "$out/wide.log"
check "summary.json carries the warning" node -e "
  const s = JSON.parse(require('fs').readFileSync('$out/wide/summary.json'));
  process.exit(s.warnings.length === 1 && /fov_y 175/.test(s.warnings[0]) ? 0 : 1);"
check "a render inside the range has no warnings" node -e "
  const s = JSON.parse(require('fs').readFileSync('$out/r/summary.json'));
  process.exit(Array.isArray(s.warnings) && s.warnings.length === 0 ? 0 : 1);"
printf '{"camera":{"type":"perspective","position":[0,1,-3],"look_at":[0,0,0],"fov_y":40},"image":{"width":8,"height":8},"objects":[{"shape":{"type":"mesh","file":"junk.obj"}}],"technique":{"name":"rt_ao"}}' >"$out/junk.json"
echo "not a mesh" >"$out/junk.obj"
"$cli" render "$out/junk.json" -o "$out/junk" >"$out/junk.log" 2>&1
check "unreadable mesh exits 2" test $? -eq 2
check "unreadable mesh names the field" grep -q "/objects/0/shape/file: cannot import mesh" "$out/junk.log"
"$cli" render "$root/scenes/sphere_on_plane.json" -o "$out/far" --set /objects/1/shape/radius=1e25 \
  >"$out/far.log" 2>&1
check "geometry out of range exits 2" test $? -eq 2
check "out of range is explained" grep -q "beyond the renderer's range" "$out/far.log"
"$cli" render "$root/scenes/sphere_on_plane.json" -o "" --set /technique/params/samples=1 \
  >"$out/empty.log" 2>&1
check "empty output directory exits 2" test $? -eq 2
"$cli" render "$root/scenes/sphere_on_plane.json" -o "$out/r" --set /image/width=40 \
  --set /image/height=30 --set /technique/params/samples=64.0 >/dev/null 2>&1
check "integral real samples render finite" node -e "
  const s = JSON.parse(require('fs').readFileSync('$out/r/summary.json'));
  process.exit(s.samples === 64 && s.nan_count === 0 && s.ao.mean > 0.5 ? 0 : 1);"
check "no staging files left" bash -c "! ls -A '$out/r' | grep -q '^\\.'"
# Messages that say what to do: why a scene file cannot be opened, the quotes a bare string needs,
# the nearest parameter name.
"$cli" render "$out/does-not-exist.json" --technique ssao >"$out/m2.log" 2>&1
check "missing file says why" \
  grep -q "does-not-exist.json: cannot open scene file: No such file or directory" "$out/m.log"
check "missing file says why with --technique too" \
  grep -q "does-not-exist.json: cannot open scene file: No such file or directory" "$out/m2.log"
if [ "$(id -u)" -ne 0 ]; then
  printf '{}' >"$out/secret.json" && chmod 000 "$out/secret.json"
  "$cli" validate "$out/secret.json" >"$out/perm.log" 2>&1
  check "unreadable file exits 2" test $? -eq 2
  check "unreadable file says why" grep -q "cannot open scene file: Permission denied" "$out/perm.log"
fi
# A bare word is a string: enum values need no JSON quotes; JSON values stay JSON.
"$cli" validate "$root/scenes/cornell_box.json" --set /technique/params/weighting=uniform >"$out/q.log" 2>&1
check "bare string --set is taken as a string" grep -q "valid (rt_ao," "$out/q.log"
"$cli" render "$root/scenes/sphere_on_plane.json" -o "$out/sqrt" --set /image/width=8 \
  --set /image/height=8 --set /technique/params/samples=2 --set /technique/params/falloff=sqrt \
  --set /technique/params/max_distance=2 --quiet >"$out/sqrt.log" 2>&1
check "bare enum --set renders with that value" node -e "
  const s = JSON.parse(require('fs').readFileSync('$out/sqrt/summary.json'));
  process.exit(s.params.falloff === 'sqrt' && s.params.max_distance === 2 ? 0 : 1);"
"$cli" validate "$root/scenes/cornell_box.json" --set /technique/params/samples=many >"$out/q3.log" 2>&1
rc=$?
check "a bare word where a number belongs exits 2 naming the pointer" \
  bash -c "[ $rc -eq 2 ] && grep -q '/technique/params/samples: .*\"many\"' '$out/q3.log'"
"$cli" validate "$root/scenes/cornell_box.json" --set '/image/width={' >"$out/q2.log" 2>&1
check "broken JSON --set exits 2 without a quote hint" \
  bash -c "grep -q 'the value is not JSON: ' '$out/q2.log' && ! grep -q 'did you mean' '$out/q2.log'"
"$cli" validate "$root/scenes/cornell_box.json" --set /technique/params/samplez=8 >"$out/n.log" 2>&1
check "misspelt parameter exits 2" test $? -eq 2
check "misspelt parameter keeps the pointer and suggests the name" \
  grep -qF 'cornell_box.json: /technique/params/samplez: unknown parameter (did you mean "samples"?)' "$out/n.log"
"$cli" validate "$root/scenes/cornell_box.json" --technique hbao --set /technique/params/raduis=8 \
  >"$out/n2.log" 2>&1
check "misspelt parameter of another technique suggests its name" \
  grep -qF '/technique/params/raduis: unknown parameter (did you mean "radius"?)' "$out/n2.log"
# --base-dir: a copy of a scene that reads a file, elsewhere, resolves it against the directory
# given; --progress-file holds the fraction done, 1 at the end.
mkdir -p "$out/elsewhere"
cp "$root/scenes/volume_head.json" "$out/elsewhere/"
"$cli" render "$out/elsewhere/volume_head.json" -o "$out/nobase" --set /image/width=8 \
  --set /image/height=8 >"$out/nobase.log" 2>&1
check "a relative volume file beside the copy is missing (exit 2)" test $? -eq 2
"$cli" render "$out/elsewhere/volume_head.json" -o "$out/base" --base-dir "$root/scenes" \
  --set /image/width=8 --set /image/height=8 --set /technique/params/samples=2 \
  --progress-file "$out/progress" >"$out/base.log" 2>&1
check "--base-dir resolves it" test -s "$out/base/final.exr"
check "--progress-file ends at 1" test "$(cat "$out/progress")" = "1.0000"
"$cli" render "$out/elsewhere/volume_head.json" --base-dir "$out/none" >"$out/nodir.log" 2>&1
check "--base-dir that is no directory exits 2" test $? -eq 2
check "--base-dir names it" grep -q -- "--base-dir $out/none: not a directory" "$out/nodir.log"
# The bundled defaults give a readable first image (small renders; figures at these sizes):
# proximity_ao on the hangar shows its occlusion (the thesis's settings gave AO mean 0.980, min
# 0.64: nearly white; now 0.964, min 0), volume_engine's final.png is not clipped (radiance mean
# 1.01, max 1.63: the exposure of -1 EV shows 0.51 and 0.82), path_trace's default paths keep the
# noise under 7.5 % of the radiance (16 paths: 9.9 %, 64: 5.3 %).
"$cli" render "$root/scenes/hangar.json" -o "$out/hangar" --set /image/width=80 \
  --set /image/height=60 --quiet >"$out/hangar.log" 2>&1
check "hangar: proximity_ao shows occlusion (AO mean <= 0.97, min <= 0.3)" node -e "
  const s = JSON.parse(require('fs').readFileSync('$out/hangar/summary.json'));
  process.exit(s.ao.mean <= 0.97 && s.ao.mean >= 0.85 && s.ao.min <= 0.3 ? 0 : 1);"
"$cli" render "$root/scenes/volume_engine.json" -o "$out/engine" --set /image/width=48 \
  --set /image/height=48 --quiet >"$out/engine.log" 2>&1
check "volume_engine: final.png neither blown out nor dark (shown mean in [0.25, 0.75], max <= 1)" node -e "
  const s = JSON.parse(require('fs').readFileSync('$out/engine/summary.json'));
  const k = 2 ** s.params.exposure, f = s.outputs.final;
  const mean = f.luminance_mean * k, max = Math.max(...Object.values(f.channels).map(c => c.max)) * k;
  process.exit(mean >= 0.25 && mean <= 0.75 && max <= 1 ? 0 : 1);"
"$cli" render "$root/scenes/cornell_box.json" --technique path_trace -o "$out/pt" \
  --set /image/width=32 --set /image/height=32 --quiet >"$out/pt.log" 2>&1
check "path_trace's default: noise under 7.5 % of the radiance" node -e "
  const s = JSON.parse(require('fs').readFileSync('$out/pt/summary.json'));
  const r = s.outputs.radiance_stderr.luminance_mean / s.outputs.radiance.luminance_mean;
  process.exit(r > 0 && r <= 0.075 ? 0 : 1);"
# --help on every subcommand: its own usage on stdout, exit 0.
for cmd in render validate techniques submit jobs compare; do
  "$cli" "$cmd" --help >"$out/help-$cmd.txt" 2>&1
  check "$cmd --help exits 0" test $? -eq 0
  check "$cmd --help shows its usage" grep -q "^  obscura $cmd " "$out/help-$cmd.txt"
  check "$cmd --help shows only its usage" test "$(grep -c '^  obscura ' "$out/help-$cmd.txt")" -eq 1
done
"$cli" jobs -h | grep -q "OBSCURA_SERVER, else http://127.0.0.1:8080"
check "help names the default server and OBSCURA_SERVER" test $? -eq 0
"$cli" frobnicate >/dev/null 2>"$out/unknown.err"
check "unknown command exits 2" test $? -eq 2
check "unknown command points at obscura help, without the whole usage" bash -c "
  grep -qx \"obscura: 'obscura help' lists the commands\" '$out/unknown.err' && ! grep -q usage '$out/unknown.err'"
for cmd in job cancel fetch comparisons; do
  "$cli" help "$cmd" >"$out/help-$cmd.txt" 2>&1
  check "help $cmd shows only its usage" \
    bash -c "grep -q '^  obscura $cmd ' '$out/help-$cmd.txt' && [ \$(grep -c '^  obscura ' '$out/help-$cmd.txt') -eq 1 ]"
done
"$cli" render "$root/scenes/sphere_on_plane.json" --threads 0 >"$out/hint.out" 2>"$out/hint.err"
rc=$?
check "a bad option exits 2 with its message and the hint only" bash -c "[ $rc -eq 2 ] &&
  grep -q -- '--threads must be' '$out/hint.err' && grep -qx \"obscura: 'obscura help render' shows its options\" '$out/hint.err' &&
  [ \$(wc -l <'$out/hint.err') -eq 2 ]"
# Without -o every render writes out/: a second scene's render must not replace the first's.
mkdir -p "$out/cwd"
tiny=(--set /image/width=8 --set /image/height=6 --set /technique/params/samples=1 --quiet)
(cd "$out/cwd" && "$cli" render "$root/scenes/sphere_on_plane.json" "${tiny[@]}") >/dev/null 2>&1
check "render without -o writes out/" test -s "$out/cwd/out/summary.json"
(cd "$out/cwd" && "$cli" render "$root/scenes/sphere_on_plane.json" "${tiny[@]}") >/dev/null 2>&1
check "render without -o of the same scene replaces out/" test $? -eq 0
(cd "$out/cwd" && "$cli" render "$root/scenes/cornell_box.json" "${tiny[@]}") >"$out/guard.log" 2>&1
check "render without -o of another scene exits 2" test $? -eq 2
check "render without -o of another scene says whose outputs out/ holds" \
  grep -q "out/ holds the outputs of sphere_on_plane.json (out/summary.json), not of cornell_box.json: give -o DIR" "$out/guard.log"
check "out/ still holds the first scene's outputs" grep -q '"scene": "sphere_on_plane.json"' "$out/cwd/out/summary.json"
(cd "$out/cwd" && "$cli" render "$root/scenes/cornell_box.json" "${tiny[@]}" -o out) >/dev/null 2>&1
check "render -o out replaces them" grep -q '"scene": "cornell_box.json"' "$out/cwd/out/summary.json"
echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
