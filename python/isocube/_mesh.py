"""Triangle meshes: what extract, marching-cubes-style calls and reconstructions give."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ._isocube import save_mesh as _save_mesh


@dataclass
class Mesh:
    """A triangle mesh: the isosurface :func:`extract` makes.

    Attributes
    ----------
    vertices : (V, 3) float32 ndarray
        Vertex positions, in the volume's index order (``volume[i, j, k]`` → ``(i, j, k)``),
        scaled by the spacing and moved by the origin.
    triangles : (F, 3) uint32 ndarray
        Vertex indices, counter-clockwise seen from the side above the level (the side the
        triangles face; with ``flip=True`` the side below).
    normals : (V, 3) float32 ndarray or None
        Unit normals from the field's gradient, towards the side the triangles face.
    values : (V,) float32 ndarray or None
        The larger of the values at the two ends of the grid edge each vertex lies on (inside
        a cell: the largest of its eight corners): the largest value near the vertex.
    stats : dict
        Counts from the extraction (``cells``, ``active_cells``, ``tunnels``,
        ``snapped_points``, ...) and ``seconds``, the engine's time.

    Examples
    --------
    >>> import numpy as np
    >>> import isocube
    >>> volume = np.zeros((4, 4, 4), np.float32)
    >>> volume[1:3, 1:3, 1:3] = 1.0
    >>> mesh = isocube.extract(volume, 0.5)
    >>> mesh.is_watertight()
    True
    >>> len(mesh.triangles), mesh.stats["active_cells"]
    (44, 26)
    """

    vertices: np.ndarray
    triangles: np.ndarray
    normals: np.ndarray | None = None
    values: np.ndarray | None = None
    stats: dict[str, float] = field(default_factory=dict)

    def is_watertight(self) -> bool:
        """Whether every edge is shared by exactly two triangles, in opposite directions.

        >>> import numpy as np
        >>> import isocube
        >>> isocube.extract(np.arange(8.0).reshape(2, 2, 2), 3.5).is_watertight()
        False
        """
        t = self.triangles.astype(np.int64)
        if len(t) == 0:
            return False
        edges = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
        n = np.int64(len(self.vertices))
        directed = edges[:, 0] * n + edges[:, 1]
        reverse = edges[:, 1] * n + edges[:, 0]
        if len(np.unique(directed)) != len(directed):
            return False
        return bool(np.isin(reverse, directed).all())

    def save(
        self, path: str | os.PathLike[str], *, ascii: bool = False, values_name: str = "values"
    ) -> None:
        """Writes the mesh in the format `path`'s extension names: ``.ply``, ``.obj``,
        ``.stl``, ``.off``, ``.glb``, ``.vtp``, ``.vtk`` or ``.msh``, byte for byte what
        ``isocube extract`` writes for the same mesh. The file is written whole or not at all
        (a temporary file renamed over the target). Normals are written where the format holds
        them, values (named `values_name`) by the formats with per-vertex data (PLY, glTF,
        VTK, Gmsh); `ascii` writes PLY as text.

        Raises
        ------
        FormatError
            The file could not be written (its message names the file and why), or the
            format cannot hold the mesh's values.

        Examples
        --------
        >>> import os, tempfile
        >>> import numpy as np
        >>> import isocube
        >>> mesh = isocube.extract(np.arange(8.0).reshape(2, 2, 2), 3.5)
        >>> path = os.path.join(tempfile.mkdtemp(), "cut.ply")
        >>> mesh.save(path)
        >>> open(path, "rb").read(3)
        b'ply'
        """

        def optional(a: np.ndarray | None) -> np.ndarray | None:
            return None if a is None else np.ascontiguousarray(a, dtype=np.float32)

        _save_mesh(
            os.fspath(path),
            np.ascontiguousarray(self.vertices, dtype=np.float32),
            np.ascontiguousarray(self.triangles, dtype=np.uint32),
            optional(self.normals),
            optional(self.values),
            values_name,
            ascii,
        )

    def to_trimesh(self) -> Any:
        """The mesh as a ``trimesh.Trimesh`` (needs the `trimesh` package), normals and
        values (``vertex_attributes['values']``) included, nothing merged or reordered.

        >>> import numpy as np
        >>> import isocube
        >>> x, y, z = np.mgrid[-1:1:24j, -1:1:24j, -1:1:24j]
        >>> isocube.extract(x**2 + y**2 + z**2, 0.5).to_trimesh().is_watertight
        True
        """
        import trimesh

        attributes: dict[str, Any] = {} if self.values is None else {"values": self.values}
        return trimesh.Trimesh(
            vertices=self.vertices,
            faces=self.triangles,
            vertex_normals=self.normals,
            vertex_attributes=attributes,
            process=False,
        )

    def to_pyvista(self) -> Any:
        """The mesh as a ``pyvista.PolyData`` (needs the `pyvista` package), with the normals
        as ``point_data['Normals']`` and values as ``point_data['values']``.

        >>> import numpy as np
        >>> import isocube
        >>> x, y, z = np.mgrid[-1:1:24j, -1:1:24j, -1:1:24j]
        >>> surface = isocube.extract(x**2 + y**2 + z**2, 0.5).to_pyvista()
        >>> surface.n_cells > 0 and surface.is_all_triangles
        True
        """
        import pyvista

        faces = np.empty((len(self.triangles), 4), dtype=np.int64)
        faces[:, 0] = 3
        faces[:, 1:] = self.triangles
        surface = pyvista.PolyData(self.vertices, faces.ravel())
        if self.normals is not None:
            surface.point_data["Normals"] = self.normals
        if self.values is not None:
            surface.point_data["values"] = self.values
        return surface

    def napari(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The ``(vertices, faces, values)`` tuple napari's Surface layer takes.

        >>> import numpy as np
        >>> import isocube
        >>> v, f, values = isocube.extract(np.arange(8.0).reshape(2, 2, 2), 3.5).napari()
        >>> len(values) == len(v)
        True
        """
        values = self.values
        if values is None:
            values = np.zeros(len(self.vertices), np.float32)
        return self.vertices, self.triangles, values
