"""Writes NIfTI-2 and 4-d reader fixtures into tests/data/volumes/ with nibabel, SimpleITK and
pynrrd, beside make_volumes.py's, and records the NIfTI-2 one in expected.json.

    pip install -r tests/interop/requirements-volumes.txt
    python tests/interop/make_frames.py [OUTDIR]

- nifti2.nii.gz: NIfTI-2 (540-byte header, float64 geometry), rotated and anisotropic, int16
  with a slope and intercept; the fixture's values.
- frames.nii: NIfTI-1, 4-d: three frames of uint16, frame t holding the fixture's values plus
  1000 t; its sform the identity scaled by (1, 2, 3).
- channels.nii.gz: NIfTI-1, 5-d: two frames × two channels of float32, volume (t, c) holding
  the fixture's values plus 1000 t + 10000 c.
- frames.mha (SimpleITK, NDims = 4) and frames.nrrd (pynrrd, kinds "domain domain domain
  list"): three frames as frames.nii.
- vectors.mha (SimpleITK, ElementNumberOfChannels = 2) and vectors.nrrd (pynrrd, kinds "vector
  domain domain domain", the channels interleaved): channel c holds the fixture's values plus
  10000 c.
- hyperstack.tif (tifffile, an ImageJ hyperstack TZCYX: 2 frames, 8 slices, 2 channels, 16-bit):
  frame t, channel c holds the fixture's values plus 1000 t + 10000 c.
- rgb.tif (tifffile, 8 pages of 8-bit RGB): sample c holds (the fixture's values + 40 c) mod 256.
"""

import json
import math
import sys
from pathlib import Path

import nibabel as nib
import numpy as np

out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parents[1] / "data" / "volumes"
expected_path = out / "expected.json"
expected = json.loads(expected_path.read_text())
NX, NY, NZ = expected["dims"]
i, j, k = np.meshgrid(np.arange(NX), np.arange(NY), np.arange(NZ), indexing="ij")
values = 100 + i + 10 * j + 100 * k

c, s = math.cos(math.radians(-40)), math.sin(math.radians(-40))
linear = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]]) @ np.diag([0.75, 1.25, 2.5])
origin = np.array([3.5, -7.25, 12.0])
affine = np.eye(4)
affine[:3, :3] = linear
affine[:3, 3] = origin
image = nib.Nifti2Image(values.astype(np.int16), affine)
image.header.set_slope_inter(0.25, -3.0)
image.set_sform(affine, code=1)
image.set_qform(affine, code=1)
nib.save(image, out / "nifti2.nii.gz")
expected["files"]["nifti2.nii.gz"] = {"linear": linear.tolist(), "origin": origin.tolist(), "scale": 0.25, "offset": -3.0}

frames = np.stack([values + 1000 * t for t in range(3)], axis=-1).astype(np.uint16)
nib.save(nib.Nifti1Image(frames, np.diag([1.0, 2.0, 3.0, 1.0])), out / "frames.nii")
volumes = np.stack(
    [np.stack([values + 1000 * t + 10000 * ch for ch in range(2)], axis=-1) for t in range(2)], axis=-2
).astype(np.float32)
assert volumes.shape == (NX, NY, NZ, 2, 2)
nib.save(nib.Nifti1Image(volumes, np.diag([1.0, 2.0, 3.0, 1.0])), out / "channels.nii.gz")

import nrrd
import SimpleITK as sitk

# SimpleITK's arrays are [t, z, y, x] (and [z, y, x, c] for vector images).
sitk.WriteImage(
    sitk.GetImageFromArray(frames.transpose(3, 2, 1, 0), isVector=False), str(out / "frames.mha"), useCompression=True
)
vectors = np.stack([values + 10000 * ch for ch in range(2)], axis=-1).astype(np.int32)  # [x, y, z, c]
sitk.WriteImage(
    sitk.GetImageFromArray(vectors.transpose(2, 1, 0, 3), isVector=True), str(out / "vectors.mha"), useCompression=False
)
nrrd.write(
    str(out / "frames.nrrd"),
    frames,
    {"kinds": ["domain", "domain", "domain", "list"], "encoding": "gzip"},
    index_order="F",
)
nrrd.write(
    str(out / "vectors.nrrd"),
    np.ascontiguousarray(vectors.transpose(3, 0, 1, 2)),
    {"kinds": ["vector", "domain", "domain", "domain"], "encoding": "raw"},
    index_order="F",
)

import tifffile

# [t, z, c, y, x] as ImageJ orders a hyperstack's pages (channel fastest, then slice, then frame).
hyper = np.stack(
    [np.stack([values + 1000 * t + 10000 * ch for ch in range(2)], axis=0) for t in range(2)], axis=0
)  # [t, c, x, y, z]
hyper = hyper.transpose(0, 4, 1, 3, 2).astype(np.uint16)  # [t, z, c, y, x]
tifffile.imwrite(out / "hyperstack.tif", hyper, imagej=True, metadata={"axes": "TZCYX", "spacing": 2.5})
rgb = np.stack([(values + 40 * ch) % 256 for ch in range(3)], axis=-1).astype(np.uint8)  # [x, y, z, c]
tifffile.imwrite(out / "rgb.tif", rgb.transpose(2, 1, 0, 3), photometric="rgb")

expected_path.write_text(json.dumps(expected, indent=1) + "\n")
print("wrote nifti2.nii.gz, frames.nii/.mha/.nrrd, channels.nii.gz, vectors.mha/.nrrd, hyperstack.tif, rgb.tif to", out)
