//! Labelled images (segmentations): one closed surface per label, and where two labels touch,
//! the very same triangles (opposite ways round) in both surfaces.
//!
//! # Method
//! Binary Marching Cubes cannot do this: each label's cell polygons separate that label from
//! "everything else", so where three labels meet in a cell the surfaces do not fit, and
//! ambiguous faces are decided differently per label. isocube instead splits every cell into
//! the six tetrahedra of the Kuhn (Freudenthal) triangulation — a triangulation of the whole
//! grid, so neighbouring cells agree on every shared face — and gives each grid point the part
//! of every tetrahedron around it that its barycentric subdivision assigns to it: its *dual
//! cell*. A label's region is the union of its points' dual cells; the interface between two
//! labels is made of the small triangles (edge midpoint, face centroid, tetrahedron centroid)
//! that separate the dual cells of an edge's two ends.
//!
//! Dual cells of two points touch only when the points share a tetrahedron, and then along a
//! whole face; around any dual vertex or edge the cells are those of one simplex's vertices,
//! which all touch one another. So every label's surface is a closed 2-manifold (watertight,
//! no non-manifold edge or vertex), consistently oriented, and two labels' surfaces share their
//! interface exactly. The grid is surrounded by one layer of "outside" points, so labels
//! touching the boundary are closed half a cell beyond it.
//!
//! Vertices sit at edge midpoints, triangle centroids and tetrahedron centroids: the surfaces
//! follow the voxels' boundaries (like a smoothed cuberille), not an interpolated level set.

use rayon::prelude::*;
use rustc_hash::FxHashMap;

use crate::field::GridView;
use crate::mesh::Mesh;

use super::chunk::{join_tagged, CellBox, ChunkMesh, KeyKind, VertexKey};
use super::ExtractError;

/// Which labels to mesh.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub enum LabelSelection {
    /// Every label except the background.
    #[default]
    All,
    /// These labels only (the others still bound them).
    Only(Vec<i64>),
}

/// Options of [`extract_labels`].
#[derive(Clone, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub struct LabelOptions {
    /// The label that is never meshed (the surroundings), usually 0.
    pub background: i64,
    /// Which labels get a surface.
    pub labels: LabelSelection,
    /// Smoothing sweeps: each vertex moves halfway toward the mean of its neighbours (on all
    /// surfaces at once, so shared interfaces stay shared), never more than one cell from where
    /// it started along any axis. 0 keeps the voxels' staircase.
    pub smoothing: usize,
    /// Volume meshes ([`crate::volume::tetmesh_labels`]): how each label's interior coarsens
    /// away from its surfaces (surfaces ignore it).
    pub grading: crate::volume::Grading,
}

impl Default for LabelOptions {
    /// Background 0, every label, 60 smoothing sweeps.
    fn default() -> Self {
        LabelOptions {
            background: 0,
            labels: LabelSelection::All,
            smoothing: 60,
            grading: crate::volume::Grading::DEFAULT,
        }
    }
}

impl LabelOptions {
    /// With `sweeps` smoothing sweeps (0 keeps the voxels' staircase).
    ///
    /// ```
    /// use isocube::extract::LabelOptions;
    /// assert_eq!(LabelOptions::default().with_smoothing(0).smoothing, 0);
    /// ```
    pub fn with_smoothing(mut self, sweeps: usize) -> LabelOptions {
        self.smoothing = sweeps;
        self
    }

    /// With `labels` meshed.
    ///
    /// ```
    /// use isocube::extract::{LabelOptions, LabelSelection};
    /// let only = LabelOptions::default().with_labels(LabelSelection::Only(vec![2]));
    /// assert_eq!(only.labels, LabelSelection::Only(vec![2]));
    /// ```
    pub fn with_labels(mut self, labels: LabelSelection) -> LabelOptions {
        self.labels = labels;
        self
    }

    /// With `background` as the label never meshed.
    ///
    /// ```
    /// use isocube::extract::LabelOptions;
    /// assert_eq!(LabelOptions::default().with_background(-1).background, -1);
    /// ```
    pub fn with_background(mut self, background: i64) -> LabelOptions {
        self.background = background;
        self
    }

    /// With the interiors of volume meshes graded by `grading`.
    ///
    /// ```
    /// use isocube::extract::LabelOptions;
    /// use isocube::volume::Grading;
    /// let options = LabelOptions::default().with_grading(Grading::default());
    /// assert_eq!(options.grading.largest_cells(), 16);
    /// ```
    pub fn with_grading(mut self, grading: crate::volume::Grading) -> LabelOptions {
        self.grading = grading;
        self
    }
}

/// One label's surface.
#[derive(Clone, Debug)]
pub struct LabelSurface {
    /// The label.
    pub label: i64,
    /// Its closed surface, triangles facing out of the label.
    pub mesh: Mesh,
}

/// The six tetrahedra of a cell, each a path 0 → e_a → e_a + e_b → (1, 1, 1) through the
/// corners (as bit masks: 1 = +x, 2 = +y, 4 = +z).
pub(crate) const TETS: [[u8; 4]; 6] = [
    [0, 1, 3, 7],
    [0, 1, 5, 7],
    [0, 2, 3, 7],
    [0, 2, 6, 7],
    [0, 4, 5, 7],
    [0, 4, 6, 7],
];

/// Meshes every label of a labelled grid (values are labels: integers; a value that is not an
/// integer is an error naming the point).
///
/// ```
/// use isocube::extract::{extract_labels, LabelOptions};
/// use isocube::field::Grid;
/// // Two touching boxes, labels 1 and 2, in a 6 × 4 × 4 grid of background 0.
/// let dims = [6, 4, 4];
/// let values = (0..96)
///     .map(|p| {
///         let (i, j, k) = (p % 6, p / 6 % 4, p / 24);
///         let inside = (1..3).contains(&j) && (1..3).contains(&k);
///         match i { 1 | 2 if inside => 1.0, 3 | 4 if inside => 2.0, _ => 0.0 }
///     })
///     .collect();
/// let surfaces = extract_labels(&Grid::new(dims, values).unwrap(), &LabelOptions::default()).unwrap();
/// assert_eq!(surfaces.len(), 2);
/// for s in &surfaces {
///     let r = s.mesh.report();
///     assert!(r.watertight && r.oriented && r.nonmanifold_edges == 0);
///     assert_eq!((r.components, r.euler), (1, 2));
/// }
/// ```
pub fn extract_labels<'a>(
    grid: impl Into<GridView<'a>>,
    options: &LabelOptions,
) -> Result<Vec<LabelSurface>, ExtractError> {
    let grid = grid.into();
    extract_labels_boxes(grid, options, &label_slabs(grid.dims())?)
}

/// [`label_cells`] cut into slabs of a few layers, the unit of parallel work.
pub(crate) fn label_slabs(dims: [usize; 3]) -> Result<Vec<CellBox>, ExtractError> {
    let cells = label_cells(dims);
    let height = super::binary::slab_height(cells.max[0], cells.max[1], cells.max[2]);
    CellBox::tile(
        cells.max.map(|c| c + 1),
        [cells.max[0], cells.max[1], height],
    )
}

/// The cells labelled meshing visits: the grid's cells and one more layer all round (the grid
/// is surrounded by a layer of outside points), numbered from 0 at the outside layer. Boxes of
/// these cells are what [`extract_labels_boxes`] takes.
///
/// ```
/// use isocube::extract::{label_cells, CellBox};
/// assert_eq!(label_cells([4, 5, 6]), CellBox::new([0, 0, 0], [5, 6, 7]));
/// ```
pub fn label_cells(dims: [usize; 3]) -> CellBox {
    CellBox::whole(dims.map(|d| d + 2))
}

/// [`extract_labels`] with the cells of [`label_cells`] cut into `boxes` (disjoint), each
/// meshed on its own in parallel and then joined: with boxes that cover every cell, the result
/// is [`extract_labels`]'s, to the bit.
///
/// ```
/// use isocube::extract::{extract_labels, extract_labels_boxes, label_cells, CellBox, LabelOptions};
/// use isocube::field::Grid;
/// let dims = [6, 5, 4];
/// let values = (0..120).map(|p| ((p * 7 % 11) % 3) as f32).collect();
/// let grid = Grid::new(dims, values).unwrap();
/// let options = LabelOptions::default();
/// let cells = label_cells(dims);
/// let boxes = CellBox::tile(cells.max.map(|c| c + 1), [2, 3, 4]).unwrap();
/// let chunked = extract_labels_boxes(&grid, &options, &boxes).unwrap();
/// let whole = extract_labels(&grid, &options).unwrap();
/// assert_eq!(chunked.len(), whole.len());
/// for (a, b) in chunked.iter().zip(&whole) {
///     assert_eq!((a.label, &a.mesh), (b.label, &b.mesh));
/// }
/// ```
pub fn extract_labels_boxes<'a>(
    grid: impl Into<GridView<'a>>,
    options: &LabelOptions,
    boxes: &[CellBox],
) -> Result<Vec<LabelSurface>, ExtractError> {
    let grid = grid.into();
    let labelled = Labelled::new(grid, options)?;
    let (all, tags) = labelled.surfaces(boxes, None)?;
    Ok(labelled.split(
        all,
        &tags,
        grid.spacing(),
        grid.orientation(),
        grid.origin(),
    ))
}

/// The labels of the padded label cells `cells` (see [`label_cells`]) of a labelled grid of
/// `dims` points, meshed from a block of the grid: `ids` holds points `at .. at + block` (`x`
/// fastest) as 1-based numbers into `names`, the grid's labels in the order a pass over the
/// whole grid meets them first (`x` fastest, then `y`, then `z`) — what
/// [`extract_labels`] numbers them by. The block must hold the grid points of the cells'
/// corners (label cells read nothing beyond them). Join the chunks (any tiling of
/// [`label_cells`]) with [`super::merge_chunks`] on the padded grid (`dims` + 2), then
/// [`label_surfaces_of`].
///
/// ```
/// use isocube::extract::{extract_labels, label_cells, label_surfaces_of, mesh_label_block,
///     merge_chunks, CellBox, LabelOptions};
/// use isocube::field::{Grid, Orientation};
/// let dims = [7, 6, 5];
/// let values: Vec<f32> = (0..210).map(|p| ((p * 7 % 11) % 3) as f32).collect();
/// let grid = Grid::new(dims, values.clone()).unwrap();
/// let options = LabelOptions::default();
/// // Labels by first appearance: 0, 1, 2 here.
/// let mut names: Vec<i64> = Vec::new();
/// for v in &values {
///     if !names.contains(&(*v as i64)) { names.push(*v as i64); }
/// }
/// let ids: Vec<u32> = values.iter()
///     .map(|v| names.iter().position(|n| *n == *v as i64).unwrap() as u32 + 1).collect();
/// let padded = dims.map(|d| d + 2);
/// let chunks: Vec<_> = CellBox::tile(padded, [4, 4, 4]).unwrap().into_iter().map(|cells| {
///     mesh_label_block(&ids, [0, 0, 0], dims, dims, cells, &names, &options, [1.0; 3], [0.0; 3])
///         .unwrap()
/// }).collect();
/// let whole_chunk = merge_chunks(padded, chunks).unwrap();
/// let surfaces = label_surfaces_of(whole_chunk, &names, &options, [1.0; 3],
///     Orientation::IDENTITY, [0.0; 3]).unwrap();
/// let whole = extract_labels(&grid, &options).unwrap();
/// assert_eq!(surfaces.len(), whole.len());
/// for (a, b) in surfaces.iter().zip(&whole) {
///     assert_eq!((a.label, &a.mesh), (b.label, &b.mesh));
/// }
/// ```
#[allow(clippy::too_many_arguments)]
pub fn mesh_label_block(
    ids: &[u32],
    at: [usize; 3],
    block: [usize; 3],
    dims: [usize; 3],
    cells: CellBox,
    names: &[i64],
    options: &LabelOptions,
    spacing: [f64; 3],
    origin: [f64; 3],
) -> Result<ChunkMesh, ExtractError> {
    let padded_dims = dims.map(|d| d + 2);
    cells.check(padded_dims)?;
    if ids.len() != block.iter().product::<usize>() {
        return Err(ExtractError::Unsupported(
            "the block's numbers do not fill its dimensions",
        ));
    }
    // Padded points cells.min ..= cells.max; padded point q is grid point q - 1.
    let local: [usize; 3] = std::array::from_fn(|a| cells.max[a] - cells.min[a] + 1);
    let mut padded = vec![0u32; local.iter().product()];
    for k in 0..local[2] {
        for j in 0..local[1] {
            for i in 0..local[0] {
                let grid_point: [Option<usize>; 3] = std::array::from_fn(|a| {
                    let c = [i, j, k][a] + cells.min[a];
                    (c >= 1 && c <= dims[a]).then(|| c - 1)
                });
                let [Some(x), Some(y), Some(z)] = grid_point else {
                    continue;
                };
                let inside = [x, y, z]
                    .iter()
                    .zip(at.iter().zip(&block))
                    .all(|(&p, (&a, &b))| p >= a && p < a + b);
                if !inside {
                    return Err(ExtractError::Block {
                        cells,
                        at,
                        block,
                        halo: 0,
                    });
                }
                let id = ids[(x - at[0]) + block[0] * ((y - at[1]) + block[1] * (z - at[2]))];
                if id == 0 || id as usize > names.len() {
                    return Err(ExtractError::Unsupported(
                        "a label number outside the list of names",
                    ));
                }
                padded[i + local[0] * (j + local[1] * k)] = id;
            }
        }
    }
    let labelled = Labelled {
        options,
        names: names.to_vec(),
        padded,
        dims: local,
        background: names
            .iter()
            .position(|&n| n == options.background)
            .map(|i| i as u32 + 1),
        spacing,
        origin,
        at: cells.min,
    };
    let mut chunk = labelled.mesh_box(CellBox::new([0; 3], local.map(|l| l - 1)))?;
    let [px, py, _] = padded_dims;
    for key in &mut chunk.keys {
        if let KeyKind::Simplex { point, corners } = key.kind() {
            let (i, j, k) = (
                point % local[0],
                point / local[0] % local[1],
                point / (local[0] * local[1]),
            );
            let global = (i + cells.min[0]) + px * ((j + cells.min[1]) + py * (k + cells.min[2]));
            *key = VertexKey::simplex(global, corners);
        }
    }
    chunk.cells = cells;
    chunk.faces = cells.shared_faces(padded_dims);
    Ok(chunk)
}

/// The labels' surfaces from the chunk of all padded label cells (merged from
/// [`mesh_label_block`]'s chunks): smoothed together, one mesh per label in label order, as
/// [`extract_labels`] makes them. `orientation` turns the grid's frame into the world.
pub fn label_surfaces_of(
    chunk: ChunkMesh,
    names: &[i64],
    options: &LabelOptions,
    spacing: [f64; 3],
    orientation: crate::field::Orientation,
    origin: [f64; 3],
) -> Result<Vec<LabelSurface>, ExtractError> {
    if chunk.tags.len() != chunk.mesh.triangles.len()
        || chunk
            .tags
            .iter()
            .any(|&t| t == 0 || t as usize > names.len())
    {
        return Err(ExtractError::MalformedChunk { cells: chunk.cells });
    }
    let labelled = Labelled {
        options,
        names: names.to_vec(),
        padded: Vec::new(),
        dims: chunk.cells.max.map(|m| m + 1),
        background: names
            .iter()
            .position(|&n| n == options.background)
            .map(|i| i as u32 + 1),
        spacing,
        origin,
        at: [0; 3],
    };
    Ok(labelled.split(chunk.mesh, &chunk.tags, spacing, orientation, origin))
}

/// A labelled grid ready for meshing boxes: dense label numbers on a grid padded by one layer
/// of outside points.
pub(crate) struct Labelled<'a> {
    options: &'a LabelOptions,
    /// The labels met, by dense number − 1 (dense 0 is the outside layer).
    pub(crate) names: Vec<i64>,
    /// Dense numbers of the padded grid's points.
    pub(crate) padded: Vec<u32>,
    /// The padded grid's points per axis.
    pub(crate) dims: [usize; 3],
    background: Option<u32>,
    spacing: [f64; 3],
    origin: [f64; 3],
    /// The whole padded grid's index of this one's point (0, 0, 0), when it is a block of it.
    at: [usize; 3],
}

impl<'a> Labelled<'a> {
    /// Every label's unsmoothed triangles over one joined vertex list (each triangle tagged
    /// with its label's dense number, facing out of it), meshed in `boxes`; with `keys`, each
    /// vertex's key.
    pub(crate) fn surfaces(
        &self,
        boxes: &[CellBox],
        keys: Option<&mut Vec<VertexKey>>,
    ) -> Result<(Mesh, Vec<u32>), ExtractError> {
        let chunks: Vec<ChunkMesh> = boxes
            .par_iter()
            .map(|&cells| self.mesh_box(cells))
            .collect::<Result<_, _>>()?;
        let mut all = Mesh::new();
        let mut tags = Vec::new();
        join_tagged(self.dims, chunks, &mut all, &mut tags, keys, &mut |_| {})?;
        Ok((all, tags))
    }

    pub(crate) fn new(
        grid: GridView,
        options: &'a LabelOptions,
    ) -> Result<Labelled<'a>, ExtractError> {
        if grid.heights().is_some() {
            return Err(ExtractError::Unsupported(
                "labelled volumes are meshed on evenly spaced planes only",
            ));
        }
        let [nx, ny, nz] = grid.dims();
        let mut names: Vec<i64> = Vec::new();
        let mut dense: FxHashMap<i64, u32> = FxHashMap::default();
        let (px, py, pz) = (nx + 2, ny + 2, nz + 2);
        let mut padded = vec![0u32; px * py * pz];
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    let v = grid.value(i, j, k);
                    if !v.is_finite() || v.fract() != 0.0 || v.abs() > 9.0e15 {
                        return Err(ExtractError::Label {
                            point: [i, j, k],
                            value: v,
                        });
                    }
                    let label = v as i64;
                    // Dense numbers are u32 (so are the padded grid's); past that, too many
                    // labels to mesh.
                    let next = u32::try_from(names.len() + 1)
                        .map_err(|_| ExtractError::TooManyVertices)?;
                    let id = *dense.entry(label).or_insert_with(|| {
                        names.push(label);
                        next
                    });
                    padded[(i + 1) + px * ((j + 1) + py * (k + 1))] = id;
                }
            }
        }
        // The outside counts as background: the background's name, if it occurs, shares id 0's
        // role.
        let background = dense.get(&options.background).copied();
        Ok(Labelled {
            options,
            names,
            padded,
            dims: [px, py, pz],
            background,
            spacing: grid.spacing(),
            origin: grid.origin(),
            at: [0; 3],
        })
    }

    /// Every label's triangles out of the joined mesh (`tags`: each triangle's label number),
    /// smoothed together, each label's mesh with its own vertices numbered by first use, in
    /// label order, turned into the world.
    fn split(
        &self,
        mut all: Mesh,
        tags: &[u32],
        spacing: [f64; 3],
        orientation: crate::field::Orientation,
        origin: [f64; 3],
    ) -> Vec<LabelSurface> {
        let options = self.options;
        let mut triangles: Vec<Vec<[u32; 3]>> = vec![Vec::new(); self.names.len() + 1];
        for (t, &tag) in all.triangles.iter().zip(tags) {
            triangles[tag as usize].push(*t);
        }
        smooth(&mut all.positions, &triangles, options.smoothing, spacing);
        // Each label's mesh keeps only its own vertices, numbered by first use.
        let mut out: Vec<LabelSurface> = Vec::new();
        let mut order: Vec<u32> = (1..=self.names.len() as u32)
            .filter(|&id| self.meshed(id))
            .collect();
        order.sort_by_key(|&id| self.names[id as usize - 1]);
        for id in order {
            let mut map: FxHashMap<u32, u32> = FxHashMap::default();
            let mut mesh = Mesh::new();
            for t in &triangles[id as usize] {
                let t = t.map(|v| {
                    *map.entry(v).or_insert_with(|| {
                        mesh.positions.push(all.positions[v as usize]);
                        // At most as many as `all` has, which are numbered by u32.
                        (mesh.positions.len() - 1) as u32
                    })
                });
                mesh.triangles.push(t);
            }
            mesh.compute_normals();
            orientation.orient_mesh(&mut mesh, origin);
            out.push(LabelSurface {
                label: self.names[id as usize - 1],
                mesh,
            });
        }
        out
    }

    pub(crate) fn meshed(&self, id: u32) -> bool {
        id != 0
            && Some(id) != self.background
            && match &self.options.labels {
                LabelSelection::All => true,
                LabelSelection::Only(list) => list.contains(&self.names[id as usize - 1]),
            }
    }

    /// The padded point at `base` + the corner offset `bits` (1 = +x, 2 = +y, 4 = +z).
    pub(crate) fn corner(&self, base: usize, bits: u8) -> usize {
        let [px, py, _] = self.dims;
        let strides = [1usize, px, px * py];
        base + (0..3)
            .filter(|a| bits >> a & 1 == 1)
            .map(|a| strides[a])
            .sum::<usize>()
    }

    pub(crate) fn position(&self, p: usize) -> [f64; 3] {
        let [px, py, _] = self.dims;
        let c = [p % px, p / px % py, p / (px * py)];
        // Padded index 0 is one step before the grid.
        std::array::from_fn(|a| {
            self.origin[a] + self.spacing[a] * ((c[a] + self.at[a]) as f64 - 1.0)
        })
    }

    /// The centroid of padded points, summed in the order given.
    fn centroid(&self, simplex: &[usize]) -> [f64; 3] {
        let n = simplex.len() as f64;
        let mut x = [0.0f64; 3];
        for &p in simplex {
            let q = self.position(p);
            for d in 0..3 {
                x[d] += q[d] / n;
            }
        }
        x
    }

    /// The key of a simplex of a cell's Kuhn triangulation: its lowest point and the offsets
    /// of the others from it.
    pub(crate) fn key(&self, simplex: &[usize]) -> VertexKey {
        let [px, py, _] = self.dims;
        let low = *simplex.iter().min().expect("a simplex has points");
        let mut corners = 0u8;
        for &p in simplex.iter().filter(|&&p| p != low) {
            let d = p - low;
            let bits = u8::from(d % px != 0)
                | u8::from(d / px % py != 0) << 1
                | u8::from(d >= px * py) << 2;
            corners |= 1 << (bits - 1);
        }
        VertexKey::simplex(low, corners)
    }

    /// Meshes one box of the padded grid's cells: every label's triangles, tagged with its
    /// dense number.
    fn mesh_box(&self, cells: CellBox) -> Result<ChunkMesh, ExtractError> {
        cells.check(self.dims)?;
        let [px, py, _] = self.dims;
        let mut out = ChunkMesh::new(cells);
        let mut ids: FxHashMap<VertexKey, u32> = FxHashMap::default();
        let mut vertex = |out: &mut ChunkMesh, simplex: &[usize]| -> Result<u32, ExtractError> {
            let key = self.key(simplex);
            if let Some(&id) = ids.get(&key) {
                return Ok(id);
            }
            let id = u32::try_from(out.mesh.positions.len())
                .ok()
                .filter(|&id| id != u32::MAX)
                .ok_or(ExtractError::TooManyVertices)?;
            out.mesh
                .positions
                .push(self.centroid(simplex).map(|c| c as f32));
            out.keys.push(key);
            ids.insert(key, id);
            Ok(id)
        };
        for k in cells.min[2]..cells.max[2] {
            for j in cells.min[1]..cells.max[1] {
                for i in cells.min[0]..cells.max[0] {
                    let base = i + px * (j + py * k);
                    let first = self.padded[base];
                    if (1..8u8).all(|b| self.padded[self.corner(base, b)] == first) {
                        continue;
                    }
                    out.stats.active_cells += 1;
                    for tet in TETS {
                        let pts = tet.map(|b| self.corner(base, b));
                        let lab = pts.map(|p| self.padded[p]);
                        if lab.iter().all(|&l| l == lab[0]) {
                            continue;
                        }
                        let centre = vertex(&mut out, &pts)?;
                        for a in 0..4 {
                            for b in a + 1..4 {
                                if lab[a] == lab[b] || !(self.meshed(lab[a]) || self.meshed(lab[b]))
                                {
                                    continue;
                                }
                                let mid = vertex(&mut out, &[pts[a], pts[b]])?;
                                // The two faces of the tetrahedron through edge (a, b).
                                for c in (0..4).filter(|&c| c != a && c != b) {
                                    let face = vertex(&mut out, &[pts[a], pts[b], pts[c]])?;
                                    let mut t = [mid, face, centre];
                                    // Orient out of a: the triangle's normal along b − a.
                                    let p = [
                                        self.centroid(&[pts[a], pts[b]]),
                                        self.centroid(&[pts[a], pts[b], pts[c]]),
                                        self.centroid(&pts),
                                    ];
                                    let n = crate::mesh::cross(
                                        crate::mesh::sub(p[1], p[0]),
                                        crate::mesh::sub(p[2], p[0]),
                                    );
                                    let ab = crate::mesh::sub(
                                        self.position(pts[b]),
                                        self.position(pts[a]),
                                    );
                                    if crate::mesh::dot(n, ab) < 0.0 {
                                        t.swap(1, 2);
                                    }
                                    if self.meshed(lab[a]) {
                                        out.mesh.triangles.push(t);
                                        out.tags.push(lab[a]);
                                    }
                                    if self.meshed(lab[b]) {
                                        out.mesh.triangles.push([t[0], t[2], t[1]]);
                                        out.tags.push(lab[b]);
                                    }
                                }
                            }
                        }
                    }
                }
                out.end_row()?;
            }
        }
        Ok(out)
    }
}

/// How far a vertex may move from where it started, along each axis, in cells: the staircase's
/// corners lie up to about one cell from a smooth boundary.
const LIMIT: f64 = 1.0;

/// Constrained Laplacian smoothing of the shared vertices (Jacobi sweeps: the result does not
/// depend on the order vertices are visited).
fn smooth(positions: &mut [[f32; 3]], triangles: &[Vec<[u32; 3]>], sweeps: usize, h: [f64; 3]) {
    if sweeps == 0 || positions.is_empty() {
        return;
    }
    let mut edges: Vec<(u32, u32)> = triangles
        .iter()
        .flatten()
        .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
        .flat_map(|(a, b)| [(a, b), (b, a)])
        .collect();
    edges.sort_unstable();
    edges.dedup();
    let mut start = vec![0usize; positions.len() + 1];
    for &(a, _) in &edges {
        start[a as usize + 1] += 1;
    }
    for v in 0..positions.len() {
        start[v + 1] += start[v];
    }
    let original: Vec<[f64; 3]> = positions.iter().map(|p| p.map(f64::from)).collect();
    let mut now = original.clone();
    let mut next = original.clone();
    for _ in 0..sweeps {
        for v in 0..now.len() {
            let around = &edges[start[v]..start[v + 1]];
            if around.is_empty() {
                continue;
            }
            let n = around.len() as f64;
            for d in 0..3 {
                let mean = around.iter().map(|&(_, w)| now[w as usize][d]).sum::<f64>() / n;
                let x = now[v][d] + 0.5 * (mean - now[v][d]);
                next[v][d] = x.clamp(original[v][d] - LIMIT * h[d], original[v][d] + LIMIT * h[d]);
            }
        }
        std::mem::swap(&mut now, &mut next);
    }
    for (p, x) in positions.iter_mut().zip(&now) {
        *p = x.map(|c| c as f32);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::Grid;

    /// Blocks cut from the grid (the cells' points only, at odd offsets) and merged in a
    /// tree give extract_labels' surfaces to the bit, smoothing included.
    #[test]
    fn label_blocks_merge_into_the_whole_surfaces() {
        use crate::extract::merge_chunks;
        let dims = [13, 11, 9];
        let mut rng = crate::TestRng::new(5);
        let values: Vec<f32> = (0..dims.iter().product::<usize>())
            .map(|_| [0.0, 3.0, 900.0, 4.0][(rng.next_u64() >> 60) as usize % 4])
            .collect();
        let grid = Grid::new(dims, values.clone()).unwrap();
        let options = LabelOptions::default();
        let whole = extract_labels(&grid, &options).unwrap();
        let mut names: Vec<i64> = Vec::new();
        for v in &values {
            if !names.contains(&(*v as i64)) {
                names.push(*v as i64);
            }
        }
        let id = |p: [usize; 3]| {
            let v = grid.value(p[0], p[1], p[2]) as i64;
            names.iter().position(|n| *n == v).unwrap() as u32 + 1
        };
        let padded = dims.map(|d| d + 2);
        let mut chunks = Vec::new();
        for cells in CellBox::tile(padded, [5, 3, 4]).unwrap() {
            let at: [usize; 3] = std::array::from_fn(|a| cells.min[a].saturating_sub(1));
            let end: [usize; 3] = std::array::from_fn(|a| cells.max[a].min(dims[a]));
            let block: [usize; 3] = std::array::from_fn(|a| end[a] - at[a]);
            let mut ids = Vec::new();
            for k in 0..block[2] {
                for j in 0..block[1] {
                    for i in 0..block[0] {
                        ids.push(id([at[0] + i, at[1] + j, at[2] + k]));
                    }
                }
            }
            let chunk = mesh_label_block(
                &ids, at, block, dims, cells, &names, &options, [1.0; 3], [0.0; 3],
            )
            .unwrap();
            chunks.push(ChunkMesh::from_bytes(&chunk.to_bytes()).unwrap());
        }
        // Merged along z in pairs, then everything.
        chunks.sort_by_key(|c| (c.cells.min[0], c.cells.min[1], c.cells.min[2]));
        let mut columns: Vec<ChunkMesh> = Vec::new();
        for column in chunks.chunk_by(|a, b| a.cells.min[..2] == b.cells.min[..2]) {
            columns.push(merge_chunks(padded, column.to_vec()).unwrap());
        }
        let all = merge_chunks(padded, columns).unwrap();
        let got = label_surfaces_of(
            all,
            &names,
            &options,
            [1.0; 3],
            crate::field::Orientation::IDENTITY,
            [0.0; 3],
        )
        .unwrap();
        assert_eq!(got.len(), whole.len());
        for (a, b) in got.iter().zip(&whole) {
            assert_eq!((a.label, &a.mesh), (b.label, &b.mesh));
        }
    }

    fn labelled(dims: [usize; 3], mut f: impl FnMut(usize, usize, usize) -> f32) -> Grid {
        let mut v = Vec::new();
        for k in 0..dims[2] {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    v.push(f(i, j, k));
                }
            }
        }
        Grid::new(dims, v).unwrap()
    }

    /// Canonical position triples of a mesh's triangles, orientation kept.
    fn faces(mesh: &Mesh) -> Vec<[[u32; 3]; 3]> {
        let mut out: Vec<[[u32; 3]; 3]> = mesh
            .triangles
            .iter()
            .map(|t| {
                let p = t.map(|v| mesh.positions[v as usize].map(f32::to_bits));
                let i = (0..3).min_by_key(|&i| p[i]).unwrap();
                [p[i], p[(i + 1) % 3], p[(i + 2) % 3]]
            })
            .collect();
        out.sort_unstable();
        out
    }

    /// Random label fields, every label meshed (the background is a value that does not occur):
    /// every surface is closed, manifold, oriented outward; and every triangle inside the grid
    /// (not facing the outside layer) is found, reversed, in exactly one other label's surface.
    #[test]
    fn random_labels_give_closed_surfaces_with_shared_interfaces() {
        for seed in 0..40u64 {
            let mut rng = crate::TestRng::new(seed);
            let dims = [4 + (seed % 4) as usize, 5, 3 + (seed % 3) as usize];
            let labels = 2 + seed % 4;
            let grid = labelled(dims, |_, _, _| (rng.next_u64() % labels) as f32 * 3.0);
            let smoothed = LabelOptions {
                background: -1,
                ..LabelOptions::default()
            };
            // Interfaces are checked on the unsmoothed positions (outside-facing triangles
            // are those beyond the grid); smoothing moves shared vertices, never the triangles.
            let exact = LabelOptions {
                smoothing: 0,
                ..smoothed.clone()
            };
            let surfaces = extract_labels(&grid, &exact).unwrap();
            let smooth = extract_labels(&grid, &smoothed).unwrap();
            let all: Vec<Vec<[[u32; 3]; 3]>> = surfaces.iter().map(|s| faces(&s.mesh)).collect();
            for (n, s) in surfaces.iter().enumerate() {
                for mesh in [&s.mesh, &smooth[n].mesh] {
                    let r = mesh.report();
                    assert!(
                        r.watertight && r.oriented,
                        "seed {seed} label {}: {r:?}",
                        s.label
                    );
                    assert_eq!((r.nonmanifold_edges, r.degenerate), (0, 0));
                    assert!(r.volume.unwrap() > 0.0, "outward");
                }
                assert_eq!(s.mesh.triangles, smooth[n].mesh.triangles);
                let inside = |t: &[[u32; 3]; 3]| {
                    t.iter().all(|p| {
                        (0..3).all(|a| {
                            let x = f32::from_bits(p[a]);
                            x >= 0.0 && x <= (dims[a] - 1) as f32
                        })
                    })
                };
                for t in all[n].iter().filter(|t| inside(t)) {
                    let r = [t[0], t[2], t[1]];
                    let i = (0..3).min_by_key(|&i| r[i]).unwrap();
                    let reversed = [r[i], r[(i + 1) % 3], r[(i + 2) % 3]];
                    let owners = all
                        .iter()
                        .filter(|f| f.binary_search(&reversed).is_ok())
                        .count();
                    assert_eq!(
                        owners, 1,
                        "seed {seed}: interface triangle of {} shared {owners} times",
                        s.label
                    );
                }
            }
        }
    }

    #[test]
    fn selection_background_and_bad_values() {
        // A ball of 5 inside a box of 2 in background 0.
        let grid = labelled([9, 9, 9], |i, j, k| {
            let r2 = [i, j, k]
                .map(|c| (c as f32 - 4.0).powi(2))
                .iter()
                .sum::<f32>();
            if r2 <= 4.0 {
                5.0
            } else if (1..8).contains(&i) && (1..8).contains(&j) && (1..8).contains(&k) {
                2.0
            } else {
                0.0
            }
        });
        let all = extract_labels(&grid, &LabelOptions::default()).unwrap();
        assert_eq!(all.iter().map(|s| s.label).collect::<Vec<_>>(), vec![2, 5]);
        let box_ = all[0].mesh.report();
        let ball = all[1].mesh.report();
        // The box has a cavity: two components (outer and inner shells).
        assert_eq!((box_.components, box_.euler), (2, 4));
        assert_eq!((ball.components, ball.euler), (1, 2));
        // The ball's whole surface is the box's inner shell, reversed.
        let inner: usize = ball.triangles;
        assert!(box_.triangles > inner);
        let only = LabelOptions {
            labels: LabelSelection::Only(vec![5]),
            ..LabelOptions::default()
        };
        let just_ball = extract_labels(&grid, &only).unwrap();
        assert_eq!(just_ball.len(), 1);
        assert_eq!(faces(&just_ball[0].mesh), faces(&all[1].mesh));
        // Background 2: the box is not meshed, and label 0 is.
        let other = LabelOptions {
            background: 2,
            ..LabelOptions::default()
        };
        let labels: Vec<i64> = extract_labels(&grid, &other)
            .unwrap()
            .iter()
            .map(|s| s.label)
            .collect();
        assert_eq!(labels, vec![0, 5]);
        let bad = labelled([3, 3, 3], |i, _, _| if i == 1 { 0.5 } else { 1.0 });
        let e = extract_labels(&bad, &LabelOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("[1, 0, 0]") && e.contains("0.5"), "{e}");
    }
}

#[cfg(test)]
mod partition_tests {
    use super::*;
    use crate::field::Grid;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]
        /// Labelled meshing gives the same surfaces, to the bit, however its cells are cut into
        /// boxes (cuts along every axis, single cells, any order) and with any smoothing.
        #[test]
        fn any_partition_gives_the_same_surfaces(
            nx in 2usize..7, ny in 2usize..7, nz in 2usize..7, labels in 1u64..5,
            seed in any::<u64>(), sx in 1usize..5, sy in 1usize..5, sz in 1usize..5,
            smoothing in 0usize..4, background in 0i64..3,
        ) {
            let mut rng = crate::TestRng::new(seed);
            let dims = [nx, ny, nz];
            let values = (0..nx * ny * nz).map(|_| (rng.next_u64() % (labels + 1)) as f32).collect();
            let grid = Grid::new(dims, values).unwrap();
            let options = LabelOptions { background, smoothing, ..LabelOptions::default() };
            let whole = extract_labels_boxes(&grid, &options, &[label_cells(dims)]).unwrap();
            let points = label_cells(dims).max.map(|c| c + 1);
            let mut boxes = CellBox::tile(points, [sx, sy, sz]).unwrap();
            boxes.reverse();
            let tiled = extract_labels_boxes(&grid, &options, &boxes).unwrap();
            prop_assert_eq!(tiled.len(), whole.len());
            for (a, b) in tiled.iter().zip(&whole) {
                prop_assert_eq!(a.label, b.label);
                prop_assert_eq!(&a.mesh, &b.mesh);
            }
            let default = extract_labels(&grid, &options).unwrap();
            for (a, b) in default.iter().zip(&whole) {
                prop_assert_eq!(&a.mesh, &b.mesh);
            }
            // Cuts at random places along random axes, in a random order.
            let boxes = crate::random_partition(points, &mut rng);
            let cut = extract_labels_boxes(&grid, &options, &boxes).unwrap();
            for (a, b) in cut.iter().zip(&whole) {
                prop_assert_eq!(&a.mesh, &b.mesh, "boxes {:?}", &boxes);
            }
        }
    }
}
