//! Tunnels that would cross themselves, mended.
//!
//! Marching Cubes 33's tunnels are stored as one triangulation per case: a band joining two of
//! the cell's loops, through interior points where the rule that keeps meshes manifold forbids a
//! direct band (see [`crate::cube::triangulate`]). With the crossings where some cells put them,
//! the tube's long triangles pass through each other (about a third of the tunnels in random
//! cells). Such a surface is still closed but not embedded: no region has it as its boundary,
//! and a volume mesher cannot fill it.
//!
//! Where a tunnel cell's triangles cross (exact predicates on the stored positions), [`mend`]
//! finds triangles that do not: the same ones with the interior points moved, else another band
//! between the same two loops. Only the tube changes: its loops, and so every edge on the
//! cell's faces, stay the table's, so neighbours are unaffected, and the result depends on the
//! cell's values alone (the same whatever the chunks or threads).

use super::place::{centroid_in, clamp_into, Bounds};
use crate::cube::polygons::Corner;
use crate::cube::table::CellTriangles;
use crate::cube::triangulate::band_at;
use crate::mesh::intersect::{collinear, first_crossing};
use crate::mesh::{cross, dot, sub};

/// A tunnel cell's triangles that cross nothing, and where their interior points go
/// (`interiors[k]` for [`Corner::interior`]`(k)`, rounded as stored).
pub(super) struct Mended {
    pub triangles: Vec<[Corner; 3]>,
    pub interiors: Vec<[f64; 3]>,
}

/// Mends a tunnel cell whose triangles (`cell`, the tunnel joining loops `l1` and `l2`) cross
/// each other with the crossings at `position` (edge corners; `f32` values as stored), or
/// have a triangle of no area through an interior point lying between two crossings: `None`
/// when they do neither (a triangle of no area between crossings on one grid point: they
/// touch, they do not cross), or when nothing tried helps.
///
/// Tried in order, the first that crosses nothing: the table's triangles with the interior
/// points moved ([`untangle`]); a band searched anew on the actual crossings under the table's
/// rule for rungs ([`band_at`]), direct or through one interior point at the loops' centroid,
/// the middle of their centroids or the cell centre; bands through a ring of interior points
/// ([`rings`]). The cell's other triangles (disks) stay. `same` maps a corner to the one whose
/// vertex it shares (ternary cells collapse crossings onto zero points; the identity otherwise):
/// triangles are tested as they will be emitted, those with a repeated vertex dropped. A new
/// band is taken only if `accept` takes it (the mesher's own rules once collapsed).
pub(super) fn mend(
    cell: &CellTriangles,
    (l1, l2): (&[Corner], &[Corner]),
    position: &dyn Fn(Corner) -> [f64; 3],
    same: &dyn Fn(Corner) -> Corner,
    accept: &dyn Fn(&[[Corner; 3]]) -> bool,
    bounds: &Bounds,
) -> Option<Mended> {
    let stored = |p: [f64; 3]| p.map(|c| f64::from(c as f32));
    let table_interiors: Vec<[f64; 3]> = (0..cell.interior_count())
        .map(|k| {
            let support = cell.interior_support(k);
            let corners = support.iter().map(|&c| position(c).map(|x| x as f32));
            stored(centroid_in(corners, bounds))
        })
        .collect();
    let at = |c: Corner, xs: &[[f64; 3]]| match c.as_interior() {
        Some(k) => xs[usize::from(k)],
        None => position(c),
    };
    // Local vertices: distinct corners after `same`.
    let local = |triangles: &[[Corner; 3]], xs: &[[f64; 3]]| {
        let (corners, tris) = number_locally(triangles.iter().map(|t| t.map(same)));
        let positions: Vec<[f64; 3]> = corners.iter().map(|&c| at(c, xs)).collect();
        (corners, tris, positions)
    };
    let (corners, tris, positions) = local(cell.triangles, &table_interiors);
    // A triangle of no area is mended only where an interior point lies on the line through
    // its two crossings (a symmetric cell puts the centre there): moving the point helps. Two
    // crossings on one point (values at the level) touch, and nothing is to be mended.
    let (mut flat, mut interior_on_a_line) = (false, false);
    for t in &tris {
        let p = t.map(|v| positions[v as usize]);
        if !collinear(p) {
            continue;
        }
        flat = true;
        let mut crossings = (0..3)
            .filter(|&k| corners[t[k] as usize].as_interior().is_none())
            .map(|k| p[k]);
        if let (Some(a), Some(b), None) = (crossings.next(), crossings.next(), crossings.next()) {
            interior_on_a_line |= a != b;
        }
    }
    let crossing = || first_crossing(&tris, &|v: u32| positions[v as usize]).is_some();
    if flat && !interior_on_a_line || !flat && !crossing() {
        return None;
    }
    let movable: Vec<u32> = (0..corners.len() as u32)
        .filter(|&v| corners[v as usize].as_interior().is_some())
        .collect();
    if let Some(places) = untangle(&tris, &positions, &movable, bounds) {
        let mut interiors = table_interiors;
        for (&v, p) in movable.iter().zip(places) {
            let k = corners[v as usize]
                .as_interior()
                .expect("movable points are interior");
            interiors[usize::from(k)] = p;
        }
        return Some(Mended {
            triangles: cell.triangles.to_vec(),
            interiors,
        });
    }
    let in_tube = |c: Corner| l1.contains(&c) || l2.contains(&c) || c.as_interior().is_some();
    let disks: Vec<[Corner; 3]> = cell
        .triangles
        .iter()
        .filter(|t| !t.iter().all(|&c| in_tube(c)))
        .copied()
        .collect();
    if disks.iter().flatten().any(|c| c.as_interior().is_some()) {
        return None;
    }
    let mean = |cs: &[Corner]| -> [f64; 3] {
        let n = cs.len() as f64;
        std::array::from_fn(|d| cs.iter().map(|&c| position(c)[d]).sum::<f64>() / n)
    };
    let (lo, hi) = *bounds;
    let centre: [f64; 3] = std::array::from_fn(|d| 0.5 * (lo[d] + hi[d]));
    let (m1, m2) = (mean(l1), mean(l2));
    let middle: [f64; 3] = std::array::from_fn(|d| 0.5 * (m1[d] + m2[d]));
    let both: Vec<Corner> = l1.iter().chain(l2).copied().collect();
    let places = [mean(&both), middle, centre].map(|p| stored(clamp_into(p, bounds)));
    let variants = std::iter::once((false, places[0])).chain(places.iter().map(|&p| (true, p)));
    let singles = variants.filter_map(|(through, x)| {
        let xs = vec![x];
        let band = band_at(l1, l2, &|c| at(c, &xs), through)?;
        Some((band, xs))
    });
    let p1: Vec<[f64; 3]> = l1.iter().map(|&c| position(c)).collect();
    let p2: Vec<[f64; 3]> = l2.iter().map(|&c| position(c)).collect();
    let ringed = rings(&p1, &p2).filter_map(|ring| {
        let xs: Vec<[f64; 3]> = ring
            .into_iter()
            .map(|p| stored(clamp_into(p, bounds)))
            .collect();
        let r: Vec<Corner> = (0..xs.len() as u8).map(Corner::interior).collect();
        let back: Vec<Corner> = r.iter().rev().copied().collect();
        let to_ring = band_at(l1, &r, &|c| at(c, &xs), false)?;
        let from_ring = band_at(&back, l2, &|c| at(c, &xs), false)?;
        Some((to_ring.into_iter().chain(from_ring).collect(), xs))
    });
    singles.chain(ringed).find_map(|(band, xs)| {
        let triangles: Vec<[Corner; 3]> = disks.iter().chain(&band).copied().collect();
        let (_, tris, positions) = local(&triangles, &xs);
        let ok = !degenerate(&tris, &positions)
            && first_crossing(&tris, &|v: u32| positions[v as usize]).is_none()
            && accept(&triangles);
        ok.then_some(Mended {
            triangles,
            interiors: xs,
        })
    })
}

/// The triangles on local vertex numbers (by first use), those with a repeated vertex dropped,
/// and the vertices in that order: one cell's patch, small enough for a linear search.
pub(super) fn number_locally<T: Copy + PartialEq>(
    triangles: impl IntoIterator<Item = [T; 3]>,
) -> (Vec<T>, Vec<[u32; 3]>) {
    let mut vertices: Vec<T> = Vec::new();
    let mut tris = Vec::new();
    for t in triangles {
        if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
            continue;
        }
        tris.push(t.map(|c| match vertices.iter().position(|&x| x == c) {
            Some(k) => k as u32,
            None => {
                vertices.push(c);
                vertices.len() as u32 - 1
            }
        }));
    }
    (vertices, tris)
}

/// New places for the interior points `movable` (local vertex numbers into `positions`) at which
/// the triangles (which cross, see [`crosses`]) cross nothing, in the order of `movable`; `None`
/// when no place tried helps. Places keep to `bounds` and are rounded as stored (`f32`).
fn untangle(
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

/// Rings of interior points for a tube between the loops at `p1` and `p2` (each oriented as a
/// boundary of the tube, so they run opposite ways round it), to try in order: regular polygons
/// of 4 or 3 points round the line between the loops' centroids, at a few places along it and a
/// few fractions of the loops' radius, each running opposite to the first loop (so the first
/// loop and the ring bound an annulus, and the ring reversed and the second loop another).
///
/// A band to a ring needs no chord on a face of the cell (every rung ends at an interior point),
/// so the manifold rule never forbids one; whether it crosses is the caller's test.
fn rings(p1: &[[f64; 3]], p2: &[[f64; 3]]) -> Box<dyn Iterator<Item = Vec<[f64; 3]>>> {
    let mean = |p: &[[f64; 3]]| -> [f64; 3] {
        std::array::from_fn(|d| p.iter().map(|q| q[d]).sum::<f64>() / p.len() as f64)
    };
    let unit = |a: [f64; 3]| {
        let l = dot(a, a).sqrt();
        (l > 1e-12).then(|| a.map(|c| c / l))
    };
    if p1.len() < 3 || p2.len() < 3 {
        return Box::new(std::iter::empty());
    }
    let (m1, m2) = (mean(p1), mean(p2));
    let axis = sub(m2, m1);
    let Some(n) = unit(axis) else {
        return Box::new(std::iter::empty());
    };
    let flat = |a: [f64; 3]| {
        let h = dot(a, n);
        std::array::from_fn::<f64, 3, _>(|d| a[d] - h * n[d])
    };
    let winding: f64 = (0..p1.len())
        .map(|i| {
            let (a, b) = (sub(p1[i], m1), sub(p1[(i + 1) % p1.len()], m1));
            dot(cross(a, b), n)
        })
        .sum();
    let u = unit(flat(sub(p1[0], m1)))
        .or_else(|| unit(flat([1.0, 0.0, 0.0])))
        .or_else(|| unit(flat([0.0, 1.0, 0.0])))
        .expect("some axis is not parallel to n");
    let v = cross(n, u);
    let radius = |p: &[[f64; 3]], m: [f64; 3]| {
        p.iter()
            .map(|&q| dot(flat(sub(q, m)), flat(sub(q, m))).sqrt())
            .sum::<f64>()
            / p.len() as f64
    };
    let r0 = radius(p1, m1).min(radius(p2, m2));
    // Opposite to the first loop's winding about n.
    let sense = if winding > 0.0 { -1.0 } else { 1.0 };
    const ALONG: [f64; 5] = [0.5, 0.35, 0.65, 0.2, 0.8];
    const RADII: [f64; 5] = [0.5, 0.3, 0.7, 0.15, 0.9];
    let shapes = [(4usize, 0.0), (4, 0.5), (3, 0.0), (3, 0.5)];
    // Built one at a time: most tunnels are mended before the rings, or by one of the first.
    let all = ALONG.into_iter().flat_map(move |t| {
        RADII.into_iter().flat_map(move |f| {
            shapes.into_iter().map(move |(m, phase)| {
                let r = f * r0;
                (0..m)
                    .map(|k| {
                        let angle = sense * std::f64::consts::TAU * (k as f64 + phase) / m as f64;
                        let (c, s) = (angle.cos() * r, angle.sin() * r);
                        std::array::from_fn(|d| m1[d] + t * axis[d] + c * u[d] + s * v[d])
                    })
                    .collect()
            })
        })
    });
    Box::new(all)
}
