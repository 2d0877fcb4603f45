"""The peer's route through a DICOM series, as a user writes it: pydicom reads and decodes the
slices (its plugins for compressed ones), rescales and stacks them; scikit-image's
marching_cubes meshes; NumPy writes a binary PLY.

    python pydicom_skimage.py FOLDER LEVEL OUT.ply
"""

import sys
import time
from pathlib import Path

import numpy as np
import pydicom
from skimage.measure import marching_cubes

start = time.perf_counter()
slices = [pydicom.dcmread(f) for f in Path(sys.argv[1]).glob("*.dcm")]
slices.sort(key=lambda d: float(d.ImagePositionPatient[2]))
volume = np.stack(
    [d.pixel_array.astype(np.float32) * float(d.RescaleSlope) + float(d.RescaleIntercept) for d in slices]
)
read = time.perf_counter()
spacing = (2.0, float(slices[0].PixelSpacing[0]), float(slices[0].PixelSpacing[1]))
verts, faces, _, _ = marching_cubes(volume, float(sys.argv[2]), spacing=spacing)
meshed = time.perf_counter()
with open(sys.argv[3], "wb") as out:
    out.write(
        f"ply\nformat binary_little_endian 1.0\nelement vertex {len(verts)}\nproperty float x\n"
        f"property float y\nproperty float z\nelement face {len(faces)}\n"
        "property list uchar int vertex_indices\nend_header\n".encode()
    )
    out.write(verts[:, ::-1].astype("<f4").tobytes())
    records = np.empty(len(faces), dtype=[("n", "u1"), ("i", "<i4", 3)])
    records["n"], records["i"] = 3, faces
    out.write(records.tobytes())
done = time.perf_counter()
print(
    f"pydicom+skimage {Path(sys.argv[1]).name:4} {done - start:.2f} s "
    f"(read {read - start:.2f}, mesh {meshed - read:.2f}, write {done - meshed:.2f}; {len(faces)} triangles)"
)
