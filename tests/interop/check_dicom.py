"""isocube against pydicom on the DICOM files pydicom ships (its own test files, from PyPI):
every image is meshed by `isocube extract` straight from the file, in patient coordinates, and
the same surface is made from the array pydicom decodes (through its plugins for the
compressed ones, with Rescale Slope/Intercept and Dose Grid Scaling applied) placed by Image
Position/Orientation, Pixel Spacing and the Grid Frame Offset Vector. The two must have the
same triangles and their vertices agree within 1e-4 of the voxel size.

Single-frame files become a series of three copies of themselves a slice thickness apart
(pydicom writes the copies, keeping each file's transfer syntax and its compressed pixel data
as they are), since one plane holds no cells.

    python check_dicom.py ISOCUBE WORKDIR
"""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pydicom
import trimesh
from pydicom.data import get_testdata_file
from pydicom.uid import generate_uid

isocube = sys.argv[1]
work = Path(sys.argv[2])
work.mkdir(parents=True, exist_ok=True)

SINGLE = [
    "CT_small.dcm",
    "MR_small.dcm",
    "MR_small_implicit.dcm",
    "MR_small_expb.dcm",
    "MR_small_bigendian.dcm",
    "MR_small_RLE.dcm",
    "MR_small_jp2klossless.dcm",
    "MR_small_jpeg_ls_lossless.dcm",
    "JPEG2000.dcm",
    "JPGExtended.dcm",
]
MULTI = ["rtdose.dcm", "rtdose_rle.dcm"]


def series_of(name):
    """A folder of three copies of a single-frame file, a slice thickness apart."""
    source = Path(get_testdata_file(name))
    folder = work / name.replace(".dcm", "")
    folder.mkdir(exist_ok=True)
    ds = pydicom.dcmread(source)
    if "ImagePositionPatient" not in ds:
        # A nuclear medicine image without patient geometry: placed at the origin, axis-aligned.
        ds.ImagePositionPatient = [0.0, 0.0, 0.0]
        ds.ImageOrientationPatient = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0]
    iop = np.array(ds.ImageOrientationPatient, float)
    normal = np.cross(iop[:3], iop[3:])
    thickness = float(getattr(ds, "SliceThickness", 0) or 1.0)
    first = np.array(ds.ImagePositionPatient, float)
    series = generate_uid()
    for k in range(3):
        copy = pydicom.dcmread(source)
        copy.ImagePositionPatient = [float(x) for x in first + k * thickness * normal]
        copy.ImageOrientationPatient = [float(x) for x in iop]
        copy.SeriesInstanceUID = series
        copy.SOPInstanceUID = generate_uid()
        copy.save_as(folder / f"{k}.dcm")
    return folder


def decoded(paths):
    """pydicom's planes, modality-scaled, sorted along the normal: values [x, y, z], the
    index-to-patient map (3 × 3) and origin."""
    planes = []
    for path in paths:
        ds = pydicom.dcmread(path)
        raw = ds.pixel_array.astype(np.float64)
        frames = raw if int(getattr(ds, "NumberOfFrames", 1) or 1) > 1 else raw[None]
        values = frames * float(getattr(ds, "RescaleSlope", 1) or 1) + float(getattr(ds, "RescaleIntercept", 0) or 0)
        values *= float(getattr(ds, "DoseGridScaling", 1) or 1)
        iop = np.array(ds.ImageOrientationPatient, float)
        row, col = iop[:3], iop[3:]
        normal = np.cross(row, col)
        ipp = np.array(ds.ImagePositionPatient, float)
        offsets = [float(o) for o in getattr(ds, "GridFrameOffsetVector", [0.0] * len(frames))]
        for f, plane in enumerate(values):
            planes.append((ipp + (offsets[f] - offsets[0]) * normal, plane))
        spacing = [float(s) for s in ds.PixelSpacing]
    planes.sort(key=lambda p: float(np.dot(p[0], normal)))
    positions = np.array([p[0] for p in planes])
    volume = np.stack([p[1] for p in planes]).transpose(2, 1, 0)  # [x, y, z]
    step = positions[1] - positions[0]
    linear = np.stack([row * spacing[1], col * spacing[0], step], axis=1)
    return volume, linear, positions[0], min(spacing[0], spacing[1], float(np.linalg.norm(step)))


def extract(args, out):
    run = subprocess.run([isocube, "extract", *args, "-o", str(out)], capture_output=True, text=True)
    assert run.returncode == 0, f"{args}: {run.stderr}"
    return trimesh.load(out, process=False)


def compare(name, inputs, path, level):
    volume, linear, origin, voxel = decoded(inputs)
    np.save(work / "ref.npy", volume.astype(np.float32))
    mine = extract([str(path), "--level", repr(level), "--quiet"], work / f"{name}.ply")
    ref = extract([str(work / "ref.npy"), "--level", repr(level), "--index-space", "--quiet"], work / "ref.ply")
    placed = np.asarray(ref.vertices, float) @ linear.T + origin
    assert len(mine.faces) == len(ref.faces) > 0, f"{name}: {len(mine.faces)} / {len(ref.faces)} triangles"
    far = float(np.abs(np.asarray(mine.vertices, float) - placed).max())
    assert far <= 1e-4 * voxel, f"{name}: vertices {far} apart (voxel {voxel})"
    print(f"{name}: {len(mine.faces)} triangles, level {level:.6g}, vertices within {far:.2e} (voxel {voxel:.4g})")
    return (work / f"{name}.ply").read_bytes()


meshes = {}
for name in SINGLE:
    folder = series_of(name)
    volume, *_ = decoded(sorted(folder.glob("*.dcm")))
    level = float(volume.min() + 0.5 * (volume.max() - volume.min()))
    if name.startswith("MR_small"):
        level = 600.0  # one level for every encoding of the same image
    meshes[name] = compare(name, sorted(folder.glob("*.dcm")), folder, level)

for name in MULTI:
    path = Path(get_testdata_file(name))
    volume, *_ = decoded([path])
    # The isodose surface at half the maximum dose (Gy): this small grid's doses all lie above
    # it (0.795 to 1.254 Gy), so no cell crosses it — the command says so (exit 2), and with
    # --allow-empty writes the empty mesh. At 90 % of the maximum the surface is there.
    half = 0.5 * float(volume.max())
    run = subprocess.run([isocube, "extract", str(path), "--level", repr(half), "-o", str(work / "half.ply")], capture_output=True, text=True)
    assert run.returncode == 2 and "no cell crosses" in run.stderr, run.stderr
    run = subprocess.run(
        [isocube, "extract", str(path), "--level", repr(half), "--allow-empty", "-o", str(work / "half.ply")],
        capture_output=True,
        text=True,
    )
    assert run.returncode == 0 and "0 triangles" in run.stderr and float(volume.min()) > half, run.stderr
    print(f"{name}: 50 % of the maximum dose ({half:.4g} Gy) lies below every dose: empty, as pydicom's array says")
    meshes[name] = compare(name, [path], path, 0.9 * float(volume.max()))

# Compressed and uncompressed encodings of one image: the very same file.
for name in SINGLE:
    if name.startswith("MR_small_"):
        assert meshes[name] == meshes["MR_small.dcm"], f"{name} differs from MR_small.dcm"
assert meshes["rtdose_rle.dcm"] == meshes["rtdose.dcm"]
print("compressed, big-endian and implicit encodings give the uncompressed file's mesh byte for byte")

# pydicom's RT Structure Set (a bare data set, without the Part 10 header): the 'patient' ROI's
# three CLOSED_PLANAR contours become a closed surface through every contour vertex, in patient
# coordinates; the two POINT ROIs are listed as skipped.
plan = get_testdata_file("rtstruct.dcm")
run = subprocess.run(
    [isocube, "contours", plan, "-o", str(work / "plan.ply"), "--cap", "flat"], capture_output=True, text=True
)
assert run.returncode == 0, run.stderr
assert "skipped (no CLOSED_PLANAR contours): 2 'Isocenter 1' (1 POINT), 3 'Isocenter 2' (1 POINT)" in run.stderr, run.stderr
surface = trimesh.load(work / "plan-patient.ply", process=False)
assert surface.is_watertight
ds = pydicom.dcmread(plan, force=True)
contours = ds.ROIContourSequence[0].ContourSequence
assert len(contours) == 3
vertices = np.asarray(surface.vertices, float)
diagonal = float(np.linalg.norm(vertices.max(0) - vertices.min(0)))
far = max(
    float(np.min(np.linalg.norm(vertices - p, axis=1)))
    for c in contours
    for p in np.array(c.ContourData, float).reshape(-1, 3)
)
assert far <= 1e-6 * diagonal, far
print(
    f"rtstruct.dcm: ROI 'patient' {len(surface.faces)} triangles, watertight, every contour vertex "
    f"within {far:.1e} (diagonal {diagonal:.1f} mm); POINT ROIs skipped"
)

# pydicom's DICOM SEG (BINARY, 1 bit per pixel; a liver segment on 512 × 512 CT pixels), cut
# down to one frame there: made a three-frame file (its functional groups already place three
# frames 1 mm apart) by repeating the frame. `--labels` meshes segment 1, named, from the file;
# the reference is the array pydicom decodes, as labels, placed by the frames' positions.
liver = pydicom.dcmread(get_testdata_file("liver_1frame.dcm"))
assert liver.SegmentationType == "BINARY" and len(liver.PerFrameFunctionalGroupsSequence) == 3
liver.NumberOfFrames = 3
liver.PixelData = liver.PixelData * 3
liver.save_as(work / "liver3.dcm")
seg = pydicom.dcmread(work / "liver3.dcm")
masks = seg.pixel_array.astype(np.float32)  # [frame, row, column]
groups = seg.PerFrameFunctionalGroupsSequence
shared = seg.SharedFunctionalGroupsSequence[0] if "SharedFunctionalGroupsSequence" in seg else groups[0]
iop = np.array(shared.PlaneOrientationSequence[0].ImageOrientationPatient, float)
spacing = [float(s) for s in shared.PixelMeasuresSequence[0].PixelSpacing]
positions = np.array([g.PlanePositionSequence[0].ImagePositionPatient for g in groups], float)
normal = np.cross(iop[:3], iop[3:])
order = np.argsort(positions @ normal)
labels = masks[order].transpose(2, 1, 0)  # [x, y, z]; the frames' segment is 1
np.save(work / "liver.npy", labels)
linear = np.stack([iop[:3] * spacing[1], iop[3:] * spacing[0], positions[order[1]] - positions[order[0]]], axis=1)
for smooth in ["0", "60"]:
    run = subprocess.run(
        [isocube, "extract", str(work / "liver3.dcm"), "--labels", "--smooth", smooth, "-o", str(work / "liver.ply")],
        capture_output=True,
        text=True,
    )
    assert run.returncode == 0 and "label 1 'Liver'" in run.stderr, run.stderr
    subprocess.run(
        [isocube, "extract", str(work / "liver.npy"), "--labels", "--smooth", smooth, "--index-space", "-q", "-o", str(work / "ref.ply")],
        check=True,
    )
    mine = trimesh.load(work / "liver-1.ply", process=False)
    ref = trimesh.load(work / "ref-1.ply", process=False)
    placed = np.asarray(ref.vertices, float) @ linear.T + positions[order[0]]
    voxel = min(spacing + [float(np.linalg.norm(linear[:, 2]))])
    assert len(mine.faces) == len(ref.faces) > 0 and mine.is_watertight
    far = float(np.abs(np.asarray(mine.vertices, float) - placed).max())
    assert far <= 1e-4 * voxel, far
    print(f"liver SEG (3 frames), --smooth {smooth}: segment 1 'Liver' {len(mine.faces)} triangles, watertight, vertices within {far:.1e}")
