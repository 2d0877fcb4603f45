//! isocube's side of the peer benchmark (`bench/peers/`): for each `.npy` volume (`a[z, y, x]`,
//! x fastest), the time of a plain read of its values (the memory-bandwidth floor) and of
//! extraction alone, best of several runs, as one JSON object per line.
//!
//! `cargo run --release -p isocube-io --example peer_timing -- LEVEL:FILE.npy …`

use std::path::Path;
use std::time::Instant;

use isocube::extract::{extract_into, ExtractOptions};
use isocube::mesh::Mesh;
use isocube_io::{read_npy, NpyAxes};
use rayon::prelude::*;

// The same allocator as the `isocube` command.
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn best(runs: usize, mut f: impl FnMut()) -> f64 {
    (0..runs)
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64() * 1e3
        })
        .fold(f64::INFINITY, f64::min)
}

fn main() {
    for arg in std::env::args().skip(1) {
        let (level, path) = arg.split_once(':').expect("LEVEL:FILE.npy");
        let level: f32 = level.parse().expect("a level");
        let grid = read_npy(Path::new(path), NpyAxes::Zyx).expect("a volume");
        // The floor: every value read once, on all threads as extraction does (summed so the
        // read cannot be skipped).
        let mut sum = 0.0f64;
        let read_ms = best(5, || {
            sum = grid
                .values()
                .par_chunks(1 << 16)
                .map(|c| c.iter().map(|&v| f64::from(v)).sum::<f64>())
                .sum();
        });
        let options = ExtractOptions::default()
            .with_level(level)
            .with_normals(false);
        let mut mesh = Mesh::new();
        let extract_ms = best(7, || {
            extract_into(&grid, &options, &mut mesh, &mut isocube::no_progress).expect("extracts");
        });
        println!(
            "{{\"path\": \"{path}\", \"read_ms\": {read_ms:.3}, \"extract_ms\": {extract_ms:.3}, \"triangles\": {}, \"vertices\": {}, \"threads\": {}, \"checksum\": {sum:e}}}",
            mesh.triangles.len(),
            mesh.positions.len(),
            rayon::current_num_threads()
        );
    }
}
