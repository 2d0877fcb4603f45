//! Catmull–Clark refinement speed: a 30 000-quad torus (200 × 150) refined two levels (to
//! 480 000 quads), as in issue 7's benchmark, and one level; plus a 30 000-triangle torus.
//!
//! `cargo bench -p isocube --bench subdiv`.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use isocube::subdiv::samples::torus;
use isocube::subdiv::{subdivide, SubdivOptions};

fn refine(c: &mut Criterion) {
    let mut group = c.benchmark_group("subdivide");
    group.sample_size(10);
    for (name, mesh) in [
        ("quads-30000", torus(200, 150, false)),
        ("triangles-30000", torus(150, 100, true)),
    ] {
        group.throughput(Throughput::Elements(mesh.faces.len() as u64));
        for levels in [1, 2] {
            group.bench_with_input(BenchmarkId::new(name, levels), &mesh, |b, mesh| {
                b.iter(|| subdivide(mesh, levels, &SubdivOptions::default()).unwrap())
            });
        }
    }
    group.finish();
}

criterion_group!(benches, refine);
criterion_main!(benches);
