//! Extraction throughput: MC33 against classic Marching Cubes on the built-in samples, then the
//! other methods against the default on one sample (local and optimal triangulation, ternary,
//! slab-wise streaming into memory).
//!
//! `cargo bench -p isocube --bench extract` (add `-- --quick` for a short run). Each case is
//! labelled `topology/sample/N` or `method/sample/N` and reports cells per second; the output
//! mesh is reused between iterations so allocation is not timed (except when streaming).

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use isocube::cube::Topology;
use isocube::extract::{extract_into, extract_streamed, ExtractOptions, Method};
use isocube::field::Sample;
use isocube::mesh::Mesh;
use isocube::quality::Strategy;

fn topologies(c: &mut Criterion) {
    let mut group = c.benchmark_group("extract");
    group.sample_size(20);
    for sample in [
        Sample::Sphere,
        Sample::Torus,
        Sample::Tangle,
        Sample::Gyroid,
        Sample::SchwarzP,
        Sample::Noise { seed: 1 },
    ] {
        let n = 128;
        let grid = sample.grid(n);
        group.throughput(Throughput::Elements(grid.cell_count() as u64));
        for topology in [Topology::Classic, Topology::Mc33] {
            let options = ExtractOptions::default().with_topology(topology);
            let mut mesh = Mesh::new();
            // Warm the output buffers and the case table.
            extract_into(&grid, &options, &mut mesh, &mut isocube::no_progress).unwrap();
            group.bench_with_input(
                BenchmarkId::new(topology.name(), format!("{sample}/{n}")),
                &grid,
                |b, grid| {
                    b.iter(|| {
                        extract_into(grid, &options, &mut mesh, &mut isocube::no_progress).unwrap()
                    })
                },
            );
        }
    }
    group.finish();
}

fn methods(c: &mut Criterion) {
    let mut group = c.benchmark_group("methods");
    group.sample_size(10);
    let n = 128;
    let sample = Sample::Tangle;
    let grid = sample.grid(n);
    group.throughput(Throughput::Elements(grid.cell_count() as u64));
    let default = ExtractOptions::default();
    for (name, options) in [
        ("default", default),
        ("local", default.with_triangulation(Strategy::Local)),
        ("optimal", default.with_triangulation(Strategy::Optimal)),
        (
            "ternary",
            default.with_method(Method::Ternary(Default::default())),
        ),
    ] {
        let mut mesh = Mesh::new();
        extract_into(&grid, &options, &mut mesh, &mut isocube::no_progress).unwrap();
        group.bench_with_input(
            BenchmarkId::new(name, format!("{sample}/{n}")),
            &grid,
            |b, grid| {
                b.iter(|| {
                    extract_into(grid, &options, &mut mesh, &mut isocube::no_progress).unwrap()
                })
            },
        );
    }
    group.bench_with_input(
        BenchmarkId::new("streamed", format!("{sample}/{n}")),
        &grid,
        |b, grid| {
            b.iter(|| {
                let mut mesh = Mesh::new();
                extract_streamed(grid, &default, &mut mesh, &mut isocube::no_progress).unwrap();
                mesh
            })
        },
    );
    group.finish();
}

criterion_group!(benches, topologies, methods);
criterion_main!(benches);
