#!/usr/bin/env bash
# Regenerates every copy of technique facts the repository keeps from the registry
# (`obscura techniques --schema | --openapi | --docs NAME | --markdown`): the technique members of
# $defs in schema/scene.schema.json (from "technique" to the end of $defs), the registry block of
# schema/openapi.yaml and the parameter table of each docs/techniques/<name>.md (between their
# markers), docs/accuracy.md's range table (scripts/gen-ranges.sh), and the metric table's copies
# (`obscura metrics --markdown | --openapi`): docs/metrics.md's table and schema/openapi.yaml's
# Metrics schema, between their markers. The tests cli.registry_* and cli.ranges_doc fail while
# a copy differs. Usage:
#   scripts/gen-registry.sh [path/to/obscura]     (default: build/obscura)
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cli=${1:-$root/build/obscura}
part=$(mktemp)
trap 'rm -f "$part"' EXIT

# splice FILE BEGIN-REGEX END-REGEX KEEP-BEGIN: replaces the lines between the two markers (the
# begin line itself too unless KEEP-BEGIN is 1) with $part.
splice() {
  awk -v part="$part" -v b="$2" -v e="$3" -v keep="$4" '
    !skip && $0 ~ b { if (keep) print; while ((getline line < part) > 0) print line; skip = 1; next }
    skip && $0 ~ e { skip = 0 }
    !skip { print }
  ' "$1" >"$1.new"
  mv "$1.new" "$1"
}

"$cli" techniques --schema >"$part"
splice "$root/schema/scene.schema.json" '^    "technique": [{]$' '^  [}]$' 0
"$cli" techniques --openapi >"$part"
splice "$root/schema/openapi.yaml" '^    # registry:begin' '^    # registry:end' 1
for name in $("$cli" techniques | sed -n 's/^    "name": "\(.*\)",$/\1/p'); do
  doc=$root/docs/techniques/$name.md
  [ -f "$doc" ] || { echo "gen-registry: $doc is missing (add the page with its params-table markers)" >&2; exit 1; }
  "$cli" techniques --docs "$name" >"$part"
  splice "$doc" '<!-- params-table:begin -->' '<!-- params-table:end -->' 1
done
"$cli" metrics --markdown >"$part"
splice "$root/docs/metrics.md" '<!-- metrics-table:begin -->' '<!-- metrics-table:end -->' 1
"$cli" metrics --openapi >"$part"
splice "$root/schema/openapi.yaml" '^    # metrics:begin' '^    # metrics:end' 1
"$root/scripts/gen-ranges.sh" "$cli"
