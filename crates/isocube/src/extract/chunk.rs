//! The engine's unit of work and its joiner.
//!
//! Any box of cells is meshed on its own into a [`ChunkMesh`] whose vertices carry global
//! [`VertexKey`]s: a crossing is named by its grid edge, a snapped point by its grid point, a
//! point inside a cell by that cell and a number. Two chunks that touch make the same key for a
//! vertex on their common face, so [`join`] welds them by key alone.
//!
//! # The canonical order
//! One pass over the grid visits cells by rows (`x` fastest, then `y`, then `z`) and creates a
//! vertex when a cell first asks for it. Every cell asks for its vertices in the same order
//! whichever box it is meshed in, so a chunk records, for each row of its cells, how many
//! triangles and vertices it had made by the end of that row. The joiner then lays the rows of
//! all chunks out in the one pass's order (rows by `z`, `y`, then boxes by `x`), gives a vertex
//! shared by several chunks to the one whose row comes first, and numbers vertices in that order:
//! the joined mesh is the one pass's mesh, to the bit, however the cells were cut into boxes.
//!
//! # The halo a box needs
//! What a box's mesh depends on beyond its own cells' corner points (`min..=max` per axis):
//! - binary Marching Cubes (MC33 or classic, any triangulation): one more point on each side
//!   for the normals' central differences; none without normals;
//! - ternary: which points are zero is decided point by point in 88 ordered groups (11 rounds
//!   of crossing distance × 8 parity classes), each decision reading the zero state of points
//!   one step away decided in earlier groups, and the values read are settled from their own
//!   neighbours (a lone tie), so a box's zero points depend on the field up to 90 points beyond
//!   it. [`super::Extractor`] decides them once on the whole grid, and every box
//!   then needs one point beyond it, as for binary;
//! - labels: the labelled grid is padded by a layer of outside points, and a box of its cells
//!   reads only its own corner points (smoothing runs after the join, on the whole mesh);
//! - the contours' sectional cells (a grid of plane points by section layers): the sparse
//!   distances and the contour pieces are computed once for the stack, and a box reads only its
//!   own corners and the pieces of its own squares.

use rayon::prelude::*;
use rustc_hash::FxHashMap;

use crate::mesh::Mesh;

use super::layout::{ChunkOutline, JoinLayout};
use super::{ExtractError, ExtractStats};

/// A box of cells: cells `(i, j, k)` with `min[a] ≤ i, j, k < max[a]` along each axis `a` (a cell
/// is named by its first grid point).
///
/// ```
/// use isocube::extract::CellBox;
/// // A 9 × 9 × 9 point grid has 8³ cells; boxes of 5 cells per axis leave 3 in the last ones.
/// let boxes = CellBox::tile([9, 9, 9], [5, 5, 5]).unwrap();
/// assert_eq!(boxes.len(), 8);
/// assert_eq!(boxes.iter().map(|b| b.cell_count()).sum::<usize>(), 512);
/// assert_eq!(boxes[7], CellBox::new([5, 5, 5], [8, 8, 8]));
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct CellBox {
    /// The first cell along each axis.
    pub min: [usize; 3],
    /// One past the last cell along each axis.
    pub max: [usize; 3],
}

impl CellBox {
    /// The cells from `min` up to, not including, `max`.
    pub fn new(min: [usize; 3], max: [usize; 3]) -> CellBox {
        CellBox { min, max }
    }

    /// Every cell of a grid of `dims` points.
    pub fn whole(dims: [usize; 3]) -> CellBox {
        CellBox::new([0; 3], dims.map(|d| d.saturating_sub(1)))
    }

    /// The grid's cells cut into boxes of `size` cells per axis (smaller at the far ends), in
    /// the order `x` fastest, then `y`, then `z`. Every size must be at least 1.
    pub fn tile(dims: [usize; 3], size: [usize; 3]) -> Result<Vec<CellBox>, ExtractError> {
        if size.contains(&0) {
            return Err(ExtractError::ChunkSize { size });
        }
        let cells = dims.map(|d| d.saturating_sub(1));
        let starts = |a: usize| (0..cells[a]).step_by(size[a]);
        let mut boxes = Vec::new();
        for z in starts(2) {
            for y in starts(1) {
                for x in starts(0) {
                    let min = [x, y, z];
                    let max = [0, 1, 2].map(|a| (min[a] + size[a]).min(cells[a]));
                    boxes.push(CellBox::new(min, max));
                }
            }
        }
        Ok(boxes)
    }

    /// Cells along each axis.
    pub fn extent(&self) -> [usize; 3] {
        [0, 1, 2].map(|a| self.max[a].saturating_sub(self.min[a]))
    }

    /// Number of cells.
    pub fn cell_count(&self) -> usize {
        self.extent().iter().product()
    }

    /// Rows of cells (`y` fastest, then `z`): the units of the canonical order.
    pub(super) fn rows(&self) -> usize {
        let e = self.extent();
        e[1] * e[2]
    }

    /// Rows, for a non-empty box whose cells can be counted without overflow (a box read from
    /// bytes); every count over the box then fits.
    pub(crate) fn checked_rows(&self) -> Option<usize> {
        let e = (0..3).try_fold(Vec::new(), |mut e, a| {
            e.push(self.max[a].checked_sub(self.min[a]).filter(|&n| n > 0)?);
            Some(e)
        })?;
        let rows = e[1].checked_mul(e[2])?;
        e[0].checked_mul(rows)?;
        Some(rows)
    }

    /// Per axis, the planes of the box's low and high faces where another box of a grid of
    /// `dims` points may share them, else `usize::MAX`.
    pub(crate) fn shared_faces(&self, dims: [usize; 3]) -> [[usize; 2]; 3] {
        std::array::from_fn(|a| {
            [
                if self.min[a] > 0 {
                    self.min[a]
                } else {
                    usize::MAX
                },
                if self.max[a] + 1 < dims[a] {
                    self.max[a]
                } else {
                    usize::MAX
                },
            ]
        })
    }

    /// An error unless the box is non-empty and inside a grid of `dims` points.
    pub(crate) fn check(&self, dims: [usize; 3]) -> Result<(), ExtractError> {
        let inside = (0..3).all(|a| self.min[a] < self.max[a] && self.max[a] < dims[a]);
        if inside {
            Ok(())
        } else {
            Err(ExtractError::CellBox { cells: *self, dims })
        }
    }
}

/// The global name of a chunk mesh's vertex: the same in every chunk that makes the vertex.
///
/// Points and cells are numbered as in the grid (`x + nx·(y + ny·z)`; a cell by its first point).
///
/// ```
/// use isocube::extract::{KeyKind, VertexKey};
/// let k = VertexKey::crossing(17, 2);
/// assert_eq!(k.kind(), KeyKind::Crossing { point: 17, axis: 2 });
/// assert_eq!(k.on_plane([4, 4, 4], 2, 1), false); // a z edge never lies in a z plane
/// assert!(VertexKey::point(17).on_plane([4, 4, 4], 2, 1)); // point 17 is (1, 0, 1)
/// ```
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct VertexKey(u64);

/// What a [`VertexKey`] names.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum KeyKind {
    /// The crossing on the grid edge from `point` one step along `axis`.
    Crossing {
        /// The edge's first grid point.
        point: usize,
        /// 0, 1 or 2 for x, y, z.
        axis: usize,
    },
    /// A grid point the surface passes through (ternary extraction).
    Point(usize),
    /// A point inside one cell (a split loop's centre, a tunnel's vertex).
    Interior {
        /// The cell, by its first grid point.
        cell: usize,
        /// Which of the cell's interior points.
        index: usize,
    },
    /// A point of the input contours (a contour vertex, or a crossing folded into a contour
    /// piece) in sectional meshing, by its number in the stack. Its section plane is not in the
    /// key: the sectional mesher notes such vertices on shared faces itself.
    Contour(usize),
    /// The centroid of a simplex of the cells' Kuhn triangulation (labelled meshing): its lowest
    /// grid point and, as bits `1 << (o − 1)`, the corner offsets `o` (1 = +x, 2 = +y, 4 = +z,
    /// summed) of its other points.
    Simplex {
        /// The simplex's lowest grid point.
        point: usize,
        /// Its other points' offsets.
        corners: u8,
    },
}

// The kind in the top bits, then the payload; the ternary mesher builds keys from these too.
pub(super) const TAG_SHIFT: u32 = 61;
pub(super) const CROSSING: u64 = 0;
pub(super) const POINT: u64 = 1;
pub(super) const INTERIOR: u64 = 2;
const SIMPLEX: u64 = 3;
const CONTOUR: u64 = 4;
pub(super) const PAYLOAD: u64 = (1 << TAG_SHIFT) - 1;
/// Interior points per cell that keys can tell apart.
pub(super) const INTERIOR_SLOTS: usize = 8;

impl VertexKey {
    /// The crossing on the edge from grid point `point` along `axis`.
    #[inline]
    pub fn crossing(point: usize, axis: usize) -> VertexKey {
        VertexKey(CROSSING << TAG_SHIFT | (point as u64 * 3 + axis as u64))
    }

    /// Grid point `point`.
    #[inline]
    pub fn point(point: usize) -> VertexKey {
        VertexKey(POINT << TAG_SHIFT | point as u64)
    }

    /// Interior point `index` (below 8) of the cell whose first grid point is `cell`.
    #[inline]
    pub fn interior(cell: usize, index: usize) -> VertexKey {
        debug_assert!(index < INTERIOR_SLOTS);
        VertexKey(INTERIOR << TAG_SHIFT | (cell * INTERIOR_SLOTS + index) as u64)
    }

    /// The simplex of the Kuhn triangulation with lowest point `point` and other points at the
    /// offsets whose bits `corners` holds (see [`KeyKind::Simplex`]).
    #[inline]
    pub fn simplex(point: usize, corners: u8) -> VertexKey {
        debug_assert!(corners < 128);
        VertexKey(SIMPLEX << TAG_SHIFT | (point as u64) << 7 | u64::from(corners))
    }

    /// Point `number` of the input contours (see [`KeyKind::Contour`]).
    #[inline]
    pub fn contour(number: usize) -> VertexKey {
        VertexKey(CONTOUR << TAG_SHIFT | number as u64)
    }

    /// The key as one number (its kind in the top three bits).
    pub fn to_bits(self) -> u64 {
        self.0
    }

    /// The key of [`VertexKey::to_bits`].
    pub fn from_bits(bits: u64) -> VertexKey {
        VertexKey(bits)
    }

    /// What the key names.
    pub fn kind(self) -> KeyKind {
        let payload = (self.0 & PAYLOAD) as usize;
        match self.0 >> TAG_SHIFT {
            CROSSING => KeyKind::Crossing {
                point: payload / 3,
                axis: payload % 3,
            },
            POINT => KeyKind::Point(payload),
            SIMPLEX => KeyKind::Simplex {
                point: payload >> 7,
                corners: (payload & 127) as u8,
            },
            CONTOUR => KeyKind::Contour(payload),
            _ => KeyKind::Interior {
                cell: payload / INTERIOR_SLOTS,
                index: payload % INTERIOR_SLOTS,
            },
        }
    }

    /// Whether the vertex lies in the grid plane `axis = value` of a grid of `dims` points (an
    /// interior point never does).
    pub fn on_plane(self, dims: [usize; 3], axis: usize, value: usize) -> bool {
        let coord = |p: usize| [p % dims[0], p / dims[0] % dims[1], p / (dims[0] * dims[1])];
        match self.kind() {
            KeyKind::Crossing { point, axis: along } => {
                along != axis && coord(point)[axis] == value
            }
            KeyKind::Point(point) => coord(point)[axis] == value,
            KeyKind::Simplex { point, corners } => {
                // Every offset present must leave the axis alone.
                let moves = (1..8u8).any(|o| corners >> (o - 1) & 1 == 1 && o >> axis & 1 == 1);
                !moves && coord(point)[axis] == value
            }
            KeyKind::Interior { .. } | KeyKind::Contour(_) => false,
        }
    }
}

/// One box of cells meshed on its own: the mesh with local vertex numbers, each vertex's global
/// key, and where each row of cells ends. [`join`] welds chunks into the mesh of one pass.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ChunkMesh {
    /// The cells meshed.
    pub cells: CellBox,
    /// Vertices in the order the chunk made them, triangles over them.
    pub mesh: Mesh,
    /// The global key of each vertex.
    pub keys: Vec<VertexKey>,
    /// Counts for the box's cells.
    pub stats: ExtractStats,
    /// One tag per triangle (the label, for labelled meshing), or none.
    pub tags: Vec<u32>,
    /// After each row of cells (`y` fastest, then `z`): triangles and vertices made so far.
    pub(crate) rows: Vec<[u32; 2]>,
    /// The vertices on faces the box shares with others and the rows that made them, when the
    /// mesher noted them as it went (else they are found from the keys).
    pub(crate) on_faces: Option<Vec<[u32; 2]>>,
    /// For the mesher: per axis, the planes of the box's two faces if another box may share
    /// them, else `usize::MAX`.
    pub(crate) faces: [[usize; 2]; 3],
}

impl Default for CellBox {
    fn default() -> Self {
        CellBox::new([0; 3], [0; 3])
    }
}

impl ChunkMesh {
    /// An empty chunk for `cells`, ready for a cell mesher.
    pub(crate) fn new(cells: CellBox) -> ChunkMesh {
        ChunkMesh {
            cells,
            stats: ExtractStats {
                cells: cells.cell_count(),
                ..ExtractStats::default()
            },
            rows: Vec::with_capacity(cells.rows()),
            ..ChunkMesh::default()
        }
    }

    /// Bytes the chunk holds (what its arrays use, not what they reserved).
    pub fn bytes(&self) -> u64 {
        let m = &self.mesh;
        let v3 = std::mem::size_of::<[f32; 3]>();
        let n = (m.positions.len() + m.normals.len()) * v3
            + m.triangles.len() * std::mem::size_of::<[u32; 3]>()
            + self.keys.len() * std::mem::size_of::<VertexKey>()
            + self.tags.len() * 4
            + self.rows.len() * 8
            + self.on_faces.as_ref().map_or(0, |f| f.len() * 8);
        n as u64
    }

    /// Closes the current row of cells.
    #[inline]
    pub(crate) fn end_row(&mut self) -> Result<(), ExtractError> {
        let count = |n: usize| u32::try_from(n).map_err(|_| ExtractError::TooManyVertices);
        let row = [
            count(self.mesh.triangles.len())?,
            count(self.mesh.positions.len())?,
        ];
        self.rows.push(row);
        Ok(())
    }

    /// Whether the parts agree with one another.
    pub(super) fn well_formed(&self) -> bool {
        let m = &self.mesh;
        let v = m.positions.len();
        let rows_ok = self.rows.len() == self.cells.rows()
            && self
                .rows
                .windows(2)
                .all(|w| w[0][0] <= w[1][0] && w[0][1] <= w[1][1])
            && self
                .rows
                .last()
                .is_none_or(|r| r[0] as usize == m.triangles.len() && r[1] as usize == v);
        // Triangles' vertex numbers are checked as the joiner maps them.
        rows_ok
            && (self.tags.is_empty() || self.tags.len() == m.triangles.len())
            && self.keys.len() == v
            && (m.normals.is_empty() || m.normals.len() == v)
    }

    /// The box's faces that another box may share, as (axis, plane).
    fn shared_planes(&self, dims: [usize; 3]) -> Vec<(usize, usize)> {
        let faces = self.cells.shared_faces(dims);
        (0..3)
            .flat_map(|a| faces[a].map(|p| (a, p)))
            .filter(|&(_, p)| p != usize::MAX)
            .collect()
    }

    /// The vertices that another box may make too, with the row that made each, by vertex.
    pub(crate) fn shared_vertices(&self, dims: [usize; 3]) -> Vec<(usize, usize)> {
        let planes = self.shared_planes(dims);
        if planes.is_empty() {
            return Vec::new();
        }
        match &self.on_faces {
            Some(list) => list
                .iter()
                .map(|&[v, row]| (v as usize, row as usize))
                .collect(),
            None => (0..self.keys.len())
                .filter(|&v| {
                    planes
                        .iter()
                        .any(|&(a, p)| self.keys[v].on_plane(dims, a, p))
                })
                // The row that made vertex v: the first whose count passes it.
                .map(|v| (v, self.rows.partition_point(|r| r[1] as usize <= v)))
                .collect(),
        }
    }

    /// The global row of local row `r`: (z, y), then the box's first x orders boxes in a row.
    fn rank(&self, r: usize) -> Rank {
        rank_in(self.cells, r)
    }
}

/// The global row of row `r` of box `cells`.
pub(crate) fn rank_in(cells: CellBox, r: usize) -> Rank {
    let ny = cells.extent()[1];
    (cells.min[2] + r / ny, cells.min[1] + r % ny, cells.min[0])
}

/// Where a row of cells comes in the canonical order: (z, y, the box's first x).
pub(crate) type Rank = (usize, usize, usize);

/// Joins chunk meshes of disjoint boxes of a grid of `dims` points into `mesh` (cleared first):
/// vertices with one key become one, and vertices and triangles come in the canonical order
/// (see the module's documentation), so the result does not depend on how the cells were cut
/// nor on the order of `chunks`. `progress(done)` is called as chunks are written.
///
/// ```
/// use isocube::extract::{extract, join, CellBox, ExtractOptions, Extractor};
/// use isocube::field::Sample;
/// use isocube::mesh::Mesh;
/// let grid = Sample::Tangle.grid(24);
/// let options = ExtractOptions::default();
/// let extractor = Extractor::new(&grid, &options).unwrap();
/// let mut chunks = Vec::new();
/// for cells in CellBox::tile(grid.dims(), [7, 5, 3]).unwrap().into_iter().rev() {
///     chunks.push(extractor.mesh_box(cells).unwrap());
/// }
/// let mut joined = Mesh::new();
/// join(grid.dims(), chunks, &mut joined, &mut |_| {}).unwrap();
/// assert_eq!(joined, extract(&grid, &options).unwrap().0);
/// ```
pub fn join(
    dims: [usize; 3],
    chunks: Vec<ChunkMesh>,
    mesh: &mut Mesh,
    progress: &mut dyn FnMut(usize),
) -> Result<ExtractStats, ExtractError> {
    join_tagged(dims, chunks, mesh, &mut Vec::new(), None, progress)
}

/// [`join`], with the chunks' triangle tags into `tags` (in the joined triangles' order; left
/// empty when no chunk has tags) and, if asked, each joined vertex's key into `keys`.
pub(crate) fn join_tagged(
    dims: [usize; 3],
    chunks: Vec<ChunkMesh>,
    mesh: &mut Mesh,
    tags: &mut Vec<u32>,
    keys: Option<&mut Vec<VertexKey>>,
    progress: &mut dyn FnMut(usize),
) -> Result<ExtractStats, ExtractError> {
    mesh.clear();
    tags.clear();
    for c in &chunks {
        c.cells.check(dims)?;
    }
    if let Some(bad) = chunks.par_iter().find_first(|c| !c.well_formed()) {
        return Err(ExtractError::MalformedChunk { cells: bad.cells });
    }
    let tagged = chunks.iter().any(|c| !c.tags.is_empty());
    let normals = chunks.iter().any(|c| !c.mesh.normals.is_empty());
    if let Some(bad) = chunks.iter().find(|c| {
        (tagged && c.tags.len() != c.mesh.triangles.len())
            || (normals && c.mesh.normals.len() != c.keys.len())
    }) {
        return Err(ExtractError::MalformedChunk { cells: bad.cells });
    }
    // The layout from the chunks' outlines, as for chunks that are not in one place.
    let outlines: Vec<ChunkOutline> = chunks
        .par_iter()
        .map(|c| c.outline_with(dims, false))
        .collect();
    let layout = JoinLayout::new(dims, &outlines)?;
    drop(outlines);
    let (nv, nt) = (layout.vertices(), layout.triangles());
    let places = layout.places();
    let global: Vec<Vec<u32>> = chunks
        .par_iter()
        .zip(places)
        .map(|(chunk, place)| place.ids(chunk.keys.len()))
        .collect();
    // A chunk whose keys repeat (never made by a mesher; bytes from elsewhere may say so)
    // leaves vertices without a number: refused rather than written out of range.
    if let Some(c) = global
        .par_iter()
        .position_any(|ids| ids.iter().any(|&id| id as usize >= nv))
    {
        return Err(ExtractError::MalformedChunk {
            cells: chunks[c].cells,
        });
    }
    if let Some(keys) = keys {
        sized(keys, nv);
        for (chunk, ids) in chunks.iter().zip(&global) {
            for (&key, &id) in chunk.keys.iter().zip(ids) {
                keys[id as usize] = key;
            }
        }
    }
    sized(&mut mesh.positions, nv);
    if normals {
        sized(&mut mesh.normals, nv);
    }
    sized(&mut mesh.triangles, nt);
    if tagged {
        sized(tags, nt);
    }
    // Each run's output ranges, handed to the chunk that fills them.
    type Out<'a> = (
        usize,
        &'a mut [[f32; 3]],
        &'a mut [[f32; 3]],
        &'a mut [[u32; 3]],
        &'a mut [u32],
    );
    let mut outputs: Vec<Vec<Out>> = chunks.iter().map(|_| Vec::new()).collect();
    {
        let (mut p_rest, mut n_rest, mut t_rest, mut g_rest) = (
            &mut mesh.positions[..],
            &mut mesh.normals[..],
            &mut mesh.triangles[..],
            &mut tags[..],
        );
        for (s, &(c, r)) in layout.order.iter().enumerate() {
            let run = &places[c as usize].runs[r as usize];
            let end = layout
                .order
                .get(s + 1)
                .map(|&(c, r)| &places[c as usize].runs[r as usize]);
            let v = end.map_or(nv as u64, |e| e.first_vertex) - run.first_vertex;
            let t = (run.triangles[1] - run.triangles[0]) as usize;
            let v = v as usize;
            let (p, rest) = std::mem::take(&mut p_rest).split_at_mut(v);
            p_rest = rest;
            let (n, rest) = std::mem::take(&mut n_rest).split_at_mut(if normals { v } else { 0 });
            n_rest = rest;
            let (tri, rest) = std::mem::take(&mut t_rest).split_at_mut(t);
            t_rest = rest;
            let (g, rest) = std::mem::take(&mut g_rest).split_at_mut(if tagged { t } else { 0 });
            g_rest = rest;
            outputs[c as usize].push((r as usize, p, n, tri, g));
        }
    }
    // Each chunk is dropped as soon as it is copied: the joined mesh's memory is touched only
    // as it is filled (see `sized`), so the two are not both whole at any moment.
    let mut stats = ExtractStats::default();
    for c in &chunks {
        stats.add(&c.stats);
    }
    let cells: Vec<CellBox> = chunks.iter().map(|c| c.cells).collect();
    let count = chunks.len();
    let fits = chunks
        .into_par_iter()
        .zip(outputs)
        .zip(places)
        .zip(&global)
        .map(|(((chunk, outs), place), ids)| {
            let mut fits = true;
            for (r, p, n, tri, g) in outs {
                let run = &place.runs[r];
                let [t0, t1] = run.triangles.map(|t| t as usize);
                // Own vertices: runs between aliased ones, copied whole.
                let mut at = 0;
                for range in place.own(run) {
                    let len = range.len();
                    p[at..at + len].copy_from_slice(&chunk.mesh.positions[range.clone()]);
                    if !n.is_empty() {
                        n[at..at + len].copy_from_slice(&chunk.mesh.normals[range]);
                    }
                    at += len;
                }
                for (out, t) in tri.iter_mut().zip(&chunk.mesh.triangles[t0..t1]) {
                    *out = t.map(|x| match ids.get(x as usize) {
                        Some(&id) => id,
                        None => {
                            fits = false;
                            0
                        }
                    });
                }
                if !g.is_empty() {
                    g.copy_from_slice(&chunk.tags[t0..t1]);
                }
            }
            fits
        })
        .collect::<Vec<bool>>();
    if let Some(c) = fits.iter().position(|&f| !f) {
        mesh.clear();
        tags.clear();
        return Err(ExtractError::MalformedChunk { cells: cells[c] });
    }
    for done in 0..count {
        progress(done + 1);
    }
    Ok(stats)
}

/// Joins chunks whose boxes tile `cells` into the chunk mesh of `cells`: [`join_tagged`]'s mesh
/// and keys, and the row ends of the box's rows, so that it can be joined again.
pub(super) fn join_rows(
    dims: [usize; 3],
    chunks: Vec<ChunkMesh>,
    cells: CellBox,
) -> Result<ChunkMesh, ExtractError> {
    cells.check(dims)?;
    let ny = cells.extent()[1];
    let rows = cells.rows();
    // Triangles and vertices each row of the merged box makes: every chunk's own per row,
    // less the vertices on shared faces that a chunk with an earlier row makes first (the
    // joiner's rule), found among the seam vertices only.
    let mut triangles = vec![0u32; rows];
    let mut vertices = vec![0u32; rows];
    let row_of = |rank: Rank| (rank.0 - cells.min[2]) * ny + (rank.1 - cells.min[1]);
    for c in &chunks {
        c.cells.check(dims)?;
        let inside =
            (0..3).all(|a| cells.min[a] <= c.cells.min[a] && c.cells.max[a] <= cells.max[a]);
        if !inside || !c.well_formed() {
            return Err(ExtractError::MalformedChunk { cells: c.cells });
        }
        let mut before = [0u32; 2];
        for (r, &row) in c.rows.iter().enumerate() {
            let u = row_of(c.rank(r));
            triangles[u] += row[0] - before[0];
            vertices[u] += row[1] - before[1];
            before = row;
        }
    }
    let shared: Vec<(VertexKey, Rank)> = chunks
        .par_iter()
        .flat_map_iter(|chunk| {
            chunk
                .shared_vertices(dims)
                .into_iter()
                .map(|(v, row)| (chunk.keys[v], chunk.rank(row)))
        })
        .collect();
    let mut first: FxHashMap<VertexKey, Rank> =
        FxHashMap::with_capacity_and_hasher(shared.len(), Default::default());
    for &(key, rank) in &shared {
        first
            .entry(key)
            .and_modify(|f| *f = (*f).min(rank))
            .or_insert(rank);
    }
    // Each seam vertex counted once, in its first row: the later makers' counts come off.
    let mut counted: FxHashMap<VertexKey, ()> =
        FxHashMap::with_capacity_and_hasher(first.len(), Default::default());
    for &(key, rank) in &shared {
        if rank != first[&key] || counted.insert(key, ()).is_some() {
            // Malformed chunks can make this wrap; the total is checked after the join.
            let v = &mut vertices[row_of(rank)];
            *v = v.wrapping_sub(1);
        }
    }
    let mut mesh = Mesh::new();
    let mut tags = Vec::new();
    let mut keys = Vec::new();
    let stats = join_tagged(
        dims,
        chunks,
        &mut mesh,
        &mut tags,
        Some(&mut keys),
        &mut |_| {},
    )?;
    let mut ends = Vec::with_capacity(rows);
    let mut sum = [0u32; 2];
    for (t, v) in triangles.into_iter().zip(vertices) {
        sum = [sum[0].wrapping_add(t), sum[1].wrapping_add(v)];
        ends.push(sum);
    }
    if sum[1] as usize != keys.len() {
        return Err(ExtractError::MalformedChunk { cells });
    }
    Ok(ChunkMesh {
        cells,
        mesh,
        keys,
        stats,
        tags,
        rows: ends,
        on_faces: None,
        faces: cells.shared_faces(dims),
    })
}

/// `v` with `n` elements, all to be overwritten. Grown as a fresh zeroed allocation when it
/// must grow: the allocator hands out untouched pages, which become resident only as they are
/// written, where growing by `resize` would write every element first.
fn sized<T: Clone + Default>(v: &mut Vec<T>, n: usize) {
    if v.capacity() < n {
        *v = vec![T::default(); n];
    } else {
        v.clear();
        v.resize(n, T::default());
    }
}

/// Rows of one chunk that follow one another in the canonical order.
pub(crate) struct Run {
    /// The first row's place.
    rank: Rank,
    pub(crate) chunk: u32,
    /// Local rows.
    pub(crate) rows: std::ops::Range<usize>,
}

/// How many of box `b`'s rows follow one another in the canonical order of a grid of `dims`
/// points: all of them for a box spanning every cell in `x` and `y`, a layer's for one spanning
/// `x`, else one.
pub(crate) fn rows_per_run(dims: [usize; 3], b: CellBox) -> usize {
    let whole = CellBox::whole(dims);
    let [_, by, bz] = b.extent();
    let full_x = b.min[0] == 0 && b.max[0] == whole.max[0];
    let full_y = b.min[1] == 0 && b.max[1] == whole.max[1];
    match (full_x, full_y) {
        (true, true) => by * bz,
        (true, false) => by,
        _ => 1,
    }
}

/// The chunks' rows in the canonical order, as runs: a box spanning every cell in `x` is one run
/// per layer, one spanning `x` and `y` a single run, any other box a run per row. Fails if two
/// boxes share a cell.
pub(crate) fn ordered_runs(dims: [usize; 3], chunks: &[CellBox]) -> Result<Vec<Run>, ExtractError> {
    let whole = CellBox::whole(dims);
    let mut runs = Vec::new();
    for (c, &b) in chunks.iter().enumerate() {
        let [_, by, bz] = b.extent();
        let per_run = rows_per_run(dims, b);
        for first in (0..by * bz).step_by(per_run) {
            runs.push(Run {
                rank: rank_in(b, first),
                chunk: c as u32,
                rows: first..first + per_run,
            });
        }
    }
    runs.par_sort_unstable_by_key(|r| (r.rank, r.chunk));
    // Rows counted over the grid: a run covers [start, end) and cells [x0, x1) of each.
    let ny = whole.max[1];
    let place = |r: &Run| {
        let b = chunks[r.chunk as usize];
        let start = r.rank.0 * ny + r.rank.1;
        (start, start + r.rows.len(), b.min[0], b.max[0])
    };
    let mut covered = (0usize, 0usize);
    let mut previous: Option<&Run> = None;
    for run in &runs {
        let (start, end, x0, x1) = place(run);
        let clash = if start < covered.0 {
            Some(covered.1)
        } else {
            previous
                .filter(|p| {
                    let (_, p_end, p_x0, p_x1) = place(p);
                    p_end > start && p_x0 < x1 && x0 < p_x1
                })
                .map(|p| p.chunk as usize)
        };
        if let Some(other) = clash {
            return Err(ExtractError::OverlappingBoxes {
                first: chunks[other],
                second: chunks[run.chunk as usize],
            });
        }
        if end > start + 1 && end > covered.0 {
            covered = (end, run.chunk as usize);
        }
        previous = Some(run);
    }
    Ok(runs)
}

/// Joins chunks one after the other as they come, for meshes written as they are made: each
/// chunk must hold whole layers of cells (every row in `x` and `y`) and start where the previous
/// one ended, so the canonical order is the order of arrival. Vertices on the plane between two
/// chunks belong to the earlier one.
pub(super) struct LayerJoiner {
    dims: [usize; 3],
    next_layer: usize,
    next_vertex: u64,
    /// The previous chunk's vertices on its top plane: (key, global id), by key.
    top: Vec<(VertexKey, u32)>,
    remap: Vec<u32>,
}

/// One chunk's new vertices and its triangles, numbered globally.
pub(super) struct Joined<'a> {
    pub(super) positions: Vec<[f32; 3]>,
    pub(super) normals: Vec<[f32; 3]>,
    pub(super) triangles: Vec<[u32; 3]>,
    pub(super) chunk: &'a ChunkMesh,
}

impl LayerJoiner {
    pub(super) fn new(dims: [usize; 3]) -> LayerJoiner {
        LayerJoiner {
            dims,
            next_layer: 0,
            next_vertex: 0,
            top: Vec::new(),
            remap: Vec::new(),
        }
    }

    /// Numbers `chunk` after everything joined so far; `normals` replaces the chunk's normals
    /// when given (filled ones).
    pub(super) fn push<'a>(
        &mut self,
        chunk: &'a ChunkMesh,
        normals: Option<&[[f32; 3]]>,
    ) -> Result<Joined<'a>, ExtractError> {
        let cells = chunk.cells;
        let whole = CellBox::whole(self.dims);
        let layers = (0..2).all(|a| cells.min[a] == 0 && cells.max[a] == whole.max[a])
            && cells.min[2] == self.next_layer;
        if !layers || !chunk.well_formed() {
            return Err(ExtractError::MalformedChunk { cells });
        }
        self.next_layer = cells.max[2];
        let mesh = &chunk.mesh;
        let normals = normals.unwrap_or(&mesh.normals);
        self.remap.clear();
        self.remap.resize(mesh.positions.len(), u32::MAX);
        // Only vertices on the chunk's shared faces can be the previous chunk's, or the next's.
        let on_faces: Vec<usize> = match &chunk.on_faces {
            Some(list) => list.iter().map(|&[v, _]| v as usize).collect(),
            None => {
                let planes = chunk.shared_planes(self.dims);
                (0..chunk.keys.len())
                    .filter(|&v| {
                        planes
                            .iter()
                            .any(|&(a, p)| chunk.keys[v].on_plane(self.dims, a, p))
                    })
                    .collect()
            }
        };
        if cells.min[2] > 0 {
            for &v in &on_faces {
                if let Ok(at) = self.top.binary_search_by_key(&chunk.keys[v], |e| e.0) {
                    self.remap[v] = self.top[at].1;
                }
            }
        }
        let mut out = Joined {
            positions: Vec::new(),
            normals: Vec::new(),
            triangles: Vec::with_capacity(mesh.triangles.len()),
            chunk,
        };
        for (v, r) in self.remap.iter_mut().enumerate() {
            if *r == u32::MAX {
                if self.next_vertex >= u64::from(u32::MAX) {
                    return Err(ExtractError::TooManyVertices);
                }
                *r = self.next_vertex as u32;
                self.next_vertex += 1;
                out.positions.push(mesh.positions[v]);
                if let Some(n) = normals.get(v) {
                    out.normals.push(*n);
                }
            }
        }
        out.triangles.extend(
            mesh.triangles
                .iter()
                .map(|t| t.map(|v| self.remap[v as usize])),
        );
        self.top.clear();
        let plane = cells.max[2];
        self.top.extend(
            on_faces
                .iter()
                .map(|&v| (chunk.keys[v], v))
                .filter(|(k, _)| k.on_plane(self.dims, 2, plane))
                .map(|(k, v)| (k, self.remap[v])),
        );
        self.top.sort_unstable();
        Ok(out)
    }
}
