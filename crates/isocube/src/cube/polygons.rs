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
//! The [`CaseTable`] derives polygons this way only for the 14 class representatives under the
//! full group (rotations, mirror, flip) and every decision pattern of their ambiguous faces, and
//! obtains all 256 configurations through their transforms: corners are mapped by the edge
//! permutation, face decisions by the face permutation (inverted under flip, since above and below
//! trade places), and the loops reversed when the transform mirrors or flips.
//!
//! Triangulation here is a fan where possible. A diagonal joining two crossings of one ambiguous
//! face could be produced by the neighbouring cell too, and the edge would then belong to four
//! triangles; [`safe_triangulation`] allows such diagonals only across positive faces and picks
//! a fan apex, or another triangulation with the same `n − 2` triangles, within that rule.

use std::collections::HashMap;
use std::sync::OnceLock;

use super::config::{ClassTable, ConfigKind, Group};
use super::symmetry::Transform;
use super::{FACES, FACE_EDGES};

/// One bit per face: bit `f` set means the above corners of face `f` are joined through the
/// face. Only bits of ambiguous faces (four crossings) matter.
pub type FaceDecisions = u8;

/// A polygon corner: a crossing on a cube edge (0..12), a cube vertex (12..20, for ternary
/// configurations) or a point inside the cell (20).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Corner(u8);

impl Corner {
    /// A point inside the cell.
    pub const INTERIOR: Corner = Corner(20);

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

    /// The raw code: 0..12 edges, 12..20 vertices, 20 interior.
    pub fn code(self) -> u8 {
        self.0
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
    pub fn faces(self) -> u8 {
        let mut mask = 0;
        for f in 0..6 {
            let on = if let Some(e) = self.as_edge() {
                FACE_EDGES[f].contains(&e)
            } else if let Some(v) = self.as_vertex() {
                FACES[f].contains(&v)
            } else {
                false
            };
            if on {
                mask |= 1 << f;
            }
        }
        mask
    }
}

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

/// Triangulation that never puts a diagonal where the neighbouring cell might put the same one.
///
/// Two corners of a polygon that lie on a common face but are not consecutive can only occur on
/// an ambiguous face (four crossings). The cell across that face sees the same four crossings and
/// might join the same two, giving an edge of four triangles. So such diagonals are allowed only
/// across the cell's positive faces (x=1, y=1, z=1): the neighbour sees that face as a negative
/// one and never uses it. Within that rule the triangulation is a fan when some apex allows one,
/// otherwise any triangulation found by dynamic programming over sub-polygons (at most 12
/// corners). Always `n − 2` triangles.
///
/// Returns `None` when no such triangulation exists (the caller then needs an interior point).
pub fn safe_triangulation(polygon: &[Corner]) -> Option<Vec<[Corner; 3]>> {
    let n = polygon.len();
    let allowed = |i: usize, j: usize| {
        let d = i.abs_diff(j);
        d == 1 || d == n - 1 || polygon[i].faces() & polygon[j].faces() & NEGATIVE_FACES == 0
    };
    if let Some(apex) = (0..n).find(|&k| (0..n).all(|j| allowed(k, j) || j == k)) {
        return Some(
            (1..n - 1)
                .map(|i| {
                    [
                        polygon[apex],
                        polygon[(apex + i) % n],
                        polygon[(apex + i + 1) % n],
                    ]
                })
                .collect(),
        );
    }
    // split[i][j]: a corner k that splits the sub-polygon i..=j (closed by chord i–j) into two
    // triangulable parts, if any.
    let mut split = vec![vec![None::<usize>; n]; n];
    for len in 2..n {
        for i in 0..n - len {
            let j = i + len;
            if !allowed(i, j) {
                continue;
            }
            split[i][j] = (i + 1..j).find(|&k| {
                (k == i + 1 || split[i][k].is_some()) && (k + 1 == j || split[k][j].is_some())
            });
        }
    }
    split[0][n - 1]?;
    let mut triangles = Vec::with_capacity(n - 2);
    let mut stack = vec![(0, n - 1)];
    while let Some((i, j)) = stack.pop() {
        if j - i < 2 {
            continue;
        }
        let k = split[i][j].expect("sub-polygons of a found split are triangulable");
        triangles.push([polygon[i], polygon[k], polygon[j]]);
        stack.push((i, k));
        stack.push((k, j));
    }
    Some(triangles)
}

/// Faces y=0, x=0 and z=0.
const NEGATIVE_FACES: u8 = 1 << 0 | 1 << 3 | 1 << 4;

/// Triangles of a polygon around an interior point (used when no safe fan exists).
pub fn star(polygon: &[Corner]) -> Vec<[Corner; 3]> {
    let n = polygon.len();
    (0..n)
        .map(|i| [polygon[i], polygon[(i + 1) % n], Corner::INTERIOR])
        .collect()
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

#[derive(Clone, Copy, Debug, Default)]
struct Variant {
    polygons: (u32, u32),
    triangles: (u32, u32),
    /// The polygon (index into `polygon_ranges`) triangulated around an interior point.
    interior: Option<u32>,
}

/// Polygons and fan triangles of every binary configuration and face-decision pattern.
///
/// Look-up at run time is two array reads: the configuration's entry gives its ambiguous faces
/// and the first of its `2^k` variants (k ambiguous faces); the decisions of those faces, packed
/// in face order, select the variant.
#[derive(Clone, Debug)]
pub struct CaseTable {
    ambiguous: [u8; 256],
    first_variant: [u32; 257],
    variants: Vec<Variant>,
    polygon_ranges: Vec<(u32, u32)>,
    corners: Vec<Corner>,
    triangles: Vec<[Corner; 3]>,
}

impl CaseTable {
    /// The shared binary table, built once (a fraction of a millisecond).
    pub fn binary() -> &'static CaseTable {
        static TABLE: OnceLock<CaseTable> = OnceLock::new();
        TABLE.get_or_init(CaseTable::build_binary)
    }

    fn build_binary() -> CaseTable {
        let classes = ClassTable::get(ConfigKind::Binary, Group::All);
        // The only polygons derived from face signs: those of the 14 class representatives,
        // for every decision pattern of their ambiguous faces.
        let representative_polygons: HashMap<(u8, FaceDecisions), Vec<Vec<Corner>>> = classes
            .representatives()
            .iter()
            .flat_map(|&rep| {
                let rep = rep as u8;
                decision_patterns(rep).map(move |d| ((rep, d), derive_polygons(rep, d)))
            })
            .collect();
        let mut table = CaseTable {
            ambiguous: [0; 256],
            first_variant: [0; 257],
            variants: Vec::new(),
            polygon_ranges: Vec::new(),
            corners: Vec::new(),
            triangles: Vec::new(),
        };
        for config in 0..256usize {
            let entry = classes.entry(config);
            let t = entry.transform;
            let rep = entry.representative as u8;
            let amb = ambiguous_faces(config as u8);
            table.ambiguous[config] = amb;
            table.first_variant[config] = table.variants.len() as u32;
            let face_map = t.face_map();
            for packed in 0..(1u32 << amb.count_ones()) {
                let decisions = unpack(amb, packed);
                // Decision on the representative's face f is the configuration's decision on
                // face g(f), inverted under flip (joined above ↔ joined below).
                let mut rep_decisions = 0u8;
                for (f, &image) in face_map.iter().enumerate() {
                    let bit = decisions >> image & 1;
                    rep_decisions |= (bit ^ u8::from(t.flip)) << f;
                }
                let key = (rep, rep_decisions & ambiguous_faces(rep));
                let polygons = transform_polygons(&representative_polygons[&key], t);
                table.push_variant(&polygons);
            }
        }
        table.first_variant[256] = table.variants.len() as u32;
        table
    }

    fn push_variant(&mut self, polygons: &[Vec<Corner>]) {
        let p0 = self.polygon_ranges.len() as u32;
        let t0 = self.triangles.len() as u32;
        let mut interior = None;
        for p in polygons {
            let c0 = self.corners.len() as u32;
            self.corners.extend_from_slice(p);
            match safe_triangulation(p) {
                Some(tris) => self.triangles.extend(tris),
                None => {
                    // Rare (a dozen variants of two classes); one polygon per variant at most,
                    // checked by the tests, so a cell needs one interior point at most.
                    debug_assert!(interior.is_none());
                    interior = Some(self.polygon_ranges.len() as u32);
                    self.triangles.extend(star(p));
                }
            }
            self.polygon_ranges.push((c0, self.corners.len() as u32));
        }
        self.variants.push(Variant {
            polygons: (p0, self.polygon_ranges.len() as u32),
            triangles: (t0, self.triangles.len() as u32),
            interior,
        });
    }

    /// The ambiguous faces of a configuration (mask).
    #[inline]
    pub fn ambiguous_faces(&self, config: u8) -> u8 {
        self.ambiguous[usize::from(config)]
    }

    #[inline]
    fn variant(&self, config: u8, decisions: FaceDecisions) -> &Variant {
        let amb = self.ambiguous[usize::from(config)];
        let first = self.first_variant[usize::from(config)] as usize;
        &self.variants[first + pack(amb, decisions) as usize]
    }

    /// The fan triangles of a configuration under the given face decisions.
    #[inline]
    pub fn triangles(&self, config: u8, decisions: FaceDecisions) -> &[[Corner; 3]] {
        let v = self.variant(config, decisions);
        &self.triangles[v.triangles.0 as usize..v.triangles.1 as usize]
    }

    /// The polygons of a configuration under the given face decisions.
    pub fn polygons(
        &self,
        config: u8,
        decisions: FaceDecisions,
    ) -> impl Iterator<Item = &[Corner]> + '_ {
        let v = *self.variant(config, decisions);
        (v.polygons.0..v.polygons.1).map(move |p| {
            let (a, b) = self.polygon_ranges[p as usize];
            &self.corners[a as usize..b as usize]
        })
    }

    /// The polygon whose triangles use [`Corner::INTERIOR`], if any: the interior point is then
    /// placed from that polygon's corners.
    #[inline]
    pub fn interior_polygon(&self, config: u8, decisions: FaceDecisions) -> Option<&[Corner]> {
        let p = self.variant(config, decisions).interior?;
        let (a, b) = self.polygon_ranges[p as usize];
        Some(&self.corners[a as usize..b as usize])
    }

    /// Number of variants that need an interior point.
    pub fn interior_variant_count(&self) -> usize {
        self.variants
            .iter()
            .filter(|v| v.interior.is_some())
            .count()
    }

    /// Total number of stored variants (configurations × decision patterns).
    pub fn variant_count(&self) -> usize {
        self.variants.len()
    }
}

/// Packs the bits of `decisions` at the faces in `mask` into consecutive low bits.
#[inline]
fn pack(mask: u8, decisions: FaceDecisions) -> u32 {
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

fn unpack(mask: u8, packed: u32) -> FaceDecisions {
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
    use crate::cube::{EDGES, OPPOSITE_FACE, VERTICES};

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
        let table = CaseTable::binary();
        let mut stars = 0;
        for config in 0..=255u8 {
            for d in decision_patterns(config) {
                let tris = table.triangles(config, d);
                let mut expected = 0;
                let mut star_polygons = 0;
                for p in table.polygons(config, d) {
                    if safe_triangulation(p).is_some() {
                        expected += p.len() - 2;
                    } else {
                        expected += p.len();
                        star_polygons += 1;
                    }
                }
                assert_eq!(tris.len(), expected);
                assert!(star_polygons <= 1);
                assert_eq!(
                    table.interior_polygon(config, d).is_some(),
                    star_polygons == 1
                );
                let uses = tris.iter().flatten().any(|&c| c == Corner::INTERIOR);
                assert_eq!(uses, star_polygons == 1);
                stars += star_polygons;
                // Configurations without ambiguous faces are plain fans.
                if ambiguous_faces(config) == 0 {
                    assert_eq!(star_polygons, 0);
                }
            }
        }
        assert_eq!(stars, table.interior_variant_count());
        assert!(stars <= 16, "{stars} variants need an interior point");
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
