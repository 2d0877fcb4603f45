"""Benchmark volumes as .npy (a[z, y, x], x fastest): tangle, sphere and gyroid sampled like
isocube's built-in samples, and a CT-like 16-bit volume (a body of soft tissue with bones and
noise, in Hounsfield-like units offset by 1024). Prints LEVEL:PATH lines.

    python volumes.py OUTDIR [N ...]
"""
import os
import sys

import numpy as np


def sample(name, n):
    lo, hi = {"sphere": (-1.0, 1.0), "tangle": (-3.0, 3.0), "gyroid": (-3.0, 3.0)}[name]
    x = np.linspace(lo, hi, n, dtype=np.float64)
    z, y, xx = np.meshgrid(x, x, x, indexing="ij")
    if name == "sphere":
        v = np.sqrt(xx * xx + y * y + z * z) - 0.8
    elif name == "tangle":
        v = xx**4 - 5 * xx**2 + y**4 - 5 * y**2 + z**4 - 5 * z**2 + 11.8
    else:
        v = np.sin(xx) * np.cos(y) + np.sin(y) * np.cos(z) + np.sin(z) * np.cos(xx)
    return v.astype(np.float32)


def ct(n):
    """A torso-like ellipsoid of soft tissue (about 40 HU), a spine and ribs of bone (about
    700 HU) and noise, air outside (-1000 HU); stored as uint16 with +1024."""
    rng = np.random.default_rng(7)
    x = np.linspace(-1.0, 1.0, n, dtype=np.float32)
    z, y, xx = np.meshgrid(x, x, x, indexing="ij")
    hu = np.full((n, n, n), -1000.0, dtype=np.float32)
    body = (xx / 0.9) ** 2 + (y / 0.6) ** 2 < 1.0
    hu[body] = 40.0
    spine = (xx**2 + (y + 0.35) ** 2 < 0.01) & body
    hu[spine] = 700.0
    for k in range(-4, 5):
        rib = (np.abs(z - 0.18 * k) < 0.03) & (np.abs(np.sqrt((xx / 0.8) ** 2 + (y / 0.52) ** 2) - 1.0) < 0.04)
        hu[rib & body] = 700.0
    hu += rng.normal(0.0, 20.0, size=hu.shape).astype(np.float32)
    return np.clip(hu + 1024.0, 0, 65535).astype(np.uint16)


def main():
    out = sys.argv[1]
    sizes = [int(a) for a in sys.argv[2:]] or [256, 512]
    os.makedirs(out, exist_ok=True)
    for n in sizes:
        for name in ["tangle", "sphere", "gyroid"]:
            path = os.path.join(out, f"{name}-{n}.npy")
            if not os.path.exists(path):
                np.save(path, sample(name, n))
            print(f"0:{path}")
    n = sizes[-1]
    path = os.path.join(out, f"ct-{n}.npy")
    if not os.path.exists(path):
        np.save(path, ct(n))
    # Bone: 300 HU above water, +1024 offset.
    print(f"1324:{path}")


if __name__ == "__main__":
    main()
