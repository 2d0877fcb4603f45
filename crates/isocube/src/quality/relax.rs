//! Relaxation: vertices slide along the isosurface to lift the angles no per-cell change can fix.
//!
//! Each sweep of the first half first splits edges whose midpoint lies farther than
//! [`SPLIT_ABOVE`] grid spacings from the level set (at the midpoint projected onto it). Every
//! sweep then flips edges where the other
//! diagonal of two triangles is better (same
//! measure as below, no folds), projects every vertex onto the level set (unless that would turn
//! a triangle over), then visits the vertices in index order (so the result is deterministic).
//! A vertex moves
//! toward the area-weighted centroid of its triangles, tangentially (the component along the
//! field's gradient removed), and is then projected back onto the level set by Newton steps on the
//! field. The move is kept only if none of its triangles turns over and the worst quality among
//! them does not drop, where a triangle's quality is the smaller of its smallest angle and
//! `(180° − largest angle) · 3/7` (so 30° and 110° score the same); otherwise half the move is
//! tried, then none. Vertices on open edges stay put, so boundaries do not drift.

use crate::field::GridView;
use crate::mesh::{cross, dot, sub, Mesh};

/// A scalar field that can be evaluated with its gradient anywhere near the surface.
pub trait Field {
    /// The value and gradient at `p`, or `None` where the field is not defined.
    fn value_and_gradient(&self, p: [f64; 3]) -> Option<(f64, [f64; 3])>;
}

/// The trilinear interpolant of a grid (the field Marching Cubes approximates).
pub struct Trilinear<'a>(pub GridView<'a>);

impl Field for Trilinear<'_> {
    fn value_and_gradient(&self, p: [f64; 3]) -> Option<(f64, [f64; 3])> {
        let g = self.0;
        let dims = g.dims();
        let h = g.spacing();
        let o = g.origin();
        let mut cell = [0usize; 3];
        let mut f = [0.0f64; 3];
        let mut h = h;
        for a in 0..3 {
            if let (2, Some(heights)) = (a, g.heights()) {
                // Uneven planes: the cell holding p, and the fraction of its height.
                let z = p[2] - o[2];
                if !z.is_finite() {
                    return None;
                }
                let c = heights.partition_point(|&t| t <= z).clamp(1, dims[2] - 1) - 1;
                h[2] = heights[c + 1] - heights[c];
                cell[2] = c;
                f[2] = (z - heights[c]) / h[2];
                continue;
            }
            let u = (p[a] - o[a]) / h[a];
            if !u.is_finite() {
                return None;
            }
            let c = (u.floor().max(0.0) as usize).min(dims[a] - 2);
            cell[a] = c;
            f[a] = u - c as f64;
        }
        let v = |dx: usize, dy: usize, dz: usize| {
            f64::from(g.value(cell[0] + dx, cell[1] + dy, cell[2] + dz))
        };
        let c: [f64; 8] = [
            v(0, 0, 0),
            v(1, 0, 0),
            v(0, 1, 0),
            v(1, 1, 0),
            v(0, 0, 1),
            v(1, 0, 1),
            v(0, 1, 1),
            v(1, 1, 1),
        ];
        if c.iter().any(|x| !x.is_finite()) {
            return None;
        }
        let [x, y, z] = f;
        let lerp = |a: f64, b: f64, t: f64| a + t * (b - a);
        let (c00, c10, c01, c11) = (
            lerp(c[0], c[1], x),
            lerp(c[2], c[3], x),
            lerp(c[4], c[5], x),
            lerp(c[6], c[7], x),
        );
        let (c0, c1) = (lerp(c00, c10, y), lerp(c01, c11, y));
        let value = lerp(c0, c1, z);
        let dx = {
            let a = lerp(c[1] - c[0], c[3] - c[2], y);
            let b = lerp(c[5] - c[4], c[7] - c[6], y);
            lerp(a, b, z)
        };
        let dy = {
            let a = lerp(c[2] - c[0], c[3] - c[1], x);
            let b = lerp(c[6] - c[4], c[7] - c[5], x);
            lerp(a, b, z)
        };
        let dz = c1 - c0;
        Some((value, [dx / h[0], dy / h[1], dz / h[2]]))
    }
}

/// A field known only by its values (an implicit function); the gradient is taken by central
/// differences with step `.1`.
pub struct Implicit<F: Fn([f64; 3]) -> f64>(pub F, pub f64);

impl<F: Fn([f64; 3]) -> f64> Field for Implicit<F> {
    fn value_and_gradient(&self, p: [f64; 3]) -> Option<(f64, [f64; 3])> {
        let v = (self.0)(p);
        let h = self.1;
        let g: [f64; 3] = std::array::from_fn(|a| {
            let (mut lo, mut hi) = (p, p);
            lo[a] -= h;
            hi[a] += h;
            ((self.0)(hi) - (self.0)(lo)) / (2.0 * h)
        });
        (v.is_finite() && g.iter().all(|c| c.is_finite())).then_some((v, g))
    }
}

/// Any closure `p → (value, gradient)` is a field.
impl<F: Fn([f64; 3]) -> Option<(f64, [f64; 3])>> Field for F {
    fn value_and_gradient(&self, p: [f64; 3]) -> Option<(f64, [f64; 3])> {
        self(p)
    }
}

/// Moves the mesh's vertices in `sweeps` relaxation sweeps (see the module documentation),
/// keeping them on the `level` set of `field`; `step_limit` bounds a single projection step (use
/// the grid spacing). Normals, if the mesh has them, are reset to the unit gradient (flipped when
/// the winding faces against it). Returns how many moves were kept.
pub fn relax(
    mesh: &mut Mesh,
    field: &dyn Field,
    level: f64,
    sweeps: usize,
    step_limit: f64,
) -> usize {
    let nv = mesh.positions.len();
    if nv == 0 || sweeps == 0 {
        return 0;
    }
    // Vertices on open or non-manifold edges are fixed.
    let edges = sorted_edges(mesh);
    let mut fixed = vec![false; nv];
    for group in edges.chunk_by(|a, b| (a.0, a.1) == (b.0, b.1)) {
        if group.len() != 2 {
            fixed[group[0].0 as usize] = true;
            fixed[group[0].1 as usize] = true;
        }
    }
    let mut kept = 0;
    let (mut start, mut incident) = incidence(mesh);
    let budget = mesh.triangles.len() + mesh.triangles.len() * SPLIT_BUDGET_PERCENT / 100;
    for sweep in 0..sweeps {
        // Vertices off the level set (interior points of cells, say) go onto it first.
        for v in 0..mesh.positions.len() {
            let tris = &incident[start[v] as usize..start[v + 1] as usize];
            if !fixed[v] && !tris.is_empty() {
                if let Some(p) = project_vertex(mesh, v, tris, field, level, step_limit) {
                    mesh.positions[v] = p;
                }
            }
        }
        // Splits in the first half only, so that the second half relaxes around the new
        // vertices.
        let split = if 2 * sweep < sweeps && mesh.triangles.len() < budget {
            split_far_edges(mesh, &mut fixed, field, level, step_limit, budget)
        } else {
            0
        };
        if flip_edges(mesh, field, level, step_limit) + split > 0 {
            (start, incident) = incidence(mesh);
        }
        for v in 0..mesh.positions.len() {
            if fixed[v] {
                continue;
            }
            let tris = &incident[start[v] as usize..start[v + 1] as usize];
            if tris.is_empty() {
                continue;
            }
            if let Some(p) = try_move(mesh, v, tris, field, level, step_limit) {
                mesh.positions[v] = p;
                kept += 1;
            }
        }
    }
    if !mesh.normals.is_empty() {
        reset_normals(mesh, field, &incident, &start);
    }
    kept
}

/// Every triangle edge as `(low vertex, high vertex, triangle)`, sorted: the uses of one edge are
/// consecutive.
fn sorted_edges(mesh: &Mesh) -> Vec<(u32, u32, u32)> {
    let mut half: Vec<(u32, u32, u32)> = Vec::with_capacity(3 * mesh.triangles.len());
    for (ti, t) in mesh.triangles.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            half.push((a.min(b), a.max(b), ti as u32));
        }
    }
    half.sort_unstable();
    half
}

/// First-order distance `|f − level| / |∇f|` of `x` from the level set, in units of `unit`
/// (infinite where the field is undefined or flat).
fn distance_off(field: &dyn Field, level: f64, unit: f64, x: [f64; 3]) -> f64 {
    field.value_and_gradient(x).map_or(f64::INFINITY, |(f, g)| {
        let gl = dot(g, g).sqrt();
        if gl == 0.0 {
            f64::INFINITY
        } else {
            (f - level).abs() / gl / unit
        }
    })
}

/// Incident triangles per vertex, as CSR arrays.
fn incidence(mesh: &Mesh) -> (Vec<u32>, Vec<u32>) {
    let nv = mesh.positions.len();
    let mut start = vec![0u32; nv + 1];
    for t in &mesh.triangles {
        for &v in t {
            start[v as usize + 1] += 1;
        }
    }
    for i in 0..nv {
        start[i + 1] += start[i];
    }
    let mut fill = start.clone();
    let mut incident = vec![0u32; start[nv] as usize];
    for (ti, t) in mesh.triangles.iter().enumerate() {
        for &v in t {
            incident[fill[v as usize] as usize] = ti as u32;
            fill[v as usize] += 1;
        }
    }
    (start, incident)
}

/// Edges whose midpoint lies farther than this many `step_limit`s (grid spacings) from the level
/// set are split at the midpoint projected onto it.
pub const SPLIT_ABOVE: f64 = 0.04;
/// Edges shorter than this many `step_limit`s are not split: at a crease of the field no chord
/// comes close, and splitting would only multiply needles.
pub const SPLIT_MIN_LENGTH: f64 = 0.5;
/// Splits add at most this share of the triangles a relaxation starts with.
pub const SPLIT_BUDGET_PERCENT: usize = 50;

/// One pass of edge splits: an edge at least [`SPLIT_MIN_LENGTH`] long whose midpoint is farther
/// than [`SPLIT_ABOVE`] from the level set gets a new vertex at the midpoint projected onto it,
/// and its one or two triangles are halved, within the triangle budget. Triangles touched in this pass are left for the next. Returns the number of splits.
fn split_far_edges(
    mesh: &mut Mesh,
    fixed: &mut Vec<bool>,
    field: &dyn Field,
    level: f64,
    step_limit: f64,
    budget: usize,
) -> usize {
    let half = sorted_edges(mesh);
    let mut touched = vec![false; mesh.triangles.len()];
    let mut splits = 0;
    for group in half.chunk_by(|x, y| (x.0, x.1) == (y.0, y.1)) {
        if group.len() > 2 || group.iter().any(|h| touched[h.2 as usize]) {
            continue;
        }
        if mesh.triangles.len() + group.len() > budget {
            break;
        }
        let (a, b) = (group[0].0, group[0].1);
        let (pa, pb) = (pos(mesh, a), pos(mesh, b));
        let e = sub(pa, pb);
        if dot(e, e).sqrt() < SPLIT_MIN_LENGTH * step_limit {
            continue;
        }
        let mid: [f64; 3] = std::array::from_fn(|d| (pa[d] + pb[d]) / 2.0);
        let Some((f, g)) = field.value_and_gradient(mid) else {
            continue;
        };
        let gl = dot(g, g).sqrt();
        if gl == 0.0 || (f - level).abs() / gl <= SPLIT_ABOVE * step_limit {
            continue;
        }
        let Some(m) = project(mid, field, level, step_limit) else {
            continue;
        };
        let m32 = m.map(|c| c as f32);
        let m = m32.map(f64::from);
        // The new triangles must face the way the old ones did.
        let mut new_triangles = Vec::with_capacity(4);
        // A mesh at the end of u32 numbering is not split further.
        let Ok(id) = u32::try_from(mesh.positions.len()) else {
            break;
        };
        for h in group {
            let t = mesh.triangles[h.2 as usize];
            let k = (0..3)
                .find(|&k| {
                    let (x, y) = (t[k], t[(k + 1) % 3]);
                    (x.min(y), x.max(y)) == (a, b)
                })
                .expect("the edge is in its triangle");
            let (x, y, z) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
            new_triangles.push((h.2 as usize, [x, id, z], [id, y, z]));
        }
        let at = |v: u32| if v == id { m } else { pos(mesh, v) };
        let ok = new_triangles.iter().all(|(ti, t1, t2)| {
            let old = normal(mesh.triangles[*ti].map(|v| pos(mesh, v)));
            dot(normal(t1.map(at)), old) > 0.0 && dot(normal(t2.map(at)), old) > 0.0
        });
        if !ok {
            continue;
        }
        mesh.positions.push(m32);
        if !mesh.normals.is_empty() {
            let n = g.map(|c| (c / gl) as f32);
            mesh.normals.push(n);
        }
        fixed.push(group.len() == 1);
        for (ti, t1, t2) in new_triangles {
            mesh.triangles[ti] = t1;
            mesh.triangles.push(t2);
            touched[ti] = true;
            touched.push(true);
        }
        splits += 1;
    }
    splits
}

/// One pass of edge flips: an edge shared by two triangles is replaced by the other diagonal of
/// their quad when that raises the pair's worst quality, the new edge is not in the mesh yet, and
/// both new triangles face the way the pair did (no fold, at most 30° between them), and the new
/// edge's midpoint is within [`SPLIT_ABOVE`] of the level set (or closer than the old one's). The
/// topology is unchanged; triangles touched in this pass are left for the next.
fn flip_edges(mesh: &mut Mesh, field: &dyn Field, level: f64, step_limit: f64) -> usize {
    let off = |x: [f64; 3]| distance_off(field, level, step_limit, x);
    let half = sorted_edges(mesh);
    let mut existing: std::collections::HashSet<(u32, u32)> =
        half.iter().map(|h| (h.0, h.1)).collect();
    let mut touched = vec![false; mesh.triangles.len()];
    let mut flips = 0;
    let cos30 = 30f64.to_radians().cos();
    for group in half.chunk_by(|x, y| (x.0, x.1) == (y.0, y.1)) {
        if group.len() != 2 {
            continue;
        }
        let (t1, t2) = (group[0].2 as usize, group[1].2 as usize);
        if touched[t1] || touched[t2] {
            continue;
        }
        let (ta, tb) = (mesh.triangles[t1], mesh.triangles[t2]);
        // Orient: ta has a→b, tb has b→a.
        let Some(k) = (0..3).find(|&k| {
            let (a, b) = (ta[k], ta[(k + 1) % 3]);
            (0..3).any(|m| tb[m] == b && tb[(m + 1) % 3] == a)
        }) else {
            continue;
        };
        let (a, b, c) = (ta[k], ta[(k + 1) % 3], ta[(k + 2) % 3]);
        let Some(&d) = tb.iter().find(|&&x| x != a && x != b) else {
            continue;
        };
        if c == d || existing.contains(&(c.min(d), c.max(d))) {
            continue;
        }
        let p = |v: u32| pos(mesh, v);
        let old = score([p(a), p(b), p(c)]).min(score([p(b), p(a), p(d)]));
        let (n1, n2) = ([c, a, d], [d, b, c]);
        let new = score(n1.map(p)).min(score(n2.map(p)));
        if new <= old + 1e-9 {
            continue;
        }
        let on = normal([p(a), p(b), p(c)]);
        let on2 = normal([p(b), p(a), p(d)]);
        let sum: [f64; 3] = std::array::from_fn(|i| on[i] + on2[i]);
        let (q1, q2) = (normal(n1.map(p)), normal(n2.map(p)));
        let unit_dot = |u: [f64; 3], w: [f64; 3]| dot(u, w) / (dot(u, u) * dot(w, w)).sqrt();
        if dot(q1, sum) <= 0.0 || dot(q2, sum) <= 0.0 || unit_dot(q1, q2) < cos30 {
            continue;
        }
        // The new edge must stay as close to the level set as splitting keeps edges.
        let mid = |u: u32, w: u32| -> [f64; 3] {
            let (pu, pw) = (p(u), p(w));
            std::array::from_fn(|k| (pu[k] + pw[k]) / 2.0)
        };
        let new_off = off(mid(c, d));
        if new_off > SPLIT_ABOVE && new_off > off(mid(a, b)) {
            continue;
        }
        mesh.triangles[t1] = n1;
        mesh.triangles[t2] = n2;
        touched[t1] = true;
        touched[t2] = true;
        existing.remove(&(a.min(b), a.max(b)));
        existing.insert((c.min(d), c.max(d)));
        flips += 1;
    }
    flips
}

fn pos(mesh: &Mesh, v: u32) -> [f64; 3] {
    mesh.positions[v as usize].map(f64::from)
}

/// Smallest angle and `(180° − largest) · 3/7`, the smaller; −1 if degenerate.
fn score(p: [[f64; 3]; 3]) -> f64 {
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    for k in 0..3 {
        let u = sub(p[(k + 1) % 3], p[k]);
        let w = sub(p[(k + 2) % 3], p[k]);
        let c = cross(u, w);
        if dot(c, c) == 0.0 {
            return -1.0;
        }
        let a = dot(c, c).sqrt().atan2(dot(u, w)).to_degrees();
        lo = lo.min(a);
        hi = hi.max(a);
    }
    lo.min((180.0 - hi) * 3.0 / 7.0)
}

fn normal(p: [[f64; 3]; 3]) -> [f64; 3] {
    cross(sub(p[1], p[0]), sub(p[2], p[0]))
}

fn project(x: [f64; 3], field: &dyn Field, level: f64, step_limit: f64) -> Option<[f64; 3]> {
    let mut x = x;
    for _ in 0..4 {
        let (f, g) = field.value_and_gradient(x)?;
        let gg = dot(g, g);
        if gg == 0.0 {
            return None;
        }
        let s = (f - level) / gg;
        let step = g.map(|c| -s * c);
        let len = dot(step, step).sqrt();
        if len > step_limit {
            return None;
        }
        x = std::array::from_fn(|d| x[d] + step[d]);
        if len < 1e-9 * step_limit {
            break;
        }
    }
    Some(x)
}

/// Triangle `t`'s corners with vertex `v` moved to `at`.
fn with_vertex_at(mesh: &Mesh, t: u32, v: usize, at: [f64; 3]) -> [[f64; 3]; 3] {
    mesh.triangles[t as usize].map(|w| if w as usize == v { at } else { pos(mesh, w) })
}

/// The vertex projected onto the level set, unless that turns a triangle over.
fn project_vertex(
    mesh: &Mesh,
    v: usize,
    tris: &[u32],
    field: &dyn Field,
    level: f64,
    step_limit: f64,
) -> Option<[f32; 3]> {
    let x = pos(mesh, v as u32);
    let y32 = project(x, field, level, step_limit)?.map(|c| c as f32);
    let y = y32.map(f64::from);
    let corners = |t: u32, at: [f64; 3]| with_vertex_at(mesh, t, v, at);
    tris.iter()
        .all(|&t| dot(normal(corners(t, x)), normal(corners(t, y))) > 0.0)
        .then_some(y32)
}

fn try_move(
    mesh: &Mesh,
    v: usize,
    tris: &[u32],
    field: &dyn Field,
    level: f64,
    step_limit: f64,
) -> Option<[f32; 3]> {
    let x = pos(mesh, v as u32);
    let corners = |t: u32, at: [f64; 3]| with_vertex_at(mesh, t, v, at);
    let (mut area, mut target) = (0.0, [0.0; 3]);
    let mut old_score = f64::INFINITY;
    for &t in tris {
        let p = corners(t, x);
        let n = normal(p);
        let a = dot(n, n).sqrt();
        area += a;
        for d in 0..3 {
            target[d] += a * (p[0][d] + p[1][d] + p[2][d]) / 3.0;
        }
        old_score = old_score.min(score(p));
    }
    if area == 0.0 {
        return None;
    }
    let target = target.map(|c| c / area);
    let (_, g) = field.value_and_gradient(x)?;
    let gl = dot(g, g).sqrt();
    if gl == 0.0 {
        return None;
    }
    let n = g.map(|c| c / gl);
    let d = sub(target, x);
    let dn = dot(d, n);
    let tangential: [f64; 3] = std::array::from_fn(|k| d[k] - dn * n[k]);
    // How far the incident triangles' centroids and the midpoints of the vertex's edges lie from
    // the level set (in grid spacings), with the vertex at `at`.
    let off_surface = |at: [f64; 3]| -> f64 {
        let off = |q: [f64; 3]| distance_off(field, level, step_limit, q);
        let mut worst: f64 = 0.0;
        for &t in tris {
            let p = corners(t, at);
            worst = worst.max(off(std::array::from_fn(|d| {
                (p[0][d] + p[1][d] + p[2][d]) / 3.0
            })));
            for q in p {
                if q != at {
                    worst = worst.max(off(std::array::from_fn(|d| (q[d] + at[d]) / 2.0)));
                }
            }
        }
        worst
    };
    let allowed_off = off_surface(x).max(SPLIT_ABOVE);
    // The worst incident quality at a candidate position, if no triangle turns over and the
    // triangles stay as close to the level set as before (or within the split threshold).
    let evaluate = |moved: [f64; 3]| -> Option<(f64, [f32; 3])> {
        let y = project(moved, field, level, step_limit)?;
        let y32 = y.map(|c| c as f32);
        let y = y32.map(f64::from);
        let ok = tris
            .iter()
            .all(|&t| dot(normal(corners(t, x)), normal(corners(t, y))) > 0.0);
        if !ok || off_surface(y) > allowed_off {
            return None;
        }
        let s = tris
            .iter()
            .map(|&t| score(corners(t, y)))
            .fold(f64::INFINITY, f64::min);
        Some((s, y32))
    };
    for fraction in [1.0, 0.5] {
        let moved: [f64; 3] = std::array::from_fn(|k| x[k] + fraction * tangential[k]);
        if let Some((s, y)) = evaluate(moved) {
            if s >= old_score {
                return Some(y);
            }
        }
    }
    // Where the centroid does not help a poor vertex, search its tangent plane directly for the
    // position that best raises its worst triangle.
    if old_score >= SEARCH_BELOW {
        return None;
    }
    let seed = if n[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let u = {
        let c = cross(n, seed);
        let l = dot(c, c).sqrt();
        c.map(|w| w / l)
    };
    let w = cross(n, u);
    let mean_edge = tris
        .iter()
        .map(|&t| {
            let p = corners(t, x);
            let e = sub(p[1], p[0]);
            dot(e, e).sqrt()
        })
        .sum::<f64>()
        / tris.len() as f64;
    let (mut best, mut at, mut found) = (old_score, x, None);
    let mut step = 0.2 * mean_edge;
    for _ in 0..12 {
        let mut improved = false;
        for (a, b) in [(1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0)] {
            let moved: [f64; 3] = std::array::from_fn(|k| at[k] + step * (a * u[k] + b * w[k]));
            if let Some((s, y)) = evaluate(moved) {
                if s > best + 1e-9 {
                    (best, at, found) = (s, y.map(f64::from), Some(y));
                    improved = true;
                }
            }
        }
        if !improved {
            step *= 0.5;
        }
    }
    found
}

/// Vertices whose worst triangle scores below this (degrees) get the direct search.
const SEARCH_BELOW: f64 = 35.0;

fn reset_normals(mesh: &mut Mesh, field: &dyn Field, incident: &[u32], start: &[u32]) {
    for v in 0..mesh.positions.len() {
        let x = pos(mesh, v as u32);
        let Some((_, g)) = field.value_and_gradient(x) else {
            continue;
        };
        let gl = dot(g, g).sqrt();
        if gl == 0.0 {
            continue;
        }
        // Orientation from the winding around the vertex.
        let mut wn = [0.0; 3];
        for &t in &incident[start[v] as usize..start[v + 1] as usize] {
            let p = mesh.triangles[t as usize].map(|w| pos(mesh, w));
            let n = normal(p);
            for d in 0..3 {
                wn[d] += n[d];
            }
        }
        let s = if dot(wn, g) < 0.0 { -1.0 } else { 1.0 };
        mesh.normals[v] = g.map(|c| (s * c / gl) as f32);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::extract::{extract, ExtractOptions};
    use crate::field::{Grid, Sample};
    use crate::quality::quality_report;

    #[test]
    fn trilinear_matches_a_linear_field_and_its_gradient() {
        let f = |p: [f64; 3]| 0.5 * p[0] - 2.0 * p[1] + 0.25 * p[2];
        let grid = Grid::from_fn([5, 6, 7], [0.5, 0.25, 0.2], [-1.0, 0.0, 1.0], f);
        let t = Trilinear(grid.view());
        for p in [[0.1, 0.3, 1.3], [-0.9, 1.2, 2.1], [0.7, 0.01, 1.05]] {
            let (v, g) = t.value_and_gradient(p).unwrap();
            assert!((v - f(p)).abs() < 1e-5, "{v} {}", f(p));
            assert!(
                (g[0] - 0.5).abs() < 1e-5
                    && (g[1] + 2.0).abs() < 1e-5
                    && (g[2] - 0.25).abs() < 1e-5
            );
        }
    }

    #[test]
    fn relaxing_a_sphere_raises_its_smallest_angle_and_keeps_it_on_the_surface() {
        let grid = Sample::Sphere.grid(24);
        let (mut mesh, _) = extract(&grid, &ExtractOptions::default()).unwrap();
        let before = quality_report(&mesh);
        let report = mesh.report();
        let kept = relax(
            &mut mesh,
            &Trilinear(grid.view()),
            0.0,
            5,
            grid.spacing()[0],
        );
        assert!(kept > 0);
        let after = quality_report(&mesh);
        assert!(
            after.min_angle.min >= before.min_angle.min,
            "{before:?} {after:?}"
        );
        assert!(after.below[1] < before.below[1]);
        let r = mesh.report();
        assert_eq!(
            (r.watertight, r.oriented, r.euler),
            (report.watertight, report.oriented, report.euler)
        );
        let t = Trilinear(grid.view());
        for p in &mesh.positions {
            let (v, _) = t.value_and_gradient(p.map(f64::from)).unwrap();
            assert!(v.abs() < 1e-4, "{v}");
        }
    }
}
