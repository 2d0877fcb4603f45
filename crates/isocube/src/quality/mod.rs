//! Mesh quality: one report of the Verdict measures and angles ([`QualityReport`]) and the
//! distance of a mesh from a field's level set.
//!
//! ```
//! use isocube::extract::{extract, ExtractOptions};
//! use isocube::field::Sample;
//! use isocube::quality::{level_set_distance, quality_report};
//! let grid = Sample::Sphere.grid(20);
//! let (mesh, _) = extract(&grid, &ExtractOptions::default()).unwrap();
//! let q = quality_report(&mesh);
//! assert!(q.min_angle.min > 0.0 && q.max_angle.max < 180.0);
//! assert_eq!(q.min_angle.min, mesh.report().min_angle); // one angle measure everywhere
//! // The sphere's field is a distance, so this is the geometric error in grid spacings.
//! let d = level_set_distance(&mesh, |p| Sample::Sphere.eval(p), 0.0, grid.spacing()[0]);
//! assert!(d.max < 0.05);
//! ```

pub mod relax;
pub mod triangulate;

pub use relax::{relax, Field, Implicit, Trilinear};
pub use triangulate::{triangulate, PolygonTriangles, Strategy};
pub(crate) use triangulate::{triangulate_polygon, Chords, MAX_CORNERS};

use crate::mesh::{cross, dot, sub, Mesh};

/// Distance statistics of a mesh from a level set, in units of the grid spacing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Distance {
    /// Largest first-order distance `|f − level| / |∇f|` over the sample points.
    pub max: f64,
    /// Mean over the sample points.
    pub mean: f64,
    /// Number of sample points (each vertex, each edge midpoint, each triangle centroid).
    pub samples: usize,
}

/// The first-order distance `|f(x) − level| / |∇f(x)|` from the level set of `field` at the
/// mesh's vertices, edge midpoints and triangle centroids, divided by `spacing`. The gradient is
/// taken by central differences with a step of `1e-4 · spacing`; points where it vanishes are
/// skipped.
pub fn level_set_distance(
    mesh: &Mesh,
    field: impl Fn([f64; 3]) -> f64,
    level: f64,
    spacing: f64,
) -> Distance {
    let h = 1e-4 * spacing;
    let distance = |x: [f64; 3]| {
        let g: [f64; 3] = std::array::from_fn(|a| {
            let (mut lo, mut hi) = (x, x);
            lo[a] -= h;
            hi[a] += h;
            (field(hi) - field(lo)) / (2.0 * h)
        });
        let len = dot(g, g).sqrt();
        (len > 0.0).then(|| (field(x) - level).abs() / len / spacing)
    };
    let (mut max, mut sum, mut n) = (0.0f64, 0.0f64, 0usize);
    let mut add = |d: Option<f64>| {
        if let Some(d) = d {
            max = max.max(d);
            sum += d;
            n += 1;
        }
    };
    for p in &mesh.positions {
        add(distance(p.map(f64::from)));
    }
    let mut edges: Vec<(u32, u32)> = Vec::with_capacity(3 * mesh.triangles.len());
    for t in &mesh.triangles {
        let p = t.map(|v| mesh.positions[v as usize].map(f64::from));
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            edges.push((a.min(b), a.max(b)));
        }
        add(distance(std::array::from_fn(|a| {
            (p[0][a] + p[1][a] + p[2][a]) / 3.0
        })));
    }
    edges.sort_unstable();
    edges.dedup();
    for (a, b) in edges {
        let (p, q) = (mesh.positions[a as usize], mesh.positions[b as usize]);
        add(distance(std::array::from_fn(|k| {
            (f64::from(p[k]) + f64::from(q[k])) / 2.0
        })));
    }
    Distance {
        max,
        mean: if n > 0 { sum / n as f64 } else { 0.0 },
        samples: n,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn verdict_measures_of_a_right_isosceles_triangle() {
        let q = triangle_quality([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]).unwrap();
        let s2 = 2f64.sqrt();
        // R = √2/2, r = (2 − √2)/2: R/(2r) = (√2/2)/(2 − √2) = (1 + √2)/2.
        assert!((q.radius_ratio - (1.0 + s2) / 2.0).abs() < 1e-12);
        // L_max · P / (4√3 A) = √2 (2 + √2) / (4√3 · 1/2).
        assert!((q.aspect_ratio - s2 * (2.0 + s2) / (2.0 * 3f64.sqrt())).abs() < 1e-12);
        assert!((q.edge_ratio - s2).abs() < 1e-12 && (q.area - 0.5).abs() < 1e-12);
        assert!(triangle_quality([[0.0; 3], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]]).is_none());
        let mesh = Mesh {
            positions: vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            normals: Vec::new(),
            triangles: vec![[0, 1, 2], [0, 0, 1]],
        };
        let r = quality_report(&mesh);
        assert_eq!((r.triangles, r.degenerate), (2, 1));
        assert_eq!(r.histogram.iter().sum::<usize>(), 3);
        assert_eq!((r.histogram[9], r.histogram[18]), (2, 1));
    }

    #[test]
    fn right_isosceles_triangle() {
        let mesh = Mesh {
            positions: vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            normals: Vec::new(),
            triangles: vec![[0, 1, 2]],
        };
        let s = quality_report(&mesh);
        assert!((s.min_angle.min - 45.0).abs() < 1e-9 && (s.max_angle.max - 90.0).abs() < 1e-9);
        assert_eq!((s.below[0], s.below[1]), (0.0, 0.0));
        // Plane z = 0.25 as the field: every sample point is 0.25 away.
        let d = level_set_distance(&mesh, |p| p[2] - 0.25, 0.0, 0.5);
        assert!((d.max - 0.5).abs() < 1e-6 && (d.mean - 0.5).abs() < 1e-6);
        assert_eq!(d.samples, 3 + 3 + 1);
    }
}

/// Quality measures of one triangle, as the Verdict library (used by VTK) defines them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleQuality {
    /// Smallest angle, degrees (60 for equilateral).
    pub min_angle: f64,
    /// Largest angle, degrees (60 for equilateral).
    pub max_angle: f64,
    /// Circumradius over twice the inradius (1 for equilateral, ∞ for degenerate).
    pub radius_ratio: f64,
    /// Longest edge times perimeter over `4√3` times area (1 for equilateral).
    pub aspect_ratio: f64,
    /// Longest edge over shortest edge (1 for equilateral).
    pub edge_ratio: f64,
    /// Area.
    pub area: f64,
}

/// The smallest angle, in radians, of a triangle in a plane (exact zero for a degenerate one).
pub(crate) fn smallest_angle_2d(pa: [f64; 2], pb: [f64; 2], pc: [f64; 2]) -> f64 {
    let angle = |o: [f64; 2], p: [f64; 2], q: [f64; 2]| {
        let (x, y) = ([p[0] - o[0], p[1] - o[1]], [q[0] - o[0], q[1] - o[1]]);
        (x[0] * y[1] - x[1] * y[0])
            .abs()
            .atan2(x[0] * y[0] + x[1] * y[1])
    };
    angle(pa, pb, pc)
        .min(angle(pb, pc, pa))
        .min(angle(pc, pa, pb))
}

/// The Verdict measures of a triangle; `None` when it has zero area.
///
/// ```
/// use isocube::quality::triangle_quality;
/// let q = triangle_quality([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.5, 0.75f64.sqrt(), 0.0]]).unwrap();
/// assert!((q.min_angle - 60.0).abs() < 1e-9 && (q.radius_ratio - 1.0).abs() < 1e-9);
/// assert!((q.aspect_ratio - 1.0).abs() < 1e-9 && (q.edge_ratio - 1.0).abs() < 1e-9);
/// ```
pub fn triangle_quality(p: [[f64; 3]; 3]) -> Option<TriangleQuality> {
    let a = crate::mesh::triangle_angles(p)?;
    let len: [f64; 3] = std::array::from_fn(|k| {
        let d = sub(p[(k + 1) % 3], p[k]);
        dot(d, d).sqrt()
    });
    let n = cross(sub(p[1], p[0]), sub(p[2], p[0]));
    let area = dot(n, n).sqrt() / 2.0;
    let perimeter = len[0] + len[1] + len[2];
    let lmax = len[0].max(len[1]).max(len[2]);
    let lmin = len[0].min(len[1]).min(len[2]);
    let inradius = 2.0 * area / perimeter;
    let circumradius = len[0] * len[1] * len[2] / (4.0 * area);
    Some(TriangleQuality {
        min_angle: a[0].min(a[1]).min(a[2]),
        max_angle: a[0].max(a[1]).max(a[2]),
        radius_ratio: circumradius / (2.0 * inradius),
        aspect_ratio: lmax * perimeter / (4.0 * 3f64.sqrt() * area),
        edge_ratio: lmax / lmin,
        area,
    })
}

/// Minimum, maximum and mean of one measure over a mesh.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Range {
    /// Smallest value.
    pub min: f64,
    /// Largest value.
    pub max: f64,
    /// Mean.
    pub mean: f64,
}

impl Range {
    fn of(values: impl Iterator<Item = f64>) -> Range {
        let (mut min, mut max, mut sum, mut n) = (f64::INFINITY, f64::NEG_INFINITY, 0.0, 0usize);
        for v in values {
            min = min.min(v);
            max = max.max(v);
            sum += v;
            n += 1;
        }
        if n == 0 {
            return Range {
                min: f64::NAN,
                max: f64::NAN,
                mean: f64::NAN,
            };
        }
        Range {
            min,
            max,
            mean: sum / n as f64,
        }
    }
}

/// A mesh's quality: the Verdict measures over its non-degenerate triangles and the histogram of
/// all its angles in 5° bins.
#[derive(Clone, Debug, PartialEq)]
pub struct QualityReport {
    /// Triangles.
    pub triangles: usize,
    /// Triangles with zero area (left out of the measures).
    pub degenerate: usize,
    /// Smallest angle per triangle.
    pub min_angle: Range,
    /// Largest angle per triangle.
    pub max_angle: Range,
    /// Verdict radius ratio.
    pub radius_ratio: Range,
    /// Verdict aspect ratio.
    pub aspect_ratio: Range,
    /// Verdict edge ratio.
    pub edge_ratio: Range,
    /// Area.
    pub area: Range,
    /// Share of triangles whose smallest angle is below 10°, 20° and 30°.
    pub below: [f64; 3],
    /// Number of angles in each 5° bin: `histogram[i]` counts angles in `[5i, 5i + 5)`, the last
    /// bin includes 180°.
    pub histogram: [usize; 36],
}

/// Computes a mesh's [`QualityReport`].
pub fn quality_report(mesh: &Mesh) -> QualityReport {
    let qs: Vec<TriangleQuality> = mesh
        .triangles
        .iter()
        .filter_map(|t| triangle_quality(t.map(|v| mesh.positions[v as usize].map(f64::from))))
        .collect();
    let mut histogram = [0usize; 36];
    for t in &mesh.triangles {
        if let Some(a) =
            crate::mesh::triangle_angles(t.map(|v| mesh.positions[v as usize].map(f64::from)))
        {
            for x in a {
                histogram[((x / 5.0) as usize).min(35)] += 1;
            }
        }
    }
    let share = |limit: f64| {
        if qs.is_empty() {
            0.0
        } else {
            qs.iter().filter(|q| q.min_angle < limit).count() as f64 / qs.len() as f64
        }
    };
    QualityReport {
        triangles: mesh.triangles.len(),
        degenerate: mesh.triangles.len() - qs.len(),
        min_angle: Range::of(qs.iter().map(|q| q.min_angle)),
        max_angle: Range::of(qs.iter().map(|q| q.max_angle)),
        radius_ratio: Range::of(qs.iter().map(|q| q.radius_ratio)),
        aspect_ratio: Range::of(qs.iter().map(|q| q.aspect_ratio)),
        edge_ratio: Range::of(qs.iter().map(|q| q.edge_ratio)),
        area: Range::of(qs.iter().map(|q| q.area)),
        below: [share(10.0), share(20.0), share(30.0)],
        histogram,
    }
}
