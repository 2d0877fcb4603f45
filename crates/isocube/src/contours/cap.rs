//! Flat caps: the open boundary of a reconstruction on an end section's plane, triangulated as
//! polygons with holes (ear clipping, holes bridged to their outer loop).

use crate::mesh::Mesh;

/// Why a set of boundary edges could not be closed with a flat polygon (its loops chained,
/// holes bridged, then triangulated).
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum LoopError {
    /// Two edges leave one vertex.
    #[error("branches")]
    Branches,
    /// A loop passes a vertex twice.
    #[error("is not a set of simple loops")]
    NotSimple,
    /// An edge leads to a vertex no edge leaves.
    #[error("is not closed")]
    NotClosed,
    /// A hole without vertices.
    #[error("has an empty hole")]
    EmptyHole,
    /// A hole has no visible vertex to bridge to, or ear clipping found no ear.
    #[error("cannot be triangulated")]
    Untriangulable,
}

type P2 = [f64; 2];

fn cross(o: P2, a: P2, b: P2) -> f64 {
    (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
}

pub(crate) fn area(poly: &[P2]) -> f64 {
    let n = poly.len();
    (0..n)
        .map(|i| {
            let (a, b) = (poly[i], poly[(i + 1) % n]);
            a[0] * b[1] - b[0] * a[1]
        })
        .sum::<f64>()
        / 2.0
}

fn inside(p: P2, poly: &[P2]) -> bool {
    let mut c = false;
    let n = poly.len();
    for i in 0..n {
        let (a, b) = (poly[i], poly[(i + 1) % n]);
        if (a[1] > p[1]) != (b[1] > p[1]) {
            let x = a[0] + (p[1] - a[1]) / (b[1] - a[1]) * (b[0] - a[0]);
            if x > p[0] {
                c = !c;
            }
        }
    }
    c
}

/// Closes the open boundary of `mesh` lying in the plane `z` (as stored, `f32`). Boundary loops
/// there are grouped by nesting into polygons with holes and triangulated; cap triangles run
/// each boundary edge the other way, so the result is watertight and consistently oriented.
/// Returns the number of triangles added, or an error if the boundary in the plane is not a set
/// of simple closed loops.
pub(super) fn close_plane(mesh: &mut Mesh, z: f32) -> Result<usize, LoopError> {
    // Directed boundary edges in the plane: half-edges without a twin.
    let mut half: std::collections::HashMap<(u32, u32), usize> = std::collections::HashMap::new();
    for t in &mesh.triangles {
        for k in 0..3 {
            *half.entry((t[k], t[(k + 1) % 3])).or_insert(0) += 1;
        }
    }
    let on = |v: u32| mesh.positions[v as usize][2] == z;
    let mut open: Vec<(u32, u32)> = half
        .keys()
        .copied()
        .filter(|&(a, b)| !half.contains_key(&(b, a)) && on(a) && on(b))
        // The cap runs each edge the other way.
        .map(|(a, b)| (b, a))
        .collect();
    open.sort_unstable();
    let loops = chain_loops(&open)?;
    let xy = |v: u32| {
        let p = mesh.positions[v as usize];
        [f64::from(p[0]), f64::from(p[1])]
    };
    let polys: Vec<Vec<P2>> = loops
        .iter()
        .map(|l| l.iter().map(|&v| xy(v)).collect())
        .collect();
    // Nesting depth: even depth loops are outer boundaries of the cap, odd ones holes.
    let depth: Vec<usize> = (0..loops.len())
        .map(|i| {
            (0..loops.len())
                .filter(|&j| j != i && inside(polys[i][0], &polys[j]))
                .count()
        })
        .collect();
    let orientation = polys
        .iter()
        .zip(&depth)
        .find(|(_, d)| *d % 2 == 0)
        .map_or(1.0, |(p, _)| area(p).signum());
    let mut added = 0;
    for i in 0..loops.len() {
        if depth[i] % 2 == 1 {
            continue;
        }
        // Holes directly inside loop i.
        let holes: Vec<usize> = (0..loops.len())
            .filter(|&j| depth[j] == depth[i] + 1 && inside(polys[j][0], &polys[i]))
            .collect();
        let mut ring: Vec<u32> = loops[i].clone();
        let mut order: Vec<usize> = holes.clone();
        // Bridge holes from the one reaching farthest right, as ear-clipping implementations do.
        order.sort_by(|&a, &b| {
            let mx = |k: usize| polys[k].iter().map(|p| p[0]).fold(f64::MIN, f64::max);
            mx(b).total_cmp(&mx(a))
        });
        for h in order {
            ring = bridge(&ring, &loops[h], &xy)?;
        }
        let tris = ear_clip(&ring, &xy, orientation)?;
        added += tris.len();
        mesh.triangles.extend(tris);
    }
    Ok(added)
}

/// Chains directed edges (sorted, for a deterministic result) into closed loops, each edge
/// followed by the one leaving its end. Errors say how the edges fail to form simple loops.
pub(crate) fn chain_loops(edges: &[(u32, u32)]) -> Result<Vec<Vec<u32>>, LoopError> {
    let mut next: std::collections::HashMap<u32, u32> = std::collections::HashMap::new();
    for &(a, b) in edges {
        if next.insert(a, b).is_some() {
            return Err(LoopError::Branches);
        }
    }
    let mut loops: Vec<Vec<u32>> = Vec::new();
    let mut seen = std::collections::HashSet::new();
    for &(start, _) in edges {
        if seen.contains(&start) {
            continue;
        }
        let mut l = vec![start];
        seen.insert(start);
        let mut v = next[&start];
        while v != start {
            if !seen.insert(v) {
                return Err(LoopError::NotSimple);
            }
            l.push(v);
            v = *next.get(&v).ok_or(LoopError::NotClosed)?;
        }
        loops.push(l);
    }
    Ok(loops)
}

/// Joins a hole to the ring by a two-way cut from the hole's rightmost vertex to a ring vertex
/// it can see.
pub(crate) fn bridge(
    ring: &[u32],
    hole: &[u32],
    xy: &dyn Fn(u32) -> P2,
) -> Result<Vec<u32>, LoopError> {
    let (hi, &h) = hole
        .iter()
        .enumerate()
        .max_by(|a, b| xy(*a.1)[0].total_cmp(&xy(*b.1)[0]))
        .ok_or(LoopError::EmptyHole)?;
    let hp = xy(h);
    let n = ring.len();
    // Visible ring vertices: the segment to them crosses no ring or hole edge.
    let segments_cross = |a: P2, b: P2, poly: &[u32], skip: u32| {
        let m = poly.len();
        (0..m).any(|k| {
            let (u, w) = (poly[k], poly[(k + 1) % m]);
            if u == skip || w == skip {
                return false;
            }
            let (c, d) = (xy(u), xy(w));
            let d1 = cross(a, b, c);
            let d2 = cross(a, b, d);
            let d3 = cross(c, d, a);
            let d4 = cross(c, d, b);
            (d1 > 0.0) != (d2 > 0.0) && (d3 > 0.0) != (d4 > 0.0) && d1 != 0.0 && d2 != 0.0
        })
    };
    let mut candidates: Vec<(f64, usize)> = (0..n)
        .map(|k| {
            let p = xy(ring[k]);
            ((p[0] - hp[0]).powi(2) + (p[1] - hp[1]).powi(2), k)
        })
        .collect();
    candidates.sort_by(|a, b| a.0.total_cmp(&b.0));
    let k = candidates
        .into_iter()
        .map(|(_, k)| k)
        .find(|&k| {
            let p = xy(ring[k]);
            !segments_cross(hp, p, ring, ring[k]) && !segments_cross(hp, p, hole, h)
        })
        .ok_or(LoopError::Untriangulable)?;
    let mut out = Vec::with_capacity(n + hole.len() + 2);
    out.extend_from_slice(&ring[..=k]);
    for t in 0..=hole.len() {
        out.push(hole[(hi + t) % hole.len()]);
    }
    out.push(ring[k]);
    out.extend_from_slice(&ring[k + 1..]);
    Ok(out)
}

/// Rings up to this many vertices are clipped best ear first.
const BEST_EAR_RING: usize = 400;

/// Ear clipping of a (weakly) simple ring whose orientation has the sign `orientation`.
pub(crate) fn ear_clip(
    ring: &[u32],
    xy: &dyn Fn(u32) -> P2,
    orientation: f64,
) -> Result<Vec<[u32; 3]>, LoopError> {
    let mut v: Vec<u32> = ring.to_vec();
    let mut out = Vec::with_capacity(v.len());
    let mut guard = 0usize;
    // The smallest angle of a triangle, for choosing among ears.
    let smallest = crate::quality::smallest_angle_2d;
    while v.len() > 3 {
        let n = v.len();
        // Small rings take the best-shaped ear (quadratic per ear); large ones, as dense
        // contours make, the first (keeping the whole linear per ear).
        let choose = n <= BEST_EAR_RING;
        let mut best: Option<(f64, usize)> = None;
        for i in 0..n {
            let (a, b, c) = (v[(i + n - 1) % n], v[i], v[(i + 1) % n]);
            let (pa, pb, pc) = (xy(a), xy(b), xy(c));
            let turn = cross(pa, pb, pc) * orientation;
            // Not convex, or straight up to rounding (refined edges and dense contours have runs
            // of collinear points): clipping there would leave a flat triangle.
            let scale = (pb[0] - pa[0]).hypot(pb[1] - pa[1]) * (pc[0] - pb[0]).hypot(pc[1] - pb[1]);
            if turn <= 1e-9 * scale {
                continue;
            }
            // No other ring point inside or on the ear (bridge duplicates share positions).
            let blocked = v.iter().any(|&w| {
                if w == a || w == b || w == c {
                    return false;
                }
                let p = xy(w);
                if p == pa || p == pb || p == pc {
                    return false;
                }
                let s1 = cross(pa, pb, p) * orientation;
                let s2 = cross(pb, pc, p) * orientation;
                let s3 = cross(pc, pa, p) * orientation;
                s1 >= 0.0 && s2 >= 0.0 && s3 >= 0.0
            });
            if blocked {
                continue;
            }
            let q = if choose { smallest(pa, pb, pc) } else { 0.0 };
            if best.is_none_or(|(bq, _)| q > bq) {
                best = Some((q, i));
            }
            if !choose {
                break;
            }
        }
        let Some((_, i)) = best else {
            return Err(LoopError::Untriangulable);
        };
        out.push([v[(i + n - 1) % n], v[i], v[(i + 1) % n]]);
        v.remove(i);
        guard += 1;
        if guard > 4 * ring.len() + 16 {
            return Err(LoopError::Untriangulable);
        }
    }
    if v.len() == 3 && cross(xy(v[0]), xy(v[1]), xy(v[2])) * orientation > 0.0 {
        out.push([v[0], v[1], v[2]]);
    }
    Ok(out)
}
