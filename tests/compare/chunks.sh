#!/usr/bin/env bash
# `isocube extract --chunk` writes the same file as without it, byte for byte: every sample and
# option below, with boxes of 7×5×3, 64×64×64 and 1×200×13 cells.
#
#   tests/compare/chunks.sh BINARY WORKDIR
set -euo pipefail
bin=$(realpath "$1")
work=$2
here="$(cd "$(dirname "$0")" && pwd)"
mkdir -p "$work/in"
python3 "$here/make_volumes.py" "$work/in"

inputs=(sample:tangle:64 sample:gyroid:64 sample:schwarz-p:64 sample:noise:64)
variants=(
  ""
  "--method ternary"
  "--method ternary --snap 0.5"
  "--method ternary --zero-threshold 0.02 --snap 0.2"
  "--method ternary --snap-position grid --triangulate optimal"
  "--triangulate local"
  "--triangulate optimal"
  "--topology classic"
  "--flip"
)
status=0
count=0
check() {
  local name=$1
  shift
  rm -rf "$work/whole" "$work/chunk"
  mkdir -p "$work/whole" "$work/chunk"
  "$bin" --quiet extract "$@" -o "$work/whole/$name.ply"
  for chunk in 7,5,3 64,64,64 1,200,13; do
    rm -f "$work/chunk/"*
    "$bin" --quiet extract "$@" --chunk "$chunk" -o "$work/chunk/$name.ply"
    count=$((count + 1))
    # --labels writes one file per label: every file must be there and the same.
    if ! diff -q "$work/whole" "$work/chunk" >/dev/null; then
      echo "DIFFERENT with --chunk $chunk: $*"
      status=1
    fi
  done
}
for input in "${inputs[@]}"; do
  for variant in "${variants[@]}"; do
    # shellcheck disable=SC2086
    check run "$input" $variant
  done
done
# Relaxation runs on the joined mesh (the noise sample's exact field is slow to relax: tangle only).
check relax sample:tangle:64 --relax 2
check zyx "$work/in/blobs-zyx.npy" --axes zyx
check zyx-ternary "$work/in/blobs-zyx.npy" --axes zyx --method ternary --snap 0.5
check labels "$here/../data/volumes/labels.nii.gz" --labels
# Integers exactly at the level, stored as u8 (shifted by 2), i16, i32, f32 (also with -0.0 for
# its zeros) and f64 in C order:
# every type, with and without --chunk, writes the f32 file's bytes (mapped f32 read in place,
# the others converted slab by slab or read whole for boxes and ternary snapping).
types=0
for level in -1 0 1; do
  for variant in "" "--method ternary" "--method ternary --snap 0.5 --triangulate optimal" "--relax 1"; do
    rm -rf "$work/types" && mkdir -p "$work/types"
    for type in u8 i16 i32 f32 f64 f32neg; do
      at=$level
      [ $type = u8 ] && at=$((level + 2))
      # shellcheck disable=SC2086
      check "tied-$type" "$work/in/tied-$type.npy" --level "$at" $variant
      cp "$work/whole/tied-$type.ply" "$work/types/$type.ply"
    done
    for type in u8 i16 i32 f64 f32neg; do
      types=$((types + 1))
      if ! cmp -s "$work/types/f32.ply" "$work/types/$type.ply"; then
        echo "DIFFERENT from f32: $type at level $level $variant"
        status=1
      fi
    done
  done
done
echo "--chunk: $count runs, $types type comparisons, $([ $status = 0 ] && echo "all identical" || echo "some differ")"
exit $status
