//! The binary (classic and MC33) extraction engine: empty space skipped 64 cells at a time, slabs
//! of cell layers meshed in parallel, slabs stitched in order.
//!
//! 1. Sign masks: one bit per grid point (at or above the level), and, only if the slab has any,
//!    one per non-finite point; rows of 64-bit words, computed by each slab for its own planes.
//! 2. A cell is empty when its eight corners agree; for 64 cells of a row that is a few word
//!    operations on the masks of the four point rows around them (all above: the AND of the rows
//!    and of the rows shifted by one; all below: the same on the complements). Only the other
//!    cells are visited.
//! 3. Cell layers are cut into slabs of a fixed height (a function of the grid's size only), each
//!    meshed on its own with its own edge cache; slab `c`'s vertices on its bottom plane are the
//!    ones slab `c − 1` made on its top plane, and are replaced by them when the slabs are joined,
//!    in order. Vertices are thus numbered by first use along z exactly as a single pass would, and
//!    the output is the same bytes whatever the number of threads.

use rayon::prelude::*;

use super::place::Placer;
use super::weld::EdgeCache;
use super::window::Window;
use super::{
    cell_config, choose_tunnel, emit_polygon, face_decisions, place_interior, ExtractError,
    ExtractOptions, ExtractStats,
};
use crate::cube::{CaseTable, Corner, Topology};
use crate::field::Grid;
use crate::mesh::Mesh;
use crate::quality::Strategy;

/// Sign masks of every point row.
pub(super) struct Masks {
    /// 64-bit words per row.
    pub(super) words: usize,
    above: Vec<u64>,
    /// Non-finite points, if the grid has any.
    invalid: Option<Vec<u64>>,
}

impl Masks {
    /// Masks of the point planes `k0..=k1` (rows indexed from `k0`).
    pub(super) fn new(window: &Window, level: f32, k0: usize, k1: usize) -> Masks {
        let [nx, ny, _] = window.dims();
        let words = nx.div_ceil(64);
        let values = window.planes(k0, k1);
        let mut above = vec![0u64; ny * (k1 + 1 - k0) * words];
        let invalid = pack_rows(values, nx, level, &mut above);
        Masks::finish(values, nx, words, above, invalid)
    }

    /// [`Masks::new`] for all of `window`'s planes, a plane per task.
    pub(super) fn new_parallel(window: &Window, level: f32) -> Masks {
        let [nx, ny, nz] = window.dims();
        let words = nx.div_ceil(64);
        let values = window.planes(0, nz - 1);
        let mut above = vec![0u64; ny * nz * words];
        let invalid = values
            .par_chunks(nx * ny)
            .zip(above.par_chunks_mut(ny * words))
            .map(|(plane, out)| pack_rows(plane, nx, level, out))
            .reduce(|| false, |a, b| a | b);
        Masks::finish(values, nx, words, above, invalid)
    }

    fn finish(values: &[f32], nx: usize, words: usize, above: Vec<u64>, invalid: bool) -> Masks {
        let invalid = invalid.then(|| {
            let mut bad = vec![0u64; above.len()];
            for (row, out) in values.chunks_exact(nx).zip(bad.chunks_exact_mut(words)) {
                for (w, chunk) in row.chunks(64).enumerate() {
                    out[w] = chunk
                        .iter()
                        .enumerate()
                        .fold(0, |m, (b, v)| m | u64::from(!v.is_finite()) << b);
                }
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

/// Packs the above bits of `values` (rows of `nx`) into `out` (rows of whole words); returns
/// whether some value is not finite.
fn pack_rows(values: &[f32], nx: usize, level: f32, out: &mut [u64]) -> bool {
    let words = nx.div_ceil(64);
    let mut invalid = false;
    for (row, out) in values.chunks_exact(nx).zip(out.chunks_exact_mut(words)) {
        // v · 0 is NaN exactly for non-finite v: one sum per row finds them, and the loops
        // stay simple enough to vectorise.
        let mut probe = 0.0f32;
        let full = row.chunks_exact(64);
        let tail = full.remainder();
        for (w, chunk) in full.enumerate() {
            out[w] = pack_above(chunk, level);
            probe += chunk.iter().map(|&v| v * 0.0).sum::<f32>();
        }
        if !tail.is_empty() {
            let mut bits = 0u64;
            for (b, &v) in tail.iter().enumerate() {
                bits |= u64::from(v >= level) << b;
                probe += v * 0.0;
            }
            out[words - 1] = bits;
        }
        invalid |= probe.is_nan();
    }
    invalid
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

/// Bit `b` set when `values[b]` is at or above the level, for 64 values: the comparisons go to
/// bytes (which vectorises), and each 8 bytes of 0/1 are gathered into 8 bits by one multiply.
#[inline]
fn pack_above(values: &[f32], level: f32) -> u64 {
    let mut bytes = [0u8; 64];
    for (o, &v) in bytes.iter_mut().zip(values) {
        *o = u8::from(v >= level);
    }
    let mut bits = 0u64;
    for (k, eight) in bytes.chunks_exact(8).enumerate() {
        let x = u64::from_le_bytes(eight.try_into().expect("8 bytes"));
        bits |= (x.wrapping_mul(0x0102_0408_1020_4080) >> 56) << (8 * k);
    }
    bits
}

/// One slab's mesh, with the vertices on its bottom and top planes by edge slot.
pub(super) struct Slab {
    pub(super) mesh: Mesh,
    pub(super) stats: ExtractStats,
    /// Vertices on the bottom and top planes as (slot, local index): the slot names the
    /// vertex's place on the plane (an edge slot, or a ternary key) so neighbours can match it.
    pub(super) bottom: Vec<(u64, u32)>,
    pub(super) top: Vec<(u64, u32)>,
}

/// Cell layers per slab: at least 16 slabs to balance the cores, and a slab's planes within
/// about 8 MiB, so the values its masks read are still cached when its cells read them again;
/// a function of the grid's size only, for determinism.
pub(super) fn slab_height(nx: usize, ny: usize, nz: usize) -> usize {
    let plane = nx * ny * std::mem::size_of::<f32>();
    let fit = (8 << 20) / plane.max(1);
    fit.min(nz.div_ceil(16)).max(4)
}

pub(super) fn extract_binary(
    grid: &Grid,
    options: &ExtractOptions,
    mesh: &mut Mesh,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<ExtractStats, ExtractError> {
    let [nx, ny, nz] = grid.dims();
    let height = slab_height(nx, ny, nz - 1);
    extract_in_slabs(grid, options, mesh, progress, height)
}

fn extract_in_slabs(
    grid: &Grid,
    options: &ExtractOptions,
    mesh: &mut Mesh,
    progress: &mut dyn FnMut(usize, usize),
    height: usize,
) -> Result<ExtractStats, ExtractError> {
    let [nx, ny, nz] = grid.dims();
    let slabs = (nz - 1).div_ceil(height);
    let parts: Vec<Result<Slab, ExtractError>> = (0..slabs)
        .into_par_iter()
        .map_init(
            || EdgeCache::new(nx, ny),
            |cache, s| {
                let k0 = s * height;
                let k1 = ((s + 1) * height).min(nz - 1);
                cache.reset();
                mesh_slab(Window::whole(grid), options, cache, k0, k1)
            },
        )
        .collect();
    let parts: Vec<Slab> = parts.into_iter().collect::<Result<_, _>>()?;
    let stats = join(parts, grid, mesh, &mut |s| {
        progress(((s + 1) * height).min(nz - 1), nz - 1)
    })?;
    Ok(stats)
}

/// Joins the slabs in order: a slab's bottom-plane vertices are its predecessor's top-plane
/// ones, every other vertex is new, numbered after all the earlier slabs' new vertices. The
/// numbering needs only counts, so the copying runs in parallel.
pub(super) fn join(
    parts: Vec<Slab>,
    grid: &Grid,
    mesh: &mut Mesh,
    progress: &mut dyn FnMut(usize),
) -> Result<ExtractStats, ExtractError> {
    let mut stats = ExtractStats {
        cells: grid.cell_count(),
        ..ExtractStats::default()
    };
    // For each slab, its bottom vertices that the slab below made too: (local, local below).
    let shared: Vec<Vec<(u32, u32)>> = (0..parts.len())
        .into_par_iter()
        .map(|s| {
            if s == 0 {
                return Vec::new();
            }
            let mut below: Vec<(u64, u32)> = parts[s - 1].top.clone();
            below.sort_unstable();
            parts[s]
                .bottom
                .iter()
                .filter_map(|&(slot, local)| {
                    below
                        .binary_search_by_key(&slot, |e| e.0)
                        .ok()
                        .map(|k| (local, below[k].1))
                })
                .collect()
        })
        .collect();
    // New vertices per slab and where each slab's go.
    let mut vertex_base = Vec::with_capacity(parts.len() + 1);
    let mut triangle_base = Vec::with_capacity(parts.len() + 1);
    vertex_base.push(0usize);
    triangle_base.push(0usize);
    for (part, shared) in parts.iter().zip(&shared) {
        vertex_base.push(vertex_base.last().unwrap() + part.mesh.positions.len() - shared.len());
        triangle_base.push(triangle_base.last().unwrap() + part.mesh.triangles.len());
    }
    let vertices = *vertex_base.last().unwrap();
    if vertices > u32::MAX as usize {
        return Err(ExtractError::TooManyVertices);
    }
    // Local → global, first for each slab's new vertices, then for its shared ones (the slab
    // below's top vertices are always new there: its top and bottom planes differ).
    let mut remaps: Vec<Vec<u32>> = parts
        .par_iter()
        .zip(&shared)
        .zip(&vertex_base)
        .map(|((part, shared), &base)| {
            let mut remap = vec![u32::MAX; part.mesh.positions.len()];
            for &(local, _) in shared {
                remap[local as usize] = u32::MAX - 1;
            }
            let mut next = base as u32;
            for r in remap.iter_mut() {
                if *r == u32::MAX {
                    *r = next;
                    next += 1;
                }
            }
            remap
        })
        .collect();
    for s in 1..parts.len() {
        let (lower, upper) = remaps.split_at_mut(s);
        let below = &lower[s - 1];
        for &(local, local_below) in &shared[s] {
            upper[0][local as usize] = below[local_below as usize];
        }
    }
    let normals = parts.iter().any(|p| !p.mesh.normals.is_empty());
    mesh.positions.resize(vertices, [0.0; 3]);
    if normals {
        mesh.normals.resize(vertices, [0.0; 3]);
    }
    mesh.triangles
        .resize(*triangle_base.last().unwrap(), [0; 3]);
    // Disjoint output ranges per slab.
    let mut positions: Vec<&mut [[f32; 3]]> = Vec::with_capacity(parts.len());
    let mut normal_out: Vec<&mut [[f32; 3]]> = Vec::with_capacity(parts.len());
    let mut triangles: Vec<&mut [[u32; 3]]> = Vec::with_capacity(parts.len());
    let (mut p_rest, mut n_rest, mut t_rest) = (
        &mut mesh.positions[..],
        &mut mesh.normals[..],
        &mut mesh.triangles[..],
    );
    for s in 0..parts.len() {
        let nv = vertex_base[s + 1] - vertex_base[s];
        let (p, rest) = p_rest.split_at_mut(nv);
        positions.push(p);
        p_rest = rest;
        if normals {
            let (n, rest) = n_rest.split_at_mut(nv);
            normal_out.push(n);
            n_rest = rest;
        } else {
            normal_out.push(&mut []);
        }
        let (t, rest) = t_rest.split_at_mut(triangle_base[s + 1] - triangle_base[s]);
        triangles.push(t);
        t_rest = rest;
    }
    parts
        .par_iter()
        .zip(&remaps)
        .zip(&vertex_base)
        .zip(positions)
        .zip(normal_out)
        .zip(triangles)
        .for_each(|(((((part, remap), &base), p_out), n_out), t_out)| {
            for (local, &global) in remap.iter().enumerate() {
                let g = global as usize;
                if g >= base && g < base + p_out.len() {
                    p_out[g - base] = part.mesh.positions[local];
                    if let Some(n) = part.mesh.normals.get(local) {
                        n_out[g - base] = *n;
                    }
                }
            }
            for (out, t) in t_out.iter_mut().zip(&part.mesh.triangles) {
                *out = t.map(|v| remap[v as usize]);
            }
        });
    for (s, part) in parts.iter().enumerate() {
        stats.active_cells += part.stats.active_cells;
        stats.skipped_cells += part.stats.skipped_cells;
        stats.interior_vertices += part.stats.interior_vertices;
        stats.tunnels += part.stats.tunnels;
        progress(s);
    }
    Ok(stats)
}

/// Meshes cell layers `k0..k1` (the window must hold point planes `k0 − 1..=k1 + 1` where the
/// grid has them: normals read one plane beyond the cells).
pub(super) fn mesh_slab(
    grid: Window,
    options: &ExtractOptions,
    cache: &mut EdgeCache,
    k0: usize,
    k1: usize,
) -> Result<Slab, ExtractError> {
    let table = CaseTable::binary();
    let [nx, ny, _] = grid.dims();
    let level = options.level;
    let mut stats = ExtractStats::default();
    let mut mesh = Mesh::new();
    let placer = Placer::new(grid, options);
    let values = grid.values();
    let (sy, sz) = (nx, nx * ny);
    // Offsets of the cube vertices from the cell's first point, in the numbering of `cube`.
    let corner_offsets = [0, 1, 1 + sy, sy, sz, 1 + sz, 1 + sy + sz, sy + sz];
    // The slab's own masks: its planes are read once, just before their cells are visited.
    let masks = Masks::new(&grid, level, k0, k1);
    let mut visit = vec![0u64; masks.words];
    // Room for what the slab will make (about one vertex and two triangles per cell visited),
    // so the arrays are not copied as they grow.
    let mut candidates = 0usize;
    for k in k0..k1 {
        for j in 0..ny - 1 {
            masks.visit(j, k - k0, ny, nx - 1, &mut visit);
            candidates += visit.iter().map(|w| w.count_ones() as usize).sum::<usize>();
        }
    }
    mesh.positions.reserve(candidates + candidates / 8);
    mesh.triangles.reserve(2 * candidates + candidates / 4);
    if options.normals {
        mesh.normals.reserve(candidates + candidates / 8);
    }
    let mut bottom = Vec::new();
    let mut top = Vec::new();
    for k in k0..k1 {
        for j in 0..ny - 1 {
            masks.visit(j, k - k0, ny, nx - 1, &mut visit);
            {
                for i in set_bits(&visit) {
                    let base = grid.index(i, j, k);
                    let v = corner_offsets.map(|o| values[base + o]);
                    if v.iter().any(|x| !x.is_finite()) {
                        stats.skipped_cells += 1;
                        continue;
                    }
                    let config = cell_config(&v, level);
                    if config == 0 || config == 255 {
                        continue;
                    }
                    mesh_cell(
                        table,
                        options,
                        [i, j, k],
                        &v,
                        config,
                        &grid,
                        &placer,
                        cache,
                        &mut mesh,
                        &mut stats,
                    )?;
                }
            }
        }
        let wide = |entries: Vec<(u32, u32)>| -> Vec<(u64, u32)> {
            entries
                .into_iter()
                .map(|(s, v)| (u64::from(s), v))
                .collect()
        };
        if k == k0 {
            bottom = wide(cache.plane_entries(false));
        }
        if k + 1 == k1 {
            top = wide(cache.plane_entries(true));
        }
        cache.next_layer();
    }
    Ok(Slab {
        mesh,
        stats,
        bottom,
        top,
    })
}

#[allow(clippy::too_many_arguments)]
fn mesh_cell(
    table: &CaseTable,
    options: &ExtractOptions,
    [i, j, k]: [usize; 3],
    v: &[f32; 8],
    config: u8,
    grid: &Window,
    placer: &Placer,
    cache: &mut EdgeCache,
    mesh: &mut Mesh,
    stats: &mut ExtractStats,
) -> Result<(), ExtractError> {
    let level = options.level;
    stats.active_cells += 1;
    let decisions = face_decisions(v, level, table.ambiguous_faces(config));
    let tunnel =
        if options.topology == Topology::Mc33 && table.has_tunnel_candidates(config, decisions) {
            choose_tunnel(table, config, decisions, v, level)
        } else {
            None
        };
    stats.tunnels += usize::from(tunnel.is_some());
    if options.triangulation != Strategy::Fan && tunnel.is_none() {
        let bounds = (grid.point(i, j, k), grid.point(i + 1, j + 1, k + 1));
        for polygon in table.polygons(config, decisions) {
            emit_polygon(
                polygon,
                [i, j, k],
                v,
                bounds,
                options,
                cache,
                placer,
                mesh,
                stats,
            )?;
        }
        return Ok(());
    }
    let cell = table.cell_triangles(config, decisions, options.topology, tunnel);
    let mut interior = [u32::MAX; Corner::MAX_INTERIOR];
    for tri in cell.triangles {
        let mut ids = [0u32; 3];
        for (slot, &corner) in ids.iter_mut().zip(tri) {
            *slot = if let Some(e) = corner.as_edge() {
                cache.vertex(i, j, e, || placer.edge_vertex_of([i, j, k], v, e, mesh))?
            } else {
                let p = usize::from(
                    corner
                        .as_interior()
                        .expect("binary cells have edge and interior corners"),
                );
                if interior[p] == u32::MAX {
                    interior[p] =
                        place_interior(cell.interior_support(p), cache, placer, mesh, [i, j, k])?;
                    stats.interior_vertices += 1;
                }
                interior[p]
            };
        }
        if options.flip {
            ids.swap(1, 2);
        }
        mesh.triangles.push(ids);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::Sample;

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
            assert_eq!(pack_above(&values, 0.0), naive);
        }
    }

    fn run(grid: &Grid, options: &ExtractOptions, threads: usize, height: usize) -> Mesh {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let mut mesh = Mesh::new();
        pool.install(|| extract_in_slabs(grid, options, &mut mesh, &mut |_, _| {}, height))
            .unwrap();
        mesh
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
