//! Filling a cell's part of the region from several cone points when no single point sees it
//! all: the general construction behind [`super::Context::fill`]'s last attempt.
//!
//! Every triangle of the part is coned to a point that sees it from inside. Between two cones
//! that meet along an edge `a → b` lies a wedge: one tetrahedron `(b, a, s_i, s_j)`, or, where
//! that would turn inside out (the surface folds outward there, so the two cone points lie on
//! either side of the fold's reflex angle), two through a point `m` placed inside the fold.
//! Around each vertex where cones meet, the wedges leave a cycle of faces `(v, x, y)`: a fan
//! from one of its points closes it, or its ears cut off one by one, or a star around one more
//! point near the vertex. What is left has only Steiner points for corners, and is coned to one
//! more point (or one of its own). The result is accepted only when every face of the tetrahedra
//! cancels except the part's own triangles and every tetrahedron is positive: then they tile the
//! part exactly.

use super::check;
use super::STEINER;

/// Steiner points and the tetrahedra using them (`STEINER | index` into the points).
pub(super) type Tiled = (Vec<[f64; 3]>, Vec<[u32; 4]>);

/// The tetrahedra tiling `part`, each triangle coned to `points[group[t]]`, and the Steiner
/// points they use (`STEINER | index` into the returned points, which keep the given points'
/// order, those added after), or why not. With `only = Some(v)`, `part` is the triangles
/// around `v` and only the tetrahedra there are made (a check for [`assign`]).
pub(super) fn tile(
    part: &[[u32; 3]],
    tris: &[[[f64; 3]; 3]],
    degenerate: &[bool],
    points: &[[f64; 3]],
    group: &[u32],
    position: &dyn Fn(u32) -> [f64; 3],
    only: Option<u32>,
) -> Result<Tiled, &'static str> {
    let mut pts: Vec<[f64; 3]> = points.to_vec();
    let steiner = |g: u32| STEINER | g;
    let bounds = bounds(tris);
    let mut tets: Vec<[u32; 4]> = part
        .iter()
        .zip(group)
        .map(|(t, &g)| [t[0], t[2], t[1], steiner(g)])
        .collect();
    let cones = tets.len();
    let at = |pts: &[[f64; 3]], v: u32| {
        if v & STEINER != 0 {
            pts[(v & !STEINER) as usize]
        } else {
            position(v)
        }
    };
    let positive = |pts: &[[f64; 3]], t: [u32; 4]| {
        let [a, b, c, d] = t.map(|v| at(pts, v));
        check::positive(a, b, c, d)
    };

    // Wedges between cones.
    let mut directed: Vec<(u32, u32, u32, usize)> = part
        .iter()
        .zip(group)
        .enumerate()
        .flat_map(|(i, (t, &g))| (0..3).map(move |k| (t[k], t[(k + 1) % 3], g, i)))
        .collect();
    directed.sort_unstable();
    for &(a, b, i, ti) in &directed {
        let from = directed.partition_point(|x| (x.0, x.1) < (b, a));
        let Some(other) = directed.get(from).filter(|x| (x.0, x.1) == (b, a)) else {
            if only.is_some() {
                continue;
            }
            return Err("unpaired edge");
        };
        let (j, tj) = (other.2, other.3);
        if i >= j {
            continue;
        }
        let wedge = [b, a, steiner(i), steiner(j)];
        if positive(&pts, wedge) {
            tets.push(wedge);
            continue;
        }
        let (pa, pb) = (position(a), position(b));
        let m = fold_point(
            pa,
            pb,
            &tris[ti],
            &tris[tj],
            at(&pts, steiner(i)),
            at(&pts, steiner(j)),
            bounds,
        )
        .ok_or("fold point")?;
        let id = steiner(pts.len() as u32);
        pts.push(m);
        let placed = [[b, a, steiner(i), id], [b, a, id, steiner(j)]];
        tets.extend(placed);
    }

    // Cycles of faces (v, x, y) around each vertex.
    let mut around: Vec<(u32, u32, u32)> = open_faces(&tets, part)
        .iter()
        .filter_map(|f| {
            let rotations = [[f[0], f[1], f[2]], [f[1], f[2], f[0]], [f[2], f[0], f[1]]];
            rotations
                .iter()
                .find(|r| r[0] & STEINER == 0 && r[1] & STEINER != 0 && r[2] & STEINER != 0)
                .map(|r| (r[0], r[1], r[2]))
        })
        .collect();
    around.sort_unstable();
    let mut i = 0;
    while i < around.len() {
        let v = around[i].0;
        let mut j = i;
        while j < around.len() && around[j].0 == v {
            j += 1;
        }
        if only.is_some_and(|o| o != v) {
            i = j;
            continue;
        }
        let mut edges: Vec<(u32, u32)> = around[i..j].iter().map(|e| (e.1, e.2)).collect();
        while let Some(&(start, _)) = edges.iter().min() {
            let mut cycle = vec![start];
            let mut here = start;
            loop {
                let k = edges.iter().position(|e| e.0 == here).ok_or("open cycle")?;
                let (_, next) = edges.swap_remove(k);
                if next == start {
                    break;
                }
                cycle.push(next);
                here = next;
            }
            let n = cycle.len();
            let fan = (0..n).find_map(|r| {
                let c = |k: usize| cycle[(r + k) % n];
                let fan: Vec<[u32; 4]> = (1..n - 1).map(|k| [v, c(k), c(k + 1), c(0)]).collect();
                fan.iter().all(|&t| positive(&pts, t)).then_some(fan)
            });
            let fan = match fan.or_else(|| ears(v, &cycle, &|t| positive(&pts, t))) {
                Some(fan) => fan,
                None => {
                    // A star around a point between the vertex and its cycle's centroid.
                    let pv = position(v);
                    let centre: [f64; 3] = std::array::from_fn(|d| {
                        cycle.iter().map(|&c| at(&pts, c)[d]).sum::<f64>() / n as f64
                    });
                    let id = steiner(pts.len() as u32);
                    let star = [0.5, 0.25, 0.75, 0.1].iter().find_map(|&f| {
                        let w: [f64; 3] = std::array::from_fn(|d| {
                            f64::from((pv[d] + f * (centre[d] - pv[d])) as f32)
                        });
                        pts.push(w);
                        let star: Vec<[u32; 4]> = (0..n)
                            .map(|k| [v, cycle[k], cycle[(k + 1) % n], id])
                            .collect();
                        if star.iter().all(|&t| positive(&pts, t)) {
                            Some(star)
                        } else {
                            pts.pop();
                            None
                        }
                    });
                    star.ok_or("no fan")?
                }
            };
            tets.extend(fan);
        }
        i = j;
    }

    if only.is_some() {
        return Ok((pts, tets));
    }
    // What is left has Steiner points only: a cone from their centroid, or from one of them.
    let left = open_faces(&tets, part);
    if !left.is_empty() {
        if left.iter().any(|f| f.iter().any(|&v| v & STEINER == 0)) {
            return Err("open faces on the part's vertices");
        }
        let mut used: Vec<u32> = left.iter().flatten().copied().collect();
        used.sort_unstable();
        used.dedup();
        let n = used.len() as f64;
        let centroid: [f64; 3] = std::array::from_fn(|d| {
            f64::from((used.iter().map(|&v| at(&pts, v)[d]).sum::<f64>() / n) as f32)
        });
        pts.push(centroid);
        let core = steiner(pts.len() as u32 - 1);
        let apexes = std::iter::once(core).chain(used.iter().copied());
        let closing = apexes
            .clone()
            .find_map(|apex| {
                let cone: Vec<[u32; 4]> = left
                    .iter()
                    .filter(|f| !f.contains(&apex))
                    .map(|f| [f[0], f[1], f[2], apex])
                    .collect();
                cone.iter().all(|&t| positive(&pts, t)).then_some(cone)
            })
            .ok_or("no core")?;
        if !closing.iter().any(|t| t[3] == core) {
            pts.pop();
        }
        tets.extend(closing);
        if !open_faces(&tets, part).is_empty() {
            return Err("still open");
        }
    }
    let all_positive = tets.iter().enumerate().all(|(k, &t)| {
        positive(&pts, t) || {
            let [a, b, c, d] = t.map(|v| at(&pts, v));
            k < cones && degenerate[k] && !check::positive(a, c, b, d)
        }
    });
    if !all_positive {
        return Err("not positive");
    }
    // Only the points some tetrahedron uses, renumbered in order.
    let mut used = vec![u32::MAX; pts.len()];
    for v in tets.iter().flatten() {
        if v & STEINER != 0 {
            used[(v & !STEINER) as usize] = 0;
        }
    }
    let mut kept = Vec::new();
    for (k, u) in used.iter_mut().enumerate() {
        if *u == 0 {
            *u = kept.len() as u32;
            kept.push(pts[k]);
        }
    }
    for v in tets.iter_mut().flatten() {
        if *v & STEINER != 0 {
            *v = STEINER | used[(*v & !STEINER) as usize];
        }
    }
    Ok((kept, tets))
}

/// Chooses each triangle's cone point among those that see it, so that the cones of every two
/// neighbours either coincide or leave a wedge that [`tile`] can fill (one tetrahedron, or two
/// through a point inside a fold): a small search with backtracking, in breadth-first order
/// over the part's edges, preferring earlier points. `None` if none is found within its budget.
pub(super) fn assign(
    part: &[[u32; 3]],
    tris: &[[[f64; 3]; 3]],
    degenerate: &[bool],
    points: &[[f64; 3]],
    position: &dyn Fn(u32) -> [f64; 3],
) -> Option<Vec<u32>> {
    let n = part.len();
    let mut directed: Vec<(u32, u32, usize)> = part
        .iter()
        .enumerate()
        .flat_map(|(i, t)| (0..3).map(move |k| (t[k], t[(k + 1) % 3], i)))
        .collect();
    directed.sort_unstable();
    // (neighbour, a, b) with a → b in this triangle.
    let mut adjacent: Vec<Vec<(usize, u32, u32)>> = vec![Vec::new(); n];
    for &(a, b, i) in &directed {
        let from = directed.partition_point(|x| (x.0, x.1) < (b, a));
        if let Some(&(_, _, j)) = directed.get(from).filter(|x| (x.0, x.1) == (b, a)) {
            adjacent[i].push((j, a, b));
        }
    }
    let domain: Vec<Vec<u32>> = (0..n)
        .map(|i| {
            (0..points.len() as u32)
                .filter(|&g| sees(&tris[i], degenerate[i], points[g as usize]))
                .collect()
        })
        .collect();
    let bounds = bounds(tris);
    let compatible = |i: usize, gi: u32, j: usize, gj: u32, a: u32, b: u32| {
        gi == gj || {
            let (si, sj) = (points[gi as usize], points[gj as usize]);
            let (pa, pb) = (position(a), position(b));
            check::positive(pb, pa, si, sj)
                || fold_point(pa, pb, &tris[i], &tris[j], si, sj, bounds).is_some()
        }
    };
    // Every pair of choices across every edge, decided once.
    let mut arcs: Vec<(usize, usize, Vec<bool>)> = Vec::new();
    for i in 0..n {
        for &(j, a, b) in &adjacent[i] {
            let ok: Vec<bool> = domain[i]
                .iter()
                .flat_map(|&gi| domain[j].iter().map(move |&gj| (gi, gj)))
                .map(|(gi, gj)| compatible(i, gi, j, gj, a, b))
                .collect();
            arcs.push((i, j, ok));
        }
    }
    let mut alive: Vec<Vec<bool>> = domain.iter().map(|d| vec![true; d.len()]).collect();
    // Arc consistency: drop choices that no choice across some edge can meet.
    loop {
        let mut changed = false;
        for (i, j, ok) in &arcs {
            let w = domain[*j].len();
            for x in 0..domain[*i].len() {
                if alive[*i][x] && !(0..w).any(|y| alive[*j][y] && ok[x * w + y]) {
                    alive[*i][x] = false;
                    changed = true;
                }
            }
        }
        if !changed {
            break;
        }
    }
    if alive.iter().any(|a| !a.contains(&true)) {
        return None;
    }
    let mut by_triangle: Vec<Vec<usize>> = vec![Vec::new(); n];
    for (k, (i, _, _)) in arcs.iter().enumerate() {
        by_triangle[*i].push(k);
    }
    // The triangles around each vertex, and a check that the cones chosen around a vertex
    // leave a cycle there that can be closed.
    let mut incident: Vec<(u32, usize)> = part
        .iter()
        .enumerate()
        .flat_map(|(i, t)| t.iter().map(move |&v| (v, i)))
        .collect();
    incident.sort_unstable();
    let star = |v: u32| {
        let from = incident.partition_point(|e| e.0 < v);
        let to = incident.partition_point(|e| e.0 <= v);
        incident[from..to].iter().map(|e| e.1)
    };
    let closes = |pick: &[usize], i: usize| {
        part[i].iter().all(|&v| {
            if star(v).any(|t| pick[t] == usize::MAX) {
                return true;
            }
            let members: Vec<usize> = star(v).collect();
            let sub: Vec<[u32; 3]> = members.iter().map(|&t| part[t]).collect();
            let sub_tris: Vec<[[f64; 3]; 3]> = members.iter().map(|&t| tris[t]).collect();
            let sub_degenerate: Vec<bool> = members.iter().map(|&t| degenerate[t]).collect();
            let sub_group: Vec<u32> = members.iter().map(|&t| domain[t][pick[t]]).collect();
            tile(
                &sub,
                &sub_tris,
                &sub_degenerate,
                points,
                &sub_group,
                position,
                Some(v),
            )
            .is_ok()
        })
    };
    let mut pick = vec![usize::MAX; n];
    let mut budget = 5_000usize;
    if !search(
        &mut pick,
        &alive,
        &arcs,
        &by_triangle,
        &domain,
        &mut budget,
        &closes,
    ) {
        return None;
    }
    let group: Vec<u32> = (0..n).map(|i| domain[i][pick[i]]).collect();
    Some(group)
}

/// Tetrahedra `(v, x, y, z)` over the triangles of a cycle of points around `v` cut off ear by
/// ear: each ear positive with no other point of the cycle inside its cone from `v`.
fn ears(v: u32, cycle: &[u32], positive: &dyn Fn([u32; 4]) -> bool) -> Option<Vec<[u32; 4]>> {
    let mut left = cycle.to_vec();
    let mut out = Vec::with_capacity(cycle.len());
    while left.len() > 3 {
        let m = left.len();
        let ear = (0..m).find(|&k| {
            let (x, y, z) = (left[(k + m - 1) % m], left[k], left[(k + 1) % m]);
            positive([v, x, y, z])
                && left.iter().all(|&q| {
                    [x, y, z].contains(&q)
                        || !(positive([v, x, y, q])
                            && positive([v, y, z, q])
                            && positive([v, z, x, q]))
                })
        })?;
        let (x, y, z) = (left[(ear + m - 1) % m], left[ear], left[(ear + 1) % m]);
        out.push([v, x, y, z]);
        left.remove(ear);
    }
    let last = [v, left[0], left[1], left[2]];
    positive(last).then(|| {
        out.push(last);
        out
    })
}

/// Backtracking over the triangles' choices, the one with the fewest left first.
fn search(
    pick: &mut [usize],
    alive: &[Vec<bool>],
    arcs: &[(usize, usize, Vec<bool>)],
    by_triangle: &[Vec<usize>],
    domain: &[Vec<u32>],
    budget: &mut usize,
    closes: &dyn Fn(&[usize], usize) -> bool,
) -> bool {
    let fits = |pick: &[usize], i: usize, x: usize| {
        alive[i][x]
            && by_triangle[i].iter().all(|&k| {
                let (_, j, ok) = &arcs[k];
                pick[*j] == usize::MAX || ok[x * domain[*j].len() + pick[*j]]
            })
    };
    let Some((i, _)) = (0..pick.len())
        .filter(|&i| pick[i] == usize::MAX)
        .map(|i| {
            (
                i,
                (0..domain[i].len()).filter(|&x| fits(pick, i, x)).count(),
            )
        })
        .min_by_key(|&(i, c)| (c, i))
    else {
        return true;
    };
    for x in 0..domain[i].len() {
        if !fits(pick, i, x) {
            continue;
        }
        if *budget == 0 {
            return false;
        }
        *budget -= 1;
        pick[i] = x;
        if closes(pick, i) && search(pick, alive, arcs, by_triangle, domain, budget, closes) {
            return true;
        }
        pick[i] = usize::MAX;
    }
    false
}

/// A point inside the fold at edge `a → b` (of triangle `ti`; `tj` runs `b → a`) between the
/// cone points `si` (over `ti`) and `sj` (over `tj`), making `(b, a, si, m)` and `(b, a, m, sj)`
/// positive: from the edge's midpoint along the sum of the two triangles' inward normals, at a
/// few depths, rounded to the stored precision.
pub(super) fn fold_point(
    pa: [f64; 3],
    pb: [f64; 3],
    ti: &[[f64; 3]; 3],
    tj: &[[f64; 3]; 3],
    si: [f64; 3],
    sj: [f64; 3],
    bounds: ([f64; 3], [f64; 3]),
) -> Option<[f64; 3]> {
    let mid: [f64; 3] = std::array::from_fn(|d| 0.5 * (pa[d] + pb[d]));
    let inward = |t: &[[f64; 3]; 3]| {
        let n = check::cross(check::sub(t[1], t[0]), check::sub(t[2], t[0]));
        let len = check::dot(n, n).sqrt().max(f64::MIN_POSITIVE);
        n.map(|x| -x / len)
    };
    let (ni, nj) = (inward(ti), inward(tj));
    let dir: [f64; 3] = std::array::from_fn(|d| ni[d] + nj[d]);
    let len = check::dot(dir, dir).sqrt();
    if len == 0.0 {
        return None;
    }
    let reach = [si, sj]
        .iter()
        .map(|s| check::dot(check::sub(*s, mid), check::sub(*s, mid)).sqrt())
        .fold(f64::INFINITY, f64::min);
    let inside = |m: [f64; 3]| (0..3).all(|d| bounds.0[d] < m[d] && m[d] < bounds.1[d]);
    [0.25, 0.1, 0.5, 0.05, 0.02].iter().find_map(|&f| {
        let m: [f64; 3] =
            std::array::from_fn(|d| f64::from((mid[d] + f * reach * dir[d] / len) as f32));
        (inside(m) && check::positive(pb, pa, si, m) && check::positive(pb, pa, m, sj)).then_some(m)
    })
}

/// The box around a part (its cell, where the part has a corner of it on each side).
fn bounds(tris: &[[[f64; 3]; 3]]) -> ([f64; 3], [f64; 3]) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in tris.iter().flatten() {
        for d in 0..3 {
            lo[d] = lo[d].min(p[d]);
            hi[d] = hi[d].max(p[d]);
        }
    }
    (lo, hi)
}

/// Whether a point sees a part's triangle from inside (or, for a triangle of no area, does not
/// see it from outside).
pub(super) fn sees(t: &[[f64; 3]; 3], degenerate: bool, s: [f64; 3]) -> bool {
    check::positive(t[0], t[2], t[1], s) || (degenerate && !check::positive(t[0], t[1], t[2], s))
}

/// Whether `s` sees every triangle of a part from inside ([`sees`]).
pub(super) fn sees_all(tris: &[[[f64; 3]; 3]], degenerate: &[bool], s: [f64; 3]) -> bool {
    tris.iter().zip(degenerate).all(|(t, &d)| sees(t, d, s))
}

/// The faces of the tetrahedra, together with the part's triangles reversed, that do not cancel
/// in pairs of opposite orientation: empty exactly when the tetrahedra's boundary is the part.
pub(super) fn open_faces(tets: &[[u32; 4]], part: &[[u32; 3]]) -> Vec<[u32; 3]> {
    let canonical = |f: [u32; 3]| {
        let r = (0..3).min_by_key(|&r| f[r]).expect("three");
        let f = [f[r], f[(r + 1) % 3], f[(r + 2) % 3]];
        let mut key = f;
        key.sort_unstable();
        (key, f)
    };
    let mut faces: Vec<([u32; 3], [u32; 3])> = tets
        .iter()
        .flat_map(|&[a, b, c, d]| [[a, c, b], [a, b, d], [a, d, c], [b, c, d]].map(canonical))
        .chain(part.iter().map(|t| canonical([t[0], t[2], t[1]])))
        .collect();
    faces.sort_unstable();
    let mut left = Vec::new();
    let mut i = 0;
    while i < faces.len() {
        let mut j = i + 1;
        while j < faces.len() && faces[j].0 == faces[i].0 {
            j += 1;
        }
        let first = faces[i].1;
        let plus = faces[i..j].iter().filter(|f| f.1 == first).count();
        let minus = (j - i) - plus;
        let other = faces[i..j].iter().find(|f| f.1 != first).map(|f| f.1);
        for _ in minus..plus {
            left.push(first);
        }
        if let Some(o) = other {
            for _ in plus..minus {
                left.push(o);
            }
        }
        i = j;
    }
    left
}
