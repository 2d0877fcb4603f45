//! Times Catmull–Clark on a 30 000-quad torus, two levels (issue 7's benchmark).
//!
//! `cargo run --release -p isocube --example subdiv_scale`

use std::time::Instant;

use isocube::subdiv::samples::torus;
use isocube::subdiv::{subdivide, SubdivOptions};

fn main() {
    let m = torus(200, 150, false);
    let mut best = f64::INFINITY;
    let mut faces = 0;
    for _ in 0..10 {
        let t = Instant::now();
        let fine = subdivide(&m, 2, &SubdivOptions::default()).expect("subdivides");
        best = best.min(t.elapsed().as_secs_f64());
        faces = fine.faces.len();
    }
    println!(
        "{} quads, 2 levels → {faces} quads: {:.1} ms (best of 10, {} threads)",
        m.faces.len(),
        best * 1e3,
        rayon::current_num_threads()
    );
}
