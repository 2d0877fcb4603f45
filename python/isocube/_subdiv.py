"""Polygon cages with creases, corners, holes and faces with inner loops; Catmull–Clark
subdivision as OpenSubdiv defines it."""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping, Sequence
from typing import Any, Union

import numpy as np

from . import _isocube
from ._mesh import Mesh


class PolyMesh:
    """A polygon mesh with OpenSubdiv's tags: what :func:`subdivide` refines and returns.

    Build one from arrays, read one with :meth:`PolyMesh.read` (``.obj`` with tags, a
    triangle mesh, or a built-in cage), or take an :class:`isocube.Mesh`.

    Parameters
    ----------
    vertices : (V, 3) array_like
    faces : iterable of sequences of int, or (F, k) array_like
        Each face's vertex indices (0-based), counter-clockwise seen from outside.
    creases : dict, optional
        Edge ``(a, b)`` → sharpness (0 smooth, 10 or more infinitely sharp, fractions blend).
    corners : dict, optional
        Vertex → corner sharpness.
    holes : iterable of int, optional
        Faces tagged as holes (left out of the limit surface).
    inner_loops : dict, optional
        Face → its inner loops (a face with holes, as booleans of solids make).
    boundary : {'edge-only', 'edge-and-corner', 'none'}, optional
        How open boundaries are refined.

    Examples
    --------
    >>> import isocube
    >>> square = isocube.PolyMesh([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], [[0, 1, 2, 3]])
    >>> square.subdivide(2).stats()["faces"]
    16
    """

    def __init__(
        self,
        vertices: Any,
        faces: Iterable[Sequence[int]] | np.ndarray,
        *,
        creases: Mapping[tuple[int, int], float] | None = None,
        corners: Mapping[int, float] | None = None,
        holes: Iterable[int] = (),
        inner_loops: Mapping[int, Sequence[Sequence[int]]] | None = None,
        boundary: str | None = None,
    ) -> None:
        self._mesh = _isocube.poly_mesh(
            np.ascontiguousarray(vertices, dtype=np.float64).reshape(-1, 3),
            [[int(v) for v in face] for face in faces],
            inner_loops=[
                (int(f), [[int(v) for v in loop] for loop in loops])
                for f, loops in (inner_loops or {}).items()
            ],
            creases=[((int(a), int(b)), float(s)) for (a, b), s in (creases or {}).items()],
            corners=[(int(v), float(s)) for v, s in (corners or {}).items()],
            holes=[int(f) for f in holes],
            boundary=boundary,
        )

    @classmethod
    def _wrap(cls, mesh: _isocube.PolyMesh) -> PolyMesh:
        self = cls.__new__(cls)
        self._mesh = mesh
        return self

    @classmethod
    def read(cls, path: str | os.PathLike[str]) -> PolyMesh:
        """A cage from a file — ``.obj`` (polygons and OpenSubdiv's ``t crease``,
        ``t corner``, ``t hole``, ``t interpolateboundary`` tags, isocube's ``t innerloop``)
        or a triangle mesh (``.ply``, ``.stl``, ...) — or a built-in one
        (``"sample:cube"``, ``"sample:plate"``, ``"sample:box-hole"``, ``"sample:boss"``).

        >>> import isocube
        >>> isocube.PolyMesh.read("sample:boss").stats()["faces"] > 0
        True
        """
        return cls._wrap(_isocube.poly_read(os.fspath(path)))

    @property
    def vertices(self) -> np.ndarray:
        """(V, 3) float64 positions."""
        return self._mesh.vertices

    @property
    def faces(self) -> list[np.ndarray]:
        """Each face's outer loop of vertex indices."""
        offsets, indices = self._mesh.faces
        return np.split(indices, offsets[1:-1].astype(np.int64))

    def quads(self) -> np.ndarray:
        """The faces as an (F, 4) uint32 array, when every face is a quad (as after one level
        of subdivision).

        Raises
        ------
        ValueError
            Some face is not a quad.
        """
        offsets, indices = self._mesh.faces
        if not (np.diff(offsets) == 4).all():
            raise ValueError("not every face is a quad")
        quads: np.ndarray = indices.reshape(-1, 4)
        return quads

    @property
    def creases(self) -> dict[tuple[int, int], float]:
        """Edge sharpness, ``(a, b)`` with ``a < b``."""
        return dict(self._mesh.creases)

    @property
    def corners(self) -> dict[int, float]:
        """Vertex corner sharpness."""
        return dict(self._mesh.corners)

    @property
    def holes(self) -> list[int]:
        """Faces tagged as holes."""
        return self._mesh.holes

    @property
    def inner_loops(self) -> dict[int, list[list[int]]]:
        """Face → its inner loops."""
        return dict(self._mesh.inner_loops)

    @property
    def boundary(self) -> str | None:
        """The boundary rule the mesh carries, if any."""
        return self._mesh.boundary

    def stats(self) -> dict[str, int]:
        """Counts: ``vertices``, ``faces``, ``quads``, ``creases``, ``corners``."""
        return dict(self._mesh.stats())

    def subdivide(
        self,
        levels: int = 1,
        *,
        holes: str = "smooth",
        boundary: str | None = None,
        limit: bool = False,
    ) -> PolyMesh:
        """See :func:`isocube.subdivide`."""
        return PolyMesh._wrap(
            self._mesh.subdivide(int(levels), holes=holes, boundary=boundary, limit=bool(limit))
        )

    def triangulate(self) -> Mesh:
        """The faces split into triangles, as an :class:`isocube.Mesh` (what ``.ply`` and
        ``.stl`` files get)."""
        vertices, triangles = self._mesh.triangulate()
        return Mesh(vertices, triangles)

    def to_obj(self) -> str:
        """OBJ text, polygons and tags."""
        return self._mesh.to_obj()

    def save(self, path: str | os.PathLike[str], *, ascii: bool = False) -> None:
        """Writes ``.obj`` (polygons and tags) or a triangle format (``.ply``, ``.stl``,
        ...) byte for byte as ``isocube subdivide`` does, atomically.

        >>> import os, tempfile
        >>> import isocube
        >>> path = os.path.join(tempfile.mkdtemp(), "boss.obj")
        >>> isocube.subdivide("sample:boss", 1).save(path)
        >>> open(path).read().count("\\nf ") > 0
        True
        """
        self._mesh.save(os.fspath(path), ascii=bool(ascii))

    def to_pyvista(self) -> Any:
        """The polygons as a ``pyvista.PolyData`` (needs `pyvista`).

        >>> import isocube
        >>> isocube.subdivide("sample:cube", 2).to_pyvista().n_cells
        96
        """
        import pyvista

        offsets, indices = self._mesh.faces
        sizes = np.diff(offsets).astype(np.int64)
        cells = np.insert(indices.astype(np.int64), offsets[:-1].astype(np.int64), sizes)
        return pyvista.PolyData(self.vertices, cells)

    def __repr__(self) -> str:
        s = self.stats()
        return f"PolyMesh({s['vertices']} vertices, {s['faces']} faces)"


Cage = Union[str, "os.PathLike[str]", PolyMesh, Mesh]


def subdivide(
    cage: Cage,
    levels: int = 1,
    *,
    holes: str = "smooth",
    boundary: str | None = None,
    limit: bool = False,
) -> PolyMesh:
    """Catmull–Clark subdivision as OpenSubdiv's Catmark scheme defines it, as
    ``isocube subdivide`` does: creases and corners (sharpness decreasing by one per level,
    fractional sharpness blending), hole faces, boundary rules, and faces with inner loops.

    Parameters
    ----------
    cage : PolyMesh, Mesh, or path
        A :class:`PolyMesh`, an :class:`isocube.Mesh` (its triangles), a file or a built-in
        cage (see :meth:`PolyMesh.read`).
    levels : int
        Refinement levels (each makes about four faces of each).
    holes : {'smooth', 'sharp'}
        Faces with inner loops: joined and rounded over, or kept sharp with their holes.
    boundary : {'edge-only', 'edge-and-corner', 'none'}, optional
        Overrides the cage's boundary rule.
    limit : bool
        Move the refined vertices to their limit positions.

    Returns
    -------
    PolyMesh

    Raises
    ------
    InputError
        A cage that cannot be refined (a face or tag that is wrong; the message says which).
    MemoryLimitError
        More faces than the library refines (2**28).

    Examples
    --------
    >>> import isocube
    >>> smooth = isocube.subdivide("sample:cube", 3, limit=True)
    >>> smooth.stats()["faces"], smooth.triangulate().is_watertight()
    (384, True)
    """
    if isinstance(cage, PolyMesh):
        poly = cage
    elif isinstance(cage, Mesh):
        poly = PolyMesh(cage.vertices, cage.triangles)
    else:
        poly = PolyMesh.read(cage)
    return poly.subdivide(levels, holes=holes, boundary=boundary, limit=limit)
