//! Tetrahedra of the body between sections, for finite elements.

use super::field::stacked_field;
use super::plane::PlaneGrid;
use super::reconstruct::Cap;
use super::SectionStack;
use crate::extract::{ExtractError, ExtractOptions};
use crate::field::Grid;
use crate::volume::{TetError, TetMesh};

/// Fills the body the stack's contours outline with tetrahedra ([`crate::volume::tetmesh`] on
/// the stacked field): the grid is `plane` across and the sections (with the extension layers
/// of [`Cap::Extend`]) along `z`, each at its own height. Crossings interpolate the signed
/// distances, as in [`super::Fidelity::Plain`]: the body's cut by a section plane is within a
/// fraction of a cell of the contour, not on it. With [`Cap::Flat`] the body ends at the end
/// sections, and the boundary there is [`TetMesh::walls`]; [`Cap::Open`] bounds no volume and
/// is refused.
///
/// Sections are usually much further apart than the plane grid's cells, and elements that
/// long are poor for finite elements. With `layer_spacing`, each gap between neighbouring
/// layers longer than it is split evenly by planes where the field is interpolated linearly
/// between the two layers, as Marching Cubes interpolates along the vertical edges: the body's
/// cut by every section stays the same, the surface between follows the same trilinear field
/// more closely, and the elements are about as tall as they are wide with `plane.spacing`.
/// `None` keeps the sections only: the surface is then `reconstruct`'s with
/// [`super::Fidelity::Plain`] (the same triangles over the same vertices, but for the points
/// the two place inside cells on MC33's tunnels).
///
/// `options` are the volume mesher's (method, snapping, topology, triangulation, memory); the
/// level must be 0 (the contours), and [`ExtractOptions::flip`] meshes the space around the
/// body instead, within the grid's box.
///
/// ```
/// use isocube::contours::{tetmesh, Cap, PlaneGrid, SectionStack};
/// use isocube::extract::ExtractOptions;
/// let stack = SectionStack::sample_orebody();
/// let plane = PlaneGrid::across(&stack, 24);
/// let options = ExtractOptions::default();
/// let tets = tetmesh(&stack, &plane, Cap::Extend(6.0), Some(plane.spacing), &options).unwrap();
/// let check = tets.check();
/// assert!(check.conforming && check.inverted == 0);
/// assert!((check.volume - check.enclosed).abs() <= 1e-9 * check.enclosed);
/// // Extended caps close the body inside the grid: no boundary on the grid's faces.
/// assert!(tets.walls.is_empty());
/// ```
pub fn tetmesh(
    stack: &SectionStack,
    plane: &PlaneGrid,
    cap: Cap,
    layer_spacing: Option<f64>,
    options: &ExtractOptions,
) -> Result<TetMesh, TetError> {
    if options.level != 0.0 {
        return Err(TetError::Unsupported(
            "a contour stack's body is meshed at its contours: the level must be 0",
        ));
    }
    if let Some(d) = layer_spacing.filter(|d| !(d.is_finite() && *d > 0.0)) {
        return Err(ExtractError::Option {
            name: "layer spacing",
            range: "a finite distance > 0",
            value: d as f32,
        }
        .into());
    }
    if cap == Cap::Open {
        return Err(TetError::Unsupported(
            "an open stack bounds no volume: close its ends (flat or extended)",
        ));
    }
    let extend = cap.extension()?;
    if stack.sections().len() < 2 && extend.is_none() {
        return Err(ExtractError::SingleSection.into());
    }
    // The layers' heights (the sections', and the caps' ends), then the planes between.
    let mut coarse: Vec<f64> = stack.sections().iter().map(|s| s.z()).collect();
    if let Some(d) = extend {
        coarse.insert(0, coarse[0] - d);
        coarse.push(coarse[coarse.len() - 1] + d);
    }
    let splits: Vec<usize> = coarse
        .windows(2)
        .map(|w| match layer_spacing {
            // At most a million planes per gap: beyond that memory says no anyway.
            Some(d) => ((w[1] - w[0]) / d).ceil().clamp(1.0, 1e6) as usize,
            None => 1,
        })
        .collect();
    let planes = 1 + splits.iter().sum::<usize>();
    if let Some(limit) = options.max_memory {
        // The field is held whole: four bytes a point, before any element.
        let bytes = (plane.dims[0] as u64)
            .saturating_mul(plane.dims[1] as u64)
            .saturating_mul(planes as u64 * 4);
        if bytes > limit {
            return Err(TetError::Memory { bytes, limit });
        }
    }
    let (field, heights) = stacked_field(stack, plane, extend);
    debug_assert_eq!(heights, coarse);
    let (grid, heights) = split_layers(&field.grid, &heights, &splits)?;
    drop(field);
    let view = grid
        .view()
        .with_heights(&heights)
        .map_err(ExtractError::Grid)?;
    // The field is positive inside: the body is the side at or above the level.
    let options = ExtractOptions {
        flip: !options.flip,
        ..*options
    };
    crate::volume::tetmesh(view, &options)
}

/// The field with gap `g` between layers split into `splits[g]` even steps, values interpolated
/// linearly between the two layers, and the planes' heights.
fn split_layers(
    grid: &Grid,
    heights: &[f64],
    splits: &[usize],
) -> Result<(Grid, Vec<f64>), TetError> {
    let [nx, ny, _] = grid.dims();
    let layer = nx * ny;
    let values = grid.values();
    let planes = 1 + splits.iter().sum::<usize>();
    let mut out = Vec::new();
    out.try_reserve_exact(layer * planes)
        .map_err(|_| TetError::Memory {
            bytes: (layer * planes * 4) as u64,
            limit: 0,
        })?;
    let mut z = Vec::with_capacity(planes);
    for (g, &n) in splits.iter().enumerate() {
        let (a, b) = (
            &values[g * layer..][..layer],
            &values[(g + 1) * layer..][..layer],
        );
        for s in 0..n {
            let t = s as f64 / n as f64;
            z.push(heights[g] + t * (heights[g + 1] - heights[g]));
            if s == 0 {
                out.extend_from_slice(a);
            } else {
                out.extend(
                    a.iter()
                        .zip(b)
                        .map(|(&u, &v)| (f64::from(u) + t * (f64::from(v) - f64::from(u))) as f32),
                );
            }
        }
    }
    z.push(heights[heights.len() - 1]);
    out.extend_from_slice(&values[splits.len() * layer..][..layer]);
    let grid = Grid::new([nx, ny, planes], out)
        .and_then(|g| g.with_spacing(grid.spacing()))
        .and_then(|g| g.with_origin([grid.origin()[0], grid.origin()[1], 0.0]))
        .map_err(ExtractError::Grid)?;
    Ok((grid, z))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contours::{cut_distance, reconstruct_with, Fidelity, ReconstructOptions};
    use crate::extract::{Method, SnapPosition, Snapping};
    use crate::mesh::Mesh;
    use crate::quality::Strategy;

    fn check(tets: &TetMesh) {
        let c = tets.check();
        assert!(c.conforming && c.inverted == 0, "{c:?}");
        let rel = (c.volume - c.enclosed).abs() / c.enclosed.abs();
        assert!(rel <= 1e-9, "{rel:e}");
    }

    /// The boundary is the plain reconstruction's surface (same triangles over the same
    /// positions) with extension caps, and ends at the end sections with flat ones; every
    /// vertex lies on a layer or between two.
    #[test]
    fn the_sample_ore_body_fills_conforming_between_its_sections() {
        let stack = SectionStack::sample_orebody();
        let z: Vec<f64> = stack.sections().iter().map(|s| s.z()).collect();
        for cells in [16, 30] {
            let plane = PlaneGrid::across(&stack, cells);
            for method in [
                Method::MarchingCubes,
                Method::Ternary(
                    Snapping::default()
                        .with_snap(0.3)
                        .with_position(SnapPosition::GridPoint),
                ),
            ] {
                let options = ExtractOptions::default().with_method(method);
                let split = Some(plane.spacing);
                let extended = tetmesh(&stack, &plane, Cap::Extend(6.0), split, &options).unwrap();
                check(&extended);
                assert!(extended.walls.is_empty());
                let flat = tetmesh(&stack, &plane, Cap::Flat, split, &options).unwrap();
                check(&flat);
                assert!(!flat.walls.is_empty());
                for p in &flat.positions {
                    let h = f64::from(p[2]);
                    assert!(h >= z[0] - 1e-4 && h <= z[z.len() - 1] + 1e-4, "{h}");
                }
                for w in &flat.walls {
                    let h = w.map(|v| f64::from(flat.positions[v as usize][2]));
                    let end = |e: f64| h.iter().all(|&x| x == f64::from(e as f32));
                    assert!(
                        end(z[0]) || end(z[z.len() - 1]),
                        "{:?} {w:?} surface {} grid {} steiner {}",
                        w.map(|v| flat.positions[v as usize]),
                        flat.surface_vertices,
                        flat.stats.grid_points,
                        flat.stats.steiner_points
                    );
                }
                // The flat body is the extended one cut at the end sections.
                assert!(flat.check().volume < extended.check().volume);
            }
            // The surface is the plain reconstruction's, within a fraction of a cell of the
            // contours on every section.
            let options = ExtractOptions::default().with_triangulation(Strategy::Local);
            let tets = tetmesh(&stack, &plane, Cap::Extend(6.0), None, &options).unwrap();
            let surface = Mesh {
                positions: tets.positions[..tets.surface_vertices].to_vec(),
                triangles: tets.surface.clone(),
                ..Mesh::default()
            };
            let plain = reconstruct_with(
                &stack,
                &plane,
                &ReconstructOptions::new(Cap::Extend(6.0)).with_fidelity(Fidelity::Plain),
            )
            .unwrap();
            // The same triangles over the same vertices, but for the points MC33 puts inside a
            // cell (tunnels), which the two meshers place differently: such a vertex, found in
            // one mesh only, compares as a wildcard.
            let bits = |m: &Mesh| -> std::collections::HashSet<[u32; 3]> {
                m.positions.iter().map(|p| p.map(f32::to_bits)).collect()
            };
            let shared: Vec<[u32; 3]> = bits(&surface)
                .intersection(&bits(&plain.mesh))
                .copied()
                .collect();
            let canon = |m: &Mesh| {
                let mut t: Vec<[[u32; 3]; 3]> = m
                    .triangles
                    .iter()
                    .map(|t| {
                        let p = t.map(|v| {
                            let b = m.positions[v as usize].map(f32::to_bits);
                            if shared.contains(&b) {
                                b
                            } else {
                                [u32::MAX; 3]
                            }
                        });
                        let r = (0..3).min_by_key(|&r| p[r]).unwrap();
                        [p[r], p[(r + 1) % 3], p[(r + 2) % 3]]
                    })
                    .collect();
                t.sort_unstable();
                t
            };
            assert_eq!(canon(&surface), canon(&plain.mesh), "{cells}");
            let own = surface.positions.len() - shared.len();
            assert!(
                own * 100 <= surface.positions.len(),
                "{cells}: {own} of {}",
                surface.positions.len()
            );
            let report = surface.report();
            assert!(report.watertight && report.oriented, "{report:?}");
            assert_eq!(report.genus, Some(1));
            let d = cut_distance(&surface, &stack);
            let p = cut_distance(&plain.mesh, &stack);
            assert!(d.contour_to_cut < plane.spacing, "{d:?}");
            assert!(
                (d.contour_to_cut - p.contour_to_cut).abs() < 1e-3 * plane.spacing,
                "{d:?} {p:?}"
            );
        }
    }

    /// Planes between the sections: the cut by every section is the same as without them, the
    /// body's volume close to it, the elements far better shaped.
    #[test]
    fn planes_between_sections_keep_the_cuts_and_mend_the_shapes() {
        let stack = SectionStack::sample_orebody();
        let plane = PlaneGrid::across(&stack, 24);
        // Uniform: the layers' cells, not cubes of them, make the count.
        let options = ExtractOptions::default().with_grading(crate::volume::Grading::UNIFORM);
        let coarse = tetmesh(&stack, &plane, Cap::Extend(6.0), None, &options).unwrap();
        let fine = tetmesh(
            &stack,
            &plane,
            Cap::Extend(6.0),
            Some(plane.spacing),
            &options,
        )
        .unwrap();
        check(&fine);
        let surface = |t: &TetMesh| Mesh {
            positions: t.positions[..t.surface_vertices].to_vec(),
            triangles: t.surface.clone(),
            ..Mesh::default()
        };
        let (a, b) = (surface(&coarse), surface(&fine));
        let report = b.report();
        assert!(
            report.watertight && report.oriented && report.genus == Some(1),
            "{report:?}"
        );
        let (da, db) = (cut_distance(&a, &stack), cut_distance(&b, &stack));
        assert!(
            (da.contour_to_cut - db.contour_to_cut).abs() < 1e-4 * plane.spacing
                && (da.cut_to_contour - db.cut_to_contour).abs() < 1e-4 * plane.spacing,
            "{da:?} {db:?}"
        );
        let (va, vb) = (a.report().volume.unwrap(), report.volume.unwrap());
        assert!((va - vb).abs() < 0.05 * va, "{va} {vb}");
        assert!(fine.tets.len() > 3 * coarse.tets.len());
        // With ternary snapping the elements between sections are as good as the grid's
        // elsewhere; with the sections alone they are long and flat (the improvement step
        // lifts the worst of them, but not into the range, and the rest stay stretched).
        let ternary = options.with_method(Method::Ternary(
            Snapping::default()
                .with_snap(0.3)
                .with_position(SnapPosition::GridPoint),
        ));
        let q = |split| {
            let t = tetmesh(&stack, &plane, Cap::Extend(6.0), split, &ternary).unwrap();
            check(&t);
            t.quality_report()
        };
        let (qa, qb) = (q(None), q(Some(plane.spacing)));
        assert!(
            qb.min_dihedral >= 10.0 && qb.max_dihedral <= 165.0,
            "{qb:?}"
        );
        assert!(
            qa.min_dihedral < 10.0 && qa.mean_radius_ratio > 1.5 * qb.mean_radius_ratio,
            "{qa:?}"
        );
    }

    #[test]
    fn open_caps_other_levels_and_single_sections_are_refused() {
        let stack = SectionStack::sample_orebody();
        let plane = PlaneGrid::across(&stack, 12);
        let options = ExtractOptions::default();
        assert!(matches!(
            tetmesh(&stack, &plane, Cap::Open, None, &options),
            Err(TetError::Unsupported(_))
        ));
        assert!(matches!(
            tetmesh(&stack, &plane, Cap::Flat, None, &options.with_level(1.0)),
            Err(TetError::Unsupported(_))
        ));
        let one = SectionStack::new(vec![stack.sections()[0].clone()]).unwrap();
        assert!(matches!(
            tetmesh(&one, &plane, Cap::Flat, None, &options),
            Err(TetError::Extract(ExtractError::SingleSection))
        ));
        check(&tetmesh(&one, &plane, Cap::Extend(5.0), Some(2.0), &options).unwrap());
        assert!(matches!(
            tetmesh(&stack, &plane, Cap::Flat, Some(0.0), &options),
            Err(TetError::Extract(ExtractError::Option { .. }))
        ));
        assert!(matches!(
            tetmesh(
                &stack,
                &plane,
                Cap::Flat,
                None,
                &options.with_max_memory(Some(1000))
            ),
            Err(TetError::Memory { .. })
        ));
    }
}
