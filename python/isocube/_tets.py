"""Volume meshes: tetrahedra of the region inside an isosurface, or of each label."""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable
from typing import Any

import numpy as np

from . import _isocube
from ._arrays import ArrayLike, _labels, _matrix, _triple, _volume
from ._isocube import InputError
from ._progress import _progress_bar


class TetMesh:
    """Tetrahedra filling the region inside an isosurface (or each label of a segmentation),
    made by :func:`tetmesh`.

    The arrays are read-only views of the buffers the mesher filled (no copy); they stay valid
    as long as any of them, or the mesh, is referenced.

    Attributes
    ----------
    vertices : (V, 3) float32 ndarray
        The surface's vertices first (``surface_vertices`` of them, the positions
        :func:`extract` gives with the same options), then the grid points inside the region,
        then points added inside cut cells.
    tets : (T, 4) uint32 ndarray
        Tetrahedra, each positively oriented: ``(b - a) · ((c - a) × (d - a)) > 0``.
    surface : (F, 3) uint32 ndarray
        The isosurface's triangles, facing out of the region: the boundary of the tetrahedra
        together with `walls`.
    walls : (W, 3) uint32 ndarray
        Boundary triangles where the region meets the grid's outer faces, facing out.
    surface_vertices : int
        How many of the first vertices are the surface's.
    tet_labels, surface_labels : (T,) and (F,) int64 ndarray or None
        For a segmentation: the label of each tetrahedron, and the label each surface
        triangle bounds.
    interfaces : (I, 3) uint32 ndarray or None
        For a segmentation: the triangles where two labels meet (inner faces of the mesh).
    interface_labels : (I, 2) int64 ndarray or None
        The two labels on either side of each interface triangle (the first is the one it
        faces out of).
    stats : dict
        Counts (``lattice_cells``, ``cut_cells``, ``grid_points``, ``steiner_points``; graded:
        ``cubes``, ``largest_cube`` (cells on a side) and ``cube_tets``, ``cells_too_long``
        when the cells are longer than 3:1 and the interior stays uniform; the
        improvement's ``flips_23``, ``moved_points``, ``widened`` (elements worked on around
        those left outside [10°, 165°]), ... and the surface's) and ``seconds``.
    """

    def __init__(self, mesh: _isocube.TetMesh) -> None:
        self._mesh = mesh
        self.vertices: np.ndarray = mesh.vertices
        self.tets: np.ndarray = mesh.tets
        self.surface: np.ndarray = mesh.surface
        self.walls: np.ndarray = mesh.walls
        self.surface_vertices: int = mesh.surface_vertices
        self.stats: dict[str, float] = mesh.stats
        self.tet_labels: np.ndarray | None = None
        self.surface_labels: np.ndarray | None = None
        self.interfaces: np.ndarray | None = None
        self.interface_labels: np.ndarray | None = None
        labels = mesh.labels
        if labels is not None:
            names, tets, surface, interfaces, pairs = labels
            values = np.asarray(names, dtype=np.int64)
            self.tet_labels = values[tets]
            self.surface_labels = values[surface]
            self.interfaces = interfaces
            self.interface_labels = values[pairs]

    def __repr__(self) -> str:
        return (
            f"TetMesh({len(self.tets)} tetrahedra, {len(self.vertices)} vertices, "
            f"{len(self.surface)} surface + {len(self.walls)} wall triangles)"
        )

    def quality(self) -> dict[str, Any]:
        """Element quality, as ``isocube quality`` reports it: ``min_dihedral`` and
        ``max_dihedral`` (degrees), ``mean_radius_ratio`` and ``max_radius_ratio`` (1 for a
        regular tetrahedron), and ``min_dihedral_histogram`` (elements by smallest dihedral
        angle in 5° bins). ``outside_range`` counts the elements with a dihedral angle
        outside [10°, 165°], sorted as ``isocube tetmesh`` sorts them: ``at_sharp_edges``
        (an edge of the surface sharper than 10°, which no element can widen),
        ``beside_fine_detail`` (surface detail smaller than the snap distance, kept for the
        topology) and ``others``.

        >>> import numpy as np
        >>> import isocube
        >>> x, y, z = np.mgrid[-1:1:20j, -1:1:20j, -1:1:20j]
        >>> q = isocube.tetmesh(x**2 + y**2 + z**2 - 0.6, method="ternary").quality()
        >>> q["min_dihedral"] > 5 and q["max_dihedral"] < 175
        True
        >>> q["outside_range"] == q["at_sharp_edges"] + q["beside_fine_detail"] + q["others"]
        True
        """
        return dict(self._mesh.quality())

    def check(self) -> dict[str, Any]:
        """Checks the mesh: ``conforming`` (every inner face shared by exactly two elements,
        the boundary faces exactly `surface` and `walls`), ``inverted`` and ``flat`` element
        counts, the mesh's ``volume`` and the volume its boundary ``enclosed``.

        >>> import numpy as np
        >>> import isocube
        >>> x, y, z = np.mgrid[-1:1:16j, -1:1:16j, -1:1:16j]
        >>> c = isocube.tetmesh(x**2 + y**2 + z**2 - 0.5).check()
        >>> c["conforming"], c["inverted"], abs(c["volume"] / c["enclosed"] - 1) < 1e-9
        (True, 0, True)
        """
        return dict(self._mesh.check())

    def save(self, path: str | os.PathLike[str], *, binary: bool = False) -> None:
        """Writes the mesh as ``isocube tetmesh`` does, byte for byte: Gmsh ``.msh`` 4.1
        (binary with `binary`), VTK ``.vtu`` (each element's quality as cell data), MEDIT
        ``.mesh`` or Abaqus ``.inp``; physical groups for the region (or each label) and the
        boundaries. Written whole or not at all (a temporary file renamed over the target).

        Raises
        ------
        InputError
            An unknown extension, or `binary` for a text-only format.
        FormatError
            The file could not be written.

        Examples
        --------
        >>> import os, tempfile
        >>> import numpy as np
        >>> import isocube
        >>> x, y, z = np.mgrid[-1:1:12j, -1:1:12j, -1:1:12j]
        >>> path = os.path.join(tempfile.mkdtemp(), "ball.msh")
        >>> isocube.tetmesh(x**2 + y**2 + z**2 - 0.5).save(path)
        >>> open(path).readline().strip()
        '$MeshFormat'
        """
        self._mesh.save(os.fspath(path), binary=bool(binary))

    def to_pyvista(self) -> Any:
        """The mesh as a ``pyvista.UnstructuredGrid`` of tetrahedra (needs `pyvista`), each
        element's label as ``cell_data['label']`` for a segmentation.

        >>> import numpy as np
        >>> import isocube
        >>> x, y, z = np.mgrid[-1:1:12j, -1:1:12j, -1:1:12j]
        >>> grid = isocube.tetmesh(x**2 + y**2 + z**2 - 0.5).to_pyvista()
        >>> bool(grid.volume > 0), grid.n_cells > 0
        (True, True)
        """
        import pyvista

        cells = np.empty((len(self.tets), 5), dtype=np.int64)
        cells[:, 0] = 4
        cells[:, 1:] = self.tets
        kinds = np.full(len(self.tets), pyvista.CellType.TETRA, dtype=np.uint8)
        grid = pyvista.UnstructuredGrid(cells.ravel(), kinds, self.vertices)
        if self.tet_labels is not None:
            grid.cell_data["label"] = self.tet_labels
        return grid

    def to_meshio(self) -> Any:
        """The mesh as a ``meshio.Mesh`` (needs `meshio`): tetrahedra, then the boundary
        triangles (surface and walls) as a second cell block; ``cell_data['label']`` for a
        segmentation (the boundary triangles' labels those of their region, walls 0).

        >>> import numpy as np
        >>> import isocube
        >>> x, y, z = np.mgrid[-1:1:12j, -1:1:12j, -1:1:12j]
        >>> m = isocube.tetmesh(x**2 + y**2 + z**2 - 0.5).to_meshio()
        >>> [block.type for block in m.cells]
        ['tetra', 'triangle']
        """
        import meshio

        boundary = np.concatenate([self.surface, self.walls])
        cell_data: dict[str, list[np.ndarray]] = {}
        if self.tet_labels is not None and self.surface_labels is not None:
            walls = np.zeros(len(self.walls), dtype=np.int64)
            cell_data["label"] = [self.tet_labels, np.concatenate([self.surface_labels, walls])]
        return meshio.Mesh(
            self.vertices,
            [("tetra", self.tets), ("triangle", boundary)],
            cell_data=cell_data,
        )


def tetmesh(
    volume: ArrayLike,
    level: float = 0.0,
    *,
    spacing: ArrayLike = (1.0, 1.0, 1.0),
    origin: ArrayLike = (0.0, 0.0, 0.0),
    direction: ArrayLike | None = None,
    method: str = "ternary",
    topology: str = "mc33",
    triangulate: str = "fan",
    snap: float = 0.3,
    zero_threshold: float = 0.0,
    snap_position: str = "crossing",
    flip: bool = False,
    labels: bool | Iterable[int] = False,
    background: int = 0,
    max_memory: int | None = None,
    max_size: float | str | None = None,
    grading: int = 0,
    uniform: bool = False,
    progress: bool | Callable[[int, int], object] = False,
) -> TetMesh:
    """Fills the region of `volume` below `level` (above it with `flip`) with tetrahedra, as
    ``isocube tetmesh`` does: conforming, every element positively oriented, the boundary
    exactly the isosurface :func:`extract` makes with the same options (plus the grid's outer
    faces where the region meets them). Cells wholly inside are cut into six lattice
    tetrahedra; cells the surface cuts are filled around it, then poor elements are improved
    by flips and points moved or added inside cut cells.

    With `labels` (``True``, or the labels to mesh) the volume is a segmentation and every
    label gets its region, neighbours conforming across their interfaces; `background` is the
    label left out.

    Parameters
    ----------
    volume : (M, N, P) array_like
        Any real dtype (``float32`` in any memory order is read in place).
    level : float
    spacing, origin : three floats
    direction : (3, 3) array_like, optional
        Columns: the world directions of the array's axes (as :func:`read_volume` gives).
    method : {'ternary', 'mc'}
        Ternary snapping (the default; `snap`, `zero_threshold`, `snap_position` as in
        :func:`extract`, snapped points on the nearest crossing by default, as the command's)
        gives good elements with the boundary on the level set: no boundary triangle is a
        sliver. ``'mc'`` keeps Marching Cubes' surface and its slivers.
    topology, triangulate, flip
        As in :func:`extract`.
    labels : bool or iterable of int
    background : int
    max_memory : int, optional
        Refuse (``MemoryLimitError``) a mesh estimated to need more bytes.
    max_size : float or str, optional
        The graded interior's largest cubes, as ``isocube tetmesh --max-size``: away from the
        surface, cells are gathered into cubes of 2, 4, 8, ... cells up to this size, a
        distance in the units of `spacing` or ``'16c'`` for 16 cells (the boundary is
        unchanged; with `labels`, every label's interior, the interfaces unchanged too).
        Default: 16 cells. On cells longer than 3:1 the interior is uniform (the transition
        cubes' elements would leave 10°–165°).
    grading : int
        Cubes of each size keep this many cubes of their size from the cells the surface
        passes through (0: sizes may double from one cube to the next).
    uniform : bool
        Every inside cell six tetrahedra (no `max_size`), as ``--uniform``.
    progress : bool or callable
        As in :func:`extract` (the surface's cells, then the cells filled, out of twice the
        volume's cells). Ctrl-C stops the work within a fraction of a second
        (``KeyboardInterrupt``); a segmentation's mesh runs to its end.

    Returns
    -------
    TetMesh

    Raises
    ------
    InputError
        No grid point inside the region, a label that does not occur, a non-finite value.
    MemoryLimitError

    Examples
    --------
    >>> import numpy as np
    >>> import isocube
    >>> x, y, z = np.mgrid[-1:1:24j, -1:1:24j, -1:1:24j]
    >>> ball = isocube.tetmesh(np.sqrt(x**2 + y**2 + z**2), 0.8)
    >>> ball.tets.shape[1], ball.check()["conforming"]
    (4, True)
    """
    if labels is False:
        a = _volume(volume)
        label_mode, only = False, None
    else:
        a = _labels(volume)
        label_mode, only = True, None if labels is True else [int(x) for x in labels]
    size, in_cells = _max_size(max_size)
    with _progress_bar(progress, "isocube.tetmesh") as report:
        mesh = _isocube.tetmesh(
            a,
            float(level),
            spacing=_triple("spacing", spacing),
            origin=_triple("origin", origin),
            direction=None if direction is None else _matrix(direction),
            method=method,
            topology=topology,
            triangulate=triangulate,
            snap=float(snap),
            zero_threshold=float(zero_threshold),
            snap_position=snap_position,
            flip=bool(flip),
            labels=label_mode,
            only=only,
            background=int(background),
            max_memory=max_memory,
            max_size=size,
            max_size_cells=in_cells,
            grading=int(grading),
            uniform=bool(uniform),
            progress=report,
        )
    return TetMesh(mesh)


def _max_size(max_size: float | str | None) -> tuple[float | None, bool]:
    """`max_size` as a number and whether it counts cells (``'16c'``)."""
    if max_size is None:
        return None, False
    if isinstance(max_size, str):
        text = max_size.strip()
        in_cells = text.endswith("c")
        try:
            return float(text[:-1] if in_cells else text), in_cells
        except ValueError:
            raise InputError(
                f"max_size {max_size!r}: expected a size > 0, in cells ('16c') or in the "
                "units of spacing"
            ) from None
    return float(max_size), False
