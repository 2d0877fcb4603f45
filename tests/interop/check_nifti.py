"""isocube against nibabel on NIfTI files nibabel ships (its test data, from PyPI): NIfTI-2
(`example_nifti2.nii.gz`) and 4-d series (`functional.nii`, `example4d.nii.gz`), each frame
meshed by `isocube extract --frame N` straight from the file, in world coordinates, and from
the frame nibabel decodes (scaled to float32) with the affine nibabel makes of the header (its
sform or qform), written by nibabel as a plain 3-d file. The two must have the same triangles
and their vertices agree within 1e-4 of the voxel size. Without `--frame` a 4-d file is refused
with the choice named.

(The reference is meshed from a file rather than mapped from an index-space mesh because
isocube's tunnel mending decides on positions as stored, in the grid's spacing: an index-space
mesh carried by the affine can differ from the world mesh by a few triangles in tunnel cells
whose crossings are decided at rounding level.)

    python check_nifti.py ISOCUBE WORKDIR
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
    run = subprocess.run([isocube, "extract", *args, "-o", str(out)], capture_output=True, text=True)
    assert run.returncode == 0, f"{args}: {run.stderr}"
    return trimesh.load(out, process=False)


for name in ["example_nifti2.nii.gz", "functional.nii", "example4d.nii.gz"]:
    path = data / name
    image = nibabel.load(path)
    frames = image.shape[3]
    assert isinstance(image, nibabel.Nifti2Image) == (name == "example_nifti2.nii.gz")
    run = subprocess.run([isocube, "extract", str(path), "-o", str(work / "x.ply")], capture_output=True, text=True)
    assert run.returncode == 2 and f"{frames} frames (dim[4]): choose one with --frame (0 to {frames - 1})" in run.stderr, run.stderr
    affine = image.affine
    voxel = float(min(np.linalg.norm(affine[:3, :3], axis=0)))
    for frame in range(min(frames, 3)):
        volume = np.asarray(image.dataobj[..., frame], dtype=np.float64)
        level = float(volume.min() + 0.5 * (volume.max() - volume.min()))
        mine = extract([str(path), "--frame", str(frame), "--level", repr(level), "--quiet"], work / "mine.ply")
        kind = nibabel.Nifti2Image if isinstance(image, nibabel.Nifti2Image) else nibabel.Nifti1Image
        copy = kind(volume.astype(np.float32), affine)
        copy.set_sform(affine, code=1)
        copy.set_qform(None, code=0)
        nibabel.save(copy, work / "ref.nii")
        ref = extract([str(work / "ref.nii"), "--level", repr(level), "--quiet"], work / "ref.ply")
        placed = np.asarray(ref.vertices, float)
        assert len(mine.faces) == len(ref.faces) > 0, f"{name} frame {frame}"
        far = float(np.abs(np.asarray(mine.vertices, float) - placed).max())
        assert far <= 1e-4 * voxel, f"{name} frame {frame}: {far}"
        print(f"{name} frame {frame} of {frames}: {len(mine.faces)} triangles, vertices within {far:.2e} (voxel {voxel:.3g})")
