"""isocube.extract from NumPy: the arrays as they come, the arrays that go out, errors."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import isocube


def sphere(n: int = 48, dtype: type = np.float32) -> np.ndarray:
    x, y, z = np.mgrid[-1 : 1 : n * 1j, -1 : 1 : n * 1j, -1 : 1 : n * 1j]
    # Not symmetric in the axes, so a transposed array meshes differently.
    field: np.ndarray = (np.sqrt((1.3 * x) ** 2 + y**2 + (0.8 * z) ** 2) - 0.7).astype(dtype)
    return field


def edge_counts(triangles: np.ndarray) -> tuple[int, int]:
    """(boundary edges, non-manifold edges) of an indexed triangle mesh."""
    t = np.asarray(triangles, dtype=np.int64)
    e = np.sort(np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]]), axis=1)
    _, counts = np.unique(e, axis=0, return_counts=True)
    return int((counts == 1).sum()), int((counts > 2).sum())


def test_a_closed_surface_is_watertight_and_encloses_its_volume() -> None:
    n = 64
    mesh = isocube.extract(sphere(n), 0.0, spacing=(2 / (n - 1),) * 3)
    assert mesh.is_watertight()
    assert edge_counts(mesh.triangles) == (0, 0)
    p = mesh.vertices[mesh.triangles].astype(np.float64)
    volume = np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2])).sum() / 6
    # An ellipsoid of semi-axes 0.7/1.3, 0.7, 0.7/0.8; triangles face away from the inside.
    exact = 4 / 3 * np.pi * 0.7**3 / (1.3 * 0.8)
    assert abs(volume - exact) < 0.01 * exact


def test_outputs_own_the_engines_buffers() -> None:
    mesh = isocube.extract(sphere(), 0.0)
    for a, dtype in [
        (mesh.vertices, np.float32),
        (mesh.triangles, np.uint32),
        (mesh.normals, np.float32),
    ]:
        assert a is not None and a.dtype == dtype and a.shape[1] == 3
        assert a.flags.c_contiguous and a.flags.writeable
        # Not NumPy's allocation: a view of the buffer Rust filled, kept alive by its base.
        assert not a.flags.owndata and a.base is not None
    normals = mesh.normals
    assert normals is not None
    assert np.allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-5)


def surface_measures(mesh: isocube.Mesh) -> tuple[float, float]:
    """(area, signed volume) of a mesh."""
    p = mesh.vertices[mesh.triangles].astype(np.float64)
    cross = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    area = float(np.linalg.norm(cross, axis=1).sum() / 2)
    volume = float(np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2])).sum() / 6)
    return area, volume


@pytest.mark.parametrize("dtype", [np.float32, np.float64, np.int16, np.uint8])
def test_memory_order_and_dtype_keep_the_surface(dtype: type) -> None:
    a: np.ndarray = (sphere(40) * 100).astype(dtype)
    c_order = isocube.extract(np.ascontiguousarray(a), 10.0)
    # The same memory order: the same arrays, bit for bit.
    again = isocube.extract(np.ascontiguousarray(a)[:, :, :], 10.0)
    assert np.array_equal(again.vertices, c_order.vertices)
    assert np.array_equal(again.triangles, c_order.triangles)
    # Another memory order is meshed in its own order (as the command line meshes a file): the
    # same vertices and surface, the cells' polygons possibly split along other diagonals.
    fortran = isocube.extract(np.asfortranarray(a), 10.0)
    assert fortran.is_watertight() and c_order.is_watertight()
    assert np.array_equal(np.unique(fortran.vertices, axis=0), np.unique(c_order.vertices, axis=0))
    (area_c, volume_c), (area_f, volume_f) = surface_measures(c_order), surface_measures(fortran)
    assert area_f == pytest.approx(area_c, rel=1e-3)
    assert volume_f == pytest.approx(volume_c, rel=1e-4)


def test_strided_views_are_read_in_place() -> None:
    a = sphere(80)
    view = a[::2, 1::2, ::3]
    assert not view.flags.c_contiguous and not view.flags.f_contiguous
    mesh = isocube.extract(view, 0.0)
    copied = isocube.extract(np.ascontiguousarray(view), 0.0)
    assert np.array_equal(mesh.vertices, copied.vertices)
    assert np.array_equal(mesh.triangles, copied.triangles)
    # A reversed axis (a negative stride) is copied first, with the same result.
    flipped = isocube.extract(a[::-1], 0.0)
    assert len(flipped.triangles) == len(
        isocube.extract(np.ascontiguousarray(a[::-1]), 0.0).triangles
    )


def test_spacing_and_origin_place_the_vertices() -> None:
    a = sphere(32)
    plain = isocube.extract(a, 0.0)
    placed = isocube.extract(a, 0.0, spacing=(0.5, 2.0, 3.0), origin=(1.0, -2.0, 5.0))
    assert np.array_equal(plain.triangles, placed.triangles)
    expected = plain.vertices.astype(np.float64) * [0.5, 2.0, 3.0] + [1.0, -2.0, 5.0]
    assert np.allclose(placed.vertices, expected, atol=1e-4)


def test_ternary_snapping_leaves_no_short_edges() -> None:
    a = sphere(48)
    mc = isocube.extract(a, 0.0)
    ternary = isocube.extract(a, 0.0, method="ternary", snap=0.3, snap_position="grid")
    assert ternary.is_watertight()
    assert ternary.stats["snapped_points"] > 0

    def shortest(m: isocube.Mesh) -> float:
        p = m.vertices[m.triangles].astype(np.float64)
        return float(
            min(np.linalg.norm(p[:, i] - p[:, (i + 1) % 3], axis=1).min() for i in range(3))
        )

    # Crossings within 0.3 of a corner are gone: no edge shorter than the snap leaves.
    assert shortest(ternary) > 10 * shortest(mc)


def test_flip_turns_the_triangles_and_the_normals() -> None:
    a = sphere(32)
    up = isocube.extract(a, 0.0)
    down = isocube.extract(a, 0.0, flip=True)
    assert np.array_equal(up.vertices, down.vertices)
    assert np.array_equal(np.sort(up.triangles, axis=1), np.sort(down.triangles, axis=1))
    assert up.normals is not None and down.normals is not None
    assert np.allclose(up.normals, -down.normals)


def test_bad_options_raise_input_errors() -> None:
    a = sphere(16)
    with pytest.raises(isocube.InputError, match="method"):
        isocube.extract(a, 0.0, method="dual")
    with pytest.raises(isocube.InputError, match="topology"):
        isocube.extract(a, 0.0, topology="mc34")
    with pytest.raises(isocube.InputError, match="snap"):
        isocube.extract(a, 0.0, method="ternary", snap=0.9)
    with pytest.raises(isocube.InputError, match="three"):
        isocube.extract(a[0], 0.0)
    with pytest.raises(isocube.InputError):
        isocube.extract(a, 0.0, spacing=(1.0, 2.0))
    assert issubclass(isocube.InputError, isocube.Error)
    assert issubclass(isocube.MemoryLimitError, isocube.Error)


def test_a_memory_limit_is_a_typed_error() -> None:
    with pytest.raises(isocube.MemoryLimitError):
        isocube.extract(sphere(64), 0.0, max_memory=1000)


def test_two_threads_extract_at_once() -> None:
    a = sphere(96)
    reference = isocube.extract(a, 0.0)
    results: list[isocube.Mesh] = []

    def work() -> None:
        results.append(isocube.extract(a, 0.0))

    threads = [threading.Thread(target=work) for _ in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(results) == 2
    for mesh in results:
        assert np.array_equal(mesh.triangles, reference.triangles)


def wavy(n: int) -> np.ndarray:
    x = np.linspace(-1, 1, n, dtype=np.float32)
    volume: np.ndarray = (
        np.sin(9 * x)[:, None, None] * np.cos(7 * x)[None, :, None] + np.sin(8 * x)[None, None, :]
    )
    return volume


@pytest.mark.parametrize("method,share", [("mc", 0.25), ("ternary", 0.25), ("ternary", 0.05)])
def test_ctrl_c_stops_the_work_soon(method: str, share: float) -> None:
    if threading.current_thread() is not threading.main_thread():
        pytest.skip("signals reach the main thread only")
    # Large enough to take well over the interrupt's delay on any machine. Ternary at 5 %:
    # while snapped points are chosen, before any cell is meshed.
    volume = wavy(320)
    start = time.perf_counter()
    isocube.extract(volume, 0.1, method=method)
    whole = time.perf_counter() - start
    delay = whole * share
    timer = threading.Timer(delay, lambda: os.kill(os.getpid(), signal.SIGINT))
    start = time.perf_counter()
    timer.start()
    with pytest.raises(KeyboardInterrupt):
        isocube.extract(volume, 0.1, method=method)
    stopped = time.perf_counter() - start
    timer.join()
    # Stopped within 0.2 s of the signal, and before the work would have finished.
    assert stopped < delay + 0.2 and stopped < whole, (delay, stopped, whole)


@pytest.mark.parametrize("method", ["mc", "ternary"])
def test_progress_is_told_and_can_stop_the_work(method: str) -> None:
    volume = wavy(256)
    calls: list[tuple[int, int]] = []
    mesh = isocube.extract(volume, 0.1, method=method, progress=lambda d, t: calls.append((d, t)))
    cells = mesh.stats["cells"]
    assert calls and all(t == cells and 0 <= d <= t for d, t in calls)
    assert [d for d, _ in calls] == sorted(d for d, _ in calls)

    class Enough(Exception):
        pass

    def stop(done: int, total: int) -> None:
        raise Enough

    with pytest.raises(Enough):
        isocube.extract(volume, 0.1, method=method, progress=stop)


def test_progress_bars_with_and_without_tqdm(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    volume = wavy(256)
    expected = isocube.extract(volume, 0.1)
    pytest.importorskip("tqdm")
    with_bar = isocube.extract(volume, 0.1, progress=True)
    assert np.array_equal(with_bar.triangles, expected.triangles)
    # Without tqdm: a percentage on stderr.
    monkeypatch.setitem(sys.modules, "tqdm.auto", None)
    capsys.readouterr()
    plain = isocube.extract(volume, 0.1, progress=True)
    assert np.array_equal(plain.triangles, expected.triangles)
    assert "isocube.extract:" in capsys.readouterr().err


# Run in a fresh interpreter per array, so no memory an earlier run freed is counted as free.
MEMMAP_PROBE = """
import sys, threading, time
import numpy as np
import isocube

def anonymous_mib():
    # The process's resident anonymous memory: its own, not pages of mapped files.
    with open("/proc/self/status") as status:
        for line in status:
            if line.startswith("RssAnon:"):
                return float(line.split()[1]) / 1024

def peak_during(work):
    peak, done = [anonymous_mib()], threading.Event()
    def sample():
        while not done.is_set():
            peak[0] = max(peak[0], anonymous_mib())
            time.sleep(0.001)
    sampler = threading.Thread(target=sample)
    sampler.start()
    result = work()
    done.set()
    sampler.join()
    return result, max(peak[0], anonymous_mib())

path, n, order, copy = sys.argv[1], int(sys.argv[2]), sys.argv[3], sys.argv[4] == "copy"
mapped = np.memmap(path, dtype=np.float32, mode="r", shape=(n, n, n))
a = mapped if order == "C" else mapped.T
assert a.flags.f_contiguous == (order == "F")
before = anonymous_mib()
mesh, peak = peak_during(lambda: isocube.extract(np.array(a) if copy else a, 0.0, normals=False))
assert mesh.is_watertight()
print(peak - before, (mesh.vertices.nbytes + mesh.triangles.nbytes) / 2**20)
"""


@pytest.mark.skipif(not os.path.exists("/proc/self/status"), reason="needs Linux's /proc")
def test_a_memory_mapped_volume_is_meshed_in_place(tmp_path: Path) -> None:
    """A 512³ float32 np.memmap, C order and its Fortran-ordered transpose: the process's own
    memory grows by less than the mesh and 64 MiB (a copy of the volume would be 512 MiB)."""
    n = 512
    path = tmp_path / "volume.f32"
    volume = np.memmap(path, dtype=np.float32, mode="w+", shape=(n, n, n))
    x = np.linspace(-1, 1, n, dtype=np.float32)
    for i in range(n):  # a sphere's distance, written plane by plane
        volume[i] = np.sqrt(x[i] ** 2 + x[:, None] ** 2 + x[None, :] ** 2) - 0.7
    volume.flush()
    del volume

    def probe(order: str, copy: bool) -> tuple[float, float]:
        out = subprocess.run(
            [sys.executable, "-c", MEMMAP_PROBE, str(path), str(n), order, "copy" if copy else ""],
            check=True,
            capture_output=True,
            text=True,
        ).stdout.split()
        return float(out[0]), float(out[1])

    for order in ("C", "F"):
        grown, mesh_mib = probe(order, copy=False)
        print(f"{order}: grew {grown:.1f} MiB, mesh {mesh_mib:.1f} MiB")
        assert grown < mesh_mib + 64, (order, grown, mesh_mib)
    # The measurement can fail: a copy of the volume shows.
    grown, _ = probe("F", copy=True)
    assert grown > 400, grown


def test_trimesh_and_pyvista_take_the_mesh_as_it_is() -> None:
    trimesh = pytest.importorskip("trimesh")
    pyvista = pytest.importorskip("pyvista")
    mesh = isocube.extract(sphere(40), 0.0, values=True)
    assert mesh.values is not None and mesh.normals is not None
    t = mesh.to_trimesh()
    assert isinstance(t, trimesh.Trimesh) and t.is_watertight and t.is_winding_consistent
    assert np.array_equal(t.faces, mesh.triangles) and np.allclose(t.vertices, mesh.vertices)
    # Triangles face the side above the level: the volume trimesh finds is the inside's.
    assert t.volume > 0
    p = mesh.to_pyvista()
    assert isinstance(p, pyvista.PolyData)
    assert p.n_points == len(mesh.vertices) and p.n_cells == len(mesh.triangles)
    assert np.array_equal(p.regular_faces, mesh.triangles)
    assert np.array_equal(p.point_data["values"], mesh.values)
    v, f, values = mesh.napari()
    assert v is mesh.vertices and f is mesh.triangles and values is mesh.values


@pytest.mark.parametrize("order", ["C", "F"])
@pytest.mark.parametrize("method", ["mc", "ternary"])
def test_chunks_give_the_same_mesh(order: str, method: str) -> None:
    a = np.asarray(wavy(37)[:, 3:34, 5:], order=order)  # type: ignore[call-overload]
    whole = isocube.extract(a, 0.1, method=method)
    for chunk in [(1, 1, 1), (5, 7, 3), (36, 2, 9), (100, 100, 100)]:
        part = isocube.extract(a, 0.1, method=method, chunk=chunk)
        for name in ("vertices", "triangles", "normals"):
            assert np.array_equal(getattr(part, name), getattr(whole, name)), (chunk, name)
    with pytest.raises(isocube.InputError, match="chunk"):
        isocube.extract(a, 0.1, chunk=(0, 4, 4))


def test_relaxed_meshes_are_the_command_lines(tmp_path: Path) -> None:
    from .test_save import cli

    npy = tmp_path / "volume.npy"
    np.save(npy, sphere(40))
    mesh = isocube.extract(np.load(npy), 0.0, method="ternary", relax=3)
    plain = isocube.extract(np.load(npy), 0.0, method="ternary")
    assert not np.array_equal(mesh.vertices, plain.vertices) and mesh.is_watertight()
    ours, theirs = tmp_path / "python.ply", tmp_path / "cli.ply"
    mesh.save(ours)
    subprocess.run(
        [cli(), "extract", str(npy), "-o", str(theirs), "--method", "ternary", "--relax", "3"],
        check=True,
        capture_output=True,
    )
    assert ours.read_bytes() == theirs.read_bytes()
