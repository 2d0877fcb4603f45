"""Writes the labelled volumes the multi-material volume meshes are checked on.

    python make_labels.py OUTDIR

- `three.npy` (u8, 40³): labels 1 and 2, two overlapping balls, and 3, a slab under them, in
  background 0; labels 1–2 and 1–3 touch.
- `packed.npy` (u8, 36³): two materials filling the box: spheres of a deterministic random
  packing (label 1, some cut by the box) and the pores between them (label 2).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np


def three(n: int = 40) -> np.ndarray:
    z, y, x = np.mgrid[0:n, 0:n, 0:n] / (n - 1.0)
    lab = np.zeros((n, n, n), np.uint8)
    lab[(x - 0.4) ** 2 + (y - 0.5) ** 2 + (z - 0.5) ** 2 < 0.3**2] = 1
    lab[(x - 0.65) ** 2 + (y - 0.5) ** 2 + (z - 0.5) ** 2 < 0.2**2] = 2
    lab[(x > 0.3) & (x < 0.5) & (y > 0.2) & (y < 0.8) & (z < 0.3)] = 3
    return lab


def packed(n: int = 36, seed: int = 5) -> np.ndarray:
    rng = np.random.default_rng(seed)
    spheres: list[tuple[np.ndarray, float]] = []
    for _ in range(2000):
        if len(spheres) == 30:
            break
        c, r = rng.uniform(-0.05, 1.05, 3), rng.uniform(0.07, 0.15)
        if all(np.linalg.norm(c - d) > r + s + 0.02 for d, s in spheres):
            spheres.append((c, r))
    z, y, x = np.mgrid[0:n, 0:n, 0:n] / (n - 1.0)
    inside = np.zeros((n, n, n), bool)
    for c, r in spheres:
        inside |= (x - c[0]) ** 2 + (y - c[1]) ** 2 + (z - c[2]) ** 2 < r * r
    return np.where(inside, 1, 2).astype(np.uint8)


def main() -> None:
    out = Path(sys.argv[1])
    out.mkdir(parents=True, exist_ok=True)
    np.save(out / "three.npy", three())
    np.save(out / "packed.npy", packed())


if __name__ == "__main__":
    main()
