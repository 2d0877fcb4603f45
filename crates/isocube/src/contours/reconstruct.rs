//! Surfaces through a stack of sections: Marching Cubes (MC33 topology) on the stacked field,
//! heights mapped back to the sections' own, unevenly spaced planes.

use super::plane::PlaneGrid;
use super::sectional::{extract_sectional, resolution, Fidelity};
use super::SectionStack;
use crate::extract::ExtractError;
use crate::mesh::Mesh;
use crate::quality::Strategy;

/// How the ends of the stack are closed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Cap {
    /// Not closed: the surface ends at the first and last sections.
    Open,
    /// The body is extrapolated this far beyond each end section, tapering to the end contours'
    /// innermost points (geologists use half the section spacing).
    Extend(f64),
    /// The end sections' contours are filled flat (holes kept open), in their planes.
    Flat,
}

impl Cap {
    /// The default caps: the body extended beyond each end section by half the mean section
    /// spacing (a quarter of the contours' larger extent for a single section), as geologists
    /// extrapolate ore bodies.
    ///
    /// ```
    /// use isocube::contours::{Cap, SectionStack};
    /// let square = |s: f64| vec![[-s, -s], [s, -s], [s, s], [-s, s]];
    /// let stack = SectionStack::from_points(vec![(0.0, vec![square(1.0)]), (4.0, vec![square(1.0)])])
    ///     .unwrap();
    /// assert_eq!(Cap::extended(&stack), Cap::Extend(2.0));
    /// ```
    pub fn extended(stack: &SectionStack) -> Cap {
        let z: Vec<f64> = stack.sections().iter().map(|s| s.z()).collect();
        let spacing = if z.len() > 1 {
            (z[z.len() - 1] - z[0]) / (z.len() - 1) as f64
        } else {
            let (lo, hi, _) = stack.bounds();
            (hi[0] - lo[0]).max(hi[1] - lo[1]) / 4.0
        };
        Cap::Extend(spacing / 2.0)
    }

    /// The distance the body is extended beyond the end sections, if any (checked).
    pub(crate) fn extension(self) -> Result<Option<f64>, ExtractError> {
        match self {
            Cap::Open | Cap::Flat => Ok(None),
            Cap::Extend(d) if d.is_finite() && d > 0.0 => Ok(Some(d)),
            Cap::Extend(d) => Err(ExtractError::Option {
                name: "cap extension",
                range: "a finite distance > 0",
                value: d as f32,
            }),
        }
    }
}

/// A reconstructed surface and what it cost.
#[derive(Clone, Debug)]
pub struct Reconstruction {
    /// The surface: outward normals and winding, positions in the contours' coordinates.
    pub mesh: Mesh,
    /// Grid points whose distance was computed.
    pub evaluated: usize,
    /// Grid points in the stacked volume.
    pub points: usize,
    /// Cells the surface passes through.
    pub active_cells: usize,
    /// Grid edges crossed more than once by parts of the contours that are not one excursion
    /// across the edge and back (two contours, or two arms of one, closer than a cell): the cut
    /// cannot follow the contours there; refine the grid. Always 0 for [`Fidelity::Plain`].
    pub unresolved_edges: usize,
    /// Contours enclosing no grid point (smaller than a cell): the surface misses them; refine
    /// the grid. Always 0 for [`Fidelity::Plain`].
    pub missed_contours: usize,
    /// The plane grid used: the one asked for, or for [`Fidelity::Exact`] a shifted or slightly
    /// finer one where the asked grid has edges a contour crosses more than once.
    pub plane: PlaneGrid,
}

/// The grid to follow the contours on: `plane` if it resolves every contour (see
/// [`Reconstruction::unresolved_edges`]), otherwise the first of a few shifted copies of it, then
/// of grids with cells 15 % and 28 % smaller, that does, or failing that the one with the fewest
/// unresolved places. The search is bounded on purpose: a grid much finer than asked is the
/// caller's decision.
fn resolving_plane(stack: &SectionStack, plane: &PlaneGrid) -> PlaneGrid {
    let score = |p: &PlaneGrid| {
        let r = resolution(stack, p);
        r.unresolved_edges + r.missed_contours
    };
    let first = score(plane);
    if first == 0 {
        return *plane;
    }
    let shifts = [[1.3371, 1.6103], [1.5813, 1.2917], [1.8127, 1.4561]];
    let mut best = (first, *plane);
    for scale in [1.0, 0.85, 0.72, 0.6, 0.5] {
        for shift in shifts {
            let p = PlaneGrid::with_cell_and_shift(stack, plane.spacing * scale, shift);
            let u = score(&p);
            if u == 0 {
                return p;
            }
            if u < best.0 {
                best = (u, p);
            }
        }
    }
    best.1
}

/// Reconstructs the surface of the body the stack's contours outline, on `plane`.
///
/// ```
/// use isocube::contours::{reconstruct, Cap, PlaneGrid, SectionStack};
/// let square = |s: f64| vec![[-s, -s], [s, -s], [s, s], [-s, s]];
/// let stack = SectionStack::from_points(vec![
///     (0.0, vec![square(1.0)]),
///     (1.5, vec![square(0.8)]),
///     (2.0, vec![square(1.2)]),
/// ])
/// .unwrap();
/// let r = reconstruct(&stack, &PlaneGrid::across(&stack, 20), Cap::Extend(0.5)).unwrap();
/// let report = r.mesh.report();
/// assert!(report.watertight && report.oriented);
/// assert_eq!((report.components, report.genus), (1, Some(0)));
/// assert!(report.volume.unwrap() > 0.0); // outward
/// ```
pub fn reconstruct(
    stack: &SectionStack,
    plane: &PlaneGrid,
    cap: Cap,
) -> Result<Reconstruction, ExtractError> {
    reconstruct_with(stack, plane, &ReconstructOptions::new(cap))
}

/// How to reconstruct: the caps, how closely to follow the contours, and how to triangulate each
/// cell's polygons.
///
/// ```
/// use isocube::contours::{Cap, Fidelity, ReconstructOptions};
/// use isocube::quality::Strategy;
/// let options = ReconstructOptions::new(Cap::Flat)
///     .with_fidelity(Fidelity::Plain)
///     .with_triangulation(Strategy::Optimal);
/// assert_eq!(options.fidelity, Fidelity::Plain);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub struct ReconstructOptions {
    /// How the ends are closed.
    pub cap: Cap,
    /// Exact contours (default) or the paper's plain crossings.
    pub fidelity: Fidelity,
    /// How each cell polygon (with its inserted contour points) is split into triangles:
    /// [`Strategy::Local`] by default; [`Strategy::Optimal`] maximises each polygon's smallest
    /// angle at about two and a half times the cost; [`Strategy::Fan`] fans from the polygon's
    /// centroid.
    pub triangulation: Strategy,
    /// The most memory the reconstruction may take, in bytes, checked against
    /// [`MeshEstimate`] before any work: a resolution past it is refused at once rather than
    /// run until the system kills it. `None`: no limit.
    pub max_memory: Option<u64>,
}

impl ReconstructOptions {
    /// Exact fidelity and local triangulation, with these caps, no memory limit.
    pub fn new(cap: Cap) -> Self {
        ReconstructOptions {
            cap,
            fidelity: Fidelity::Exact,
            triangulation: Strategy::Local,
            max_memory: None,
        }
    }

    /// With this memory limit in bytes.
    pub fn with_max_memory(self, bytes: u64) -> Self {
        ReconstructOptions {
            max_memory: Some(bytes),
            ..self
        }
    }

    /// With this fidelity.
    pub fn with_fidelity(self, fidelity: Fidelity) -> Self {
        ReconstructOptions { fidelity, ..self }
    }

    /// With this triangulation of the cell polygons.
    pub fn with_triangulation(self, triangulation: Strategy) -> Self {
        ReconstructOptions {
            triangulation,
            ..self
        }
    }
}

/// What a reconstruction will roughly make and need, from the surface's area (the walls between
/// sections: mean perimeter times the gap; the ends: their contours' area, plus an extension's
/// walls) and the plane grid's cell size.
///
/// ```
/// use isocube::contours::{Cap, MeshEstimate, PlaneGrid, SectionStack};
/// let stack = SectionStack::sample_orebody();
/// let coarse = MeshEstimate::of(&stack, &PlaneGrid::across(&stack, 40), Cap::Flat);
/// let fine = MeshEstimate::of(&stack, &PlaneGrid::across(&stack, 80), Cap::Flat);
/// assert!(fine.triangles > 3.5 * coarse.triangles);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeshEstimate {
    /// Triangles.
    pub triangles: f64,
    /// Peak bytes while reconstructing.
    pub bytes: f64,
}

impl MeshEstimate {
    /// Triangles per square cell of surface, and peak bytes per triangle, measured on the
    /// orebody at cells from 0.1 down to 0.005 (0.80 triangles and 60–74 bytes), rounded up.
    const TRIANGLES_PER_CELL_AREA: f64 = 0.9;
    const BYTES_PER_TRIANGLE: f64 = 80.0;

    /// The estimate for `stack` on `plane` with these caps.
    pub fn of(stack: &SectionStack, plane: &PlaneGrid, cap: Cap) -> MeshEstimate {
        let sections = stack.sections();
        let perimeter = |k: usize| -> f64 {
            sections[k]
                .contours()
                .iter()
                .flat_map(|c| c.segments())
                .map(|(a, b)| ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)).sqrt())
                .sum()
        };
        let area = |k: usize| -> f64 {
            sections[k]
                .contours()
                .iter()
                .map(|c| c.signed_area().abs())
                .sum()
        };
        let walls: f64 = (1..sections.len())
            .map(|k| {
                0.5 * (perimeter(k - 1) + perimeter(k)) * (sections[k].z() - sections[k - 1].z())
            })
            .sum();
        let last = sections.len() - 1;
        let ends = match cap {
            Cap::Open => 0.0,
            Cap::Flat => area(0) + area(last),
            Cap::Extend(d) => area(0) + area(last) + d * (perimeter(0) + perimeter(last)),
        };
        let triangles = Self::TRIANGLES_PER_CELL_AREA * (walls + ends) / plane.spacing.powi(2);
        MeshEstimate {
            triangles,
            bytes: triangles * Self::BYTES_PER_TRIANGLE,
        }
    }
}

/// [`reconstruct`] with a choice of [`ReconstructOptions`].
pub fn reconstruct_with(
    stack: &SectionStack,
    plane: &PlaneGrid,
    options: &ReconstructOptions,
) -> Result<Reconstruction, ExtractError> {
    let (cap, fidelity) = (options.cap, options.fidelity);
    if let Some(limit) = options.max_memory {
        // A tiny cell on a large body can ask for more triangles than memory holds: refused
        // before starting rather than killed half-way.
        let estimate = MeshEstimate::of(stack, plane, cap);
        if estimate.bytes > limit as f64 {
            return Err(ExtractError::MemoryLimit {
                cell: plane.spacing,
                triangles: estimate.triangles,
                bytes: estimate.bytes,
                limit,
            });
        }
    }
    if cap == Cap::Flat {
        let open = ReconstructOptions {
            cap: Cap::Open,
            ..*options
        };
        let mut r = reconstruct_with(stack, plane, &open)?;
        let sections = stack.sections();
        for z in [sections[0].z(), sections[sections.len() - 1].z()] {
            super::cap::close_plane(&mut r.mesh, z as f32)
                .map_err(|reason| ExtractError::Cap { z, reason })?;
        }
        r.mesh.compute_normals();
        return Ok(r);
    }
    let extend = cap.extension()?;
    if stack.sections().len() < 2 && extend.is_none() {
        return Err(ExtractError::SingleSection);
    }
    let plane = match fidelity {
        Fidelity::Exact => resolving_plane(stack, plane),
        Fidelity::Plain => *plane,
    };
    let (mesh, stats) =
        extract_sectional(stack, &plane, extend, fidelity, options.triangulation, None)?;
    Ok(Reconstruction {
        mesh,
        evaluated: stats.evaluated,
        points: stats.points,
        active_cells: stats.active_cells,
        unresolved_edges: stats.unresolved_edges,
        missed_contours: stats.missed_contours,
        plane,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contours::Point2;

    fn square(cx: f64, cy: f64, s: f64) -> Vec<Point2> {
        vec![
            [cx - s, cy - s],
            [cx + s, cy - s],
            [cx + s, cy + s],
            [cx - s, cy + s],
        ]
    }

    use crate::contours::test_circle as circle;

    fn build(sections: Vec<(f64, Vec<Vec<Point2>>)>, cells: usize, cap: Cap) -> Reconstruction {
        let stack = SectionStack::from_points(sections).unwrap();
        reconstruct(&stack, &PlaneGrid::across(&stack, cells), cap).unwrap()
    }

    #[test]
    fn a_prism_closes_into_a_sphere_like_body() {
        let r = build(
            vec![
                (0.0, vec![square(0.0, 0.0, 1.0)]),
                (3.0, vec![square(0.0, 0.0, 1.0)]),
            ],
            16,
            Cap::Extend(0.5),
        );
        let rep = r.mesh.report();
        assert!(rep.watertight && rep.oriented, "{rep:?}");
        assert_eq!((rep.components, rep.genus), (1, Some(0)));
        // Between the sections the body is the 2 × 2 prism (the cut of a square by MC is exact
        // on grid-aligned sides): volume at least the prism's 12, at most with caps added.
        let v = rep.volume.unwrap();
        assert!(v > 11.0 && v < 12.0 + 2.0 * 4.0 * 0.5, "{v}");
        let zs: Vec<f32> = r.mesh.positions.iter().map(|p| p[2]).collect();
        let (lo, hi) = zs
            .iter()
            .fold((f32::MAX, f32::MIN), |(a, b), &z| (a.min(z), b.max(z)));
        assert!(lo >= -0.5 - 1e-6 && hi <= 3.5 + 1e-6, "{lo} {hi}");
        assert!(r.evaluated < r.points);
    }

    #[test]
    fn a_hole_through_the_sections_makes_a_handle() {
        let ring = |z: f64| {
            (
                z,
                vec![circle(0.0, 0.0, 3.0, 48), circle(0.2, 0.0, 1.2, 24)],
            )
        };
        let r = build(
            vec![ring(0.0), ring(1.0), ring(2.5), ring(3.0)],
            40,
            Cap::Extend(0.5),
        );
        let rep = r.mesh.report();
        assert!(rep.watertight && rep.oriented, "{rep:?}");
        assert_eq!((rep.components, rep.genus), (1, Some(1)));
        assert!(rep.volume.unwrap() > 0.0);
    }

    #[test]
    fn the_sample_ore_body_is_one_closed_surface_of_genus_one() {
        let stack = SectionStack::sample_orebody();
        for cells in [20, 40, 80] {
            let r =
                reconstruct(&stack, &PlaneGrid::across(&stack, cells), Cap::Extend(6.0)).unwrap();
            let rep = r.mesh.report();
            assert!(rep.watertight && rep.oriented, "{cells}: {rep:?}");
            assert_eq!((rep.components, rep.genus), (1, Some(1)), "{cells}");
            assert!(rep.volume.unwrap() > 0.0);
        }
    }

    /// The mesh's cut by every section plane is the input contour (both directions of the
    /// Hausdorff distance within 1e-6 of the bounding-box diagonal), where the plain approach is
    /// off by a fraction of a cell.
    #[test]
    fn cuts_follow_the_contours_exactly() {
        let stack = SectionStack::sample_orebody();
        let (lo, hi, z) = stack.bounds();
        let diag =
            ((hi[0] - lo[0]).powi(2) + (hi[1] - lo[1]).powi(2) + (z[1] - z[0]).powi(2)).sqrt();
        for cells in [20, 40, 160] {
            let plane = PlaneGrid::across(&stack, cells);
            let exact = reconstruct(&stack, &plane, Cap::Extend(6.0)).unwrap();
            let d = cut_distance(&exact.mesh, &stack);
            assert_eq!(exact.unresolved_edges, 0, "{cells}");
            assert!(
                d.contour_to_cut <= 1e-6 * diag && d.cut_to_contour <= 1e-6 * diag,
                "{cells}: {d:?}"
            );
            let options = ReconstructOptions::new(Cap::Extend(6.0)).with_fidelity(Fidelity::Plain);
            let plain = reconstruct_with(&stack, &plane, &options).unwrap();
            let p = cut_distance(&plain.mesh, &stack);
            assert!(
                p.contour_to_cut > 1e3 * d.contour_to_cut.max(1e-9),
                "{cells}: {p:?}"
            );
        }
    }

    use proptest::prelude::*;

    /// A star-shaped contour around `(cx, cy)`: simple whatever the radii.
    fn star(cx: f64, cy: f64, radii: &[f64], phase: f64, hole: bool) -> Vec<Point2> {
        let n = radii.len();
        let mut p: Vec<Point2> = (0..n)
            .map(|i| {
                let a = phase + 2.0 * std::f64::consts::PI * i as f64 / n as f64;
                [cx + radii[i] * a.cos(), cy + radii[i] * a.sin()]
            })
            .collect();
        if hole {
            p.reverse();
        }
        p
    }

    /// A stack of 2–4 star contours (one or two lobes, sometimes a hole) at uneven spacing.
    fn star_stack(layers: &[(f64, Vec<f64>, f64, u8)]) -> SectionStack {
        let mut z = 0.0;
        let mut sections = Vec::new();
        for (dz, radii, phase, kind) in layers {
            z += dz;
            let mut contours = vec![star(0.0, 0.0, radii, *phase, false)];
            if kind & 1 == 1 {
                contours.push(star(5.0, 1.0, radii, phase + 1.0, false));
            }
            if kind & 2 == 2 {
                let small: Vec<f64> = radii.iter().map(|r| 0.3 * r).collect();
                contours.push(star(0.1, 0.0, &small, *phase, true));
            }
            sections.push((z, contours));
        }
        SectionStack::from_points(sections).unwrap()
    }

    fn diagonal(stack: &SectionStack) -> f64 {
        let (lo, hi, z) = stack.bounds();
        ((hi[0] - lo[0]).powi(2) + (hi[1] - lo[1]).powi(2) + (z[1] - z[0]).powi(2)).sqrt()
    }

    /// Reconstructs with flat or extension caps and checks the surface is closed, oriented
    /// outward.
    fn closed(
        stack: &SectionStack,
        plane: &PlaneGrid,
        flat: bool,
    ) -> Result<Reconstruction, TestCaseError> {
        let cap = if flat { Cap::Flat } else { Cap::Extend(0.5) };
        let r = reconstruct(stack, plane, cap).unwrap();
        let rep = r.mesh.report();
        prop_assert!(rep.watertight && rep.oriented, "{:?}", rep);
        prop_assert!(rep.volume.unwrap() > 0.0);
        Ok(r)
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 400, failure_persistence: None, ..ProptestConfig::default() })]

        /// Random stacks whose features are coarser than the grid but whose sharp corners poke
        /// through grid edges all the time (almost every case folds excursions): watertight,
        /// oriented outward, every contour followed, and every section's cut is its contours
        /// (Hausdorff both ways within 1e-6 of the bounding-box diagonal).
        #[test]
        fn random_stacks_keep_their_contours(
            layers in proptest::collection::vec(
                (0.5f64..3.0, proptest::collection::vec(0.8f64..1.2, 10..32), 0.0f64..6.3, 0u8..4),
                2..5,
            ),
            cells in 12usize..48,
            flat: bool,
        ) {
            let stack = star_stack(&layers);
            let diag = diagonal(&stack);
            let asked = PlaneGrid::across(&stack, cells);
            let r = closed(&stack, &asked, flat)?;
            prop_assert_eq!((r.unresolved_edges, r.missed_contours), (0, 0));
            // The asked grid is kept whenever it resolves the contours.
            let asked_resolution = resolution(&stack, &asked);
            if asked_resolution.unresolved_edges + asked_resolution.missed_contours == 0 {
                prop_assert_eq!(r.plane, asked);
            }
            let d = cut_distance(&r.mesh, &stack);
            prop_assert!(d.contour_to_cut <= 1e-6 * diag && d.cut_to_contour <= 1e-6 * diag, "{:?}", d);
        }

        /// The sectional cells on the engine: however the (x, y, layer) grid's cells are cut into
        /// boxes (along every axis, single cells, any order), the joined mesh is the one-pass
        /// mesh, to the bit, for both fidelities, every triangulation and either cap.
        #[test]
        fn any_partition_of_the_sectional_cells_gives_one_mesh(
            layers in proptest::collection::vec(
                (0.5f64..3.0, proptest::collection::vec(0.8f64..1.2, 10..24), 0.0f64..6.3, 0u8..4),
                2..4,
            ),
            cells in 4usize..14,
            extend: bool,
            exact: bool,
            strategy in 0u8..3,
            seed: u64,
        ) {
            use super::super::sectional::extract_sectional;
            let stack = star_stack(&layers);
            let plane = PlaneGrid::across(&stack, cells);
            let extend = extend.then_some(0.7);
            let fidelity = if exact { Fidelity::Exact } else { Fidelity::Plain };
            let strategy = [crate::quality::Strategy::Fan, crate::quality::Strategy::Local, crate::quality::Strategy::Optimal][usize::from(strategy)];
            let (one, stats) = extract_sectional(&stack, &plane, extend, fidelity, strategy, None).unwrap();
            let layer_count = stack.sections().len() + if extend.is_some() { 2 } else { 0 };
            let dims = [plane.dims[0], plane.dims[1], layer_count];
            let mut rng = crate::TestRng::new(seed);
            let boxes = crate::random_partition(dims, &mut rng);
            let (cut, cut_stats) =
                extract_sectional(&stack, &plane, extend, fidelity, strategy, Some(&boxes)).unwrap();
            prop_assert_eq!(&cut, &one, "boxes {:?}", boxes);
            prop_assert_eq!(cut_stats.active_cells, stats.active_cells);
        }

        /// Spiky stacks with needles thinner than a cell, which no grid of that size can follow
        /// everywhere: the surface is still closed and oriented, and wherever the grid resolves
        /// the contours the cut is exact.
        #[test]
        fn needles_thinner_than_a_cell_keep_the_surface_closed(
            layers in proptest::collection::vec(
                (0.5f64..3.0, proptest::collection::vec(0.6f64..1.3, 10..64), 0.0f64..6.3, 0u8..4),
                2..5,
            ),
            cells in 12usize..48,
            flat: bool,
        ) {
            let stack = star_stack(&layers);
            let r = closed(&stack, &PlaneGrid::across(&stack, cells), flat)?;
            if r.unresolved_edges + r.missed_contours == 0 {
                let diag = diagonal(&stack);
                let d = cut_distance(&r.mesh, &stack);
                prop_assert!(d.contour_to_cut <= 1e-6 * diag && d.cut_to_contour <= 1e-6 * diag, "{:?}", d);
            }
        }
    }

    /// A corner poking through a grid edge whose ends are both outside: the excursion is folded
    /// into the piece it leaves from, the asked grid is kept, and the cut is exact.
    #[test]
    fn an_excursion_across_a_grid_edge_is_followed() {
        // A square body with a thin spike whose tip crosses the grid line x = 2 between two
        // grid points, then comes back.
        let plane = PlaneGrid {
            origin: [-2.0, -2.0],
            spacing: 1.0,
            dims: [6, 6],
        };
        let body = vec![
            [-0.5, -0.5],
            [1.5, -0.5],
            [1.5, 0.3],
            [2.3, 0.5],
            [1.5, 0.7],
            [1.5, 1.5],
            [-0.5, 1.5],
        ];
        let stack =
            SectionStack::from_points(vec![(0.0, vec![body.clone()]), (1.0, vec![body])]).unwrap();
        let res = resolution(&stack, &plane);
        assert_eq!(
            (res.unresolved_edges, res.missed_contours, res.folded),
            (0, 0, 2)
        );
        for cap in [Cap::Flat, Cap::Extend(0.5)] {
            let r = reconstruct(&stack, &plane, cap).unwrap();
            assert_eq!(r.plane, plane);
            let rep = r.mesh.report();
            assert!(
                rep.watertight && rep.oriented && rep.volume.unwrap() > 0.0,
                "{rep:?}"
            );
            let d = cut_distance(&r.mesh, &stack);
            assert!(d.contour_to_cut < 1e-6 && d.cut_to_contour < 1e-6, "{d:?}");
            // The spike's tip is a mesh vertex.
            assert!(r.mesh.positions.iter().any(|p| p[0] == 2.3 && p[1] == 0.5));
        }
    }

    /// Two contours closer than a cell cross one grid edge between them, and a contour smaller
    /// than a cell encloses no grid point: both are reported, and a finer grid is chosen.
    #[test]
    fn what_a_grid_cannot_follow_is_reported() {
        let plane = PlaneGrid {
            origin: [-2.0, -2.0],
            spacing: 1.0,
            dims: [8, 6],
        };
        let a = vec![[-0.5, -0.5], [0.3, -0.5], [0.3, 1.5], [-0.5, 1.5]];
        let b = vec![[0.6, -0.5], [2.5, -0.5], [2.5, 1.5], [0.6, 1.5]];
        let tiny = vec![[3.2, 0.2], [3.6, 0.2], [3.6, 0.6], [3.2, 0.6]];
        let stack = SectionStack::from_points(vec![
            (0.0, vec![a.clone(), b.clone(), tiny.clone()]),
            (1.0, vec![a, b, tiny]),
        ])
        .unwrap();
        let res = resolution(&stack, &plane);
        assert!(res.unresolved_edges > 0, "{res:?}");
        assert_eq!(res.missed_contours, 2, "{res:?}");
        let r = reconstruct(&stack, &plane, Cap::Flat).unwrap();
        assert!(r.plane.spacing < plane.spacing);
        let rep = r.mesh.report();
        assert!(rep.watertight && rep.oriented, "{rep:?}");
    }

    /// Found by the needle property: a grid point a hair inside a contour put vertical crossings
    /// within single-precision rounding of the first section's plane, adding edges to its cut.
    #[test]
    fn crossings_next_to_a_section_stay_off_its_plane() {
        let a: Vec<f64> = {
            let mut v = vec![0.6; 51];
            v[28] = 1.2665175580941979;
            v[29] = 0.6824057746140384;
            v[31] = 1.235053445738214;
            v
        };
        let b: Vec<f64> = {
            let mut v = vec![0.6; 26];
            v[12] = 1.272585696967887;
            v
        };
        let c: Vec<f64> = {
            let mut v = vec![0.6; 44];
            v[20] = 0.990271264530644;
            v[34] = 1.2859655461294672;
            v
        };
        let layers = vec![
            (0.5, a, 0.8285119418228813, 1u8),
            (0.5, b, 0.22351948150465245, 0),
            (0.5, c, 0.47431296112946736, 1),
        ];
        let stack = star_stack(&layers);
        let asked = PlaneGrid::across(&stack, 45);
        let r = reconstruct(&stack, &asked, Cap::Extend(0.5)).unwrap();
        assert_eq!((r.unresolved_edges, r.missed_contours), (0, 0));
        let d = cut_distance(&r.mesh, &stack);
        let diag = diagonal(&stack);
        assert!(
            d.contour_to_cut <= 1e-6 * diag && d.cut_to_contour <= 1e-6 * diag,
            "{d:?}"
        );
        assert_eq!(r.mesh.report().degenerate, 0);
    }

    /// A star of `n` points of radius 0.6 with spikes (index, radius).
    fn spiky(n: usize, spikes: &[(usize, f64)]) -> Vec<f64> {
        let mut radii = vec![0.6; n];
        for &(i, r) in spikes {
            radii[i] = r;
        }
        radii
    }

    /// Flat caps on a grid of `cells`: closed, outward, no flat triangle, and the cut exact
    /// wherever the grid resolves the contours.
    fn assert_closed_with_flat_caps(layers: &[(f64, Vec<f64>, f64, u8)], cells: usize) {
        let stack = star_stack(layers);
        let r = reconstruct(&stack, &PlaneGrid::across(&stack, cells), Cap::Flat).unwrap();
        let rep = r.mesh.report();
        assert!(
            rep.watertight && rep.oriented && rep.degenerate == 0,
            "{rep:?}"
        );
        assert!(rep.volume.unwrap() > 0.0);
        if r.unresolved_edges + r.missed_contours == 0 {
            let d = cut_distance(&r.mesh, &stack);
            let diag = diagonal(&stack);
            assert!(
                d.contour_to_cut <= 1e-6 * diag && d.cut_to_contour <= 1e-6 * diag,
                "{d:?}"
            );
        }
    }

    /// Found by the needle property: a vertex of a second lobe 3e-7 cells from a grid line,
    /// which single precision put on its crossing (flat caps, 33 cells): three boundary edges
    /// and a flat triangle.
    #[test]
    fn needles_of_a_second_lobe_keep_the_surface_closed() {
        let b = spiky(
            30,
            &[
                (2, 0.6684641029114624),
                (3, 0.7079800684870328),
                (11, 1.2763638404262168),
                (12, 0.8710067132473372),
                (22, 1.2498566809685014),
            ],
        );
        assert_closed_with_flat_caps(
            &[
                (0.5, vec![0.6; 36], 0.0, 0),
                (0.5, b, 0.4827244410469335, 1),
            ],
            33,
        );
    }

    /// Found by the needle property too: a contour passing within rounding of a grid point,
    /// whose crossings on two of its edges single precision made one point (44 cells).
    #[test]
    fn needles_over_a_plain_section_keep_the_surface_closed() {
        let b = spiky(
            45,
            &[
                (3, 1.2961796453956875),
                (14, 1.2131794955024298),
                (19, 1.295475400706063),
                (20, 0.9695121385949563),
                (36, 1.2432864733715838),
            ],
        );
        assert_closed_with_flat_caps(
            &[
                (0.5, vec![0.6; 12], 0.0, 0),
                (0.5, b, 2.8305106346173656, 0),
            ],
            44,
        );
    }

    /// A section without contours ends the body: it closes between the last contour and it.
    #[test]
    fn an_empty_section_ends_the_body() {
        for cap in [Cap::Flat, Cap::Extend(0.5), Cap::Open] {
            let r = build(
                vec![
                    (0.0, vec![circle(0.0, 0.0, 2.0, 30)]),
                    (1.0, vec![circle(0.0, 0.0, 2.0, 30)]),
                    (2.0, vec![]),
                ],
                20,
                cap,
            );
            let rep = r.mesh.report();
            assert!(rep.oriented && rep.degenerate == 0, "{cap:?}: {rep:?}");
            let top = r
                .mesh
                .positions
                .iter()
                .map(|p| p[2])
                .fold(f32::MIN, f32::max);
            assert!(top > 1.0 && top < 2.0, "{cap:?}: {top}");
            if cap != Cap::Open {
                assert!(rep.watertight && rep.genus == Some(0), "{cap:?}: {rep:?}");
            }
        }
    }

    /// Layer pairs are meshed in parallel; the mesh is the same with one thread or several.
    #[test]
    fn output_does_not_depend_on_the_thread_count() {
        let stack = SectionStack::sample_orebody();
        let plane = PlaneGrid::across(&stack, 60);
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| reconstruct(&stack, &plane, Cap::Extend(6.0)).unwrap().mesh)
        };
        let one = run(1);
        for threads in [2, 3] {
            let many = run(threads);
            assert_eq!(one.positions, many.positions, "{threads}");
            assert_eq!(one.triangles, many.triangles, "{threads}");
        }
    }

    /// Triangles passing through a section plane count in the cut: a box from z = −1 to 1 with
    /// no vertex at z = 0 is cut along its square.
    #[test]
    fn cut_includes_triangles_through_the_plane() {
        let mut mesh = Mesh::new();
        for z in [-1.0f32, 1.0] {
            for [x, y] in [[-1.0f32, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]] {
                mesh.positions.push([x, y, z]);
            }
        }
        for k in 0..4u32 {
            let (a, b) = (k, (k + 1) % 4);
            mesh.triangles.push([a, b, b + 4]);
            mesh.triangles.push([a, b + 4, a + 4]);
        }
        let stack =
            |s: f64| SectionStack::from_points(vec![(0.0, vec![square(0.0, 0.0, s)])]).unwrap();
        let d = cut_distance(&mesh, &stack(1.0));
        assert!(
            d.contour_to_cut < 1e-12 && d.cut_to_contour < 1e-12,
            "{d:?}"
        );
        let d = cut_distance(&mesh, &stack(0.75));
        assert!((d.contour_to_cut - 0.25).abs() < 1e-12, "{d:?}");
        assert!(
            (d.cut_to_contour - 0.25 * 2f64.sqrt()).abs() < 1e-12,
            "{d:?}"
        );
    }

    #[test]
    fn flat_caps_close_in_the_end_planes() {
        // A 2 × 2 × 3 box: exact caps and cuts; between the sections only the corner cells
        // bend a little.
        let r = build(
            vec![
                (0.0, vec![square(0.0, 0.0, 1.0)]),
                (3.0, vec![square(0.0, 0.0, 1.0)]),
            ],
            16,
            Cap::Flat,
        );
        let rep = r.mesh.report();
        assert!(rep.watertight && rep.oriented, "{rep:?}");
        assert_eq!((rep.components, rep.genus), (1, Some(0)));
        assert!((rep.volume.unwrap() - 12.0).abs() < 0.002 * 12.0, "{rep:?}");
        assert!(
            (rep.area - (2.0 * 4.0 + 4.0 * 6.0)).abs() < 0.005 * 32.0,
            "{rep:?}"
        );
        // The ore body: a hole through the bottom section stays open in the cap.
        let stack = SectionStack::sample_orebody();
        for cells in [20, 40, 100] {
            let r = reconstruct(&stack, &PlaneGrid::across(&stack, cells), Cap::Flat).unwrap();
            let rep = r.mesh.report();
            assert!(rep.watertight && rep.oriented, "{cells}: {rep:?}");
            assert_eq!((rep.components, rep.genus), (1, Some(1)), "{cells}");
            assert!(rep.volume.unwrap() > 0.0 && rep.degenerate == 0);
            let (lo, hi, z) = stack.bounds();
            let diag =
                ((hi[0] - lo[0]).powi(2) + (hi[1] - lo[1]).powi(2) + (z[1] - z[0]).powi(2)).sqrt();
            let zs = r.mesh.positions.iter().map(|p| f64::from(p[2]));
            assert!(
                zs.clone().fold(f64::MAX, f64::min) >= z[0] && zs.fold(f64::MIN, f64::max) <= z[1]
            );
            let d = cut_distance(&r.mesh, &stack);
            assert!(d.contour_to_cut <= 1e-6 * diag, "{d:?}");
        }
    }

    #[test]
    fn a_branch_keeps_one_body() {
        let r = build(
            vec![
                (0.0, vec![circle(0.0, 0.0, 3.0, 40)]),
                (
                    1.0,
                    vec![circle(-1.5, 0.0, 1.2, 30), circle(1.6, 0.0, 1.1, 30)],
                ),
                (
                    2.0,
                    vec![circle(-1.8, 0.0, 1.0, 30), circle(1.9, 0.0, 1.0, 30)],
                ),
            ],
            40,
            Cap::Extend(0.5),
        );
        let rep = r.mesh.report();
        assert!(rep.watertight && rep.oriented, "{rep:?}");
        assert_eq!((rep.components, rep.genus), (1, Some(0)));
    }

    #[test]
    fn open_ends_leave_boundaries_on_the_end_planes_only() {
        let r = build(
            vec![
                (1.0, vec![circle(0.0, 0.0, 2.0, 30)]),
                (2.0, vec![circle(0.3, 0.0, 1.8, 30)]),
            ],
            24,
            Cap::Open,
        );
        let mesh = &r.mesh;
        let rep = mesh.report();
        assert!(rep.boundary_edges > 0 && rep.nonmanifold_edges == 0 && rep.oriented);
        let mut uses = std::collections::HashMap::new();
        for t in &mesh.triangles {
            for k in 0..3 {
                let (a, b) = (t[k].min(t[(k + 1) % 3]), t[k].max(t[(k + 1) % 3]));
                *uses.entry((a, b)).or_insert(0) += 1;
            }
        }
        for ((a, b), n) in uses {
            if n == 1 {
                let (za, zb) = (mesh.positions[a as usize][2], mesh.positions[b as usize][2]);
                assert!(
                    za == zb && (za == 1.0 || za == 2.0),
                    "open edge at z {za}, {zb}"
                );
            }
        }
        assert!(reconstruct(
            &SectionStack::from_points(vec![(0.0, vec![square(0.0, 0.0, 1.0)])]).unwrap(),
            &PlaneGrid::with_cell(
                &SectionStack::from_points(vec![(0.0, vec![square(0.0, 0.0, 1.0)])]).unwrap(),
                0.5
            ),
            Cap::Extend(f64::NAN)
        )
        .is_err());
    }
}

/// How far a mesh's cuts by the section planes are from the input contours, both ways (the two
/// halves of the Hausdorff distance), in the contours' units. The cut at a section is the set of
/// mesh edges whose both ends lie on its plane; both sides are sampled at their vertices and at
/// seven interior points per segment.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CutDistance {
    /// Largest distance from a contour point to the mesh's cut.
    pub contour_to_cut: f64,
    /// Largest distance from a point of the cut to the contours.
    pub cut_to_contour: f64,
}

/// Measures [`CutDistance`] for every section and returns the worst. The cut at a section is
/// made of the mesh edges in its plane that border a triangle leaving the plane (so the inside
/// of a flat cap does not count), and of the segments where triangles pass through the plane.
pub fn cut_distance(mesh: &Mesh, stack: &SectionStack) -> CutDistance {
    let mut worst = CutDistance {
        contour_to_cut: 0.0,
        cut_to_contour: 0.0,
    };
    let samples = |a: [f64; 2], b: [f64; 2]| {
        (0..=8).map(move |k| {
            let t = f64::from(k) / 8.0;
            [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]
        })
    };
    for section in stack.sections() {
        let z = section.z() as f32;
        // The cut: edges in the plane with a triangle on them that leaves the plane (edges inside
        // a flat cap have only in-plane triangles on both sides).
        let in_plane = |t: &[u32; 3]| t.iter().all(|&v| mesh.positions[v as usize][2] == z);
        let mut cut: Vec<([f64; 2], [f64; 2])> = Vec::new();
        for t in &mesh.triangles {
            if in_plane(t) {
                continue;
            }
            for k in 0..3 {
                let (a, b) = (t[k].min(t[(k + 1) % 3]), t[k].max(t[(k + 1) % 3]));
                let (p, q) = (mesh.positions[a as usize], mesh.positions[b as usize]);
                if p[2] == z && q[2] == z {
                    cut.push((
                        [f64::from(p[0]), f64::from(p[1])],
                        [f64::from(q[0]), f64::from(q[1])],
                    ));
                }
            }
            // A triangle passing through the plane (corners strictly on both sides) cuts it
            // along a segment too.
            let corners = t.map(|v| mesh.positions[v as usize].map(f64::from));
            let side = corners.map(|c| (c[2] - f64::from(z)).signum() as i8);
            if side.contains(&1) && side.contains(&-1) {
                let zf = f64::from(z);
                let mut ends = Vec::with_capacity(2);
                for k in 0..3 {
                    let (p, q) = (corners[k], corners[(k + 1) % 3]);
                    if (p[2] - zf) * (q[2] - zf) < 0.0 {
                        let u = (zf - p[2]) / (q[2] - p[2]);
                        ends.push([p[0] + u * (q[0] - p[0]), p[1] + u * (q[1] - p[1])]);
                    } else if p[2] == zf {
                        ends.push([p[0], p[1]]);
                    }
                }
                if let [a, b] = ends[..] {
                    cut.push((a, b));
                }
            }
        }
        // Edges used by two triangles appear twice with a < b once each way round: dedupe.
        cut.sort_by(|x, y| x.partial_cmp(y).expect("finite"));
        cut.dedup();
        for &(a, b) in &cut {
            for p in samples(a, b) {
                worst.cut_to_contour = worst.cut_to_contour.max(section.distance(p));
            }
        }
        for c in section.contours() {
            for (a, b) in c.segments() {
                for p in samples(a, b) {
                    let d = cut
                        .iter()
                        .map(|&(u, w)| super::segment_distance(p, u, w))
                        .fold(f64::INFINITY, f64::min);
                    worst.contour_to_cut = worst.contour_to_cut.max(d);
                }
            }
        }
    }
    worst
}
