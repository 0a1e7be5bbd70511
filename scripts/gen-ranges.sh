#!/usr/bin/env bash
# Regenerates the guaranteed-range table of docs/accuracy.md from the technique registry
# (`obscura techniques --markdown`), between its ranges-table markers. Usage:
#   scripts/gen-ranges.sh [path/to/obscura]     (default: build/obscura)
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cli=${1:-$root/build/obscura}
doc=$root/docs/accuracy.md
table=$(mktemp)
trap 'rm -f "$table"' EXIT
"$cli" techniques --markdown >"$table"
awk -v table="$table" '
  /<!-- ranges-table:begin -->/ { print; while ((getline line < table) > 0) print line; skip = 1; next }
  /<!-- ranges-table:end -->/ { skip = 0 }
  !skip { print }
' "$doc" >"$doc.new"
mv "$doc.new" "$doc"
