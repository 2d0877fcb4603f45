"""Isosurfaces that are correct, good and fast, from NumPy arrays.

isocube extracts watertight isosurfaces with Marching Cubes 33's topology (the trilinear
interpolant's), or with ternary snapping (grid points near the level become surface vertices,
so no triangle is a sliver). Arrays are read where they lie, whatever their memory order, and
the meshes come back as arrays that own the engine's buffers.

>>> import numpy as np
>>> import isocube
>>> x, y, z = np.mgrid[-1:1:32j, -1:1:32j, -1:1:32j]
>>> mesh = isocube.extract(np.sqrt(x**2 + y**2 + z**2) - 0.8, spacing=(2 / 31,) * 3)
>>> mesh.triangles.shape[1], mesh.vertices.dtype.name
(3, 'float32')
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from . import contours
from ._arrays import ArrayLike, _labels, _matrix, _triple, _volume
from ._errors import EmptySurfaceError, LevelOutsideError
from ._errors import empty_surface as _empty_surface
from ._isocube import Error, FormatError, InputError, MemoryLimitError, __version__
from ._isocube import extract as _extract
from ._isocube import label_surfaces as _label_surfaces
from ._isocube import marching_cubes as _marching_cubes
from ._isocube import read_volume as _read_volume
from ._isocube import resolve_level as _resolve_level
from ._mesh import Mesh
from ._progress import _progress_bar
from ._subdiv import PolyMesh, subdivide
from ._tables import tables
from ._tets import TetMesh, tetmesh

__all__ = [
    "EmptySurfaceError",
    "Error",
    "FormatError",
    "InputError",
    "LevelOutsideError",
    "MemoryLimitError",
    "Mesh",
    "PolyMesh",
    "TetMesh",
    "Volume",
    "__version__",
    "contours",
    "extract",
    "label_surfaces",
    "marching_cubes",
    "read_volume",
    "subdivide",
    "tables",
    "tetmesh",
]


def extract(
    volume: ArrayLike,
    level: float | str = 0.0,
    *,
    spacing: ArrayLike = (1.0, 1.0, 1.0),
    origin: ArrayLike = (0.0, 0.0, 0.0),
    method: str = "mc",
    topology: str = "mc33",
    triangulate: str = "fan",
    relax: int = 0,
    snap: float = 0.3,
    zero_threshold: float = 0.0,
    snap_position: str = "crossing",
    flip: bool = False,
    normals: bool = True,
    values: bool = False,
    chunk: tuple[int, int, int] | None = None,
    max_memory: int | None = None,
    direction: ArrayLike | None = None,
    progress: bool | Callable[[int, int], object] = False,
    allow_empty: bool = False,
) -> Mesh:
    """Extracts the isosurface of `volume` at `level`.

    Parameters
    ----------
    volume : (M, N, P) array_like
        The field; ``float32`` arrays are read where they lie (C or Fortran order, views,
        ``np.memmap``), other dtypes are converted first.
    level : float or str
        The isovalue, or one taken from the values as ``isocube extract --level`` takes it:
        ``'auto'`` (Otsu's threshold of their 256-bin histogram) or ``'40%'`` (that fraction of
        their range, from the smallest).
    spacing, origin : three floats
        Distance between neighbouring points along each array axis, and the position of
        ``volume[0, 0, 0]``.
    method : {'mc', 'ternary'}
        Marching Cubes, or ternary extraction (grid points near the level snapped onto the
        surface).
    topology : {'mc33', 'classic'}
        The trilinear interpolant's topology (watertight, no ambiguity left), or the classic
        table's.
    triangulate : {'fan', 'local', 'optimal'}
        How each cell's polygons become triangles.
    relax : int
        Relaxation sweeps after extraction: vertices slide along the level set towards
        better-shaped triangles (flips and splits keep the mesh close to it; none turns over).
    snap, zero_threshold, snap_position
        Ternary: snap a grid point when a crossing lies within this fraction of an edge; count
        values this close to the level as on it; put a snapped point's vertex on the grid point
        (``'grid'``) or the nearest crossing (``'crossing'``).
    flip : bool
        Face the triangles towards the side below the level.
    normals, values : bool
        Compute vertex normals (from the gradient) and values (see :class:`Mesh`).
    chunk : (int, int, int), optional
        Mesh boxes of this many cells along each array axis, in parallel, joined by their
        vertices' grid keys: the same mesh, array for array, as without (the unit of work for
        volumes cut into chunks).
    max_memory : int, optional
        Refuse work whose mesh would need more bytes than this.
    direction : (3, 3) array_like, optional
        How the array's axes lie in the world (column ``a``: the unit vector of axis ``a``, as
        :func:`read_volume` gives it): vertices are turned about `origin`, normals with them,
        and a reflection keeps the triangles facing the side above the level.
    progress : bool or callable
        ``True`` shows a progress bar (tqdm's if installed, else a line on stderr); a callable
        is called as ``progress(cells_done, cells_total)`` a few times a second while the work
        runs (an exception it raises stops the work and is raised here). Ctrl-C stops the work
        within a fraction of a second either way (``KeyboardInterrupt``).
    allow_empty : bool
        Return an empty mesh when no cell crosses the level, instead of raising
        :class:`EmptySurfaceError` (as ``isocube extract --allow-empty``).

    Returns
    -------
    Mesh

    Raises
    ------
    EmptySurfaceError
        No cell crosses the level (unless `allow_empty`); the message gives the values' range.
        Also a ``RuntimeError``; :class:`LevelOutsideError` (also a ``ValueError``) when the
        level lies outside the values.
    InputError
        A bad option or a volume that cannot be meshed.
    MemoryLimitError
        The mesh would need more than `max_memory` bytes.

    Examples
    --------
    >>> import numpy as np
    >>> import isocube
    >>> x, y, z = np.mgrid[-1:1:40j, -1:1:40j, -1:1:40j]
    >>> r = np.sqrt(x**2 + y**2 + z**2)
    >>> mesh = isocube.extract(r, 0.7, method="ternary", snap=0.3)
    >>> mesh.is_watertight()
    True
    >>> isocube.extract(r, "auto").is_watertight()  # Otsu's threshold of the values
    True
    """
    a = _volume(volume)
    if isinstance(level, str):
        level = _resolve_level(a, level)
    with _progress_bar(progress, "isocube.extract") as report:
        v, t, n, vals, stats = _extract(
            a,
            float(level),
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
            values=bool(values),
            max_memory=max_memory,
            direction=None if direction is None else _matrix(direction),
            progress=report,
            relax=int(relax),
            chunk=None if chunk is None else _chunk(chunk),
            allow_empty=bool(allow_empty),
        )
    return Mesh(v, t, n, vals, stats)


def _chunk(chunk: tuple[int, int, int]) -> tuple[int, int, int]:
    c = tuple(int(x) for x in chunk)
    if len(c) != 3 or min(c) < 1:
        raise InputError(f"`chunk` must be three cell counts of at least 1, not {chunk}")
    return (c[0], c[1], c[2])


@dataclass
class Volume:
    """A volume read from a file: values indexed ``[x, y, z]`` and where they lie.

    Attributes
    ----------
    values : (X, Y, Z) float32 ndarray
        In the file's memory order (``x`` fastest, as most volume files store it; a ``.npy``
        saved in C order as a view with ``z`` fastest), owning the reader's buffer: meshed in
        that order, as ``isocube extract`` meshes the file, so :meth:`extract` writes its bytes.
    spacing, origin : tuple of three floats
    direction : (3, 3) list
        Column ``a`` is the world vector of axis ``a`` (identity for files without one).

    Examples
    --------
    >>> import os, tempfile
    >>> import numpy as np
    >>> import isocube
    >>> path = os.path.join(tempfile.mkdtemp(), "cube.npy")
    >>> np.save(path, np.arange(27, dtype=np.float32).reshape(3, 3, 3))
    >>> volume = isocube.read_volume(path)
    >>> volume.values.shape, volume.values[1, 0, 0]
    ((3, 3, 3), np.float32(9.0))
    >>> volume.extract(13.5).is_watertight()
    False
    """

    values: np.ndarray
    spacing: tuple[float, float, float]
    origin: tuple[float, float, float]
    direction: list[list[float]]

    def extract(self, level: float | str = 0.0, **options: Any) -> Mesh:
        """:func:`extract` with the volume's spacing, origin and direction."""
        return extract(
            self.values,
            level,
            spacing=self.spacing,
            origin=self.origin,
            direction=self.direction,
            **options,
        )


def read_volume(
    path: str | os.PathLike[str],
    *,
    spacing: ArrayLike | None = None,
    origin: ArrayLike | None = None,
    max_memory: int | None = None,
    npy_axes: str = "xyz",
    frame: int | None = None,
    channel: int | None = None,
) -> Volume:
    """Reads a volume file as ``isocube extract`` does: by extension ``.npy``, ``.nrrd`` /
    ``.nhdr``, ``.nii`` / ``.nii.gz`` (NIfTI-1 and NIfTI-2), ``.mnc`` / ``.mnc.gz`` (MINC-1),
    ``.mha`` / ``.mhd``, ``.tif`` / ``.tiff`` (a stack), ``.vti``, ``.dcm`` (one DICOM file:
    multi-frame, RT Dose, SEG as labels); a folder as a DICOM series (sorted along its normal,
    rescaled) or a Zarr store.

    Parameters
    ----------
    path : path-like
    spacing, origin : three floats, optional
        Override the file's.
    max_memory : int, optional
        Refuse files whose reading would take more bytes (checked before allocating).
    npy_axes : {'xyz', 'zyx'}
        How a ``.npy`` array's axes map to x, y, z.
    frame, channel : int, optional
        Of a file holding several 3-d volumes (4-d or 5-d NIfTI, a DICOM series over time, an
        OME-Zarr ``t``/``c`` axis), the one to read; where there are several and none is given,
        :class:`FormatError` names the choice.

    Raises
    ------
    FormatError
        The file cannot be read: the message names it, the position and why.
    MemoryLimitError
        Reading would take more than `max_memory`.

    Examples
    --------
    See :class:`Volume`.
    """
    values, s, o, d = _read_volume(
        os.fspath(path),
        spacing=None if spacing is None else _triple("spacing", spacing),
        origin=None if origin is None else _triple("origin", origin),
        max_memory=max_memory,
        npy_axes=npy_axes,
        frame=frame,
        channel=channel,
    )
    return Volume(values, (s[0], s[1], s[2]), (o[0], o[1], o[2]), [list(row) for row in d])


def marching_cubes(
    volume: np.ndarray,
    level: float | None = None,
    *,
    spacing: ArrayLike = (1.0, 1.0, 1.0),
    gradient_direction: str = "descent",
    step_size: int = 1,
    allow_degenerate: bool = True,
    method: str = "lewiner",
    mask: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A drop-in for :func:`skimage.measure.marching_cubes`, watertight.

    Takes the same arguments and raises the same exceptions; ``method='lewiner'`` meshes with
    Marching Cubes 33's topology, ``'lorensen'`` with the classic table's.

    Parameters
    ----------
    volume : (M, N, P) ndarray
    level : float, optional
        The isovalue; by default halfway between the volume's smallest and largest value.
    spacing : three floats
    gradient_direction : {'descent', 'ascent'}
        As scikit-image: with ``'descent'`` the triangles face the side above the level,
        with ``'ascent'`` the side below; the normals point down the gradient either way.
    step_size : int
        Mesh every `step_size`-th point along each axis (a coarser, faster surface, still
        watertight); the vertices stay in the full volume's index space, as scikit-image's.
    allow_degenerate : bool
        With ``False``, triangles of no area are removed.
    method : {'lewiner', 'lorensen'}
    mask : (M, N, P) bool ndarray, optional
        Only the cubes whose last corner (largest index on every axis) is ``True`` are meshed,
        as scikit-image does.

    Returns
    -------
    verts : (V, 3) ndarray
        float32, or float64 when scaled by a float64 `spacing` (as scikit-image).
    faces : (F, 3) int32 ndarray
    normals : (V, 3) float32 ndarray
    values : (V,) float32 ndarray

    Examples
    --------
    >>> import numpy as np
    >>> import isocube
    >>> x, y, z = np.mgrid[-1:1:20j, -1:1:20j, -1:1:20j]
    >>> verts, faces, normals, values = isocube.marching_cubes(x**2 + y**2 + z**2, 0.5)
    >>> verts.shape[1], faces.dtype.name
    (3, 'int32')
    """
    if method == "lorensen":
        topology = "classic"
    elif method == "lewiner":
        topology = "mc33"
    else:
        raise ValueError("method should be either 'lewiner' or 'lorensen'")
    if not isinstance(volume, np.ndarray) or volume.ndim != 3:
        raise ValueError("Input volume should be a 3D numpy array.")
    if volume.shape[0] < 2 or volume.shape[1] < 2 or volume.shape[2] < 2:
        raise ValueError("Input array must be at least 2x2x2.")
    if level is not None:
        level = float(level)
    if len(spacing) != 3:
        raise ValueError("`spacing` must consist of three floats.")
    step_size = int(step_size)
    if step_size < 1:
        raise ValueError("step_size must be at least one.")
    if gradient_direction not in ("descent", "ascent"):
        raise ValueError(
            f"Incorrect input {gradient_direction} in `gradient_direction`, see docstring."
        )
    if mask is not None and mask.shape != volume.shape:
        raise ValueError("volume and mask must have the same shape.")
    if step_size > 1:
        # Every step_size-th point: a strided view, read in place. The default level is the
        # whole volume's, as scikit-image takes it.
        if level is None:
            a = _volume(volume)
            level = float(np.float32(0.5) * (np.nanmin(a) + np.nanmax(a)))
        volume = volume[::step_size, ::step_size, ::step_size]
        if mask is not None:
            mask = mask[::step_size, ::step_size, ::step_size]
    # The level's range check, the mesh, the faces' turn and dtype, in one pass of the engine.
    verts, faces, normals, values = _marching_cubes(
        _volume(volume), level, topology=topology, descent=gradient_direction == "descent"
    )
    keep: np.ndarray | None = None
    if mask is not None:
        keep = _cubes_kept(verts, faces, np.asarray(mask, dtype=bool))
    if not allow_degenerate:
        p = verts[faces].astype(np.float64)
        area2 = np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
        keep = area2 > 0 if keep is None else keep & (area2 > 0)
    if mask is not None and keep is not None and not keep.any():
        # scikit-image finds no vertex in the cubes the mask keeps and raises.
        raise EmptySurfaceError(_masked_out(volume, level))
    if keep is not None and not keep.all():
        verts, faces, normals, values = _compact(verts, faces[keep], normals, values)
    if step_size > 1:
        verts *= np.float32(step_size)
    if not np.array_equal(spacing, (1, 1, 1)):
        # As scikit-image: scaled after meshing (float64 results for float64 spacings).
        verts = verts * np.r_[spacing]
    return verts, faces, normals, values


def _masked_out(volume: np.ndarray, level: float | None) -> EmptySurfaceError:
    """Why a mask left no surface, in the words of the unmasked case."""
    a = _volume(volume)
    lo, hi = np.nanmin(a), np.nanmax(a)
    used = float(np.float32(0.5) * (lo + hi)) if level is None else float(level)
    e = _empty_surface(used, lo, hi, lead="No surface found at the given iso value: ", hint=".")
    # Inside the range (scikit-image checked that): a surface the mask leaves out.
    return EmptySurfaceError(str(e).replace("no cell crosses", "no cube the mask keeps crosses"))


def _cubes_kept(verts: np.ndarray, faces: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Which triangles lie in a cube whose last corner the mask keeps (index space)."""
    centroid = verts[faces].astype(np.float64).mean(axis=1)
    upper = np.minimum(np.floor(centroid).astype(np.int64) + 1, np.array(mask.shape) - 1)
    upper = np.maximum(upper, 1)
    kept: np.ndarray = mask[upper[:, 0], upper[:, 1], upper[:, 2]]
    return kept


def _compact(
    verts: np.ndarray, faces: np.ndarray, normals: np.ndarray, values: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The vertices `faces` use, renumbered in order."""
    used = np.zeros(len(verts), bool)
    used[faces.ravel()] = True
    number = (np.cumsum(used) - 1).astype(np.int32)
    return verts[used], number[faces], normals[used], values[used]


def label_surfaces(
    labels: ArrayLike,
    *,
    spacing: ArrayLike = (1.0, 1.0, 1.0),
    origin: ArrayLike = (0.0, 0.0, 0.0),
    background: int = 0,
    only: Sequence[int] | None = None,
    smoothing: int = 60,
) -> dict[int, Mesh]:
    """The closed surface of every label of a segmentation, as ``isocube extract --labels``.

    Neighbouring labels share their interface: the same vertices and triangles, facing
    opposite ways, so the surfaces fit together with no gap or overlap.

    Parameters
    ----------
    labels : (M, N, P) array_like of integers
        The segmentation (integer values up to 2**24 in magnitude; floats must be integers).
    spacing, origin : three floats
    background : int
        The label that is not meshed (the surroundings).
    only : sequence of int, optional
        Mesh these labels only (the others still bound them).
    smoothing : int
        Smoothing sweeps (0 keeps the voxels' staircase); a vertex never moves more than a
        cell along any axis.

    Returns
    -------
    dict of int to Mesh
        Each label's surface, triangles facing out of the label, in increasing label order.

    Raises
    ------
    InputError
        A value that is not an integer, or one too large to be held exactly.

    Examples
    --------
    >>> import numpy as np
    >>> import isocube
    >>> seg = np.zeros((8, 6, 6), np.uint8)
    >>> seg[1:4, 1:5, 1:5] = 1
    >>> seg[4:7, 1:5, 1:5] = 2
    >>> surfaces = isocube.label_surfaces(seg, smoothing=0)
    >>> sorted(surfaces), all(m.is_watertight() for m in surfaces.values())
    ([1, 2], True)
    """
    surfaces = _label_surfaces(
        _labels(labels),
        spacing=_triple("spacing", spacing),
        origin=_triple("origin", origin),
        background=int(background),
        only=None if only is None else [int(x) for x in only],
        smoothing=int(smoothing),
    )
    return {label: Mesh(v, t, n) for label, v, t, n in surfaces}
