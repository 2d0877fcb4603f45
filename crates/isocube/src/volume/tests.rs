use super::*;
use crate::cube::Topology;
use crate::extract::SnapPosition;
use crate::field::{Grid, Sample};
use crate::quality::Strategy;

/// Both topologies, every triangulation, both sides.
fn all_options() -> Vec<ExtractOptions> {
    let mut out = Vec::new();
    for topology in [Topology::Mc33, Topology::Classic] {
        for strategy in [Strategy::Fan, Strategy::Local, Strategy::Optimal] {
            for flip in [false, true] {
                out.push(
                    ExtractOptions::default()
                        .with_topology(topology)
                        .with_triangulation(strategy)
                        .with_flip(flip),
                );
            }
        }
    }
    out
}

/// [`all_options`] with ternary extraction at snap distances 0.3 and 0.5, snapped points on
/// their grid points or on crossings, both sides.
fn ternary_options() -> Vec<ExtractOptions> {
    let mut out = Vec::new();
    for snap in [0.3, 0.5] {
        for position in [SnapPosition::GridPoint, SnapPosition::NearestCrossing] {
            let method = Method::Ternary(
                crate::extract::Snapping::default()
                    .with_snap(snap)
                    .with_position(position),
            );
            out.extend(all_options().into_iter().map(|o| o.with_method(method)));
        }
    }
    out
}

/// The grid's box volume.
fn box_volume(grid: &Grid) -> f64 {
    let d = grid.dims();
    let s = grid.spacing();
    (0..3).map(|a| (d[a] - 1) as f64 * s[a]).product()
}

fn assert_valid(tets: &TetMesh, what: &str) -> TetCheck {
    let c = tets.check();
    assert!(
        c.conforming && c.inverted == 0 && c.flat == 0 && c.unused == 0,
        "{what}: {c:?}"
    );
    assert!(
        (c.volume - c.enclosed).abs() <= 1e-9 * c.enclosed.abs().max(1e-300),
        "{what}: {c:?}"
    );
    c
}

#[test]
fn kuhn_tetrahedra_are_positive_and_fill_the_cube() {
    let corner = |o: u8| [o & 1, o >> 1 & 1, o >> 2 & 1].map(f64::from);
    // Six times the volumes, exact in floating point: the cube's six.
    let mut volume = 0.0;
    for t in KUHN {
        let [a, b, c, d] = t.map(corner);
        assert!(positive(a, b, c, d), "{t:?}");
        volume += check::dot(
            check::sub(b, a),
            check::cross(check::sub(c, a), check::sub(d, a)),
        );
    }
    assert_eq!(volume, 6.0);
    // Their dihedral angles are 45°, 60° and 90°.
    for t in KUHN {
        let q = TetQuality::of(t.map(corner));
        assert!(
            (q.min_dihedral - 45.0).abs() < 1e-9 && (q.max_dihedral - 90.0).abs() < 1e-9,
            "{q:?}"
        );
    }
}

/// Smooth fields, every option (Marching Cubes and ternary): conforming, positive, the volume
/// the boundary encloses, and the surface is `extract`'s, vertex for vertex and triangle for
/// triangle. The two sides of the level fill the grid's box together.
#[test]
fn samples_give_valid_meshes_bounded_by_the_extracted_surface() {
    for (sample, n) in [
        (Sample::Sphere, 20),
        (Sample::Gyroid, 20),
        (Sample::Tangle, 24),
        (Sample::Torus, 24),
    ] {
        let grid = sample.grid(n);
        let mut sides = Vec::new();
        for options in all_options().into_iter().chain(ternary_options()) {
            let what = format!("{sample:?} {n} {options:?}");
            let tets = tetmesh(&grid, &options).unwrap_or_else(|e| panic!("{what}: {e}"));
            let c = assert_valid(&tets, &what);
            let (surface, stats) = crate::extract::extract(&grid, &options).unwrap();
            assert_eq!(surface.triangles, tets.surface, "{what}");
            assert_eq!(stats, tets.stats.extract, "{what}");
            assert_eq!(
                surface.positions[..],
                tets.positions[..tets.surface_vertices],
                "{what}"
            );
            assert!(
                tets.stats.lattice_cells > 0 && tets.stats.cut_cells > 0,
                "{what}"
            );
            // Snapped points on the grid's outer faces stay on them (every method): the two
            // sides share the surface and split the box between them.
            sides.push((format!("{:?}", options.with_flip(false)), c.volume));
        }
        let total = box_volume(&grid);
        sides.sort_by(|a, b| a.0.cmp(&b.0));
        assert_eq!(sides.len(), all_options().len() + ternary_options().len());
        for pair in sides.chunk_by(|a, b| a.0 == b.0) {
            assert_eq!(pair.len(), 2, "{sample:?}: {}", pair[0].0);
            let sum = pair[0].1 + pair[1].1;
            assert!(
                (sum - total).abs() <= 1e-9 * total,
                "{sample:?}: {sum} vs {total}"
            );
        }
    }
}

/// Random grids (uniform values and ties at the level): every grid meshes, validly, with every
/// option set — but plain Marching Cubes on values at the level, whose triangles of no area
/// bound no region, which it says naming the cell (the default, ternary, meshes those too).
#[test]
fn random_grids_give_valid_meshes_or_name_the_cell() {
    let mut rng = crate::TestRng::new(7);
    let (mut meshed, mut refused) = (0, 0);
    for case in 0..150 {
        let (dims, ties, values) = random_values(&mut rng, case, 5);
        let grid = Grid::new(dims, values).unwrap();
        // Ternary on every third untied grid and every fourth tied one (the snapping choice is
        // the slow part of a case; a tied grid's points kept off the level `MIN_OFFSET` from
        // their crossings can take a second to fill).
        let ternary = if case % 3 == 1 || case % 12 == 0 {
            ternary_options()
        } else {
            Vec::new()
        };
        for options in all_options().into_iter().chain(ternary) {
            match tetmesh(&grid, &options) {
                Ok(tets) => {
                    // Ties put Marching Cubes' crossings on grid points: the surface itself
                    // has flat triangles there, and so do the tetrahedra on them; nothing may
                    // be inverted. Ternary extraction snaps ties or keeps crossings off them.
                    let c = tets.check();
                    assert!(
                        c.conforming && c.inverted == 0,
                        "case {case} {options:?} {c:?}"
                    );
                    if !ties || options.method != Method::MarchingCubes {
                        assert_valid(&tets, &format!("case {case} {options:?}"));
                    }
                    meshed += 1;
                }
                Err(TetError::Empty) => {}
                Err(TetError::TiedValues { cell, ties: n, .. }) => {
                    assert!(ties && n > 0 && options.method == Method::MarchingCubes);
                    assert!((0..3).all(|d| cell[d] + 1 < dims[d]), "{cell:?}");
                    refused += 1;
                }
                // Every cell fills (random probe: 0 of 28 800 runs refused a cell).
                Err(e) => panic!("case {case} {options:?}: {e}"),
            }
        }
    }
    eprintln!("random grids: {meshed} meshed, {refused} refused (Marching Cubes on ties)");
    assert!(meshed > 0);
}

#[test]
fn bad_input_is_refused() {
    let grid = Sample::Sphere.grid(8);
    let relax = ExtractOptions::default().with_relax(2);
    assert!(matches!(
        tetmesh(&grid, &relax),
        Err(TetError::Unsupported(_))
    ));
    let everything_above = ExtractOptions::default().with_level(-1e9);
    assert!(matches!(
        tetmesh(&grid, &everything_above),
        Err(TetError::Empty)
    ));
    let holed = crate::with_nan_holes(grid, 97);
    assert!(matches!(
        tetmesh(&holed, &ExtractOptions::default()),
        Err(TetError::NonFinite {
            point: [0, 0, 0],
            ..
        })
    ));
}

/// Sweep over the samples at the resolutions (run with `--ignored --release`).
#[test]
#[ignore]
fn sample_sweep() {
    for sample in [
        Sample::Sphere,
        Sample::Gyroid,
        Sample::Tangle,
        Sample::Torus,
    ] {
        for n in [24, 40, 64] {
            for options in all_options() {
                let grid = sample.grid(n);
                let tets = tetmesh(&grid, &options).unwrap();
                assert_valid(&tets, &format!("{sample:?} {n} {options:?}"));
            }
        }
    }
}

/// How often one random cell is refused, per option set (run with `--ignored`).
#[test]
#[ignore]
fn single_cell_refusals() {
    for options in all_options().into_iter().chain(ternary_options()) {
        let mut rng = crate::TestRng::new(3);
        let mut refused = 0;
        let mut reasons = std::collections::BTreeMap::new();
        let n = 4000;
        let start = std::time::Instant::now();
        let mut slowest = 0.0f64;
        for _ in 0..n {
            let values: Vec<f32> = (0..8).map(|_| rng.unit() as f32 * 2.0 - 1.0).collect();
            let grid = Grid::new([2, 2, 2], values).unwrap();
            let one = std::time::Instant::now();
            if let Err(TetError::Cell { reason, .. }) = tetmesh(&grid, &options) {
                refused += 1;
                *reasons.entry(reason).or_insert(0) += 1;
            }
            slowest = slowest.max(one.elapsed().as_secs_f64());
        }
        eprintln!(
            "{:?} {:?} flip {}: {refused} / {n} {reasons:?} in {:.1} s, slowest cell {:.3} s",
            options.topology,
            options.triangulation,
            options.flip,
            start.elapsed().as_secs_f64(),
            slowest
        );
    }
}

/// Rough throughput on one sample (run with `--ignored --release --nocapture`; not a benchmark).
#[test]
#[ignore]
fn throughput_probe() {
    let grid = Sample::Sphere.grid(128);
    let start = std::time::Instant::now();
    let tets = tetmesh(&grid, &ExtractOptions::default()).unwrap();
    let took = start.elapsed().as_secs_f64();
    eprintln!(
        "sphere 128: {} tets, {} cut cells, {} lattice cells, {:.3} s, {:.2} M tets/s",
        tets.tets.len(),
        tets.stats.cut_cells,
        tets.stats.lattice_cells,
        took,
        tets.tets.len() as f64 / took / 1e6
    );
}

/// Schwarz P has values within rounding of the level on whole lines of grid points: the
/// surface has triangles of no area there, and the tetrahedra on them are flat, never
/// inverted; the rest is as everywhere.
#[test]
fn values_at_the_level_give_flat_never_inverted_tetrahedra() {
    let grid = Sample::SchwarzP.grid(40);
    for flip in [false, true] {
        let tets = tetmesh(&grid, &ExtractOptions::default().with_flip(flip)).unwrap();
        let c = tets.check();
        assert!(c.conforming && c.inverted == 0 && c.flat > 0, "{c:?}");
        assert!((c.volume - c.enclosed).abs() <= 1e-9 * c.enclosed, "{c:?}");
        let (surface, _) =
            crate::extract::extract(&grid, &ExtractOptions::default().with_flip(flip)).unwrap();
        assert!(surface.report().degenerate > 0);
    }
}

/// A unit cube's corner `o` (bit 0: +x, bit 1: +y, bit 2: +z).
pub(super) fn cube_corner(o: u32) -> [f64; 3] {
    [o & 1, o >> 1 & 1, o >> 2 & 1].map(f64::from)
}

/// A unit cube's boundary: twelve triangles over its corners ([`cube_corner`]), outward.
pub(super) fn cube_boundary() -> Vec<[u32; 3]> {
    // Faces as quads (outward, counterclockwise seen from outside).
    let quads = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    quads
        .iter()
        .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
        .collect()
}

/// Cones from two or three points over a cube's boundary (12 triangles, outward): the
/// tetrahedra tile it (volume 1, all positive), wedges and junctions included.
#[test]
fn cones_from_several_points_tile_a_cube() {
    let corner = cube_corner;
    let part = cube_boundary();
    let tris: Vec<[[f64; 3]; 3]> = part.iter().map(|t| t.map(corner)).collect();
    let degenerate = vec![false; part.len()];
    for points in [
        vec![[0.3, 0.5, 0.5], [0.7, 0.5, 0.5]],
        vec![[0.2, 0.3, 0.5], [0.8, 0.3, 0.5], [0.5, 0.8, 0.5]],
    ] {
        let group: Vec<u32> = tris
            .iter()
            .map(|t| {
                points
                    .iter()
                    .position(|&s| cones::sees(t, false, s))
                    .unwrap() as u32
            })
            .collect();
        let (points, tets) =
            cones::tile(&part, &tris, &degenerate, &points, &group, &corner, None).expect("tiles");
        let p = |v: u32| {
            if v & STEINER != 0 {
                points[(v & !STEINER) as usize]
            } else {
                corner(v)
            }
        };
        let volume: f64 = tets
            .iter()
            .map(|t| {
                let [a, b, c, d] = t.map(p);
                check::dot(
                    check::sub(b, a),
                    check::cross(check::sub(c, a), check::sub(d, a)),
                ) / 6.0
            })
            .sum();
        assert!((volume - 1.0).abs() < 1e-12, "{volume} {}", tets.len());
    }
}

/// The paper's example: the pores between packed spheres, some cut by the box, meshed as a
/// region reaching the grid's faces.
#[test]
fn the_pores_between_packed_spheres() {
    let spec: crate::field::SampleSpec = "sample:packed-spheres:64:1".parse().unwrap();
    let grid = spec.grid();
    let tets = tetmesh(&grid, &ExtractOptions::default().with_flip(true)).unwrap();
    let c = assert_valid(&tets, "pores");
    assert!(!tets.walls.is_empty() && tets.beyond.is_empty());
    // The pores and the spheres fill the box; the spheres' volume is close to the packing's.
    let balls = crate::field::sphere_packing(1);
    let balls_volume: f64 = balls
        .iter()
        .map(|(_, r)| 4.0 / 3.0 * std::f64::consts::PI * r.powi(3))
        .sum();
    let solid = 1.0 - c.volume;
    // Spheres sticking out of the box lose a part, so the solid is at most the balls' volume.
    assert!(
        solid < balls_volume && solid > 0.5 * balls_volume,
        "{solid} vs {balls_volume}"
    );
}

/// The check finds what is wrong: a missing tetrahedron (a hole in the boundary), a doubled
/// one (faces used three times), a turned one (inverted, faces used twice the same way).
#[test]
fn the_check_catches_broken_meshes() {
    let good = tetmesh(&Sample::Torus.grid(16), &ExtractOptions::default()).unwrap();
    assert!(good.check().conforming);
    let mut missing = good.clone();
    missing.tets.remove(missing.tets.len() / 2);
    let c = missing.check();
    assert!(!c.conforming && c.boundary_mismatch > 0, "{c:?}");
    let mut doubled = good.clone();
    doubled.tets.push(doubled.tets[7]);
    let c = doubled.check();
    assert!(!c.conforming && c.bad_faces == 4, "{c:?}");
    let mut turned = good.clone();
    turned.tets[3].swap(0, 1);
    let c = turned.check();
    assert!(!c.conforming && c.inverted == 1, "{c:?}");
    // A tetrahedron split into three at a point inside one of its faces: every piece positive,
    // the volume the same, but the face no longer meets its neighbour's.
    let mut split = good.clone();
    let t = split.tets.swap_remove(split.tets.len() / 3);
    let centre: [f32; 3] = std::array::from_fn(|d| {
        (0..3)
            .map(|k| split.positions[t[k] as usize][d])
            .sum::<f32>()
            / 3.0
    });
    let m = split.positions.len() as u32;
    split.positions.push(centre);
    let [a, b, c, d] = t;
    split
        .tets
        .extend([[a, b, m, d], [b, c, m, d], [c, a, m, d]]);
    let c = split.check();
    assert!(!c.conforming && c.inverted == 0, "{c:?}");
    assert!(
        (c.volume - good.check().volume).abs() < 1e-9 * c.volume,
        "{c:?}"
    );
}

/// Refusals on packed spheres at the resolutions, every option set (run with
/// `--ignored --release --nocapture`).
#[test]
#[ignore]
fn packed_sweep() {
    let mut reasons = std::collections::BTreeMap::new();
    let mut total = 0;
    for seed in 0..4u64 {
        for n in [24, 40, 64] {
            let grid = Sample::PackedSpheres { seed }.grid(n);
            for options in all_options() {
                total += 1;
                match tetmesh(&grid, &options) {
                    Ok(t) => {
                        assert_valid(&t, &format!("{seed} {n} {options:?}"));
                    }
                    Err(TetError::Cell { reason, .. }) => *reasons.entry(reason).or_insert(0) += 1,
                    Err(e) => panic!("{seed} {n} {options:?}: {e}"),
                }
            }
        }
    }
    eprintln!("{total} runs, refusals {reasons:?}");
}

/// A U-shaped prism is not star-shaped: no point sees all of it. Cone points in the arms and
/// the base, each triangle's chosen by the search, tile it exactly (volume 5).
#[test]
fn cones_fill_a_region_no_point_sees_whole() {
    let outline: [[f64; 2]; 8] = [
        [0.0, 0.0],
        [3.0, 0.0],
        [3.0, 2.0],
        [2.0, 2.0],
        [2.0, 1.0],
        [1.0, 1.0],
        [1.0, 2.0],
        [0.0, 2.0],
    ];
    // Vertices 0..8 at z = 0, 8..16 at z = 1.
    let corner = |v: u32| {
        let [x, y] = outline[(v % 8) as usize];
        [x, y, f64::from(v / 8)]
    };
    let cap: [[u32; 3]; 6] = [
        [7, 0, 5],
        [7, 5, 6],
        [0, 1, 4],
        [0, 4, 5],
        [1, 2, 3],
        [1, 3, 4],
    ];
    let mut part: Vec<[u32; 3]> = Vec::new();
    for t in cap {
        part.push(t.map(|v| v + 8));
        part.push([t[0], t[2], t[1]]);
    }
    for i in 0..8u32 {
        let j = (i + 1) % 8;
        part.push([i, j, j + 8]);
        part.push([i, j + 8, i + 8]);
    }
    let tris: Vec<[[f64; 3]; 3]> = part.iter().map(|t| t.map(corner)).collect();
    let degenerate = vec![false; part.len()];
    let points = [
        [0.5, 1.5, 0.5],
        [2.5, 1.5, 0.5],
        [1.5, 0.5, 0.5],
        [0.5, 0.5, 0.5],
        [2.5, 0.5, 0.5],
    ];
    assert!(check::kernel_point(&tris).is_none());
    for p in points {
        assert!(!tris.iter().all(|t| cones::sees(t, false, p)));
    }
    let group = cones::assign(&part, &tris, &degenerate, &points, &corner).expect("assigned");
    let (steiner, tets) =
        cones::tile(&part, &tris, &degenerate, &points, &group, &corner, None).expect("tiles");
    let p = |v: u32| {
        if v & STEINER != 0 {
            steiner[(v & !STEINER) as usize]
        } else {
            corner(v)
        }
    };
    let mut volume = 0.0;
    for t in &tets {
        let [a, b, c, d] = t.map(p);
        assert!(check::positive(a, b, c, d), "{t:?}");
        volume += check::dot(
            check::sub(b, a),
            check::cross(check::sub(c, a), check::sub(d, a)),
        ) / 6.0;
    }
    assert!((volume - 5.0).abs() < 1e-12, "{volume}");
    assert!(cones::open_faces(&tets, &part).is_empty());
    // Every Steiner point returned is used.
    assert!((0..steiner.len() as u32).all(|k| tets.iter().flatten().any(|&v| v == STEINER | k)));
}

/// Two inside corners joined across a face (a tube along it): the optimal triangulation puts an
/// interior point above the face and two chords in it, so the surface touches the face along
/// them and the tube's part of the face between the chords has no corner. That part keeps the
/// side of the strip it was cut from (inside), and the cell's region closes.
#[test]
fn chords_touching_a_face_keep_the_strip_inside() {
    let values = vec![
        0.021_070_123,
        -0.375_273_76,
        0.620_647_43,
        0.056_394_458,
        0.355_478_4,
        0.818_865_06,
        0.015_649_796,
        -0.270_416_68,
    ];
    let grid = Grid::new([2, 2, 2], values).unwrap();
    for topology in [Topology::Mc33, Topology::Classic] {
        let options = ExtractOptions::default()
            .with_topology(topology)
            .with_triangulation(Strategy::Optimal);
        let (surface, _) = crate::extract::extract(&grid, &options).unwrap();
        // The premise: two surface edges lie in the face x = 1 without being its trace.
        let on_x1 = |v: u32| surface.positions[v as usize][0] == 1.0;
        let mut in_face: Vec<[u32; 2]> = surface
            .triangles
            .iter()
            .flat_map(|t| (0..3).map(move |k| [t[k], t[(k + 1) % 3]]))
            .filter(|e| on_x1(e[0]) && on_x1(e[1]))
            .map(|[a, b]| [a.min(b), a.max(b)])
            .collect();
        in_face.sort_unstable();
        let shared = in_face.windows(2).filter(|w| w[0] == w[1]).count();
        assert!(shared >= 1, "{topology:?}: no chord in the face");
        let tets = tetmesh(&grid, &options).unwrap();
        assert_valid(&tets, &format!("{topology:?}"));
    }
}

/// The faces used once by `tets` ([`cones::open_faces`]), outward, as position triples in a
/// canonical rotation, sorted.
fn open_face_positions(positions: &[[f32; 3]], tets: &[[u32; 4]]) -> Vec<[[u32; 3]; 3]> {
    let mut out: Vec<[[u32; 3]; 3]> = cones::open_faces(tets, &[])
        .into_iter()
        .map(|f| canonical_positions(f.map(|v| positions[v as usize])))
        .collect();
    out.sort_unstable();
    out
}

/// A triangle by its corners' bits, rotated to start at the smallest.
fn canonical_positions(t: [[f32; 3]; 3]) -> [[u32; 3]; 3] {
    let bits = t.map(|p| p.map(f32::to_bits));
    let r = (0..3).min_by_key(|&r| bits[r]).unwrap();
    [bits[r], bits[(r + 1) % 3], bits[(r + 2) % 3]]
}

/// Labelled volumes (three labels in a background, random and in blobs, with every selection):
/// conforming, positive, each label's tetrahedra bounded exactly by its `extract_labels`
/// surface and filling the volume it encloses; interfaces shared face to face.
#[test]
fn labelled_volumes_give_conforming_regions_bounded_by_the_label_surfaces() {
    use crate::extract::{extract_labels, LabelOptions, LabelSelection};
    let mut rng = crate::TestRng::new(11);
    let (mut meshed, mut interfaces) = (0, 0);
    for case in 0..24 {
        let dims = [0, 1, 2].map(|_| 2 + (rng.next_u64() % 6) as usize);
        let blobs = case % 2 == 0;
        let centres: Vec<[f64; 3]> = (0..3)
            .map(|_| std::array::from_fn(|d| rng.unit() * dims[d] as f64))
            .collect();
        let mut values = Vec::new();
        for k in 0..dims[2] {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    let v = if blobs {
                        let p = [i, j, k].map(|c| c as f64);
                        let d: Vec<f64> = centres
                            .iter()
                            .map(|c| (0..3).map(|a| (p[a] - c[a]).powi(2)).sum::<f64>())
                            .collect();
                        let (best, dist) = d
                            .iter()
                            .enumerate()
                            .min_by(|a, b| a.1.total_cmp(b.1))
                            .unwrap();
                        if *dist < 4.0 {
                            best as f32 + 1.0
                        } else {
                            0.0
                        }
                    } else {
                        (rng.next_u64() % 4) as f32
                    };
                    values.push(v);
                }
            }
        }
        let grid = Grid::new(dims, values).unwrap();
        for selection in [LabelSelection::All, LabelSelection::Only(vec![2])] {
            let options = LabelOptions::default()
                .with_smoothing(0)
                .with_labels(selection.clone());
            let what = format!("case {case} {dims:?} {selection:?}");
            let mesh = match tetmesh_labels(&grid, &options, None) {
                Ok(m) => m,
                Err(TetError::Empty | TetError::NoLabel(_)) => continue,
                Err(e) => panic!("{what}: {e}"),
            };
            assert_valid(&mesh, &what);
            let labels = mesh.labels.as_ref().unwrap();
            meshed += 1;
            interfaces += labels.interfaces.len();
            assert_eq!(labels.tets.len(), mesh.tets.len());
            let surfaces = extract_labels(&grid, &options).unwrap();
            assert_eq!(
                surfaces.iter().map(|s| s.label).collect::<Vec<_>>(),
                labels.names,
                "{what}"
            );
            for (index, s) in surfaces.iter().enumerate() {
                let own: Vec<[u32; 4]> = mesh
                    .tets
                    .iter()
                    .zip(&labels.tets)
                    .filter(|(_, &l)| l as usize == index)
                    .map(|(t, _)| *t)
                    .collect();
                let mut expected: Vec<[[u32; 3]; 3]> = s
                    .mesh
                    .triangles
                    .iter()
                    .map(|t| canonical_positions(t.map(|v| s.mesh.positions[v as usize])))
                    .collect();
                expected.sort_unstable();
                assert_eq!(
                    open_face_positions(&mesh.positions, &own),
                    expected,
                    "{what}: label {}",
                    s.label
                );
            }
            // Each interface triangle is a face of one tetrahedron of each of its labels.
            for (t, pair) in labels.interfaces.iter().zip(&labels.pairs) {
                let mut key = *t;
                key.sort_unstable();
                let holders: Vec<u32> = mesh
                    .tets
                    .iter()
                    .zip(&labels.tets)
                    .filter(|(tet, _)| key.iter().all(|v| tet.contains(v)))
                    .map(|(_, &l)| l)
                    .collect();
                let mut sides = holders.clone();
                sides.sort_unstable();
                assert_eq!(sides, pair.to_vec(), "{what}");
            }
        }
    }
    assert!(
        meshed >= 30 && interfaces > 0,
        "{meshed} meshed, {interfaces} interfaces"
    );
}

/// A reflected, rotated grid direction: the meshes stay positive, conforming and outward (one
/// region and labels).
#[test]
fn oriented_grids_give_valid_meshes() {
    use crate::extract::LabelOptions;
    use crate::field::Orientation;
    let (c, s) = (0.6f64, 0.8f64);
    // A rotation about z followed by a reflection of x: determinant −1.
    let reflect = Orientation::new([[-c, s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]).unwrap();
    assert!(reflect.determinant() < 0.0);
    let grid = Sample::Torus.grid(16);
    let view = grid.view().with_orientation(reflect);
    for options in [
        ExtractOptions::default(),
        ExtractOptions::default().with_flip(true),
    ] {
        let tets = tetmesh(view, &options).unwrap();
        let c = assert_valid(&tets, "torus reflected");
        assert!(c.enclosed > 0.0);
    }
    let values = (0..512)
        .map(|p| ((p % 8) / 3 + (p / 64) / 4) as f32)
        .collect();
    let labels = Grid::new([8, 8, 8], values).unwrap();
    let mesh = tetmesh_labels(
        labels.view().with_orientation(reflect),
        &LabelOptions::default().with_smoothing(0),
        None,
    )
    .unwrap();
    let c = assert_valid(&mesh, "labels reflected");
    assert!(c.enclosed > 0.0);
}

/// The mesh's qualities (shapes computed once per run of translates) are, bit for bit, those of
/// every element computed on its own.
#[test]
fn qualities_match_each_element() {
    for options in ternary_options().into_iter().take(2) {
        let mesh = tetmesh(&Sample::Tangle.grid(28), &options).unwrap();
        let all = mesh.qualities();
        assert_eq!(all.len(), mesh.tets.len());
        for (q, t) in all.iter().zip(&mesh.tets) {
            let own = TetQuality::of(t.map(|v| mesh.positions[v as usize].map(f64::from)));
            assert_eq!(
                [q.min_dihedral, q.max_dihedral, q.radius_ratio].map(f64::to_bits),
                [own.min_dihedral, own.max_dihedral, own.radius_ratio].map(f64::to_bits)
            );
        }
    }
}

/// Planes placed by heights: heights that repeat the regular spacing give the very same meshes
/// (surface and tetrahedra, every bit); uneven heights give a valid mesh of the stretched
/// region (volume within the box, boundary on the level set of the stretched field).
#[test]
fn planes_at_heights_mesh_like_spaced_planes() {
    let grid = Sample::Torus
        .grid(14)
        .with_spacing([0.25, 0.75, 0.5])
        .unwrap();
    let even: Vec<f64> = (0..14).map(|k| k as f64 * 0.5).collect();
    let view = grid.view().with_heights(&even).unwrap();
    for options in all_options().into_iter().chain(ternary_options()) {
        let a = tetmesh(&grid, &options).unwrap();
        let b = tetmesh(view, &options).unwrap();
        assert_eq!(a, b, "{options:?}");
    }
    let uneven: Vec<f64> = (0..14).map(|k| (k as f64 / 13.0).powf(1.5) * 6.5).collect();
    let view = grid.view().with_heights(&uneven).unwrap();
    for options in all_options().into_iter().chain(ternary_options()) {
        let t = tetmesh(view, &options).unwrap();
        let c = assert_valid(&t, &format!("{options:?}"));
        let cells = 13.0 * 0.25 * 13.0 * 0.75 * 6.5;
        assert!(c.volume > 0.0 && c.volume < cells, "{}", c.volume);
        // Every vertex within the box the heights span.
        assert!(t
            .positions
            .iter()
            .all(|p| p[2] >= grid.origin()[2] as f32 - 1e-5
                && p[2] <= (grid.origin()[2] + 6.5) as f32 + 1e-5));
    }
}

/// The region's angle at each boundary edge, as the sum of the dihedral angles of the
/// tetrahedra around it, for every edge with two boundary triangles.
/// The sum of the tetrahedra's dihedral angles at each boundary edge (the region's angle there,
/// or the sum of its wedges where more than two boundary triangles meet), and how many boundary
/// triangles meet at it.
fn boundary_angles_from_tets(mesh: &TetMesh) -> HashMap<[u32; 2], (f64, usize)> {
    let mut count: HashMap<[u32; 2], usize> = HashMap::default();
    for f in mesh.boundary_triangles() {
        for k in 0..3 {
            let (a, b) = (f[k], f[(k + 1) % 3]);
            *count.entry([a.min(b), a.max(b)]).or_default() += 1;
        }
    }
    let mut angles: HashMap<[u32; 2], (f64, usize)> = count
        .into_iter()
        .filter(|&(_, n)| n >= 2)
        .map(|(e, n)| (e, (0.0, n)))
        .collect();
    let p = |v: u32| mesh.positions[v as usize].map(f64::from);
    for t in &mesh.tets {
        for (a, b, c, d) in [
            (0, 1, 2, 3),
            (0, 2, 1, 3),
            (0, 3, 1, 2),
            (1, 2, 0, 3),
            (1, 3, 0, 2),
            (2, 3, 0, 1),
        ] {
            let Some((sum, _)) = angles.get_mut(&[t[a].min(t[b]), t[a].max(t[b])]) else {
                continue;
            };
            let e = crate::mesh::sub(p(t[b]), p(t[a]));
            let n1 = crate::mesh::cross(e, crate::mesh::sub(p(t[c]), p(t[a])));
            let n2 = crate::mesh::cross(e, crate::mesh::sub(p(t[d]), p(t[a])));
            let cos = crate::mesh::dot(n1, n2)
                / (crate::mesh::dot(n1, n1) * crate::mesh::dot(n2, n2)).sqrt();
            *sum += cos.clamp(-1.0, 1.0).acos().to_degrees();
        }
    }
    angles
}

#[test]
fn the_sharpest_boundary_edge_bounds_the_tetrahedra_around_it() {
    // Packed spheres give grazing cuts by the box and thin gaps; the sphere's pores convex
    // and reflex edges; the pores of seed 4 a surface touching a wall along an edge.
    let ternary = ternary_options()[0];
    let mut touching = 0;
    for (grid, options) in [
        (
            Sample::PackedSpheres { seed: 4 }.grid(24),
            ternary.with_flip(true),
        ),
        (Sample::PackedSpheres { seed: 1 }.grid(24), ternary),
        (
            Sample::PackedSpheres { seed: 1 }.grid(24),
            ExtractOptions::default(),
        ),
        (
            Sample::Sphere.grid(12),
            ExtractOptions::default().with_flip(true),
        ),
        (Sample::Torus.grid(16), ternary),
    ] {
        let mesh = tetmesh(&grid, &options).expect("meshed");
        let angles = boundary_angles_from_tets(&mesh);
        let sharpest = mesh.sharpest_boundary_edge().expect("a boundary");
        let (&edge, &(least, _)) = angles
            .iter()
            .filter(|e| e.1 .1 == 2)
            .min_by(|x, y| x.1 .0.total_cmp(&y.1 .0))
            .expect("edges");
        // The same angle from the boundary's two triangles as from the tetrahedra; where more
        // meet, one wedge of the angles the tetrahedra share out there.
        assert!(
            sharpest.angle <= least + 1e-6,
            "{sharpest:?} vs {edge:?} {least}"
        );
        let (sum, triangles) = angles[&sharpest.edge];
        if triangles == 2 {
            assert!((sum - sharpest.angle).abs() < 1e-6);
            assert!((least - sharpest.angle).abs() < 1e-6);
        } else {
            touching += 1;
            assert!(sharpest.angle < sum, "{sharpest:?}: {sum}");
        }
        let worst = mesh.quality_report().min_dihedral;
        assert!(worst <= sharpest.angle + 1e-9, "{worst} > {sharpest:?}");
        // Read back from a file, the tetrahedra alone give the boundary.
        let bare = TetMesh {
            positions: mesh.positions.clone(),
            tets: mesh.tets.clone(),
            ..TetMesh::default()
        };
        let again = bare.sharpest_boundary_edge().expect("a boundary");
        assert!(
            (again.angle - sharpest.angle).abs() < 1e-9,
            "{again:?} vs {sharpest:?}"
        );
    }
    assert!(
        touching > 0,
        "no input has its sharpest wedge where the surface touches"
    );
}

/// Packed spheres at 40 points per axis on the quality table's three sub-cell offsets: with
/// ternary snapping (points snapped onto their grid points, `tetmesh`'s default) every
/// dihedral angle is within [10°, 165°]. Two needle-shaped surface
/// triangles (a crossing kept 0.03 of a cell off its grid point) left elements at 9.20° while
/// new points only replaced a poor element with all its neighbours; it takes a point that
/// replaces the element with some of them.
#[test]
fn packed_spheres_at_40_stay_within_the_range() {
    let sample = Sample::PackedSpheres { seed: 1 };
    let (lo, hi) = sample.bounds();
    let h = (hi - lo) / 39.0;
    for shift in [
        [
            0.851_025_269_385_737_5,
            0.569_540_269_752_792_5,
            0.468_694_716_173_873_5,
        ],
        [
            0.022_349_112_301_368_934,
            0.074_070_180_478_396_64,
            0.392_900_713_844_465_8,
        ],
        [
            0.931_826_334_304_119_1,
            0.860_540_463_966_323_9,
            0.207_118_479_865_874_95,
        ],
    ] {
        let origin = shift.map(|s| lo + (s - 0.5) * h);
        let grid = Grid::from_fn([40; 3], [h; 3], origin, |p| sample.eval(p));
        for snap in [0.3, 0.5] {
            let options = ExtractOptions::default().with_method(Method::Ternary(
                crate::extract::Snapping::default()
                    .with_snap(snap)
                    .with_position(SnapPosition::GridPoint),
            ));
            assert_meshed_within_the_range(&grid, &options, &format!("{shift:?} {snap}"));
        }
    }
}

/// `tetmesh` meshes `grid` with `options`, valid, every dihedral angle within [10°, 165°].
fn assert_meshed_within_the_range(grid: &Grid, options: &ExtractOptions, what: &str) {
    let tets = tetmesh(grid, options).unwrap_or_else(|e| panic!("{what}: {e}"));
    assert_valid(&tets, what);
    let report = tets.quality_report();
    assert!(
        report.min_dihedral >= 10.0 && report.max_dihedral <= 165.0,
        "{what}: {:.2}°..{:.2}°",
        report.min_dihedral,
        report.max_dihedral
    );
}

/// The pores of packed spheres at 48 points (eight seeds), as `isocube tetmesh --flip` meshes
/// them by default: every element within [10°, 165°]. Spheres meeting the box's faces at a
/// grazing angle leave a film of pore between sphere and face; with points on the faces snapped
/// only for a crossing along the face's normal within 0.1 of an edge, seven of the eight had
/// elements outside (down to 5.73°, at edges as sharp as the film), none with 0.2 (`WALL_SNAP`).
#[test]
fn pores_of_packed_spheres_at_48_stay_within_the_range() {
    for seed in 1..=8 {
        let grid = Sample::PackedSpheres { seed }.grid(48);
        let options = ExtractOptions::default()
            .with_method(Method::Ternary(crate::extract::Snapping::default()))
            .with_flip(true);
        assert_meshed_within_the_range(&grid, &options, &format!("seed {seed}"));
    }
}

/// Integer volumes with ties, as segmentations and CT give them: balls' signed distances rounded
/// to integers (×1 and ×10), some with a share of points set exactly to the level. Ternary
/// extraction (the command's default) meshes both sides, valid, with no speck of surface
/// around a lone tie (before, each one became a zero-size sphere and the volume mesh a hole
/// of slivers around it: 0.67° at 21 × 18 × 25 with 30 % zeros, 6000 points added), and every
/// dihedral angle at least 5° unless the surface's sharpest edge forces less.
#[test]
fn tied_integer_volumes_mesh_without_specks() {
    let mut rng = crate::TestRng::new(11);
    let mut runs = 0;
    for case in 0..12 {
        let n = 10 + (case % 3) * 4;
        let dims = [n, n + 1 - case % 2, n + 2];
        let centre = dims.map(|d| d as f64 / 2.0 + rng.unit() - 0.5);
        let radius = n as f64 * 0.33;
        let scale = if case % 2 == 0 { 10.0 } else { 1.0 };
        let zeros = [0.0, 0.1, 0.3][case % 3];
        let mut values = Vec::with_capacity(dims.iter().product());
        for k in 0..dims[2] {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    let p = [i, j, k].map(|c| c as f64);
                    let d = (0..3)
                        .map(|a| (p[a] - centre[a]).powi(2))
                        .sum::<f64>()
                        .sqrt();
                    let zero = rng.unit() < zeros;
                    values.push(if zero {
                        0.0
                    } else {
                        ((d - radius) * scale).round() as f32
                    });
                }
            }
        }
        let grid = Grid::new(dims, values).unwrap();
        for flip in [false, true] {
            let options = ExtractOptions::default()
                .with_method(Method::Ternary(crate::extract::Snapping::default()))
                .with_flip(flip);
            let what = format!("case {case} flip {flip}");
            let (surface, _) = crate::extract::extract(&grid, &options).unwrap();
            let smallest = surface_components(&surface)
                .into_iter()
                .fold(f64::INFINITY, f64::min);
            assert!(smallest >= 0.5, "{what}: a component {smallest} across");
            let tets = tetmesh(&grid, &options).unwrap_or_else(|e| panic!("{what}: {e}"));
            assert_valid(&tets, &what);
            let report = tets.quality_report();
            let forced = tets.sharpest_boundary_edge().map_or(180.0, |e| e.angle);
            assert!(
                report.min_dihedral >= 5.0_f64.min(forced - 1e-9),
                "{what}: {report:?}, sharpest edge {forced}"
            );
            runs += 1;
        }
    }
    assert_eq!(runs, 24);
}

/// The extent (largest side of the bounding box) of each connected component of `mesh`.
fn surface_components(mesh: &crate::mesh::Mesh) -> Vec<f64> {
    let n = mesh.positions.len();
    let mut parent: Vec<usize> = (0..n).collect();
    fn root(parent: &mut [usize], mut v: usize) -> usize {
        while parent[v] != v {
            parent[v] = parent[parent[v]];
            v = parent[v];
        }
        v
    }
    for t in &mesh.triangles {
        for e in 0..3 {
            let (a, b) = (
                root(&mut parent, t[e] as usize),
                root(&mut parent, t[(e + 1) % 3] as usize),
            );
            parent[a] = b;
        }
    }
    let mut boxes: HashMap<usize, ([f64; 3], [f64; 3])> = HashMap::default();
    for t in &mesh.triangles {
        let r = root(&mut parent, t[0] as usize);
        let b = boxes
            .entry(r)
            .or_insert(([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]));
        for &v in t {
            for a in 0..3 {
                let x = f64::from(mesh.positions[v as usize][a]);
                b.0[a] = b.0[a].min(x);
                b.1[a] = b.1[a].max(x);
            }
        }
    }
    boxes
        .values()
        .map(|(lo, hi)| (0..3).map(|a| hi[a] - lo[a]).fold(0.0, f64::max))
        .collect()
}

/// Counts refusals and invalid meshes on random grids per option set (run with `--ignored
/// --release --nocapture`; `ISOCUBE_PROBE_CASES` cases, seed `ISOCUBE_PROBE_SEED`).
#[test]
#[ignore]
fn random_probe() {
    let cases: usize = std::env::var("ISOCUBE_PROBE_CASES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(300);
    let seed: u64 = std::env::var("ISOCUBE_PROBE_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(11);
    let only = std::env::var("ISOCUBE_PROBE_ONLY").unwrap_or_default();
    let mut rng = crate::TestRng::new(seed);
    let mut tally: std::collections::BTreeMap<String, [usize; 4]> = Default::default();
    let mut reasons: std::collections::BTreeMap<String, usize> = Default::default();
    let mut examples: std::collections::BTreeMap<String, String> = Default::default();
    for case in 0..cases {
        let (dims, ties, values) = random_values(&mut rng, case, 5);
        let grid = Grid::new(dims, values.clone()).unwrap();
        for options in all_options().into_iter().chain(ternary_options()) {
            let key = match options.method {
                Method::MarchingCubes => format!("mc flip={} ties={ties}", options.flip),
                Method::Ternary(s) => format!(
                    "ternary {} {:?} flip={} ties={ties}",
                    s.snap, s.position, options.flip
                ),
            };
            if !key.contains(&only) {
                continue;
            }
            let t = tally.entry(key.clone()).or_default();
            t[0] += 1;
            let what = match tetmesh(&grid, &options) {
                Ok(tets) => {
                    let c = tets.check();
                    let bad = !c.conforming
                        || c.inverted > 0
                        || (!ties && c.flat > 0)
                        || (!ties && (c.volume - c.enclosed).abs() > 1e-9 * c.enclosed.abs());
                    if bad {
                        t[2] += 1;
                        Some(format!("{c:?}"))
                    } else {
                        None
                    }
                }
                Err(TetError::Empty) => None,
                Err(TetError::TiedValues { .. }) => {
                    t[3] += 1;
                    None
                }
                Err(e) => {
                    t[1] += 1;
                    if let TetError::Cell { reason, .. } = e {
                        let surface = crate::extract::extract(&grid, &options).unwrap().0;
                        let at = |v: u32| surface.positions[v as usize].map(f64::from);
                        let selfx = crate::mesh::intersect::first_crossing(&surface.triangles, &at)
                            .is_some();
                        *reasons
                            .entry(format!("{key}: self-crossing surface {selfx}: {reason}"))
                            .or_default() += 1;
                    }
                    Some(e.to_string())
                }
            };
            if let Some(w) = what {
                examples.entry(key).or_insert_with(|| {
                    format!("case {case} dims {dims:?} {options:?} values {values:?}: {w}")
                });
            }
        }
    }
    for (k, t) in &tally {
        eprintln!(
            "{k}: {} runs, {} refused, {} invalid, {} ties",
            t[0], t[1], t[2], t[3]
        );
    }
    for (k, n) in &reasons {
        eprintln!("REASON {k}: {n}");
    }
    for (k, e) in &examples {
        eprintln!("EXAMPLE {k}: {e}");
    }
}

/// Counts extracted surfaces that pass through themselves on random grids, per snap option,
/// and shows the first crossing pair of each (run with `--ignored --release --nocapture`).
/// Issue 50's measurement: snapped onto crossings, a few surfaces in ten thousand do.
#[test]
#[ignore]
fn self_crossing_probe() {
    let cases: usize = std::env::var("ISOCUBE_PROBE_CASES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(3000);
    let mut rng = crate::TestRng::new(5);
    let mut tally: std::collections::BTreeMap<String, [usize; 2]> = Default::default();
    for case in 0..cases {
        let (dims, ties, values) = random_values(&mut rng, case, 6);
        let grid = Grid::new(dims, values).unwrap();
        for options in ternary_options() {
            let Method::Ternary(s) = options.method else {
                continue;
            };
            let key = format!(
                "{} {:?} flip={} ties={ties}",
                s.snap, s.position, options.flip
            );
            let surface = crate::extract::extract(&grid, &options).unwrap().0;
            let at = |v: u32| surface.positions[v as usize].map(f64::from);
            let t = tally.entry(key).or_default();
            t[0] += 1;
            if let Some((i, j)) = crate::mesh::intersect::first_crossing(&surface.triangles, &at) {
                t[1] += 1;
                // The first pair of each option set, to look at.
                if t[1] == 1 {
                    let show =
                        |k: usize| surface.triangles[k].map(|v| surface.positions[v as usize]);
                    eprintln!(
                        "case {case} {dims:?} {options:?}\n  {:?}\n  {:?}",
                        show(i),
                        show(j)
                    );
                }
            }
        }
    }
    for (k, t) in &tally {
        eprintln!("{k}: {} surfaces, {} pass through themselves", t[0], t[1]);
    }
}

/// A probe's random grid: 2 to `spread + 1` points per axis, and on every third case integer
/// values from −2 to 2 (ties with the level) instead of uniform ones in [−1, 1).
fn random_values(
    rng: &mut crate::TestRng,
    case: usize,
    spread: u64,
) -> ([usize; 3], bool, Vec<f32>) {
    let dims = [0, 1, 2].map(|_| 2 + (rng.next_u64() % spread) as usize);
    let ties = case % 3 == 0;
    let values = (0..dims[0] * dims[1] * dims[2])
        .map(|_| {
            if ties {
                (rng.next_u64() % 5) as f32 - 2.0
            } else {
                rng.unit() as f32 * 2.0 - 1.0
            }
        })
        .collect();
    (dims, ties, values)
}

/// Tied integer values, the pores' side: an optimal interior point a rounding away from the
/// grid's top face was stored on it, where the wall's triangles pass through it, and the cell
/// was refused as a surface passing through itself (the random probe's case 108, both snap
/// positions). Interior points are now kept off the faces as stored.
#[test]
fn an_interior_point_is_not_stored_on_a_face() {
    use crate::extract::{Method, SnapPosition, Snapping};
    let values: Vec<f32> = [
        0, 0, -2, 1, 0, -2, -2, 1, 1, 0, -2, -1, 1, -2, -1, 0, 2, 2, -1, 2, -2, -1, -2, 0, 0, -2,
        0, 1, -2, 0, 2, -2, -1, -2, 0, 1, 2, -2, 0, -2, 1, 1, -2, -2, -1, -1, 0, 2, -1, -1, -2, -2,
        0, -1, -2, 0, 0, -2, 1, -2, 1, -2, 1, 2, -2, 2, 0, 2, -2, -1, 1, 1, 0, -1, 1, 1, -1, -2,
        -2, 1, 1, -2, -1, 1, 1, -1, -1, -2, 0, -2, -1, -1, -1, -1, 1, 1, 1, -1, -1, 0, 2, 1, 1, 2,
        0, -2, -1, 2, 0, 2, -2, 2, 0, 0, 2, 1, 0, -1, 1, -2,
    ]
    .map(|v: i32| v as f32)
    .to_vec();
    let grid = Grid::new([5, 6, 4], values).unwrap();
    for position in [SnapPosition::GridPoint, SnapPosition::NearestCrossing] {
        let snapping = Snapping::default().with_snap(0.3).with_position(position);
        let options = ExtractOptions::default()
            .with_flip(true)
            .with_triangulation(crate::quality::Strategy::Optimal)
            .with_method(Method::Ternary(snapping));
        let tets = tetmesh(&grid, &options).unwrap_or_else(|e| panic!("{position:?}: {e}"));
        let c = tets.check();
        assert!(c.conforming && c.inverted == 0, "{position:?}: {c:?}");
    }
}

/// The random probe's case 152 (Marching Cubes, the side above, optimal triangulation): the
/// region in cell (0, 2, 0) folds around the surface's interior vertex so that no cone fills it
/// and the usual number of splits runs out; the last attempt at a group of cells gets more.
#[test]
fn a_fold_that_runs_out_of_splits_is_filled() {
    #[rustfmt::skip]
    let values: Vec<f32> = vec![
        -0.8436916, -0.5602671, 0.7507528, 0.09380734, 0.1758585, 0.2281599, 0.7632785,
        -0.19564658, 0.8121214, 0.2570492, -0.837751, -0.8080182, -0.4703232, 0.94948614, 0.660517,
        -0.46081907, 0.67819643, -0.34486634, 0.53017926, -0.57362163, -0.422428, 0.38176143,
        -0.878804, -0.8425341, 0.13468361, -0.018951535, -0.14978647, -0.5682124, 0.7495005,
        0.59032214, -0.13813108, -0.3616299, -0.11992782, -0.7405899, 0.8301941, -0.4473241,
        -0.37952483, 0.18102324, -0.049310982, 0.550859, 0.16727483, 0.32016587, 0.58343565,
        0.028443098, -0.19341213, 0.2210437, -0.88053817, 0.292225, 0.7238102, 0.7600002,
        -0.20606744, 0.4248687, 0.42698622, 0.4012301, 0.7961559, -0.36134475, -0.70192754,
        0.33624732, 0.40056467, 0.839394, 0.006105423, 0.13112831, 0.5133548, 0.38259745,
        -0.9692576, 0.9818033, 0.08567858, 0.5144675, 0.8102349, 0.6118281, 0.16565084, -0.6061542,
        -0.9244844, -0.695449, -0.45905745, 0.9065454, -0.78012115, -0.75318754, 0.5858388,
        -0.24463356, 0.1805098, -0.6439776, 0.6919216, -0.17297345, 0.7921363, -0.06741947,
        0.041079998, -0.83701783, 0.6828592, -0.06444365,
    ];
    let grid = Grid::new([3, 6, 5], values).unwrap();
    for topology in [Topology::Mc33, Topology::Classic] {
        let options = ExtractOptions::default()
            .with_topology(topology)
            .with_triangulation(Strategy::Optimal)
            .with_flip(true);
        let tets = tetmesh(&grid, &options).unwrap();
        let c = tets.check();
        assert!(c.conforming && c.inverted == 0 && c.flat == 0, "{c:?}");
        assert!((c.volume - c.enclosed).abs() <= 1e-9 * c.enclosed, "{c:?}");
    }
}

/// The poor elements' classes, found through the cell lookup, are those a scan of every surface
/// vertex and every wall finds; noise at a coarse grid has thin gaps and necks on both sides.
#[test]
fn poor_elements_are_classed_as_a_full_scan_classes_them() {
    let mut seen_fine = 0;
    for seed in 1..=4 {
        for flip in [false, true] {
            let grid = Sample::Noise { seed }.grid(16);
            let cell = grid.spacing()[0];
            let mesh = tetmesh(&grid, &ExtractOptions::default().with_flip(flip)).unwrap();
            let poor = mesh.poor_elements(cell, 0.3);
            let at = |v: u32| mesh.positions[v as usize].map(f64::from);
            let q = mesh.qualities();
            let sharp: Vec<[u32; 2]> = mesh
                .boundary_edges(None)
                .into_iter()
                .filter(|e| e.angle < 10.0)
                .map(|e| e.edge)
                .collect();
            let planes: Vec<(usize, f64)> = mesh
                .walls
                .iter()
                .flat_map(|f| {
                    let p = f.map(at);
                    (0..3)
                        .filter(move |&a| p[0][a] == p[1][a] && p[1][a] == p[2][a])
                        .map(move |a| (a, p[0][a]))
                })
                .collect();
            let (mut count, mut forced, mut fine) = (0, 0, 0);
            for (t, q) in mesh.tets.iter().zip(&q) {
                if q.min_dihedral >= 10.0 && q.max_dihedral <= 165.0 {
                    continue;
                }
                count += 1;
                let edges = (0..4).flat_map(|a| (a + 1..4).map(move |b| [a, b]));
                if edges
                    .map(|[a, b]| [t[a].min(t[b]), t[a].max(t[b])])
                    .any(|e| sharp.contains(&e))
                {
                    forced += 1;
                    continue;
                }
                let p = t.map(at);
                let c: [f64; 3] =
                    std::array::from_fn(|d| p.iter().map(|x| x[d]).sum::<f64>() / 4.0);
                let near: Vec<u32> = (0..mesh.surface_vertices as u32)
                    .filter(|&v| {
                        let x = at(v);
                        check::dot(check::sub(x, c), check::sub(x, c)) <= (1.5 * cell).powi(2)
                    })
                    .collect();
                let close_pair = near.iter().any(|&a| {
                    (0..mesh.surface_vertices as u32).any(|b| {
                        let d = check::sub(at(a), at(b));
                        b != a && check::dot(d, d).sqrt() < 0.3 * cell
                    })
                });
                let close_wall = near.iter().map(|&a| at(a)).any(|a| {
                    planes.iter().any(|&(axis, x)| {
                        let d = (a[axis] - x).abs();
                        d > 0.0 && d < 0.3 * cell
                    })
                });
                if close_pair || close_wall {
                    fine += 1;
                }
            }
            let what = format!("noise:16:{seed} flip {flip}");
            assert_eq!(poor.count, count, "{what}");
            assert_eq!(poor.at_sharp_edges, forced, "{what}");
            assert_eq!(poor.beside_fine_detail, fine, "{what}");
            assert_eq!(poor.others, count - forced - fine, "{what}");
            assert_eq!(poor.worst_other.is_some(), poor.others > 0, "{what}");
            seen_fine += fine;
            // Read back from a file the mesh knows no surface or walls: the faces of one
            // element in the faces of its bounding box are taken for walls (every wall, and
            // any surface triangle lying in such a face), and the sort is the same.
            let bare = TetMesh {
                positions: mesh.positions.clone(),
                tets: mesh.tets.clone(),
                ..TetMesh::default()
            };
            let (surface, walls) = bare.surface_and_walls();
            let sorted = |faces: &[[u32; 3]]| -> std::collections::HashSet<[u32; 3]> {
                faces
                    .iter()
                    .map(|f| {
                        let mut f = *f;
                        f.sort_unstable();
                        f
                    })
                    .collect()
            };
            let (found, known) = (sorted(&walls), sorted(&mesh.walls));
            assert!(found.is_superset(&known), "{what}");
            let surface_faces = sorted(&mesh.surface);
            assert!(found.difference(&known).all(|f| surface_faces.contains(f)));
            assert!(surface
                .iter()
                .all(|&v| (v as usize) < mesh.surface_vertices));
            assert_eq!(bare.poor_elements(cell, 0.3), poor, "{what}");
        }
    }
    assert!(
        seen_fine > 0,
        "no poor element beside fine detail: the test looks at nothing"
    );
}

/// Elements left outside [10°, 165°] that neither a sharp boundary edge nor surface detail
/// under the snap distance explains are rare: the improvement's second round, with a wider
/// margin around each element still outside, lifts most of those the first round leaves (on
/// these 32 meshes, 54 in 16 meshes without the second round, 7 in 4 with it). The meshes stay
/// valid.
#[test]
fn few_elements_outside_the_range_are_left_unexplained() {
    let (mut others, mut widened, mut meshes) = (0, 0, 0);
    for seed in 1..=8 {
        for sample in [Sample::Noise { seed }, Sample::PackedSpheres { seed }] {
            for flip in [false, true] {
                let grid = sample.grid(16);
                // As `isocube tetmesh` by default.
                let options = ExtractOptions::default()
                    .with_method(Method::Ternary(crate::extract::Snapping::default()))
                    .with_flip(flip);
                let mesh = tetmesh(&grid, &options).unwrap();
                assert_valid(&mesh, &format!("{sample:?} flip {flip}"));
                let poor = mesh.poor_elements(grid.spacing()[0], 0.3);
                others += poor.others;
                widened += mesh.stats.improve.widened;
                meshes += 1;
            }
        }
    }
    assert!(widened > 0, "no second round: the test looks at nothing");
    assert!(
        3 * others <= meshes,
        "{others} elements outside [10°, 165°] unexplained in {meshes} meshes"
    );
}

/// The graded mesh of `grid`, checked valid against the `uniform` one: the same surface over
/// the same vertices, the same volume, never more elements.
fn graded_like(
    grid: &Grid,
    options: &ExtractOptions,
    grading: Grading,
    uniform: &TetMesh,
    what: &str,
) -> TetMesh {
    let graded =
        tetmesh(grid, &options.with_grading(grading)).unwrap_or_else(|e| panic!("{what}: {e}"));
    let c = assert_valid(&graded, what);
    let u = uniform.check();
    assert!((c.volume - u.volume).abs() <= 1e-9 * u.volume, "{what}");
    assert_eq!(graded.surface, uniform.surface, "{what}");
    assert_eq!(
        graded.positions[..graded.surface_vertices],
        uniform.positions[..uniform.surface_vertices],
        "{what}"
    );
    assert!(graded.tets.len() <= uniform.tets.len(), "{what}");
    graded
}

/// No edge of `mesh` (on a grid of unit spacing) is longer than the diagonal of `grading`'s
/// largest cube.
fn assert_edges_within(mesh: &TetMesh, grading: Grading, what: &str) {
    let longest = (1u32 << grading.max_level) as f64 * 3f64.sqrt();
    for t in &mesh.tets {
        for a in 0..4 {
            for b in a + 1..4 {
                let [p, q] = [t[a], t[b]].map(|v| mesh.positions[v as usize]);
                let d = (0..3)
                    .map(|i| f64::from(p[i] - q[i]).powi(2))
                    .sum::<f64>()
                    .sqrt();
                assert!(d <= longest + 1e-6, "{what}: an edge of {d}");
            }
        }
    }
}

/// Graded meshes: conforming, positive, the same boundary as the uniform mesh (the surface is
/// `extract`'s) and the same volume, with fewer elements and no point in none; on smooth
/// fields with the default method every angle stays in [10°, 165°].
#[test]
fn graded_meshes_keep_the_boundary_with_fewer_elements() {
    let ternary = ExtractOptions::default().with_method(Method::Ternary(Default::default()));
    for (sample, n) in [
        (Sample::Sphere, 40),
        (Sample::Torus, 36),
        (Sample::PackedSpheres { seed: 3 }, 30),
    ] {
        let grid = sample.grid(n);
        for options in [ternary, ternary.with_flip(true), ExtractOptions::default()] {
            let uniform = tetmesh(&grid, &options.with_grading(Grading::UNIFORM)).unwrap();
            for layers in [0, 1] {
                let grading = Grading {
                    max_level: 3,
                    layers,
                };
                let what = format!("{sample:?} {n} {options:?} {grading:?}");
                let graded = graded_like(&grid, &options, grading, &uniform, &what);
                // Thin tubes and small balls hold no cube with room around it.
                let fewer = graded.tets.len() < uniform.tets.len();
                assert!(fewer || sample != Sample::Sphere, "{what}");
                assert!(graded.tets.len() <= uniform.tets.len(), "{what}");
                assert_eq!(
                    graded.positions.len(),
                    graded.surface_vertices
                        + graded.stats.grid_points
                        + graded.stats.steiner_points,
                    "{what}"
                );
                if options.method != Method::MarchingCubes
                    && !matches!(sample, Sample::PackedSpheres { .. })
                {
                    let q = graded.quality_report();
                    assert!(
                        q.min_dihedral >= 10.0 && q.max_dihedral <= 165.0,
                        "{what}: {q:?}"
                    );
                }
            }
        }
    }
}

/// Random bodies (balls with noise, on grids of random sizes) under random gradings and
/// options: valid, the uniform mesh's surface and volume, never more elements, and no edge
/// longer than the largest cube's diagonal.
#[test]
fn random_bodies_under_random_gradings() {
    let mut rng = crate::TestRng::new(51);
    let mut coarser = 0;
    for case in 0..40 {
        let dims = [0; 3].map(|_| 12 + (rng.next_u64() % 24) as usize);
        let centre = dims.map(|d| (d as f64 - 1.0) * (0.3 + 0.4 * rng.unit()));
        let radius = 4.0 + rng.unit() * dims.iter().min().copied().unwrap_or(12) as f64 * 0.6;
        let noise = 0.6 * rng.unit();
        let mut values = Vec::with_capacity(dims[0] * dims[1] * dims[2]);
        for k in 0..dims[2] {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    let d = [i, j, k]
                        .iter()
                        .zip(centre)
                        .map(|(&x, c)| (x as f64 - c).powi(2))
                        .sum::<f64>()
                        .sqrt();
                    values.push((d - radius + noise * (rng.unit() - 0.5)) as f32);
                }
            }
        }
        let grid = Grid::new(dims, values).unwrap();
        let grading = Grading {
            max_level: 1 + (rng.next_u64() % 4) as u8,
            layers: (rng.next_u64() % 3) as u8,
        };
        let options = match case % 4 {
            0 => ExtractOptions::default(),
            1 => ExtractOptions::default().with_flip(true),
            2 => ExtractOptions::default()
                .with_method(Method::Ternary(Default::default()))
                .with_flip(true),
            _ => ExtractOptions::default().with_method(Method::Ternary(Default::default())),
        };
        let what = format!("case {case} {dims:?} {grading:?} {options:?}");
        let uniform = match tetmesh(&grid, &options.with_grading(Grading::UNIFORM)) {
            Ok(mesh) => mesh,
            Err(TetError::Empty) => continue,
            Err(e) => panic!("{what}: {e}"),
        };
        let graded = graded_like(&grid, &options, grading, &uniform, &what);
        assert_eq!(graded.walls.is_empty(), uniform.walls.is_empty(), "{what}");
        coarser += usize::from(graded.tets.len() < uniform.tets.len());
        assert_edges_within(&graded, grading, &what);
    }
    assert!(coarser >= 20, "{coarser} of 40 coarsened");
}

/// Labelled volumes under random gradings: valid, the uniform mesh's boundary and interfaces
/// over the same vertices, each label's volume unchanged, fewer elements, no edge longer than
/// the largest cube's diagonal.
#[test]
fn graded_labelled_volumes_keep_their_interfaces() {
    use crate::extract::LabelOptions;
    let mut rng = crate::TestRng::new(52);
    let volumes = |mesh: &TetMesh| {
        let labels = mesh.labels.as_ref().expect("labelled");
        let mut v = vec![0.0f64; labels.names.len()];
        for (t, &l) in mesh.tets.iter().zip(&labels.tets) {
            let p = t.map(|i| mesh.positions[i as usize].map(f64::from));
            let d: [[f64; 3]; 3] =
                std::array::from_fn(|k| std::array::from_fn(|a| p[k + 1][a] - p[0][a]));
            v[l as usize] += (d[0][0] * (d[1][1] * d[2][2] - d[1][2] * d[2][1])
                - d[0][1] * (d[1][0] * d[2][2] - d[1][2] * d[2][0])
                + d[0][2] * (d[1][0] * d[2][1] - d[1][1] * d[2][0]))
                / 6.0;
        }
        v
    };
    for case in 0..8 {
        let dims = [0; 3].map(|_| 24 + (rng.next_u64() % 16) as usize);
        // Three or four labels splitting a ball (nearest of random seeds), background around.
        let seeds: Vec<[f64; 3]> = (0..3 + case % 2)
            .map(|_| std::array::from_fn(|a| dims[a] as f64 * (0.2 + 0.6 * rng.unit())))
            .collect();
        let centre = dims.map(|d| (d as f64 - 1.0) / 2.0);
        let radius = 0.42 * dims.iter().min().copied().unwrap_or(24) as f64;
        let mut values = Vec::with_capacity(dims[0] * dims[1] * dims[2]);
        for k in 0..dims[2] {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    let p = [i, j, k].map(|x| x as f64);
                    let d = |c: &[f64; 3]| (0..3).map(|a| (p[a] - c[a]).powi(2)).sum::<f64>();
                    let label = if d(&centre) > radius * radius {
                        0
                    } else {
                        1 + (0..seeds.len())
                            .min_by(|&a, &b| d(&seeds[a]).total_cmp(&d(&seeds[b])))
                            .unwrap_or(0)
                    };
                    values.push(label as f32);
                }
            }
        }
        let grid = Grid::new(dims, values).unwrap();
        let grading = Grading {
            max_level: 1 + (rng.next_u64() % 4) as u8,
            layers: (rng.next_u64() % 2) as u8,
        };
        let what = format!("case {case} {dims:?} {grading:?}");
        let options = LabelOptions::default().with_smoothing(0);
        let uniform =
            tetmesh_labels(&grid, &options.clone().with_grading(Grading::UNIFORM), None).unwrap();
        let graded = tetmesh_labels(&grid, &options.clone().with_grading(grading), None)
            .unwrap_or_else(|e| panic!("{what}: {e}"));
        assert_valid(&graded, &what);
        assert!(graded.stats.cubes > 0, "{what}");
        assert!(graded.tets.len() < uniform.tets.len(), "{what}");
        assert_eq!(graded.surface, uniform.surface, "{what}");
        assert_eq!(
            graded.positions[..graded.surface_vertices],
            uniform.positions[..uniform.surface_vertices],
            "{what}"
        );
        let (g, u) = (
            graded.labels.as_ref().unwrap(),
            uniform.labels.as_ref().unwrap(),
        );
        assert_eq!(g.interfaces, u.interfaces, "{what}");
        assert_eq!(g.pairs, u.pairs, "{what}");
        assert_eq!(g.surface, u.surface, "{what}");
        for (a, b) in volumes(&graded).iter().zip(volumes(&uniform)) {
            assert!(
                (a - b).abs() <= 1e-9 * b.abs().max(1.0),
                "{what}: {a} against {b}"
            );
        }
        assert_eq!(
            graded.positions.len(),
            graded.surface_vertices + graded.stats.grid_points + graded.stats.steiner_points,
            "{what}"
        );
        assert_edges_within(&graded, grading, &what);
    }
}

/// Long and flat cells: up to 3:1 the default grades and leaves no more elements outside
/// [10°, 165°] than the uniform mesh (the transition cubes stay inside it); beyond, the
/// interior is the uniform mesh, and the counts say why.
#[test]
fn long_cells_grade_up_to_three_to_one() {
    let outside = |mesh: &TetMesh| {
        mesh.qualities()
            .iter()
            .filter(|q| q.min_dihedral < 10.0 || q.max_dihedral > 165.0)
            .count()
    };
    let ternary = ExtractOptions::default().with_method(Method::Ternary(Default::default()));
    assert_eq!(ternary.grading, Grading::DEFAULT);
    for (spacing, graded) in [
        ([0.5, 0.5, 1.5], true),
        ([1.0, 1.0 / 3.0, 1.0], true),
        ([0.3, 0.6, 0.9], true),
        ([1.0, 1.0, 3.2], false),
        ([0.3, 1.0, 1.0], false),
    ] {
        let grid = Sample::Sphere.grid(32).with_spacing(spacing).unwrap();
        let what = format!("{spacing:?}");
        let uniform = tetmesh(&grid, &ternary.with_grading(Grading::UNIFORM)).unwrap();
        let mesh = graded_like(&grid, &ternary, Grading::DEFAULT, &uniform, &what);
        assert_eq!(mesh.stats.cells_too_long, !graded, "{what}");
        assert_eq!(mesh.stats.cubes > 0, graded, "{what}");
        assert!(!uniform.stats.cells_too_long, "{what}");
        if graded {
            assert!(mesh.tets.len() < uniform.tets.len(), "{what}");
            assert!(outside(&mesh) <= outside(&uniform), "{what}");
        } else {
            assert_eq!(mesh.tets, uniform.tets, "{what}");
        }
    }
}
