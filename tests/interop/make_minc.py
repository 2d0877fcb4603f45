"""Writes tests/data/minc/: MINC files with what nibabel reads from them, for the MINC reader's
tests (crates/isocube-io/src/minc). Run from anywhere:

    pip install nibabel==5.4.2 h5py scipy
    python tests/interop/make_minc.py

- Copies of MINC-1 (NetCDF) and MINC-2 (HDF5) files from nibabel's test data (MIT licence,
  LICENSE-nibabel beside them): one scale for the volume, a scale per slice, 4-d with time,
  16-bit signed MINC-2.
- oblique.mnc, written here with scipy's NetCDF writer: signed 16-bit voxels with a valid range,
  image-min/image-max varying over two dimensions (zspace and yspace), oblique direction
  cosines, a negative step, and the dimensions in an unusual order (yspace, zspace, xspace).
- records.mnc: the same image over an unlimited `time` dimension (a record variable), two
  frames, scaled per (time, yspace).
- vector.mnc: float voxels with a `vector_dimension` of 3 (CDF-2, 64-bit offsets), each channel
  holding 1000 c + x + 10 y + 100 z.
- expected.json: for each file (and frame), nibabel's affine (file axis order) and the name of
  NAME[-frameN].npy, nibabel's scaled values as float32, stored as isocube reads them (x fastest:
  a Fortran-order array over the file's axes reversed).
"""

import json
import os
import shutil
from pathlib import Path

import nibabel
import numpy as np
from scipy.io import netcdf_file

out = Path(__file__).resolve().parents[1] / "data" / "minc"
out.mkdir(parents=True, exist_ok=True)
source = Path(os.path.dirname(nibabel.__file__)) / "tests" / "data"
COPIED = [
    "minc1_1_scale.mnc",
    "tiny.mnc",
    "minc1_4d.mnc",
    "minc2_1_scale.mnc",
    "minc2_4d.mnc",
    "small.mnc",
]
for name in COPIED:
    shutil.copy(source / name, out / name)
licence = (
    Path(os.path.dirname(nibabel.__file__)).parent
    / "nibabel-5.4.2.dist-info"
    / "licenses"
    / "COPYING"
)
if not licence.exists():
    licence = next(
        Path(os.path.dirname(nibabel.__file__)).parent.glob(
            "nibabel-*.dist-info/**/COPYING"
        )
    )
shutil.copy(licence, out / "LICENSE-nibabel")

rng = np.random.default_rng(7)
shape = (6, 5, 7)  # yspace, zspace, xspace
y, z, x = np.meshgrid(*(np.arange(n) for n in shape), indexing="ij")
real = 40.0 * np.sin(x / 2.0) + 30.0 * np.cos(y / 1.7) + 25.0 * z - 20.0
c, s = np.cos(0.4), np.sin(0.4)
cosines = {"xspace": [c, s, 0.0], "yspace": [-s, c, 0.0], "zspace": [0.0, 0.0, 1.0]}
steps = {"xspace": -1.5, "yspace": 0.8, "zspace": 2.5}
starts = {"xspace": 12.0, "yspace": -4.0, "zspace": 30.0}
valid = (-1000.0, 3000.0)


def write(name, frames):
    nc = netcdf_file(out / name, "w", version=1)
    dims = ("yspace", "zspace", "xspace")
    if frames:
        nc.createDimension("time", None)
        t = nc.createVariable("time", "i", ())
        t.spacing = b"regular__"
        t.step = 1.0
        t.start = 0.0
    for d, n in zip(dims, shape):
        nc.createDimension(d, n)
    for d in dims:
        v = nc.createVariable(d, "i", ())
        v.spacing = b"regular__"
        v.step = steps[d]
        v.start = starts[d]
        v.direction_cosines = np.array(cosines[d])
    image_dims = (("time",) if frames else ()) + dims
    image = nc.createVariable("image", "h", image_dims)
    image.signtype = b"signed__"
    image.valid_range = np.array(valid)
    # Two scaling dimensions (nibabel reads no more): (yspace, zspace) for one frame, (time,
    # yspace) over time.
    scale_dims = image_dims[:2]
    lo = nc.createVariable("image-min", "d", scale_dims)
    hi = nc.createVariable("image-max", "d", scale_dims)
    for t in range(max(frames, 1)):
        values = real + 100.0 * t
        over = (2,) if not frames else (1, 2)
        mins = values.min(axis=over, keepdims=True) - rng.uniform(
            1, 5, values.min(axis=over, keepdims=True).shape
        )
        maxs = values.max(axis=over, keepdims=True) + rng.uniform(1, 5, mins.shape)
        stored = np.round(
            valid[0] + (values - mins) / (maxs - mins) * (valid[1] - valid[0])
        )
        if frames:
            image[t] = stored.astype(np.int16)
            lo[t], hi[t] = mins.ravel(), maxs.ravel()
        else:
            image[:] = stored.astype(np.int16)
            lo[:], hi[:] = mins[..., 0], maxs[..., 0]
    nc.close()


write("oblique.mnc", 0)
write("records.mnc", 2)

# vector.mnc: RGB-like float voxels, `vector_dimension` fastest (nibabel does not read these):
# channel c at (x, y, z) holds 1000 c + x + 10 y + 100 z.
nc = netcdf_file(out / "vector.mnc", "w", version=2)
for d, n in [("zspace", 4), ("yspace", 3), ("xspace", 5), ("vector_dimension", 3)]:
    nc.createDimension(d, n)
vector = nc.createVariable("image", "f", ("zspace", "yspace", "xspace", "vector_dimension"))
z, y, x, ch = np.meshgrid(*(np.arange(n) for n in (4, 3, 5, 3)), indexing="ij")
vector[:] = (1000 * ch + x + 10 * y + 100 * z).astype(np.float32)
nc.close()

expected = {}
for name in sorted(p.name for p in out.glob("*.mnc") if p.name != "vector.mnc"):
    image = nibabel.load(out / name)
    data = np.asarray(image.get_fdata(), dtype=np.float32)
    frames = data.shape[0] if data.ndim == 4 else 0
    for frame in range(frames) if frames else [None]:
        volume = data if frame is None else data[frame]
        npy = name.replace(".mnc", "" if frame is None else f"-frame{frame}") + ".npy"
        np.save(out / npy, np.asfortranarray(volume.transpose(2, 1, 0)))
        key = name if frame is None else f"{name}#{frame}"
        expected[key] = {
            "file": name,
            "frame": frame,
            "values": npy,
            "affine": image.affine.tolist(),
        }
        print(key, volume.shape, float(volume.min()), float(volume.max()))
(out / "expected.json").write_text(json.dumps(expected, indent=1) + "\n")
