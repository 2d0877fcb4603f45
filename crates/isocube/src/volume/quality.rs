//! Tetrahedron quality: dihedral angles and the radius ratio (Verdict's definitions).

use rayon::prelude::*;

use super::check::{cross, dot, sub};
use super::TetMesh;

/// The quality of one tetrahedron.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TetQuality {
    /// The smallest of its six dihedral angles, in degrees (70.5° for the regular tetrahedron).
    pub min_dihedral: f64,
    /// The largest dihedral angle, in degrees.
    pub max_dihedral: f64,
    /// Verdict's radius ratio: the circumradius over three times the inradius (1 for the
    /// regular tetrahedron, growing without bound as it flattens; infinite when flat).
    pub radius_ratio: f64,
}

impl TetQuality {
    /// The quality of the tetrahedron with these corners.
    ///
    /// ```
    /// use isocube::volume::TetQuality;
    /// let s = 1.0 / 2f64.sqrt();
    /// let regular = [[1.0, 0.0, -s], [-1.0, 0.0, -s], [0.0, 1.0, s], [0.0, -1.0, s]];
    /// let q = TetQuality::of(regular);
    /// assert!((q.min_dihedral - 70.528779).abs() < 1e-5 && (q.radius_ratio - 1.0).abs() < 1e-12);
    /// ```
    pub fn of(p: [[f64; 3]; 4]) -> TetQuality {
        // Outward-or-inward normals of the faces opposite each corner, all the same way.
        let face = |i: usize| {
            let [a, b, c] = [(i + 1) % 4, (i + 2) % 4, (i + 3) % 4].map(|k| p[k]);
            let n = cross(sub(b, a), sub(c, a));
            // Point away from the opposite corner.
            if dot(n, sub(p[i], a)) > 0.0 {
                n.map(|x| -x)
            } else {
                n
            }
        };
        let normals: [[f64; 3]; 4] = std::array::from_fn(face);
        let areas: [f64; 4] = normals.map(|n| 0.5 * dot(n, n).sqrt());
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for i in 0..4 {
            for j in i + 1..4 {
                let (a, b) = (normals[i], normals[j]);
                let len = (dot(a, a) * dot(b, b)).sqrt();
                // The dihedral angle at the edge the two faces share.
                let angle = if len > 0.0 {
                    180.0 - (dot(a, b) / len).clamp(-1.0, 1.0).acos().to_degrees()
                } else {
                    0.0
                };
                lo = lo.min(angle);
                hi = hi.max(angle);
            }
        }
        let [a, b, c] = [0, 1, 2].map(|k| sub(p[k], p[3]));
        let six_volume = dot(a, cross(b, c)).abs();
        let radius_ratio = if six_volume > 0.0 {
            let w = [cross(b, c), cross(c, a), cross(a, b)];
            let s = [dot(a, a), dot(b, b), dot(c, c)];
            let m: [f64; 3] =
                std::array::from_fn(|d| s[0] * w[0][d] + s[1] * w[1][d] + s[2] * w[2][d]);
            let circumradius = dot(m, m).sqrt() / (2.0 * six_volume);
            let inradius = 0.5 * six_volume / areas.iter().sum::<f64>();
            circumradius / (3.0 * inradius)
        } else {
            f64::INFINITY
        };
        TetQuality {
            min_dihedral: lo,
            max_dihedral: hi,
            radius_ratio,
        }
    }
}

/// The smallest and largest dihedral angles of a tetrahedron, in degrees, as
/// [`TetQuality::of`] finds them, with two arc cosines instead of six (the cone-point search
/// scores many candidate tetrahedra).
pub(super) fn dihedral_extremes(p: [[f64; 3]; 4]) -> (f64, f64) {
    let face = |i: usize| {
        let [a, b, c] = [(i + 1) % 4, (i + 2) % 4, (i + 3) % 4].map(|k| p[k]);
        let n = cross(sub(b, a), sub(c, a));
        let n = if dot(n, sub(p[i], a)) > 0.0 {
            n.map(|x| -x)
        } else {
            n
        };
        let len = dot(n, n).sqrt();
        if len > 0.0 {
            n.map(|x| x / len)
        } else {
            n
        }
    };
    let normals: [[f64; 3]; 4] = std::array::from_fn(face);
    // The dihedral angle is 180° less the angle between outward normals: its cosine is
    // minus their dot product.
    let (mut hi_cos, mut lo_cos) = (f64::NEG_INFINITY, f64::INFINITY);
    for i in 0..4 {
        for j in i + 1..4 {
            let c = -dot(normals[i], normals[j]);
            hi_cos = hi_cos.max(c);
            lo_cos = lo_cos.min(c);
        }
    }
    let angle = |c: f64| c.clamp(-1.0, 1.0).acos().to_degrees();
    (angle(hi_cos), angle(lo_cos))
}

/// A whole mesh's quality.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TetReport {
    /// Tetrahedra.
    pub tets: usize,
    /// The smallest dihedral angle, in degrees.
    pub min_dihedral: f64,
    /// The largest dihedral angle, in degrees.
    pub max_dihedral: f64,
    /// The worst (largest) radius ratio.
    pub max_radius_ratio: f64,
    /// The mean radius ratio.
    pub mean_radius_ratio: f64,
    /// Tetrahedra by smallest dihedral angle, in 5° bins from 0° to 90° (the last bin holds
    /// everything from 85° up).
    pub min_dihedral_histogram: [usize; 18],
}

impl TetMesh {
    /// Every tetrahedron's quality, in order.
    pub fn qualities(&self) -> Vec<TetQuality> {
        self.tets
            .par_iter()
            .map(|t| TetQuality::of(t.map(|v| self.positions[v as usize].map(f64::from))))
            .collect()
    }

    /// The mesh's quality summary.
    pub fn quality_report(&self) -> TetReport {
        TetReport::of(&self.qualities())
    }
}

impl TetReport {
    /// The summary of these tetrahedra's qualities.
    pub fn of(qualities: &[TetQuality]) -> TetReport {
        let mut r = TetReport {
            tets: qualities.len(),
            min_dihedral: f64::INFINITY,
            max_dihedral: f64::NEG_INFINITY,
            ..TetReport::default()
        };
        let mut sum = 0.0;
        for q in qualities {
            r.min_dihedral = r.min_dihedral.min(q.min_dihedral);
            r.max_dihedral = r.max_dihedral.max(q.max_dihedral);
            r.max_radius_ratio = r.max_radius_ratio.max(q.radius_ratio);
            sum += q.radius_ratio;
            let bin = ((q.min_dihedral / 5.0).max(0.0) as usize).min(17);
            r.min_dihedral_histogram[bin] += 1;
        }
        r.mean_radius_ratio = if qualities.is_empty() {
            0.0
        } else {
            sum / qualities.len() as f64
        };
        if qualities.is_empty() {
            r.min_dihedral = 0.0;
            r.max_dihedral = 0.0;
        }
        r
    }
}
