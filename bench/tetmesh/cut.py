"""Draws the README's cut through a graded volume mesh (docs/graded-cut.png).

    python bench/tetmesh/cut.py ISOCUBE [OUT.png]

Needs the Python package (`isocube`, with NumPy). A ball of radius 0.8 sampled on 64 points
per axis is meshed graded (`max_size="16c"`, ternary snapping); the tetrahedra whose centroid
lies on one side of the plane through the ball's centre are kept, and the boundary of what is kept (the cut
face shows the cubes growing inward, the rest is the ball's surface) is drawn by
`isocube render --wireframe`.
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
from pathlib import Path

import isocube
import numpy as np


def main() -> None:
    binary = sys.argv[1]
    out = Path(
        sys.argv[2]
        if len(sys.argv) > 2
        else Path(__file__).parents[2] / "docs" / "graded-cut.png"
    )
    x, y, z = np.mgrid[-1:1:64j, -1:1:64j, -1:1:64j]
    field = np.sqrt(x**2 + y**2 + z**2)
    mesh = isocube.tetmesh(field, 0.8, method="ternary", max_size="16c")
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    tets = np.asarray(mesh.tets, dtype=np.int64)
    # The mesh is in grid index coordinates: the cut is through the ball's centre.
    middle = (vertices[:, 0].min() + vertices[:, 0].max()) / 2
    kept = tets[vertices[tets].mean(axis=1)[:, 0] < middle]
    # Outward faces of positive tetrahedra; a face used twice is inside what is kept.
    faces = np.concatenate(
        [kept[:, [1, 2, 3]], kept[:, [0, 3, 2]], kept[:, [0, 1, 3]], kept[:, [0, 2, 1]]]
    )
    key = np.sort(faces, axis=1)
    _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    boundary = faces[counts[inverse.ravel()] == 1]
    with tempfile.TemporaryDirectory() as work:
        ply = Path(work) / "cut.ply"
        with ply.open("w") as f:
            f.write(
                f"ply\nformat ascii 1.0\nelement vertex {len(vertices)}\n"
                "property float x\nproperty float y\nproperty float z\n"
                f"element face {len(boundary)}\nproperty list uchar int vertex_indices\nend_header\n"
            )
            np.savetxt(f, vertices, fmt="%.7g")
            np.savetxt(
                f, np.hstack([np.full((len(boundary), 1), 3), boundary]), fmt="%d"
            )
        subprocess.run(
            [
                binary,
                "render",
                str(ply),
                "-o",
                str(out),
                "--size",
                "640x480",
                "--wireframe",
                "--view",
                "20,15",
                "--quiet",
            ],
            check=True,
        )
    print(
        f"{out}: {len(kept)} of {len(tets)} tetrahedra kept, {len(boundary)} faces drawn"
    )


if __name__ == "__main__":
    main()
