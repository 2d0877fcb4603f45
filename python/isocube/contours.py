"""Surfaces and volume meshes through stacks of cross-section contours (mining sections,
segmented slices), as ``isocube contours`` and ``isocube tetmesh`` make them.

A stack is a contour file (``.csv`` with columns ``section,z,contour,x,y``, ``.json``, ``.dxf``),
``"sample:orebody"``, or sections given directly: a sequence of ``(z, contours)`` pairs (or a
``dict`` from ``z`` to contours) in any order, each contour an ``(n, 2)`` array_like
of its points, closed implicitly (the last point joins the first). Inside is decided by the
even–odd rule, so a contour inside another is a hole. The surface passes through every input
point and its cut by each section's plane is that section's contours.

>>> import numpy as np
>>> from isocube import contours
>>> t = np.linspace(0, 2 * np.pi, 24, endpoint=False)
>>> circle = np.c_[np.cos(t), np.sin(t)]
>>> mesh = contours.reconstruct([(0.0, [circle]), (1.0, [0.8 * circle]), (2.0, [circle])])
>>> mesh.is_watertight()
True
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping, Sequence
from typing import Any, Union

import numpy as np

from . import _isocube
from ._mesh import Mesh
from ._tets import TetMesh

__all__ = ["read", "reconstruct", "tetmesh"]

Stack = Union[
    str,
    "os.PathLike[str]",
    Mapping[float, Iterable[Any]],
    Sequence[tuple[float, Iterable[Any]]],
]


def _stack(stack: Stack) -> tuple[str | None, list[tuple[float, list[np.ndarray]]] | None]:
    """A path for the reader, or the sections as float64 point arrays."""
    if isinstance(stack, (str, os.PathLike)):
        return os.fspath(stack), None
    pairs = stack.items() if isinstance(stack, Mapping) else stack
    sections = [
        (float(z), [np.ascontiguousarray(c, dtype=np.float64) for c in contours])
        for z, contours in pairs
    ]
    # In any order, as the files' sections may come (two at one height are an error).
    sections.sort(key=lambda s: s[0])
    return None, sections


def _grid(grid: tuple[int, int] | None) -> tuple[int, int] | None:
    return None if grid is None else (int(grid[0]), int(grid[1]))


def read(
    path: str | os.PathLike[str], *, close: bool = False
) -> list[tuple[float, list[np.ndarray]]]:
    """The sections of a contour file (``.csv``, ``.json``, ``.dxf``, or
    ``"sample:orebody"``): ``(z, contours)`` pairs, lowest first, each contour an ``(n, 2)``
    ``float64`` array, validated as the command line validates them (errors name the section
    and contour). A contour is a closed curve: in CSV and JSON its last point may repeat its
    first or not; an open DXF polyline is refused unless `close` (as ``--close``).

    Raises
    ------
    FormatError
        The file cannot be read, or a contour is invalid (too few points, self-crossing,
        touching another); the message names the file, the line and why.

    Examples
    --------
    >>> from isocube import contours
    >>> sections = contours.read("sample:orebody")
    >>> len(sections) > 3, sections[0][1][0].shape[1]
    (True, 2)
    """
    return _isocube.contours_read(os.fspath(path), bool(close))


def reconstruct(
    stack: Stack,
    *,
    cell: float | None = None,
    grid: tuple[int, int] | None = None,
    cap: str = "extend",
    extend: float | None = None,
    plain: bool = False,
    triangulate: str = "local",
    max_memory: int | None = None,
    close: bool = False,
) -> Mesh:
    """The surface of the body a stack's contours outline, watertight and outward.

    Parameters
    ----------
    stack
        A contour file, ``"sample:orebody"``, or sections (see the module's documentation).
    cell : float, optional
        Square cells of this size in the sections' plane (in the contours' units).
    grid : (int, int), optional
        At most this many cells along x and y over the contours' bounding box (by default
        100 across the longer side).
    cap : {'extend', 'flat', 'none'}
        How the ends close: the body extrapolated `extend` beyond each end section (by
        default half the mean section spacing), the end contours filled flat in their planes,
        or left open.
    plain : bool
        The section-data paper's plain crossings (no contour points inserted).
    triangulate : {'local', 'optimal', 'fan'}
    max_memory : int, optional
        Refuse (``MemoryLimitError``) a reconstruction estimated to need more bytes.
    close : bool
        Close open DXF polylines of a contour file instead of refusing them (``--close``).

    Returns
    -------
    Mesh
        With normals; ``stats`` holds the plane grid used (``plane_dims``, ``cell``), the
        points whose distance was evaluated, and ``unresolved_edges`` / ``missed_contours``
        (places the grid is too coarse to follow).

    Examples
    --------
    >>> from isocube import contours
    >>> mesh = contours.reconstruct("sample:orebody", grid=(40, 40))
    >>> mesh.is_watertight(), mesh.stats["missed_contours"]
    (True, 0)
    """
    path, sections = _stack(stack)
    v, t, n, stats = _isocube.contours_reconstruct(
        path,
        sections,
        cell=None if cell is None else float(cell),
        grid=_grid(grid),
        cap=cap,
        extend=None if extend is None else float(extend),
        plain=bool(plain),
        triangulate=triangulate,
        max_memory=max_memory,
        close=bool(close),
    )
    return Mesh(v, t, n, None, stats)


def tetmesh(
    stack: Stack,
    *,
    cell: float | None = None,
    grid: tuple[int, int] | None = None,
    cap: str = "extend",
    extend: float | None = None,
    layer_spacing: float | str | None = None,
    method: str = "ternary",
    snap: float = 0.3,
    zero_threshold: float = 0.0,
    snap_position: str = "crossing",
    triangulate: str = "fan",
    max_memory: int | None = None,
    close: bool = False,
) -> TetMesh:
    """Tetrahedra of the body a stack's contours outline, as ``isocube tetmesh`` makes them
    from a contour file: conforming, positive, bounded by the body's surface.

    Parameters
    ----------
    stack, cell, grid, cap, extend, close
        As in :func:`reconstruct`.
    layer_spacing : float or 'sections', optional
        Planes between sections at most this far apart (by default the plane grid's cell),
        or ``'sections'`` for planes at the sections only.
    method, snap, zero_threshold, snap_position, triangulate, max_memory
        As in :func:`isocube.tetmesh`.

    Examples
    --------
    >>> from isocube import contours
    >>> body = contours.tetmesh("sample:orebody", grid=(24, 24))
    >>> check = body.check()
    >>> check["conforming"], check["inverted"]
    (True, 0)
    """
    path, sections = _stack(stack)
    mesh = _isocube.contours_tetmesh(
        path,
        sections,
        cell=None if cell is None else float(cell),
        grid=_grid(grid),
        cap=cap,
        extend=None if extend is None else float(extend),
        layer_spacing=None if layer_spacing is None else str(layer_spacing),
        method=method,
        snap=float(snap),
        zero_threshold=float(zero_threshold),
        snap_position=snap_position,
        triangulate=triangulate,
        max_memory=max_memory,
        close=bool(close),
    )
    return TetMesh(mesh)
