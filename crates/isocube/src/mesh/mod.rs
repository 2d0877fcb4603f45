//! Indexed triangle meshes and the checks every test, the CLI and the reports share.
//!
//! [`Mesh`] is plain data: `[f32; 3]` positions, optional per-vertex normals of the same length,
//! and `[u32; 3]` triangles whose right-hand normal is the front. [`MeshReport`] measures what
//! matters for an isosurface: boundary and non-manifold edges, orientation, components, Euler
//! characteristic, genus, degenerate triangles and angle range.

pub(crate) mod intersect;
mod report;

pub use report::{EdgeReport, MeshReport};

/// Why a mesh's parts do not fit together ([`Mesh::validate`]).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum MeshError {
    /// Normals are given, but not one per vertex.
    #[error("{normals} normals for {vertices} vertices")]
    NormalCount {
        /// Normals given.
        normals: usize,
        /// Vertices.
        vertices: usize,
    },
    /// A triangle names a vertex that does not exist.
    #[error("triangle {triangle} {indices:?} indexes past {vertices} vertices")]
    VertexIndex {
        /// The triangle's place.
        triangle: usize,
        /// Its vertex numbers.
        indices: [u32; 3],
        /// Vertices.
        vertices: usize,
    },
}

/// An indexed triangle mesh.
///
/// Invariant: every index in `triangles` is below `positions.len()`, and `normals` is either
/// empty or as long as `positions`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    /// Vertex positions.
    pub positions: Vec<[f32; 3]>,
    /// Unit vertex normals, or empty.
    pub normals: Vec<[f32; 3]>,
    /// Triangles as vertex indices, counter-clockwise seen from the front.
    pub triangles: Vec<[u32; 3]>,
}

impl Mesh {
    /// An empty mesh.
    pub fn new() -> Mesh {
        Mesh::default()
    }

    /// Empties the mesh, keeping its allocations for reuse.
    pub fn clear(&mut self) {
        self.positions.clear();
        self.normals.clear();
        self.triangles.clear();
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// Whether the mesh has no triangles.
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    /// Reverses every triangle and negates the normals: front and back trade places.
    pub fn flip_orientation(&mut self) {
        for t in &mut self.triangles {
            t.swap(1, 2);
        }
        for n in &mut self.normals {
            *n = n.map(|c| -c);
        }
    }

    /// Checks the index invariant; `Err` names the first offending triangle.
    ///
    /// ```
    /// use isocube::mesh::{Mesh, MeshError};
    /// let mut mesh = Mesh::new();
    /// mesh.positions = vec![[0.0; 3]; 3];
    /// mesh.triangles = vec![[0, 1, 3]];
    /// assert_eq!(
    ///     mesh.validate(),
    ///     Err(MeshError::VertexIndex { triangle: 0, indices: [0, 1, 3], vertices: 3 })
    /// );
    /// ```
    pub fn validate(&self) -> Result<(), MeshError> {
        if !self.normals.is_empty() && self.normals.len() != self.positions.len() {
            return Err(MeshError::NormalCount {
                normals: self.normals.len(),
                vertices: self.positions.len(),
            });
        }
        let n = self.positions.len();
        for (i, t) in self.triangles.iter().enumerate() {
            if t.iter().any(|&v| v as usize >= n) {
                return Err(MeshError::VertexIndex {
                    triangle: i,
                    indices: *t,
                    vertices: n,
                });
            }
        }
        Ok(())
    }

    /// Area-weighted vertex normals from the triangles (replacing any present).
    pub fn compute_normals(&mut self) {
        let mut acc = vec![[0.0f64; 3]; self.positions.len()];
        for t in &self.triangles {
            let n = area_vector(t.map(|v| self.positions[v as usize]));
            for &v in t {
                for a in 0..3 {
                    acc[v as usize][a] += n[a];
                }
            }
        }
        self.normals = acc
            .into_iter()
            .map(|n| {
                let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
                if len > 0.0 {
                    n.map(|c| (c / len) as f32)
                } else {
                    [0.0; 3]
                }
            })
            .collect();
    }

    /// The normals with every zero one (a flat spot of the field, or averaged normals that
    /// cancel) replaced by the area-weighted normal of its triangles, or +z where those cancel
    /// too; `None` when no normal is zero (or there are none). Extraction does this last; a
    /// mesh joined from chunks ([`crate::extract::join`], [`crate::extract::merge_chunks`]) needs
    /// it to be [`crate::extract::extract`]'s.
    ///
    /// ```
    /// use isocube::mesh::Mesh;
    /// let mut mesh = Mesh::new();
    /// mesh.positions = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    /// mesh.normals = vec![[0.0, 0.0, 1.0], [0.0; 3], [0.0, 0.0, 1.0]];
    /// mesh.triangles = vec![[0, 1, 2]];
    /// assert_eq!(mesh.filled_normals().unwrap()[1], [0.0, 0.0, 1.0]);
    /// ```
    pub fn filled_normals(&self) -> Option<Vec<[f32; 3]>> {
        if self.normals.len() != self.positions.len() || !self.normals.contains(&[0.0; 3]) {
            return None;
        }
        let mut normals = self.normals.clone();
        let mut acc: Vec<[f64; 3]> = vec![[0.0; 3]; normals.len()];
        for t in &self.triangles {
            if t.iter().all(|&v| normals[v as usize] != [0.0; 3]) {
                continue;
            }
            let n = area_vector(t.map(|v| self.positions[v as usize]));
            for &v in t {
                for a in 0..3 {
                    acc[v as usize][a] += n[a];
                }
            }
        }
        for (n, a) in normals.iter_mut().zip(&acc) {
            if *n == [0.0; 3] {
                *n = unit_or_up(*a);
            }
        }
        Some(normals)
    }

    /// Axis-aligned bounds `(min, max)`, or `None` for no vertices.
    pub fn bounds(&self) -> Option<([f32; 3], [f32; 3])> {
        let mut it = self.positions.iter();
        let first = *it.next()?;
        Some(it.fold((first, first), |(lo, hi), p| {
            (
                [0, 1, 2].map(|a| lo[a].min(p[a])),
                [0, 1, 2].map(|a| hi[a].max(p[a])),
            )
        }))
    }

    /// The topology and quality report.
    pub fn report(&self) -> MeshReport {
        MeshReport::of(self)
    }

    /// Whether the mesh is closed and oriented, without the rest of [`Mesh::report`].
    pub fn edge_report(&self) -> EdgeReport {
        EdgeReport::of(self)
    }
}

/// `a − b`.
///
/// ```
/// use isocube::mesh::{cross, dot, sub};
/// let n = cross(sub([1.0, 0.0, 0.0], [0.0; 3]), sub([0.0, 1.0, 0.0], [0.0; 3]));
/// assert_eq!((n, dot(n, n)), ([0.0, 0.0, 1.0], 1.0));
/// ```
pub fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// Twice the area of triangle `p` along its normal: what [`Mesh::filled_normals`] sums.
pub(crate) fn area_vector(p: [[f32; 3]; 3]) -> [f64; 3] {
    let p = p.map(|q| q.map(f64::from));
    cross(sub(p[1], p[0]), sub(p[2], p[0]))
}

/// A sum of [`area_vector`]s made a unit normal, or +z when they cancel.
pub(crate) fn unit_or_up(a: [f64; 3]) -> [f32; 3] {
    let len = dot(a, a).sqrt();
    if len > 0.0 && len.is_finite() {
        a.map(|c| (c / len) as f32)
    } else {
        [0.0, 0.0, 1.0]
    }
}

/// The cross product `a × b` (see [`sub`] for an example).
pub fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// The dot product `a · b` (see [`sub`] for an example).
pub fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The three angles of triangle `p` in degrees (at `p[0]`, `p[1]`, `p[2]`), or `None` when it
/// has zero area: the one angle measure of every report.
///
/// ```
/// let a = isocube::mesh::triangle_angles([[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]).unwrap();
/// assert!((a[0] - 90.0).abs() < 1e-12 && (a[1] - 45.0).abs() < 1e-12);
/// ```
pub fn triangle_angles(p: [[f64; 3]; 3]) -> Option<[f64; 3]> {
    let n = cross(sub(p[1], p[0]), sub(p[2], p[0]));
    if dot(n, n) == 0.0 {
        return None;
    }
    Some(std::array::from_fn(|k| {
        let a = sub(p[(k + 1) % 3], p[k]);
        let b = sub(p[(k + 2) % 3], p[k]);
        let c = cross(a, b);
        dot(c, c).sqrt().atan2(dot(a, b)).to_degrees()
    }))
}
