"""A real consumer of isocube's volume meshes: scikit-fem solves a Poisson problem on them.

    python fem_poisson.py ISOCUBE WORKDIR [ball|torus] [N ...] [-- TETMESH OPTIONS]

For each N (default 16 24 32 48), `isocube tetmesh sample:sphere:N` (or `sample:torus:N`)
meshes the body as Gmsh MSH, and meshio reads it back. scikit-fem then solves -Δu = f with
u = 0 on the boundary, with P1 and with P2 elements, where the exact solution is known:
- the ball (the sample's sphere, radius 0.8, scaled to the unit ball): f = 1 and
  u = (1 - r²)/6;
- the torus (the sample's, tube radius a = 0.25 around a circle of radius R = 0.6, in the
  sample's own units): u = a² - (R - ρ)² - z² with ρ = √(x² + y²), which vanishes on the
  torus, and f = -Δu = 6 - 2R/ρ (smooth inside: ρ ≥ R - a there).
The L2 error against u is printed as a Markdown table with the observed convergence rates, and
the fitted rate must be at least 1.8 for both elements (the boundary is piecewise flat, so P2
cannot beat h² either). The discrete boundary is the meshed surface, not the exact one: the
rate measures the geometry as much as the elements.

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
from skfem import (
    Basis,
    ElementTetP1,
    ElementTetP2,
    Functional,
    LinearForm,
    MeshTet,
    asm,
)
from skfem.models.poisson import laplace

RADIUS = 0.8  # the sphere sample's radius, in its [-1, 1] box
MAJOR, MINOR = 0.6, 0.25  # the torus sample's circle and tube radii, in its [-1, 1] box
MIN_RATE = 1.8


def exact(shape: str, x: np.ndarray) -> np.ndarray:
    if shape == "ball":
        return (1.0 - (x[0] ** 2 + x[1] ** 2 + x[2] ** 2)) / 6.0
    rho = np.sqrt(x[0] ** 2 + x[1] ** 2)
    return MINOR**2 - (MAJOR - rho) ** 2 - x[2] ** 2


def source(shape: str, x: np.ndarray) -> np.ndarray:
    if shape == "ball":
        return np.ones_like(x[0])
    return 6.0 - 2.0 * MAJOR / np.sqrt(x[0] ** 2 + x[1] ** 2)


def load(path: Path, scale: float) -> MeshTet:
    # ".msh" is Ansys's extension too: name the format, or meshio tries that reader first.
    mesh = meshio.read(path, file_format="gmsh")
    tets = mesh.cells_dict["tetra"]
    points = mesh.points / scale
    a, b, c, d = (points[tets[:, k]] for k in range(4))
    signed = np.einsum("ij,ij->i", b - a, np.cross(c - a, d - a)) / 6.0
    if not (signed > 0).all():
        raise SystemExit(f"{path}: {(signed <= 0).sum()} tetrahedra are not positive")
    used = np.zeros(len(points), dtype=bool)
    used[tets.ravel()] = True
    if not used.all():
        raise SystemExit(f"{path}: {(~used).sum()} vertices belong to no tetrahedron")
    return MeshTet(points.T.copy(), tets.T.copy())


def solve(mesh: MeshTet, element, shape: str) -> tuple[float, float, int]:
    """The L2 error, the largest error at a degree of freedom's node, and the dof count."""
    basis = Basis(mesh, element, intorder=4)
    stiffness = asm(laplace, basis)

    @LinearForm
    def load(v, w):
        return source(shape, w.x) * v

    @Functional
    def squared_error(w):
        return (w["uh"] - exact(shape, w.x)) ** 2

    load_vector = asm(load, basis)
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
    nodal = float(np.abs(u - exact(shape, basis.doflocs)).max())
    return error, nodal, basis.N


def rate(hs: list[float], errors: list[float]) -> float:
    """The least-squares slope of log(error) against log(h)."""
    return float(np.polyfit(np.log(hs), np.log(errors), 1)[0])


def main() -> None:
    isocube, work = sys.argv[1], Path(sys.argv[2])
    rest = sys.argv[3:]
    # Options after `--` go to `isocube tetmesh` (e.g. `-- --method ternary --snap 0.5`).
    extra = rest[rest.index("--") + 1 :] if "--" in rest else []
    rest = rest[: rest.index("--")] if "--" in rest else rest
    shape = "ball"
    if rest and rest[0] in ("ball", "torus"):
        shape, rest = rest[0], rest[1:]
    sample, scale = ("sphere", RADIUS) if shape == "ball" else ("torus", 1.0)
    sizes = [int(n) for n in rest] or [16, 24, 32, 48]
    work.mkdir(parents=True, exist_ok=True)
    rows = []
    for n in sizes:
        path = work / f"{shape}-{n}.msh"
        subprocess.run(
            [isocube, "tetmesh", f"sample:{sample}:{n}", "-o", str(path), *extra],
            check=True,
            capture_output=True,
        )
        mesh = load(path, scale)
        h = 2.0 / (n - 1) / scale  # grid spacing, in the solved problem's units
        start = time.perf_counter()
        p1 = solve(mesh, ElementTetP1(), shape)
        p2 = solve(mesh, ElementTetP2(), shape)
        took = time.perf_counter() - start
        rows.append((n, h, mesh.t.shape[1], p1, p2, took))

    print(f"{shape}, tetmesh options: {' '.join(extra) or '(defaults)'}")
    print(
        "| N | h | tetrahedra | element | dofs | L2 error | rate | max nodal error | rate |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    hs = [row[1] for row in rows]
    fitted = []
    for e, name in ((3, "P1"), (4, "P2")):
        for k, row in enumerate(rows):
            n, h, tets, (l2, nodal, dofs) = row[0], row[1], row[2], row[e]
            if k:
                before, h0 = rows[k - 1][e], rows[k - 1][1]
                r = [
                    f"{math.log(before[m] / now) / math.log(h0 / h):.2f}"
                    for m, now in ((0, l2), (1, nodal))
                ]
            else:
                r = ["–", "–"]
            print(
                f"| {n} | {h:.4f} | {tets} | {name} | {dofs} | {l2:.3e} | {r[0]} | {nodal:.3e} | {r[1]} |"
            )
        fitted.append(
            (
                rate(hs, [row[e][0] for row in rows]),
                rate(hs, [row[e][1] for row in rows]),
            )
        )
    print(
        f"fitted rates, L2 / max nodal: P1 {fitted[0][0]:.2f} / {fitted[0][1]:.2f}, "
        f"P2 {fitted[1][0]:.2f} / {fitted[1][1]:.2f} (at least {MIN_RATE} required)"
    )
    print(f"solve time: {sum(row[5] for row in rows):.1f} s")
    if len(rows) >= 2 and min(min(f) for f in fitted) < MIN_RATE:
        raise SystemExit("the error does not fall like h²")


if __name__ == "__main__":
    main()
