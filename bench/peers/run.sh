#!/usr/bin/env bash
# The peer benchmark: installs VTK, scikit-image, PyMCubes and trimesh into a virtual environment
# (from PyPI), writes the benchmark volumes, and prints two tables: the kernel (volumes already in
# memory, isocube's timing example) and end to end (the `isocube` command and each peer reading a
# file, extracting and writing a binary PLY, in every file format; e2e.py).
# Usage: bench/peers/run.sh [SIZE ...]   (default 256 512; volumes are cached in bench/peers/data)
# E2E=0 skips the end-to-end table; E2E_RUNS sets its repetitions (default 3).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$here/../.."
venv="${PEERS_VENV:-$here/.venv}"
if [ ! -x "$venv/bin/python" ]; then
  python3 -m venv "$venv"
  "$venv/bin/pip" install --quiet --upgrade pip
  "$venv/bin/pip" install --quiet numpy vtk scikit-image PyMCubes trimesh
fi
cargo build --release --quiet --manifest-path "$root/Cargo.toml" -p isocube-io --example peer_timing
cargo build --release --quiet --manifest-path "$root/Cargo.toml" -p isocube-cli
mapfile -t specs < <("$venv/bin/python" "$here/volumes.py" "$here/data" "$@")
"$venv/bin/python" "$here/peers.py" "${CARGO_TARGET_DIR:-$root/target}/release/examples/peer_timing" "${specs[@]}"
if [ "${E2E:-1}" != 0 ]; then
  echo
  echo "End to end (file → binary PLY with normals):"
  echo
  "$venv/bin/python" "$here/e2e.py" "${CARGO_TARGET_DIR:-$root/target}/release/isocube" "${specs[@]}"
fi
