#!/usr/bin/env bash
# Angle histograms of the built-in cages with faces with holes, three levels, both methods
# (the README's Subdivision section). Usage: docs/subdiv/histograms.sh [path/to/isocube]
set -euo pipefail
cd "$(dirname "$0")"
isocube=${1:-isocube}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
for cage in plate box-hole boss; do
  for holes in smooth sharp; do
    "$isocube" subdivide "sample:$cage" -o "$tmp/m.ply" --levels 3 --holes "$holes" --quiet
    "$isocube" quality "$tmp/m.ply" --histogram "$cage-$holes.svg" > /dev/null
    echo "$cage-$holes.svg"
  done
done
