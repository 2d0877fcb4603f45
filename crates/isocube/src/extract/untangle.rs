//! Tunnels that cross themselves, with their interior points moved.
//!
//! Marching Cubes 33's tunnels are stored as one triangulation per case: a band joining two of
//! the cell's loops, through interior points where the rule that keeps meshes manifold forbids a
//! direct band (see [`crate::cube::triangulate`]). The interior points sit at the centroid of
//! some of the loops' corners. With the crossings where some cells put them, the tube's long
//! triangles then pass through each other: about a third of the tunnels in random cells (the
//! extract tests count them). Such a surface is still closed but not embedded: no region has it
//! as its boundary, and a volume mesher cannot fill it.
//!
//! Where a cell's triangles cross (decided by exact predicates on the stored positions), its
//! interior points are moved — to the first of a fixed list of places in the cell, the nearest
//! first, where nothing crosses. The triangles stay the table's (the same topology, the same
//! edges, so neighbours are unaffected); only where the points are changes.

use super::place::{clamp_into, Bounds};
use crate::mesh::intersect::{collinear, first_crossing};

/// New places for the interior points `movable` (local vertex numbers into `positions`) at which
/// the triangles (which cross, see [`crosses`]) cross nothing, in the order of `movable`; `None`
/// when no place tried helps. Places keep to `bounds` and are rounded as stored (`f32`).
pub(super) fn untangle(
    tris: &[[u32; 3]],
    positions: &[[f64; 3]],
    movable: &[u32],
    bounds: &Bounds,
) -> Option<Vec<[f64; 3]>> {
    if movable.is_empty() {
        return None;
    }
    let (lo, hi) = *bounds;
    let current: Vec<[f64; 3]> = movable.iter().map(|&v| positions[v as usize]).collect();
    let n = current.len() as f64;
    let mean: [f64; 3] = std::array::from_fn(|d| current.iter().map(|p| p[d]).sum::<f64>() / n);
    // Each candidate moves all the points by one offset (a ring keeps its shape), their mean to
    // one of 7³ places spread over the cell.
    let mut offsets: Vec<[f64; 3]> = Vec::new();
    const STEPS: [f64; 7] = [0.1, 0.25, 0.4, 0.5, 0.6, 0.75, 0.9];
    for x in STEPS {
        for y in STEPS {
            for z in STEPS {
                let p = [
                    lo[0] + x * (hi[0] - lo[0]),
                    lo[1] + y * (hi[1] - lo[1]),
                    lo[2] + z * (hi[2] - lo[2]),
                ];
                offsets.push(std::array::from_fn(|d| p[d] - mean[d]));
            }
        }
    }
    let length = |o: &[f64; 3]| o.iter().map(|x| x * x).sum::<f64>();
    offsets.sort_by(|a, b| {
        length(a)
            .total_cmp(&length(b))
            .then(a.partial_cmp(b).expect("finite"))
    });
    let mut moved = positions.to_vec();
    for offset in offsets {
        for (k, &v) in movable.iter().enumerate() {
            let p: [f64; 3] = std::array::from_fn(|d| current[k][d] + offset[d]);
            moved[v as usize] = clamp_into(p, bounds).map(|c| f64::from(c as f32));
        }
        let at = |v: u32| moved[v as usize];
        if !degenerate(tris, &moved) && first_crossing(tris, &at).is_none() {
            return Some(movable.iter().map(|&v| moved[v as usize]).collect());
        }
    }
    None
}

/// Whether the triangles (none of no area) cross each other.
pub(super) fn crosses(tris: &[[u32; 3]], positions: &[[f64; 3]]) -> bool {
    !degenerate(tris, positions) && first_crossing(tris, &|v: u32| positions[v as usize]).is_some()
}

/// Whether a triangle has no area (values at the level put several crossings on one grid point:
/// crossing is not the question there).
fn degenerate(tris: &[[u32; 3]], positions: &[[f64; 3]]) -> bool {
    tris.iter()
        .any(|t| collinear(t.map(|v| positions[v as usize])))
}
