"""One peer's end-to-end run, in its own process: read FILE, extract the level, write a binary
PLY. Prints the milliseconds from before the read to after the write (the interpreter's start
and the imports are not counted) and the triangle count.

    python e2e_peer.py vtk|skimage|pymcubes FILE AXES LEVEL OUT.ply

AXES is `zyx` for arrays saved a[z, y, x] (x fastest) and `xyz` for a[x, y, z]; other formats
say their own layout.
"""
import os
import sys
import time

import numpy as np


def load_npy(path, axes):
    """The array with x fastest, a[z, y, x], as every peer needs it."""
    a = np.load(path)
    if axes == "xyz":
        a = np.ascontiguousarray(a.transpose(2, 1, 0))
    return a


def vtk_run(path, axes, level, out):
    import vtk
    from vtk.util import numpy_support

    vtk.vtkSMPTools.SetBackend("STDThread")
    vtk.vtkSMPTools.Initialize(os.cpu_count())
    start = time.perf_counter()
    if path.endswith(".npy"):
        a = load_npy(path, axes)
        nz, ny, nx = a.shape
        image = vtk.vtkImageData()
        image.SetDimensions(nx, ny, nz)
        image.GetPointData().SetScalars(numpy_support.numpy_to_vtk(a.ravel(), deep=0))
        source = None
    else:
        if path.endswith((".nii", ".nii.gz")):
            source = vtk.vtkNIFTIImageReader()
        elif path.endswith((".mha", ".mhd")):
            source = vtk.vtkMetaImageReader()
        elif path.endswith(".vti"):
            source = vtk.vtkXMLImageDataReader()
        else:
            raise SystemExit(f"no VTK reader for {path}")
        source.SetFileName(path)
    fe = vtk.vtkFlyingEdges3D()
    if source is None:
        fe.SetInputData(image)
    else:
        fe.SetInputConnection(source.GetOutputPort())
    fe.SetValue(0, level)
    fe.ComputeNormalsOn()
    writer = vtk.vtkPLYWriter()
    writer.SetFileName(out)
    writer.SetFileTypeToBinary()
    writer.SetInputConnection(fe.GetOutputPort())
    writer.Write()
    ms = (time.perf_counter() - start) * 1e3
    return ms, fe.GetOutput().GetNumberOfPolys()


def export_ply(verts, faces, normals, out):
    import trimesh

    kw = {} if normals is None else {"vertex_normals": normals}
    trimesh.Trimesh(verts, faces, process=False, **kw).export(out)


def skimage_run(path, axes, level, out):
    from skimage import measure

    start = time.perf_counter()
    a = np.load(path)
    verts, faces, normals, _ = measure.marching_cubes(a, level)
    if axes == "zyx":
        verts, normals = verts[:, ::-1], normals[:, ::-1]
    export_ply(verts, faces, normals, out)
    return (time.perf_counter() - start) * 1e3, len(faces)


def pymcubes_run(path, axes, level, out):
    import mcubes

    start = time.perf_counter()
    a = np.load(path)
    verts, faces = mcubes.marching_cubes(a.astype(np.float64, copy=False), level)
    if axes == "zyx":
        verts = verts[:, ::-1]
    export_ply(verts, faces, None, out)
    return (time.perf_counter() - start) * 1e3, len(faces)


def main():
    tool, path, axes, level, out = sys.argv[1:6]
    run = {"vtk": vtk_run, "skimage": skimage_run, "pymcubes": pymcubes_run}[tool]
    ms, tris = run(path, axes, float(level), out)
    print(f"{ms:.3f} {tris}")


if __name__ == "__main__":
    main()
