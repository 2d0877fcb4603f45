#!/usr/bin/env bash
# Runs a fixed list of commands with two isocube binaries and compares every file they write,
# byte for byte: the check that a rewrite changed no output.
#
#   tests/compare/run.sh OLD_BINARY NEW_BINARY WORKDIR
#
# Prints one line per command (same / DIFFERENT) and exits 1 if any output differs.
set -euo pipefail
old=$(realpath "$1")
new=$(realpath "$2")
work=$3
here="$(cd "$(dirname "$0")" && pwd)"
data="$(cd "$here/../data/volumes" && pwd)"
mkdir -p "$work/in" "$work/old" "$work/new"
python3 "$here/make_volumes.py" "$work/in"

# Each line: output file name, then the command's arguments ({in} = inputs, {data} = test data).
commands=(
  "tangle.ply|extract sample:tangle:64"
  "gyroid.ply|extract sample:gyroid:64"
  "schwarz.ply|extract sample:schwarz-p:64"
  "noise.ply|extract sample:noise:64"
  "sphere-classic.ply|extract sample:sphere:40 --topology classic"
  "tangle-local.ply|extract sample:tangle:64 --triangulate local"
  "tangle-optimal.ply|extract sample:tangle:64 --triangulate optimal"
  "tangle-flip.ply|extract sample:tangle:64 --flip"
  "tangle-ternary.ply|extract sample:tangle:64 --method ternary"
  "gyroid-ternary.ply|extract sample:gyroid:64 --method ternary --snap 0.5"
  "noise-ternary.ply|extract sample:noise:64 --method ternary --zero-threshold 0.05"
  "sphere-ternary-grid.ply|extract sample:sphere:40 --method ternary --snap-position grid --triangulate optimal"
  "schwarz-ternary-local.ply|extract sample:schwarz-p:64 --method ternary --triangulate local --topology classic"
  "tangle-relax.ply|extract sample:tangle:40 --relax 3"
  "sphere-best.ply|extract sample:sphere:40 --method ternary --snap 0.5 --triangulate optimal --relax 5"
  "tangle-ascii.ply|extract sample:tangle:40 --no-normals --ascii"
  "tangle.obj|extract sample:tangle:40"
  "tangle.stl|extract sample:tangle:40"
  "tangle.off|extract sample:tangle:40"
  "tangle.glb|extract sample:tangle:40"
  "tangle.vtp|extract sample:tangle:40"
  "tangle.msh|extract sample:tangle:40"
  "tangle-values.ply|extract sample:tangle:40 --values sample:sphere:40"
  "blobs-zyx.ply|extract {in}/blobs-zyx.npy --axes zyx"
  "blobs-xyz.ply|extract {in}/blobs-xyz.npy"
  "blobs-raw.ply|extract {in}/blobs.raw --dims 37,29,23 --type f32"
  "blobs-stream.ply|extract {in}/blobs-zyx.npy --axes zyx --stream"
  "blobs-ternary.ply|extract {in}/blobs-zyx.npy --axes zyx --method ternary --snap 0.4"
  "fortran.ply|extract {data}/fortran.npy --level 455.5"
  "nrrd.ply|extract {data}/oblique.nrrd --level 455.5"
  "nii.ply|extract {data}/flipped.nii --level 455.5"
  "niigz.ply|extract {data}/rotated.nii.gz --level 455.5"
  "mha.ply|extract {data}/rotated.mha --level 455.5"
  "mhd.ply|extract {data}/plain.mhd --level 455.5"
  "vti.ply|extract {data}/binary-zlib.vti --level 455.5"
  "tiff.ply|extract {data}/stack.tif --level 455.5"
  "dicom.ply|extract {data}/dicom --level 455.5"
  "labels.ply|extract {data}/labels.nii.gz --labels"
  "orebody.ply|contours sample:orebody"
  "orebody-plain.ply|contours sample:orebody --plain --cap flat"
  "boss.obj|subdivide sample:boss --levels 2"
  "box-hole.ply|subdivide sample:box-hole --levels 2 --holes sharp"
)

status=0
for entry in "${commands[@]}"; do
  name=${entry%%|*}
  args=${entry#*|}
  args=${args//\{in\}/$work/in}
  args=${args//\{data\}/$data}
  for side in old new; do
    bin=$old
    [ "$side" = new ] && bin=$new
    # shellcheck disable=SC2086
    "$bin" --quiet $args -o "$work/$side/$name"
  done
  # --labels writes NAME-LABEL.ply files; compare whatever each side wrote for this name.
  stem=${name%.*}
  same=yes
  for f in "$work/old/$stem"*; do
    cmp -s "$f" "$work/new/$(basename "$f")" || same=no
  done
  for f in "$work/new/$stem"*; do
    [ -e "$work/old/$(basename "$f")" ] || same=no
  done
  if [ $same = yes ]; then
    echo "same       $name: $args"
  else
    echo "DIFFERENT  $name: $args"
    status=1
  fi
done
exit $status
