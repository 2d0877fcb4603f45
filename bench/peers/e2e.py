"""End to end, file to file: read a volume file, extract, write a binary PLY with normals, each
tool in its own process, best of RUNS (default 3), with its peak resident memory. Prints a
Markdown table.

    python e2e.py ISOCUBE_BINARY LEVEL:PATH ...

PATH is a benchmark volume saved a[z, y, x] (volumes.py). Beside it this writes, once, the
same values as a[x, y, z] (`.xyz.npy`, isocube's default axes), NIfTI (`.nii`, `.nii.gz`),
MetaImage (`.mha`, raw) and VTK ImageData (`.vti`, raw appended), all with VTK's writers.

isocube's time is the whole process (start-up included), measured from outside. The Python
peers' times are measured inside their process from before the read to after the write, so
the interpreter's start and the imports (about 0.2 s for VTK) are not charged to them; their
peak memory includes the interpreter and libraries. VTK reads NIfTI, MetaImage and VTI with its
own readers, `.npy` with `np.load` (transposed to x fastest when saved a[x, y, z]); scikit-image
and PyMCubes run on the `.npy` files only and export through trimesh. `floor` is `cat FILE >
/dev/null` plus copying isocube's PLY: the bytes any tool must move.
"""
import os
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
PEER = os.path.join(HERE, "e2e_peer.py")


def variants(path):
    """Writes the other layouts and formats beside PATH (once) and returns (label, file, axes)."""
    stem = path[: -len(".npy")]
    out = [("npy a[z,y,x] --axes zyx", path, "zyx"), ("npy a[x,y,z]", stem + ".xyz.npy", "xyz")]
    formats = [(".nii", "nii"), (".nii.gz", "nii.gz"), (".mha", "mha"), (".vti", "vti")]
    missing = [ext for ext, _ in formats if not os.path.exists(stem + ext)]
    if missing or not os.path.exists(stem + ".xyz.npy"):
        # In a child process: the peak memory of a child counts its parent's at the fork, so
        # this process stays small.
        subprocess.run([sys.executable, __file__, "--write-variants", path, *missing], check=True)
    out += [(label, stem + ext, "zyx") for ext, label in formats]
    return out


def write_variants(path, stem, missing):
    import numpy as np
    import vtk
    from vtk.util import numpy_support

    a = np.load(path)
    if not os.path.exists(stem + ".xyz.npy"):
        np.save(stem + ".xyz.npy", np.ascontiguousarray(a.transpose(2, 1, 0)))
    nz, ny, nx = a.shape
    image = vtk.vtkImageData()
    image.SetDimensions(nx, ny, nz)
    image.GetPointData().SetScalars(numpy_support.numpy_to_vtk(a.ravel(), deep=1))
    for ext in missing:
        if ext in (".nii", ".nii.gz"):
            w = vtk.vtkNIFTIImageWriter()
        elif ext == ".mha":
            w = vtk.vtkMetaImageWriter()
            w.SetCompression(False)
        else:
            w = vtk.vtkXMLImageDataWriter()
            w.SetCompressorTypeToNone()
            w.SetDataModeToAppended()
            w.EncodeAppendedDataOff()
        w.SetFileName(stem + ext)
        w.SetInputData(image)
        w.Write()


def run(cmd):
    """Runs CMD; returns (wall ms, peak RSS MiB, stdout). A child's peak memory starts at its
    parent's at the fork (Linux), so this process holds no volume."""
    start = time.perf_counter()
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    _, status, usage = os.wait4(p.pid, 0)
    wall = (time.perf_counter() - start) * 1e3
    out, err = p.stdout.read(), p.stderr.read()
    p.stdout.close()
    p.stderr.close()
    p.returncode = os.waitstatus_to_exitcode(status)
    if p.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{err}")
    return wall, usage.ru_maxrss / 1024.0, out


def best(runs, f):
    results = [f() for _ in range(runs)]
    ms = min(r[0] for r in results)
    rss = max(r[1] for r in results)
    return ms, rss, results[-1][2]


def ply_triangles(path):
    with open(path, "rb") as f:
        for line in f:
            if line.startswith(b"element face"):
                return int(line.split()[2])
            if line.startswith(b"end_header"):
                break
    return -1


def main():
    if sys.argv[1] == "--write-variants":
        path = sys.argv[2]
        write_variants(path, path[: -len(".npy")], sys.argv[3:])
        return
    binary, specs = sys.argv[1], sys.argv[2:]
    runs = int(os.environ.get("E2E_RUNS", "3"))
    py = sys.executable
    tmp = tempfile.mkdtemp(prefix="isocube-e2e-")
    ours_out, peer_out, floor_out = (os.path.join(tmp, n) for n in ("ours.ply", "peer.ply", "floor.ply"))
    rows = []
    for spec in specs:
        level, path = spec.split(":", 1)
        for label, file, axes in variants(path):
            cmd = [binary, "extract", file, "--level", level, "-o", ours_out, "--quiet"]
            if file.endswith(".npy") and axes == "zyx":
                cmd += ["--axes", "zyx"]
            me_ms, me_rss, _ = best(runs, lambda: run(cmd))
            me_tris = ply_triangles(ours_out)
            floor = ["sh", "-c", 'cat "$1" > /dev/null; cat "$2" > "$3"', "floor", file, ours_out, floor_out]
            floor_ms = min(run(floor)[0] for _ in range(runs))

            def peer(tool):
                ms, rss, out = best(runs, lambda: run([py, PEER, tool, file, axes, level, peer_out]))
                return float(out.split()[0]), rss, int(out.split()[1])

            vtk_ms, vtk_rss, vtk_tris = peer("vtk")
            cells = [
                f"| {os.path.basename(file)} ({label}) | {floor_ms:.0f} | **{me_ms:.0f}** ({me_rss:.0f}) | "
                f"{vtk_ms:.0f} ({vtk_rss:.0f}) **{vtk_ms / me_ms:.2f}×** |"
            ]
            tris = [me_tris, vtk_tris]
            if file.endswith(".npy") and axes == "zyx":
                for tool in ("skimage", "pymcubes"):
                    t_ms, t_rss, t_tris = peer(tool)
                    cells.append(f" {t_ms:.0f} ({t_rss:.0f}) {t_ms / me_ms:.1f}× |")
                    tris.append(t_tris)
            else:
                cells.append(" – | – |")
            cells.append(" " + " / ".join(str(t) for t in tris) + " |")
            rows.append("".join(cells))
            print(rows[-1], file=sys.stderr, flush=True)
    print("| file (layout) | floor ms | isocube ms (peak MiB) | VTK ms (peak MiB) ÷ isocube | scikit-image + trimesh ms (MiB) | PyMCubes + trimesh ms (MiB) | triangles: isocube / VTK / … |")
    print("|---|---:|---:|---:|---:|---:|---|")
    for r in rows:
        print(r)


if __name__ == "__main__":
    main()
