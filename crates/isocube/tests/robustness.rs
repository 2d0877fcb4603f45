//! Property tests of the whole pipeline on arbitrary input, through the public API: random fields
//! (NaN, infinities, extreme and subnormal values, every method and option), random contour
//! stacks (anything the contour types accept) and random polygon cages (bad indices, repeated
//! vertices, non-manifold edges, stray tags). Nothing panics; what is accepted keeps its
//! invariants, and what is refused is refused with an error.

use isocube::contours::{
    reconstruct_with, Cap, Fidelity, PlaneGrid, Point2, ReconstructOptions, SectionStack,
};
use isocube::cube::Topology;
use isocube::extract::{extract, ExtractOptions, Method, SnapPosition, Snapping};
use isocube::field::Grid;
use isocube::quality::Strategy as Triangulation;
use isocube::subdiv::{
    limit_positions, subdivide, BoundaryRule, Face, HoleMethod, PolyMesh, SubdivOptions,
};
use proptest::prelude::*;

/// A value for an arbitrary field: mostly ordinary (with ties), sometimes extreme.
fn field_value() -> impl Strategy<Value = f32> {
    prop_oneof![
        8 => (-4i8..=4).prop_map(|x| f32::from(x) / 2.0),
        2 => -1.0e3f32..1.0e3,
        1 => prop_oneof![
            Just(f32::MAX),
            Just(f32::MIN),
            Just(f32::MIN_POSITIVE),
            Just(-1.0e-40f32),
            Just(1.0e-40f32),
            Just(-0.0f32),
            Just(f32::NAN),
            Just(f32::INFINITY),
            Just(f32::NEG_INFINITY),
        ],
    ]
}

fn options() -> impl Strategy<Value = ExtractOptions> {
    (
        prop_oneof![4 => (-4i8..=4).prop_map(|x| f32::from(x) / 2.0), 1 => Just(f32::MAX), 1 => Just(-1.0e-40f32)],
        any::<bool>(),
        any::<bool>(),
        any::<bool>(),
        prop_oneof![Just(Triangulation::Fan), Just(Triangulation::Local), Just(Triangulation::Optimal)],
        0usize..3,
        proptest::option::of((0.0f32..1.0, 0.0f32..=0.5, any::<bool>())),
    )
        .prop_map(|(level, flip, normals, classic, strategy, relax, ternary)| {
            let mut o = ExtractOptions::default()
                .with_level(level)
                .with_flip(flip)
                .with_normals(normals)
                .with_topology(if classic { Topology::Classic } else { Topology::Mc33 })
                .with_triangulation(strategy)
                .with_relax(relax);
            if let Some((zero_threshold, snap, on_grid)) = ternary {
                o = o.with_method(Method::Ternary(
                    Snapping::default()
                        .with_zero_threshold(zero_threshold)
                        .with_snap(snap)
                        .with_position(if on_grid { SnapPosition::GridPoint } else { SnapPosition::NearestCrossing }),
                ));
            }
            o
        })
}

fn arbitrary_grid() -> impl Strategy<Value = Grid> {
    (2usize..7, 2usize..7, 2usize..6)
        .prop_flat_map(|(a, b, c)| {
            (
                Just([a, b, c]),
                proptest::collection::vec(field_value(), a * b * c),
            )
        })
        .prop_map(|(dims, values)| Grid::new(dims, values).unwrap())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 3_000, failure_persistence: None, ..ProptestConfig::default() })]

    /// Arbitrary fields under arbitrary valid options: extraction succeeds, skips exactly the
    /// cells with a non-finite corner, and gives an indexed, finite, edge-manifold, oriented mesh
    /// with a unit normal per vertex when asked for.
    #[test]
    fn arbitrary_fields_give_valid_meshes(grid in arbitrary_grid(), options in options()) {
        let (mesh, stats) = extract(&grid, &options).unwrap();
        mesh.validate().unwrap();
        prop_assert!(mesh.positions.iter().flatten().all(|c| c.is_finite()));
        let [nx, ny, nz] = grid.dims();
        let bad = (0..nz - 1)
            .flat_map(|k| (0..ny - 1).flat_map(move |j| (0..nx - 1).map(move |i| [i, j, k])))
            .filter(|&[i, j, k]| {
                (0..8).any(|c| !grid.value(i + (c & 1), j + (c >> 1 & 1), k + (c >> 2)).is_finite())
            })
            .count();
        prop_assert_eq!(stats.skipped_cells, bad);
        let r = mesh.report();
        prop_assert_eq!(r.nonmanifold_edges, 0);
        prop_assert!(r.oriented);
        if options.normals {
            prop_assert_eq!(mesh.normals.len(), mesh.positions.len());
            for n in &mesh.normals {
                let len = n.iter().map(|c| c * c).sum::<f32>().sqrt();
                prop_assert!(n.iter().all(|c| c.is_finite()) && (len - 1.0).abs() < 1e-3, "{:?}", n);
            }
        }
    }
}

/// A wild contour: a star around a centre, with radii on a coarse lattice so that collinear,
/// repeated and touching points come up often (most are refused).
fn wild_contour() -> impl Strategy<Value = Vec<Point2>> {
    (
        (-4i8..4, -4i8..4),
        proptest::collection::vec(0u8..6, 0..9),
        any::<bool>(),
    )
        .prop_map(|((cx, cy), radii, close)| {
            let n = radii.len().max(1) as f64;
            let mut pts: Vec<Point2> = radii
                .iter()
                .enumerate()
                .map(|(i, &r)| {
                    let a = std::f64::consts::TAU * i as f64 / n;
                    let r = f64::from(r) * 0.5;
                    [
                        f64::from(cx) * 0.5 + r * a.cos(),
                        f64::from(cy) * 0.5 + r * a.sin(),
                    ]
                })
                .collect();
            if close && !pts.is_empty() {
                pts.push(pts[0]);
            }
            pts
        })
}

/// A simple star-shaped polygon around `centre`, its radii between 0.6 and 1 times `scale`.
fn star(centre: Point2, scale: f64) -> impl Strategy<Value = Vec<Point2>> {
    proptest::collection::vec(0.6f64..1.0, 3..12).prop_map(move |radii| {
        let n = radii.len() as f64;
        radii
            .iter()
            .enumerate()
            .map(|(i, r)| {
                let a = std::f64::consts::TAU * i as f64 / n;
                [
                    centre[0] + scale * r * a.cos(),
                    centre[1] + scale * r * a.sin(),
                ]
            })
            .collect()
    })
}

/// A section's contours: mostly valid (a body, perhaps a hole in it and an island beside it,
/// at shifting places), sometimes wild.
fn section_contours() -> impl Strategy<Value = Vec<Vec<Point2>>> {
    let valid = (-1.0f64..1.0, -1.0f64..1.0, any::<bool>(), any::<bool>()).prop_flat_map(
        |(dx, dy, hole, island)| {
            let c = [dx, dy];
            (
                star(c, 2.0),
                star(c, 0.7).prop_map(move |s| hole.then_some(s)),
                star([dx + 5.0, dy], 1.0).prop_map(move |s| island.then_some(s)),
            )
                .prop_map(|(body, hole, island)| {
                    std::iter::once(body)
                        .chain(hole)
                        .chain(island)
                        .collect::<Vec<_>>()
                })
        },
    );
    prop_oneof![
        4 => valid,
        1 => proptest::collection::vec(wild_contour(), 0..4),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 600, failure_persistence: None, ..ProptestConfig::default() })]

    /// Arbitrary stacks: the contour types refuse what is not a set of simple, non-crossing
    /// polygons; whatever they accept reconstructs, at any grid, cap, fidelity and
    /// triangulation, into an indexed, finite, edge-manifold, oriented mesh, closed when the
    /// ends are extended.
    #[test]
    fn arbitrary_contour_stacks_reconstruct_or_are_refused(
        sections in proptest::collection::vec((-3i8..6, section_contours()), 1..5),
        cells in 2usize..40,
        cap in 0u8..3,
        plain: bool,
        strategy in prop_oneof![Just(Triangulation::Fan), Just(Triangulation::Local), Just(Triangulation::Optimal)],
    ) {
        let mut sections: Vec<(f64, Vec<Vec<Point2>>)> =
            sections.into_iter().map(|(z, cs)| (f64::from(z) * 0.75, cs)).collect();
        sections.sort_by(|a, b| a.0.total_cmp(&b.0));
        let Ok(stack) = SectionStack::from_points(sections) else {
            return Ok(());
        };
        let cap = [Cap::Open, Cap::Flat, Cap::Extend(0.4)][usize::from(cap)];
        let options = ReconstructOptions::new(cap)
            .with_fidelity(if plain { Fidelity::Plain } else { Fidelity::Exact })
            .with_triangulation(strategy);
        let result = reconstruct_with(&stack, &PlaneGrid::across(&stack, cells), &options);
        // The one refusal of an accepted stack: a single section closes only by extension.
        if stack.sections().len() == 1 && !matches!(cap, Cap::Extend(_)) {
            prop_assert!(result.is_err());
            return Ok(());
        }
        let r = result.unwrap();
        r.mesh.validate().unwrap();
        prop_assert!(r.mesh.positions.iter().flatten().all(|c| c.is_finite()));
        let rep = r.mesh.report();
        prop_assert_eq!(rep.nonmanifold_edges, 0);
        prop_assert!(rep.oriented);
        if matches!(cap, Cap::Extend(_)) && r.mesh.triangle_count() > 0 {
            prop_assert!(rep.watertight, "{:?}", rep);
        }
    }
}

/// One way to damage a cage.
#[derive(Clone, Debug)]
enum Damage {
    /// Replace a face's vertex by another index (maybe out of range, maybe already in it).
    Index {
        face: usize,
        at: usize,
        to: u32,
    },
    /// Add a face over existing vertices (a third face on an edge, a repeated face, a sliver).
    Face(Vec<u32>),
    /// Drop a face (opens a boundary).
    Drop(usize),
    /// Reverse a face (inconsistent orientation).
    Reverse(usize),
    /// An inner loop on a face.
    Inner {
        face: usize,
        lp: Vec<u32>,
    },
    /// A crease between any two vertices, or a corner on any vertex.
    Crease(u32, u32, f32),
    Corner(u32, f32),
    /// Hole tags on some faces.
    Holes(Vec<bool>),
    /// A vertex moved onto another (coincident points).
    Collapse(usize, usize),
}

fn damage() -> impl Strategy<Value = Damage> {
    prop_oneof![
        (0usize..64, 0usize..8, 0u32..40).prop_map(|(face, at, to)| Damage::Index { face, at, to }),
        proptest::collection::vec(0u32..40, 0..6).prop_map(Damage::Face),
        (0usize..64).prop_map(Damage::Drop),
        (0usize..64).prop_map(Damage::Reverse),
        (0usize..64, proptest::collection::vec(0u32..40, 0..5))
            .prop_map(|(face, lp)| Damage::Inner { face, lp }),
        (0u32..40, 0u32..40, 0.0f32..12.0).prop_map(|(a, b, s)| Damage::Crease(a, b, s)),
        (0u32..40, 0.0f32..12.0).prop_map(|(v, s)| Damage::Corner(v, s)),
        proptest::collection::vec(any::<bool>(), 0..64).prop_map(Damage::Holes),
        (0usize..40, 0usize..40).prop_map(|(a, b)| Damage::Collapse(a, b)),
    ]
}

/// A cage: one of the built-in cages (quads, faces with holes, creases) or a random quad patch,
/// with up to three kinds of damage (none a quarter of the time).
fn cage() -> impl Strategy<Value = PolyMesh> {
    let base = prop_oneof![
        (0usize..4)
            .prop_map(
                |i| isocube::subdiv::samples::sample(isocube::subdiv::samples::SAMPLES[i]).unwrap()
            ),
        (
            1usize..4,
            1usize..4,
            proptest::collection::vec(-0.3f64..0.3, 16)
        )
            .prop_map(|(nu, nv, bumps)| {
                let mut m = PolyMesh::default();
                for j in 0..=nv {
                    for i in 0..=nu {
                        let k = (i + j * (nu + 1)) % bumps.len();
                        m.positions.push([i as f64, j as f64, bumps[k]]);
                    }
                }
                let at = |i: usize, j: usize| (i + j * (nu + 1)) as u32;
                for j in 0..nv {
                    for i in 0..nu {
                        m.faces.push(Face::new(vec![
                            at(i, j),
                            at(i + 1, j),
                            at(i + 1, j + 1),
                            at(i, j + 1),
                        ]));
                    }
                }
                m
            }),
    ];
    (
        base,
        prop_oneof![1 => Just(Vec::new()), 3 => proptest::collection::vec(damage(), 1..4)],
        proptest::option::of(0u8..3),
    )
        .prop_map(|(mut m, damages, rule)| {
            let nf = m.faces.len().max(1);
            let nv = m.positions.len().max(1);
            for d in damages {
                match d {
                    Damage::Index { face, at, to } => {
                        if let Some(f) = m.faces.get_mut(face % nf) {
                            let len = f.outer.len().max(1);
                            if let Some(v) = f.outer.get_mut(at % len) {
                                *v = to;
                            }
                        }
                    }
                    Damage::Face(outer) => m.faces.push(Face::new(outer)),
                    Damage::Drop(face) => {
                        if face % nf < m.faces.len() {
                            m.faces.remove(face % nf);
                            m.holes.clear();
                        }
                    }
                    Damage::Reverse(face) => {
                        if let Some(f) = m.faces.get_mut(face % nf) {
                            f.outer.reverse();
                        }
                    }
                    Damage::Inner { face, lp } => {
                        if let Some(f) = m.faces.get_mut(face % nf) {
                            f.inner.push(lp);
                        }
                    }
                    Damage::Crease(a, b, s) => m.set_crease(a, b, s),
                    Damage::Corner(v, s) => {
                        m.corners.insert(v, s);
                    }
                    Damage::Holes(h) => m.holes = h,
                    Damage::Collapse(a, b) => {
                        let p = m.positions[a % nv];
                        if let Some(q) = m.positions.get_mut(b % nv) {
                            *q = p;
                        }
                    }
                }
            }
            if let Some(r) = rule {
                m.boundary = Some(
                    [
                        BoundaryRule::None,
                        BoundaryRule::EdgeAndCorner,
                        BoundaryRule::EdgeOnly,
                    ][usize::from(r)],
                );
            }
            m
        })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 4_000, failure_persistence: None, ..ProptestConfig::default() })]

    /// Arbitrary cages: subdivision either refuses the cage with an error or gives a valid,
    /// finite mesh whose faces triangulate; limit positions likewise.
    #[test]
    fn arbitrary_cages_subdivide_or_are_refused(
        cage in cage(),
        levels in 0usize..3,
        sharp: bool,
        rule in proptest::option::of(0u8..3),
    ) {
        let mut options = SubdivOptions::default();
        options.boundary = rule.map(|r| [BoundaryRule::None, BoundaryRule::EdgeAndCorner, BoundaryRule::EdgeOnly][usize::from(r)]);
        options.holes = if sharp { HoleMethod::Sharp } else { HoleMethod::Smooth };
        if let Ok(fine) = subdivide(&cage, levels, &options) {
            fine.validate().unwrap();
            prop_assert!(fine.positions.iter().flatten().all(|c| c.is_finite()));
            // Faces with inner loops triangulate only when their geometry allows: with distinct
            // vertices and faces with holes that lie in a plane, if the cage's do, the refined
            // faces' must. (Coincident vertices, or a face with a hole bent out of its plane,
            // can make refined loops overlap: an error, never a panic; see
            // `a_bent_face_with_a_hole_is_refused_after_refinement`.)
            let distinct = {
                let mut p = cage.positions.clone();
                p.sort_by(|a, b| a.partial_cmp(b).unwrap());
                p.windows(2).all(|w| w[0] != w[1])
            };
            match fine.triangulate() {
                Ok(mesh) => mesh.validate().unwrap(),
                Err(e) => prop_assert!(
                    !distinct || !holed_faces_planar(&cage) || cage.triangulate().is_err(),
                    "{e}"
                ),
            }
            if let Ok(limit) = limit_positions(&fine) {
                prop_assert_eq!(limit.len(), fine.positions.len());
                prop_assert!(limit.iter().flatten().all(|c| c.is_finite()));
            }
        }
    }
}

/// Whether every face with inner loops has all its vertices in one plane (to a relative 1e-9).
fn holed_faces_planar(cage: &PolyMesh) -> bool {
    cage.faces.iter().filter(|f| !f.inner.is_empty()).all(|f| {
        let at = |v: &u32| cage.positions.get(*v as usize).copied();
        let Some(points) = f
            .outer
            .iter()
            .chain(f.inner.iter().flatten())
            .map(at)
            .collect::<Option<Vec<_>>>()
        else {
            return false;
        };
        // Newell's normal of the outer loop, and every point's distance to its plane.
        let outer = &points[..f.outer.len()];
        let mut n = [0.0f64; 3];
        for (i, a) in outer.iter().enumerate() {
            let b = outer[(i + 1) % outer.len()];
            n[0] += (a[1] - b[1]) * (a[2] + b[2]);
            n[1] += (a[2] - b[2]) * (a[0] + b[0]);
            n[2] += (a[0] - b[0]) * (a[1] + b[1]);
        }
        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        let scale = points.iter().flatten().fold(1.0f64, |m, c| m.max(c.abs()));
        len > 0.0
            && points.iter().all(|p| {
                let d = (0..3).map(|k| (p[k] - outer[0][k]) * n[k]).sum::<f64>() / len;
                d.abs() <= 1e-9 * scale
            })
    })
}

/// The case the property test above found (recorded when the claim was narrowed to planar
/// faces with holes): a box whose top face has a square hole, its outer loop bent down to a
/// bottom corner. Subdivided sharply twice, the refined outer and inner loops overlap as the
/// triangulation sees them: the triangulation says so, and nothing panics.
#[test]
fn a_bent_face_with_a_hole_is_refused_after_refinement() {
    let positions = vec![
        [-2.0, -2.0, 0.0],
        [2.0, -2.0, 0.0],
        [2.0, 2.0, 0.0],
        [-2.0, 2.0, 0.0],
        [-2.0, -2.0, 1.0],
        [2.0, -2.0, 1.0],
        [2.0, 2.0, 1.0],
        [-2.0, 2.0, 1.0],
        [-0.5, -0.5, 1.0],
        [0.5, -0.5, 1.0],
        [0.5, 0.5, 1.0],
        [-0.5, 0.5, 1.0],
        [-0.5, -0.5, 1.5],
        [0.5, -0.5, 1.5],
        [0.5, 0.5, 1.5],
        [-0.5, 0.5, 1.5],
    ];
    let mut faces = vec![Face::new(vec![3, 2, 1, 0])];
    let mut top = Face::new(vec![4, 5, 6, 3]);
    top.inner = vec![vec![11, 10, 9, 8]];
    faces.push(top);
    for outer in [
        [12, 13, 14, 15],
        [0, 1, 5, 4],
        [1, 2, 6, 5],
        [2, 3, 7, 6],
        [3, 0, 4, 7],
        [8, 9, 13, 12],
        [9, 10, 14, 13],
        [10, 11, 15, 14],
        [11, 8, 12, 15],
    ] {
        faces.push(Face::new(outer.to_vec()));
    }
    let mut cage = PolyMesh::default();
    cage.positions.extend(positions);
    cage.faces.extend(faces);
    assert!(!holed_faces_planar(&cage));
    assert!(cage.triangulate().is_ok());
    let mut options = SubdivOptions::default();
    options.holes = HoleMethod::Sharp;
    let fine = subdivide(&cage, 2, &options).expect("the cage subdivides");
    fine.validate().unwrap();
    let err = fine
        .triangulate()
        .expect_err("the refined loops overlap")
        .to_string();
    assert!(err.contains("inner loops"), "{err}");
}
