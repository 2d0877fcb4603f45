"""One file, one mesh: the same tied integer volume stored as u8, i16, i32, f32 (also with its
zeros as -0.0) and f64 meshes to the command line's bytes through every Python path
(isocube.extract in one pass and in boxes, ternary, Volume.extract from read_volume,
isocube.dask) — and an empty surface is an error naming the values' range unless asked for."""

from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np
import pytest

import isocube
import isocube.dask

from .test_save import cli

TYPES = [np.uint8, np.int16, np.int32, np.float32, np.float64]


def tied(seed: int, shape: tuple[int, int, int] = (17, 19, 23)) -> np.ndarray:
    """Random integers in −2..2: most points exactly at a level."""
    return np.random.default_rng(seed).integers(-2, 3, size=shape)


def stored(values: np.ndarray, dtype: type | str) -> tuple[np.ndarray, int]:
    """The values as `dtype` (shifted by 2 for unsigned types) and the shift; `"-0"`: float32
    with every zero stored as ``-0.0``, as rounding negative floats leaves them."""
    if dtype == "-0":
        a = values.astype(np.float32)
        a[a == 0] = -0.0
        return a, 0
    shift = 2 if np.dtype(dtype).kind == "u" else 0
    return (values + shift).astype(dtype), shift


@pytest.mark.parametrize("seed", [1, 49])
@pytest.mark.parametrize(
    "options",
    [
        {},
        {"method": "ternary"},
        {"method": "ternary", "snap": 0.5, "triangulate": "optimal"},
        {"relax": 1},
    ],
)
def test_every_type_and_path_is_the_command_lines_file(
    tmp_path: Path, seed: int, options: dict[str, object]
) -> None:
    values = tied(seed)
    flags: list[str] = []
    for key, value in options.items():
        flags += [f"--{key.replace('_', '-')}", str(value)]
    # Relaxation is the slow one on so rough a surface: one level is enough for it.
    for level in (0,) if "relax" in options else (-1, 0, 1):
        want: bytes | None = None
        kinds: list[type | str] = [*TYPES, "-0"]
        for dtype in kinds:
            a, shift = stored(values, dtype)
            npy = tmp_path / f"v-{a.dtype.name}{'-neg' if dtype == '-0' else ''}.npy"
            np.save(npy, a)
            theirs = tmp_path / "cli.ply"
            chunked = tmp_path / "cli-chunk.ply"
            for out, extra in ((theirs, []), (chunked, ["--chunk", "7,5,3"])):
                subprocess.run(
                    [cli(), "extract", str(npy), "-o", str(out), "--level", str(level + shift)]
                    + flags
                    + extra,
                    check=True,
                    capture_output=True,
                )
            cli_bytes = theirs.read_bytes()
            assert chunked.read_bytes() == cli_bytes, (dtype, level, options)
            if want is None:
                want = cli_bytes
            assert cli_bytes == want, (dtype, level, options)
            ours = tmp_path / "python.ply"
            for mesh in (
                isocube.extract(np.load(npy), level + shift, **options),  # type: ignore[arg-type]
                isocube.extract(np.load(npy), level + shift, chunk=(5, 7, 3), **options),  # type: ignore[arg-type]
                isocube.read_volume(npy).extract(level + shift, **options),
            ):
                mesh.save(ours)
                assert ours.read_bytes() == want, (dtype, level, options)


@pytest.mark.parametrize("dtype", TYPES)
def test_dask_writes_the_command_lines_file(tmp_path: Path, dtype: type) -> None:
    da = pytest.importorskip("dask.array")
    a, shift = stored(tied(7), dtype)
    npy = tmp_path / "v.npy"
    np.save(npy, a)
    theirs = tmp_path / "cli.ply"
    subprocess.run(
        [cli(), "extract", str(npy), "-o", str(theirs), "--level", str(shift)],
        check=True,
        capture_output=True,
    )
    ours = tmp_path / "dask.ply"
    isocube.dask.extract(da.from_array(a, chunks=(5, 7, 9)), shift, scheduler="sync").save(ours)
    assert ours.read_bytes() == theirs.read_bytes()
    written = tmp_path / "written.ply"
    isocube.dask.write_ply(da.from_array(a, chunks=(6, 4, 11)), written, shift, scheduler="sync")
    assert written.read_bytes() == theirs.read_bytes()


def test_an_empty_surface_is_an_error_naming_the_range_unless_allowed() -> None:
    volume = np.linspace(-1, 2.5, 27, dtype=np.float32).reshape(3, 3, 3)
    with pytest.raises(isocube.LevelOutsideError, match="range from -1 to 2.5") as outside:
        isocube.extract(volume, 5.0)
    # Both isocube's error and the built-in ones scikit-image's callers catch.
    assert isinstance(outside.value, isocube.InputError)
    assert isinstance(outside.value, RuntimeError) and isinstance(outside.value, ValueError)
    assert "allow_empty=True" in str(outside.value)
    # At the smallest value every point counts as above: inside the range, still no surface.
    with pytest.raises(isocube.EmptySurfaceError, match="level -1: its values") as inside:
        isocube.extract(volume, -1.0)
    assert not isinstance(inside.value, ValueError) and isinstance(inside.value, RuntimeError)
    placed = isocube.Volume(volume, (1.0, 1.0, 1.0), (0.0, 0.0, 0.0), np.eye(3).tolist())
    for mesh in (
        isocube.extract(volume, 5.0, allow_empty=True),
        isocube.extract(volume, -1.0, allow_empty=True, method="ternary"),
        placed.extract(5.0, allow_empty=True),
    ):
        assert mesh.vertices.shape == (0, 3) and mesh.triangles.shape == (0, 3)
    with pytest.raises(isocube.EmptySurfaceError):
        placed.extract(9.0)
    nothing = np.full((4, 4, 4), np.nan, np.float32)
    with pytest.raises(isocube.LevelOutsideError, match="no finite value"):
        isocube.extract(nothing, 0.0)


def test_dask_follows_extract_on_an_empty_surface() -> None:
    da = pytest.importorskip("dask.array")
    volume = np.linspace(-1, 2.5, 64, dtype=np.float32).reshape(4, 4, 4)
    with pytest.raises(isocube.LevelOutsideError, match="range from -1 to 2.5"):
        isocube.dask.extract(da.from_array(volume, chunks=2), 5.0, scheduler="sync")
    mesh = isocube.dask.extract(
        da.from_array(volume, chunks=2), 5.0, scheduler="sync", allow_empty=True
    )
    assert len(mesh.triangles) == 0
