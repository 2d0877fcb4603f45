//! Classification: the cell's binary configuration and the asymptotic decider on its faces.

use crate::cube::{FaceDecisions, FACES};

/// The binary configuration: bit `i` set when vertex `i` is at or above the level.
#[inline]
pub(super) fn cell_config(v: &[f32; 8], level: f32) -> u8 {
    let mut config = 0u8;
    for (i, &x) in v.iter().enumerate() {
        config |= u8::from(x >= level) << i;
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
pub(super) fn face_decisions(v: &[f32; 8], level: f32, ambiguous: u8) -> FaceDecisions {
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
