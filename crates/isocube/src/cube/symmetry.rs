//! The symmetry group of the cube, generated rather than typed in.
//!
//! The 24 rotations are the closure of the three quarter turns about the x, y and z axes through
//! the cube's centre, listed in breadth-first order from the identity (so rotation 0 is the
//! identity and the numbering is stable). Adding the mirror `x ↦ 1 − x` gives the 48 isometries,
//! and the sign flip (complement: above ↔ below) doubles that to 96 operations.
//!
//! A [`Transform`] is one of those 96 operations, packed in 7 bits: the rotation index in bits
//! 0–4, the mirror in bit 5 and the flip in bit 6. Its geometric part acts on the cube by first
//! mirroring (if set) and then rotating. It maps a configuration `c` to `g·c` with
//! `(g·c)(g(v)) = c(v)` (complemented when the flip bit is set). Mirror and flip each reverse the
//! orientation of the surface, so triangle winding must be reversed when exactly one of them is
//! set ([`Transform::reverses_winding`]).

use std::sync::OnceLock;

use super::{edge_between, vertex_at, FACES, VERTICES};

type Matrix = [[i8; 3]; 3];

/// Index of one of the 24 rotations of the cube (0 is the identity).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Rotation(u8);

impl Rotation {
    /// Number of rotations of the cube.
    pub const COUNT: usize = 24;
    /// The identity rotation.
    pub const IDENTITY: Rotation = Rotation(0);

    /// The rotation with this index, if `index < 24`.
    pub fn new(index: u8) -> Option<Rotation> {
        (usize::from(index) < Self::COUNT).then_some(Rotation(index))
    }

    /// The index of this rotation (0..24).
    pub fn index(self) -> u8 {
        self.0
    }

    /// The rotation's 3×3 integer matrix, acting on coordinates centred on the cube's centre.
    pub fn matrix(self) -> [[i8; 3]; 3] {
        group().matrices[usize::from(self.0)]
    }

    /// All 24 rotations in their stable order.
    pub fn all() -> impl Iterator<Item = Rotation> {
        (0..Self::COUNT as u8).map(Rotation)
    }
}

/// One of the 96 operations of the cube's full symmetry group with sign flip.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Transform {
    /// The rotation, applied after the mirror.
    pub rotation: Rotation,
    /// Mirror `x ↦ 1 − x`, applied first.
    pub mirror: bool,
    /// Complement the values (above ↔ below; in ternary, + ↔ −, zero stays zero).
    pub flip: bool,
}

impl Transform {
    /// The identity.
    pub const IDENTITY: Transform = Transform {
        rotation: Rotation::IDENTITY,
        mirror: false,
        flip: false,
    };

    /// Packs the transform in 7 bits: rotation in bits 0–4, mirror in bit 5, flip in bit 6.
    pub fn bits(self) -> u8 {
        self.rotation.0 | (u8::from(self.mirror) << 5) | (u8::from(self.flip) << 6)
    }

    /// Unpacks [`Transform::bits`]; `None` for a rotation index ≥ 24 or bit 7 set.
    pub fn from_bits(bits: u8) -> Option<Transform> {
        if bits & 0x80 != 0 {
            return None;
        }
        Some(Transform {
            rotation: Rotation::new(bits & 0x1f)?,
            mirror: bits & 0x20 != 0,
            flip: bits & 0x40 != 0,
        })
    }

    /// Whether triangle winding must be reversed: exactly one of mirror and flip is set.
    pub fn reverses_winding(self) -> bool {
        self.mirror ^ self.flip
    }

    /// Where each vertex goes: `vertex_map()[v] = g(v)`.
    pub fn vertex_map(self) -> [u8; 8] {
        let g = group();
        g.vertex_maps[usize::from(self.rotation.0)][usize::from(self.mirror)]
    }

    /// Where each edge goes.
    pub fn edge_map(self) -> [u8; 12] {
        let g = group();
        g.edge_maps[usize::from(self.rotation.0)][usize::from(self.mirror)]
    }

    /// Where each face goes.
    pub fn face_map(self) -> [u8; 6] {
        let g = group();
        g.face_maps[usize::from(self.rotation.0)][usize::from(self.mirror)]
    }

    /// The inverse vertex map: `inverse_vertex_map()[g(v)] = v`.
    pub fn inverse_vertex_map(self) -> [u8; 8] {
        let map = self.vertex_map();
        let mut inv = [0u8; 8];
        for (v, &w) in map.iter().enumerate() {
            inv[usize::from(w)] = v as u8;
        }
        inv
    }

    /// Applies the transform to a configuration given as per-vertex digits in `0..base` (base 2:
    /// 0 below, 1 above; base 3: 0 below, 1 zero, 2 above).
    pub fn apply_digits(self, digits: [u8; 8], base: u8) -> [u8; 8] {
        let map = self.vertex_map();
        let mut out = [0u8; 8];
        for v in 0..8 {
            let d = digits[v];
            out[usize::from(map[v])] = if self.flip { base - 1 - d } else { d };
        }
        out
    }

    /// All 96 transforms, in the order used to pick the canonical transform of a configuration:
    /// no flip before flip, no mirror before mirror, then by rotation index.
    pub fn all() -> impl Iterator<Item = Transform> {
        [false, true].into_iter().flat_map(|flip| {
            [false, true].into_iter().flat_map(move |mirror| {
                Rotation::all().map(move |rotation| Transform {
                    rotation,
                    mirror,
                    flip,
                })
            })
        })
    }
}

struct Group {
    matrices: Vec<Matrix>,
    vertex_maps: Vec<[[u8; 8]; 2]>,
    edge_maps: Vec<[[u8; 12]; 2]>,
    face_maps: Vec<[[u8; 6]; 2]>,
}

fn group() -> &'static Group {
    static GROUP: OnceLock<Group> = OnceLock::new();
    GROUP.get_or_init(build_group)
}

fn mul(a: &Matrix, b: &Matrix) -> Matrix {
    let mut out = [[0i8; 3]; 3];
    for (i, row) in out.iter_mut().enumerate() {
        for (j, cell) in row.iter_mut().enumerate() {
            *cell = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    out
}

fn build_group() -> Group {
    const IDENTITY: Matrix = [[1, 0, 0], [0, 1, 0], [0, 0, 1]];
    // Quarter turns about x, y and z (right-handed).
    let generators: [Matrix; 3] = [
        [[1, 0, 0], [0, 0, -1], [0, 1, 0]],
        [[0, 0, 1], [0, 1, 0], [-1, 0, 0]],
        [[0, -1, 0], [1, 0, 0], [0, 0, 1]],
    ];
    let mut matrices = vec![IDENTITY];
    let mut next = 0;
    while next < matrices.len() {
        let m = matrices[next];
        for g in &generators {
            let n = mul(g, &m);
            if !matrices.contains(&n) {
                matrices.push(n);
            }
        }
        next += 1;
    }
    assert_eq!(
        matrices.len(),
        Rotation::COUNT,
        "the rotation group has 24 elements"
    );

    let mirror: Matrix = [[-1, 0, 0], [0, 1, 0], [0, 0, 1]];
    let act = |m: &Matrix, v: u8| -> u8 {
        // Centre the cube: coordinates 0/1 become −1/+1.
        let s = VERTICES[usize::from(v)].map(|c| 2 * c as i8 - 1);
        let r: [i8; 3] = [0, 1, 2].map(|i| (0..3).map(|k| m[i][k] * s[k]).sum());
        let c = r.map(|x| ((x + 1) / 2) as u8);
        vertex_at(c[0], c[1], c[2])
    };
    let mut vertex_maps = Vec::with_capacity(24);
    let mut edge_maps = Vec::with_capacity(24);
    let mut face_maps = Vec::with_capacity(24);
    for m in &matrices {
        let mut vm = [[0u8; 8]; 2];
        let mut em = [[0u8; 12]; 2];
        let mut fm = [[0u8; 6]; 2];
        for mirrored in 0..2 {
            let full = if mirrored == 1 { mul(m, &mirror) } else { *m };
            for v in 0..8u8 {
                vm[mirrored][usize::from(v)] = act(&full, v);
            }
            for (e, out) in em[mirrored].iter_mut().enumerate() {
                let [a, b] = super::EDGES[e];
                let (ga, gb) = (vm[mirrored][usize::from(a)], vm[mirrored][usize::from(b)]);
                *out = edge_between(ga, gb).expect("isometries keep edges");
            }
            for (f, out) in fm[mirrored].iter_mut().enumerate() {
                let mut image = FACES[f].map(|v| vm[mirrored][usize::from(v)]);
                image.sort_unstable();
                *out = (0..6u8)
                    .find(|&g| {
                        let mut c = FACES[usize::from(g)];
                        c.sort_unstable();
                        c == image
                    })
                    .expect("isometries keep faces");
            }
        }
        vertex_maps.push(vm);
        edge_maps.push(em);
        face_maps.push(fm);
    }
    Group {
        matrices,
        vertex_maps,
        edge_maps,
        face_maps,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashSet;

    fn det(m: &Matrix) -> i32 {
        let m = m.map(|r| r.map(i32::from));
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    }

    #[test]
    fn twenty_four_distinct_proper_rotations() {
        let maps: HashSet<[u8; 8]> = Rotation::all()
            .map(|r| {
                assert_eq!(det(&r.matrix()), 1);
                Transform {
                    rotation: r,
                    mirror: false,
                    flip: false,
                }
                .vertex_map()
            })
            .collect();
        assert_eq!(maps.len(), 24);
        assert_eq!(
            Rotation::IDENTITY.matrix(),
            [[1, 0, 0], [0, 1, 0], [0, 0, 1]]
        );
    }

    #[test]
    fn forty_eight_distinct_isometries_closed_under_composition() {
        let maps: HashSet<[u8; 8]> = Transform::all()
            .filter(|t| !t.flip)
            .map(Transform::vertex_map)
            .collect();
        assert_eq!(maps.len(), 48);
        for a in &maps {
            for b in &maps {
                let c: [u8; 8] = std::array::from_fn(|v| a[usize::from(b[v])]);
                assert!(maps.contains(&c));
            }
        }
    }

    #[test]
    fn bits_round_trip_in_seven_bits() {
        for t in Transform::all() {
            assert!(t.bits() < 128);
            assert_eq!(Transform::from_bits(t.bits()), Some(t));
        }
        assert_eq!(Transform::from_bits(24), None);
        assert_eq!(Transform::from_bits(0x80), None);
    }

    #[test]
    fn maps_preserve_incidence() {
        for t in Transform::all() {
            let vm = t.vertex_map();
            let em = t.edge_map();
            let fm = t.face_map();
            for (e, &image) in em.iter().enumerate() {
                let [a, b] = super::super::EDGES[e];
                let [c, d] = super::super::EDGES[usize::from(image)];
                let mut x = [vm[usize::from(a)], vm[usize::from(b)]];
                let mut y = [c, d];
                x.sort_unstable();
                y.sort_unstable();
                assert_eq!(x, y);
            }
            for f in 0..6 {
                let image: HashSet<u8> = FACES[f].iter().map(|&v| vm[usize::from(v)]).collect();
                let target: HashSet<u8> = FACES[usize::from(fm[f])].iter().copied().collect();
                assert_eq!(image, target);
            }
            let inv = t.inverse_vertex_map();
            for v in 0..8 {
                assert_eq!(inv[usize::from(vm[v])] as usize, v);
            }
        }
    }

    #[test]
    fn mirror_reverses_face_orientation() {
        // A proper rotation keeps each face's counter-clockwise corner order (up to a cyclic
        // shift); the mirror reverses it. This is why winding is reversed for mirrored cases.
        for t in Transform::all().filter(|t| !t.flip) {
            let vm = t.vertex_map();
            let fm = t.face_map();
            for f in 0..6 {
                let image = FACES[f].map(|v| vm[usize::from(v)]);
                let target = FACES[usize::from(fm[f])];
                let shift = target.iter().position(|&v| v == image[0]).unwrap();
                let same = (0..4).all(|i| target[(shift + i) % 4] == image[i]);
                let reversed = (0..4).all(|i| target[(shift + 4 - i) % 4] == image[i]);
                assert_eq!(same, !t.mirror);
                assert_eq!(reversed, t.mirror);
            }
        }
    }
}
