"""isocube.dask: chunked volumes meshed by Dask tasks give isocube.extract's mesh exactly."""

from __future__ import annotations

import json
import os
import shutil
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import isocube

dask = pytest.importorskip("dask")
da = pytest.importorskip("dask.array")
zarr = pytest.importorskip("zarr")
distributed = pytest.importorskip("distributed")

import isocube.dask  # noqa: E402


def gyroid(shape: tuple[int, int, int]) -> np.ndarray:
    axes = [np.linspace(-1, 1, n, dtype=np.float32) for n in shape]
    x, y, z = np.meshgrid(*axes, indexing="ij")
    t = 3.1 * x, 2.9 * y, 3.3 * z
    g = np.sin(t[0]) * np.cos(t[1]) + np.sin(t[1]) * np.cos(t[2]) + np.sin(t[2]) * np.cos(t[0])
    return np.ascontiguousarray(g, dtype=np.float32)


def assert_same(mesh: isocube.Mesh, whole: isocube.Mesh) -> None:
    assert len(whole.triangles) > 0
    np.testing.assert_array_equal(mesh.vertices, whole.vertices)
    np.testing.assert_array_equal(mesh.triangles, whole.triangles)
    if whole.normals is None:
        assert mesh.normals is None
    else:
        assert mesh.normals is not None
        np.testing.assert_array_equal(mesh.normals, whole.normals)
    for key in ("cells", "active_cells", "tunnels", "interior_vertices", "snapped_points"):
        assert mesh.stats[key] == whole.stats[key], key


OPTIONS: list[dict[str, Any]] = [
    {},
    {"topology": "classic", "flip": True},
    {"triangulate": "local"},
    {"triangulate": "optimal", "normals": False},
    {"spacing": (0.5, 0.7, 1.3), "origin": (3, -2, 1), "direction": np.eye(3)[[1, 0, 2]]},
    {"method": "ternary"},
    {"method": "ternary", "snap": 0.45, "snap_position": "grid", "triangulate": "local"},
]


@pytest.mark.parametrize("options", OPTIONS, ids=lambda o: ",".join(map(str, o)) or "mc")
def test_threaded_chunks_give_the_whole_mesh(options: dict[str, Any]) -> None:
    # Long along the first axis, so the ternary halo (115 points) does not reach across.
    volume = gyroid((290, 26, 21))
    whole = isocube.extract(volume, 0.1, **options)
    for chunks, split in [((40, 9, 8), 2), ((64, 26, 21), 4), ((17, 13, 5), 3)]:
        mesh = isocube.dask.extract(
            da.from_array(volume, chunks=chunks),
            0.1,
            split_every=split,
            scheduler="threads",
            **options,
        )
        assert_same(mesh, whole)


@pytest.mark.parametrize("options", OPTIONS, ids=lambda o: ",".join(map(str, o)) or "mc")
def test_ply_written_by_the_chunks_is_the_whole_meshs_file(
    options: dict[str, Any], tmp_path: Path
) -> None:
    volume = gyroid((290, 26, 21))
    expected = tmp_path / "whole.ply"
    isocube.extract(volume, 0.1, **options).save(expected)
    for n, (chunks, split) in enumerate([((40, 9, 8), 2), ((64, 26, 21), 4), ((17, 13, 5), 3)]):
        path = tmp_path / f"dask{n}.ply"
        stats = isocube.dask.write_ply(
            da.from_array(volume, chunks=chunks),
            path,
            0.1,
            split_every=split,
            scheduler="threads",
            **options,
        )
        assert path.read_bytes() == expected.read_bytes(), chunks
        assert stats["cells"] == 289 * 25 * 20
    # Nothing but the files asked for is left beside them.
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "dask0.ply",
        "dask1.ply",
        "dask2.ply",
        "whole.ply",
    ]


def test_a_failed_ply_leaves_nothing(tmp_path: Path) -> None:
    volume = gyroid((40, 40, 40))
    store = tmp_path / "g.zarr"
    write_zarr(store, volume, chunks=(16, 16, 16))
    (store / "c" / "1" / "2" / "0").write_bytes(b"not a chunk")
    with pytest.raises(isocube.FormatError, match=r"chunk 'c/1/2/0'"):
        isocube.dask.write_ply(str(store), tmp_path / "out.ply", scheduler="threads")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["g.zarr"]


def test_integer_volumes_and_ties_at_the_level() -> None:
    rng = np.random.default_rng(7)
    volume = rng.integers(0, 5, size=(31, 23, 27), dtype=np.uint16)
    whole = isocube.extract(volume, 2.0)
    mesh = isocube.dask.extract(da.from_array(volume, chunks=(8, 7, 9)), 2.0, scheduler="sync")
    assert_same(mesh, whole)
    # A chunk one point thick at the end owns no cell: its point goes to the one before.
    assert isocube.dask.boxes(((30, 1), (23,), (27,)))[-1][0] == (0, 30)
    thin = isocube.dask.extract(da.from_array(volume, chunks=(30, 23, 27)), 2.0)
    assert_same(thin, whole)


def test_bad_arguments() -> None:
    with pytest.raises(isocube.InputError, match="three dimensions"):
        isocube.dask.extract(da.zeros((4, 4), chunks=2))
    with pytest.raises(isocube.InputError, match="dask array"):
        isocube.dask.extract(np.zeros((4, 4, 4)))
    with pytest.raises(isocube.InputError, match="two points"):
        isocube.dask.extract(da.zeros((4, 1, 4), chunks=2))
    with pytest.raises(isocube.InputError, match="split_every"):
        isocube.dask.extract(da.zeros((4, 4, 4), chunks=2), split_every=1)


def write_zarr(path: Path, volume: np.ndarray, **kwargs: Any) -> Any:
    z = zarr.create_array(
        str(path), shape=volume.shape, dtype=volume.dtype, overwrite=True, **kwargs
    )
    z[:] = volume
    return z


@pytest.fixture(scope="module")
def cluster() -> Any:
    with (
        distributed.LocalCluster(
            n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
        ) as c,
        distributed.Client(c) as client,
    ):
        yield client


@pytest.fixture(scope="module")
def stores(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """A 256 × 251 × 243 gyroid (64³ chunks, the last ones short) as Zarr v3 with zstd, Zarr
    v2 with blosc, and an OME-Zarr image with two scales."""
    from zarr.codecs import BloscCodec, ZstdCodec

    root = tmp_path_factory.mktemp("zarr")
    volume = gyroid((256, 251, 243))
    write_zarr(root / "v3.zarr", volume, chunks=(64, 64, 64), compressors=[ZstdCodec()])
    write_zarr(
        root / "v2.zarr",
        volume,
        chunks=(64, 64, 64),
        zarr_format=2,
        compressors=[__import__("numcodecs").Blosc()],
    )
    ome = zarr.open_group(str(root / "ome.zarr"), mode="w", zarr_format=3)
    coarse = np.ascontiguousarray(volume[::2, ::2, ::2])
    for name, level in (("0", volume), ("1", coarse)):
        a = ome.create_array(
            name,
            shape=level.shape,
            dtype="f4",
            chunks=(48, 48, 48),
            compressors=[BloscCodec()],
        )
        a[:] = level
    axes = [{"name": n, "type": "space"} for n in "zyx"]
    ome.attrs["ome"] = {
        "version": "0.5",
        "multiscales": [
            {
                "axes": axes,
                "datasets": [
                    {
                        "path": str(s),
                        "coordinateTransformations": [{"type": "scale", "scale": [2.0**s] * 3}],
                    }
                    for s in (0, 1)
                ],
            }
        ],
    }
    return {"root": root, "volume": volume, "coarse": coarse}


@pytest.mark.parametrize(
    "options",
    [{}, {"method": "ternary"}, {"triangulate": "local"}, {"triangulate": "optimal"}],
    ids=["mc", "ternary", "local", "optimal"],
)
def test_a_local_cluster_meshes_zarr_v3_as_one_process(
    cluster: Any, stores: dict[str, Any], options: dict[str, Any]
) -> None:
    whole = isocube.extract(stores["volume"], 0.0, **options)
    mesh = isocube.dask.extract(str(stores["root"] / "v3.zarr"), 0.0, **options)
    assert_same(mesh, whole)
    # A dask array the client made (da.from_zarr), not a path: the same.
    array = da.from_zarr(str(stores["root"] / "v3.zarr"))
    assert_same(isocube.dask.extract(array, 0.0, **options), whole)


@pytest.mark.parametrize("method", ["mc", "ternary"])
def test_a_local_cluster_writes_the_ply_without_gathering_the_mesh(
    cluster: Any, stores: dict[str, Any], method: str, tmp_path: Path
) -> None:
    expected = tmp_path / "whole.ply"
    isocube.extract(stores["volume"], 0.0, method=method).save(expected)
    path = tmp_path / "dask.ply"
    stats = isocube.dask.write_ply(str(stores["root"] / "v3.zarr"), path, 0.0, method=method)
    assert path.read_bytes() == expected.read_bytes()
    # What went to the layout task: the bands' outlines, a few percent of the file.
    assert stats["layout_bytes"] < 0.1 * path.stat().st_size


def test_zarr_v2_and_ome_zarr_levels(cluster: Any, stores: dict[str, Any]) -> None:
    whole = isocube.extract(stores["volume"], 0.0)
    assert_same(isocube.dask.extract(str(stores["root"] / "v2.zarr"), 0.0), whole)
    ome = str(stores["root"] / "ome.zarr")
    assert_same(isocube.dask.extract(ome, 0.0, component="0"), whole)
    coarse = isocube.extract(stores["coarse"], 0.0, spacing=(2, 2, 2))
    assert_same(isocube.dask.extract(ome, 0.0, component="1", spacing=(2, 2, 2)), coarse)


@pytest.mark.parametrize("write", [False, True], ids=["extract", "write_ply"])
def test_a_worker_killed_mid_run_changes_nothing(
    cluster: Any, stores: dict[str, Any], write: bool, tmp_path: Path
) -> None:
    whole = isocube.extract(stores["volume"], 0.0, method="ternary")
    store = str(stores["root"] / "v3.zarr")
    if write:
        delayed = isocube.dask.write_ply(
            store, tmp_path / "dask.ply", 0.0, method="ternary", compute=False
        )
    else:
        delayed = isocube.dask.extract(store, 0.0, method="ternary", compute=False)
    future = cluster.compute(delayed)
    # Kill one worker's process once tasks are under way; its nanny starts another and the
    # scheduler runs the lost tasks again.
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        processing = cluster.processing()
        if any(processing.values()):
            break
        time.sleep(0.05)
    victim = next(iter(cluster.scheduler_info()["workers"]))
    cluster.run(lambda: os._exit(1), workers=[victim], nanny=False, on_error="ignore")
    result = future.result(timeout=600)
    if write:
        whole.save(tmp_path / "whole.ply")
        assert (tmp_path / "dask.ply").read_bytes() == (tmp_path / "whole.ply").read_bytes()
        assert result["triangles"] == len(whole.triangles)
    else:
        assert_same(result, whole)
    # The process was replaced (a new address), so its tasks were run again elsewhere.
    assert victim not in cluster.scheduler_info()["workers"]


def test_damaged_and_absent_chunks(tmp_path: Path) -> None:
    volume = gyroid((40, 40, 40))
    path = tmp_path / "g.zarr"
    write_zarr(path, volume, chunks=(16, 16, 16))
    # Absent: the fill value, as the Zarr specification says (and as zarr reads it).
    shutil.rmtree(path / "c" / "1" / "1")
    expected = np.asarray(zarr.open_array(str(path), mode="r")[:])
    mesh = isocube.dask.extract(str(path), 0.0, scheduler="threads")
    assert_same(mesh, isocube.extract(expected, 0.0))
    # Unless asked to refuse them: then an absent chunk (whichever task met one first) is named.
    with pytest.raises(
        isocube.FormatError,
        match=r"chunk 'c/1/1/(\d)' \(chunk grid indices 1, 1, \1\): absent \(strict",
    ):
        isocube.dask.extract(str(path), 0.0, scheduler="threads", strict=True)
    # Damaged: the error names the chunk.
    (path / "c" / "2" / "0" / "1").write_bytes(b"not a chunk")
    with pytest.raises(
        isocube.FormatError, match=r"chunk 'c/2/0/1' \(chunk grid indices 2, 0, 1\)"
    ):
        isocube.dask.extract(str(path), 0.0, scheduler="threads")
    # A chunk of the wrong size (the metadata says float32; the chunk holds fewer bytes).
    raw = tmp_path / "raw.zarr"
    write_zarr(raw, volume, chunks=(16, 16, 16), compressors=None)
    (raw / "c" / "0" / "1" / "0").write_bytes(np.zeros(7, np.float32).tobytes())
    with pytest.raises(isocube.FormatError, match=r"chunk 'c/0/1/0'"):
        isocube.dask.extract(str(raw), 0.0, scheduler="threads")
    meta = json.loads((raw / "zarr.json").read_text())
    assert meta["data_type"] == "float32"


def segmentation(shape: tuple[int, int, int], seed: int, size: float = 0.45) -> np.ndarray:
    """Blobs of several labels (large ids, background 0) touching one another and the border."""
    rng = np.random.default_rng(seed)
    grids = np.meshgrid(*[np.arange(n) for n in shape], indexing="ij")
    seg = np.zeros(shape, np.uint32)
    for label in rng.choice(100_000, size=7, replace=False):
        centre = [rng.uniform(0, n) for n in shape]
        radius = rng.uniform(0.4, 1.0) * size * min(shape)
        inside = sum((g - c) ** 2 for g, c in zip(grids, centre)) < radius**2
        seg[inside] = label + 1
    return seg


def assert_same_surfaces(got: dict[int, isocube.Mesh], whole: dict[int, isocube.Mesh]) -> None:
    assert sorted(got) == sorted(whole) and len(whole) > 2
    for label, mesh in whole.items():
        np.testing.assert_array_equal(got[label].vertices, mesh.vertices)
        np.testing.assert_array_equal(got[label].triangles, mesh.triangles)
        np.testing.assert_array_equal(got[label].normals, mesh.normals)


@pytest.mark.parametrize(
    "options",
    [{}, {"smoothing": 0, "background": 0}, {"only": [1], "spacing": (0.5, 1, 2)}],
    ids=["smoothed", "staircase", "only"],
)
def test_label_surfaces_in_chunks_are_the_whole_ones(options: dict[str, Any]) -> None:
    seg = segmentation((37, 29, 33), 11)
    if "only" in options:
        options = {**options, "only": [int(seg[18, 14, 16]) or int(seg.max())]}
    whole = isocube.label_surfaces(seg, **options)
    for chunks, split in [((10, 9, 11), 2), ((37, 29, 33), 4), ((6, 29, 17), 3)]:
        got = isocube.dask.label_surfaces(
            da.from_array(seg, chunks=chunks), split_every=split, scheduler="threads", **options
        )
        if "only" in options:
            assert sorted(got) == sorted(whole) == options["only"]
            for label, mesh in whole.items():
                np.testing.assert_array_equal(got[label].vertices, mesh.vertices)
        else:
            assert_same_surfaces(got, whole)


def test_label_values_that_are_not_integers_are_named() -> None:
    seg = np.zeros((8, 8, 8), np.float32)
    seg[5, 6, 7] = 1.5
    with pytest.raises(isocube.InputError, match=r"point \(5, 6, 7\) holds 1.5"):
        isocube.dask.label_surfaces(da.from_array(seg, chunks=4), scheduler="sync")


def test_a_local_cluster_meshes_a_labelled_zarr_as_one_process(
    cluster: Any, tmp_path: Path
) -> None:
    from zarr.codecs import ZstdCodec

    # Cells in a 256³ tile: small blobs, some touching, dense meshes (12 triangles per voxel face).
    seg = segmentation((256, 251, 243), 5, size=0.12)
    path = tmp_path / "seg.zarr"
    write_zarr(path, seg, chunks=(64, 64, 64), compressors=[ZstdCodec()])
    whole = isocube.label_surfaces(seg)
    assert_same_surfaces(isocube.dask.label_surfaces(str(path)), whole)
