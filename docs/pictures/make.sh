#!/usr/bin/env bash
# Draws the README's pictures with the isocube command (demo and render).
#
#   docs/pictures/make.sh [OUTDIR]     (default: this folder)
#
# The renderer is deterministic: CI draws them again into a temporary folder and compares bytes.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../.." && pwd)"
out="${1:-$here}"
mkdir -p "$out"
cargo build --quiet --release --manifest-path "$root/Cargo.toml" -p isocube-cli
isocube="${CARGO_TARGET_DIR:-$root/target}/release/isocube"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
# Four of the demo's pictures, smaller.
"$isocube" demo --out "$work/demo" --picture 320x240 --quiet > /dev/null
for name in tangle two-tori schwarz-p noise; do
  cp "$work/demo/$name-64.png" "$out/$name.png"
done
# Triangle quality on a coarse sphere: Marching Cubes against ternary snapping with optimal
# triangulation (the edges drawn).
"$isocube" extract sample:sphere:12 -o "$work/mc.ply" --quiet
"$isocube" extract sample:sphere:12 -o "$work/best.ply" --method ternary --snap 0.5 --triangulate optimal --quiet
"$isocube" render "$work/mc.ply" -o "$out/sphere-mc.png" --size 320x240 --wireframe --view 30,25 --quiet
"$isocube" render "$work/best.ply" -o "$out/sphere-ternary-optimal.png" --size 320x240 --wireframe --view 30,25 --quiet
