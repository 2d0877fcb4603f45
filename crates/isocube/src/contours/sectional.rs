//! Marching Cubes between sections, on the sparse sectional field, keeping the input contours.
//!
//! Only the cells the surface passes through are visited ([`SparseField`]). With
//! [`Fidelity::Exact`], on every section plane:
//! - a crossing on a grid edge is the exact intersection of the contour with that edge;
//! - the contour is walked once and split into *pieces*, one per grid square it passes through,
//!   each running from the crossing where it enters the square to the one where it leaves, with
//!   the contour vertices in between;
//! - an excursion of the contour across a grid edge and back (a sharp corner or a bulge poking
//!   through an edge whose two ends are on the same side) is folded into the piece it leaves
//!   from: its two crossings and the points between become inserted points of that piece, so
//!   the grid edge keeps the one crossing (or none) that its end states call for;
//! - a square with four crossings is decided by the contour itself (which crossings its pieces
//!   join), not by the asymptotic decider;
//! - in a cell's loop, two consecutive corners on the same section face are joined by the piece
//!   between them, its points inserted as extra corners (the cell on the other side of the plane
//!   inserts the same points in reverse, so the mesh stays watertight);
//! - loops are triangulated without any edge lying in a section plane other than the pieces.
//!
//! The mesh's cut by each section plane is then the contour itself. Between sections, crossings
//! on vertical edges interpolate the signed distances, as in the paper. [`Fidelity::Plain`] is
//! the paper's approach: every crossing interpolated, nothing inserted.
//!
//! What a grid cannot follow is counted, not guessed: a grid edge crossed more than once by
//! contour parts that are not one excursion (two contours, or two arms of one, closer than a
//! cell), and a contour that encloses no grid point.

use rustc_hash::FxHashMap as HashMap;

use super::plane::PlaneGrid;
use super::sparse::SparseField;
use super::{Point2, Section, SectionStack};
use crate::cube::polygons::face_segments;
use crate::cube::triangulate::{may_join_on, Z_FACES};
use crate::cube::{CaseTable, Corner, EDGES, EDGE_AXIS, VERTICES};
use crate::extract::{
    cell_config, face_decisions, join, CellBox, ChunkMesh, ExtractError, VertexKey,
};
use crate::mesh::Mesh;
use crate::quality::{triangulate, Strategy};
use rayon::prelude::*;

/// How closely the mesh follows the contours on the section planes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Fidelity {
    /// The cut by each section plane is the input contour: exact crossings, contour vertices
    /// inserted, ambiguous squares decided by the contour (default).
    #[default]
    Exact,
    /// The section-data paper's plain approach: crossings interpolated from the distances, no
    /// contour vertices inserted (chords cut corners).
    Plain,
}

/// The closest a crossing on a vertical edge comes to either section, as a fraction of their
/// distance (more where single precision needs it: far from the origin, or for very close
/// sections).
const VERTICAL_MARGIN: f64 = 1e-4;

/// A grid edge in a section plane: (layer, axis 0 = x / 1 = y, i, j of its first point).
type PlaneEdge = (usize, u8, usize, usize);

/// A mesh vertex: a plane crossing, a contour vertex, a folded crossing, a vertical crossing or
/// a loop's centre.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
enum Key {
    Plane(PlaneEdge),
    /// (section, contour, vertex index).
    ContourVertex(usize, usize, usize),
    /// (section, contour, crossing number along the contour): a crossing folded into a piece.
    ContourCrossing(usize, usize, usize),
    Vertical(usize, usize, usize),
    Centre(usize, usize, usize, usize),
}

/// One contour piece inside one grid square.
#[derive(Clone, Debug)]
struct Piece {
    from: PlaneEdge,
    to: PlaneEdge,
    /// Points strictly between the two crossings, in contour order.
    inner: Vec<(Key, Point2)>,
}

/// The contour pieces of one section, and where each grid edge of its plane is crossed.
#[derive(Default)]
struct LayerPieces {
    /// (i, j) of the square → pieces in it.
    squares: HashMap<(usize, usize), Vec<Piece>>,
    /// Plane edge → crossing point.
    crossings: HashMap<PlaneEdge, Point2>,
    unresolved_edges: usize,
    missed_contours: usize,
    folded: usize,
}

/// The contour pieces of every layer (none on the virtual layers of caps).
#[derive(Default)]
struct Pieces {
    layers: Vec<LayerPieces>,
    /// Plane edges crossed more than once after folding excursions.
    unresolved_edges: usize,
    /// Contours that cross no grid edge once excursions are folded (they enclose no grid point).
    missed_contours: usize,
    /// Excursions folded into pieces.
    folded: usize,
}

impl Pieces {
    /// A number for every contour point the pieces insert, unique in the stack.
    fn numbered(&self) -> HashMap<Key, usize> {
        let mut numbers = HashMap::default();
        for layer in &self.layers {
            for piece in layer.squares.values().flatten() {
                for &(key, _) in &piece.inner {
                    let next = numbers.len();
                    numbers.entry(key).or_insert(next);
                }
            }
        }
        numbers
    }

    fn square(&self, layer: usize, i: usize, j: usize) -> Option<&Vec<Piece>> {
        self.layers.get(layer)?.squares.get(&(i, j))
    }

    fn crossing(&self, e: PlaneEdge) -> Option<Point2> {
        self.layers.get(e.0)?.crossings.get(&e).copied()
    }
}

/// A crossing of a contour with a grid edge, and the contour points up to the next crossing.
struct Crossing {
    edge: PlaneEdge,
    at: Point2,
    key: Key,
    after: Vec<(Key, Point2)>,
}

/// The grid crossings of the segment `p → q`, in order along it.
fn segment_crossings(
    p: Point2,
    q: Point2,
    plane: &PlaneGrid,
    layer: usize,
    hits: &mut Vec<(f64, PlaneEdge, Point2)>,
) {
    let (h, o) = (plane.spacing, plane.origin);
    hits.clear();
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
                    // A contour passing within rounding of a grid point would put the crossings
                    // on two of its edges at one single-precision point: each is kept a few
                    // units of that precision away from its edge's ends.
                    let (lo, hi) = (o[other] + k as f64 * h, o[other] + (k + 1) as f64 * h);
                    let margin = 8.0 * f64::from(f32::EPSILON) * lo.abs().max(hi.abs()).max(h);
                    if hi - lo > 4.0 * margin {
                        at[other] = at[other].clamp(lo + margin, hi - margin);
                    }
                    hits.push((t, (layer, (1 - axis) as u8, i, j), at));
                }
            }
            line += 1;
        }
    }
    hits.sort_by(|x, y| x.0.total_cmp(&y.0));
}

/// Whether two points in a section plane are the same once written in single precision (or
/// within a few units of its last place): such a pair cannot be two vertices of a mesh.
fn same_point(a: Point2, b: Point2) -> bool {
    let scale = a[0].abs().max(a[1].abs()).max(b[0].abs()).max(b[1].abs());
    let tolerance = 4.0 * f64::from(f32::EPSILON) * scale.max(f64::MIN_POSITIVE);
    (a[0] - b[0]).abs() <= tolerance && (a[1] - b[1]).abs() <= tolerance
}

/// The squares next to a plane edge.
fn squares_of(e: PlaneEdge) -> [Option<(usize, usize)>; 2] {
    let (_, axis, i, j) = e;
    if axis == 0 {
        [j.checked_sub(1).map(|j| (i, j)), Some((i, j))]
    } else {
        [i.checked_sub(1).map(|i| (i, j)), Some((i, j))]
    }
}

/// Folds excursions: while two crossings that follow each other along the contour lie on the
/// same grid edge, the contour went across that edge and came back without crossing anything
/// else; both crossings and the points between join the points after the crossing before them.
/// Returns the crossings left, in contour order (empty if everything folded away).
fn fold_excursions(mut xs: Vec<Crossing>, folded: &mut usize) -> Vec<Crossing> {
    let m = xs.len();
    if m < 2 {
        return xs;
    }
    let mut next: Vec<usize> = (0..m).map(|k| (k + 1) % m).collect();
    let mut prev: Vec<usize> = (0..m).map(|k| (k + m - 1) % m).collect();
    let mut alive = vec![true; m];
    let mut left = m;
    let mut work: Vec<usize> = (0..m).rev().collect();
    while let Some(a) = work.pop() {
        if !alive[a] || left < 2 {
            continue;
        }
        let b = next[a];
        if b == a || xs[a].edge != xs[b].edge {
            continue;
        }
        *folded += 1;
        if left == 2 {
            // The whole contour is one excursion across one edge.
            return Vec::new();
        }
        let p = prev[a];
        let n = next[b];
        let mut moved = Vec::new();
        for k in [a, b] {
            moved.push((xs[k].key, xs[k].at));
            moved.append(&mut xs[k].after);
        }
        xs[p].after.append(&mut moved);
        alive[a] = false;
        alive[b] = false;
        left -= 2;
        next[p] = n;
        prev[n] = p;
        work.push(p);
    }
    // In contour order, from the first crossing still alive.
    let Some(start) = (0..m).find(|&k| alive[k]) else {
        return Vec::new();
    };
    let mut order = vec![start];
    let mut k = next[start];
    while k != start {
        order.push(k);
        k = next[k];
    }
    let mut slots: Vec<Option<Crossing>> = xs.into_iter().map(Some).collect();
    order
        .into_iter()
        .map(|k| slots[k].take().expect("each crossing once"))
        .collect()
}

/// Walks every section's contours (in parallel) into pieces; section `s` lies on layer
/// `s + offset` of `layers`.
fn walk_contours(stack: &SectionStack, plane: &PlaneGrid, offset: usize, layers: usize) -> Pieces {
    let walked: Vec<LayerPieces> = stack
        .sections()
        .par_iter()
        .enumerate()
        .map(|(s, section)| walk_section(s, section, s + offset, plane))
        .collect();
    let mut out = Pieces::default();
    out.layers.resize_with(offset, LayerPieces::default);
    for p in walked {
        out.unresolved_edges += p.unresolved_edges;
        out.missed_contours += p.missed_contours;
        out.folded += p.folded;
        out.layers.push(p);
    }
    out.layers.resize_with(layers, LayerPieces::default);
    out
}

fn walk_section(s: usize, section: &Section, layer: usize, plane: &PlaneGrid) -> LayerPieces {
    let mut out = LayerPieces::default();
    let mut count: HashMap<PlaneEdge, usize> = HashMap::default();
    let mut hits = Vec::new();
    for (c, contour) in section.contours().iter().enumerate() {
        let pts = contour.points();
        let n = pts.len();
        let mut xs: Vec<Crossing> = Vec::new();
        // Vertices before the first crossing belong after the last one (the contour closes).
        let mut lead: Vec<(Key, Point2)> = Vec::new();
        // Whether contour vertex `a` is kept: not where a crossing of a segment next to it is.
        let mut kept = vec![true; n];
        for a in 0..n {
            let (p, q) = (pts[a], pts[(a + 1) % n]);
            segment_crossings(p, q, plane, layer, &mut hits);
            // A vertex within rounding of a grid line would be its crossing's twin once written
            // in single precision: a flat triangle between them, and a cap that cannot close.
            // The crossing is on the contour, so it stands for the vertex.
            if kept[a] && !hits.first().is_some_and(|h| same_point(h.2, p)) {
                let vertex = (Key::ContourVertex(s, c, a), p);
                match xs.last_mut() {
                    Some(x) => x.after.push(vertex),
                    None => lead.push(vertex),
                }
            }
            for &(_, edge, at) in &hits {
                if same_point(at, q) {
                    kept[(a + 1) % n] = false;
                }
                let key = Key::ContourCrossing(s, c, xs.len());
                xs.push(Crossing {
                    edge,
                    at,
                    key,
                    after: Vec::new(),
                });
            }
        }
        if !kept[0] {
            lead.retain(|v| v.0 != Key::ContourVertex(s, c, 0));
        }
        if let Some(x) = xs.last_mut() {
            x.after.append(&mut lead);
        }
        let xs = fold_excursions(xs, &mut out.folded);
        if xs.is_empty() {
            out.missed_contours += 1;
            continue;
        }
        let m = xs.len();
        let edges: Vec<PlaneEdge> = xs.iter().map(|x| x.edge).collect();
        for (k, x) in xs.into_iter().enumerate() {
            *count.entry(x.edge).or_insert(0) += 1;
            out.crossings.insert(x.edge, x.at);
            let to = edges[(k + 1) % m];
            let [a0, a1] = squares_of(x.edge);
            let common = squares_of(to);
            let Some(square) = [a0, a1]
                .into_iter()
                .flatten()
                .find(|sq| common.contains(&Some(*sq)))
            else {
                continue;
            };
            out.squares.entry(square).or_default().push(Piece {
                from: x.edge,
                to,
                inner: x.after,
            });
        }
    }
    out.unresolved_edges = count.values().filter(|&&n| n > 1).count();
    out
}

/// How well a plane grid follows a stack's contours.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Resolution {
    /// Grid edges crossed more than once by different parts of the contours.
    pub(super) unresolved_edges: usize,
    /// Contours enclosing no grid point.
    pub(super) missed_contours: usize,
    /// Excursions across a grid edge and back, folded into pieces.
    pub(super) folded: usize,
}

/// Walks the contours on `plane` and says what it could and could not follow.
pub(super) fn resolution(stack: &SectionStack, plane: &PlaneGrid) -> Resolution {
    let p = walk_contours(stack, plane, 0, stack.sections().len());
    Resolution {
        unresolved_edges: p.unresolved_edges,
        missed_contours: p.missed_contours,
        folded: p.folded,
    }
}

/// What [`extract_sectional`] made, besides the mesh.
pub(super) struct SectionalStats {
    pub(super) evaluated: usize,
    pub(super) points: usize,
    pub(super) active_cells: usize,
    pub(super) unresolved_edges: usize,
    pub(super) missed_contours: usize,
}

/// Extracts the surface between the sections (see the module documentation). The stack must
/// give at least two layers (two sections, or one with extension caps). The engine's grid is
/// the plane grid's points by layers; `boxes` (disjoint, covering its cells) cut the work, a box
/// a layer pair by default: the mesh is the same, to the bit, however it is cut.
pub(super) fn extract_sectional(
    stack: &SectionStack,
    plane: &PlaneGrid,
    extend: Option<f64>,
    fidelity: Fidelity,
    triangulation: Strategy,
    boxes: Option<&[CellBox]>,
) -> Result<(Mesh, SectionalStats), ExtractError> {
    let field = SparseField::new(stack, plane, extend);
    let [nx, ny] = plane.dims;
    let offset = usize::from(extend.is_some());
    let exact = fidelity == Fidelity::Exact;
    let pieces = if exact {
        walk_contours(stack, plane, offset, field.heights.len())
    } else {
        Pieces::default()
    };
    let table = CaseTable::binary();
    let ctx = Context {
        field: &field,
        pieces: &pieces,
        plane,
        exact,
        offset,
        table,
        triangulation,
        dims: [nx, ny, field.heights.len()],
        contour_points: pieces.numbered(),
    };
    let layers = field.heights.len();
    // Layer pairs are boxes of the engine's grid of (x, y, layer) points, meshed in parallel and
    // joined by their vertices' keys.
    let boxes = match boxes {
        Some(boxes) => boxes.to_vec(),
        None => CellBox::tile(ctx.dims, [nx - 1, ny - 1, 1])?,
    };
    let chunks: Vec<ChunkMesh> = boxes
        .into_par_iter()
        .map(|cells| {
            cells.check(ctx.dims)?;
            ctx.mesh_box(cells)
        })
        .collect::<Result<_, _>>()?;
    let mut mesh = Mesh::new();
    join(ctx.dims, chunks, &mut mesh, &mut |_| {})?;
    mesh.flip_orientation();
    mesh.compute_normals();
    let stats = SectionalStats {
        evaluated: field.evaluated,
        points: nx * ny * layers,
        active_cells: field.active_cells,
        unresolved_edges: pieces.unresolved_edges,
        missed_contours: pieces.missed_contours,
    };
    Ok((mesh, stats))
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

struct Context<'a> {
    field: &'a SparseField,
    pieces: &'a Pieces,
    plane: &'a PlaneGrid,
    exact: bool,
    /// Layer of section 0 (1 with extension caps).
    offset: usize,
    table: &'a CaseTable,
    triangulation: Strategy,
    /// The engine's grid: plane points by layers.
    dims: [usize; 3],
    /// The number of every contour point a piece inserts (their keys in the engine).
    contour_points: HashMap<Key, usize>,
}

impl Context<'_> {
    /// The engine's key of a vertex, and whether it lies on one of `faces` (a box's faces
    /// that other boxes share, per axis; see [`ChunkMesh`]).
    fn engine_key(&self, key: Key, faces: &[[usize; 2]; 3]) -> (VertexKey, bool) {
        let [nx, ny, _] = self.dims;
        let point = |i: usize, j: usize, layer: usize| i + nx * (j + ny * layer);
        let engine = match key {
            Key::Plane((layer, axis, i, j)) => {
                VertexKey::crossing(point(i, j, layer), usize::from(axis))
            }
            Key::Vertical(i, j, l) => VertexKey::crossing(point(i, j, l), 2),
            Key::Centre(i, j, l, index) => VertexKey::interior(point(i, j, l), index),
            Key::ContourVertex(s, ..) | Key::ContourCrossing(s, ..) => {
                // Strictly inside a square of its section plane: shared only across that plane.
                let engine = VertexKey::contour(self.contour_points[&key]);
                return (engine, faces[2].contains(&(s + self.offset)));
            }
        };
        let shared = (0..3).any(|a| faces[a].iter().any(|&p| engine.on_plane(self.dims, a, p)));
        (engine, shared)
    }

    /// Meshes the active cells between layers `l` and `l + 1`.
    fn mesh_box(&self, cells: CellBox) -> Result<ChunkMesh, ExtractError> {
        let field = self.field;
        let table = self.table;
        let mut ids: HashMap<Key, u32> = HashMap::default();
        let mut out = ChunkMesh::new(cells);
        out.on_faces = Some(Vec::new());
        out.faces = cells.shared_faces(self.dims);
        let [x0, x1] = [cells.min[0] as u32, cells.max[0] as u32 - 1];
        for l in cells.min[2]..cells.max[2] {
            for j in cells.min[1]..cells.max[1] {
                for span in &field.active[l][j] {
                    let (first, last) = (span[0], span[1] + 1);
                    let (lo, hi) = (span[0].max(x0), span[1].min(x1));
                    if lo > hi {
                        continue;
                    }
                    // The four point rows bounding this run of cells: (layer, row) by dz * 2 + dy.
                    let rows: [Option<(&[f64], f64)>; 4] = std::array::from_fn(|r| {
                        let (layer, partner) = if r < 2 { (l, l + 1) } else { (l + 1, l) };
                        field.run(layer, partner, j + r % 2, first, last)
                    });
                    for i in lo..=hi {
                        let v: [f32; 8] = std::array::from_fn(|c| {
                            let o = VERTICES[c];
                            let (dx, dy, dz) =
                                (usize::from(o[0]), usize::from(o[1]), usize::from(o[2]));
                            let x = (i - first) as usize + dx;
                            let value = match rows[dz * 2 + dy] {
                                Some((values, drop)) => values[x] - drop,
                                None => field.value(l + dz, l + 1 - dz, i as usize + dx, j + dy),
                            };
                            value as f32
                        });
                        let config = cell_config(&v, 0.0);
                        if config == 0 || config == 255 {
                            continue;
                        }
                        let cell = [i as usize, j, l];
                        let decisions = self.decisions(table, config, &v, cell);
                        for (loop_index, polygon) in table.polygons(config, decisions).enumerate() {
                            self.emit_loop(polygon, cell, loop_index, &v, &mut ids, &mut out);
                        }
                    }
                }
                out.end_row()?;
            }
        }
        Ok(out)
    }

    /// Whether `layer` is a section (not a cap's virtual layer) whose contour is followed.
    fn followed(&self, layer: usize) -> bool {
        self.exact && self.field.section_of[layer].is_some()
    }

    /// Face decisions: the asymptotic decider, except on section faces the contour decides.
    fn decisions(&self, table: &CaseTable, config: u8, v: &[f32; 8], [i, j, l]: [usize; 3]) -> u8 {
        let amb = table.ambiguous_faces(config);
        let mut decisions = face_decisions(v, 0.0, amb);
        // Section faces: bottom (face 4, layer l) and top (face 5, layer l + 1).
        for (face, layer) in [(4usize, l), (5usize, l + 1)] {
            if amb >> face & 1 == 0 || !self.followed(layer) {
                continue;
            }
            let Some(list) = self.pieces.square(layer, i, j) else {
                continue;
            };
            for bit in [0u8, 1] {
                let d = (decisions & !(1 << face)) | bit << face;
                let matches = face_segments(config, d, face).iter().all(|&(a, b)| {
                    let (ea, eb) = (plane_edge(a, i, j, l), plane_edge(b, i, j, l));
                    list.iter()
                        .any(|p| (p.from, p.to) == (ea, eb) || (p.from, p.to) == (eb, ea))
                });
                if matches {
                    decisions = d;
                    break;
                }
            }
        }
        decisions
    }

    /// A loop corner: its key, position and the cube faces it lies on.
    fn corner(&self, c: Corner, [i, j, l]: [usize; 3], v: &[f32; 8]) -> (Key, [f64; 3], u8) {
        let heights = &self.field.heights;
        let e = c.as_edge().expect("binary loops have edge corners");
        let axis = EDGE_AXIS[usize::from(e)];
        let [a, b] = EDGES[usize::from(e)];
        let t = {
            let (va, vb) = (f64::from(v[usize::from(a)]), f64::from(v[usize::from(b)]));
            va / (va - vb)
        };
        if axis < 2 {
            let pe = plane_edge(e, i, j, l);
            let crossing = if self.followed(pe.0) {
                self.pieces.crossing(pe)
            } else {
                None
            };
            let xy = crossing.unwrap_or_else(|| {
                let mut x = self.plane.point(pe.2, pe.3);
                x[usize::from(axis)] += t * self.plane.spacing;
                x
            });
            (Key::Plane(pe), [xy[0], xy[1], heights[pe.0]], c.faces())
        } else {
            let o = VERTICES[usize::from(a)];
            let (pi, pj) = (i + usize::from(o[0]), j + usize::from(o[1]));
            let xy = self.plane.point(pi, pj);
            // A grid point almost on a contour puts the crossing almost on the section plane;
            // kept a hair off it, so that once written in single precision it is not on the
            // plane, where it would add an edge to the cut that is not the contour.
            let (z0, z1) = (heights[l], heights[l + 1]);
            let ulps = 8.0 * f64::from(f32::EPSILON) * z0.abs().max(z1.abs()) / (z1 - z0);
            let margin = VERTICAL_MARGIN.max(ulps).min(0.25);
            let t = t.clamp(margin, 1.0 - margin);
            let z = z0 + t * (z1 - z0);
            (Key::Vertical(pi, pj, l), [xy[0], xy[1], z], c.faces())
        }
    }

    fn emit_loop(
        &self,
        polygon: &[Corner],
        cell: [usize; 3],
        loop_index: usize,
        v: &[f32; 8],
        ids: &mut HashMap<Key, u32>,
        out: &mut ChunkMesh,
    ) {
        let [i, j, l] = cell;
        let heights = &self.field.heights;
        let mut corners: Vec<(Key, [f64; 3], u8)> = Vec::with_capacity(polygon.len() + 8);
        let n = polygon.len();
        for k in 0..n {
            let (a, b) = (polygon[k], polygon[(k + 1) % n]);
            corners.push(self.corner(a, cell, v));
            // Both on the bottom face or both on the top face of a followed section: insert the
            // piece between them.
            for (face, layer) in [(4u8, l), (5u8, l + 1)] {
                let mask = 1 << face;
                if a.faces() & mask == 0 || b.faces() & mask == 0 || !self.followed(layer) {
                    continue;
                }
                let (ea, eb) = (
                    plane_edge(a.as_edge().expect("edge"), i, j, l),
                    plane_edge(b.as_edge().expect("edge"), i, j, l),
                );
                let Some(list) = self.pieces.square(layer, i, j) else {
                    continue;
                };
                let z = heights[layer];
                if let Some(p) = list.iter().find(|p| p.from == ea && p.to == eb) {
                    corners.extend(
                        p.inner
                            .iter()
                            .map(|&(key, xy)| (key, [xy[0], xy[1], z], mask)),
                    );
                } else if let Some(p) = list.iter().find(|p| p.from == eb && p.to == ea) {
                    corners.extend(
                        p.inner
                            .iter()
                            .rev()
                            .map(|&(key, xy)| (key, [xy[0], xy[1], z], mask)),
                    );
                }
            }
        }
        let mut id = |key: Key, p: [f64; 3], out: &mut ChunkMesh| -> u32 {
            *ids.entry(key).or_insert_with(|| {
                // Checked for the whole chunk when its row ends.
                let id = out.mesh.positions.len() as u32;
                out.mesh.positions.push(p.map(|c| c as f32));
                let (engine, shared) = self.engine_key(key, &out.faces);
                out.keys.push(engine);
                if shared {
                    let row = out.rows.len() as u32;
                    out.on_faces.get_or_insert_with(Vec::new).push([id, row]);
                }
                id
            })
        };
        let vids: Vec<u32> = corners.iter().map(|&(k, p, _)| id(k, p, out)).collect();
        let positions: Vec<[f64; 3]> = vids
            .iter()
            .map(|&v| out.mesh.positions[v as usize].map(f64::from))
            .collect();
        let allowed = |x: usize, y: usize| may_join_on(corners[x].2 & corners[y].2, Z_FACES);
        let c = self.plane.point(i, j);
        // An interior vertex stays strictly between the sections: on a section plane it would
        // add edges to the cut that are not the contour.
        let margin = 1e-3 * (heights[l + 1] - heights[l]);
        let h = self.plane.spacing;
        let bounds = (
            [c[0], c[1], heights[l] + margin],
            [c[0] + h, c[1] + h, heights[l + 1] - margin],
        );
        let result = if corners.len() <= 16 {
            triangulate(&positions, &allowed, self.triangulation, bounds)
        } else {
            None
        };
        match result {
            Some(t) => {
                let centre = t
                    .interior
                    .map(|x| id(Key::Centre(i, j, l, loop_index), x, out));
                for tri in t.triangles {
                    let pick = |q: u8| {
                        vids.get(usize::from(q))
                            .copied()
                            .unwrap_or_else(|| centre.expect("a centre"))
                    };
                    out.mesh.triangles.push(tri.map(pick));
                }
            }
            None => {
                let m = positions.len() as f64;
                let x: [f64; 3] =
                    std::array::from_fn(|d| positions.iter().map(|p| p[d]).sum::<f64>() / m);
                let centre = id(Key::Centre(i, j, l, loop_index), x, out);
                for k in 0..vids.len() {
                    out.mesh
                        .triangles
                        .push([vids[k], vids[(k + 1) % vids.len()], centre]);
                }
            }
        }
    }
}
