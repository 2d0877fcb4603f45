"""isocube against nibabel on the MINC files nibabel ships (its test data, from PyPI): MINC-1
(NetCDF) and MINC-2 (HDF5; isocube built with the `minc2` feature), 3-d and 4-d. Each file (each
frame, `--frame N`) is meshed by `isocube extract` straight from the file, in world coordinates,
and from the array nibabel decodes (scaled, as float32) with nibabel's affine, written as a
NIfTI file with the axes in isocube's order (the file's, fastest first). The two must have the
same triangles and their vertices agree within 1e-4 of the voxel size. Without `--frame` a 4-d
file is refused with the choice named.

    python check_minc.py ISOCUBE WORKDIR
"""

import os
import subprocess
import sys
from pathlib import Path

import nibabel
import numpy as np
import trimesh

isocube = sys.argv[1]
work = Path(sys.argv[2])
work.mkdir(parents=True, exist_ok=True)
data = Path(os.path.dirname(nibabel.__file__)) / "tests" / "data"


def extract(args, out):
    run = subprocess.run(
        [isocube, "extract", *args, "-o", str(out)], capture_output=True, text=True
    )
    assert run.returncode == 0, f"{args}: {run.stderr}"
    return trimesh.load(out, process=False)


checked = 0
for path in sorted(data.glob("*.mnc")):
    image = nibabel.load(path)
    values = np.asarray(image.get_fdata(), dtype=np.float32)
    frames = values.shape[0] if values.ndim == 4 else 0
    if frames:
        run = subprocess.run(
            [isocube, "extract", str(path), "-o", str(work / "x.ply")],
            capture_output=True,
            text=True,
        )
        assert (
            run.returncode == 2
            and f"{frames} frames (time): choose one with --frame (0 to {frames - 1})"
            in run.stderr
        ), run.stderr
    # isocube's axes are the file's reversed (fastest first): so the reference's.
    affine = image.affine.copy()
    affine[:3, :3] = affine[:3, [2, 1, 0]]
    voxel = float(min(np.linalg.norm(affine[:3, :3], axis=0)))
    for frame in range(frames) if frames else [None]:
        volume = (values if frame is None else values[frame]).transpose(2, 1, 0)
        level = float(volume.min() + 0.4 * (volume.max() - volume.min()))
        args = [str(path), "--level", repr(level), "--quiet"] + (
            [] if frame is None else ["--frame", str(frame)]
        )
        name = path.name + ("" if frame is None else f" frame {frame}")
        if volume.min() == volume.max():
            # A constant frame: nothing to mesh, and the command says so with nibabel's value.
            run = subprocess.run(
                [isocube, "extract", *args, "-o", str(work / "x.ply")],
                capture_output=True,
                text=True,
            )
            assert (
                run.returncode == 2
                and f"range from {volume.min():g} to {volume.max():g}" in run.stderr
            ), run.stderr
            print(f"{name}: constant {volume.min():g}, refused as nibabel's array says")
            continue
        mine = extract(args, work / "mine.ply")
        copy = nibabel.Nifti1Image(np.ascontiguousarray(volume), affine)
        copy.set_sform(affine, code=1)
        copy.set_qform(None, code=0)
        nibabel.save(copy, work / "ref.nii")
        ref = extract(
            [str(work / "ref.nii"), "--level", repr(level), "--quiet"], work / "ref.ply"
        )
        assert len(mine.faces) == len(ref.faces) > 0, (
            f"{name}: {len(mine.faces)} / {len(ref.faces)}"
        )
        far = float(
            np.abs(
                np.asarray(mine.vertices, float) - np.asarray(ref.vertices, float)
            ).max()
        )
        assert far <= 1e-4 * voxel, f"{name}: {far}"
        kind = "MINC-2" if path.read_bytes()[:4] == b"\x89HDF" else "MINC-1"
        print(
            f"{name} ({kind}): {len(mine.faces)} triangles, vertices within {far:.2e} (voxel {voxel:.3g})"
        )
        checked += 1
assert checked >= 10, checked
