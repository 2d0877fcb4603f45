//! How closely the mesh follows the contours: the built-in ore body at 20×20, 40×40 and 160×160,
//! exact fidelity against the section-data paper's plain approach. Prints the README's table.
//!
//! `cargo run --release -p isocube --example contours_fidelity`

use std::time::Instant;

use isocube::contours::{
    cut_distance, reconstruct_with, Cap, Fidelity, PlaneGrid, ReconstructOptions, SectionStack,
};

fn main() {
    let stack = SectionStack::sample_orebody();
    let (lo, hi, z) = stack.bounds();
    let diagonal =
        ((hi[0] - lo[0]).powi(2) + (hi[1] - lo[1]).powi(2) + (z[1] - z[0]).powi(2)).sqrt();
    println!("bounding-box diagonal {diagonal:.1}\n");
    println!("| grid | exact: cut ↔ contour | triangles, time | plain (paper): cut ↔ contour | triangles, time |");
    println!("|---|---:|---:|---:|---:|");
    for cells in [20, 40, 160] {
        let plane = PlaneGrid::across(&stack, cells);
        let mut cols = Vec::new();
        let mut note = String::new();
        for fidelity in [Fidelity::Exact, Fidelity::Plain] {
            let options = ReconstructOptions::new(Cap::Extend(6.0)).with_fidelity(fidelity);
            let started = Instant::now();
            let r = reconstruct_with(&stack, &plane, &options).expect("reconstructs");
            let ms = started.elapsed().as_secs_f64() * 1e3;
            let rep = r.mesh.report();
            assert!(
                rep.watertight && rep.oriented && rep.genus == Some(1),
                "{rep:?}"
            );
            if r.plane != plane {
                let scale = r.plane.spacing / plane.spacing;
                note = format!(
                    " (a grid with {:.0} % smaller cells used)",
                    100.0 * (1.0 - scale)
                );
            }
            let d = cut_distance(&r.mesh, &stack);
            let fmt = |x: f64| {
                if x < 1e-3 {
                    format!("{x:.1e}")
                } else {
                    format!("{x:.3}")
                }
            };
            cols.push(format!(
                "{} / {} | {}, {ms:.0} ms",
                fmt(d.contour_to_cut),
                fmt(d.cut_to_contour),
                rep.triangles
            ));
        }
        println!("| {cells}×{cells}{note} | {} | {} |", cols[0], cols[1]);
    }
}
