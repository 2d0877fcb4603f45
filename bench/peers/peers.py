"""Times isocube and its peers on the same volumes, extraction only, in one run, and prints a
Markdown table: the time of a plain read of the volume (the memory-bandwidth floor), isocube's
extraction, and each peer's with the ratio peer / isocube, plus triangle counts.

    python peers.py ISOCUBE_TIMING_BINARY LEVEL:PATH ...

Peers: VTK's vtkFlyingEdges3D (SMP backend STDThread, all cores), scikit-image's
marching_cubes, PyMCubes. Normals and other extras are off everywhere.
"""
import json
import os
import subprocess
import sys
import time

import numpy as np


def best(runs, f):
    t = []
    out = None
    for _ in range(runs):
        s = time.perf_counter()
        out = f()
        t.append(time.perf_counter() - s)
    return min(t) * 1e3, out


def vtk_flying_edges(volume, level):
    import vtk
    from vtk.util import numpy_support

    vtk.vtkSMPTools.SetBackend("STDThread")
    vtk.vtkSMPTools.Initialize(os.cpu_count())
    nz, ny, nx = volume.shape
    image = vtk.vtkImageData()
    image.SetDimensions(nx, ny, nz)
    scalars = numpy_support.numpy_to_vtk(volume.ravel(), deep=1)
    image.GetPointData().SetScalars(scalars)
    fe = vtk.vtkFlyingEdges3D()
    fe.SetInputData(image)
    fe.SetValue(0, level)
    fe.ComputeNormalsOff()
    fe.ComputeGradientsOff()
    fe.ComputeScalarsOff()

    def run():
        fe.Modified()
        fe.Update()
        return fe.GetOutput().GetNumberOfPolys()

    ms, tris = best(5, run)
    return ms, tris, f"{vtk.vtkSMPTools.GetBackend()}×{vtk.vtkSMPTools.GetEstimatedNumberOfThreads()}"


def skimage_mc(volume, level):
    from skimage import measure

    ms, out = best(3, lambda: measure.marching_cubes(volume, level))
    return ms, len(out[1])


def pymcubes(volume, level):
    import mcubes

    ms, out = best(3, lambda: mcubes.marching_cubes(volume.astype(np.float64, copy=False), level))
    return ms, len(out[1])


def main():
    binary, specs = sys.argv[1], sys.argv[2:]
    ours = {}
    for line in subprocess.run([binary, *specs], check=True, capture_output=True, text=True).stdout.splitlines():
        r = json.loads(line)
        ours[r["path"]] = r
    rows = []
    backend = ""
    for spec in specs:
        level, path = spec.split(":", 1)
        level = float(level)
        volume = np.load(path)
        if volume.dtype != np.float32:
            # Every tool gets the same float volume; isocube converts integer volumes on reading.
            volume = volume.astype(np.float32)
        me = ours[path]
        fe_ms, fe_tris, backend = vtk_flying_edges(volume, level)
        sk_ms, sk_tris = skimage_mc(volume, level)
        pm_ms, pm_tris = pymcubes(volume, level)
        rows.append(
            f"| {os.path.basename(path)} | {me['read_ms']:.1f} | **{me['extract_ms']:.1f}** | "
            f"{fe_ms:.1f} ({fe_ms / me['extract_ms']:.2f}×) | {sk_ms:.0f} ({sk_ms / me['extract_ms']:.1f}×) | "
            f"{pm_ms:.0f} ({pm_ms / me['extract_ms']:.1f}×) | {me['triangles']} / {fe_tris} / {sk_tris} / {pm_tris} |"
        )
    print(f"isocube threads: {next(iter(ours.values()))['threads']}; VTK backend: {backend}\n")
    print("| volume | plain read ms | isocube ms | vtkFlyingEdges3D ms (÷ isocube) | scikit-image ms | PyMCubes ms | triangles: isocube / VTK / skimage / PyMCubes |")
    print("|---|---:|---:|---:|---:|---:|---|")
    for r in rows:
        print(r)


if __name__ == "__main__":
    main()
