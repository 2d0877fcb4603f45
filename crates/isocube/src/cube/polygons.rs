//! Surface polygons inside one cell, derived from the face signs and stored per class.
//!
//! The surface of a cell is one or more closed polygons whose corners are crossings on cube
//! edges. They are derived generically, never typed in:
//!
//! 1. On each face, walk the corners counter-clockwise as seen from outside. A crossing is an
//!    *exit* where the walk goes from above to below, an *entry* where it goes from below to
//!    above. Each exit is joined to an entry by a segment running from exit to entry, which
//!    leaves the above region on the segment's left when seen from outside.
//! 2. A face with four crossings is ambiguous: its above corners are either joined through the
//!    face (each exit pairs with the next entry) or separated (each exit pairs with the previous
//!    entry). The caller decides, normally with the asymptotic decider, and passes the decision
//!    as one bit per face ([`FaceDecisions`]: bit `f` set = the above corners of face `f` are
//!    joined). Two cells sharing a face see the same four values, decide alike and so emit the
//!    same segments with opposite directions.
//! 3. Every crossing is the exit of one of its two faces and the entry of the other, so the
//!    segments chain into closed loops. Walking a loop in segment order, the surface normal
//!    (right-hand rule) points toward the above side, i.e. toward increasing values.
//!
//! The [`CaseTable`](super::CaseTable) derives polygons this way only for the 14 class
//! representatives under the full group (rotations, mirror, flip) and every decision pattern of
//! their ambiguous faces, and obtains all 256 configurations through their transforms: corners
//! are mapped by the edge permutation, face decisions by the face permutation (inverted under
//! flip, since above and below trade places), and the loops reversed when the transform mirrors
//! or flips.

use super::symmetry::Transform;
use super::{EDGES, FACES, FACE_EDGES};

/// One bit per face: bit `f` set means the above corners of face `f` are joined through the
/// face. Only bits of ambiguous faces (four crossings) matter.
pub type FaceDecisions = u8;

/// A polygon corner: a crossing on a cube edge (0..12), a cube vertex (12..20, for ternary
/// configurations) or one of up to [`Corner::MAX_INTERIOR`] points inside the cell (20..24).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Corner(u8);

impl Corner {
    /// The first point inside the cell.
    pub const INTERIOR: Corner = Corner(20);
    /// How many interior points a cell may use.
    pub const MAX_INTERIOR: usize = 4;

    /// Interior point `k` (< [`Corner::MAX_INTERIOR`]).
    pub const fn interior(k: u8) -> Corner {
        assert!((k as usize) < Corner::MAX_INTERIOR);
        Corner(20 + k)
    }

    /// The interior point's number, if this corner is one.
    pub fn as_interior(self) -> Option<u8> {
        (self.0 >= 20).then(|| self.0 - 20)
    }

    /// The crossing on edge `e` (< 12).
    pub const fn edge(e: u8) -> Corner {
        assert!(e < 12);
        Corner(e)
    }

    /// The cube vertex `v` (< 8).
    pub const fn vertex(v: u8) -> Corner {
        assert!(v < 8);
        Corner(12 + v)
    }

    /// The edge, if this corner is an edge crossing.
    pub fn as_edge(self) -> Option<u8> {
        (self.0 < 12).then_some(self.0)
    }

    /// The cube vertex, if this corner is one.
    pub fn as_vertex(self) -> Option<u8> {
        (12..20).contains(&self.0).then(|| self.0 - 12)
    }

    /// The raw code: 0..12 edges, 12..20 vertices, 20.. interior points.
    pub fn code(self) -> u8 {
        self.0
    }

    /// The corner with this [`Corner::code`], if there is one.
    pub(crate) fn from_code(code: u8) -> Option<Corner> {
        (usize::from(code) < 20 + Corner::MAX_INTERIOR).then_some(Corner(code))
    }

    /// The corner's image under a transform's geometric part.
    pub fn transformed(self, t: Transform) -> Corner {
        if let Some(e) = self.as_edge() {
            Corner(t.edge_map()[usize::from(e)])
        } else if let Some(v) = self.as_vertex() {
            Corner(12 + t.vertex_map()[usize::from(v)])
        } else {
            self
        }
    }

    /// The faces this corner lies on, as a bit mask.
    #[inline]
    pub fn faces(self) -> u8 {
        CORNER_FACES.get(usize::from(self.0)).copied().unwrap_or(0)
    }
}

/// [`Corner::faces`] for every edge crossing (codes 0..12) and cube vertex (12..20); interior
/// points are on no face.
const CORNER_FACES: [u8; 20] = {
    let mut out = [0u8; 20];
    let mut f = 0;
    while f < 6 {
        let mut k = 0;
        while k < 4 {
            out[FACE_EDGES[f][k] as usize] |= 1 << f;
            out[12 + FACES[f][k] as usize] |= 1 << f;
            k += 1;
        }
        f += 1;
    }
    out
};

/// The faces of a binary configuration that have four crossings (ambiguous faces), as a mask.
pub fn ambiguous_faces(config: u8) -> u8 {
    let mut mask = 0;
    for (f, corners) in FACES.iter().enumerate() {
        let above = corners.map(|v| config >> v & 1);
        if above[0] == above[2] && above[1] == above[3] && above[0] != above[1] {
            mask |= 1 << f;
        }
    }
    mask
}

/// The directed segments `(from_edge, to_edge)` a binary configuration puts on one face.
pub fn face_segments(config: u8, decisions: FaceDecisions, face: usize) -> Vec<(u8, u8)> {
    let corners = FACES[face];
    let above = |i: usize| config >> corners[i % 4] & 1 == 1;
    // Crossings in counter-clockwise order: (edge, is_exit).
    let crossings: Vec<(u8, bool)> = (0..4)
        .filter(|&i| above(i) != above(i + 1))
        .map(|i| (FACE_EDGES[face][i], above(i)))
        .collect();
    let n = crossings.len();
    let joined = decisions >> face & 1 == 1;
    let mut segments = Vec::with_capacity(n / 2);
    for (k, &(edge, exit)) in crossings.iter().enumerate() {
        if !exit {
            continue;
        }
        // With two crossings both rules pick the same partner.
        let partner = if joined { (k + 1) % n } else { (k + n - 1) % n };
        segments.push((edge, crossings[partner].0));
    }
    segments
}

/// Derives the polygons of a binary configuration directly (no table, no symmetry): face
/// segments chained into loops, each loop starting at its smallest edge.
pub fn derive_polygons(config: u8, decisions: FaceDecisions) -> Vec<Vec<Corner>> {
    let mut next = [u8::MAX; 12];
    for face in 0..6 {
        for (from, to) in face_segments(config, decisions, face) {
            debug_assert_eq!(
                next[usize::from(from)],
                u8::MAX,
                "each crossing exits one face"
            );
            next[usize::from(from)] = to;
        }
    }
    let mut seen = [false; 12];
    let mut polygons = Vec::new();
    for start in 0..12u8 {
        if next[usize::from(start)] == u8::MAX || seen[usize::from(start)] {
            continue;
        }
        let mut loop_ = Vec::new();
        let mut e = start;
        while !seen[usize::from(e)] {
            seen[usize::from(e)] = true;
            loop_.push(Corner::edge(e));
            e = next[usize::from(e)];
        }
        debug_assert_eq!(e, start, "segments close into loops");
        polygons.push(loop_);
    }
    polygons
}

/// Maps polygons through a transform: corners by the geometric part, loops reversed when the
/// transform reverses winding.
pub fn transform_polygons(polygons: &[Vec<Corner>], t: Transform) -> Vec<Vec<Corner>> {
    polygons
        .iter()
        .map(|p| {
            let mut q: Vec<Corner> = p.iter().map(|c| c.transformed(t)).collect();
            if t.reverses_winding() {
                q.reverse();
            }
            q
        })
        .collect()
}

/// The regions a configuration's surface cuts the cube's boundary into, as vertex masks.
///
/// Every region on the cube's surface contains at least one cube vertex (the restriction of a
/// trilinear function to a face is bilinear and has no interior extremum), so a region is known
/// by its vertices: same-sign vertices joined by a cube edge, or across an ambiguous face whose
/// decision joins them.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Regions {
    /// Vertex masks of the regions at or above the level.
    pub above: Vec<u8>,
    /// Vertex masks of the regions below the level.
    pub below: Vec<u8>,
}

impl Regions {
    /// The regions of a binary configuration under face decisions.
    pub fn of(config: u8, decisions: FaceDecisions) -> Regions {
        let mut group: [u8; 8] = std::array::from_fn(|v| 1 << v);
        let mut join = |a: u8, b: u8| {
            let merged = group[usize::from(a)] | group[usize::from(b)];
            for (v, g) in group.iter_mut().enumerate() {
                if merged >> v & 1 == 1 {
                    *g = merged;
                }
            }
        };
        let above = |v: u8| config >> v & 1 == 1;
        for [a, b] in EDGES {
            if above(a) == above(b) {
                join(a, b);
            }
        }
        let ambiguous = ambiguous_faces(config);
        for (f, c) in FACES.iter().enumerate() {
            if ambiguous >> f & 1 == 0 {
                continue;
            }
            let joined_above = decisions >> f & 1 == 1;
            // Corners 0 and 2 share a sign, as do 1 and 3; join the pair the decision joins.
            let (p, q) = if above(c[0]) == joined_above {
                (c[0], c[2])
            } else {
                (c[1], c[3])
            };
            join(p, q);
        }
        let mut regions = Regions {
            above: Vec::new(),
            below: Vec::new(),
        };
        for v in 0..8u8 {
            let g = group[usize::from(v)];
            if g.trailing_zeros() == u32::from(v) {
                if above(v) {
                    regions.above.push(g);
                } else {
                    regions.below.push(g);
                }
            }
        }
        regions
    }

    /// The above and below regions a loop separates, as vertex masks.
    pub fn of_loop(&self, config: u8, polygon: &[Corner]) -> (u8, u8) {
        let e = polygon[0]
            .as_edge()
            .expect("binary loops have edge corners");
        let [a, b] = EDGES[usize::from(e)];
        let (up, down) = if config >> a & 1 == 1 { (a, b) } else { (b, a) };
        let find = |list: &[u8], v: u8| {
            *list
                .iter()
                .find(|m| *m >> v & 1 == 1)
                .expect("every vertex has a region")
        };
        (find(&self.above, up), find(&self.below, down))
    }
}

/// Puts each loop in a canonical form (start at its smallest corner) and sorts the loops, so
/// polygon sets can be compared regardless of where each loop starts.
pub fn canonical(polygons: &[Vec<Corner>]) -> Vec<Vec<Corner>> {
    let mut out: Vec<Vec<Corner>> = polygons
        .iter()
        .map(|p| {
            let k = (0..p.len()).min_by_key(|&i| p[i]).unwrap_or(0);
            p[k..].iter().chain(&p[..k]).copied().collect()
        })
        .collect();
    out.sort();
    out
}

/// Packs the bits of `decisions` at the faces in `mask` into consecutive low bits.
#[inline]
pub(crate) fn pack(mask: u8, decisions: FaceDecisions) -> u32 {
    let mut out = 0;
    let mut k = 0;
    let mut m = mask;
    while m != 0 {
        let f = m.trailing_zeros();
        out |= u32::from(decisions >> f & 1) << k;
        k += 1;
        m &= m - 1;
    }
    out
}

pub(crate) fn unpack(mask: u8, packed: u32) -> FaceDecisions {
    let mut out = 0;
    let mut k = 0;
    let mut m = mask;
    while m != 0 {
        let f = m.trailing_zeros();
        out |= ((packed >> k & 1) as u8) << f;
        k += 1;
        m &= m - 1;
    }
    out
}

/// Every decision pattern of a configuration's ambiguous faces.
pub fn decision_patterns(config: u8) -> impl Iterator<Item = FaceDecisions> {
    let amb = ambiguous_faces(config);
    (0..1u32 << amb.count_ones()).map(move |p| unpack(amb, p))
}

/// The segment a polygon edge lies on, as `(face, from, to)`.
pub fn polygon_segments(polygon: &[Corner]) -> Vec<(usize, Corner, Corner)> {
    let n = polygon.len();
    (0..n)
        .map(|i| {
            let (a, b) = (polygon[i], polygon[(i + 1) % n]);
            let shared = a.faces() & b.faces();
            debug_assert_eq!(shared.count_ones(), 1, "a segment lies on exactly one face");
            (shared.trailing_zeros() as usize, a, b)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cube::triangulate::safe_triangulation;
    use crate::cube::{CaseTable, OPPOSITE_FACE, VERTICES};

    #[test]
    fn segments_chain_and_count() {
        for config in 0..=255u8 {
            for d in decision_patterns(config) {
                let polys = derive_polygons(config, d);
                let crossings = (0..12)
                    .filter(|&e| {
                        let [a, b] = EDGES[e];
                        (config >> a & 1) != (config >> b & 1)
                    })
                    .count();
                let corners: usize = polys.iter().map(Vec::len).sum();
                assert_eq!(
                    corners, crossings,
                    "config {config}: every crossing used once"
                );
                assert!(polys.iter().all(|p| p.len() >= 3));
            }
        }
    }

    /// The table (representative + transform) agrees with direct derivation for every
    /// configuration and every decision pattern.
    #[test]
    fn transformed_polygons_equal_direct_polygons() {
        let table = CaseTable::binary();
        for config in 0..=255u8 {
            for d in decision_patterns(config) {
                let from_table: Vec<Vec<Corner>> =
                    table.polygons(config, d).map(<[Corner]>::to_vec).collect();
                assert_eq!(
                    canonical(&from_table),
                    canonical(&derive_polygons(config, d)),
                    "config {config} decisions {d:06b}"
                );
            }
        }
    }

    /// Every segment leaves the above corners of its face on its left as seen from outside,
    /// so the loops' right-hand normals point toward increasing values.
    #[test]
    fn segments_keep_above_on_the_left() {
        let table = CaseTable::binary();
        let mid = |e: u8| {
            let [a, b] = EDGES[usize::from(e)];
            let (pa, pb) = (VERTICES[usize::from(a)], VERTICES[usize::from(b)]);
            [0, 1, 2].map(|i| (pa[i] as f64 + pb[i] as f64) / 2.0)
        };
        for config in 1..=254u8 {
            for d in decision_patterns(config) {
                for poly in table.polygons(config, d) {
                    for (f, a, b) in polygon_segments(poly) {
                        let (ea, eb) = (a.as_edge().unwrap(), b.as_edge().unwrap());
                        let (pa, pb) = (mid(ea), mid(eb));
                        let c = FACES[f].map(|v| VERTICES[usize::from(v)].map(f64::from));
                        let centre = [0, 1, 2].map(|i| c.iter().map(|p| p[i]).sum::<f64>() / 4.0);
                        let n = [0, 1, 2].map(|i| centre[i] - 0.5);
                        let t = [0, 1, 2].map(|i| pb[i] - pa[i]);
                        let left = [
                            n[1] * t[2] - n[2] * t[1],
                            n[2] * t[0] - n[0] * t[2],
                            n[0] * t[1] - n[1] * t[0],
                        ];
                        let m = [0, 1, 2].map(|i| (pa[i] + pb[i]) / 2.0);
                        for v in EDGES[usize::from(ea)]
                            .into_iter()
                            .chain(EDGES[usize::from(eb)])
                        {
                            let p = VERTICES[usize::from(v)];
                            let side: f64 = (0..3).map(|i| left[i] * (p[i] as f64 - m[i])).sum();
                            let above = config >> v & 1 == 1;
                            assert!(side != 0.0);
                            assert_eq!(side > 0.0, above, "config {config} d {d:06b} face {f}");
                        }
                    }
                }
            }
        }
    }

    /// Two cells sharing a face emit the same segments on it, in opposite directions, for every
    /// face pattern (four corner signs and the decision).
    #[test]
    fn neighbours_agree_on_shared_faces() {
        // The vertex across face f (on the neighbour's opposite face) of each vertex of f.
        let across = |f: usize, v: u8| -> u8 {
            let axis = (0..3)
                .find(|&a| {
                    FACES[f].iter().all(|&w| {
                        VERTICES[usize::from(w)][a] == VERTICES[usize::from(FACES[f][0])][a]
                    })
                })
                .unwrap();
            let mut c = VERTICES[usize::from(v)];
            c[axis] = 1 - c[axis];
            crate::cube::vertex_at(c[0], c[1], c[2])
        };
        let edge_across = |f: usize, e: u8| -> u8 {
            let [a, b] = EDGES[usize::from(e)];
            crate::cube::edge_between(across(f, a), across(f, b)).unwrap()
        };
        let on_face = |config: u8, d: u8, f: usize| -> Vec<(u8, u8)> {
            let mut s: Vec<(u8, u8)> = CaseTable::binary()
                .polygons(config, d)
                .flat_map(polygon_segments)
                .filter(|&(face, _, _)| face == f)
                .map(|(_, a, b)| (a.as_edge().unwrap(), b.as_edge().unwrap()))
                .collect();
            s.sort_unstable();
            s
        };
        let mut checked = 0;
        for f in [1usize, 2, 5] {
            let g = OPPOSITE_FACE[f] as usize;
            for c1 in 0..=255u8 {
                for d1 in decision_patterns(c1) {
                    let mine = on_face(c1, d1, f);
                    for c2 in 0..=255u8 {
                        let same_face_values = FACES[f]
                            .iter()
                            .all(|&v| (c1 >> v & 1) == (c2 >> across(f, v) & 1));
                        if !same_face_values {
                            continue;
                        }
                        for d2 in decision_patterns(c2) {
                            let amb = ambiguous_faces(c2) >> g & 1 == 1;
                            if amb && (d2 >> g & 1) != (d1 >> f & 1) {
                                continue;
                            }
                            let mut theirs: Vec<(u8, u8)> = on_face(c2, d2, g)
                                .into_iter()
                                .map(|(a, b)| (edge_across(f, b), edge_across(f, a)))
                                .collect();
                            theirs.sort_unstable();
                            assert_eq!(mine, theirs, "face {f}: {c1}/{d1:06b} vs {c2}/{d2:06b}");
                            checked += 1;
                        }
                    }
                }
            }
        }
        assert!(checked > 10_000);
    }

    #[test]
    fn triangle_counts_and_interior_points() {
        use crate::cube::Topology;
        let table = CaseTable::binary();
        let mut stars = 0;
        for config in 0..=255u8 {
            for d in decision_patterns(config) {
                for topology in [Topology::Classic, Topology::Mc33] {
                    let cell = table.cell_triangles(config, d, topology, None);
                    let mut expected = 0;
                    let mut star_polygons = 0;
                    for p in table.polygons(config, d) {
                        let big =
                            topology == Topology::Mc33 && p.len() >= CaseTable::MC33_STAR_CORNERS;
                        if !big && safe_triangulation(p).is_some() {
                            expected += p.len() - 2;
                        } else {
                            expected += p.len();
                            star_polygons += 1;
                        }
                    }
                    assert_eq!(cell.triangles.len(), expected);
                    assert!(star_polygons <= 1);
                    assert_eq!(cell.interior_count(), star_polygons);
                    let uses = cell
                        .triangles
                        .iter()
                        .flatten()
                        .any(|&c| c == Corner::INTERIOR);
                    assert_eq!(uses, star_polygons == 1);
                    if topology == Topology::Classic {
                        stars += star_polygons;
                    }
                    // Configurations without ambiguous faces are plain fans.
                    if ambiguous_faces(config) == 0 {
                        assert_eq!(star_polygons, 0);
                    }
                }
            }
        }
        assert!(
            stars <= 16,
            "{stars} classic variants need an interior point"
        );
    }

    #[test]
    fn pack_unpack_round_trip() {
        for mask in 0..64u8 {
            for p in 0..(1u32 << mask.count_ones()) {
                assert_eq!(pack(mask, unpack(mask, p)), p);
            }
        }
    }
}
