//! Prints the triangle-quality table of classic Marching Cubes, MC33 and ternary extraction at
//! several snap distances on built-in samples (the table in the README).
//!
//! `cargo run --release --example ternary_quality`

use isocube::cube::Topology;
use isocube::extract::{extract, ExtractOptions, Method, SnapPosition, Snapping};
use isocube::field::Sample;
use isocube::quality::{level_set_distance, quality_report};

fn main() {
    let cases = [
        (Sample::Sphere, 10),
        (Sample::Sphere, 40),
        (Sample::Torus, 64),
        (Sample::Gyroid, 64),
    ];
    let methods: [(&str, ExtractOptions); 8] = [
        (
            "classic MC",
            ExtractOptions::default().with_topology(Topology::Classic),
        ),
        ("MC33", ExtractOptions::default()),
        ("ternary D=0.1", ternary(0.1, SnapPosition::NearestCrossing)),
        ("ternary D=0.3", ternary(0.3, SnapPosition::NearestCrossing)),
        ("ternary D=0.5", ternary(0.5, SnapPosition::NearestCrossing)),
        ("ternary D=0.1, grid", ternary(0.1, SnapPosition::GridPoint)),
        ("ternary D=0.3, grid", ternary(0.3, SnapPosition::GridPoint)),
        ("ternary D=0.5, grid", ternary(0.5, SnapPosition::GridPoint)),
    ];
    println!(
        "| sample | method | triangles | min angle | max angle | < 10° | < 20° | max distance |"
    );
    println!("|---|---|---:|---:|---:|---:|---:|---:|");
    for (sample, n) in cases {
        let grid = sample.grid(n);
        for (name, options) in &methods {
            let (mesh, _) = extract(&grid, options).expect("samples extract");
            let a = quality_report(&mesh);
            let d = level_set_distance(&mesh, |p| sample.eval(p), 0.0, grid.spacing()[0]);
            println!(
                "| {sample}:{n} | {name} | {} | {:.2}° | {:.2}° | {:.2} % | {:.2} % | {:.4} |",
                mesh.triangle_count(),
                a.min_angle.min,
                a.max_angle.max,
                100.0 * a.below[0],
                100.0 * a.below[1],
                d.max
            );
        }
    }
}

fn ternary(snap: f32, position: SnapPosition) -> ExtractOptions {
    ExtractOptions::default().with_method(Method::Ternary(
        Snapping::default().with_snap(snap).with_position(position),
    ))
}
