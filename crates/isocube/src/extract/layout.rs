//! The join in three steps, for a mesh that is never in one place: each chunk's **outline**
//! (where its rows end and the vertices it may share: a few percent of its bytes), the
//! **layout** of the joined mesh made from the outlines alone (which chunk owns each shared
//! vertex, where each run of rows goes), and each chunk **placed** by its part of the layout
//! where the chunk is — its vertices and triangles numbered as in the joined mesh, ready to be
//! written at their offsets in one file. [`super::join`] runs the same three steps in memory.

use rustc_hash::FxHashMap;

use super::block::Reader;
use super::chunk::{ordered_runs, rows_per_run, CellBox, ChunkMesh, Rank, VertexKey};
use super::{ExtractError, ExtractStats};
use crate::mesh::{area_vector, unit_or_up, Mesh};

/// A vertex of a chunk that another chunk may make too.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct SharedVertex {
    pub(crate) key: VertexKey,
    /// The chunk's number for it.
    pub(crate) vertex: u32,
    /// The chunk's row of cells that made it.
    pub(crate) row: u32,
    /// Its normal is zero (the field was flat there): the joined mesh fills it from the
    /// triangles around it, which several chunks hold.
    pub(crate) flat: bool,
}

/// A triangle around a flat shared vertex: its part of the vertex's filled normal.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct FlatTouch {
    vertex: u32,
    triangle: u32,
    area: [f64; 3],
}

/// What the layout of a join needs of one chunk mesh: its box, its counts, where its runs of
/// rows end (one run per row, per layer for a box spanning the grid's `x`, one for a box
/// spanning `x` and `y`), and the vertices on faces it shares with other boxes (with, where the
/// field was flat there, the triangles around them). Small beside the chunk when its runs are
/// long: for bands of 128³ chunks of a 512³ gyroid that span `x`, 0.5 % of the mesh's PLY.
///
/// ```
/// use isocube::extract::{CellBox, ChunkOutline, ExtractOptions, Extractor};
/// use isocube::field::Sample;
/// let grid = Sample::Gyroid.grid(33);
/// let extractor = Extractor::new(&grid, &ExtractOptions::default()).unwrap();
/// let chunk = extractor.mesh_box(CellBox::new([0, 0, 0], [16, 32, 32])).unwrap();
/// let outline = chunk.outline(grid.dims());
/// assert_eq!(ChunkOutline::from_bytes(&outline.to_bytes()).unwrap(), outline);
/// assert!(outline.to_bytes().len() * 10 < chunk.to_bytes().len());
/// ```
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ChunkOutline {
    pub(crate) cells: CellBox,
    pub(crate) stats: ExtractStats,
    /// After each run of rows (see `rows_per_run`): triangles and vertices made so far.
    pub(crate) runs: Vec<[u32; 2]>,
    /// By vertex.
    pub(crate) shared: Vec<SharedVertex>,
    /// By triangle.
    pub(crate) touches: Vec<FlatTouch>,
}

impl ChunkMesh {
    /// The chunk's outline in a grid of `dims` points: what [`JoinLayout::new`] needs of it.
    pub fn outline(&self, dims: [usize; 3]) -> ChunkOutline {
        self.outline_with(dims, true)
    }

    /// The outline, with the triangles around flat shared vertices if `touches`.
    pub(crate) fn outline_with(&self, dims: [usize; 3], touches: bool) -> ChunkOutline {
        let normals = &self.mesh.normals;
        let flat = |v: usize| normals.get(v).is_some_and(|n| *n == [0.0; 3]);
        let shared: Vec<SharedVertex> = self
            .shared_vertices(dims)
            .into_iter()
            .map(|(v, row)| SharedVertex {
                key: self.keys[v],
                vertex: v as u32,
                row: row as u32,
                flat: flat(v),
            })
            .collect();
        let mut list = Vec::new();
        if touches && shared.iter().any(|s| s.flat) {
            let is_flat_shared = |v: u32| {
                shared
                    .binary_search_by_key(&v, |s| s.vertex)
                    .is_ok_and(|at| shared[at].flat)
            };
            for (t, tri) in self.mesh.triangles.iter().enumerate() {
                let corners: Vec<u32> =
                    tri.iter().copied().filter(|&v| is_flat_shared(v)).collect();
                if corners.is_empty() {
                    continue;
                }
                let area = area_vector(tri.map(|v| self.mesh.positions[v as usize]));
                for vertex in corners {
                    list.push(FlatTouch {
                        vertex,
                        triangle: t as u32,
                        area,
                    });
                }
            }
        }
        // Rows that follow one another in the joined mesh are one run there: their ends
        // within the run are not needed.
        let per_run = rows_per_run(dims, self.cells);
        ChunkOutline {
            cells: self.cells,
            stats: self.stats,
            runs: self
                .rows
                .iter()
                .skip(per_run - 1)
                .step_by(per_run)
                .copied()
                .collect(),
            shared,
            touches: list,
        }
    }
}

impl ChunkOutline {
    /// The box of cells outlined.
    pub fn cells(&self) -> CellBox {
        self.cells
    }

    /// Shared vertices without a normal (the field flat there): the joined mesh fills their
    /// normals from triangles that several chunks hold.
    pub fn flat_shared(&self) -> usize {
        self.shared.iter().filter(|s| s.flat).count()
    }

    /// Vertices and triangles of the chunk.
    fn counts(&self) -> [usize; 2] {
        self.runs
            .last()
            .map_or([0, 0], |r| [r[1] as usize, r[0] as usize])
    }

    /// Whether the parts agree with one another (outlines may come from bytes) in a grid of
    /// `dims` points.
    fn well_formed(&self, dims: [usize; 3]) -> bool {
        let [nv, nt] = self.counts();
        let per_run = rows_per_run(dims, self.cells);
        let runs_ok = self.runs.len() * per_run == self.cells.rows()
            && self
                .runs
                .windows(2)
                .all(|w| w[0][0] <= w[1][0] && w[0][1] <= w[1][1]);
        if !runs_ok {
            return false;
        }
        let shared_ok = self.shared.windows(2).all(|w| w[0].vertex < w[1].vertex)
            && self.shared.iter().all(|s| {
                let k = s.row as usize / per_run;
                (s.vertex as usize) < nv
                    && (s.row as usize) < self.cells.rows()
                    && self.runs[k][1] > s.vertex
                    && (k == 0 || self.runs[k - 1][1] <= s.vertex)
            });
        let touches_ok = self
            .touches
            .windows(2)
            .all(|w| w[0].triangle <= w[1].triangle)
            && self.touches.iter().all(|t| {
                (t.triangle as usize) < nt
                    && self
                        .shared
                        .binary_search_by_key(&t.vertex, |s| s.vertex)
                        .is_ok_and(|at| self.shared[at].flat)
            });
        shared_ok && touches_ok
    }

    /// The outline as bytes (little-endian), read back by [`ChunkOutline::from_bytes`].
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(
            160 + self.runs.len() * 8 + self.shared.len() * 17 + self.touches.len() * 32,
        );
        out.extend_from_slice(OUTLINE_MAGIC);
        let mut word = |n: u64| out.extend_from_slice(&n.to_le_bytes());
        put_box(&mut word, self.cells);
        put_stats(&mut word, &self.stats);
        word(self.runs.len() as u64);
        word(self.shared.len() as u64);
        word(self.touches.len() as u64);
        for r in self.runs.iter().flatten() {
            out.extend_from_slice(&r.to_le_bytes());
        }
        for s in &self.shared {
            out.extend_from_slice(&s.key.to_bits().to_le_bytes());
            out.extend_from_slice(&s.vertex.to_le_bytes());
            out.extend_from_slice(&s.row.to_le_bytes());
            out.push(u8::from(s.flat));
        }
        for t in &self.touches {
            out.extend_from_slice(&t.vertex.to_le_bytes());
            out.extend_from_slice(&t.triangle.to_le_bytes());
            for a in t.area {
                out.extend_from_slice(&a.to_le_bytes());
            }
        }
        out
    }

    /// An outline from [`ChunkOutline::to_bytes`]; anything else is refused with
    /// [`ExtractError::MalformedChunk`].
    pub fn from_bytes(bytes: &[u8]) -> Result<ChunkOutline, ExtractError> {
        let bad = |cells| ExtractError::MalformedChunk { cells };
        let body = bytes
            .strip_prefix(OUTLINE_MAGIC.as_slice())
            .ok_or(bad(CellBox::default()))?;
        let mut r = Reader { bytes: body };
        let cells = r.cell_box().ok_or(bad(CellBox::default()))?;
        let bad = || bad(cells);
        let stats = r.stats().ok_or_else(bad)?;
        let mut count = || r.count().ok_or_else(bad);
        let [nr, ns, nt] = [count()?, count()?, count()?];
        // Runs of rows: as many as the rows, a layer's, or one (checked against the grid by
        // the layout).
        let rows = cells.checked_rows().ok_or_else(bad)?;
        if nr == 0 || rows % nr != 0 {
            return Err(bad());
        }
        let mut runs = Vec::with_capacity(nr.min(r.bytes.len() / 8));
        for _ in 0..nr {
            runs.push([r.u32().ok_or_else(bad)?, r.u32().ok_or_else(bad)?]);
        }
        let mut shared = Vec::with_capacity(ns.min(r.bytes.len() / 17));
        for _ in 0..ns {
            let key = VertexKey::from_bits(r.u64().ok_or_else(bad)?);
            let vertex = r.u32().ok_or_else(bad)?;
            let row = r.u32().ok_or_else(bad)?;
            let flat = match r.take(1).ok_or_else(bad)?[0] {
                0 => false,
                1 => true,
                _ => return Err(bad()),
            };
            shared.push(SharedVertex {
                key,
                vertex,
                row,
                flat,
            });
        }
        let mut touches = Vec::with_capacity(nt.min(r.bytes.len() / 32));
        for _ in 0..nt {
            let vertex = r.u32().ok_or_else(bad)?;
            let triangle = r.u32().ok_or_else(bad)?;
            let mut area = [0.0; 3];
            for a in &mut area {
                *a = f64::from_bits(r.u64().ok_or_else(bad)?);
            }
            touches.push(FlatTouch {
                vertex,
                triangle,
                area,
            });
        }
        let outline = ChunkOutline {
            cells,
            stats,
            runs,
            shared,
            touches,
        };
        if !r.bytes.is_empty() {
            return Err(bad());
        }
        Ok(outline)
    }
}

/// A run of a chunk's rows that comes in one piece in the joined mesh.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct PlacedRun {
    /// The chunk's vertices `[first, end)` made by the run's rows.
    pub(crate) vertices: [u32; 2],
    /// The chunk's triangles `[first, end)`.
    pub(crate) triangles: [u32; 2],
    /// Where the run's own vertices (those no earlier row makes) start in the joined mesh.
    pub(crate) first_vertex: u64,
    /// Where its triangles start.
    pub(crate) first_triangle: u64,
}

/// One chunk's part of a [`JoinLayout`]: where its runs of rows go in the joined mesh, which of
/// its vertices another chunk owns (and their joined numbers), and the filled normals of the
/// flat shared vertices it owns. [`ChunkPlace::place`] applies it to the chunk.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ChunkPlace {
    cells: CellBox,
    /// The joined mesh's vertices and triangles.
    whole: [u64; 2],
    /// In the chunk's row order, covering all its rows.
    pub(crate) runs: Vec<PlacedRun>,
    /// (chunk's vertex, joined number) of the vertices other chunks own, by vertex.
    pub(crate) aliases: Vec<(u32, u32)>,
    /// (chunk's vertex, normal) of the flat shared vertices it owns, by vertex.
    filled: Vec<(u32, [f32; 3])>,
}

/// How a chunk's vertices and triangles come into the joined mesh: every chunk's
/// [`ChunkPlace`], made from [`ChunkOutline`]s alone.
///
/// ```
/// use isocube::extract::{extract, CellBox, ExtractOptions, Extractor, JoinLayout};
/// use isocube::field::Sample;
/// let grid = Sample::Tangle.grid(30);
/// let extractor = Extractor::new(&grid, &ExtractOptions::default()).unwrap();
/// let chunks: Vec<_> = CellBox::tile(grid.dims(), [12, 10, 29]).unwrap().into_iter()
///     .map(|b| extractor.mesh_box(b).unwrap()).collect();
/// // Only the outlines travel to the layout; the chunks stay where they are.
/// let outlines: Vec<_> = chunks.iter().map(|c| c.outline(grid.dims())).collect();
/// let layout = JoinLayout::new(grid.dims(), &outlines).unwrap();
/// let whole = extract(&grid, &ExtractOptions::default()).unwrap().0;
/// assert_eq!(layout.vertices(), whole.vertex_count());
/// let mut positions = vec![[0.0; 3]; layout.vertices()];
/// let mut triangles = vec![[0; 3]; layout.triangles()];
/// for (chunk, place) in chunks.iter().zip(layout.places()) {
///     for piece in place.place(chunk).unwrap() {
///         let (v, t) = (piece.first_vertex as usize, piece.first_triangle as usize);
///         positions[v..v + piece.positions.len()].copy_from_slice(&piece.positions);
///         triangles[t..t + piece.triangles.len()].copy_from_slice(&piece.triangles);
///     }
/// }
/// assert_eq!((positions, triangles), (whole.positions, whole.triangles));
/// ```
#[derive(Clone, Debug, Default, PartialEq)]
pub struct JoinLayout {
    vertices: usize,
    triangles: usize,
    stats: ExtractStats,
    places: Vec<ChunkPlace>,
    /// (chunk, run) in the joined mesh's order.
    pub(crate) order: Vec<(u32, u32)>,
}

/// Where a chunk's row comes in the canonical order.
fn rank(cells: CellBox, row: usize) -> Rank {
    let ny = cells.extent()[1];
    (
        cells.min[2] + row / ny,
        cells.min[1] + row % ny,
        cells.min[0],
    )
}

impl JoinLayout {
    /// The layout of the join of chunks of disjoint boxes of a grid of `dims` points, from
    /// their outlines (in any order; place `i` is outline `i`'s).
    pub fn new(dims: [usize; 3], outlines: &[ChunkOutline]) -> Result<JoinLayout, ExtractError> {
        for o in outlines {
            o.cells.check(dims)?;
            if !o.well_formed(dims) {
                return Err(ExtractError::MalformedChunk { cells: o.cells });
            }
        }
        let cells: Vec<CellBox> = outlines.iter().map(|o| o.cells).collect();
        let runs = ordered_runs(dims, &cells)?;
        // A vertex on faces several boxes share belongs to the first row that makes it.
        let total: usize = outlines.iter().map(|o| o.shared.len()).sum();
        let mut owners: FxHashMap<VertexKey, (Rank, u32, u32, bool)> =
            FxHashMap::with_capacity_and_hasher(total, Default::default());
        for (c, o) in outlines.iter().enumerate() {
            for s in &o.shared {
                let r = rank(o.cells, s.row as usize);
                owners
                    .entry(s.key)
                    .and_modify(|e| {
                        if r < e.0 {
                            *e = (r, c as u32, s.vertex, s.flat);
                        }
                    })
                    .or_insert((r, c as u32, s.vertex, s.flat));
            }
        }
        // Per chunk, by vertex: (vertex, owner chunk, owner's vertex).
        let aliased: Vec<Vec<(u32, u32, u32)>> = outlines
            .iter()
            .enumerate()
            .map(|(c, o)| {
                o.shared
                    .iter()
                    .filter_map(|s| {
                        let (_, oc, ov, _) = owners[&s.key];
                        ((oc, ov) != (c as u32, s.vertex)).then_some((s.vertex, oc, ov))
                    })
                    .collect()
            })
            .collect();
        // Runs in the joined order; each takes its rows' triangles and own vertices.
        let mut places: Vec<ChunkPlace> = outlines
            .iter()
            .map(|o| ChunkPlace {
                cells: o.cells,
                ..ChunkPlace::default()
            })
            .collect();
        let mut order = Vec::with_capacity(runs.len());
        let (mut nv, mut nt) = (0u64, 0u64);
        for run in &runs {
            let c = run.chunk as usize;
            let ends = &outlines[c].runs;
            let k = run.rows.start / run.rows.len();
            let [t0, v0] = if k == 0 { [0, 0] } else { ends[k - 1] };
            let [t1, v1] = ends[k];
            let a = &aliased[c];
            let others = a.partition_point(|e| e.0 < v1) - a.partition_point(|e| e.0 < v0);
            order.push((run.chunk, places[c].runs.len() as u32));
            places[c].runs.push(PlacedRun {
                vertices: [v0, v1],
                triangles: [t0, t1],
                first_vertex: nv,
                first_triangle: nt,
            });
            nv += u64::from(v1 - v0) - others as u64;
            nt += u64::from(t1 - t0);
        }
        if nv > u64::from(u32::MAX) {
            return Err(ExtractError::TooManyVertices);
        }
        // Each aliased vertex's joined number, from its owner's runs.
        let own_number = |oc: usize, ov: u32| -> Option<u32> {
            let p = &places[oc];
            let run = p
                .runs
                .get(p.runs.partition_point(|r| r.vertices[1] <= ov))?;
            let a = &aliased[oc];
            let before =
                a.partition_point(|e| e.0 < ov) - a.partition_point(|e| e.0 < run.vertices[0]);
            let id = run.first_vertex + u64::from(ov - run.vertices[0]) - before as u64;
            u32::try_from(id).ok()
        };
        let mut numbered = Vec::with_capacity(outlines.len());
        for list in &aliased {
            let mut out = Vec::with_capacity(list.len());
            for &(v, oc, ov) in list {
                let id = own_number(oc as usize, ov).ok_or(ExtractError::MalformedChunk {
                    cells: cells[oc as usize],
                })?;
                out.push((v, id));
            }
            numbered.push(out);
        }
        for (p, list) in places.iter_mut().zip(numbered) {
            p.aliases = list;
            p.whole = [nv, nt];
        }
        // Flat shared vertices: their triangles' areas summed in the joined triangles' order,
        // as one pass fills them.
        let mut sums: FxHashMap<VertexKey, Vec<(u64, [f64; 3])>> = FxHashMap::default();
        for (c, o) in outlines.iter().enumerate() {
            for t in &o.touches {
                let at = o.shared.binary_search_by_key(&t.vertex, |s| s.vertex);
                let key = o.shared[at.expect("checked by well_formed")].key;
                let runs = &places[c].runs;
                let run = &runs[runs.partition_point(|r| r.triangles[1] <= t.triangle)];
                let joined = run.first_triangle + u64::from(t.triangle - run.triangles[0]);
                sums.entry(key).or_default().push((joined, t.area));
            }
        }
        for (key, &(_, oc, ov, flat)) in &owners {
            if !flat {
                continue;
            }
            let mut acc = [0.0f64; 3];
            if let Some(list) = sums.get_mut(key) {
                list.sort_by_key(|e| e.0);
                for (_, a) in list.iter() {
                    for i in 0..3 {
                        acc[i] += a[i];
                    }
                }
            }
            places[oc as usize].filled.push((ov, unit_or_up(acc)));
        }
        for p in &mut places {
            p.filled.sort_by_key(|e| e.0);
        }
        let mut stats = ExtractStats::default();
        for o in outlines {
            stats.add(&o.stats);
        }
        Ok(JoinLayout {
            vertices: nv as usize,
            triangles: nt as usize,
            stats,
            places,
            order,
        })
    }

    /// Vertices of the joined mesh.
    pub fn vertices(&self) -> usize {
        self.vertices
    }

    /// Triangles of the joined mesh.
    pub fn triangles(&self) -> usize {
        self.triangles
    }

    /// The chunks' counts summed.
    pub fn stats(&self) -> &ExtractStats {
        &self.stats
    }

    /// Each chunk's place, in the outlines' order.
    pub fn places(&self) -> &[ChunkPlace] {
        &self.places
    }

    /// The places, taken.
    pub fn into_places(self) -> Vec<ChunkPlace> {
        self.places
    }
}

/// A stretch of the joined mesh that one chunk fills: vertices from `first_vertex` on,
/// triangles from `first_triangle` on (their vertex numbers the joined mesh's).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PlacedPiece {
    /// The joined number of the first vertex.
    pub first_vertex: u64,
    /// The vertices' positions.
    pub positions: Vec<[f32; 3]>,
    /// Their normals (flat ones filled as the whole mesh fills them), or none.
    pub normals: Vec<[f32; 3]>,
    /// The joined number of the first triangle.
    pub first_triangle: u64,
    /// The triangles.
    pub triangles: Vec<[u32; 3]>,
}

/// The joined mesh of `vertices` vertices and `triangles` triangles (with normals if
/// `normals`) from the pieces every chunk placed, in any order; the pieces must cover each
/// vertex and triangle exactly once.
///
/// ```
/// use isocube::extract::{assemble, extract, CellBox, ExtractOptions, Extractor, JoinLayout};
/// use isocube::field::Sample;
/// let grid = Sample::Sphere.grid(20);
/// let extractor = Extractor::new(&grid, &ExtractOptions::default()).unwrap();
/// let chunks: Vec<_> = CellBox::tile(grid.dims(), [19, 19, 6]).unwrap().into_iter()
///     .map(|b| extractor.mesh_box(b).unwrap()).collect();
/// let outlines: Vec<_> = chunks.iter().map(|c| c.outline(grid.dims())).collect();
/// let layout = JoinLayout::new(grid.dims(), &outlines).unwrap();
/// let mut pieces = Vec::new();
/// for (chunk, place) in chunks.iter().zip(layout.places()) {
///     pieces.extend(place.place(chunk).unwrap());
/// }
/// let mesh = assemble(layout.vertices(), layout.triangles(), true, pieces).unwrap();
/// assert_eq!(mesh, extract(&grid, &ExtractOptions::default()).unwrap().0);
/// ```
pub fn assemble(
    vertices: usize,
    triangles: usize,
    normals: bool,
    mut pieces: Vec<PlacedPiece>,
) -> Result<Mesh, ExtractError> {
    let bad = || ExtractError::MalformedChunk {
        cells: CellBox::default(),
    };
    // Sorted by where they start, the pieces must follow one another with no gap or overlap.
    let tiles = |spans: &mut Vec<(u64, usize)>, total: usize| {
        spans.sort_unstable();
        let mut end = 0u64;
        for &(first, n) in spans.iter() {
            if first != end {
                return false;
            }
            end += n as u64;
        }
        end == total as u64
    };
    let mut v: Vec<(u64, usize)> = pieces
        .iter()
        .filter(|p| !p.positions.is_empty())
        .map(|p| (p.first_vertex, p.positions.len()))
        .collect();
    let mut t: Vec<(u64, usize)> = pieces
        .iter()
        .filter(|p| !p.triangles.is_empty())
        .map(|p| (p.first_triangle, p.triangles.len()))
        .collect();
    let normals_ok = pieces
        .iter()
        .all(|p| p.normals.len() == if normals { p.positions.len() } else { 0 });
    let indices_ok = pieces.iter().all(|p| {
        p.triangles
            .iter()
            .flatten()
            .all(|&i| (i as usize) < vertices)
    });
    if !tiles(&mut v, vertices) || !tiles(&mut t, triangles) || !normals_ok || !indices_ok {
        return Err(bad());
    }
    let mut mesh = Mesh::new();
    mesh.positions = vec![[0.0; 3]; vertices];
    if normals {
        mesh.normals = vec![[0.0; 3]; vertices];
    }
    mesh.triangles = vec![[0; 3]; triangles];
    // Only non-empty parts were checked to fit; an empty one may name any place.
    for p in pieces.drain(..) {
        let (v, t) = (p.first_vertex as usize, p.first_triangle as usize);
        if !p.positions.is_empty() {
            mesh.positions[v..v + p.positions.len()].copy_from_slice(&p.positions);
            if normals {
                mesh.normals[v..v + p.normals.len()].copy_from_slice(&p.normals);
            }
        }
        if !p.triangles.is_empty() {
            mesh.triangles[t..t + p.triangles.len()].copy_from_slice(&p.triangles);
        }
    }
    Ok(mesh)
}

impl PlacedPiece {
    /// Pieces as bytes (little-endian), to send between processes; read back by
    /// [`PlacedPiece::list_from_bytes`].
    pub fn list_to_bytes(pieces: &[PlacedPiece]) -> Vec<u8> {
        let size: usize = pieces
            .iter()
            .map(|p| 32 + (p.positions.len() + p.normals.len() + p.triangles.len()) * 12)
            .sum();
        let mut out = Vec::with_capacity(16 + size);
        out.extend_from_slice(PIECES_MAGIC);
        out.extend_from_slice(&(pieces.len() as u64).to_le_bytes());
        for p in pieces {
            for n in [
                p.first_vertex,
                p.first_triangle,
                p.positions.len() as u64,
                p.normals.len() as u64,
                p.triangles.len() as u64,
            ] {
                out.extend_from_slice(&n.to_le_bytes());
            }
            for x in p.positions.iter().chain(&p.normals).flatten() {
                out.extend_from_slice(&x.to_le_bytes());
            }
            for v in p.triangles.iter().flatten() {
                out.extend_from_slice(&v.to_le_bytes());
            }
        }
        out
    }

    /// Pieces from [`PlacedPiece::list_to_bytes`]; anything else is refused with
    /// [`ExtractError::MalformedChunk`].
    pub fn list_from_bytes(bytes: &[u8]) -> Result<Vec<PlacedPiece>, ExtractError> {
        let bad = || ExtractError::MalformedChunk {
            cells: CellBox::default(),
        };
        let body = bytes
            .strip_prefix(PIECES_MAGIC.as_slice())
            .ok_or_else(bad)?;
        let mut r = Reader { bytes: body };
        let n = r.count().ok_or_else(bad)?;
        let mut pieces = Vec::with_capacity(n.min(r.bytes.len() / 40));
        for _ in 0..n {
            let first_vertex = r.u64().ok_or_else(bad)?;
            let first_triangle = r.u64().ok_or_else(bad)?;
            let [nv, nn, nt] = [r.count(), r.count(), r.count()];
            let (nv, nn, nt) = (
                nv.ok_or_else(bad)?,
                nn.ok_or_else(bad)?,
                nt.ok_or_else(bad)?,
            );
            if nn != 0 && nn != nv {
                return Err(bad());
            }
            let positions = r.float_triples(nv).ok_or_else(bad)?;
            let normals = r.float_triples(nn).ok_or_else(bad)?;
            let triangles = r.triples(nt).ok_or_else(bad)?;
            pieces.push(PlacedPiece {
                first_vertex,
                positions,
                normals,
                first_triangle,
                triangles,
            });
        }
        if !r.bytes.is_empty() {
            return Err(bad());
        }
        Ok(pieces)
    }
}

impl ChunkPlace {
    /// The box of cells placed.
    pub fn cells(&self) -> CellBox {
        self.cells
    }

    /// The joined mesh's vertex and triangle counts.
    pub fn whole(&self) -> [u64; 2] {
        self.whole
    }

    /// The chunk's own vertices in run `run`: ranges between the aliased ones.
    pub(crate) fn own(&self, run: &PlacedRun) -> impl Iterator<Item = std::ops::Range<usize>> + '_ {
        let [v0, v1] = run.vertices.map(|v| v as usize);
        let first = self.aliases.partition_point(|e| (e.0 as usize) < v0);
        let stops = self.aliases[first..]
            .iter()
            .map(|e| e.0 as usize)
            .take_while(move |&v| v < v1)
            .chain(std::iter::once(v1));
        let mut from = v0;
        stops.map(move |stop| {
            let range = from..stop;
            from = stop + 1;
            range
        })
    }

    /// Each of the chunk's `count` vertices' joined number.
    pub(crate) fn ids(&self, count: usize) -> Vec<u32> {
        let mut ids = vec![u32::MAX; count];
        for run in &self.runs {
            let mut next = run.first_vertex as u32;
            for range in self.own(run) {
                for id in &mut ids[range] {
                    *id = next;
                    next += 1;
                }
            }
        }
        for &(v, id) in &self.aliases {
            ids[v as usize] = id;
        }
        ids
    }

    /// Whether the place fits a chunk of `counts` vertices and triangles.
    fn fits(&self, counts: [usize; 2]) -> bool {
        let [nv, nt] = counts;
        let mut end = [0u32; 2];
        let runs_ok = self.runs.iter().all(|r| {
            let ok = r.vertices[0] == end[0]
                && r.triangles[0] == end[1]
                && r.vertices[0] <= r.vertices[1]
                && r.triangles[0] <= r.triangles[1];
            end = [r.vertices[1], r.triangles[1]];
            ok
        }) && end == [nv as u32, nt as u32]
            && nv <= u32::MAX as usize
            && nt <= u32::MAX as usize;
        let sorted =
            |v: &[u32]| v.windows(2).all(|w| w[0] < w[1]) && v.iter().all(|&x| (x as usize) < nv);
        let firsts = |v: Vec<u32>| sorted(&v);
        runs_ok
            && firsts(self.aliases.iter().map(|a| a.0).collect())
            && firsts(self.filled.iter().map(|a| a.0).collect())
            && self.aliases.iter().all(|a| u64::from(a.1) < self.whole[0])
            && self.runs.iter().all(|r| {
                let own = self.own(r).map(|x| x.len() as u64).sum::<u64>();
                let within = |first: u64, n: u64, whole: u64| {
                    first.checked_add(n).is_some_and(|e| e <= whole)
                };
                within(r.first_vertex, own, self.whole[0])
                    && within(
                        r.first_triangle,
                        u64::from(r.triangles[1] - r.triangles[0]),
                        self.whole[1],
                    )
            })
    }

    /// The chunk's pieces of the joined mesh, one per run of rows: its own vertices (normals
    /// filled where the field was flat, exactly as the joined mesh fills them) and its
    /// triangles, numbered as in the joined mesh. The chunk must be the one outlined.
    pub fn place(&self, chunk: &ChunkMesh) -> Result<Vec<PlacedPiece>, ExtractError> {
        let m = &chunk.mesh;
        let counts = [m.positions.len(), m.triangles.len()];
        if chunk.cells != self.cells || !chunk.well_formed() || !self.fits(counts) {
            return Err(ExtractError::MalformedChunk { cells: chunk.cells });
        }
        let ids = self.ids(counts[0]);
        // Flat vertices no other chunk touches are filled from this chunk's triangles alone;
        // the shared ones the layout filled.
        let mut normals = if m.normals.is_empty() {
            Vec::new()
        } else {
            m.filled_normals().unwrap_or_else(|| m.normals.clone())
        };
        if !normals.is_empty() {
            for &(v, n) in &self.filled {
                normals[v as usize] = n;
            }
        }
        let mut pieces = Vec::with_capacity(self.runs.len());
        for run in &self.runs {
            let mut piece = PlacedPiece {
                first_vertex: run.first_vertex,
                first_triangle: run.first_triangle,
                ..PlacedPiece::default()
            };
            for range in self.own(run) {
                piece
                    .positions
                    .extend_from_slice(&m.positions[range.clone()]);
                if !normals.is_empty() {
                    piece.normals.extend_from_slice(&normals[range]);
                }
            }
            let [t0, t1] = run.triangles.map(|t| t as usize);
            piece.triangles.reserve(t1 - t0);
            for t in &m.triangles[t0..t1] {
                let mapped = t.map(|v| ids.get(v as usize).copied().unwrap_or(u32::MAX));
                if mapped.iter().any(|&id| u64::from(id) >= self.whole[0]) {
                    return Err(ExtractError::MalformedChunk { cells: chunk.cells });
                }
                piece.triangles.push(mapped);
            }
            if !piece.positions.is_empty() || !piece.triangles.is_empty() {
                pieces.push(piece);
            }
        }
        Ok(pieces)
    }

    /// The place as bytes (little-endian), read back by [`ChunkPlace::from_bytes`].
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(
            120 + self.runs.len() * 32 + self.aliases.len() * 8 + self.filled.len() * 16,
        );
        out.extend_from_slice(PLACE_MAGIC);
        let mut word = |n: u64| out.extend_from_slice(&n.to_le_bytes());
        put_box(&mut word, self.cells);
        word(self.whole[0]);
        word(self.whole[1]);
        word(self.runs.len() as u64);
        word(self.aliases.len() as u64);
        word(self.filled.len() as u64);
        for r in &self.runs {
            for x in r.vertices.iter().chain(&r.triangles) {
                out.extend_from_slice(&x.to_le_bytes());
            }
            out.extend_from_slice(&r.first_vertex.to_le_bytes());
            out.extend_from_slice(&r.first_triangle.to_le_bytes());
        }
        for (v, id) in &self.aliases {
            out.extend_from_slice(&v.to_le_bytes());
            out.extend_from_slice(&id.to_le_bytes());
        }
        for (v, n) in &self.filled {
            out.extend_from_slice(&v.to_le_bytes());
            for x in n {
                out.extend_from_slice(&x.to_le_bytes());
            }
        }
        out
    }

    /// A place from [`ChunkPlace::to_bytes`]; anything else is refused with
    /// [`ExtractError::MalformedChunk`] (and a place that does not fit its chunk, by
    /// [`ChunkPlace::place`]).
    pub fn from_bytes(bytes: &[u8]) -> Result<ChunkPlace, ExtractError> {
        let bad = |cells| ExtractError::MalformedChunk { cells };
        let body = bytes
            .strip_prefix(PLACE_MAGIC.as_slice())
            .ok_or(bad(CellBox::default()))?;
        let mut r = Reader { bytes: body };
        let cells = r.cell_box().ok_or(bad(CellBox::default()))?;
        let bad = || bad(cells);
        let whole = [r.u64().ok_or_else(bad)?, r.u64().ok_or_else(bad)?];
        let mut count = || r.count().ok_or_else(bad);
        let [nr, na, nf] = [count()?, count()?, count()?];
        let mut runs = Vec::with_capacity(nr.min(r.bytes.len() / 32));
        for _ in 0..nr {
            let mut x = [0u32; 4];
            for v in &mut x {
                *v = r.u32().ok_or_else(bad)?;
            }
            runs.push(PlacedRun {
                vertices: [x[0], x[1]],
                triangles: [x[2], x[3]],
                first_vertex: r.u64().ok_or_else(bad)?,
                first_triangle: r.u64().ok_or_else(bad)?,
            });
        }
        let mut aliases = Vec::with_capacity(na.min(r.bytes.len() / 8));
        for _ in 0..na {
            aliases.push((r.u32().ok_or_else(bad)?, r.u32().ok_or_else(bad)?));
        }
        let mut filled = Vec::with_capacity(nf.min(r.bytes.len() / 16));
        for _ in 0..nf {
            let v = r.u32().ok_or_else(bad)?;
            let mut n = [0.0f32; 3];
            for x in &mut n {
                *x = f32::from_bits(r.u32().ok_or_else(bad)?);
            }
            filled.push((v, n));
        }
        if !r.bytes.is_empty() || cells.checked_rows().is_none() {
            return Err(bad());
        }
        Ok(ChunkPlace {
            cells,
            whole,
            runs,
            aliases,
            filled,
        })
    }
}

const OUTLINE_MAGIC: &[u8; 8] = b"isoOUT\x00\x01";
const PLACE_MAGIC: &[u8; 8] = b"isoPLC\x00\x01";
const PIECES_MAGIC: &[u8; 8] = b"isoPCS\x00\x01";

/// Writes a box's six coordinates.
pub(super) fn put_box(word: &mut impl FnMut(u64), cells: CellBox) {
    for v in cells.min.iter().chain(&cells.max) {
        word(*v as u64);
    }
}

/// Writes the counts of [`ExtractStats`].
pub(super) fn put_stats(word: &mut impl FnMut(u64), s: &ExtractStats) {
    for v in [
        s.cells,
        s.active_cells,
        s.skipped_cells,
        s.interior_vertices,
        s.tunnels,
        s.snapped_points,
        s.refused_points,
    ] {
        word(v as u64);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::extract::{join, ExtractOptions, Extractor};
    use crate::field::Sample;

    /// The layout fills the normals of flat vertices on shared faces from the triangles of
    /// every chunk around them, summed in the joined mesh's order: the pieces placed are the
    /// joined mesh with its normals filled, to the bit. (Extraction gives zero normals only
    /// where a snapped point's gradient vanishes; here every fifth vertex by key is made
    /// flat, alike in every chunk, as a flat field would.)
    #[test]
    fn flat_shared_vertices_are_filled_as_the_whole_mesh_fills_them() {
        let grid = Sample::Tangle.grid(30);
        let dims = grid.dims();
        let extractor = Extractor::new(&grid, &ExtractOptions::default()).unwrap();
        for tile in [[7, 5, 3], [29, 4, 6], [10, 29, 10]] {
            let mut chunks: Vec<ChunkMesh> = CellBox::tile(dims, tile)
                .unwrap()
                .into_iter()
                .map(|b| extractor.mesh_box(b).unwrap())
                .collect();
            for c in &mut chunks {
                for (n, k) in c.mesh.normals.iter_mut().zip(&c.keys) {
                    if k.to_bits() % 5 == 0 {
                        *n = [0.0; 3];
                    }
                }
            }
            let mut whole = Mesh::new();
            join(dims, chunks.clone(), &mut whole, &mut |_| {}).unwrap();
            whole.normals = whole.filled_normals().unwrap();
            let outlines: Vec<ChunkOutline> = chunks
                .iter()
                .map(|c| ChunkOutline::from_bytes(&c.outline(dims).to_bytes()).unwrap())
                .collect();
            assert!(outlines.iter().map(|o| o.flat_shared()).sum::<usize>() > 10);
            let layout = JoinLayout::new(dims, &outlines).unwrap();
            let mut placed = Mesh::new();
            placed.positions = vec![[f32::NAN; 3]; layout.vertices()];
            placed.normals = vec![[f32::NAN; 3]; layout.vertices()];
            placed.triangles = vec![[u32::MAX; 3]; layout.triangles()];
            for (chunk, place) in chunks.iter().zip(layout.places()) {
                let place = ChunkPlace::from_bytes(&place.to_bytes()).unwrap();
                for p in place.place(chunk).unwrap() {
                    let (v, t) = (p.first_vertex as usize, p.first_triangle as usize);
                    placed.positions[v..v + p.positions.len()].copy_from_slice(&p.positions);
                    placed.normals[v..v + p.normals.len()].copy_from_slice(&p.normals);
                    placed.triangles[t..t + p.triangles.len()].copy_from_slice(&p.triangles);
                }
            }
            let bits = |m: &Mesh| -> Vec<u32> {
                m.positions
                    .iter()
                    .chain(&m.normals)
                    .flatten()
                    .map(|x| x.to_bits())
                    .collect()
            };
            assert_eq!(bits(&placed), bits(&whole), "boxes of {tile:?}");
            assert_eq!(placed.triangles, whole.triangles, "boxes of {tile:?}");
        }
    }

    /// A place refuses a chunk it was not made for, and bytes cut short or altered are refused.
    #[test]
    fn places_and_outlines_refuse_what_does_not_fit() {
        let grid = Sample::Gyroid.grid(20);
        let dims = grid.dims();
        let extractor = Extractor::new(&grid, &ExtractOptions::default()).unwrap();
        let chunks: Vec<ChunkMesh> = CellBox::tile(dims, [10, 19, 19])
            .unwrap()
            .into_iter()
            .map(|b| extractor.mesh_box(b).unwrap())
            .collect();
        let outlines: Vec<ChunkOutline> = chunks.iter().map(|c| c.outline(dims)).collect();
        let layout = JoinLayout::new(dims, &outlines).unwrap();
        let places = layout.places();
        assert!(places[0].place(&chunks[1]).is_err());
        for bytes in [outlines[1].to_bytes(), places[1].to_bytes()] {
            for cut in [0, 8, bytes.len() / 2, bytes.len() - 1] {
                assert!(ChunkOutline::from_bytes(&bytes[..cut]).is_err());
                assert!(ChunkPlace::from_bytes(&bytes[..cut]).is_err());
            }
        }
        // A place whose runs claim more triangles than the chunk has.
        let mut wrong = places[1].clone();
        wrong.runs.last_mut().unwrap().triangles[1] += 1;
        assert!(wrong.place(&chunks[1]).is_err());
        // Two outlines of one box overlap.
        assert!(JoinLayout::new(dims, &[outlines[0].clone(), outlines[0].clone()]).is_err());
    }
}
