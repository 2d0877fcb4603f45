"""isocube tetmesh beside TetGen, fTetWild and CGAL's Mesh_3 on the same fields, in one run.

    python bench/peers/tets.py ISOCUBE_BINARY [SAMPLE:N[:SEED] ...]

For each sample (by default sphere:48, torus:48 and packed-spheres:48:1), isocube runs as a
user runs it: `isocube tetmesh sample:... -o out.vtu` (the field sampled, meshed, checked and
written), timed from outside, with `--uniform` (every inside cell six tetrahedra), with
`--method mc --uniform` and with the default flags (graded: cubes up to 16 cells on a side).
The peers get the same field in the form each takes:

- TetGen (PyPI `tetgen`) gets the meshes' boundary (`isocube extract --method
  ternary`'s surface, closed by the box's faces where the region meets them): `-pYqQ` keeps it as it is (quality refinement inside only), and
  `-pqQa` with the uniform mesh's mean element volume as the bound (elements of the same size) may split
  it, and `-pqQ` (no size bound: TetGen grades as its quality rule allows). Its time is the `tetrahedralize` call alone, input already in memory.
- fTetWild (PyPI `wildmeshing`) gets the same surface with its defaults (envelope 1e-3 of the
  diagonal, target edge 5 % of it): it stays within the envelope, it does not keep the
  triangles. Its time is `tetrahedralize` plus `get_tet_mesh`.
- CGAL's Mesh_3 (PyPI `pygalmesh`) meshes the exact implicit function (its own `Ball` and
  `Torus`, the samples' radii) with the criteria CGAL's users start from (facet angle 25°,
  radius–edge 2), the surface and element size the grid spacing and the facet distance
  isocube's own largest boundary distance (the same accuracy asked for); then its optimisers'
  defaults (perturb, exude); once with cells bounded by the grid spacing and once by 16 of them
  (graded, beside isocube's default). Packed spheres have no built-in domain: CGAL is not run there.
  Its time is the `generate_mesh` call.

Each mesh is measured the same way: elements, smallest and largest dihedral angle, and the
distance of its boundary from the level set (the boundary's triangles written as a PLY and
measured by `isocube quality --field sample:...`, the sample's exact function, over vertices
and points inside the triangles, in grid spacings). A peer that fails is counted as refused.
Prints a Markdown table.
"""

from __future__ import annotations

import contextlib
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import meshio
import numpy as np

SPHERE_RADIUS = 0.8
# The graded rows' largest element, in grid spacings.
GRADED = 16
TORUS = (0.6, 0.25)


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
    return (
        np.abs(
            np.einsum(
                "ij,ij->i",
                p[:, 1] - p[:, 0],
                np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 0]),
            )
        )
        / 6.0
    )


def boundary(tets: np.ndarray) -> np.ndarray:
    """The faces of the tetrahedra that belong to one of them only."""
    t = tets.astype(np.int64)
    faces = np.concatenate(
        [t[:, [1, 2, 3]], t[:, [0, 3, 2]], t[:, [0, 1, 3]], t[:, [0, 2, 1]]]
    )
    _, first, counts = np.unique(
        np.sort(faces, axis=1), axis=0, return_index=True, return_counts=True
    )
    return faces[first[counts == 1]]


def distance(
    binary: str,
    field: str,
    box: tuple[float, float],
    points: np.ndarray,
    tets: np.ndarray,
    work: Path,
) -> tuple[float, float]:
    """The largest distance of the mesh's boundary from the field's level set, in grid spacings:
    the boundary but its parts on the box's faces (where the region meets the box)."""
    points = np.asarray(points, dtype=np.float64)
    faces = boundary(np.asarray(tets))
    corners = points[faces]
    scale = box[1] - box[0]
    on_wall = np.zeros(len(faces), dtype=bool)
    for side in box:
        on_wall |= (np.abs(corners - side) < 1e-6 * scale).all(axis=1).any(axis=1)
    faces = faces[~on_wall]
    used, compact = np.unique(faces, return_inverse=True)
    path = work / "boundary.ply"
    mesh = meshio.Mesh(
        points[used], [("triangle", compact.reshape(-1, 3).astype(np.int32))]
    )
    meshio.write(path, mesh, binary=True)
    done = subprocess.run(
        [binary, "-q", "quality", str(path), "--field", field, "--json"],
        check=True,
        capture_output=True,
        text=True,
    )
    measured = json.loads(done.stdout)["distance"]
    return float(measured["max"]), float(measured["mean"])


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


def isolated(work: Path, job) -> tuple[np.ndarray, np.ndarray, float] | str:
    """Runs `job` (returning points, tetrahedra and seconds) in a forked child, so that a peer
    that crashes (TetGen segfaults on some inputs) counts as refused instead of ending the run."""
    out = work / "peer.npz"
    out.unlink(missing_ok=True)
    pid = os.fork()
    if pid == 0:
        code = 1
        try:
            with quiet():
                points, tets, took = job()
            np.savez(
                out,
                points=np.asarray(points, dtype=np.float64),
                tets=np.asarray(tets)[:, :4],
                took=took,
            )
            code = 0
        except BaseException as e:  # reported by the parent as the reason
            (work / "peer.err").write_text(str(e)[:80])
        finally:
            os._exit(code)
    _, status = os.waitpid(pid, 0)
    if os.WIFSIGNALED(status):
        return f"crashed (signal {os.WTERMSIG(status)})"
    if os.WEXITSTATUS(status) != 0:
        err = work / "peer.err"
        return f"failed: {err.read_text() if err.exists() else ''}"
    data = np.load(out)
    return data["points"], data["tets"], float(data["took"])


def row(
    sample: str, tool: str, points, tets, took: float, dist: tuple[float, float]
) -> None:
    lo, hi = dihedrals(np.asarray(points), np.asarray(tets))
    print(
        f"| {sample} | {tool} | {len(tets)} | {lo:.2f}° | {hi:.2f}° | {dist[0]:.4f} / {dist[1]:.4f} | {took:.3f} |"
    )


def main() -> None:
    binary = sys.argv[1]
    samples = sys.argv[2:] or ["sphere:48", "torus:48", "packed-spheres:48:1"]
    import tetgen

    try:
        import wildmeshing
    except ImportError:
        wildmeshing = None
    try:
        import pygalmesh
    except ImportError:
        pygalmesh = None

    print(
        "| sample | tool | elements | min dihedral | max dihedral | boundary distance, max / mean (h) | seconds |"
    )
    print("|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        for sample in samples:
            field = f"sample:{sample}"
            name, n = sample.split(":")[:2]
            box = (0.0, 1.0) if name == "packed-spheres" else (-1.0, 1.0)
            h = (box[1] - box[0]) / (int(n) - 1)
            reference = None
            for label, options in [
                ("isocube tetmesh --uniform", ["--uniform"]),
                (
                    "isocube tetmesh --method mc --uniform",
                    ["--method", "mc", "--uniform"],
                ),
                (f"isocube tetmesh (defaults: graded to {GRADED}c)", []),
            ]:
                out = work / "t.vtu"
                start = time.perf_counter()
                done = subprocess.run(
                    [binary, "-q", "tetmesh", field, "-o", str(out), *options],
                    capture_output=True,
                )
                took = time.perf_counter() - start
                if done.returncode != 0:
                    print(
                        f"| {sample} | {label} | refused: {done.stderr.decode().strip()[:80]} | | | | |"
                    )
                    continue
                m = meshio.read(out)
                tets = m.cells_dict["tetra"]
                dist = distance(binary, field, box, m.points, tets, work)
                row(sample, label, m.points, tets, took, dist)
                if reference is None:
                    reference = (
                        float(volumes(m.points, tets).mean()),
                        dist[0],
                        m.points,
                        tets,
                    )
            if reference is None:
                continue
            mean_volume, isocube_distance, points, tets = reference
            # The peers that take a surface get the default mesh's whole boundary: `extract`'s
            # surface and, where the region meets the box, the box's faces (closed).
            faces = boundary(tets)
            used, compact = np.unique(faces, return_inverse=True)
            surface = meshio.Mesh(
                np.asarray(points, dtype=np.float64)[used],
                [("triangle", compact.reshape(-1, 3))],
            )
            pts, tri = (
                surface.points.astype(np.float64),
                surface.cells_dict["triangle"].astype(np.int32),
            )

            def tetgen_job(switches: str):
                gen = tetgen.TetGen(pts, tri)
                start = time.perf_counter()
                result = gen.tetrahedralize(switches=switches)
                return result[0], result[1], time.perf_counter() - start

            def wild_job():
                # fTetWild writes __tracked_surface.stl into the working folder: keep it in ours.
                with contextlib.chdir(work):
                    wild = wildmeshing.Tetrahedralizer()
                    wild.set_mesh(pts, tri)
                    start = time.perf_counter()
                    wild.tetrahedralize()
                    nodes, elems = wild.get_tet_mesh()[:2]
                return nodes, elems, time.perf_counter() - start

            def cgal_job(cell: float):
                domain = (
                    pygalmesh.Ball([0.0, 0.0, 0.0], SPHERE_RADIUS)
                    if name == "sphere"
                    else pygalmesh.Torus(*TORUS)
                )
                start = time.perf_counter()
                m = pygalmesh.generate_mesh(
                    domain,
                    min_facet_angle=25.0,
                    max_radius_surface_delaunay_ball=h,
                    max_facet_distance=max(isocube_distance, 1e-3) * h,
                    max_circumradius_edge_ratio=2.0,
                    max_cell_circumradius=cell * h,
                    verbose=False,
                    seed=1,
                )
                return m.points, m.cells_dict["tetra"], time.perf_counter() - start

            jobs = [
                (f"TetGen -{sw}", lambda sw=sw: tetgen_job(sw))
                for sw in ["pYqQ", f"pqQa{mean_volume:.3e}", "pqQ"]
            ]
            if wildmeshing is not None:
                jobs.append(("fTetWild (defaults)", wild_job))
            if pygalmesh is not None and name in ("sphere", "torus"):
                jobs.append(("CGAL Mesh_3 (pygalmesh)", lambda: cgal_job(1.0)))
                # Graded: elements up to the graded mesh's largest cube inside.
                jobs.append(
                    (
                        f"CGAL Mesh_3, cells up to {GRADED}h",
                        lambda: cgal_job(float(GRADED)),
                    )
                )
            for tool, job in jobs:
                result = isolated(work, job)
                if isinstance(result, str):
                    print(f"| {sample} | {tool} | refused: {result} | | | | |")
                    continue
                nodes, elems, took = result
                row(
                    sample,
                    tool,
                    nodes,
                    elems,
                    took,
                    distance(binary, field, box, nodes, elems, work),
                )


if __name__ == "__main__":
    main()
