"""Writes the DICOM variants of the reader fixtures into tests/data/volumes/, from the checked-in
`dicom` series (make_volumes.py), with programs that share no code with isocube: pydicom and
its encoders (RLE in pydicom, JPEG-LS by CharLS through pyjpegls, JPEG 2000 by OpenJPEG through
imagecodecs, lossless JPEG by libjpeg-turbo through imagecodecs), and records each in
expected.json beside the others.

    pip install -r tests/interop/requirements-volumes.txt
    python tests/interop/make_dicom.py [OUTDIR]

What each variant exercises in isocube's reader:
- dicom-bigendian, dicom-deflate: explicit VR big endian; a deflated data set.
- dicom-rle, dicom-jpegls, dicom-j2k, dicom-jpeg-lossless: one compressed slice per file, with
  negative stored values (a rescale intercept brings them back), so sign extension shows.
- dicom-jpeg12: 12-bit lossy JPEG (process 4), with dicom-jpeg12.npy, the values pydicom
  decodes from it.
- enhanced.dcm: an enhanced CT, one multi-frame file whose frames are out of order, placed by
  per-frame Plane Position, with shared Pixel Measures, Plane Orientation and value transform.
- enhanced-jpegls.dcm: the same with its frames JPEG-LS compressed (one fragment per frame).
- rtdose.dcm, rtdose-rle.dcm: an RT Dose grid, 32-bit unsigned, frames placed by the Grid Frame
  Offset Vector, values scaled by Dose Grid Scaling; and the same in RLE.
"""

import json
import sys
from pathlib import Path

import numpy as np
import pydicom
from pydicom.dataset import Dataset, FileDataset, FileMetaDataset
from pydicom.encaps import encapsulate
from pydicom.sequence import Sequence
from pydicom.uid import (
    DeflatedExplicitVRLittleEndian,
    ExplicitVRBigEndian,
    ExplicitVRLittleEndian,
    JPEG2000Lossless,
    JPEGLosslessSV1,
    JPEGExtended12Bit,
    JPEGLSLossless,
    RLELossless,
    generate_uid,
)

out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parents[1] / "data" / "volumes"
expected_path = out / "expected.json"
expected = json.loads(expected_path.read_text())
base = expected["files"]["dicom"]
slices = sorted(
    (pydicom.dcmread(p) for p in (out / "dicom").glob("*.dcm")),
    key=lambda ds: float(np.dot(ds.ImagePositionPatient, np.cross(ds.ImageOrientationPatient[:3], ds.ImageOrientationPatient[3:]))),
)
NZ = len(slices)
frames = np.stack([ds.pixel_array for ds in slices])  # [z, y, x], int16
linear = np.array(base["linear"])
origin = np.array(base["origin"])
normal = linear[:, 2] / np.linalg.norm(linear[:, 2])
step = float(np.linalg.norm(linear[:, 2]))


def record(name, scale=2.0, offset=-1024.0):
    expected["files"][name] = {**base, "scale": scale, "offset": offset}


def fresh(folder):
    folder.mkdir(exist_ok=True)
    for old in folder.glob("*.dcm"):
        old.unlink()
    return folder


# Byte order and deflate: the same slices re-encoded by pydicom.
for name, syntax in [("dicom-bigendian", ExplicitVRBigEndian), ("dicom-deflate", DeflatedExplicitVRLittleEndian)]:
    folder = fresh(out / name)
    for ds in slices:
        source = pydicom.dcmread(ds.filename)
        ds = FileDataset(source.filename, {}, file_meta=source.file_meta, preamble=b"\0" * 128)
        # Elements as values (not the raw little-endian bytes), so pydicom encodes them anew.
        for tag in source.keys():
            if tag != 0x7FE00010:
                ds[tag] = source[tag]
        ds.file_meta.TransferSyntaxUID = syntax
        # Pixel data held anew in little endian: pydicom swaps OW values for big endian.
        ds.PixelData = source.pixel_array.astype("<i2").tobytes()
        ds["PixelData"].VR = "OW"
        if syntax == ExplicitVRBigEndian:
            pydicom.dcmwrite(folder / Path(ds.filename).name, ds, little_endian=False, implicit_vr=False, enforce_file_format=True)
        else:
            ds.save_as(folder / Path(ds.filename).name, enforce_file_format=True)
        back = pydicom.dcmread(folder / Path(ds.filename).name)
        assert np.array_equal(back.pixel_array, pydicom.dcmread(ds.filename).pixel_array), name
    record(name)


# Compressed slices; stored values shifted down by 600 (some negative), the intercept up by
# 2 × 600, so the rescaled values are the series' own.
SHIFT = 600


def encode(frame, syntax):
    if syntax == JPEGLosslessSV1:
        import imagecodecs

        return imagecodecs.jpeg8_encode(frame.astype(np.uint16), lossless=True, predictor=1, bitspersample=16)
    if syntax == JPEG2000Lossless:
        import imagecodecs

        # Two resolution levels: OpenJPEG's default of six needs images of 32 pixels or more.
        return imagecodecs.jpeg2k_encode(frame, level=0, codecformat="J2K", reversible=True, resolutions=2)
    raise ValueError(syntax)


for name, syntax in [
    ("dicom-rle", RLELossless),
    ("dicom-jpegls", JPEGLSLossless),
    ("dicom-j2k", JPEG2000Lossless),
    ("dicom-jpeg-lossless", JPEGLosslessSV1),
]:
    folder = fresh(out / name)
    for ds in slices:
        ds = pydicom.dcmread(ds.filename)
        shifted = (ds.pixel_array.astype(np.int32) - SHIFT).astype(np.int16)
        ds.RescaleIntercept = -1024 + 2 * SHIFT
        if syntax in (JPEGLosslessSV1, JPEG2000Lossless):
            ds.PixelData = encapsulate([encode(shifted, syntax)])
            ds["PixelData"].VR = "OB"
            ds.file_meta.TransferSyntaxUID = syntax
        else:
            ds.compress(syntax, shifted)
        target = folder / Path(ds.filename).name
        ds.save_as(target, enforce_file_format=True)
        back = pydicom.dcmread(target)
        assert back.file_meta.TransferSyntaxUID == syntax
        assert np.array_equal(back.pixel_array.astype(np.int16), shifted), name
    record(name)


# 12-bit lossy JPEG (JPEG Extended, process 4): the series' stored values as unsigned 12-bit
# samples, encoded by libjpeg-turbo's 12-bit build (imagecodecs). Lossy, so the volume test
# allows the coding error ("tolerance", in rescaled units); beside it, dicom-jpeg12.npy holds
# what Thomas Richter's libjpeg (pydicom's decoder for this syntax, through
# pylibjpeg-libjpeg) makes of the very frames, which isocube must give value for value.
def jpeg12():
    import imagecodecs

    folder = fresh(out / "dicom-jpeg12")
    reference = []
    error = 0
    for ds in slices:
        ds = pydicom.dcmread(ds.filename)
        stored = ds.pixel_array.astype(np.uint16)
        ds.BitsStored, ds.HighBit, ds.PixelRepresentation = 12, 11, 0
        ds.LossyImageCompression = "01"
        ds.PixelData = encapsulate([imagecodecs.jpeg8_encode(stored, level=95, bitspersample=12)])
        ds["PixelData"].VR = "OB"
        ds.file_meta.TransferSyntaxUID = JPEGExtended12Bit
        target = folder / Path(ds.filename).name
        ds.save_as(target, enforce_file_format=True)
        back = pydicom.dcmread(target)
        reference.append((float(np.dot(back.ImagePositionPatient, normal)), back.pixel_array))
        error = max(error, int(np.abs(back.pixel_array.astype(int) - stored).max()))
    planes = np.stack([plane for _, plane in sorted(reference, key=lambda r: r[0])])  # [z, y, x]
    np.save(out / "dicom-jpeg12.npy", np.asfortranarray(planes.transpose(2, 1, 0)))
    record("dicom-jpeg12")
    # Rescaled by the slope 2; one more stored unit of slack for rounding.
    expected["files"]["dicom-jpeg12"]["tolerance"] = 2.0 * (error + 1)
    print(f"dicom-jpeg12: lossy error up to {error} stored units")


jpeg12()


def new_file(name, sop_class, syntax=ExplicitVRLittleEndian):
    meta = FileMetaDataset()
    meta.MediaStorageSOPClassUID = sop_class
    meta.MediaStorageSOPInstanceUID = generate_uid()
    meta.TransferSyntaxUID = syntax
    ds = FileDataset(str(name), {}, file_meta=meta, preamble=b"\0" * 128)
    ds.SOPClassUID = sop_class
    ds.SOPInstanceUID = meta.MediaStorageSOPInstanceUID
    ds.SeriesInstanceUID = generate_uid()
    ds.StudyInstanceUID = slices[0].StudyInstanceUID
    ds.Rows, ds.Columns = slices[0].Rows, slices[0].Columns
    ds.SamplesPerPixel = 1
    ds.PhotometricInterpretation = "MONOCHROME2"
    ds.NumberOfFrames = NZ
    return ds


def item(**elements):
    d = Dataset()
    for k, v in elements.items():
        setattr(d, k, v)
    return d


# Enhanced CT: frames stored in the order 3, 0, 6, 1, 4, 7, 2, 5 of the slices.
order = [(3 * k) % NZ for k in range(NZ)]
for name, syntax in [("enhanced.dcm", ExplicitVRLittleEndian), ("enhanced-jpegls.dcm", JPEGLSLossless)]:
    ds = new_file(out / name, "1.2.840.10008.5.1.4.1.1.2.1", syntax)
    ds.Modality = "CT"
    ds.BitsAllocated, ds.BitsStored, ds.HighBit = 16, 16, 15
    ds.PixelRepresentation = 1
    ds.SharedFunctionalGroupsSequence = Sequence(
        [
            item(
                PixelMeasuresSequence=Sequence([item(PixelSpacing=list(slices[0].PixelSpacing), SliceThickness=step)]),
                PlaneOrientationSequence=Sequence([item(ImageOrientationPatient=list(slices[0].ImageOrientationPatient))]),
                PixelValueTransformationSequence=Sequence(
                    [item(RescaleSlope=2, RescaleIntercept=-1024 + 2 * SHIFT, RescaleType="HU")]
                ),
            )
        ]
    )
    ds.PerFrameFunctionalGroupsSequence = Sequence(
        [
            item(PlanePositionSequence=Sequence([item(ImagePositionPatient=list(slices[z].ImagePositionPatient))]))
            for z in order
        ]
    )
    stack = (frames[order].astype(np.int32) - SHIFT).astype(np.int16)
    if syntax == ExplicitVRLittleEndian:
        ds.PixelData = stack.astype("<i2").tobytes()
    else:
        ds.compress(syntax, stack)
    ds.save_as(out / name, enforce_file_format=True)
    back = pydicom.dcmread(out / name)
    assert np.array_equal(back.pixel_array.astype(np.int16), stack), name
    record(name)


# RT Dose: 32-bit unsigned doses, frames at the Grid Frame Offset Vector's offsets along the
# normal (relative: the first is 0), Gy = stored × Dose Grid Scaling.
SCALE = 2.5e-3
# PS3.5 8.2.2 allows RLE of 32-bit samples, as RT Dose grids are; pydicom's encoder handles any
# sample width but its table of profiles stops at 16 bits.
from pydicom.pixels.encoders.base import ENCODING_PROFILES

ENCODING_PROFILES[RLELossless].append(("MONOCHROME2", 1, (0, 1), (32,), range(1, 33)))
for name, syntax in [("rtdose.dcm", ExplicitVRLittleEndian), ("rtdose-rle.dcm", RLELossless)]:
    ds = new_file(out / name, "1.2.840.10008.5.1.4.1.1.481.2", syntax)
    ds.Modality = "RTDOSE"
    ds.BitsAllocated, ds.BitsStored, ds.HighBit = 32, 32, 31
    ds.PixelRepresentation = 0
    ds.ImagePositionPatient = list(slices[0].ImagePositionPatient)
    ds.ImageOrientationPatient = list(slices[0].ImageOrientationPatient)
    ds.PixelSpacing = list(slices[0].PixelSpacing)
    ds.FrameIncrementPointer = 0x3004000C
    ds.GridFrameOffsetVector = [step * k for k in range(NZ)]
    ds.DoseUnits, ds.DoseType, ds.DoseSummationType = "GY", "PHYSICAL", "PLAN"
    ds.DoseGridScaling = SCALE
    # The fixture's values themselves (100 + i + 10 j + 100 k), as unsigned 32-bit doses.
    doses = frames.astype(np.uint32)
    if syntax == ExplicitVRLittleEndian:
        ds.PixelData = doses.astype("<u4").tobytes()
    else:
        ds.compress(syntax, doses)
    ds.save_as(out / name, enforce_file_format=True)
    back = pydicom.dcmread(out / name)
    assert np.array_equal(back.pixel_array, doses), name
    record(name, SCALE, 0.0)

expected_path.write_text(json.dumps(expected, indent=1) + "\n")
print("wrote the DICOM variants to", out)


# An RT Structure Set: ROI 1 'ring' drawn as a key-hole polygon (an outline reached to its hole
# by a zero-width channel) on three axial planes, 5 mm apart; ROI 7 'marker' a POINT.
ds = new_file(out / "rtstruct.dcm", "1.2.840.10008.5.1.4.1.1.481.3")
for tag in ("Rows", "Columns", "SamplesPerPixel", "PhotometricInterpretation", "NumberOfFrames"):
    delattr(ds, tag)
ds.Modality = "RTSTRUCT"
ds.StructureSetLabel = "fixture"
ds.StructureSetROISequence = Sequence(
    [item(ROINumber=1, ROIName="ring", ROIGenerationAlgorithm="MANUAL"), item(ROINumber=7, ROIName="marker")]
)
ds.RTROIObservationsSequence = Sequence(
    [
        item(ObservationNumber=1, ReferencedROINumber=1, RTROIInterpretedType="ORGAN"),
        item(ObservationNumber=2, ReferencedROINumber=7, RTROIInterpretedType="MARKER"),
    ]
)


def keyhole(z, outer, inner):
    """A square of half-width `outer` with a square hole of half-width `inner`, one polygon."""
    o, i = outer, inner
    xy = [(-o, -o), (o, -o), (o, o), (-o, o), (-o, 0), (-i, 0), (-i, i), (i, i), (i, -i), (-i, -i), (-i, 0), (-o, 0)]
    return item(
        ContourGeometricType="CLOSED_PLANAR",
        NumberOfContourPoints=len(xy),
        ContourData=[float(c) for x, y in xy for c in (x + 10.0, y - 20.0, z)],
    )


ds.ROIContourSequence = Sequence(
    [
        item(
            ReferencedROINumber=1,
            ContourSequence=Sequence([keyhole(z, 30.0 - k, 12.0 + k) for k, z in enumerate([-5.0, 0.0, 5.0])]),
        ),
        item(
            ReferencedROINumber=7,
            ContourSequence=Sequence(
                [item(ContourGeometricType="POINT", NumberOfContourPoints=1, ContourData=[10.0, -20.0, 0.0])]
            ),
        ),
    ]
)
ds.save_as(out / "rtstruct.dcm", enforce_file_format=True)
print("wrote rtstruct.dcm")


# A DICOM SEG (BINARY, 1 bit per pixel, frames packed without padding): segment 1 'low' where
# the series' stored values are below 350, segment 2 'high' above 750; only frames holding
# something are stored (slices 3 to 5 hold neither), in a shuffled order.
from pydicom.pixels import pack_bits

ds = new_file(out / "seg.dcm", "1.2.840.10008.5.1.4.1.1.66.4")
ds.Modality = "SEG"
ds.SegmentationType = "BINARY"
ds.BitsAllocated, ds.BitsStored, ds.HighBit = 1, 1, 0
ds.PixelRepresentation = 0
ds.SegmentSequence = Sequence(
    [item(SegmentNumber=1, SegmentLabel="low", SegmentAlgorithmType="MANUAL"),
     item(SegmentNumber=2, SegmentLabel="high", SegmentAlgorithmType="MANUAL")]
)
ds.SharedFunctionalGroupsSequence = Sequence(
    [
        item(
            PixelMeasuresSequence=Sequence(
                [item(PixelSpacing=list(slices[0].PixelSpacing), SliceThickness=step, SpacingBetweenSlices=step)]
            ),
            PlaneOrientationSequence=Sequence([item(ImageOrientationPatient=list(slices[0].ImageOrientationPatient))]),
        )
    ]
)
masks = []
groups = []
for segment, inside in [(1, frames < 350), (2, frames > 750)]:
    for z in range(NZ):
        if inside[z].any():
            masks.append(inside[z])
            groups.append(
                item(
                    PlanePositionSequence=Sequence([item(ImagePositionPatient=list(slices[z].ImagePositionPatient))]),
                    SegmentIdentificationSequence=Sequence([item(ReferencedSegmentNumber=segment)]),
                )
            )
shuffle = [(3 * f) % len(masks) for f in range(len(masks))]
assert sorted(shuffle) == list(range(len(masks)))
ds.NumberOfFrames = len(masks)
ds.PerFrameFunctionalGroupsSequence = Sequence([groups[f] for f in shuffle])
ds.PixelData = pack_bits(np.stack([masks[f] for f in shuffle]).astype(np.uint8))
ds.save_as(out / "seg.dcm", enforce_file_format=True)
back = pydicom.dcmread(out / "seg.dcm")
assert np.array_equal(back.pixel_array, np.stack([masks[f] for f in shuffle]))
print("wrote seg.dcm:", len(masks), "frames")

# The same structure set with a third region whose contour crosses itself (a bow tie): the
# other regions are read, the bow tie refused by name.
ds = pydicom.dcmread(out / "rtstruct.dcm")
ds.SOPInstanceUID = generate_uid()
ds.file_meta.MediaStorageSOPInstanceUID = ds.SOPInstanceUID
ds.StructureSetROISequence.append(item(ROINumber=9, ROIName="bowtie"))
bowtie = [(0, 0), (20, 20), (20, 0), (0, 20)]
ds.ROIContourSequence.append(
    item(
        ReferencedROINumber=9,
        ContourSequence=Sequence(
            [
                item(
                    ContourGeometricType="CLOSED_PLANAR",
                    NumberOfContourPoints=4,
                    ContourData=[float(c) for x, y in bowtie for c in (x, y, z)],
                )
                for z in (0.0, 5.0)
            ]
        ),
    )
)
ds.save_as(out / "rtstruct-bowtie.dcm", enforce_file_format=True)
print("wrote rtstruct-bowtie.dcm")
