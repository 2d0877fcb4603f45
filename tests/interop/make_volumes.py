"""Writes small volumes with programs that share no code with isocube (nibabel, SimpleITK),
each with a known value at every index and a known index-to-world geometry, into
tests/data/volumes/, plus expected.json describing them. isocube's reader tests compare what
they read against that description.

    pip install -r tests/interop/requirements-volumes.txt
    python tests/interop/make_volumes.py [OUTDIR]

DICOM files get new UIDs on every run; the other files come out byte for byte the same.
"""

import json
import math
import sys
from pathlib import Path

import numpy as np

out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parents[1] / "data" / "volumes"
out.mkdir(parents=True, exist_ok=True)

NX, NY, NZ = 12, 10, 8


def values():
    """v[i, j, k] = 100 + i + 10 j + 100 k: any axis mix-up shows."""
    i, j, k = np.meshgrid(np.arange(NX), np.arange(NY), np.arange(NZ), indexing="ij")
    return (100 + i + 10 * j + 100 * k).astype(np.int16)


def rotation_z(deg):
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


expected = {"dims": [NX, NY, NZ], "value": "100 + i + 10 j + 100 k", "files": {}}


def record(name, linear, origin, scale=1.0, offset=0.0):
    """World = linear @ (i, j, k) + origin; stored value v reads as scale * v + offset."""
    expected["files"][name] = {
        "linear": np.asarray(linear).tolist(),
        "origin": np.asarray(origin).tolist(),
        "scale": scale,
        "offset": offset,
    }


# NIfTI-1, gzip: rotated 30° about z, anisotropic spacing, sform and qform both set, with a
# slope and intercept.
import nibabel as nib

spacing = np.array([0.8, 0.9, 1.5])
linear = rotation_z(30) @ np.diag(spacing)
origin = np.array([-10.0, 5.0, 20.0])
affine = np.eye(4)
affine[:3, :3] = linear
affine[:3, 3] = origin
img = nib.Nifti1Image(values(), affine)
img.header.set_slope_inter(0.5, 10.0)
img.set_qform(affine, code=1)
img.set_sform(affine, code=1)
nib.save(img, out / "rotated.nii.gz")
record("rotated.nii.gz", linear, origin, 0.5, 10.0)

# NIfTI-1, plain: x axis flipped (a reflection, as radiological files have), float32, qform only.
linear = np.diag([-1.2, 1.0, 2.0])
origin = np.array([14.0, -3.0, 0.5])
affine = np.eye(4)
affine[:3, :3] = linear
affine[:3, 3] = origin
img = nib.Nifti1Image(values().astype(np.float32), affine)
img.set_qform(affine, code=2)
img.set_sform(None, code=0)
nib.save(img, out / "flipped.nii")
record("flipped.nii", linear, origin)

# MetaImage with SimpleITK: .mha (zlib-compressed) rotated about x, .mhd + .raw axis-aligned.
import SimpleITK as sitk

arr = values().transpose(2, 1, 0)  # SimpleITK arrays are [z, y, x]
image = sitk.GetImageFromArray(arr)
image.SetSpacing((0.5, 0.75, 1.25))
image.SetOrigin((1.0, 2.0, 3.0))
c, s = math.cos(math.radians(20)), math.sin(math.radians(20))
direction = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
image.SetDirection(tuple(direction.flatten()))
sitk.WriteImage(image, str(out / "rotated.mha"), useCompression=True)
record("rotated.mha", direction @ np.diag([0.5, 0.75, 1.25]), [1.0, 2.0, 3.0])

image = sitk.GetImageFromArray(arr.astype(np.uint16))
image.SetSpacing((2.0, 1.0, 0.5))
image.SetOrigin((-4.0, 0.0, 7.5))
sitk.WriteImage(image, str(out / "plain.mhd"))
record("plain.mhd", np.diag([2.0, 1.0, 0.5]), [-4.0, 0.0, 7.5])

# Multi-page TIFF with tifffile: an ImageJ hyperstack (pixel size from the resolution tags, slice
# spacing from ImageJ's description), and a plain float32 stack without any geometry.
import tifffile

stack = values().transpose(2, 1, 0)  # pages are z, rows y, columns x
tifffile.imwrite(
    out / "stack.tif",
    stack.astype(np.uint16),
    imagej=True,
    resolution=(1 / 0.25, 1 / 0.4),
    metadata={"spacing": 2.5, "unit": "um", "axes": "ZYX"},
)
record("stack.tif", np.diag([0.25, 0.4, 2.5]), [0.0, 0.0, 0.0])
tifffile.imwrite(out / "plain.tiff", stack.astype(np.float32))
record("plain.tiff", np.eye(3), [0.0, 0.0, 0.0])

# VTK ImageData (.vti) with VTK itself: ASCII; binary inline with zlib and 32-bit headers;
# appended raw; appended base64 with zlib and 64-bit headers. One carries a direction.
import vtk
from vtk.util.numpy_support import numpy_to_vtk

for name, mode, compress, encode, header64, rotated in [
    ("ascii.vti", "ascii", False, False, False, False),
    ("binary-zlib.vti", "binary", True, False, False, True),
    ("appended-raw.vti", "appended", False, False, True, False),
    ("appended-base64.vti", "appended", True, True, True, False),
]:
    image = vtk.vtkImageData()
    image.SetDimensions(NX, NY, NZ)
    image.SetSpacing(0.6, 0.7, 0.8)
    image.SetOrigin(-1.0, -2.0, -3.0)
    direction = rotation_z(-40) if rotated else np.eye(3)
    image.SetDirectionMatrix(*direction.flatten())
    flat = values().transpose(2, 1, 0).ravel()  # x fastest
    arr = numpy_to_vtk(flat.astype(np.int16 if mode != "ascii" else np.float32), deep=True)
    arr.SetName("density")
    image.GetPointData().SetScalars(arr)
    w = vtk.vtkXMLImageDataWriter()
    w.SetFileName(str(out / name))
    w.SetInputData(image)
    {"ascii": w.SetDataModeToAscii, "binary": w.SetDataModeToBinary, "appended": w.SetDataModeToAppended}[mode]()
    w.SetEncodeAppendedData(encode)
    if compress:
        w.SetCompressorTypeToZLib()
        w.SetBlockSize(512)  # several compressed blocks
    else:
        w.SetCompressorTypeToNone()
    if header64:
        w.SetHeaderTypeToUInt64()
    else:
        w.SetHeaderTypeToUInt32()
    assert w.Write() == 1
    record(name, direction @ np.diag([0.6, 0.7, 0.8]), [-1.0, -2.0, -3.0])

# NRRD with pynrrd: oblique space directions, gzip; NumPy .npy with numpy itself (x fastest
# means a Fortran-order [x, y, z] array, isocube's default axes).
import nrrd

directions = rotation_z(60) @ np.diag([0.3, 0.3, 1.1])
nrrd.write(
    str(out / "oblique.nrrd"),
    values().astype(np.int32),
    header={
        "space": "left-posterior-superior",
        "space directions": directions.T,  # one row per axis
        "space origin": np.array([5.0, 6.0, -7.0]),
        "encoding": "gzip",
    },
    index_order="F",
)
record("oblique.nrrd", directions, [5.0, 6.0, -7.0])
np.save(out / "fortran.npy", np.asfortranarray(values().astype(np.float64)))
record("fortran.npy", np.eye(3), [0.0, 0.0, 0.0])

# A DICOM series with pydicom: oblique slices (rows along a rotated axis), 1.5 mm apart,
# CT-style stored values with a rescale intercept, files named out of slice order.
import pydicom
from pydicom.dataset import FileDataset, FileMetaDataset
from pydicom.uid import ExplicitVRLittleEndian, generate_uid

series = out / "dicom"
series.mkdir(exist_ok=True)
for old in series.glob("*.dcm"):
    old.unlink()
row_dir = rotation_z(25) @ np.array([1.0, 0.0, 0.0])
col_dir = rotation_z(25) @ np.array([0.0, 1.0, 0.0])
normal = np.cross(row_dir, col_dir)
pixel = (0.7, 0.6)  # PixelSpacing: between rows (y), between columns (x)
first = np.array([-50.0, 20.0, 100.0])
series_uid, study_uid = generate_uid(), generate_uid()
stored = values().transpose(2, 1, 0)  # [z, y, x]
for k in range(NZ):
    meta = FileMetaDataset()
    meta.MediaStorageSOPClassUID = "1.2.840.10008.5.1.4.1.1.2"
    meta.MediaStorageSOPInstanceUID = generate_uid()
    meta.TransferSyntaxUID = ExplicitVRLittleEndian
    name = series / f"slice-{(k * 5) % NZ:02d}-{k}.dcm"  # not in slice order
    ds = FileDataset(str(name), {}, file_meta=meta, preamble=b"\0" * 128)
    ds.SOPClassUID = meta.MediaStorageSOPClassUID
    ds.SOPInstanceUID = meta.MediaStorageSOPInstanceUID
    ds.SeriesInstanceUID = series_uid
    ds.StudyInstanceUID = study_uid
    ds.Modality = "CT"
    ds.InstanceNumber = k + 1
    ds.ImagePositionPatient = [float(x) for x in first + 1.5 * k * normal]
    ds.ImageOrientationPatient = [float(x) for x in [*row_dir, *col_dir]]
    ds.PixelSpacing = list(pixel)
    ds.SliceThickness = 1.5
    ds.Rows, ds.Columns = NY, NX
    ds.SamplesPerPixel = 1
    ds.PhotometricInterpretation = "MONOCHROME2"
    ds.BitsAllocated, ds.BitsStored, ds.HighBit = 16, 16, 15
    ds.PixelRepresentation = 1
    ds.RescaleSlope = 2
    ds.RescaleIntercept = -1024
    ds.PixelData = stored[k].astype(np.int16).tobytes()
    ds.save_as(name, enforce_file_format=True)
linear = np.stack([row_dir * pixel[1], col_dir * pixel[0], normal * 1.5], axis=1)
record("dicom", linear, first, 2.0, -1024.0)

# The same series in implicit VR little endian (the DICOM default transfer syntax).
from pydicom.uid import ImplicitVRLittleEndian

implicit = out / "dicom-implicit"
implicit.mkdir(exist_ok=True)
for old in implicit.glob("*.dcm"):
    old.unlink()
for name in sorted(series.glob("*.dcm")):
    ds = pydicom.dcmread(name)
    ds.file_meta.TransferSyntaxUID = ImplicitVRLittleEndian
    ds.save_as(implicit / name.name, enforce_file_format=True, implicit_vr=True, little_endian=True)
record("dicom-implicit", linear, first, 2.0, -1024.0)

# A small segmentation for `isocube extract --labels` (README): three touching ellipsoids,
# labels 1, 2, 3, in background 0, 1 mm × 1 mm × 1.5 mm voxels.
i, j, k = np.meshgrid(np.arange(48), np.arange(40), np.arange(32), indexing="ij")
seg = np.zeros((48, 40, 32), np.uint8)
for label, (cx, cy, cz, rx, ry, rz) in enumerate(
    [(16, 20, 16, 10, 12, 10), (30, 20, 16, 9, 10, 9), (23, 20, 26, 12, 9, 5)], start=1
):
    inside = ((i - cx) / rx) ** 2 + ((j - cy) / ry) ** 2 + ((k - cz) / rz) ** 2 <= 1
    seg[inside & (seg == 0)] = label
affine = np.diag([1.0, 1.0, 1.5, 1.0])
nib.save(nib.Nifti1Image(seg, affine), out / "labels.nii.gz")

(out / "expected.json").write_text(json.dumps(expected, indent=1) + "\n")
print("wrote", ", ".join(expected["files"]), "to", out)
