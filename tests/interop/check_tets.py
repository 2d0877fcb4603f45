"""Reads isocube's tetrahedral meshes back with meshio (.msh, .vtu, .mesh, .inp) and gmsh (.msh,
.mesh; gmsh reads neither .vtu nor Abaqus input).

    python check_tets.py MANIFEST

Each manifest line: `path tetrahedra vertices surface_triangles wall_triangles`. Checks the
counts, that every tetrahedron has a positive signed volume, that the volumes add up to what the
boundary triangles enclose (divergence theorem), and the physical groups (1 region, 2 surface,
3 walls); for Abaqus, the boundary is the element sides named in the surfaces' element sets.
"""

from __future__ import annotations

import sys

import meshio
import numpy as np


def signed_volumes(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    p = points.astype(np.float64)
    a, b, c, d = (p[tets[:, k]] for k in range(4))
    return np.einsum("ij,ij->i", b - a, np.cross(c - a, d - a)) / 6.0


def enclosed(points: np.ndarray, tris: np.ndarray) -> float:
    p = points.astype(np.float64) - points[0].astype(np.float64)
    a, b, c = (p[tris[:, k]] for k in range(3))
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


# Abaqus C3D4 sides S1..S4 as corner positions.
C3D4_FACES = np.array([[0, 1, 2], [0, 3, 1], [1, 3, 2], [2, 3, 0]])


def check_meshio(path: str, tets: int, vertices: int, surface: int, walls: int) -> None:
    # ".msh" is Ansys's extension too: name the format, or meshio tries that reader first.
    m = meshio.read(path, file_format="gmsh" if path.endswith(".msh") else None)
    assert len(m.points) == vertices, (path, len(m.points), vertices)
    tet = np.concatenate([c.data for c in m.cells if c.type == "tetra"])
    assert len(tet) == tets, (path, len(tet), tets)
    vol = signed_volumes(m.points, tet)
    assert (vol > 0).all(), (path, int((vol <= 0).sum()))
    if path.endswith(".inp"):
        assert len(m.cell_sets["REGION"][0]) == tets, path
        faces = {"SURFACE": [], "WALLS": []}
        for name, (elements,) in m.cell_sets.items():
            group, _, side = name.rpartition("_S")
            if group in faces:
                faces[group].append(tet[elements][:, C3D4_FACES[int(side) - 1]])
        found = {g: sum(len(f) for f in fs) for g, fs in faces.items()}
        assert found == {"SURFACE": surface, "WALLS": walls}, (path, found)
        # The sides' corners run clockwise seen from outside (each face's right-hand normal
        # points to the element's fourth node).
        tri = np.concatenate(faces["SURFACE"] + faces["WALLS"])[:, ::-1]
        total = vol.sum()
        assert abs(total - enclosed(m.points, tri)) <= 1e-6 * abs(total), path
    elif not path.endswith(".vtu"):
        tri = np.concatenate([c.data for c in m.cells if c.type == "triangle"])
        assert len(tri) == surface + walls, (path, len(tri), surface + walls)
        total = vol.sum()
        assert abs(total - enclosed(m.points, tri)) <= 1e-6 * abs(total), path
    if path.endswith(".msh"):
        groups = {name: tag for name, (tag, _dim) in m.field_data.items()}
        assert groups["region"] == 1 and groups["surface"] == 2, (path, groups)
        phys = m.cell_data["gmsh:physical"]
        by_type: dict[str, set[int]] = {}
        for block, tags in zip(m.cells, phys):
            by_type.setdefault(block.type, set()).update(int(t) for t in tags)
        assert by_type["tetra"] == {1}, by_type
        assert by_type["triangle"] <= {2, 3} and 2 in by_type["triangle"], by_type
    if path.endswith(".mesh"):
        refs = m.cell_data["medit:ref"]
        for block, r in zip(m.cells, refs):
            expected = {1} if block.type == "tetra" else {2, 3}
            assert set(int(x) for x in r) <= expected, (path, block.type, set(r))
    if path.endswith(".vtu"):
        region = np.concatenate(m.cell_data["region"])
        assert (region == 1).all(), path
        dihedral = np.concatenate(m.cell_data["min_dihedral"])
        assert len(dihedral) == tets and (dihedral > 0).all(), path


def check_gmsh(path: str, tets: int, vertices: int, surface: int, walls: int) -> None:
    """Opens the file in gmsh and counts elements by group: for .msh the physical groups by
    name; for MEDIT, whose references gmsh turns into elementary entities, by entity (3, 1)
    the region and (2, 2), (2, 3) the boundaries."""
    import gmsh

    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.open(path)
        tags, _, _ = gmsh.model.mesh.getNodes()
        assert len(tags) == vertices, (path, len(tags), vertices)

        def elements(dim: int, entity: int) -> int:
            _, blocks, _ = gmsh.model.mesh.getElements(dim, entity)
            return sum(len(b) for b in blocks)

        if path.endswith(".msh"):
            found = {
                gmsh.model.getPhysicalName(dim, tag): sum(
                    elements(dim, e) for e in gmsh.model.getEntitiesForPhysicalGroup(dim, tag)
                )
                for dim, tag in gmsh.model.getPhysicalGroups()
            }
            expected = {"region": tets, "surface": surface}
            if walls:
                expected["walls"] = walls
        else:
            counts = {(dim, tag): elements(dim, tag) for dim, tag in gmsh.model.getEntities()}
            found = {k: v for k, v in counts.items() if v}
            expected = {(3, 1): tets, (2, 2): surface}
            if walls:
                expected[(2, 3)] = walls
        assert found == expected, (path, found, expected)
    finally:
        gmsh.finalize()


def main() -> None:
    checked = 0
    with open(sys.argv[1]) as manifest:
        for line in manifest:
            path, *numbers = line.split()
            tets, vertices, surface, walls = (int(x) for x in numbers)
            check_meshio(path, tets, vertices, surface, walls)
            if path.endswith((".msh", ".mesh")):
                check_gmsh(path, tets, vertices, surface, walls)
            checked += 1
    print(f"{checked} tetrahedral meshes read back by meshio and gmsh")


if __name__ == "__main__":
    main()
