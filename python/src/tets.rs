//! `isocube.tetmesh`: tetrahedra of the region inside the surface (or of each label), from a
//! NumPy array, kept in Rust and shown to Python as read-only arrays over its buffers.

use std::path::PathBuf;
use std::time::Instant;

use isocube::extract::ExtractOptions;
use isocube::extract::{ExtractError, LabelOptions, LabelSelection};
use isocube::field::Orientation;
use isocube::volume::{
    snap_detail, tetmesh_labels, tetmesh_with_progress, Grading, TetError, TetMesh,
};
use isocube_io::TetFormat;
use numpy::ndarray::ArrayView2;
use numpy::{PyArray1, PyArray2, PyReadonlyArray3};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::{
    direction_of, extract_error, index_order_view, interruptible, method_of, surface_options,
    view_of, Error, FormatError, InputError, MemoryLimitError,
};

/// A tetrahedral mesh made by [`tetmesh`]; never changed after it is made (`frozen`), so the
/// arrays Python sees over its buffers stay valid and true.
#[pyclass(module = "isocube._isocube", name = "TetMesh", frozen)]
pub(crate) struct PyTetMesh {
    mesh: TetMesh,
    seconds: f64,
    /// The grid's cell width (its smallest spacing) and the surface detail, in cells, the
    /// elements outside the dihedral range are weighed against ([`TetMesh::poor_elements`]).
    cell: f64,
    detail: f64,
}

/// A read-only `(n, N)` array over `rows`, which `owner` holds: no copy.
fn borrowed<'py, T: numpy::Element, const N: usize>(
    owner: &Bound<'py, PyTetMesh>,
    rows: &[[T; N]],
) -> PyResult<Bound<'py, PyArray2<T>>> {
    let view = ArrayView2::from_shape((rows.len(), N), rows.as_flattened())
        .expect("a row of N elements per item");
    // SAFETY: the array reads the mesh's buffers, which the frozen object never changes nor
    // moves, and which live as long as the object the array keeps as its base.
    let array = unsafe { PyArray2::borrow_from_array(&view, owner.clone().into_any()) };
    array.getattr("flags")?.setattr("writeable", false)?;
    Ok(array)
}

/// A read-only `(n,)` array over `items`, which `owner` holds.
fn borrowed_1d<'py>(
    owner: &Bound<'py, PyTetMesh>,
    items: &[u32],
) -> PyResult<Bound<'py, PyArray1<u32>>> {
    let view = numpy::ndarray::ArrayView1::from(items);
    // SAFETY: as in `borrowed`.
    let array = unsafe { PyArray1::borrow_from_array(&view, owner.clone().into_any()) };
    array.getattr("flags")?.setattr("writeable", false)?;
    Ok(array)
}

impl PyTetMesh {
    pub(crate) fn new(mesh: TetMesh, seconds: f64, cell: f64, detail: f64) -> PyTetMesh {
        PyTetMesh {
            mesh,
            seconds,
            cell,
            detail,
        }
    }
}

#[pymethods]
impl PyTetMesh {
    /// Vertex positions, `(V, 3)` `float32`: the surface's vertices first, then grid points
    /// inside the region, then Steiner points.
    #[getter]
    fn vertices<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        borrowed(slf, &slf.get().mesh.positions)
    }

    /// Tetrahedra, `(T, 4)` `uint32`, each positively oriented.
    #[getter]
    fn tets<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyArray2<u32>>> {
        borrowed(slf, &slf.get().mesh.tets)
    }

    /// The isosurface's triangles, `(F, 3)`, facing out of the region.
    #[getter]
    fn surface<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyArray2<u32>>> {
        borrowed(slf, &slf.get().mesh.surface)
    }

    /// Boundary triangles on the grid's outer faces, `(W, 3)`, facing out.
    #[getter]
    fn walls<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyArray2<u32>>> {
        borrowed(slf, &slf.get().mesh.walls)
    }

    /// Surface triangles bounding no tetrahedron (in an outer face of the grid).
    #[getter]
    fn beyond<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyArray1<u32>>> {
        borrowed_1d(slf, &slf.get().mesh.beyond)
    }

    /// How many of the first vertices are the surface's.
    #[getter]
    fn surface_vertices(&self) -> usize {
        self.mesh.surface_vertices
    }

    /// Multi-material meshes: (label names, each tetrahedron's label index, each surface
    /// triangle's label index, interface triangles, the label pair of each interface).
    #[getter]
    #[allow(clippy::type_complexity)]
    fn labels<'py>(
        slf: &Bound<'py, Self>,
    ) -> PyResult<
        Option<(
            Vec<i64>,
            Bound<'py, PyArray1<u32>>,
            Bound<'py, PyArray1<u32>>,
            Bound<'py, PyArray2<u32>>,
            Bound<'py, PyArray2<u32>>,
        )>,
    > {
        let Some(labels) = &slf.get().mesh.labels else {
            return Ok(None);
        };
        Ok(Some((
            labels.names.clone(),
            borrowed_1d(slf, &labels.tets)?,
            borrowed_1d(slf, &labels.surface)?,
            borrowed(slf, &labels.interfaces)?,
            borrowed(slf, &labels.pairs)?,
        )))
    }

    /// Counts: cells cut into lattice tetrahedra or filled around the surface, grid and
    /// Steiner points, the improvement's work, the surface extraction's counts, `seconds`.
    #[getter]
    fn stats<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let s = &self.mesh.stats;
        let d = crate::stats_dict(py, &s.extract, self.seconds)?;
        d.set_item("lattice_cells", s.lattice_cells)?;
        d.set_item("cut_cells", s.cut_cells)?;
        d.set_item("cubes", s.cubes)?;
        d.set_item("largest_cube", s.largest_cube)?;
        d.set_item("cube_tets", s.cube_tets)?;
        d.set_item("cells_too_long", s.cells_too_long)?;
        d.set_item("grid_points", s.grid_points)?;
        d.set_item("steiner_points", s.steiner_points)?;
        d.set_item("poor_elements", s.improve.poor)?;
        d.set_item("flips_23", s.improve.flips_23)?;
        d.set_item("flips_32", s.improve.flips_32)?;
        d.set_item("edge_removals", s.improve.edge_removals)?;
        d.set_item("moved_points", s.improve.moves)?;
        d.set_item("inserted_points", s.improve.inserted)?;
        d.set_item("removed_points", s.improve.removed + s.improve.removed_grid)?;
        d.set_item("widened", s.improve.widened)?;
        Ok(d)
    }

    /// Element quality (see `isocube quality`): dihedral angles in degrees, radius ratios,
    /// and the elements outside [10°, 165°] sorted as `isocube tetmesh` sorts them.
    fn quality<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let (r, poor) = py.detach(|| {
            (
                self.mesh.quality_report(),
                self.mesh.poor_elements(self.cell, self.detail),
            )
        });
        let d = PyDict::new(py);
        d.set_item("outside_range", poor.count)?;
        d.set_item("at_sharp_edges", poor.at_sharp_edges)?;
        d.set_item("beside_fine_detail", poor.beside_fine_detail)?;
        d.set_item("others", poor.others)?;
        d.set_item("tets", r.tets)?;
        d.set_item("min_dihedral", r.min_dihedral)?;
        d.set_item("max_dihedral", r.max_dihedral)?;
        d.set_item("mean_radius_ratio", r.mean_radius_ratio)?;
        d.set_item("max_radius_ratio", r.max_radius_ratio)?;
        d.set_item("min_dihedral_histogram", r.min_dihedral_histogram.to_vec())?;
        Ok(d)
    }

    /// The mesh checked: conforming (every inner face shared by two elements, the boundary
    /// the surface and walls), inverted and flat elements, the volume and the volume the
    /// boundary encloses.
    fn check<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let c = py.detach(|| self.mesh.check());
        let d = PyDict::new(py);
        d.set_item("conforming", c.conforming)?;
        d.set_item("bad_faces", c.bad_faces)?;
        d.set_item("boundary_mismatch", c.boundary_mismatch)?;
        d.set_item("inverted", c.inverted)?;
        d.set_item("flat", c.flat)?;
        d.set_item("unused", c.unused)?;
        d.set_item("volume", c.volume)?;
        d.set_item("enclosed", c.enclosed)?;
        Ok(d)
    }

    /// Writes the mesh as `isocube tetmesh` does (`.msh` — binary with `binary` —, `.vtu`
    /// with each element's quality, `.mesh`, `.inp`), atomically: the same bytes.
    #[pyo3(signature = (path, *, binary = false))]
    fn save(&self, py: Python<'_>, path: PathBuf, binary: bool) -> PyResult<()> {
        let format = match (TetFormat::from_path(&path), binary) {
            (None, _) => {
                return Err(InputError::new_err(format!(
                    "{}: unknown tetrahedral mesh extension (expected .msh, .vtu, .mesh or .inp)",
                    path.display()
                )))
            }
            (Some(TetFormat::Medit | TetFormat::Inp), true) => {
                return Err(InputError::new_err(format!(
                    "binary: {} is written as text (binary: .msh or .vtu)",
                    path.display()
                )))
            }
            (Some(TetFormat::Msh), true) => TetFormat::MshBinary,
            (Some(format), _) => format,
        };
        py.detach(|| {
            let qualities = (format == TetFormat::Vtu).then(|| self.mesh.quality_columns().0);
            isocube_io::write_tet_mesh_as(&path, format, &self.mesh, qualities.as_ref())
        })
        .map_err(|e| FormatError::new_err(e.to_string()))
    }
}

pub(crate) fn tet_error(e: TetError) -> PyErr {
    match e {
        TetError::Extract(e) => extract_error(e),
        e @ (TetError::Memory { .. } | TetError::TooManyVertices) => {
            MemoryLimitError::new_err(e.to_string())
        }
        e @ TetError::Cell { .. } => Error::new_err(e.to_string()),
        e => InputError::new_err(e.to_string()),
    }
}

/// Tetrahedra of the region below the level (above it with `flip`) of a `float32` volume
/// indexed `volume[x, y, z]`, any positive strides, or of each label (`labels`; `only` picks
/// some): as `isocube tetmesh` meshes the array saved as `.npy`.
#[pyfunction]
#[pyo3(signature = (
    volume, level, *, spacing, origin, direction, method, topology, triangulate, snap,
    zero_threshold, snap_position, flip, labels, only, background, max_memory, max_size=None,
    max_size_cells=false, grading=0, uniform=false, progress=None
))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn tetmesh(
    py: Python<'_>,
    volume: PyReadonlyArray3<'_, f32>,
    level: f32,
    spacing: [f64; 3],
    origin: [f64; 3],
    direction: Option<[[f64; 3]; 3]>,
    method: &str,
    topology: &str,
    triangulate: &str,
    snap: f32,
    zero_threshold: f32,
    snap_position: &str,
    flip: bool,
    labels: bool,
    only: Option<Vec<i64>>,
    background: i64,
    max_memory: Option<u64>,
    max_size: Option<f64>,
    max_size_cells: bool,
    grading: u8,
    uniform: bool,
    progress: Option<Py<PyAny>>,
) -> PyResult<PyTetMesh> {
    let direction = direction_of(direction)?;
    let started = Instant::now();
    let cell = spacing
        .into_iter()
        .map(f64::abs)
        .fold(f64::INFINITY, f64::min);
    let grading = match max_size {
        None if uniform => Grading::UNIFORM,
        None => Grading {
            layers: grading,
            ..Grading::DEFAULT
        },
        Some(_) if uniform => {
            return Err(InputError::new_err(
                "max_size and uniform: a uniform interior has no largest size",
            ))
        }
        Some(size) if !(size.is_finite() && size > 0.0) => {
            return Err(InputError::new_err(format!(
                "max_size {size}: expected a size > 0"
            )))
        }
        Some(size) => Grading::within(if max_size_cells { size } else { size / cell }, grading),
    };
    let mut detail = snap_detail(&ExtractOptions::default());
    let meshed = if labels {
        // Labels are meshed in the array's index order, as the command line reads a file's.
        let mut grid = index_order_view(&volume, spacing, origin)?;
        if let Some(d) = direction {
            grid = grid.with_orientation(d);
        }
        let mut options = LabelOptions::default()
            .with_smoothing(0)
            .with_background(background)
            .with_grading(grading);
        if let Some(list) = only {
            options = options.with_labels(LabelSelection::Only(list));
        }
        py.detach(|| tetmesh_labels(grid, &options, max_memory))
    } else {
        let (grid, order) = view_of(&volume, spacing, origin)?;
        // The grid's axes are the array's in memory order; a direction turns the array's.
        let grid = match direction {
            None => grid,
            Some(d) => {
                let m = d.direction();
                let turned = std::array::from_fn(|r| std::array::from_fn(|a| m[r][order[a]]));
                grid.with_orientation(Orientation::new(turned).expect("a turn of the axes"))
            }
        };
        let options = surface_options(
            level,
            flip,
            topology,
            triangulate,
            method_of(method, snap, zero_threshold, snap_position)?,
            max_memory,
        )?
        .with_normals(false)
        .with_grading(grading);
        detail = snap_detail(&options);
        interruptible(
            py,
            progress,
            |e| matches!(e, TetError::Extract(ExtractError::Cancelled)),
            |report| tetmesh_with_progress(grid, &options, report),
        )?
    };
    let mesh = meshed.map_err(tet_error)?;
    Ok(PyTetMesh::new(
        mesh,
        started.elapsed().as_secs_f64(),
        cell,
        detail,
    ))
}
