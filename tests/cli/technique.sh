#!/usr/bin/env bash
# obscura render --technique: the scene's params stay for its own technique; another technique's
# lengths are fitted to the scene's size with a note; --set wins over a derived value; a length far
# off the scene's size warns.
set -u
cli=$1 root=$2 out=$3
pass=0 fail=0
check() { # description, command...
  local d=$1; shift
  if "$@"; then pass=$((pass + 1)); echo "ok: $d"; else fail=$((fail + 1)); echo "FAIL: $d"; fi
}
field() { # summary.json, expression over s
  node -e "const s = JSON.parse(require('fs').readFileSync('$1')); console.log($2)"
}
rm -rf "$out" && mkdir -p "$out"
small=(--set /image/width=32 --set /image/height=32 --quiet)
scene=$root/scenes/cornell_box.json

"$cli" render "$scene" -o "$out/own" "${small[@]}" --set /technique/params/samples=8 2>"$out/own.log"
check "own scene renders" test $? -eq 0
"$cli" render "$scene" -o "$out/same" --technique rt_ao "${small[@]}" \
  --set /technique/params/samples=8 2>"$out/same.log"
check "--technique rt_ao renders" test $? -eq 0
check "--technique rt_ao keeps max_distance: the same AO mean" \
  test "$(field "$out/own/summary.json" s.ao.mean)" = "$(field "$out/same/summary.json" s.ao.mean)"
check "--technique rt_ao notes nothing" test ! -s "$out/same.log"

"$cli" render "$scene" -o "$out/hbao" --technique hbao --backend cpu "${small[@]}" 2>"$out/hbao.log"
check "--technique hbao renders" test $? -eq 0
check "--technique hbao notes the derived radius" \
  grep -q "note: hbao radius = [0-9.]* derived from the scene's size" "$out/hbao.log"
mean=$(field "$out/hbao/summary.json" s.ao.mean)
check "hbao with a derived radius is neither white nor black ($mean)" \
  node -e "process.exit($mean > 0.2 && $mean < 0.95 ? 0 : 1)"

"$cli" render "$scene" -o "$out/tiny" --technique hbao --backend cpu "${small[@]}" \
  --set /technique/params/radius=0.5 2>"$out/tiny.log"
check "--set radius renders" test $? -eq 0
check "--set radius is not noted as derived" bash -c "! grep -q 'note:' '$out/tiny.log'"
check "a radius of 0.5 on a 960-unit scene warns" \
  grep -q "warning: radius = 0.5 is .* less than 0.001 scene sizes" "$out/tiny.log"

echo "$pass passed, $fail failed"
test "$fail" -eq 0
