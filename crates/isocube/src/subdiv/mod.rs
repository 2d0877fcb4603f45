//! Polygon meshes with creases, corners, holes and faces with inner loops, and Catmull–Clark
//! subdivision as OpenSubdiv defines it.
//!
//! A [`PolyMesh`] holds faces of any number of sides; a face may have inner loops (a face with
//! holes, as boolean operations on solids produce). Edges carry sharpness (0 smooth, 10 or more
//! infinitely sharp, fractional values blend), vertices corner sharpness, faces a hole tag. The
//! boundary rule says how open boundaries behave ([`BoundaryRule`]).
//!
//! [`subdivide`] refines uniformly: OpenSubdiv's Catmark scheme with its uniform crease rule
//! (sharpness decreases by one per level, the rules blend where it becomes fractional); faces
//! with inner loops are first turned into ordinary faces by one of the two methods of the
//! solid-modelling paper ([`HoleMethod`]). [`limit_positions`] gives where the refined vertices
//! go in the limit.
//!
//! ```
//! use isocube::subdiv::{subdivide, PolyMesh, SubdivOptions};
//! let cube = PolyMesh::from_obj(
//!     "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n\
//!      f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n",
//! )
//! .unwrap();
//! let fine = subdivide(&cube, 2, &SubdivOptions::default()).unwrap();
//! assert_eq!((fine.positions.len(), fine.faces.len()), (98, 96));
//! ```

mod catmark;
mod holes;
mod obj;
pub mod samples;

pub use catmark::{limit_positions, refine, subdivide};
pub use holes::HoleMethod;

use std::collections::BTreeMap;

use thiserror::Error;

use crate::mesh::Mesh;

/// Sharpness at or above which an edge or vertex is infinitely sharp (OpenSubdiv's convention).
pub const INFINITELY_SHARP: f32 = 10.0;

/// How open boundaries are refined (OpenSubdiv's `interpolateboundary`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum BoundaryRule {
    /// Boundaries are not interpolated: faces touching the boundary become holes.
    None,
    /// Boundary edges are sharp creases; the surface follows the boundary curve (default, as in
    /// OpenSubdiv's regression suite).
    #[default]
    EdgeOnly,
    /// As `EdgeOnly`, and boundary vertices with a single face are sharp corners.
    EdgeAndCorner,
}

impl BoundaryRule {
    /// The rule's OpenSubdiv tag value (0 none, 1 edge-and-corner, 2 edge-only).
    pub fn tag(self) -> u32 {
        match self {
            BoundaryRule::None => 0,
            BoundaryRule::EdgeAndCorner => 1,
            BoundaryRule::EdgeOnly => 2,
        }
    }
}

/// A face: an outer loop of vertex indices, counter-clockwise seen from outside, and any inner
/// loops (holes in the face), clockwise.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Face {
    /// The outer loop.
    pub outer: Vec<u32>,
    /// Inner loops.
    pub inner: Vec<Vec<u32>>,
}

impl Face {
    /// A face without inner loops.
    pub fn new(outer: Vec<u32>) -> Face {
        Face {
            outer,
            inner: Vec::new(),
        }
    }
}

/// A polygon mesh with subdivision tags.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PolyMesh {
    /// Vertex positions.
    pub positions: Vec<[f64; 3]>,
    /// Faces.
    pub faces: Vec<Face>,
    /// Edge sharpness by vertex pair (smaller index first); edges not listed are smooth.
    pub creases: BTreeMap<(u32, u32), f32>,
    /// Corner sharpness by vertex.
    pub corners: BTreeMap<u32, f32>,
    /// Whether each face is a hole (same length as `faces`, or empty for none).
    pub holes: Vec<bool>,
    /// The boundary rule the mesh asks for (`None`: not stated; [`BoundaryRule::EdgeOnly`]
    /// applies).
    pub boundary: Option<BoundaryRule>,
}

/// Why a polygon mesh was rejected.
#[derive(Debug, Error, Clone, PartialEq)]
#[non_exhaustive]
pub enum SubdivError {
    /// A text line could not be read.
    #[error("line {line}: {reason}")]
    Parse {
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        reason: String,
    },
    /// A face refers to a vertex that does not exist, repeats one, or has fewer than 3.
    #[error("face {face}: {reason}")]
    Face {
        /// 0-based face index.
        face: usize,
        /// What is wrong.
        reason: String,
    },
    /// A tag refers to something that does not exist or is not supported.
    #[error("tag {tag}: {reason}")]
    Tag {
        /// The tag's name.
        tag: String,
        /// What is wrong.
        reason: String,
    },
    /// A face with inner loops could not be made into ordinary faces.
    #[error("face {face} with inner loops: {reason}")]
    Holes {
        /// 0-based face index.
        face: usize,
        /// What is wrong.
        reason: String,
    },
    /// The refined mesh would have more faces than [`MAX_FACES`].
    #[error(
        "{levels} levels make about {faces} faces; at most {} are supported",
        MAX_FACES
    )]
    TooManyFaces {
        /// The levels asked for.
        levels: usize,
        /// The faces they would make (saturating).
        faces: usize,
    },
}

/// The most faces [`subdivide`] makes: refinement multiplies faces by about 4 per level, and
/// beyond this many the output would not fit in memory anyway.
pub const MAX_FACES: usize = 1 << 28;

/// What [`subdivide`] is asked to do beyond the mesh's own tags.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[non_exhaustive]
pub struct SubdivOptions {
    /// Overrides the mesh's boundary rule.
    pub boundary: Option<BoundaryRule>,
    /// How faces with inner loops are handled.
    pub holes: HoleMethod,
}

impl PolyMesh {
    /// Checks indices and loops: every index in range, at least 3 distinct vertices per loop, no
    /// vertex twice in a face, tags on existing edges and vertices.
    pub fn validate(&self) -> Result<(), SubdivError> {
        let n = self.positions.len() as u32;
        let mut seen: Vec<u32> = Vec::new();
        for (f, face) in self.faces.iter().enumerate() {
            seen.clear();
            for lp in std::iter::once(&face.outer).chain(&face.inner) {
                if lp.len() < 3 {
                    return Err(SubdivError::Face {
                        face: f,
                        reason: format!("a loop of {} vertices; at least 3 are needed", lp.len()),
                    });
                }
                for &v in lp {
                    if v >= n {
                        return Err(SubdivError::Face {
                            face: f,
                            reason: format!("vertex {} does not exist ({n} vertices)", v + 1),
                        });
                    }
                    seen.push(v);
                }
            }
            seen.sort_unstable();
            if let Some(w) = seen.windows(2).find(|w| w[0] == w[1]) {
                return Err(SubdivError::Face {
                    face: f,
                    reason: format!("vertex {} appears twice", w[0] + 1),
                });
            }
        }
        for (&(a, b), &s) in &self.creases {
            if a >= n || b >= n || a == b || !s.is_finite() || s < 0.0 {
                return Err(SubdivError::Tag {
                    tag: "crease".into(),
                    reason: format!("edge {a}–{b} with sharpness {s} is not valid"),
                });
            }
        }
        for (&v, &s) in &self.corners {
            if v >= n || !s.is_finite() || s < 0.0 {
                return Err(SubdivError::Tag {
                    tag: "corner".into(),
                    reason: format!("vertex {v} with sharpness {s} is not valid"),
                });
            }
        }
        if !self.holes.is_empty() && self.holes.len() != self.faces.len() {
            return Err(SubdivError::Tag {
                tag: "hole".into(),
                reason: "one flag per face is needed".into(),
            });
        }
        Ok(())
    }

    /// Whether face `f` is a hole.
    pub fn is_hole(&self, f: usize) -> bool {
        self.holes.get(f).copied().unwrap_or(false)
    }

    /// Sets the sharpness of the edge `a–b`.
    pub fn set_crease(&mut self, a: u32, b: u32, sharpness: f32) {
        self.creases.insert((a.min(b), a.max(b)), sharpness);
    }

    /// The sharpness of the edge `a–b` (0 when not tagged).
    pub fn crease(&self, a: u32, b: u32) -> f32 {
        self.creases
            .get(&(a.min(b), a.max(b)))
            .copied()
            .unwrap_or(0.0)
    }

    /// A triangle mesh of the faces that are not holes: simple faces by fans from their first
    /// vertex (refined Catmull–Clark faces are convex quads), faces with inner loops by ear
    /// clipping in their plane with the holes bridged.
    pub fn triangulate(&self) -> Result<Mesh, SubdivError> {
        let mut mesh = Mesh::new();
        mesh.positions = self.positions.iter().map(|p| p.map(|c| c as f32)).collect();
        for (f, face) in self.faces.iter().enumerate() {
            if self.is_hole(f) {
                continue;
            }
            if face.inner.is_empty() {
                let o = &face.outer;
                for k in 1..o.len() - 1 {
                    mesh.triangles.push([o[0], o[k], o[k + 1]]);
                }
            } else {
                let tris = holes::triangulate_face(&self.positions, face)
                    .map_err(|reason| SubdivError::Holes { face: f, reason })?;
                mesh.triangles.extend(tris);
            }
        }
        mesh.compute_normals();
        Ok(mesh)
    }
}
