"""isocube tetmesh beside TetGen and fTetWild on the same surfaces, end to end, in one run.

    python bench/peers/tets.py ISOCUBE_BINARY [SAMPLE:N ...]

For each sample, isocube runs as a user runs it: `isocube tetmesh sample:NAME:N -o out.vtu`
(the field sampled, meshed, checked and written), timed from outside, with Marching Cubes and
with ternary extraction at snap 0.5; each peer gets that run's surface. TetGen (PyPI `tetgen`)
gets isocube's surface (`isocube extract`, read from the PLY) and must keep it: `-pYQ` (no
quality refinement) and `-pYqQ` (quality refinement, boundary kept; `Q` only silences it), and `-pYqQa` with isocube's mean element
volume as the bound (elements of the same size: the same work). Its time is the
`tetrahedralize` call alone, input already in memory. fTetWild (PyPI `wildmeshing`, if
installed) gets the same surface with its defaults (envelope 1e-3 of the diagonal, target edge
length 5 % of it): it does not keep the surface's triangles, it stays within the envelope. Its
time is `tetrahedralize` plus `get_tet_mesh` (which extracts the inside). Prints a Markdown table:
elements, dihedral angles, seconds.
"""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import meshio
import numpy as np


def dihedrals(points: np.ndarray, tets: np.ndarray) -> tuple[float, float]:
    p = points.astype(np.float64)[tets]
    lo, hi = np.inf, -np.inf
    faces = [(1, 2, 3), (0, 2, 3), (0, 1, 3), (0, 1, 2)]
    normals = []
    for k, (a, b, c) in enumerate(faces):
        n = np.cross(p[:, b] - p[:, a], p[:, c] - p[:, a])
        # Away from the opposite corner.
        side = np.einsum("ij,ij->i", n, p[:, k] - p[:, a])
        n[side > 0] *= -1
        normals.append(n / np.linalg.norm(n, axis=1, keepdims=True))
    for i in range(4):
        for j in range(i + 1, 4):
            cos = np.clip(np.einsum("ij,ij->i", normals[i], normals[j]), -1, 1)
            angle = 180.0 - np.degrees(np.arccos(cos))
            lo, hi = min(lo, angle.min()), max(hi, angle.max())
    return float(lo), float(hi)


def volumes(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    p = points.astype(np.float64)[tets]
    return np.abs(np.einsum("ij,ij->i", p[:, 1] - p[:, 0], np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 0]))) / 6.0


@contextlib.contextmanager
def quiet():
    """Silences a native library's own logging to the process's stdout and stderr."""
    sys.stdout.flush()
    saved = [os.dup(1), os.dup(2)]
    with open(os.devnull, "w") as null:
        os.dup2(null.fileno(), 1)
        os.dup2(null.fileno(), 2)
        try:
            yield
        finally:
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            for fd in saved:
                os.close(fd)


def main() -> None:
    binary = sys.argv[1]
    samples = sys.argv[2:] or ["sphere:64", "torus:64", "tangle:64"]
    import tetgen

    try:
        import wildmeshing
    except ImportError:
        wildmeshing = None

    # isocube's variants, each with the `extract` options giving the same surface.
    variants = [
        ("mc", [], []),
        ("ternary 0.5", ["--method", "ternary", "--snap", "0.5"], ["--method", "ternary", "--snap", "0.5", "--snap-position", "grid"]),
    ]
    print("| surface | tool | elements | min dihedral | max dihedral | seconds |")
    print("|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as work:
        for sample in samples:
            volume = f"sample:{sample}"
            for name, tet_options, surface_options in variants:
                out = Path(work) / "t.vtu"
                start = time.perf_counter()
                subprocess.run([binary, "-q", "tetmesh", volume, "-o", str(out), *tet_options], check=True)
                took = time.perf_counter() - start
                m = meshio.read(out)
                tets = m.cells_dict["tetra"]
                lo, hi = dihedrals(m.points, tets)
                print(f"| {sample} {name} | isocube tetmesh (end to end) | {len(tets)} | {lo:.2f} | {hi:.2f} | {took:.3f} |")
                ply = Path(work) / "s.ply"
                subprocess.run(
                    [binary, "-q", "extract", volume, "-o", str(ply), "--no-normals", *surface_options], check=True
                )
                surface = meshio.read(ply)
                faces = surface.cells_dict["triangle"]
                # The same element size as isocube's too: TetGen's volume bound at isocube's mean.
                volume_bound = float(volumes(m.points, tets).mean())
                for switches in ["pYQ", "pYqQ", f"pYqQa{volume_bound:.3e}"]:
                    gen = tetgen.TetGen(surface.points.astype(np.float64), faces.astype(np.int32))
                    start = time.perf_counter()
                    try:
                        with quiet():
                            result = gen.tetrahedralize(switches=switches)
                    except Exception as e:  # TetGen refuses some surfaces (self-intersections)
                        print(f"| {sample} {name} | TetGen -{switches} | failed: {str(e)[:60]} | | | |")
                        continue
                    took = time.perf_counter() - start
                    nodes, elems = result[0], result[1]
                    lo, hi = dihedrals(np.asarray(nodes), np.asarray(elems)[:, :4])
                    print(f"| {sample} {name} | TetGen -{switches} | {len(elems)} | {lo:.2f} | {hi:.2f} | {took:.3f} |")
                if wildmeshing is not None:
                    # fTetWild writes __tracked_surface.stl into the working folder: keep it in ours.
                    with quiet(), contextlib.chdir(work):
                        wild = wildmeshing.Tetrahedralizer()
                        wild.set_mesh(surface.points.astype(np.float64), faces.astype(np.int32))
                    start = time.perf_counter()
                    with quiet(), contextlib.chdir(work):
                        wild.tetrahedralize()
                        nodes, elems = wild.get_tet_mesh()[:2]
                    took = time.perf_counter() - start
                    lo, hi = dihedrals(np.asarray(nodes), np.asarray(elems)[:, :4])
                    print(f"| {sample} {name} | fTetWild (defaults) | {len(elems)} | {lo:.2f} | {hi:.2f} | {took:.3f} |")


if __name__ == "__main__":
    main()
