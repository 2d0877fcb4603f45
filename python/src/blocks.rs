//! The pieces `isocube.dask` puts on a cluster: a block of a C-ordered volume meshed where it
//! was read (its chunk mesh as bytes), chunk meshes merged in a tree, and the last one turned
//! into the arrays `isocube.extract` gives for the whole volume.
//!
//! Everything here is in the frame `isocube.extract` meshes a C-ordered array in: the grid's
//! `x` is the array's last axis. Indices given by Python are in the array's order `[i, j, k]`
//! and are reversed here.

use isocube::extract::{
    self, CellBox, ChunkMesh, ChunkOutline, ChunkPlace, ExtractOptions, JoinLayout, LabelOptions,
    LabelSelection, PlacedPiece,
};
use isocube::field::{GridView, Orientation};
use isocube::mesh::Mesh;
use isocube_io::PlyLayout;
use numpy::{PyArrayMethods, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict};

use crate::{
    direction_of, extract_error, method_of, rows_array, samples_of, stats_dict, surface_options,
    FormatError, InputError,
};

/// Array order `[i, j, k]` → the grid's `[x, y, z]` (and back).
fn reversed<T: Copy>(a: [T; 3]) -> [T; 3] {
    [a[2], a[1], a[0]]
}

#[allow(clippy::too_many_arguments)]
fn options_of(
    level: f32,
    method: &str,
    topology: &str,
    triangulate: &str,
    snap: f32,
    zero_threshold: f32,
    snap_position: &str,
    flip: bool,
    normals: bool,
) -> PyResult<ExtractOptions> {
    Ok(surface_options(
        level,
        flip,
        topology,
        triangulate,
        method_of(method, snap, zero_threshold, snap_position)?,
        None,
    )?
    .with_normals(normals))
}

/// Points a block must hold beyond its cells for `method` (and normals or not).
#[pyfunction]
#[pyo3(signature = (method, normals))]
pub(crate) fn block_halo(method: &str, normals: bool) -> PyResult<usize> {
    let options = ExtractOptions::default()
        .with_method(method_of(method, 0.3, 0.0, "crossing")?)
        .with_normals(normals);
    Ok(extract::block_halo(&options))
}

/// Points `lo..=hi` (array order) of the 3-d Zarr array at `path` (`component` in a group) as
/// `float32`, read with zarrs without holding the GIL; absent chunks are the fill value unless
/// `strict`, and a chunk that cannot be read is named.
#[pyfunction]
#[pyo3(signature = (path, component, lo, hi, strict))]
pub(crate) fn read_zarr_block<'py>(
    py: Python<'py>,
    path: std::path::PathBuf,
    component: Option<String>,
    lo: [u64; 3],
    hi: [u64; 3],
    strict: bool,
) -> PyResult<Bound<'py, numpy::PyArray3<f32>>> {
    if (0..3).any(|a| hi[a] < lo[a]) {
        return Err(InputError::new_err(format!(
            "points {lo:?} to {hi:?}: an empty block"
        )));
    }
    let shape: [u64; 3] = std::array::from_fn(|a| hi[a] - lo[a] + 1);
    let values = py
        .detach(|| isocube_io::read_zarr_block(&path, component.as_deref(), lo, shape, strict))
        .map_err(|e| FormatError::new_err(e.to_string()))?;
    let shape = shape.map(|n| n as usize);
    numpy::PyArray1::from_vec(py, values).reshape(shape)
}

/// Meshes cells `lo..hi` (array order) of a volume of `shape` points from `block`, its points
/// `at .. at + block.shape`; returns the chunk mesh as bytes.
#[pyfunction]
#[pyo3(signature = (
    block, at, shape, lo, hi, level, *, spacing, origin, method, topology, triangulate, snap,
    zero_threshold, snap_position, flip, normals
))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn mesh_block<'py>(
    py: Python<'py>,
    block: PyReadonlyArray3<'py, f32>,
    at: [usize; 3],
    shape: [usize; 3],
    lo: [usize; 3],
    hi: [usize; 3],
    level: f32,
    spacing: [f64; 3],
    origin: [f64; 3],
    method: &str,
    topology: &str,
    triangulate: &str,
    snap: f32,
    zero_threshold: f32,
    snap_position: &str,
    flip: bool,
    normals: bool,
) -> PyResult<Bound<'py, PyBytes>> {
    let options = options_of(
        level,
        method,
        topology,
        triangulate,
        snap,
        zero_threshold,
        snap_position,
        flip,
        normals,
    )?;
    let b = block.shape();
    let (samples, strides) = samples_of(&block)?;
    let view = GridView::strided(samples, reversed([b[0], b[1], b[2]]), reversed(strides))
        .and_then(|g| g.with_spacing(reversed(spacing)))
        .and_then(|g| g.with_origin(origin))
        .map_err(|e| InputError::new_err(e.to_string()))?;
    let cells = CellBox::new(reversed(lo), reversed(hi));
    let (at, dims) = (reversed(at), reversed(shape));
    let bytes = py
        .detach(|| {
            extract::mesh_block(view, at, dims, cells, &options).map(|chunk| chunk.to_bytes())
        })
        .map_err(extract_error)?;
    Ok(PyBytes::new(py, &bytes))
}

fn chunks_of(chunks: &[Vec<u8>]) -> PyResult<Vec<ChunkMesh>> {
    chunks
        .iter()
        .map(|c| ChunkMesh::from_bytes(c).map_err(extract_error))
        .collect()
}

/// Merges chunk meshes (bytes) whose boxes tile one box of a volume of `shape` points.
#[pyfunction]
pub(crate) fn merge_chunks<'py>(
    py: Python<'py>,
    shape: [usize; 3],
    chunks: Vec<Vec<u8>>,
) -> PyResult<Bound<'py, PyBytes>> {
    let bytes = py.detach(|| {
        let chunks = chunks_of(&chunks)?;
        extract::merge_chunks(reversed(shape), chunks)
            .map(|c| c.to_bytes())
            .map_err(extract_error)
    })?;
    Ok(PyBytes::new(py, &bytes))
}

/// The outline of a chunk mesh (bytes) of a volume of `shape` points: its rows and the
/// vertices it may share, all the layout needs of it.
#[pyfunction]
pub(crate) fn chunk_outline<'py>(
    py: Python<'py>,
    chunk: Vec<u8>,
    shape: [usize; 3],
) -> PyResult<Bound<'py, PyBytes>> {
    let bytes = py.detach(|| {
        ChunkMesh::from_bytes(&chunk)
            .map(|c| c.outline(reversed(shape)).to_bytes())
            .map_err(extract_error)
    })?;
    Ok(PyBytes::new(py, &bytes))
}

/// The layout of the mesh of a whole volume of `shape` points from its chunks' outlines
/// (bytes): (vertices, triangles, counts, each chunk's place as bytes).
#[pyfunction]
pub(crate) fn join_layout<'py>(
    py: Python<'py>,
    shape: [usize; 3],
    outlines: Vec<Vec<u8>>,
) -> PyResult<Layout<'py>> {
    let dims = reversed(shape);
    let layout = py.detach(|| -> PyResult<JoinLayout> {
        let outlines = outlines
            .iter()
            .map(|o| ChunkOutline::from_bytes(o).map_err(extract_error))
            .collect::<PyResult<Vec<_>>>()?;
        let layout = JoinLayout::new(dims, &outlines).map_err(extract_error)?;
        let whole = CellBox::whole(dims).cell_count();
        if layout.stats().cells != whole {
            return Err(InputError::new_err(format!(
                "the chunks cover {} of the volume's {whole} cells",
                layout.stats().cells
            )));
        }
        Ok(layout)
    })?;
    let stats = stats_dict(py, layout.stats(), 0.0)?;
    let (nv, nt) = (layout.vertices(), layout.triangles());
    let places = layout
        .places()
        .iter()
        .map(|p| PyBytes::new(py, &p.to_bytes()))
        .collect();
    Ok((nv, nt, stats, places))
}

/// Vertices, triangles, counts and the chunks' places (bytes).
type Layout<'py> = (usize, usize, Bound<'py, PyDict>, Vec<Bound<'py, PyBytes>>);

/// Makes the binary PLY file at `path` that chunks' pieces fill: its header and length, what
/// is already there kept (a task run again loses nothing).
#[pyfunction]
pub(crate) fn create_ply(
    py: Python<'_>,
    path: std::path::PathBuf,
    vertices: u64,
    triangles: u64,
    normals: bool,
) -> PyResult<()> {
    py.detach(|| PlyLayout::new(vertices, triangles, normals).create(&path))
        .map_err(|e| FormatError::new_err(e.to_string()))
}

/// A chunk mesh (bytes) placed by its place (bytes): its pieces of the whole mesh, turned as
/// `isocube.extract` turns a C-ordered volume's mesh (the grid's frame into the array's index
/// order, then by `direction`).
fn placed(
    chunk: &[u8],
    place: &[u8],
    origin: [f64; 3],
    normals: bool,
    turn: Option<Orientation>,
) -> PyResult<(Vec<PlacedPiece>, [u64; 2])> {
    let chunk = ChunkMesh::from_bytes(chunk).map_err(extract_error)?;
    let place = ChunkPlace::from_bytes(place).map_err(extract_error)?;
    let mut pieces = place.place(&chunk).map_err(extract_error)?;
    let axes = Orientation::axes([2, 1, 0]).expect("a permutation");
    for p in &mut pieces {
        if !normals {
            p.normals.clear();
        }
        for o in std::iter::once(axes).chain(turn) {
            o.orient_parts(&mut p.positions, &mut p.normals, &mut p.triangles, origin);
        }
    }
    Ok((pieces, place.whole()))
}

/// Places a chunk mesh (bytes) by its place (bytes) and writes its pieces into the PLY file
/// at `path` that [`create_ply`] made; returns the vertices and triangles written.
#[pyfunction]
#[pyo3(signature = (path, chunk, place, *, origin, normals, direction=None))]
pub(crate) fn write_ply_chunk(
    py: Python<'_>,
    path: std::path::PathBuf,
    chunk: Vec<u8>,
    place: Vec<u8>,
    origin: [f64; 3],
    normals: bool,
    direction: Option<[[f64; 3]; 3]>,
) -> PyResult<(usize, usize)> {
    let turn = direction_of(direction)?;
    py.detach(|| {
        let (pieces, [v, t]) = placed(&chunk, &place, origin, normals, turn)?;
        PlyLayout::new(v, t, normals)
            .write_pieces(&path, &pieces)
            .map_err(|e| FormatError::new_err(e.to_string()))?;
        let nv = pieces.iter().map(|p| p.positions.len()).sum();
        let nt = pieces.iter().map(|p| p.triangles.len()).sum();
        Ok((nv, nt))
    })
}

/// A chunk mesh (bytes) placed by its place (bytes): its pieces of the whole mesh as bytes.
#[pyfunction]
#[pyo3(signature = (chunk, place, *, origin, normals, direction=None))]
pub(crate) fn place_chunk<'py>(
    py: Python<'py>,
    chunk: Vec<u8>,
    place: Vec<u8>,
    origin: [f64; 3],
    normals: bool,
    direction: Option<[[f64; 3]; 3]>,
) -> PyResult<Bound<'py, PyBytes>> {
    let turn = direction_of(direction)?;
    let bytes = py.detach(|| {
        placed(&chunk, &place, origin, normals, turn).map(|(p, _)| PlacedPiece::list_to_bytes(&p))
    })?;
    Ok(PyBytes::new(py, &bytes))
}

/// The whole mesh's arrays (vertices, triangles, normals or `None`) from every chunk's pieces
/// (bytes).
#[pyfunction]
pub(crate) fn assemble_pieces<'py>(
    py: Python<'py>,
    vertices: usize,
    triangles: usize,
    normals: bool,
    pieces: Vec<Vec<u8>>,
) -> PyResult<Assembled<'py>> {
    let mesh = py.detach(|| -> PyResult<Mesh> {
        let mut all = Vec::new();
        for p in &pieces {
            all.extend(PlacedPiece::list_from_bytes(p).map_err(extract_error)?);
        }
        extract::assemble(vertices, triangles, normals, all).map_err(extract_error)
    })?;
    let Mesh {
        positions,
        normals: vertex_normals,
        triangles,
    } = mesh;
    let normals = normals
        .then(|| rows_array(py, vertex_normals))
        .transpose()?;
    Ok((
        rows_array(py, positions)?,
        rows_array(py, triangles)?,
        normals,
    ))
}

/// Vertices, triangles and normals (or `None`).
type Assembled<'py> = (
    Bound<'py, numpy::PyArray2<f32>>,
    Bound<'py, numpy::PyArray2<u32>>,
    Option<Bound<'py, numpy::PyArray2<f32>>>,
);

fn label_options(background: i64, only: Option<Vec<i64>>, smoothing: usize) -> LabelOptions {
    let options = LabelOptions::default()
        .with_background(background)
        .with_smoothing(smoothing);
    match only {
        Some(list) => options.with_labels(LabelSelection::Only(list)),
        None => options,
    }
}

/// Meshes the padded label cells `lo..hi` (array order, as the grid's: labels are meshed in
/// the array's index order) of a segmentation of `shape` points from `ids`, its points
/// `at .. at + ids.shape` as 1-based numbers into `names`; returns the chunk mesh as bytes.
#[pyfunction]
#[pyo3(signature = (ids, at, shape, lo, hi, names, *, spacing, origin, background, only))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn mesh_label_block<'py>(
    py: Python<'py>,
    ids: PyReadonlyArray3<'py, u32>,
    at: [usize; 3],
    shape: [usize; 3],
    lo: [usize; 3],
    hi: [usize; 3],
    names: Vec<i64>,
    spacing: [f64; 3],
    origin: [f64; 3],
    background: i64,
    only: Option<Vec<i64>>,
) -> PyResult<Bound<'py, PyBytes>> {
    let view = ids.as_array();
    let b = view.shape();
    let block = [b[0], b[1], b[2]];
    // x (the array's first axis) fastest.
    let mut values = Vec::with_capacity(block.iter().product());
    for k in 0..block[2] {
        for j in 0..block[1] {
            for i in 0..block[0] {
                values.push(view[[i, j, k]]);
            }
        }
    }
    let options = label_options(background, only, 0);
    let bytes = py
        .detach(|| {
            extract::mesh_label_block(
                &values,
                at,
                block,
                shape,
                CellBox::new(lo, hi),
                &names,
                &options,
                spacing,
                origin,
            )
            .map(|c| c.to_bytes())
        })
        .map_err(extract_error)?;
    Ok(PyBytes::new(py, &bytes))
}

/// Merges label chunk meshes (bytes) whose boxes tile one box of a segmentation's padded
/// cells (`shape` + 2 points, in the array's index order).
#[pyfunction]
pub(crate) fn merge_label_chunks<'py>(
    py: Python<'py>,
    shape: [usize; 3],
    chunks: Vec<Vec<u8>>,
) -> PyResult<Bound<'py, PyBytes>> {
    let bytes = py.detach(|| {
        let chunks = chunks_of(&chunks)?;
        extract::merge_chunks(shape.map(|n| n + 2), chunks)
            .map(|c| c.to_bytes())
            .map_err(extract_error)
    })?;
    Ok(PyBytes::new(py, &bytes))
}

/// Every label's surface from the merged chunk of all padded cells, as `label_surfaces`.
#[pyfunction]
#[pyo3(signature = (chunk, shape, names, *, spacing, origin, background, only, smoothing))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn finish_label_chunks<'py>(
    py: Python<'py>,
    chunk: Vec<u8>,
    shape: [usize; 3],
    names: Vec<i64>,
    spacing: [f64; 3],
    origin: [f64; 3],
    background: i64,
    only: Option<Vec<i64>>,
    smoothing: usize,
) -> PyResult<Vec<crate::LabelArrays<'py>>> {
    let options = label_options(background, only, smoothing);
    let surfaces = py
        .detach(|| {
            let chunk = ChunkMesh::from_bytes(&chunk)?;
            if chunk.cells != CellBox::whole(shape.map(|n| n + 2)) {
                return Err(isocube::extract::ExtractError::MalformedChunk { cells: chunk.cells });
            }
            extract::label_surfaces_of(
                chunk,
                &names,
                &options,
                spacing,
                Orientation::IDENTITY,
                origin,
            )
        })
        .map_err(extract_error)?;
    crate::label_arrays(py, surfaces)
}
