"""Type stubs of the extension module (see isocube/__init__.py for the documented API)."""

from collections.abc import Callable

import numpy as np
import numpy.typing as npt

__version__: str

class Error(Exception): ...
class InputError(Error): ...
class FormatError(Error): ...
class MemoryLimitError(Error): ...

def extract(
    volume: npt.NDArray[np.float32],
    level: float,
    *,
    spacing: tuple[float, float, float],
    origin: tuple[float, float, float],
    method: str,
    topology: str,
    triangulate: str,
    snap: float,
    zero_threshold: float,
    snap_position: str,
    flip: bool,
    normals: bool,
    values: bool,
    max_memory: int | None,
    direction: list[list[float]] | None = None,
    progress: Callable[[int, int], object] | None = None,
    relax: int = 0,
    chunk: tuple[int, int, int] | None = None,
    allow_empty: bool = True,
) -> tuple[
    npt.NDArray[np.float32],
    npt.NDArray[np.uint32],
    npt.NDArray[np.float32] | None,
    npt.NDArray[np.float32] | None,
    dict[str, float],
]: ...
def marching_cubes(
    volume: npt.NDArray[np.float32],
    level: float | None,
    *,
    topology: str,
    descent: bool,
) -> tuple[
    npt.NDArray[np.float32],
    npt.NDArray[np.int32],
    npt.NDArray[np.float32],
    npt.NDArray[np.float32],
]: ...
def save_mesh(
    path: str,
    vertices: npt.NDArray[np.float32],
    triangles: npt.NDArray[np.uint32],
    normals: npt.NDArray[np.float32] | None,
    values: npt.NDArray[np.float32] | None,
    values_name: str,
    ascii: bool,
) -> None: ...
def resolve_level(volume: npt.NDArray[np.float32], spec: str) -> float: ...
def read_volume(
    path: str,
    *,
    spacing: tuple[float, float, float] | None = None,
    origin: tuple[float, float, float] | None = None,
    max_memory: int | None = None,
    npy_axes: str = "xyz",
    frame: int | None = None,
    channel: int | None = None,
) -> tuple[
    npt.NDArray[np.float32],
    list[float],
    list[float],
    list[list[float]],
]: ...
def label_surfaces(
    labels: npt.NDArray[np.float32],
    *,
    spacing: tuple[float, float, float],
    origin: tuple[float, float, float],
    background: int,
    only: list[int] | None,
    smoothing: int,
) -> list[
    tuple[
        int,
        npt.NDArray[np.float32],
        npt.NDArray[np.uint32],
        npt.NDArray[np.float32] | None,
    ]
]: ...

class TetMesh:
    @property
    def vertices(self) -> npt.NDArray[np.float32]: ...
    @property
    def tets(self) -> npt.NDArray[np.uint32]: ...
    @property
    def surface(self) -> npt.NDArray[np.uint32]: ...
    @property
    def walls(self) -> npt.NDArray[np.uint32]: ...
    @property
    def beyond(self) -> npt.NDArray[np.uint32]: ...
    @property
    def surface_vertices(self) -> int: ...
    @property
    def labels(
        self,
    ) -> (
        tuple[
            list[int],
            npt.NDArray[np.uint32],
            npt.NDArray[np.uint32],
            npt.NDArray[np.uint32],
            npt.NDArray[np.uint32],
        ]
        | None
    ): ...
    @property
    def stats(self) -> dict[str, float]: ...
    def quality(self) -> dict[str, float | int | list[int]]: ...
    def check(self) -> dict[str, float | int | bool]: ...
    def save(self, path: str, *, binary: bool = False) -> None: ...

def tetmesh(
    volume: npt.NDArray[np.float32],
    level: float,
    *,
    spacing: tuple[float, float, float],
    origin: tuple[float, float, float],
    direction: list[list[float]] | None,
    method: str,
    topology: str,
    triangulate: str,
    snap: float,
    zero_threshold: float,
    snap_position: str,
    flip: bool,
    labels: bool,
    only: list[int] | None,
    background: int,
    max_memory: int | None,
    max_size: float | None = None,
    max_size_cells: bool = False,
    grading: int = 0,
    uniform: bool = False,
    progress: Callable[[int, int], object] | None = None,
) -> TetMesh: ...
def contours_read(
    path: str, close: bool = False
) -> list[tuple[float, list[npt.NDArray[np.float64]]]]: ...
def contours_reconstruct(
    path: str | None,
    sections: list[tuple[float, list[npt.NDArray[np.float64]]]] | None,
    *,
    cell: float | None,
    grid: tuple[int, int] | None,
    cap: str,
    extend: float | None,
    plain: bool,
    triangulate: str,
    max_memory: int | None,
    close: bool = False,
) -> tuple[
    npt.NDArray[np.float32],
    npt.NDArray[np.uint32],
    npt.NDArray[np.float32],
    dict[str, float],
]: ...
def contours_tetmesh(
    path: str | None,
    sections: list[tuple[float, list[npt.NDArray[np.float64]]]] | None,
    *,
    cell: float | None,
    grid: tuple[int, int] | None,
    cap: str,
    extend: float | None,
    layer_spacing: str | None,
    method: str,
    snap: float,
    zero_threshold: float,
    snap_position: str,
    triangulate: str,
    max_memory: int | None,
    close: bool = False,
) -> TetMesh: ...

class PolyMesh:
    @property
    def vertices(self) -> npt.NDArray[np.float64]: ...
    @property
    def faces(self) -> tuple[npt.NDArray[np.uint64], npt.NDArray[np.uint32]]: ...
    @property
    def inner_loops(self) -> list[tuple[int, list[list[int]]]]: ...
    @property
    def creases(self) -> list[tuple[tuple[int, int], float]]: ...
    @property
    def corners(self) -> list[tuple[int, float]]: ...
    @property
    def holes(self) -> list[int]: ...
    @property
    def boundary(self) -> str | None: ...
    def subdivide(
        self, levels: int, *, holes: str, boundary: str | None, limit: bool
    ) -> PolyMesh: ...
    def triangulate(self) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.uint32]]: ...
    def to_obj(self) -> str: ...
    def save(self, path: str, *, ascii: bool = False) -> None: ...
    def stats(self) -> dict[str, int]: ...

def poly_mesh(
    vertices: npt.NDArray[np.float64],
    faces: list[list[int]],
    *,
    inner_loops: list[tuple[int, list[list[int]]]],
    creases: list[tuple[tuple[int, int], float]],
    corners: list[tuple[int, float]],
    holes: list[int],
    boundary: str | None,
) -> PolyMesh: ...
def poly_read(path: str) -> PolyMesh: ...
def tables(kind: str, group: str, polygons: bool) -> str | dict[str, npt.NDArray[np.generic]]: ...
def block_halo(method: str, normals: bool) -> int: ...
def mesh_block(
    block: npt.NDArray[np.float32],
    at: tuple[int, int, int],
    shape: tuple[int, int, int],
    lo: tuple[int, int, int],
    hi: tuple[int, int, int],
    level: float,
    *,
    spacing: tuple[float, float, float],
    origin: tuple[float, float, float],
    method: str,
    topology: str,
    triangulate: str,
    snap: float,
    zero_threshold: float,
    snap_position: str,
    flip: bool,
    normals: bool,
) -> bytes: ...
def merge_chunks(shape: tuple[int, int, int], chunks: list[bytes]) -> bytes: ...
def read_zarr_block(
    path: str,
    component: str | None,
    lo: tuple[int, int, int],
    hi: tuple[int, int, int],
    strict: bool,
) -> npt.NDArray[np.float32]: ...
def chunk_outline(chunk: bytes, shape: tuple[int, int, int]) -> bytes: ...
def join_layout(
    shape: tuple[int, int, int], outlines: list[bytes]
) -> tuple[int, int, dict[str, float], list[bytes]]: ...
def place_chunk(
    chunk: bytes,
    place: bytes,
    *,
    origin: tuple[float, float, float],
    normals: bool,
    direction: list[list[float]] | None = None,
) -> bytes: ...
def assemble_pieces(
    vertices: int, triangles: int, normals: bool, pieces: list[bytes]
) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.uint32], npt.NDArray[np.float32] | None]: ...
def create_ply(path: str, vertices: int, triangles: int, normals: bool) -> None: ...
def write_ply_chunk(
    path: str,
    chunk: bytes,
    place: bytes,
    *,
    origin: tuple[float, float, float],
    normals: bool,
    direction: list[list[float]] | None = None,
) -> tuple[int, int]: ...
def mesh_label_block(
    ids: npt.NDArray[np.uint32],
    at: tuple[int, int, int],
    shape: tuple[int, int, int],
    lo: tuple[int, int, int],
    hi: tuple[int, int, int],
    names: list[int],
    *,
    spacing: tuple[float, float, float],
    origin: tuple[float, float, float],
    background: int,
    only: list[int] | None,
) -> bytes: ...
def merge_label_chunks(shape: tuple[int, int, int], chunks: list[bytes]) -> bytes: ...
def finish_label_chunks(
    chunk: bytes,
    shape: tuple[int, int, int],
    names: list[int],
    *,
    spacing: tuple[float, float, float],
    origin: tuple[float, float, float],
    background: int,
    only: list[int] | None,
    smoothing: int,
) -> list[
    tuple[
        int,
        npt.NDArray[np.float32],
        npt.NDArray[np.uint32],
        npt.NDArray[np.float32] | None,
    ]
]: ...
