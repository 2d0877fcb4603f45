"""A real consumer of isocube's volume meshes: scikit-fem solves a Poisson problem on them.

    python fem_poisson.py ISOCUBE WORKDIR [N ...] [-- TETMESH OPTIONS]

For each N (default 16 24 32 48), `isocube tetmesh sample:sphere:N` meshes the ball of radius
0.8 (the sample's sphere) as Gmsh MSH; meshio reads it back and the coordinates are scaled to
the unit ball. scikit-fem then solves -Δu = 1 with u = 0 on the boundary, with P1 and with P2
elements; the exact solution on the ball is u = (1 - r²)/6. The L2 error against it is printed
as a Markdown table with the observed convergence rates, and the fitted rate must be at least
1.8 for both elements (the boundary is piecewise flat, so P2 cannot beat h² either).

scikit-fem integrates with |det J| and would not notice an inverted element, so the signed
volume of every tetrahedron is checked here first.
"""

from __future__ import annotations

import math
import subprocess
import sys
import time
from pathlib import Path

import meshio
import numpy as np
import scipy.sparse.linalg as spla
from skfem import Basis, ElementTetP1, ElementTetP2, Functional, MeshTet, asm
from skfem.models.poisson import laplace, unit_load

RADIUS = 0.8  # the sphere sample's radius, in its [-1, 1] box
MIN_RATE = 1.8


def load(path: Path) -> MeshTet:
    # ".msh" is Ansys's extension too: name the format, or meshio tries that reader first.
    mesh = meshio.read(path, file_format="gmsh")
    tets = mesh.cells_dict["tetra"]
    points = mesh.points / RADIUS
    a, b, c, d = (points[tets[:, k]] for k in range(4))
    signed = np.einsum("ij,ij->i", b - a, np.cross(c - a, d - a)) / 6.0
    if not (signed > 0).all():
        raise SystemExit(f"{path}: {(signed <= 0).sum()} tetrahedra are not positive")
    used = np.zeros(len(points), dtype=bool)
    used[tets.ravel()] = True
    if not used.all():
        raise SystemExit(f"{path}: {(~used).sum()} vertices belong to no tetrahedron")
    return MeshTet(points.T.copy(), tets.T.copy())


@Functional
def squared_error(w):
    x = w.x
    exact = (1.0 - (x[0] ** 2 + x[1] ** 2 + x[2] ** 2)) / 6.0
    return (w["uh"] - exact) ** 2


def solve(mesh: MeshTet, element) -> tuple[float, int]:
    basis = Basis(mesh, element, intorder=4)
    stiffness = asm(laplace, basis)
    load_vector = asm(unit_load, basis)
    boundary = basis.get_dofs().flatten()
    free = np.setdiff1d(np.arange(basis.N), boundary)
    a = stiffness[free][:, free].tocsr()
    inverse_diagonal = 1.0 / a.diagonal()
    jacobi = spla.LinearOperator(a.shape, matvec=lambda r: inverse_diagonal * r)
    u_free, info = spla.cg(a, load_vector[free], rtol=1e-12, maxiter=20_000, M=jacobi)
    if info != 0:
        raise SystemExit(f"conjugate gradients did not converge ({info})")
    u = np.zeros(basis.N)
    u[free] = u_free
    error = math.sqrt(squared_error.assemble(basis, uh=basis.interpolate(u)))
    return error, basis.N


def rate(hs: list[float], errors: list[float]) -> float:
    """The least-squares slope of log(error) against log(h)."""
    return float(np.polyfit(np.log(hs), np.log(errors), 1)[0])


def main() -> None:
    isocube, work = sys.argv[1], Path(sys.argv[2])
    rest = sys.argv[3:]
    # Options after `--` go to `isocube tetmesh` (e.g. `-- --method ternary --snap 0.5`).
    extra = rest[rest.index("--") + 1 :] if "--" in rest else []
    rest = rest[: rest.index("--")] if "--" in rest else rest
    sizes = [int(n) for n in rest] or [16, 24, 32, 48]
    work.mkdir(parents=True, exist_ok=True)
    rows = []
    for n in sizes:
        path = work / f"ball-{n}.msh"
        subprocess.run(
            [isocube, "tetmesh", f"sample:sphere:{n}", "-o", str(path), *extra],
            check=True,
            capture_output=True,
        )
        mesh = load(path)
        h = 2.0 / (n - 1) / RADIUS  # grid spacing, in the unit ball's units
        start = time.perf_counter()
        p1, dofs1 = solve(mesh, ElementTetP1())
        p2, dofs2 = solve(mesh, ElementTetP2())
        took = time.perf_counter() - start
        rows.append((n, h, mesh.t.shape[1], dofs1, p1, dofs2, p2, took))

    print("| N | h | tetrahedra | P1 dofs | P1 L2 error | rate | P2 dofs | P2 L2 error | rate |")
    print("|---|---|---|---|---|---|---|---|---|")
    for k, (n, h, tets, dofs1, p1, dofs2, p2, _) in enumerate(rows):
        if k:
            previous = rows[k - 1]
            r1 = f"{math.log(previous[4] / p1) / math.log(previous[1] / h):.2f}"
            r2 = f"{math.log(previous[6] / p2) / math.log(previous[1] / h):.2f}"
        else:
            r1 = r2 = "–"
        print(f"| {n} | {h:.4f} | {tets} | {dofs1} | {p1:.3e} | {r1} | {dofs2} | {p2:.3e} | {r2} |")
    hs = [row[1] for row in rows]
    fitted = (rate(hs, [row[4] for row in rows]), rate(hs, [row[6] for row in rows]))
    print(f"fitted rates: P1 {fitted[0]:.2f}, P2 {fitted[1]:.2f} (at least {MIN_RATE} required)")
    print(f"solve time: {sum(row[7] for row in rows):.1f} s")
    if len(rows) >= 2 and min(fitted) < MIN_RATE:
        raise SystemExit("the error does not fall like h²")


if __name__ == "__main__":
    main()
