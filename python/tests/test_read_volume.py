"""isocube.read_volume on the repository's test volumes (every format the command line reads):
the values, where they lie, and the surface the command line makes from the same file."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import isocube

from .test_save import cli

DATA = Path(__file__).resolve().parents[2] / "tests" / "data" / "volumes"


def expected() -> dict[str, Any]:
    loaded: dict[str, Any] = json.loads((DATA / "expected.json").read_text())
    return loaded


@pytest.mark.parametrize("name", sorted(expected()["files"]))
def test_values_and_their_places_are_the_files(name: str) -> None:
    spec = expected()
    volume = isocube.read_volume(DATA / name)
    dims = spec["dims"]
    assert volume.values.shape == tuple(dims) and volume.values.dtype == np.float32
    i, j, k = np.meshgrid(*(np.arange(d) for d in dims), indexing="ij")
    # Stored values are 100 + i + 10 j + 100 k; the files' rescaling gives the real ones.
    file = spec["files"][name]
    real = (100 + i + 10 * j + 100 * k) * file["scale"] + file["offset"]
    # Lossy encodings carry their coding error.
    assert np.allclose(volume.values, real, atol=file.get("tolerance", 1e-3))
    # World position of point (i, j, k): origin + direction · (spacing ∘ (i, j, k)).
    linear = np.asarray(spec["files"][name]["linear"], dtype=np.float64)
    ours = np.asarray(volume.direction) * np.asarray(volume.spacing)
    assert np.allclose(ours, linear, atol=1e-9)
    assert np.allclose(volume.origin, spec["files"][name]["origin"], atol=1e-9)


@pytest.mark.parametrize("name", sorted(expected()["files"]))
def test_the_surface_is_the_command_lines(tmp_path: Path, name: str) -> None:
    ours, theirs = tmp_path / "python.ply", tmp_path / "cli.ply"
    file = expected()["files"][name]
    level = 400.5 * file["scale"] + file["offset"]
    mesh = isocube.read_volume(DATA / name).extract(level)
    assert len(mesh.triangles) > 50
    mesh.save(ours)
    subprocess.run(
        [cli(), "extract", str(DATA / name), "-o", str(theirs), "--level", str(level)],
        check=True,
        capture_output=True,
    )
    assert ours.read_bytes() == theirs.read_bytes()


def test_a_missing_or_broken_file_is_a_format_error(tmp_path: Path) -> None:
    with pytest.raises(isocube.FormatError, match="nothing.nii"):
        isocube.read_volume(tmp_path / "nothing.nii")
    broken = tmp_path / "broken.npy"
    broken.write_bytes(b"\x93NUMPY\x01\x00garbage")
    with pytest.raises(isocube.FormatError, match="broken.npy"):
        isocube.read_volume(broken)
    with pytest.raises(isocube.MemoryLimitError):
        isocube.read_volume(DATA / "plain.mhd", max_memory=100)


def test_frames_and_channels_are_picked() -> None:
    """A 4-d NIfTI: ``frame`` picks a volume (frame t holds the fixture's values + 1000 t);
    without it the error names the choice."""
    for t in range(3):
        volume = isocube.read_volume(DATA / "frames.nii", frame=t)
        assert volume.values.shape == (12, 10, 8)
        assert volume.values[3, 2, 1] == 100 + 3 + 20 + 100 + 1000 * t
    with pytest.raises(isocube.FormatError, match=r"choose one with --frame \(0 to 2\)"):
        isocube.read_volume(DATA / "frames.nii")
    both = isocube.read_volume(DATA / "channels.nii.gz", frame=1, channel=1)
    assert both.values[11, 9, 7] == 100 + 11 + 90 + 700 + 1000 + 10000


def test_levels_from_the_data(tmp_path: Path) -> None:
    """``level='40%'`` is that fraction of the value range and ``'auto'`` Otsu's threshold, as
    the command line takes them: the same surface as the number the command line prints."""
    volume = isocube.read_volume(DATA / "rotated.nii.gz")
    low, high = float(volume.values.min()), float(volume.values.max())
    forty = volume.extract("40%")
    assert (
        forty.triangles.shape
        == volume.extract(float(np.float32(low + 0.4 * (high - low)))).triangles.shape
    )
    run = subprocess.run(
        [
            cli(),
            "extract",
            str(DATA / "rotated.nii.gz"),
            "--level",
            "auto",
            "-o",
            str(tmp_path / "auto.ply"),
        ],
        capture_output=True,
        text=True,
    )
    assert run.returncode == 0, run.stderr
    printed = float(run.stderr.split("(level ")[1].split(",")[0])
    auto = volume.extract("auto")
    assert len(auto.triangles) > 0
    assert np.array_equal(auto.triangles, volume.extract(printed).triangles)
    with pytest.raises(isocube.InputError):
        volume.extract("lots")


MINC = DATA.parent / "minc"


@pytest.mark.parametrize("key", sorted(json.loads((MINC / "expected.json").read_text())))
def test_minc_files_read_as_nibabel_reads_them(key: str) -> None:
    """MINC-1 files give nibabel's values and affine (tests/interop/make_minc.py); MINC-2 (HDF5)
    needs the ``minc2`` build and is refused by name without it."""
    entry = json.loads((MINC / "expected.json").read_text())[key]
    path = MINC / entry["file"]
    if path.read_bytes()[:4] == b"\x89HDF":
        with pytest.raises(isocube.FormatError, match="minc2"):
            isocube.read_volume(path, frame=entry["frame"])
        return
    volume = isocube.read_volume(path, frame=entry["frame"])
    want = np.load(MINC / entry["values"])
    assert np.array_equal(volume.values, want)
    # nibabel's affine is over the file's axes, slowest first: isocube's reversed.
    affine = np.asarray(entry["affine"])
    ours = np.asarray(volume.direction) * np.asarray(volume.spacing)
    assert np.allclose(ours, affine[:3, [2, 1, 0]], atol=1e-9)
    assert np.allclose(volume.origin, affine[:3, 3], atol=1e-9)
