"""Isosurfaces of volumes cut into chunks, meshed on a Dask cluster: the mesh one pass makes.

Each task meshes the cells one chunk of the array owns, from that chunk and the points around
it the method needs (:func:`halo`: one for Marching Cubes' normals, none without normals, 90
for ternary snapping), read on the worker. Every vertex carries a global key (the grid edge,
point or cell it belongs to), so chunk meshes are welded by key in a tree of merges, never by
comparing coordinates; the result is :func:`isocube.extract`'s on the whole array (C order):
the same vertices, triangles and normals, in the same order, array for array — whatever the
chunks, the workers, the scheduler or the retries. Tasks are pure: a lost worker's work done
again gives the same bytes.

Only keys and chunk meshes travel between tasks; voxels stay where the chunks are read (a
Zarr store opened by the workers themselves when a path is given).

Examples
--------
>>> import numpy as np
>>> import dask.array as da
>>> import isocube, isocube.dask
>>> x, y, z = np.mgrid[-1:1:40j, -1:1:40j, -1:1:40j]
>>> volume = (np.sqrt(x**2 + y**2 + z**2) - 0.7).astype(np.float32)
>>> mesh = isocube.dask.extract(da.from_array(volume, chunks=16), 0.0)
>>> whole = isocube.extract(volume, 0.0)
>>> bool((mesh.vertices == whole.vertices).all() and (mesh.triangles == whole.triangles).all())
True
"""

from __future__ import annotations

import os
import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from ._arrays import ArrayLike, _matrix, _triple
from ._isocube import FormatError, InputError
from ._isocube import block_halo as _block_halo
from ._isocube import finish_chunks as _finish_chunks
from ._isocube import merge_chunks as _merge_chunks
from ._isocube import mesh_block as _mesh_block
from ._mesh import Mesh

__all__ = ["boxes", "extract", "halo"]


def halo(method: str = "mc", normals: bool = True) -> int:
    """Points a chunk's task reads beyond its own cells, on each side where the volume goes on.

    Marching Cubes reads one more point for the normals' central differences (none without
    normals); ternary extraction reads 90, as far as its choice of snapped points can look
    (88 ordered rounds, each one point further, and the values around the first).

    >>> import isocube.dask
    >>> from isocube.dask import halo
    >>> halo("mc"), halo("mc", normals=False), halo("ternary")
    (1, 0, 90)
    """
    return int(_block_halo(method, bool(normals)))


def boxes(chunks: Sequence[Sequence[int]]) -> list[tuple[tuple[int, int], ...]]:
    """The boxes of cells the chunks of an array own, in array order: per axis ``(first, end)``.

    A chunk owns the cells whose first point it holds; the last chunk along an axis stops a
    point early (the last point starts no cell), and a chunk left with no cell gives its
    points to the one before.

    >>> import isocube.dask
    >>> isocube.dask.boxes(((3, 3), (5,), (4, 1)))
    [((0, 3), (0, 4), (0, 4)), ((3, 5), (0, 4), (0, 4))]
    """
    bounds = []
    for sizes in chunks:
        n = int(sum(sizes))
        if n < 2:
            raise InputError("every axis of the volume needs at least two points")
        edges = np.cumsum([0, *sizes])
        bounds.append(sorted({min(int(e), n - 1) for e in edges}))
    out: list[tuple[tuple[int, int], ...]] = []
    for a in zip(bounds[0][:-1], bounds[0][1:]):
        for b in zip(bounds[1][:-1], bounds[1][1:]):
            for c in zip(bounds[2][:-1], bounds[2][1:]):
                out.append((a, b, c))
    return out


def _mesh_task(block: Any, at: tuple[int, int, int], **kwargs: Any) -> bytes:
    return bytes(_mesh_block(np.asarray(block, dtype=np.float32), at, **kwargs))


def _read_block(
    path: str, component: str | None, lo: tuple[int, int, int], hi: tuple[int, int, int]
) -> np.ndarray:
    """Points ``lo..=hi`` of the Zarr array at `path` (`component`), read on the worker; a
    chunk that cannot be read is named in the error."""
    import zarr

    z = zarr.open_array(path, mode="r", path=component or "")
    region = tuple(slice(lo[a], hi[a] + 1) for a in range(3))
    try:
        return np.asarray(z[region], dtype=np.float32)
    except Exception as e:
        # Find the first chunk of the block that fails on its own, to name it.
        chunks = z.chunks
        ranges = [range(lo[a] // chunks[a], hi[a] // chunks[a] + 1) for a in range(3)]
        for i in ranges[0]:
            for j in ranges[1]:
                for k in ranges[2]:
                    c = (i, j, k)
                    one = tuple(slice(c[a] * chunks[a], (c[a] + 1) * chunks[a]) for a in range(3))
                    try:
                        z[one]
                    except Exception as bad:
                        key = z.metadata.encode_chunk_key(c)
                        raise FormatError(
                            f"{path}: chunk '{key}' (chunk grid indices {i}, {j}, {k}): {bad}"
                        ) from bad
        raise FormatError(f"{path}: points {lo} to {hi}: {e}") from e


def _merge_task(shape: tuple[int, int, int], *chunks: bytes) -> bytes:
    return bytes(_merge_chunks(shape, list(chunks)))


def _finish_task(chunk: bytes, shape: tuple[int, int, int], **kwargs: Any) -> Any:
    return _finish_chunks(chunk, shape, **kwargs)


def extract(
    array: Any,
    level: float = 0.0,
    *,
    spacing: ArrayLike = (1.0, 1.0, 1.0),
    origin: ArrayLike = (0.0, 0.0, 0.0),
    direction: ArrayLike | None = None,
    method: str = "mc",
    topology: str = "mc33",
    triangulate: str = "fan",
    snap: float = 0.3,
    zero_threshold: float = 0.0,
    snap_position: str = "crossing",
    flip: bool = False,
    normals: bool = True,
    component: str | None = None,
    split_every: int = 4,
    compute: bool = True,
    scheduler: Any = None,
) -> Any:
    """Extracts the isosurface of a chunked volume on Dask: :func:`isocube.extract`'s mesh.

    Parameters
    ----------
    array : dask.array.Array, or str or os.PathLike
        The volume indexed ``[i, j, k]`` (any dtype; each block is converted to ``float32``
        on its worker), or the path of a Zarr array or group (with `component`) that the
        workers open themselves.
    level, spacing, origin, direction, method, topology, triangulate, snap, zero_threshold,
    snap_position, flip, normals
        As :func:`isocube.extract` (relaxation and vertex values need the whole mesh and are
        not offered).
    component : str, optional
        The array inside the Zarr group at `array` (e.g. ``"0"``, an OME-Zarr level).
    split_every : int
        How many neighbouring chunk meshes one merge task welds (the tree's fan-in).
    compute : bool
        Compute now and return the :class:`~isocube.Mesh`, or return a ``dask.delayed`` that
        computes it.
    scheduler : optional
        Passed to Dask's ``compute`` (``"threads"``, ``"processes"``, ``"sync"``, a
        ``distributed.Client``); by default Dask's current one (a ``Client``'s once made).

    Returns
    -------
    Mesh, or dask.delayed.Delayed of one
        Its ``stats`` hold the counts summed over the chunks and ``seconds``, the wall time.

    Examples
    --------
    >>> import numpy as np, dask.array as da
    >>> import isocube, isocube.dask
    >>> rng = np.random.default_rng(1)
    >>> volume = rng.integers(0, 3, size=(20, 17, 23)).astype(np.float32)
    >>> mesh = isocube.dask.extract(da.from_array(volume, chunks=(7, 9, 5)), 1.0)
    >>> whole = isocube.extract(volume, 1.0)
    >>> bool((mesh.triangles == whole.triangles).all() and (mesh.vertices == whole.vertices).all())
    True
    """
    import dask.array as da
    from dask.delayed import delayed

    started = time.perf_counter()
    path = None
    if isinstance(array, (str, os.PathLike)):
        # Opened here for its shape and chunks only; each task reads its own block.
        path = os.fspath(array)
        array = da.from_zarr(path, component=component)  # type: ignore[no-untyped-call]
    elif not isinstance(array, da.Array):
        raise InputError("`array` must be a dask array or the path of a Zarr store")
    if array.ndim != 3:
        raise InputError(f"the volume must have three dimensions, not {array.ndim}")
    if int(split_every) < 2:
        raise InputError("`split_every` must be at least 2")
    shape = (int(array.shape[0]), int(array.shape[1]), int(array.shape[2]))
    h = halo(method, normals)
    options: dict[str, Any] = dict(
        level=float(level),
        spacing=_triple("spacing", spacing),
        origin=_triple("origin", origin),
        method=method,
        topology=topology,
        triangulate=triangulate,
        snap=float(snap),
        zero_threshold=float(zero_threshold),
        snap_position=snap_position,
        flip=bool(flip),
        normals=bool(normals),
    )
    matrix = None if direction is None else _matrix(direction)
    mesh_task = delayed(_mesh_task, pure=True)
    read_task = delayed(_read_block, pure=True)
    merge_task = delayed(_merge_task, pure=True)
    # Per box of cells: the task meshing it from its block (its points and the halo).
    parts: dict[tuple[int, int, int], Any] = {}
    owned = boxes(array.chunks)
    firsts = [sorted({b[a][0] for b in owned}) for a in range(3)]
    for box in owned:
        lo = tuple(max(0, b[0] - h) for b in box)
        hi = tuple(min(shape[a] - 1, box[a][1] + h) for a in range(3))
        if path is None:
            block = array[lo[0] : hi[0] + 1, lo[1] : hi[1] + 1, lo[2] : hi[2] + 1]
        else:
            block = read_task(path, component, lo, hi)
        place = (
            firsts[0].index(box[0][0]),
            firsts[1].index(box[1][0]),
            firsts[2].index(box[2][0]),
        )
        parts[place] = mesh_task(
            block,
            lo,
            shape=shape,
            lo=tuple(b[0] for b in box),
            hi=tuple(b[1] for b in box),
            **options,
        )
    # A tree of merges: neighbours along the last axis first, then the middle, then the first,
    # `split_every` at a time; every merge's boxes tile a box.
    counts = [len(f) for f in firsts]
    for axis in (2, 1, 0):
        while counts[axis] > 1:
            merged: dict[tuple[int, int, int], Any] = {}
            groups = range(0, counts[axis], int(split_every))
            for place in list(parts):
                if place[axis] != 0:
                    continue
                for g, start in enumerate(groups):
                    members = []
                    for n in range(start, min(start + int(split_every), counts[axis])):
                        p = list(place)
                        p[axis] = n
                        members.append(parts[(p[0], p[1], p[2])])
                    q = list(place)
                    q[axis] = g
                    merged[(q[0], q[1], q[2])] = (
                        merge_task(shape, *members) if len(members) > 1 else members[0]
                    )
            parts = merged
            counts[axis] = len(groups)
    (root,) = parts.values()
    arrays = delayed(_finish_task, pure=True)(
        root, shape, origin=options["origin"], normals=options["normals"], direction=matrix
    )
    result = delayed(_to_mesh, pure=True)(arrays)
    if not compute:
        return result
    mesh: Mesh = result.compute(scheduler=scheduler)
    mesh.stats["seconds"] = time.perf_counter() - started
    return mesh


def _to_mesh(arrays: Any) -> Mesh:
    v, t, n, values, stats = arrays
    return Mesh(v, t, n, values, stats)
