"""Mesh.save writes what the command line writes: the same bytes, for every format."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import isocube

FORMATS = ["ply", "obj", "stl", "off", "glb", "vtp", "vtk", "msh"]


def cli() -> str:
    """The `isocube` binary: $ISOCUBE_BIN (CI sets it), or one on the PATH."""
    found = os.environ.get("ISOCUBE_BIN") or shutil.which("isocube")
    if not found:
        pytest.skip("no isocube binary (set ISOCUBE_BIN)")
    return found


def volume() -> np.ndarray:
    x, y, z = np.mgrid[-1:1:33j, -1:1:34j, -1:1:35j]
    field: np.ndarray = (np.sqrt((1.3 * x) ** 2 + y**2 + (0.8 * z) ** 2) - 0.7).astype(np.float32)
    return field


@pytest.mark.parametrize("order", ["C", "F"])
@pytest.mark.parametrize(
    "options,flags",
    [
        ({}, []),
        ({"method": "ternary", "snap": 0.3}, ["--method", "ternary", "--snap", "0.3"]),
        ({"triangulate": "optimal", "flip": True}, ["--triangulate", "optimal", "--flip"]),
    ],
)
def test_files_are_the_command_lines_bytes(
    tmp_path: Path, order: str, options: dict[str, Any], flags: list[str]
) -> None:
    a = np.ascontiguousarray(volume()) if order == "C" else np.asfortranarray(volume())
    npy = tmp_path / "volume.npy"
    np.save(npy, a)
    mesh = isocube.extract(np.load(npy), 0.0, **options)
    assert len(mesh.triangles) > 1000
    for ext in FORMATS:
        ours, theirs = tmp_path / f"python.{ext}", tmp_path / f"cli.{ext}"
        mesh.save(ours)
        subprocess.run(
            [cli(), "extract", str(npy), "-o", str(theirs), "--level", "0", *flags],
            check=True,
            capture_output=True,
        )
        assert ours.read_bytes() == theirs.read_bytes(), ext


def test_values_and_ascii_reach_the_file(tmp_path: Path) -> None:
    mesh = isocube.extract(volume(), 0.0, values=True)
    assert mesh.values is not None
    mesh.save(tmp_path / "m.ply", ascii=True, values_name="dose")
    text = (tmp_path / "m.ply").read_text()
    assert text.startswith("ply\nformat ascii 1.0")
    assert "property float dose" in text
    # A format without per-vertex data refuses values rather than dropping them.
    with pytest.raises(isocube.FormatError, match="values"):
        mesh.save(tmp_path / "m.stl")
    assert not (tmp_path / "m.stl").exists()


def test_a_bad_path_is_a_format_error_naming_it(tmp_path: Path) -> None:
    mesh = isocube.extract(volume(), 0.0)
    with pytest.raises(isocube.FormatError, match="extension"):
        mesh.save(tmp_path / "m.xyz")
    missing = tmp_path / "no" / "such" / "dir" / "m.ply"
    with pytest.raises(isocube.FormatError, match="m.ply"):
        mesh.save(missing)


DTYPES = ["u1", "i1", "u2", "i2", "u4", "i4", "u8", "i8", "f4", "f8"]


@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("order", ["C", "F"])
@pytest.mark.parametrize("endian", ["<", ">"])
def test_every_dtype_the_command_reads_gives_its_mesh(
    tmp_path: Path, dtype: str, order: str, endian: str
) -> None:
    if endian == ">" and dtype[1] == "1":
        pytest.skip("one byte: no byte order")
    # Values from 0 to 127 fit every dtype; the level between two integers.
    field = np.clip((volume() + 0.8) * 100, 0, 127)
    a = np.asarray(field.astype(endian + dtype), order=order)  # type: ignore[call-overload]
    npy = tmp_path / "volume.npy"
    np.save(npy, a)
    loaded = np.load(npy)
    assert loaded.dtype == np.dtype(endian + dtype)
    ours, theirs = tmp_path / "python.ply", tmp_path / "cli.ply"
    mesh = isocube.extract(loaded, 80.5)
    assert len(mesh.triangles) > 1000 and mesh.is_watertight()
    mesh.save(ours)
    subprocess.run(
        [cli(), "extract", str(npy), "-o", str(theirs), "--level", "80.5"],
        check=True,
        capture_output=True,
    )
    assert ours.read_bytes() == theirs.read_bytes()
