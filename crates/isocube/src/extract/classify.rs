//! Classification: the cell's binary configuration and the asymptotic decider on its faces.

use crate::cube::{FaceDecisions, FACES};
use crate::field::is_above;

/// The binary configuration: bit `i` set when vertex `i` is at or above the level.
#[inline]
pub(crate) fn cell_config(v: &[f32; 8], level: f32) -> u8 {
    let mut config = 0u8;
    for (i, &x) in v.iter().enumerate() {
        config |= u8::from(is_above(x, level)) << i;
    }
    config
}

/// Decides each ambiguous face (bit set in `ambiguous`): bit `f` of the result is set when the
/// above corners of face `f` are joined, i.e. the bilinear interpolant's saddle value is at or
/// above the level.
///
/// On an ambiguous face the above corners `p, q` and the below corners `r, s` sit on opposite
/// diagonals. With offsets from the level, the saddle value is `(pq − rs) / (p + q − r − s)`
/// and the denominator is positive, so the test is `pq ≥ rs`. Offsets and products are taken
/// in `f64` from the same four `f32` values by both cells sharing the face, so the two cells
/// always reach the same decision.
#[inline]
pub(crate) fn face_decisions(v: &[f32; 8], level: f32, ambiguous: u8) -> FaceDecisions {
    let mut decisions = 0;
    let mut mask = ambiguous;
    while mask != 0 {
        let f = mask.trailing_zeros() as usize;
        mask &= mask - 1;
        let c = FACES[f].map(|corner| f64::from(v[usize::from(corner)]) - f64::from(level));
        let (above, below) = if c[0] >= 0.0 {
            (c[0] * c[2], c[1] * c[3])
        } else {
            (c[1] * c[3], c[0] * c[2])
        };
        if above >= below {
            decisions |= 1 << f;
        }
    }
    decisions
}

/// The vertical edges of the cell in the order they meet a z-slice: the slice's corners
/// (0,0), (1,0), (1,1), (0,1), as (bottom vertex, top vertex).
const VERTICAL: [(usize, usize); 4] = [(0, 4), (1, 5), (2, 6), (3, 7)];

/// Pairs of same-sign cube vertices that the trilinear interpolant joins through the cell's
/// interior, found by sweeping the cell with z-slices.
///
/// On the slice at height `t` the interpolant is bilinear with corner values `A(t)…D(t)` taken
/// linearly along the four vertical edges. Every sign region of a slice contains a slice corner
/// (a bilinear function has no interior extremum), so the sign regions of the whole cell are
/// unions of vertical-edge intervals, joined wherever two of them share a slice region at some
/// height. Adjacent corners share a region only along a side face, which the boundary regions
/// already account for; the only joins through the interior are between diagonal corners `A, C`
/// (or `B, D`) when the other two have the opposite sign and the slice's saddle value has their
/// sign: `A·C ≥ B·D` for the above side (ties count as above, as for faces), `A·C > B·D` for the
/// below side. `A·C − B·D` is quadratic in `t`, so checking its interval's ends and its vertex is
/// exact. Each returned pair names one vertex (an end of the edge with that sign) of each joined
/// vertical edge.
pub(super) fn interior_links(v: &[f32; 8], level: f32) -> impl Iterator<Item = (u8, u8)> {
    let r: [f64; 8] = v.map(|x| f64::from(x) - f64::from(level));
    let edge = |k: usize| [r[VERTICAL[k].0], r[VERTICAL[k].1]];
    let endpoint = |k: usize, above: bool| {
        let (lo, hi) = VERTICAL[k];
        if (r[lo] >= 0.0) == above {
            lo as u8
        } else {
            hi as u8
        }
    };
    let mut links = [(0u8, 0u8); 4];
    let mut n = 0;
    for (p, q, s, u) in [(0, 2, 1, 3), (1, 3, 0, 2)] {
        for above in [true, false] {
            if slice_join(edge(p), edge(q), edge(s), edge(u), above) {
                links[n] = (endpoint(p, above), endpoint(q, above));
                n += 1;
            }
        }
    }
    links.into_iter().take(n)
}

/// Whether some slice `t ∈ [0, 1]` has diagonal corners `a, c` of one sign (`above`), `b, d` of
/// the other, and a saddle on the side of `a, c`.
fn slice_join(a: [f64; 2], c: [f64; 2], b: [f64; 2], d: [f64; 2], above: bool) -> bool {
    let at = |e: [f64; 2], t: f64| e[0] + t * (e[1] - e[0]);
    let holds = |t: f64| {
        let (av, bv, cv, dv) = (at(a, t), at(b, t), at(c, t), at(d, t));
        let same = |x: f64| (x >= 0.0) == above;
        let q = av * cv - bv * dv;
        same(av) && same(cv) && !same(bv) && !same(dv) && if above { q >= 0.0 } else { q > 0.0 }
    };
    // The interval where the four signs hold (each linear constraint keeps one end of [0, 1]).
    let (mut lo, mut hi) = (0.0f64, 1.0f64);
    for (e, want) in [(a, above), (c, above), (b, !above), (d, !above)] {
        let ok = |x: f64| (x >= 0.0) == want;
        match (ok(e[0]), ok(e[1])) {
            (true, true) => {}
            (false, false) => return false,
            (start, _) => {
                let root = e[0] / (e[0] - e[1]);
                if start {
                    hi = hi.min(root);
                } else {
                    lo = lo.max(root);
                }
            }
        }
    }
    if lo > hi {
        return false;
    }
    // A·C − B·D = α t² + β t + γ; its maximum over [lo, hi] is at an end or at the vertex.
    let (da, db, dc, dd) = (a[1] - a[0], b[1] - b[0], c[1] - c[0], d[1] - d[0]);
    let alpha = da * dc - db * dd;
    let beta = a[0] * dc + c[0] * da - b[0] * dd - d[0] * db;
    let mut candidates = [lo, hi, 0.5 * (lo + hi), f64::NAN];
    if alpha < 0.0 {
        let vertex = -beta / (2.0 * alpha);
        if vertex > lo && vertex < hi {
            candidates[3] = vertex;
        }
    }
    candidates.into_iter().filter(|t| !t.is_nan()).any(holds)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Case 4 (vertices 0 and 6 above): the body-diagonal corners are joined through the interior
    /// exactly when the trilinear interpolant has a positive tube between them.
    #[test]
    fn body_diagonal_tunnel() {
        let mut v = [-1.0f32; 8];
        v[0] = 1.0;
        v[6] = 1.0;
        // Far below: the corners stay apart (links between below vertices are allowed, and
        // redundant: the below region is one region on the boundary already).
        assert!(interior_links(&v, 0.0)
            .all(|(p, q)| v[usize::from(p)] < 0.0 && v[usize::from(q)] < 0.0));
        // Strong corners and weak negatives: the interpolant joins them.
        let mut w = [-0.1f32; 8];
        w[0] = 1.0;
        w[6] = 1.0;
        let links: Vec<_> = interior_links(&w, 0.0)
            .filter(|&(p, _)| w[usize::from(p)] >= 0.0)
            .collect();
        assert_eq!(links.len(), 1);
        let (p, q) = links[0];
        assert_eq!((p.min(q), p.max(q)), (0, 6));
    }
}
