#!/usr/bin/env bash
# docs/accuracy.md's guaranteed-range table is the registry's: it must equal what
# `obscura techniques --markdown` prints (regenerate with scripts/gen-ranges.sh).
set -u
cli=$1 root=$2
doc="$root/docs/accuracy.md"
want=$("$cli" techniques --markdown) || { echo "FAIL: obscura techniques --markdown failed"; exit 1; }
have=$(sed -n '/<!-- ranges-table:begin -->/,/<!-- ranges-table:end -->/p' "$doc" | sed '1d;$d')
if [ "$want" != "$have" ]; then
  echo "FAIL: the table in docs/accuracy.md differs from the registry; run scripts/gen-ranges.sh"
  diff <(echo "$have") <(echo "$want")
  exit 1
fi
echo "ok: docs/accuracy.md guaranteed-range table matches the registry"
