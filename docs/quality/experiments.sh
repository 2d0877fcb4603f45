#!/usr/bin/env bash
# Regenerates the triangle-quality tables and angle histograms in docs/quality (see the README).
# Usage: docs/quality/experiments.sh [path/to/isocube]
set -euo pipefail
cd "$(dirname "$0")"
isocube=${1:-isocube}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
row() { # sample label extract-options...
  local sample=$1 label=$2; shift 2
  "$isocube" extract "sample:$sample" "$@" -o "$tmp/m.ply" --quiet
  local name; name=$(echo "$sample-$label" | tr ':, =' '----')
  "$isocube" quality "$tmp/m.ply" --field "sample:$sample" --histogram "$name.svg" --json > "$tmp/q.json"
  python3 - "$sample" "$label" "$name.svg" "$tmp/q.json" <<'PY'
import json, sys
sample, label, svg, path = sys.argv[1:]
q = json.load(open(path))
print(f"| {sample} | {label} | {q['triangles']} | {q['min_angle']['min']:.2f}° | {q['max_angle']['max']:.2f}° "
      f"| {100*q['below_20']:.1f} % | {q['distance']['max']:.4f} | [svg]({svg}) |")
PY
}
echo "| sample | triangulation | triangles | min angle | max angle | min < 20° | max distance | histogram |"
echo "|---|---|---:|---:|---:|---:|---:|---|"
for sample in sphere:10 hyperboloid:40 tubes:40; do
  for t in fan local optimal; do
    row "$sample" "$t" --triangulate "$t"
  done
  row "$sample" "ternary+optimal+relax" --method ternary --snap 0.5 --triangulate optimal --relax 10
done
