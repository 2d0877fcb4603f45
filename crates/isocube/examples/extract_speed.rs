//! Times extraction alone (grid already in memory) on built-in samples, best of several runs.
//!
//! `cargo run --release -p isocube --example extract_speed -- [sample:tangle:256 …] [--normals]
//! [--local | --optimal] [--ternary]`

use std::time::Instant;

use isocube::extract::{extract_into, ExtractOptions};
use isocube::field::SampleSpec;
use isocube::mesh::Mesh;
use isocube::quality::Strategy;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let normals = args.iter().any(|a| a == "--normals");
    let specs: Vec<String> = args
        .iter()
        .filter(|a| !a.starts_with("--"))
        .cloned()
        .collect();
    let specs = if specs.is_empty() {
        vec![
            "sample:tangle:256".to_string(),
            "sample:sphere:256".into(),
            "sample:gyroid:256".into(),
        ]
    } else {
        specs
    };
    let mut options = ExtractOptions::default().with_normals(normals);
    for (flag, strategy) in [
        ("--local", Strategy::Local),
        ("--optimal", Strategy::Optimal),
    ] {
        if args.iter().any(|a| a == flag) {
            options = options.with_triangulation(strategy);
        }
    }
    if args.iter().any(|a| a == "--ternary") {
        options = options.with_method(isocube::extract::Method::Ternary(Default::default()));
    }
    for spec in specs {
        let spec: SampleSpec = spec.parse().expect("a sample");
        let grid = spec.grid();
        let mut mesh = Mesh::new();
        let mut best = f64::INFINITY;
        let runs = if args.iter().any(|a| a == "--long") {
            60
        } else {
            7
        };
        for _ in 0..runs {
            let t = Instant::now();
            extract_into(&grid, &options, &mut mesh, &mut isocube::no_progress).expect("extracts");
            best = best.min(t.elapsed().as_secs_f64());
        }
        println!(
            "{spec}: {:.1} ms, {} triangles ({} threads, normals {normals})",
            best * 1e3,
            mesh.triangles.len(),
            rayon::current_num_threads()
        );
    }
}
