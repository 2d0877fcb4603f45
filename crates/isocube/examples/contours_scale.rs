//! Contour reconstruction at the scale of a real section survey, and how its cost grows.
//!
//! The stack: 200 unevenly spaced sections, each with four 2 000-point contours (lobes whose
//! shape drifts from section to section). Three tables:
//! 1. the benchmark itself: a 512 × 512 plane grid, plain and exact fidelity;
//! 2. the same contours and cell size on grids padded with empty space to 4× and 16× the points:
//!    the cells the contours cross do not change, and neither does the time;
//! 3. grids of 128, 256 and 512 cells across: the crossed cells grow about linearly with the
//!    resolution while the grid grows with its square; the time follows the crossed cells.
//!
//! `cargo run --release -p isocube --example contours_scale [-- --quick]` (`--quick`: 40
//! sections, for CI).

use std::time::Instant;

use isocube::contours::{
    reconstruct_with, Cap, Fidelity, PlaneGrid, ReconstructOptions, Reconstruction, SectionStack,
};

fn survey(sections: usize, points: usize) -> SectionStack {
    let stack: Vec<(f64, Vec<Vec<[f64; 2]>>)> = (0..sections)
        .map(|k| {
            let z = k as f64 + 0.3 * (k as f64 * 0.7).sin();
            let lobes = [(-40.0, -40.0), (40.0, -40.0), (-40.0, 40.0), (40.0, 40.0)];
            let contours = lobes
                .iter()
                .enumerate()
                .map(|(l, &(cx, cy))| {
                    (0..points)
                        .map(|i| {
                            let a = 2.0 * std::f64::consts::PI * i as f64 / points as f64;
                            let r = 25.0
                                + 5.0 * (3.0 * a + 0.05 * k as f64 + l as f64).sin()
                                + 2.0 * (7.0 * a - 0.03 * k as f64).cos();
                            [cx + r * a.cos(), cy + r * a.sin()]
                        })
                        .collect()
                })
                .collect();
            (z, contours)
        })
        .collect();
    SectionStack::from_points(stack).expect("valid stack")
}

fn run(stack: &SectionStack, plane: &PlaneGrid, fidelity: Fidelity) -> (f64, Reconstruction) {
    let options = ReconstructOptions::new(Cap::Extend(0.5)).with_fidelity(fidelity);
    let started = Instant::now();
    let r = reconstruct_with(stack, plane, &options).expect("reconstructs");
    (started.elapsed().as_secs_f64(), r)
}

fn row(label: &str, fidelity: Fidelity, seconds: f64, r: &Reconstruction) {
    let rep = r.mesh.report();
    assert!(rep.watertight && rep.oriented, "{label}: {rep:?}");
    println!(
        "| {label} | {fidelity:?} | {}×{} | {:.1} M | {} | {} | {:.2} | {} | {:.0} |",
        r.plane.dims[0],
        r.plane.dims[1],
        r.points as f64 / 1e6,
        r.active_cells,
        r.evaluated,
        seconds,
        rep.triangles,
        seconds * 1e9 / r.active_cells as f64,
    );
}

fn header() {
    println!("| grid | fidelity | plane points | grid points | active cells | distances | seconds | triangles | ns per active cell |");
    println!("|---|---|---|---|---|---|---|---|---|");
}

fn main() {
    let quick = std::env::args().any(|a| a == "--quick");
    let sections = if quick { 40 } else { 200 };
    let started = Instant::now();
    let stack = survey(sections, 2000);
    println!(
        "{sections} sections × 4 contours × 2 000 points, validated in {:.0} ms, {} threads\n",
        started.elapsed().as_secs_f64() * 1e3,
        rayon::current_num_threads()
    );

    println!("Benchmark: 512 cells across\n");
    header();
    let plane = PlaneGrid::across(&stack, 512);
    for fidelity in [Fidelity::Plain, Fidelity::Exact] {
        let (t, r) = run(&stack, &plane, fidelity);
        row("512 across", fidelity, t, &r);
    }

    println!("\nSame cells, more empty grid around them\n");
    header();
    let base = PlaneGrid::across(&stack, 256);
    for factor in [1usize, 2, 4] {
        let plane = base.padded(factor);
        let (t, r) = run(&stack, &plane, Fidelity::Exact);
        row(
            &format!("256 across, padded ×{factor}"),
            Fidelity::Exact,
            t,
            &r,
        );
    }

    println!("\nFiner grids\n");
    header();
    for cells in [128, 256, 512] {
        let plane = PlaneGrid::across(&stack, cells);
        for fidelity in [Fidelity::Plain, Fidelity::Exact] {
            let (t, r) = run(&stack, &plane, fidelity);
            row(&format!("{cells} across"), fidelity, t, &r);
        }
    }
}
