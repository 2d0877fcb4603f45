//! The topology oracle: the truth about the trilinear interpolant's isosurface, from refinement.
//!
//! Refining a grid k× per axis (trilinear interpolation) and extracting the fine grid gives a
//! surface whose cells are so small that no ambiguity is left to resolve, except where the field
//! is within a rounding error of a degenerate configuration. Where k = 16 and k = 32 agree on
//! components and Euler characteristic, that is taken as the truth ("stable" trial); MC33 on the
//! coarse grid must match it every time.

use isocube::cube::{CaseTable, Topology};
use isocube::extract::{extract, ExtractOptions};
use isocube::field::Grid;
use isocube::mesh::MeshReport;

mod common;

use common::{Rng, GRID_INDEX};

/// `ISOCUBE_ORACLE_SCALE=N` multiplies the trial counts (for long campaigns in release builds).
fn scale() -> usize {
    std::env::var("ISOCUBE_ORACLE_SCALE")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1)
}

fn report(grid: &Grid, topology: Topology) -> MeshReport {
    let (mesh, _) = extract(
        grid,
        &ExtractOptions::default()
            .with_topology(topology)
            .with_normals(false),
    )
    .unwrap();
    mesh.report()
}

fn refined(grid: &Grid, k: usize) -> (usize, i64) {
    let r = report(&grid.upsample(k), Topology::Classic);
    (r.components, r.euler)
}

/// The truth where k = 16 and 32 agree. A feature thinner than 1/32 of a cell (values within
/// about 1e-8 of the level beside values of order 1) can fool both alike; so when MC33 disagrees
/// with them, finer refinements are asked in turn (k = 64, 128, … up to `max_k`) and the first
/// two consecutive ones that agree are the truth. Returns the truth and whether the finer
/// refinements were needed.
fn truth(grid: &Grid, mc33: (usize, i64), max_k: usize) -> Option<((usize, i64), bool)> {
    let (a, b) = (refined(grid, 16), refined(grid, 32));
    if a != b {
        return None;
    }
    if a == mc33 {
        return Some((a, false));
    }
    let mut k = 64;
    let mut previous = refined(grid, k);
    while k < max_k {
        k *= 2;
        let next = refined(grid, k);
        if next == previous {
            return Some((next, true));
        }
        previous = next;
    }
    Some((a, false))
}

/// Values for one cell: uniform, or with signs forced to a configuration that can open a
/// tunnel (so the interior test is exercised often).
fn random_cell(rng: &mut Rng, ambiguous: &[u8]) -> Vec<f32> {
    if rng.next() % 4 == 0 {
        return (0..8).map(|_| rng.signed()).collect();
    }
    let config = ambiguous[(rng.next() % ambiguous.len() as u64) as usize];
    // Skewing one sign's magnitudes toward zero moves saddles across the level, which is where
    // tunnels open and close.
    let powers = [0.25f32, 0.5, 1.0, 2.0, 4.0, 8.0];
    let above_power = powers[(rng.next() % 6) as usize];
    let below_power = powers[(rng.next() % 6) as usize];
    (0..8)
        .map(|g| {
            let m = rng.unit();
            if config >> GRID_INDEX[g] & 1 == 1 {
                m.powf(above_power)
            } else {
                -m.powf(below_power)
            }
        })
        .collect()
}

fn tunnel_configs() -> Vec<u8> {
    let table = CaseTable::binary();
    (0..=255u8)
        .filter(|&c| {
            isocube::cube::polygons::decision_patterns(c).any(|d| table.has_tunnel_candidates(c, d))
        })
        .collect()
}

#[test]
fn mc33_matches_the_refined_truth_on_random_cells() {
    let ambiguous = tunnel_configs();
    let mut rng = Rng(0x5EED_0001 + scale() as u64);
    let (mut stable, mut differs_from_classic, mut tunnels, mut needed_finer) = (0, 0, 0, 0);
    for trial in 0..5_000 * scale() {
        let values = random_cell(&mut rng, &ambiguous);
        let grid = Grid::new([2, 2, 2], values.clone()).unwrap();
        let (mesh, stats) = extract(&grid, &ExtractOptions::default()).unwrap();
        let r = mesh.report();
        assert_eq!(r.nonmanifold_edges, 0, "trial {trial}: {values:?}");
        assert!(r.oriented, "trial {trial}: {values:?}");
        tunnels += stats.tunnels;
        let Some((expected, finer)) = truth(&grid, (r.components, r.euler), 512) else {
            continue;
        };
        stable += 1;
        needed_finer += usize::from(finer);
        assert_eq!(
            (r.components, r.euler),
            expected,
            "trial {trial}: values {values:?}"
        );
        if report(&grid, Topology::Classic).euler != r.euler {
            differs_from_classic += 1;
        }
    }
    assert!(stable >= 4_000, "only {stable} stable trials");
    assert!(
        tunnels > 50 && differs_from_classic > 50,
        "{tunnels} tunnels, {differs_from_classic} differ from classic"
    );
    println!(
        "{stable} stable single cells, {tunnels} tunnels, {differs_from_classic} differ from classic MC, \
         {needed_finer} needed finer refinement"
    );
}

#[test]
fn mc33_matches_the_refined_truth_on_random_closed_grids() {
    let mut rng = Rng(0x5EED_0002 + scale() as u64);
    let (mut stable, mut tunnels, mut needed_finer) = (0, 0, 0);
    for trial in 0..240 * scale() {
        let n = 6;
        let values: Vec<f32> = (0..n * n * n)
            .map(|i| {
                let (x, y, z) = (i % n, i / n % n, i / (n * n));
                let boundary = [x, y, z].iter().any(|&c| c == 0 || c == n - 1);
                if boundary {
                    -1.0
                } else {
                    rng.signed()
                }
            })
            .collect();
        let grid = Grid::new([n; 3], values).unwrap();
        let (mesh, stats) = extract(&grid, &ExtractOptions::default()).unwrap();
        let r = mesh.report();
        tunnels += stats.tunnels;
        assert!(
            r.watertight && r.oriented && r.nonmanifold_edges == 0,
            "trial {trial}: {r:?}"
        );
        let Some((expected, finer)) = truth(&grid, (r.components, r.euler), 128) else {
            continue;
        };
        stable += 1;
        needed_finer += usize::from(finer);
        assert_eq!((r.components, r.euler), expected, "trial {trial}");
    }
    assert!(stable >= 200, "only {stable} stable trials");
    assert!(tunnels > 0);
    println!(
        "{stable} stable 6x6x6 grids, {tunnels} tunnels, {needed_finer} needed finer refinement"
    );
}
