//! The binary (classic and MC33) cell mesher: a box of cells at a time, empty space skipped 64
//! cells at a time.
//!
//! 1. Sign masks: one bit per point of the box (at or above the level), and, only if the box has
//!    any, one per non-finite point; rows of 64-bit words, computed by each box for its own
//!    points.
//! 2. A cell is empty when its eight corners agree; for 64 cells of a row that is a few word
//!    operations on the masks of the four point rows around them (all above: the AND of the rows
//!    and of the rows shifted by one; all below: the same on the complements). Only the other
//!    cells are visited.
//! 3. Each vertex is made when a cell first asks for it, and carries its global key; the joiner
//!    ([`super::chunk`]) welds boxes into the mesh of one pass, whatever the partition.

use rayon::prelude::*;

use super::chunk::{CellBox, ChunkMesh, VertexKey};
use super::place::{interior_bounds, Bounds, Placer};
use super::untangle::mend;
use super::weld::EdgeCache;
use super::window::Window;
use super::{cell_config, choose_tunnel, face_decisions, ExtractError, ExtractOptions};
use crate::cube::triangulate::{may_join, safe_triangulation_where};
use crate::cube::{CaseTable, CellTriangles, Corner, Topology, EDGES, EDGE_AXIS, VERTICES};
use crate::field::is_above;
use crate::mesh::Mesh;
use crate::quality::{triangulate_polygon, Chords, Strategy, MAX_CORNERS};

/// Sign masks of every point row.
pub(super) struct Masks {
    /// 64-bit words per row.
    pub(super) words: usize,
    above: Vec<u64>,
    /// Non-finite points, if the grid has any.
    invalid: Option<Vec<u64>>,
}

impl Masks {
    /// Masks of the points of the cells of a box from cell `min` up to `max` (points `min..=max`
    /// per axis); rows and bits are counted from `min`.
    pub(super) fn new(window: &Window, level: f32, min: [usize; 3], max: [usize; 3]) -> Masks {
        let width = max[0] + 1 - min[0];
        let words = width.div_ceil(64);
        let rows = (max[1] + 1 - min[1]) * (max[2] + 1 - min[2]);
        let mut above = vec![0u64; rows * words];
        let mut invalid = false;
        let mut out = above.chunks_exact_mut(words);
        window.for_each_row(min, max, |row| {
            invalid |= pack_row(row, level, out.next().expect("a mask row per point row"));
        });
        let invalid = invalid.then(|| {
            let mut bad = vec![0u64; above.len()];
            let mut out = bad.chunks_exact_mut(words);
            window.for_each_row(min, max, |row| {
                invalid_row(row, out.next().expect("a mask row per point row"));
            });
            bad
        });
        Masks {
            words,
            above,
            invalid,
        }
    }

    /// [`Masks::new`] for all points of a grid stored `x` fastest, a plane per task.
    pub(super) fn new_parallel(values: &[f32], dims: [usize; 3], level: f32) -> Masks {
        let [nx, ny, nz] = dims;
        let words = nx.div_ceil(64);
        let mut above = vec![0u64; ny * nz * words];
        let invalid = values
            .par_chunks(nx * ny)
            .zip(above.par_chunks_mut(ny * words))
            .map(|(plane, out)| {
                plane
                    .chunks_exact(nx)
                    .zip(out.chunks_exact_mut(words))
                    .fold(false, |bad, (row, out)| bad | pack_row(row, level, out))
            })
            .reduce(|| false, |a, b| a | b);
        let invalid = invalid.then(|| {
            let mut bad = vec![0u64; above.len()];
            for (row, out) in values.chunks_exact(nx).zip(bad.chunks_exact_mut(words)) {
                invalid_row(row, out);
            }
            bad
        });
        Masks {
            words,
            above,
            invalid,
        }
    }

    /// The above bits of row `(j, k)` (`k` counted from the masks' first plane).
    pub(super) fn above(&self, j: usize, k: usize, ny: usize) -> &[u64] {
        self.row(&self.above, j, k, ny)
    }

    /// Whether every point is finite (no non-finite mask was needed).
    pub(super) fn all_finite(&self) -> bool {
        self.invalid.is_none()
    }

    /// The above bits of points `i..i + 3` of row `(j, k)`, as the low three bits (`i + 3` at
    /// most the row's length).
    #[inline]
    pub(super) fn above3(&self, i: usize, j: usize, k: usize, ny: usize) -> u64 {
        bits3(&self.above, (k * ny + j) * self.words * 64 + i)
    }

    /// The word holding point `(i, j, k)`'s above bit, if the masks hold that point.
    pub(super) fn word(&self, i: usize, j: usize, k: usize, ny: usize) -> Option<&u64> {
        self.above.get((k * ny + j) * self.words + i / 64)
    }

    /// Marks point `(i, j, k)` above the level (`k` counted from the masks' first plane).
    pub(super) fn set_above(&mut self, [i, j, k]: [usize; 3], ny: usize) {
        self.above[(k * ny + j) * self.words + i / 64] |= 1 << (i % 64);
    }

    fn row<'a>(&self, masks: &'a [u64], j: usize, k: usize, ny: usize) -> &'a [u64] {
        let r = k * ny + j;
        &masks[r * self.words..(r + 1) * self.words]
    }

    /// The cells of row `(j, k)` to visit, one bit each: corners that disagree, or a non-finite
    /// corner (counted and skipped by the cell code).
    pub(super) fn visit(&self, j: usize, k: usize, ny: usize, cells: usize, out: &mut [u64]) {
        let rows = [(j, k), (j + 1, k), (j, k + 1), (j + 1, k + 1)];
        let a = rows.map(|(j, k)| self.row(&self.above, j, k, ny));
        let shifted = |m: &[&[u64]; 4], w: usize, and: bool| -> (u64, u64) {
            let pick = |w: usize| {
                let x = [m[0][w], m[1][w], m[2][w], m[3][w]];
                if and {
                    x[0] & x[1] & x[2] & x[3]
                } else {
                    x[0] | x[1] | x[2] | x[3]
                }
            };
            let here = pick(w);
            let next = if w + 1 < self.words { pick(w + 1) } else { 0 };
            (here, (here >> 1) | (next << 63))
        };
        for (w, slot) in out.iter_mut().enumerate() {
            let (all, all_next) = shifted(&a, w, true);
            let (any, any_next) = shifted(&a, w, false);
            // All eight above: all rows above at i and i + 1; all below: none above at either.
            let mut v = !((all & all_next) | !(any | any_next));
            if let Some(bad) = &self.invalid {
                let b = rows.map(|(j, k)| self.row(bad, j, k, ny));
                let (touch, touch_next) = shifted(&b, w, false);
                v |= touch | touch_next;
            }
            // Only cells 0..cells.
            let first = w * 64;
            if first + 64 > cells {
                let keep = cells.saturating_sub(first);
                v &= if keep >= 64 { !0 } else { (1u64 << keep) - 1 };
            }
            *slot = v;
        }
    }
}

/// Bits `at..at + 3` of a bit array (bit `b` of word `w` is `64 w + b`), as the low three bits.
#[inline]
pub(super) fn bits3(words: &[u64], at: usize) -> u64 {
    let (w, b) = (at / 64, at % 64);
    let low = words[w] >> b;
    let high = if b > 61 { words[w + 1] << (64 - b) } else { 0 };
    (low | high) & 7
}

/// Packs the above bits of one row of values into `out` (whole words); returns whether some
/// value is not finite.
fn pack_row(row: &[f32], level: f32, out: &mut [u64]) -> bool {
    let mut invalid = false;
    let full = row.chunks_exact(64);
    let tail = full.remainder();
    for (w, chunk) in full.enumerate() {
        let (bits, bad) = pack_above(chunk, level);
        out[w] = bits;
        invalid |= bad;
    }
    if !tail.is_empty() {
        let mut bits = 0u64;
        for (b, &v) in tail.iter().enumerate() {
            bits |= u64::from(is_above(v, level)) << b;
            invalid |= !v.is_finite();
        }
        out[out.len() - 1] = bits;
    }
    invalid
}

/// The non-finite bits of one row.
fn invalid_row(row: &[f32], out: &mut [u64]) {
    for (w, chunk) in row.chunks(64).enumerate() {
        out[w] = chunk
            .iter()
            .enumerate()
            .fold(0, |m, (b, v)| m | u64::from(!v.is_finite()) << b);
    }
}

/// The positions of the set bits of `words` (bit `b` of word `w` is `64 w + b`), in order: the
/// cells [`Masks::visit`] marked.
pub(super) fn set_bits(words: &[u64]) -> impl Iterator<Item = usize> + '_ {
    words.iter().enumerate().flat_map(|(w, &word)| {
        let mut bits = word;
        std::iter::from_fn(move || {
            (bits != 0).then(|| {
                let i = w * 64 + bits.trailing_zeros() as usize;
                bits &= bits - 1;
                i
            })
        })
    })
}

/// Bit `b` set when `values[b]` is at or above the level, for 64 values, and whether one of
/// them is not finite: the comparisons go to bytes (which vectorises), and each 8 bytes of 0/1
/// are gathered into 8 bits by one multiply. Non-finite values are found from their bits
/// (exponent all ones), or-ed lane by lane: a float sum would be a chain of dependent adds the
/// compiler may not reorder, four times slower than the rest of the loop.
#[inline]
fn pack_above(values: &[f32], level: f32) -> (u64, bool) {
    const EXPONENT: u32 = 0x7f80_0000;
    let mut bytes = [0u8; 64];
    let mut bad = 0u32;
    for (o, &v) in bytes.iter_mut().zip(values) {
        *o = u8::from(is_above(v, level));
        bad |= u32::from(v.to_bits() & EXPONENT == EXPONENT);
    }
    let mut bits = 0u64;
    for (k, eight) in bytes.chunks_exact(8).enumerate() {
        let x = u64::from_le_bytes(eight.try_into().expect("8 bytes"));
        bits |= (x.wrapping_mul(0x0102_0408_1020_4080) >> 56) << (8 * k);
    }
    (bits, bad != 0)
}

/// Cell layers per slab of the default partition: at least 16 slabs to balance the cores, and a
/// slab's planes within about 8 MiB, so the values its masks read are still cached when its
/// cells read them again; a function of the grid's size only.
pub(super) fn slab_height(nx: usize, ny: usize, nz: usize) -> usize {
    let plane = nx * ny * std::mem::size_of::<f32>();
    let fit = (8 << 20) / plane.max(1);
    fit.min(nz.div_ceil(16)).max(4)
}

/// The default partition: slabs of whole cell layers.
pub(crate) fn slabs(dims: [usize; 3]) -> Vec<CellBox> {
    let [nx, ny, nz] = dims;
    let height = slab_height(nx, ny, nz - 1);
    CellBox::tile(dims, [nx - 1, ny - 1, height]).expect("sizes of at least 1")
}

/// The binary cell mesher: one box of cells at a time, from the values of a [`Window`] that
/// holds the box's points and one more plane on each side where the grid has them (normals
/// read one point beyond the cells).
pub(super) struct BinaryCells<'a> {
    table: &'static CaseTable,
    options: &'a ExtractOptions,
    grid: Window<'a>,
    placer: Placer<'a>,
}

impl<'a> BinaryCells<'a> {
    pub(super) fn new(grid: Window<'a>, options: &'a ExtractOptions) -> BinaryCells<'a> {
        BinaryCells {
            table: CaseTable::binary(),
            options,
            grid,
            placer: Placer::new(grid, options),
        }
    }

    /// Meshes the cells of `cells` (inside the window), reusing `cache`.
    pub(super) fn mesh_box(
        &self,
        cache: &mut EdgeCache,
        cells: CellBox,
    ) -> Result<ChunkMesh, ExtractError> {
        let grid = &self.grid;
        let level = self.options.level;
        let [bx, by, _] = cells.extent();
        let [x0, y0, z0] = cells.min;
        let mut out = ChunkMesh::new(cells);
        out.on_faces = Some(Vec::new());
        out.faces = cells.shared_faces(grid.dims());
        cache.prepare(bx + 1, by + 1);
        let values = grid.values();
        let [sx, sy, sz] = grid.strides();
        // Offsets of the cube vertices from the cell's first point, in the numbering of `cube`.
        let corner_offsets = [0, sx, sx + sy, sy, sz, sx + sz, sx + sy + sz, sy + sz];
        // The box's own masks: its planes are read once, just before their cells are visited.
        let masks = Masks::new(grid, level, cells.min, cells.max);
        let rows = by + 1;
        // The cells to visit, row by row, found once: counted first to size the arrays (about
        // one vertex and two triangles per cell visited, so they are not copied as they grow),
        // then walked.
        let words = masks.words;
        let mut visits = vec![0u64; by * cells.extent()[2] * words];
        for (r, out) in visits.chunks_exact_mut(words).enumerate() {
            masks.visit(r % by, r / by, rows, bx, out);
        }
        let candidates: usize = visits.iter().map(|w| w.count_ones() as usize).sum();
        let mesh = &mut out.mesh;
        mesh.positions.reserve(candidates + candidates / 8);
        out.keys.reserve(candidates + candidates / 8);
        mesh.triangles.reserve(2 * candidates + candidates / 4);
        if self.options.normals {
            mesh.normals.reserve(candidates + candidates / 8);
        }
        let mut visit_rows = visits.chunks_exact(words);
        for k in 0..cells.extent()[2] {
            for j in 0..by {
                let visit = visit_rows.next().expect("a row of visits per row of cells");
                for i in set_bits(visit) {
                    let cell = [x0 + i, y0 + j, z0 + k];
                    let base = grid.index(cell[0], cell[1], cell[2]);
                    // Written out: `array::map` here was not always inlined.
                    let o = &corner_offsets;
                    let v = [
                        values[base + o[0]],
                        values[base + o[1]],
                        values[base + o[2]],
                        values[base + o[3]],
                        values[base + o[4]],
                        values[base + o[5]],
                        values[base + o[6]],
                        values[base + o[7]],
                    ];
                    if v.iter().any(|x| !x.is_finite()) {
                        out.stats.skipped_cells += 1;
                        continue;
                    }
                    let config = cell_config(&v, level);
                    if config == 0 || config == 255 {
                        continue;
                    }
                    let at = At {
                        local: [i, j],
                        cell,
                        v: &v,
                    };
                    self.mesh_cell(cache, &mut out, at, config)?;
                }
                out.end_row()?;
            }
            cache.next_layer();
        }
        Ok(out)
    }

    /// The crossing on edge `e` of `cell`, made on first use (`local`: the cell in the box).
    #[inline(always)]
    fn edge(
        &self,
        cache: &mut EdgeCache,
        out: &mut ChunkMesh,
        at: At,
        e: u8,
    ) -> Result<u32, ExtractError> {
        let [li, lj] = at.local;
        cache.vertex(li, lj, e, || self.new_edge_vertex(out, at.cell, at.v, e))
    }

    /// Makes the crossing on edge `e` of `cell`, with its key. Kept out of line: it runs once
    /// per vertex, while the look-up around it runs for every corner of every cell.
    #[inline(never)]
    fn new_edge_vertex(
        &self,
        out: &mut ChunkMesh,
        cell: [usize; 3],
        v: &[f32; 8],
        e: u8,
    ) -> Result<u32, ExtractError> {
        let id = self.placer.edge_vertex_of(cell, v, e, &mut out.mesh)?;
        let start = VERTICES[usize::from(EDGES[usize::from(e)][0])];
        let p = [0, 1, 2].map(|a| cell[a] + usize::from(start[a]));
        let axis = usize::from(EDGE_AXIS[usize::from(e)]);
        out.keys
            .push(VertexKey::crossing(self.grid.point_index(p), axis));
        // On a face another box may share: noted now, so the joiner need not decode keys.
        let faces = &out.faces;
        let on_face = (0..3).any(|a| a != axis && (p[a] == faces[a][0] || p[a] == faces[a][1]));
        if on_face {
            let row = out.rows.len() as u32;
            out.on_faces.get_or_insert_with(Vec::new).push([id, row]);
        }
        Ok(id)
    }

    /// Interior point `index` of `cell`, made by `make`.
    fn interior(
        &self,
        out: &mut ChunkMesh,
        cell: [usize; 3],
        index: usize,
        make: impl FnOnce(&Placer, &mut Mesh) -> Result<u32, ExtractError>,
    ) -> Result<u32, ExtractError> {
        let id = make(&self.placer, &mut out.mesh)?;
        out.keys
            .push(VertexKey::interior(self.grid.point_index(cell), index));
        out.stats.interior_vertices += 1;
        Ok(id)
    }

    fn push(&self, out: &mut ChunkMesh, mut t: [u32; 3]) {
        if self.options.flip {
            t.swap(1, 2);
        }
        out.mesh.triangles.push(t);
    }

    fn mesh_cell(
        &self,
        cache: &mut EdgeCache,
        out: &mut ChunkMesh,
        at: At,
        config: u8,
    ) -> Result<(), ExtractError> {
        let (table, options) = (self.table, self.options);
        let level = options.level;
        out.stats.active_cells += 1;
        let decisions = face_decisions(at.v, level, table.ambiguous_faces(config));
        let tunnel = if options.topology == Topology::Mc33
            && table.has_tunnel_candidates(config, decisions)
        {
            choose_tunnel(table, config, decisions, at.v, level)
        } else {
            None
        };
        out.stats.tunnels += usize::from(tunnel.is_some());
        let fan = options.triangulation == Strategy::Fan;
        let sheet = |p: &[Corner]| face_square_start(p, at.v, level);
        // Crossings on points of a face can join across it: the table's chord may be the
        // diagonal the cell across does not draw. Only crossings on grid points (a corner's
        // value the level) can: where no corner is at the level, as in most cells, there is
        // nothing to look for.
        let on_level = at.v.contains(&level);
        let across = |p: &[Corner]| {
            on_level
                && p.iter().enumerate().any(|(i, &a)| {
                    p[i + 1..]
                        .iter()
                        .any(|&b| off_face_diagonal(a, b, at.v, level))
                })
        };
        if tunnel.is_none() && (!fan || table.polygons(config, decisions).any(across)) {
            let bounds = self.interior_bounds(at.cell);
            for (l, polygon) in table.polygons(config, decisions).enumerate() {
                if let Some(i) = sheet(polygon) {
                    let ids = self.corner_ids(cache, out, at, polygon)?;
                    let q = |k: usize| ids[(i + k) % 4];
                    self.push(out, [q(0), q(1), q(2)]);
                    self.push(out, [q(0), q(2), q(3)]);
                } else if fan {
                    let ids = self.corner_ids(cache, out, at, polygon)?;
                    self.table_triangles(out, at, l, polygon, &ids)?;
                } else {
                    self.emit_polygon(cache, out, at, l, polygon, bounds)?;
                }
            }
            return Ok(());
        }
        let triangles = table.cell_triangles(config, decisions, options.topology, tunnel);
        if let Some(k) = tunnel {
            let loops = table.tunnel_loops(config, decisions, k);
            if self.untangled(cache, out, at, &triangles, loops)? {
                return Ok(());
            }
        }
        let mut interior = [u32::MAX; Corner::MAX_INTERIOR];
        for tri in triangles.triangles {
            let mut ids = [0u32; 3];
            for (slot, &corner) in ids.iter_mut().zip(tri) {
                *slot = if let Some(e) = corner.as_edge() {
                    self.edge(cache, out, at, e)?
                } else {
                    let p = usize::from(
                        corner
                            .as_interior()
                            .expect("binary cells have edge and interior corners"),
                    );
                    if interior[p] == u32::MAX {
                        let support = triangles.interior_support(p);
                        let ids = self.corner_ids(cache, out, at, support)?;
                        let bounds = self.interior_bounds(at.cell);
                        interior[p] = self.interior(out, at.cell, p, |placer, mesh| {
                            placer.centroid_vertex(&ids, &bounds, mesh)
                        })?;
                    }
                    interior[p]
                };
            }
            self.push(out, ids);
        }
        Ok(())
    }

    /// Emits a tunnel whose triangles, at the table's places, cross each other, mended
    /// ([`mend`]); `false` (nothing emitted) when they do not cross or nothing mends them: the
    /// table's triangles are then emitted as they are.
    fn untangled(
        &self,
        cache: &mut EdgeCache,
        out: &mut ChunkMesh,
        at: At,
        triangles: &CellTriangles,
        loops: (&[Corner], &[Corner]),
    ) -> Result<bool, ExtractError> {
        let mut ids = [u32::MAX; 12];
        let mut edge_position = [[0.0f64; 3]; 12];
        for &c in triangles.triangles.iter().flatten() {
            if let Some(e) = c.as_edge() {
                let e = usize::from(e);
                if ids[e] == u32::MAX {
                    ids[e] = self.edge(cache, out, at, e as u8)?;
                    edge_position[e] = out.mesh.positions[ids[e] as usize].map(f64::from);
                }
            }
        }
        let position = |c: Corner| edge_position[usize::from(c.as_edge().expect("crossings"))];
        let bounds = self.interior_bounds(at.cell);
        let Some(mended) = mend(triangles, loops, &position, &|c| c, &|_| true, &bounds) else {
            return Ok(false);
        };
        // Interior points take their normals from the loops'.
        let support = self.corner_ids(cache, out, at, &[loops.0, loops.1].concat())?;
        let mut interior = [u32::MAX; Corner::MAX_INTERIOR];
        for t in mended.triangles {
            let mut tri = [0u32; 3];
            for (slot, c) in tri.iter_mut().zip(t) {
                *slot = match c.as_edge() {
                    Some(e) => self.edge(cache, out, at, e)?,
                    None => {
                        let k = usize::from(c.as_interior().expect("edge or interior corners"));
                        if interior[k] == u32::MAX {
                            let x = mended.interiors[k];
                            interior[k] = self.interior(out, at.cell, k, |placer, mesh| {
                                placer.interior_vertex(x, &support, mesh)
                            })?;
                        }
                        interior[k]
                    }
                };
            }
            self.push(out, tri);
        }
        Ok(true)
    }

    fn corner_ids(
        &self,
        cache: &mut EdgeCache,
        out: &mut ChunkMesh,
        at: At,
        polygon: &[Corner],
    ) -> Result<Vec<u32>, ExtractError> {
        polygon
            .iter()
            .map(|c| {
                let e = c.as_edge().expect("binary polygons have edge corners");
                self.edge(cache, out, at, e)
            })
            .collect()
    }

    /// Triangulates loop `l` of a cell by the options' strategy, from the actual positions of
    /// its crossings. Diagonals follow the table's rule (never one a neighbour could draw too);
    /// if the strategy finds nothing, the table's triangulation of the loop is used.
    fn emit_polygon(
        &self,
        cache: &mut EdgeCache,
        out: &mut ChunkMesh,
        at: At,
        l: usize,
        polygon: &[Corner],
        bounds: Bounds,
    ) -> Result<(), ExtractError> {
        let n = polygon.len();
        if n > MAX_CORNERS {
            // Never for cell loops (at most 12 corners); kept total all the same.
            let ids = self.corner_ids(cache, out, at, polygon)?;
            return self.table_triangles(out, at, l, polygon, &ids);
        }
        let mut ids = [0u32; MAX_CORNERS];
        let mut positions = [[0.0f64; 3]; MAX_CORNERS];
        for (slot, c) in polygon.iter().enumerate() {
            let e = c.as_edge().expect("binary polygons have edge corners");
            ids[slot] = self.edge(cache, out, at, e)?;
            positions[slot] = out.mesh.positions[ids[slot] as usize].map(f64::from);
        }
        let ids = &ids[..n];
        if n == 3 {
            self.push(out, [ids[0], ids[1], ids[2]]);
            return Ok(());
        }
        // Such a pair joined through the search's own choice could draw the face's other
        // diagonal; searching with that chord forbidden added interior points (+16 % triangles
        // on tie-heavy data), so the table's triangulation, which can avoid it, takes these.
        let level = self.options.level;
        if (0..n)
            .any(|a| (a + 1..n).any(|b| off_face_diagonal(polygon[a], polygon[b], at.v, level)))
        {
            return self.table_triangles(out, at, l, polygon, ids);
        }
        let chords = Chords::new(n, |a, b| may_join(polygon[a], polygon[b]));
        match triangulate_polygon(&positions[..n], &chords, self.options.triangulation, bounds) {
            Some((triangles, interior)) => {
                let interior = match interior {
                    Some(x) => {
                        self.interior(out, at.cell, INTERIOR_LOOPS + l, |placer, mesh| {
                            placer.interior_vertex(x, ids, mesh)
                        })?
                    }
                    None => u32::MAX,
                };
                for t in triangles.as_slice() {
                    let id = |c: u8| ids.get(usize::from(c)).copied().unwrap_or(interior);
                    self.push(out, t.map(id));
                }
                Ok(())
            }
            None => self.table_triangles(out, at, l, polygon, ids),
        }
    }

    fn interior_bounds(&self, [i, j, k]: [usize; 3]) -> Bounds {
        interior_bounds(
            self.grid.point(i, j, k),
            self.grid.point(i + 1, j + 1, k + 1),
        )
    }

    /// The table's triangulation of loop `l`, or else any triangulation of it by the table's
    /// chords, that draws no face diagonal off the face's lowest point (see
    /// [`off_face_diagonal`]); a star around its centroid if none does.
    fn table_triangles(
        &self,
        out: &mut ChunkMesh,
        at: At,
        l: usize,
        polygon: &[Corner],
        ids: &[u32],
    ) -> Result<(), ExtractError> {
        let cell = at.cell;
        let level = self.options.level;
        let canonical = |a: Corner, b: Corner| !off_face_diagonal(a, b, at.v, level);
        match safe_triangulation_where(polygon, &canonical) {
            Some(tris) => {
                for t in tris {
                    let id =
                        |c: Corner| ids[polygon.iter().position(|&x| x == c).expect("a corner")];
                    self.push(out, t.map(id));
                }
            }
            None => {
                let bounds = self.interior_bounds(cell);
                let centre = self.interior(out, cell, INTERIOR_LOOPS + l, |placer, mesh| {
                    placer.centroid_vertex(ids, &bounds, mesh)
                })?;
                for a in 0..ids.len() {
                    self.push(out, [ids[a], ids[(a + 1) % ids.len()], centre]);
                }
            }
        }
        Ok(())
    }
}

/// The cell vertex (0–7) a crossing sits on: the end of its edge whose value is the level.
fn at_point(c: Corner, v: &[f32; 8], level: f32) -> Option<usize> {
    let [a, b] = EDGES[usize::from(c.as_edge()?)].map(usize::from);
    match (v[a] == level, v[b] == level) {
        (true, false) => Some(a),
        (false, true) => Some(b),
        _ => None,
    }
}

/// A cell point's place in the grid's order (z, then y, then x), from its coordinates.
fn grid_order(c: [u8; 3]) -> u8 {
    4 * c[2] + 2 * c[1] + c[0]
}

/// Whether crossings `a` and `b` sit on cell points opposite on a face whose lowest point (in
/// the grid's order) is neither of them. Both lie in the face, where the cell across it may
/// join crossings too: both cells draw only the diagonal through the lowest point, or their
/// edges would cross in the face.
fn off_face_diagonal(a: Corner, b: Corner, v: &[f32; 8], level: f32) -> bool {
    let (Some(p), Some(q)) = (at_point(a, v, level), at_point(b, v, level)) else {
        return false;
    };
    let (a, b) = (VERTICES[p], VERTICES[q]);
    let mut apart = (0..3).filter(|&d| a[d] != b[d]);
    let (Some(d), Some(e), None) = (apart.next(), apart.next(), apart.next()) else {
        return false;
    };
    // The face's other two corners: one coordinate of each from `a`, the other from `b`.
    let (mut r, mut s) = (a, a);
    r[d] = b[d];
    s[e] = b[e];
    grid_order(r).min(grid_order(s)) < grid_order(a).min(grid_order(b))
}

/// Where a loop of four crossings all lies on the four points of one cell face (each point's
/// value the level, the cells on both sides of the face below it: each puts a square in the
/// face, a sheet of no thickness), the loop's corner the diagonal starts from: the one on the
/// face's lowest point, so that both squares take the same diagonal (the table's or a
/// strategy's choice, a tie, would depend on the side the face is seen from). `None` for every
/// other loop.
fn face_square_start(polygon: &[Corner], v: &[f32; 8], level: f32) -> Option<usize> {
    if polygon.len() != 4 {
        return None;
    }
    let mut points = [0usize; 4];
    for (slot, &c) in points.iter_mut().zip(polygon) {
        *slot = at_point(c, v, level)?;
    }
    // On one face: the four points share a coordinate (they are distinct, on parallel edges).
    let coords = points.map(|p| VERTICES[p]);
    let one_face = (0..3).any(|d| coords.iter().all(|c| c[d] == coords[0][d]));
    let mut distinct = points;
    distinct.sort_unstable();
    if !one_face || distinct.windows(2).any(|w| w[0] == w[1]) {
        return None;
    }
    (0..4).min_by_key(|&k| grid_order(coords[k]))
}

/// The cell being meshed: its place in the box (for the edge cache), in the grid, and its eight
/// values in cube vertex order.
#[derive(Clone, Copy)]
struct At<'v> {
    local: [usize; 2],
    cell: [usize; 3],
    v: &'v [f32; 8],
}

/// Interior keys of a cell: the table's points first, then one per loop.
pub(super) const INTERIOR_LOOPS: usize = Corner::MAX_INTERIOR;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::{Grid, Sample};

    #[test]
    fn packed_masks_match_the_comparisons() {
        let mut rng = crate::TestRng::new(5);
        for _ in 0..2000 {
            let values: Vec<f32> = (0..64)
                .map(|_| ((rng.next_u64() >> 40) % 7) as f32 - 3.0)
                .collect();
            let naive = values
                .iter()
                .enumerate()
                .fold(0u64, |m, (b, &v)| m | u64::from(v >= 0.0) << b);
            assert_eq!(pack_above(&values, 0.0), (naive, false));
        }
    }

    #[test]
    fn packed_rows_find_every_kind_of_non_finite_value() {
        for bad in [f32::NAN, -f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            for len in [1, 63, 64, 65, 130] {
                for at in [0, len / 2, len - 1] {
                    let mut row = vec![1.0f32; len];
                    row[at] = bad;
                    let mut out = vec![0u64; len.div_ceil(64)];
                    assert!(pack_row(&row, 0.5, &mut out), "{bad} at {at} of {len}");
                    row[at] = f32::MAX;
                    assert!(!pack_row(&row, 0.5, &mut out), "f32::MAX at {at} of {len}");
                }
            }
        }
    }

    fn run(grid: &Grid, options: &ExtractOptions, threads: usize, height: usize) -> Mesh {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let [nx, ny, _] = grid.dims();
        let boxes = CellBox::tile(grid.dims(), [nx - 1, ny - 1, height]).unwrap();
        pool.install(|| super::super::extract_boxes(grid, options, &boxes))
            .unwrap()
            .0
    }

    /// The same mesh, to the bit, with 1, 2 or 3 threads and whatever the slab height (a single
    /// slab is the plain one-pass order): MC33 and classic, normals, tunnels, and a grid with
    /// NaN values.
    #[test]
    fn output_does_not_depend_on_threads_or_slabs() {
        let holey = crate::with_nan_holes(Sample::Gyroid.grid(33), 997);
        let grids = [
            Sample::Tangle.grid(40),
            Sample::Noise { seed: 3 }.grid(37),
            holey,
        ];
        for grid in &grids {
            for options in [
                ExtractOptions::default(),
                ExtractOptions::default()
                    .with_topology(Topology::Classic)
                    .with_normals(false),
            ] {
                let nz = grid.dims()[2] - 1;
                let one = run(grid, &options, 1, nz);
                assert!(!one.triangles.is_empty());
                for (threads, height) in [
                    (1, 4),
                    (2, 4),
                    (2, 7),
                    (3, 1),
                    (2, slab_height(grid.dims()[0], grid.dims()[1], nz)),
                ] {
                    let other = run(grid, &options, threads, height);
                    assert_eq!(one.positions, other.positions, "{threads} {height}");
                    assert_eq!(one.normals, other.normals, "{threads} {height}");
                    assert_eq!(one.triangles, other.triangles, "{threads} {height}");
                }
            }
        }
    }
}
