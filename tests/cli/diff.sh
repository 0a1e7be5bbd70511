#!/usr/bin/env bash
# `obscura diff` and `obscura metrics` end to end on small renders: a folder against itself gives
# the ideal value of every metric over the reference's covered pixels (alpha, by default); the figures a pair gives are the table's (keys, ranges), read
# from folders or files alike, with the properties their definitions imply (PSNR from RMSE, bias
# changes sign and RMSE and LDR-FLIP do not when the roles swap); RGB outputs get the RGB entries
# and HDR-FLIP; -o writes the error and FLIP maps; bad input exits 2 with a message naming it.
set -u
cli=$1 root=$2 out=$3
pass=0 fail=0
check() { # description, command...
  local d=$1; shift
  if "$@"; then pass=$((pass + 1)); echo "ok: $d"; else fail=$((fail + 1)); echo "FAIL: $d"; fi
}
rm -rf "$out" && mkdir -p "$out"
# --backend cpu: no Vulkan probe (its driver's process-lifetime allocations trouble LeakSanitizer).
small=(--quiet --backend cpu --set /image/width=40 --set /image/height=30)
"$cli" render "$root/scenes/cornell_box.json" -o "$out/rt" "${small[@]}" \
  --set /technique/params/samples=64 >/dev/null 2>&1 &&
  "$cli" render "$root/scenes/cornell_box.json" -o "$out/ss" --technique ssao "${small[@]}" \
    >/dev/null 2>&1 &&
  "$cli" render "$root/scenes/cornell_box.json" -o "$out/p1" --technique path_trace \
    "${small[@]}" >/dev/null 2>&1 &&
  "$cli" render "$root/scenes/cornell_box.json" -o "$out/p2" --technique path_trace \
    "${small[@]}" --set /technique/params/seed=2 >/dev/null 2>&1
check "the renders exit 0" test $? -eq 0

"$cli" metrics --json >"$out/table.json"
check "metrics --json lists the table" node -e "
  const t = JSON.parse(require('fs').readFileSync('$out/table.json'));
  const names = t.map((m) => m.name);
  process.exit(['rmse', 'psnr', 'ssim', 'flip', 'angle_deg', 'rel_mse'].every((n) => names.includes(n))
    && t.every((m) => ['lower', 'higher', 'zero', 'none'].includes(m.direction)) ? 0 : 1);"

"$cli" diff "$out/rt" "$out/rt" --json >"$out/same.json"
check "a folder against itself: exit 0" test $? -eq 0
check "a folder against itself: every metric ideal" node -e "
  const m = JSON.parse(require('fs').readFileSync('$out/same.json')).metrics;
  process.exit(m.rmse === 0 && m.bias === 0 && m.max_abs === 0 && m.psnr === 100 &&
    m.ssim === 1 && m.flip === 0 && m.pixels > 0 && m.pixels < 1200 ? 0 : 1);"

"$cli" diff "$out/ss" "$out/rt" --json -o "$out/maps" >"$out/ab.json"
check "ssao against rt_ao: exit 0" test $? -eq 0
"$cli" diff "$out/rt/ao.exr" "$out/ss/ao.exr" --channel ao --json >"$out/ba.json"
check "files and folders, both ways round" node -e "
  const fs = require('fs');
  const t = JSON.parse(fs.readFileSync('$out/table.json'));
  const ab = JSON.parse(fs.readFileSync('$out/ab.json')), ba = JSON.parse(fs.readFileSync('$out/ba.json'));
  const a = ab.metrics, b = ba.metrics, ok = [];
  const scalar = ['rmse', 'bias', 'max_abs', 'psnr', 'ssim', 'flip', 'ref_noise'];
  ok.push(Object.keys(a).filter((k) => !['pixels', 'at_reference_accuracy'].includes(k)).join() === scalar.join());
  for (const k of scalar) {
    const d = t.find((m) => m.name === k);
    ok.push(a[k] >= (d.min ?? -Infinity) && a[k] <= (d.max ?? Infinity));
  }
  ok.push(ab.channel === 'ao' && ab.mask === 'alpha');
  ok.push(a.rmse > 0.01 && a.flip > 0 && a.flip < 1 && a.ssim < 1);
  ok.push(Math.abs(a.psnr + 20 * Math.log10(a.rmse)) < 1e-9);
  ok.push(b.rmse === a.rmse && b.bias === -a.bias && b.max_abs === a.max_abs && b.flip === a.flip);
  console.log(ok.join(' '));
  process.exit(ok.every(Boolean) ? 0 : 1);"
for f in error.exr error.png flip.exr flip.png; do
  check "-o writes $f" test -s "$out/maps/$f"
done
"$cli" diff "$out/ss" "$out/rt" >"$out/ab.txt"
check "the text form prints every applicable metric" bash -c "
  for k in rmse bias max_abs psnr ssim flip; do grep -q \"^  \$k \" '$out/ab.txt' || exit 1; done"
"$cli" diff "$out/ss" "$out/rt" --mask none --json >"$out/nomask.json"
check "--mask none counts every pixel" node -e "
  const m = JSON.parse(require('fs').readFileSync('$out/nomask.json'));
  process.exit(m.mask === null && m.metrics.pixels === 1200 ? 0 : 1);"

"$cli" diff "$out/p2" "$out/p1" --json >"$out/rgb.json"
check "path_trace radiance: the RGB entries and HDR-FLIP" node -e "
  const m = JSON.parse(require('fs').readFileSync('$out/rgb.json'));
  const x = m.metrics;
  process.exit(m.channel === 'radiance' && x.rmse_r > 0 && x.rmse_g > 0 && x.rmse_b > 0 &&
    x.rel_mse > 0 && x.flip > 0 && x.flip < 1 && x.ssim === x.ssim_luminance ? 0 : 1);"

# A candidate whose output is named otherwise than the reference's (obscurance's `final` against
# path_trace's `radiance`): the reference's channels are read under the candidate's names.
"$cli" render "$root/scenes/cornell_box.json" -o "$out/ob" --technique obscurance "${small[@]}" \
  --set /technique/params/samples=4 >/dev/null 2>&1
"$cli" diff "$out/ob" "$out/p1" --json >"$out/named.json"
check "final against radiance: exit 0" test $? -eq 0
check "final against radiance: the RGB entries, the reference's noise" node -e "
  const m = JSON.parse(require('fs').readFileSync('$out/named.json'));
  const x = m.metrics;
  process.exit(m.channel === 'final' && x.rmse > 0 && x.rmse_r > 0 && x.ref_noise > 0 ? 0 : 1);"

"$cli" metrics --bogus >"$out/bad.log" 2>&1
check "metrics with an unknown option exits 2" test $? -eq 2
check "metrics says what it takes" grep -q -- "--json, --markdown, --openapi; got --bogus" "$out/bad.log"

# Bad input: exit 2, a message naming what is wrong, nothing written.
bad() { # description, expected message, args...
  local d=$1 msg=$2; shift 2
  "$cli" diff "$@" >"$out/bad.log" 2>&1
  local rc=$?
  check "$d exits 2" test $rc -eq 2
  check "$d says so" grep -q -- "$msg" "$out/bad.log"
}
bad "a missing file" "$out/nope: no such file" "$out/rt" "$out/nope"
bad "an unknown channel" '"nothing"' "$out/rt" "$out/ss" --channel nothing
bad "one argument" "needs a candidate and a reference" "$out/rt"
bad "an unknown option" "unknown option --frobnicate" "$out/rt" "$out/ss" --frobnicate
bad "a folder without summary" "not an output folder" "$out/rt" "$out/maps" -o "$out/none"
check "bad input writes no maps" test ! -e "$out/none"
"$cli" render "$root/scenes/cornell_box.json" -o "$out/big" --quiet --set /image/width=41 \
  --set /image/height=30 --set /technique/params/samples=4 >/dev/null 2>&1
bad "images of different sizes" "sizes differ" "$out/big" "$out/rt"

echo "diff: $pass passed, $fail failed"
[ "$fail" -eq 0 ]
