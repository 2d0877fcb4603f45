"""The volume-mesh modes side by side on held-out inputs, for one or more isocube binaries.

    python bench/tetmesh/table.py ISOCUBE_BINARY [ISOCUBE_BINARY ...]

Sixteen inputs: balls and tori as `.npy` distance fields with random sub-cell centres, spacing
and a negative origin (24, 32, 40 and 40 points per axis), packed spheres and noise at 24, 32,
40 and 40 points with seeds 1–4 (built-in samples). Each is meshed on both sides (the values
below the level and, with `--flip`, the rest) by `isocube tetmesh` with `--method mc`,
`--snap-position grid` and the default flags (ternary, snap 0.3, vertices on the crossings).
For each binary and mode: how many of the 32 runs were refused, the smallest and largest
dihedral angle over the meshes made, how many meshes have every angle within [10°, 165°] and
how many others reach the bound their surface forces (the smallest angle is the sharpest
boundary edge's, under 10°), and the largest distance of a mesh's surface from the
level set, in grid cells, on the distance fields (balls, tori: `|f|` trilinear at the vertices
and triangle centres; packed spheres: `isocube quality --field`, the exact function); noise is
no distance field, and `|f| / |∇f|` there is no distance near its critical points.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
import tempfile
from pathlib import Path

import meshio
import numpy as np

MODES = {
    "mc": ["--method", "mc"],
    "ternary, grid": ["--snap-position", "grid"],
    "default": [],
}


def fields(work: Path) -> list[tuple[str, list[str], str]]:
    """(input, extra options, field for the distance) for the sixteen inputs."""
    rng = np.random.default_rng(50)
    out = []
    for shape in ("ball", "torus"):
        for n in (24, 32, 40, 40):
            spacing = rng.uniform(0.5, 2.0, 3)
            origin = -rng.uniform(5.0, 50.0, 3)
            extent = spacing * (n - 1)
            centre = origin + extent / 2 + rng.uniform(-0.5, 0.5, 3) * spacing
            axes = [origin[a] + spacing[a] * np.arange(n) for a in range(3)]
            x, y, z = np.meshgrid(*axes, indexing="ij")
            x, y, z = x - centre[0], y - centre[1], z - centre[2]
            size = 0.4 * extent.min()
            if shape == "ball":
                f = np.sqrt(x * x + y * y + z * z) - 0.8 * size
            else:
                f = (
                    np.sqrt((np.sqrt(x * x + y * y) - 0.6 * size) ** 2 + z * z)
                    - 0.25 * size
                )
            path = work / f"{shape}-{n}-{len(out)}.npy"
            np.save(path, f.astype(np.float32))
            options = [
                "--spacing",
                ",".join(f"{s:.6g}" for s in spacing),
                "--origin",
                ",".join(f"{o:.6g}" for o in origin),
            ]
            out.append((str(path), options, str(path)))
    for name in ("packed-spheres", "noise"):
        for seed, n in enumerate((24, 32, 40, 40), start=1):
            spec = f"sample:{name}:{n}:{seed}"
            out.append((spec, [], spec))
    return out


def boundary_distance(binary: str, mesh: Path, field: str, work: Path) -> float:
    m = meshio.read(mesh, file_format="gmsh")
    surface = m.cells_dict["triangle"][
        m.cell_data_dict["gmsh:physical"]["triangle"] == 2
    ]
    used, compact = np.unique(surface, return_inverse=True)
    ply = work / "surface.ply"
    meshio.write(
        ply,
        meshio.Mesh(
            m.points[used], [("triangle", compact.reshape(-1, 3).astype(np.int32))]
        ),
        binary=True,
    )
    done = subprocess.run(
        [binary, "-q", "quality", str(ply), "--field", field, "--json"],
        capture_output=True,
        text=True,
    )
    if done.returncode != 0:
        return float("nan")
    return float(json.loads(done.stdout)["distance"]["max"])


def main() -> None:
    binaries = sys.argv[1:]
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        inputs = fields(work)
        print(
            "| binary | mode | refused (of 32) | min / max dihedral | meshes within [10°, 165°] "
            "| others at the bound the surface forces | largest surface distance (h) |"
        )
        print("|---|---|---|---|---|---|---|")
        for binary in binaries:
            for mode, options in MODES.items():
                refused, lo, hi, far, within, forced = 0, 180.0, 0.0, 0.0, 0, 0
                reasons = []
                for path, extra, field in inputs:
                    for flip in ([], ["--flip"]):
                        out = work / "m.msh"
                        done = subprocess.run(
                            [
                                binary,
                                "tetmesh",
                                path,
                                "-o",
                                str(out),
                                *extra,
                                *options,
                                *flip,
                            ],
                            capture_output=True,
                            text=True,
                        )
                        if done.returncode != 0:
                            refused += 1
                            reasons.append(
                                f"{path.split('/')[-1]} {' '.join(flip)}: {done.stderr.strip().splitlines()[-1][:90]}"
                            )
                            continue
                        angles = re.search(
                            r"dihedral angles ([0-9.]+)°\.\.([0-9.]+)°", done.stderr
                        )
                        assert angles, done.stderr
                        low, high = float(angles.group(1)), float(angles.group(2))
                        lo, hi = min(lo, low), max(hi, high)
                        sharpest = re.search(
                            r"sharpest boundary edge: ([0-9.]+)°", done.stderr
                        )
                        if low >= 10.0 and high <= 165.0:
                            within += 1
                        elif (
                            sharpest
                            and float(sharpest.group(1)) < 10.0
                            and low >= float(sharpest.group(1)) - 0.01
                        ):
                            forced += 1
                        if field.endswith(".npy"):
                            d = npy_distance(out, path, extra)
                        elif "noise" not in field:
                            d = boundary_distance(binary, out, field, work)
                        else:
                            d = 0.0
                        if "DEBUG" in __import__("os").environ:
                            print(path, flip, d, file=sys.stderr)
                        far = max(far, d)
                print(
                    f"| {Path(binary).name} | {mode} | {refused} | {lo:.2f}° / {hi:.2f}° | {within} | {forced} | {far:.3f} |"
                )
                for r in reasons:
                    print(f"  refused: {r}")


def npy_distance(mesh: Path, path: str, extra: list[str]) -> float:
    """The surface's largest distance from the level set of the `.npy` field (trilinear), in
    grid cells (the smallest spacing), placed as `extra` says."""
    from scipy.interpolate import RegularGridInterpolator

    values = np.load(path).astype(np.float64)
    spacing = np.array(
        [float(s) for s in extra[extra.index("--spacing") + 1].split(",")]
    )
    origin = np.array([float(s) for s in extra[extra.index("--origin") + 1].split(",")])
    axes = [origin[a] + spacing[a] * np.arange(values.shape[a]) for a in range(3)]
    f = RegularGridInterpolator(axes, values)
    m = meshio.read(mesh, file_format="gmsh")
    surface = m.cells_dict["triangle"][
        m.cell_data_dict["gmsh:physical"]["triangle"] == 2
    ]
    p = m.points[surface]
    samples = np.concatenate([m.points[np.unique(surface)], p.mean(axis=1)])
    lo, hi = np.array([a[0] for a in axes]), np.array([a[-1] for a in axes])
    samples = np.clip(samples, lo, hi)
    # A distance field: |∇f| = 1 up to the interpolation, so |f| is the distance.
    return float(np.abs(f(samples)).max() / spacing.min())


if __name__ == "__main__":
    main()
