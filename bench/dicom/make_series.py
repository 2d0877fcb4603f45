"""A 256 × 256 × 120 CT-like series (two nested balls and noise, 0.8 × 0.8 × 2 mm) in five
transfer syntaxes, written by pydicom and its encoders into the current folder: raw/, rle/,
jls/, j2k/, and j12/ (12-bit lossy JPEG Extended, quality 90, by libjpeg-turbo through
imagecodecs) (bench/dicom/run.sh)."""

from pathlib import Path

import numpy as np
from pydicom.dataset import FileDataset, FileMetaDataset
from pydicom.encaps import encapsulate
from pydicom.uid import (
    ExplicitVRLittleEndian,
    JPEGExtended12Bit,
    JPEG2000Lossless,
    JPEGLSLossless,
    RLELossless,
    generate_uid,
)

N, NZ = 256, 120
x, y = np.meshgrid(np.arange(N), np.arange(N), indexing="xy")
rng = np.random.default_rng(1)
for syntax, name in [
    (ExplicitVRLittleEndian, "raw"),
    (RLELossless, "rle"),
    (JPEGLSLossless, "jls"),
    (JPEG2000Lossless, "j2k"),
    (JPEGExtended12Bit, "j12"),
]:
    folder = Path(name)
    folder.mkdir(exist_ok=True)
    series = generate_uid()
    for k in range(NZ):
        r = np.sqrt((x - 128) ** 2 + (y - 128) ** 2 + ((k - 60) * 2.0) ** 2)
        image = (1000 * (r < 90) + 400 * (r < 60) + rng.normal(0, 20, (N, N))).astype(np.int16)
        meta = FileMetaDataset()
        meta.MediaStorageSOPClassUID = "1.2.840.10008.5.1.4.1.1.2"
        meta.MediaStorageSOPInstanceUID = generate_uid()
        meta.TransferSyntaxUID = ExplicitVRLittleEndian
        ds = FileDataset(str(folder / f"{k}.dcm"), {}, file_meta=meta, preamble=b"\0" * 128)
        ds.SOPClassUID = meta.MediaStorageSOPClassUID
        ds.SOPInstanceUID = meta.MediaStorageSOPInstanceUID
        ds.SeriesInstanceUID = series
        ds.Modality = "CT"
        ds.ImagePositionPatient = [0.0, 0.0, 2.0 * k]
        ds.ImageOrientationPatient = [1, 0, 0, 0, 1, 0]
        ds.PixelSpacing = [0.8, 0.8]
        ds.Rows, ds.Columns = N, N
        ds.SamplesPerPixel = 1
        ds.PhotometricInterpretation = "MONOCHROME2"
        ds.BitsAllocated, ds.BitsStored, ds.HighBit = 16, 16, 15
        ds.PixelRepresentation = 1
        ds.RescaleSlope, ds.RescaleIntercept = 1, -1024
        if syntax == ExplicitVRLittleEndian:
            ds.PixelData = image.tobytes()
        elif syntax == JPEGExtended12Bit:
            import imagecodecs

            # 12-bit samples are unsigned: shifted up by 100, the intercept down by as much.
            ds.BitsStored, ds.HighBit, ds.PixelRepresentation = 12, 11, 0
            ds.RescaleIntercept = -1124
            stored = np.clip(image.astype(np.int32) + 100, 0, 4095).astype(np.uint16)
            ds.PixelData = encapsulate([imagecodecs.jpeg8_encode(stored, level=90, bitspersample=12)])
            ds["PixelData"].VR = "OB"
            ds.file_meta.TransferSyntaxUID = syntax
        else:
            ds.compress(syntax, image)
        ds.save_as(folder / f"{k}.dcm", enforce_file_format=True)
