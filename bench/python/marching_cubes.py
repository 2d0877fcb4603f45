"""isocube's Python package beside scikit-image, PyMCubes and PyVista, on the same arrays.

    python bench/python/marching_cubes.py [N]

Each tool meshes a float32 N³ array (default 256) already in memory, as a Python user calls it:
``isocube.marching_cubes`` (scikit-image's signature and outputs), ``isocube.extract`` (the
library call), ``skimage.measure.marching_cubes``, ``mcubes.marching_cubes`` (PyMCubes) and
PyVista's ``contour(method='flying_edges')`` on an ``ImageData`` wrapping the array. Best of
three calls each. The engine's own time (``Mesh.stats['seconds']``, measured in Rust around the
extraction, with and without the vertex values the drop-in returns) shows what the Python layer
adds. Prints a Markdown table.

Then end to end from a file, as a user runs it (best of three): the field saved as ``.npy``,
read with ``np.load``, meshed and written as binary PLY — ``isocube.extract(...).save(...)``
beside scikit-image's ``marching_cubes`` written by ``trimesh`` (if installed), and the
``isocube extract`` command (``$ISOCUBE_BIN``, or ``isocube`` on the PATH) on the same file.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
import time
from functools import partial
from typing import Any, Callable

import numpy as np

import isocube


def fields(n: int) -> dict[str, tuple[np.ndarray, float]]:
    x = np.linspace(-1, 1, n, dtype=np.float32)
    X, Y, Z = np.meshgrid(x, x, x, indexing="ij")
    t = 3 * X, 3 * Y, 3 * Z
    return {
        "sphere": (np.sqrt(X**2 + Y**2 + Z**2) - 0.7, 0.0),
        "tangle": (
            t[0] ** 4
            - 5 * t[0] ** 2
            + t[1] ** 4
            - 5 * t[1] ** 2
            + t[2] ** 4
            - 5 * t[2] ** 2
            + 11.8,
            0.0,
        ),
        "gyroid": (
            np.sin(2 * np.pi * X) * np.cos(2 * np.pi * Y)
            + np.sin(2 * np.pi * Y) * np.cos(2 * np.pi * Z)
            + np.sin(2 * np.pi * Z) * np.cos(2 * np.pi * X),
            0.0,
        ),
    }


def best(f: Callable[[], Any], runs: int = 3) -> tuple[float, Any]:
    times, out = [], None
    for _ in range(runs):
        # The previous result freed outside the timing, for every tool alike.
        out = None
        start = time.perf_counter()
        out = f()
        times.append(time.perf_counter() - start)
    return min(times), out


def main() -> None:
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 256
    tools: list[tuple[str, Callable[[np.ndarray, float], Any]]] = [
        ("isocube.marching_cubes", lambda a, level: isocube.marching_cubes(a, level)),
        ("isocube.extract", lambda a, level: isocube.extract(a, level)),
    ]
    try:
        from skimage.measure import marching_cubes as sk

        tools.append(("skimage.measure.marching_cubes", lambda a, level: sk(a, level)))
    except ImportError:
        pass
    try:
        import mcubes

        tools.append(
            ("mcubes.marching_cubes (PyMCubes)", lambda a, level: mcubes.marching_cubes(a, level))
        )
    except ImportError:
        pass
    try:
        import pyvista as pv

        def flying_edges(a: np.ndarray, level: float) -> Any:
            grid = pv.ImageData(dimensions=a.shape)
            grid.point_data["f"] = a.ravel(order="F")
            return grid.contour([level], scalars="f", method="flying_edges")

        tools.append(("pyvista contour (flying_edges)", flying_edges))
    except ImportError:
        pass
    print(
        f"| field ({n}³ float32) | tool | triangles | seconds "
        "| isocube.marching_cubes is × faster |"
    )
    print("|---|---|---:|---:|---:|")
    for name, (a, level) in fields(n).items():
        ours, _ = best(partial(isocube.marching_cubes, a, level))
        engine = min(isocube.extract(a, level).stats["seconds"] for _ in range(3))
        # The same work as the drop-in in Rust alone: the mesh, normals and vertex values.
        same_work = min(
            isocube.extract(a, level, values=True).stats["seconds"] for _ in range(3)
        )
        for tool, f in tools:
            seconds, out = best(partial(f, a, level))
            if isinstance(out, tuple):
                triangles = len(out[1])
            elif isinstance(out, isocube.Mesh):
                triangles = len(out.triangles)
            else:
                triangles = out.n_cells
            print(f"| {name} | {tool} | {triangles} | {seconds:.3f} | {seconds / ours:.1f} |")
        print(
            f"| {name} | isocube engine alone (Rust, in the call) | | {engine:.3f} "
            f"| {engine / ours:.2f} |"
        )
        print(
            f"| {name} | isocube engine + vertex values (Rust, the drop-in's work) | "
            f"| {same_work:.3f} | {same_work / ours:.2f} |"
        )


def end_to_end(n: int) -> None:
    tools: list[tuple[str, Callable[[str, float, str], Any]]] = [
        (
            "np.load + isocube.extract + Mesh.save",
            lambda npy, level, ply: isocube.extract(np.load(npy), level).save(ply),
        )
    ]
    binary = os.environ.get("ISOCUBE_BIN") or shutil.which("isocube")
    if binary:
        tools.append(
            (
                "isocube extract (command)",
                lambda npy, level, ply: subprocess.run(
                    [binary, "extract", npy, "-o", ply, "--level", str(level), "--quiet"],
                    check=True,
                ),
            )
        )
    try:
        import trimesh
        from skimage.measure import marching_cubes as sk

        def skimage_to_ply(npy: str, level: float, ply: str) -> None:
            verts, faces, normals, _ = sk(np.load(npy), level)
            trimesh.Trimesh(verts, faces, vertex_normals=normals, process=False).export(ply)

        tools.append(("np.load + skimage + trimesh export", skimage_to_ply))
    except ImportError:
        pass
    print()
    print(f"| field ({n}³ .npy → binary PLY) | tool | seconds | × isocube.extract + save |")
    print("|---|---|---:|---:|")
    with tempfile.TemporaryDirectory() as work:
        for name, (a, level) in fields(n).items():
            npy = os.path.join(work, f"{name}.npy")
            np.save(npy, a)
            first = None
            for tool, f in tools:
                ply = os.path.join(work, f"{name}.ply")
                seconds, _ = best(partial(f, npy, level, ply))
                first = first or seconds
                print(f"| {name} | {tool} | {seconds:.3f} | {seconds / first:.1f} |")


if __name__ == "__main__":
    main()
    end_to_end(int(sys.argv[1]) if len(sys.argv) > 1 else 256)
