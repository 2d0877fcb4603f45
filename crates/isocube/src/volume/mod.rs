//! Tetrahedral meshes of the region inside an isosurface, for finite elements.
//!
//! [`tetmesh`] fills the region `f < level` (`f ≥ level` with [`ExtractOptions::flip`]: the two
//! sides of the binary classification [`crate::extract`] uses) with tetrahedra whose boundary is
//! the surface [`crate::extract::extract`] makes with the same options — the same vertex
//! positions and the same triangles, no point added on it — plus, where the region reaches the
//! grid's outer faces, the parts of those faces inside it (the *walls*).
//!
//! How each cell is filled:
//! - **A cell with all eight corners inside** is cut into the six tetrahedra of its Kuhn
//!   triangulation (the paths from its lowest to its highest corner along the three axes in
//!   each order). On cubic cells their dihedral angles are 45°, 60° and 90°.
//! - **A cell the surface passes through**: its part of the region is bounded by the cell's
//!   surface triangles and by the parts of its six faces inside the region. Each face part is
//!   cut by the surface's segments on that face into convex pieces, and every piece is
//!   triangulated by a rule that reads only the face (a whole square along the Kuhn diagonal,
//!   anything else the triangulation with the largest smallest angle), so both cells sharing a
//!   face cut it the same way and the mesh is conforming. Each connected part of the cell's
//!   region is then coned from one point inside it (a Steiner point, never on the boundary).
//! - **Ternary extraction** ([`Method::Ternary`] with [`SnapPosition::GridPoint`][grid]): a zero
//!   point is a corner on the surface, the surface's vertex there. A cell whose other corners
//!   are inside, and which the surface only touches at such corners, is still six Kuhn
//!   tetrahedra. As the crossings left keep at least the snap distance from the corners, the
//!   cut cells' parts are fat, and their cone points are placed for the angles: of the
//!   candidate points the one whose tetrahedra have the best dihedral angles, moved by a short
//!   compass search while its worst angle is under 12° (or 165° for the largest), or one of the
//!   part's own corners when that does better (thin parts). With snap 0.3 or 0.5 the angles
//!   stay within [10°, 165°] on smooth surfaces resolved by a few cells (the README's table).
//!   Snapped onto a crossing ([`SnapPosition::NearestCrossing`][crossing]), a zero point's
//!   vertex leaves its grid point and the cells around it follow it there (as in isosurface
//!   stuffing): faces bend, every tetrahedron is still checked, and the surface keeps Marching
//!   Cubes' accuracy. Where a cell's surface passes through a bent face into its neighbour, or
//!   its part does not fill alone, it is filled together with its neighbours (a group of up to
//!   12 cells).
//!
//! [grid]: crate::extract::SnapPosition::GridPoint
//! [crossing]: crate::extract::SnapPosition::NearestCrossing
//!
//! Every cone tetrahedron is checked with an exact orientation predicate on the coordinates as
//! stored (`f32`): all positive, over a closed boundary, means the cone tiles the part exactly.
//! Where no point sees a part whole (the surface folds in the cell), it is coned from several
//! points, or split in two along a disc spanning a short cycle of its edges and each side
//! filled (600 splits tried per part; 20 000 on the last attempt, the groups of cells filled at
//! the end). A part that none of this fills is reported as an error naming the cell rather than
//! meshed wrongly.
//!
//! ```
//! use isocube::extract::ExtractOptions;
//! use isocube::field::Sample;
//! use isocube::volume::tetmesh;
//! let grid = Sample::Sphere.grid(16);
//! let tets = tetmesh(&grid, &ExtractOptions::default().with_flip(false)).unwrap();
//! let check = tets.check();
//! assert!(check.conforming && check.inverted == 0 && check.flat == 0);
//! assert!((check.volume - check.enclosed).abs() <= 1e-9 * check.enclosed.abs());
//!
//! // Ternary extraction, snapped points on their grid points: the angles stay moderate.
//! use isocube::extract::{Method, SnapPosition, Snapping};
//! let snapping = Snapping::default().with_snap(0.5).with_position(SnapPosition::GridPoint);
//! let options = ExtractOptions::default().with_method(Method::Ternary(snapping));
//! let report = tetmesh(&Sample::Sphere.grid(24), &options).unwrap().quality_report();
//! assert!(report.min_dihedral > 10.0 && report.max_dihedral < 165.0);
//! ```

use std::ops::ControlFlow;

use rayon::prelude::*;
use rustc_hash::FxHashMap as HashMap;

use crate::extract::{
    join_tagged, slabs, ExtractError, ExtractOptions, ExtractStats, Extractor, KeyKind, Method,
    VertexKey,
};
use crate::field::GridView;
use crate::mesh::Mesh;

mod check;
mod cones;
mod cycles;
mod face;
mod front;
mod graded;
mod improve;
mod labels;
mod numbering;
mod quality;

pub use check::{positive, TetCheck};
pub use graded::Grading;
pub use improve::ImproveStats;
pub use labels::{tetmesh_labels, TetLabels};
pub use quality::{snap_detail, BoundaryEdge, PoorElements, QualityColumns, TetQuality, TetReport};

/// A tetrahedral mesh of the region inside a surface.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TetMesh {
    /// Vertex positions: the surface's vertices first (in the order [`crate::extract::extract`]
    /// gives them), then the grid points inside the region, then the Steiner points.
    pub positions: Vec<[f32; 3]>,
    /// Tetrahedra, each positively oriented: `(b − a) · ((c − a) × (d − a)) > 0`.
    pub tets: Vec<[u32; 4]>,
    /// The isosurface's triangles, outward: [`crate::extract::extract`]'s triangles.
    pub surface: Vec<[u32; 3]>,
    /// Boundary triangles on the grid's outer faces, outward.
    pub walls: Vec<[u32; 3]>,
    /// Surface triangles (indices into [`TetMesh::surface`]) that bound no tetrahedron: they lie
    /// in one of the grid's outer faces with the region beyond the grid (a sliver of it the grid
    /// does not hold).
    pub beyond: Vec<u32>,
    /// How many of [`TetMesh::positions`] are the surface's vertices.
    pub surface_vertices: usize,
    /// Counts.
    pub stats: TetStats,
    /// Multi-material meshes ([`tetmesh_labels`]): the label of each tetrahedron and boundary
    /// triangle, and the interfaces between labels. `None` for one region.
    pub labels: Option<TetLabels>,
}

/// Counts from [`tetmesh`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TetStats {
    /// Cells entirely inside, cut into six Kuhn tetrahedra each.
    pub lattice_cells: usize,
    /// Cells the surface passes through.
    pub cut_cells: usize,
    /// Graded meshes ([`crate::extract::ExtractOptions::grading`]): the cubes of 2 or more
    /// cells on a side whole cells were gathered into (their cells are counted in
    /// `lattice_cells`), the side of the largest, and the elements they hold.
    pub cubes: usize,
    /// The side of the largest cube, in cells (0 without cubes).
    pub largest_cube: usize,
    /// The tetrahedra of the cubes.
    pub cube_tets: usize,
    /// Grading was asked for, but the cells are longer than [`Grading::MAX_ASPECT`] to one:
    /// the interior is uniform.
    pub cells_too_long: bool,
    /// Grid points inside the region (vertices of the mesh).
    pub grid_points: usize,
    /// Points added inside cut cells (one per connected part).
    pub steiner_points: usize,
    /// Cut cells filled together with a neighbour, because the surface in one passes through
    /// their shared face, bent by corners snapped onto crossings (counted in `cut_cells` too).
    pub grouped_cells: usize,
    /// The surface extraction's counts.
    pub extract: ExtractStats,
    /// What the improvement after filling the cells did (flips, Steiner points moved).
    pub improve: ImproveStats,
}

/// Why a volume mesh could not be made.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum TetError {
    /// Extracting the surface failed.
    #[error(transparent)]
    Extract(#[from] ExtractError),
    /// A value is NaN or infinite: the region is not defined there.
    #[error("point {point:?} holds {value}: a volume mesh needs a finite value at every point")]
    NonFinite {
        /// The grid point.
        point: [usize; 3],
        /// Its value.
        value: f32,
    },
    /// No grid point lies inside the region.
    #[error("no region to mesh: no grid point is on the inside of the level (or of a label)")]
    Empty,
    /// A label asked for does not occur in the volume.
    #[error("label {0} does not occur in the volume")]
    NoLabel(i64),
    /// An option the volume mesher does not take.
    #[error("{0}")]
    Unsupported(&'static str),
    /// A cell's part of the region could not be filled (a bug: please report the input).
    #[error("cell {cell:?}: {reason}")]
    Cell {
        /// The cell, by its lowest grid point.
        cell: [usize; 3],
        /// What went wrong.
        reason: &'static str,
    },
    /// Marching Cubes' surface of values equal to the level has triangles of no area (crossings
    /// on grid points), and a cell's region around them could not be filled.
    #[error(
        "cell {cell:?}: {ties} values equal the level {level}, so Marching Cubes puts crossings \
         on grid points and its surface has triangles of no area that bound no region here; \
         ternary extraction (`--method ternary`, the command's default) makes such points the \
         surface's vertices and meshes this volume"
    )]
    TiedValues {
        /// The cell that could not be filled.
        cell: [usize; 3],
        /// How many grid values equal the level.
        ties: usize,
        /// The level.
        level: f32,
    },
    /// The mesh would take more memory than allowed.
    #[error("the volume mesh needs about {bytes} bytes, more than the limit of {limit}")]
    Memory {
        /// Bytes estimated.
        bytes: u64,
        /// The limit.
        limit: u64,
    },
    /// More vertices than 32-bit indices can number.
    #[error("too many vertices for 32-bit indices")]
    TooManyVertices,
}

/// Steiner points are numbered per layer of cells while the layers are meshed in parallel; this
/// bit marks such a local number until the layers are joined.
const STEINER: u32 = 1 << 31;

/// The cell number of surface triangles that bound no tetrahedron ([`TetMesh::beyond`]).
const BEYOND: u64 = u64::MAX - 1;

/// Meshes the region inside the isosurface of `grid` with tetrahedra (see the module
/// documentation). The options are [`crate::extract::extract`]'s; relaxation is refused (it
/// moves surface vertices off the cell faces the construction relies on).
pub fn tetmesh<'a>(
    grid: impl Into<GridView<'a>>,
    options: &ExtractOptions,
) -> Result<TetMesh, TetError> {
    tetmesh_with_progress(grid, options, &mut crate::no_progress)
}

/// [`tetmesh`], telling `progress(done, total)` as the work goes — the surface's cells, then
/// the layers of cells filled, counted in cells of twice the grid's — and stopping with
/// [`ExtractError::Cancelled`] (as [`TetError::Extract`]) when it says so.
///
/// ```
/// use std::ops::ControlFlow;
/// use isocube::extract::{ExtractError, ExtractOptions};
/// use isocube::field::Sample;
/// use isocube::volume::{tetmesh_with_progress, TetError};
/// let grid = Sample::Sphere.grid(40);
/// let mut seen = Vec::new();
/// let mesh = tetmesh_with_progress(&grid, &ExtractOptions::default(), &mut |done, total| {
///     seen.push((done, total));
///     ControlFlow::Continue(())
/// })
/// .unwrap();
/// assert!(!mesh.tets.is_empty());
/// assert_eq!(seen.last(), Some(&(2 * 39 * 39 * 39, 2 * 39 * 39 * 39)));
/// let stopped = tetmesh_with_progress(&grid, &ExtractOptions::default(), &mut |done, total| {
///     if 2 * done > total { ControlFlow::Break(()) } else { ControlFlow::Continue(()) }
/// });
/// assert!(matches!(stopped, Err(TetError::Extract(ExtractError::Cancelled))));
/// ```
pub fn tetmesh_with_progress<'a>(
    grid: impl Into<GridView<'a>>,
    options: &ExtractOptions,
    progress: &mut dyn FnMut(usize, usize) -> ControlFlow<()>,
) -> Result<TetMesh, TetError> {
    let grid = grid.into();
    match mesh_region(grid, options, progress) {
        Err(TetError::Cell { cell, reason }) if options.method == Method::MarchingCubes => {
            let [nx, ny, nz] = grid.dims();
            let level = options.level;
            let ties = (0..nz)
                .into_par_iter()
                .map(|k| {
                    let mut ties = 0;
                    for j in 0..ny {
                        for i in 0..nx {
                            ties += usize::from(grid.value(i, j, k) == level);
                        }
                    }
                    ties
                })
                .sum();
            Err(match ties {
                0 => TetError::Cell { cell, reason },
                ties => TetError::TiedValues { cell, ties, level },
            })
        }
        result => result,
    }
}

fn mesh_region(
    grid: GridView<'_>,
    options: &ExtractOptions,
    progress: &mut dyn FnMut(usize, usize) -> ControlFlow<()>,
) -> Result<TetMesh, TetError> {
    if options.relax > 0 {
        return Err(TetError::Unsupported(
            "relaxation moves surface vertices off the cell faces: a volume mesh cannot keep it",
        ));
    }
    let dims = grid.dims();
    if let Some((point, value)) = first_non_finite(&grid) {
        return Err(TetError::NonFinite { point, value });
    }
    let level = options.level;
    let flip = options.flip;
    let inside = move |v: f32| crate::field::is_above(v, level) == flip;

    // The surface, and every vertex's key.
    let surface_options = ExtractOptions {
        normals: false,
        relax: 0,
        ..*options
    };
    let cells = grid.cell_count();
    let total = 2 * cells;
    let extractor =
        Extractor::with_progress(grid, &surface_options, &mut |_, _| progress(0, total))?;
    let mut asked = |done: usize| match progress(done, total) {
        ControlFlow::Continue(()) => Ok(()),
        ControlFlow::Break(()) => Err(TetError::Extract(ExtractError::Cancelled)),
    };
    // The surface's slabs a batch at a time, the progress told between (the same chunks as
    // all at once).
    let boxes = slabs(dims);
    let batch = (boxes.len() / 32).max(4 * rayon::current_num_threads());
    let mut chunks = Vec::with_capacity(boxes.len());
    let mut done = 0;
    for group in boxes.chunks(batch) {
        chunks.extend(extractor.mesh_boxes(group)?);
        done += group.iter().map(|b| b.cell_count()).sum::<usize>();
        asked(done)?;
    }
    let mut surface = Mesh::new();
    let mut keys = Vec::new();
    let mut extract_stats = join_tagged(
        dims,
        chunks,
        &mut surface,
        &mut Vec::new(),
        Some(&mut keys),
        &mut |_| {},
    )?;
    (extract_stats.snapped_points, extract_stats.refused_points) = extractor.snapping_counts();

    // Each grid point's vertex: a zero point (ternary) is the surface's vertex there; inside
    // points are numbered after the surface's vertices in grid order.
    let point_count = dims[0] * dims[1] * dims[2];
    let ternary = matches!(options.method, Method::Ternary(_));
    let base = surface.positions.len();
    let zero_vertices = keys
        .iter()
        .enumerate()
        .filter_map(|(v, key)| match key.kind() {
            KeyKind::Point(p) => Some((p as u32, v as u32)),
            _ => None,
        })
        .collect();
    let mut rank = numbering::Numbering::new(point_count, base as u32, zero_vertices);
    let is_in = |[i, j, k]: [usize; 3]| {
        let p = i + dims[0] * (j + dims[1] * k);
        if ternary && extractor.is_zero_point([i, j, k]) {
            // A zero point the surface does not pass through: the surface around it vanished
            // as the point reached the level, leaving it on the side of its neighbours.
            !rank.is_zero(p) && {
                let c = [i, j, k];
                let sides: Vec<bool> = (0..6)
                    .filter_map(|e| {
                        let mut q = c;
                        q[e / 2] = (c[e / 2] + 1).checked_sub(2 * (e % 2))?;
                        (q[e / 2] < dims[e / 2] && !extractor.is_zero_point(q))
                            .then(|| inside(extractor.value_at(q)))
                    })
                    .collect();
                if sides.is_empty() {
                    flip
                } else {
                    sides.contains(&true)
                }
            }
        } else {
            inside(extractor.value_at([i, j, k]))
        }
    };
    // Classified slice by slice in parallel, numbered in grid order: counted first, then
    // written in place (a large body's points are not held twice).
    let slice_points = |k: usize| {
        (0..dims[1]).flat_map(move |j| {
            (0..dims[0])
                .filter(move |&i| is_in([i, j, k]))
                .map(move |i| (i + dims[0] * (j + dims[1] * k)) as u32)
        })
    };
    let counts: Vec<usize> = (0..dims[2])
        .into_par_iter()
        .map(|k| slice_points(k).count())
        .collect();
    let mut inside_points = vec![0u32; counts.iter().sum()];
    let mut parts = Vec::with_capacity(dims[2]);
    let mut rest = &mut inside_points[..];
    for &n in &counts {
        let (part, tail) = rest.split_at_mut(n);
        parts.push(part);
        rest = tail;
    }
    parts.into_par_iter().enumerate().for_each(|(k, part)| {
        for (slot, p) in part.iter_mut().zip(slice_points(k)) {
            *slot = p;
        }
    });
    asked(cells)?;
    // The extraction's own state (its sign masks and zero points) is done with.
    drop(extractor);
    rank.number(&inside_points);
    if inside_points.is_empty() {
        return Err(TetError::Empty);
    }
    if base + inside_points.len() >= STEINER as usize {
        return Err(TetError::TooManyVertices);
    }
    // Graded: away from the surface, whole cells gathered into cubes (see `graded`), on
    // cells whose transition cubes keep their angles.
    let grading = options.grading.on_cells(grid.spacing());
    // The bytes of the mesh with `tets` tetrahedra over `points` grid points (their positions
    // and numbers), the surface and the numbering's bits.
    let needs = |tets: usize, points: usize| {
        tets as u64 * 16
            + points as u64 * (12 + 4)
            + surface.triangles.len() as u64 * 24
            + point_count as u64 / 4
    };
    if let Some(limit) = options.max_memory.filter(|_| grading.max_level == 0) {
        // About six tetrahedra per inside point.
        let bytes = needs(6 * inside_points.len(), inside_points.len());
        if bytes > limit {
            return Err(TetError::Memory { bytes, limit });
        }
    }

    // Surface triangles by cell.
    let plane = |n: usize, m: usize| {
        let mut c = [0; 3];
        c[n] = m;
        grid.point(c[0], c[1], c[2])[n] as f32
    };
    let cell_dims = [dims[0] - 1, dims[1] - 1, dims[2] - 1];
    let mut by_cell: Vec<(u64, u32)> = surface
        .triangles
        .par_iter()
        .enumerate()
        .map(|(t, tri)| {
            let cell = match triangle_cell(tri, &keys, &surface.positions, dims, &plane) {
                Owner::Cell(c) => (c[0] + cell_dims[0] * (c[1] + cell_dims[1] * c[2])) as u64,
                Owner::Beyond => BEYOND,
                Owner::Nowhere => u64::MAX,
            };
            (cell, t as u32)
        })
        .collect();
    by_cell.par_sort_unstable();
    asked(cells)?;
    let beyond: Vec<u32> = by_cell
        .iter()
        .filter(|e| e.0 == BEYOND)
        .map(|e| e.1)
        .collect();
    if let Some(&(_, t)) = by_cell.last().filter(|e| e.0 == u64::MAX) {
        let tri = surface.triangles[t as usize];
        let c = cell_near(keys[tri[0] as usize], dims);
        return Err(TetError::Cell {
            cell: c,
            reason: "a surface triangle's vertices share no cell",
        });
    }

    // Crossing vertices by key, and the surface's segments on each cell face.
    let crossings: HashMap<VertexKey, u32> = keys
        .iter()
        .enumerate()
        .filter(|(_, k)| matches!(k.kind(), KeyKind::Crossing { .. }))
        .map(|(v, &k)| (k, v as u32))
        .collect();
    asked(cells)?;
    let mut owner = vec![u64::MAX; surface.triangles.len()];
    for &(cell, t) in &by_cell {
        owner[t as usize] = cell;
    }
    let inner_face = |v: u32| {
        let KeyKind::Interior { cell, .. } = keys[v as usize].kind() else {
            return None;
        };
        let p = surface.positions[v as usize];
        let mut q = coords(cell, dims);
        let n = (0..3).find(|&n| p[n] == plane(n, q[n]) || p[n] == plane(n, q[n] + 1))?;
        if p[n] != plane(n, q[n]) {
            q[n] += 1;
        }
        Some(face::face_id(q, n, dims))
    };
    let segments = face::surface_on_faces(
        &surface.triangles,
        &owner,
        &keys,
        dims,
        &inner_face,
        &mut || asked(cells),
    )?;

    let mut ctx = Context {
        grid,
        dims,
        rank,
        inside_points,
        positions: &surface.positions,
        surface: &surface.triangles,
        by_cell: &by_cell,
        crossings: &crossings,
        segments: &segments,
        base,
        flip,
        shape: ternary,
        grouped: Vec::new(),
        patient: false,
        cubes: None,
    };
    asked(cells)?;
    let cubes = (grading.max_level > 0).then(|| {
        let shared = &ctx;
        let whole: Vec<bool> = (0..cells)
            .into_par_iter()
            .map(|c| {
                matches!(shared.cell_fill(coords(c, cell_dims)), CellFill::Whole(ids)
                    if ids.iter().all(|&v| v != u32::MAX && v as usize >= shared.base))
            })
            .collect();
        graded::Cubes::new(cell_dims, grid.spacing(), whole, grading)
    });
    if let Some(cubes) = &cubes {
        // Only the grid points the mesh can use are numbered (most of a large body's are
        // inside cubes): the others' positions are never made.
        let used = cubes.grid_points();
        let uniform = 6 * ctx.inside_points.len();
        ctx.inside_points.retain(|&p| used[p as usize]);
        ctx.inside_points.shrink_to_fit();
        ctx.rank.number(&ctx.inside_points);
        if let Some(limit) = options.max_memory {
            let bytes = needs(cubes.element_estimate(uniform), ctx.inside_points.len());
            if bytes > limit {
                return Err(TetError::Memory { bytes, limit });
            }
        }
    }
    ctx.cubes = cubes;
    asked(cells)?;
    // The layers of cells are meshed in parallel a batch at a time and appended in order, each
    // freed once copied: the tetrahedra are held about once (all the layers first, then their
    // concatenation, held them twice, the allocator keeping the freed layers for a while).
    // Steiner points come after the grid points, in layer order.
    let steiner_base = base + ctx.inside_points.len();
    let mut positions = Vec::with_capacity(steiner_base);
    positions.extend_from_slice(&surface.positions);
    positions.par_extend(
        ctx.inside_points
            .par_iter()
            .map(|&p| ctx.point_position(p as usize)),
    );
    let mut stats = TetStats {
        grid_points: ctx.inside_points.len(),
        extract: extract_stats,
        cells_too_long: options.grading.max_level > 0 && grading.max_level == 0,
        ..TetStats::default()
    };
    // Room for six tetrahedra per inside point and a few per surface triangle reserved (not
    // touched): the vector seldom moves.
    let mut tets = Vec::with_capacity(6 * ctx.inside_points.len() + 8 * surface.triangles.len());
    let mut walls = Vec::new();
    let layer_cells = cell_dims[0] * cell_dims[1];
    // Snapped onto crossings, zero points carry the cells' corners off the grid: a cell face
    // bends, and the surface of the cell on one side may pass through it into the other. The
    // layers report such cells instead of filling them; then the layers are meshed again with
    // those cells left out, each filled together with its neighbours across the faces it
    // passes through (which then bound nothing).
    let mut crossed = Vec::new();
    let mut groups: Vec<Vec<[usize; 3]>> = Vec::new();
    let filled = loop {
        let filled = in_batches(
            cell_dims[2],
            |k| ctx.layer(k),
            |layers| asked(cells + layers * layer_cells),
            |layer| {
                append_layer(&layer, &mut positions, &mut tets, &mut walls, &mut stats)?;
                crossed.extend(layer.crossed);
                Ok(())
            },
        );
        if filled.is_err() || crossed.is_empty() || !ctx.grouped.is_empty() {
            break filled;
        }
        groups = match ctx.groups(std::mem::take(&mut crossed)) {
            Ok(groups) => groups,
            Err((cell, reason)) => break Err(TetError::Cell { cell, reason }),
        };
        ctx.grouped = groups
            .iter()
            .flatten()
            .map(|&c| ctx.cell_index(c))
            .collect();
        ctx.grouped.sort_unstable();
        tets.clear();
        walls.clear();
        positions.truncate(steiner_base);
        stats.steiner_points = 0;
        stats.lattice_cells = 0;
        stats.cut_cells = 0;
        stats.cubes = 0;
        stats.largest_cube = 0;
        stats.cube_tets = 0;
    };
    debug_assert!(crossed.is_empty());
    // The groups of cells last, in order: the last attempt at them.
    ctx.patient = true;
    let filled = filled.and_then(|()| {
        let layers: Vec<Layer> = groups
            .par_iter()
            .map(|cells| {
                ctx.fill_group(cells).map_err(|reason| TetError::Cell {
                    cell: cells[0],
                    reason,
                })
            })
            .collect::<Result<_, _>>()?;
        for layer in layers {
            append_layer(&layer, &mut positions, &mut tets, &mut walls, &mut stats)?;
            stats.grouped_cells += layer.cut_cells;
        }
        Ok(())
    });
    // The look-ups the cells were filled from are done with: a million small allocations, freed
    // while the work goes on (or the stop returns at once).
    let points = std::mem::take(&mut ctx.inside_points);
    release((segments, crossings, by_cell, keys, points));
    if let Err(e) = filled {
        release((tets, positions, walls, surface));
        return Err(e);
    }
    let total_steiner = stats.steiner_points;
    // Ternary meshes are held to the dihedral angle range: what the cells could not reach,
    // flips and moves across cells often can. With plain Marching Cubes the slivers come with
    // the surface (its triangles' corners fixed), several per cent of the elements, and the
    // work would cost far more than the meshing.
    if ternary {
        let steiner_end = steiner_base as u32 + total_steiner as u32;
        let improved = improve::improve_with(
            &mut positions,
            &mut tets,
            &mut walls,
            None,
            base as u32..steiner_base as u32,
            steiner_base as u32..steiner_end,
            &mut || asked(total),
        );
        stats.improve = match improved {
            Ok(s) => s,
            Err(e) => {
                release((tets, positions, walls, surface));
                return Err(e);
            }
        };
        stats.steiner_points += stats.improve.inserted;
        stats.steiner_points -= stats.improve.removed;
        stats.grid_points -= stats.improve.removed_grid;
    }
    if grading.max_level > 0 {
        // The grid points strictly inside cubes (but the centres of transition cubes) are in
        // no element: dropped, the later points numbered down.
        let unused = check::unused_points(positions.len(), &tets, base as u32);
        stats.grid_points -= unused.len();
        check::drop_points(&mut positions, &mut tets, &mut walls, &unused);
    }
    let mut mesh = TetMesh {
        positions,
        tets,
        surface: surface.triangles,
        walls,
        beyond,
        surface_vertices: base,
        stats,
        labels: None,
    };
    mesh.orient(&grid);
    Ok(mesh)
}

/// Appends a layer's tetrahedra, walls and Steiner points (numbered after `positions`) and
/// counts.
fn append_layer(
    layer: &Layer,
    positions: &mut Vec<[f32; 3]>,
    tets: &mut Vec<[u32; 4]>,
    walls: &mut Vec<[u32; 3]>,
    stats: &mut TetStats,
) -> Result<(), TetError> {
    if positions.len() + layer.steiner.len() >= STEINER as usize {
        return Err(TetError::TooManyVertices);
    }
    let map = steiner_map(positions.len() as u32);
    walls.extend(layer.walls.iter().map(|t| t.map(map)));
    tets.extend(layer.tets.iter().map(|t| t.map(map)));
    positions.extend_from_slice(&layer.steiner);
    stats.steiner_points += layer.steiner.len();
    stats.lattice_cells += layer.lattice_cells;
    stats.cut_cells += layer.cut_cells;
    stats.cubes += layer.cubes;
    stats.largest_cube = stats.largest_cube.max(layer.largest_cube);
    stats.cube_tets += layer.cube_tets;
    Ok(())
}

/// Meshes layers `0..count` in parallel a batch at a time and hands them to `append` in
/// order, a batch being appended while the next is meshed; each layer is freed once appended,
/// so the mesh is not held twice (all the layers, then their concatenation). `meshed` is told
/// the layers meshed so far before each batch and at the end (an error stops the work).
fn in_batches<L: Send>(
    count: usize,
    layer: impl Fn(usize) -> Result<L, TetError> + Sync,
    mut meshed: impl FnMut(usize) -> Result<(), TetError>,
    mut append: impl FnMut(L) -> Result<(), TetError> + Send,
) -> Result<(), TetError> {
    // Two layers a thread: enough to keep them busy, few enough that a stop is soon seen.
    let batch = 2 * rayon::current_num_threads().max(1);
    let mut pending: Vec<L> = Vec::new();
    let mut append_all = |layers: Vec<L>| layers.into_iter().try_for_each(&mut append);
    for first in (0..count).step_by(batch) {
        // Told (on this thread) how many layers are meshed before each batch starts.
        meshed(first)?;
        let (appended, layers) = rayon::join(
            || append_all(std::mem::take(&mut pending)),
            || {
                (first..(first + batch).min(count))
                    .into_par_iter()
                    .map(&layer)
                    .collect::<Result<Vec<L>, _>>()
            },
        );
        appended?;
        pending = layers?;
    }
    append_all(pending)?;
    meshed(count)
}

/// Frees buffers on a thread of their own: returning a million small allocations or a gigabyte
/// of elements to the system takes a fifth of a second or more, which neither the rest of the
/// work nor a stop asked for at the keyboard should wait for.
fn release<T: Send + 'static>(buffers: T) {
    // Where no thread can be had, the closure — buffers and all — is dropped here instead.
    let _ = std::thread::Builder::new()
        .name("isocube-release".into())
        .spawn(move || drop(buffers));
}

/// A layer's vertex numbers in the mesh: its Steiner points (`STEINER | k`) numbered from
/// `offset`, the rest as they are.
fn steiner_map(offset: u32) -> impl Fn(u32) -> u32 + Copy {
    move |v| {
        if v & STEINER != 0 {
            offset + (v & !STEINER)
        } else {
            v
        }
    }
}

impl TetMesh {
    /// Meshing runs in the grid's frame; its direction turns the mesh into the world (a
    /// reflection turns every element and triangle over, to keep them positive and outward).
    fn orient(&mut self, grid: &GridView) {
        let orientation = grid.orientation();
        if orientation.is_identity() {
            return;
        }
        let mut none: Vec<[f32; 3]> = Vec::new();
        orientation.orient_parts(
            &mut self.positions,
            &mut none,
            &mut self.surface,
            grid.origin(),
        );
        if orientation.determinant() < 0.0 {
            let interfaces = self.labels.as_mut().map(|l| &mut l.interfaces);
            for t in self
                .walls
                .iter_mut()
                .chain(interfaces.into_iter().flatten())
            {
                t.swap(1, 2);
            }
            for t in &mut self.tets {
                t.swap(2, 3);
            }
        }
    }
}

fn first_non_finite(grid: &GridView) -> Option<([usize; 3], f32)> {
    let [nx, ny, nz] = grid.dims();
    (0..nz).into_par_iter().find_map_first(|k| {
        for j in 0..ny {
            for i in 0..nx {
                let v = grid.value(i, j, k);
                if !v.is_finite() {
                    return Some(([i, j, k], v));
                }
            }
        }
        None
    })
}

/// Grid coordinates of point `p`.
fn coords(p: usize, dims: [usize; 3]) -> [usize; 3] {
    [p % dims[0], p / dims[0] % dims[1], p / (dims[0] * dims[1])]
}

/// The cells (as ranges of lowest corners per axis) a vertex with key `key` can belong to.
fn cell_range(key: VertexKey, dims: [usize; 3]) -> [[usize; 2]; 3] {
    let around = |c: [usize; 3], fixed: Option<usize>| {
        std::array::from_fn(|d| {
            if Some(d) == fixed {
                [c[d], c[d]]
            } else {
                [c[d].saturating_sub(1), c[d]]
            }
        })
    };
    match key.kind() {
        KeyKind::Crossing { point, axis } => around(coords(point, dims), Some(axis)),
        KeyKind::Interior { cell, .. } => {
            let c = coords(cell, dims);
            std::array::from_fn(|d| [c[d], c[d]])
        }
        KeyKind::Point(point) => around(coords(point, dims), None),
        _ => [[0, usize::MAX]; 3],
    }
}

/// Where a surface triangle belongs.
enum Owner {
    /// The cell whose part of the region it bounds.
    Cell([usize; 3]),
    /// It lies in one of the grid's outer faces with the region beyond it: it bounds no
    /// tetrahedron.
    Beyond,
    /// Its vertices share no cell (a bug).
    Nowhere,
}

/// The cell whose part of the region the triangle bounds: the one cell holding all three
/// vertices or, for a triangle lying in a grid plane, the cell on its inside (the surface is
/// outward, so its normal points away from that cell).
fn triangle_cell(
    tri: &[u32; 3],
    keys: &[VertexKey],
    positions: &[[f32; 3]],
    dims: [usize; 3],
    plane: &dyn Fn(usize, usize) -> f32,
) -> Owner {
    let k = tri.map(|v| keys[v as usize]);
    let on_grid = k.iter().find_map(|key| match key.kind() {
        KeyKind::Crossing { point, .. } | KeyKind::Point(point) => Some(point),
        _ => None,
    });
    if let Some(point) = on_grid {
        let c = coords(point, dims);
        // A cell's interior point lies in one of its faces when the polygon it splits does.
        let on_plane = |v: u32, n: usize| {
            let key = keys[v as usize];
            key.on_plane(dims, n, c[n])
                || (matches!(key.kind(), KeyKind::Interior { .. })
                    && positions[v as usize][n] == plane(n, c[n]))
        };
        for n in 0..3 {
            if tri.iter().all(|&v| on_plane(v, n)) {
                let p = tri.map(|v| positions[v as usize].map(f64::from));
                let normal = check::cross(check::sub(p[1], p[0]), check::sub(p[2], p[0]))[n];
                if normal == 0.0 {
                    return Owner::Nowhere;
                }
                // Outward along +n: the region is on the side of lower cells.
                let side = if normal > 0.0 {
                    c[n].checked_sub(1)
                } else {
                    Some(c[n])
                };
                let Some(layer) = side.filter(|&l| l + 1 < dims[n]) else {
                    return Owner::Beyond;
                };
                let range = common_range(&k, dims);
                let mut cell: [usize; 3] = std::array::from_fn(|d| range[d][0]);
                cell[n] = layer;
                let unique = (0..3).all(|d| d == n || range[d][0] == range[d][1]);
                return if unique {
                    Owner::Cell(cell)
                } else {
                    Owner::Nowhere
                };
            }
        }
    }
    let range = common_range(&k, dims);
    if (0..3).all(|d| range[d][0] == range[d][1]) {
        Owner::Cell(std::array::from_fn(|d| range[d][0]))
    } else {
        Owner::Nowhere
    }
}

/// The cells (ranges of lowest corners per axis, within the grid) that hold all the keys.
fn common_range(keys: &[VertexKey], dims: [usize; 3]) -> [[usize; 2]; 3] {
    let mut range = [[0usize, usize::MAX]; 3];
    for &key in keys {
        let r = cell_range(key, dims);
        for d in 0..3 {
            range[d][0] = range[d][0].max(r[d][0]);
            range[d][1] = range[d][1].min(r[d][1]).min(dims[d] - 2);
        }
    }
    range
}

/// A cell next to a vertex, to name in an error.
fn cell_near(key: VertexKey, dims: [usize; 3]) -> [usize; 3] {
    let r = cell_range(key, dims);
    std::array::from_fn(|d| r[d][0].min(dims[d] - 2))
}

/// The tetrahedra of one layer of cells, with Steiner points numbered locally.
#[derive(Default)]
struct Layer {
    tets: Vec<[u32; 4]>,
    walls: Vec<[u32; 3]>,
    steiner: Vec<[f32; 3]>,
    lattice_cells: usize,
    cut_cells: usize,
    cubes: usize,
    largest_cube: usize,
    cube_tets: usize,
    /// Cells left unfilled because their boundary passes through one of their faces (bent by
    /// corners off their grid points), with that face.
    crossed: Vec<([usize; 3], Side)>,
}

impl Layer {
    /// Appends another layer's tetrahedra and Steiner points (renumbered after these).
    fn append(&mut self, other: Layer) {
        let base = self.steiner.len() as u32;
        self.steiner.extend(other.steiner);
        self.tets.extend(other.tets.into_iter().map(|t| {
            t.map(|v| {
                if v & STEINER != 0 {
                    STEINER | (base + (v & !STEINER))
                } else {
                    v
                }
            })
        }));
        self.walls.extend(other.walls);
    }

    /// Appends tetrahedra whose Steiner points (`STEINER | k`) index `points`.
    fn push_tiled(&mut self, (points, tets): cones::Tiled) {
        self.append(Layer {
            tets,
            steiner: points.iter().map(|p| p.map(|x| x as f32)).collect(),
            ..Layer::default()
        });
    }
}

struct Context<'a> {
    grid: GridView<'a>,
    dims: [usize; 3],
    /// Inside grid points' vertex numbers (`u32::MAX` outside; a graded mesh numbers only
    /// those it can use).
    rank: numbering::Numbering,
    /// The grid points numbered, in order.
    inside_points: Vec<u32>,
    positions: &'a [[f32; 3]],
    surface: &'a [[u32; 3]],
    /// (cell, triangle), sorted.
    by_cell: &'a [(u64, u32)],
    crossings: &'a HashMap<VertexKey, u32>,
    segments: &'a HashMap<u64, face::OnFace>,
    /// Number of the first grid point vertex.
    base: usize,
    flip: bool,
    /// Whether to place cone points for the tetrahedra's angles: with ternary extraction only,
    /// whose crossings keep away from the corners. Marching Cubes' surface has needles and
    /// slivers next to corners that no cone point can lift, and the search would only cost time.
    shape: bool,
    /// Cells filled together with neighbours ([`Context::groups`]), by index, sorted: the layers
    /// leave them out.
    grouped: Vec<u64>,
    /// Whether a part whose fill runs out of splits gets [`LAST_SPLIT_BUDGET`] more: on the last
    /// attempt only (the groups of cells, filled at the end), as a first attempt that fails is
    /// cheaper to answer by grouping the cell with its neighbours.
    patient: bool,
    /// Graded meshes: the cubes whole cells are gathered into away from the surface.
    cubes: Option<graded::Cubes>,
}

/// A cell's boundary triangle: the surface's, or one of a cell face's inside part (the cell and
/// its face `2 · axis + side`, side 1 the upper face).
type Side = Option<([usize; 3], usize)>;

/// A cell and why it could not be filled.
type CellFailure = ([usize; 3], &'static str);

/// How a cell is filled.
enum CellFill {
    /// Not at all: no part of the region in it.
    Empty,
    /// With the six Kuhn tetrahedra over these corners.
    Whole([u32; 8]),
    /// Along the surface and its faces' inside parts.
    Cut,
}

/// The most cells filled together ([`Context::groups`]).
const MAX_GROUP: usize = 12;

/// How many times a group that does not fill is grown and tried again.
const FILL_TRIES: u32 = 2;

/// Where a cell corner lies.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Corner {
    /// Inside the region: a grid point vertex.
    In,
    /// On the surface: a zero point of ternary extraction, the surface's vertex.
    Zero,
    /// Outside.
    Out,
}

/// The six Kuhn tetrahedra of a cube, as corner offsets (bit 0: +x, bit 1: +y, bit 2: +z),
/// each positively oriented.
const KUHN: [[u8; 4]; 6] = [
    // Even permutations (x y z, y z x, z x y) keep the path's orientation; odd ones are
    // written with their last two points swapped.
    [0, 1, 3, 7],
    [0, 2, 6, 7],
    [0, 4, 5, 7],
    [0, 1, 7, 5],
    [0, 2, 7, 3],
    [0, 4, 7, 6],
];

impl Context<'_> {
    fn point_position(&self, p: usize) -> [f32; 3] {
        let [i, j, k] = coords(p, self.dims);
        self.grid.point(i, j, k).map(|c| c as f32)
    }

    /// Any vertex's position (grid points and surface vertices; not Steiner points).
    fn position(&self, v: u32) -> [f32; 3] {
        let v = v as usize;
        if v < self.base {
            self.positions[v]
        } else {
            self.point_position(self.inside_points[v - self.base] as usize)
        }
    }

    fn point_id(&self, c: [usize; 3]) -> u32 {
        self.rank
            .get(c[0] + self.dims[0] * (c[1] + self.dims[1] * c[2]))
    }

    /// The side of the corner whose vertex (by [`Context::point_id`]) is `id`.
    fn corner(&self, id: u32) -> Corner {
        if id == u32::MAX {
            Corner::Out
        } else if (id as usize) < self.base {
            Corner::Zero
        } else {
            Corner::In
        }
    }

    /// The surface's triangles bounding the cell's part of the region.
    fn cell_triangles(&self, cell: [usize; 3]) -> &[(u64, u32)] {
        let [cx, cy] = [self.dims[0] - 1, self.dims[1] - 1];
        let index = (cell[0] + cx * (cell[1] + cy * cell[2])) as u64;
        let from = self.by_cell.partition_point(|e| e.0 < index);
        let to = self.by_cell.partition_point(|e| e.0 <= index);
        &self.by_cell[from..to]
    }

    /// Whether the surface has an edge on one of the cell's six faces.
    fn touches_faces(&self, cell: [usize; 3]) -> bool {
        (0..3).any(|n| {
            let mut q = cell;
            q[n] += 1;
            [cell, q]
                .iter()
                .any(|&f| self.segments.contains_key(&face::face_id(f, n, self.dims)))
        })
    }

    /// The cell's index among the cells (as in `by_cell`).
    fn cell_index(&self, cell: [usize; 3]) -> u64 {
        let [cx, cy] = [self.dims[0] - 1, self.dims[1] - 1];
        (cell[0] + cx * (cell[1] + cy * cell[2])) as u64
    }

    /// The vertices of the cell's corners ([`Context::point_id`]), in corner-offset order.
    fn corner_ids(&self, [i, j, k]: [usize; 3]) -> [u32; 8] {
        std::array::from_fn(|o| self.point_id([i + (o & 1), j + (o >> 1 & 1), k + (o >> 2 & 1)]))
    }

    /// How the cell is filled.
    fn cell_fill(&self, cell: [usize; 3]) -> CellFill {
        let ids = self.corner_ids(cell);
        let outside = ids.iter().filter(|&&v| v == u32::MAX).count();
        let zero = ids.iter().filter(|&&v| (v as usize) < self.base).count();
        let inside = 8 - outside - zero;
        // Zero corners (ternary): the surface passes through them. The cell is whole
        // when the rest are inside and the surface only touches it at those points;
        // with zero corners only, it lies on the side where `g`, the level, counts.
        let owns = zero > 0 && !self.cell_triangles(cell).is_empty();
        // Snapped onto a crossing, a zero corner has left its grid point: the cell's
        // Kuhn tetrahedra are checked like any other.
        let whole = outside == 0
            && (zero == 0
                || ((inside > 0 || self.flip)
                    && !owns
                    && !self.touches_faces(cell)
                    && KUHN.iter().all(|t| {
                        let p = t.map(|o| self.position(ids[usize::from(o)]).map(f64::from));
                        check::positive(p[0], p[1], p[2], p[3])
                    })));
        if whole {
            CellFill::Whole(ids)
        } else if inside > 0 || owns || (outside == 0 && self.flip) {
            CellFill::Cut
        } else {
            CellFill::Empty
        }
    }

    fn layer(&self, k: usize) -> Result<Layer, TetError> {
        let [nx, ny, _] = self.dims;
        let mut out = Layer::default();
        let mut scratch = face::Scratch::default();
        for j in 0..ny - 1 {
            for i in 0..nx - 1 {
                let cell = [i, j, k];
                if !self.grouped.is_empty()
                    && self.grouped.binary_search(&self.cell_index(cell)).is_ok()
                {
                    continue;
                }
                if let Some(cubes) = &self.cubes {
                    let level = cubes.level(cell);
                    if level > 0 {
                        let mask = (1usize << level) - 1;
                        if cell.iter().all(|&x| x & mask == 0) {
                            let id = |p: [usize; 3]| self.point_id(p);
                            let before = out.tets.len();
                            cubes.cube(cell, level, &id, &mut out.tets, &mut out.walls);
                            out.lattice_cells += 1 << (3 * level);
                            out.cubes += 1;
                            out.largest_cube = out.largest_cube.max(1 << level);
                            out.cube_tets += out.tets.len() - before;
                        }
                        continue;
                    }
                }
                let failed = |reason| TetError::Cell { cell, reason };
                match self.cell_fill(cell) {
                    CellFill::Whole(ids) => {
                        out.lattice_cells += 1;
                        out.tets
                            .extend(KUHN.iter().map(|t| t.map(|o| ids[usize::from(o)])));
                        self.cell_walls(cell, &mut out.walls, &mut scratch)
                            .map_err(failed)?;
                    }
                    CellFill::Cut => {
                        out.cut_cells += 1;
                        self.cut_cell(cell, &mut out, &mut scratch)
                            .map_err(failed)?;
                    }
                    CellFill::Empty => {}
                }
            }
        }
        Ok(out)
    }

    /// The closed boundary of the region in a set of cells (sorted by index): the surface's
    /// triangles in them and their faces' inside parts, outward, but for the faces two of them
    /// share; with the side of each. The parts of the grid's outer faces go to `walls` too.
    fn boundary(
        &self,
        cells: &[[usize; 3]],
        mut walls: Option<&mut Vec<[u32; 3]>>,
        scratch: &mut face::Scratch,
    ) -> Result<(Vec<[u32; 3]>, Vec<Side>), &'static str> {
        let mut boundary: Vec<[u32; 3]> = Vec::new();
        let mut sides: Vec<Side> = Vec::new();
        for &cell in cells {
            boundary.extend(
                self.cell_triangles(cell)
                    .iter()
                    .map(|&(_, t)| self.surface[t as usize]),
            );
            sides.resize(boundary.len(), None);
            for dir in 0..6 {
                if self
                    .across(cell, dir)
                    .is_some_and(|next| cells.contains(&next))
                {
                    continue;
                }
                let (n, upper) = (dir / 2, dir % 2 == 1);
                let start = boundary.len();
                let mut q = cell;
                q[n] += usize::from(upper);
                self.face_triangles(q, n, &mut boundary, scratch)?;
                if !upper {
                    for t in &mut boundary[start..] {
                        t.swap(1, 2);
                    }
                }
                let outer = if upper {
                    cell[n] + 2 == self.dims[n]
                } else {
                    cell[n] == 0
                };
                if let Some(walls) = walls.as_deref_mut().filter(|_| outer) {
                    walls.extend_from_slice(&boundary[start..]);
                }
                sides.resize(boundary.len(), Some((cell, dir)));
            }
        }
        Ok((boundary, sides))
    }

    /// The cell across face `dir` (`2 · axis + side`) of `cell`, if the grid has one.
    fn across(&self, cell: [usize; 3], dir: usize) -> Option<[usize; 3]> {
        let n = dir / 2;
        let mut next = cell;
        if dir % 2 == 1 {
            next[n] += 1;
            (next[n] + 1 < self.dims[n]).then_some(next)
        } else {
            next[n] = next[n].checked_sub(1)?;
            Some(next)
        }
    }

    /// Where a boundary passes through itself: `Some(face)` when one of the triangles that
    /// meet lies in a face of the cells (the face to open), `Some(None)` when only the surface's
    /// do, `None` when nothing crosses (or where vertices meet, which only touch).
    fn crossing(&self, boundary: &[[u32; 3]], sides: &[Side], bent: u8) -> Option<Side> {
        let position = |v: u32| self.position(v).map(f64::from);
        if boundary.iter().any(|t| check::collinear(t.map(position)))
            || shared_points(boundary, &position)
        {
            return None;
        }
        // Only a bent face can be crossed: the cell's surface lies on the inside of every flat
        // face's plane (its vertices leave the cell only along a face's normal, bending it).
        let at = |t: [u32; 3]| t.map(|v| (v, position(v)));
        let surface = (0..boundary.len()).filter(|&i| sides[i].is_none());
        let faces: Vec<usize> = (0..boundary.len())
            .filter(|&i| sides[i].is_some_and(|(_, dir)| bent >> dir & 1 == 1))
            .collect();
        for i in surface {
            for &j in &faces {
                if crate::mesh::intersect::triangles_cross(at(boundary[i]), at(boundary[j])) {
                    return Some(sides[j]);
                }
            }
        }
        None
    }

    /// The cells to fill together: each cell the layers could not fill alone (`crossed`: its
    /// boundary passes through one of its faces, named, bent by corners off their grid points;
    /// or no cone, split or front filled it), joined with its neighbour across that face, or
    /// across another face its region continues through (bent faces first), until the group's
    /// boundary passes through none of its faces and the group fills ([`MAX_GROUP`] cells at
    /// most; a grid point is never left inside a group, where no tetrahedron would hold it).
    fn groups(
        &self,
        crossed: Vec<([usize; 3], Side)>,
    ) -> Result<Vec<Vec<[usize; 3]>>, CellFailure> {
        let mut groups: Vec<Vec<[usize; 3]>> = Vec::new();
        let mut member: HashMap<u64, usize> = HashMap::default();
        let mut scratch = face::Scratch::default();
        for (cell, side) in crossed {
            if member.contains_key(&self.cell_index(cell)) {
                continue;
            }
            let g = groups.len();
            groups.push(vec![cell]);
            member.insert(self.cell_index(cell), g);
            let mut open = side;
            // Filling a group that does not fill costs a search: tried a few times only.
            let mut tries = FILL_TRIES;
            loop {
                let face = match open {
                    Some(face) => Some(face),
                    None if tries == 0 => None,
                    None if self.fill_group(&groups[g]).is_ok() => None,
                    None => {
                        tries -= 1;
                        self.face_to_open(&groups[g], &member)
                    }
                };
                let Some((at, dir)) = face else { break };
                let Some(next) = self.across(at, dir) else {
                    break;
                };
                let joined = match member.get(&self.cell_index(next)) {
                    Some(&h) if h == g => break,
                    Some(&h) => std::mem::take(&mut groups[h]),
                    None => vec![next],
                };
                if groups[g].len() + joined.len() > MAX_GROUP
                    || self.encloses_point(&groups[g], &joined)
                {
                    // Back where it was: filling the group reports the cell.
                    if let Some(&h) = member.get(&self.cell_index(joined[0])) {
                        groups[h] = joined;
                    }
                    break;
                }
                for &c in &joined {
                    member.insert(self.cell_index(c), g);
                }
                groups[g].extend(joined);
                groups[g].sort_unstable_by_key(|&c| self.cell_index(c));
                let (boundary, sides) = self
                    .boundary(&groups[g], None, &mut scratch)
                    .map_err(|reason| (cell, reason))?;
                let bent = groups[g].iter().fold(0, |b, &c| b | self.bent_faces(c));
                open = match bent {
                    0 => None,
                    _ => self.crossing(&boundary, &sides, 0x3f).flatten(),
                };
            }
        }
        groups.retain(|g| !g.is_empty());
        groups.sort_unstable_by_key(|g| self.cell_index(g[0]));
        Ok(groups)
    }

    /// A face of the group's cells to open next: one the region continues through to a cell
    /// the group may take (bent faces first, then in cell and face order).
    fn face_to_open(
        &self,
        group: &[[usize; 3]],
        member: &HashMap<u64, usize>,
    ) -> Option<([usize; 3], usize)> {
        let mut scratch = face::Scratch::default();
        let mut faces = Vec::new();
        for &cell in group {
            let bent = self.bent_faces(cell);
            for dir in 0..6 {
                let Some(next) = self.across(cell, dir) else {
                    continue;
                };
                if group.contains(&next)
                    || member.contains_key(&self.cell_index(next))
                    || self.encloses_point(group, &[next])
                {
                    continue;
                }
                let mut q = cell;
                q[dir / 2] += dir % 2;
                let mut on = Vec::new();
                if self
                    .face_triangles(q, dir / 2, &mut on, &mut scratch)
                    .is_err()
                    || on.is_empty()
                {
                    continue;
                }
                faces.push((bent >> dir & 1 == 0, cell, dir));
            }
        }
        faces.sort_unstable_by_key(|&(flat, cell, dir)| (flat, self.cell_index(cell), dir));
        faces.first().map(|&(_, cell, dir)| (cell, dir))
    }

    /// The grid point of corner `o` of the cell (linear index).
    fn corner_point(&self, [i, j, k]: [usize; 3], o: usize) -> usize {
        let c = [i + (o & 1), j + (o >> 1 & 1), k + (o >> 2 & 1)];
        c[0] + self.dims[0] * (c[1] + self.dims[1] * c[2])
    }

    /// Whether joining `more` to the cells `group` would put a grid point inside the union
    /// (all eight cells around it in it).
    fn encloses_point(&self, group: &[[usize; 3]], more: &[[usize; 3]]) -> bool {
        let all: Vec<[usize; 3]> = group.iter().chain(more).copied().collect();
        more.iter().any(|&cell| {
            (0..8).any(|o| {
                let c = [
                    cell[0] + (o & 1),
                    cell[1] + (o >> 1 & 1),
                    cell[2] + (o >> 2 & 1),
                ];
                (0..8).all(|r| {
                    let around = [0, 1, 2].map(|d| c[d].checked_sub((r >> d) & 1));
                    around
                        .iter()
                        .all(|x| x.is_some())
                        .then(|| around.map(|x| x.unwrap_or(0)))
                        .is_some_and(|a| all.contains(&a))
                })
            })
        })
    }

    /// Fills a group of cells ([`Context::groups`]) as one region.
    fn fill_group(&self, cells: &[[usize; 3]]) -> Result<Layer, &'static str> {
        let mut out = Layer {
            cut_cells: cells.len(),
            ..Layer::default()
        };
        let mut scratch = face::Scratch::default();
        let (boundary, _) = self.boundary(cells, Some(&mut out.walls), &mut scratch)?;
        if !boundary.is_empty() {
            self.fill_boundary(cells[0], &boundary, &mut out)?;
        }
        // A group's boundary bounds volume everywhere: a flat element would be a fill gone wrong.
        let at = |v: u32| {
            if v & STEINER != 0 {
                out.steiner[(v & !STEINER) as usize].map(f64::from)
            } else {
                self.position(v).map(f64::from)
            }
        };
        if out.tets.iter().any(|t| {
            let p = t.map(at);
            !check::positive(p[0], p[1], p[2], p[3])
        }) {
            return Err(FOLDED);
        }
        Ok(out)
    }

    /// The triangles of the cell's faces on the grid's outer faces, outward.
    fn cell_walls(
        &self,
        cell: [usize; 3],
        walls: &mut Vec<[u32; 3]>,
        scratch: &mut face::Scratch,
    ) -> Result<(), &'static str> {
        for n in 0..3 {
            if cell[n] == 0 {
                let from = walls.len();
                self.face_triangles(cell, n, walls, scratch)?;
                for t in &mut walls[from..] {
                    t.swap(1, 2);
                }
            }
            if cell[n] + 2 == self.dims[n] {
                let mut q = cell;
                q[n] += 1;
                self.face_triangles(q, n, walls, scratch)?;
            }
        }
        Ok(())
    }

    fn cut_cell(
        &self,
        cell: [usize; 3],
        out: &mut Layer,
        scratch: &mut face::Scratch,
    ) -> Result<(), &'static str> {
        let (walls, tets, steiner) = (out.walls.len(), out.tets.len(), out.steiner.len());
        let (boundary, sides) = self.boundary(&[cell], Some(&mut out.walls), scratch)?;
        // The first time through (no groups yet), a cell that does not fill alone is reported,
        // to be filled with neighbours.
        let first = self.grouped.is_empty();
        let bent = self.bent_faces(cell);
        let crossed = match bent {
            0 => None,
            _ => self.crossing(&boundary, &sides, bent),
        };
        let filled = match crossed {
            Some(_) if first => Err(CROSSED),
            _ => self.fill_boundary(cell, &boundary, out),
        };
        match filled {
            Err(_) if first => {
                out.walls.truncate(walls);
                out.tets.truncate(tets);
                out.steiner.truncate(steiner);
                out.crossed.push((cell, crossed.flatten()));
                Ok(())
            }
            filled => filled,
        }
    }

    /// The cell's faces (bit `2 · axis + side`) with a corner off their plane: a zero point
    /// snapped onto a crossing along the face's normal.
    fn bent_faces(&self, cell: [usize; 3]) -> u8 {
        let ids = self.corner_ids(cell);
        let mut bent = 0;
        for (o, &v) in ids.iter().enumerate() {
            if (v as usize) >= self.base {
                continue;
            }
            let at = self.positions[v as usize];
            let grid = self.point_position(self.corner_point(cell, o));
            for n in (0..3).filter(|&n| at[n] != grid[n]) {
                bent |= 1 << (2 * n + (o >> n & 1));
            }
        }
        bent
    }

    /// Fills the closed boundary of the region in a cell (or a group of cells around `cell`),
    /// part by part.
    fn fill_boundary(
        &self,
        cell: [usize; 3],
        boundary: &[[u32; 3]],
        out: &mut Layer,
    ) -> Result<(), &'static str> {
        for part in parts(boundary, &|v| self.position(v))? {
            let mut budget = SPLIT_BUDGET;
            let Some(peeled) = self.shape.then(|| self.peeled(cell, &part)).flatten() else {
                if let Err(reason) = self.fill(cell, &part, out, SPLIT_DEPTH, &mut budget) {
                    // (A part whose surface passes through itself no split can fill.)
                    if !self.patient || reason == CROSSED {
                        return Err(reason);
                    }
                    // The last attempt at a part that folds so that the usual number of splits
                    // (and the front after them) fails: many more (such parts are rare, and only
                    // they pay for it; the first 600 are tried again, at most ~0.4 s).
                    let mut budget = LAST_SPLIT_BUDGET;
                    self.fill(cell, &part, out, SPLIT_DEPTH, &mut budget)?;
                }
                continue;
            };
            // Cutting the ears off is kept only when it beats filling the part as it is.
            let mut plain = Layer::default();
            match self.fill(cell, &part, &mut plain, SPLIT_DEPTH, &mut budget) {
                Ok(()) if self.worst(&plain) >= self.worst(&peeled) => out.append(plain),
                _ => out.append(peeled),
            }
        }
        Ok(())
    }

    /// A thin wedge of the part — two boundary triangles meeting at an edge at a small angle
    /// inside, as where a snapped surface leaves a cell face at a shallow slope — caps the
    /// dihedral angles of any cone: a cone point splits the wedge's angle between two
    /// tetrahedra at that edge. Such a wedge is cut off whole instead, as the tetrahedron of its
    /// two triangles (an *ear*: positive by the exact predicate), and the rest filled as usual.
    /// `None` when the part has no such wedge or the rest does not fill. As everywhere, all
    /// tetrahedra positive over closed boundaries makes the result tile the part.
    fn peeled(&self, cell: [usize; 3], part: &[[u32; 3]]) -> Option<Layer> {
        let position = |v: u32| self.position(v).map(f64::from);
        let mut rest: Vec<[u32; 3]> = part.to_vec();
        let mut ears: Vec<[u32; 4]> = Vec::new();
        while ears.len() < MAX_EARS {
            let Some(ear) = thinnest_wedge(&rest, &position) else {
                break;
            };
            let [u, a, v, b] = ear;
            let rotations = |t: [u32; 3]| [t, [t[1], t[2], t[0]], [t[2], t[0], t[1]]];
            let same = |x: &[u32; 3], t: [u32; 3]| rotations(t).contains(x);
            // The wedge's two triangles go; the ear's other faces, seen from the rest, come
            // (cancelling a triangle they meet the other way round).
            rest.retain(|t| !same(t, [u, v, a]) && !same(t, [v, u, b]));
            for face in [[a, b, v], [u, b, a]] {
                let back = [face[0], face[2], face[1]];
                match rest.iter().position(|t| same(t, back)) {
                    Some(k) => {
                        rest.swap_remove(k);
                    }
                    None => rest.push(face),
                }
            }
            ears.push(ear);
        }
        if ears.is_empty() {
            return None;
        }
        let mut peeled = Layer::default();
        peeled.tets.extend_from_slice(&ears);
        let filled = rest.is_empty()
            || parts(&rest, &|v| self.position(v)).is_ok_and(|pieces| {
                pieces.iter().all(|piece| {
                    // A piece with no volume would take flat tetrahedra.
                    let tris: Vec<[[f64; 3]; 3]> = piece.iter().map(|t| t.map(position)).collect();
                    let mut budget = SPLIT_BUDGET;
                    !check::coplanar(&tris)
                        && self
                            .fill(cell, piece, &mut peeled, SPLIT_DEPTH, &mut budget)
                            .is_ok()
                })
            });
        filled.then_some(peeled)
    }

    /// The worst [`tet_score`] of a layer's tetrahedra.
    fn worst(&self, layer: &Layer) -> f64 {
        let at = |v: u32| {
            if v & STEINER != 0 {
                layer.steiner[(v & !STEINER) as usize].map(f64::from)
            } else {
                self.position(v).map(f64::from)
            }
        };
        layer
            .tets
            .iter()
            .map(|t| tet_score(t.map(at)))
            .fold(f64::INFINITY, f64::min)
    }

    /// Fills a closed part with tetrahedra, trying in turn: a cone from one candidate point that
    /// sees every triangle from inside; from one of the part's own corners; from the centre of
    /// the largest ball in its kernel; from two or three candidates; from points chosen by a
    /// search ([`Context::spread_cones`]); splitting the part in two along a disc and filling
    /// each side ([`Context::split`], at most [`SPLIT_DEPTH`] times, the sides with the quick
    /// attempts only). Every tetrahedron is checked positive on the stored
    /// coordinates: with a closed boundary, that makes the tetrahedra tile the part exactly
    /// (their signed indicators add up to its winding number).
    fn fill(
        &self,
        cell: [usize; 3],
        part: &[[u32; 3]],
        out: &mut Layer,
        depth: u32,
        budget: &mut u32,
    ) -> Result<(), &'static str> {
        let tris: Vec<[[f64; 3]; 3]> = part
            .iter()
            .map(|t| t.map(|v| self.position(v).map(f64::from)))
            .collect();
        // Values within rounding of the level put crossings on grid points: the surface has
        // triangles of no area there (the mesh `extract` writes has them too), and a part may
        // have no volume at all. Tetrahedra over such triangles, or in such a part, are flat;
        // none may be inverted.
        let degenerate: Vec<bool> = tris.iter().map(|t| check::collinear(*t)).collect();
        // A triangle (p, q, r) seen from inside, with the apex, is the tetrahedron (p, r, q, apex).
        let cone = |apex: [f64; 3]| -> cones::Tiled {
            let tets = part.iter().map(|t| [t[0], t[2], t[1], STEINER]).collect();
            (vec![apex], tets)
        };
        if check::coplanar(&tris) {
            // A side of a split with no volume: the disc lies in the part's boundary.
            if depth < SPLIT_DEPTH {
                return Err(FOLDED);
            }
            out.push_tiled(cone(tris[0][0]));
            return Ok(());
        }
        let candidates = self.candidates(cell, part);
        let sees_all = |apex: [f64; 3]| cones::sees_all(&tris, &degenerate, apex);
        let apex = self.best_apex(cell, &tris, &degenerate, &candidates);
        if let Some((apex, _)) = apex.filter(|a| !self.shape || a.1 >= GOOD_CONE) {
            out.push_tiled(cone(apex));
            return Ok(());
        }
        // A cone from one of the part's own corners, over the triangles not touching it: no
        // Steiner point at all (the apex of a fan that folds the surface often sees the rest;
        // a thin part's corner often makes better tetrahedra than any point inside).
        let mut corners: Vec<u32> = part.iter().flatten().copied().collect();
        corners.sort_unstable();
        corners.dedup();
        let mut best_corner: Option<(u32, f64)> = None;
        for &v in &corners {
            let pv = self.position(v).map(f64::from);
            let far = || part.iter().zip(&tris).filter(|(t, _)| !t.contains(&v));
            if far().all(|(_, t)| check::positive(t[0], t[2], t[1], pv)) {
                if !self.shape {
                    out.tets.extend(far().map(|(t, _)| [t[0], t[2], t[1], v]));
                    return Ok(());
                }
                let q = far()
                    .map(|(_, t)| cone_quality(t, pv))
                    .fold(f64::INFINITY, f64::min);
                if best_corner.is_none_or(|b| q > b.1) {
                    best_corner = Some((v, q));
                }
            }
        }
        match (apex, best_corner) {
            (Some((_, a)), Some((v, c))) if c > a => {
                let far = part.iter().filter(|t| !t.contains(&v));
                out.tets.extend(far.map(|t| [t[0], t[2], t[1], v]));
                return Ok(());
            }
            (Some((apex, _)), _) => {
                out.push_tiled(cone(apex));
                return Ok(());
            }
            (None, Some((v, _))) => {
                let far = part.iter().filter(|t| !t.contains(&v));
                out.tets.extend(far.map(|t| [t[0], t[2], t[1], v]));
                return Ok(());
            }
            (None, None) => {}
        }
        let position = |v: u32| self.position(v).map(f64::from);
        // A boundary that passes through itself bounds no region: no search can fill it. (Not
        // asked where values at the level put several vertices on one point: those touch.)
        if depth == SPLIT_DEPTH
            && !degenerate.contains(&true)
            && !shared_points(part, &position)
            && crate::mesh::intersect::first_crossing(part, &position).is_some()
        {
            return Err(CROSSED);
        }
        // (The largest ball's centre costs a linear program: not for the many parts splits try.)
        if let Some(apex) = (depth == SPLIT_DEPTH)
            .then(|| check::kernel_point(&tris))
            .flatten()
            .map(|a| a.map(f64::from))
            .filter(|&a| sees_all(a))
        {
            out.push_tiled(cone(apex));
            return Ok(());
        }
        // Parts split off a larger one get only the quick attempts above and further splits.
        if depth == SPLIT_DEPTH {
            if let Some(tiled) = self.several_cones(cell, part, &tris, &degenerate, &candidates) {
                out.push_tiled(tiled);
                return Ok(());
            }
        }
        if depth > 0 && self.split(cell, part, out, depth - 1, budget) {
            return Ok(());
        }
        if depth == SPLIT_DEPTH {
            // The last resort: tetrahedra added one at a time from the boundary inward.
            if let Ok(tiled) = front::advance(part, &position, &tet_score) {
                out.push_tiled(tiled);
                return Ok(());
            }
        }
        Err(FOLDED)
    }

    /// Cones from two, then three candidates, then from points chosen by
    /// [`Context::spread_cones`].
    fn several_cones(
        &self,
        cell: [usize; 3],
        part: &[[u32; 3]],
        tris: &[[[f64; 3]; 3]],
        degenerate: &[bool],
        candidates: &[[f64; 3]],
    ) -> Option<cones::Tiled> {
        // Two, then three points, each triangle coned to the first that sees it.
        let n = candidates.len();
        let pairs = (0..n).flat_map(|i| (0..n).filter(move |&j| j != i).map(move |j| vec![i, j]));
        let triples = (0..n)
            .flat_map(|i| (i + 1..n).flat_map(move |j| (j + 1..n).map(move |k| vec![i, j, k])));
        let position = |v: u32| self.position(v).map(f64::from);
        for pick in pairs.chain(triples) {
            let points: Vec<[f64; 3]> = pick.iter().map(|&i| candidates[i]).collect();
            // Each triangle to the first point that sees it.
            let group: Option<Vec<u32>> = tris
                .iter()
                .zip(degenerate)
                .map(|(t, &d)| {
                    points
                        .iter()
                        .position(|&s| cones::sees(t, d, s))
                        .map(|g| g as u32)
                })
                .collect();
            let Some(group) = group else { continue };
            if let Ok(tiled) = cones::tile(part, tris, degenerate, &points, &group, &position, None)
            {
                return Some(tiled);
            }
        }
        self.spread_cones(cell, part, tris, degenerate, candidates)
    }

    /// Splits a part no cone fills into two along a disc spanning a short cycle of its edges
    /// (through a reflex edge first), the disc a fan from one of the cycle's vertices, and fills
    /// each side ([`Context::fill`], which may split again while `depth` and `budget` last). The sides'
    /// tetrahedra add up, as chains, to the part's boundary (the disc cancels), so all positive
    /// they tile it. On failure `out` is left as it was.
    fn split(
        &self,
        cell: [usize; 3],
        part: &[[u32; 3]],
        out: &mut Layer,
        depth: u32,
        budget: &mut u32,
    ) -> bool {
        let position = |v: u32| self.position(v).map(f64::from);
        let Some(split) = cycles::Splitter::new(part, &position) else {
            return false;
        };
        let (tets, steiner) = (out.tets.len(), out.steiner.len());
        for (a, b) in split.sides() {
            if *budget == 0 {
                return false;
            }
            *budget -= 1;
            if self.fill(cell, &a, out, depth, budget).is_ok()
                && (b.is_empty() || self.fill(cell, &b, out, depth, budget).is_ok())
            {
                return true;
            }
            out.tets.truncate(tets);
            out.steiner.truncate(steiner);
        }
        false
    }

    /// Among the candidates that see every triangle, the apex whose cone has the best angles,
    /// moved by a short compass search while that improves them (only where the best
    /// candidate's angles are poor). With [`Context::shape`] off, the first candidate.
    fn best_apex(
        &self,
        cell: [usize; 3],
        tris: &[[[f64; 3]; 3]],
        degenerate: &[bool],
        candidates: &[[f64; 3]],
    ) -> Option<([f64; 3], f64)> {
        let sees_all = |apex: [f64; 3]| cones::sees_all(tris, degenerate, apex);
        // The cone's worst score, or None as soon as a tetrahedron scores `bound` or less (the
        // cone cannot win).
        let score = |apex: [f64; 3], bound: f64| {
            let mut worst = f64::INFINITY;
            for (t, _) in tris.iter().zip(degenerate).filter(|(_, &d)| !d) {
                worst = worst.min(cone_quality(t, apex));
                if worst <= bound {
                    return None;
                }
            }
            Some(worst)
        };
        if !self.shape {
            return candidates
                .iter()
                .copied()
                .find(|&c| sees_all(c))
                .map(|c| (c, 0.0));
        }
        const GOOD: f64 = GOOD_CONE;
        let mut best: Option<([f64; 3], f64)> = None;
        for &c in candidates {
            if sees_all(c) {
                let Some(q) = score(c, best.map_or(f64::NEG_INFINITY, |b| b.1)) else {
                    continue;
                };
                if q >= GOOD {
                    return Some((c, q));
                }
                best = Some((c, q));
            }
        }
        let (mut apex, mut quality) = best?;
        let lo = self.grid.point(cell[0], cell[1], cell[2]);
        let hi = self.grid.point(cell[0] + 1, cell[1] + 1, cell[2] + 1);
        let mut step = (0..3).map(|d| hi[d] - lo[d]).fold(f64::INFINITY, f64::min) / 8.0;
        for _ in 0..5 {
            let mut moved = false;
            for axis in 0..6 {
                let mut p = apex;
                p[axis / 2] += if axis % 2 == 0 { step } else { -step };
                let p = p.map(|x| f64::from(x as f32));
                if sees_all(p) {
                    if let Some(q) = score(p, quality) {
                        (apex, quality, moved) = (p, q, true);
                    }
                }
            }
            if quality >= GOOD {
                break;
            }
            if !moved {
                step /= 2.0;
            }
        }
        Some((apex, quality))
    }

    /// Cones from points chosen by [`cones::assign`] among the candidates and two points inside
    /// each triangle (those covering the part greedily first, then those seeing most), tiled by
    /// [`cones::tile`].
    fn spread_cones(
        &self,
        cell: [usize; 3],
        part: &[[u32; 3]],
        tris: &[[[f64; 3]; 3]],
        degenerate: &[bool],
        candidates: &[[f64; 3]],
    ) -> Option<cones::Tiled> {
        let lo = self.grid.point(cell[0], cell[1], cell[2]);
        let hi = self.grid.point(cell[0] + 1, cell[1] + 1, cell[2] + 1);
        let size = (0..3).map(|d| hi[d] - lo[d]).fold(f64::INFINITY, f64::min);
        let n = part.len();
        let mut pool: Vec<[f64; 3]> = candidates.to_vec();
        for (t, &d) in tris.iter().zip(degenerate) {
            if d {
                continue;
            }
            let nrm = check::cross(check::sub(t[1], t[0]), check::sub(t[2], t[0]));
            let len = check::dot(nrm, nrm).sqrt();
            for depth in [0.4, 0.25, 0.1, 0.04] {
                pool.push(std::array::from_fn(|k| {
                    let c = (t[0][k] + t[1][k] + t[2][k]) / 3.0;
                    f64::from((c - depth * size * nrm[k] / len) as f32)
                }));
            }
        }
        let seen_by: Vec<Vec<bool>> = pool
            .iter()
            .map(|&p| {
                (0..n)
                    .map(|i| cones::sees(&tris[i], degenerate[i], p))
                    .collect()
            })
            .collect();
        let mut covered = vec![false; n];
        let mut points: Vec<[f64; 3]> = Vec::new();
        while covered.iter().any(|&c| !c) {
            if points.len() >= 8 {
                return None;
            }
            let gain = |k: usize| (0..n).filter(|&i| !covered[i] && seen_by[k][i]).count();
            let best = (0..pool.len()).max_by_key(|&k| (gain(k), std::cmp::Reverse(k)))?;
            if gain(best) == 0 {
                return None;
            }
            for i in 0..n {
                covered[i] |= seen_by[best][i];
            }
            points.push(pool[best]);
        }
        // Spare points give the search room: the pool's others, those seeing most first.
        let mut spare: Vec<usize> = (0..pool.len()).collect();
        spare.sort_by_key(|&k| std::cmp::Reverse(seen_by[k].iter().filter(|&&x| x).count()));
        for k in spare {
            if points.len() >= 60 {
                break;
            }
            if !points.contains(&pool[k]) {
                points.push(pool[k]);
            }
        }
        let position = |v: u32| self.position(v).map(f64::from);
        let group = cones::assign(part, tris, degenerate, &points, &position)?;
        cones::tile(part, tris, degenerate, &points, &group, &position, None).ok()
    }

    /// Points to cone a part from, already rounded to the stored precision: its vertices'
    /// centroid, its grid corners' centroid, the cell's centre, and points between its corners
    /// and its centroid.
    fn candidates(&self, cell: [usize; 3], part: &[[u32; 3]]) -> Vec<[f64; 3]> {
        let mut vertices: Vec<u32> = part.iter().flatten().copied().collect();
        vertices.sort_unstable();
        vertices.dedup();
        let points: Vec<[f64; 3]> = vertices
            .iter()
            .map(|&v| self.position(v).map(f64::from))
            .collect();
        let mean = |pts: &[[f64; 3]]| {
            let n = pts.len() as f64;
            std::array::from_fn::<f64, 3, _>(|d| pts.iter().map(|p| p[d]).sum::<f64>() / n)
        };
        let mix = |a: [f64; 3], b: [f64; 3], t: f64| -> [f64; 3] {
            std::array::from_fn(|d| a[d] + t * (b[d] - a[d]))
        };
        let centroid = mean(&points);
        let corners: Vec<[f64; 3]> = vertices
            .iter()
            .filter(|&&v| v as usize >= self.base)
            .map(|&v| self.position(v).map(f64::from))
            .collect();
        let lo = self.grid.point(cell[0], cell[1], cell[2]);
        let hi = self.grid.point(cell[0] + 1, cell[1] + 1, cell[2] + 1);
        let centre: [f64; 3] = std::array::from_fn(|d| 0.5 * (lo[d] + hi[d]));
        let mut out = vec![centroid];
        if !corners.is_empty() {
            let c = mean(&corners);
            out.push(c);
            out.push(mix(c, centroid, 0.5));
        }
        out.push(centre);
        for &c in &corners {
            for t in [0.5, 0.75] {
                out.push(mix(c, centroid, t));
            }
        }
        for p in &points {
            out.push(mix(*p, centroid, 0.6));
        }
        out.into_iter()
            .map(|c| c.map(|x| f64::from(x as f32)))
            .collect()
    }

    fn face_triangles(
        &self,
        q: [usize; 3],
        n: usize,
        out: &mut Vec<[u32; 3]>,
        scratch: &mut face::Scratch,
    ) -> Result<(), &'static str> {
        face::triangles(self, q, n, out, scratch)
    }
}

/// A cone tetrahedron's angles scored ([`tet_score`]).
fn cone_quality(t: &[[f64; 3]; 3], apex: [f64; 3]) -> f64 {
    tet_score([t[0], t[2], t[1], apex])
}

/// A tetrahedron's angles scored: the worst of its smallest dihedral angle and its largest
/// one's supplement, scaled so that the goal's bounds, 10° and 165°, score alike.
fn tet_score(p: [[f64; 3]; 4]) -> f64 {
    let (lo, hi) = quality::dihedral_extremes(p);
    lo.min((180.0 - hi) * (10.0 / 15.0))
}

/// At most this many ears are cut off a part ([`Context::peeled`]).
const MAX_EARS: usize = 4;

/// A part's wedges thinner than this (degrees inside, between two boundary triangles) are cut
/// off as ears: a cone point would split them into two angles under [`GOOD_CONE`].
const THIN_WEDGE: f64 = 2.0 * GOOD_CONE;

/// The ear `[u, a, v, b]` (a positive tetrahedron) of the part's thinnest wedge under
/// [`THIN_WEDGE`]: boundary triangles `(u, v, a)` and `(v, u, b)` meeting at edge `uv`, each
/// edge used once each way.
fn thinnest_wedge(part: &[[u32; 3]], position: &dyn Fn(u32) -> [f64; 3]) -> Option<[u32; 4]> {
    let mut directed: HashMap<(u32, u32), (u32, usize)> = HashMap::default();
    for tri in part {
        for k in 0..3 {
            let e = directed
                .entry((tri[k], tri[(k + 1) % 3]))
                .or_insert((tri[(k + 2) % 3], 0));
            e.1 += 1;
        }
    }
    let mut best: Option<(f64, [u32; 4])> = None;
    for (&(u, v), &(a, count)) in &directed {
        let Some(&(b, back)) = directed.get(&(v, u)) else {
            continue;
        };
        if count != 1 || back != 1 || a == b || u > v {
            continue;
        }
        let [pu, pv, pa, pb] = [u, v, a, b].map(position);
        // The wedge's angle between the two triangles, inside when the ear is positive.
        let Some(angle) = check::angle_across(pu, pv, pa, pb) else {
            continue;
        };
        if angle < THIN_WEDGE
            && best.is_none_or(|(b, _)| angle < b)
            && check::positive(pu, pa, pv, pb)
        {
            best = Some((angle, [u, a, v, b]));
        }
    }
    best.map(|(_, ear)| ear)
}

/// Whether two of the part's vertices lie at one point.
fn shared_points(part: &[[u32; 3]], position: &dyn Fn(u32) -> [f64; 3]) -> bool {
    let mut vertices: Vec<u32> = part.iter().flatten().copied().collect();
    vertices.sort_unstable();
    vertices.dedup();
    let mut points: Vec<[u64; 3]> = vertices
        .iter()
        .map(|&v| position(v).map(f64::to_bits))
        .collect();
    points.sort_unstable();
    points.windows(2).any(|w| w[0] == w[1])
}

const CROSSED: &str =
    "the surface passes through itself in this cell, so it bounds no region here (`extract` keeps \
     snapped points off crossings where that would happen: please report the input)";

const FOLDED: &str =
    "no set of cone points found fills the cell's part of the region (a fold of the surface no cone reaches)";

/// How many times [`Context::fill`] may split a part in two ([`Context::split`]), and how many
/// splits it tries in all for one part of a cell (the search is exhaustive within them: a part
/// that no split fills costs the whole budget).
const SPLIT_DEPTH: u32 = 2;
const SPLIT_BUDGET: u32 = 600;
/// The splits tried for a part once [`SPLIT_BUDGET`] ran out.
const LAST_SPLIT_BUDGET: u32 = 20_000;

/// A cone point whose tetrahedra score this well ([`cone_quality`]) is kept without looking
/// further: beyond the goal's bounds with room to spare.
const GOOD_CONE: f64 = 12.0;

/// The closed parts of a cell's region boundary: triangles joined across their edges. An edge
/// used once each way joins its two triangles; an edge where the region is pinched (a fold of
/// the surface touching a face) is used by more, and each triangle is joined to the one next to
/// it, around the edge, on its inside. Fails when the edges do not pair up (an open boundary).
fn parts(
    boundary: &[[u32; 3]],
    position: &dyn Fn(u32) -> [f32; 3],
) -> Result<Vec<Vec<[u32; 3]>>, &'static str> {
    // (lower vertex, upper vertex, forward: the triangle runs lower → upper, triangle).
    let mut edges: Vec<(u32, u32, bool, u32)> = boundary
        .iter()
        .enumerate()
        .flat_map(|(t, tri)| {
            (0..3).map(move |k| {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                (a.min(b), a.max(b), a < b, t as u32)
            })
        })
        .collect();
    edges.sort_unstable();
    let mut parent: Vec<u32> = (0..boundary.len() as u32).collect();
    fn find(parent: &mut [u32], mut x: u32) -> u32 {
        while parent[x as usize] != x {
            parent[x as usize] = parent[parent[x as usize] as usize];
            x = parent[x as usize];
        }
        x
    }
    let union = |parent: &mut Vec<u32>, x: u32, y: u32| {
        let (rx, ry) = (find(parent, x), find(parent, y));
        parent[rx as usize] = ry;
    };
    let mut i = 0;
    while i < edges.len() {
        let (a, b) = (edges[i].0, edges[i].1);
        let mut j = i;
        while j < edges.len() && (edges[j].0, edges[j].1) == (a, b) {
            j += 1;
        }
        let group = &edges[i..j];
        let forward = group.iter().filter(|e| e.2).count();
        if forward * 2 != group.len() {
            return Err("the cell's region is not closed");
        }
        if group.len() == 2 {
            union(&mut parent, group[0].3, group[1].3);
        } else {
            // Around the edge a → b, by angle: a triangle running a → b has its outward normal
            // toward larger angles, so its inside neighbour is the next one below it.
            let pa = position(a).map(f64::from);
            let d = check::sub(position(b).map(f64::from), pa);
            let helper = if d[0].abs() <= d[1].abs() && d[0].abs() <= d[2].abs() {
                [1.0, 0.0, 0.0]
            } else if d[1].abs() <= d[2].abs() {
                [0.0, 1.0, 0.0]
            } else {
                [0.0, 0.0, 1.0]
            };
            let e1 = check::cross(d, helper);
            let e2 = check::cross(d, e1);
            let mut around: Vec<(f64, bool, u32)> = group
                .iter()
                .map(|&(_, _, fwd, t)| {
                    let tri = boundary[t as usize];
                    let c = tri
                        .into_iter()
                        .find(|&v| v != a && v != b)
                        .expect("a triangle");
                    let w = check::sub(position(c).map(f64::from), pa);
                    let angle = check::dot(w, e2).atan2(check::dot(w, e1));
                    (angle, fwd, t)
                })
                .collect();
            around.sort_by(|x, y| x.0.total_cmp(&y.0));
            let m = around.len();
            for k in 0..m {
                if around[k].1 {
                    let below = around[(k + m - 1) % m];
                    if below.1 {
                        return Err("the region's triangles around an edge do not alternate");
                    }
                    union(&mut parent, around[k].2, below.2);
                }
            }
        }
        i = j;
    }
    let mut groups: Vec<(u32, usize)> = (0..boundary.len())
        .map(|t| (find(&mut parent, t as u32), t))
        .collect();
    groups.sort_unstable();
    let mut out: Vec<Vec<[u32; 3]>> = Vec::new();
    let mut last = u32::MAX;
    for (root, t) in groups {
        if root != last {
            out.push(Vec::new());
            last = root;
        }
        out.last_mut().expect("pushed").push(boundary[t]);
    }
    // Parts in the order of their first triangle, so the Steiner points' order is fixed.
    out.sort_by_key(|p| p[0]);
    Ok(out)
}

#[cfg(test)]
mod tests;
