use std::f64::consts::PI;
use std::fmt;
use std::str::FromStr;

use super::Grid;

/// Built-in implicit functions, each with default bounds (a cube `[lo, hi]^3`).
///
/// Every sample is negative inside and positive outside, with level 0, so extracted normals
/// (which point toward increasing values) point outward.
///
/// | name | function | bounds | surface |
/// |---|---|---|---|
/// | `sphere` | `|p| − 0.8` | `[−1, 1]` | closed, 1 component, χ = 2 |
/// | `torus` | `√((√(x²+y²) − 0.6)² + z²) − 0.25` | `[−1, 1]` | closed, 1 component, χ = 0 |
/// | `two-tori` | two linked tori (R 0.5, r 0.15) | `[−1, 1]` | closed, 2 components, χ = 0 |
/// | `tangle` | `x⁴ − 5x² + y⁴ − 5y² + z⁴ − 5z² + 11.8` | `[−3, 3]` | closed, 1 component, χ = −8 (genus 5) |
/// | `gyroid` | `sin x cos y + sin y cos z + sin z cos x` | `[−3, 3]` | open, 1 component, χ = −3 |
/// | `schwarz-p` | `cos x + cos y + cos z` | `[−2π, 2π]` | open, 1 component, χ = −32 |
/// | `hyperboloid` | `x² + y² − z² − 0.25` | `[−1, 1]` | open annulus, 1 component, χ = 0 |
/// | `tubes` | `1.2 − max(cos y + cos z, cos z + cos x, cos x + cos y)` | `[−3π, 3π]` | open, 1 component, χ = −108 |
/// | `noise` | seeded smooth value noise, 3 octaves | `[0, 4]` | open, many components |
/// | `packed-spheres` | signed distance to a seeded packing of spheres | `[0, 1]` | many components, some cut by the box |
///
/// The box cuts the open samples transversally, so their components and Euler characteristic
/// (counted with the boundary) do not change with resolution; the test suite checks them at 40
/// and 64 points per axis. The gyroid's box stops short of a full period (±π) on purpose: at
/// ±π the box touches the surface tangentially and small slivers appear or vanish with
/// resolution.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Sample {
    /// A sphere of radius 0.8.
    Sphere,
    /// A torus, major radius 0.6, minor radius 0.25.
    Torus,
    /// Two interlocked tori (a Hopf link).
    TwoTori,
    /// The tangle cube.
    Tangle,
    /// The gyroid (triply periodic minimal surface approximation).
    Gyroid,
    /// Schwarz P surface.
    SchwarzP,
    /// A hyperboloid of one sheet.
    Hyperboloid,
    /// A lattice of tubes along the three axes, from cosines.
    Tubes,
    /// Smooth value noise from a seed.
    Noise {
        /// Seed of the lattice values.
        seed: u64,
    },
    /// The signed distance to the union of non-overlapping spheres of random radii packed in
    /// the unit box, some cut by its faces (see [`sphere_packing`]): the porous microstructure
    /// of Tokunaga's section 6. `tetmesh` meshes the spheres; with `--flip`, the pores.
    PackedSpheres {
        /// Seed of the packing.
        seed: u64,
    },
}

/// A sphere of a packing: centre and radius.
pub type Ball = ([f64; 3], f64);

/// The packing of [`Sample::PackedSpheres`] for `seed`: radii drawn between 0.06 and 0.14,
/// placed largest first at random centres in the unit box (a sphere may stick out of it) with
/// at least 0.02 between any two, each tried at up to 400 places. Deterministic.
///
/// ```
/// use isocube::field::sphere_packing;
/// let balls = sphere_packing(1);
/// assert!(balls.len() > 40);
/// for (i, a) in balls.iter().enumerate() {
///     for b in &balls[i + 1..] {
///         let d = (0..3).map(|k| (a.0[k] - b.0[k]).powi(2)).sum::<f64>().sqrt();
///         assert!(d >= a.1 + b.1 + 0.02);
///     }
/// }
/// ```
pub fn sphere_packing(seed: u64) -> Vec<Ball> {
    let mut state = seed ^ 0x5EED_0F5F_E7E5;
    let mut next = move || {
        state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut radii: Vec<f64> = (0..160).map(|_| 0.06 + 0.08 * next()).collect();
    radii.sort_by(|a, b| b.total_cmp(a));
    let mut balls: Vec<Ball> = Vec::new();
    for r in radii {
        for _ in 0..400 {
            let c = [next(), next(), next()];
            let free = balls.iter().all(|(d, q)| {
                let dist = (0..3).map(|k| (c[k] - d[k]).powi(2)).sum::<f64>().sqrt();
                dist >= r + q + 0.02
            });
            if free {
                balls.push((c, r));
                break;
            }
        }
    }
    balls
}

/// Packings already made, by seed: evaluating the sample point by point must not pack again.
fn packing(seed: u64) -> std::sync::Arc<Vec<Ball>> {
    use std::collections::HashMap;
    use std::sync::{Arc, Mutex, OnceLock};
    static MADE: OnceLock<Mutex<HashMap<u64, Arc<Vec<Ball>>>>> = OnceLock::new();
    let made = MADE.get_or_init(Default::default);
    let mut made = made.lock().unwrap_or_else(|e| e.into_inner());
    made.entry(seed)
        .or_insert_with(|| Arc::new(sphere_packing(seed)))
        .clone()
}

impl Sample {
    /// All samples (noise with seed 1), in documentation order.
    pub const ALL: [Sample; 9] = [
        Sample::Sphere,
        Sample::Torus,
        Sample::TwoTori,
        Sample::Tangle,
        Sample::Gyroid,
        Sample::SchwarzP,
        Sample::Hyperboloid,
        Sample::Tubes,
        Sample::Noise { seed: 1 },
    ];

    /// The name used in `sample:NAME:N`.
    pub fn name(self) -> &'static str {
        match self {
            Sample::Sphere => "sphere",
            Sample::Torus => "torus",
            Sample::TwoTori => "two-tori",
            Sample::Tangle => "tangle",
            Sample::Gyroid => "gyroid",
            Sample::SchwarzP => "schwarz-p",
            Sample::Hyperboloid => "hyperboloid",
            Sample::Tubes => "tubes",
            Sample::Noise { .. } => "noise",
            Sample::PackedSpheres { .. } => "packed-spheres",
        }
    }

    /// Default bounds: the cube `[lo, hi]^3`.
    pub fn bounds(self) -> (f64, f64) {
        match self {
            Sample::Sphere | Sample::Torus | Sample::TwoTori | Sample::Hyperboloid => (-1.0, 1.0),
            Sample::Tangle => (-3.0, 3.0),
            Sample::Gyroid => (-3.0, 3.0),
            Sample::SchwarzP => (-2.0 * PI, 2.0 * PI),
            Sample::Tubes => (-3.0 * PI, 3.0 * PI),
            Sample::Noise { .. } => (0.0, 4.0),
            Sample::PackedSpheres { .. } => (0.0, 1.0),
        }
    }

    /// Evaluates the function at a point.
    pub fn eval(self, p: [f64; 3]) -> f64 {
        let [x, y, z] = p;
        match self {
            Sample::Sphere => (x * x + y * y + z * z).sqrt() - 0.8,
            Sample::Torus => torus(x, y, z, 0.6, 0.25),
            Sample::TwoTori => {
                // Each circle passes through the other's centre; the tubes keep 0.2 apart.
                let a = torus(x + 0.25, y, z, 0.5, 0.15);
                let b = torus(x - 0.25, z, y, 0.5, 0.15);
                a.min(b)
            }
            Sample::Tangle => {
                x.powi(4) - 5.0 * x * x + y.powi(4) - 5.0 * y * y + z.powi(4) - 5.0 * z * z + 11.8
            }
            Sample::Gyroid => x.sin() * y.cos() + y.sin() * z.cos() + z.sin() * x.cos(),
            Sample::SchwarzP => x.cos() + y.cos() + z.cos(),
            Sample::Hyperboloid => x * x + y * y - z * z - 0.25,
            Sample::Tubes => {
                let (cx, cy, cz) = (x.cos(), y.cos(), z.cos());
                1.2 - (cy + cz).max(cz + cx).max(cx + cy)
            }
            Sample::Noise { seed } => {
                let mut sum = 0.0;
                let mut amplitude = 1.0;
                let mut frequency = 1.0;
                for octave in 0..3u64 {
                    sum += amplitude
                        * value_noise(seed.wrapping_add(octave), [x, y, z].map(|c| c * frequency));
                    amplitude *= 0.5;
                    frequency *= 2.0;
                }
                sum
            }
            Sample::PackedSpheres { seed } => packing(seed)
                .iter()
                .map(|(c, r)| {
                    ((x - c[0]).powi(2) + (y - c[1]).powi(2) + (z - c[2]).powi(2)).sqrt() - r
                })
                .fold(f64::INFINITY, f64::min),
        }
    }

    /// Samples the function on `n` points per axis over its default bounds.
    ///
    /// ```
    /// use isocube::field::Sample;
    /// let g = Sample::Sphere.grid(10);
    /// assert_eq!(g.dims(), [10, 10, 10]);
    /// assert!(g.value(0, 0, 0) > 0.0 && g.value(5, 5, 5) < 0.0);
    /// ```
    pub fn grid(self, n: usize) -> Grid {
        let (lo, hi) = self.bounds();
        let n = n.max(2);
        let h = (hi - lo) / (n - 1) as f64;
        Grid::from_fn([n; 3], [h; 3], [lo; 3], |p| self.eval(p)).with_exact(self)
    }
}

impl fmt::Display for Sample {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

fn torus(x: f64, y: f64, z: f64, major: f64, minor: f64) -> f64 {
    let q = (x * x + y * y).sqrt() - major;
    (q * q + z * z).sqrt() - minor
}

fn lattice_value(seed: u64, i: i64, j: i64, k: i64) -> f64 {
    // SplitMix64 over the packed lattice coordinates: cheap, well mixed, reproducible.
    let mut h = seed
        ^ (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ (j as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
        ^ (k as u64).wrapping_mul(0x1656_67B1_9E37_79F9);
    h = (h ^ (h >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    h = (h ^ (h >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    h ^= h >> 31;
    (h >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
}

fn value_noise(seed: u64, p: [f64; 3]) -> f64 {
    let cell = p.map(|c| c.floor());
    let t = [0, 1, 2].map(|a| {
        let f = p[a] - cell[a];
        f * f * (3.0 - 2.0 * f)
    });
    let c = cell.map(|c| c as i64);
    let mut sum = 0.0;
    for corner in 0..8 {
        let (dx, dy, dz) = (corner & 1, corner >> 1 & 1, corner >> 2 & 1);
        let w = [(dx, 0), (dy, 1), (dz, 2)]
            .iter()
            .map(|&(d, a)| if d == 1 { t[a] } else { 1.0 - t[a] })
            .product::<f64>();
        sum += w * lattice_value(seed, c[0] + dx, c[1] + dy, c[2] + dz);
    }
    sum
}

impl FromStr for Sample {
    type Err = crate::ParseError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Sample::ALL
            .iter()
            .copied()
            .chain([Sample::PackedSpheres { seed: 1 }])
            .find(|x| x.name() == s)
            .ok_or_else(|| {
                let mut names: Vec<&str> = Sample::ALL.iter().map(|x| x.name()).collect();
                names.push("packed-spheres");
                crate::ParseError::new(
                    "sample",
                    s,
                    format!("unknown sample '{s}': expected one of {}", names.join(", ")),
                )
            })
    }
}

/// A sample and its resolution, as written on the command line: `sample:NAME:N[:SEED]`.
///
/// ```
/// use isocube::field::{Sample, SampleSpec};
/// let s: SampleSpec = "sample:sphere:10".parse().unwrap();
/// assert_eq!((s.sample, s.n), (Sample::Sphere, 10));
/// assert!("sample:sphere:1".parse::<SampleSpec>().is_err());
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SampleSpec {
    /// The function.
    pub sample: Sample,
    /// Points per axis.
    pub n: usize,
}

impl SampleSpec {
    /// Largest accepted `N` (1024³ points, 4 GiB of values).
    pub const MAX_N: usize = 1024;

    /// Whether a volume argument names a sample rather than a file.
    pub fn is_sample(arg: &str) -> bool {
        arg.starts_with("sample:")
    }

    /// Samples the grid.
    pub fn grid(&self) -> Grid {
        self.sample.grid(self.n)
    }
}

impl fmt::Display for SampleSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.sample {
            Sample::Noise { seed } => write!(f, "sample:noise:{}:{seed}", self.n),
            Sample::PackedSpheres { seed } => {
                write!(f, "sample:packed-spheres:{}:{seed}", self.n)
            }
            s => write!(f, "sample:{}:{}", s.name(), self.n),
        }
    }
}

impl FromStr for SampleSpec {
    type Err = crate::ParseError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let rest = s.strip_prefix("sample:").ok_or_else(|| {
            crate::ParseError::new(
                "sample",
                s,
                format!("'{s}' is not of the form sample:NAME:N"),
            )
        })?;
        let parts: Vec<&str> = rest.split(':').collect();
        if parts.len() < 2 || parts.len() > 3 {
            return Err(crate::ParseError::new(
                "sample",
                s,
                format!("'{s}' is not of the form sample:NAME:N[:SEED]"),
            ));
        }
        let mut sample: Sample = parts[0].parse()?;
        let n: usize = parts[1].parse().map_err(|_| {
            crate::ParseError::new(
                "sample",
                s,
                format!("'{}' in '{s}' is not a whole number of points", parts[1]),
            )
        })?;
        if !(2..=Self::MAX_N).contains(&n) {
            return Err(crate::ParseError::new(
                "sample",
                s,
                format!(
                    "{n} points per axis in '{s}' is out of range (2 to {})",
                    Self::MAX_N
                ),
            ));
        }
        if let Some(seed) = parts.get(2) {
            let seed: u64 = seed.parse().map_err(|_| {
                crate::ParseError::new(
                    "sample",
                    s,
                    format!("seed '{seed}' in '{s}' is not a whole number"),
                )
            })?;
            match &mut sample {
                Sample::Noise { seed: s0 } | Sample::PackedSpheres { seed: s0 } => *s0 = seed,
                _ => {
                    return Err(crate::ParseError::new(
                        "sample",
                        s,
                        format!("only the noise and packed-spheres samples take a seed ('{s}')"),
                    ))
                }
            }
        }
        Ok(SampleSpec { sample, n })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn closed_samples_are_positive_on_the_boundary() {
        for s in [
            Sample::Sphere,
            Sample::Torus,
            Sample::TwoTori,
            Sample::Tangle,
        ] {
            let g = s.grid(33);
            let [nx, ny, nz] = g.dims();
            for k in 0..nz {
                for j in 0..ny {
                    for i in 0..nx {
                        let on_boundary =
                            i == 0 || j == 0 || k == 0 || i == nx - 1 || j == ny - 1 || k == nz - 1;
                        if on_boundary {
                            assert!(g.value(i, j, k) > 0.0, "{s} at {i},{j},{k}");
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn parse_round_trips() {
        for s in Sample::ALL {
            let spec = SampleSpec { sample: s, n: 17 };
            assert_eq!(spec.to_string().parse::<SampleSpec>().unwrap(), spec);
        }
        assert!("sample:cube:10".parse::<SampleSpec>().is_err());
        assert!("sample:sphere".parse::<SampleSpec>().is_err());
        assert!("sample:sphere:ten".parse::<SampleSpec>().is_err());
        assert!("sample:sphere:10:3".parse::<SampleSpec>().is_err());
        assert!("sample:sphere:100000".parse::<SampleSpec>().is_err());
        let n: SampleSpec = "sample:noise:8:42".parse().unwrap();
        assert_eq!(n.sample, Sample::Noise { seed: 42 });
    }

    #[test]
    fn noise_depends_on_seed_and_is_reproducible() {
        let a = Sample::Noise { seed: 1 }.grid(9);
        let b = Sample::Noise { seed: 1 }.grid(9);
        let c = Sample::Noise { seed: 2 }.grid(9);
        assert_eq!(a, b);
        assert_ne!(a, c);
        let (lo, hi) = a.finite_range().unwrap();
        assert!(lo < 0.0 && hi > 0.0);
    }
}
