//! Contour reconstruction throughput on the built-in ore body, exact against plain fidelity, and
//! the same body on a grid padded with empty space (the time should not change: only the cells
//! the surface crosses are visited).
//!
//! `cargo bench -p isocube --bench contours`. Each case is labelled `fidelity/grid` and reports
//! active cells per second. The full-scale survey (200 sections × 4 × 2 000 points on 512 × 512)
//! is the `contours_scale` example.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use isocube::contours::{
    reconstruct_with, Cap, Fidelity, PlaneGrid, ReconstructOptions, SectionStack,
};

fn orebody(c: &mut Criterion) {
    let stack = SectionStack::sample_orebody();
    let mut group = c.benchmark_group("contours");
    group.sample_size(20);
    for (label, plane) in [
        ("40".to_string(), PlaneGrid::across(&stack, 40)),
        ("160".to_string(), PlaneGrid::across(&stack, 160)),
        (
            "160-padded-x4".to_string(),
            PlaneGrid::across(&stack, 160).padded(4),
        ),
    ] {
        for fidelity in [Fidelity::Plain, Fidelity::Exact] {
            let options = ReconstructOptions::new(Cap::Extend(6.0)).with_fidelity(fidelity);
            let active = reconstruct_with(&stack, &plane, &options)
                .expect("reconstructs")
                .active_cells;
            group.throughput(Throughput::Elements(active as u64));
            group.bench_with_input(
                BenchmarkId::new(format!("{fidelity:?}").to_lowercase(), &label),
                &plane,
                |b, plane| {
                    b.iter(|| reconstruct_with(&stack, plane, &options).expect("reconstructs"))
                },
            );
        }
    }
    group.finish();
}

criterion_group!(benches, orebody);
criterion_main!(benches);
