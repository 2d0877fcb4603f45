#!/usr/bin/env bash
# The peer benchmark: installs VTK, scikit-image and PyMCubes into a virtual environment (from
# PyPI), writes the benchmark volumes, builds isocube's timing example and prints the table.
# Usage: bench/peers/run.sh [SIZE ...]   (default 256 512; volumes are cached in bench/peers/data)
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$here/../.."
venv="${PEERS_VENV:-$here/.venv}"
if [ ! -x "$venv/bin/python" ]; then
  python3 -m venv "$venv"
  "$venv/bin/pip" install --quiet --upgrade pip
  "$venv/bin/pip" install --quiet numpy vtk scikit-image PyMCubes
fi
cargo build --release --quiet --manifest-path "$root/Cargo.toml" -p isocube-io --example peer_timing
mapfile -t specs < <("$venv/bin/python" "$here/volumes.py" "$here/data" "$@")
"$venv/bin/python" "$here/peers.py" "${CARGO_TARGET_DIR:-$root/target}/release/examples/peer_timing" "${specs[@]}"
