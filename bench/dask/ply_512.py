"""Dask against one process, end to end on a Zarr file: read, mesh, write a binary PLY.

    python bench/dask/ply_512.py STORE.zarr [REPEATS]

Times, best and worst of REPEATS, all writing the same PLY bytes (checked):
- the ``isocube`` command reading the store itself (``isocube extract STORE -o out.ply``);
- one Python process: zarr-python reads the array, ``isocube.extract``, ``Mesh.save``;
- ``isocube.dask.extract`` (gathered) + ``save``, on the threaded scheduler;
- ``isocube.dask.write_ply`` (never gathered), threaded, and on a LocalCluster of two
  one-thread worker processes.
Set ISOCUBE_BIN to the command (default: target/release/isocube).
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from typing import Any, Callable

import numpy as np
import zarr
from distributed import Client, LocalCluster

import isocube
import isocube.dask


def best(f: Callable[[], Any], n: int) -> tuple[float, float, Any]:
    times, result = [], None
    for _ in range(n):
        t0 = time.perf_counter()
        result = f()
        times.append(time.perf_counter() - t0)
    return min(times), max(times), result


def main() -> None:
    store = sys.argv[1]
    repeats = int(sys.argv[2]) if len(sys.argv) > 2 else 3
    binary = os.environ.get("ISOCUBE_BIN", "target/release/isocube")
    out = tempfile.mkdtemp()
    files = {
        k: os.path.join(out, f"{k}.ply")
        for k in ("cli", "one", "gathered", "threads", "cluster")
    }

    def cli() -> None:
        subprocess.run([binary, "extract", store, "-o", files["cli"], "-q"], check=True)

    def one() -> None:
        volume = np.asarray(zarr.open_array(store, mode="r")[:])
        isocube.extract(volume, 0.0).save(files["one"])

    def gathered() -> None:
        isocube.dask.extract(store, 0.0, scheduler="threads").save(files["gathered"])

    def threads() -> dict[str, Any]:
        return isocube.dask.write_ply(store, files["threads"], 0.0, scheduler="threads")

    rows = [("isocube command", best(cli, repeats))]
    rows.append(("one process: zarr read + extract + save", best(one, repeats)))
    rows.append(("dask threads: extract (gathered) + save", best(gathered, repeats)))
    rows.append(("dask threads: write_ply", best(threads, repeats)))
    with (
        LocalCluster(
            n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
        ) as c,
        Client(c),
    ):
        isocube.dask.write_ply(store, files["cluster"], 0.0)  # workers warmed
        rows.append(
            (
                "LocalCluster(2 processes): write_ply",
                best(
                    lambda: isocube.dask.write_ply(store, files["cluster"], 0.0),
                    repeats,
                ),
            )
        )
    reference = open(files["cli"], "rb").read()
    same = all(open(f, "rb").read() == reference for f in files.values())
    stats = rows[3][1][2]
    print(
        f"{store}: {stats['vertices']} vertices, {stats['triangles']} triangles, "
        f"PLY {len(reference) / 1e6:.1f} MB, outlines to the layout {stats['layout_bytes'] / 1e6:.2f} MB; "
        f"identical files: {same}"
    )
    for name, (lo, hi, _) in rows:
        print(f"  {name:45s} {lo:6.2f} – {hi:6.2f} s")


if __name__ == "__main__":
    main()
