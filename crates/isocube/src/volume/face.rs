//! The inside parts of cell faces, triangulated by a rule that reads only the face, so that the
//! two cells sharing a face cut it the same way.

use rayon::prelude::*;
use rustc_hash::FxHashMap as HashMap;

use super::{coords, Context, Corner, TetError};
use crate::extract::{KeyKind, VertexKey};

/// A cell face: its lowest grid point (linear index) times 3 plus its normal axis.
pub(super) fn face_id(q: [usize; 3], n: usize, dims: [usize; 3]) -> u64 {
    ((q[0] + dims[0] * (q[1] + dims[1] * q[2])) * 3 + n) as u64
}

/// The cell faces holding a crossing (on an edge, so up to four) or a grid point (a corner of up
/// to twelve), as ids.
fn faces_of(key: VertexKey, dims: [usize; 3], out: &mut Vec<u64>) {
    out.clear();
    // Faces with normal `n` holding the point `c` (its coordinate along `axis`, if any, fixed).
    let mut around = |c: [usize; 3], n: usize, fixed: Option<usize>| {
        let (u, v) = ((n + 1) % 3, (n + 2) % 3);
        let range = |d: usize| {
            let lo = if fixed == Some(d) {
                c[d]
            } else {
                c[d].saturating_sub(1)
            };
            (lo..=c[d]).filter(move |&x| x + 1 < dims[d])
        };
        for qu in range(u) {
            for qv in range(v) {
                let mut q = c;
                q[u] = qu;
                q[v] = qv;
                out.push(face_id(q, n, dims));
            }
        }
    };
    match key.kind() {
        KeyKind::Crossing { point, axis } => {
            let c = coords(point, dims);
            for n in (0..3).filter(|&n| n != axis) {
                around(c, n, Some(axis));
            }
        }
        KeyKind::Point(point) => {
            let c = coords(point, dims);
            for n in 0..3 {
                around(c, n, None);
            }
        }
        _ => {}
    }
}

/// The surface on one cell face: its edges lying in the face, and its triangles lying in it.
#[derive(Default)]
pub(super) struct OnFace {
    /// Each edge as its two vertices' numbers (lower first), and whether it is a chord: an edge
    /// inside one cell's patch that only touches the face (both its triangles belong to the same
    /// cell), as opposed to the trace of the surface across the face, which separates the
    /// region's side from the other.
    segments: Vec<([u32; 2], bool)>,
    /// Surface triangles lying in the face, as their sorted vertex numbers.
    flat: Vec<[u32; 3]>,
    /// Surface vertices inside the face (a cell's interior point that a polygon lying in the
    /// face put there): the edges to them lie within flat triangles.
    inner: Vec<u32>,
}

/// The surface's edges and triangles lying in cell faces, by face. `owner` is each triangle's
/// cell (or any other value telling triangles in different cells apart); `inner_face` gives the
/// face a vertex lies inside of, for vertices that are neither crossings nor grid points.
pub(super) fn surface_on_faces(
    triangles: &[[u32; 3]],
    owner: &[u64],
    keys: &[VertexKey],
    dims: [usize; 3],
    inner_face: &(dyn Fn(u32) -> Option<u64> + Sync),
    check: &mut dyn FnMut() -> Result<(), TetError>,
) -> Result<HashMap<u64, OnFace>, TetError> {
    // (face, edge, owner) for every triangle edge in a face; (face, [u32::MAX, t]) marks a
    // triangle lying in a face.
    let mut found: Vec<(u64, [u32; 2], u64)> = triangles
        .par_iter()
        .enumerate()
        .fold(
            || (Vec::new(), [Vec::new(), Vec::new(), Vec::new()]),
            |(mut acc, mut faces), (t, tri)| {
                for k in 0..3 {
                    faces_of(keys[tri[k] as usize], dims, &mut faces[k]);
                    if faces[k].is_empty() {
                        faces[k].extend(inner_face(tri[k]));
                    }
                }
                for k in 0..3 {
                    let (a, b) = (tri[k], tri[(k + 1) % 3]);
                    for f in faces[k].iter().filter(|f| faces[(k + 1) % 3].contains(f)) {
                        acc.push((*f, [a.min(b), a.max(b)], owner[t]));
                    }
                }
                for f in faces[0]
                    .iter()
                    .filter(|f| faces[1].contains(f) && faces[2].contains(f))
                {
                    acc.push((*f, [u32::MAX, t as u32], 0));
                }
                (acc, faces)
            },
        )
        .map(|(acc, _)| acc)
        .reduce(Vec::new, |mut a, mut b| {
            a.append(&mut b);
            a
        });
    found.par_sort_unstable();
    check()?;
    let mut map: HashMap<u64, OnFace> = HashMap::default();
    let mut i = 0;
    let mut next_check = 1 << 16;
    while i < found.len() {
        // Half a second on a 256³ grid, one entry after another: asked now and then whether
        // to stop.
        if i >= next_check {
            check()?;
            next_check = i + (1 << 16);
        }
        let (f, edge, cell) = found[i];
        let mut j = i + 1;
        while j < found.len() && (found[j].0, found[j].1) == (f, edge) {
            j += 1;
        }
        let entry = map.entry(f).or_default();
        if edge[0] == u32::MAX {
            let mut tri = triangles[edge[1] as usize];
            tri.sort_unstable();
            entry.flat.push(tri);
        } else {
            let chord = j - i == 2 && found[i + 1].2 == cell;
            entry.segments.push((edge, chord));
            for v in edge {
                if inner_face(v).is_some() && !entry.inner.contains(&v) {
                    entry.inner.push(v);
                }
            }
        }
        i = j;
    }
    Ok(map)
}

/// Buffers reused from face to face.
#[derive(Default)]
pub(super) struct Scratch {
    pieces: Vec<Vec<usize>>,
    /// Whether each piece (once the trace has cut the face) lies inside the region.
    status: Vec<bool>,
}

/// A point of a face's boundary cycle: a corner or a crossing.
#[derive(Clone, Copy)]
struct Point {
    /// The vertex number (`u32::MAX` for a corner outside the region).
    id: u32,
    /// A corner's side; `None` for a crossing.
    kind: Option<Corner>,
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
    let kinds = ids.map(|id| ctx.corner(id));
    let on_face = ctx.segments.get(&face_id(q, n, dims));
    if on_face.is_none() && !kinds.contains(&Corner::Out) {
        // A whole square: along the Kuhn diagonal, from its lowest to its highest corner. Zero
        // corners alone (the surface passing through them) bound the region's side of `g`, where
        // they count as the level: inside with `flip` only.
        if kinds.contains(&Corner::In) || ctx.flip {
            out.push([ids[0], ids[1], ids[2]]);
            out.push([ids[0], ids[2], ids[3]]);
        }
        return Ok(());
    }
    if kinds.iter().all(|&k| k == Corner::Out) {
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
            kind: Some(kinds[s]),
            // A zero corner is a surface vertex: its stored position.
            at: if kinds[s] == Corner::Zero {
                plane(ids[s])
            } else {
                corner_at
            },
        });
        let ends = [kinds[s], kinds[(s + 1) % 4]];
        if ends.contains(&Corner::In) && ends.contains(&Corner::Out) {
            let (from, axis) = sides[s];
            let key = VertexKey::crossing(point_index(from), axis);
            let &id = ctx
                .crossings
                .get(&key)
                .ok_or("a face edge whose ends differ has no crossing")?;
            cycle.push(Point {
                id,
                kind: None,
                at: plane(id),
            });
        }
    }
    // Cut the face along the surface's trace on it; each piece is inside or outside the region
    // by its corners. Then cut the pieces along the chords where the surface only touches the
    // face: the parts keep their piece's side.
    let pieces = &mut scratch.pieces;
    pieces.clear();
    pieces.push((0..cycle.len()).collect());
    let status = &mut scratch.status;
    status.clear();
    let segments = on_face.map_or(&[][..], |o| &o.segments[..]);
    for chords in [false, true] {
        if chords {
            // Pieces as the trace leaves them: with an inside corner and no outside one, in;
            // with an outside corner, out. With neither, only zero corners: inside with `flip`
            // (where `g`, the level there, counts as inside), else out. A surface triangle lying
            // in the face bounds the region on one side only, so the cell on that side has it
            // (skipped below, whatever the piece's side).
            for piece in pieces.iter() {
                let has = |kind| piece.iter().any(|&x| cycle[x].kind == Some(kind));
                let (inside, outside) = (has(Corner::In), has(Corner::Out));
                if inside && outside {
                    return Err("the surface's segments do not separate a face's corners");
                }
                status.push(inside || (!outside && ctx.flip));
            }
        }
        let inner = on_face.map_or(&[][..], |o| &o.inner[..]);
        for &(s, _) in segments
            .iter()
            .filter(|s| s.1 == chords && !s.0.iter().any(|v| inner.contains(v)))
        {
            // Crossings and zero corners: the surface's vertices on the face's edges.
            let find = |id: u32| cycle.iter().position(|p| p.id == id);
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
            if chords {
                status.push(status[k]);
            }
        }
    }
    let flat = on_face.map_or(&[][..], |o| &o.flat[..]);
    for (piece, &inside) in pieces.iter().zip(status.iter()) {
        if !inside {
            continue;
        }
        // Surface triangles lying in the face take the piece's place in its cell.
        if covered(
            piece,
            &cycle,
            flat,
            on_face.map_or(&[][..], |o| &o.inner[..]),
            ctx,
            (u, v),
        ) {
            continue;
        }
        convex_triangulation(piece, &cycle, out);
    }
    Ok(())
}

/// Whether surface triangles lying in the face (`flat`) cover the convex piece: those over its
/// vertices and the face's inner vertices add up to its area.
fn covered(
    piece: &[usize],
    cycle: &[Point],
    flat: &[[u32; 3]],
    inner: &[u32],
    ctx: &Context,
    (u, v): (usize, usize),
) -> bool {
    if flat.is_empty() {
        return false;
    }
    let ids: Vec<u32> = piece.iter().map(|&k| cycle[k].id).collect();
    if piece.len() == 3 {
        let mut sorted = [ids[0], ids[1], ids[2]];
        sorted.sort_unstable();
        if flat.contains(&sorted) {
            return true;
        }
    }
    let area = |a: [f64; 2], b: [f64; 2], c: [f64; 2]| {
        ((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])).abs() / 2.0
    };
    let at = |id: u32| {
        let p = ctx.position(id);
        [f64::from(p[u]), f64::from(p[v])]
    };
    let first = cycle[piece[0]].at;
    let whole: f64 = (1..piece.len() - 1)
        .map(|k| area(first, cycle[piece[k]].at, cycle[piece[k + 1]].at))
        .sum();
    let within = |x: &u32| ids.contains(x) || inner.contains(x);
    let flat_area: f64 = flat
        .iter()
        .filter(|t| t.iter().all(within) && t.iter().any(|x| ids.contains(x)))
        .map(|t| area(at(t[0]), at(t[1]), at(t[2])))
        .sum();
    whole > 0.0 && flat_area >= whole * (1.0 - 1e-9)
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
    if m == 4 {
        // Two diagonals. Equally good (a rectangle), the one through the vertex numbered
        // lowest: diagonals chosen by one order of the vertices never twist a prism of three
        // such faces into one that has no tetrahedra without an inner point (Schönhardt's),
        // which a thin cut cell would have to cone at a poor angle.
        let smallest =
            |a: usize, b: usize, c: usize| crate::quality::smallest_angle_2d(at(a), at(b), at(c));
        let through_02 = smallest(0, 1, 2).min(smallest(0, 2, 3));
        let through_13 = smallest(0, 1, 3).min(smallest(1, 2, 3));
        let lowest = (0..4).min_by_key(|&k| id(k)).expect("four vertices");
        let tie = (through_02 - through_13).abs() <= 1e-9;
        if through_02 > through_13 || (tie && lowest % 2 == 0) {
            out.push([id(0), id(1), id(2)]);
            out.push([id(0), id(2), id(3)]);
        } else {
            out.push([id(0), id(1), id(3)]);
            out.push([id(1), id(2), id(3)]);
        }
        return;
    }
    let smallest =
        |a: usize, b: usize, c: usize| crate::quality::smallest_angle_2d(at(a), at(b), at(c));
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
