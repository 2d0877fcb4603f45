//! Multi-material volume meshes of labelled images: every label's region in tetrahedra, the
//! interfaces between labels shared face to face.
//!
//! [`crate::extract::extract_labels`] bounds each label by the dual cells of its grid points in
//! the Kuhn triangulation of the grid (padded by one layer of outside points): the interface is
//! made of triangles (edge midpoint, face centroid, tetrahedron centroid) across the edges whose
//! ends differ. The volume mesh fills those dual cells:
//! - a Kuhn tetrahedron whose four corners carry one label is kept whole;
//! - any other is coned from its centroid over its four faces, each face a fan from its
//!   centroid around its corners and the midpoints of its edges whose ends differ (a face whose
//!   three corners agree stays whole). Each small tetrahedron holds exactly one grid point's
//!   share and takes its label.
//!
//! Faces and edges are cut by what their own corners carry, so neighbouring tetrahedra agree and
//! the mesh is conforming; two small tetrahedra of different labels meet exactly on the
//! interface triangles, and the boundary against the unmeshed labels (the background, the
//! outside) is exactly the labels' surfaces there. No point is added beyond the surfaces'
//! vertices and the grid points.
//!
//! Graded ([`LabelOptions::grading`]): the cells whose eight corners carry one meshed label
//! are filled with their six Kuhn tetrahedra whole, so away from the interfaces they are
//! gathered into cubes as a one-region mesh's whole cells are ([`super::graded`]); cells
//! sharing a corner share its label, so a cube holds one label, and its faces towards the
//! cells cut by interfaces are those cells' Kuhn triangles.

use rayon::prelude::*;
use rustc_hash::FxHashMap as HashMap;

use super::{check, graded::Cubes, TetError, TetMesh, TetStats};
use crate::extract::{
    label_slabs, KeyKind, LabelOptions, LabelSelection, Labelled, VertexKey, KUHN_PATHS,
};
use crate::field::GridView;

/// Which label each tetrahedron and boundary triangle of a multi-material mesh belongs to.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct TetLabels {
    /// The labels meshed, in increasing order.
    pub names: Vec<i64>,
    /// Each tetrahedron's label (an index into [`TetLabels::names`]).
    pub tets: Vec<u32>,
    /// The label each of [`TetMesh::surface`]'s triangles bounds (facing out of it).
    pub surface: Vec<u32>,
    /// Triangles where two meshed labels meet (interior faces of the mesh), each facing out of
    /// the first label of its pair.
    pub interfaces: Vec<[u32; 3]>,
    /// The labels on either side of each interface triangle (indices into
    /// [`TetLabels::names`], lower first).
    pub pairs: Vec<[u32; 2]>,
}

/// Meshes every selected label of a labelled grid with tetrahedra: one region per label,
/// conforming across the interfaces (see the module documentation). The boundary of each
/// label's tetrahedra is the surface [`crate::extract::extract_labels`] makes with the same
/// options — which must have no smoothing: smoothed vertices leave the dual cells. A mesh
/// estimated to need more than `max_memory` bytes is refused before it is made.
///
/// ```
/// use isocube::extract::LabelOptions;
/// use isocube::field::Grid;
/// use isocube::volume::tetmesh_labels;
/// // Two touching boxes, labels 1 and 2, in background 0.
/// let values = (0..96)
///     .map(|p| {
///         let (i, j, k) = (p % 6, p / 6 % 4, p / 24);
///         let inside = (1..3).contains(&j) && (1..3).contains(&k);
///         match i { 1 | 2 if inside => 1.0, 3 | 4 if inside => 2.0, _ => 0.0 }
///     })
///     .collect();
/// let grid = Grid::new([6, 4, 4], values).unwrap();
/// let options = LabelOptions::default().with_smoothing(0);
/// let mesh = tetmesh_labels(&grid, &options, None).unwrap();
/// let labels = mesh.labels.as_ref().unwrap();
/// assert_eq!(labels.names, [1, 2]);
/// let check = mesh.check();
/// assert!(check.conforming && check.inverted == 0 && check.flat == 0);
/// assert!(!labels.interfaces.is_empty());
/// ```
pub fn tetmesh_labels<'a>(
    grid: impl Into<GridView<'a>>,
    options: &LabelOptions,
    max_memory: Option<u64>,
) -> Result<TetMesh, TetError> {
    let grid = grid.into();
    if options.smoothing > 0 {
        return Err(TetError::Unsupported(
            "a labelled volume mesh keeps the labels' unsmoothed surfaces (smoothing 0): \
             smoothed vertices leave the cells the tetrahedra fill",
        ));
    }
    let labelled = Labelled::new(grid, options)?;
    let mut keys = Vec::new();
    let (surface, tags) = labelled.surfaces(&label_slabs(grid.dims())?, Some(&mut keys))?;
    let by_key: HashMap<VertexKey, u32> = keys
        .iter()
        .enumerate()
        .map(|(v, &k)| (k, v as u32))
        .collect();
    if let LabelSelection::Only(list) = &options.labels {
        if let Some(&label) = list.iter().find(|l| !labelled.names.contains(l)) {
            return Err(TetError::NoLabel(label));
        }
    }
    let meshed: Vec<u32> = (1..=labelled.names.len() as u32)
        .filter(|&id| labelled.meshed(id))
        .collect();
    if meshed.is_empty() {
        return Err(TetError::Empty);
    }
    // Label indices in increasing label order.
    let mut order = meshed.clone();
    order.sort_by_key(|&id| labelled.names[id as usize - 1]);
    let mut index = vec![u32::MAX; labelled.names.len() + 1];
    for (i, &id) in order.iter().enumerate() {
        index[id as usize] = i as u32;
    }

    // Grid points of meshed labels, numbered after the surface's vertices.
    let base = surface.positions.len();
    let [px, py, pz] = labelled.dims;
    let mut rank = vec![u32::MAX; px * py * pz];
    let mut positions = surface.positions.clone();
    for (p, &id) in labelled.padded.iter().enumerate() {
        if labelled.meshed(id) {
            rank[p] = positions.len() as u32;
            positions.push(labelled.position(p).map(|c| c as f32));
        }
    }
    if positions.len() >= u32::MAX as usize {
        return Err(TetError::TooManyVertices);
    }
    // Six tetrahedra per grid point and about two per surface triangle (measured: 1.2 on blobs
    // and packed spheres).
    let estimate = 6 * (positions.len() - base) + 2 * surface.triangles.len();
    // Each tetrahedron with its label; the positions; the surfaces.
    let needs = |tets: usize| {
        tets as u64 * 20 + positions.len() as u64 * 12 + surface.triangles.len() as u64 * 16
    };
    // Graded: the cells of one meshed label gathered into cubes, on cells whose transition
    // cubes keep their angles.
    let cell_dims = [px - 1, py - 1, pz - 1];
    let grading = options.grading.on_cells(grid.spacing());
    if let Some(limit) = max_memory.filter(|_| grading.max_level == 0) {
        let bytes = needs(estimate);
        if bytes > limit {
            return Err(TetError::Memory { bytes, limit });
        }
    }
    let cubes = (grading.max_level > 0).then(|| {
        let whole: Vec<bool> = (0..cell_dims[0] * cell_dims[1] * cell_dims[2])
            .into_par_iter()
            .map(|c| {
                let [i, j, k] = super::coords(c, cell_dims);
                let base = i + px * (j + py * k);
                let first = labelled.padded[base];
                labelled.meshed(first)
                    && (1..8).all(|b| labelled.padded[labelled.corner(base, b)] == first)
            })
            .collect();
        Cubes::new(cell_dims, grid.spacing(), whole, grading)
    });
    if let (Some(cubes), Some(limit)) = (&cubes, max_memory) {
        let bytes = needs(cubes.element_estimate(estimate));
        if bytes > limit {
            return Err(TetError::Memory { bytes, limit });
        }
    }
    let ctx = Context {
        labelled: &labelled,
        by_key: &by_key,
        rank: &rank,
        index: &index,
        positions: &positions,
        cubes: cubes.as_ref(),
    };
    // Room reserved as estimated (not touched): the vectors seldom move.
    let mut tets = Vec::with_capacity(if cubes.is_some() { 0 } else { estimate });
    let mut tet_labels = Vec::with_capacity(tets.capacity());
    let mut graded = [0usize; 3];
    super::in_batches(
        pz - 1,
        |k| ctx.layer(k),
        |_| Ok(()),
        |layer| {
            tets.extend(layer.tets);
            tet_labels.extend(layer.labels);
            graded[0] += layer.cubes;
            graded[1] = graded[1].max(layer.largest_cube);
            graded[2] += layer.cube_tets;
            Ok(())
        },
    )?;
    drop(cubes);

    // Surface triangles: a triangle both of whose sides are meshed labels is an interface
    // (it comes twice, once facing out of each); the others bound the mesh.
    let mut sorted: Vec<([u32; 3], usize)> = surface
        .triangles
        .iter()
        .enumerate()
        .map(|(t, tri)| {
            let mut key = *tri;
            key.sort_unstable();
            (key, t)
        })
        .collect();
    sorted.par_sort_unstable();
    let mut boundary = Vec::new();
    let mut boundary_labels = Vec::new();
    let mut interfaces = Vec::new();
    let mut pairs = Vec::new();
    let mut i = 0;
    while i < sorted.len() {
        let (key, t) = sorted[i];
        if sorted.get(i + 1).is_some_and(|n| n.0 == key) {
            let u = sorted[i + 1].1;
            let (a, b) = (index[tags[t] as usize], index[tags[u] as usize]);
            let (first, second, tri) = if a < b {
                (a, b, surface.triangles[t])
            } else {
                (b, a, surface.triangles[u])
            };
            interfaces.push(tri);
            pairs.push([first, second]);
            i += 2;
        } else {
            boundary.push(surface.triangles[t]);
            boundary_labels.push(index[tags[t] as usize]);
            i += 1;
        }
    }
    let grid_end = positions.len() as u32;
    let improve = super::improve::improve(
        &mut positions,
        &mut tets,
        Some(&mut tet_labels),
        base as u32..grid_end,
        grid_end..grid_end,
    );
    let mut stats = TetStats {
        grid_points: grid_end as usize - base - improve.removed_grid,
        steiner_points: improve.inserted - improve.removed,
        cubes: graded[0],
        largest_cube: graded[1],
        cube_tets: graded[2],
        cells_too_long: options.grading.max_level > 0 && grading.max_level == 0,
        improve,
        ..TetStats::default()
    };
    if grading.max_level > 0 {
        // The grid points strictly inside cubes (but the centres coned from) are in no
        // element: dropped, the later points numbered down.
        let unused = check::unused_points(positions.len(), &tets, base as u32);
        stats.grid_points -= unused.len();
        check::drop_points(&mut positions, &mut tets, &mut Vec::new(), &unused);
    }
    let mut mesh = TetMesh {
        positions,
        tets,
        surface: boundary,
        walls: Vec::new(),
        beyond: Vec::new(),
        surface_vertices: base,
        stats,
        labels: Some(TetLabels {
            names: order
                .iter()
                .map(|&id| labelled.names[id as usize - 1])
                .collect(),
            tets: tet_labels,
            surface: boundary_labels,
            interfaces,
            pairs,
        }),
    };
    mesh.orient(&grid);
    Ok(mesh)
}

struct Context<'a, 'b> {
    labelled: &'a Labelled<'b>,
    by_key: &'a HashMap<VertexKey, u32>,
    /// Meshed grid points' vertex numbers (padded numbering; `u32::MAX` elsewhere).
    rank: &'a [u32],
    /// Label index by dense label number (`u32::MAX` for labels not meshed).
    index: &'a [u32],
    positions: &'a [[f32; 3]],
    /// Graded meshes: the cubes the cells of one label are gathered into.
    cubes: Option<&'a Cubes>,
}

/// A layer of cells' tetrahedra and their labels, with the cubes met there.
struct Layer {
    tets: Vec<[u32; 4]>,
    labels: Vec<u32>,
    cubes: usize,
    largest_cube: usize,
    cube_tets: usize,
}

impl Context<'_, '_> {
    /// The surface's vertex at the centroid of a simplex of padded points.
    fn vertex(&self, simplex: &[usize]) -> Result<u32, TetError> {
        let key = self.labelled.key(simplex);
        debug_assert!(matches!(key.kind(), KeyKind::Simplex { .. }));
        self.by_key.get(&key).copied().ok_or(TetError::Unsupported(
            "a labelled interface vertex is missing from the surfaces (a bug: please report the input)",
        ))
    }

    /// Appends the tetrahedron positively oriented (exact predicate).
    fn push(
        &self,
        t: [u32; 4],
        label: u32,
        out: &mut (Vec<[u32; 4]>, Vec<u32>),
    ) -> Result<(), TetError> {
        let p = t.map(|v| self.positions[v as usize].map(f64::from));
        let t = if check::positive(p[0], p[1], p[2], p[3]) {
            t
        } else if check::positive(p[0], p[2], p[1], p[3]) {
            [t[0], t[2], t[1], t[3]]
        } else {
            return Err(TetError::Unsupported(
                "a labelled tetrahedron is flat at the stored precision",
            ));
        };
        out.0.push(t);
        out.1.push(label);
        Ok(())
    }

    fn layer(&self, k: usize) -> Result<Layer, TetError> {
        let l = self.labelled;
        let [px, py, _] = l.dims;
        let mut out = (Vec::new(), Vec::new());
        let (mut cubes, mut largest_cube, mut cube_tets) = (0, 0, 0);
        let id = |p: [usize; 3]| self.rank[p[0] + px * (p[1] + py * p[2])];
        let mut cube_out = (Vec::new(), Vec::new());
        for j in 0..py - 1 {
            for i in 0..px - 1 {
                let base = i + px * (j + py * k);
                if let Some(c) = self.cubes {
                    let level = c.level([i, j, k]);
                    if level > 0 {
                        // Emitted once, at the cube's first cell.
                        let mask = (1usize << level) - 1;
                        if i & mask == 0 && j & mask == 0 && k & mask == 0 {
                            let label = self.index[l.padded[base] as usize];
                            cube_out.0.clear();
                            c.cube([i, j, k], level, &id, &mut cube_out.0, &mut cube_out.1);
                            debug_assert!(
                                cube_out.1.is_empty(),
                                "the padding keeps cubes off the walls"
                            );
                            cubes += 1;
                            largest_cube = largest_cube.max(1 << level);
                            cube_tets += cube_out.0.len();
                            for &t in &cube_out.0 {
                                self.push(t, label, &mut out)?;
                            }
                        }
                        continue;
                    }
                }
                for path in KUHN_PATHS {
                    let pts = path.map(|b| l.corner(base, b));
                    let lab = pts.map(|p| l.padded[p]);
                    if !lab.iter().any(|&d| l.meshed(d)) {
                        continue;
                    }
                    if lab.iter().all(|&d| d == lab[0]) {
                        self.push(
                            pts.map(|p| self.rank[p]),
                            self.index[lab[0] as usize],
                            &mut out,
                        )?;
                        continue;
                    }
                    let centre = self.vertex(&pts)?;
                    for skip in 0..4 {
                        let face: Vec<usize> = (0..4).filter(|&c| c != skip).collect();
                        let fl = face.iter().map(|&c| lab[c]).collect::<Vec<_>>();
                        if fl.iter().all(|&d| d == fl[0]) {
                            if l.meshed(fl[0]) {
                                let [a, b, c] = [0, 1, 2].map(|x| self.rank[pts[face[x]]]);
                                self.push([a, b, c, centre], self.index[fl[0] as usize], &mut out)?;
                            }
                            continue;
                        }
                        if !fl.iter().any(|&d| l.meshed(d)) {
                            continue;
                        }
                        let fp: Vec<usize> = face.iter().map(|&c| pts[c]).collect();
                        let f = self.vertex(&fp)?;
                        // Around the face: each corner, then its edge's midpoint to the next
                        // corner when their labels differ.
                        for x in 0..3 {
                            let (a, b) = (face[x], face[(x + 1) % 3]);
                            let own = |c: usize| -> Option<(u32, u32)> {
                                l.meshed(lab[c])
                                    .then(|| (self.rank[pts[c]], self.index[lab[c] as usize]))
                            };
                            if lab[a] == lab[b] {
                                if let Some((va, label)) = own(a) {
                                    self.push([va, self.rank[pts[b]], f, centre], label, &mut out)?;
                                }
                            } else if own(a).is_some() || own(b).is_some() {
                                let m = self.vertex(&[pts[a], pts[b]])?;
                                if let Some((va, label)) = own(a) {
                                    self.push([va, m, f, centre], label, &mut out)?;
                                }
                                if let Some((vb, label)) = own(b) {
                                    self.push([m, vb, f, centre], label, &mut out)?;
                                }
                            }
                        }
                    }
                }
            }
        }
        Ok(Layer {
            tets: out.0,
            labels: out.1,
            cubes,
            largest_cube,
            cube_tets,
        })
    }
}
