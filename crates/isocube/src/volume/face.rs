//! The inside parts of cell faces, triangulated by a rule that reads only the face, so that the
//! two cells sharing a face cut it the same way.

use rayon::prelude::*;
use rustc_hash::FxHashMap as HashMap;

use super::{coords, Context};
use crate::extract::{KeyKind, VertexKey};

/// A cell face: its lowest grid point (linear index) times 3 plus its normal axis.
pub(super) fn face_id(q: [usize; 3], n: usize, dims: [usize; 3]) -> u64 {
    ((q[0] + dims[0] * (q[1] + dims[1] * q[2])) * 3 + n) as u64
}

/// The cell faces holding the crossing `key` (on an edge, so up to four), as ids.
fn faces_of(key: VertexKey, dims: [usize; 3], out: &mut Vec<u64>) {
    out.clear();
    let KeyKind::Crossing { point, axis } = key.kind() else {
        return;
    };
    let c = coords(point, dims);
    for n in (0..3).filter(|&n| n != axis) {
        let m = 3 - n - axis;
        for q_m in [c[m].checked_sub(1), Some(c[m])].into_iter().flatten() {
            if q_m + 1 < dims[m] {
                let mut q = c;
                q[m] = q_m;
                out.push(face_id(q, n, dims));
            }
        }
    }
}

/// The surface's edges lying in cell faces, by face: each as the two vertices' numbers, lower
/// first, once.
pub(super) fn segments_by_face(
    triangles: &[[u32; 3]],
    keys: &[VertexKey],
    dims: [usize; 3],
) -> HashMap<u64, Vec<[u32; 2]>> {
    let mut found: Vec<(u64, [u32; 2])> = triangles
        .par_iter()
        .fold(
            || (Vec::new(), Vec::new(), Vec::new()),
            |(mut acc, mut fa, mut fb), t| {
                for k in 0..3 {
                    let (a, b) = (t[k], t[(k + 1) % 3]);
                    faces_of(keys[a as usize], dims, &mut fa);
                    if fa.is_empty() {
                        continue;
                    }
                    faces_of(keys[b as usize], dims, &mut fb);
                    for f in fa.iter().filter(|f| fb.contains(f)) {
                        acc.push((*f, [a.min(b), a.max(b)]));
                    }
                }
                (acc, fa, fb)
            },
        )
        .map(|(acc, _, _)| acc)
        .reduce(Vec::new, |mut a, mut b| {
            a.append(&mut b);
            a
        });
    found.par_sort_unstable();
    found.dedup();
    let mut map: HashMap<u64, Vec<[u32; 2]>> = HashMap::default();
    for (f, s) in found {
        map.entry(f).or_default().push(s);
    }
    map
}

/// Buffers reused from face to face.
#[derive(Default)]
pub(super) struct Scratch {
    pieces: Vec<Vec<usize>>,
}

/// A point of a face's boundary cycle: a corner (inside or not) or a crossing.
#[derive(Clone, Copy)]
struct Point {
    /// The vertex number (`u32::MAX` for a corner outside the region).
    id: u32,
    corner: bool,
    /// Coordinates in the face's plane.
    at: [f64; 2],
}

/// Appends the triangles of the inside part of the face with lowest point `q` and normal axis
/// `n`, oriented with their normals along `+n`.
pub(super) fn triangles(
    ctx: &Context,
    q: [usize; 3],
    n: usize,
    out: &mut Vec<[u32; 3]>,
    scratch: &mut Scratch,
) -> Result<(), &'static str> {
    let dims = ctx.dims;
    let (u, v) = ((n + 1) % 3, (n + 2) % 3);
    let offset = |du: usize, dv: usize| {
        let mut c = q;
        c[u] += du;
        c[v] += dv;
        c
    };
    // Counterclockwise seen from +n.
    let corners = [offset(0, 0), offset(1, 0), offset(1, 1), offset(0, 1)];
    let ids = corners.map(|c| ctx.point_id(c));
    let segments = ctx.segments.get(&face_id(q, n, dims));
    if segments.is_none() && ids.iter().all(|&i| i != u32::MAX) {
        // A whole square: along the Kuhn diagonal, from its lowest to its highest corner.
        out.push([ids[0], ids[1], ids[2]]);
        out.push([ids[0], ids[2], ids[3]]);
        return Ok(());
    }
    if ids.iter().all(|&i| i == u32::MAX) {
        return Ok(());
    }
    let point_index = |c: [usize; 3]| c[0] + dims[0] * (c[1] + dims[1] * c[2]);
    // The crossing on side s (from corner s to corner s + 1) lies on the edge from its lower end.
    let sides = [
        (corners[0], u),
        (corners[1], v),
        (corners[3], u),
        (corners[0], v),
    ];
    let plane = |id: u32| {
        let p = ctx.position(id);
        [f64::from(p[u]), f64::from(p[v])]
    };
    let mut cycle: Vec<Point> = Vec::with_capacity(8);
    for s in 0..4 {
        let corner_at = {
            let p = ctx.grid.point(corners[s][0], corners[s][1], corners[s][2]);
            [p[u] as f32, p[v] as f32].map(f64::from)
        };
        cycle.push(Point {
            id: ids[s],
            corner: true,
            at: corner_at,
        });
        if (ids[s] == u32::MAX) != (ids[(s + 1) % 4] == u32::MAX) {
            let (from, axis) = sides[s];
            let key = VertexKey::crossing(point_index(from), axis);
            let &id = ctx
                .crossings
                .get(&key)
                .ok_or("a face edge whose ends differ has no crossing")?;
            cycle.push(Point {
                id,
                corner: false,
                at: plane(id),
            });
        }
    }
    // Cut the face along the surface's segments on it.
    let pieces = &mut scratch.pieces;
    pieces.clear();
    pieces.push((0..cycle.len()).collect());
    for s in segments.into_iter().flatten() {
        let find = |id: u32| cycle.iter().position(|p| !p.corner && p.id == id);
        let (Some(a), Some(b)) = (find(s[0]), find(s[1])) else {
            return Err("a surface segment on a face does not end on its edges");
        };
        let Some(k) = pieces.iter().position(|p| p.contains(&a) && p.contains(&b)) else {
            return Err("surface segments on a face cross");
        };
        let piece = std::mem::take(&mut pieces[k]);
        let ia = piece.iter().position(|&x| x == a).expect("contains");
        let ib = piece.iter().position(|&x| x == b).expect("contains");
        let (ia, ib) = (ia.min(ib), ia.max(ib));
        if ib - ia == 1 || (ia == 0 && ib == piece.len() - 1) {
            // Already a side of the piece.
            pieces[k] = piece;
            continue;
        }
        let first: Vec<usize> = piece[ia..=ib].to_vec();
        let second: Vec<usize> = piece[ib..].iter().chain(&piece[..=ia]).copied().collect();
        pieces[k] = first;
        pieces.push(second);
    }
    for piece in pieces.iter() {
        let outside = piece
            .iter()
            .any(|&x| cycle[x].corner && cycle[x].id == u32::MAX);
        let inside = piece
            .iter()
            .any(|&x| cycle[x].corner && cycle[x].id != u32::MAX);
        match (inside, outside) {
            (false, true) => continue,
            (true, false) => {}
            (true, true) => return Err("the surface's segments do not separate a face's corners"),
            // A surface triangle lying in the face: it bounds the region on one side only, and
            // belongs to that side's cell.
            (false, false) => continue,
        }
        convex_triangulation(piece, &cycle, out);
    }
    Ok(())
}

/// The triangulation of a convex polygon (counterclockwise) with the largest smallest angle;
/// ties go to the first found, so the result depends only on the polygon.
fn convex_triangulation(piece: &[usize], cycle: &[Point], out: &mut Vec<[u32; 3]>) {
    let m = piece.len();
    let at = |k: usize| cycle[piece[k]].at;
    let id = |k: usize| cycle[piece[k]].id;
    if m == 3 {
        out.push([id(0), id(1), id(2)]);
        return;
    }
    let smallest = |a: usize, b: usize, c: usize| {
        let angle = |o: [f64; 2], p: [f64; 2], q: [f64; 2]| {
            let (x, y) = ([p[0] - o[0], p[1] - o[1]], [q[0] - o[0], q[1] - o[1]]);
            (x[0] * y[1] - x[1] * y[0])
                .abs()
                .atan2(x[0] * y[0] + x[1] * y[1])
        };
        let (pa, pb, pc) = (at(a), at(b), at(c));
        angle(pa, pb, pc)
            .min(angle(pb, pc, pa))
            .min(angle(pc, pa, pb))
    };
    // best[i][j]: the best smallest angle over triangulations of the sub-polygon i..=j.
    let mut best = vec![[f64::INFINITY; 8]; 8];
    let mut split = vec![[0usize; 8]; 8];
    debug_assert!(m <= 8);
    for len in 2..m {
        for i in 0..m - len {
            let j = i + len;
            best[i][j] = f64::NEG_INFINITY;
            for k in i + 1..j {
                let q = smallest(i, k, j).min(best[i][k]).min(best[k][j]);
                if q > best[i][j] {
                    best[i][j] = q;
                    split[i][j] = k;
                }
            }
        }
    }
    let mut stack = vec![(0usize, m - 1)];
    while let Some((i, j)) = stack.pop() {
        if j - i < 2 {
            continue;
        }
        let k = split[i][j];
        out.push([id(i), id(k), id(j)]);
        stack.push((i, k));
        stack.push((k, j));
    }
}
