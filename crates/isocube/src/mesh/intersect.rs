//! Whether triangles meet, decided exactly: the test behind self-intersection checks of
//! surfaces and the volume mesher's advancing front.

use super::sub;

/// The first pair of triangles (indices) that meet anywhere but in the vertices and edges they
/// share, by exact predicates on the positions given. Triangles of no area are left out (where
/// they meet is not a question of crossing).
pub(crate) fn first_crossing(
    tris: &[[u32; 3]],
    position: &dyn Fn(u32) -> [f64; 3],
) -> Option<(usize, usize)> {
    let at = |t: [u32; 3]| t.map(|v| (v, position(v)));
    let flat: Vec<bool> = tris.iter().map(|t| collinear(t.map(position))).collect();
    (0..tris.len()).filter(|&i| !flat[i]).find_map(|i| {
        (i + 1..tris.len())
            .find(|&j| !flat[j] && triangles_cross(at(tris[i]), at(tris[j])))
            .map(|j| (i, j))
    })
}

/// Every pair of triangles (indices, smaller first, sorted) that cross as
/// [`triangles_cross`] decides, found through boxes of side `size` so that large meshes are
/// checked in time proportional to their size (triangles of no area left out).
#[cfg(test)]
pub(crate) fn crossing_pairs(
    tris: &[[u32; 3]],
    position: &dyn Fn(u32) -> [f64; 3],
    size: f64,
) -> Vec<(usize, usize)> {
    let mut boxes: std::collections::HashMap<[i64; 3], Vec<usize>> = Default::default();
    for (i, t) in tris.iter().enumerate() {
        let p = t.map(position);
        if collinear(p) {
            continue;
        }
        let lo: [i64; 3] =
            std::array::from_fn(|d| (p[0][d].min(p[1][d]).min(p[2][d]) / size).floor() as i64);
        let hi: [i64; 3] =
            std::array::from_fn(|d| (p[0][d].max(p[1][d]).max(p[2][d]) / size).floor() as i64);
        for x in lo[0]..=hi[0] {
            for y in lo[1]..=hi[1] {
                for z in lo[2]..=hi[2] {
                    boxes.entry([x, y, z]).or_default().push(i);
                }
            }
        }
    }
    let at = |i: usize| tris[i].map(|v| (v, position(v)));
    let mut pairs: Vec<(usize, usize)> = boxes
        .values()
        .flat_map(|list| {
            list.iter().enumerate().flat_map(move |(k, &i)| {
                list[k + 1..]
                    .iter()
                    .filter(move |&&j| triangles_cross(at(i), at(j)))
                    .map(move |&j| (i.min(j), i.max(j)))
            })
        })
        .collect();
    pairs.sort_unstable();
    pairs.dedup();
    pairs
}

/// Whether a triangle's corners lie on one line (exactly).
pub(crate) fn collinear(t: [[f64; 3]; 3]) -> bool {
    (0..3).all(|axis| orient2(t[0], t[1], t[2], axis) == 0.0)
}

/// The sign of the orientation of `(a, b, c, d)`, decided exactly: positive when `(b − a) ·
/// ((c − a) × (d − a)) > 0`, zero when the four points lie in one plane.
pub(crate) fn orient(a: [f64; 3], b: [f64; 3], c: [f64; 3], d: [f64; 3]) -> f64 {
    // `robust` measures the other way round: positive when d lies below the plane of a, b, c
    // seen counterclockwise.
    let coord = |x: [f64; 3]| robust::Coord3D {
        x: x[0],
        y: x[1],
        z: x[2],
    };
    -robust::orient3d(coord(a), coord(b), coord(c), coord(d))
}

/// Whether two triangles (vertex ids with positions, neither of no area) meet anywhere but in
/// the vertices and the edge they share; two over the same three vertices do not cross.
pub(crate) fn triangles_cross(t: [(u32, [f64; 3]); 3], g: [(u32, [f64; 3]); 3]) -> bool {
    let mut shared = [0u32; 3];
    let mut count = 0;
    for x in &t {
        if g.iter().any(|y| y.0 == x.0) {
            shared[count] = x.0;
            count += 1;
        }
    }
    let shared = &shared[..count];
    let tp = t.map(|x| x.1);
    let gp = g.map(|x| x.1);
    match count {
        // Two triangles meet when an edge of one meets the other (closed): in one plane too,
        // where the segment test works in two dimensions. Boxes apart settle most pairs.
        0 => {
            let apart = (0..3).any(|d| {
                let (t0, t1) = (tp.map(|x| x[d]), gp.map(|x| x[d]));
                let max = |a: [f64; 3]| a[0].max(a[1]).max(a[2]);
                let min = |a: [f64; 3]| a[0].min(a[1]).min(a[2]);
                max(t0) < min(t1) || max(t1) < min(t0)
            });
            if apart {
                return false;
            }
            (0..3).any(|k| segment_meets(tp[k], tp[(k + 1) % 3], gp))
                || (0..3).any(|k| segment_meets(gp[k], gp[(k + 1) % 3], tp))
        }
        1 => {
            let v = shared[0];
            // Each triangle rotated to start at the shared vertex.
            let rot = |x: [(u32, [f64; 3]); 3]| {
                let r = (0..3).find(|&r| x[r].0 == v).expect("shared");
                [x[r].1, x[(r + 1) % 3].1, x[(r + 2) % 3].1]
            };
            let (a, b) = (rot(t), rot(g));
            // The other corners of one strictly on one side of the other's plane: that plane
            // holds only the shared vertex of it, and so does the other triangle (most pairs).
            let side = |x: [[f64; 3]; 3], y: [[f64; 3]; 3]| {
                orient(y[0], y[1], y[2], x[1]) * orient(y[0], y[1], y[2], x[2]) > 0.0
            };
            if side(a, b) || side(b, a) {
                return false;
            }
            // Off the shared vertex they meet along a segment from it that ends on an edge
            // opposite it, or along an edge through it lying in the other's plane.
            segment_meets(a[1], a[2], b)
                || segment_meets(b[1], b[2], a)
                || [a[1], a[2]].iter().any(|&x| edge_enters(a[0], x, b))
                || [b[1], b[2]].iter().any(|&x| edge_enters(b[0], x, a))
        }
        // Over the same three vertices they coincide: not a crossing (a sheet of no thickness).
        3 => false,
        _ => {
            // Sharing an edge, they meet beyond it only lying in one plane on one side of it.
            // (Only the other corner is asked: the shared ones lie in the plane, and an exact
            // zero is the slowest answer the predicate gives.)
            let other = |x: [(u32, [f64; 3]); 3]| {
                x.iter()
                    .find(|y| !shared.contains(&y.0))
                    .expect("three vertices")
                    .1
            };
            if orient(tp[0], tp[1], tp[2], other(g)) != 0.0 {
                return false;
            }
            let (a, b) = (
                t.iter().find(|y| y.0 == shared[0]).expect("shared").1,
                t.iter().find(|y| y.0 == shared[1]).expect("shared").1,
            );
            let axis = projection(tp);
            let s1 = orient2(a, b, other(t), axis);
            let s2 = orient2(a, b, other(g), axis);
            s1 * s2 > 0.0
        }
    }
}

/// Whether the edge from `v` (a corner of `t`, `t[0]`) towards `x` runs into `t` beyond `v`:
/// only when it lies in `t`'s plane, within its angle at `v`.
fn edge_enters(v: [f64; 3], x: [f64; 3], t: [[f64; 3]; 3]) -> bool {
    if orient(t[0], t[1], t[2], x) != 0.0 {
        return false;
    }
    let axis = projection(t);
    let sigma = orient2(v, t[1], t[2], axis);
    sigma * orient2(v, t[1], x, axis) >= 0.0 && sigma * orient2(v, x, t[2], axis) >= 0.0
}

/// Whether the closed segment `p q` meets the closed triangle `t` (of some area).
fn segment_meets(p: [f64; 3], q: [f64; 3], t: [[f64; 3]; 3]) -> bool {
    let (op, oq) = (orient(t[0], t[1], t[2], p), orient(t[0], t[1], t[2], q));
    if op * oq > 0.0 {
        return false;
    }
    if op == 0.0 && oq == 0.0 {
        // In the triangle's plane: a question in two dimensions.
        let axis = projection(t);
        let inside = |x: [f64; 3]| {
            let s = [
                orient2(t[0], t[1], x, axis),
                orient2(t[1], t[2], x, axis),
                orient2(t[2], t[0], x, axis),
            ];
            s.iter().all(|&o| o >= 0.0) || s.iter().all(|&o| o <= 0.0)
        };
        return inside(p)
            || inside(q)
            || (0..3).any(|k| segments_meet_2d(p, q, t[k], t[(k + 1) % 3], axis));
    }
    // The line through p and q passes the triangle's plane within the segment: it meets the
    // triangle when it passes on no side of its edges but one.
    let s = [
        orient(p, q, t[0], t[1]),
        orient(p, q, t[1], t[2]),
        orient(p, q, t[2], t[0]),
    ];
    !(s.iter().any(|&o| o > 0.0) && s.iter().any(|&o| o < 0.0))
}

/// The coordinate to drop to see a triangle of some area without flattening it.
fn projection(t: [[f64; 3]; 3]) -> usize {
    let n = {
        let (u, w) = (sub(t[1], t[0]), sub(t[2], t[0]));
        [
            u[1] * w[2] - u[2] * w[1],
            u[2] * w[0] - u[0] * w[2],
            u[0] * w[1] - u[1] * w[0],
        ]
    };
    let mut axes = [0, 1, 2];
    axes.sort_by(|&a, &b| n[b].abs().total_cmp(&n[a].abs()));
    axes.into_iter()
        .find(|&axis| orient2(t[0], t[1], t[2], axis) != 0.0)
        .unwrap_or(axes[0])
}

/// The orientation of three points seen along `axis`, exactly.
fn orient2(a: [f64; 3], b: [f64; 3], c: [f64; 3], axis: usize) -> f64 {
    let (u, w) = ((axis + 1) % 3, (axis + 2) % 3);
    let p = |x: [f64; 3]| robust::Coord { x: x[u], y: x[w] };
    robust::orient2d(p(a), p(b), p(c))
}

/// Whether two closed segments meet, seen along `axis`.
fn segments_meet_2d(p: [f64; 3], q: [f64; 3], a: [f64; 3], b: [f64; 3], axis: usize) -> bool {
    let (d1, d2) = (orient2(a, b, p, axis), orient2(a, b, q, axis));
    let (d3, d4) = (orient2(p, q, a, axis), orient2(p, q, b, axis));
    if d1 * d2 < 0.0 && d3 * d4 < 0.0 {
        return true;
    }
    let (u, w) = ((axis + 1) % 3, (axis + 2) % 3);
    let within = |x: [f64; 3], s: [f64; 3], e: [f64; 3]| {
        (0..3).filter(|&d| d == u || d == w).all(|d| {
            let (lo, hi) = if s[d] <= e[d] {
                (s[d], e[d])
            } else {
                (e[d], s[d])
            };
            lo <= x[d] && x[d] <= hi
        })
    };
    (d1 == 0.0 && within(p, a, b))
        || (d2 == 0.0 && within(q, a, b))
        || (d3 == 0.0 && within(a, p, q))
        || (d4 == 0.0 && within(b, p, q))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri(ids: [u32; 3], p: [[f64; 3]; 3]) -> [(u32, [f64; 3]); 3] {
        [(ids[0], p[0]), (ids[1], p[1]), (ids[2], p[2])]
    }

    const FLOOR: [[f64; 3]; 3] = [[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0]];

    #[test]
    fn apart_piercing_and_touching() {
        let t = tri([0, 1, 2], FLOOR);
        // Standing through the floor triangle: crosses.
        let through = tri(
            [3, 4, 5],
            [[0.5, 0.5, -1.0], [0.5, 0.5, 1.0], [1.5, -1.0, 0.0]],
        );
        assert!(triangles_cross(t, through));
        // Above it: apart.
        let above = tri(
            [3, 4, 5],
            [[0.5, 0.5, 1.0], [1.0, 0.5, 1.0], [0.5, 1.0, 2.0]],
        );
        assert!(!triangles_cross(t, above));
        // Touching it at one point of its inside (a vertex on it): meets.
        let touching = tri(
            [3, 4, 5],
            [[0.5, 0.5, 0.0], [1.0, 0.5, 1.0], [0.5, 1.0, 2.0]],
        );
        assert!(triangles_cross(t, touching));
    }

    #[test]
    fn shared_vertices_and_edges() {
        let t = tri([0, 1, 2], FLOOR);
        // Sharing an edge, bent up: they meet in the edge only.
        let hinge = tri([0, 1, 3], [FLOOR[0], FLOOR[1], [1.0, 0.0, 1.0]]);
        assert!(!triangles_cross(t, hinge));
        // Sharing an edge, in the plane, on the other side: apart; on the same side: overlap.
        let beside = tri([1, 0, 3], [FLOOR[1], FLOOR[0], [1.0, -1.0, 0.0]]);
        assert!(!triangles_cross(t, beside));
        let folded = tri([1, 0, 3], [FLOOR[1], FLOOR[0], [0.5, 0.5, 0.0]]);
        assert!(triangles_cross(t, folded));
        // Sharing a vertex, the opposite edge through the floor: crosses.
        let pierce = tri([0, 3, 4], [FLOOR[0], [0.6, 0.6, -1.0], [0.6, 0.6, 1.0]]);
        assert!(triangles_cross(t, pierce));
        // Sharing a vertex, an edge lying in the floor inside its angle: meets beyond it.
        let lying = tri([0, 3, 4], [FLOOR[0], [0.5, 0.5, 0.0], [0.0, 0.0, 1.0]]);
        assert!(triangles_cross(t, lying));
        // Sharing a vertex, in the plane outside its angle: apart.
        let outside = tri([0, 3, 4], [FLOOR[0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]]);
        assert!(!triangles_cross(t, outside));
        // The same three vertices: no crossing.
        assert!(!triangles_cross(
            t,
            tri([0, 2, 1], [FLOOR[0], FLOOR[2], FLOOR[1]])
        ));
    }

    #[test]
    fn first_crossing_of_a_surface() {
        let positions = [
            [0.0, 0.0, 0.0],
            [2.0, 0.0, 0.0],
            [0.0, 2.0, 0.0],
            [0.5, 0.5, -1.0],
            [0.5, 0.5, 1.0],
            [1.5, -1.0, 0.0],
        ];
        let position = |v: u32| positions[v as usize];
        assert_eq!(first_crossing(&[[0, 1, 2]], &position), None);
        assert_eq!(
            first_crossing(&[[0, 1, 2], [3, 4, 5]], &position),
            Some((0, 1))
        );
        assert!(collinear([[0.0; 3], [1.0, 1.0, 1.0], [2.0, 2.0, 2.0]]));
        assert!(!collinear(FLOOR));
    }
}
