//! The unit cube: vertex, edge and face numbering, its symmetry group, configurations and the
//! case tables derived from them.
//!
//! ```text
//!         7 ──────e6────── 6            z
//!        ╱│               ╱│            │  y
//!      e7 │             e5 │            │ ╱
//!      ╱  e11           ╱  e10          │╱
//!     4 ──────e4────── 5   │            └──── x
//!     │   │            │   │
//!     │   3 ─────e2────│── 2
//!     e8 ╱             e9 ╱
//!     │ e3             │ e1
//!     │╱               │╱
//!     0 ──────e0────── 1
//! ```
//!
//! Vertex `i` sits at [`VERTICES`]`[i]`: 0 (0,0,0), 1 (1,0,0), 2 (1,1,0), 3 (0,1,0), 4 (0,0,1),
//! 5 (1,0,1), 6 (1,1,1), 7 (0,1,1). Edges 0–3 go round the bottom face (0-1, 1-2, 3-2, 0-3), 4–7 round
//! the top face in the same way, 8–11 are the vertical edges (0-4, 1-5, 2-6, 3-7). Faces are numbered 0 (y=0), 1 (x=1), 2 (y=1), 3 (x=0), 4 (z=0),
//! 5 (z=1), and each lists its corners counter-clockwise as seen from outside the cube.
//!
//! A *binary configuration* is the index `Σ 2^i` over the vertices whose value is at or above the
//! level (256 of them); a *ternary configuration* is `Σ d_i·3^i` with `d = 0` below, `1` equal (zero)
//! and `2` above (6561 of them). [`symmetry`] generates the 24 rotations, the mirror and the sign
//! flip; [`config`] sorts configurations into classes under them; [`polygons`] derives the loops a
//! configuration's surface leaves on the cube's faces; [`table`] turns them into patches (disks and
//! tunnels) for every configuration, from its class representative; [`triangulate`] splits
//! patches into triangles; [`ternary`] lists the polygons of the 6561 ternary configurations,
//! built from the 183 classes under rotations and flip.

pub mod config;
pub mod polygons;
pub mod symmetry;
pub mod table;
pub mod ternary;
pub mod triangulate;

pub use config::{ClassTable, ConfigEntry, ConfigKind, Group};
pub use polygons::{Corner, FaceDecisions, Regions};
pub use symmetry::{Rotation, Transform};
pub use table::{CaseTable, CellTriangles, Topology, TunnelRegions};
pub use ternary::{TernaryTable, TieRule};

/// Number of cube vertices.
pub const VERTEX_COUNT: usize = 8;
/// Number of cube edges.
pub const EDGE_COUNT: usize = 12;
/// Number of cube faces.
pub const FACE_COUNT: usize = 6;

/// Coordinates of the cube vertices, in the numbering of the seed papers.
pub const VERTICES: [[u8; 3]; 8] = [
    [0, 0, 0],
    [1, 0, 0],
    [1, 1, 0],
    [0, 1, 0],
    [0, 0, 1],
    [1, 0, 1],
    [1, 1, 1],
    [0, 1, 1],
];

/// The two end vertices of each edge; the first is the one with the smaller coordinate along the
/// edge's axis, so an edge always runs in the positive direction of its axis.
pub const EDGES: [[u8; 2]; 12] = [
    [0, 1],
    [1, 2],
    [3, 2],
    [0, 3],
    [4, 5],
    [5, 6],
    [7, 6],
    [4, 7],
    [0, 4],
    [1, 5],
    [2, 6],
    [3, 7],
];

/// The axis (0 = x, 1 = y, 2 = z) each edge runs along.
pub const EDGE_AXIS: [u8; 12] = [0, 1, 0, 1, 0, 1, 0, 1, 2, 2, 2, 2];

/// Face corners, counter-clockwise as seen from outside the cube (so the right-hand normal of the
/// loop points outward). Faces: 0 y=0, 1 x=1, 2 y=1, 3 x=0, 4 z=0, 5 z=1.
pub const FACES: [[u8; 4]; 6] = [
    [0, 1, 5, 4],
    [1, 2, 6, 5],
    [2, 3, 7, 6],
    [3, 0, 4, 7],
    [0, 3, 2, 1],
    [4, 5, 6, 7],
];

/// `FACE_EDGES[f][i]` is the edge from `FACES[f][i]` to `FACES[f][(i + 1) % 4]`.
pub const FACE_EDGES: [[u8; 4]; 6] = face_edges();

/// The face on the other side of the cube (the one a neighbouring cell shares with this one).
pub const OPPOSITE_FACE: [u8; 6] = [2, 3, 0, 1, 5, 4];

/// The edge joining two vertices, if they are adjacent.
pub const fn edge_between(a: u8, b: u8) -> Option<u8> {
    let mut e = 0;
    while e < 12 {
        let [p, q] = EDGES[e];
        if (p == a && q == b) || (p == b && q == a) {
            return Some(e as u8);
        }
        e += 1;
    }
    None
}

const fn face_edges() -> [[u8; 4]; 6] {
    let mut out = [[0u8; 4]; 6];
    let mut f = 0;
    while f < 6 {
        let mut i = 0;
        while i < 4 {
            match edge_between(FACES[f][i], FACES[f][(i + 1) % 4]) {
                Some(e) => out[f][i] = e,
                None => panic!("face corners must be adjacent"),
            }
            i += 1;
        }
        f += 1;
    }
    out
}

/// Whether two edges lie on a common cube face.
pub fn edges_share_face(a: u8, b: u8) -> bool {
    FACE_EDGES.iter().any(|f| f.contains(&a) && f.contains(&b))
}

/// The vertex with the given 0/1 coordinates.
pub const fn vertex_at(x: u8, y: u8, z: u8) -> u8 {
    let mut v = 0;
    while v < 8 {
        let c = VERTICES[v];
        if c[0] == x && c[1] == y && c[2] == z {
            return v as u8;
        }
        v += 1;
    }
    panic!("coordinates must be 0 or 1")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sub(a: [u8; 3], b: [u8; 3]) -> [i32; 3] {
        [0, 1, 2].map(|i| a[i] as i32 - b[i] as i32)
    }

    fn cross(a: [i32; 3], b: [i32; 3]) -> [i32; 3] {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    }

    #[test]
    fn faces_are_counter_clockwise_from_outside() {
        for (f, corners) in FACES.iter().enumerate() {
            let p = corners.map(|v| VERTICES[v as usize]);
            let n = cross(sub(p[1], p[0]), sub(p[2], p[0]));
            // Outward direction: from the cube centre to the face centre.
            let centre: [i32; 3] =
                [0, 1, 2].map(|i| p.iter().map(|q| q[i] as i32).sum::<i32>() * 2 - 4);
            let dot: i32 = (0..3).map(|i| n[i] * centre[i]).sum();
            assert!(dot > 0, "face {f} is not counter-clockwise from outside");
            // All four corners share the coordinate that defines the face.
            assert!((0..3).any(|axis| p.iter().all(|q| q[axis] == p[0][axis])));
        }
    }

    #[test]
    fn edges_are_axis_aligned_and_positive() {
        for (e, [a, b]) in EDGES.iter().enumerate() {
            let d = sub(VERTICES[*b as usize], VERTICES[*a as usize]);
            let axis = EDGE_AXIS[e] as usize;
            assert_eq!(d[axis], 1, "edge {e}");
            assert_eq!(d.iter().map(|x| x.abs()).sum::<i32>(), 1, "edge {e}");
        }
        // Every edge lies on exactly two faces.
        for e in 0..12u8 {
            let n = FACE_EDGES.iter().filter(|f| f.contains(&e)).count();
            assert_eq!(n, 2, "edge {e}");
        }
    }

    #[test]
    fn opposite_faces_are_translates() {
        for f in 0..6 {
            let g = OPPOSITE_FACE[f] as usize;
            let axis = (0..3)
                .find(|&a| {
                    FACES[f]
                        .iter()
                        .all(|&v| VERTICES[v as usize][a] == VERTICES[FACES[f][0] as usize][a])
                })
                .unwrap();
            let vf = VERTICES[FACES[f][0] as usize][axis];
            let vg = VERTICES[FACES[g][0] as usize][axis];
            assert_ne!(vf, vg);
            assert!(FACES[g].iter().all(|&v| VERTICES[v as usize][axis] == vg));
        }
    }
}
