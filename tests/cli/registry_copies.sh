#!/usr/bin/env bash
# The repository's copies of technique facts are the registry's: each must equal what
# `obscura techniques --schema | --openapi | --docs NAME` prints (regenerate them all with
# scripts/gen-registry.sh), and the metric table's copies what `obscura metrics --markdown |
# --openapi` prints; `drift` checks that a changed copy fails. Usage:
#   registry_copies.sh schema|openapi|docs|metrics|drift OBSCURA ROOT
set -u
what=$1 cli=$2 root=$3
fail=0
# compare LABEL WANT HAVE
compare() {
  if [ "$2" != "$3" ]; then
    echo "FAIL: $1 differs from the registry; run scripts/gen-registry.sh"
    diff <(echo "$3") <(echo "$2") | head -40
    fail=1
  else
    echo "ok: $1 matches the registry"
  fi
}
case $what in
  schema)
    want=$("$cli" techniques --schema) || { echo "FAIL: obscura techniques --schema"; exit 1; }
    have=$(awk '/^    "technique": [{]$/ { on = 1 } on && /^  [}]$/ { on = 0 } on' \
      "$root/schema/scene.schema.json")
    compare "schema/scene.schema.json (technique members of \$defs)" "$want" "$have" ;;
  openapi)
    want=$("$cli" techniques --openapi) || { echo "FAIL: obscura techniques --openapi"; exit 1; }
    have=$(sed -n '/^    # registry:begin/,/^    # registry:end/p' "$root/schema/openapi.yaml" |
      sed '1d;$d')
    compare "schema/openapi.yaml (registry block)" "$want" "$have" ;;
  docs)
    names=$("$cli" techniques | sed -n 's/^    "name": "\(.*\)",$/\1/p')
    [ -n "$names" ] || { echo "FAIL: no technique names from obscura techniques"; exit 1; }
    for name in $names; do
      doc=$root/docs/techniques/$name.md
      if ! grep -q '<!-- params-table:begin -->' "$doc" 2>/dev/null; then
        echo "FAIL: $doc has no params-table markers"
        fail=1
        continue
      fi
      want=$("$cli" techniques --docs "$name") || { echo "FAIL: --docs $name"; exit 1; }
      have=$(sed -n '/<!-- params-table:begin -->/,/<!-- params-table:end -->/p' "$doc" |
        sed '1d;$d')
      compare "docs/techniques/$name.md (parameter table)" "$want" "$have"
    done ;;
  metrics)
    want=$("$cli" metrics --markdown) || { echo "FAIL: obscura metrics --markdown"; exit 1; }
    have=$(sed -n '/<!-- metrics-table:begin -->/,/<!-- metrics-table:end -->/p' \
      "$root/docs/metrics.md" | sed '1d;$d')
    compare "docs/metrics.md (metric table)" "$want" "$have"
    want=$("$cli" metrics --openapi) || { echo "FAIL: obscura metrics --openapi"; exit 1; }
    have=$(sed -n '/^    # metrics:begin/,/^    # metrics:end/p' "$root/schema/openapi.yaml" |
      sed '1d;$d')
    compare "schema/openapi.yaml (Metrics schema)" "$want" "$have" ;;
  drift)
    # The comparisons themselves: one changed character in each copy must fail its check.
    tmp=$(mktemp -d)
    trap 'rm -rf "$tmp"' EXIT
    mkdir -p "$tmp/schema" "$tmp/docs"
    cp "$root/schema/scene.schema.json" "$root/schema/openapi.yaml" "$tmp/schema/"
    cp -r "$root/docs/techniques" "$root/docs/metrics.md" "$tmp/docs/"
    sed -i 's/"maximum": 65536/"maximum": 65537/' "$tmp/schema/scene.schema.json"
    sed -i '/^    # registry:begin/,/^    # registry:end/s/enum: \[\([a-z_]*\)/enum: [\12/' \
      "$tmp/schema/openapi.yaml"
    sed -i 's/^| `samples` | integer (uint32) | 64 |/| `samples` | integer (uint32) | 65 |/' \
      "$tmp/docs/techniques/rt_ao.md"
    sed -i 's/^| `psnr` | PSNR | dB | higher |/| `psnr` | PSNR | dB | lower |/' "$tmp/docs/metrics.md"
    for copy in schema openapi docs metrics; do
      if bash "$0" "$copy" "$cli" "$tmp" >/dev/null; then
        echo "FAIL: a changed $copy copy passed its check"
        fail=1
      else
        echo "ok: a changed $copy copy fails its check"
      fi
    done ;;
  *) echo "usage: registry_copies.sh schema|openapi|docs|metrics|drift OBSCURA ROOT"; exit 2 ;;
esac
exit $fail
