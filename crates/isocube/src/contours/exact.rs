//! Sectional Marching Cubes that keeps the input contours exactly.
//!
//! On a section plane the surface must cut the plane along the contour, not along chords between
//! interpolated crossings. So, on every section plane:
//! - a crossing on a grid edge is the exact intersection of the contour with that edge;
//! - the contour is walked once and split into *pieces*, one per grid square it passes through,
//!   each running from the crossing where it enters the square to the one where it leaves, with
//!   the contour vertices in between;
//! - a square with four crossings is decided by the contour itself (which crossings its pieces
//!   join), not by the asymptotic decider;
//! - in a cell's loop, two consecutive corners on the same section face are joined by the piece
//!   between them, its contour vertices inserted as extra corners (the cell on the other side of
//!   the plane inserts the same points in reverse, so the mesh stays watertight);
//! - loops are triangulated without any edge lying in a section plane other than the pieces.
//!
//! The mesh's cut by each section plane is then the contour itself. Between sections, crossings
//! on vertical edges interpolate the signed distances, as in the paper.
//!
//! The grid must resolve the contours: a contour that crosses one grid edge more than once (a
//! wiggle smaller than a cell) cannot be followed; such edges are counted and reported.

use std::collections::HashMap;

use super::field::{stacked_field, PlaneGrid};
use super::{Point2, SectionStack};
use crate::cube::polygons::face_segments;
use crate::cube::{CaseTable, Corner, EDGES, EDGE_AXIS, VERTICES};
use crate::extract::{cell_config, face_decisions};
use crate::mesh::Mesh;
use crate::quality::{triangulate, Strategy};

/// A grid edge in a section plane: (layer, axis 0 = x / 1 = y, i, j of its first point).
type PlaneEdge = (usize, u8, usize, usize);

/// One contour piece inside one grid square.
#[derive(Clone, Debug)]
struct Piece {
    from: PlaneEdge,
    to: PlaneEdge,
    /// Contour vertices strictly inside the square, in contour order, as (section, contour,
    /// index) keys with their positions.
    inner: Vec<((usize, usize, usize), Point2)>,
}

/// The contour pieces of every section, and where each grid edge is crossed.
struct Pieces {
    /// (layer, i, j) of the square → pieces in it.
    squares: HashMap<(usize, usize, usize), Vec<Piece>>,
    /// Plane edge → crossing point.
    crossings: HashMap<PlaneEdge, Point2>,
    /// Plane edges crossed more than once (unresolved wiggles).
    multiple: usize,
}

fn walk_contours(stack: &SectionStack, plane: &PlaneGrid, layer_of: &[usize]) -> Pieces {
    let mut squares: HashMap<(usize, usize, usize), Vec<Piece>> = HashMap::new();
    let mut crossings: HashMap<PlaneEdge, Point2> = HashMap::new();
    let mut count: HashMap<PlaneEdge, usize> = HashMap::new();
    let h = plane.spacing;
    let o = plane.origin;
    for (s, section) in stack.sections().iter().enumerate() {
        let layer = layer_of[s];
        for (c, contour) in section.contours().iter().enumerate() {
            let pts = contour.points();
            let n = pts.len();
            // Events along the contour: crossings (edge, point) and vertices.
            enum Event {
                Cross(PlaneEdge, Point2),
                Vertex(usize, Point2),
            }
            let mut events: Vec<Event> = Vec::new();
            for a in 0..n {
                let (p, q) = (pts[a], pts[(a + 1) % n]);
                events.push(Event::Vertex(a, p));
                let mut hits: Vec<(f64, PlaneEdge, Point2)> = Vec::new();
                for axis in 0..2 {
                    // Grid lines perpendicular to `axis` between p and q.
                    let (u0, u1) = ((p[axis] - o[axis]) / h, (q[axis] - o[axis]) / h);
                    if u0 == u1 {
                        continue;
                    }
                    let (lo, hi) = (u0.min(u1), u0.max(u1));
                    let mut line = lo.floor() as i64 + 1;
                    if (line as f64) - 1.0 == lo {
                        line -= 1;
                    }
                    while (line as f64) <= hi {
                        let t = (line as f64 - u0) / (u1 - u0);
                        if t > 0.0 && t <= 1.0 {
                            let x = [p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1])];
                            let other = 1 - axis;
                            let k = ((x[other] - o[other]) / h).floor() as i64;
                            if line >= 0 && k >= 0 {
                                // A line x = const holds y-edges (axis 1) and vice versa.
                                let (i, j) = if axis == 0 {
                                    (line as usize, k as usize)
                                } else {
                                    (k as usize, line as usize)
                                };
                                let mut at = x;
                                at[axis] = o[axis] + line as f64 * h;
                                hits.push((t, (layer, (1 - axis) as u8, i, j), at));
                            }
                        }
                        line += 1;
                    }
                }
                hits.sort_by(|x, y| x.0.total_cmp(&y.0));
                for (_, e, at) in hits {
                    events.push(Event::Cross(e, at));
                }
            }
            let first = events.iter().position(|e| matches!(e, Event::Cross(..)));
            let Some(first) = first else {
                continue;
            };
            let m = events.len();
            let mut k = first;
            loop {
                let Event::Cross(from, at) = events[k] else {
                    unreachable!()
                };
                *count.entry(from).or_insert(0) += 1;
                crossings.insert(from, at);
                let mut inner = Vec::new();
                let mut next = (k + 1) % m;
                loop {
                    match events[next] {
                        Event::Vertex(a, p) => inner.push(((s, c, a), p)),
                        Event::Cross(to, at2) => {
                            // The square: the one both crossings bound, found from a point of the
                            // piece just inside.
                            let probe = inner
                                .first()
                                .map_or([(at[0] + at2[0]) / 2.0, (at[1] + at2[1]) / 2.0], |v| v.1);
                            let sq = (
                                layer,
                                ((probe[0] - o[0]) / h).floor().max(0.0) as usize,
                                ((probe[1] - o[1]) / h).floor().max(0.0) as usize,
                            );
                            squares
                                .entry(sq)
                                .or_default()
                                .push(Piece { from, to, inner });
                            break;
                        }
                    }
                    next = (next + 1) % m;
                }
                k = next;
                if k == first {
                    break;
                }
            }
        }
    }
    let multiple = count.values().filter(|&&n| n > 1).count();
    Pieces {
        squares,
        crossings,
        multiple,
    }
}

/// Grid edges of `plane` that some contour crosses more than once.
pub(super) fn unresolved_edges(stack: &SectionStack, plane: &PlaneGrid) -> usize {
    let layers: Vec<usize> = (0..stack.sections().len()).collect();
    walk_contours(stack, plane, &layers).multiple
}

/// A mesh vertex: a plane crossing, a contour vertex, a vertical crossing or a loop's centre.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
enum Key {
    Plane(PlaneEdge),
    ContourVertex(usize, usize, usize),
    Vertical(usize, usize, usize),
    Centre(usize, usize, usize, usize),
}

/// What [`extract_exact`] made, besides the mesh.
pub(super) struct ExactStats {
    pub(super) evaluated: usize,
    pub(super) points: usize,
    pub(super) active_cells: usize,
    pub(super) unresolved_edges: usize,
}

/// Extracts the surface with the contours kept exactly (see the module documentation).
pub(super) fn extract_exact(
    stack: &SectionStack,
    plane: &PlaneGrid,
    extend: Option<f64>,
) -> (Mesh, ExactStats) {
    let (field, heights) = stacked_field(stack, plane, extend);
    let grid = &field.grid;
    let [nx, ny, nz] = grid.dims();
    let offset = usize::from(extend.is_some());
    let layer_of: Vec<usize> = (0..stack.sections().len()).map(|s| s + offset).collect();
    let real_layer = |l: usize| l >= offset && l < offset + stack.sections().len();
    let pieces = walk_contours(stack, plane, &layer_of);
    let table = CaseTable::binary();
    let values = grid.values();
    let at = |i: usize, j: usize, k: usize| values[i + nx * (j + ny * k)];
    let mut mesh = Mesh::new();
    let mut ids: HashMap<Key, u32> = HashMap::new();
    let mut active = 0;
    let plane_point = |i: usize, j: usize| plane.point(i, j);
    for l in 0..nz - 1 {
        for j in 0..ny - 1 {
            for i in 0..nx - 1 {
                let v: [f32; 8] = std::array::from_fn(|c| {
                    let o = VERTICES[c];
                    at(
                        i + usize::from(o[0]),
                        j + usize::from(o[1]),
                        l + usize::from(o[2]),
                    )
                });
                let config = cell_config(&v, 0.0);
                if config == 0 || config == 255 {
                    continue;
                }
                active += 1;
                let amb = table.ambiguous_faces(config);
                let mut decisions = face_decisions(&v, 0.0, amb);
                // Section faces: bottom (face 4, layer l) and top (face 5, layer l + 1).
                for (face, layer) in [(4usize, l), (5usize, l + 1)] {
                    if amb >> face & 1 == 0 || !real_layer(layer) {
                        continue;
                    }
                    let Some(list) = pieces.squares.get(&(layer, i, j)) else {
                        continue;
                    };
                    let joined: Vec<(PlaneEdge, PlaneEdge)> =
                        list.iter().map(|p| (p.from, p.to)).collect();
                    for bit in [0u8, 1] {
                        let d = (decisions & !(1 << face)) | bit << face;
                        let segs = face_segments(config, d, face);
                        let matches = segs.iter().all(|&(a, b)| {
                            let (ea, eb) = (plane_edge(a, i, j, l), plane_edge(b, i, j, l));
                            joined
                                .iter()
                                .any(|&(x, y)| (x, y) == (ea, eb) || (x, y) == (eb, ea))
                        });
                        if matches {
                            decisions = d;
                            break;
                        }
                    }
                }
                for (loop_index, polygon) in table.polygons(config, decisions).enumerate() {
                    emit_loop(
                        polygon,
                        [i, j, l],
                        loop_index,
                        &v,
                        &pieces,
                        &real_layer,
                        &heights,
                        plane,
                        &plane_point,
                        &mut ids,
                        &mut mesh,
                    );
                }
            }
        }
    }
    mesh.flip_orientation();
    mesh.compute_normals();
    (
        mesh,
        ExactStats {
            evaluated: field.evaluated,
            points: values.len(),
            active_cells: active,
            unresolved_edges: pieces.multiple,
        },
    )
}

/// The plane edge a cube edge lies on, if it lies in the cell's bottom or top face.
fn plane_edge(e: u8, i: usize, j: usize, l: usize) -> PlaneEdge {
    let [a, _] = EDGES[usize::from(e)];
    let o = VERTICES[usize::from(a)];
    (
        l + usize::from(o[2]),
        EDGE_AXIS[usize::from(e)],
        i + usize::from(o[0]),
        j + usize::from(o[1]),
    )
}

#[allow(clippy::too_many_arguments)]
fn emit_loop(
    polygon: &[Corner],
    [i, j, l]: [usize; 3],
    loop_index: usize,
    v: &[f32; 8],
    pieces: &Pieces,
    real_layer: &dyn Fn(usize) -> bool,
    heights: &[f64],
    plane: &PlaneGrid,
    plane_point: &dyn Fn(usize, usize) -> Point2,
    ids: &mut HashMap<Key, u32>,
    mesh: &mut Mesh,
) {
    // Corners with their keys, positions, and the cube faces they lie on.
    let mut corners: Vec<(Key, [f64; 3], u8)> = Vec::new();
    let corner = |c: Corner| -> (Key, [f64; 3], u8) {
        let e = c.as_edge().expect("binary loops have edge corners");
        let axis = EDGE_AXIS[usize::from(e)];
        let [a, b] = EDGES[usize::from(e)];
        if axis < 2 {
            let pe = plane_edge(e, i, j, l);
            let z = heights[pe.0];
            let xy = if real_layer(pe.0) {
                pieces.crossings.get(&pe).copied()
            } else {
                None
            };
            let xy = xy.unwrap_or_else(|| {
                // No contour crossing recorded (a virtual cap layer): interpolate.
                let (va, vb) = (f64::from(v[usize::from(a)]), f64::from(v[usize::from(b)]));
                let t = va / (va - vb);
                let p0 = plane_point(pe.2, pe.3);
                let mut x = p0;
                x[usize::from(axis)] += t * plane.spacing;
                x
            });
            (Key::Plane(pe), [xy[0], xy[1], z], c.faces())
        } else {
            let o = VERTICES[usize::from(a)];
            let (pi, pj) = (i + usize::from(o[0]), j + usize::from(o[1]));
            let (va, vb) = (f64::from(v[usize::from(a)]), f64::from(v[usize::from(b)]));
            let t = va / (va - vb);
            let xy = plane_point(pi, pj);
            let z = heights[l] + t * (heights[l + 1] - heights[l]);
            (Key::Vertical(pi, pj, l), [xy[0], xy[1], z], c.faces())
        }
    };
    let n = polygon.len();
    for k in 0..n {
        let (a, b) = (polygon[k], polygon[(k + 1) % n]);
        let ca = corner(a);
        corners.push(ca);
        // Both on the bottom face or both on the top face of a real section: insert the piece.
        for (face, layer) in [(4u8, l), (5u8, l + 1)] {
            let mask = 1 << face;
            if a.faces() & mask == 0 || b.faces() & mask == 0 || !real_layer(layer) {
                continue;
            }
            let (ea, eb) = (
                plane_edge(a.as_edge().expect("edge"), i, j, l),
                plane_edge(b.as_edge().expect("edge"), i, j, l),
            );
            let Some(list) = pieces.squares.get(&(layer, i, j)) else {
                continue;
            };
            if let Some(p) = list.iter().find(|p| p.from == ea && p.to == eb) {
                for &((s, c, idx), xy) in &p.inner {
                    corners.push((
                        Key::ContourVertex(s, c, idx),
                        [xy[0], xy[1], heights[layer]],
                        mask,
                    ));
                }
            } else if let Some(p) = list.iter().find(|p| p.from == eb && p.to == ea) {
                for &((s, c, idx), xy) in p.inner.iter().rev() {
                    corners.push((
                        Key::ContourVertex(s, c, idx),
                        [xy[0], xy[1], heights[layer]],
                        mask,
                    ));
                }
            }
        }
    }
    let mut id = |key: Key, p: [f64; 3], mesh: &mut Mesh| -> u32 {
        *ids.entry(key).or_insert_with(|| {
            mesh.positions.push(p.map(|c| c as f32));
            (mesh.positions.len() - 1) as u32
        })
    };
    let vids: Vec<u32> = corners.iter().map(|&(k, p, _)| id(k, p, mesh)).collect();
    let positions: Vec<[f64; 3]> = vids
        .iter()
        .map(|&v| mesh.positions[v as usize].map(f64::from))
        .collect();
    // No diagonal in a section plane (it would add a chord to the cut) or on a face a neighbour
    // could also split.
    let section_faces = 1 << 4 | 1 << 5;
    let allowed = |x: usize, y: usize| {
        let shared = corners[x].2 & corners[y].2;
        shared & section_faces == 0 && shared & (1 << 0 | 1 << 3) == 0
    };
    let c = plane.point(i, j);
    // An interior vertex stays strictly between the sections: on a section plane it would add
    // edges to the cut that are not the contour.
    let margin = 1e-3 * (heights[l + 1] - heights[l]);
    let bounds = (
        [c[0], c[1], heights[l] + margin],
        [
            c[0] + plane.spacing,
            c[1] + plane.spacing,
            heights[l + 1] - margin,
        ],
    );
    let result = if corners.len() <= 16 {
        triangulate(&positions, &allowed, Strategy::Optimal, bounds)
    } else {
        None
    };
    match result {
        Some(t) => {
            let centre = t
                .interior
                .map(|x| id(Key::Centre(i, j, l, loop_index), x, mesh));
            for tri in t.triangles {
                let pick = |q: u8| {
                    vids.get(usize::from(q))
                        .copied()
                        .unwrap_or_else(|| centre.expect("a centre"))
                };
                mesh.triangles.push(tri.map(pick));
            }
        }
        None => {
            let m = positions.len() as f64;
            let x: [f64; 3] =
                std::array::from_fn(|d| positions.iter().map(|p| p[d]).sum::<f64>() / m);
            let centre = id(Key::Centre(i, j, l, loop_index), x, mesh);
            for k in 0..vids.len() {
                mesh.triangles
                    .push([vids[k], vids[(k + 1) % vids.len()], centre]);
            }
        }
    }
}
