//! Polygons of ternary configurations (vertices below, at, or above the level).
//!
//! A zero vertex is a point of the surface. The polygons of a ternary configuration are those
//! of its *binary skeleton*, the binary configuration in which zero vertices count on one side
//! (the tie rule), with every crossing on an edge that ends at a zero vertex moved onto that
//! vertex: the limit of the binary surface as the zero vertices' values reach the level.
//! Corners that coincide are merged, loops left with fewer than three corners vanish (the
//! surface only touches the vertex there), and a loop that passes twice through a vertex is split
//! there into two loops that touch (a pinch: the extractor never makes one, see
//! [`crate::extract`]).
//!
//! The tie rule matters only at degenerate spots: a face entirely at zero between a cell above
//! and a cell below is the surface and must be emitted by exactly one of the two cells. Under the
//! rule *zero counts as above* (the library's rule for values equal to the level, used by
//! extraction) the cell whose other vertices are below emits it. Sign flip exchanges the two
//! rules, which is why a table under rotations **and** flip carries both: a configuration
//! obtained from its class representative by a flipping transform takes the representative's
//! polygons under the other rule. [`TernaryTable`] is built that way, from the 183 classes under
//! rotations and flip, and checked against direct derivation for all 6561 configurations.
//!
//! ```
//! use isocube::cube::{ConfigKind, TernaryTable, TieRule};
//! let table = TernaryTable::get();
//! // Vertex 0 at the level, the rest above: the surface only touches vertex 0.
//! let config = ConfigKind::Ternary.index([1, 2, 2, 2, 2, 2, 2, 2]);
//! assert_eq!(table.polygons(config, 0).count(), 0);
//! // Vertices 0 and 1 at the level, 3 and 2 above, the top face below: a quad through the two
//! // zero vertices and the crossings on the vertical edges 10 and 11.
//! let config = ConfigKind::Ternary.index([1, 1, 2, 2, 0, 0, 0, 0]);
//! let loops: Vec<_> = table.polygons(config, 0).collect();
//! assert_eq!(loops.len(), 1);
//! assert_eq!(loops[0].len(), 4);
//! assert_eq!(table.tie_rule(), TieRule::Above);
//! ```

use std::collections::HashMap;
use std::sync::OnceLock;

use super::config::{ClassTable, ConfigKind, Group};
use super::polygons::{
    ambiguous_faces, derive_polygons, transform_polygons, unpack, Corner, FaceDecisions,
};
use super::EDGES;

/// Which side zero vertices count on in a ternary configuration's binary skeleton.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum TieRule {
    /// Zero counts as above (the library's rule for values equal to the level).
    Above,
    /// Zero counts as below.
    Below,
}

impl TieRule {
    /// The other rule (what sign flip turns this one into).
    pub fn flipped(self) -> TieRule {
        match self {
            TieRule::Above => TieRule::Below,
            TieRule::Below => TieRule::Above,
        }
    }
}

/// The binary skeleton of a ternary configuration: `(binary configuration, zero-vertex mask)`.
pub fn skeleton(ternary: usize, rule: TieRule) -> (u8, u8) {
    let digits = ConfigKind::Ternary.digits(ternary);
    let mut above = 0u8;
    let mut zero = 0u8;
    for (v, &d) in digits.iter().enumerate() {
        if d == 1 {
            zero |= 1 << v;
        }
        let is_above = match rule {
            TieRule::Above => d >= 1,
            TieRule::Below => d == 2,
        };
        if is_above {
            above |= 1 << v;
        }
    }
    (above, zero)
}

/// Moves every crossing on an edge ending at a zero vertex (bit set in `zero`) onto that vertex
/// and cleans the loops: repeated corners merged, loops of fewer than three corners dropped,
/// loops through a vertex twice split there.
///
/// An edge with both ends zero carries no crossing in a skeleton (both ends are on the same side),
/// so the vertex is unique.
pub fn collapse(loops: &[Vec<Corner>], zero: u8) -> Vec<Vec<Corner>> {
    let mut out = Vec::new();
    for l in loops {
        let mut mapped: Vec<Corner> = Vec::with_capacity(l.len());
        for &c in l {
            mapped.push(collapse_corner(c, zero));
        }
        mapped.dedup();
        while mapped.len() > 1 && mapped.first() == mapped.last() {
            mapped.pop();
        }
        split_pinches(mapped, &mut out);
    }
    out
}

/// A corner after collapse onto the zero vertices in `zero`.
pub fn collapse_corner(c: Corner, zero: u8) -> Corner {
    match c.as_edge() {
        Some(e) => {
            let [a, b] = EDGES[usize::from(e)];
            if zero >> a & 1 == 1 {
                Corner::vertex(a)
            } else if zero >> b & 1 == 1 {
                Corner::vertex(b)
            } else {
                c
            }
        }
        None => c,
    }
}

fn split_pinches(l: Vec<Corner>, out: &mut Vec<Vec<Corner>>) {
    for i in 0..l.len() {
        if let Some(j) = (i + 1..l.len()).find(|&j| l[j] == l[i]) {
            let inner: Vec<Corner> = l[i..j].to_vec();
            let outer: Vec<Corner> = l[..i].iter().chain(&l[j..]).copied().collect();
            split_pinches(inner, out);
            split_pinches(outer, out);
            return;
        }
    }
    if l.len() >= 3 {
        out.push(l);
    }
}

/// Derives a ternary configuration's polygons directly, without the symmetry group.
/// `decisions` are for the ambiguous faces of the skeleton (bit `f`: above corners joined).
pub fn derive_ternary_polygons(
    ternary: usize,
    decisions: FaceDecisions,
    rule: TieRule,
) -> Vec<Vec<Corner>> {
    let (binary, zero) = skeleton(ternary, rule);
    collapse(&derive_polygons(binary, decisions), zero)
}

/// The polygons of all 6561 ternary configurations under every decision pattern of their
/// skeleton's ambiguous faces, with zero counting as above.
pub struct TernaryTable {
    ambiguous: Vec<u8>,
    first_variant: Vec<u32>,
    variants: Vec<(u32, u32)>,
    loops: Vec<(u32, u32)>,
    corners: Vec<Corner>,
}

impl TernaryTable {
    /// The shared table, built once from the 183 classes under rotations and flip.
    pub fn get() -> &'static TernaryTable {
        static TABLE: OnceLock<TernaryTable> = OnceLock::new();
        TABLE.get_or_init(TernaryTable::build)
    }

    fn build() -> TernaryTable {
        let classes = ClassTable::get(ConfigKind::Ternary, Group::RotationsFlip);
        // The representatives' polygons under both rules: flip exchanges them.
        let mut rep_polygons: HashMap<(u16, TieRule, FaceDecisions), Vec<Vec<Corner>>> =
            HashMap::new();
        for &rep in classes.representatives() {
            for rule in [TieRule::Above, TieRule::Below] {
                let (binary, _) = skeleton(usize::from(rep), rule);
                let amb = ambiguous_faces(binary);
                for packed in 0..1u32 << amb.count_ones() {
                    let d = unpack(amb, packed);
                    rep_polygons.insert(
                        (rep, rule, d),
                        derive_ternary_polygons(usize::from(rep), d, rule),
                    );
                }
            }
        }
        let mut table = TernaryTable {
            ambiguous: Vec::with_capacity(6561),
            first_variant: Vec::with_capacity(6562),
            variants: Vec::new(),
            loops: Vec::new(),
            corners: Vec::new(),
        };
        for config in 0..ConfigKind::Ternary.count() {
            let entry = classes.entry(config);
            let t = entry.transform;
            let rule = if t.flip {
                TieRule::Below
            } else {
                TieRule::Above
            };
            let (binary, _) = skeleton(config, TieRule::Above);
            let amb = ambiguous_faces(binary);
            let (rep_binary, _) = skeleton(usize::from(entry.representative), rule);
            let rep_amb = ambiguous_faces(rep_binary);
            table.ambiguous.push(amb);
            table.first_variant.push(table.variants.len() as u32);
            let face_map = t.face_map();
            for packed in 0..1u32 << amb.count_ones() {
                let decisions = unpack(amb, packed);
                // As for the binary table: the representative's face f is this configuration's
                // face g(f); flip exchanges "above joined" and "below joined".
                let mut rep_decisions = 0u8;
                for (f, &image) in face_map.iter().enumerate() {
                    rep_decisions |= ((decisions >> image & 1) ^ u8::from(t.flip)) << f;
                }
                let loops = transform_polygons(
                    &rep_polygons[&(entry.representative, rule, rep_decisions & rep_amb)],
                    t,
                );
                let l0 = table.loops.len() as u32;
                for l in &loops {
                    let c0 = table.corners.len() as u32;
                    table.corners.extend_from_slice(l);
                    table.loops.push((c0, table.corners.len() as u32));
                }
                table.variants.push((l0, table.loops.len() as u32));
            }
        }
        table.first_variant.push(table.variants.len() as u32);
        table
    }

    /// The rule the table's skeletons use: [`TieRule::Above`].
    pub fn tie_rule(&self) -> TieRule {
        TieRule::Above
    }

    /// The ambiguous faces of a configuration's skeleton (mask): the faces whose decisions
    /// select among its variants.
    pub fn ambiguous_faces(&self, ternary: usize) -> u8 {
        self.ambiguous[ternary]
    }

    /// The loops of a configuration under the given decisions (bits of non-ambiguous faces are
    /// ignored).
    pub fn polygons(
        &self,
        ternary: usize,
        decisions: FaceDecisions,
    ) -> impl Iterator<Item = &[Corner]> + '_ {
        let amb = self.ambiguous[ternary];
        let packed = super::polygons::pack(amb, decisions);
        let (a, b) = self.variants[self.first_variant[ternary] as usize + packed as usize];
        (a..b).map(move |l| {
            let (c0, c1) = self.loops[l as usize];
            &self.corners[c0 as usize..c1 as usize]
        })
    }

    /// Writes the table as tab-separated values: one row per configuration and decision pattern,
    /// with its class under rotations and flip, the representative, the transform from it (the
    /// 7 bits of [`crate::cube::Transform::bits`]), the decisions (`f1=1`: the above corners of
    /// face 1 are joined) and the loops (`e0`…`e11` crossings, `v0`…`v7` zero vertices, loops
    /// separated by ` | `, `-` for none).
    pub fn write_tsv(&self, out: &mut impl std::io::Write) -> std::io::Result<()> {
        self.write_rows(out, ConfigKind::Ternary, |c| c)
    }

    /// The same listing for the 256 binary configurations (the ternary ones without zeros).
    pub fn write_binary_tsv(&self, out: &mut impl std::io::Write) -> std::io::Result<()> {
        self.write_rows(out, ConfigKind::Binary, |binary| {
            let digits: [u8; 8] = std::array::from_fn(|v| if binary >> v & 1 == 1 { 2 } else { 0 });
            ConfigKind::Ternary.index(digits)
        })
    }

    fn write_rows(
        &self,
        out: &mut impl std::io::Write,
        kind: ConfigKind,
        ternary_of: impl Fn(usize) -> usize,
    ) -> std::io::Result<()> {
        let classes = ClassTable::get(kind, Group::RotationsFlip);
        writeln!(
            out,
            "config\tdigits\tclass\trepresentative\ttransform\tdecisions\tpolygons"
        )?;
        for config in 0..kind.count() {
            let entry = classes.entry(config);
            let ternary = ternary_of(config);
            let digits: String = ConfigKind::Ternary
                .digits(ternary)
                .iter()
                .map(|d| ['-', '0', '+'][usize::from(*d)])
                .collect();
            let amb = self.ambiguous[ternary];
            for packed in 0..1u32 << amb.count_ones() {
                let decisions = unpack(amb, packed);
                let decided: Vec<String> = (0..6)
                    .filter(|f| amb >> f & 1 == 1)
                    .map(|f| format!("f{f}={}", decisions >> f & 1))
                    .collect();
                let loops: Vec<String> = self
                    .polygons(ternary, decisions)
                    .map(|l| {
                        l.iter()
                            .map(|c| match (c.as_edge(), c.as_vertex()) {
                                (Some(e), _) => format!("e{e}"),
                                (_, Some(v)) => format!("v{v}"),
                                _ => format!("c{}", c.code()),
                            })
                            .collect::<Vec<_>>()
                            .join(" ")
                    })
                    .collect();
                writeln!(
                    out,
                    "{config}\t{digits}\t{}\t{}\t{}\t{}\t{}",
                    entry.class,
                    entry.representative,
                    entry.transform.bits(),
                    if decided.is_empty() {
                        "-".to_string()
                    } else {
                        decided.join(",")
                    },
                    if loops.is_empty() {
                        "-".to_string()
                    } else {
                        loops.join(" | ")
                    }
                )?;
            }
        }
        Ok(())
    }

    /// Number of stored variants (configurations × decision patterns).
    pub fn variant_count(&self) -> usize {
        self.variants.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cube::polygons::canonical;
    use crate::cube::{CaseTable, Topology};

    fn table_loops(t: &TernaryTable, config: usize, d: FaceDecisions) -> Vec<Vec<Corner>> {
        canonical(
            &t.polygons(config, d)
                .map(<[Corner]>::to_vec)
                .collect::<Vec<_>>(),
        )
    }

    /// The table, built from 183 representatives through the group, equals direct derivation for
    /// every configuration and decision pattern.
    #[test]
    fn table_equals_direct_derivation() {
        let t = TernaryTable::get();
        let mut variants = 0;
        for config in 0..6561 {
            let (binary, _) = skeleton(config, TieRule::Above);
            let amb = ambiguous_faces(binary);
            assert_eq!(t.ambiguous_faces(config), amb);
            for packed in 0..1u32 << amb.count_ones() {
                let d = unpack(amb, packed);
                let direct = canonical(&derive_ternary_polygons(config, d, TieRule::Above));
                assert_eq!(
                    table_loops(t, config, d),
                    direct,
                    "config {config}, decisions {d:06b}"
                );
                variants += 1;
            }
        }
        assert_eq!(variants, t.variant_count());
        assert_eq!(
            ClassTable::get(ConfigKind::Ternary, Group::RotationsFlip).class_count(),
            183
        );
    }

    /// Without zero vertices the table is the binary one.
    #[test]
    fn binary_configurations_match_the_binary_table() {
        let t = TernaryTable::get();
        for binary in 0..256u32 {
            let digits: [u8; 8] = std::array::from_fn(|v| if binary >> v & 1 == 1 { 2 } else { 0 });
            let config = ConfigKind::Ternary.index(digits);
            for d in super::super::polygons::decision_patterns(binary as u8) {
                let expected = canonical(&derive_polygons(binary as u8, d));
                assert_eq!(table_loops(t, config, d), expected);
            }
        }
    }

    /// Flip exchanges the tie rules: the polygons of a flipped configuration under one rule are
    /// the reversed polygons of the configuration under the other, with decisions inverted.
    #[test]
    fn flip_exchanges_the_tie_rules() {
        for config in 0..6561 {
            let flipped = ConfigKind::Ternary.flip(config);
            let (binary, _) = skeleton(config, TieRule::Below);
            let amb = ambiguous_faces(binary);
            for packed in 0..1u32 << amb.count_ones() {
                let d = unpack(amb, packed);
                let mut reversed = derive_ternary_polygons(config, d, TieRule::Below);
                for l in &mut reversed {
                    l.reverse();
                }
                assert_eq!(
                    canonical(&derive_ternary_polygons(flipped, !d & amb, TieRule::Above)),
                    canonical(&reversed),
                    "config {config}"
                );
            }
        }
    }

    /// What extraction does — collapse the binary skeleton's triangles — has exactly the table's
    /// polygons as its boundary, for every configuration and decision pattern (classic topology;
    /// MC33 only adds interior structure inside the same boundary).
    #[test]
    fn collapsed_triangles_are_bounded_by_the_table_polygons() {
        let t = TernaryTable::get();
        let binary_table = CaseTable::binary();
        for config in 0..6561 {
            let (binary, zero) = skeleton(config, TieRule::Above);
            let amb = ambiguous_faces(binary);
            for packed in 0..1u32 << amb.count_ones() {
                let d = unpack(amb, packed);
                let cell = binary_table.cell_triangles(binary, d, Topology::Classic, None);
                let mut half_edges: Vec<(Corner, Corner)> = Vec::new();
                for tri in cell.triangles {
                    let k = tri.map(|c| collapse_corner(c, zero));
                    if k[0] == k[1] || k[1] == k[2] || k[0] == k[2] {
                        continue;
                    }
                    for i in 0..3 {
                        half_edges.push((k[i], k[(i + 1) % 3]));
                    }
                }
                // Boundary: half-edges whose twin is absent (pairs cancel).
                let mut boundary: Vec<(Corner, Corner)> = half_edges
                    .iter()
                    .copied()
                    .filter(|&(a, b)| {
                        let fwd = half_edges.iter().filter(|&&h| h == (a, b)).count();
                        let back = half_edges.iter().filter(|&&h| h == (b, a)).count();
                        fwd > back
                    })
                    .collect();
                boundary.sort();
                boundary.dedup();
                let mut expected: Vec<(Corner, Corner)> = t
                    .polygons(config, d)
                    .flat_map(|l| (0..l.len()).map(move |i| (l[i], l[(i + 1) % l.len()])))
                    .collect();
                expected.sort();
                expected.dedup();
                // Pinched loops (a vertex visited twice) cancel segments in both; compare the
                // net boundary.
                let net = |v: &[(Corner, Corner)]| -> Vec<(Corner, Corner)> {
                    v.iter()
                        .copied()
                        .filter(|&(a, b)| !v.contains(&(b, a)))
                        .collect()
                };
                assert_eq!(
                    net(&boundary),
                    net(&expected),
                    "config {config}, decisions {d:06b}"
                );
            }
        }
    }

    /// The degenerate situations the third value creates, one by one.
    #[test]
    fn degenerate_situations() {
        let t = TernaryTable::get();
        let idx = |d: [u8; 8]| ConfigKind::Ternary.index(d);
        let count = |d: [u8; 8]| t.polygons(idx(d), 0).count();
        // An isolated zero vertex touching from above or below: nothing.
        assert_eq!(count([1, 2, 2, 2, 2, 2, 2, 2]), 0);
        assert_eq!(count([1, 0, 0, 0, 0, 0, 0, 0]), 0);
        // Face z=0 entirely at zero: the surface when the rest is below (zero counts as above,
        // so this cell emits it) and nothing when the rest is above (the cell on the other side
        // emits it).
        let face: Vec<Vec<Corner>> = t
            .polygons(idx([1, 1, 1, 1, 0, 0, 0, 0]), 0)
            .map(<[Corner]>::to_vec)
            .collect();
        assert_eq!(face.len(), 1);
        let mut corners = face[0].clone();
        corners.sort();
        assert_eq!(corners, [0, 1, 2, 3].map(Corner::vertex));
        assert_eq!(count([1, 1, 1, 1, 2, 2, 2, 2]), 0);
        // An edge at zero between an above face and a below face: the loop runs along it.
        let l: Vec<Vec<Corner>> = t
            .polygons(idx([1, 1, 2, 2, 0, 0, 0, 0]), 0)
            .map(<[Corner]>::to_vec)
            .collect();
        assert_eq!(l.len(), 1);
        assert!(l[0].contains(&Corner::vertex(0)) && l[0].contains(&Corner::vertex(1)));
        // Zero vertices on an ambiguous face: 0 and 2 at zero, 1 and 3 opposite signs — the
        // surface runs along the face's diagonal.
        let l: Vec<Vec<Corner>> = t
            .polygons(idx([1, 2, 1, 0, 0, 2, 0, 0]), 0)
            .map(<[Corner]>::to_vec)
            .collect();
        assert!(!l.is_empty());
        let through = l
            .iter()
            .any(|p| p.contains(&Corner::vertex(0)) && p.contains(&Corner::vertex(2)));
        assert!(through, "{l:?}");
    }
}
