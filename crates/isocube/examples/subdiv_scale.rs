//! Times Catmull–Clark on a 30 000-quad torus, two levels (issue 7's benchmark).
//!
//! `cargo run --release -p isocube --example subdiv_scale`

use std::time::Instant;

use isocube::subdiv::{subdivide, Face, PolyMesh, SubdivOptions};

fn main() {
    let (nu, nv) = (200, 150);
    let mut m = PolyMesh::default();
    for i in 0..nu {
        for j in 0..nv {
            let (u, v) = (
                2.0 * std::f64::consts::PI * i as f64 / nu as f64,
                2.0 * std::f64::consts::PI * j as f64 / nv as f64,
            );
            let r = 3.0 + v.cos();
            m.positions.push([r * u.cos(), r * u.sin(), v.sin()]);
        }
    }
    let at = |i: usize, j: usize| ((i % nu) * nv + j % nv) as u32;
    for i in 0..nu {
        for j in 0..nv {
            m.faces.push(Face::new(vec![
                at(i, j),
                at(i + 1, j),
                at(i + 1, j + 1),
                at(i, j + 1),
            ]));
        }
    }
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
