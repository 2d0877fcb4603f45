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


def npy_typed(path: Path, shape: tuple[int, int, int], code: str, values: list[int]) -> None:
    """A C-order .npy of integers stored with struct `code` ('B', 'h', 'i', 'f', 'd')."""
    descr = {"B": "|u1", "h": "<i2", "i": "<i4", "f": "<f4", "d": "<f8"}[code]
    header = "{'descr': '%s', 'fortran_order': False, 'shape': (%d, %d, %d), }" % (descr, *shape)
    pad = 64 - (10 + len(header) + 1) % 64
    header = header + " " * pad + "\n"
    with path.open("wb") as f:
        f.write(b"\x93NUMPY\x01\x00" + struct.pack("<H", len(header)) + header.encode())
        f.write(struct.pack("<%d%s" % (len(values), code), *values))


def tied(path_stem: Path) -> None:
    """Random integers in -2..2, saved a[x, y, z] (C order: z fastest) as u8 (shifted by 2),
    i16, i32, f32 (also with -0.0 for its zeros) and f64: most points lie exactly on the levels
    -1, 0 and 1."""
    shape = (17, 19, 23)
    state = 49
    values = []
    for _ in range(shape[0] * shape[1] * shape[2]):
        state = (state * 6364136223846793005 + 1442695040888963407) % 2**64
        values.append((state >> 33) % 5 - 2)
    for name, code, shift in (("u8", "B", 2), ("i16", "h", 0), ("i32", "i", 0), ("f32", "f", 0), ("f64", "d", 0)):
        npy_typed(path_stem.with_name(f"{path_stem.name}-{name}.npy"), shape, code, [v + shift for v in values])
    # f32 with its zeros stored as -0.0, as rounding negative floats leaves them: the same values.
    npy_typed(path_stem.with_name(f"{path_stem.name}-f32neg.npy"), shape, "f", [v if v else -0.0 for v in values])


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
    tied(out / "tied")


main()
