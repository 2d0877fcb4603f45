"""Writes tests/data/jpeg12/: 12-bit lossy JPEG streams (extended sequential DCT, SOF1) for the
decoder in crates/isocube-io/src/dicom/dct.rs, each beside the image Thomas Richter's libjpeg
decodes from it (through pylibjpeg-libjpeg, as pydicom does) as a 16-bit PGM.

    pip install -r tests/interop/requirements-volumes.txt
    python tests/interop/make_jpeg12.py [PATH_TO_RICHTERS_jpeg]

The streams come from two encoders that share no code with isocube: libjpeg-turbo's 12-bit
build (through imagecodecs), and, when the path to its `jpeg` program is given, Richter's
libjpeg (github.com/thorfdbg/libjpeg, built with `./configure && make`), which writes restart
markers on request (`-z`).
"""

import subprocess
import sys
import tempfile
from pathlib import Path

import imagecodecs
import libjpeg
import numpy as np

out = Path(__file__).resolve().parents[1] / "data" / "jpeg12"
out.mkdir(exist_ok=True)

rng = np.random.default_rng(5)
y, x = np.mgrid[0:37, 0:53]
# A smooth field with noise, 53 × 37: blocks cut at both edges.
smooth = (2048 + 1500 * np.sin(x / 7.0) * np.cos(y / 5.0) + rng.normal(0, 60, x.shape)).clip(0, 4095).astype(np.uint16)
# Full-range stripes: the inverse transform overshoots, so the clamp to 0 ..= 4095 shows.
stripes = ((np.indices((40, 48)).sum(0) // 3) % 2 * 4095).astype(np.uint16)


def pgm(path, image):
    path.write_bytes(b"P5\n%d %d\n4095\n" % (image.shape[1], image.shape[0]) + image.astype(">u2").tobytes())


def write(name, stream):
    assert stream[stream.find(b"\xff\xc1") + 4] == 12, name
    (out / f"{name}.jpg").write_bytes(stream)
    pgm(out / f"{name}.pgm", libjpeg.decode(stream))
    print(name, len(stream), "bytes")


write("turbo-q5", imagecodecs.jpeg8_encode(smooth, level=5, bitspersample=12))
write("turbo-q90", imagecodecs.jpeg8_encode(smooth, level=90, bitspersample=12))
write("stripes-q10", imagecodecs.jpeg8_encode(stripes, level=10, bitspersample=12))
if len(sys.argv) > 1:
    with tempfile.TemporaryDirectory() as tmp:
        source = Path(tmp) / "smooth.pgm"
        pgm(source, smooth)
        for quality, interval in [(30, 5), (85, 1)]:
            target = Path(tmp) / "out.jpg"
            subprocess.run([sys.argv[1], "-q", str(quality), "-z", str(interval), str(source), str(target)], check=True, capture_output=True)
            write(f"richter-q{quality}-restart{interval}", target.read_bytes())
