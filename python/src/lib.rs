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
    extract_into, ExtractError, ExtractOptions, ExtractStats, Method, SnapPosition, Snapping,
};
use isocube::field::GridView;
use isocube::mesh::Mesh;
use numpy::{PyArray1, PyArray2, PyArrayMethods, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyKeyboardInterrupt, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;

create_exception!(
    _isocube,
    Error,
    PyException,
    "Base class of isocube's errors."
);
create_exception!(
    _isocube,
    InputError,
    Error,
    "The input cannot be meshed as given (a bad option, a value out of range)."
);
create_exception!(
    _isocube,
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

/// A `(n, 3)` array owning `rows`' buffer.
fn rows_array<'py, T: numpy::Element + Copy>(
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

fn extract_error(e: ExtractError) -> PyErr {
    match e {
        ExtractError::MemoryLimit { .. } | ExtractError::MeshMemory { .. } => {
            MemoryLimitError::new_err(e.to_string())
        }
        e => InputError::new_err(e.to_string()),
    }
}

fn stats_dict<'py>(py: Python<'py>, stats: &ExtractStats) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
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

/// The largest value among the grid points of the cells around each vertex (the four cells
/// around its edge; for a vertex inside a cell, that cell's corners): as scikit-image's
/// `values`, the largest corner value of the cubes that make the vertex (a colour scale's
/// input, not an interpolation).
fn vertex_values(grid: &GridView, positions: &[[f32; 3]]) -> Vec<f32> {
    let (origin, spacing, dims) = (grid.origin(), grid.spacing(), grid.dims());
    positions
        .iter()
        .map(|p| {
            let mut range = [[0usize; 2]; 3];
            for a in 0..3 {
                let q = (f64::from(p[a]) - origin[a]) / spacing[a];
                let near = q.round();
                // A coordinate within rounding of a grid plane lies on it: the cells on both
                // sides of the plane hold the vertex.
                let (lo, hi) = if (q - near).abs() < 1e-4 {
                    (near - 1.0, near + 1.0)
                } else {
                    (q.floor(), q.ceil())
                };
                let clamp = |x: f64| (x.max(0.0) as usize).min(dims[a] - 1);
                range[a] = [clamp(lo), clamp(hi)];
            }
            let mut best = f32::NEG_INFINITY;
            for k in range[2][0]..=range[2][1] {
                for j in range[1][0]..=range[1][1] {
                    for i in range[0][0]..=range[0][1] {
                        best = best.max(grid.value(i, j, k));
                    }
                }
            }
            best
        })
        .collect()
}

/// Extracts the isosurface of a `float32` volume indexed `volume[x, y, z]` (any positive
/// strides). Vertices come in the array's index order, scaled by `spacing`, moved by `origin`;
/// triangles face away from the side below the level (towards it with `flip`).
#[pyfunction]
#[pyo3(signature = (
    volume, level, *, spacing, origin, method, topology, triangulate, snap, zero_threshold,
    snap_position, flip, normals, values, max_memory
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
) -> PyResult<Extracted<'py>> {
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
    let grid = GridView::strided(samples, dims, strides)
        .and_then(|g| g.with_spacing(spacing))
        .and_then(|g| g.with_origin(origin))
        .map_err(|e| InputError::new_err(e.to_string()))?;
    let method = match method {
        "mc" => Method::MarchingCubes,
        "ternary" => Method::Ternary(
            Snapping::default()
                .with_snap(snap)
                .with_zero_threshold(zero_threshold)
                .with_position(parse::<SnapPosition>(snap_position)?),
        ),
        other => {
            return Err(InputError::new_err(format!(
                "unknown method '{other}': expected mc or ternary"
            )))
        }
    };
    let options = ExtractOptions::default()
        .with_level(level)
        .with_flip(flip)
        .with_normals(normals)
        .with_topology(parse(topology)?)
        .with_triangulation(parse(triangulate)?)
        .with_method(method)
        .with_max_memory(max_memory);
    let mut mesh = Mesh::new();
    let mut interrupted: Option<PyErr> = None;
    let result = py.detach(|| {
        let mut last = Instant::now();
        let mut progress = |_: usize, _: usize| {
            if last.elapsed() < SIGNAL_CHECK {
                return ControlFlow::Continue(());
            }
            last = Instant::now();
            match Python::attach(|py| py.check_signals()) {
                Ok(()) => ControlFlow::Continue(()),
                Err(e) => {
                    interrupted = Some(e);
                    ControlFlow::Break(())
                }
            }
        };
        let stats = extract_into(grid, &options, &mut mesh, &mut progress)?;
        let values = values.then(|| vertex_values(&grid, &mesh.positions));
        Ok((stats, values))
    });
    let (stats, values) = match result {
        Ok(done) => done,
        Err(ExtractError::Cancelled) => {
            return Err(interrupted.unwrap_or_else(|| PyKeyboardInterrupt::new_err(())));
        }
        Err(e) => return Err(extract_error(e)),
    };
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
        stats_dict(py, &stats)?,
    ))
}

/// The extension module.
#[pymodule]
fn _isocube(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(extract, m)?)?;
    m.add("Error", m.py().get_type::<Error>())?;
    m.add("InputError", m.py().get_type::<InputError>())?;
    m.add("MemoryLimitError", m.py().get_type::<MemoryLimitError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
