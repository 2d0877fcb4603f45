use proptest::prelude::*;
use proptest::strategy::Strategy;

use super::ternary::without_lone_ties;
use super::*;
use crate::cube::Topology;
use crate::extract::{Method, SnapPosition, Snapping};
use crate::field::Sample;
use crate::mesh::MeshReport;

fn run(grid: &Grid, level: f32) -> (Mesh, ExtractStats) {
    extract(grid, &ExtractOptions::default().with_level(level)).unwrap()
}

fn signed_volume(mesh: &Mesh) -> f64 {
    mesh.triangles
        .iter()
        .map(|t| {
            let p = t.map(|v| mesh.positions[v as usize].map(f64::from));
            let c = crate::mesh::cross(p[1], p[2]);
            crate::mesh::dot(p[0], c) / 6.0
        })
        .sum()
}

#[test]
fn sphere_at_ten_points_has_524_triangles() {
    let (mesh, stats) = run(&Sample::Sphere.grid(10), 0.0);
    assert_eq!(mesh.triangle_count(), 524);
    let r = mesh.report();
    assert!(r.watertight && r.oriented);
    assert_eq!((r.components, r.euler, r.genus), (1, 2, Some(0)));
    assert_eq!(stats.skipped_cells, 0);
}

#[test]
fn normals_and_winding_point_toward_increasing_values() {
    let grid = Sample::Sphere.grid(24);
    let (mesh, _) = run(&grid, 0.0);
    // The sphere field increases outward: positive enclosed volume, outward normals.
    let v = signed_volume(&mesh);
    assert!((mesh.report().volume.unwrap() - v).abs() < 1e-9);
    let area = mesh.report().area;
    let exact_area = 4.0 * std::f64::consts::PI * 0.8f64.powi(2);
    assert!(
        (area - exact_area).abs() < 0.03 * exact_area,
        "area {area} vs {exact_area}"
    );
    let exact = 4.0 / 3.0 * std::f64::consts::PI * 0.8f64.powi(3);
    assert!((v - exact).abs() < 0.03 * exact, "volume {v} vs {exact}");
    for (p, n) in mesh.positions.iter().zip(&mesh.normals) {
        let radial: f32 = (0..3).map(|a| p[a] * n[a]).sum();
        assert!(radial > 0.0);
        let len: f32 = n.iter().map(|c| c * c).sum();
        assert!((len - 1.0).abs() < 1e-5);
    }
    let (flipped, _) = extract(&grid, &ExtractOptions::default().with_flip(true)).unwrap();
    assert!((signed_volume(&flipped) + v).abs() < 1e-9 * v.abs());
    assert!(flipped
        .normals
        .iter()
        .zip(&mesh.normals)
        .all(|(a, b)| a.iter().zip(b).all(|(x, y)| *x == -*y)));
    assert!(flipped.report().oriented);
}

#[test]
fn vertices_lie_on_a_linear_field_level_set() {
    let f = |p: [f64; 3]| 0.3 * p[0] - 0.5 * p[1] + 0.8 * p[2] - 0.1;
    let grid = Grid::from_fn([9, 8, 7], [0.25, 0.3, 0.2], [-1.0, -1.1, -0.7], f);
    let (mesh, _) = run(&grid, 0.0);
    assert!(mesh.triangle_count() > 50);
    for p in &mesh.positions {
        assert!(f(p.map(f64::from)).abs() < 1e-5, "{p:?}");
    }
    // A plane through the box: one disc with boundary on the grid faces only.
    let r = mesh.report();
    assert_eq!((r.components, r.euler, r.nonmanifold_edges), (1, 1, 0));
    assert!(r.oriented);
}

#[test]
fn nan_cells_are_skipped_and_leave_a_hole() {
    let mut grid = Sample::Sphere.grid(20);
    // A NaN just outside the surface, on the column through the middle: the eight cells around
    // it are skipped.
    let k = (0..20)
        .rev()
        .find(|&k| grid.value(10, 10, k) < 0.0)
        .unwrap();
    let poke = grid.index(10, 10, k + 1);
    grid.values_mut()[poke] = f32::NAN;
    let (mesh, stats) = run(&grid, 0.0);
    assert_eq!(stats.skipped_cells, 8);
    let r = mesh.report();
    assert!(r.boundary_edges > 0);
    assert_eq!(r.nonmanifold_edges, 0);
    assert!(r.oriented);
    assert!(mesh
        .positions
        .iter()
        .all(|p| p.iter().all(|c| c.is_finite())));
}

#[test]
fn rejects_a_non_finite_level() {
    let grid = Sample::Sphere.grid(4);
    for level in [f32::NAN, f32::INFINITY] {
        let err = extract(&grid, &ExtractOptions::default().with_level(level)).unwrap_err();
        assert!(matches!(err, ExtractError::Level(_)));
    }
}

/// Components and Euler characteristic of the built-in samples, as documented in the README
/// (sample table). Checked at two resolutions so they are not an accident of sampling.
#[test]
fn sample_topology_is_as_documented() {
    let cases: [(Sample, usize, i64, bool); 8] = [
        (Sample::Sphere, 1, 2, true),
        (Sample::Torus, 1, 0, true),
        (Sample::TwoTori, 2, 0, true),
        (Sample::Tangle, 1, -8, true),
        (Sample::Gyroid, 1, -3, false),
        (Sample::SchwarzP, 1, -32, false),
        (Sample::Hyperboloid, 1, 0, false),
        (Sample::Tubes, 1, -108, false),
    ];
    for (sample, components, euler, closed) in cases {
        for n in [40, 64] {
            let (mesh, _) = run(&sample.grid(n), 0.0);
            let r = mesh.report();
            assert_eq!(
                (r.components, r.euler, r.watertight),
                (components, euler, closed),
                "{sample} at {n}: {r:?}"
            );
            assert!(r.oriented && r.nonmanifold_edges == 0, "{sample} at {n}");
        }
    }
}

/// A grid whose values come from a small integer set (many exact ties with the level) and whose
/// boundary is strictly below the level, so the surface is closed.
fn closed_grid() -> impl Strategy<Value = Grid> {
    (2usize..6, 2usize..6, 2usize..6)
        .prop_flat_map(|(a, b, c)| {
            let dims = [a + 2, b + 2, c + 2];
            let n = dims.iter().product::<usize>();
            (Just(dims), proptest::collection::vec(-3i8..=3, n), 0u8..3)
        })
        .prop_map(|(dims, raw, scale)| {
            let mut values: Vec<f32> = raw
                .iter()
                .map(|&x| f32::from(x) * (1.0 + f32::from(scale)))
                .collect();
            for k in 0..dims[2] {
                for j in 0..dims[1] {
                    for i in 0..dims[0] {
                        let edge = i == 0
                            || j == 0
                            || k == 0
                            || i + 1 == dims[0]
                            || j + 1 == dims[1]
                            || k + 1 == dims[2];
                        if edge {
                            values[i + dims[0] * (j + dims[1] * k)] = -1.0;
                        }
                    }
                }
            }
            Grid::new(dims, values).unwrap()
        })
}

/// Values from a seeded generator, quantised to quarters in [−1, 1] so that ties with levels on
/// the same quarters occur.
fn quantised_values(dims: [usize; 3], seed: u64) -> Vec<f32> {
    let n: usize = dims.iter().product();
    let mut rng = crate::TestRng::new(seed);
    (0..n)
        .map(|_| ((rng.next_u64() >> 40) % 9) as f32 / 4.0 - 1.0)
        .collect()
}

/// How many triangles use each undirected edge (low vertex first).
fn edge_uses(mesh: &Mesh) -> std::collections::HashMap<(u32, u32), usize> {
    let mut uses = std::collections::HashMap::new();
    for t in &mesh.triangles {
        for i in 0..3 {
            let (a, b) = (t[i], t[(i + 1) % 3]);
            *uses.entry((a.min(b), a.max(b))).or_insert(0) += 1;
        }
    }
    uses
}

fn assert_closed_manifold(r: &MeshReport) {
    assert_eq!(r.boundary_edges, 0, "{r:?}");
    assert_eq!(r.nonmanifold_edges, 0, "{r:?}");
    assert!(r.oriented, "{r:?}");
    assert_eq!(r.euler % 2, 0, "{r:?}");
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 10_000, failure_persistence: None, ..ProptestConfig::default() })]

    /// 10 000 random small grids with many exact ties: always watertight, edge-manifold and
    /// consistently oriented.
    #[test]
    fn random_tied_grids_are_closed_manifolds(grid in closed_grid()) {
        for topology in [Topology::Mc33, Topology::Classic] {
            let (mesh, _) = extract(&grid, &ExtractOptions::default().with_topology(topology)).unwrap();
            mesh.validate().unwrap();
            let r = mesh.report();
            if mesh.triangle_count() > 0 {
                assert_closed_manifold(&r);
            }
            prop_assert!(mesh.positions.iter().all(|p| p.iter().all(|c| c.is_finite())));
        }
    }
}

/// The cells (by their lowest corner) with a NaN or infinite corner.
fn cells_touching_non_finite(grid: &Grid) -> Vec<[usize; 3]> {
    let [nx, ny, nz] = grid.dims();
    let mut cells = Vec::new();
    for k in 0..nz - 1 {
        for j in 0..ny - 1 {
            for i in 0..nx - 1 {
                let bad = (0..8).any(|c| {
                    let v = grid.value(i + (c & 1), j + (c >> 1 & 1), k + (c >> 2));
                    !v.is_finite()
                });
                if bad {
                    cells.push([i, j, k]);
                }
            }
        }
    }
    cells
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 1_500, failure_persistence: None, ..ProptestConfig::default() })]

    /// NaN, +∞ and −∞ sprinkled over random closed surfaces, for every method and
    /// triangulation: exactly the cells touching them are skipped and counted, every vertex is
    /// finite, the mesh stays edge-manifold and oriented, and its open edges all lie in skipped
    /// cells (without the bad values it is closed).
    #[test]
    fn non_finite_values_leave_holes_only_around_them(
        grid in closed_grid(),
        spots in proptest::collection::vec((any::<proptest::sample::Index>(), 0u8..3), 1..4),
        ternary: bool,
        strategy in prop_oneof![
            Just(crate::quality::Strategy::Fan),
            Just(crate::quality::Strategy::Local),
            Just(crate::quality::Strategy::Optimal),
        ],
        classic: bool,
    ) {
        let mut grid = grid;
        let n = grid.values().len();
        for (at, kind) in &spots {
            grid.values_mut()[at.index(n)] = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY][usize::from(*kind)];
        }
        let mut options = ExtractOptions::default()
            .with_triangulation(strategy)
            .with_topology(if classic { Topology::Classic } else { Topology::Mc33 });
        if ternary {
            options = options.with_method(Method::Ternary(Snapping { snap: 0.5, ..Snapping::default() }));
        }
        let (mesh, stats) = extract(&grid, &options).unwrap();
        let skipped = cells_touching_non_finite(&grid);
        prop_assert_eq!(stats.skipped_cells, skipped.len());
        mesh.validate().unwrap();
        prop_assert!(mesh.positions.iter().flatten().all(|c| c.is_finite()));
        let r = mesh.report();
        prop_assert_eq!(r.nonmanifold_edges, 0);
        prop_assert!(r.oriented);
        // Open edges: those used by one triangle. Both ends must lie in a skipped cell's box.
        let mut uses: std::collections::HashMap<(u32, u32), usize> = std::collections::HashMap::new();
        for t in &mesh.triangles {
            for e in 0..3 {
                let (a, b) = (t[e], t[(e + 1) % 3]);
                *uses.entry((a.min(b), a.max(b))).or_default() += 1;
            }
        }
        let in_skipped = |v: u32| {
            let p = mesh.positions[v as usize];
            skipped.iter().any(|c| (0..3).all(|a| {
                let x = f64::from(p[a]);
                x >= c[a] as f64 - 1e-6 && x <= c[a] as f64 + 1.0 + 1e-6
            }))
        };
        for (&(a, b), &count) in &uses {
            if count == 1 {
                prop_assert!(in_skipped(a) && in_skipped(b), "open edge {a}–{b} away from the skipped cells");
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2_000, failure_persistence: None, ..ProptestConfig::default() })]

    /// Random grids at a random level, surface free to reach the boundary: manifold and
    /// oriented, and open edges only on the grid's boundary faces — also where ternary
    /// extraction puts snapped points on crossings (a point on an outer face keeps to it).
    #[test]
    fn open_edges_lie_on_the_grid_boundary(
        dims in (2usize..7, 2usize..7, 2usize..7),
        seed in any::<u64>(),
        level in -1.0f32..1.0,
        method in 0usize..5,
        smooth in any::<bool>(),
    ) {
        let dims = [dims.0, dims.1, dims.2];
        let values = match smooth {
            // Values off the quantised steps, so that crossings fall anywhere along edges.
            true => {
                let mut rng = crate::TestRng::new(seed ^ 1);
                quantised_values(dims, seed).iter().map(|v| v + rng.unit() as f32 * 0.24).collect()
            }
            false => quantised_values(dims, seed),
        };
        let level = (level * 4.0).round() / 4.0;
        let grid = Grid::new(dims, values).unwrap();
        let snapping = |snap: f32, position| Method::Ternary(Snapping { snap, position, ..Snapping::default() });
        let method = match method {
            0 => Method::MarchingCubes,
            1 => snapping(0.3, SnapPosition::NearestCrossing),
            2 => snapping(0.5, SnapPosition::NearestCrossing),
            3 => snapping(0.3, SnapPosition::GridPoint),
            _ => snapping(0.5, SnapPosition::GridPoint),
        };
        let (mesh, _) = extract(&grid, &ExtractOptions::default().with_level(level).with_method(method)).unwrap();
        let r = mesh.report();
        prop_assert_eq!(r.nonmanifold_edges, 0);
        prop_assert!(r.oriented);
        // Boundary edges: both ends on the same boundary face of the grid.
        let counts = edge_uses(&mesh);
        let hi = [0, 1, 2].map(|a| (dims[a] - 1) as f32);
        for ((a, b), c) in counts {
            if c == 1 {
                let (p, q) = (mesh.positions[a as usize], mesh.positions[b as usize]);
                let shared = (0..3).any(|ax| (p[ax] == 0.0 && q[ax] == 0.0) || (p[ax] == hi[ax] && q[ax] == hi[ax]));
                prop_assert!(shared, "open edge {:?}-{:?} inside the grid", p, q);
            }
        }
    }
}

/// Where no cell opens a tunnel, MC33 and classic Marching Cubes agree on the topology.
#[test]
fn mc33_and_classic_agree_without_tunnels_on_the_samples() {
    for sample in Sample::ALL {
        for n in [40, 64] {
            let grid = sample.grid(n);
            let (mc33, stats) = extract(&grid, &ExtractOptions::default()).unwrap();
            let (classic, _) = extract(
                &grid,
                &ExtractOptions::default().with_topology(Topology::Classic),
            )
            .unwrap();
            let (a, b) = (mc33.report(), classic.report());
            if stats.tunnels == 0 {
                assert_eq!(
                    (a.components, a.euler),
                    (b.components, b.euler),
                    "{sample} at {n}"
                );
            }
            assert!(a.oriented && a.nonmanifold_edges == 0, "{sample} at {n}");
        }
    }
}

/// A single case 4 cell with strong corners: MC33 joins them by a tunnel, classic does not.
#[test]
fn mc33_opens_the_case_4_tunnel() {
    // Grid order (x fastest): vertices 0 (0,0,0) and 6 (1,1,1) above.
    let values = vec![1.0, -0.1, -0.1, -0.1, -0.1, -0.1, -0.1, 1.0];
    let grid = Grid::new([2, 2, 2], values).unwrap();
    let (mc33, stats) = extract(&grid, &ExtractOptions::default()).unwrap();
    let (classic, _) = extract(
        &grid,
        &ExtractOptions::default().with_topology(Topology::Classic),
    )
    .unwrap();
    assert_eq!(stats.tunnels, 1);
    let (a, b) = (mc33.report(), classic.report());
    assert_eq!((a.components, a.euler), (1, 0));
    assert_eq!((b.components, b.euler), (2, 2));
    assert!(a.oriented && a.nonmanifold_edges == 0);
}

mod ternary {
    use super::*;
    use crate::extract::{Method, SnapPosition, Snapping, MIN_OFFSET};

    fn ternary(zero_threshold: f32, snap: f32) -> ExtractOptions {
        ExtractOptions::default().with_method(Method::Ternary(Snapping {
            zero_threshold,
            snap,
            position: SnapPosition::NearestCrossing,
        }))
    }

    fn ternary_on_grid(zero_threshold: f32, snap: f32) -> ExtractOptions {
        ExtractOptions::default().with_method(Method::Ternary(Snapping {
            zero_threshold,
            snap,
            position: SnapPosition::GridPoint,
        }))
    }

    /// A sphere just inside the grid, 0.04 or 0.15 of an edge from one of its six faces: the
    /// points there whose crossing along the face's normal is within `WALL_SNAP` are snapped
    /// onto themselves, so the surface touches the face (no film of region between the two) and
    /// stays within that distance of the sphere; with a snap distance under it, they are not.
    #[test]
    fn a_surface_grazing_a_wall_touches_it() {
        use crate::extract::WALL_SNAP;
        let n = 12;
        for (axis, gap) in (0..3).flat_map(|a| [(a, 0.04), (a, 0.15)]) {
            for high in [false, true] {
                let mut centre = [5.5, 5.3, 5.7];
                centre[axis] = if high {
                    (n - 1) as f64 - 4.0 - gap
                } else {
                    4.0 + gap
                };
                let values: Vec<f32> = (0..n * n * n)
                    .map(|p| {
                        let c = [p % n, p / n % n, p / (n * n)];
                        let d = (0..3)
                            .map(|a| (c[a] as f64 - centre[a]).powi(2))
                            .sum::<f64>();
                        (d.sqrt() - 4.0) as f32
                    })
                    .collect();
                let grid = Grid::new([n; 3], values).unwrap();
                let wall = if high { (n - 1) as f32 } else { 0.0 };
                let off_wall = |p: &[f32; 3]| (p[axis] - wall).abs();
                for (snap, touches) in [(0.3, true), (0.05, false)] {
                    let (mesh, stats) = extract(&grid, &ternary(0.0, snap)).unwrap();
                    assert_clean(&mesh);
                    assert_eq!(topology(&mesh), (1, 2, true), "{axis} {gap} {high} {snap}");
                    assert_eq!(stats.refused_points, 0);
                    let on = mesh.positions.iter().filter(|p| off_wall(p) == 0.0).count();
                    let near = mesh
                        .positions
                        .iter()
                        .filter(|p| off_wall(p) > 0.0 && f64::from(off_wall(p)) < WALL_SNAP)
                        .count();
                    if touches {
                        assert!(
                            on > 0 && near == 0,
                            "{axis} {gap} {high}: {on} on, {near} near"
                        );
                    } else {
                        assert!(
                            on == 0 && near > 0,
                            "{axis} {gap} {high}: {on} on, {near} near"
                        );
                    }
                    for p in &mesh.positions {
                        let d = (0..3)
                            .map(|a| (f64::from(p[a]) - centre[a]).powi(2))
                            .sum::<f64>();
                        assert!((d.sqrt() - 4.0).abs() < WALL_SNAP + 0.05, "{p:?}");
                    }
                }
            }
        }
    }

    /// A tunnel whose band runs through the cell's centre, which lies exactly between two of
    /// its crossings (quantised values, a symmetric cell): the table's triangles there have no
    /// area, and the interior point is moved (found by `random_open_grids`, 1 run in about 40).
    #[test]
    fn a_centre_between_two_crossings_is_moved() {
        let dims = [5, 6, 2];
        let grid = Grid::new(dims, quantised_values(dims, 6843947057787533948)).unwrap();
        let (mesh, stats) = extract(&grid, &ternary(0.0, 0.0).with_level(-0.25)).unwrap();
        assert_eq!(stats.tunnels, 1);
        assert_clean(&mesh);
    }

    /// No triangle repeats (in either orientation) and none has zero area.
    fn assert_clean(mesh: &Mesh) {
        let mut sets: Vec<[u32; 3]> = mesh
            .triangles
            .iter()
            .map(|t| {
                let mut s = *t;
                s.sort_unstable();
                s
            })
            .collect();
        sets.sort_unstable();
        assert!(sets.windows(2).all(|w| w[0] != w[1]), "duplicate triangle");
        assert_eq!(mesh.report().degenerate, 0, "degenerate triangle");
    }

    /// Every vertex but the interior points is a grid point or lies on a grid edge, at least
    /// `min_offset` from its ends; no more vertices lie off the grid edges than there are
    /// interior points.
    fn assert_on_grid_edges(grid: &Grid, mesh: &Mesh, interior: usize, min_offset: f64) {
        let h = grid.spacing();
        let o = grid.origin();
        let mut off_edges = 0;
        for p in &mesh.positions {
            let u = [0, 1, 2].map(|a| (f64::from(p[a]) - o[a]) / h[a]);
            let frac: Vec<f64> = u.iter().map(|x| (x - x.round()).abs()).collect();
            let fractional = frac.iter().filter(|&&f| f > 1e-4).count();
            match fractional {
                0 => {}
                1 => {
                    let f = frac.iter().copied().fold(0.0, f64::max);
                    assert!(f >= min_offset * 0.99, "crossing {f} from a grid point");
                }
                _ => off_edges += 1,
            }
        }
        // An interior point (a centroid) may happen to fall on a grid line, hence "at most".
        assert!(
            off_edges <= interior,
            "only interior points lie off grid edges: {off_edges} > {interior}"
        );
    }

    /// A grid `random_tied_grids` found (threshold 1, snap 0.1, on grid points): a tunnel cell
    /// whose crossings collapse onto zero points, once mended into a band whose collapsed rung
    /// lay in a cell face the neighbour used too (an edge of four triangles).
    #[test]
    fn tied_tunnel_mended_without_a_hole() {
        let values: [i8; 180] = [
            -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1,
            -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, 0,
            0, 0, 0, -1, -1, 0, 0, 3, -1, -1, -1, 0, 0, 0, -1, -1, -1, 0, 0, 0, 0, -1, -1, -1, -1,
            -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, 0, 0, 0, 0, -1, -1, 0, 0, -2, 1, -1, -1, 0, 0,
            0, 0, -1, -1, 0, 0, 0, 0, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, 0, 0,
            0, 0, -1, -1, 0, 0, 0, -1, -1, -1, 0, 0, -2, -2, -1, -1, 0, 0, 0, 0, -1, -1, -1, -1,
            -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1,
            -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1,
        ];
        let grid = Grid::new([6, 6, 5], values.iter().map(|&v| f32::from(v)).collect()).unwrap();
        let mc33 = extract(&without_lone_ties(&grid, 0.0), &ExtractOptions::default())
            .unwrap()
            .0;
        let mesh = extract(&grid, &ternary_on_grid(1.0, 0.1)).unwrap().0;
        assert_eq!(topology(&mesh), topology(&mc33));
    }

    fn topology(mesh: &Mesh) -> (usize, i64, bool) {
        let r = mesh.report();
        (r.components, r.euler, r.watertight)
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 10_000, failure_persistence: None, ..ProptestConfig::default() })]

        /// 10 000 random small grids with many values exactly at the level: the ternary mesh is
        /// watertight, edge-manifold, oriented, without repeated or zero-area triangles, and has
        /// the components and Euler characteristic of the MC33 mesh.
        #[test]
        fn random_tied_grids(grid in closed_grid(), threshold in 0u8..3, snap in 0u8..6, on_grid: bool) {
            let mc33 = extract(&without_lone_ties(&grid, 0.0), &ExtractOptions::default()).unwrap().0;
            // Values are multiples of 1, 2 or 3: a threshold of 1 makes the ±1 values zero too.
            let (t, d) = (f32::from(threshold) * 0.5, f32::from(snap) * 0.1);
            let options = if on_grid { ternary_on_grid(t, d) } else { ternary(t, d) };
            let (mesh, stats) = extract(&grid, &options).unwrap();
            mesh.validate().unwrap();
            prop_assert_eq!(topology(&mesh), topology(&mc33));
            if mesh.triangle_count() > 0 {
                assert_closed_manifold(&mesh.report());
            }
            assert_clean(&mesh);
            let min_offset = if on_grid { MIN_OFFSET } else { 0.0 };
            assert_on_grid_edges(&grid, &mesh, stats.interior_vertices, min_offset);
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 2_000, failure_persistence: None, ..ProptestConfig::default() })]

        /// Open surfaces (random level, surface reaching the grid boundary): manifold, oriented,
        /// clean, with the MC33 mesh's topology.
        #[test]
        fn random_open_grids(
            dims in (2usize..7, 2usize..7, 2usize..7),
            seed in any::<u64>(),
            level in -4i8..4,
            snap in 0u8..6,
        ) {
            let dims = [dims.0, dims.1, dims.2];
            let values = quantised_values(dims, seed);
            let grid = Grid::new(dims, values).unwrap();
            let level = f32::from(level) / 4.0;
            let mc33 = extract(&without_lone_ties(&grid, level), &ExtractOptions::default().with_level(level)).unwrap().0;
            let options = ternary(0.0, f32::from(snap) * 0.1).with_level(level);
            let (mesh, _) = extract(&grid, &options).unwrap();
            let r = mesh.report();
            prop_assert_eq!(r.nonmanifold_edges, 0);
            prop_assert!(r.oriented);
            prop_assert_eq!((r.components, r.euler), (mc33.report().components, mc33.report().euler));
            prop_assert_eq!(r.boundary_edges > 0, mc33.report().boundary_edges > 0);
            assert_clean(&mesh);
        }
    }

    /// Fields whose signs repeat with period 3 but whose magnitudes are random: the same 27-point
    /// neighbourhoods come back around many points, with ambiguous faces and tunnels decided
    /// both ways, and snapped vertices that coincide, so the memo of patterns gets reused where
    /// it must not decide or must test areas (tests re-run the full check on every reuse). The
    /// results keep MC33's topology and have no zero-area triangle.
    #[test]
    fn repeated_neighbourhoods_with_ambiguous_cells() {
        let dims = [20, 20, 20];
        let mut checked = 0;
        for seed in 0..12u64 {
            let mut rng = crate::TestRng::new(seed);
            let signs: Vec<f32> = (0..27).map(|_| (rng.next_u64() % 3) as f32 - 1.0).collect();
            let magnitudes: Vec<f32> = (0..27)
                .map(|_| [0.25, 0.5, 1.0][(rng.next_u64() % 3) as usize])
                .collect();
            let mut values = Vec::with_capacity(dims.iter().product());
            for k in 0..dims[2] {
                for j in 0..dims[1] {
                    for i in 0..dims[0] {
                        let sign = signs[i % 3 + 3 * (j % 3) + 9 * (k % 3)];
                        // Odd seeds: periodic magnitudes from a small set, so crossings often
                        // sit exactly halfway and snapped vertices coincide, again and again
                        // (zero-area refusals of known patterns).
                        let magnitude = if seed % 2 == 1 {
                            magnitudes[i % 3 + 3 * (j % 3) + 9 * (k % 3)]
                        } else {
                            0.05 + rng.unit() as f32
                        };
                        values.push(sign * magnitude);
                    }
                }
            }
            let grid = Grid::new(dims, values).unwrap();
            // Even seeds put points exactly at the level: chains of them between bodies, and
            // lone ones, which ternary extraction settles below.
            let settled = without_lone_ties(&grid, 0.0);
            let mc33 = extract(&settled, &ExtractOptions::default()).unwrap().0;
            for snap in [0.2, 0.5] {
                let (mesh, stats) = extract(&grid, &ternary(0.0, snap)).unwrap();
                checked += stats.snapped_points + stats.refused_points;
                let (a, b) = (mesh.report(), mc33.report());
                assert_eq!(
                    (a.components, a.euler),
                    (b.components, b.euler),
                    "seed {seed}"
                );
                assert!(a.oriented && a.nonmanifold_edges == 0);
                assert_clean(&mesh);
            }
        }
        assert!(checked > 10_000, "{checked}");
        // Small integers (ties, halfway crossings) repeating along x with period 4: every
        // decision, zero-area refusals included, recurs at the next period.
        for seed in 0..40u64 {
            let dims = [42, 6, 6];
            let base = quantised_values([4, 6, 6], seed);
            let mut values = Vec::with_capacity(dims.iter().product());
            for k in 0..dims[2] {
                for j in 0..dims[1] {
                    for i in 0..dims[0] {
                        values.push(base[i % 4 + 4 * (j + 6 * k)]);
                    }
                }
            }
            let grid = Grid::new(dims, values).unwrap();
            for (level, snap) in [(0.0, 0.5), (0.125, 0.5), (0.25, 0.3)] {
                let mc33 = extract(
                    &without_lone_ties(&grid, level),
                    &ExtractOptions::default().with_level(level),
                )
                .unwrap()
                .0;
                let options = ternary(0.0, snap).with_level(level);
                let (mesh, _) = extract(&grid, &options).unwrap();
                let (a, b) = (mesh.report(), mc33.report());
                assert_eq!(
                    (a.components, a.euler),
                    (b.components, b.euler),
                    "seed {seed}"
                );
                assert_clean(&mesh);
            }
        }
    }

    /// Schwarz P at 40 per axis: crossings land on or within rounding of grid points, so plain
    /// Marching Cubes makes zero-area triangles by the thousand; ternary makes none.
    #[test]
    fn schwarz_p_has_no_degenerate_triangles() {
        let grid = Sample::SchwarzP.grid(40);
        let (mc, _) = extract(&grid, &ExtractOptions::default()).unwrap();
        assert!(mc.report().degenerate > 1000, "{}", mc.report().degenerate);
        for (threshold, snap) in [(0.0, 0.0), (0.0, 0.1), (0.0, 0.3), (0.0, 0.5), (1e-3, 0.0)] {
            let (mesh, stats) = extract(&grid, &ternary(threshold, snap)).unwrap();
            assert_eq!(topology(&mesh), topology(&mc), "ε {threshold}, D {snap}");
            assert_clean(&mesh);
            assert!(mesh.report().oriented && mesh.report().nonmanifold_edges == 0);
            if snap > 0.0 {
                assert!(stats.snapped_points > 1000);
            }
        }
    }

    /// Every built-in sample at 40 and 64 per axis, with the default snapping, full snapping and a
    /// zero threshold: same components, Euler characteristic and closedness as MC33.
    #[test]
    fn sample_topology_equals_mc33() {
        for sample in Sample::ALL {
            for n in [40, 64] {
                let grid = sample.grid(n);
                let (mc33, _) = extract(&grid, &ExtractOptions::default()).unwrap();
                let range = grid.finite_range().unwrap();
                let eps = (range.1 - range.0) * 1e-3;
                for snapping in [
                    Snapping::default(),
                    Snapping {
                        snap: 0.5,
                        ..Snapping::default()
                    },
                    Snapping {
                        snap: 0.5,
                        position: SnapPosition::GridPoint,
                        ..Snapping::default()
                    },
                    Snapping {
                        zero_threshold: eps,
                        snap: 0.0,
                        ..Snapping::default()
                    },
                ] {
                    let options = ExtractOptions::default().with_method(Method::Ternary(snapping));
                    let (mesh, stats) = extract(&grid, &options).unwrap();
                    assert_eq!(
                        topology(&mesh),
                        topology(&mc33),
                        "{sample} at {n}, {snapping:?}"
                    );
                    let r = mesh.report();
                    assert!(r.oriented && r.nonmanifold_edges == 0, "{sample} at {n}");
                    assert_clean(&mesh);
                    let min_offset = match snapping.position {
                        SnapPosition::GridPoint => MIN_OFFSET,
                        SnapPosition::NearestCrossing => 0.0,
                    };
                    assert_on_grid_edges(&grid, &mesh, stats.interior_vertices, min_offset);
                }
            }
        }
    }

    /// A grid point exactly at the level with no neighbour above touches the level without
    /// enclosing anything: MC33's tie rule wraps it in a closed surface of zero size, which
    /// ternary extraction does not make — alone, in a cluster of such points, or with its only
    /// point above across a face diagonal. A tie beside a point above is that body's surface
    /// point and is snapped.
    #[test]
    fn lone_ties_make_no_surface() {
        let at = |i: usize, j: usize, k: usize| i + 5 * (j + 5 * k);
        let grid_with = |points: &[(usize, f32)]| {
            let mut values = vec![-1.0f32; 125];
            for &(p, v) in points {
                values[p] = v;
            }
            Grid::new([5, 5, 5], values).unwrap()
        };
        for points in [
            vec![(at(2, 2, 2), 0.0)],
            vec![(at(2, 2, 2), 0.0), (at(3, 2, 2), 0.0), (at(3, 3, 2), 0.0)],
            vec![(at(2, 2, 2), 0.0), (at(1, 1, 1), 0.0)],
            vec![(at(0, 0, 0), 0.0), (at(4, 4, 4), 0.0)],
        ] {
            let grid = grid_with(&points);
            let (mc33, _) = extract(&grid, &ExtractOptions::default()).unwrap();
            assert!(mc33.triangle_count() > 0, "{points:?}");
            for snap in [0.0, 0.3, 0.5] {
                for options in [ternary(0.0, snap), ternary_on_grid(0.0, snap)] {
                    let (mesh, stats) = extract(&grid, &options).unwrap();
                    assert_eq!(mesh.triangle_count(), 0, "{points:?} {options:?}");
                    assert_eq!((stats.snapped_points, stats.refused_points), (0, 0));
                }
            }
        }
        // A tie beside a point above: a small body with the tie on its surface, as MC33's.
        // Its only point above across a face diagonal: the tie is lone, the body is the other
        // point's alone.
        for (tie, above) in [(at(2, 2, 2), at(3, 2, 2)), (at(2, 2, 2), at(3, 3, 2))] {
            let grid = grid_with(&[(tie, 0.0), (above, 1.0)]);
            let lone = grid_with(&[(above, 1.0)]);
            let (mc33, _) = extract(&grid, &ExtractOptions::default()).unwrap();
            let (mesh, _) = extract(&grid, &ternary(0.0, 0.3)).unwrap();
            assert_clean(&mesh);
            assert_eq!(topology(&mesh), (1, 2, true));
            let c = [tie % 5, tie / 5 % 5, tie / 25].map(|x| x as f64);
            let on_tie = mesh.positions.iter().any(|p| p.map(f64::from) == c);
            if above == at(3, 2, 2) {
                assert_eq!(topology(&mc33), (1, 2, true));
                assert!(on_tie);
            } else {
                assert_eq!(topology(&mc33).0, 2);
                assert!(!on_tie);
                let (alone, _) = extract(&lone, &ternary(0.0, 0.3)).unwrap();
                assert_eq!(
                    (&mesh.positions, &mesh.triangles),
                    (&alone.positions, &alone.triangles)
                );
            }
        }
    }

    /// A face exactly at the level between a cell below and a cell above is the surface, emitted
    /// once; with both sides above, or both below (its points are then lone ties), there is no
    /// surface at all.
    #[test]
    fn a_zero_face_is_emitted_once() {
        // 2×2×3 points: z = 0 below, z = 1 at the level, z = 2 above or below.
        for top in [1.0f32, -1.0] {
            let mut values = vec![-1.0f32; 4];
            values.extend([0.0; 4]);
            values.extend([top; 4]);
            let grid = Grid::new([2, 2, 3], values).unwrap();
            let (mc33, _) =
                extract(&without_lone_ties(&grid, 0.0), &ExtractOptions::default()).unwrap();
            let (mesh, stats) = extract(&grid, &ternary(0.0, 0.0)).unwrap();
            assert_clean(&mesh);
            assert_eq!(topology(&mesh).0, topology(&mc33).0);
            assert_eq!(mesh.report().euler, mc33.report().euler);
            if top > 0.0 {
                // The whole face is the surface: two triangles on the grid points at z = 1.
                assert_eq!(stats.snapped_points, 4);
                assert_eq!(mesh.triangle_count(), 2);
                assert!(mesh.positions.iter().all(|p| p[2] == 1.0));
            } else {
                assert_eq!(mesh.triangle_count(), 0);
            }
        }
        let mut values = vec![1.0f32; 4];
        values.extend([0.0; 4]);
        values.extend([1.0; 4]);
        let grid = Grid::new([2, 2, 3], values).unwrap();
        assert_eq!(
            extract(&grid, &ternary(0.0, 0.3))
                .unwrap()
                .0
                .triangle_count(),
            0
        );
    }

    #[test]
    fn rejects_bad_snapping() {
        let grid = Sample::Sphere.grid(4);
        for (t, d) in [
            (-1.0, 0.1),
            (f32::NAN, 0.1),
            (0.0, 0.6),
            (0.0, -0.1),
            (0.0, f32::NAN),
        ] {
            let err = extract(&grid, &ternary(t, d)).unwrap_err();
            assert!(matches!(err, ExtractError::Option { .. }), "{err}");
        }
    }

    /// Same input, same bytes: vertex order and triangles do not depend on anything but the
    /// field.
    #[test]
    fn deterministic() {
        let grid = Sample::Tangle.grid(40);
        let a = extract(&grid, &ternary(0.0, 0.3)).unwrap().0;
        let b = extract(&grid, &ternary(0.0, 0.3)).unwrap().0;
        assert_eq!(a.positions, b.positions);
        assert_eq!(a.triangles, b.triangles);
    }

    /// Zero points are checked in parallel within independent groups: the choices, and so the
    /// bytes, are the same with 1, 2 or 3 threads — on tied integer data too, where many
    /// points compete, and with a quality triangulation.
    #[test]
    fn same_output_whatever_the_thread_count() {
        let grids = [
            Sample::Tangle.grid(40),
            Grid::new([17, 15, 19], quantised_values([17, 15, 19], 9)).unwrap(),
        ];
        for grid in &grids {
            for options in [
                ternary(0.0, 0.4),
                ternary(0.1, 0.3).with_triangulation(crate::quality::Strategy::Local),
            ] {
                let run = |threads: usize| {
                    rayon::ThreadPoolBuilder::new()
                        .num_threads(threads)
                        .build()
                        .unwrap()
                        .install(|| extract(grid, &options).unwrap())
                };
                let (one, stats) = run(1);
                assert!(stats.snapped_points > 0 && !one.triangles.is_empty());
                // The groups decide as one point after the other would.
                let Method::Ternary(snapping) = options.method else {
                    unreachable!()
                };
                let zeros = |grouped: bool| {
                    let mut t =
                        super::super::ternary::Ternary::new(grid.view(), &options, snapping);
                    t.choose_zeros_in_groups(grouped, &mut || std::ops::ControlFlow::Continue(()))
                        .unwrap();
                    let placer = super::super::place::Placer::new(t.window(), &options);
                    let chunk = t
                        .mesh_box(&placer, options.flip, CellBox::whole(grid.dims()))
                        .unwrap();
                    let mut mesh = Mesh::new();
                    join(grid.dims(), vec![chunk], &mut mesh, &mut |_| {}).unwrap();
                    mesh
                };
                assert_eq!(zeros(false), one);
                assert_eq!(zeros(true), one);
                for threads in [2, 3] {
                    let (other, other_stats) = run(threads);
                    assert_eq!(stats, other_stats, "{threads}");
                    assert_eq!(one, other, "{threads}");
                }
            }
        }
    }
}

/// The quality SnapMC reports on a sphere sampled at 40 points per axis (smallest angle about 17°
/// at D = 0.3 and 30° at D = 0.5, largest distance about 0.05 grid spacings), reached or bettered
/// at the same D.
#[test]
fn ternary_sphere_quality_matches_snapmc() {
    use crate::extract::{Method, Snapping};
    use crate::quality::{level_set_distance, quality_report};
    let grid = Sample::Sphere.grid(40);
    let (mc, _) = extract(&grid, &ExtractOptions::default()).unwrap();
    let mc_angles = quality_report(&mc);
    for (snap, min_angle) in [(0.3, 17.0), (0.5, 30.0)] {
        let options = ExtractOptions::default().with_method(Method::Ternary(Snapping {
            snap,
            ..Snapping::default()
        }));
        let (mesh, _) = extract(&grid, &options).unwrap();
        let a = quality_report(&mesh);
        let d = level_set_distance(&mesh, |p| Sample::Sphere.eval(p), 0.0, grid.spacing()[0]);
        assert!(a.min_angle.min >= min_angle, "D {snap}: {a:?}");
        assert!(d.max <= 0.05, "D {snap}: {d:?}");
        assert!(a.below[0] < mc_angles.below[0] && a.max_angle.max < mc_angles.max_angle.max);
    }
}

mod strategies {
    use super::*;
    use crate::extract::{Method, Snapping};
    use crate::quality::Strategy;

    proptest! {
        #![proptest_config(ProptestConfig { cases: 5_000, failure_persistence: None, ..ProptestConfig::default() })]

        /// Every triangulation strategy, with binary or ternary extraction and with or without
        /// relaxation, keeps random tied grids watertight, edge-manifold and oriented with the
        /// MC33 mesh's components and Euler characteristic; ternary meshes also stay free of
        /// zero-area triangles.
        #[test]
        fn every_strategy_keeps_closed_manifolds(
            grid in closed_grid(),
            strategy in prop_oneof![Just(Strategy::Fan), Just(Strategy::Local), Just(Strategy::Optimal)],
            ternary: bool,
            relax in 0usize..3,
        ) {
            let mut options = ExtractOptions::default()
                .with_triangulation(strategy)
                .with_relax(relax);
            // Ternary extraction makes no surface around a lone tie (a point at the level with
            // nothing above beside it): MC33's zero-size sphere there is not counted.
            let mc33 = if ternary {
                options = options.with_method(Method::Ternary(Snapping { snap: 0.5, ..Snapping::default() }));
                extract(&super::super::ternary::without_lone_ties(&grid, 0.0), &ExtractOptions::default())
            } else {
                extract(&grid, &ExtractOptions::default())
            }.unwrap().0.report();
            let (mesh, _) = extract(&grid, &options).unwrap();
            mesh.validate().unwrap();
            let r = mesh.report();
            prop_assert_eq!((r.components, r.euler), (mc33.components, mc33.euler));
            if mesh.triangle_count() > 0 {
                assert_closed_manifold(&r);
            }
            if ternary {
                prop_assert_eq!(r.degenerate, 0);
            }
        }
    }

    /// The combination of ternary snapping, optimal triangulation and relaxation on the exact
    /// function (what `isocube extract … --relax` does for built-in samples): smallest angle at
    /// least 30° (27° next to the grid's outer faces), largest at most 110°, within 0.05 grid
    /// spacings of the zero set, at most 1.3× the triangles of classic Marching Cubes, same
    /// topology as MC33.
    #[test]
    fn best_combination_meets_the_quality_targets() {
        use crate::quality::{level_set_distance, quality_report, relax, Implicit};
        for sample in [
            Sample::Sphere,
            Sample::Torus,
            Sample::Hyperboloid,
            Sample::Gyroid,
            Sample::Tangle,
        ] {
            for n in [40, 64] {
                let grid = sample.grid(n);
                let h = grid.spacing()[0];
                let classic = extract(
                    &grid,
                    &ExtractOptions::default().with_topology(Topology::Classic),
                )
                .unwrap()
                .0;
                let mc33_mesh = extract(&grid, &ExtractOptions::default()).unwrap().0;
                let mc33 = mc33_mesh.report();
                let options = ExtractOptions::default()
                    .with_method(Method::Ternary(Snapping {
                        snap: 0.5,
                        ..Snapping::default()
                    }))
                    .with_triangulation(Strategy::Optimal);
                let (mut mesh, _) = extract(&grid, &options).unwrap();
                relax(
                    &mut mesh,
                    &Implicit(|p| sample.eval(p), 1e-4 * h),
                    0.0,
                    10,
                    h,
                );
                let a = quality_report(&mesh);
                let d = level_set_distance(&mesh, |p| sample.eval(p), 0.0, h);
                let r = mesh.report();
                let what = format!("{sample}:{n}: {a:?} {d:?}");
                // The README's table (`--nocapture`).
                let mc33_distance = level_set_distance(&mc33_mesh, |p| sample.eval(p), 0.0, h);
                eprintln!(
                    "| {sample}:{n} | {} ({:.2}) | {:.2}° | {:.2}° | {:.4} ({:.4}) | {} (χ {}) |",
                    mesh.triangle_count(),
                    mesh.triangle_count() as f64 / classic.triangle_count() as f64,
                    a.min_angle.min,
                    a.max_angle.max,
                    d.max,
                    mc33_distance.max,
                    if (r.components, r.euler) == (mc33.components, mc33.euler) {
                        "yes"
                    } else {
                        "no"
                    },
                    r.euler,
                );
                assert!(a.max_angle.max <= 110.0, "{what}");
                // Where the surface meets the grid's outer faces, its rim stays on them and
                // relaxation keeps the rim's vertices: triangles with a vertex there keep 27°
                // (gyroid:64 has four at 27.7°, with a rim edge 0.7 spacings long and a crossing
                // next to it), every other triangle 30°.
                let rim: std::collections::HashSet<u32> = edge_uses(&mesh)
                    .iter()
                    .filter(|&(_, &n)| n == 1)
                    .flat_map(|(&(a, b), _)| [a, b])
                    .collect();
                for t in &mesh.triangles {
                    let p = t.map(|v| mesh.positions[v as usize].map(f64::from));
                    let smallest = crate::mesh::triangle_angles(p)
                        .map_or(0.0, |a| a.into_iter().fold(180.0, f64::min));
                    let least = match t.iter().any(|v| rim.contains(v)) {
                        true => 27.0,
                        false => 30.0,
                    };
                    assert!(smallest >= least, "{what}: {p:?} {smallest}°");
                }
                assert!(d.max <= 0.05, "{what}");
                assert!(
                    mesh.triangle_count() as f64 <= 1.3 * classic.triangle_count() as f64,
                    "{what}"
                );
                assert_eq!(
                    (r.components, r.euler, r.watertight),
                    (mc33.components, mc33.euler, mc33.watertight),
                    "{what}"
                );
                assert_eq!(r.nonmanifold_edges, 0, "{what}");
            }
        }
    }
}

/// Every method, topology, triangulation and option that changes the mesh.
fn any_options() -> impl Strategy<Value = ExtractOptions> {
    (
        0u8..3,
        any::<bool>(),
        any::<bool>(),
        any::<bool>(),
        0u8..4,
        0u8..3,
        0u8..6,
        any::<bool>(),
        0u8..4,
    )
        .prop_map(
            |(strategy, classic, flip, normals, method, threshold, snap, on_grid, level)| {
                let mut o = ExtractOptions::default()
                    .with_level(f32::from(level) * 0.25 - 0.25)
                    .with_flip(flip)
                    .with_normals(normals)
                    .with_triangulation(match strategy {
                        0 => crate::quality::Strategy::Fan,
                        1 => crate::quality::Strategy::Local,
                        _ => crate::quality::Strategy::Optimal,
                    });
                if classic {
                    o = o.with_topology(Topology::Classic);
                }
                if method > 0 {
                    o = o.with_method(Method::Ternary(Snapping {
                        zero_threshold: f32::from(threshold) * 0.1,
                        snap: f32::from(snap) * 0.1,
                        position: if on_grid {
                            SnapPosition::GridPoint
                        } else {
                            SnapPosition::NearestCrossing
                        },
                    }));
                }
                o
            },
        )
}

/// Closed, open and holed fields: ties with the level, surfaces through the grid's boundary,
/// NaN and infinite values.
fn any_grid() -> impl Strategy<Value = Grid> {
    prop_oneof![
        closed_grid(),
        (2usize..9, 2usize..9, 2usize..9, any::<u64>(), 0u8..3).prop_map(
            |(nx, ny, nz, seed, holes)| {
                let dims = [nx, ny, nz];
                let mut values = quantised_values(dims, seed);
                // Smooth values too, not only quarters.
                if seed % 3 == 0 {
                    let mut rng = crate::TestRng::new(seed ^ 0x5eed);
                    for v in &mut values {
                        *v += (rng.unit() as f32 - 0.5) * 0.3;
                    }
                }
                for (i, v) in values.iter_mut().enumerate() {
                    match holes {
                        1 if i % 11 == 3 => *v = f32::NAN,
                        2 if i % 13 == 5 => *v = f32::INFINITY,
                        _ => {}
                    }
                }
                Grid::new(dims, values).unwrap()
            }
        ),
    ]
}

/// The grid's values stored with the axes in memory order `order` (fastest first), after
/// `offset` unused elements: the storage, and the view's strides.
fn stored_as(grid: &Grid, order: [usize; 3], offset: usize) -> (Vec<f32>, [usize; 3]) {
    let dims = grid.dims();
    let mut strides = [0; 3];
    let mut step = 1;
    for &a in &order {
        strides[a] = step;
        step *= dims[a];
    }
    let mut values = vec![f32::NAN; offset + step];
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                values[offset + i * strides[0] + j * strides[1] + k * strides[2]] =
                    grid.value(i, j, k);
            }
        }
    }
    (values, strides)
}

const MEMORY_ORDERS: [[usize; 3]; 6] = [
    [0, 1, 2],
    [0, 2, 1],
    [1, 0, 2],
    [1, 2, 0],
    [2, 0, 1],
    [2, 1, 0],
];

#[test]
fn every_memory_order_is_read_in_place_into_the_same_mesh() {
    let options = [
        ExtractOptions::default(),
        ExtractOptions::default().with_relax(1),
        ExtractOptions::default().with_triangulation(crate::quality::Strategy::Optimal),
        ExtractOptions::default().with_method(Method::Ternary(Snapping::default())),
    ];
    for sample in [Sample::Tangle, Sample::Gyroid, Sample::Noise { seed: 7 }] {
        let grid = Sample::grid(sample, 13);
        for options in &options {
            let one = extract(&grid, options).unwrap();
            for (n, order) in MEMORY_ORDERS.into_iter().enumerate() {
                let (values, strides) = stored_as(&grid, order, n);
                let view = GridView::with_offset(&values, grid.dims(), strides, n)
                    .and_then(|v| v.with_spacing(grid.spacing()))
                    .and_then(|v| v.with_origin(grid.origin()))
                    .unwrap();
                assert_eq!(view.is_x_fastest(), order == [0, 1, 2]);
                // Relaxation follows the interpolant here (the view is not marked as the
                // sample), so compare like with like.
                let reference = match options.relax {
                    0 => one.clone(),
                    _ => extract(
                        grid.clone().with_spacing(grid.spacing()).unwrap().view(),
                        options,
                    )
                    .unwrap(),
                };
                assert_eq!(
                    extract(view, options).unwrap(),
                    reference,
                    "{sample} {order:?}"
                );
            }
        }
    }
}

#[test]
fn a_reflected_direction_keeps_fronts_facing_increasing_values() {
    let grid = Sample::Torus.grid(16);
    let options = ExtractOptions::default();
    let (plain, _) = extract(&grid, &options).unwrap();
    // Grid x along world −x: a reflection.
    let mirror =
        crate::field::Orientation::new([[-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
            .unwrap();
    let (mesh, _) = extract(grid.view().with_orientation(mirror), &options).unwrap();
    let o = grid.origin();
    for (p, q) in mesh.positions.iter().zip(&plain.positions) {
        assert_eq!(p[0], (o[0] - (f64::from(q[0]) - o[0])) as f32);
        assert_eq!((p[1], p[2]), (q[1], q[2]));
    }
    // Outward still: the same enclosed volume, positive.
    let (v, w) = (signed_volume(&mesh), signed_volume(&plain));
    assert!(v > 0.0 && (v - w).abs() < 1e-6 * w, "{v} {w}");
    assert!(mesh.report().watertight && mesh.report().oriented);
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 768, ..ProptestConfig::default() })]

    /// The mesh does not depend on how the grid is cut: any partition into boxes, meshed in any
    /// order and joined, gives one pass's mesh and counts, for every method and option.
    #[test]
    fn any_partition_joins_into_the_one_pass_mesh(
        grid in any_grid(), options in any_options(), seed in any::<u64>(), relax in 0usize..2,
    ) {
        let options = options.with_relax(relax);
        let one = extract(&grid, &options).unwrap();
        let mut rng = crate::TestRng::new(seed);
        let boxes = crate::random_partition(grid.dims(), &mut rng);
        let joined = extract_boxes(&grid, &options, &boxes).unwrap();
        prop_assert_eq!(&joined.0, &one.0, "boxes {:?}", boxes);
        prop_assert_eq!(joined.1, one.1);
        // Regular tilings too, single cells included.
        let size = [0, 1, 2].map(|_| 1 + (rng.next_u64() % 4) as usize);
        let tiles = CellBox::tile(grid.dims(), size).unwrap();
        prop_assert_eq!(&extract_boxes(&grid, &options, &tiles).unwrap().0, &one.0, "size {:?}", size);
        // The same values in another memory order, read in place and cut the same way.
        let order = MEMORY_ORDERS[(rng.next_u64() % 6) as usize];
        let (values, strides) = stored_as(&grid, order, 3);
        let view = GridView::with_offset(&values, grid.dims(), strides, 3).unwrap();
        prop_assert_eq!(&extract_boxes(view, &options, &boxes).unwrap().0, &one.0, "order {:?}", order);
    }
}

#[test]
fn a_mesh_larger_than_the_memory_limit_stops_with_a_typed_error() {
    let grid = Sample::Gyroid.grid(48);
    let options = ExtractOptions::default();
    let (mesh, _) = extract(&grid, &options).unwrap();
    let bytes = (mesh.positions.len() * 24 + mesh.triangles.len() * 12) as u64;
    // Far below the mesh: refused, saying how far it got.
    let small = options.with_max_memory(Some(bytes / 4));
    match extract(&grid, &small) {
        Err(ExtractError::MeshMemory {
            done,
            total,
            bytes: held,
            limit,
        }) => {
            assert!(done <= total && held * 2 > limit && limit == bytes / 4);
        }
        other => panic!("{other:?}"),
    }
    // Room enough: the same mesh as without a limit.
    let roomy = options.with_max_memory(Some(bytes * 4));
    assert_eq!(extract(&grid, &roomy).unwrap().0, mesh);
}

#[test]
fn overlapping_and_outside_boxes_are_refused() {
    let grid = Sample::Sphere.grid(8);
    let options = ExtractOptions::default();
    let overlap = [
        CellBox::new([0, 0, 0], [4, 7, 7]),
        CellBox::new([3, 0, 0], [7, 7, 7]),
    ];
    assert!(matches!(
        extract_boxes(&grid, &options, &overlap),
        Err(ExtractError::OverlappingBoxes { .. })
    ));
    for bad in [
        CellBox::new([0, 0, 0], [8, 7, 7]),
        CellBox::new([2, 0, 0], [2, 7, 7]),
    ] {
        assert!(matches!(
            extract_boxes(&grid, &options, &[bad]),
            Err(ExtractError::CellBox { .. })
        ));
    }
    assert!(matches!(
        CellBox::tile(grid.dims(), [3, 0, 1]),
        Err(ExtractError::ChunkSize { .. })
    ));
    // A chunk whose keys were lost is refused by the joiner, not trusted.
    let extractor = Extractor::new(&grid, &options).unwrap();
    let mut chunk = extractor.mesh_box(CellBox::whole(grid.dims())).unwrap();
    chunk.keys.pop();
    assert!(matches!(
        join(grid.dims(), vec![chunk], &mut Mesh::new(), &mut |_| {}),
        Err(ExtractError::MalformedChunk { .. })
    ));
}

/// Pairs of the mesh's edges that lie in one cell face and cross there, properly (each through
/// the other's interior): the surface would pass through itself.
/// Two edges' end points.
type EdgePair = [[f32; 3]; 4];

/// A cell face: (axis, plane, the cell's other two coordinates).
type FaceKey = (usize, i64, i64, i64);

fn edges_crossing_in_faces(mesh: &Mesh) -> Vec<EdgePair> {
    let mut edges: Vec<(u32, u32)> = mesh
        .triangles
        .iter()
        .flat_map(|t| (0..3).map(move |k| (t[k].min(t[(k + 1) % 3]), t[k].max(t[(k + 1) % 3]))))
        .collect();
    edges.sort_unstable();
    edges.dedup();
    let mut by_face: std::collections::BTreeMap<FaceKey, Vec<(u32, u32)>> = Default::default();
    for &(a, b) in &edges {
        let (p, q) = (mesh.positions[a as usize], mesh.positions[b as usize]);
        for d in 0..3 {
            if p[d] != q[d] || p[d].fract() != 0.0 {
                continue;
            }
            let (u, v) = ((d + 1) % 3, (d + 2) % 3);
            let cell = |k: usize| ((p[k] + q[k]) * 0.5).floor() as i64;
            by_face
                .entry((d, p[d] as i64, cell(u), cell(v)))
                .or_default()
                .push((a, b));
        }
    }
    let mut out = Vec::new();
    for ((d, ..), list) in &by_face {
        let (u, v) = ((d + 1) % 3, (d + 2) % 3);
        let at = |i: u32| {
            let p = mesh.positions[i as usize];
            robust::Coord {
                x: f64::from(p[u]),
                y: f64::from(p[v]),
            }
        };
        for (i, &(a, b)) in list.iter().enumerate() {
            for &(c, e) in &list[i + 1..] {
                // Not `signum`, which calls 0 positive.
                let side = |x: u32, y: u32, z: u32| {
                    let o = robust::orient2d(at(x), at(y), at(z));
                    f64::from(i8::from(o > 0.0) - i8::from(o < 0.0))
                };
                let shared = [a, b].iter().any(|x| *x == c || *x == e);
                if !shared
                    && side(a, b, c) * side(a, b, e) < 0.0
                    && side(c, e, a) * side(c, e, b) < 0.0
                {
                    let p = |x: u32| mesh.positions[x as usize];
                    out.push([p(a), p(b), p(c), p(e)]);
                }
            }
        }
    }
    out
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// Edges of the surface lying in a cell face never cross there. (MC33's tunnels once put
    /// both diagonals of an ambiguous face into one band; MC33 ring points placed in a face;
    /// ternary faces of four zero points whose two cells chose different diagonals.)
    #[test]
    fn surface_edges_in_a_face_never_cross(grid in any_grid(), options in any_options()) {
        let (mesh, _) = extract(&grid, &options).unwrap();
        let crossing = edges_crossing_in_faces(&mesh);
        prop_assert!(crossing.is_empty(), "{crossing:?}");
    }
}

/// The same on single random cells, many of them, every topology and triangulation: the cells
/// where MC33's tunnel bands used both diagonals of a face were about 1 in 300.
#[test]
fn random_cells_have_no_edges_crossing_in_a_face() {
    let mut rng = crate::TestRng::new(3);
    for _ in 0..3000 {
        let values: Vec<f32> = (0..8).map(|_| rng.unit() as f32 * 2.0 - 1.0).collect();
        let grid = Grid::new([2, 2, 2], values.clone()).unwrap();
        for topology in [Topology::Mc33, Topology::Classic] {
            for strategy in [
                crate::quality::Strategy::Fan,
                crate::quality::Strategy::Local,
                crate::quality::Strategy::Optimal,
            ] {
                let options = ExtractOptions::default()
                    .with_topology(topology)
                    .with_triangulation(strategy);
                let (mesh, _) = extract(&grid, &options).unwrap();
                let crossing = edges_crossing_in_faces(&mesh);
                assert!(crossing.is_empty(), "{values:?} {options:?}: {crossing:?}");
            }
        }
    }
}

/// The surface inside one random cell does not cross itself (exact predicates on the stored
/// positions), for every topology, triangulation and method, but in tunnels (counted).
#[test]
fn cell_surfaces_do_not_cross_themselves() {
    use crate::quality::Strategy as Tri;
    let mut rng = crate::TestRng::new(11);
    let mut crossing: std::collections::BTreeMap<String, (usize, usize)> = Default::default();
    for _ in 0..20000 {
        let values: Vec<f32> = (0..8).map(|_| rng.unit() as f32 * 2.0 - 1.0).collect();
        let grid = Grid::new([2, 2, 2], values).unwrap();
        for topology in [Topology::Mc33, Topology::Classic] {
            for (tri, snap) in [Tri::Fan, Tri::Local, Tri::Optimal]
                .into_iter()
                .flat_map(|t| [(t, None), (t, Some(0.0)), (t, Some(0.3))])
            {
                let method = snap.map_or(Method::MarchingCubes, |s| {
                    Method::Ternary(Snapping::default().with_snap(s))
                });
                let options = ExtractOptions::default()
                    .with_topology(topology)
                    .with_triangulation(tri)
                    .with_method(method);
                let (mesh, stats) = extract(&grid, &options).unwrap();
                let position = |v: u32| mesh.positions[v as usize].map(f64::from);
                let bad = crate::mesh::intersect::first_crossing(&mesh.triangles, &position);
                let e = crossing
                    .entry(format!(
                        "{topology:?} {tri:?} {snap:?} tunnel {}",
                        stats.tunnels
                    ))
                    .or_default();
                e.0 += 1;
                e.1 += usize::from(bad.is_some());
            }
        }
    }
    eprintln!("{crossing:#?}");
    for (what, &(cells, crossed)) in &crossing {
        // Tunnels cross themselves with the table's bands at about a third of these cells
        // (28 of 89 with Marching Cubes, 21 ternary); mended, none does. Elsewhere only rarely,
        // with ternary snapping and the classic table.
        let limit = if what.contains("Classic") && what.contains("Some") {
            cells / 10_000
        } else {
            0
        };
        assert!(crossed <= limit, "{what}: {crossed} of {cells} cells cross");
    }
}

/// Measurement (ignored: about half a minute): Marching Cubes 33 tunnels, binary and ternary, in
/// many random cells, half with values bunched near the level. None crosses itself but where two
/// crossings are one point (a value within about 1e-9 of the level): touching, not crossing.
#[test]
#[ignore]
fn tunnel_crossings_in_many_cells() {
    let mut rng = crate::TestRng::new(12);
    let ternary = Method::Ternary(Snapping::default().with_snap(0.3));
    let (mut tunnels, mut touching) = ([0usize; 2], [0usize; 2]);
    for n in 0..800_000 {
        let power = if n % 2 == 0 { 1 } else { 3 };
        let values: Vec<f32> = (0..8)
            .map(|_| (rng.unit() as f32 * 2.0 - 1.0).powi(power))
            .collect();
        let grid = Grid::new([2, 2, 2], values).unwrap();
        for (m, method) in [Method::MarchingCubes, ternary].into_iter().enumerate() {
            let options = ExtractOptions::default().with_method(method);
            let (mesh, stats) = extract(&grid, &options).unwrap();
            if stats.tunnels == 0 {
                continue;
            }
            tunnels[m] += 1;
            let position = |v: u32| mesh.positions[v as usize].map(f64::from);
            if crate::mesh::intersect::first_crossing(&mesh.triangles, &position).is_none() {
                continue;
            }
            let mut at = mesh.positions.clone();
            at.sort_by(|a, b| a.partial_cmp(b).expect("finite"));
            let tied = at.windows(2).any(|w| w[0] == w[1]);
            assert!(tied, "{method:?} {:?} crosses itself", grid.values());
            touching[m] += 1;
        }
    }
    eprintln!("tunnel cells {tunnels:?}, touching at a tied point {touching:?}");
}

/// Measurement (ignored: about a minute): whole surfaces of small random grids never pass
/// through themselves, per snapping option. Snapped onto crossings, the cells around a point
/// follow it onto an edge of another cell, and their triangles could reach through a
/// neighbour's (2 of 3 000 grids at snap 0.5 did, before such points were kept on their grid
/// points).
#[test]
#[ignore]
fn random_grid_surfaces_do_not_cross() {
    let mut rng = crate::TestRng::new(13);
    let mut counts: std::collections::BTreeMap<String, (usize, usize)> = Default::default();
    for _ in 0..3000 {
        let values: Vec<f32> = (0..64).map(|_| rng.unit() as f32 * 2.0 - 1.0).collect();
        let grid = Grid::new([4, 4, 4], values).unwrap();
        for snap in [0.3, 0.5] {
            for position in [SnapPosition::GridPoint, SnapPosition::NearestCrossing] {
                let snapping = Snapping::default().with_snap(snap).with_position(position);
                let options = ExtractOptions::default().with_method(Method::Ternary(snapping));
                let (mesh, _) = extract(&grid, &options).unwrap();
                let mut at = mesh.positions.clone();
                at.sort_by(|a, b| a.partial_cmp(b).expect("finite"));
                if at.windows(2).any(|w| w[0] == w[1]) {
                    continue;
                }
                let p = |v: u32| mesh.positions[v as usize].map(f64::from);
                let crossed = crate::mesh::intersect::first_crossing(&mesh.triangles, &p).is_some();
                assert!(!crossed, "{snap} {position:?} {:?}", grid.values());
                let e = counts.entry(format!("{snap} {position:?}")).or_default();
                e.0 += 1;
                e.1 += usize::from(crossed);
            }
        }
    }
    eprintln!("(grids, crossing) {counts:#?}");
}

/// A face whose four points lie at the level with both cells beside it below: each cell puts
/// a square in the face (ternary: the same four zero points) (a sheet of no thickness), and the two squares must take the same
/// diagonal, or their edges cross in the face. A tie for every triangulation strategy, so the
/// diagonal is the one through the face's lowest point (the property test found a grid where
/// `local` took one diagonal on each side). Every axis, both orientations.
#[test]
fn sheets_in_a_face_take_one_diagonal() {
    use crate::quality::Strategy as Tri;
    for axis in 0..3 {
        let mut dims = [2, 2, 2];
        dims[axis] = 3;
        let values: Vec<f32> = (0..12)
            .map(|i| {
                let c = [i % dims[0], i / dims[0] % dims[1], i / (dims[0] * dims[1])];
                if c[axis] == 1 {
                    0.0
                } else {
                    -1.0
                }
            })
            .collect();
        let grid = Grid::new(dims, values).unwrap();
        for flip in [false, true] {
            for topology in [Topology::Mc33, Topology::Classic] {
                for strategy in [Tri::Fan, Tri::Local, Tri::Optimal] {
                    for method in [Method::MarchingCubes, Method::Ternary(Snapping::default())] {
                        let options = ExtractOptions::default()
                            .with_flip(flip)
                            .with_topology(topology)
                            .with_triangulation(strategy)
                            .with_method(method);
                        let (mesh, _) = extract(&grid, &options).unwrap();
                        // Ternary extraction: the sheet's points are lone ties (nothing above
                        // beside them), so there is no surface at all.
                        let sheets = if method == Method::MarchingCubes {
                            4
                        } else {
                            0
                        };
                        assert_eq!(mesh.triangles.len(), sheets, "{axis} {options:?}");
                        let crossing = edges_crossing_in_faces(&mesh);
                        assert!(crossing.is_empty(), "{axis} {options:?}: {crossing:?}");
                    }
                }
            }
        }
    }
}

/// Positions, normals (as their bits) and triangles.
type MeshBits = (Vec<[u32; 3]>, Vec<[u32; 3]>, Vec<[u32; 3]>);

/// The bits of a mesh: positions and normals compared as stored (`-0.0` is not `0.0` here).
fn mesh_bits(mesh: &Mesh) -> MeshBits {
    let bits = |v: &[[f32; 3]]| v.iter().map(|p| p.map(f32::to_bits)).collect();
    (
        bits(&mesh.positions),
        bits(&mesh.normals),
        mesh.triangles.clone(),
    )
}

/// A float file's zeros may be `-0.0` (rounded negatives) where an integer file's are `0`: the
/// same field, so the same bytes — normals where the gradient is flat along an axis included —
/// for every method, orientation and flip, on grids with many values exactly at the level.
#[test]
fn signed_zeros_in_the_values_give_the_same_bytes() {
    let mirror =
        crate::field::Orientation::new([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
            .unwrap();
    let mut compared = 0;
    for seed in 0..6u64 {
        let dims = [9, 8, 7];
        let plain: Vec<f32> = quantised_values(dims, seed)
            .iter()
            .map(|v| (v * 4.0).round() / 2.0)
            .collect();
        let signed: Vec<f32> = plain
            .iter()
            .enumerate()
            .map(|(i, &v)| if v == 0.0 && i % 2 == 0 { -0.0 } else { v })
            .collect();
        assert!(signed.iter().any(|v| v.to_bits() == (-0.0f32).to_bits()));
        let a = Grid::new(dims, plain).unwrap();
        let b = Grid::new(dims, signed).unwrap();
        for options in [
            ExtractOptions::default(),
            ExtractOptions::default().with_flip(true),
            ExtractOptions::default().with_method(Method::Ternary(Snapping::default())),
            ExtractOptions::default().with_level(0.5),
        ] {
            for turn in [crate::field::Orientation::IDENTITY, mirror] {
                let one = extract(a.view().with_orientation(turn), &options)
                    .unwrap()
                    .0;
                let two = extract(b.view().with_orientation(turn), &options)
                    .unwrap()
                    .0;
                assert!(!one.triangles.is_empty());
                assert_eq!(mesh_bits(&one), mesh_bits(&two), "seed {seed} {options:?}");
                compared += 1;
            }
        }
    }
    assert_eq!(compared, 48);
}

/// Snapped onto crossings, vertices leave some of their cells: the surface never passes through
/// itself (the points whose vertices would make it are kept on their grid points), checked with
/// exact predicates over the whole mesh — noise and packed spheres, with ties and without, at
/// the default snap distance and the largest. Before that rule, noise seed 1 at 24 points and
/// snap 0.5 crossed itself near cell [14, 9, 7].
#[test]
fn snapped_surfaces_do_not_cross_themselves() {
    let mut checked = 0;
    let cases = [(Sample::Noise { seed: 1 }, 24, [false, true, false])]
        .into_iter()
        .chain([2, 3, 5].map(|seed| (Sample::Noise { seed }, 16, [true, true, true])))
        .chain([2, 4].map(|seed| (Sample::PackedSpheres { seed }, 18, [true, true, true])));
    for (sample, n, runs) in cases {
        let grid = sample.grid(n);
        let h = grid.spacing().into_iter().fold(0.0f64, f64::max);
        // Integer values: exact ties at the level, which snap onto their grid points.
        let ties = Grid::new(
            grid.dims(),
            grid.values().iter().map(|v| (v * 12.0).round()).collect(),
        )
        .unwrap();
        let all = [(&grid, 0.0, 0.3), (&grid, 0.0, 0.5), (&ties, 1.0, 0.5)];
        for (&(grid, level, snap), _) in all.iter().zip(runs).filter(|(_, run)| *run) {
            let options = ExtractOptions::default()
                .with_level(level)
                .with_method(Method::Ternary(Snapping::default().with_snap(snap)));
            let (mesh, _) = extract(grid, &options).unwrap();
            let position = |v: u32| mesh.positions[v as usize].map(f64::from);
            let pairs = crate::mesh::intersect::crossing_pairs(&mesh.triangles, &position, h);
            assert!(
                pairs.is_empty(),
                "{sample:?} {n} level {level} snap {snap}: {} pairs cross, first {:?}",
                pairs.len(),
                pairs[0]
            );
            checked += mesh.triangles.len();
        }
    }
    assert!(checked > 20_000, "{checked} triangles checked");
}
