#!/usr/bin/env bash
# Writes meshes in every format isocube writes and loads each back with an independent reader
# (trimesh, meshio, VTK, gmsh), checking counts, positions, normals and vertex values; a finite
# element solver (scikit-fem) uses the volume meshes; and pydicom's own DICOM files (every
# transfer syntax isocube reads, RT Dose) and nibabel's NIfTI and MINC files mesh as the arrays
# pydicom and nibabel decode.
#
#   tests/interop/run.sh [WORKDIR]
#
# The readers go into a virtual environment (WORKDIR/venv, or $ISOCUBE_PY_VENV if set) from
# PyPI, pinned in requirements.txt.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../.." && pwd)"
work="${1:-$(mktemp -d)}"
mkdir -p "$work"
venv="${ISOCUBE_PY_VENV:-$work/venv}"
if [ ! -x "$venv/bin/python" ]; then
  python3 -m venv "$venv"
  "$venv/bin/pip" install --quiet --disable-pip-version-check -r "$here/requirements.txt"
fi
# With MINC-2 (the opt-in minc2 feature: the HDF5 library, Debian libhdf5-dev), for check_minc.py.
cargo build --quiet --release --manifest-path "$root/Cargo.toml" -p isocube-cli --features minc2
isocube="${CARGO_TARGET_DIR:-$root/target}/release/isocube"

# Two surfaces: a closed torus with another field's values on it, an open gyroid patch.
cases=("torus sample:torus:40 sample:sphere:40" "gyroid sample:gyroid:36 sample:tangle:36")
manifest="$work/manifest.txt"
: > "$manifest"
for case in "${cases[@]}"; do
  read -r name volume values <<< "$case"
  for ext in ply obj stl off glb vtp vtk msh; do
    out="$work/$name.$ext"
    extra=()
    case "$ext" in ply|glb|vtp|vtk|msh) extra=(--values "$values") ;; esac
    summary=$("$isocube" extract "$volume" -o "$out" "${extra[@]}" 2>&1 | tail -1)
    # "<file>: V vertices, T triangles, ..."
    v=$(sed -E 's/.*: ([0-9]+) vertices, ([0-9]+) triangles.*/\1/' <<< "$summary")
    t=$(sed -E 's/.*: ([0-9]+) vertices, ([0-9]+) triangles.*/\2/' <<< "$summary")
    echo "$out $v $t ${#extra[@]}" >> "$manifest"
  done
done
"$venv/bin/python" "$here/check_meshes.py" "$manifest"

# Tetrahedral meshes: a closed region (sphere), one reaching the grid's faces (gyroid's
# other side), a ternary one and the body between contour sections (flat ends: walls), in every
# tetrahedral format (and .msh in Gmsh's binary form too).
tets="$work/tets.txt"
: > "$tets"
for case in "sphere sample:sphere:32" "gyroid sample:gyroid:24 --flip" \
  "torus-ternary sample:torus:24 --method ternary --snap 0.5" \
  "orebody sample:orebody --grid 40x40 --cap flat --method ternary"; do
  read -r name volume flip <<< "$case"
  for ext in msh binary.msh vtu mesh inp; do
    out="$work/tet-$name.$ext"
    binary=()
    [[ $ext == binary.msh ]] && binary=(--binary)
    summary=$("$isocube" tetmesh "$volume" $flip "${binary[@]}" -o "$out" 2>&1)
    summary=${summary%%$'\n'*}
    # "<file>: T tetrahedra, V vertices (...); boundary S surface + W wall triangles"
    numbers=$(sed -E 's/.*: ([0-9]+) tetrahedra, ([0-9]+) vertices.*boundary ([0-9]+) surface \+ ([0-9]+) wall.*/\1 \2 \3 \4/' <<< "$summary")
    echo "$out $numbers" >> "$tets"
  done
done
"$venv/bin/python" "$here/check_tets.py" "$tets"

# Multi-material volume meshes (`tetmesh --labels`): three labels in a background, and packed
# spheres with the pores between them as a second material; regions, boundaries and interfaces
# counted and checked face to face by meshio and gmsh.
"$venv/bin/python" "$here/make_labels.py" "$work/labels"
labelled="$work/labelled.txt"
: > "$labelled"
for name in three packed; do
  for ext in msh vtu mesh inp; do
    out="$work/labels-$name.$ext"
    summary=$("$isocube" tetmesh "$work/labels/$name.npy" --labels -o "$out" 2>&1)
    first=${summary%%$'\n'*}
    # "<file>: T tetrahedra, V vertices (...); boundary S surface + W wall triangles"
    numbers=$(sed -E 's/.*: [0-9]+ tetrahedra, ([0-9]+) vertices.*boundary ([0-9]+) surface.*/\1 \2/' <<< "$first")
    # "regions: label 1: N, label 2: M; I interface triangles"
    regions=$(grep '^regions:' <<< "$summary")
    interfaces=$(sed -E 's/.*; ([0-9]+) interface triangles/\1/' <<< "$regions")
    counts=$(sed -E 's/^regions: //; s/;.*//; s/label ([-0-9]+): ([0-9]+)/\1:\2/g; s/,//g' <<< "$regions")
    echo "$out $numbers $interfaces $counts" >> "$labelled"
  done
done
"$venv/bin/python" "$here/check_labels.py" "$labelled"

# A real consumer of the volume meshes: scikit-fem solves Poisson problems with known solutions
# on the ball and the torus with P1 and P2 elements; the L2 and largest nodal errors must fall
# like h² (README, Volume meshes) on meshes refined everywhere (`--uniform`; the default graded
# interior keeps cubes up to 16 cells, whose interpolation error dominates P1's at these sizes):
# ternary snapped onto crossings, snap 0.5, and Marching Cubes.
"$venv/bin/python" "$here/fem_poisson.py" "$isocube" "$work/fem" -- --uniform
"$venv/bin/python" "$here/fem_poisson.py" "$isocube" "$work/fem-torus" torus -- --uniform
"$venv/bin/python" "$here/fem_poisson.py" "$isocube" "$work/fem-ternary" -- --snap 0.5 --uniform
"$venv/bin/python" "$here/fem_poisson.py" "$isocube" "$work/fem-mc" -- --method mc --uniform

# DICOM files as pydicom ships them (CT, MR in seven encodings, NM JPEG 2000, RT Dose plain and
# RLE): meshed from the file, and from the array pydicom decodes placed in patient coordinates.
"$venv/bin/python" "$here/check_dicom.py" "$isocube" "$work/dicom"

# NIfTI-2 and 4-d NIfTI as nibabel ships them: every frame (--frame) meshed from the file and
# from the frame nibabel decodes, placed by the affine nibabel reads.
"$venv/bin/python" "$here/check_nifti.py" "$isocube" "$work/nifti"

# MINC-1 and MINC-2 as nibabel ships them: every file and frame meshed from the file and from
# the array nibabel decodes, placed by nibabel's affine.
"$venv/bin/python" "$here/check_minc.py" "$isocube" "$work/minc"
