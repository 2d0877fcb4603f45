#!/usr/bin/env bash
# A 256 × 256 × 120 CT-like DICOM series in five transfer syntaxes (uncompressed, RLE, JPEG-LS,
# JPEG 2000, 12-bit lossy JPEG; written by pydicom and its encoders), meshed end to end — read, decode, mesh,
# write a binary PLY — by `isocube extract` and by pydicom (with its plugins) + scikit-image's
# marching_cubes, best of REPEATS runs each.
#
#   bench/dicom/run.sh [WORKDIR] [REPEATS]
#
# Needs a Python with numpy, pydicom, pylibjpeg, pylibjpeg-libjpeg, pylibjpeg-openjpeg, pyjpegls,
# imagecodecs (the 12-bit JPEG encoder) and scikit-image
# ($PYTHON, default python3).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../.." && pwd)"
work="${1:-$(mktemp -d)}"
repeats="${2:-3}"
python="${PYTHON:-python3}"
mkdir -p "$work"
cargo build --quiet --release --manifest-path "$root/Cargo.toml" -p isocube-cli
isocube="${CARGO_TARGET_DIR:-$root/target}/release/isocube"
(cd "$work" && "$python" "$here/make_series.py")
for syntax in raw rle jls j2k j12; do
  best=""
  for _ in $(seq "$repeats"); do
    start=$(date +%s.%N)
    "$isocube" extract "$work/$syntax" --level 200 -o "$work/$syntax.ply" --quiet
    t=$(echo "$(date +%s.%N) - $start" | bc)
    if [ -z "$best" ] || (( $(echo "$t < $best" | bc) )); then best=$t; fi
  done
  printf 'isocube         %-4s %.2f s (best of %s)\n' "$syntax" "$best" "$repeats"
  for _ in $(seq "$repeats"); do
    "$python" "$here/pydicom_skimage.py" "$work/$syntax" 200 "$work/peer-$syntax.ply"
  done
done
