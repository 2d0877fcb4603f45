"""Isosurfaces of volumes cut into chunks, meshed on a Dask cluster: the mesh one pass makes.

Each task meshes the cells one chunk of the array owns, from that chunk and the points around
it the method needs (:func:`halo`: one for Marching Cubes' normals, none without normals, 115
for ternary snapping), read on the worker. Every vertex carries a global key (the grid edge,
point or cell it belongs to), so chunk meshes are welded by key, never by comparing
coordinates: each line of chunks along the last axis is merged into a band, one task lays out
the whole mesh from the bands' *outlines* (where their runs of rows end, and the vertices they
share), and each band numbers its vertices as the whole mesh does. The result is
:func:`isocube.extract`'s on the whole array (C order): the same vertices, triangles and
normals, in the same order, array for array — whatever the chunks, the workers, the scheduler
or the retries. Tasks are pure: a lost worker's work done again gives the same bytes.
:func:`write_ply` has the bands write their parts of one PLY file in place, so the mesh is
never gathered: for meshes larger than any one machine's memory.

Voxels stay where the chunks are read (a Zarr store opened by the workers themselves when a
path is given); halos travel as thin slices, chunk meshes once into their band, and only
outlines and places to and from the layout.

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
import uuid
from collections.abc import Sequence
from typing import Any

import numpy as np

from ._arrays import ArrayLike, _matrix, _triple
from ._errors import empty_surface
from ._isocube import FormatError, InputError
from ._isocube import assemble_pieces as _assemble_pieces
from ._isocube import block_halo as _block_halo
from ._isocube import chunk_outline as _chunk_outline
from ._isocube import create_ply as _create_ply
from ._isocube import finish_label_chunks as _finish_label_chunks
from ._isocube import join_layout as _join_layout
from ._isocube import merge_chunks as _merge_chunks
from ._isocube import merge_label_chunks as _merge_label_chunks
from ._isocube import mesh_block as _mesh_block
from ._isocube import mesh_label_block as _mesh_label_block
from ._isocube import place_chunk as _place_chunk
from ._isocube import read_zarr_block as _read_zarr_block
from ._isocube import write_ply_chunk as _write_ply_chunk
from ._mesh import Mesh

__all__ = ["boxes", "extract", "halo", "label_surfaces", "write_ply"]


def halo(method: str = "mc", normals: bool = True) -> int:
    """Points a chunk's task reads beyond its own cells, on each side where the volume goes on.

    Marching Cubes reads one more point for the normals' central differences (none without
    normals); ternary extraction reads 115, as far as its choice of snapped points can look
    (88 ordered rounds, each one point further, the values around the first, and their
    neighbours, which settle lone ties; then up to six rounds, each four points further, that
    keep on their grid points the snapped points whose vertices would make the surface cross
    itself).

    >>> import isocube.dask
    >>> from isocube.dask import halo
    >>> halo("mc"), halo("mc", normals=False), halo("ternary")
    (1, 0, 115)
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


def _zarr_array(
    path: str, component: str | None, dtype: Any = np.float32, strict: bool = False
) -> Any:
    """The Zarr array at `path` as a dask array whose tasks read one chunk each on the workers
    (naming the chunk when it cannot be read, or, if `strict`, when it is absent)."""
    import dask.array as da
    import zarr
    from dask.delayed import delayed

    z = zarr.open_array(path, mode="r", path=component or "")
    if z.ndim != 3:
        raise InputError(f"{path}: the array has {z.ndim} dimensions, not three")
    read = delayed(_read_block, pure=True)
    edges = [list(range(0, n, c)) + [n] for n, c in zip(z.shape, z.chunks)]
    rows = []
    for i in range(len(edges[0]) - 1):
        plane = []
        for j in range(len(edges[1]) - 1):
            line = []
            for k in range(len(edges[2]) - 1):
                lo = (edges[0][i], edges[1][j], edges[2][k])
                end = (edges[0][i + 1], edges[1][j + 1], edges[2][k + 1])
                shape = tuple(end[a] - lo[a] for a in range(3))
                hi = (end[0] - 1, end[1] - 1, end[2] - 1)
                block = read(path, component, lo, hi, strict=strict)
                line.append(da.from_delayed(block, shape, dtype=np.float32))
            plane.append(line)
        rows.append(plane)
    return da.block(rows)


def _read_block(
    path: str,
    component: str | None,
    lo: tuple[int, int, int],
    hi: tuple[int, int, int],
    dtype: Any = np.float32,
    strict: bool = False,
) -> np.ndarray:
    """Points ``lo..=hi`` of the Zarr array at `path` (`component`), read on the worker; a
    chunk that cannot be read is named in the error, and so is an absent one if `strict`."""
    import zarr

    if dtype is np.float32:
        # Values to mesh: decoded by zarrs without the GIL (zarr-python's reads share it,
        # and two threads read barely faster than one).
        return _read_zarr_block(path, component, lo, hi, strict)
    z = zarr.open_array(path, mode="r", path=component or "")
    if strict:
        _refuse_absent(z, path, lo, hi)
    region = tuple(slice(lo[a], hi[a] + 1) for a in range(3))
    try:
        return np.asarray(z[region], dtype=dtype)
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


def _refuse_absent(z: Any, path: str, lo: tuple[int, int, int], hi: tuple[int, int, int]) -> None:
    """An error naming the first chunk (a shard, for sharded arrays) of points ``lo..=hi``
    that the store does not hold."""
    from zarr.core.sync import sync

    grid = getattr(z, "shards", None) or z.chunks
    prefix = f"{z.path}/" if z.path else ""
    for i in range(lo[0] // grid[0], hi[0] // grid[0] + 1):
        for j in range(lo[1] // grid[1], hi[1] // grid[1] + 1):
            for k in range(lo[2] // grid[2], hi[2] // grid[2] + 1):
                key = z.metadata.encode_chunk_key((i, j, k))
                if not sync(z.store.exists(prefix + key)):
                    raise FormatError(
                        f"{path}: chunk '{key}' (chunk grid indices {i}, {j}, {k}): absent "
                        f"(strict: not read as the fill value {z.fill_value})"
                    )


def _merge_task(shape: tuple[int, int, int], *chunks: bytes) -> bytes:
    return bytes(_merge_chunks(shape, list(chunks)))


def _chunk_meshes(
    array: Any,
    level: float,
    *,
    component: str | None,
    split_every: int,
    strict: bool,
    **kwargs: Any,
) -> tuple[dict[tuple[int, int, int], Any], tuple[int, int, int], dict[str, Any]]:
    """The tasks meshing each chunk's cells (by the chunk's place in the grid of chunks that
    own cells), the volume's shape and the options passed to every task."""
    import dask.array as da
    from dask.delayed import delayed

    if isinstance(array, (str, os.PathLike)):
        array = _zarr_array(os.fspath(array), component, strict=strict)
    elif not isinstance(array, da.Array):
        raise InputError("`array` must be a dask array or the path of a Zarr store")
    if array.ndim != 3:
        raise InputError(f"the volume must have three dimensions, not {array.ndim}")
    if int(split_every) < 2:
        raise InputError("`split_every` must be at least 2")
    shape = (int(array.shape[0]), int(array.shape[1]), int(array.shape[2]))
    if min(shape) < 2:
        raise InputError("every axis of the volume needs at least two points")
    # Each chunk is read once; its neighbours send it the `depth` points around it (dask's
    # overlap: thin slices, not whole chunks). Its last cell needs the point after the chunk,
    # and the halo is counted from there: one more than the halo. Chunks thinner than the
    # depth are first joined.
    # (No more than the axis holds: dask's overlap refuses that, and it reaches the ends.)
    reach = halo(kwargs["method"], kwargs["normals"]) + 1
    depth = tuple(min(reach, n - 1) for n in shape)
    if any(min(c) < d for c, d in zip(array.chunks, depth)):
        from dask.array.overlap import ensure_minimum_chunksize

        array = array.rechunk(
            tuple(ensure_minimum_chunksize(d, c) for c, d in zip(array.chunks, depth))
        )
    options: dict[str, Any] = dict(
        level=float(level),
        spacing=_triple("spacing", kwargs["spacing"]),
        origin=_triple("origin", kwargs["origin"]),
        method=kwargs["method"],
        topology=kwargs["topology"],
        triangulate=kwargs["triangulate"],
        snap=float(kwargs["snap"]),
        zero_threshold=float(kwargs["zero_threshold"]),
        snap_position=kwargs["snap_position"],
        flip=bool(kwargs["flip"]),
        normals=bool(kwargs["normals"]),
    )
    mesh_task = delayed(_mesh_task, pure=True)
    overlapped = da.overlap.overlap(array, depth={a: depth[a] for a in range(3)}, boundary="none")
    blocks = overlapped.to_delayed()
    edges = [np.cumsum([0, *c]) for c in array.chunks]
    # Per chunk: the task meshing the cells it owns (those whose first point it holds; none
    # for a last chunk of one point) from its block.
    parts: dict[tuple[int, int, int], Any] = {}
    for index in np.ndindex(*blocks.shape):
        first = [int(edges[a][index[a]]) for a in range(3)]
        lo = tuple(min(first[a], shape[a] - 1) for a in range(3))
        hi = tuple(min(int(edges[a][index[a] + 1]), shape[a] - 1) for a in range(3))
        if any(lo[a] == hi[a] for a in range(3)):
            continue
        at = tuple(max(0, first[a] - depth[a]) for a in range(3))
        parts[(index[0], index[1], index[2])] = mesh_task(
            blocks[index], at, shape=shape, lo=lo, hi=hi, **options
        )
    firsts = [sorted({p[a] for p in parts}) for a in range(3)]
    parts = {
        (firsts[0].index(p[0]), firsts[1].index(p[1]), firsts[2].index(p[2])): t
        for p, t in parts.items()
    }
    return parts, shape, options


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
    strict: bool = False,
    split_every: int = 4,
    compute: bool = True,
    scheduler: Any = None,
    allow_empty: bool = False,
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
    strict : bool
        For a Zarr path: an absent chunk is an error naming it, not the fill value (which
        the Zarr specification makes it, and zarr-python leaves chunks of the fill value
        unwritten).
    split_every : int
        How many neighbouring chunk meshes one merge task welds (the tree's fan-in).
    compute : bool
        Compute now and return the :class:`~isocube.Mesh`, or return a ``dask.delayed`` that
        computes it.
    scheduler : optional
        Passed to Dask's ``compute`` (``"threads"``, ``"processes"``, ``"sync"``, a
        ``distributed.Client``); by default Dask's current one (a ``Client``'s once made).
    allow_empty : bool
        As :func:`isocube.extract`: without it, a mesh computed empty raises
        :class:`~isocube.EmptySurfaceError` naming the values' range (found then, in one more
        pass over the chunks). A delayed result (``compute=False``) is returned as computed.

    Returns
    -------
    Mesh, or dask.delayed.Delayed of one
        Its ``stats`` hold the counts summed over the chunks and ``seconds``, the wall time.

    Raises
    ------
    EmptySurfaceError
        No cell crosses the level (unless `allow_empty`), as :func:`isocube.extract`.

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
    from dask.delayed import delayed

    started = time.perf_counter()
    parts, shape, options = _chunk_meshes(
        array,
        level,
        spacing=spacing,
        origin=origin,
        method=method,
        topology=topology,
        triangulate=triangulate,
        snap=snap,
        zero_threshold=zero_threshold,
        snap_position=snap_position,
        flip=flip,
        normals=normals,
        component=component,
        strict=strict,
        split_every=split_every,
    )
    matrix = None if direction is None else _matrix(direction)
    bands, layout = _bands_and_layout(parts, shape, int(split_every))
    place = delayed(_place_task, pure=True)
    placed = delayed(_placed_task, pure=True)
    pieces = [
        placed(
            band,
            place(layout, i),
            origin=options["origin"],
            normals=options["normals"],
            direction=matrix,
        )
        for i, band in enumerate(bands)
    ]
    result = delayed(_assemble_task, pure=True)(layout, options["normals"], *pieces)
    if not compute:
        return result
    mesh: Mesh = result.compute(scheduler=scheduler)
    if len(mesh.triangles) == 0 and not allow_empty:
        raise _why_empty(array, component, strict, float(level), scheduler)
    mesh.stats["seconds"] = time.perf_counter() - started
    return mesh


def _why_empty(
    array: Any, component: str | None, strict: bool, level: float, scheduler: Any
) -> InputError:
    """The error :func:`isocube.extract` raises for an empty surface, from the chunks' range."""
    import dask.array as da
    from dask.base import compute

    if isinstance(array, (str, os.PathLike)):
        array = _zarr_array(os.fspath(array), component, strict=strict)
    lo, hi = compute(da.nanmin(array), da.nanmax(array), scheduler=scheduler)
    return empty_surface(level, lo, hi, hint=" (pass allow_empty=True for the empty mesh)")


def write_ply(
    array: Any,
    path: str | os.PathLike[str],
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
    strict: bool = False,
    split_every: int = 4,
    compute: bool = True,
    scheduler: Any = None,
) -> Any:
    """Writes the isosurface of a chunked volume to a binary PLY file from the workers,
    without ever gathering the mesh: for meshes larger than any one machine's memory.

    The file holds, byte for byte, what ``isocube.extract(volume, ...).save(path)`` (and the
    ``isocube extract`` command) write for the whole volume. The chunk meshes are joined along
    the array's last axis into bands (each a line of chunks: no bigger than that line's mesh),
    and only each band's *outline* travels to one task — where its rows of cells end and its
    vertices on faces other bands share (a few percent of its bytes) — which lays out the
    whole mesh: who owns each shared vertex, where each band's runs of rows go. Each band then
    writes its own vertices and triangles at their offsets in the file. Every worker must see
    `path`'s directory (one machine's disk, or a shared filesystem on a cluster: NFS, Lustre,
    GPFS…). The file is written under a temporary name beside `path` and renamed when whole;
    writes are positioned and repeat identically when Dask runs a task again.

    A single PLY rather than fragments and a manifest: it is the file a single pass writes,
    every mesh tool opens it, and the canonical order (rows of cells) needs no welding later.

    Parameters
    ----------
    array, level, spacing, origin, direction, method, topology, triangulate, snap,
    zero_threshold, snap_position, flip, normals, component, strict, split_every, scheduler
        As :func:`extract`.
    path : str or os.PathLike
        The PLY file to write.
    compute : bool
        Write now and return the counts, or return a ``dask.delayed`` that writes the file
        and computes them (a failed computation then leaves its temporary file, named
        ``.NAME.*.tmp`` beside `path`, for the caller to remove).

    Returns
    -------
    dict, or dask.delayed.Delayed of one
        ``vertices``, ``triangles``, the counts :func:`extract` puts in ``Mesh.stats``,
        ``layout_bytes`` (what the outlines sent to the layout task weighed) and ``seconds``.

    Examples
    --------
    >>> import os, tempfile
    >>> import numpy as np, dask.array as da
    >>> import isocube, isocube.dask
    >>> x, y, z = np.mgrid[-1:1:40j, -1:1:40j, -1:1:40j]
    >>> volume = (np.sqrt(x**2 + y**2 + z**2) - 0.7).astype(np.float32)
    >>> out = tempfile.mkdtemp()
    >>> stats = isocube.dask.write_ply(da.from_array(volume, chunks=16), os.path.join(out, "a.ply"))
    >>> isocube.extract(volume, 0.0).save(os.path.join(out, "b.ply"))
    >>> stats["triangles"] == isocube.extract(volume, 0.0).triangles.shape[0]
    True
    >>> a, b = (open(os.path.join(out, n), "rb").read() for n in ("a.ply", "b.ply"))
    >>> a == b
    True
    """
    from dask.delayed import delayed

    started = time.perf_counter()
    target = os.path.abspath(os.fspath(path))
    parts, shape, options = _chunk_meshes(
        array,
        level,
        spacing=spacing,
        origin=origin,
        method=method,
        topology=topology,
        triangulate=triangulate,
        snap=snap,
        zero_threshold=zero_threshold,
        snap_position=snap_position,
        flip=flip,
        normals=normals,
        component=component,
        strict=strict,
        split_every=split_every,
    )
    matrix = None if direction is None else _matrix(direction)
    bands, layout = _bands_and_layout(parts, shape, int(split_every))
    folder, name = os.path.split(target)
    temporary = os.path.join(folder, f".{name}.{uuid.uuid4().hex}.tmp")
    created = delayed(_create_task, pure=True)(temporary, layout, options["normals"])
    place = delayed(_place_task, pure=True)
    write = delayed(_write_task, pure=True)
    written = [
        write(
            temporary,
            band,
            place(layout, i),
            created,
            origin=options["origin"],
            normals=options["normals"],
            direction=matrix,
        )
        for i, band in enumerate(bands)
    ]
    done = delayed(_rename_task, pure=True)(temporary, target, layout, *written)
    if not compute:
        return done
    try:
        stats: dict[str, Any] = done.compute(scheduler=scheduler)
    except BaseException:
        if os.path.exists(temporary):
            os.remove(temporary)
        raise
    stats["seconds"] = time.perf_counter() - started
    return stats


def _bands_and_layout(
    parts: dict[tuple[int, int, int], Any], shape: tuple[int, int, int], split_every: int
) -> tuple[list[Any], Any]:
    """The chunk meshes joined along the array's last axis into bands (lines of chunks), and
    the task laying out the whole mesh from the bands' outlines."""
    from dask.delayed import delayed

    merge_task = delayed(_merge_task, pure=True)
    joined = _merge_along(parts, lambda *members: merge_task(shape, *members), split_every, 2)
    bands = [joined[k] for k in sorted(joined)]
    outline = delayed(_outline_task, pure=True)
    layout = delayed(_layout_task, pure=True)(shape, *(outline(b, shape) for b in bands))
    return bands, layout


def _placed_task(band: bytes, place: bytes, **kwargs: Any) -> bytes:
    return bytes(_place_chunk(band, place, **kwargs))


def _assemble_task(layout: tuple[Any, ...], normals: bool, *pieces: bytes) -> Mesh:
    vertices, triangles, stats, _ = layout
    v, t, n = _assemble_pieces(vertices, triangles, normals, list(pieces))
    stats = {k: x for k, x in stats.items() if k != "layout_bytes"}
    return Mesh(v, t, n, None, stats)


def _outline_task(chunk: bytes, shape: tuple[int, int, int]) -> bytes:
    return bytes(_chunk_outline(chunk, shape))


def _layout_task(shape: tuple[int, int, int], *outlines: bytes) -> tuple[Any, ...]:
    vertices, triangles, stats, places = _join_layout(shape, list(outlines))
    stats["layout_bytes"] = sum(len(o) for o in outlines)
    return vertices, triangles, stats, [bytes(p) for p in places]


def _create_task(path: str, layout: tuple[Any, ...], normals: bool) -> bool:
    _create_ply(path, layout[0], layout[1], normals)
    return True


def _place_task(layout: tuple[Any, ...], index: int) -> bytes:
    place: bytes = layout[3][index]
    return place


def _write_task(
    path: str, chunk: bytes, place: bytes, created: bool, **kwargs: Any
) -> tuple[int, int]:
    vertices, triangles = _write_ply_chunk(path, chunk, place, **kwargs)
    return int(vertices), int(triangles)


def _rename_task(
    temporary: str, path: str, layout: tuple[Any, ...], *written: tuple[int, int]
) -> dict[str, Any]:
    vertices, triangles, stats, _ = layout
    if (sum(w[0] for w in written), sum(w[1] for w in written)) != (vertices, triangles):
        raise InputError(f"{path}: the bands wrote other counts than the layout's")
    os.replace(temporary, path)
    return {"vertices": vertices, "triangles": triangles, **stats}


def _tree(parts: dict[tuple[int, int, int], Any], merge: Any, split_every: int) -> Any:
    """Merges the chunk tasks at `parts` (by their place in the grid of chunks) in a tree:
    neighbours along the last axis first, then the middle, then the first, `split_every` at a
    time; every merge's boxes tile a box."""
    for axis in (2, 1, 0):
        parts = _merge_along(parts, merge, split_every, axis)
    (root,) = parts.values()
    return root


def _merge_along(
    parts: dict[tuple[int, int, int], Any], merge: Any, split_every: int, axis: int
) -> dict[tuple[int, int, int], Any]:
    """Merges the tasks at `parts` along `axis` until one is left in each line of that axis."""
    count = len({p[axis] for p in parts})
    while count > 1:
        merged: dict[tuple[int, int, int], Any] = {}
        groups = range(0, count, split_every)
        for place in list(parts):
            if place[axis] != 0:
                continue
            for g, start in enumerate(groups):
                members = []
                for n in range(start, min(start + split_every, count)):
                    p = list(place)
                    p[axis] = n
                    members.append(parts[(p[0], p[1], p[2])])
                q = list(place)
                q[axis] = g
                merged[(q[0], q[1], q[2])] = merge(*members) if len(members) > 1 else members[0]
        parts = merged
        count = len(groups)
    return parts


def _first_seen(
    block: Any, at: tuple[int, int, int], shape: tuple[int, int, int]
) -> dict[int, int]:
    """Each label of a block and where a pass over the whole volume (first axis fastest) meets
    it first; an error for a value that is not an integer."""
    a = np.asarray(block)
    if a.dtype.kind == "f":
        bad = ~np.isfinite(a) | (a != np.round(a))
        if bad.any():
            i, j, k = (int(x) for x in np.argwhere(bad)[0])
            point = (i + at[0], j + at[1], k + at[2])
            raise InputError(f"point {point} holds {a[i, j, k]}, which is not an integer label")
    flat = a.ravel(order="F")
    labels, first = np.unique(flat, return_index=True)
    ii, jj, kk = np.unravel_index(first, a.shape, order="F")
    where = (ii + at[0]) + shape[0] * ((jj + at[1]) + shape[1] * (kk + at[2]))
    return {int(label): int(w) for label, w in zip(labels.tolist(), where.tolist())}


def _union_first_seen(*tables: dict[int, int]) -> dict[int, int]:
    out: dict[int, int] = {}
    for table in tables:
        for label, where in table.items():
            if label not in out or where < out[label]:
                out[label] = where
    return out


def _mesh_label_task(
    block: Any, names: np.ndarray, at: tuple[int, int, int], **kwargs: Any
) -> bytes:
    a = np.asarray(block)
    order = np.argsort(names, kind="stable")
    sorted_names = names[order]
    ids = (order[np.searchsorted(sorted_names, a.astype(np.int64))] + 1).astype(np.uint32)
    return bytes(_mesh_label_block(ids, at, names=[int(n) for n in names], **kwargs))


def _merge_label_task(shape: tuple[int, int, int], *chunks: bytes) -> bytes:
    return bytes(_merge_label_chunks(shape, list(chunks)))


def _finish_label_task(
    chunk: bytes, shape: tuple[int, int, int], names: np.ndarray, **kwargs: Any
) -> dict[int, Mesh]:
    surfaces = _finish_label_chunks(chunk, shape, [int(n) for n in names], **kwargs)
    return {label: Mesh(v, t, n) for label, v, t, n in surfaces}


def label_surfaces(
    labels: Any,
    *,
    spacing: ArrayLike = (1.0, 1.0, 1.0),
    origin: ArrayLike = (0.0, 0.0, 0.0),
    background: int = 0,
    only: Sequence[int] | None = None,
    smoothing: int = 60,
    component: str | None = None,
    strict: bool = False,
    split_every: int = 4,
    scheduler: Any = None,
) -> dict[int, Mesh]:
    """Every label's closed surface of a chunked segmentation on Dask:
    :func:`isocube.label_surfaces`'s meshes of the whole array.

    A first pass finds the labels in the order a pass over the whole array meets them (a small
    table per chunk); then each chunk meshes its cells from its points and the plane after
    them (label cells read no further), the chunk meshes are merged by key in a tree, and the
    smoothing, which moves vertices over the whole mesh, runs on the merged surfaces.

    Parameters
    ----------
    labels : dask.array.Array, or str or os.PathLike
        Integer labels indexed ``[i, j, k]`` (floats must hold integers), or the path of a
        Zarr array that the workers read themselves.
    spacing, origin, background, only, smoothing
        As :func:`isocube.label_surfaces`.
    component, strict, split_every, scheduler
        As :func:`extract`.

    Returns
    -------
    dict of int to Mesh

    Examples
    --------
    >>> import numpy as np, dask.array as da
    >>> import isocube, isocube.dask
    >>> seg = np.zeros((20, 18, 16), np.uint16)
    >>> seg[2:9, 3:15, 2:14], seg[9:17, 3:15, 2:14] = 7, 3
    >>> surfaces = isocube.dask.label_surfaces(da.from_array(seg, chunks=6), scheduler="sync")
    >>> whole = isocube.label_surfaces(seg)
    >>> sorted(surfaces), all((surfaces[k].vertices == whole[k].vertices).all() for k in whole)
    ([3, 7], True)
    """
    import dask.array as da
    from dask.base import compute
    from dask.delayed import delayed

    if isinstance(labels, (str, os.PathLike)):
        labels = _zarr_array(os.fspath(labels), component, dtype=None, strict=strict)
    elif not isinstance(labels, da.Array):
        raise InputError("`labels` must be a dask array or the path of a Zarr store")
    if labels.ndim != 3:
        raise InputError(f"the labels must have three dimensions, not {labels.ndim}")
    if int(split_every) < 2:
        raise InputError("`split_every` must be at least 2")
    shape = (int(labels.shape[0]), int(labels.shape[1]), int(labels.shape[2]))
    # Where each label is first met, chunk by chunk, then over all: the labels' numbers.
    edges = [np.cumsum([0, *c]) for c in labels.chunks]
    chunks = labels.to_delayed()
    seen = delayed(_first_seen, pure=True)
    tables = [
        seen(chunks[index], tuple(int(edges[a][index[a]]) for a in range(3)), shape)
        for index in np.ndindex(*chunks.shape)
    ]
    (first,) = compute(delayed(_union_first_seen, pure=True)(*tables), scheduler=scheduler)
    names = np.array(sorted(first, key=first.__getitem__), dtype=np.int64)
    if np.abs(names).max(initial=0) > 9.0e15:
        raise InputError("labels beyond 9e15 in magnitude cannot be meshed")
    names_task = delayed(names, pure=True)
    # Padded cells (the volume ringed by one layer of outside points): chunk c owns those
    # from its first point + 1 to the next chunk's; it reads its points and the next plane.
    overlapped = da.overlap.overlap(
        labels, depth={a: min(1, shape[a] - 1) for a in range(3)}, boundary="none"
    )
    blocks = overlapped.to_delayed()
    bounds = [[0, *(int(e) + 1 for e in edges[a][1:-1]), shape[a] + 1] for a in range(3)]
    options = dict(
        spacing=_triple("spacing", spacing),
        origin=_triple("origin", origin),
        background=int(background),
        only=None if only is None else [int(x) for x in only],
    )
    mesh_task = delayed(_mesh_label_task, pure=True)
    parts: dict[tuple[int, int, int], Any] = {}
    for index in np.ndindex(*blocks.shape):
        lo = tuple(bounds[a][index[a]] for a in range(3))
        hi = tuple(bounds[a][index[a] + 1] for a in range(3))
        at = tuple(max(0, int(edges[a][index[a]]) - 1) for a in range(3))
        parts[(index[0], index[1], index[2])] = mesh_task(
            blocks[index], names_task, at, shape=shape, lo=lo, hi=hi, **options
        )
    merge_task = delayed(_merge_label_task, pure=True)
    root = _tree(parts, lambda *members: merge_task(shape, *members), int(split_every))
    result = delayed(_finish_label_task, pure=True)(
        root,
        shape,
        names_task,
        spacing=options["spacing"],
        origin=options["origin"],
        background=options["background"],
        only=options["only"],
        smoothing=int(smoothing),
    )
    surfaces: dict[int, Mesh] = result.compute(scheduler=scheduler)
    return surfaces
