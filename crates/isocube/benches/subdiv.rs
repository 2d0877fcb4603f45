//! Catmull–Clark refinement speed: a 30 000-quad torus (200 × 150) refined two levels (to
//! 480 000 quads), as in issue 7's benchmark, and one level; plus a 30 000-triangle torus.
//!
//! `cargo bench -p isocube --bench subdiv`.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use isocube::subdiv::{subdivide, Face, PolyMesh, SubdivOptions};

/// A torus of `nu × nv` quads, or twice as many triangles.
fn torus(nu: usize, nv: usize, triangles: bool) -> PolyMesh {
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
            let q = [at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)];
            if triangles {
                m.faces.push(Face::new(vec![q[0], q[1], q[2]]));
                m.faces.push(Face::new(vec![q[0], q[2], q[3]]));
            } else {
                m.faces.push(Face::new(q.to_vec()));
            }
        }
    }
    m
}

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
