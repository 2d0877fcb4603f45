//! `isocube._isocube`: the extension module behind the `isocube` Python package. NumPy arrays
//! come in and are read where they lie (any positive strides: C order, Fortran order, views,
//! `np.memmap`); meshes go out as arrays that own the buffers the engine filled, no copy. The
//! work runs with the GIL released; Ctrl-C stops it.
//!
//! The Python layer (`isocube/__init__.py`) checks arguments the way its users expect (e.g.
//! scikit-image's `marching_cubes`) and converts other dtypes; this module takes `float32`.

use std::ops::ControlFlow;
use std::time::{Duration, Instant};

use isocube::extract::{
    extract_boxes_into, extract_into, extract_labels, CellBox, ExtractError, ExtractOptions,
    ExtractStats, LabelOptions, LabelSelection, Method, SnapPosition, Snapping,
};
use isocube::field::{GridView, Orientation, PlaneSource};
use isocube::mesh::Mesh;
use numpy::{PyArray1, PyArray2, PyArrayMethods, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyKeyboardInterrupt, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rayon::prelude::*;

mod blocks;
mod contours;
mod subdiv;
mod tets;

create_exception!(
    isocube,
    Error,
    PyException,
    "Base class of isocube's errors."
);
create_exception!(
    isocube,
    InputError,
    Error,
    "The input cannot be meshed as given (a bad option, a value out of range)."
);
create_exception!(
    isocube,
    FormatError,
    Error,
    "A file could not be read or written: its message names the file, the position and why."
);
create_exception!(
    isocube,
    MemoryLimitError,
    Error,
    "The work would need more memory than allowed."
);

/// How often the work stops to ask Python whether Ctrl-C was pressed.
const SIGNAL_CHECK: Duration = Duration::from_millis(50);

/// Flattens `[f32; 3]` rows (or any `[T; 3]`) into one vector without copying.
fn flatten<T: Copy>(rows: Vec<[T; 3]>) -> Vec<T> {
    let mut rows = std::mem::ManuallyDrop::new(rows);
    let (ptr, len, cap) = (rows.as_mut_ptr(), rows.len(), rows.capacity());
    // SAFETY: `[T; 3]` has `T`'s alignment and three times its size, so the allocation of
    // `cap` rows is exactly one of `3 * cap` elements, of which the first `3 * len` are set.
    unsafe { Vec::from_raw_parts(ptr.cast::<T>(), 3 * len, 3 * cap) }
}

/// Vertex indices as `int32`, scikit-image's dtype, in the same buffer (every index below
/// `i32::MAX`, which the caller checks).
fn as_i32(rows: Vec<[u32; 3]>) -> Vec<[i32; 3]> {
    let mut rows = std::mem::ManuallyDrop::new(rows);
    let (ptr, len, cap) = (rows.as_mut_ptr(), rows.len(), rows.capacity());
    // SAFETY: `[u32; 3]` and `[i32; 3]` have the same size and alignment, and every `u32`
    // below 2^31 is the same bits as the `i32` of that value.
    unsafe { Vec::from_raw_parts(ptr.cast::<[i32; 3]>(), len, cap) }
}

/// A `(n, 3)` array owning `rows`' buffer.
pub(crate) fn rows_array<'py, T: numpy::Element + Copy>(
    py: Python<'py>,
    rows: Vec<[T; 3]>,
) -> PyResult<Bound<'py, PyArray2<T>>> {
    let n = rows.len();
    PyArray1::from_vec(py, flatten(rows)).reshape([n, 3])
}

fn parse<T: std::str::FromStr>(value: &str) -> PyResult<T>
where
    T::Err: std::fmt::Display,
{
    value
        .parse()
        .map_err(|e: T::Err| InputError::new_err(e.to_string()))
}

/// The extraction method by name: `mc`, or `ternary` with its snapping options.
pub(crate) fn method_of(
    method: &str,
    snap: f32,
    zero_threshold: f32,
    snap_position: &str,
) -> PyResult<Method> {
    match method {
        "mc" => Ok(Method::MarchingCubes),
        "ternary" => Ok(Method::Ternary(
            Snapping::default()
                .with_snap(snap)
                .with_zero_threshold(zero_threshold)
                .with_position(parse::<SnapPosition>(snap_position)?),
        )),
        other => Err(InputError::new_err(format!(
            "unknown method '{other}': expected mc or ternary"
        ))),
    }
}

/// A direction matrix (columns: the world vectors of the array's axes) as an orientation.
pub(crate) fn direction_of(direction: Option<[[f64; 3]; 3]>) -> PyResult<Option<Orientation>> {
    direction
        .map(|d| {
            Orientation::new(d).ok_or_else(|| {
                InputError::new_err("the direction must be a finite, non-singular 3 × 3 matrix")
            })
        })
        .transpose()
}

/// The options `extract` and `tetmesh` share, by name where Python gives names.
pub(crate) fn surface_options(
    level: f32,
    flip: bool,
    topology: &str,
    triangulate: &str,
    method: Method,
    max_memory: Option<u64>,
) -> PyResult<ExtractOptions> {
    Ok(ExtractOptions::default()
        .with_level(level)
        .with_flip(flip)
        .with_topology(parse(topology)?)
        .with_triangulation(parse(triangulate)?)
        .with_method(method)
        .with_max_memory(max_memory))
}

pub(crate) fn extract_error(e: ExtractError) -> PyErr {
    match e {
        ExtractError::MemoryLimit { .. } | ExtractError::MeshMemory { .. } => {
            MemoryLimitError::new_err(e.to_string())
        }
        e => InputError::new_err(e.to_string()),
    }
}

/// The extraction's counts, and the seconds the engine took (the call less the Python layer).
pub(crate) fn stats_dict<'py>(
    py: Python<'py>,
    stats: &ExtractStats,
    seconds: f64,
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("seconds", seconds)?;
    d.set_item("cells", stats.cells)?;
    d.set_item("active_cells", stats.active_cells)?;
    d.set_item("skipped_cells", stats.skipped_cells)?;
    d.set_item("interior_vertices", stats.interior_vertices)?;
    d.set_item("tunnels", stats.tunnels)?;
    d.set_item("snapped_points", stats.snapped_points)?;
    d.set_item("refused_points", stats.refused_points)?;
    Ok(d)
}

/// The arrays `extract` hands back: vertices, triangles, normals and values (or `None`),
/// counts.
type Extracted<'py> = (
    Bound<'py, PyArray2<f32>>,
    Bound<'py, PyArray2<u32>>,
    Option<Bound<'py, PyArray2<f32>>>,
    Option<Bound<'py, PyArray1<f32>>>,
    Bound<'py, PyDict>,
);

/// The larger of the values at the two ends of the grid edge each vertex lies on (a vertex on
/// a grid point: that point's value; inside a cell: the largest of its eight corners). As
/// scikit-image's `values`, the largest value near the vertex, a colour scale's input, not an
/// interpolation; two reads per vertex, in the order the vertices were made.
fn vertex_values(grid: &GridView, order: [usize; 3], positions: &[[f32; 3]]) -> Vec<f32> {
    let (origin, spacing, dims) = (grid.origin(), grid.spacing(), grid.dims());
    let inverse = spacing.map(|h| 1.0 / h);
    let strides = grid.strides();
    let values = grid.values();
    positions
        .par_iter()
        .with_min_len(1 << 12)
        .map(|p| {
            // The lower corner of the cell, edge or point holding the vertex, and the steps to
            // the other corners (none along an axis whose plane holds it): eight reads, the
            // same address repeated where a step is none, so no branches.
            let (mut base, mut step) = (grid.index(0, 0, 0), [0usize; 3]);
            for a in 0..3 {
                // Grid axis `a` is the array's axis `order[a]`.
                let w = order[a];
                let q = (f64::from(p[w]) - origin[w]) * inverse[a];
                let near = q.round();
                // Within rounding of a grid plane: on it.
                let (lo, hi) = if (q - near).abs() < 1e-4 {
                    (near, near)
                } else {
                    (q.floor(), q.ceil())
                };
                let clamp = |x: f64| (x.max(0.0) as usize).min(dims[a] - 1);
                let (lo, hi) = (clamp(lo), clamp(hi));
                base += lo * strides[a];
                step[a] = (hi - lo) * strides[a];
            }
            let at = |d: usize| values[base + d];
            let [x, y, z] = step;
            let low = at(0).max(at(x)).max(at(y)).max(at(x + y));
            let high = at(z).max(at(x + z)).max(at(y + z)).max(at(x + y + z));
            low.max(high)
        })
        .collect()
}

/// The elements a `float32` array may read (from its first to its last) and its strides in
/// elements; an error for negative strides or strides that are not whole elements.
pub(crate) fn samples_of<'a>(
    volume: &'a PyReadonlyArray3<'_, f32>,
) -> PyResult<(&'a [f32], [usize; 3])> {
    let shape = volume.shape();
    let dims = [shape[0], shape[1], shape[2]];
    let item = std::mem::size_of::<f32>() as isize;
    let mut strides = [0usize; 3];
    for (axis, &s) in volume.strides().iter().enumerate() {
        if s < 0 || s % item != 0 {
            return Err(PyValueError::new_err(
                "the volume's strides must be positive multiples of 4 bytes (isocube.extract \
                 copies other arrays first)",
            ));
        }
        strides[axis] = (s / item) as usize;
    }
    // The span from the first element to the last, in elements: what the view may read.
    let span = 1
        + (0..3)
            .map(|a| dims[a].saturating_sub(1) * strides[a])
            .sum::<usize>();
    let samples: &[f32] = if dims.contains(&0) {
        &[]
    } else {
        // SAFETY: NumPy guarantees every element `data + Σ i_a·stride_a` of the array lies in
        // its buffer; with positive strides the farthest is `span - 1` elements on, and the
        // readonly borrow keeps the buffer alive and unchanged by Rust while this runs.
        unsafe { std::slice::from_raw_parts(volume.data() as *const f32, span) }
    };
    Ok((samples, strides))
}

/// A `float32` volume indexed `volume[x, y, z]` as a grid view in its memory order, and that
/// order (grid axis `a` is the array's axis `order[a]`).
fn view_of<'a>(
    volume: &'a PyReadonlyArray3<'_, f32>,
    spacing: [f64; 3],
    origin: [f64; 3],
) -> PyResult<(GridView<'a>, [usize; 3])> {
    let shape = volume.shape();
    let dims = [shape[0], shape[1], shape[2]];
    let (samples, strides) = samples_of(volume)?;
    // Meshed in memory order (the fastest axis as the grid's x), as the command line meshes a
    // mapped file: a C-order array read along its last axis, not across it (several times
    // faster), and the same mesh as `isocube extract` on the array saved as `.npy`. The grid's
    // frame is turned back to the array's index order by an axis permutation.
    let mut order = [0usize, 1, 2];
    order.sort_by_key(|&a| (strides[a], a));
    let grid = GridView::strided(samples, order.map(|a| dims[a]), order.map(|a| strides[a]))
        .and_then(|g| g.with_spacing(order.map(|a| spacing[a])))
        .and_then(|g| g.with_origin(origin))
        .map_err(|e| InputError::new_err(e.to_string()))?
        .with_orientation(Orientation::axes(order).expect("a permutation of the axes"));
    Ok((grid, order))
}

/// A `float32` volume indexed `volume[x, y, z]` as a grid view in that index order (the
/// array's axes as the grid's, whatever its strides): where meshes depend on the frame (label
/// meshes cut cells into tetrahedra along the grid's axes), the command line's frame for a file.
fn index_order_view<'a>(
    volume: &'a PyReadonlyArray3<'_, f32>,
    spacing: [f64; 3],
    origin: [f64; 3],
) -> PyResult<GridView<'a>> {
    let (memory_order, order) = view_of(volume, spacing, origin)?;
    let mut strides = [0usize; 3];
    for (a, &w) in order.iter().enumerate() {
        strides[w] = memory_order.strides()[a];
    }
    let shape = volume.shape();
    GridView::strided(
        memory_order.values(),
        [shape[0], shape[1], shape[2]],
        strides,
    )
    .and_then(|g| g.with_spacing(spacing))
    .and_then(|g| g.with_origin(origin))
    .map_err(|e| InputError::new_err(e.to_string()))
}

/// What one extraction made: the mesh, its counts, vertex values if asked, the engine's seconds.
struct Run {
    mesh: Mesh,
    stats: ExtractStats,
    values: Option<Vec<f32>>,
    seconds: f64,
}

/// Runs `work` with the GIL released, handing it a progress function that asks Python, at
/// once and then every [`SIGNAL_CHECK`], whether Ctrl-C was pressed and tells `report` (a
/// Python callable taking `(done, total)`) where the work is. When either stops the work
/// (`work`'s error is then one `cancelled` recognises), the result is the `KeyboardInterrupt`
/// or the exception `report` raised; other errors are `work`'s own.
pub(crate) fn interruptible<T: Send, E: Send>(
    py: Python<'_>,
    report: Option<Py<PyAny>>,
    cancelled: impl Fn(&E) -> bool,
    work: impl FnOnce(&mut dyn FnMut(usize, usize) -> ControlFlow<()>) -> Result<T, E> + Send,
) -> PyResult<Result<T, E>> {
    let mut interrupted: Option<PyErr> = None;
    let result = py.detach(|| {
        let mut last: Option<Instant> = None;
        let mut progress = |done: usize, total: usize| {
            if last.is_some_and(|t| t.elapsed() < SIGNAL_CHECK) {
                return ControlFlow::Continue(());
            }
            last = Some(Instant::now());
            // Ctrl-C first; then the caller's progress report (an exception it raises stops
            // the work too).
            let asked = Python::attach(|py| {
                py.check_signals()?;
                if let Some(report) = &report {
                    report.call1(py, (done, total))?;
                }
                Ok(())
            });
            match asked {
                Ok(()) => ControlFlow::Continue(()),
                Err(e) => {
                    interrupted = Some(e);
                    ControlFlow::Break(())
                }
            }
        };
        work(&mut progress)
    });
    match result {
        Err(e) if cancelled(&e) => {
            Err(interrupted.unwrap_or_else(|| PyKeyboardInterrupt::new_err(())))
        }
        other => Ok(other),
    }
}

/// Extracts with the GIL released, stopping on Ctrl-C (see [`interruptible`]).
fn run(
    py: Python<'_>,
    grid: GridView<'_>,
    order: [usize; 3],
    options: &ExtractOptions,
    values: bool,
    report: Option<Py<PyAny>>,
    chunk: Option<[usize; 3]>,
) -> PyResult<Run> {
    let result = interruptible(
        py,
        report,
        |e| matches!(e, ExtractError::Cancelled),
        |progress| {
            let mut mesh = Mesh::new();
            let started = Instant::now();
            let stats = match chunk {
                // Boxes of the array's axes, in the grid's (memory) order.
                Some(size) => {
                    let boxes = CellBox::tile(grid.dims(), order.map(|w| size[w]))?;
                    extract_boxes_into(grid, options, &boxes, &mut mesh, progress)?
                }
                None => extract_into(grid, options, &mut mesh, progress)?,
            };
            let values = values.then(|| vertex_values(&grid, order, &mesh.positions));
            Ok(Run {
                mesh,
                stats,
                values,
                seconds: started.elapsed().as_secs_f64(),
            })
        },
    )?;
    result.map_err(extract_error)
}

/// Extracts the isosurface of a `float32` volume indexed `volume[x, y, z]` (any positive
/// strides). Vertices come in the array's index order, scaled by `spacing`, moved by `origin`;
/// triangles face away from the side below the level (towards it with `flip`).
#[pyfunction]
#[pyo3(signature = (
    volume, level, *, spacing, origin, method, topology, triangulate, snap, zero_threshold,
    snap_position, flip, normals, values, max_memory, direction=None, progress=None, relax=0,
    chunk=None, allow_empty=true
))]
#[allow(clippy::too_many_arguments)]
fn extract<'py>(
    py: Python<'py>,
    volume: PyReadonlyArray3<'py, f32>,
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
    values: bool,
    max_memory: Option<u64>,
    direction: Option<[[f64; 3]; 3]>,
    progress: Option<Py<PyAny>>,
    relax: usize,
    chunk: Option<[usize; 3]>,
    allow_empty: bool,
) -> PyResult<Extracted<'py>> {
    let (grid, order) = view_of(&volume, spacing, origin)?;
    let turn = direction_of(direction)?;
    let options = surface_options(
        level,
        flip,
        topology,
        triangulate,
        method_of(method, snap, zero_threshold, snap_position)?,
        max_memory,
    )?
    .with_normals(normals)
    .with_relax(relax);
    let Run {
        mut mesh,
        stats,
        values,
        seconds,
    } = run(py, grid, order, &options, values, progress, chunk)?;
    if mesh.triangles.is_empty() && !allow_empty {
        let (why, outside) = why_empty(py, &grid, f64::from(level));
        let message = format!("{why} (pass allow_empty=True for the empty mesh)");
        return Err(empty_surface(py, outside, message));
    }
    // Turned into the world after the values are found in the array's frame.
    if let Some(turn) = turn {
        turn.orient_mesh(&mut mesh, origin);
    }
    let Mesh {
        positions,
        normals: vertex_normals,
        triangles,
    } = mesh;
    let normals = (normals && vertex_normals.len() == positions.len())
        .then(|| rows_array(py, vertex_normals))
        .transpose()?;
    Ok((
        rows_array(py, positions)?,
        rows_array(py, triangles)?,
        normals,
        values.map(|v| PyArray1::from_vec(py, v)),
        stats_dict(py, &stats, seconds)?,
    ))
}

/// Why the surface at `level` is empty (the library's words, with the values' range), and
/// whether the level lies outside that range (or no value is finite).
fn why_empty(py: Python<'_>, grid: &GridView<'_>, level: f64) -> (ExtractError, bool) {
    let (lo, hi) = py.detach(|| value_range(grid));
    let range = (lo <= hi).then_some((lo, hi));
    let outside = range.is_none_or(|(lo, hi)| level < f64::from(lo) || level > f64::from(hi));
    let why = ExtractError::EmptySurface {
        level: level as f32,
        range,
    };
    (why, outside)
}

/// `isocube.LevelOutsideError` (`outside`) or `isocube.EmptySurfaceError`: both an
/// `isocube.InputError` and a `RuntimeError`, the first a `ValueError` too, so that code
/// written for scikit-image and for isocube both catch them (see `isocube/_errors.py`).
fn empty_surface(py: Python<'_>, outside: bool, message: String) -> PyErr {
    let class = match outside {
        true => "LevelOutsideError",
        false => "EmptySurfaceError",
    };
    match py
        .import("isocube._errors")
        .and_then(|m| m.getattr(class))
        .and_then(|c| c.call1((message,)))
    {
        Ok(error) => PyErr::from_value(error),
        Err(e) => e,
    }
}

/// The smallest and largest value of a view, over all threads (NaNs left out).
fn value_range(grid: &GridView) -> (f32, f32) {
    fn fold(values: &[f32]) -> (f32, f32) {
        // Plain comparisons, so that the loop vectorises.
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        for &v in values {
            lo = if v < lo { v } else { lo };
            hi = if v > hi { v } else { hi };
        }
        (lo, hi)
    }
    let both = |a: (f32, f32), b: (f32, f32)| (a.0.min(b.0), a.1.max(b.1));
    let none = || (f32::INFINITY, f32::NEG_INFINITY);
    let [nx, ny, nz] = grid.dims();
    let values = grid.values();
    if values.len() == nx * ny * nz {
        // Every element of the buffer is a point: one sweep of memory.
        return values.par_chunks(1 << 16).map(fold).reduce(none, both);
    }
    (0..nz)
        .into_par_iter()
        .map(|k| {
            let mut range = none();
            for j in 0..ny {
                for i in 0..nx {
                    let v = grid.value(i, j, k);
                    range = both(range, (v, v));
                }
            }
            range
        })
        .reduce(none, both)
}

/// scikit-image's `marching_cubes` after its argument checks (`isocube.marching_cubes`): the
/// level (by default halfway through the value range) checked against the range, the mesh in
/// index space with normals down the gradient, faces as `int32` turned as `descent` asks
/// (towards the side above the level) or not (below), and vertex values.
#[pyfunction]
#[pyo3(signature = (volume, level, *, topology, descent))]
fn marching_cubes<'py>(
    py: Python<'py>,
    volume: PyReadonlyArray3<'py, f32>,
    level: Option<f64>,
    topology: &str,
    descent: bool,
) -> PyResult<McOutput<'py>> {
    let (grid, order) = view_of(&volume, [1.0; 3], [0.0; 3])?;
    // A level outside the value range meets no cell, so its mesh is empty: the range (a pass
    // over the whole volume) is needed first only to find the default level, and otherwise only
    // when nothing was found, to say why.
    let requested = level;
    let level = match level {
        // In single precision, as scikit-image computes it from NumPy's float32 scalars.
        None => {
            let (lo, hi) = py.detach(|| value_range(&grid));
            0.5 * (lo + hi)
        }
        Some(l) => l as f32,
    };
    // isocube's normals follow its faces; scikit-image's point down the gradient whatever the
    // direction. `descent` turns the faces towards the side above the level, as isocube's own
    // (`flip` off), and its normals are then turned round; `ascent` is isocube's `flip`, normals
    // and all.
    let options = ExtractOptions::default()
        .with_level(level)
        .with_flip(!descent)
        .with_topology(parse(topology)?);
    let Run {
        mut mesh, values, ..
    } = run(py, grid, order, &options, true, None, None)?;
    if mesh.triangles.is_empty() {
        // The level as given (in double precision, as scikit-image compares it), and
        // scikit-image's words first: code matching them keeps working.
        let (why, outside) = why_empty(py, &grid, requested.unwrap_or(f64::from(level)));
        let lead = match outside {
            true => "Surface level must be within volume data range",
            false => "No surface found at the given iso value",
        };
        return Err(empty_surface(py, outside, format!("{lead}: {why}.")));
    }
    let n = mesh.positions.len();
    if mesh.normals.len() != n {
        mesh.normals = vec![[0.0; 3]; n];
    } else if descent {
        py.detach(|| {
            mesh.normals
                .par_iter_mut()
                .with_min_len(1 << 14)
                .for_each(|g| *g = g.map(|c| -c));
        });
    }
    // Indices below `u32::MAX` (the engine refuses more vertices), well within `i32` for any
    // mesh NumPy can index: reinterpreted in place.
    if n > i32::MAX as usize {
        return Err(MemoryLimitError::new_err(
            "more than 2^31 vertices: scikit-image's int32 faces cannot index them",
        ));
    }
    let faces = as_i32(mesh.triangles);
    let normals = mesh.normals;
    Ok((
        rows_array(py, mesh.positions)?,
        rows_array(py, faces)?,
        rows_array(py, normals)?,
        PyArray1::from_vec(py, values.unwrap_or_default()),
    ))
}

/// `marching_cubes`' arrays: vertices, faces, normals, values.
type McOutput<'py> = (
    Bound<'py, PyArray2<f32>>,
    Bound<'py, PyArray2<i32>>,
    Bound<'py, PyArray2<f32>>,
    Bound<'py, PyArray1<f32>>,
);

/// Rows of a `(n, 3)` array (C-contiguous: the Python layer makes it so).
fn rows<T: numpy::Element + Copy>(a: &numpy::PyReadonlyArray2<'_, T>) -> PyResult<Vec<[T; 3]>> {
    if a.shape()[1] != 3 {
        return Err(InputError::new_err(format!(
            "expected an array of shape (n, 3), not {:?}",
            a.shape()
        )));
    }
    let flat = a
        .as_slice()
        .map_err(|_| InputError::new_err("expected a C-contiguous array"))?;
    Ok(flat.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect())
}

/// Writes a mesh in the format its path's extension names (`.ply`, `.obj`, `.stl`, `.off`,
/// `.glb`, `.vtp`, `.vtk`, `.msh`), atomically (a temporary file renamed over the target): the
/// same writer, and so the same bytes, as the command line's.
#[pyfunction]
#[pyo3(signature = (path, vertices, triangles, normals, values, values_name, ascii))]
#[allow(clippy::too_many_arguments)]
fn save_mesh(
    py: Python<'_>,
    path: std::path::PathBuf,
    vertices: numpy::PyReadonlyArray2<'_, f32>,
    triangles: numpy::PyReadonlyArray2<'_, u32>,
    normals: Option<numpy::PyReadonlyArray2<'_, f32>>,
    values: Option<numpy::PyReadonlyArray1<'_, f32>>,
    values_name: &str,
    ascii: bool,
) -> PyResult<()> {
    let mesh = Mesh {
        positions: rows(&vertices)?,
        triangles: rows(&triangles)?,
        normals: normals.as_ref().map(rows).transpose()?.unwrap_or_default(),
    };
    let values: Option<&[f32]> = values
        .as_ref()
        .map(|v| {
            v.as_slice()
                .map_err(|_| InputError::new_err("expected contiguous values"))
        })
        .transpose()?;
    let mut options = isocube_io::MeshWriteOptions::default();
    options.ascii = ascii;
    options.normals = !mesh.normals.is_empty();
    let written = py.detach(|| {
        isocube_io::write_mesh_with_values(
            &path,
            &mesh,
            &options,
            values.map(|values| isocube_io::VertexValues {
                name: values_name,
                values,
            }),
        )
    });
    written.map_err(|e| FormatError::new_err(e.to_string()))
}

/// A volume file's values, indexed `[x, y, z]` (a Fortran-ordered array owning the reader's
/// buffer), spacing, origin and direction (columns: the world vectors of the axes).
type ReadVolume<'py> = (
    Bound<'py, numpy::PyArray3<f32>>,
    [f64; 3],
    [f64; 3],
    [[f64; 3]; 3],
);

/// Reads a volume file as the command line does: by extension (`.npy`, `.nrrd`/`.nhdr`,
/// `.nii`/`.nii.gz`, `.mha`/`.mhd`, `.tif`/`.tiff`, `.vti`, `.dcm`), a folder as a DICOM series
/// or a Zarr store; `frame` and `channel` pick one volume of a 4-d or 5-d file.
#[pyfunction]
#[pyo3(signature = (path, *, spacing=None, origin=None, max_memory=None, npy_axes="xyz", frame=None, channel=None))]
#[allow(clippy::too_many_arguments)]
fn read_volume<'py>(
    py: Python<'py>,
    path: std::path::PathBuf,
    spacing: Option<[f64; 3]>,
    origin: Option<[f64; 3]>,
    max_memory: Option<u64>,
    npy_axes: &str,
    frame: Option<usize>,
    channel: Option<usize>,
) -> PyResult<ReadVolume<'py>> {
    let mut options = isocube_io::VolumeOptions::default();
    options.frame = frame;
    options.channel = channel;
    options.spacing = spacing;
    options.origin = origin;
    options.max_memory = max_memory;
    options.npy_axes = npy_axes
        .parse()
        .map_err(|e: String| InputError::new_err(e))?;
    let failed = |e: isocube_io::IoError| match e {
        isocube_io::IoError::TooLarge { .. } => MemoryLimitError::new_err(e.to_string()),
        e => FormatError::new_err(e.to_string()),
    };
    // A file that maps is read as the command line walks it (its memory order: a `.npy` saved
    // in C order has `x` slowest), so that `extract` on the array, which meshes arrays in
    // their memory order, makes the command line's file; the array is then indexed `[x, y, z]`
    // by a transposed view, with no copy.
    let read = py.detach(|| {
        Ok::<_, isocube_io::IoError>(match isocube_io::MappedVolume::try_open(&path, &options)? {
            Some(volume) => {
                let grid = volume.read_whole(options.max_memory)?;
                (grid, volume.orientation(), volume.file_axes())
            }
            None => {
                let (grid, orientation) = isocube_io::read_volume_oriented(&path, &options)?;
                (grid, orientation, [0, 1, 2])
            }
        })
    });
    let (grid, orientation, axes) = read.map_err(failed)?;
    let (dims, walked_spacing, origin) = (grid.dims(), grid.spacing(), grid.origin());
    let walked = numpy::PyArray1::from_vec(py, grid.into_values())
        .reshape_with_order(dims, numpy::npyffi::NPY_ORDER::NPY_FORTRANORDER)?;
    // Grid axis `a` walks the file's axis `axes[a]`: the index-order array's axis `w` is the
    // grid's axis `a` with `axes[a] == w`.
    let mut order = [0usize; 3];
    let mut spacing = [0.0; 3];
    let turned = orientation.direction();
    let mut direction = [[0.0; 3]; 3];
    for (a, &w) in axes.iter().enumerate() {
        order[w] = a;
        spacing[w] = walked_spacing[a];
        for (row, turned_row) in direction.iter_mut().zip(&turned) {
            row[w] = turned_row[a];
        }
    }
    let values = walked
        .call_method1("transpose", (order.to_vec(),))?
        .cast_into::<numpy::PyArray3<f32>>()?;
    Ok((values, spacing, origin, direction))
}

/// The level `spec` names for `volume`'s values: a number, `auto` (Otsu's threshold of the
/// histogram) or `P%` (that fraction of the value range), as `isocube extract --level` takes it.
#[pyfunction]
fn resolve_level(py: Python<'_>, volume: PyReadonlyArray3<'_, f32>, spec: &str) -> PyResult<f32> {
    let level: isocube::field::Level = spec
        .parse()
        .map_err(|e: isocube::ParseError| InputError::new_err(e.to_string()))?;
    if let isocube::field::Level::Value(v) = level {
        return Ok(v);
    }
    let view = volume.as_array();
    let owned;
    let values = match view.as_slice_memory_order() {
        Some(values) => values,
        None => {
            owned = view.iter().copied().collect::<Vec<f32>>();
            &owned
        }
    };
    let summary = py.detach(|| isocube::field::ValueSummary::of(values));
    let summary = summary.ok_or_else(|| {
        InputError::new_err("the volume holds no finite value to take a level from")
    })?;
    Ok(level.resolve(&summary))
}

/// One label's surface as `label_surfaces` hands it back: label, vertices, triangles, normals.
pub(crate) type LabelArrays<'py> = (
    i64,
    Bound<'py, PyArray2<f32>>,
    Bound<'py, PyArray2<u32>>,
    Option<Bound<'py, PyArray2<f32>>>,
);

/// The closed surface of every label of a labelled volume (integers stored as `float32`),
/// neighbours sharing their interfaces, as `isocube extract --labels` makes them: the volume
/// read in its index order (the command line's frame for a file), any strides.
#[pyfunction]
#[pyo3(signature = (labels, *, spacing, origin, background, only, smoothing))]
fn label_surfaces<'py>(
    py: Python<'py>,
    labels: PyReadonlyArray3<'py, f32>,
    spacing: [f64; 3],
    origin: [f64; 3],
    background: i64,
    only: Option<Vec<i64>>,
    smoothing: usize,
) -> PyResult<Vec<LabelArrays<'py>>> {
    let grid = index_order_view(&labels, spacing, origin)?;
    let mut options = LabelOptions::default()
        .with_background(background)
        .with_smoothing(smoothing);
    if let Some(list) = only {
        options = options.with_labels(LabelSelection::Only(list));
    }
    let surfaces = py
        .detach(|| extract_labels(grid, &options))
        .map_err(extract_error)?;
    label_arrays(py, surfaces)
}

/// Each label's surface as `(label, vertices, triangles, normals)`, the arrays owning the
/// meshes' buffers.
pub(crate) fn label_arrays(
    py: Python<'_>,
    surfaces: Vec<isocube::extract::LabelSurface>,
) -> PyResult<Vec<LabelArrays<'_>>> {
    surfaces
        .into_iter()
        .map(|s| {
            let Mesh {
                positions,
                normals,
                triangles,
            } = s.mesh;
            let normals = (normals.len() == positions.len())
                .then(|| rows_array(py, normals))
                .transpose()?;
            Ok((
                s.label,
                rows_array(py, positions)?,
                rows_array(py, triangles)?,
                normals,
            ))
        })
        .collect()
}

/// The extension module.
#[pymodule]
fn _isocube(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(extract, m)?)?;
    m.add_function(wrap_pyfunction!(marching_cubes, m)?)?;
    m.add_function(wrap_pyfunction!(save_mesh, m)?)?;
    m.add_function(wrap_pyfunction!(read_volume, m)?)?;
    m.add_function(wrap_pyfunction!(resolve_level, m)?)?;
    m.add_function(wrap_pyfunction!(label_surfaces, m)?)?;
    m.add_function(wrap_pyfunction!(tets::tetmesh, m)?)?;
    m.add_class::<tets::PyTetMesh>()?;
    m.add_function(wrap_pyfunction!(contours::reconstruct, m)?)?;
    m.add_function(wrap_pyfunction!(contours::tetmesh, m)?)?;
    m.add_function(wrap_pyfunction!(contours::read, m)?)?;
    m.add_class::<subdiv::PyPolyMesh>()?;
    m.add_function(wrap_pyfunction!(subdiv::poly_mesh, m)?)?;
    m.add_function(wrap_pyfunction!(subdiv::read, m)?)?;
    m.add_function(wrap_pyfunction!(tables, m)?)?;
    m.add_function(wrap_pyfunction!(blocks::block_halo, m)?)?;
    m.add_function(wrap_pyfunction!(blocks::read_zarr_block, m)?)?;
    m.add_function(wrap_pyfunction!(blocks::mesh_block, m)?)?;
    m.add_function(wrap_pyfunction!(blocks::merge_chunks, m)?)?;
    m.add_function(wrap_pyfunction!(blocks::chunk_outline, m)?)?;
    m.add_function(wrap_pyfunction!(blocks::join_layout, m)?)?;
    m.add_function(wrap_pyfunction!(blocks::create_ply, m)?)?;
    m.add_function(wrap_pyfunction!(blocks::write_ply_chunk, m)?)?;
    m.add_function(wrap_pyfunction!(blocks::place_chunk, m)?)?;
    m.add_function(wrap_pyfunction!(blocks::assemble_pieces, m)?)?;
    m.add_function(wrap_pyfunction!(blocks::mesh_label_block, m)?)?;
    m.add_function(wrap_pyfunction!(blocks::merge_label_chunks, m)?)?;
    m.add_function(wrap_pyfunction!(blocks::finish_label_chunks, m)?)?;
    m.add("Error", m.py().get_type::<Error>())?;
    m.add("InputError", m.py().get_type::<InputError>())?;
    m.add("FormatError", m.py().get_type::<FormatError>())?;
    m.add("MemoryLimitError", m.py().get_type::<MemoryLimitError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}

/// The classes of the cube's configurations under a symmetry group (`isocube tables`): one
/// row per configuration, as columns, or (with `polygons`) the derived table's polygons per
/// configuration as the command's TSV text.
#[pyfunction]
#[pyo3(signature = (kind, group, polygons))]
fn tables<'py>(
    py: Python<'py>,
    kind: &str,
    group: &str,
    polygons: bool,
) -> PyResult<Bound<'py, PyAny>> {
    use isocube::cube::{ClassTable, ConfigKind, Group, TernaryTable};
    let kind = match kind {
        "binary" => ConfigKind::Binary,
        "ternary" => ConfigKind::Ternary,
        other => {
            return Err(InputError::new_err(format!(
                "kind '{other}': expected 'binary' or 'ternary'"
            )))
        }
    };
    if polygons {
        let mut text = Vec::new();
        let table = TernaryTable::get();
        match kind {
            ConfigKind::Ternary => table.write_tsv(&mut text),
            ConfigKind::Binary => table.write_binary_tsv(&mut text),
        }
        .map_err(|e| Error::new_err(e.to_string()))?;
        let text = String::from_utf8(text).map_err(|e| Error::new_err(e.to_string()))?;
        return Ok(text.into_pyobject(py)?.into_any());
    }
    let table = ClassTable::get(kind, parse::<Group>(group)?);
    let entries = table.entries();
    let column = |f: &dyn Fn(&isocube::cube::ConfigEntry) -> i64| {
        PyArray1::from_vec(py, entries.iter().map(f).collect::<Vec<i64>>())
    };
    let d = PyDict::new(py);
    d.set_item(
        "config",
        PyArray1::from_vec(py, (0..entries.len() as i64).collect::<Vec<i64>>()),
    )?;
    d.set_item("representative", column(&|e| i64::from(e.representative)))?;
    d.set_item("class", column(&|e| i64::from(e.class)))?;
    d.set_item("orbit_size", column(&|e| i64::from(e.orbit_size)))?;
    d.set_item("flip_class", column(&|e| i64::from(e.flip_class)))?;
    let perms: Vec<[u8; 8]> = entries.iter().map(|e| e.perm()).collect();
    let n = perms.len();
    let flat: Vec<u8> = perms.into_iter().flatten().collect();
    d.set_item("perm", PyArray1::from_vec(py, flat).reshape([n, 8])?)?;
    d.set_item(
        "flipped",
        PyArray1::from_vec(
            py,
            entries
                .iter()
                .map(|e| e.transform.flip)
                .collect::<Vec<bool>>(),
        ),
    )?;
    d.set_item(
        "reversed",
        PyArray1::from_vec(
            py,
            entries
                .iter()
                .map(|e| e.transform.reverses_winding())
                .collect::<Vec<bool>>(),
        ),
    )?;
    Ok(d.into_any())
}
