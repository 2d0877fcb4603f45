//! Marching Cubes extraction: field → classify → cell patches → vertex placement → triangulate
//! → weld.
//!
//! # Contract
//! - Input: a [`Grid`] (dims ≥ 2 per axis, `f32` values, `x` fastest) and a finite level.
//! - A value equal to the level counts as **above**. Configurations are binary indices
//!   `Σ 2^i` over the cell's vertices at or above the level (vertex numbering in [`crate::cube`]).
//! - Ambiguous faces are decided by the asymptotic decider: the above corners are joined
//!   through the face when the bilinear saddle value is at or above the level, i.e. when the
//!   product of the above diagonal's offsets from the level is at least the product of the below
//!   diagonal's. Both cells sharing a face compute exactly the same numbers, so they always agree.
//! - Cells with a NaN or infinite value produce no surface; they are counted in
//!   [`ExtractStats::skipped_cells`], and the mesh has boundary edges only around them.
//!
//! # Topology
//! [`Topology::Mc33`] (the default) gives each cell the topology of the trilinear interpolant:
//! besides the faces, the cell's interior is tested for tunnels, where the interpolant joins two
//! same-sign regions of the cell's boundary through the inside (cases 4, 6, 7, 10, 12 and 13 of
//! Chernyaev's Marching Cubes 33). The test sweeps the cell with z-slices: on each slice the
//! interpolant is bilinear, and two diagonal slice corners share a region exactly when the other
//! two have the other sign and the slice's saddle lies on their side — a quadratic condition in
//! the slice height, checked exactly (see `classify::interior_links`). Ties follow the same rule
//! as values and face saddles: a saddle exactly at the level counts as above. Loops of seven or
//! more corners are split around an interior vertex, as MC33 does, so the patch passes through the
//! middle of the cell. [`Topology::Classic`] keeps the face-consistent surface without the interior
//! test. All 33 configurations of MC33 occur and are checked against refinement of the trilinear
//! field in the test suite.
//!
//! # Ternary extraction
//! [`Method::Ternary`] makes grid points on or near the level surface vertices (see [`Snapping`]):
//! extraction runs on the field with those points set to the level, crossings at them collapse onto
//! them, and each point is accepted only after an exact local check that the mesh stays a
//! manifold with the same components and Euler characteristic. The result has MC33's topology,
//! no zero-area or repeated triangles, and far better angles (see the README's quality table).
//!
//! ```
//! use isocube::extract::{extract, ExtractOptions, Method, Snapping};
//! use isocube::field::Sample;
//! let grid = Sample::Sphere.grid(40);
//! let mc = extract(&grid, &ExtractOptions::default()).unwrap().0.report();
//! let options =
//!     ExtractOptions::default().with_method(Method::Ternary(Snapping::default().with_snap(0.5)));
//! let ternary = extract(&grid, &options).unwrap().0.report();
//! assert_eq!((ternary.components, ternary.euler), (mc.components, mc.euler));
//! assert!(ternary.min_angle > 30.0 && mc.min_angle < 5.0);
//! ```
//!
//! # Output guarantees
//! - One vertex per grid edge the surface crosses, plus interior vertices in the few cells whose
//!   patches need them (split loops and some tunnels, at most three per cell), each at the
//!   centroid of a set of the cell's crossings.
//! - Normals point toward increasing values, as does the right-hand winding of every triangle;
//!   [`ExtractOptions::flip`] reverses both. Vertex normals come from the field's gradient
//!   (central differences, interpolated along the edge).
//! - Watertight, edge-manifold and consistently oriented when the surface does not reach the
//!   grid boundary — including integer data with many values exactly at the level. Where it does,
//!   open edges lie only on the grid's boundary faces.
//! - Deterministic: the same input gives the same bytes, whatever the number of threads.
//!
//! # Volumes larger than memory
//! [`extract_streamed`] reads planes from a [`crate::field::PlaneSource`] (a grid, or a mapped
//! file: `io::MappedVolume`) a batch of slabs at a time and hands the mesh to a [`MeshSink`] (a
//! [`Mesh`], or a PLY file written piece by piece: `io::PlyWriter`) in order; the result is
//! exactly [`extract`]'s.
//!
//! ```
//! use isocube::extract::{extract, ExtractOptions};
//! use isocube::field::Sample;
//! let (mesh, _) = extract(&Sample::Sphere.grid(10), &ExtractOptions::default()).unwrap();
//! assert_eq!(mesh.triangle_count(), 524);
//! let report = mesh.report();
//! assert!(report.watertight && report.oriented);
//! assert_eq!(report.euler, 2);
//! ```

mod binary;
mod block;
mod chunk;
mod classify;
mod labels;
mod layout;
mod place;

pub(crate) use classify::{cell_config, face_decisions};
pub(crate) use place::unsigned_zero;
mod patch_check;
mod stream;
mod ternary;
mod untangle;
mod weld;
mod window;

pub(crate) use binary::slabs;
pub use block::{block_halo, merge_chunks, mesh_block};
pub(crate) use chunk::join_tagged;
pub use chunk::{join, CellBox, ChunkMesh, KeyKind, VertexKey};
pub use labels::{
    extract_labels, extract_labels_boxes, label_cells, label_surfaces_of, mesh_label_block,
    LabelOptions, LabelSelection, LabelSurface,
};
pub(crate) use labels::{label_slabs, Labelled, TETS as KUHN_PATHS};
pub use layout::{assemble, ChunkOutline, ChunkPlace, JoinLayout, PlacedPiece};
pub use stream::{extract_streamed, streams_by_default, MeshSink, StreamError, STREAM_ABOVE_BYTES};

pub use ternary::{SnapPosition, Snapping, MIN_OFFSET, WALL_SNAP};

use thiserror::Error;

use rayon::prelude::*;

use crate::cube::{CaseTable, Topology};
use std::ops::ControlFlow;

use crate::field::{Grid, GridView};
use crate::mesh::Mesh;
use crate::quality::Strategy;

use binary::BinaryCells;
use classify::interior_links;
use place::Placer;
use weld::EdgeCache;
use window::Window;

/// Options of [`extract`].
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub struct ExtractOptions {
    /// The iso-value.
    pub level: f32,
    /// Reverse orientation: normals and winding point toward decreasing values.
    pub flip: bool,
    /// Compute vertex normals from the field gradient.
    pub normals: bool,
    /// The surface inside each cell: the trilinear interpolant's (MC33, default) or classic.
    pub topology: Topology,
    /// Plain (binary) Marching Cubes, or ternary with zero points on the surface.
    pub method: Method,
    /// How each cell polygon becomes triangles.
    pub triangulation: Strategy,
    /// Relaxation sweeps after extraction (see [`crate::quality::relax()`]); 0 for none.
    pub relax: usize,
    /// The most memory the mesh may take, in bytes (`None`: no limit). Extraction stops with
    /// [`ExtractError::MeshMemory`] as soon as the boxes meshed so far, and the joined copy
    /// they become, would need more: a clean error instead of the system's out-of-memory
    /// killer, whatever the front end.
    pub max_memory: Option<u64>,
    /// Volume meshes ([`crate::volume::tetmesh`]) only: how the interior coarsens away from
    /// the surface (by default [`crate::volume::Grading::DEFAULT`], cubes up to 16 cells on a
    /// side; [`crate::volume::Grading::UNIFORM`]: not at all). Extraction ignores it.
    pub grading: crate::volume::Grading,
}

/// Which Marching Cubes: binary (values at or above the level versus below) or ternary.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Method {
    /// Every grid point is above or below the level; the surface crosses grid edges.
    #[default]
    MarchingCubes,
    /// Grid points on or near the level are surface vertices (Tokunaga's extended Marching
    /// Cubes with Raman and Wenger's snapping), with the topology of [`Method::MarchingCubes`]
    /// kept: see [`Snapping`] and this module's section on ternary extraction.
    Ternary(Snapping),
}

impl Method {
    /// The name used on the command line: `mc` or `ternary`.
    pub fn name(self) -> &'static str {
        match self {
            Method::MarchingCubes => "mc",
            Method::Ternary(_) => "ternary",
        }
    }
}

impl Default for ExtractOptions {
    fn default() -> Self {
        ExtractOptions {
            level: 0.0,
            flip: false,
            normals: true,
            topology: Topology::Mc33,
            method: Method::MarchingCubes,
            triangulation: Strategy::Fan,
            relax: 0,
            max_memory: None,
            grading: crate::volume::Grading::DEFAULT,
        }
    }
}

impl ExtractOptions {
    /// Sets [`ExtractOptions::grading`].
    pub fn with_grading(mut self, grading: crate::volume::Grading) -> Self {
        self.grading = grading;
        self
    }

    /// Sets [`ExtractOptions::max_memory`].
    pub fn with_max_memory(mut self, bytes: Option<u64>) -> Self {
        self.max_memory = bytes;
        self
    }

    /// Sets the level.
    pub fn with_level(mut self, level: f32) -> Self {
        self.level = level;
        self
    }

    /// Sets the orientation flip.
    pub fn with_flip(mut self, flip: bool) -> Self {
        self.flip = flip;
        self
    }

    /// Sets whether normals are computed.
    pub fn with_normals(mut self, normals: bool) -> Self {
        self.normals = normals;
        self
    }

    /// Sets the topology.
    pub fn with_topology(mut self, topology: Topology) -> Self {
        self.topology = topology;
        self
    }

    /// Sets the method.
    pub fn with_method(mut self, method: Method) -> Self {
        self.method = method;
        self
    }

    /// Sets the number of relaxation sweeps.
    pub fn with_relax(mut self, sweeps: usize) -> Self {
        self.relax = sweeps;
        self
    }

    /// Sets the triangulation strategy.
    pub fn with_triangulation(mut self, strategy: Strategy) -> Self {
        self.triangulation = strategy;
        self
    }
}

/// Counts from one extraction.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ExtractStats {
    /// Cells in the grid.
    pub cells: usize,
    /// Cells the surface passes through.
    pub active_cells: usize,
    /// Cells skipped for a NaN or infinite value.
    pub skipped_cells: usize,
    /// Vertices placed inside cells (split loops and tunnels that need them).
    pub interior_vertices: usize,
    /// Cells where the interior test opened a tunnel (MC33 only).
    pub tunnels: usize,
    /// Ternary: grid points made surface vertices.
    pub snapped_points: usize,
    /// Ternary: candidate points left off the surface because snapping them would have changed
    /// the topology or made a degenerate triangle.
    pub refused_points: usize,
}

impl ExtractStats {
    /// Adds the counts of `other` (another box of the same grid).
    pub fn add(&mut self, other: &ExtractStats) {
        self.cells += other.cells;
        self.active_cells += other.active_cells;
        self.skipped_cells += other.skipped_cells;
        self.interior_vertices += other.interior_vertices;
        self.tunnels += other.tunnels;
        self.snapped_points += other.snapped_points;
        self.refused_points += other.refused_points;
    }
}

/// Why extraction failed.
#[derive(Debug, Error, Clone, PartialEq)]
#[non_exhaustive]
pub enum ExtractError {
    /// The level is NaN or infinite.
    #[error("the level {0} is not a finite number")]
    Level(f32),
    /// An option is out of its range.
    #[error("the {name} must be {range}, not {value}")]
    Option {
        /// The option.
        name: &'static str,
        /// Its valid range.
        range: &'static str,
        /// The value given.
        value: f32,
    },
    /// A combination of inputs this path does not handle.
    #[error("{0}")]
    Unsupported(&'static str),
    /// The ends of a contour reconstruction could not be closed flat.
    #[error(
        "cannot close the ends flat: section at z = {z}: the boundary on the end plane {reason}"
    )]
    Cap {
        /// The end section's height.
        z: f64,
        /// What is wrong with the boundary there.
        reason: crate::contours::LoopError,
    },
    /// A contour reconstruction whose estimated mesh needs more memory than allowed.
    #[error(
        "cells of {cell} would make about {triangles:.2e} triangles and need about {:.1} GiB, \
         more than the limit of {:.1} GiB",
        bytes / f64::from(1u32 << 30),
        *limit as f64 / f64::from(1u32 << 30)
    )]
    MemoryLimit {
        /// The plane grid's cell size.
        cell: f64,
        /// The estimated triangles.
        triangles: f64,
        /// The estimated bytes.
        bytes: f64,
        /// The limit in bytes.
        limit: u64,
    },
    /// The mesh needs more memory than [`ExtractOptions::max_memory`] allows.
    #[error(
        "the mesh of {done} of {total} cells already takes {:.1} MiB; with its joined copy it \
         needs more than the limit of {:.1} MiB",
        *bytes as f64 / f64::from(1u32 << 20),
        *limit as f64 / f64::from(1u32 << 20)
    )]
    MeshMemory {
        /// Cells meshed when the limit was passed.
        done: usize,
        /// Cells to mesh.
        total: usize,
        /// Bytes of the meshed boxes.
        bytes: u64,
        /// The limit.
        limit: u64,
    },
    /// A single section closes only with an extension cap.
    #[error("a single section makes a closed surface only with an extension cap")]
    SingleSection,
    /// The grid has too few points or too many.
    #[error(transparent)]
    Grid(#[from] crate::field::GridError),
    /// Slab-wise extraction was asked for something that needs the whole volume.
    #[error("ternary extraction and relaxation need the whole volume in memory, not slab by slab")]
    WholeVolume,
    /// The mesh would need more than `u32::MAX` vertices.
    #[error("the mesh would have more than {} vertices", u32::MAX)]
    TooManyVertices,
    /// A chunk size of zero cells along some axis.
    #[error("chunk sizes must be at least one cell along every axis, not {size:?}")]
    ChunkSize {
        /// The size given.
        size: [usize; 3],
    },
    /// A box of cells that is empty or reaches outside the grid.
    #[error("the box of cells {cells:?} is empty or outside a grid of {dims:?} points")]
    CellBox {
        /// The box.
        cells: CellBox,
        /// The grid's points per axis.
        dims: [usize; 3],
    },
    /// Two boxes given to the joiner share cells.
    #[error("the boxes of cells {first:?} and {second:?} overlap")]
    OverlappingBoxes {
        /// One box.
        first: CellBox,
        /// Another box with some of the same cells.
        second: CellBox,
    },
    /// A chunk mesh whose parts do not agree (keys, rows, normals), or that does not follow the
    /// previous one as a layered joiner needs.
    #[error("the chunk mesh of cells {cells:?} is malformed or out of order")]
    MalformedChunk {
        /// The chunk's box.
        cells: CellBox,
    },
    /// A block handed to [`mesh_block`] does not hold the points its cells need.
    #[error(
        "a block of {block:?} points at {at:?} does not hold the cells {cells:?} and {halo} points around them"
    )]
    Block {
        /// The cells asked for.
        cells: CellBox,
        /// The grid index of the block's first point.
        at: [usize; 3],
        /// The block's points per axis.
        block: [usize; 3],
        /// Points needed beyond the cells ([`block_halo`]).
        halo: usize,
    },
    /// No cell crosses the level, so the surface is empty: what every front end says when it
    /// refuses an empty mesh (the command line unless `--allow-empty`, Python unless
    /// `allow_empty=True`), with the range of the values so the user can pick a level inside.
    ///
    /// ```
    /// use isocube::extract::ExtractError;
    /// let e = ExtractError::EmptySurface { level: 5.0, range: Some((-1.0, 2.5)) };
    /// assert_eq!(e.to_string(), "no cell crosses the level 5: its values range from -1 to 2.5");
    /// assert!(e.outside_values());
    /// ```
    #[error("no cell crosses the level {level}: {}", match range {
        Some((lo, hi)) => format!("its values range from {lo} to {hi}"),
        None => "it has no finite value".to_string(),
    })]
    EmptySurface {
        /// The level asked for.
        level: f32,
        /// The smallest and largest finite value, `None` when no value is finite.
        range: Option<(f32, f32)>,
    },
    /// The progress callback asked to stop.
    #[error("stopped before the end (cancelled)")]
    Cancelled,
    /// A labelled grid holds a value that is not an integer label.
    #[error("point {point:?} holds {value}, which is not an integer label")]
    Label {
        /// The grid point.
        point: [usize; 3],
        /// Its value.
        value: f32,
    },
}

impl ExtractError {
    /// Whether this is [`ExtractError::EmptySurface`] with the level outside the values' range
    /// (or no finite value): no level set there at all, rather than one the cells miss.
    pub fn outside_values(&self) -> bool {
        match *self {
            ExtractError::EmptySurface { level, range } => {
                range.is_none_or(|(lo, hi)| level < lo || level > hi)
            }
            _ => false,
        }
    }
}

/// Extracts the isosurface into a new mesh.
pub fn extract<'a>(
    grid: impl Into<GridView<'a>>,
    options: &ExtractOptions,
) -> Result<(Mesh, ExtractStats), ExtractError> {
    let mut mesh = Mesh::new();
    let stats = extract_into(grid, options, &mut mesh, &mut crate::no_progress)?;
    Ok((mesh, stats))
}

/// Extracts into `mesh` (cleared first, allocations reused), calling `progress(done, total)`
/// as cells are meshed (counts of cells); when it answers [`ControlFlow::Break`] the work stops
/// and the call returns [`ExtractError::Cancelled`].
///
/// ```
/// use std::ops::ControlFlow;
/// use isocube::extract::{extract_into, ExtractError, ExtractOptions};
/// use isocube::field::Sample;
/// use isocube::mesh::Mesh;
/// let grid = Sample::Gyroid.grid(64);
/// let mut mesh = Mesh::new();
/// let mut calls = 0;
/// let stopped = extract_into(&grid, &ExtractOptions::default(), &mut mesh, &mut |done, total| {
///     calls += 1;
///     assert!(done <= total);
///     if done * 4 > total { ControlFlow::Break(()) } else { ControlFlow::Continue(()) }
/// });
/// assert!(matches!(stopped, Err(ExtractError::Cancelled)));
/// assert!(calls >= 1);
/// ```
pub fn extract_into<'a>(
    grid: impl Into<GridView<'a>>,
    options: &ExtractOptions,
    mesh: &mut Mesh,
    progress: &mut dyn FnMut(usize, usize) -> ControlFlow<()>,
) -> Result<ExtractStats, ExtractError> {
    let grid = grid.into();
    let boxes = binary::slabs(grid.dims());
    extract_boxes_into(grid, options, &boxes, mesh, progress)
}

/// Extracts the isosurface of the cells in `boxes` (disjoint; any sizes, any order), each box
/// meshed on its own in parallel and the boxes joined: with boxes that cover the grid the result
/// is [`extract`]'s, vertex for vertex and triangle for triangle.
///
/// ```
/// use isocube::extract::{extract, extract_boxes, CellBox, ExtractOptions};
/// use isocube::field::Sample;
/// let grid = Sample::Gyroid.grid(20);
/// let options = ExtractOptions::default();
/// let boxes = CellBox::tile(grid.dims(), [1, 19, 13]).unwrap();
/// assert_eq!(extract_boxes(&grid, &options, &boxes).unwrap(), extract(&grid, &options).unwrap());
/// ```
pub fn extract_boxes<'a>(
    grid: impl Into<GridView<'a>>,
    options: &ExtractOptions,
    boxes: &[CellBox],
) -> Result<(Mesh, ExtractStats), ExtractError> {
    let mut mesh = Mesh::new();
    let stats = extract_boxes_into(grid, options, boxes, &mut mesh, &mut crate::no_progress)?;
    Ok((mesh, stats))
}

/// [`extract_boxes`] into `mesh` (cleared first), calling `progress(done, total)` as cells
/// are meshed (a stop ends the work with [`ExtractError::Cancelled`], as in [`extract_into`]).
pub fn extract_boxes_into<'a>(
    grid: impl Into<GridView<'a>>,
    options: &ExtractOptions,
    boxes: &[CellBox],
    mesh: &mut Mesh,
    progress: &mut dyn FnMut(usize, usize) -> ControlFlow<()>,
) -> Result<ExtractStats, ExtractError> {
    let grid = grid.into();
    let extractor = Extractor::with_progress(grid, options, progress)?;
    let total: usize = boxes.iter().map(|b| b.cell_count()).sum();
    // Boxes are meshed a batch at a time so that progress is told, and a stop honoured, while
    // the work runs: some 32 batches, each enough to keep every thread busy.
    let batch = (boxes.len() / 32).max(4 * rayon::current_num_threads());
    let mut chunks: Vec<ChunkMesh> = Vec::with_capacity(boxes.len());
    let (mut done, mut held) = (0, 0u64);
    for group in boxes.chunks(batch) {
        let meshed = extractor.mesh_boxes(group)?;
        held += meshed.iter().map(ChunkMesh::bytes).sum::<u64>();
        chunks.extend(meshed);
        done += group.iter().map(|b| b.cell_count()).sum::<usize>();
        if let Some(limit) = options.max_memory.filter(|&l| held.saturating_mul(2) > l) {
            return Err(ExtractError::MeshMemory {
                done,
                total,
                bytes: held,
                limit,
            });
        }
        if progress(done, total).is_break() {
            return Err(ExtractError::Cancelled);
        }
    }
    let mut stats = join(grid.dims(), chunks, mesh, &mut |_| {})?;
    stats.snapped_points = extractor.snapping.0;
    stats.refused_points = extractor.snapping.1;
    if let Some(normals) = mesh.filled_normals() {
        mesh.normals = normals;
    }
    if options.relax > 0 {
        let spacing = grid.min_spacing();
        let level = f64::from(options.level);
        // A built-in sample relaxes on its exact function: the level set the grid approximates.
        match grid.exact() {
            Some(sample) => crate::quality::relax(
                mesh,
                &crate::quality::Implicit(|p| sample.eval(p), 1e-4 * spacing),
                level,
                options.relax,
                spacing,
            ),
            None => crate::quality::relax(
                mesh,
                &crate::quality::Trilinear(grid),
                level,
                options.relax,
                spacing,
            ),
        };
    }
    // Extraction ran in the grid's own frame; its direction turns the mesh into the world.
    grid.orientation().orient_mesh(mesh, grid.origin());
    Ok(stats)
}

/// A grid prepared for meshing boxes of its cells: the options checked and, for ternary
/// extraction, the zero points chosen (on the whole grid, so every box sees the same ones).
/// Boxes can then be meshed in any order, on any thread, and joined with [`join`].
///
/// ```
/// use isocube::extract::{CellBox, Extractor, ExtractOptions};
/// use isocube::field::Sample;
/// let grid = Sample::Sphere.grid(12);
/// let options = ExtractOptions::default();
/// let extractor = Extractor::new(&grid, &options).unwrap();
/// let chunk = extractor.mesh_box(CellBox::new([0, 0, 0], [6, 11, 11])).unwrap();
/// assert_eq!(chunk.keys.len(), chunk.mesh.positions.len());
/// assert!(chunk.stats.active_cells > 0);
/// ```
pub struct Extractor<'a> {
    grid: GridView<'a>,
    options: ExtractOptions,
    ternary: Option<ternary::Ternary<'a>>,
    /// Ternary: (snapped, refused) points.
    snapping: (usize, usize),
}

impl<'a> Extractor<'a> {
    /// Checks the options and makes the choices that need the whole grid.
    pub fn new(
        grid: impl Into<GridView<'a>>,
        options: &ExtractOptions,
    ) -> Result<Extractor<'a>, ExtractError> {
        Extractor::with_progress(grid, options, &mut crate::no_progress)
    }

    /// [`Extractor::new`], telling `progress` (no cells done yet, of the total) between
    /// stretches of the work over the whole grid — ternary snapping's choice of points, a
    /// fraction of a second on a 384³ grid, seconds on larger ones — and stopping with
    /// [`ExtractError::Cancelled`] when it says so.
    ///
    /// ```
    /// use std::ops::ControlFlow;
    /// use isocube::extract::{ExtractError, ExtractOptions, Extractor, Method, Snapping};
    /// use isocube::field::Sample;
    /// let grid = Sample::Gyroid.grid(48);
    /// let options = ExtractOptions::default().with_method(Method::Ternary(Snapping::default()));
    /// let mut asked = 0;
    /// let stopped = Extractor::with_progress(&grid, &options, &mut |done, _| {
    ///     assert_eq!(done, 0);
    ///     asked += 1;
    ///     if asked > 3 { ControlFlow::Break(()) } else { ControlFlow::Continue(()) }
    /// });
    /// assert!(matches!(stopped, Err(ExtractError::Cancelled)));
    /// ```
    pub fn with_progress(
        grid: impl Into<GridView<'a>>,
        options: &ExtractOptions,
        progress: &mut dyn FnMut(usize, usize) -> ControlFlow<()>,
    ) -> Result<Extractor<'a>, ExtractError> {
        let grid = grid.into();
        if !options.level.is_finite() {
            return Err(ExtractError::Level(options.level));
        }
        Grid::point_count(grid.dims())?;
        let mut extractor = Extractor {
            grid,
            options: *options,
            ternary: None,
            snapping: (0, 0),
        };
        if let Method::Ternary(snapping) = options.method {
            snapping.validate()?;
            let total = grid.cell_count();
            if progress(0, total).is_break() {
                return Err(ExtractError::Cancelled);
            }
            let mut ternary = ternary::Ternary::new(grid, options, snapping);
            extractor.snapping = ternary.choose_zeros(&mut || progress(0, total))?;
            extractor.ternary = Some(ternary);
        }
        Ok(extractor)
    }

    /// Ternary extraction: the grid points made surface vertices, and those refused.
    pub fn snapping_counts(&self) -> (usize, usize) {
        self.snapping
    }

    /// Ternary extraction: whether grid point `(i, j, k)` was made a zero point (the surface
    /// passes through it; it counts as the level). Always `false` for Marching Cubes.
    ///
    /// ```
    /// use isocube::extract::{ExtractOptions, Extractor, Method, Snapping};
    /// use isocube::field::Grid;
    /// // A plane through the middle points, x = 1.
    /// let grid = Grid::new([3, 2, 2], [-1.0, 0.0, 1.0].repeat(4)).unwrap();
    /// let options = ExtractOptions::default().with_method(Method::Ternary(Snapping::default()));
    /// let extractor = Extractor::new(&grid, &options).unwrap();
    /// assert!(extractor.is_zero_point([1, 1, 0]));
    /// assert!(!extractor.is_zero_point([0, 1, 0]));
    /// ```
    pub fn is_zero_point(&self, [i, j, k]: [usize; 3]) -> bool {
        let [nx, ny, _] = self.grid.dims();
        self.ternary
            .as_ref()
            .is_some_and(|t| t.zero_point(i + nx * (j + ny * k)))
    }

    /// The value extraction uses at grid point `(i, j, k)`: the grid's, except a ternary tie
    /// with points below around it and no neighbour above, which is below the level (no surface wraps
    /// it).
    pub(crate) fn value_at(&self, [i, j, k]: [usize; 3]) -> f32 {
        let [nx, ny, _] = self.grid.dims();
        match &self.ternary {
            Some(t) => t.value_at(i + nx * (j + ny * k)),
            None => self.grid.value(i, j, k),
        }
    }

    /// Meshes one box of cells.
    pub fn mesh_box(&self, cells: CellBox) -> Result<ChunkMesh, ExtractError> {
        self.mesh_box_with(&mut EdgeCache::new(0, 0), cells)
    }

    /// Meshes boxes in parallel; the chunks come in the order of `boxes`.
    pub fn mesh_boxes(&self, boxes: &[CellBox]) -> Result<Vec<ChunkMesh>, ExtractError> {
        boxes
            .par_iter()
            .map_init(
                || EdgeCache::new(0, 0),
                |cache, &cells| self.mesh_box_with(cache, cells),
            )
            .collect()
    }

    fn mesh_box_with(
        &self,
        cache: &mut EdgeCache,
        cells: CellBox,
    ) -> Result<ChunkMesh, ExtractError> {
        cells.check(self.grid.dims())?;
        match &self.ternary {
            Some(ternary) => {
                let placer = Placer::new(ternary.window(), &self.options);
                ternary.mesh_box(&placer, self.options.flip, cells)
            }
            None => {
                BinaryCells::new(Window::whole(self.grid), &self.options).mesh_box(cache, cells)
            }
        }
    }
}

/// How one cell is classified: its configuration, the decisions on its ambiguous faces and, under
/// MC33, the tunnel its interior opens.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CellCase {
    /// Binary configuration (bit `i` set: vertex `i` at or above the level).
    pub config: u8,
    /// Bit `f` set: the above corners of ambiguous face `f` are joined.
    pub decisions: u8,
    /// The same-sign regions the interior joins, if any (always `None` for classic).
    pub tunnel: Option<crate::cube::TunnelRegions>,
}

/// Classifies one cell from its eight values in cube vertex order (see [`crate::cube`]): what the
/// extractor decides for it. Useful to find which Marching Cubes 33 case a cell falls in.
///
/// ```
/// use isocube::cube::Topology;
/// use isocube::extract::classify_cell;
/// // Case 4 (vertices 0 and 6 above) with strong corners: the interpolant opens a tunnel.
/// let mut v = [-0.1f32; 8];
/// v[0] = 1.0;
/// v[6] = 1.0;
/// let case = classify_cell(&v, 0.0, Topology::Mc33);
/// assert_eq!(case.config, 0b0100_0001);
/// assert!(case.tunnel.is_some());
/// assert!(classify_cell(&v, 0.0, Topology::Classic).tunnel.is_none());
/// ```
pub fn classify_cell(values: &[f32; 8], level: f32, topology: Topology) -> CellCase {
    let table = CaseTable::binary();
    let config = cell_config(values, level);
    let decisions = face_decisions(values, level, table.ambiguous_faces(config));
    let tunnel = match topology {
        Topology::Mc33 if table.has_tunnel_candidates(config, decisions) => {
            choose_tunnel(table, config, decisions, values, level)
                .and_then(|k| table.tunnel_candidates(config, decisions).nth(k))
        }
        _ => None,
    };
    CellCase {
        config,
        decisions,
        tunnel,
    }
}

/// The tunnel the interior opens, as an index into the table's candidates for this cell.
fn choose_tunnel(
    table: &CaseTable,
    config: u8,
    decisions: u8,
    v: &[f32; 8],
    level: f32,
) -> Option<usize> {
    let links = interior_links(v, level);
    let mut found = None;
    for (p, q) in links {
        let joined = table.tunnel_candidates(config, decisions).position(|t| {
            let (a, b) = (t.first, t.second);
            (a >> p & 1 == 1 && b >> q & 1 == 1) || (a >> q & 1 == 1 && b >> p & 1 == 1)
        });
        if joined.is_some() {
            found = joined;
            break;
        }
    }
    found
}

#[cfg(test)]
mod tests;
