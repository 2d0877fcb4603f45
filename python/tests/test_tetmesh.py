"""isocube.tetmesh: conforming, positive tetrahedra bounded by extract's surface; files
byte for byte those of `isocube tetmesh`."""

from __future__ import annotations

import os
import signal
import subprocess
import threading
import time
from pathlib import Path
from typing import Any, Literal

import numpy as np
import pytest

import isocube

from .test_save import cli


def ellipsoid(order: Literal["C", "F"] = "C") -> np.ndarray:
    x, y, z = np.mgrid[-1:1:21j, -1:1:22j, -1:1:23j]
    field = (np.sqrt((1.3 * x) ** 2 + y**2 + (0.8 * z) ** 2) - 0.7).astype(np.float32)
    return np.asarray(field, order=order)


def signed_volumes(vertices: np.ndarray, tets: np.ndarray) -> np.ndarray:
    p = vertices[tets].astype(np.float64)
    a, b, c = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0], p[:, 3] - p[:, 0]
    volumes: np.ndarray = np.einsum("ij,ij->i", a, np.cross(b, c)) / 6
    return volumes


def faces_once(tets: np.ndarray) -> set[tuple[int, ...]]:
    """The faces of the tetrahedra that belong to one of them only, as sorted vertex triples."""
    t = tets.astype(np.int64)
    faces = np.concatenate([t[:, [1, 2, 3]], t[:, [0, 3, 2]], t[:, [0, 1, 3]], t[:, [0, 2, 1]]])
    keys, counts = np.unique(np.sort(faces, axis=1), axis=0, return_counts=True)
    assert counts.max() <= 2, "a face shared by more than two tetrahedra"
    return {tuple(k) for k in keys[counts == 1]}


def triples(triangles: np.ndarray) -> set[tuple[int, ...]]:
    return {tuple(t) for t in np.sort(triangles.astype(np.int64), axis=1)}


@pytest.mark.parametrize(
    "options",
    [{}, {"method": "mc"}, {"snap": 0.5, "flip": True}, {"snap_position": "grid"}],
)
def test_the_tetrahedra_fill_the_region_the_surface_bounds(options: dict[str, Any]) -> None:
    a = ellipsoid()
    mesh = isocube.tetmesh(a, **options)
    assert len(mesh.tets) > 1000
    # Every element positive; no face shared by three; the faces on one element only are
    # exactly the surface and the walls.
    assert (signed_volumes(mesh.vertices, mesh.tets) > 0).all()
    assert faces_once(mesh.tets) == triples(mesh.surface) | triples(mesh.walls)
    # The surface is extract's with the same options (its vertices first); the one default
    # that differs is the method (ternary for volume meshes).
    surface_options = {"method": "ternary", **options}
    surface = isocube.extract(a, normals=False, **surface_options)
    assert mesh.surface_vertices == len(surface.vertices)
    assert np.array_equal(mesh.vertices[: mesh.surface_vertices], surface.vertices)
    assert np.array_equal(mesh.surface, surface.triangles)
    for count in ("active_cells", "snapped_points", "refused_points"):
        assert mesh.stats[count] == surface.stats[count], count
    check = mesh.check()
    assert (
        check["conforming"]
        and check["inverted"] == 0
        and check["flat"] == 0
        and check["unused"] == 0
    )
    assert check["volume"] == pytest.approx(check["enclosed"], rel=1e-9)
    # Inside the ellipsoid the region is closed: no walls; flipped, it is the box around it.
    assert (len(mesh.walls) > 0) == bool(options.get("flip"))
    total = float(signed_volumes(mesh.vertices, mesh.tets).sum())
    assert total == pytest.approx(check["volume"], rel=1e-6)
    quality = mesh.quality()
    assert quality["tets"] == len(mesh.tets)
    assert 0 < quality["min_dihedral"] <= quality["max_dihedral"] < 180
    assert sum(quality["min_dihedral_histogram"]) == len(mesh.tets)
    if options.get("method") != "mc":
        # A smooth ellipsoid has neither sharp edges nor fine detail: every element is in range.
        assert quality["outside_range"] == 0
        assert quality["min_dihedral"] >= 10 and quality["max_dihedral"] <= 165


def test_elements_outside_the_range_are_sorted_by_cause() -> None:
    # Noise has sharp edges and small detail: the sort's classes add up to the count.
    rng = np.random.default_rng(7)
    a = rng.standard_normal((14, 13, 12)).astype(np.float32)
    mesh = isocube.tetmesh(a)
    quality = mesh.quality()
    histogram = quality["min_dihedral_histogram"]
    below = sum(histogram[:2])  # under 10°
    assert quality["outside_range"] >= below
    classes = ("at_sharp_edges", "beside_fine_detail", "others")
    assert quality["outside_range"] == sum(quality[c] for c in classes)


def test_ternary_elements_are_better_than_marching_cubes() -> None:
    a = ellipsoid()
    mc = isocube.tetmesh(a, method="mc").quality()
    ternary = isocube.tetmesh(a).quality()
    assert ternary["min_dihedral"] > 10 > mc["min_dihedral"]


def test_arrays_are_read_only_views_that_keep_the_mesh() -> None:
    mesh = isocube.tetmesh(ellipsoid())
    tets = mesh.tets
    assert not tets.flags.writeable and tets.dtype == np.uint32 and tets.shape[1] == 4
    with pytest.raises(ValueError):
        tets[0, 0] = 1
    expected = tets.copy()
    del mesh
    assert np.array_equal(tets, expected)


def test_labels_conform_across_their_interfaces() -> None:
    seg = np.zeros((12, 10, 9), np.uint16)
    seg[2:6, 2:8, 2:7] = 3
    seg[6:10, 2:8, 2:7] = 7
    mesh = isocube.tetmesh(seg, labels=True)
    assert mesh.tet_labels is not None and mesh.interfaces is not None
    assert mesh.interface_labels is not None and mesh.surface_labels is not None
    assert set(np.unique(mesh.tet_labels)) == {3, 7}
    assert (signed_volumes(mesh.vertices, mesh.tets) > 0).all()
    # Each label's tetrahedra are closed by its surface triangles and the interfaces.
    for label in (3, 7):
        own = faces_once(mesh.tets[mesh.tet_labels == label])
        bounding = triples(mesh.surface[mesh.surface_labels == label]) | triples(mesh.interfaces)
        assert own == bounding
    assert {tuple(p) for p in mesh.interface_labels} == {(3, 7)}
    # Volumes: the voxels' (each label 4 × 6 × 5 cells' worth of dual cells).
    volumes = signed_volumes(mesh.vertices, mesh.tets)
    for label in (3, 7):
        assert volumes[mesh.tet_labels == label].sum() == pytest.approx(4 * 6 * 5)
    only = isocube.tetmesh(seg, labels=[7])
    assert only.tet_labels is not None and set(np.unique(only.tet_labels)) == {7}


def test_graded_labels_keep_their_interfaces_and_volumes() -> None:
    seg = np.zeros((40, 36, 34), np.uint8)
    seg[2:22, 2:34, 2:32] = 3
    seg[22:38, 2:34, 2:32] = 7
    uniform = isocube.tetmesh(seg, labels=True, uniform=True)
    graded = isocube.tetmesh(seg, labels=True, max_size="8c")
    assert graded.stats["cubes"] > 0 and len(graded.tets) < len(uniform.tets)
    assert graded.check()["conforming"] and graded.check()["unused"] == 0
    assert (signed_volumes(graded.vertices, graded.tets) > 0).all()
    assert graded.interfaces is not None and uniform.interfaces is not None
    np.testing.assert_array_equal(graded.interfaces, uniform.interfaces)
    np.testing.assert_array_equal(graded.surface, uniform.surface)
    assert graded.tet_labels is not None and graded.surface_labels is not None
    for label, cells in ((3, 20 * 32 * 30), (7, 16 * 32 * 30)):
        own = faces_once(graded.tets[graded.tet_labels == label])
        bounding = triples(graded.surface[graded.surface_labels == label]) | triples(
            graded.interfaces
        )
        assert own == bounding
        volumes = signed_volumes(graded.vertices, graded.tets[graded.tet_labels == label])
        assert volumes.sum() == pytest.approx(cells)


def test_bad_input_names_the_reason() -> None:
    with pytest.raises(isocube.InputError, match="no region"):
        isocube.tetmesh(np.ones((4, 4, 4), np.float32), 0.0)
    with pytest.raises(isocube.MemoryLimitError):
        isocube.tetmesh(ellipsoid(), max_memory=1000)
    with pytest.raises(isocube.InputError, match="does not occur"):
        isocube.tetmesh(np.arange(27).reshape(3, 3, 3) % 2, labels=[5])
    a = ellipsoid()
    a[3, 4, 5] = np.nan
    with pytest.raises(isocube.InputError, match="finite"):
        isocube.tetmesh(a)
    with pytest.raises(isocube.InputError, match="extension"):
        isocube.tetmesh(ellipsoid()).save("mesh.xyz")


@pytest.mark.parametrize("flip", [False, True])
def test_a_graded_interior_keeps_the_boundary_with_fewer_elements(flip: bool) -> None:
    x, y, z = np.mgrid[-1:1:40j, -1:1:41j, -1:1:42j]
    ball = np.sqrt(x**2 + y**2 + z**2)
    uniform = isocube.tetmesh(ball, 0.8, flip=flip, uniform=True)
    graded = isocube.tetmesh(ball, 0.8, flip=flip, max_size="8c")
    assert (signed_volumes(graded.vertices, graded.tets) > 0).all()
    assert faces_once(graded.tets) == triples(graded.surface) | triples(graded.walls)
    np.testing.assert_array_equal(graded.surface, uniform.surface)
    check = graded.check()
    assert check["conforming"] and check["unused"] == 0
    stats = graded.stats
    assert stats["cubes"] > 0 and stats["largest_cube"] in (2, 4, 8)
    assert 0 < stats["cube_tets"] < len(graded.tets)
    assert uniform.stats["cubes"] == 0
    assert check["volume"] == pytest.approx(uniform.check()["volume"], rel=1e-9)
    fewer = len(graded.tets) < len(uniform.tets) / (1 if flip else 1.3)
    assert fewer, (len(graded.tets), len(uniform.tets))
    with pytest.raises(isocube.InputError, match="max_size"):
        isocube.tetmesh(ball, 0.8, max_size="big")
    with pytest.raises(isocube.InputError, match="uniform"):
        isocube.tetmesh(ball, 0.8, max_size="8c", uniform=True)


def test_the_default_interior_is_graded_up_to_16_cells() -> None:
    x, y, z = np.mgrid[-1:1:72j, -1:1:72j, -1:1:72j]
    ball = np.sqrt(x**2 + y**2 + z**2)
    default = isocube.tetmesh(ball, 0.9)
    explicit = isocube.tetmesh(ball, 0.9, max_size="16c")
    np.testing.assert_array_equal(default.tets, explicit.tets)
    np.testing.assert_array_equal(default.vertices, explicit.vertices)
    assert default.stats["cubes"] > 0 and default.stats["largest_cube"] <= 16
    uniform = isocube.tetmesh(ball, 0.9, uniform=True)
    assert uniform.stats["cubes"] == 0 and len(uniform.tets) > 2 * len(default.tets)
    # Cells longer than 3:1: the transition cubes would leave 10°-165°, the interior stays
    # uniform.
    long = isocube.tetmesh(ball, 0.9, spacing=(1.0, 1.0, 4.0))
    assert long.stats["cubes"] == 0 and long.stats["cells_too_long"]


def test_peers_read_the_mesh() -> None:
    mesh = isocube.tetmesh(ellipsoid(), method="ternary")
    enclosed = mesh.check()["enclosed"]
    pytest.importorskip("pyvista")
    grid = mesh.to_pyvista()
    assert grid.n_cells == len(mesh.tets)
    assert grid.volume == pytest.approx(enclosed, rel=1e-5)
    pytest.importorskip("meshio")
    m = mesh.to_meshio()
    assert len(m.cells[0].data) == len(mesh.tets)
    assert len(m.cells[1].data) == len(mesh.surface) + len(mesh.walls)


@pytest.mark.parametrize("order", ["C", "F"])
@pytest.mark.parametrize(
    "options,flags",
    [
        ({}, []),
        ({"method": "ternary", "snap": 0.4}, ["--method", "ternary", "--snap", "0.4"]),
        ({"flip": True, "level": 0.1}, ["--flip", "--level", "0.1"]),
        ({"max_size": "4c", "grading": 1}, ["--max-size", "4c", "--grading", "1"]),
        ({"max_size": 8.0, "flip": True}, ["--max-size", "8", "--flip"]),
    ],
)
def test_files_are_the_command_lines_bytes(
    tmp_path: Path, order: Literal["C", "F"], options: dict[str, Any], flags: list[str]
) -> None:
    npy = tmp_path / "volume.npy"
    np.save(npy, ellipsoid(order))
    mesh = isocube.tetmesh(np.load(npy), **options)
    for name, binary, extra in [
        ("a.msh", False, []),
        ("b.msh", True, ["--binary"]),
        ("c.vtu", False, []),
        ("d.mesh", False, []),
        ("e.inp", False, []),
    ]:
        ours, theirs = tmp_path / f"python-{name}", tmp_path / f"cli-{name}"
        mesh.save(ours, binary=binary)
        subprocess.run(
            [cli(), "tetmesh", str(npy), "-o", str(theirs), *flags, *extra, "--quiet"],
            check=True,
            capture_output=True,
        )
        assert ours.read_bytes() == theirs.read_bytes(), name


def test_label_files_are_the_command_lines_bytes(tmp_path: Path) -> None:
    seg = np.zeros((12, 10, 9), np.int32)
    seg[2:6, 2:8, 2:7] = 1
    seg[6:10, 3:8, 2:6] = 2
    npy = tmp_path / "labels.npy"
    np.save(npy, seg)
    ours, theirs = tmp_path / "python.msh", tmp_path / "cli.msh"
    isocube.tetmesh(seg, labels=True).save(ours)
    subprocess.run(
        [cli(), "tetmesh", str(npy), "-o", str(theirs), "--labels", "--quiet"],
        check=True,
        capture_output=True,
    )
    assert ours.read_bytes() == theirs.read_bytes()


def test_progress_is_told_and_ctrl_c_stops_the_work() -> None:
    x = np.linspace(-1, 1, 120, dtype=np.float32)
    volume = (
        np.sin(9 * x)[:, None, None] * np.cos(7 * x)[None, :, None] + np.sin(8 * x)[None, None, :]
    )
    calls: list[tuple[int, int]] = []
    start = time.perf_counter()
    mesh = isocube.tetmesh(
        volume, 0.1, method="ternary", progress=lambda d, t: calls.append((d, t))
    )
    whole = time.perf_counter() - start
    cells = 119**3
    assert calls and all(t == 2 * cells and 0 <= d <= t for d, t in calls)
    assert [d for d, _ in calls] == sorted(d for d, _ in calls) and len(mesh.tets) > 0
    if threading.current_thread() is not threading.main_thread():
        pytest.skip("signals reach the main thread only")
    for share in (0.1, 0.6):
        delay = whole * share
        timer = threading.Timer(delay, lambda: os.kill(os.getpid(), signal.SIGINT))
        start = time.perf_counter()
        timer.start()
        with pytest.raises(KeyboardInterrupt):
            isocube.tetmesh(volume, 0.1, method="ternary")
        stopped = time.perf_counter() - start
        timer.join()
        assert stopped < delay + 0.2 and stopped < whole, (share, delay, stopped, whole)
