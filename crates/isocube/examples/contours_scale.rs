//! Times contour reconstruction at the scale of issue 6's benchmark: 200 sections of four
//! 2 000-point contours on a 512 × 512 plane grid, and the same stack on grids of 128 and 256
//! cells, to show how the cost follows the cells the contours cross.
//!
//! `cargo run --release -p isocube --example contours_scale`

use std::time::Instant;

use isocube::contours::{reconstruct_with, Cap, Fidelity, PlaneGrid, SectionStack};

fn main() {
    let n = 2000;
    let sections: Vec<(f64, Vec<Vec<[f64; 2]>>)> = (0..200)
        .map(|k| {
            let z = k as f64 * 1.0 + 0.3 * (k as f64 * 0.7).sin();
            let lobes = [(-40.0, -40.0), (40.0, -40.0), (-40.0, 40.0), (40.0, 40.0)];
            let contours = lobes
                .iter()
                .enumerate()
                .map(|(l, &(cx, cy))| {
                    (0..n)
                        .map(|i| {
                            let a = 2.0 * std::f64::consts::PI * i as f64 / n as f64;
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
    let started = Instant::now();
    let stack = SectionStack::from_points(sections).expect("valid stack");
    println!(
        "validation: {:.0} ms",
        started.elapsed().as_secs_f64() * 1e3
    );
    for cells in [128, 256, 512] {
        for fidelity in [Fidelity::Plain, Fidelity::Exact] {
            let plane = PlaneGrid::across(&stack, cells);
            let t = Instant::now();
            let r =
                reconstruct_with(&stack, &plane, Cap::Extend(0.5), fidelity).expect("reconstructs");
            let rep = r.mesh.report();
            println!(
                "{cells:>4} cells {fidelity:?}: {:.0} ms, {} triangles, watertight {}, distance at {} of {} points ({:.1} %), {} active cells",
                t.elapsed().as_secs_f64() * 1e3,
                rep.triangles,
                rep.watertight,
                r.evaluated,
                r.points,
                100.0 * r.evaluated as f64 / r.points as f64,
                r.active_cells
            );
        }
    }
}
