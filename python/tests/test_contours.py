"""isocube.contours: surfaces and volume meshes through stacks of contours, from files or
arrays; files byte for byte those of `isocube contours` and `isocube tetmesh`."""

from __future__ import annotations

import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import isocube
from isocube import contours

from .test_save import cli


def ring(
    radius: float, n: int, phase: float = 0.0, centre: tuple[float, float] = (0, 0)
) -> np.ndarray:
    t = np.linspace(0, 2 * np.pi, n, endpoint=False) + phase
    points: np.ndarray = np.c_[centre[0] + radius * np.cos(t), centre[1] + radius * np.sin(t)]
    return points


def sections() -> list[tuple[float, list[np.ndarray]]]:
    """A body with a hole through its middle sections and two lobes at the top."""
    return [
        (0.0, [ring(1.0, 30)]),
        (0.7, [ring(1.2, 41, 0.1), ring(0.4, 17)]),
        (1.5, [ring(1.1, 37, 0.2), ring(0.5, 19, 0.3)]),
        (2.1, [ring(0.5, 23, 0.0, (-0.6, 0.0)), ring(0.45, 21, 0.5, (0.6, 0.1))]),
    ]


def write_csv(path: Path, stack: list[tuple[float, list[np.ndarray]]]) -> None:
    rows = ["section,z,contour,x,y"]
    for s, (z, cs) in enumerate(stack):
        for c, points in enumerate(cs):
            # Files close each contour explicitly: the first point repeated.
            for x, y in [*points, points[0]]:
                rows.append(f"{s},{z!r},{c},{float(x)!r},{float(y)!r}")
    path.write_text("\n".join(rows) + "\n")


def command_file(tmp_path: Path, command: str, flags: list[str], name: str) -> tuple[Path, Path]:
    """The stack written as CSV, and the file `isocube COMMAND` makes from it with `flags`."""
    csv, out = tmp_path / "stack.csv", tmp_path / name
    write_csv(csv, sections())
    subprocess.run(
        [cli(), command, str(csv), "-o", str(out), *flags, "--quiet"],
        check=True,
        capture_output=True,
    )
    return csv, out


def boundary_edges(triangles: np.ndarray) -> int:
    t = triangles.astype(np.int64)
    e = np.sort(np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]]), axis=1)
    _, counts = np.unique(e, axis=0, return_counts=True)
    return int((counts != 2).sum())


def test_the_surface_passes_through_every_input_point() -> None:
    stack = sections()
    mesh = contours.reconstruct(stack, cell=0.05)
    assert mesh.is_watertight() and mesh.normals is not None
    assert mesh.stats["unresolved_edges"] == 0 and mesh.stats["missed_contours"] == 0
    vertices = mesh.vertices.astype(np.float64)
    for z, cs in stack:
        for points in cs:
            p = np.c_[points, np.full(len(points), z)]
            nearest = np.min(np.linalg.norm(vertices[None, :, :] - p[:, None, :], axis=2), axis=1)
            assert nearest.max() < 1e-5, (z, nearest.max())
    # Genus 1 at the middle (the hole), the top lobes joined below: one closed body.
    assert mesh.to_trimesh().body_count == 1


def test_sections_in_any_order_and_as_a_dict_give_the_same_mesh() -> None:
    stack = sections()
    first = contours.reconstruct(stack, grid=(30, 30))
    shuffled = contours.reconstruct(dict(reversed(stack)), grid=(30, 30))
    assert np.array_equal(first.vertices, shuffled.vertices)
    assert np.array_equal(first.triangles, shuffled.triangles)


def test_caps() -> None:
    stack = sections()
    extended = contours.reconstruct(stack, cap="extend", extend=0.3, grid=(30, 30))
    flat = contours.reconstruct(stack, cap="flat", grid=(30, 30))
    open_ = contours.reconstruct(stack, cap="none", grid=(30, 30))

    def heights(m: isocube.Mesh) -> tuple[float, float]:
        return float(m.vertices[:, 2].min()), float(m.vertices[:, 2].max())

    assert heights(extended) == pytest.approx((-0.3, 2.4), abs=1e-4)
    assert heights(flat) == pytest.approx((0.0, 2.1), abs=1e-6) and flat.is_watertight()
    assert boundary_edges(open_.triangles) > 0 and boundary_edges(flat.triangles) == 0


def test_bad_stacks_name_the_section_and_contour(tmp_path: Path) -> None:
    bow_tie = np.array([[0, 0], [1, 1], [1, 0], [0, 1]], dtype=float)
    with pytest.raises(isocube.InputError, match="section 1, contour 0"):
        contours.reconstruct([(0.0, [ring(1, 12)]), (1.0, [bow_tie])])
    with pytest.raises(isocube.InputError, match="section 0, contour 1"):
        contours.reconstruct([(0.0, [ring(1, 12), np.zeros((2, 2))])])
    with pytest.raises(isocube.InputError, match="expected an \\(n, 2\\) array"):
        contours.reconstruct([(0.0, [np.zeros((5, 3))])])
    with pytest.raises(isocube.InputError, match="cap"):
        contours.reconstruct(sections(), cap="round")
    with pytest.raises(isocube.MemoryLimitError):
        contours.reconstruct(sections(), cell=1e-4, max_memory=10**6)
    bad = tmp_path / "bad.csv"
    bad.write_text("section,z,contour,x,y\n0,0,0,0,0\n0,1,0,1,0\n0,0,0,1,1\n")
    with pytest.raises(isocube.FormatError, match="bad.csv"):
        contours.read(bad)


def test_contours_are_closed_curves_and_open_dxf_needs_close(tmp_path: Path) -> None:
    square = [(0.0, 0.0), (2.0, 0.0), (2.0, 2.0), (0.0, 2.0)]
    rows = ["section,z,contour,x,y"]
    implicit = [*rows, *(f"a,0,c,{x},{y}" for x, y in square)]
    explicit = [*implicit, "a,0,c,0,0"]
    (tmp_path / "i.csv").write_text("\n".join(implicit) + "\n")
    (tmp_path / "e.csv").write_text("\n".join(explicit) + "\n")
    a, b = contours.read(tmp_path / "i.csv"), contours.read(tmp_path / "e.csv")
    assert np.array_equal(a[0][1][0], b[0][1][0])
    dxf = "0\nSECTION\n2\nENTITIES\n0\nLWPOLYLINE\n5\nP1\n38\n0\n90\n4\n70\n0\n"
    dxf += "".join(f"10\n{x}\n20\n{y}\n" for x, y in square) + "0\nENDSEC\n0\nEOF\n"
    (tmp_path / "open.dxf").write_text(dxf)
    with pytest.raises(isocube.FormatError, match="polyline 'P1' is open.*close"):
        contours.read(tmp_path / "open.dxf")
    closed = contours.read(tmp_path / "open.dxf", close=True)
    assert np.array_equal(closed[0][1][0], a[0][1][0])


def test_read_gives_the_files_sections(tmp_path: Path) -> None:
    stack = sections()
    csv = tmp_path / "stack.csv"
    write_csv(csv, stack)
    read = contours.read(csv)
    assert [z for z, _ in read] == [z for z, _ in stack]
    for (_, ours), (_, theirs) in zip(read, stack):
        assert len(ours) == len(theirs)
        for a, b in zip(ours, theirs):
            assert np.array_equal(a, b)


@pytest.mark.parametrize(
    "options,flags",
    [
        ({}, []),
        ({"grid": (40, 30), "cap": "flat"}, ["--grid", "40x30", "--cap", "flat"]),
        (
            {"cell": 0.07, "cap": "extend", "extend": 0.25},
            ["--cell", "0.07", "--cap", "extend", "0.25"],
        ),
        ({"plain": True, "triangulate": "optimal"}, ["--plain", "--triangulate", "optimal"]),
    ],
)
def test_surfaces_are_the_command_lines_bytes(
    tmp_path: Path, options: dict[str, Any], flags: list[str]
) -> None:
    csv, theirs = command_file(tmp_path, "contours", flags, "cli.ply")
    stacks: list[contours.Stack] = [csv, contours.read(csv)]
    for i, stack in enumerate(stacks):
        ours = tmp_path / f"python-{i}.ply"
        contours.reconstruct(stack, **options).save(ours)
        assert ours.read_bytes() == theirs.read_bytes(), i


@pytest.mark.parametrize(
    "options,flags",
    [
        ({"grid": (24, 24)}, ["--grid", "24x24"]),
        (
            {"grid": (24, 24), "method": "ternary", "layer_spacing": "sections"},
            ["--grid", "24x24", "--method", "ternary", "--layer-spacing", "sections"],
        ),
    ],
)
def test_volume_meshes_are_the_command_lines_bytes(
    tmp_path: Path, options: dict[str, Any], flags: list[str]
) -> None:
    csv, theirs = command_file(tmp_path, "tetmesh", flags, "cli.msh")
    body = contours.tetmesh(contours.read(csv), **options)
    check = body.check()
    assert check["conforming"] and check["inverted"] == 0
    ours = tmp_path / "python.msh"
    body.save(ours)
    assert ours.read_bytes() == theirs.read_bytes()
