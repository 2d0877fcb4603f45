"""isocube.subdivide: Catmull–Clark as OpenSubdiv computes it (its regression results, kept
in the repository with its license), from arrays, files or extracted meshes; files byte for
byte those of `isocube subdivide`."""

from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np
import pytest

import isocube

from .test_save import cli

OPENSUBDIV = Path(__file__).parents[2] / "crates/isocube/tests/data/opensubdiv"

CUBE = np.array(
    [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]],
    dtype=float,
)
CUBE_FACES = [[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]]


def nearest(a: np.ndarray, b: np.ndarray) -> float:
    """The largest distance from a point of `a` to the nearest point of `b`."""
    d = np.linalg.norm(a[:, None, :] - b[None, :, :], axis=2)
    return float(d.min(axis=1).max())


@pytest.mark.parametrize(
    "shape",
    [
        "catmark_cube_creases1",
        "catmark_cube_corner3",
        "catmark_edgecorner",
        "catmark_tent_creases0",
    ],
)
def test_refinement_matches_opensubdiv(shape: str) -> None:
    cage = isocube.PolyMesh.read(OPENSUBDIV / "shapes" / f"{shape}.obj")
    for level in range(3):
        baseline = isocube.PolyMesh.read(OPENSUBDIV / "baseline" / f"{shape}_level{level}.obj")
        ours = isocube.subdivide(cage, level + 1)
        assert ours.stats()["vertices"] == baseline.stats()["vertices"]
        assert ours.stats()["faces"] == baseline.stats()["faces"]
        assert nearest(baseline.vertices, ours.vertices) < 1e-5


def test_sharp_edges_keep_the_cube_and_smooth_ones_round_it() -> None:
    edges = {
        (min(f[i], f[(i + 1) % 4]), max(f[i], f[(i + 1) % 4])) for f in CUBE_FACES for i in range(4)
    }
    sharp = isocube.PolyMesh(CUBE, CUBE_FACES, creases={e: 10.0 for e in edges})
    assert len(sharp.creases) == 12
    kept = isocube.subdivide(sharp, 3, limit=True)
    # Every limit point lies on the cube's faces.
    v = kept.vertices
    on_face = np.isclose(v, 0, atol=1e-12) | np.isclose(v, 1, atol=1e-12)
    assert on_face.any(axis=1).all()
    assert kept.quads().shape == (384, 4)
    rounded = isocube.subdivide(isocube.PolyMesh(CUBE, CUBE_FACES), 3, limit=True).vertices
    centre = np.linalg.norm(rounded - 0.5, axis=1)
    assert centre.max() - centre.min() < 0.1 < np.ptp(np.linalg.norm(v - 0.5, axis=1))
    # A corner tag alone keeps its vertex.
    cornered = isocube.subdivide(isocube.PolyMesh(CUBE, CUBE_FACES, corners={6: 10.0}), 2)
    assert np.isclose(cornered.vertices, [1, 1, 1]).all(axis=1).any()


def test_an_extracted_mesh_refines_to_a_closed_surface() -> None:
    x, y, z = np.mgrid[-1:1:12j, -1:1:12j, -1:1:12j]
    mesh = isocube.extract(x**2 + y**2 + z**2, 0.5, spacing=(2 / 11,) * 3, origin=(-1, -1, -1))
    fine = isocube.subdivide(mesh, 2)
    # Each triangle makes three quads, each quad four.
    assert fine.stats()["faces"] == 12 * len(mesh.triangles)
    assert fine.triangulate().is_watertight()
    # Within the sphere's shrinkage: subdivision pulls towards the inside.
    r = np.linalg.norm(fine.vertices, axis=1)
    assert r.max() <= np.linalg.norm(mesh.vertices, axis=1).max() + 1e-6 and r.min() > 0.5


def test_tags_and_inner_loops_round_trip_through_obj(tmp_path: Path) -> None:
    plate = isocube.PolyMesh.read("sample:plate")
    path = tmp_path / "plate.obj"
    plate.save(path)
    again = isocube.PolyMesh.read(path)
    assert again.to_obj() == plate.to_obj()
    assert again.inner_loops == plate.inner_loops and again.creases == plate.creases
    framed = isocube.PolyMesh(
        [[0, 0, 0], [4, 0, 0], [4, 4, 0], [0, 4, 0], [1, 1, 0], [1, 3, 0], [3, 3, 0], [3, 1, 0]],
        [[0, 1, 2, 3]],
        inner_loops={0: [[4, 5, 6, 7]]},
        boundary="edge-and-corner",
    )
    assert framed.inner_loops == {0: [[4, 5, 6, 7]]} and framed.boundary == "edge-and-corner"
    # Smooth: the hole is bridged and rounded over (quads only); sharp: the face keeps its
    # hole, refined, its loops infinitely sharp.
    smooth = isocube.subdivide(framed, 2, holes="smooth")
    assert smooth.inner_loops == {} and smooth.stats()["quads"] == smooth.stats()["faces"] > 16
    sharp = isocube.subdivide(framed, 2, holes="sharp")
    assert len(sharp.inner_loops) == 1 and len(sharp.creases) == 32


def test_bad_cages_are_refused_with_the_reason() -> None:
    with pytest.raises(isocube.InputError, match="face 1"):
        isocube.PolyMesh(CUBE, [[0, 1, 2], [0, 1, 9]])
    with pytest.raises(isocube.InputError, match="appears twice"):
        isocube.PolyMesh(CUBE, [[0, 1, 1, 2]])
    with pytest.raises(isocube.InputError, match="sharpness"):
        isocube.PolyMesh(CUBE, CUBE_FACES, creases={(0, 1): -1.0})
    with pytest.raises(isocube.InputError, match="unknown sample"):
        isocube.PolyMesh.read("sample:teapot")
    with pytest.raises(isocube.MemoryLimitError):
        isocube.subdivide("sample:cube", 20)
    with pytest.raises(isocube.InputError, match="holes"):
        isocube.subdivide("sample:plate", 1, holes="round")
    with pytest.raises(ValueError, match="quad"):
        isocube.PolyMesh(CUBE, [[0, 1, 2]]).quads()


@pytest.mark.parametrize("cage", ["cube", "plate", "box-hole", "boss"])
@pytest.mark.parametrize(
    "options,flags",
    [
        ({"levels": 2}, ["--levels", "2"]),
        ({"levels": 1, "limit": True}, ["--levels", "1", "--limit"]),
        ({"levels": 2, "holes": "sharp"}, ["--levels", "2", "--holes", "sharp"]),
        (
            {"levels": 1, "boundary": "edge-and-corner"},
            ["--levels", "1", "--boundary", "edge-and-corner"],
        ),
    ],
)
def test_files_are_the_command_lines_bytes(
    tmp_path: Path, cage: str, options: dict[str, object], flags: list[str]
) -> None:
    levels = int(str(options["levels"]))
    fine = isocube.subdivide(
        f"sample:{cage}",
        levels,
        holes=str(options.get("holes", "smooth")),
        boundary=None if "boundary" not in options else str(options["boundary"]),
        limit=bool(options.get("limit", False)),
    )
    for ext in ("obj", "ply", "stl"):
        ours, theirs = tmp_path / f"python.{ext}", tmp_path / f"cli.{ext}"
        fine.save(ours)
        subprocess.run(
            [cli(), "subdivide", f"sample:{cage}", "-o", str(theirs), *flags, "--quiet"],
            check=True,
            capture_output=True,
        )
        assert ours.read_bytes() == theirs.read_bytes(), ext
