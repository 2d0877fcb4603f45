//! Meshing a grid that is never in one place: each box of cells from a block of the values
//! around it (a chunk of a Zarr array on a cluster's worker, with its halo), the chunk meshes
//! sent as bytes, and merged in any tree of neighbouring boxes into the mesh one pass over the
//! whole grid makes — the same vertices and triangles, in the same order.

use super::chunk::{join_rows, CellBox, ChunkMesh, KeyKind, VertexKey};
use super::layout::{put_box, put_stats};
use super::ExtractOptions;
use super::{ExtractError, ExtractStats, Extractor, Method};
use crate::field::GridView;

/// Points beyond a box of cells, on every side where the grid goes on, that a block must hold
/// for [`mesh_block`] to mesh the box as the whole grid would: one for the normals' central
/// differences (none without normals) in binary Marching Cubes; 115 for ternary extraction,
/// whose choice of snapped points reaches 90 points (88 ordered groups, each reading one step
/// further, and the ties settled from the points around them), 24 more for the rounds that keep
/// snapped points on their grid points where the surface would cross itself (six, each
/// reading four points further), plus one for the normals.
///
/// ```
/// use isocube::extract::{block_halo, ExtractOptions, Method, Snapping};
/// assert_eq!(block_halo(&ExtractOptions::default()), 1);
/// assert_eq!(block_halo(&ExtractOptions::default().with_normals(false)), 0);
/// let ternary = ExtractOptions::default().with_method(Method::Ternary(Snapping::default()));
/// assert_eq!(block_halo(&ternary), 115);
/// ```
pub fn block_halo(options: &ExtractOptions) -> usize {
    match options.method {
        Method::Ternary(_) => TERNARY_REACH + 1,
        Method::MarchingCubes => usize::from(options.normals),
    }
}

/// How far a ternary zero point's choice looks: 88 groups, each one step, the values one step
/// around the first, and each of those values' own neighbours (a lone tie is settled below the
/// level by them); then the rounds that keep snapped points off crossings where the surface
/// would pass through itself.
const TERNARY_REACH: usize = 90 + super::ternary::UNTANGLE_ROUNDS * super::ternary::UNTANGLE_REACH;

/// Meshes the cells `cells` of a grid of `dims` points from `block`, the values of points
/// `at .. at + block.dims()` of that grid (any strides; the grid's spacing and origin; no
/// heights, no direction — the joined mesh is turned by the caller), which must hold
/// [`block_halo`] points beyond the cells wherever the grid goes on. The chunk mesh is the one
/// [`super::Extractor::mesh_box`] makes for those cells on the whole grid: keys, positions,
/// normals and order, to the bit. Relaxation needs the whole mesh and is refused.
///
/// ```
/// use isocube::extract::{block_halo, extract, join, mesh_block, CellBox, ExtractOptions};
/// use isocube::field::{Grid, Sample};
/// use isocube::mesh::Mesh;
/// let grid = Sample::Tangle.grid(30);
/// let options = ExtractOptions::default();
/// let h = block_halo(&options);
/// let mut chunks = Vec::new();
/// for cells in CellBox::tile(grid.dims(), [16, 16, 16]).unwrap() {
///     // The block: the box's points and the halo, cut out of the grid.
///     let lo = cells.min.map(|m| m.saturating_sub(h));
///     let hi: [usize; 3] = std::array::from_fn(|a| (cells.max[a] + h).min(grid.dims()[a] - 1));
///     let bd: [usize; 3] = std::array::from_fn(|a| hi[a] + 1 - lo[a]);
///     let values: Vec<f32> = (0..bd[0] * bd[1] * bd[2])
///         .map(|n| grid.value(lo[0] + n % bd[0], lo[1] + n / bd[0] % bd[1], lo[2] + n / (bd[0] * bd[1])))
///         .collect();
///     let block = Grid::new(bd, values).unwrap()
///         .with_spacing(grid.spacing()).unwrap()
///         .with_origin(grid.origin()).unwrap();
///     chunks.push(mesh_block(block.view(), lo, grid.dims(), cells, &options).unwrap());
/// }
/// let mut joined = Mesh::new();
/// join(grid.dims(), chunks, &mut joined, &mut |_| {}).unwrap();
/// joined.normals = joined.filled_normals().unwrap_or(joined.normals);
/// assert_eq!(joined, extract(&grid, &options).unwrap().0);
/// ```
pub fn mesh_block(
    block: GridView<'_>,
    at: [usize; 3],
    dims: [usize; 3],
    cells: CellBox,
    options: &ExtractOptions,
) -> Result<ChunkMesh, ExtractError> {
    if options.relax > 0 {
        return Err(ExtractError::Unsupported(
            "relaxation moves vertices over the whole mesh: relax after joining",
        ));
    }
    if block.heights().is_some() {
        return Err(ExtractError::Unsupported(
            "blocks of grids with uneven planes (heights)",
        ));
    }
    cells.check(dims)?;
    let bd = block.dims();
    let halo = block_halo(options);
    let covered = (0..3).all(|a| {
        let lo = cells.min[a].saturating_sub(halo);
        let hi = (cells.max[a] + halo).min(dims[a] - 1);
        at[a] <= lo && hi < at[a] + bd[a]
    });
    if !covered {
        return Err(ExtractError::Block {
            cells,
            at,
            block: bd,
            halo,
        });
    }
    let local = block.with_base(at);
    let local_cells = CellBox::new(
        std::array::from_fn(|a| cells.min[a] - at[a]),
        std::array::from_fn(|a| cells.max[a] - at[a]),
    );
    let extractor = Extractor::new(local, options)?;
    let mut chunk = extractor.mesh_box(local_cells)?;
    // The block's point numbers → the grid's.
    let global = |p: usize| {
        let (i, j, k) = (p % bd[0], p / bd[0] % bd[1], p / (bd[0] * bd[1]));
        (i + at[0]) + dims[0] * ((j + at[1]) + dims[1] * (k + at[2]))
    };
    for key in &mut chunk.keys {
        *key = match key.kind() {
            KeyKind::Crossing { point, axis } => VertexKey::crossing(global(point), axis),
            KeyKind::Point(point) => VertexKey::point(global(point)),
            KeyKind::Interior { cell, index } => VertexKey::interior(global(cell), index),
            KeyKind::Simplex { point, corners } => VertexKey::simplex(global(point), corners),
            KeyKind::Contour(n) => VertexKey::contour(n),
        };
    }
    // Ternary: the snapped points this box owns (its points, and the grid's last plane where
    // the box reaches it), so that the counts add up over any tiling.
    if let Method::Ternary(_) = options.method {
        let owned = |a: usize| {
            let end = if cells.max[a] + 1 == dims[a] {
                cells.max[a] + 1
            } else {
                cells.max[a]
            };
            (cells.min[a] - at[a])..(end - at[a])
        };
        let mut snapped = 0;
        for k in owned(2) {
            for j in owned(1) {
                for i in owned(0) {
                    snapped += usize::from(extractor.is_zero_point([i, j, k]));
                }
            }
        }
        chunk.stats.snapped_points = snapped;
    }
    chunk.cells = cells;
    chunk.faces = cells.shared_faces(dims);
    // Vertices on the box's faces were noted against the block's edges; where a face the grid
    // shares lies on the block's edge (no halo there) the list is incomplete: the joiner then
    // finds them from the keys.
    let faces_inside = (0..3).all(|a| {
        (cells.min[a] == 0 || cells.min[a] > at[a])
            && (cells.max[a] + 1 == dims[a] || cells.max[a] + 1 < at[a] + bd[a])
    });
    if !faces_inside {
        chunk.on_faces = None;
    }
    Ok(chunk)
}

/// Merges chunk meshes whose boxes tile one box of cells (neighbours in any tree of merges)
/// into the chunk mesh of that box: the vertices its boxes share welded, everything in the
/// canonical order of the box's rows, keys kept, so it can be merged again. Merging the
/// chunks of every box of a grid, in any grouping, gives the mesh [`super::join`] gives.
///
/// ```
/// use isocube::extract::{extract, merge_chunks, CellBox, ExtractOptions, Extractor};
/// use isocube::field::Sample;
/// let grid = Sample::Gyroid.grid(25);
/// let extractor = Extractor::new(&grid, &ExtractOptions::default().with_normals(false)).unwrap();
/// let chunks = |tile: [usize; 3]| -> Vec<_> {
///     CellBox::tile(grid.dims(), tile).unwrap().into_iter()
///         .map(|b| extractor.mesh_box(b).unwrap()).collect()
/// };
/// // Eight boxes of 12³ cells: merged along x, then y, then z.
/// let mut level = chunks([12, 12, 12]);
/// for _ in 0..3 {
///     level = level.chunks(2).map(|pair| merge_chunks(grid.dims(), pair.to_vec()).unwrap()).collect();
/// }
/// let whole = extract(&grid, &ExtractOptions::default().with_normals(false)).unwrap().0;
/// assert_eq!(level[0].mesh, whole);
/// ```
pub fn merge_chunks(dims: [usize; 3], chunks: Vec<ChunkMesh>) -> Result<ChunkMesh, ExtractError> {
    let first = chunks.first().ok_or(ExtractError::Unsupported(
        "merging needs at least one chunk",
    ))?;
    let mut cells = first.cells;
    for c in &chunks {
        for a in 0..3 {
            cells.min[a] = cells.min[a].min(c.cells.min[a]);
            cells.max[a] = cells.max[a].max(c.cells.max[a]);
        }
    }
    let count: usize = chunks.iter().map(|c| c.cells.cell_count()).sum();
    if count != cells.cell_count() {
        return Err(ExtractError::Unsupported(
            "the chunks merged must tile one box of cells",
        ));
    }
    join_rows(dims, chunks, cells)
}

impl ChunkMesh {
    /// The chunk as bytes (little-endian), to send between processes or machines; read back
    /// by [`ChunkMesh::from_bytes`].
    ///
    /// ```
    /// use isocube::extract::{CellBox, ChunkMesh, ExtractOptions, Extractor};
    /// use isocube::field::Sample;
    /// let grid = Sample::Torus.grid(20);
    /// let extractor = Extractor::new(&grid, &ExtractOptions::default()).unwrap();
    /// let chunk = extractor.mesh_box(CellBox::new([0, 0, 0], [10, 19, 19])).unwrap();
    /// assert_eq!(ChunkMesh::from_bytes(&chunk.to_bytes()).unwrap(), chunk);
    /// ```
    pub fn to_bytes(&self) -> Vec<u8> {
        let m = &self.mesh;
        let mut out = Vec::with_capacity(self.bytes() as usize + 256);
        out.extend_from_slice(MAGIC);
        let mut word = |n: u64| out.extend_from_slice(&n.to_le_bytes());
        put_box(&mut word, self.cells);
        put_stats(&mut word, &self.stats);
        for f in self.faces.iter().flatten() {
            word(*f as u64);
        }
        word(m.positions.len() as u64);
        word(m.normals.len() as u64);
        word(m.triangles.len() as u64);
        word(self.tags.len() as u64);
        word(self.rows.len() as u64);
        word(self.on_faces.as_ref().map_or(u64::MAX, |f| f.len() as u64));
        for p in m.positions.iter().chain(&m.normals).flatten() {
            out.extend_from_slice(&p.to_le_bytes());
        }
        let words = m.triangles.iter().flatten().chain(&self.tags);
        let words = words.chain(self.rows.iter().flatten());
        let words = words.chain(self.on_faces.iter().flatten().flatten());
        for w in words {
            out.extend_from_slice(&w.to_le_bytes());
        }
        for k in &self.keys {
            out.extend_from_slice(&k.to_bits().to_le_bytes());
        }
        out
    }

    /// A chunk from [`ChunkMesh::to_bytes`]; bytes that are not one (cut short, altered, from
    /// another version) are refused with [`ExtractError::MalformedChunk`], never trusted.
    pub fn from_bytes(bytes: &[u8]) -> Result<ChunkMesh, ExtractError> {
        let bad = || ExtractError::MalformedChunk {
            cells: CellBox::default(),
        };
        let body = bytes.strip_prefix(MAGIC.as_slice()).ok_or_else(bad)?;
        let mut r = Reader { bytes: body };
        let CellBox { min, max } = r.cell_box().ok_or_else(bad)?;
        let stats = r.stats().ok_or_else(bad)?;
        let mut word = || r.count().ok_or_else(bad);
        let mut faces = [[0usize; 2]; 3];
        for f in faces.iter_mut().flatten() {
            *f = word()?;
        }
        let [nv, nn, nt, ng, nr] = [word()?, word()?, word()?, word()?, word()?];
        let nf = r.u64().ok_or_else(bad)?;
        let floats = |r: &mut Reader, n: usize| r.float_triples(n);
        let u32s = |r: &mut Reader, n: usize| -> Option<Vec<u32>> {
            let raw = r.take(n.checked_mul(4)?)?;
            Some(
                raw.chunks_exact(4)
                    .map(|c| u32::from_le_bytes(c.try_into().unwrap()))
                    .collect(),
            )
        };
        let positions = floats(&mut r, nv).ok_or_else(bad)?;
        let normals = floats(&mut r, nn).ok_or_else(bad)?;
        let triangles = u32s(&mut r, nt.checked_mul(3).ok_or_else(bad)?).ok_or_else(bad)?;
        let tags = u32s(&mut r, ng).ok_or_else(bad)?;
        let rows = u32s(&mut r, nr.checked_mul(2).ok_or_else(bad)?).ok_or_else(bad)?;
        let on_faces = match nf {
            u64::MAX => None,
            n => {
                let n = usize::try_from(n)
                    .ok()
                    .and_then(|n| n.checked_mul(2))
                    .ok_or_else(bad)?;
                Some(u32s(&mut r, n).ok_or_else(bad)?)
            }
        };
        let keys = r.take(nv.checked_mul(8).ok_or_else(bad)?).ok_or_else(bad)?;
        if !r.bytes.is_empty() {
            return Err(bad());
        }
        let pairs =
            |v: Vec<u32>| -> Vec<[u32; 2]> { v.chunks_exact(2).map(|c| [c[0], c[1]]).collect() };
        let cells = CellBox::new(min, max);
        // The box's rows, counted without overflow, must be the rows given (which the input's
        // length bounds): every later count over the box then fits.
        if cells.checked_rows() != Some(nr) {
            return Err(ExtractError::MalformedChunk { cells });
        }
        let chunk = ChunkMesh {
            cells,
            mesh: crate::mesh::Mesh {
                positions,
                normals,
                triangles: triangles
                    .chunks_exact(3)
                    .map(|c| [c[0], c[1], c[2]])
                    .collect(),
            },
            keys: keys
                .chunks_exact(8)
                .map(|c| VertexKey::from_bits(u64::from_le_bytes(c.try_into().unwrap())))
                .collect(),
            stats,
            tags,
            rows: pairs(rows),
            on_faces: on_faces.map(pairs),
            faces,
        };
        // The joiner walks the vertices on faces in order, once each.
        let triangles_in_range = chunk
            .mesh
            .triangles
            .iter()
            .flatten()
            .all(|&v| (v as usize) < nv);
        let faces_in_order = chunk.on_faces.as_ref().is_none_or(|list| {
            list.iter()
                .all(|&[v, row]| (v as usize) < nv && (row as usize) < chunk.rows.len())
                && list.windows(2).all(|w| w[0][0] < w[1][0])
        });
        let in_range = triangles_in_range && faces_in_order;
        if !in_range || !chunk.well_formed() {
            return Err(ExtractError::MalformedChunk { cells });
        }
        Ok(chunk)
    }
}

/// The first bytes of [`ChunkMesh::to_bytes`]: the format and its version.
const MAGIC: &[u8; 8] = b"isoCHK\x00\x01";

/// Little-endian numbers read off the front of bytes.
pub(super) struct Reader<'a> {
    pub(super) bytes: &'a [u8],
}

impl<'a> Reader<'a> {
    pub(super) fn take(&mut self, n: usize) -> Option<&'a [u8]> {
        if n > self.bytes.len() {
            return None;
        }
        let (head, rest) = self.bytes.split_at(n);
        self.bytes = rest;
        Some(head)
    }

    pub(super) fn u64(&mut self) -> Option<u64> {
        self.take(8)
            .map(|b| u64::from_le_bytes(b.try_into().unwrap()))
    }

    pub(super) fn u32(&mut self) -> Option<u32> {
        self.take(4)
            .map(|b| u32::from_le_bytes(b.try_into().unwrap()))
    }

    /// `n` triples of `u32`s.
    pub(super) fn triples(&mut self, n: usize) -> Option<Vec<[u32; 3]>> {
        let raw = self.take(n.checked_mul(12)?)?;
        Some(
            raw.chunks_exact(12)
                .map(|c| {
                    std::array::from_fn(|i| {
                        u32::from_le_bytes(c[4 * i..4 * i + 4].try_into().unwrap())
                    })
                })
                .collect(),
        )
    }

    /// `n` triples of `f32`s.
    pub(super) fn float_triples(&mut self, n: usize) -> Option<Vec<[f32; 3]>> {
        let t = self.triples(n)?;
        Some(t.into_iter().map(|w| w.map(f32::from_bits)).collect())
    }

    /// A `u64` that must fit a `usize`.
    pub(super) fn count(&mut self) -> Option<usize> {
        self.u64().and_then(|v| usize::try_from(v).ok())
    }

    /// Three counts.
    fn words(&mut self) -> Option<[usize; 3]> {
        Some([self.count()?, self.count()?, self.count()?])
    }

    /// A box written by `put_box` (not checked against any grid).
    pub(super) fn cell_box(&mut self) -> Option<CellBox> {
        let min = self.words()?;
        Some(CellBox::new(min, self.words()?))
    }

    /// Counts written by `put_stats`.
    pub(super) fn stats(&mut self) -> Option<ExtractStats> {
        Some(ExtractStats {
            cells: self.count()?,
            active_cells: self.count()?,
            skipped_cells: self.count()?,
            interior_vertices: self.count()?,
            tunnels: self.count()?,
            snapped_points: self.count()?,
            refused_points: self.count()?,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cube::Topology;
    use crate::extract::{extract, join, Snapping};
    use crate::field::{Grid, Sample};
    use crate::mesh::Mesh;
    use crate::quality::Strategy;
    use proptest::prelude::*;

    /// The block of `grid` around `cells` with `halo` points (clamped to the grid), as its own
    /// grid with the whole grid's spacing and origin, and its first point.
    fn block_of(grid: &Grid, cells: CellBox, halo: usize) -> (Grid, [usize; 3]) {
        let dims = grid.dims();
        let lo = cells.min.map(|m| m.saturating_sub(halo));
        let hi: [usize; 3] = std::array::from_fn(|a| (cells.max[a] + halo).min(dims[a] - 1));
        let bd: [usize; 3] = std::array::from_fn(|a| hi[a] + 1 - lo[a]);
        let values = (0..bd[0] * bd[1] * bd[2])
            .map(|n| {
                let (i, j, k) = (n % bd[0], n / bd[0] % bd[1], n / (bd[0] * bd[1]));
                grid.value(lo[0] + i, lo[1] + j, lo[2] + k)
            })
            .collect();
        let block = Grid::new(bd, values)
            .and_then(|g| g.with_spacing(grid.spacing()))
            .and_then(|g| g.with_origin(grid.origin()))
            .unwrap();
        (block, lo)
    }

    fn chunks(grid: &Grid, options: &ExtractOptions, tile: [usize; 3]) -> Vec<ChunkMesh> {
        let halo = block_halo(options);
        CellBox::tile(grid.dims(), tile)
            .unwrap()
            .into_iter()
            .map(|cells| {
                let (block, at) = block_of(grid, cells, halo);
                let chunk = mesh_block(block.view(), at, grid.dims(), cells, options).unwrap();
                ChunkMesh::from_bytes(&chunk.to_bytes()).unwrap()
            })
            .collect()
    }

    /// Merges neighbours in pairs along each of `axes` in turn, until one chunk is left.
    fn merge_tree(dims: [usize; 3], mut level: Vec<ChunkMesh>, axes: [usize; 3]) -> Vec<ChunkMesh> {
        for axis in axes {
            loop {
                let mut groups: std::collections::BTreeMap<(usize, usize, usize), Vec<ChunkMesh>> =
                    Default::default();
                for c in level {
                    let mut key = [c.cells.min[0], c.cells.min[1], c.cells.min[2]];
                    key[axis] = 0;
                    groups.entry((key[0], key[1], key[2])).or_default().push(c);
                }
                let mut next = Vec::new();
                let mut merged_any = false;
                for (_, mut line) in groups {
                    line.sort_by_key(|c| c.cells.min[axis]);
                    let mut line = line.into_iter();
                    while let Some(a) = line.next() {
                        match line.next() {
                            Some(b) => {
                                merged_any = true;
                                next.push(merge_chunks(dims, vec![b, a]).unwrap());
                            }
                            None => next.push(a),
                        }
                    }
                }
                level = next;
                if !merged_any {
                    break;
                }
            }
        }
        level
    }

    fn joined(dims: [usize; 3], chunks: Vec<ChunkMesh>) -> Mesh {
        let mut mesh = Mesh::new();
        join(dims, chunks, &mut mesh, &mut |_| {}).unwrap();
        if let Some(n) = mesh.filled_normals() {
            mesh.normals = n;
        }
        mesh
    }

    /// Blocks with their halo, meshed apart, sent as bytes and joined: the whole grid's mesh,
    /// for binary MC (MC33, classic, no normals, quality triangulations) and ternary, whose
    /// blocks are cut from a grid long enough that a box's halo of 115 does not reach across.
    #[test]
    fn blocks_join_into_the_whole_mesh() {
        let ternary = Method::Ternary(Snapping::default());
        let cases = [
            (
                Sample::Tangle.grid(37),
                ExtractOptions::default(),
                [16, 16, 16],
            ),
            (
                crate::with_nan_holes(Sample::Gyroid.grid(30), 77),
                ExtractOptions::default().with_topology(Topology::Classic),
                [7, 30, 11],
            ),
            (
                Sample::Gyroid.grid(33),
                ExtractOptions::default()
                    .with_normals(false)
                    .with_flip(true),
                [5, 9, 32],
            ),
            (
                Sample::Tangle.grid(29),
                ExtractOptions::default().with_triangulation(Strategy::Optimal),
                [10, 10, 10],
            ),
            (
                Grid::from_fn([300, 20, 18], [0.1, 0.1, 0.1], [0.0; 3], |p| {
                    (p[0] * 2.1).sin() * (p[1] * 1.7).cos() + (p[2] * 2.3).sin() * 0.6
                }),
                ExtractOptions::default().with_method(ternary),
                [20, 19, 17],
            ),
            // Integer values with points set to the level inside the body: lone ties, settled
            // from their neighbours, the blocks' edges included.
            (
                Grid::from_fn([296, 15, 13], [0.1, 0.1, 0.1], [0.0; 3], |p| {
                    let f = (p[0] * 1.3).sin() * (p[1] * 2.9).cos() + (p[2] * 2.1).sin() * 0.7;
                    let lone = (p[0] * 71.3 + p[1] * 13.1 + p[2] * 5.7).sin() > 0.6;
                    if lone && f < 0.0 {
                        0.0
                    } else {
                        (f * 4.0).round()
                    }
                }),
                ExtractOptions::default().with_method(ternary),
                [23, 8, 13],
            ),
            // Boxes of odd sizes: blocks start at odd points, where the choice's parity
            // classes are the whole grid's, not the block's.
            (
                Grid::from_fn(
                    [21, 26, 290],
                    [2.0 / 20.0, 2.0 / 25.0, 2.0 / 289.0],
                    [-1.0; 3],
                    |p| {
                        let (x, y, z) = (3.1 * p[2], 2.9 * p[1], 3.3 * p[0]);
                        x.sin() * y.cos() + y.sin() * z.cos() + z.sin() * x.cos() - 0.1
                    },
                ),
                ExtractOptions::default().with_method(ternary),
                [5, 13, 17],
            ),
        ];
        for (grid, options, tile) in cases {
            let whole = extract(&grid, &options).unwrap();
            assert!(!whole.0.triangles.is_empty());
            let parts = chunks(&grid, &options, tile);
            let snapped: usize = parts.iter().map(|c| c.stats.snapped_points).sum();
            assert_eq!(snapped, whole.1.snapped_points);
            let merged = merge_tree(grid.dims(), parts.clone(), [2, 1, 0]);
            assert_eq!(joined(grid.dims(), parts), whole.0, "{tile:?} {options:?}");
            let mut mesh = merged[0].mesh.clone();
            if let Some(n) = mesh.filled_normals() {
                mesh.normals = n;
            }
            assert_eq!(mesh, whole.0, "merged {tile:?} {options:?}");
        }
    }

    /// A block short of its halo is refused, naming what it lacks.
    #[test]
    fn blocks_without_their_halo_are_refused() {
        let grid = Sample::Sphere.grid(20);
        let cells = CellBox::new([5, 5, 5], [10, 10, 10]);
        let (block, at) = block_of(&grid, cells, 0);
        let e = mesh_block(
            block.view(),
            at,
            grid.dims(),
            cells,
            &ExtractOptions::default(),
        );
        assert!(
            matches!(e, Err(ExtractError::Block { halo: 1, .. })),
            "{e:?}"
        );
        let options = ExtractOptions::default().with_normals(false);
        assert!(mesh_block(block.view(), at, grid.dims(), cells, &options).is_ok());
    }

    /// Cut bytes, and a triangle naming a vertex past the end, are refused.
    #[test]
    fn damaged_chunk_bytes_are_refused() {
        let grid = Sample::Torus.grid(16);
        let options = ExtractOptions::default();
        let chunk = Extractor::new(&grid, &options)
            .unwrap()
            .mesh_box(CellBox::whole(grid.dims()))
            .unwrap();
        let bytes = chunk.to_bytes();
        for cut in [0, 7, 100, bytes.len() - 1] {
            assert!(ChunkMesh::from_bytes(&bytes[..cut]).is_err(), "{cut}");
        }
        let mut longer = bytes.clone();
        longer.push(0);
        assert!(ChunkMesh::from_bytes(&longer).is_err());
        let mut bad = chunk.clone();
        bad.mesh.triangles[0][1] = bad.mesh.positions.len() as u32;
        assert!(ChunkMesh::from_bytes(&bad.to_bytes()).is_err());
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]
        /// Random tied integer fields, random tiles, merged pairwise in a random order of
        /// axes: the whole mesh, whatever the tree.
        #[test]
        fn any_tree_of_merges_gives_the_whole_mesh(
            nx in 2usize..12, ny in 2usize..12, nz in 2usize..12,
            tx in 1usize..6, ty in 1usize..6, tz in 1usize..6,
            order in 0usize..6, seed in any::<u64>(),
        ) {
            let mut rng = crate::TestRng::new(seed);
            let values: Vec<f32> = (0..nx * ny * nz)
                .map(|_| ((rng.next_u64() >> 40) % 5) as f32 - 2.0)
                .collect();
            let grid = Grid::new([nx, ny, nz], values).unwrap();
            let options = ExtractOptions::default();
            let whole = extract(&grid, &options).unwrap().0;
            let dims = grid.dims();
            let axes = [[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]][order];
            let level = merge_tree(dims, chunks(&grid, &options, [tx, ty, tz]), axes);
            prop_assert_eq!(level.len(), 1);
            let merged = ChunkMesh::from_bytes(&level[0].to_bytes()).unwrap();
            let mut mesh = merged.mesh;
            if let Some(n) = mesh.filled_normals() {
                mesh.normals = n;
            }
            prop_assert_eq!(mesh, whole);
        }
    }
}
