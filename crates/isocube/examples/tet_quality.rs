//! Prints the volume-mesh quality table: dihedral angles and radius ratios of `tetmesh` for
//! Marching Cubes and ternary extraction (snapped points on their grid points, or on
//! crossings) at two snap distances, on the sphere, torus, tangle and packed spheres at 24, 40
//! and 64 points per axis, each sampled on grids moved by random sub-cell offsets (the worst
//! over the offsets).
//!
//! The last column is the sharpest edge of the region's boundary (the worst over the
//! offsets): no mesh keeping that boundary has a larger smallest dihedral angle.
//!
//! `cargo run --release -p isocube --example tet_quality [OFFSETS [SAMPLE]]`: SAMPLE (e.g.
//! `packed`) keeps the rows of samples whose name starts with it; the offsets are the same
//! as in the whole table. Refusals are printed to stderr with their reason.

use isocube::extract::{ExtractOptions, Method, SnapPosition, Snapping};
use isocube::field::{Grid, Sample};
use isocube::volume::{tetmesh, TetReport};

fn main() {
    let offsets: usize = std::env::args()
        .nth(1)
        .map_or(3, |s| s.parse().expect("a number of offsets"));
    let only = std::env::args().nth(2).unwrap_or_default();
    let samples = [
        Sample::Sphere,
        Sample::Torus,
        Sample::Tangle,
        Sample::PackedSpheres { seed: 1 },
    ];
    let methods: [(&str, ExtractOptions); 5] = [
        ("mc", ExtractOptions::default()),
        ("ternary 0.3", ternary(0.3, SnapPosition::GridPoint)),
        ("ternary 0.5", ternary(0.5, SnapPosition::GridPoint)),
        (
            "ternary 0.3 crossing",
            ternary(0.3, SnapPosition::NearestCrossing),
        ),
        (
            "ternary 0.5 crossing",
            ternary(0.5, SnapPosition::NearestCrossing),
        ),
    ];
    println!(
        "| sample | N | method | tetrahedra | min dihedral | max dihedral | outside [10°, 165°] | \
         radius ratio mean | radius ratio worst | sharpest boundary edge |"
    );
    println!("|---|---:|---|---:|---:|---:|---:|---:|---:|---:|");
    let mut state = 0x9e37_79b9_7f4a_7c15_u64;
    for sample in samples {
        for n in [24, 40, 64] {
            let shifts: Vec<[f64; 3]> = (0..offsets)
                .map(|_| std::array::from_fn(|_| unit(&mut state)))
                .collect();
            if !sample.name().starts_with(&only) {
                continue;
            }
            for (name, options) in &methods {
                let mut worst: Option<(TetReport, usize)> = None;
                let mut refused = 0;
                let mut tets = 0;
                let mut outside = 0;
                let mut sharpest = f64::INFINITY;
                for shift in &shifts {
                    let grid = shifted(sample, n, *shift);
                    let mesh = match tetmesh(&grid, options) {
                        Ok(mesh) => mesh,
                        Err(e) => {
                            eprintln!("{sample:?} {n} {name} {shift:?}: {e}");
                            refused += 1;
                            continue;
                        }
                    };
                    if let Some(e) = mesh.sharpest_boundary_edge() {
                        sharpest = sharpest.min(e.angle);
                    }
                    let qualities = mesh.qualities();
                    let report = TetReport::of(&qualities);
                    tets += report.tets;
                    outside += qualities
                        .iter()
                        .filter(|q| q.min_dihedral < 10.0 || q.max_dihedral > 165.0)
                        .count();
                    let mean_weight = report.tets;
                    worst = Some(match worst {
                        None => (report, mean_weight),
                        Some((w, count)) => (
                            TetReport {
                                min_dihedral: w.min_dihedral.min(report.min_dihedral),
                                max_dihedral: w.max_dihedral.max(report.max_dihedral),
                                max_radius_ratio: w.max_radius_ratio.max(report.max_radius_ratio),
                                mean_radius_ratio: (w.mean_radius_ratio * count as f64
                                    + report.mean_radius_ratio * mean_weight as f64)
                                    / (count + mean_weight) as f64,
                                ..w
                            },
                            count + mean_weight,
                        ),
                    });
                }
                let refusals = if refused > 0 {
                    format!(" ({refused} of {offsets} refused)")
                } else {
                    String::new()
                };
                match worst {
                    Some((w, _)) => println!(
                        "| {sample} | {n} | {name}{refusals} | {} | {:.2}° | {:.2}° | {:.4} % | {:.3} | {:.1} | {:.2}° |",
                        tets / (offsets - refused),
                        w.min_dihedral,
                        w.max_dihedral,
                        100.0 * outside as f64 / tets as f64,
                        w.mean_radius_ratio,
                        w.max_radius_ratio,
                        sharpest
                    ),
                    None => println!("| {sample} | {n} | {name} | refused | | | | | | |"),
                }
            }
        }
    }
}

fn ternary(snap: f32, position: SnapPosition) -> ExtractOptions {
    ExtractOptions::default().with_method(Method::Ternary(
        Snapping::default().with_snap(snap).with_position(position),
    ))
}

/// The sample on `n` points per axis over its bounds, the grid moved by `shift` cells.
fn shifted(sample: Sample, n: usize, shift: [f64; 3]) -> Grid {
    let (lo, hi) = sample.bounds();
    let h = (hi - lo) / (n - 1) as f64;
    let origin = shift.map(|s| lo + (s - 0.5) * h);
    Grid::from_fn([n; 3], [h; 3], origin, |p| sample.eval(p))
}

/// A uniform number in [0, 1) (SplitMix64).
fn unit(state: &mut u64) -> f64 {
    *state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^= z >> 31;
    (z >> 11) as f64 / (1u64 << 53) as f64
}
