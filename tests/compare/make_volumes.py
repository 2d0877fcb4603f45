"""Writes the volumes tests/compare/run.sh meshes: .npy in both axis orders and a raw file.

Pure Python (no NumPy), so the comparison runs on a bare machine.
"""

import math
import struct
import sys
from pathlib import Path


def npy(path: Path, shape: tuple[int, int, int], values: list[float]) -> None:
    header = "{'descr': '<f4', 'fortran_order': False, 'shape': (%d, %d, %d), }" % shape
    # Magic, version 1.0, header padded with spaces to a multiple of 64 bytes, ending in \n.
    pad = 64 - (10 + len(header) + 1) % 64
    header = header + " " * pad + "\n"
    with path.open("wb") as f:
        f.write(b"\x93NUMPY\x01\x00" + struct.pack("<H", len(header)) + header.encode())
        f.write(struct.pack("<%df" % len(values), *values))


def field(x: float, y: float, z: float) -> float:
    # Two blobs and a gyroid-like ripple: several components, saddles and ties-free values.
    r1 = math.dist((x, y, z), (-0.3, 0.1, 0.0)) - 0.45
    r2 = math.dist((x, y, z), (0.4, -0.2, 0.1)) - 0.35
    ripple = 0.08 * math.sin(7 * x) * math.cos(6 * y) * math.sin(5 * z)
    return min(r1, r2) + ripple


def main() -> None:
    out = Path(sys.argv[1])
    nx, ny, nz = 37, 29, 23
    point = lambda i, n: -1.0 + 2.0 * i / (n - 1)
    # v[z][y][x], x fastest: the usual NumPy layout.
    zyx = [field(point(i, nx), point(j, ny), point(k, nz)) for k in range(nz) for j in range(ny) for i in range(nx)]
    npy(out / "blobs-zyx.npy", (nz, ny, nx), zyx)
    # The same volume as a[x][y][z] (z fastest), read with the default axes.
    xyz = [zyx[i + nx * (j + ny * k)] for i in range(nx) for j in range(ny) for k in range(nz)]
    npy(out / "blobs-xyz.npy", (nx, ny, nz), xyz)
    with (out / "blobs.raw").open("wb") as f:
        f.write(struct.pack("<%df" % len(zyx), *zyx))


main()
