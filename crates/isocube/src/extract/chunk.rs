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
//!   one step away decided in earlier groups, so a box's zero points depend on the field up to
//!   89 points beyond it. [`super::Extractor`] decides them once on the whole grid, and every box
//!   then needs one point beyond it, as for binary.

use rayon::prelude::*;

use crate::mesh::Mesh;

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

    /// An error unless the box is non-empty and inside a grid of `dims` points.
    pub(super) fn check(&self, dims: [usize; 3]) -> Result<(), ExtractError> {
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
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct VertexKey(u64);

/// What a [`VertexKey`] names.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
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

const TAG_SHIFT: u32 = 62;
const CROSSING: u64 = 0;
const POINT: u64 = 1;
const INTERIOR: u64 = 2;
const SIMPLEX: u64 = 3;
const PAYLOAD: u64 = (1 << TAG_SHIFT) - 1;
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

    /// The key as one number (its kind in the top two bits).
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
            KeyKind::Interior { .. } => false,
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
    pub(super) rows: Vec<[u32; 2]>,
}

impl Default for CellBox {
    fn default() -> Self {
        CellBox::new([0; 3], [0; 3])
    }
}

impl ChunkMesh {
    /// An empty chunk for `cells`, ready for a cell mesher.
    pub(super) fn new(cells: CellBox) -> ChunkMesh {
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

    /// Closes the current row of cells.
    #[inline]
    pub(super) fn end_row(&mut self) -> Result<(), ExtractError> {
        let count = |n: usize| u32::try_from(n).map_err(|_| ExtractError::TooManyVertices);
        let row = [
            count(self.mesh.triangles.len())?,
            count(self.mesh.positions.len())?,
        ];
        self.rows.push(row);
        Ok(())
    }

    /// Whether the parts agree with one another.
    fn well_formed(&self) -> bool {
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
        // A triangle uses only vertices made by the end of its row.
        let mut triangles_ok = true;
        let mut start = 0usize;
        for r in &self.rows {
            let end = r[0] as usize;
            triangles_ok &= m.triangles[start..end.min(m.triangles.len())]
                .iter()
                .all(|t| t.iter().all(|&x| x < r[1]));
            start = end;
        }
        rows_ok
            && triangles_ok
            && (self.tags.is_empty() || self.tags.len() == m.triangles.len())
            && self.keys.len() == v
            && (m.normals.is_empty() || m.normals.len() == v)
    }

    /// The box's faces that another box may share, as (axis, plane).
    fn shared_planes(&self, dims: [usize; 3]) -> Vec<(usize, usize)> {
        let mut planes = Vec::with_capacity(6);
        for (a, &n) in dims.iter().enumerate() {
            if self.cells.min[a] > 0 {
                planes.push((a, self.cells.min[a]));
            }
            if self.cells.max[a] + 1 < n {
                planes.push((a, self.cells.max[a]));
            }
        }
        planes
    }

    /// The row in which each vertex was made.
    fn vertex_rows(&self) -> Vec<u32> {
        let mut out = Vec::with_capacity(self.keys.len());
        let mut start = 0usize;
        for (r, row) in self.rows.iter().enumerate() {
            let end = row[1] as usize;
            out.extend(std::iter::repeat_n(r as u32, end - start));
            start = end;
        }
        out
    }

    /// The global row of local row `r`: (z, y), then the box's first x orders boxes in a row.
    fn rank(&self, r: usize) -> (usize, usize, usize) {
        let ny = self.cells.extent()[1];
        (
            self.cells.min[2] + r / ny,
            self.cells.min[1] + r % ny,
            self.cells.min[0],
        )
    }
}

/// A vertex another chunk may make too: (key, rank of the row that made it, chunk, local).
type Shared = (VertexKey, (usize, usize, usize), u32, u32);

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
    join_tagged(dims, chunks, mesh, &mut Vec::new(), progress)
}

/// [`join`], with the chunks' triangle tags into `tags` (in the joined triangles' order; left
/// empty when no chunk has tags).
pub(super) fn join_tagged(
    dims: [usize; 3],
    chunks: Vec<ChunkMesh>,
    mesh: &mut Mesh,
    tags: &mut Vec<u32>,
    progress: &mut dyn FnMut(usize),
) -> Result<ExtractStats, ExtractError> {
    mesh.clear();
    tags.clear();
    for c in &chunks {
        c.cells.check(dims)?;
        if !c.well_formed() {
            return Err(ExtractError::MalformedChunk { cells: c.cells });
        }
    }
    // Rows of every chunk in the one pass's order; boxes that meet in a row must not overlap.
    let mut segments: Vec<((usize, usize, usize), u32, u32)> = chunks
        .iter()
        .enumerate()
        .flat_map(|(c, chunk)| {
            (0..chunk.rows.len()).map(move |r| (chunk.rank(r), c as u32, r as u32))
        })
        .collect();
    segments.par_sort_unstable();
    for w in segments.windows(2) {
        let (a, b) = (&chunks[w[0].1 as usize], &chunks[w[1].1 as usize]);
        if (w[0].0 .0, w[0].0 .1) == (w[1].0 .0, w[1].0 .1) && a.cells.max[0] > b.cells.min[0] {
            return Err(ExtractError::OverlappingBoxes {
                first: a.cells,
                second: b.cells,
            });
        }
    }
    let mut segment_of: Vec<Vec<u32>> = chunks.iter().map(|c| vec![0; c.rows.len()]).collect();
    for (s, &(_, c, r)) in segments.iter().enumerate() {
        segment_of[c as usize][r as usize] = s as u32;
    }
    // Vertices on faces two boxes share: the first row to make one owns it.
    let vertex_rows: Vec<Vec<u32>> = chunks.par_iter().map(ChunkMesh::vertex_rows).collect();
    let mut shared: Vec<Shared> = chunks
        .par_iter()
        .zip(&vertex_rows)
        .enumerate()
        .flat_map_iter(|(c, (chunk, rows))| {
            let planes = chunk.shared_planes(dims);
            chunk
                .keys
                .iter()
                .enumerate()
                .filter(move |(_, k)| planes.iter().any(|&(a, p)| k.on_plane(dims, a, p)))
                .map(move |(v, &k)| (k, chunk.rank(rows[v] as usize), c as u32, v as u32))
                .collect::<Vec<_>>()
        })
        .collect();
    shared.par_sort_unstable();
    // owned[c][v]: false for a vertex another chunk owns; aliases: (chunk, local, owner, local).
    let mut owned: Vec<Vec<bool>> = chunks.iter().map(|c| vec![true; c.keys.len()]).collect();
    let mut aliases: Vec<(u32, u32, u32, u32)> = Vec::new();
    for group in shared.chunk_by(|a, b| a.0 == b.0) {
        let owner = group[0];
        for other in &group[1..] {
            owned[other.2 as usize][other.3 as usize] = false;
            aliases.push((other.2, other.3, owner.2, owner.3));
        }
    }
    // Where each segment's new vertices and triangles go.
    let mut vertex_base = Vec::with_capacity(segments.len() + 1);
    let mut triangle_base = Vec::with_capacity(segments.len() + 1);
    let (mut nv, mut nt) = (0usize, 0usize);
    for &(_, c, r) in &segments {
        vertex_base.push(nv);
        triangle_base.push(nt);
        let chunk = &chunks[c as usize];
        let (r, c) = (r as usize, c as usize);
        let ([t0, v0], [t1, v1]) = (
            if r == 0 { [0, 0] } else { chunk.rows[r - 1] },
            chunk.rows[r],
        );
        nv += owned[c][v0 as usize..v1 as usize]
            .iter()
            .filter(|&&o| o)
            .count();
        nt += (t1 - t0) as usize;
    }
    vertex_base.push(nv);
    triangle_base.push(nt);
    if nv > u32::MAX as usize {
        return Err(ExtractError::TooManyVertices);
    }
    // Local → global: owned vertices by their segment, the others through their owner.
    let mut global: Vec<Vec<u32>> = chunks
        .par_iter()
        .enumerate()
        .map(|(c, chunk)| {
            let mut ids = vec![u32::MAX; chunk.keys.len()];
            let mut start = 0usize;
            for (r, row) in chunk.rows.iter().enumerate() {
                let mut next = vertex_base[segment_of[c][r] as usize] as u32;
                for v in start..row[1] as usize {
                    if owned[c][v] {
                        ids[v] = next;
                        next += 1;
                    }
                }
                start = row[1] as usize;
            }
            ids
        })
        .collect();
    for &(c, v, oc, ov) in &aliases {
        global[c as usize][v as usize] = global[oc as usize][ov as usize];
    }
    let normals = chunks.iter().any(|c| !c.mesh.normals.is_empty());
    if normals
        && chunks
            .iter()
            .any(|c| c.mesh.normals.is_empty() && !c.keys.is_empty())
    {
        let bad = chunks
            .iter()
            .find(|c| c.mesh.normals.is_empty() && !c.keys.is_empty())
            .expect("found above");
        return Err(ExtractError::MalformedChunk { cells: bad.cells });
    }
    mesh.positions.resize(nv, [0.0; 3]);
    if normals {
        mesh.normals.resize(nv, [0.0; 3]);
    }
    mesh.triangles.resize(nt, [0; 3]);
    let tagged = chunks.iter().any(|c| !c.tags.is_empty());
    if let Some(bad) = chunks
        .iter()
        .find(|c| tagged && c.tags.len() != c.mesh.triangles.len())
    {
        return Err(ExtractError::MalformedChunk { cells: bad.cells });
    }
    if tagged {
        tags.resize(nt, 0);
    }
    // Each segment's output ranges, handed to the chunk that fills them.
    type Out<'a> = (
        &'a mut [[f32; 3]],
        &'a mut [[f32; 3]],
        &'a mut [[u32; 3]],
        &'a mut [u32],
    );
    let mut outputs: Vec<Vec<(u32, Out)>> = chunks.iter().map(|_| Vec::new()).collect();
    {
        let (mut p_rest, mut n_rest, mut t_rest, mut g_rest) = (
            &mut mesh.positions[..],
            &mut mesh.normals[..],
            &mut mesh.triangles[..],
            &mut tags[..],
        );
        for (s, &(_, c, r)) in segments.iter().enumerate() {
            let v = vertex_base[s + 1] - vertex_base[s];
            let (p, rest) = std::mem::take(&mut p_rest).split_at_mut(v);
            p_rest = rest;
            let (n, rest) = std::mem::take(&mut n_rest).split_at_mut(if normals { v } else { 0 });
            n_rest = rest;
            let nt = triangle_base[s + 1] - triangle_base[s];
            let (t, rest) = std::mem::take(&mut t_rest).split_at_mut(nt);
            t_rest = rest;
            let (g, rest) = std::mem::take(&mut g_rest).split_at_mut(if tagged { nt } else { 0 });
            g_rest = rest;
            outputs[c as usize].push((r, (p, n, t, g)));
        }
    }
    chunks
        .par_iter()
        .enumerate()
        .zip(outputs)
        .for_each(|((c, chunk), outs)| {
            let ids = &global[c];
            for (r, (p, n, t, g)) in outs {
                let r = r as usize;
                let [t0, v0] = if r == 0 { [0, 0] } else { chunk.rows[r - 1] };
                let [t1, v1] = chunk.rows[r];
                let (v0, v1) = (v0 as usize, v1 as usize);
                let mine = owned[c][v0..v1].iter().enumerate().filter(|(_, &o)| o);
                for (slot, (v, _)) in mine.enumerate() {
                    p[slot] = chunk.mesh.positions[v0 + v];
                    if let Some(x) = n.get_mut(slot) {
                        *x = chunk.mesh.normals[v0 + v];
                    }
                }
                for (out, tri) in t
                    .iter_mut()
                    .zip(&chunk.mesh.triangles[t0 as usize..t1 as usize])
                {
                    *out = tri.map(|x| ids[x as usize]);
                }
                if !g.is_empty() {
                    g.copy_from_slice(&chunk.tags[t0 as usize..t1 as usize]);
                }
            }
        });
    let mut stats = ExtractStats::default();
    for (done, c) in chunks.iter().enumerate() {
        stats.add(&c.stats);
        progress(done + 1);
    }
    Ok(stats)
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
        if cells.min[2] > 0 {
            for (v, k) in chunk.keys.iter().enumerate() {
                if let Ok(at) = self.top.binary_search_by_key(k, |e| e.0) {
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
            chunk
                .keys
                .iter()
                .enumerate()
                .filter(|(_, k)| k.on_plane(self.dims, 2, plane))
                .map(|(v, &k)| (k, self.remap[v])),
        );
        self.top.sort_unstable();
        Ok(out)
    }
}
