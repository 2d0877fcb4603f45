"""Loads every mesh listed in a manifest (path, vertices, triangles, has-values) with readers
that share no code with isocube, and checks what they see against what isocube reported and
against the binary PLY of the same surface (positions, normals, values)."""

import sys
from pathlib import Path

import numpy as np

failures = []


def check(cond, what):
    print(("ok    " if cond else "FAIL  ") + what)
    if not cond:
        failures.append(what)


def trimesh_load(path):
    import trimesh

    return trimesh.load(path, process=False, force="mesh")


def vtk_arrays(output):
    from vtk.util.numpy_support import vtk_to_numpy

    points = vtk_to_numpy(output.GetPoints().GetData())
    polys = vtk_to_numpy(output.GetPolys().GetConnectivityArray()).reshape(-1, 3)
    data = output.GetPointData()
    arrays = {
        data.GetArrayName(i): vtk_to_numpy(data.GetArray(i))
        for i in range(data.GetNumberOfArrays())
    }
    return points, polys, arrays


def load(path):
    """(positions, triangles, normals or None, values or None, reader) for one file."""
    ext = path.suffix
    if ext == ".ply":
        import meshio

        m = meshio.read(path)
        tris = np.concatenate([c.data for c in m.cells if c.type == "triangle"])
        d = m.point_data
        normals = np.stack([d["nx"], d["ny"], d["nz"]], axis=1) if "nx" in d else None
        extra = [k for k in d if k not in ("nx", "ny", "nz")]
        values = d[extra[0]] if extra else None
        return m.points, tris, normals, values, "meshio"
    if ext in (".obj", ".off"):
        m = trimesh_load(path)
        return np.asarray(m.vertices), np.asarray(m.faces), None, None, "trimesh"
    if ext == ".stl":
        m = trimesh_load(path)
        return np.asarray(m.vertices), np.asarray(m.faces), None, None, "trimesh"
    if ext == ".glb":
        # trimesh for the geometry and the custom attribute; VTK's glTF reader for the normals
        # (trimesh recomputes its own).
        import vtk

        m = trimesh_load(path)
        values = m.vertex_attributes.get("_VALUE")
        values = None if values is None else np.ravel(values)
        r = vtk.vtkGLTFReader()
        r.SetFileName(str(path))
        r.Update()
        it = r.GetOutput().NewIterator()
        it.InitTraversal()
        _, _, arrays = vtk_arrays(it.GetCurrentDataObject())
        return np.asarray(m.vertices), np.asarray(m.faces), arrays.get("NORMAL"), values, "trimesh + VTK"
    if ext in (".vtp", ".vtk"):
        import vtk

        r = vtk.vtkXMLPolyDataReader() if ext == ".vtp" else vtk.vtkPolyDataReader()
        r.SetFileName(str(path))
        r.Update()
        points, polys, arrays = vtk_arrays(r.GetOutput())
        values = [v for k, v in arrays.items() if k != "Normals"]
        reader = "VTK XML" if ext == ".vtp" else "VTK legacy"
        return points, polys, arrays.get("Normals"), values[0] if values else None, reader
    if ext == ".msh":
        import gmsh

        gmsh.initialize()
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.open(str(path))
        tags, coords, _ = gmsh.model.mesh.getNodes()
        order = np.argsort(tags)
        points = coords.reshape(-1, 3)[order]
        _, _, nodes = gmsh.model.mesh.getElements(2)
        tris = nodes[0].reshape(-1, 3).astype(np.int64) - 1
        views = {}
        for v in gmsh.view.getTags():
            name = gmsh.option.getString(f"View[{gmsh.view.getIndex(v)}].Name")
            _, node_tags, data, _, comps = gmsh.view.getModelData(v, 0)
            arr = np.asarray(data).reshape(len(node_tags), -1)
            views[name] = arr[np.argsort(node_tags)]
        gmsh.finalize()
        values = [v[:, 0] for k, v in views.items() if k != "Normals"]
        return points, tris, views.get("Normals"), values[0] if values else None, "gmsh"
    raise ValueError(path)


def main(manifest):
    rows = [line.split() for line in Path(manifest).read_text().splitlines() if line.strip()]
    reference = {}
    for path, v, t, has_values in rows:
        path = Path(path)
        v, t, has_values = int(v), int(t), has_values != "0"
        points, tris, normals, values, reader = load(path)
        name = f"{path.name} ({reader})"
        check(len(tris) == t, f"{name}: {len(tris)} triangles, isocube wrote {t}")
        if path.suffix == ".stl":
            # STL stores three corners per triangle; the positions are those of the PLY.
            check(len(points) == 3 * t, f"{name}: {len(points)} corners = 3 × {t}")
            ref = reference.get(path.stem)
            if ref is not None:
                corners = ref[0][ref[1]].reshape(-1, 3)
                err = np.abs(points - corners).max()
                check(err == 0, f"{name}: corners equal the PLY's (max diff {err:g})")
            continue
        check(len(points) == v, f"{name}: {len(points)} vertices, isocube wrote {v}")
        if path.suffix == ".ply":
            reference[path.stem] = (points, tris, normals, values)
            continue
        ref = reference[path.stem]
        err = np.abs(points - ref[0]).max()
        # Text formats print the shortest decimal that reads back as the same f32.
        check(err <= 1e-6 * max(1.0, np.abs(ref[0]).max()), f"{name}: positions equal the PLY's (max diff {err:g})")
        check(np.array_equal(tris, ref[1]), f"{name}: triangles equal the PLY's")
        if normals is not None:
            err = np.abs(np.asarray(normals) - ref[2]).max()
            check(err <= 1e-6, f"{name}: normals equal the PLY's (max diff {err:g})")
        if has_values:
            check(values is not None and len(values) == v, f"{name}: one value per vertex")
            if values is not None:
                a, b = np.asarray(values, dtype=np.float64), np.asarray(ref[3], dtype=np.float64)
                same = np.array_equal(np.isnan(a), np.isnan(b)) and np.allclose(a[~np.isnan(a)], b[~np.isnan(b)], rtol=1e-6, atol=0)
                check(same, f"{name}: values equal the PLY's")
    if failures:
        print(f"{len(failures)} check(s) failed")
        sys.exit(1)
    print(f"all {len(rows)} files read back by independent readers")


if __name__ == "__main__":
    main(sys.argv[1])
