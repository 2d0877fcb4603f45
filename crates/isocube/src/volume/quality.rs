//! Tetrahedron quality: dihedral angles and the radius ratio (Verdict's definitions).

use rayon::prelude::*;

use super::check::{cross, dot, sub};
use super::TetMesh;

/// The quality of one tetrahedron.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TetQuality {
    /// The smallest of its six dihedral angles, in degrees (70.5° for the regular tetrahedron).
    pub min_dihedral: f64,
    /// The largest dihedral angle, in degrees.
    pub max_dihedral: f64,
    /// Verdict's radius ratio: the circumradius over three times the inradius (1 for the
    /// regular tetrahedron, growing without bound as it flattens; infinite when flat).
    pub radius_ratio: f64,
}

impl TetQuality {
    /// The quality of the tetrahedron with these corners.
    ///
    /// ```
    /// use isocube::volume::TetQuality;
    /// let s = 1.0 / 2f64.sqrt();
    /// let regular = [[1.0, 0.0, -s], [-1.0, 0.0, -s], [0.0, 1.0, s], [0.0, -1.0, s]];
    /// let q = TetQuality::of(regular);
    /// assert!((q.min_dihedral - 70.528779).abs() < 1e-5 && (q.radius_ratio - 1.0).abs() < 1e-12);
    /// ```
    pub fn of(p: [[f64; 3]; 4]) -> TetQuality {
        TetQuality::of_edges(edges(p))
    }

    /// The quality of the tetrahedron whose corners are 0 and these three edge vectors: a
    /// function of the vectors alone, so translates whose vectors are the same bits have the
    /// same quality, bit for bit.
    fn of_edges(e: [[f64; 3]; 3]) -> TetQuality {
        let (normals, lengths) = face_normals(e);
        let (min_dihedral, max_dihedral) = extremes(&normals, &lengths);
        let [a, b, c] = e;
        let six_volume = dot(a, cross(b, c)).abs();
        let radius_ratio = if six_volume > 0.0 {
            let w = [cross(b, c), cross(c, a), cross(a, b)];
            let s = [dot(a, a), dot(b, b), dot(c, c)];
            let m: [f64; 3] =
                std::array::from_fn(|d| s[0] * w[0][d] + s[1] * w[1][d] + s[2] * w[2][d]);
            let circumradius = dot(m, m).sqrt() / (2.0 * six_volume);
            // Face areas are half the normals' lengths.
            let inradius = six_volume / lengths.iter().sum::<f64>();
            circumradius / (3.0 * inradius)
        } else {
            f64::INFINITY
        };
        TetQuality {
            min_dihedral,
            max_dihedral,
            radius_ratio,
        }
    }
}

/// The edge vectors from the first corner to the others.
#[inline(always)]
fn edges(p: [[f64; 3]; 4]) -> [[f64; 3]; 3] {
    [sub(p[1], p[0]), sub(p[2], p[0]), sub(p[3], p[0])]
}

/// The normals of the faces opposite each corner (twice the faces' areas long), all pointing
/// out of the tetrahedron when it is positive and all into it when it is negative (the dihedral
/// angles depend only on their pairwise products, which do not see the difference), and their
/// lengths; from the edge vectors of the first corner.
#[inline(always)]
fn face_normals([e1, e2, e3]: [[f64; 3]; 3]) -> ([[f64; 3]; 4], [f64; 4]) {
    let normals = [
        cross(sub(e2, e1), sub(e3, e1)),
        cross(e3, e2),
        cross(e1, e3),
        cross(e2, e1),
    ];
    let lengths = normals.map(|n| dot(n, n).sqrt());
    (normals, lengths)
}

/// The smallest and largest dihedral angles, in degrees, from the outward face normals: the
/// dihedral angle at the edge two faces share is 180° less the angle between their normals, so
/// its cosine is minus their normalised dot product; only the two extreme cosines need an arc
/// cosine. A face of no area makes the smallest angle 0°.
#[inline(always)]
fn extremes(normals: &[[f64; 3]; 4], lengths: &[f64; 4]) -> (f64, f64) {
    let (mut hi_cos, mut lo_cos) = (f64::NEG_INFINITY, f64::INFINITY);
    for i in 0..4 {
        for j in i + 1..4 {
            let len = lengths[i] * lengths[j];
            let c = if len > 0.0 {
                -dot(normals[i], normals[j]) / len
            } else {
                1.0
            };
            hi_cos = hi_cos.max(c);
            lo_cos = lo_cos.min(c);
        }
    }
    let angle = |c: f64| c.clamp(-1.0, 1.0).acos().to_degrees();
    (angle(hi_cos), angle(lo_cos))
}

/// The smallest and largest dihedral angles of a tetrahedron, in degrees, as
/// [`TetQuality::of`] finds them (the cone-point search and the improvement step score many
/// candidate tetrahedra).
pub(super) fn dihedral_extremes(p: [[f64; 3]; 4]) -> (f64, f64) {
    let (normals, lengths) = face_normals(edges(p));
    extremes(&normals, &lengths)
}

/// A whole mesh's quality.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TetReport {
    /// Tetrahedra.
    pub tets: usize,
    /// The smallest dihedral angle, in degrees.
    pub min_dihedral: f64,
    /// The largest dihedral angle, in degrees.
    pub max_dihedral: f64,
    /// The worst (largest) radius ratio.
    pub max_radius_ratio: f64,
    /// The mean radius ratio.
    pub mean_radius_ratio: f64,
    /// Tetrahedra by smallest dihedral angle, in 5° bins from 0° to 90° (the last bin holds
    /// everything from 85° up).
    pub min_dihedral_histogram: [usize; 18],
}

impl TetMesh {
    /// Every tetrahedron's quality, in order.
    ///
    /// Most elements of a volume mesh are lattice tetrahedra, translates of a few shapes: a
    /// small cache per stretch of elements, keyed by the exact bits of the edge vectors (the
    /// differences of `f32` coordinates are exact in `f64`), computes each shape once. The
    /// result is the same, bit for bit, as computing every element.
    pub fn qualities(&self) -> Vec<TetQuality> {
        let mut out = vec![TetQuality::default(); self.tets.len()];
        out.par_chunks_mut(STRETCH)
            .zip(self.tets.par_chunks(STRETCH))
            .for_each(|(out, tets)| self.stretch_qualities(tets, out));
        out
    }

    /// The qualities of one stretch of tetrahedra into `out`, with the stretch's own cache.
    fn stretch_qualities(&self, tets: &[[u32; 4]], out: &mut [TetQuality]) {
        const SLOTS: usize = 1 << 10;
        let mut cache: Vec<Option<([u64; 9], TetQuality)>> = vec![None; SLOTS];
        for (q, t) in out.iter_mut().zip(tets) {
            let e = edges(t.map(|v| self.positions[v as usize].map(f64::from)));
            let key: [u64; 9] = std::array::from_fn(|i| e[i / 3][i % 3].to_bits());
            let slot = key.iter().fold(0u64, |h, &x| {
                (h.rotate_left(5) ^ x).wrapping_mul(0x517c_c1b7_2722_0a95)
            }) >> (64 - SLOTS.trailing_zeros());
            let entry = &mut cache[slot as usize];
            *q = match entry {
                Some((k, quality)) if *k == key => *quality,
                _ => {
                    let quality = TetQuality::of_edges(e);
                    *entry = Some((key, quality));
                    quality
                }
            };
        }
    }

    /// The mesh's quality summary: [`TetReport::of`] the [`TetMesh::qualities`], made stretch
    /// by stretch without holding them all (24 bytes a tetrahedron).
    pub fn quality_report(&self) -> TetReport {
        let parts: Vec<Partial> = self
            .tets
            .par_chunks(STRETCH)
            .map(|tets| {
                let mut out = vec![TetQuality::default(); tets.len()];
                self.stretch_qualities(tets, &mut out);
                Partial::of(&out)
            })
            .collect();
        Partial::report(&parts)
    }

    /// Every element's quality in single precision, as files store it (12 bytes a
    /// tetrahedron, half of [`TetMesh::qualities`]), with the report made from the full
    /// precision in the same pass (the same as [`TetMesh::quality_report`]).
    ///
    /// ```
    /// use isocube::extract::ExtractOptions;
    /// use isocube::field::Sample;
    /// use isocube::volume::tetmesh;
    /// let mesh = tetmesh(&Sample::Torus.grid(16), &ExtractOptions::default()).unwrap();
    /// let (columns, report) = mesh.quality_columns();
    /// assert_eq!(columns.min_dihedral.len(), mesh.tets.len());
    /// assert_eq!(report, mesh.quality_report());
    /// let full = mesh.qualities();
    /// for (k, q) in full.iter().enumerate() {
    ///     assert_eq!(columns.min_dihedral[k], q.min_dihedral as f32);
    ///     assert_eq!(columns.radius_ratio[k], q.radius_ratio as f32);
    /// }
    /// ```
    pub fn quality_columns(&self) -> (QualityColumns, TetReport) {
        let n = self.tets.len();
        let mut columns = QualityColumns {
            min_dihedral: vec![0.0; n],
            max_dihedral: vec![0.0; n],
            radius_ratio: vec![0.0; n],
        };
        let parts: Vec<Partial> = (
            columns.min_dihedral.par_chunks_mut(STRETCH),
            columns.max_dihedral.par_chunks_mut(STRETCH),
            columns.radius_ratio.par_chunks_mut(STRETCH),
            self.tets.par_chunks(STRETCH),
        )
            .into_par_iter()
            .map(|(lo, hi, ratio, tets)| {
                let mut out = vec![TetQuality::default(); tets.len()];
                self.stretch_qualities(tets, &mut out);
                for (k, q) in out.iter().enumerate() {
                    lo[k] = q.min_dihedral as f32;
                    hi[k] = q.max_dihedral as f32;
                    ratio[k] = q.radius_ratio as f32;
                }
                Partial::of(&out)
            })
            .collect();
        (columns, Partial::report(&parts))
    }

    /// The sharpest edge of the region's boundary (surface and walls, or for a mesh read from a
    /// file the faces of one tetrahedron only): the smallest angle the region makes there, in
    /// degrees, and the edge. The tetrahedra around a boundary edge
    /// share out that angle, so none of them has a larger dihedral angle there: no mesh
    /// keeping this boundary has a better smallest dihedral angle than the sharpest edge's.
    /// It tells a poor element forced by the surface (where it meets a wall at a grazing
    /// angle, or folds into a thin wedge) from one the mesher could have done better.
    ///
    /// Where the surface touches itself or a wall along an edge, four or more boundary triangles
    /// meet there: the region's angles are the wedges between them, the smallest counted.
    /// `None` when the boundary has no edge, and for multi-material meshes (whose interfaces are
    /// not one region's boundary).
    ///
    /// ```
    /// use isocube::extract::ExtractOptions;
    /// use isocube::field::Sample;
    /// use isocube::volume::tetmesh;
    /// // The whole grid inside: a box, its sharpest edges the box's own right angles.
    /// let grid = Sample::Sphere.grid(8);
    /// let mesh = tetmesh(&grid, &ExtractOptions::default().with_level(10.0)).unwrap();
    /// let sharpest = mesh.sharpest_boundary_edge().unwrap();
    /// assert!((sharpest.angle - 90.0).abs() < 1e-9);
    /// ```
    pub fn sharpest_boundary_edge(&self) -> Option<BoundaryEdge> {
        if self.labels.is_some() {
            return None;
        }
        let boundary: Vec<[u32; 3]> = if self.surface.is_empty() && self.walls.is_empty() {
            // Read from a file: the faces of one tetrahedron only.
            super::check::match_faces(&self.tets, self.positions.len()).1
        } else {
            self.boundary_triangles()
        };
        // Half-edges: the edge (lower vertex first), whether the triangle runs that way, and
        // its third corner; grouped by edge.
        let mut halves: Vec<([u32; 2], bool, u32)> = boundary
            .iter()
            .flat_map(|f| {
                (0..3).map(move |k| {
                    let (a, b) = (f[k], f[(k + 1) % 3]);
                    ([a.min(b), a.max(b)], a < b, f[(k + 2) % 3])
                })
            })
            .collect();
        halves.par_sort_unstable();
        let at = |v: u32| self.positions[v as usize].map(f64::from);
        halves
            .par_chunk_by(|x, y| x.0 == y.0)
            .filter_map(|group| {
                let [a, b] = group[0].0;
                let forward = group.iter().filter(|h| h.1).count();
                if group.len() < 2 || 2 * forward != group.len() {
                    return None;
                }
                // Each triangle's direction about the edge, as an angle in a frame turning
                // right-handed about it. A triangle running a → b (lower vertex first) has the
                // region on its side of smaller angle, one running b → a on its side of larger:
                // the region's wedges run from each b → a triangle to the next triangle round.
                // Where the surface touches itself or a wall along the edge, four or more
                // triangles meet there and the wedges between them are the region's angles.
                let (pa, pb) = (at(a), at(b));
                let e = sub(pb, pa);
                let across = |c: u32| {
                    let u = sub(at(c), pa);
                    let along = dot(u, e) / dot(e, e);
                    std::array::from_fn::<f64, 3, _>(|d| u[d] - along * e[d])
                };
                let x_axis = across(group[0].2);
                let y_axis = cross(e, x_axis);
                let mut around: Vec<(f64, bool)> = group
                    .iter()
                    .map(|h| {
                        let u = across(h.2);
                        let turn = (dot(u, y_axis) / dot(y_axis, y_axis).sqrt())
                            .atan2(dot(u, x_axis) / dot(x_axis, x_axis).sqrt());
                        (turn.rem_euclid(std::f64::consts::TAU).to_degrees(), h.1)
                    })
                    .collect();
                around.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
                let n = around.len();
                let mut sharpest = f64::INFINITY;
                for k in 0..n {
                    let (from, forward) = around[k];
                    if forward {
                        continue;
                    }
                    let (to, next_forward) = around[(k + 1) % n];
                    if !next_forward {
                        return None;
                    }
                    sharpest = sharpest.min((to - from).rem_euclid(360.0));
                }
                sharpest.is_finite().then_some(BoundaryEdge {
                    angle: sharpest,
                    edge: [a, b],
                })
            })
            .min_by(|x, y| x.angle.total_cmp(&y.angle).then(x.edge.cmp(&y.edge)))
    }
}

/// Each element's quality in single precision, one column a measure
/// ([`TetMesh::quality_columns`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct QualityColumns {
    /// The smallest dihedral angle of each tetrahedron, in degrees.
    pub min_dihedral: Vec<f32>,
    /// The largest dihedral angle, in degrees.
    pub max_dihedral: Vec<f32>,
    /// Verdict's radius ratio (infinite when flat).
    pub radius_ratio: Vec<f32>,
}

/// Tetrahedra are measured in stretches of this many, each with a cache of its own.
const STRETCH: usize = 1 << 14;

/// One stretch's part of a [`TetReport`].
struct Partial {
    report: TetReport,
    sum: f64,
}

impl Partial {
    fn of(qualities: &[TetQuality]) -> Partial {
        let mut r = TetReport {
            tets: qualities.len(),
            min_dihedral: f64::INFINITY,
            max_dihedral: f64::NEG_INFINITY,
            ..TetReport::default()
        };
        let mut sum = 0.0;
        for q in qualities {
            r.min_dihedral = r.min_dihedral.min(q.min_dihedral);
            r.max_dihedral = r.max_dihedral.max(q.max_dihedral);
            r.max_radius_ratio = r.max_radius_ratio.max(q.radius_ratio);
            sum += q.radius_ratio;
            let bin = ((q.min_dihedral / 5.0).max(0.0) as usize).min(17);
            r.min_dihedral_histogram[bin] += 1;
        }
        Partial { report: r, sum }
    }

    /// The parts joined in order.
    fn report(parts: &[Partial]) -> TetReport {
        let mut r = TetReport {
            min_dihedral: f64::INFINITY,
            max_dihedral: f64::NEG_INFINITY,
            ..TetReport::default()
        };
        let mut sum = 0.0;
        for p in parts {
            let q = &p.report;
            r.tets += q.tets;
            r.min_dihedral = r.min_dihedral.min(q.min_dihedral);
            r.max_dihedral = r.max_dihedral.max(q.max_dihedral);
            r.max_radius_ratio = r.max_radius_ratio.max(q.max_radius_ratio);
            for (a, b) in r
                .min_dihedral_histogram
                .iter_mut()
                .zip(q.min_dihedral_histogram)
            {
                *a += b;
            }
            sum += p.sum;
        }
        if r.tets == 0 {
            r.min_dihedral = 0.0;
            r.max_dihedral = 0.0;
        } else {
            r.mean_radius_ratio = sum / r.tets as f64;
        }
        r
    }
}

/// An edge of a volume mesh's boundary and the region's angle there
/// ([`TetMesh::sharpest_boundary_edge`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoundaryEdge {
    /// The angle, in degrees, between the two boundary triangles, measured through the region
    /// (180° where they lie flat, under 180° at a convex edge).
    pub angle: f64,
    /// The edge's vertices, the smaller first.
    pub edge: [u32; 2],
}

impl TetReport {
    /// The summary of these tetrahedra's qualities.
    pub fn of(qualities: &[TetQuality]) -> TetReport {
        // Stretch by stretch, as [`TetMesh::quality_report`] sums them: the same mean, bit for
        // bit, whichever way the qualities were had.
        let parts: Vec<Partial> = qualities.chunks(STRETCH).map(Partial::of).collect();
        Partial::report(&parts)
    }
}
