//! Triangulating one cell polygon from its actual corner positions.
//!
//! A polygon is a closed loop of corners in order (its normal, by the right-hand rule, points
//! toward increasing values). `allowed(i, j)` says whether a diagonal between corners `i` and `j`
//! may be drawn; the extractor forbids diagonals that a neighbouring cell could draw too, which is
//! what keeps the mesh watertight and manifold. An interior vertex is always allowed: it belongs to
//! the cell alone. Triangles index the corners `0..n`, and `n` stands for the interior vertex.

use crate::mesh::{cross, dot, sub};

/// How cell polygons are split into triangles.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Strategy {
    /// The table's triangulation, fixed per configuration (classic Marching Cubes).
    #[default]
    Fan,
    /// The local-change paper's method: small-angle corners cut off, an interior vertex pulled
    /// toward short sides for pentagons and larger (and long quads) unless diagonals alone do better,
    /// otherwise the largest angle split.
    Local,
    /// The triangulation that maximises the smallest angle: exact over all triangulations by
    /// diagonals, compared with the best triangulation around one interior vertex (exact over
    /// which corners it joins; its position found by a pattern search).
    Optimal,
}

impl Strategy {
    /// The name used on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Strategy::Fan => "fan",
            Strategy::Local => "local",
            Strategy::Optimal => "optimal",
        }
    }
}

impl std::str::FromStr for Strategy {
    type Err = crate::ParseError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "fan" => Ok(Strategy::Fan),
            "local" => Ok(Strategy::Local),
            "optimal" => Ok(Strategy::Optimal),
            _ => Err(crate::ParseError::new(
                "triangulation",
                s,
                format!("unknown triangulation '{s}': expected fan, local or optimal"),
            )),
        }
    }
}

/// A polygon's triangulation: triangles over corner indices (`n` is the interior vertex) and the
/// interior vertex's position if one is used.
#[derive(Clone, Debug, PartialEq)]
pub struct PolygonTriangles {
    /// Triangles, oriented like the polygon.
    pub triangles: Vec<[u8; 3]>,
    /// The interior vertex, if any.
    pub interior: Option<[f64; 3]>,
}

/// Parameters of [`Strategy::Local`].
pub const LOCAL_BAD_ANGLE_DEGREES: f64 = 30.0;
/// A quadrilateral whose longest side exceeds this many times its shortest gets an interior
/// vertex under [`Strategy::Local`].
pub const LOCAL_QUAD_RATIO: f64 = 2.0;

/// Triangulates a polygon by a strategy other than [`Strategy::Fan`]. Returns `None` when the
/// allowed diagonals admit no triangulation and no interior vertex is wanted (the caller keeps its
/// table triangulation then); every returned triangle has positive area.
pub fn triangulate(
    corners: &[[f64; 3]],
    allowed: &dyn Fn(usize, usize) -> bool,
    strategy: Strategy,
    bounds: ([f64; 3], [f64; 3]),
) -> Option<PolygonTriangles> {
    let n = corners.len();
    if !(3..=MAX_CORNERS).contains(&n) {
        return None;
    }
    triangulate_polygon(corners, &Chords::new(n, allowed), strategy, bounds).map(
        |(triangles, interior)| PolygonTriangles {
            triangles: triangles.as_slice().to_vec(),
            interior,
        },
    )
}

/// Polygons with more corners are left to the caller (cell loops have at most 12).
pub(crate) const MAX_CORNERS: usize = 16;

/// The triangles of one polygon, kept on the stack: at most two per corner (corners cut off,
/// then a star around an interior vertex).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Triangles {
    list: [[u8; 3]; 2 * MAX_CORNERS],
    len: usize,
}

impl Triangles {
    fn new() -> Triangles {
        Triangles {
            list: [[0; 3]; 2 * MAX_CORNERS],
            len: 0,
        }
    }

    #[inline]
    fn push(&mut self, t: [u8; 3]) {
        self.list[self.len] = t;
        self.len += 1;
    }

    /// The triangles, over corner indices (`n` the interior vertex).
    pub(crate) fn as_slice(&self) -> &[[u8; 3]] {
        &self.list[..self.len]
    }
}

/// Which corners may be joined: the polygon's sides always, diagonals as the caller allows; one
/// bit per pair, both ways.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Chords {
    bits: [u16; MAX_CORNERS],
}

impl Chords {
    /// The chords of an `n`-gon (`n ≤ MAX_CORNERS`) whose diagonal `(i, j)`, `i < j`, may be drawn
    /// when `allowed(i, j)`.
    pub(crate) fn new(n: usize, allowed: impl Fn(usize, usize) -> bool) -> Chords {
        let mut bits = [0u16; MAX_CORNERS];
        for i in 0..n {
            for j in i + 1..n {
                if j == i + 1 || (i == 0 && j == n - 1) || allowed(i, j) {
                    bits[i] |= 1 << j;
                    bits[j] |= 1 << i;
                }
            }
        }
        Chords { bits }
    }

    #[inline]
    fn has(&self, i: usize, j: usize) -> bool {
        self.bits[i] >> j & 1 == 1
    }

    /// The chords of the sub-polygon through corners `rest` (in order): its own sides, and the
    /// chords between its corners.
    fn sub(&self, rest: &[u8]) -> Chords {
        let m = rest.len();
        Chords::new(m, |a, b| {
            self.has(usize::from(rest[a]), usize::from(rest[b]))
        })
    }
}

/// [`triangulate`] with the chords given and the triangles on the stack: `None` when nothing
/// is found, else the triangles and the interior vertex if one is used.
pub(crate) fn triangulate_polygon(
    corners: &[[f64; 3]],
    chords: &Chords,
    strategy: Strategy,
    bounds: ([f64; 3], [f64; 3]),
) -> Option<(Triangles, Option<[f64; 3]>)> {
    let n = corners.len();
    if !(3..=MAX_CORNERS).contains(&n) {
        return None;
    }
    if n == 3 {
        let mut t = Triangles::new();
        t.push([0, 1, 2]);
        return Some((t, None));
    }
    match strategy {
        Strategy::Fan => None,
        Strategy::Local => local(corners, chords, bounds),
        Strategy::Optimal => optimal(corners, chords, bounds),
    }
}

fn triangles_of(list: &[[u8; 3]]) -> Triangles {
    let mut t = Triangles::new();
    for &x in list {
        t.push(x);
    }
    t
}

/// Newell's normal of a polygon (not normalised).
fn polygon_normal(p: &[[f64; 3]]) -> [f64; 3] {
    let mut n = [0.0; 3];
    for i in 0..p.len() {
        let (a, b) = (p[i], p[next(i, p.len())]);
        n[0] += (a[1] - b[1]) * (a[2] + b[2]);
        n[1] += (a[2] - b[2]) * (a[0] + b[0]);
        n[2] += (a[0] - b[0]) * (a[1] + b[1]);
    }
    n
}

/// The smallest angle of a triangle in radians, or −1 when it is degenerate or faces against
/// `normal` (a fold).
#[cfg(test)]
fn quality(a: [f64; 3], b: [f64; 3], c: [f64; 3], normal: [f64; 3]) -> f64 {
    smallest_angle_cot(a, b, c, normal).map_or(-1.0, |cot| 1f64.atan2(cot))
}

/// A number that ranks triangles as their smallest angle does (minus its cotangent), or −∞
/// for a degenerate or folded triangle; dynamic programs compare these, and [`angle_of_rank`]
/// turns the winner back into an angle.
fn rank(a: [f64; 3], b: [f64; 3], c: [f64; 3], normal: [f64; 3]) -> f64 {
    smallest_angle_cot(a, b, c, normal).map_or(f64::NEG_INFINITY, |cot| -cot)
}

/// The angle (radians) a [`rank`] stands for; −1 for −∞, as [`quality`] says.
fn angle_of_rank(r: f64) -> f64 {
    if r == f64::NEG_INFINITY {
        -1.0
    } else {
        1f64.atan2(-r)
    }
}

/// The cotangent of a triangle's smallest angle (it decreases as the angle grows), or `None`
/// when the triangle is degenerate or faces against `normal`. Comparing cotangents ranks
/// triangles without an arctangent each.
fn smallest_angle_cot(a: [f64; 3], b: [f64; 3], c: [f64; 3], normal: [f64; 3]) -> Option<f64> {
    let n = cross(sub(b, a), sub(c, a));
    if dot(n, n) == 0.0 || dot(n, normal) <= 0.0 {
        return None;
    }
    // The smallest angle faces the shortest side (law of sines); |n| is twice the area at every
    // corner.
    let (ab, bc, ca) = (sub(b, a), sub(c, b), sub(a, c));
    let (lab, lbc, lca) = (dot(ab, ab), dot(bc, bc), dot(ca, ca));
    let cosine_side = if lab <= lbc && lab <= lca {
        // Opposite c: the angle at c between c→a and c→b.
        -dot(ca, bc)
    } else if lbc <= lca {
        // Opposite a.
        -dot(ab, ca)
    } else {
        // Opposite b.
        -dot(bc, ab)
    };
    Some(cosine_side / dot(n, n).sqrt())
}

/// The corner after `i` in a ring of `n` (a branch: `%` is a division in the hot loops).
#[inline]
fn next(i: usize, n: usize) -> usize {
    if i + 1 == n {
        0
    } else {
        i + 1
    }
}

/// The corner before `i` in a ring of `n`.
#[inline]
fn prev(i: usize, n: usize) -> usize {
    if i == 0 {
        n - 1
    } else {
        i - 1
    }
}

/// Whether a triangle has positive area and faces along `normal`: [`smallest_angle_cot`] is
/// `Some` exactly then.
#[inline]
fn valid(a: [f64; 3], b: [f64; 3], c: [f64; 3], normal: [f64; 3]) -> bool {
    let n = cross(sub(b, a), sub(c, a));
    dot(n, n) != 0.0 && dot(n, normal) > 0.0
}

/// Angle at corner `i` of the polygon, radians.
fn corner_angle(p: &[[f64; 3]], i: usize) -> f64 {
    let n = p.len();
    let u = sub(p[prev(i, n)], p[i]);
    let v = sub(p[next(i, n)], p[i]);
    let w = cross(u, v);
    dot(w, w).sqrt().atan2(dot(u, v))
}

fn length(a: [f64; 3], b: [f64; 3]) -> f64 {
    let d = sub(a, b);
    dot(d, d).sqrt()
}

/// Exact max–min-angle triangulation by diagonals (dynamic programming over sub-polygons):
/// the best [`rank`] and its triangles.
fn best_by_diagonals(
    p: &[[f64; 3]],
    chords: &Chords,
    normal: [f64; 3],
) -> Option<(f64, Triangles)> {
    // Tables sized to the polygon: most cell loops have 4 to 6 corners.
    match p.len() {
        0..=6 => best_by_diagonals_within::<6>(p, chords, normal),
        7..=10 => best_by_diagonals_within::<10>(p, chords, normal),
        _ => best_by_diagonals_within::<MAX_CORNERS>(p, chords, normal),
    }
}

/// [`best_by_diagonals`] for polygons of at most `N` corners.
fn best_by_diagonals_within<const N: usize>(
    p: &[[f64; 3]],
    chords: &Chords,
    normal: [f64; 3],
) -> Option<(f64, Triangles)> {
    let n = p.len();
    // best[i][j]: the best smallest angle triangulating corners i..=j (chord i–j closing it).
    let mut best = [[f64::NEG_INFINITY; N]; N];
    let mut split = [[0u8; N]; N];
    for i in 0..n - 1 {
        best[i][i + 1] = f64::INFINITY;
    }
    for len in 2..n {
        for i in 0..n - len {
            let j = i + len;
            if !chords.has(i, j) {
                continue;
            }
            for k in i + 1..j {
                if !chords.has(i, k) || !chords.has(k, j) {
                    continue;
                }
                let q = rank(p[i], p[k], p[j], normal)
                    .min(best[i][k])
                    .min(best[k][j]);
                if q > best[i][j] {
                    best[i][j] = q;
                    split[i][j] = k as u8;
                }
            }
        }
    }
    if best[0][n - 1] == f64::NEG_INFINITY {
        return None;
    }
    let mut out = Triangles::new();
    let mut stack = [(0usize, 0usize); 2 * MAX_CORNERS];
    stack[0] = (0, n - 1);
    let mut top = 1;
    while top > 0 {
        top -= 1;
        let (i, j) = stack[top];
        if j <= i + 1 {
            continue;
        }
        let k = usize::from(split[i][j]);
        out.push([i as u8, k as u8, j as u8]);
        stack[top] = (i, k);
        stack[top + 1] = (k, j);
        top += 2;
    }
    Some((best[0][n - 1], out))
}

/// The [`rank`] of the star joining every side of `p` to `x` (its worst triangle).
fn star_rank(p: &[[f64; 3]], x: [f64; 3], normal: [f64; 3]) -> f64 {
    let n = p.len();
    let mut worst = f64::INFINITY;
    for i in 0..n {
        worst = worst.min(rank(p[i], p[next(i, n)], x, normal));
        if worst == f64::NEG_INFINITY {
            break;
        }
    }
    worst
}

fn star_quality(p: &[[f64; 3]], x: [f64; 3], normal: [f64; 3]) -> f64 {
    angle_of_rank(star_rank(p, x, normal))
}

/// The cotangent a star's smallest angle must stay below to beat `bar` (radians): angles in
/// (0, π/2] rank inversely to their cotangents.
fn cot_bar(bar: f64) -> f64 {
    if bar > 0.0 {
        1.0 / bar.tan()
    } else {
        f64::INFINITY
    }
}

/// [`star_quality`] if its worst cotangent is below `bar_cot` (see [`cot_bar`]), found without
/// an arctangent per triangle and given up at the first triangle that cannot beat it.
fn star_quality_above(
    p: &[[f64; 3]],
    x: [f64; 3],
    normal: [f64; 3],
    bar_cot: f64,
    first: &mut usize,
) -> Option<f64> {
    // The answer does not depend on the order the triangles are looked at (any failure fails,
    // else the largest cotangent): start with the one that was worst last time, which is
    // the likeliest to fail again, and remember the worst.
    let n = p.len();
    let mut worst = (f64::NEG_INFINITY, *first);
    let mut i = *first;
    for _ in 0..n {
        let cot = smallest_angle_cot(p[i], p[next(i, n)], x, normal);
        match cot {
            Some(c) if c < bar_cot => {
                if c > worst.0 {
                    worst = (c, i);
                }
            }
            _ => {
                *first = i;
                return None;
            }
        }
        i = next(i, n);
    }
    *first = worst.1;
    Some(1f64.atan2(worst.0))
}

fn star(n: usize) -> Vec<[u8; 3]> {
    (0..n)
        .map(|i| [i as u8, ((i + 1) % n) as u8, n as u8])
        .collect()
}

/// The paper's interior vertex: a weighted average of the corners, each weighted by
/// `sqrt(1 + SLME / LSE)` (LSE: its shortest incident side; SLME: the sum of those), pulled toward
/// the short sides.
pub fn weighted_interior_point(p: &[[f64; 3]]) -> [f64; 3] {
    let n = p.len();
    let sides: Vec<f64> = (0..n).map(|i| length(p[i], p[(i + 1) % n])).collect();
    weighted_point(p, &sides)
}

/// [`weighted_interior_point`] with the side lengths at hand (`sides[i]`: from corner `i` to
/// `i + 1`).
fn weighted_point(p: &[[f64; 3]], sides: &[f64]) -> [f64; 3] {
    let n = p.len();
    let mut lse = [0.0f64; MAX_CORNERS];
    for i in 0..n {
        lse[i] = sides[i].min(sides[prev(i, n)]);
    }
    let slme: f64 = lse[..n].iter().sum();
    let mut x = [0.0; 3];
    let mut total = 0.0;
    for i in 0..n {
        let w = (1.0 + slme / lse[i].max(1e-300)).sqrt();
        total += w;
        for d in 0..3 {
            x[d] += w * p[i][d];
        }
    }
    x.map(|c| c / total)
}

fn clamp_to(x: [f64; 3], (lo, hi): ([f64; 3], [f64; 3])) -> [f64; 3] {
    std::array::from_fn(|d| x[d].clamp(lo[d], hi[d]))
}

/// A star around one interior vertex, its position improved by a pattern search in the polygon's
/// plane from the better of the centroid and the paper's weighted point.
fn best_star(p: &[[f64; 3]], normal: [f64; 3], bounds: ([f64; 3], [f64; 3])) -> (f64, [f64; 3]) {
    let n = p.len();
    let centroid: [f64; 3] =
        std::array::from_fn(|d| p.iter().map(|q| q[d]).sum::<f64>() / n as f64);
    let weighted = weighted_interior_point(p);
    let mut x = centroid;
    let mut q = star_quality(p, x, normal);
    let qw = star_quality(p, weighted, normal);
    if qw > q {
        (x, q) = (weighted, qw);
    }
    // Two directions in the polygon's plane.
    let len = dot(normal, normal).sqrt();
    if len == 0.0 {
        return (q, x);
    }
    let nn = normal.map(|c| c / len);
    let seed = if nn[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let u = {
        let c = cross(nn, seed);
        let l = dot(c, c).sqrt();
        c.map(|v| v / l)
    };
    let v = cross(nn, u);
    let perimeter: f64 = (0..n).map(|i| length(p[i], p[(i + 1) % n])).sum();
    let mut step = 0.25 * perimeter / n as f64;
    // The bar's cotangent changes only when the star improves.
    let mut bar_cot = cot_bar(q);
    let mut first = 0;
    for _ in 0..24 {
        let mut improved = false;
        for dir in [u, v, u.map(|c| -c), v.map(|c| -c)] {
            let y = clamp_to(std::array::from_fn(|d| x[d] + step * dir[d]), bounds);
            if let Some(qy) = star_quality_above(p, y, normal, bar_cot, &mut first) {
                if qy > q {
                    (x, q) = (y, qy);
                    bar_cot = cot_bar(q);
                    improved = true;
                }
            }
        }
        if !improved {
            step *= 0.5;
        }
    }
    (q, x)
}

fn optimal(
    p: &[[f64; 3]],
    chords: &Chords,
    bounds: ([f64; 3], [f64; 3]),
) -> Option<(Triangles, Option<[f64; 3]>)> {
    let normal = polygon_normal(p);
    let by_diagonals =
        best_by_diagonals(p, chords, normal).map(|(rank, t)| (angle_of_rank(rank), t));
    // A star splits every corner's angle in two, so its smallest angle is at most half the
    // polygon's smallest corner angle: when the diagonals reach that, no star can do better.
    let half_corner = (0..p.len())
        .map(|i| corner_angle(p, i))
        .fold(f64::INFINITY, f64::min)
        / 2.0;
    if let Some((qd, tris)) = by_diagonals {
        if qd >= half_corner {
            return Some((tris, None));
        }
    }
    let (qs, x) = best_star(p, normal, bounds);
    // At that interior vertex, the best triangulation joining it to any three or more corners
    // (the rest split by diagonals): exact over the choice of corners; the full star is one.
    let with_point = best_with_point(p, chords, normal, x).filter(|(q, _)| *q >= qs);
    let (qs, star_tris) = match with_point {
        Some((q, t)) => (q, triangles_of(&t)),
        None => (qs, triangles_of(&star(p.len()))),
    };
    match by_diagonals {
        Some((qd, tris)) if qd >= qs => Some((tris, None)),
        _ if qs > 0.0 => Some((star_tris, Some(x))),
        Some((_, tris)) => Some((tris, None)),
        None => None,
    }
}

/// The max–min-angle triangulation of a polygon with one interior vertex at `x` joined to at
/// least three corners, the pockets between consecutive joined corners split by diagonals: exact,
/// by dynamic programming over cyclic corner intervals.
fn best_with_point(
    p: &[[f64; 3]],
    chords: &Chords,
    normal: [f64; 3],
    x: [f64; 3],
) -> Option<(f64, Vec<[u8; 3]>)> {
    let n = p.len();
    let at = |i: usize, len: usize| (i + len) % n;
    let chord = |i: usize, j: usize| chords.has(i, j);
    // pocket[i][len]: best smallest angle triangulating corners i, i+1, …, i+len (cyclic) by
    // diagonals, closed by the chord from i to i+len; len 1 is a polygon side (nothing to split).
    let mut pocket = vec![vec![f64::NEG_INFINITY; n]; n];
    let mut split = vec![vec![usize::MAX; n]; n];
    for row in pocket.iter_mut() {
        row[1] = f64::INFINITY;
    }
    // Each triangle of corners turns up three times below (once per corner opening a pocket),
    // and each fan triangle once per chain start: rank each once.
    let mut ranks = vec![f64::NAN; n * n * n];
    let mut triangle = |a: usize, b: usize, c: usize| {
        // A rotation of (a, b, c) is the same oriented triangle.
        let (a, b, c) = if a < b && a < c {
            (a, b, c)
        } else if b < c {
            (b, c, a)
        } else {
            (c, a, b)
        };
        let slot = &mut ranks[(a * n + b) * n + c];
        if slot.is_nan() {
            *slot = rank(p[a], p[b], p[c], normal);
        }
        *slot
    };
    for len in 2..n {
        for i in 0..n {
            let j = at(i, len);
            if !chord(i, j) {
                continue;
            }
            for m in 1..len {
                let k = at(i, m);
                if !chord(i, k) || !chord(k, j) {
                    continue;
                }
                let q = triangle(i, k, j).min(pocket[i][m]).min(pocket[k][len - m]);
                if q > pocket[i][len] {
                    pocket[i][len] = q;
                    split[i][len] = m;
                }
            }
        }
    }
    let fans: Vec<f64> = (0..n * n)
        .map(|k| {
            let (i, j) = (k / n, k % n);
            if i == j {
                f64::NEG_INFINITY
            } else {
                rank(p[i], p[j], x, normal)
            }
        })
        .collect();
    let fan = |i: usize, j: usize| fans[i * n + j];
    // Chains from the first joined corner s around to s again, through ≥ 3 joined corners.
    let mut best: (f64, usize, Vec<usize>) = (f64::NEG_INFINITY, 0, Vec::new());
    for s in 0..n {
        // value[step][c]: best over chains from s to s+step with c (capped at 3) fan triangles.
        let mut value = vec![[f64::NEG_INFINITY; 4]; n + 1];
        let mut from = vec![[usize::MAX; 4]; n + 1];
        value[0][0] = f64::INFINITY;
        for j in 1..=n {
            for i in 0..j {
                let len = j - i;
                if len >= n {
                    continue;
                }
                let (a, b) = (at(s, i), at(s, j));
                if !chord(a, b) {
                    continue;
                }
                let q = fan(a, b).min(pocket[a][len]);
                for c in 0..4 {
                    if value[i][c] == f64::NEG_INFINITY {
                        continue;
                    }
                    let v = value[i][c].min(q);
                    let c2 = (c + 1).min(3);
                    if v > value[j][c2] {
                        value[j][c2] = v;
                        from[j][c2] = i * 4 + c;
                    }
                }
            }
        }
        if value[n][3] > best.0 {
            // Walk back to the joined corners (as steps from s).
            let mut steps = vec![n];
            let (mut j, mut c) = (n, 3);
            while j > 0 {
                let f = from[j][c];
                j = f / 4;
                c = f % 4;
                steps.push(j);
            }
            steps.reverse();
            best = (value[n][3], s, steps);
        }
    }
    if best.0 == f64::NEG_INFINITY {
        return None;
    }
    let (q, s, steps) = best;
    let q = angle_of_rank(q);
    let mut out = Vec::new();
    for w in steps.windows(2) {
        let (a, len) = (at(s, w[0]), w[1] - w[0]);
        out.push([a as u8, at(a, len) as u8, n as u8]);
        let mut stack = vec![(a, len)];
        while let Some((i, len)) = stack.pop() {
            if len < 2 {
                continue;
            }
            let m = split[i][len];
            out.push([i as u8, at(i, m) as u8, at(i, len) as u8]);
            stack.push((i, m));
            stack.push((at(i, m), len - m));
        }
    }
    Some((q, out))
}

fn local(
    p: &[[f64; 3]],
    chords: &Chords,
    bounds: ([f64; 3], [f64; 3]),
) -> Option<(Triangles, Option<[f64; 3]>)> {
    let normal = polygon_normal(p);
    // A corner angle θ < 30° exactly when its cosine side is positive and tan θ below tan 30°:
    // corners are compared by tan θ = |u × v| / (u · v), no arctangent.
    let tan_bad = LOCAL_BAD_ANGLE_DEGREES.to_radians().tan();
    let n = p.len();
    // Remaining corners, by index into `p`.
    let mut rest = [0u8; MAX_CORNERS];
    for (k, r) in rest.iter_mut().enumerate().take(n) {
        *r = k as u8;
    }
    let mut m = n;
    let mut out = Triangles::new();
    let corner = |rest: &[u8], k: usize| {
        let m = rest.len();
        (
            usize::from(rest[prev(k, m)]),
            usize::from(rest[k]),
            usize::from(rest[next(k, m)]),
        )
    };
    // (1) Cut off corners with a bad angle, smallest first, while the cut is allowed and valid.
    while m > 3 {
        let mut candidates = [(0.0f64, 0usize); MAX_CORNERS];
        let mut count = 0;
        for k in 0..m {
            let (a, b, c) = corner(&rest[..m], k);
            let (u, v) = (sub(p[a], p[b]), sub(p[c], p[b]));
            let w = cross(u, v);
            let cosine = dot(u, v);
            // Most corners are far from 30°: the squared test rules them out without a root
            // (with a margin far above rounding, so borderline corners get the exact test).
            let bar = tan_bad * cosine;
            if cosine <= 0.0 || dot(w, w) > bar * bar * (1.0 + 1e-9) {
                continue;
            }
            let sine = dot(w, w).sqrt();
            if sine < bar {
                // Insertion keeps equal angles in corner order.
                let key = sine / cosine;
                let mut at = count;
                while at > 0 && candidates[at - 1].0 > key {
                    candidates[at] = candidates[at - 1];
                    at -= 1;
                }
                candidates[at] = (key, k);
                count += 1;
            }
        }
        let cut = candidates[..count].iter().find(|&&(_, k)| {
            let (a, b, c) = corner(&rest[..m], k);
            chords.has(a, c) && valid(p[a], p[b], p[c], normal)
        });
        let Some(&(_, k)) = cut else { break };
        let (a, b, c) = corner(&rest[..m], k);
        out.push([a as u8, b as u8, c as u8]);
        rest.copy_within(k + 1..m, k);
        m -= 1;
    }
    let rest = &rest[..m];
    let mut q = [[0.0f64; 3]; MAX_CORNERS];
    let mut sides = [0.0f64; MAX_CORNERS];
    for k in 0..m {
        q[k] = p[usize::from(rest[k])];
    }
    let q = &q[..m];
    for k in 0..m {
        sides[k] = length(q[k], q[next(k, m)]);
    }
    let sides = &sides[..m];
    let ratio = sides.iter().copied().fold(0.0, f64::max)
        / sides.iter().copied().fold(f64::INFINITY, f64::min);
    let interior_wanted = m >= 5 || (m == 4 && ratio > LOCAL_QUAD_RATIO);
    let with_interior = |mut out: Triangles, weighted: [f64; 3]| {
        let x = clamp_to(weighted, bounds);
        for k in 0..m {
            out.push([rest[k], rest[(k + 1) % m], n as u8]);
        }
        Some((out, Some(x)))
    };
    // With no corner cut, the remaining polygon is the polygon.
    let inner = if m == n { *chords } else { chords.sub(rest) };
    // (2) An interior vertex for pentagons and larger, and for long quads — unless diagonals
    // alone do better: in a sliver (two close, long sides) a vertex in the middle only makes
    // needles with a near-180° angle.
    // The exact search by diagonals, run at most once.
    let mut by_diagonals: Option<Option<(f64, Triangles)>> = None;
    if interior_wanted {
        let weighted = weighted_point(q, sides);
        let star = star_rank(q, weighted, normal);
        if star > f64::NEG_INFINITY
            && (ears_below(q, &inner, normal, star)
                || !by_diagonals
                    .get_or_insert_with(|| best_by_diagonals(q, &inner, normal))
                    .is_some_and(|(qd, _)| qd >= star))
        {
            return with_interior(out, weighted);
        }
    }
    if m == 3 {
        out.push([rest[0], rest[1], rest[2]]);
        return Some((out, None));
    }
    // (3) Split the largest angle toward the corner two edges away, trying the larger angles
    // first (equal angles in corner order); fall back to the exact search over the remaining
    // polygon.
    if m == 4 {
        // A diagonal is tried from its larger corner, the diagonal with the larger such corner
        // first; the triangles' order follows that corner.
        let cosines = [0, 1, 2, 3].map(|k| corner_cosine(q, k));
        let larger_first =
            |a: usize, b: usize| compare_corner_angles(q, &cosines, a, b).then(b.cmp(&a));
        let best0 = if larger_first(2, 0).is_gt() { 2 } else { 0 };
        let best1 = if larger_first(3, 1).is_gt() { 3 } else { 1 };
        let order = if larger_first(best1, best0).is_gt() {
            [best1, best0]
        } else {
            [best0, best1]
        };
        for k in order {
            let (a, b) = (k, (k + 2) % 4);
            let (ia, ib) = (usize::from(rest[a]), usize::from(rest[b]));
            if !chords.has(ia, ib) {
                continue;
            }
            let t1 = [rest[a], rest[(a + 1) % 4], rest[b]];
            let t2 = [rest[b], rest[(b + 1) % 4], rest[a]];
            let fits = |t: [u8; 3]| {
                let [x, y, z] = t.map(usize::from);
                valid(p[x], p[y], p[z], normal)
            };
            if fits(t1) && fits(t2) {
                out.push(t1);
                out.push(t2);
                return Some((out, None));
            }
        }
    }
    if let Some((_, tris)) = by_diagonals.unwrap_or_else(|| best_by_diagonals(q, &inner, normal)) {
        for t in tris.as_slice() {
            out.push(t.map(|k| rest[usize::from(k)]));
        }
        return Some((out, None));
    }
    let weighted = weighted_point(q, sides);
    if star_rank(q, weighted, normal) > f64::NEG_INFINITY {
        return with_interior(out, weighted);
    }
    None
}

/// Whether no triangulation of `p` by diagonals can reach `rank`, known from its ears alone:
/// every such triangulation has two ears (triangles cutting off one corner), so its worst
/// triangle is no better than the second-best ear. A margin far above rounding keeps the
/// answer the one the exact search would give.
fn ears_below(p: &[[f64; 3]], chords: &Chords, normal: [f64; 3], rank_to_reach: f64) -> bool {
    let n = p.len();
    let (mut first, mut second) = (f64::NEG_INFINITY, f64::NEG_INFINITY);
    for c in 0..n {
        let (a, b) = (prev(c, n), next(c, n));
        if !chords.has(a, b) {
            continue;
        }
        let r = rank(p[a], p[c], p[b], normal);
        if r > first {
            second = first;
            first = r;
        } else if r > second {
            second = r;
        }
    }
    second + 1e-9 * (1.0 + rank_to_reach.abs()) < rank_to_reach
}

/// The cosine of the angle at corner `i` (1 for a corner with a zero-length side, whose angle
/// is 0).
fn corner_cosine(p: &[[f64; 3]], i: usize) -> f64 {
    let n = p.len();
    let (u, v) = (sub(p[prev(i, n)], p[i]), sub(p[next(i, n)], p[i]));
    let norm = (dot(u, u) * dot(v, v)).sqrt();
    if norm > 0.0 {
        dot(u, v) / norm
    } else {
        1.0
    }
}

/// How the angles at corners `a` and `b` of a polygon compare, exactly as their arctangents
/// ([`corner_angle`]) do, but by their cosines when those are clearly apart (nearly always), so
/// without arctangents.
fn compare_corner_angles(
    p: &[[f64; 3]],
    cosines: &[f64],
    a: usize,
    b: usize,
) -> std::cmp::Ordering {
    let (ca, cb) = (cosines[a], cosines[b]);
    // Cosines are in error by a few ulps; angles are apart by at least their cosines' difference.
    if (ca - cb).abs() > 1e-12 {
        cb.total_cmp(&ca)
    } else {
        corner_angle(p, a).total_cmp(&corner_angle(p, b))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The one-arctangent smallest angle equals the smallest of the three corner angles.
    #[test]
    fn quality_is_the_smallest_corner_angle() {
        let mut rng = crate::TestRng::new(11);
        let mut next = || rng.unit() - 0.5;
        for _ in 0..10_000 {
            let p: [[f64; 3]; 3] = std::array::from_fn(|_| [next(), next(), 0.1 * next()]);
            let n = cross(sub(p[1], p[0]), sub(p[2], p[0]));
            let q = quality(p[0], p[1], p[2], n);
            let all = (0..3)
                .map(|k| {
                    let (u, v) = (sub(p[(k + 1) % 3], p[k]), sub(p[(k + 2) % 3], p[k]));
                    let w = cross(u, v);
                    dot(w, w).sqrt().atan2(dot(u, v))
                })
                .fold(f64::INFINITY, f64::min);
            assert!((q - all).abs() < 1e-9, "{q} vs {all}");
            assert_eq!(quality(p[0], p[2], p[1], n), -1.0);
        }
    }

    fn regular(n: usize) -> Vec<[f64; 3]> {
        (0..n)
            .map(|i| {
                let a = 2.0 * std::f64::consts::PI * i as f64 / n as f64;
                [a.cos(), a.sin(), 0.0]
            })
            .collect()
    }

    /// The triangles' corner positions (the interior vertex last).
    fn corners(p: &[[f64; 3]], t: &PolygonTriangles) -> Vec<[[f64; 3]; 3]> {
        let mut all = p.to_vec();
        all.extend(t.interior);
        t.triangles
            .iter()
            .map(|tri| tri.map(|i| all[usize::from(i)]))
            .collect()
    }

    fn min_angle(p: &[[f64; 3]], t: &PolygonTriangles) -> f64 {
        corners(p, t)
            .into_iter()
            .map(|[a, b, c]| quality(a, b, c, [0.0, 0.0, 1.0]))
            .fold(f64::INFINITY, f64::min)
            .to_degrees()
    }

    /// Area of the triangles equals the polygon's: they tile it without overlap or gap.
    fn area(p: &[[f64; 3]], t: &PolygonTriangles) -> f64 {
        corners(p, t)
            .into_iter()
            .map(|[a, b, c]| cross(sub(b, a), sub(c, a))[2] / 2.0)
            .sum()
    }

    #[test]
    fn regular_polygons() {
        let any = |_: usize, _: usize| true;
        let bounds = ([-2.0; 3], [2.0; 3]);
        for n in 4..=12 {
            let p = regular(n);
            let exact = polygon_normal(&p)[2] / 2.0;
            for s in [Strategy::Local, Strategy::Optimal] {
                let t = triangulate(&p, &any, s, bounds).unwrap();
                assert!((area(&p, &t) - exact).abs() < 1e-9, "{s:?} {n}");
                assert!(min_angle(&p, &t) > 0.0);
            }
            // Every angle of a triangulation of a regular n-gon by diagonals is a multiple of
            // 180°/n; the star around the centre has angles 360°/n and (180° − 360°/n)/2.
            // Optimal does at least as well as both.
            let t = triangulate(&p, &any, Strategy::Optimal, bounds).unwrap();
            let nf = n as f64;
            let star_angle = (360.0 / nf).min((180.0 - 360.0 / nf) / 2.0);
            let bound = star_angle.max(180.0 / nf);
            let got = min_angle(&p, &t);
            assert!(got >= bound - 1e-6, "{n}: {got}");
        }
    }

    /// Around a fixed interior vertex, the exact search over joined corners tiles the polygon and
    /// is never worse than the full star (one of its candidates), on irregular polygons.
    #[test]
    fn interior_vertex_triangulations_tile_and_beat_the_star() {
        let mut rng = crate::TestRng::new(7);
        let mut next = || rng.unit();
        let any = |_: usize, _: usize| true;
        for n in 4..=12 {
            for _ in 0..20 {
                // A star-shaped polygon around the origin with random radii.
                let p: Vec<[f64; 3]> = (0..n)
                    .map(|i| {
                        let a = 2.0 * std::f64::consts::PI * (i as f64 + 0.4 * next()) / n as f64;
                        let r = 0.3 + next();
                        [r * a.cos(), r * a.sin(), 0.0]
                    })
                    .collect();
                let normal = polygon_normal(&p);
                let x = [0.05 * next(), 0.05 * next(), 0.0];
                let star_q = star_quality(&p, x, normal);
                let Some((q, tris)) = best_with_point(&p, &Chords::new(n, any), normal, x) else {
                    assert!(star_q <= 0.0);
                    continue;
                };
                assert!(q >= star_q - 1e-12);
                let t = PolygonTriangles {
                    triangles: tris,
                    interior: Some(x),
                };
                assert_eq!(
                    t.triangles.len(),
                    n - 2 + 2,
                    "n triangles with one interior vertex"
                );
                assert!((area(&p, &t) - normal[2] / 2.0).abs() < 1e-9);
                assert!((min_angle(&p, &t) - q.to_degrees()).abs() < 1e-9);
            }
        }
    }

    #[test]
    fn forbidden_diagonals_are_respected() {
        let p = regular(6);
        // Only diagonals from corner 0.
        let from0 = |i: usize, _: usize| i == 0;
        let t = best_by_diagonals(&p, &Chords::new(6, from0), polygon_normal(&p))
            .unwrap()
            .1;
        for tri in t.as_slice() {
            for k in 0..3 {
                let (a, b) = (tri[k].min(tri[(k + 1) % 3]), tri[k].max(tri[(k + 1) % 3]));
                assert!(b == a + 1 || (a, b) == (0, 5) || a == 0, "{t:?}");
            }
        }
        // Nothing allowed: no triangulation by diagonals.
        assert!(best_by_diagonals(&p, &Chords::new(6, |_, _| false), polygon_normal(&p)).is_none());
    }

    #[test]
    fn local_skips_a_useless_interior_vertex_and_optimal_beats_local() {
        let any = |_: usize, _: usize| true;
        let bounds = ([-1.0; 3], [11.0; 3]);
        // A sliver rectangle (side ratio 10): a vertex in the middle would only add needles, so
        // local splits it by a diagonal.
        let p = vec![
            [0.0, 0.0, 0.0],
            [10.0, 0.0, 0.0],
            [10.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
        ];
        let l = triangulate(&p, &any, Strategy::Local, bounds).unwrap();
        assert!(l.interior.is_none());
        assert_eq!(l.triangles.len(), 2);
        let o = triangulate(&p, &any, Strategy::Optimal, bounds).unwrap();
        assert!(min_angle(&p, &o) >= min_angle(&p, &l) - 1e-9);
        assert!((area(&p, &o) - 10.0).abs() < 1e-9 && (area(&p, &l) - 10.0).abs() < 1e-9);
        // A hexagon with one very short side: local's interior vertex, pulled toward the short
        // side, beats every split by diagonals here, and optimal is at least as good again.
        let h = vec![
            [0.0, 0.0, 0.0],
            [2.0, -1.0, 0.0],
            [4.0, 0.0, 0.0],
            [4.0, 0.2, 0.0],
            [2.0, 1.2, 0.0],
            [0.0, 0.2, 0.0],
        ];
        let lh = triangulate(&h, &any, Strategy::Local, bounds).unwrap();
        let oh = triangulate(&h, &any, Strategy::Optimal, bounds).unwrap();
        let diagonals = angle_of_rank(
            best_by_diagonals(&h, &Chords::new(6, any), polygon_normal(&h))
                .unwrap()
                .0,
        )
        .to_degrees();
        assert!(min_angle(&h, &lh) >= diagonals - 1e-9);
        assert!(min_angle(&h, &oh) >= min_angle(&h, &lh) - 1e-9);
    }
}
