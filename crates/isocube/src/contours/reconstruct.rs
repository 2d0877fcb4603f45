//! Surfaces through a stack of sections: Marching Cubes (MC33 topology) on the stacked field,
//! heights mapped back to the sections' own, unevenly spaced planes.

use super::field::{stacked_field, PlaneGrid};
use super::SectionStack;
use crate::extract::{extract, ExtractError, ExtractOptions};
use crate::mesh::Mesh;

/// How the ends of the stack are closed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Cap {
    /// Not closed: the surface ends at the first and last sections.
    Open,
    /// The body is extrapolated this far beyond each end section, tapering to the end contours'
    /// innermost points (geologists use half the section spacing).
    Extend(f64),
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
    let extend = match cap {
        Cap::Open => None,
        Cap::Extend(d) if d.is_finite() && d > 0.0 => Some(d),
        Cap::Extend(d) => {
            return Err(ExtractError::Option {
                name: "cap extension",
                range: "a finite distance > 0",
                value: d as f32,
            })
        }
    };
    let (field, heights) = stacked_field(stack, plane, extend);
    let options = ExtractOptions::default()
        .with_flip(true)
        .with_normals(false);
    let (mut mesh, _) = extract(&field.grid, &options)?;
    // Grid z is the layer index: map it piecewise linearly onto the layers' heights. Crossings on
    // vertical edges interpolate linearly in both, so this is exact.
    let last = heights.len().saturating_sub(1);
    for p in &mut mesh.positions {
        let zi = f64::from(p[2]);
        let k = (zi.floor().max(0.0) as usize).min(last.saturating_sub(1));
        let t = zi - k as f64;
        let z = if last == 0 {
            heights[0]
        } else {
            heights[k] + t * (heights[k + 1] - heights[k])
        };
        p[2] = z as f32;
    }
    mesh.compute_normals();
    Ok(Reconstruction {
        mesh,
        evaluated: field.evaluated,
        points: field.grid.values().len(),
        active_cells: field.active_cells,
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

    fn circle(cx: f64, cy: f64, r: f64, n: usize) -> Vec<Point2> {
        (0..n)
            .map(|i| {
                let a = 2.0 * std::f64::consts::PI * i as f64 / n as f64;
                [cx + r * a.cos(), cy + r * a.sin()]
            })
            .collect()
    }

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
