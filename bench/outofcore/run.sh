#!/usr/bin/env bash
# Extraction from a volume larger than the f32 grid the in-memory path would need: a CT-like
# N³ u16 volume (default 1024³, 2 GiB) written plane by plane, extracted slab by slab from the
# memory-mapped file into a binary PLY, with the peak resident memory of the run; then, on a
# smaller volume, the streamed output compared byte for byte with the in-memory path's.
#
#   bench/outofcore/run.sh [N] [WORKDIR]
set -euo pipefail
cd "$(dirname "$0")/../.."
n=${1:-1024}
work=${2:-target/outofcore}
small=256
mkdir -p "$work"
cargo build --release -q -p isocube-cli
cargo build --release -q -p isocube --example ct_volume
# Binaries where cargo puts them (CARGO_TARGET_DIR when set).
target=${CARGO_TARGET_DIR:-target}
bin=$target/release/isocube
for size in "$n" "$small"; do
  [ -f "$work/ct-$size.npy" ] || "$target/release/examples/ct_volume" "$work/ct-$size.npy" "$size"
done

peak() { # peak resident set size of a command, in MiB (from /usr/bin/time, or getrusage)
  if [ -x /usr/bin/time ]; then
    /usr/bin/time -f "%M" -o "$work/rss" "$@" >/dev/null
    echo $(( $(cat "$work/rss") / 1024 ))
  elif command -v python3 >/dev/null; then
    python3 -c 'import resource,subprocess,sys; subprocess.run(sys.argv[1:],check=True,stdout=subprocess.DEVNULL); print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss//1024)' "$@"
  else
    "$@" >/dev/null
    echo "(not measured: neither /usr/bin/time nor python3 here)"
  fi
}

start=$(date +%s.%N)
volume_mib=$(( $(stat -c %s "$work/ct-$n.npy") / 1048576 ))
rss=$(peak "$bin" -q extract "$work/ct-$n.npy" --axes zyx --level 1324 -o "$work/ct-$n.ply")
seconds=$(awk -v a="$start" -v b="$(date +%s.%N)" 'BEGIN { printf "%.2f", b - a }')
"$bin" info "$work/ct-$n.ply" --json > "$work/ct-$n.json"
mesh_mib=$(( $(stat -c %s "$work/ct-$n.ply") / 1048576 ))
echo "ct ${n}³ u16: volume ${volume_mib} MiB, mesh ${mesh_mib} MiB, peak resident memory ${rss} MiB, extraction and writing ${seconds} s"
python3 -c 'import json,sys; r=json.load(open(sys.argv[1])); print("  %d vertices, %d triangles, watertight %s, %d components" % (r["vertices"], r["triangles"], r["watertight"], r["components"]))' "$work/ct-$n.json" 2>/dev/null || true

"$bin" -q extract "$work/ct-$small.npy" --axes zyx --level 1324 -o "$work/memory-$small.ply"
"$bin" -q extract "$work/ct-$small.npy" --axes zyx --level 1324 -o "$work/streamed-$small.ply" --stream
if cmp -s "$work/memory-$small.ply" "$work/streamed-$small.ply"; then
  echo "ct ${small}³: streamed and in-memory outputs identical ($(stat -c %s "$work/memory-$small.ply") bytes)"
else
  echo "ct ${small}³: streamed and in-memory outputs DIFFER" >&2
  exit 1
fi
