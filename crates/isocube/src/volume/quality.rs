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
        self.boundary_edges(None)
            .into_iter()
            .min_by(|x, y| x.angle.total_cmp(&y.angle).then(x.edge.cmp(&y.edge)))
    }

    /// Every edge of the region's boundary with the region's angle there (the smallest of its
    /// wedges where more than two boundary triangles meet), in no particular order; only the
    /// edges among `among` (sorted, lower vertex first) if given; none for multi-material
    /// meshes ([`TetMesh::sharpest_boundary_edge`]).
    pub(super) fn boundary_edges(&self, among: Option<&[[u32; 2]]>) -> Vec<BoundaryEdge> {
        if self.labels.is_some() {
            return Vec::new();
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
            .filter(|h| among.is_none_or(|edges| edges.binary_search(&h.0).is_ok()))
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
            .collect()
    }

    /// The surface's vertices and the walls' triangles. A mesh read from a file knows neither:
    /// its boundary (the faces of one tetrahedron only) is split into the faces lying in a face
    /// of its bounding box (the walls of the grid it was made on) and the rest (the surface).
    pub(super) fn surface_and_walls(&self) -> (Vec<u32>, std::borrow::Cow<'_, [[u32; 3]]>) {
        if !(self.surface.is_empty() && self.walls.is_empty()) {
            let surface = (0..self.surface_vertices as u32).collect();
            return (surface, std::borrow::Cow::Borrowed(&self.walls));
        }
        let boundary = super::check::match_faces(&self.tets, self.positions.len()).1;
        let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
        for p in self
            .tets
            .iter()
            .flatten()
            .map(|&v| self.positions[v as usize])
        {
            for a in 0..3 {
                lo[a] = lo[a].min(p[a]);
                hi[a] = hi[a].max(p[a]);
            }
        }
        let (walls, surface): (Vec<[u32; 3]>, Vec<[u32; 3]>) =
            boundary.into_iter().partition(|f| {
                let p = f.map(|v| self.positions[v as usize]);
                (0..3).any(|a| [lo[a], hi[a]].iter().any(|&c| p.iter().all(|q| q[a] == c)))
            });
        let mut vertices: Vec<u32> = surface.into_iter().flatten().collect();
        vertices.par_sort_unstable();
        vertices.dedup();
        (vertices, std::borrow::Cow::Owned(walls))
    }

    /// The elements outside the dihedral range volume meshes aim at, [10°, 165°], sorted by
    /// what lies beside them, for a mesh whose grid cells are `cell` wide (the smallest
    /// spacing): those with an edge where the region's boundary is sharper than 10° (the
    /// surface forces them: the elements around the edge share its angle); those within 1.5
    /// cells of surface detail finer than `detail` cells (a surface vertex with another surface
    /// vertex, or a wall of the grid it does not lie on, that close); and the others, which a
    /// better mesh of the same boundary could have avoided.
    ///
    /// Pass the snap distance as `detail` (0.3 by default): ternary extraction moves every
    /// crossing that close to a grid point onto it, so surface vertices closer than that to one
    /// another or to a wall remain only where snapping would change the topology — a gap or
    /// neck the surface keeps open, thinner than the elements can fill well (crossings more
    /// than the snap distance from their grid points are at least 0.42 cells apart). A `cell`
    /// that is not a positive width counts every such element among the others. A mesh read
    /// from a file knows no surface or walls: its boundary faces lying in a face of its bounding
    /// box are taken for walls, the others for the surface.
    ///
    /// ```
    /// use isocube::extract::ExtractOptions;
    /// use isocube::field::Sample;
    /// use isocube::volume::tetmesh;
    /// let grid = Sample::Sphere.grid(16);
    /// let mesh = tetmesh(&grid, &ExtractOptions::default()).unwrap();
    /// let poor = mesh.poor_elements(grid.spacing()[0], 0.3);
    /// assert_eq!(poor.count, poor.at_sharp_edges + poor.beside_fine_detail + poor.others);
    /// ```
    pub fn poor_elements(&self, cell: f64, detail: f64) -> PoorElements {
        let at = |v: u32| self.positions[v as usize].map(f64::from);
        let scored: Vec<(f64, u32)> = self
            .tets
            .par_iter()
            .enumerate()
            .filter_map(|(i, t)| {
                let (lo, hi) = dihedral_extremes(t.map(at));
                (lo < POOR_LOW || hi > POOR_HIGH)
                    .then_some((lo.min((180.0 - hi) * (2.0 / 3.0)), i as u32))
            })
            .collect();
        let mut poor = PoorElements {
            count: scored.len(),
            ..PoorElements::default()
        };
        if scored.is_empty() || cell.is_nan() || cell <= 0.0 {
            poor.others = poor.count;
            poor.worst_other = scored
                .iter()
                .min_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)))
                .map(|e| e.1);
            return poor;
        }
        // Only the edges of poor elements can make them forced.
        let mut edges: Vec<[u32; 2]> = scored
            .iter()
            .flat_map(|&(_, i)| {
                let t = self.tets[i as usize];
                (0..4).flat_map(move |a| (a + 1..4).map(move |b| [t[a].min(t[b]), t[a].max(t[b])]))
            })
            .collect();
        edges.par_sort_unstable();
        edges.dedup();
        let mut sharp: Vec<[u32; 2]> = self
            .boundary_edges(Some(&edges))
            .into_iter()
            .filter(|e| e.angle < POOR_LOW)
            .map(|e| e.edge)
            .collect();
        sharp.par_sort_unstable();
        // Surface vertices (numbered first) by the cell they lie in, `z` first, so that those
        // of a row of cells along `x` lie together.
        let key = |p: [f64; 3]| [p[2], p[1], p[0]].map(|c| (c / cell).floor() as i64);
        let (surface, walls) = self.surface_and_walls();
        let mut by_cell: Vec<([i64; 3], u32)> =
            surface.into_par_iter().map(|v| (key(at(v)), v)).collect();
        by_cell.par_sort_unstable();
        // The grid's walls, as planes (axis, coordinate): where the surface passes closer to
        // one than `detail` without meeting it, the region between is as thin.
        let mut planes: Vec<(usize, f32)> = walls
            .iter()
            .filter_map(|f| {
                let p = f.map(|v| self.positions[v as usize]);
                (0..3)
                    .find(|&a| p[0][a] == p[1][a] && p[1][a] == p[2][a])
                    .map(|a| (a, p[0][a]))
            })
            .collect();
        planes.sort_by(|x, y| x.0.cmp(&y.0).then(x.1.total_cmp(&y.1)));
        planes.dedup();
        let reach = 1.5 * cell;
        // Within a cell, the 27 cells around a vertex hold every vertex that close.
        let fine = detail.clamp(0.0, 1.0) * cell;
        // The surface vertices in the cells `lo..=hi` (keys), `z` rows first.
        let in_cells = |lo: [i64; 3], hi: [i64; 3]| {
            let by_cell = &by_cell;
            (lo[0]..=hi[0]).flat_map(move |z| {
                (lo[1]..=hi[1]).flat_map(move |y| {
                    let from = by_cell.partition_point(|e| e.0 < [z, y, lo[2]]);
                    let to = by_cell.partition_point(|e| e.0 <= [z, y, hi[2]]);
                    by_cell[from..to].iter().map(|e| e.1)
                })
            })
        };
        let forced: Vec<bool> = scored
            .par_iter()
            .map(|&(_, i)| {
                let t = self.tets[i as usize];
                (0..4).any(|a| {
                    (a + 1..4).any(|b| {
                        let e = [t[a].min(t[b]), t[a].max(t[b])];
                        sharp.binary_search(&e).is_ok()
                    })
                })
            })
            .collect();
        // The surface vertices within reach of each other poor element.
        let near: Vec<Vec<u32>> = scored
            .par_iter()
            .zip(&forced)
            .map(|(&(_, i), &forced)| {
                if forced {
                    return Vec::new();
                }
                let p = self.tets[i as usize].map(at);
                let centre: [f64; 3] =
                    std::array::from_fn(|d| p.iter().map(|q| q[d]).sum::<f64>() / 4.0);
                let (lo, hi) = (
                    key(centre.map(|c| c - reach)),
                    key(centre.map(|c| c + reach)),
                );
                in_cells(lo, hi)
                    .filter(|&v| {
                        let d = sub(at(v), centre);
                        dot(d, d) <= reach * reach
                    })
                    .collect()
            })
            .collect();
        let mut needed: Vec<u32> = near.iter().flatten().copied().collect();
        needed.par_sort_unstable();
        needed.dedup();
        // Each of those vertices' nearest other surface vertex, or wall it does not lie on,
        // closer than `fine` (under half a cell: within its own cell and the 26 around).
        let finest: Vec<Option<Closest>> = needed
            .par_iter()
            .map(|&v| {
                let p = at(v);
                let k = key(p);
                let mut closest: Option<Closest> = None;
                let mut take = |d: f64, pair: [u32; 2]| {
                    if d < fine && closest.is_none_or(|c| (d, pair) < c) {
                        closest = Some((d, pair));
                    }
                };
                for u in in_cells(k.map(|c| c - 1), k.map(|c| c + 1)) {
                    if u != v {
                        let d = sub(at(u), p);
                        take(dot(d, d).sqrt(), [u.min(v), u.max(v)]);
                    }
                }
                for &(axis, c) in &planes {
                    let d = (p[axis] - f64::from(c)).abs();
                    if d > 0.0 {
                        take(d, [v, v]);
                    }
                }
                closest
            })
            .collect();
        let verdicts: Vec<(u8, Option<Closest>)> = forced
            .par_iter()
            .zip(&near)
            .map(|(&forced, near)| {
                if forced {
                    return (0, None);
                }
                let closest = near
                    .iter()
                    .filter_map(|v| finest[needed.binary_search(v).expect("listed")])
                    .min_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
                match closest {
                    Some(c) => (1, Some(c)),
                    None => (2, None),
                }
            })
            .collect();
        for (&(score, i), (kind, closest)) in scored.iter().zip(verdicts) {
            match kind {
                0 => poor.at_sharp_edges += 1,
                1 => {
                    poor.beside_fine_detail += 1;
                    if let Some(c) = closest {
                        if poor.closest.is_none_or(|p| (c.0, c.1) < (p.0, p.1)) {
                            poor.closest = Some(c);
                        }
                    }
                }
                _ => {
                    poor.others += 1;
                    let worse = poor.worst_other.is_none_or(|w| {
                        let (lo, hi) = dihedral_extremes(self.tets[w as usize].map(at));
                        let s = lo.min((180.0 - hi) * (2.0 / 3.0));
                        (score, i) < (s, w)
                    });
                    if worse {
                        poor.worst_other = Some(i);
                    }
                }
            }
        }
        poor
    }
}

/// The surface detail [`TetMesh::poor_elements`] weighs a mesh made with `options` against,
/// in cells: the snap distance of ternary extraction, or the default's for a method that snaps
/// nothing (plain Marching Cubes, or ternary with snapping off), whose surface has such detail
/// wherever a crossing falls near a grid point.
///
/// ```
/// use isocube::extract::{ExtractOptions, Method, Snapping};
/// use isocube::volume::snap_detail;
/// let ternary = ExtractOptions::default().with_method(Method::Ternary(Snapping::default()));
/// assert!((snap_detail(&ternary) - 0.3).abs() < 1e-6);
/// // Plain Marching Cubes snaps nothing: its surface is weighed against the default's distance.
/// assert_eq!(snap_detail(&ExtractOptions::default()), snap_detail(&ternary));
/// ```
pub fn snap_detail(options: &crate::extract::ExtractOptions) -> f64 {
    use crate::extract::{Method, Snapping};
    match options.method {
        Method::Ternary(s) if s.snap > 0.0 => f64::from(s.snap),
        _ => f64::from(Snapping::default().snap),
    }
}

/// Two surface vertices and their distance (a vertex twice: it and the nearest wall).
type Closest = (f64, [u32; 2]);

/// The dihedral range volume meshes aim at ([`TetMesh::poor_elements`]).
const POOR_LOW: f64 = 10.0;
const POOR_HIGH: f64 = 165.0;

/// The elements of a volume mesh outside [10°, 165°] and what lies beside them
/// ([`TetMesh::poor_elements`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PoorElements {
    /// Elements with a dihedral angle under 10° or over 165°.
    pub count: usize,
    /// Of those, the elements with an edge where the region's boundary is sharper than 10°:
    /// forced by the surface.
    pub at_sharp_edges: usize,
    /// Of the rest, the elements within 1.5 cells of a surface vertex with another surface
    /// vertex, or a wall of the grid it does not lie on, closer than the detail asked about.
    pub beside_fine_detail: usize,
    /// The closest two such surface vertices (a vertex twice: it and the wall nearest to it),
    /// and their distance.
    pub closest: Option<(f64, [u32; 2])>,
    /// The remaining elements.
    pub others: usize,
    /// The worst of them (by the smaller of its smallest dihedral angle and two thirds of 180°
    /// less its largest).
    pub worst_other: Option<u32>,
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
