//! `isocube.contours`: surfaces and volume meshes through stacks of cross-section contours,
//! from NumPy point arrays or contour files, as `isocube contours` and `isocube tetmesh` make
//! them.

use std::time::Instant;

use isocube::contours::{
    reconstruct_with, tetmesh as mesh_body, Cap, Fidelity, PlaneGrid, ReconstructOptions,
    SectionStack,
};
use isocube::extract::{ExtractError, ExtractOptions};
use isocube::mesh::Mesh;
use numpy::{PyArray2, PyArrayMethods, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::tets::{tet_error, PyTetMesh};
use crate::{extract_error, method_of, parse, rows_array, FormatError, InputError};

/// A stack given as sections `(z, [contour, ...])`, each contour an `(n, 2)` array of
/// `float64` points (closed implicitly: the last point joins the first).
type Sections<'py> = Vec<(f64, Vec<PyReadonlyArray2<'py, f64>>)>;

/// The stack: read from `path` (`.csv`, `.json`, `.dxf`, open DXF polylines closed if `close`;
/// `sample:orebody`), or built from `sections`, validated either way (errors name the section
/// and contour).
fn stack_of(
    path: Option<&str>,
    sections: Option<Sections<'_>>,
    close: bool,
) -> PyResult<SectionStack> {
    match (path, sections) {
        (Some("sample:orebody"), _) => Ok(SectionStack::sample_orebody()),
        (Some(path), _) => {
            let options = isocube_io::ContourOptions::default().with_close(close);
            isocube_io::read_contours_with(std::path::Path::new(path), &options)
                .map(|r| r.stack)
                .map_err(|e| FormatError::new_err(e.to_string()))
        }
        (None, Some(sections)) => {
            let mut points = Vec::with_capacity(sections.len());
            for (s, (z, contours)) in sections.into_iter().enumerate() {
                let mut section = Vec::with_capacity(contours.len());
                for (c, contour) in contours.iter().enumerate() {
                    if contour.shape()[1] != 2 {
                        return Err(InputError::new_err(format!(
                            "section {s}, contour {c}: expected an (n, 2) array of points, not \
                             {:?}",
                            contour.shape()
                        )));
                    }
                    let array = contour.as_array();
                    section.push(array.rows().into_iter().map(|p| [p[0], p[1]]).collect());
                }
                points.push((z, section));
            }
            SectionStack::from_points(points).map_err(|e| InputError::new_err(e.to_string()))
        }
        (None, None) => Err(InputError::new_err("no sections given")),
    }
}

/// The plane grid: square cells of side `cell`, or at most `grid` cells per axis, or 100
/// across the longer side; refused when too large to index.
fn plane_of(
    stack: &SectionStack,
    cell: Option<f64>,
    grid: Option<[usize; 2]>,
) -> PyResult<PlaneGrid> {
    let plane = match (cell, grid) {
        (Some(c), _) if c.is_finite() && c > 0.0 => PlaneGrid::with_cell(stack, c),
        (Some(c), _) => {
            return Err(InputError::new_err(format!(
                "cell {c}: expected a size > 0"
            )))
        }
        (None, Some(counts)) if counts.iter().all(|&n| (1..=1 << 16).contains(&n)) => {
            PlaneGrid::with_counts(stack, counts)
        }
        (None, Some(counts)) => {
            return Err(InputError::new_err(format!(
                "grid {counts:?}: expected cell counts between 1 and 65536"
            )))
        }
        (None, None) => PlaneGrid::across(stack, 100),
    };
    if !plane.indexable(stack.sections().len()) {
        return Err(InputError::new_err(format!(
            "the plane grid would be {}×{} points over {} sections; use a coarser grid or a \
             larger cell",
            plane.dims[0],
            plane.dims[1],
            stack.sections().len()
        )));
    }
    Ok(plane)
}

/// The caps: `extend` (by `distance`, default half the mean section spacing), `flat` or
/// `none`.
fn cap_of(stack: &SectionStack, cap: &str, distance: Option<f64>) -> PyResult<Cap> {
    match (cap, distance) {
        ("extend", None) => Ok(Cap::extended(stack)),
        ("extend", Some(d)) if d.is_finite() && d > 0.0 => Ok(Cap::Extend(d)),
        ("extend", Some(d)) => Err(InputError::new_err(format!(
            "extend {d}: expected a distance > 0"
        ))),
        ("flat", None) => Ok(Cap::Flat),
        ("none", None) => Ok(Cap::Open),
        (other, None) => Err(InputError::new_err(format!(
            "cap '{other}': expected 'extend', 'flat' or 'none'"
        ))),
        (other, Some(_)) => Err(InputError::new_err(format!(
            "cap '{other}' takes no distance (only 'extend' does)"
        ))),
    }
}

/// A reconstruction's arrays: vertices, triangles, normals, and what it cost.
type Surface<'py> = (
    Bound<'py, PyArray2<f32>>,
    Bound<'py, PyArray2<u32>>,
    Bound<'py, PyArray2<f32>>,
    Bound<'py, PyDict>,
);

/// The surface through a stack's contours, as `isocube contours` makes it.
#[pyfunction(name = "contours_reconstruct")]
#[pyo3(signature = (
    path, sections, *, cell, grid, cap, extend, plain, triangulate, max_memory, close=false
))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn reconstruct<'py>(
    py: Python<'py>,
    path: Option<&str>,
    sections: Option<Sections<'py>>,
    cell: Option<f64>,
    grid: Option<[usize; 2]>,
    cap: &str,
    extend: Option<f64>,
    plain: bool,
    triangulate: &str,
    max_memory: Option<u64>,
    close: bool,
) -> PyResult<Surface<'py>> {
    let stack = stack_of(path, sections, close)?;
    let plane = plane_of(&stack, cell, grid)?;
    let mut options = ReconstructOptions::new(cap_of(&stack, cap, extend)?)
        .with_fidelity(if plain {
            Fidelity::Plain
        } else {
            Fidelity::Exact
        })
        .with_triangulation(parse(triangulate)?);
    if let Some(limit) = max_memory {
        options = options.with_max_memory(limit);
    }
    let started = Instant::now();
    let r = py
        .detach(|| reconstruct_with(&stack, &plane, &options))
        .map_err(|e| match e {
            e @ ExtractError::MemoryLimit { .. } => crate::MemoryLimitError::new_err(format!(
                "{e}; use a coarser grid or a larger cell (or raise max_memory)"
            )),
            e => extract_error(e),
        })?;
    let seconds = started.elapsed().as_secs_f64();
    let stats = PyDict::new(py);
    stats.set_item("seconds", seconds)?;
    stats.set_item("sections", stack.sections().len())?;
    stats.set_item("plane_dims", r.plane.dims.to_vec())?;
    stats.set_item("cell", r.plane.spacing)?;
    stats.set_item("evaluated", r.evaluated)?;
    stats.set_item("points", r.points)?;
    stats.set_item("active_cells", r.active_cells)?;
    stats.set_item("unresolved_edges", r.unresolved_edges)?;
    stats.set_item("missed_contours", r.missed_contours)?;
    let Mesh {
        positions,
        normals,
        triangles,
    } = r.mesh;
    Ok((
        rows_array(py, positions)?,
        rows_array(py, triangles)?,
        rows_array(py, normals)?,
        stats,
    ))
}

/// Tetrahedra of the body a stack's contours outline, as `isocube tetmesh` makes them.
#[pyfunction(name = "contours_tetmesh")]
#[pyo3(signature = (
    path, sections, *, cell, grid, cap, extend, layer_spacing, method, snap, zero_threshold,
    snap_position, triangulate, max_memory, close=false
))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn tetmesh(
    py: Python<'_>,
    path: Option<&str>,
    sections: Option<Sections<'_>>,
    cell: Option<f64>,
    grid: Option<[usize; 2]>,
    cap: &str,
    extend: Option<f64>,
    layer_spacing: Option<&str>,
    method: &str,
    snap: f32,
    zero_threshold: f32,
    snap_position: &str,
    triangulate: &str,
    max_memory: Option<u64>,
    close: bool,
) -> PyResult<PyTetMesh> {
    let stack = stack_of(path, sections, close)?;
    let plane = plane_of(&stack, cell, grid)?;
    let cap = cap_of(&stack, cap, extend)?;
    let layer_spacing = match layer_spacing {
        None => Some(plane.spacing),
        Some("sections") => None,
        Some(d) => match d.parse::<f64>() {
            Ok(v) if v.is_finite() && v > 0.0 => Some(v),
            _ => {
                return Err(InputError::new_err(format!(
                    "layer_spacing {d}: expected a distance > 0 or 'sections'"
                )))
            }
        },
    };
    let method = method_of(method, snap, zero_threshold, snap_position)?;
    let options = ExtractOptions::default()
        .with_normals(false)
        .with_triangulation(parse(triangulate)?)
        .with_max_memory(max_memory)
        .with_method(method);
    let started = Instant::now();
    let mesh = py
        .detach(|| mesh_body(&stack, &plane, cap, layer_spacing, &options))
        .map_err(tet_error)?;
    Ok(PyTetMesh::new(
        mesh,
        started.elapsed().as_secs_f64(),
        plane.spacing,
        isocube::volume::snap_detail(&options),
    ))
}

/// A stack's sections as Python sees them: `(z, [contour, ...])`.
type SectionArrays<'py> = Vec<(f64, Vec<Bound<'py, PyArray2<f64>>>)>;

/// A contour file's sections (`.csv`, `.json`, `.dxf`; `sample:orebody`): `(z, [contour,
/// ...])` with each contour an `(n, 2)` array of its points, validated as the command line
/// validates them.
#[pyfunction(name = "contours_read")]
#[pyo3(signature = (path, close=false))]
pub(crate) fn read<'py>(py: Python<'py>, path: &str, close: bool) -> PyResult<SectionArrays<'py>> {
    let stack = stack_of(Some(path), None, close)?;
    stack
        .sections()
        .iter()
        .map(|section| {
            let contours = section
                .contours()
                .iter()
                .map(|c| {
                    let n = c.points().len();
                    let flat: Vec<f64> = c.points().as_flattened().to_vec();
                    numpy::PyArray1::from_vec(py, flat).reshape([n, 2])
                })
                .collect::<PyResult<Vec<_>>>()?;
            Ok((section.z(), contours))
        })
        .collect()
}
