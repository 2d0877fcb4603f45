//! Combinatorial triangulation of cell patches: disks (one loop) and annuli (two loops).
//!
//! All of it runs once, when the case table is built. Corners are cube edges; where geometry is
//! needed to choose between triangulations (the band of an annulus), the edge midpoints stand in
//! for the crossings.

use super::polygons::Corner;
use super::{EDGES, VERTICES};

/// Faces y=0, x=0 and z=0 (bits as in [`Corner::faces`]).
pub const NEGATIVE_FACES: u8 = 1 << 0 | 1 << 3 | 1 << 4;
/// Faces z=0 and z=1: the section planes of sectional meshing.
pub const Z_FACES: u8 = 1 << 4 | 1 << 5;
/// All six faces.
pub const ALL_FACES: u8 = 0b11_1111;

/// The diagonal rule that keeps meshes manifold, for every cell mesher: a chord between two
/// corners of a cell's loop that lie on the common faces `shared` (bits as in
/// [`Corner::faces`]) may be used inside the cell unless one of those faces is a negative one or
/// in `also`.
///
/// Two corners on a common face can only be joined inside a cell when the face is ambiguous (four
/// crossings); the cell across the face sees the same four crossings and might join the same two,
/// giving an edge of four triangles. So such joins are allowed only across the cell's positive
/// faces (x=1, y=1, z=1): the neighbour sees that face as a negative one and never uses it.
/// Meshers forbid more faces where they must: ternary cells every face (their corners include
/// zero points, which a neighbour's patch may use differently), sectional cells the section
/// planes (a chord there would add an edge to the contour's cut).
///
/// ```
/// use isocube::cube::triangulate::{may_join_on, ALL_FACES};
/// assert!(may_join_on(1 << 1, 0)); // both on x = 1
/// assert!(!may_join_on(1 << 3, 0)); // both on x = 0
/// assert!(!may_join_on(1 << 1, ALL_FACES));
/// assert!(may_join_on(0, ALL_FACES)); // no common face
/// ```
#[inline]
pub fn may_join_on(shared: u8, also: u8) -> bool {
    shared & (NEGATIVE_FACES | also) == 0
}

/// [`may_join_on`] for two corners of a binary cell's loop.
pub fn may_join(a: Corner, b: Corner) -> bool {
    may_join_on(a.faces() & b.faces(), 0)
}

/// Triangulation of a disk bounded by one loop that respects [`may_join`]: a fan when some apex
/// allows one, otherwise any triangulation found by dynamic programming over sub-polygons (at
/// most 12 corners). Always `n − 2` triangles.
///
/// Returns `None` when no such triangulation exists (the caller then needs an interior point).
pub fn safe_triangulation(polygon: &[Corner]) -> Option<Vec<[Corner; 3]>> {
    safe_triangulation_where(polygon, &|_, _| true)
}

/// [`safe_triangulation`] with chords also limited to those `also` allows (the mesher's rules
/// where values sit exactly at the level).
///
/// ```
/// use isocube::cube::triangulate::safe_triangulation_where;
/// use isocube::cube::CaseTable;
/// let table = CaseTable::binary();
/// let square = table.polygons(0b0000_1111, Default::default()).next().unwrap();
/// let no_chord = safe_triangulation_where(square, &|_, _| false);
/// assert!(no_chord.is_none());
/// assert_eq!(safe_triangulation_where(square, &|_, _| true).unwrap().len(), 2);
/// ```
pub fn safe_triangulation_where(
    polygon: &[Corner],
    also: &dyn Fn(Corner, Corner) -> bool,
) -> Option<Vec<[Corner; 3]>> {
    let n = polygon.len();
    let allowed = |i: usize, j: usize| {
        let d = i.abs_diff(j);
        d == 1 || d == n - 1 || may_join(polygon[i], polygon[j]) && also(polygon[i], polygon[j])
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

/// Triangles of a polygon around an interior point ([`Corner::INTERIOR`]).
pub fn star(polygon: &[Corner]) -> Vec<[Corner; 3]> {
    let n = polygon.len();
    (0..n)
        .map(|i| [polygon[i], polygon[(i + 1) % n], Corner::INTERIOR])
        .collect()
}

fn midpoint(c: Corner) -> [f64; 3] {
    if c.as_interior().is_some() {
        return [0.5; 3];
    }
    let e = c.as_edge().expect("band corners are edge crossings");
    let [a, b] = EDGES[usize::from(e)];
    let (p, q) = (VERTICES[usize::from(a)], VERTICES[usize::from(b)]);
    [0, 1, 2].map(|i| (f64::from(p[i]) + f64::from(q[i])) / 2.0)
}

fn distance(a: Corner, b: Corner) -> f64 {
    let (p, q) = (midpoint(a), midpoint(b));
    (0..3).map(|i| (p[i] - q[i]).powi(2)).sum::<f64>().sqrt()
}

fn centroid(corners: &[Corner]) -> [f64; 3] {
    let n = corners.len() as f64;
    let mut c = [0.0; 3];
    for &k in corners {
        let p = midpoint(k);
        for i in 0..3 {
            c[i] += p[i] / n;
        }
    }
    c
}

/// Triangulates the annulus (tunnel) between two loops, each oriented as a boundary of the
/// annulus (so they run opposite ways round the tunnel): `n1 + n2` triangles, each with one loop
/// edge and a vertex of the other loop.
///
/// Among all such bands whose rungs respect [`may_join`], the one with the shortest total rung
/// length (between edge midpoints) is chosen, ties broken by search order, so the result is
/// deterministic. Returns `None` if no band exists.
pub fn band(l1: &[Corner], l2: &[Corner]) -> Option<Vec<[Corner; 3]>> {
    band_search(l1, l2, &midpoint, false)
}

/// Triangulates a tunnel through an interior point ([`Corner::INTERIOR`]) when no plain
/// [`band`] exists: the point fans one contiguous stretch of the tunnel (an arc of each loop), and
/// direct rungs triangulate the rest. The interior point touches no face, so it can always be
/// joined; at least one direct rung is kept so the point's neighbourhood is a disk, not a pinch.
/// Chooses the shortest total rung length, with the point at the cell centre. `n1 + n2 + 2`
/// triangles.
pub fn band_with_interior(l1: &[Corner], l2: &[Corner]) -> Option<Vec<[Corner; 3]>> {
    band_search(l1, l2, &midpoint, true)
}

/// [`band`] (`through_interior` false) or [`band_with_interior`] (true) with rungs measured
/// between the given positions of the corners (the interior point's too) instead of the edges'
/// midpoints: the same rule for which rungs may be drawn, the cheapest band for a cell's actual
/// crossings.
pub fn band_at(
    l1: &[Corner],
    l2: &[Corner],
    position: &dyn Fn(Corner) -> [f64; 3],
    through_interior: bool,
) -> Option<Vec<[Corner; 3]>> {
    band_search(l1, l2, position, through_interior)
}

/// Whether a rung between two crossings may be a diagonal of the face they share. Rungs of a
/// band never cross in the band, but on an ambiguous face the two loops' segments can sit so
/// that both of the face's diagonals are rungs: two edges of the surface lying in one face and
/// crossing there (a self-intersection). Of a face's two diagonals only the one through its
/// lowest-numbered edge is allowed; a band that needs the other passes through an interior
/// point instead. Any other chord in a face joins crossings next to each other round it and
/// crosses nothing.
fn diagonal_allowed(a: Corner, b: Corner) -> bool {
    let (Some(ea), Some(eb)) = (a.as_edge(), b.as_edge()) else {
        return true;
    };
    let shared = a.faces() & b.faces();
    let [p, q] = EDGES[usize::from(ea)];
    let [r, s] = EDGES[usize::from(eb)];
    if shared == 0 || ea == eb || [p, q].iter().any(|v| *v == r || *v == s) {
        return true;
    }
    let lowest = (0..12u8)
        .find(|&e| Corner::edge(e).faces() & shared != 0)
        .expect("a face has edges");
    ea == lowest || eb == lowest
}

/// The search behind [`band`] and [`band_with_interior`]: the cheapest monotone path across the
/// (n1+1)×(n2+1) grid of rungs, for every start rung. Each step advances one loop and adds a
/// triangle. With `through_interior`, the path passes once through a stretch where rungs go via
/// the interior point (phase 1), entered and left at direct rungs (phases 0 and 2).
///
/// To keep every rung distinct, the path starts by advancing along the first loop and ends by
/// advancing along the second, and (n1, 0) — the start rung again — is never visited; every band
/// has a start rung that allows this. Inside the stretch no loop may wrap round to its start
/// corner, or the point would meet that corner twice.
fn band_search(
    l1: &[Corner],
    l2: &[Corner],
    position: &dyn Fn(Corner) -> [f64; 3],
    through_interior: bool,
) -> Option<Vec<[Corner; 3]>> {
    let (n1, n2) = (l1.len(), l2.len());
    let distance = |a: Corner, b: Corner| {
        let (p, q) = (position(a), position(b));
        (0..3).map(|i| (p[i] - q[i]).powi(2)).sum::<f64>().sqrt()
    };
    let phases = if through_interior { 3 } else { 1 };
    let last = phases - 1;
    let x = Corner::INTERIOR;
    // Rung lengths and admissibility between every pair of corners, computed once (the search
    // below visits each pair for every start rung); the same arithmetic, so the same bits.
    let pair = |f: &dyn Fn(usize, usize) -> f64| -> Vec<f64> {
        (0..n1 * n2).map(|k| f(k / n2, k % n2)).collect()
    };
    let rung_length = pair(&|u, v| distance(l1[u], l2[v]));
    let via_length = match through_interior {
        true => pair(&|u, v| distance(l1[u], x) + distance(x, l2[v])),
        false => Vec::new(),
    };
    let joinable: Vec<bool> = (0..n1 * n2)
        .map(|k| may_join(l1[k / n2], l2[k % n2]) && diagonal_allowed(l1[k / n2], l2[k % n2]))
        .collect();
    let inf = f64::INFINITY;
    let size = phases * (n1 + 1) * (n2 + 1);
    let at = |phase: usize, i: usize, m: usize| (phase * (n1 + 1) + i) * (n2 + 1) + m;
    let mut cost = vec![inf; size];
    let mut step = vec![u8::MAX; size];
    let mut best: Option<(f64, Vec<[Corner; 3]>)> = None;
    // Phases: 0 before the interior stretch, 1 inside it (rungs pass through the point), 2 after.
    for r in 0..n1 {
        for s in 0..n2 {
            let ai = |i: usize| (r + i) % n1;
            let ci = |m: usize| (s + n2 * 2 - m) % n2;
            let a = |i: usize| l1[ai(i)];
            let c = |m: usize| l2[ci(m)];
            if !joinable[ai(0) * n2 + ci(0)] {
                continue;
            }
            // cost[phase][i][m] and the step that reached it: 0 L1 advance, 1 L2 advance,
            // 2 phase change at the same rung.
            cost.fill(inf);
            step.fill(u8::MAX);
            cost[at(0, 0, 0)] = 0.0;
            for i in 0..=n1 {
                for m in 0..=n2 {
                    let final_state = (i, m) == (n1, n2);
                    let k = ai(i) * n2 + ci(m);
                    let direct_ok = final_state || (i > 0 && (i, m) != (n1, 0) && joinable[k]);
                    let direct = if final_state { 0.0 } else { rung_length[k] };
                    let via = if through_interior { via_length[k] } else { 0.0 };
                    for phase in 0..phases {
                        if (i, m) == (0, 0) && phase == 0 {
                            continue;
                        }
                        let mut here = (inf, u8::MAX);
                        let mut offer = |v: f64, st: u8| {
                            if v < here.0 {
                                here = (v, st);
                            }
                        };
                        let rung = if phase == 1 { via } else { direct };
                        if phase != 1 && !direct_ok {
                            continue;
                        }
                        // Inside the stretch no loop may wrap round to its start corner, or the
                        // point would meet that corner twice.
                        if phase == 1 && (i == n1 || m == n2) {
                            continue;
                        }
                        if i > 0 && !(final_state && phase != 1) {
                            offer(cost[at(phase, i - 1, m)] + rung, 0);
                        }
                        if m > 0 {
                            offer(cost[at(phase, i, m - 1)] + rung, 1);
                        }
                        // Entering the stretch: from the direct rung at the same place.
                        if phase == 1 && (i, m) != (n1, n2) {
                            offer(cost[at(0, i, m)] + via, 2);
                        }
                        // Leaving it: back to a direct rung here, after at least one step inside.
                        if phase == 2 && step[at(1, i, m)] < 2 {
                            offer(cost[at(1, i, m)] + direct, 2);
                        }
                        cost[at(phase, i, m)] = here.0;
                        step[at(phase, i, m)] = here.1;
                    }
                }
            }
            let total = cost[at(last, n1, n2)];
            if total == inf || best.as_ref().is_some_and(|(b, _)| *b <= total) {
                continue;
            }
            let mut triangles = Vec::with_capacity(n1 + n2 + 2);
            let (mut i, mut m, mut phase) = (n1, n2, last);
            while (i, m, phase) != (0, 0, 0) {
                match step[at(phase, i, m)] {
                    0 => {
                        triangles.push(if phase == 1 {
                            [a(i - 1), a(i), x]
                        } else {
                            [a(i - 1), a(i), c(m)]
                        });
                        i -= 1;
                    }
                    1 => {
                        triangles.push(if phase == 1 {
                            [c(m), c(m - 1), x]
                        } else {
                            [c(m), c(m - 1), a(i)]
                        });
                        m -= 1;
                    }
                    _ => {
                        // Leaving (2 ← 1): triangle before the direct rung; entering (1 ← 0):
                        // triangle after it.
                        if phase == 2 {
                            triangles.push([a(i), c(m), x]);
                            phase = 1;
                        } else {
                            triangles.push([c(m), a(i), x]);
                            phase = 0;
                        }
                    }
                }
            }
            triangles.reverse();
            best = Some((total, triangles));
        }
    }
    best.map(|(_, t)| t)
}

/// Triangulates a tunnel through a ring of three interior points when neither [`band`] nor
/// [`band_with_interior`] exists: a band from the first loop to the ring and one from the ring
/// to the second loop. Interior points touch no face, so both bands always exist. Returns the
/// triangles and, for interior point `k`, the loop corners whose centroid places it (an evenly
/// spaced corner of the first loop and the nearest corner of the second, so the ring sits halfway
/// along the tunnel). `n1 + n2 + 6` triangles.
pub fn band_through_ring(l1: &[Corner], l2: &[Corner]) -> (Vec<[Corner; 3]>, Vec<Vec<Corner>>) {
    let n1 = l1.len();
    let supports: Vec<Vec<Corner>> = (0..3)
        .map(|k| {
            let a = l1[k * n1 / 3];
            let nearest = *l2
                .iter()
                .min_by(|&&x, &&y| distance(a, x).total_cmp(&distance(a, y)))
                .expect("loops have corners");
            vec![a, nearest]
        })
        .collect();
    let ring: Vec<Corner> = (0..3).map(Corner::interior).collect();
    let position = |c: Corner| match c.as_interior() {
        Some(k) => centroid(&supports[usize::from(k)]),
        None => midpoint(c),
    };
    // The ring follows the first loop's direction; as the far boundary of the first band it
    // must run the other way.
    let reversed: Vec<Corner> = ring.iter().rev().copied().collect();
    let mut triangles =
        band_search(l1, &reversed, &position, false).expect("interior rungs are always admissible");
    triangles.extend(
        band_search(&ring, l2, &position, false).expect("interior rungs are always admissible"),
    );
    (triangles, supports)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    fn edge_uses(tris: &[[Corner; 3]]) -> HashMap<(Corner, Corner), i32> {
        let mut uses = HashMap::new();
        for t in tris {
            for k in 0..3 {
                *uses.entry((t[k], t[(k + 1) % 3])).or_insert(0) += 1;
            }
        }
        uses
    }

    /// Checks that triangles form an oriented annulus bounded by the two loops.
    fn assert_annulus(tris: &[[Corner; 3]], l1: &[Corner], l2: &[Corner]) {
        let uses = edge_uses(tris);
        for (&(a, b), &n) in &uses {
            assert_eq!(n, 1, "{a:?}-{b:?}");
            let on_loop =
                |l: &[Corner]| (0..l.len()).any(|i| l[i] == a && l[(i + 1) % l.len()] == b);
            if !on_loop(l1) && !on_loop(l2) {
                assert_eq!(
                    uses.get(&(b, a)),
                    Some(&1),
                    "rung {a:?}-{b:?} used one way only"
                );
            }
        }
        for l in [l1, l2] {
            for i in 0..l.len() {
                assert_eq!(uses.get(&(l[i], l[(i + 1) % l.len()])), Some(&1));
            }
        }
        let mut vertices: Vec<Corner> = tris.iter().flatten().copied().collect();
        vertices.sort();
        vertices.dedup();
        let edges: std::collections::HashSet<_> = uses
            .keys()
            .map(|&(a, b)| if a < b { (a, b) } else { (b, a) })
            .collect();
        assert_eq!(
            vertices.len() as i32 - edges.len() as i32 + tris.len() as i32,
            0,
            "Euler characteristic"
        );
        // Each interior point, if used, has a disk neighbourhood: its link is one cycle.
        for point in (0..Corner::MAX_INTERIOR as u8).map(Corner::interior) {
            let around: Vec<_> = tris.iter().filter(|t| t.contains(&point)).collect();
            if around.is_empty() {
                continue;
            }
            let mut next = HashMap::new();
            for t in &around {
                let k = t.iter().position(|&c| c == point).unwrap();
                next.insert(t[(k + 1) % 3], t[(k + 2) % 3]);
            }
            let start = *next.keys().next().unwrap();
            let (mut v, mut steps) = (start, 0);
            loop {
                v = next[&v];
                steps += 1;
                if v == start {
                    break;
                }
            }
            assert_eq!(steps, around.len(), "the interior point is a pinch");
        }
    }

    #[test]
    fn band_through_an_interior_point_when_faces_forbid_rungs() {
        // Case 7 with a tunnel: the loop round vertex 4 and the hexagon share the negative faces
        // y=0 and x=0, so no plain band exists.
        let l1 = [4, 7, 8].map(Corner::edge);
        let l2 = [11, 6, 5, 9, 0, 3].map(Corner::edge);
        assert!(band(&l1, &l2).is_none());
        let tris = band_with_interior(&l1, &l2).unwrap();
        assert_eq!(tris.len(), 3 + 6 + 2);
        assert_annulus(&tris, &l1, &l2);
        for t in &tris {
            for k in 0..3 {
                assert!(
                    may_join(t[k], t[(k + 1) % 3])
                        || [t[k], t[(k + 1) % 3]].contains(&Corner::INTERIOR)
                        || l1.contains(&t[k]) && l1.contains(&t[(k + 1) % 3])
                        || l2.contains(&t[k]) && l2.contains(&t[(k + 1) % 3])
                );
            }
        }
    }

    #[test]
    fn band_through_a_ring_when_one_interior_point_cannot_serve() {
        // Case 7 with a tunnel from the corner at vertex 0, whose three faces are all negative:
        // neither a plain band nor a single interior point works.
        let l1 = [0, 3, 8].map(Corner::edge);
        let l2 = [1, 9, 4, 7, 11, 2].map(Corner::edge);
        assert!(band(&l1, &l2).is_none() && band_with_interior(&l1, &l2).is_none());
        let (tris, supports) = band_through_ring(&l1, &l2);
        assert_eq!(tris.len(), 3 + 6 + 6);
        assert_eq!(supports.len(), 3);
        assert_annulus(&tris, &l1, &l2);
    }

    #[test]
    fn band_of_two_triangles_is_an_oriented_annulus() {
        // Loops around vertices 0 and 6 (case 4 with a tunnel), as derive_polygons orients them.
        let l1 = [0, 3, 8].map(Corner::edge);
        let l2 = [5, 10, 6].map(Corner::edge);
        let tris = band(&l1, &l2).unwrap();
        assert_eq!(tris.len(), 6);
        assert_annulus(&tris, &l1, &l2);
        let uses = edge_uses(&tris);
        // Interior rungs are used once in each direction; loop edges once, in loop order.
        for (&(a, b), &n) in &uses {
            assert_eq!(n, 1);
            let on_loop =
                |l: &[Corner]| (0..l.len()).any(|i| l[i] == a && l[(i + 1) % l.len()] == b);
            if !on_loop(&l1) && !on_loop(&l2) {
                assert_eq!(
                    uses.get(&(b, a)),
                    Some(&1),
                    "rung {a:?}-{b:?} used one way only"
                );
            }
        }
        // Euler characteristic of the band: V − E + F = 6 − 12 + 6 = 0.
        let undirected: std::collections::HashSet<_> = uses
            .keys()
            .map(|&(a, b)| if a < b { (a, b) } else { (b, a) })
            .collect();
        assert_eq!(6 - undirected.len() as i32 + tris.len() as i32, 0);
    }
}
