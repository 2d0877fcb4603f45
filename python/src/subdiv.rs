//! `isocube.subdivide` and `isocube.PolyMesh`: polygon cages with creases, corners, holes and
//! faces with inner loops, refined by Catmull–Clark as OpenSubdiv defines it.

use std::path::PathBuf;

use isocube::mesh::Mesh;
use isocube::subdiv::{
    limit_positions, samples, subdivide, BoundaryRule, Face, HoleMethod, PolyMesh, SubdivError,
    SubdivOptions,
};
use numpy::{PyArray1, PyArray2, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::{rows_array, FormatError, InputError, MemoryLimitError};

/// A polygon mesh with its tags, never changed once made.
#[pyclass(module = "isocube._isocube", name = "PolyMesh", frozen)]
pub(crate) struct PyPolyMesh {
    mesh: PolyMesh,
}

fn subdiv_error(e: SubdivError) -> PyErr {
    match e {
        e @ SubdivError::TooManyFaces { .. } => MemoryLimitError::new_err(e.to_string()),
        e => InputError::new_err(e.to_string()),
    }
}

fn boundary_rule(name: &str) -> PyResult<BoundaryRule> {
    match name {
        "edge-only" => Ok(BoundaryRule::EdgeOnly),
        "edge-and-corner" => Ok(BoundaryRule::EdgeAndCorner),
        "none" => Ok(BoundaryRule::None),
        other => Err(InputError::new_err(format!(
            "boundary '{other}': expected 'edge-only', 'edge-and-corner' or 'none'"
        ))),
    }
}

fn boundary_name(rule: BoundaryRule) -> &'static str {
    match rule {
        BoundaryRule::EdgeOnly => "edge-only",
        BoundaryRule::EdgeAndCorner => "edge-and-corner",
        BoundaryRule::None => "none",
    }
}

/// A triangle mesh's arrays: vertices, triangles.
type Triangles<'py> = (Bound<'py, PyArray2<f32>>, Bound<'py, PyArray2<u32>>);

#[pymethods]
impl PyPolyMesh {
    /// Vertex positions, `(V, 3)` `float64` (a copy).
    #[getter]
    fn vertices<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        rows_array(py, self.mesh.positions.clone())
    }

    /// The faces' outer loops as `(offsets, indices)`: face `f` is
    /// `indices[offsets[f]:offsets[f + 1]]`.
    #[getter]
    fn faces<'py>(
        &self,
        py: Python<'py>,
    ) -> (Bound<'py, PyArray1<u64>>, Bound<'py, PyArray1<u32>>) {
        let mut offsets = Vec::with_capacity(self.mesh.faces.len() + 1);
        let mut indices = Vec::new();
        offsets.push(0u64);
        for face in &self.mesh.faces {
            indices.extend_from_slice(&face.outer);
            offsets.push(indices.len() as u64);
        }
        (
            PyArray1::from_vec(py, offsets),
            PyArray1::from_vec(py, indices),
        )
    }

    /// Inner loops (holes in faces): face index → its loops.
    #[getter]
    fn inner_loops(&self) -> Vec<(usize, Vec<Vec<u32>>)> {
        self.mesh
            .faces
            .iter()
            .enumerate()
            .filter(|(_, f)| !f.inner.is_empty())
            .map(|(i, f)| (i, f.inner.clone()))
            .collect()
    }

    /// Edge sharpness: `(a, b)` with `a < b` → sharpness (10 and above: infinitely sharp).
    #[getter]
    fn creases(&self) -> Vec<((u32, u32), f32)> {
        self.mesh.creases.iter().map(|(&k, &s)| (k, s)).collect()
    }

    /// Vertex corner sharpness.
    #[getter]
    fn corners(&self) -> Vec<(u32, f32)> {
        self.mesh.corners.iter().map(|(&v, &s)| (v, s)).collect()
    }

    /// The faces tagged as holes.
    #[getter]
    fn holes(&self) -> Vec<usize> {
        (0..self.mesh.faces.len())
            .filter(|&f| self.mesh.is_hole(f))
            .collect()
    }

    /// The boundary rule the mesh carries, if any.
    #[getter]
    fn boundary(&self) -> Option<&'static str> {
        self.mesh.boundary.map(boundary_name)
    }

    /// `levels` of Catmull–Clark refinement (then, with `limit`, every vertex moved to its
    /// limit position), as `isocube subdivide` does.
    #[pyo3(signature = (levels, *, holes, boundary, limit))]
    fn subdivide(
        &self,
        py: Python<'_>,
        levels: usize,
        holes: &str,
        boundary: Option<&str>,
        limit: bool,
    ) -> PyResult<PyPolyMesh> {
        let mut options = SubdivOptions::default();
        options.boundary = boundary.map(boundary_rule).transpose()?;
        options.holes = match holes {
            "smooth" => HoleMethod::Smooth,
            "sharp" => HoleMethod::Sharp,
            other => {
                return Err(InputError::new_err(format!(
                    "holes '{other}': expected 'smooth' or 'sharp'"
                )))
            }
        };
        let fine = py.detach(|| {
            let mut fine = subdivide(&self.mesh, levels, &options)?;
            if limit {
                if let Some(b) = options.boundary {
                    fine.boundary = Some(b);
                }
                fine.positions = limit_positions(&fine)?;
            }
            Ok(fine)
        });
        Ok(PyPolyMesh {
            mesh: fine.map_err(subdiv_error)?,
        })
    }

    /// The faces split into triangles (the form `.ply` and `.stl` files get).
    fn triangulate<'py>(&self, py: Python<'py>) -> PyResult<Triangles<'py>> {
        let Mesh {
            positions,
            triangles,
            ..
        } = self.mesh.triangulate().map_err(subdiv_error)?;
        Ok((rows_array(py, positions)?, rows_array(py, triangles)?))
    }

    /// The mesh as OBJ text with its tags (OpenSubdiv's `t crease`, `t corner`, `t hole`,
    /// `t interpolateboundary`, isocube's `t innerloop`).
    fn to_obj(&self) -> String {
        self.mesh.to_obj()
    }

    /// Writes `.obj` (polygons and tags) or a triangle format (`.ply`, `.stl`, ...), as
    /// `isocube subdivide` writes it, atomically.
    #[pyo3(signature = (path, *, ascii = false))]
    fn save(&self, py: Python<'_>, path: PathBuf, ascii: bool) -> PyResult<()> {
        let mut options = isocube_io::MeshWriteOptions::default();
        options.ascii = ascii;
        options.normals = true;
        py.detach(|| isocube_io::write_poly_mesh(&path, &self.mesh, &options))
            .map_err(|e| FormatError::new_err(e.to_string()))
    }

    /// Counts: vertices, faces, and faces by number of sides.
    fn stats<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        d.set_item("vertices", self.mesh.positions.len())?;
        d.set_item("faces", self.mesh.faces.len())?;
        let quads = self
            .mesh
            .faces
            .iter()
            .filter(|f| f.outer.len() == 4)
            .count();
        d.set_item("quads", quads)?;
        d.set_item("creases", self.mesh.creases.len())?;
        d.set_item("corners", self.mesh.corners.len())?;
        Ok(d)
    }
}

/// A polygon mesh from arrays: positions, faces (outer loops), inner loops per face, edge and
/// vertex sharpness, hole faces and a boundary rule; validated (every index in range, loops of
/// at least 3 distinct vertices, tags on existing edges and vertices).
#[pyfunction(name = "poly_mesh")]
#[pyo3(signature = (vertices, faces, *, inner_loops, creases, corners, holes, boundary))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn poly_mesh(
    vertices: PyReadonlyArray2<'_, f64>,
    faces: Vec<Vec<u32>>,
    inner_loops: Vec<(usize, Vec<Vec<u32>>)>,
    creases: Vec<((u32, u32), f32)>,
    corners: Vec<(u32, f32)>,
    holes: Vec<usize>,
    boundary: Option<&str>,
) -> PyResult<PyPolyMesh> {
    if vertices.shape()[1] != 3 {
        return Err(InputError::new_err(format!(
            "vertices: expected an (n, 3) array, not {:?}",
            vertices.shape()
        )));
    }
    let positions: Vec<[f64; 3]> = vertices
        .as_array()
        .rows()
        .into_iter()
        .map(|p| [p[0], p[1], p[2]])
        .collect();
    if let Some(i) = positions
        .iter()
        .position(|p| p.iter().any(|c| !c.is_finite()))
    {
        return Err(InputError::new_err(format!("vertex {i} is not finite")));
    }
    let mut mesh = PolyMesh {
        positions,
        faces: faces.into_iter().map(Face::new).collect(),
        boundary: boundary.map(boundary_rule).transpose()?,
        ..PolyMesh::default()
    };
    let face_count = mesh.faces.len();
    for (f, loops) in inner_loops {
        let face = mesh.faces.get_mut(f).ok_or_else(|| {
            InputError::new_err(format!(
                "inner loops of face {f}: there are {face_count} faces"
            ))
        })?;
        face.inner = loops;
    }
    mesh.holes = vec![false; face_count];
    for f in holes {
        *mesh.holes.get_mut(f).ok_or_else(|| {
            InputError::new_err(format!("hole face {f}: there are {face_count} faces"))
        })? = true;
    }
    for ((a, b), s) in creases {
        if !(s.is_finite() && s >= 0.0) {
            return Err(InputError::new_err(format!(
                "crease ({a}, {b}): sharpness {s} is not a number ≥ 0"
            )));
        }
        mesh.set_crease(a, b, s);
    }
    for (v, s) in corners {
        if !(s.is_finite() && s >= 0.0) {
            return Err(InputError::new_err(format!(
                "corner {v}: sharpness {s} is not a number ≥ 0"
            )));
        }
        mesh.corners.insert(v, s);
    }
    mesh.validate().map_err(subdiv_error)?;
    Ok(PyPolyMesh { mesh })
}

/// A cage from a file (`.obj` with tags, or a triangle mesh `.ply`/`.stl`/...) or a built-in
/// one (`sample:cube|plate|box-hole|boss`).
#[pyfunction(name = "poly_read")]
pub(crate) fn read(path: &str) -> PyResult<PyPolyMesh> {
    let mesh = match path.strip_prefix("sample:") {
        Some(name) => samples::sample(name).ok_or_else(|| {
            InputError::new_err(format!(
                "unknown sample cage '{name}' (expected one of {})",
                samples::SAMPLES.join(", ")
            ))
        })?,
        None => isocube_io::read_poly_mesh(std::path::Path::new(path))
            .map_err(|e| FormatError::new_err(e.to_string()))?,
    };
    Ok(PyPolyMesh { mesh })
}
