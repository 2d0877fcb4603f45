"""isocube.label_surfaces: closed surfaces per label, shared interfaces, the command line's
files."""

from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np
import pytest

import isocube

from .test_save import cli


def segmentation() -> np.ndarray:
    """Three labels in a 20 × 22 × 24 volume: two touching blobs and a ball inside one."""
    x, y, z = np.mgrid[0:20, 0:22, 0:24].astype(np.float64)
    seg = np.zeros(x.shape, np.int16)
    seg[(x - 7) ** 2 + (y - 11) ** 2 + (z - 12) ** 2 < 36] = 1
    seg[(x - 13) ** 2 + (y - 11) ** 2 + (z - 12) ** 2 < 30] = 2
    seg[(x - 6) ** 2 + (y - 11) ** 2 + (z - 11) ** 2 < 5] = 3
    return seg


@pytest.mark.parametrize("smoothing", [0, 60])
def test_each_label_is_closed_and_neighbours_share_their_interface(smoothing: int) -> None:
    surfaces = isocube.label_surfaces(segmentation(), smoothing=smoothing)
    assert sorted(surfaces) == [1, 2, 3]
    for mesh in surfaces.values():
        assert mesh.is_watertight()

    def oriented(mesh: isocube.Mesh) -> set[tuple[float, ...]]:
        out = set()
        for t in mesh.vertices[mesh.triangles].astype(np.float64):
            r = min(range(3), key=lambda k: tuple(t[k]))
            out.add(tuple(np.roll(t, -r, axis=0).ravel()))
        return out

    def reversed_(mesh: isocube.Mesh) -> isocube.Mesh:
        return isocube.Mesh(mesh.vertices, mesh.triangles[:, ::-1])

    # The interface of 1 and 2 is in both, facing opposite ways.
    shared = oriented(surfaces[1]) & oriented(reversed_(surfaces[2]))
    assert len(shared) > 20


@pytest.mark.parametrize("order", ["C", "F"])
def test_files_are_the_command_lines_bytes(tmp_path: Path, order: str) -> None:
    seg = segmentation()
    seg = np.ascontiguousarray(seg) if order == "C" else np.asfortranarray(seg)
    npy = tmp_path / "seg.npy"
    np.save(npy, seg)
    surfaces = isocube.label_surfaces(np.load(npy), smoothing=20, only=[1, 3])
    assert sorted(surfaces) == [1, 3]
    subprocess.run(
        [
            cli(),
            "extract",
            str(npy),
            "--labels",
            "1,3",
            "--smooth",
            "20",
            "-o",
            str(tmp_path / "cli.ply"),
        ],
        check=True,
        capture_output=True,
    )
    for label, mesh in surfaces.items():
        mesh.save(tmp_path / f"python-{label}.ply")
        ours = (tmp_path / f"python-{label}.ply").read_bytes()
        assert ours == (tmp_path / f"cli-{label}.ply").read_bytes(), label


def test_non_integer_labels_are_refused() -> None:
    seg = segmentation().astype(np.float32)
    seg[3, 3, 3] = 0.5
    with pytest.raises(isocube.InputError):
        isocube.label_surfaces(seg)
    with pytest.raises(isocube.InputError, match="2\\*\\*24"):
        isocube.label_surfaces(np.full((3, 3, 3), 2**25, np.int64))
