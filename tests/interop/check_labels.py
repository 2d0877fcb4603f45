"""Reads isocube's multi-material tetrahedral meshes (`tetmesh --labels`) back with meshio and
gmsh, and checks the regions and the interfaces independently of isocube.

    python check_labels.py MANIFEST

Each manifest line: `path vertices boundary_triangles interface_triangles label:count ...`.
Checks, per file: the vertex count; every tetrahedron positive; each label's tetrahedra (by
physical group, MEDIT reference, `.vtu` cell data `label`, or Abaqus element set `LABEL_<l>`)
counted as isocube reported; where the format carries the triangles (.msh, .mesh), the
boundary and interface groups' sizes, every interface triangle a face of exactly one
tetrahedron on each of its two sides, every boundary triangle a face of one tetrahedron of its
label, and the tetrahedra's volume equal to what the boundary encloses. For .msh, gmsh's own
count of every physical group too.
"""

from __future__ import annotations

import sys

import meshio
import numpy as np
from check_tets import enclosed, signed_volumes

FACES = np.array([[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]])


def holders(tets: np.ndarray, labels: np.ndarray) -> dict[tuple[int, ...], list[int]]:
    """Each face (sorted corners) and the labels of the tetrahedra holding it."""
    out: dict[tuple[int, ...], list[int]] = {}
    for k in range(4):
        faces = np.sort(tets[:, FACES[k]], axis=1)
        for face, label in zip(map(tuple, faces), labels):
            out.setdefault(face, []).append(int(label))
    return out


def read(path: str) -> tuple[meshio.Mesh, np.ndarray, np.ndarray]:
    """The mesh, its tetrahedra and each one's label."""
    m = meshio.read(path, file_format="gmsh" if path.endswith(".msh") else None)
    blocks = [(i, c) for i, c in enumerate(m.cells) if c.type == "tetra"]
    tets = np.concatenate([c.data for _, c in blocks])
    if path.endswith(".msh"):
        names = {tag: name for name, (tag, dim) in m.field_data.items() if dim == 3}
        tags = np.concatenate([m.cell_data["gmsh:physical"][i] for i, _ in blocks])
        labels = np.array([int(names[int(t)].split()[1]) for t in tags])
    elif path.endswith(".mesh"):
        names = {}
        refs = np.concatenate([m.cell_data["medit:ref"][i] for i, _ in blocks])
        labels = refs.astype(np.int64)  # the group number; mapped below by count
    elif path.endswith(".vtu"):
        labels = np.concatenate(m.cell_data["label"]).astype(np.int64)
    else:  # Abaqus
        # One cell block per `*Element` keyword: a set lists its members block by block.
        starts = np.cumsum([0] + [len(c.data) for c in m.cells])
        labels = np.zeros(len(tets), np.int64)
        for name, per_block in m.cell_sets.items():
            if name.startswith("LABEL_"):
                for start, elements in zip(starts, per_block):
                    labels[start + np.asarray(elements, dtype=np.int64)] = int(
                        name[len("LABEL_") :].replace("M", "-")
                    )
    return m, tets, labels


def check(path: str, vertices: int, boundary: int, interfaces: int, counts: dict[int, int]) -> None:
    m, tets, labels = read(path)
    assert len(m.points) == vertices, (path, len(m.points), vertices)
    vol = signed_volumes(m.points, tets)
    assert (vol > 0).all(), (path, int((vol <= 0).sum()))
    if path.endswith(".mesh"):
        # References are group numbers 1.. in increasing label order.
        order = sorted(counts)
        labels = np.array([order[r - 1] for r in labels])
    found = {int(l): int(c) for l, c in zip(*np.unique(labels, return_counts=True))}
    assert found == counts, (path, found, counts)
    if path.endswith(".inp"):
        # Element-based surfaces: sides in sets <SURFACE>_S1..S4, one side per triangle.
        sides = {"BOUNDARY": 0, "INTERFACE": 0}
        for name, per_block in m.cell_sets.items():
            group, _, side = name.rpartition("_S")
            kind = group.split("_")[0]
            if kind in sides and side.isdigit():
                sides[kind] += sum(len(e) for e in per_block)
        assert sides == {"BOUNDARY": boundary, "INTERFACE": interfaces}, (path, sides)
    if path.endswith((".msh", ".mesh")):
        tri_blocks = [(i, c) for i, c in enumerate(m.cells) if c.type == "triangle"]
        tris = np.concatenate([c.data for _, c in tri_blocks])
        if path.endswith(".msh"):
            names = {tag: name for name, (tag, dim) in m.field_data.items() if dim == 2}
            tags = np.concatenate([m.cell_data["gmsh:physical"][i] for i, _ in tri_blocks])
            kinds = [names[int(t)] for t in tags]
        else:
            refs = np.concatenate([m.cell_data["medit:ref"][i] for i, _ in tri_blocks])
            # Which references are interfaces: their triangles are held twice.
            kinds = []
        face_labels = holders(tets, labels)
        held = [face_labels[tuple(sorted(t))] for t in tris]
        n_interface = sum(1 for h in held if len(h) == 2)
        n_boundary = sum(1 for h in held if len(h) == 1)
        assert (n_boundary, n_interface) == (boundary, interfaces), (path, n_boundary, n_interface)
        assert all(len(h) == 2 and h[0] != h[1] or len(h) == 1 for h in held), path
        for kind, h in zip(kinds, held):
            if kind.startswith("interface"):
                a, b = (int(x) for x in kind.split()[1].split("|"))
                assert sorted(h) == sorted([a, b]), (path, kind, h)
            else:
                assert h == [int(kind.split()[1])], (path, kind, h)
        outer = np.array([t for t, h in zip(tris, held) if len(h) == 1])
        total = vol.sum()
        assert abs(total - enclosed(m.points, outer)) <= 1e-6 * abs(total), path
        if path.endswith(".mesh"):
            assert len(set(int(r) for r in refs)) >= 2, path
    if path.endswith(".msh"):
        import gmsh

        gmsh.initialize()
        try:
            gmsh.option.setNumber("General.Terminal", 0)
            gmsh.open(path)

            def elements(dim: int, entity: int) -> int:
                _, blocks, _ = gmsh.model.mesh.getElements(dim, entity)
                return sum(len(b) for b in blocks)

            groups = {
                gmsh.model.getPhysicalName(dim, tag): sum(
                    elements(dim, e) for e in gmsh.model.getEntitiesForPhysicalGroup(dim, tag)
                )
                for dim, tag in gmsh.model.getPhysicalGroups()
            }
        finally:
            gmsh.finalize()
        for label, count in counts.items():
            assert groups[f"label {label}"] == count, (path, label, groups)
        assert sum(c for n, c in groups.items() if n.startswith("interface")) == interfaces, groups
        assert sum(c for n, c in groups.items() if n.endswith("boundary")) == boundary, groups


def main() -> None:
    checked = 0
    with open(sys.argv[1]) as manifest:
        for line in manifest:
            path, vertices, boundary, interfaces, *pairs = line.split()
            counts = {int(k): int(v) for k, v in (p.split(":") for p in pairs)}
            check(path, int(vertices), int(boundary), int(interfaces), counts)
            checked += 1
    print(f"{checked} multi-material tetrahedral meshes read back by meshio and gmsh")


if __name__ == "__main__":
    main()
