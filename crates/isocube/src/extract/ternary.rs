//! Ternary (extended) Marching Cubes: grid points on or near the level become surface vertices.
//!
//! # Model
//! A *zero* grid point is one the surface passes through. Extraction is Marching Cubes on the
//! field `g` that equals the input except at zero points, where it equals the level exactly;
//! every crossing on an edge that ends at a zero point is that point (the limit of the
//! crossing as the value reaches the level). Triangles that lose a corner this way vanish. So a
//! ternary cell's polygons are the binary polygons of `g` (zero counts as above, the library's
//! tie rule) with crossings collapsed onto zero corners, which is what
//! [`crate::cube::TernaryTable`] lists for all 6561 configurations. Face consistency is inherited
//! from the binary table: both cells sharing a face collapse the same segments the same way.
//!
//! A *lone tie*, a point exactly at the level none of whose six neighbours is above it, only
//! touches the level: the tie rule would make MC33 wrap it in a closed surface of zero size, which
//! no snapping can remove without changing the topology. Such points (with points below around)
//! are first moved below the level, halfway to the highest of those (see
//! `settle_lone_ties`), so the mesh has the topology of MC33 on the settled field.
//!
//! # Choosing zero points, keeping the topology
//! Candidates are points with `|value − level| ≤ zero_threshold` (Tokunaga's ε) and points that a
//! crossing on one of their six edges lies within `snap` of, as a fraction of the edge (Raman and
//! Wenger's SnapMC distance `D`). Each candidate is accepted only if making it zero leaves the
//! mesh a manifold with the same topology: the eight cells around the point are meshed before and
//! after, and the change is accepted when, in the after-patch,
//! - every edge inside the 2×2×2 block of cells is used by 0 or 2 triangles with opposite
//!   directions (once on the grid boundary), and edges on the block's boundary faces are used
//!   exactly as before (or dropped, when the block alone used them both ways), so the rest of
//!   the mesh still fits;
//! - every vertex's triangles form one fan (a disk, or a half-disk on the grid boundary), and
//!   vertices on the block's boundary keep the ends of their fans that continue outside;
//! - the triangles form components with the same Euler characteristics and the same interface
//!   edges (boundary-face edges used once) as before, and no triangle repeats or has zero area.
//!
//! The outside of the block does not change, so each accepted step keeps the global mesh a
//! manifold with the same components and Euler characteristic; starting from MC33, so does the
//! result. Points are decided closest crossing first, in rounds of 1/20 of an edge, and within a
//! round by coordinate parity class: points of one class are two apart and their blocks share no
//! cell, so decisions within a class do not depend on each other's order (room for parallel
//! work). Refused points keep their sign; their crossings are kept at least [`MIN_OFFSET`] of an
//! edge away from the grid point so that no triangle collapses to zero area.
//!
//! Most of these checks repeat: away from the grid's boundary, when no cell of the block has an
//! ambiguous face or a tunnel to choose (before or after), the patches are a function of the
//! below / above / zero pattern of the block's 27 points. The first check of a pattern records
//! the combinatorial verdict and the new triangles by local position; later points with that
//! pattern only place those triangles' corners and test their areas. Tests (debug assertions)
//! re-run the full check on every reuse.
//!
//! # Placing zero points, keeping the surface off itself
//! A zero point's vertex goes onto its nearest crossing (or its grid point: [`SnapPosition`]).
//! On a crossing it leaves four of its eight cells, whose triangles then reach into their
//! neighbours, where they could pass through the surface; the pairs that could are tested
//! exactly, and the points whose vertices make one cross stay on their grid points (see
//! `Ternary::untangle_snaps`). The triangles keep their vertices' keys, so the topology stands.
//!
//! Finally, inside each cell, a diagonal between two triangles is flipped where that raises the
//! smaller of their smallest angles; new diagonals join corners that share no face of the cell,
//! so no neighbour can ever use the same edge, and flips never change the topology.

use rayon::prelude::*;
use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};
use std::ops::ControlFlow;

use crate::cube::triangulate::{may_join_on, safe_triangulation, star, ALL_FACES};
use crate::cube::{CaseTable, Corner, Topology, EDGES, EDGE_AXIS};
use std::borrow::Cow;

use super::window::Window;
use crate::field::{is_above, GridView};
use crate::quality::{triangulate, Strategy};

use super::chunk::{CellBox, ChunkMesh, VertexKey};
use super::classify::{cell_config, face_decisions};
use super::place::{centroid_in, interior_bounds, Bounds, Placer};
use super::untangle::{crosses, mend, number_locally};
use super::{choose_tunnel, ExtractError, ExtractOptions};

/// The smallest distance, as a fraction of the edge, between a crossing that was not snapped and
/// the ends of its edge.
pub const MIN_OFFSET: f64 = 1e-3;

/// A point on the grid's outer face whose crossing along the face's normal lies within this
/// fraction of the edge (and within the snap distance) is snapped too, its vertex kept on the
/// grid point: the surface grazes the wall there, and left off it, the sliver of region between
/// the two is thinner than any element could be good in. The vertex is then off the level set by
/// at most this fraction of an edge (the crossing is that close), and only there. At 0.1, films
/// 0.1–0.2 of an edge thick between packed spheres and the box's faces still held elements down
/// to 5°; 0.2 leaves the pores in range (`pores_of_packed_spheres_at_48_stay_within_the_range`).
pub const WALL_SNAP: f64 = 0.2;

/// How many rounds [`Ternary::untangle_snaps`] runs at most; each looks at the cells within
/// [`UNTANGLE_REACH`] points of the last round's changes.
pub(super) const UNTANGLE_ROUNDS: usize = 6;
/// How far one untangling round's decisions read, in points.
pub(super) const UNTANGLE_REACH: usize = 4;

/// How ternary extraction picks the grid points the surface passes through.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub struct Snapping {
    /// Values with `|value − level| ≤ zero_threshold` count as zero (the extended-MC paper's ε).
    pub zero_threshold: f32,
    /// A grid point is snapped when a crossing on one of its edges lies within this fraction of
    /// the edge (SnapMC's `D`, `0 ≤ snap ≤ 0.5`).
    pub snap: f32,
    /// Where a snapped point's vertex goes.
    pub position: SnapPosition,
}

/// Where the vertex of a snapped grid point is placed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SnapPosition {
    /// On the grid point itself: every snapped vertex is a grid point.
    GridPoint,
    /// On the nearest crossing among the point's six edges (the grid point itself when its
    /// value is within the zero threshold): the mesh keeps Marching Cubes' accuracy while the
    /// short edges and needles around the point are gone. A point on the grid's outer face is
    /// placed only on crossings within that face, so the surface's rim stays on the grid's
    /// faces (and a volume mesh's walls stay flat); one snapped for a crossing along the face's
    /// normal (within [`WALL_SNAP`]) stays on its grid point, and so does one whose vertex on
    /// the crossing would make the surface pass through itself.
    #[default]
    NearestCrossing,
}

impl SnapPosition {
    /// The name used on the command line: `grid` or `crossing`.
    pub fn name(self) -> &'static str {
        match self {
            SnapPosition::GridPoint => "grid",
            SnapPosition::NearestCrossing => "crossing",
        }
    }
}

impl std::str::FromStr for SnapPosition {
    type Err = crate::ParseError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "grid" => Ok(SnapPosition::GridPoint),
            "crossing" => Ok(SnapPosition::NearestCrossing),
            _ => Err(crate::ParseError::new(
                "snap position",
                s,
                format!("unknown snap position '{s}': expected grid or crossing"),
            )),
        }
    }
}

impl Default for Snapping {
    /// `zero_threshold` 0 (exact ties only), `snap` 0.3, vertices on the nearest crossing.
    fn default() -> Self {
        Snapping {
            zero_threshold: 0.0,
            snap: 0.3,
            position: SnapPosition::default(),
        }
    }
}

impl Snapping {
    /// Sets [`Snapping::snap`].
    pub fn with_snap(mut self, snap: f32) -> Snapping {
        self.snap = snap;
        self
    }

    /// Sets [`Snapping::zero_threshold`].
    pub fn with_zero_threshold(mut self, zero_threshold: f32) -> Snapping {
        self.zero_threshold = zero_threshold;
        self
    }

    /// Sets [`Snapping::position`].
    pub fn with_position(mut self, position: SnapPosition) -> Snapping {
        self.position = position;
        self
    }

    pub(super) fn validate(&self) -> Result<(), ExtractError> {
        if !(self.zero_threshold >= 0.0 && self.zero_threshold.is_finite()) {
            return Err(ExtractError::Option {
                name: "zero threshold",
                range: "a finite number ≥ 0",
                value: self.zero_threshold,
            });
        }
        if !(0.0..=0.5).contains(&self.snap) {
            return Err(ExtractError::Option {
                name: "snap distance",
                range: "between 0 and 0.5",
                value: self.snap,
            });
        }
        Ok(())
    }
}

// Keys name patch vertices independently of cells: a crossing by its grid edge, a zero point by
// its index, an interior point by its cell and number; they are the bits of the engine's
// `VertexKey`s.
type Key = u64;
use super::chunk::{CROSSING as EDGE, INTERIOR, PAYLOAD, POINT, TAG_SHIFT};

fn tag(k: Key) -> u64 {
    k >> TAG_SHIFT
}

/// Patch triangles plus, for each interior point used, the corners it belongs to and where it
/// sits: at their centroid, or at a position a triangulation strategy chose.
#[derive(Default)]
struct Patch {
    triangles: Vec<[Key; 3]>,
    interiors: Vec<Interior>,
    /// Scratch space for the checks.
    keys: Vec<Key>,
    /// Scratch space for [`Ternary::improve_cell`]: the cell's vertices placed, and the
    /// triangles' measures.
    placed: Vec<(Key, [f64; 3])>,
    measured: Vec<Option<(f64, [f64; 3])>>,
    scratch: super::patch_check::Scratch,
}

/// A triangle of a cell as [`Ternary::untangle_snaps`] tests it: its keys, positions, the
/// pokes of its corners (as [`Ternary::poke`]) and those corners, and whether it has no area.
#[derive(Clone)]
struct Gathered {
    keys: [Key; 3],
    at: [[f64; 3]; 3],
    mask: u8,
    flat: bool,
    corners: [Option<usize>; 3],
}

/// The cells [`Ternary::untangle_snaps`] emitted last, in a ring of [`UNTANGLE_CACHE`].
#[derive(Default)]
struct Emitted {
    cells: Vec<usize>,
    triangles: Vec<Vec<Gathered>>,
    next: usize,
    patch: Patch,
}

const UNTANGLE_CACHE: usize = 48;

struct Interior {
    key: Key,
    support: Vec<Key>,
    at: Option<[f64; 3]>,
}

impl Patch {
    fn clear(&mut self) {
        self.triangles.clear();
        self.interiors.clear();
    }
}

pub(super) struct Ternary<'a> {
    /// The grid's geometry (its values may lie in any order).
    grid: GridView<'a>,
    level: f32,
    topology: Topology,
    /// The values, `x` fastest (borrowed when the grid is stored so): point `p` is `values[p]`.
    values: Cow<'a, [f32]>,
    /// The input's values where lone ties were settled in `values` (else `None`): the normals'
    /// gradients read these, so that normals do not change where a tie was settled.
    input: Option<Cow<'a, [f32]>>,
    /// Zero points, one bit each: the field `g` is the level there and `values` elsewhere.
    zero: Vec<u64>,
    /// Zero points whose vertex stays on the grid point although a crossing was chosen for it:
    /// there, the surface would pass through itself (see [`Ternary::untangle_snaps`]).
    on_grid: Vec<u64>,
    /// Sign masks of `g` (zero points are above).
    masks: super::binary::Masks,
    snapping: Snapping,
    strategy: Strategy,
    offsets: [usize; 8],
    strides: [usize; 3],
}

impl<'a> Ternary<'a> {
    pub(super) fn new(
        grid: GridView<'a>,
        options: &ExtractOptions,
        snapping: Snapping,
    ) -> Ternary<'a> {
        let [nx, ny, _] = grid.dims();
        let (sy, sz) = (nx, nx * ny);
        // Snapping reads points by their number over and over: a grid stored in another order
        // is gathered once.
        let mut values = grid.x_fastest();
        let input = settle_lone_ties(&mut values, grid.dims(), options.level);
        Ternary {
            grid,
            level: options.level,
            topology: options.topology,
            zero: vec![0; values.len().div_ceil(64)],
            on_grid: vec![0; values.len().div_ceil(64)],
            masks: super::binary::Masks::new_parallel(&values, grid.dims(), options.level),
            values,
            input,
            snapping,
            strategy: options.triangulation,
            offsets: [0, 1, 1 + sy, sy, sz, 1 + sz, 1 + sy + sz, sy + sz],
            strides: [1, sy, sz],
        }
    }

    /// The input's values as the binary mesher's window reads them (`x` fastest), for the
    /// placer: positions from the crossings chosen here, normals from the input's gradient.
    pub(super) fn window(&self) -> Window<'_> {
        let g = &self.grid;
        Window::new(
            g.dims(),
            g.spacing(),
            g.origin(),
            g.heights(),
            0,
            self.input.as_deref().unwrap_or(&self.values),
        )
        .with_base(g.base())
    }

    /// Number of point `(i, j, k)`: its place in [`Ternary::values`].
    #[inline]
    fn index(&self, i: usize, j: usize, k: usize) -> usize {
        let [nx, ny, _] = self.grid.dims();
        i + nx * (j + ny * k)
    }

    fn coords(&self, p: usize) -> [usize; 3] {
        let [nx, ny, _] = self.grid.dims();
        [p % nx, p / nx % ny, p / (nx * ny)]
    }

    /// Decides the zero points. Returns (snapped, refused) counts.
    pub(super) fn choose_zeros(
        &mut self,
        check: &mut dyn FnMut() -> ControlFlow<()>,
    ) -> Result<(usize, usize), ExtractError> {
        self.choose_zeros_in_groups(true, check)
    }

    /// [`Ternary::choose_zeros`], checking independent points together (`grouped`) or strictly
    /// one after the other (the reference the grouping must reproduce).
    /// `check` is asked between stretches of the work (a plane batch, a sort, a pass of the
    /// groups), so that a stop is honoured within a fraction of the whole:
    /// [`ExtractError::Cancelled`].
    pub(super) fn choose_zeros_in_groups(
        &mut self,
        grouped: bool,
        check: &mut dyn FnMut() -> ControlFlow<()>,
    ) -> Result<(usize, usize), ExtractError> {
        let counts = self.decide_zeros(grouped, check)?;
        self.untangle_snaps(check)?;
        Ok(counts)
    }

    fn decide_zeros(
        &mut self,
        grouped: bool,
        check: &mut dyn FnMut() -> ControlFlow<()>,
    ) -> Result<(usize, usize), ExtractError> {
        let mut stop = || match check() {
            ControlFlow::Continue(()) => Ok(()),
            ControlFlow::Break(()) => Err(ExtractError::Cancelled),
        };
        let snapping = self.snapping;
        let values: &[f32] = &self.values;
        let level = f64::from(self.level);
        let dims = self.grid.dims();
        // Candidates from one pass over the grid edges, a plane at a time in parallel (the list
        // is sorted next, so its order does not matter). Points are taken closest crossing
        // first, in rounds of 1/20 of an edge: a point's round is that of its nearest crossing,
        // the smallest round of its crossings. Each is packed `point << 4 | round` so that
        // sorting integers groups a point's entries, smallest round first.
        let threshold = f64::from(snapping.zero_threshold);
        let snap = f64::from(snapping.snap);
        let [nx, ny, nz] = dims;
        let strides = self.strides;
        let masks = &self.masks;
        let round = |t: f64| (t * 20.0).floor().min(10.0) as u64;
        // Planes in some 32 batches, each in parallel, the check between them.
        let batch = nz.div_ceil(32).max(2 * rayon::current_num_threads());
        let mut planes: Vec<Vec<u64>> = Vec::with_capacity(nz);
        for first in (0..nz).step_by(batch) {
            stop()?;
            planes.par_extend((first..(first + batch).min(nz)).into_par_iter().map(|k| {
                let mut near = Vec::new();
                for j in 0..ny {
                    let row = nx * (j + ny * k);
                    if threshold > 0.0 || values[row..row + nx].contains(&self.level) {
                        for (i, &v) in values[row..row + nx].iter().enumerate() {
                            if (f64::from(v) - level).abs() <= threshold {
                                near.push(((row + i) as u64) << 4);
                            }
                        }
                    }
                    if snap <= 0.0 {
                        continue;
                    }
                    // Edges whose ends disagree, from the sign masks (a point that is not
                    // finite counts as below there, and is skipped below).
                    let here = masks.above(j, k, ny);
                    let along = |axis: usize, w: usize| -> u64 {
                        match axis {
                            0 => {
                                let next = here.get(w + 1).map_or(0, |n| n << 63);
                                // Edges start at points 0..nx − 1.
                                let keep = (nx - 1).saturating_sub(w * 64);
                                let keep = if keep >= 64 { !0 } else { (1u64 << keep) - 1 };
                                (here[w] ^ (here[w] >> 1 | next)) & keep
                            }
                            1 if j + 1 < ny => here[w] ^ masks.above(j + 1, k, ny)[w],
                            2 if k + 1 < nz => here[w] ^ masks.above(j, k + 1, ny)[w],
                            _ => 0,
                        }
                    };
                    for (axis, &stride) in strides.iter().enumerate() {
                        for w in 0..masks.words {
                            let mut bits = along(axis, w);
                            while bits != 0 {
                                let p = row + w * 64 + bits.trailing_zeros() as usize;
                                bits &= bits - 1;
                                let q = p + stride;
                                let (a, b) = (f64::from(values[p]), f64::from(values[q]));
                                if !a.is_finite() || !b.is_finite() {
                                    continue;
                                }
                                let t = (level - a) / (b - a);
                                // A point on the grid's outer face is not carried off it
                                // along the face's normal (see `snapped_place_at`).
                                let (first, last) = match axis {
                                    _ if snapping.position == SnapPosition::GridPoint => {
                                        (false, false)
                                    }
                                    0 => (p == row, p + 2 == row + nx),
                                    1 => (j == 0, j + 2 == ny),
                                    _ => (k == 0, k + 2 == nz),
                                };
                                let wall = snap.min(WALL_SNAP);
                                if t <= snap && (!first || t <= wall) {
                                    near.push((p as u64) << 4 | round(t));
                                }
                                // A crossing exactly halfway is the first end's to take (see
                                // `snapped_place_at`).
                                if 1.0 - t <= snap && (!last || 1.0 - t <= wall) && t != 0.5 {
                                    near.push((q as u64) << 4 | round(1.0 - t));
                                }
                            }
                        }
                    }
                }
                near
            }));
        }
        stop()?;
        let mut near: Vec<u64> = planes.concat();
        drop(planes);
        near.par_sort_unstable();
        stop()?;
        near.dedup_by_key(|e| *e >> 4);
        // Then by round, by parity class, and by point: `round << 59 | class << 56 | point`
        // (points number fewer than 2^56: no grid that large fits in memory).
        // The class by the whole grid's coordinates: a block of a larger grid (a chunk meshed
        // on its own) decides in the larger grid's order.
        let base = self.grid.base();
        let mut order: Vec<u64> = near
            .into_iter()
            .map(|e| {
                let p = (e >> 4) as usize;
                debug_assert!(p < 1 << 56);
                let c = self.coords(p);
                let c = [0, 1, 2].map(|a| c[a] + base[a]);
                let class = (c[0] & 1 | (c[1] & 1) << 1 | (c[2] & 1) << 2) as u64;
                (e & 15) << 59 | class << 56 | p as u64
            })
            .collect();
        order.par_sort_unstable();
        stop()?;
        // A point's check reads only the cells around it (points at most one step away), and
        // two points of one parity class are two steps apart along some axis: within a
        // (round, class) group the checks are independent, so each group is checked in
        // parallel and then applied — the same choices as one point after the other.
        let neighbourhoods = Neighbourhoods::default();
        if !grouped {
            let (mut snapped, mut refused) = (0, 0);
            for member in order.chunks(1) {
                let (s, r) = self.snap_batch(member, &neighbourhoods);
                snapped += s;
                refused += r;
            }
            return Ok((snapped, refused));
        }
        let mut groups: Vec<std::ops::Range<usize>> = Vec::new();
        for (i, e) in order.iter().enumerate() {
            match groups.last_mut() {
                Some(g) if order[g.start] >> 56 == e >> 56 => g.end = i + 1,
                _ => groups.push(i..i + 1),
            }
        }
        // Group after group, each sweeping the whole grid, the checks would fetch the same
        // neighbourhoods from memory once per group. Instead the groups advance together,
        // plane by plane, each a plane behind the one before: group `g` takes the planes up to
        // `pass · SLAB − g` in pass `pass`. When a point of plane `z` is checked, every earlier
        // group has passed `z + 1` and no later group has reached `z − 1`, so it sees exactly
        // the choices it would see group after group — and the neighbourhoods are still in
        // cache from the groups before.
        const SLAB: usize = 32;
        let plane = nx * ny;
        let plane_of = move |p: usize| p / plane;
        let (mut snapped, mut refused) = (0, 0);
        for pass in 1.. {
            stop()?;
            let mut left = false;
            for (g, range) in groups.iter_mut().enumerate() {
                let Some(limit) = (pass * SLAB).checked_sub(g) else {
                    left |= range.start < range.end;
                    continue;
                };
                let members = &order[range.clone()];
                let take = members.partition_point(|&e| plane_of(point_of(e)) <= limit);
                if take > 0 {
                    let (s, r) = self.snap_batch(&members[..take], &neighbourhoods);
                    snapped += s;
                    refused += r;
                    range.start += take;
                }
                left |= range.start < range.end;
            }
            if !left {
                break;
            }
        }
        Ok((snapped, refused))
    }

    /// Checks independent candidates `members` (see [`Ternary::choose_zeros_in_groups`]) in
    /// parallel and makes the safe ones zero points. Returns (snapped, refused) counts.
    fn snap_batch(&mut self, members: &[u64], neighbourhoods: &Neighbourhoods) -> (usize, usize) {
        let verdicts: Vec<bool> = members
            .par_iter()
            .enumerate()
            .with_min_len(8)
            .map_init(
                || (Patch::default(), Patch::default()),
                |(before, after), (i, &e)| {
                    let p = point_of(e);
                    // The values around the next points are fetched while this one is checked:
                    // one point after another, the check waits on memory more than it computes.
                    if let Some(&q) = members.get(i + 2) {
                        self.prefetch_around(point_of(q));
                    }
                    self.snap_is_safe(p, before, after, neighbourhoods)
                },
            )
            .collect();
        let (mut snapped, mut refused) = (0, 0);
        let ny = self.grid.dims()[1];
        for (&e, ok) in members.iter().zip(verdicts) {
            let p = point_of(e);
            if ok {
                self.zero[p / 64] |= 1 << (p % 64);
                self.masks.set_above(self.coords(p), ny);
                snapped += 1;
            } else {
                refused += 1;
            }
        }
        (snapped, refused)
    }

    /// Keeps on their grid points the snapped points whose vertices, carried onto a crossing,
    /// would make the surface pass through itself. Returns how many.
    ///
    /// The snapping checks decide which triangles join which vertices; where a vertex goes is a
    /// second question. A vertex on a crossing lies on an edge of its point, inside the four
    /// cells around the point that hold that edge and outside the other four: their triangles
    /// through it *poke* into the cells beside them. Every other triangle lies in its closed
    /// cell, and two cells' triangles meet there only in the segments of their common face
    /// (both draw the same). So two triangles cross only where one of them pokes, inside a cell
    /// both reach: each cell gathers its own triangles and those poking into it from its 26
    /// neighbours, and every pair with a poking one is tested exactly. The poking corners of a
    /// pair that crosses go back to their grid points, inside all their cells (the triangles
    /// keep their keys, so the topology the checks decided stands), and the cells near them are
    /// looked at again, for [`UNTANGLE_ROUNDS`] rounds at most. Everything is decided from the
    /// zero points and positions alone, in rounds of independent cells: a block with its halo
    /// decides its own cells as the whole grid does.
    fn untangle_snaps(
        &mut self,
        check: &mut dyn FnMut() -> ControlFlow<()>,
    ) -> Result<usize, ExtractError> {
        if self.snapping.position == SnapPosition::GridPoint {
            return Ok(0);
        }
        let dims = self.grid.dims();
        if dims.iter().any(|&d| d < 2) {
            return Ok(0);
        }
        // Snapped points carried onto a crossing: `(point, poke bit)`, the bit as
        // [`Ternary::poke`] gives it for the cells that do not hold the edge.
        let mut displaced: Vec<(usize, u8)> = (0..self.zero.len())
            .into_par_iter()
            .flat_map_iter(|w| {
                let mut bits = self.zero[w];
                std::iter::from_fn(move || {
                    let b = bits.trailing_zeros() as usize;
                    (bits != 0).then(|| {
                        bits &= bits - 1;
                        w * 64 + b
                    })
                })
            })
            .filter_map(|p| {
                let c = self.coords(p);
                let (c0, axis, t) = self.snapped_place_at(p, c);
                (t != 0.0).then(|| (p, 1 << (2 * axis + usize::from(c0 == c))))
            })
            .collect();
        let cell_of = move |c: [usize; 3]| c[0] + dims[0] * (c[1] + dims[1] * c[2]);
        // After a round, the cells to look at again (those whose triangles may have moved:
        // within two of a point put back), and the carried points whose pokes reach them.
        let mut near: Option<Vec<usize>> = None;
        let mut active: Vec<(usize, u8)> = Vec::new();
        let mut kept = 0;
        for _ in 0..UNTANGLE_ROUNDS {
            if check().is_break() {
                return Err(ExtractError::Cancelled);
            }
            let carried = if near.is_some() { &active } else { &displaced };
            // The cells each carried point pokes out of (the four around it on the far side of
            // its edge), with their poke bits merged.
            let mut pokers: Vec<(usize, u8)> = carried
                .par_iter()
                .flat_map_iter(|&(p, bit)| {
                    let c = self.coords(p);
                    let axis = bit.trailing_zeros() as usize / 2;
                    let forward = bit.trailing_zeros() % 2 == 1;
                    let range = move |a: usize| {
                        if a == axis {
                            let x = if forward {
                                c[a].checked_sub(1)
                            } else {
                                Some(c[a])
                            };
                            x.filter(|&x| x + 1 < dims[a]).map_or(0..0, |x| x..x + 1)
                        } else {
                            c[a].saturating_sub(1)..c[a].min(dims[a] - 2) + 1
                        }
                    };
                    range(2).flat_map(move |k| {
                        range(1).flat_map(move |j| range(0).map(move |i| (cell_of([i, j, k]), bit)))
                    })
                })
                .collect();
            pokers.par_sort_unstable();
            pokers.dedup_by(|b, a| {
                let same = a.0 == b.0;
                if same {
                    a.1 |= b.1;
                }
                same
            });
            // `(host, source)`: a cell and a neighbour (or itself) whose pokes may reach it.
            let mut pairs: Vec<(usize, usize)> = pokers
                .par_iter()
                .flat_map_iter(|&(cell, mask)| {
                    let c = self.coords(cell);
                    let steps = move |a: usize| {
                        let mut s = [0isize; 3];
                        let mut n = 1;
                        for (bit, step) in [(0, -1), (1, 1)] {
                            if mask >> (2 * a + bit) & 1 != 0 {
                                s[n] = step;
                                n += 1;
                            }
                        }
                        (s, n)
                    };
                    let (sx, sy, sz) = (steps(0), steps(1), steps(2));
                    let mut out = Vec::with_capacity(sx.1 * sy.1 * sz.1);
                    for &oz in &sz.0[..sz.1] {
                        for &oy in &sy.0[..sy.1] {
                            for &ox in &sx.0[..sx.1] {
                                let o = [ox, oy, oz];
                                let h: Option<Vec<usize>> = (0..3)
                                    .map(|a| {
                                        c[a].checked_add_signed(o[a]).filter(|&x| x + 1 < dims[a])
                                    })
                                    .collect();
                                if let Some(h) = h {
                                    out.push((cell_of([h[0], h[1], h[2]]), cell));
                                }
                            }
                        }
                    }
                    out
                })
                .collect();
            if let Some(near) = &near {
                pairs.retain(|(h, _)| near.binary_search(h).is_ok());
            }
            if check().is_break() {
                return Err(ExtractError::Cancelled);
            }
            pairs.par_sort_unstable();
            let groups: Vec<&[(usize, usize)]> = pairs.chunk_by(|a, b| a.0 == b.0).collect();
            // In some 32 batches, the stop asked between them.
            let mut found: Vec<usize> = Vec::new();
            for batch in groups.chunks(groups.len().div_ceil(32).max(1024)) {
                if check().is_break() {
                    return Err(ExtractError::Cancelled);
                }
                found.par_extend(
                    batch
                        .par_iter()
                        .with_min_len(16)
                        .map_init(Emitted::default, |cache, group| {
                            let sources: Vec<usize> = group.iter().map(|e| e.1).collect();
                            self.crossings_at(group[0].0, &sources, cache)
                        })
                        .flatten_iter(),
                );
            }
            found.par_sort_unstable();
            found.dedup();
            if found.is_empty() {
                break;
            }
            let mut next = Vec::with_capacity(64 * found.len());
            for &p in &found {
                self.on_grid[p / 64] |= 1 << (p % 64);
                let c = self.coords(p);
                let range = |a: usize| c[a].saturating_sub(2)..=(c[a] + 1).min(dims[a] - 2);
                for k in range(2) {
                    for j in range(1) {
                        for i in range(0) {
                            next.push(cell_of([i, j, k]));
                        }
                    }
                }
            }
            next.par_sort_unstable();
            next.dedup();
            near = Some(next);
            displaced.retain(|&(p, _)| self.on_grid[p / 64] >> (p % 64) & 1 == 0);
            // A point pokes into cells within one of the four it pokes out of, so within two of
            // it; a cell to look at is within two of a point put back: points within three of
            // those are all that matter next round (`found` and `displaced` are sorted).
            let within = |a: [usize; 3], b: [usize; 3]| (0..3).all(|d| a[d].abs_diff(b[d]) <= 3);
            active = displaced
                .par_iter()
                .copied()
                .filter(|&(p, _)| {
                    let c = self.coords(p);
                    // Points sorted by index are sorted by `z` first: look at those in reach.
                    let lo = found.partition_point(|&f| self.coords(f)[2] + 3 < c[2]);
                    found[lo..]
                        .iter()
                        .take_while(|&&f| self.coords(f)[2] <= c[2] + 3)
                        .any(|&f| within(self.coords(f), c))
                })
                .collect();
            kept += found.len();
        }
        Ok(kept)
    }

    /// The corners of cell `cell` that poke out of it: bit `2 · axis + forward` for a vertex
    /// carried along `axis` (forward: to higher coordinates) onto an edge the cell does not hold.
    fn poke(&self, cell: [usize; 3], p: usize, c: [usize; 3]) -> u8 {
        if !self.zero_point(p) {
            return 0;
        }
        let (c0, axis, t) = self.snapped_place_at(p, c);
        if t == 0.0 {
            return 0;
        }
        let forward = c0 == c;
        let inside = if forward {
            c[axis] == cell[axis]
        } else {
            c[axis] == cell[axis] + 1
        };
        if inside {
            0
        } else {
            1 << (2 * axis + usize::from(forward))
        }
    }

    /// The triangles of cell `n` with their positions and pokes, from `cache` when it was
    /// emitted lately (the hosts come in order, and neighbours share most of their sources).
    fn emitted<'c>(&self, n: usize, cache: &'c mut Emitted) -> &'c [Gathered] {
        if let Some(i) = cache.cells.iter().position(|&c| c == n) {
            return &cache.triangles[i];
        }
        let slot = cache.next % UNTANGLE_CACHE;
        cache.next += 1;
        if cache.cells.len() <= slot {
            cache.cells.push(n);
            cache.triangles.push(Vec::new());
        }
        cache.cells[slot] = n;
        let out = &mut cache.triangles[slot];
        out.clear();
        let patch = &mut cache.patch;
        patch.clear();
        self.emit(n, None, patch, true);
        if patch.triangles.is_empty() {
            return out;
        }
        let nc = self.coords(n);
        // The cell's corners that poke, each asked once.
        let mut pokes = [(usize::MAX, 0u8); 8];
        for (slot, &off) in pokes.iter_mut().zip(&self.offsets) {
            let p = n + off;
            if self.zero_point(p) {
                *slot = (p, self.poke(nc, p, self.coords(p)));
            }
        }
        for t in &patch.triangles {
            let mut corners = [None; 3];
            let mut mask = 0u8;
            for (slot, &k) in corners.iter_mut().zip(t) {
                if tag(k) == POINT {
                    let p = (k & PAYLOAD) as usize;
                    let m = pokes.iter().find(|e| e.0 == p).map_or(0, |e| e.1);
                    if m != 0 {
                        *slot = Some(p);
                        mask |= m;
                    }
                }
            }
            let at = t.map(|k| self.position(k, &patch.interiors).map(f64::from));
            out.push(Gathered {
                keys: *t,
                at,
                mask,
                flat: crate::mesh::intersect::collinear(at),
                corners,
            });
        }
        out
    }

    /// The poking corners of each pair of crossing triangles among those in cell `h`: its own
    /// and those of `sources` (itself or neighbours) that poke into it (see
    /// [`Ternary::untangle_snaps`]), poking corners repeated.
    fn crossings_at(&self, h: usize, sources: &[usize], cache: &mut Emitted) -> Vec<usize> {
        let hc = self.coords(h);
        let mut gathered: Vec<Gathered> = Vec::new();
        // Two triangles of one cell are tested in that cell, which is a host of its own when
        // it pokes: a host with no triangles tests only pairs from two neighbours.
        let foreign = sources.iter().filter(|&&n| n != h).count();
        if foreign < 2 && self.emitted(h, cache).is_empty() {
            return Vec::new();
        }
        let own = std::iter::once(h).chain(sources.iter().copied().filter(|&n| n != h));
        for n in own {
            let nc = self.coords(n);
            let o: [isize; 3] = std::array::from_fn(|a| hc[a] as isize - nc[a] as isize);
            let reaches = |mask: u8| {
                (0..3).all(|a| match o[a] {
                    0 => true,
                    s => mask >> (2 * a + usize::from(s > 0)) & 1 != 0,
                })
            };
            gathered.extend(
                self.emitted(n, cache)
                    .iter()
                    .filter(|g| !g.flat && reaches(g.mask))
                    .cloned(),
            );
        }
        if gathered.iter().all(|g| g.mask == 0) {
            return Vec::new();
        }
        let ids: Vec<Key> = {
            let mut all: Vec<Key> = gathered.iter().flat_map(|g| g.keys).collect();
            all.sort_unstable();
            all.dedup();
            all
        };
        let id = |k: Key| ids.binary_search(&k).expect("gathered") as u32;
        let with_ids = |g: &Gathered| [0, 1, 2].map(|v| (id(g.keys[v]), g.at[v]));
        let mut found = Vec::new();
        for (i, a) in gathered.iter().enumerate() {
            for b in &gathered[i + 1..] {
                if (a.mask | b.mask) != 0
                    && crate::mesh::intersect::triangles_cross(with_ids(a), with_ids(b))
                {
                    found.extend(a.corners.iter().chain(&b.corners).flatten());
                }
            }
        }
        found
    }

    /// Asks the processor to fetch what a check of `p` reads first: the values of the nine rows
    /// through its 3 × 3 neighbourhood and of the rows two steps away along `y` and `z`, and
    /// the sign and zero bits of the nine rows.
    #[inline]
    fn prefetch_around(&self, p: usize) {
        #[cfg(target_arch = "x86_64")]
        {
            fn fetch<T>(x: Option<&T>) {
                if let Some(x) = x {
                    // SAFETY: a prefetch is a hint: it reads nothing and cannot fault, and the
                    // pointer is to an element of a slice.
                    unsafe {
                        std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(
                            (x as *const T).cast(),
                        )
                    };
                }
            }
            let [_, sy, sz] = self.strides;
            let [i, j, k] = self.coords(p);
            let ny = self.grid.dims()[1];
            for (dy, dz) in [
                (-1, -1),
                (0, -1),
                (1, -1),
                (-1, 0),
                (0, 0),
                (1, 0),
                (-1, 1),
                (0, 1),
                (1, 1),
            ] {
                let (Some(jj), Some(kk)) = (j.checked_add_signed(dy), k.checked_add_signed(dz))
                else {
                    continue;
                };
                let Some(q) = (p + jj * sy + kk * sz).checked_sub(j * sy + k * sz + 1) else {
                    continue;
                };
                fetch(self.values.get(q));
                fetch(self.zero.get(q / 64));
                fetch(self.masks.word(i.saturating_sub(1), jj, kk, ny));
            }
            for q in [
                p.checked_sub(2 * sy),
                Some(p + 2 * sy),
                p.checked_sub(2 * sz),
                Some(p + 2 * sz),
            ] {
                fetch(q.and_then(|q| self.values.get(q)));
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        let _ = p;
    }

    /// The value extraction uses at point `p` (the input's, or below the level for a lone tie:
    /// see [`settle_lone_ties`]).
    #[inline]
    pub(super) fn value_at(&self, p: usize) -> f32 {
        self.values[p]
    }

    /// Whether `p` was chosen as a zero point.
    #[inline]
    pub(super) fn zero_point(&self, p: usize) -> bool {
        self.zero[p / 64] >> (p % 64) & 1 != 0
    }

    /// The value of `g` at `p`.
    #[inline]
    fn g(&self, p: usize) -> f32 {
        if self.zero_point(p) {
            self.level
        } else {
            self.values[p]
        }
    }

    fn value(&self, p: usize, over: Option<usize>) -> f32 {
        if over == Some(p) {
            self.level
        } else {
            self.g(p)
        }
    }

    fn is_zero(&self, p: usize, over: Option<usize>) -> bool {
        over == Some(p) || self.zero_point(p)
    }

    /// Appends the triangles of cell `cell` (its first grid point) to `patch`, with point `over`
    /// treated as zero. `last` for the mesh itself, not a snapping check: then a tunnel that
    /// would cross itself is mended and the triangles improved by flips. (The checks compare
    /// how triangles share vertices and edges, which a mended tunnel keeps: a tube between
    /// the same loops. Mending each tunnel cell of every check made noisy data a half slower.)
    /// Returns whether the cell's interior opened a tunnel.
    fn emit(&self, base: usize, over: Option<usize>, patch: &mut Patch, last: bool) -> bool {
        let flips = last;
        let pts = self.offsets.map(|o| base + o);
        let v = pts.map(|p| self.value(p, over));
        if v.iter().any(|x| !x.is_finite()) {
            return false;
        }
        let config = cell_config(&v, self.level);
        if config == 0 || config == 255 {
            return false;
        }
        let table = CaseTable::binary();
        let decisions = face_decisions(&v, self.level, table.ambiguous_faces(config));
        let tunnel =
            if self.topology == Topology::Mc33 && table.has_tunnel_candidates(config, decisions) {
                choose_tunnel(table, config, decisions, &v, self.level)
            } else {
                None
            };
        let key = |c: Corner| -> Key {
            if let Some(e) = c.as_edge() {
                let [a, b] = EDGES[usize::from(e)].map(|x| pts[usize::from(x)]);
                if self.is_zero(a, over) {
                    POINT << TAG_SHIFT | a as u64
                } else if self.is_zero(b, over) {
                    POINT << TAG_SHIFT | b as u64
                } else {
                    EDGE << TAG_SHIFT | (a * 3 + usize::from(EDGE_AXIS[usize::from(e)])) as u64
                }
            } else {
                let k = c
                    .as_interior()
                    .expect("binary cells have edge and interior corners");
                INTERIOR << TAG_SHIFT | (base * 8 + usize::from(k)) as u64
            }
        };
        let first = patch.triangles.len();
        if flips && self.strategy != Strategy::Fan && tunnel.is_none() {
            for (l, polygon) in table.polygons(config, decisions).enumerate() {
                self.emit_polygon(base, l, polygon, &key, patch);
            }
            self.face_diagonals(first, over, patch);
            self.improve_cell(base, first, patch);
            return false;
        }
        let cell = table.cell_triangles(config, decisions, self.topology, tunnel);
        let mended = tunnel.filter(|_| last).and_then(|t| {
            let loops = table.tunnel_loops(config, decisions, t);
            let position = |c: Corner| self.position(key(c), &[]).map(f64::from);
            // Corners collapsed onto one zero point are one vertex.
            let mut first_of: Vec<(Key, Corner)> = Vec::new();
            for &d in cell.triangles.iter().flatten() {
                let k = key(d);
                if d.as_edge().is_some() && first_of.iter().all(|e| e.0 != k) {
                    first_of.push((k, d));
                }
            }
            let same = |c: Corner| match c.as_edge() {
                Some(_) => first_of.iter().find(|e| e.0 == key(c)).map_or(c, |e| e.1),
                None => c,
            };
            // The snapping checks validated the table's triangles collapsed; a band collapsed
            // otherwise could pinch, so it must bound the same as they do.
            let keys = |tris: &[[Corner; 3]]| -> Vec<[Key; 3]> {
                let all = tris.iter().map(|t| t.map(key));
                all.filter(|k| k[0] != k[1] && k[1] != k[2] && k[0] != k[2])
                    .collect()
            };
            let faces = self.cell_faces(base);
            let table_keys = keys(cell.triangles);
            let accept = |t: &[[Corner; 3]]| same_surface(&table_keys, &keys(t), &faces);
            let bounds = self.interior_bounds(base);
            let m = mend(&cell, loops, &position, &same, &accept, &bounds)?;
            Some((m, [loops.0, loops.1].concat()))
        });
        let triangles = mended
            .as_ref()
            .map_or(cell.triangles, |(m, _)| &m.triangles[..]);
        let mut used = [false; Corner::MAX_INTERIOR];
        for t in triangles {
            let k = t.map(key);
            if k[0] == k[1] || k[1] == k[2] || k[0] == k[2] {
                continue;
            }
            for c in t {
                if let Some(i) = c.as_interior() {
                    used[usize::from(i)] = true;
                }
            }
            patch.triangles.push(k);
        }
        for (i, _) in used.iter().enumerate().filter(|(_, u)| **u) {
            let (support, at) = match &mended {
                // Mended points take their normals from the loops'.
                Some((m, loops)) => {
                    let mut support: Vec<Key> = loops.iter().map(|&c| key(c)).collect();
                    support.sort_unstable();
                    support.dedup();
                    (support, Some(m.interiors[i]))
                }
                None => (
                    cell.interior_support(i).iter().map(|&c| key(c)).collect(),
                    None,
                ),
            };
            patch.interiors.push(Interior {
                key: key(Corner::interior(i as u8)),
                support,
                at,
            });
        }
        self.face_diagonals(first, over, patch);
        if flips {
            // Flips in a tunnel's tube can make it pass through itself: kept only if not.
            let table_triangles = tunnel.map(|_| patch.triangles[first..].to_vec());
            self.improve_cell(base, first, patch);
            if let Some(before) = table_triangles {
                if self.crosses(&patch.triangles[first..], &patch.interiors) {
                    patch.triangles.truncate(first);
                    patch.triangles.extend(before);
                }
            }
        }
        tunnel.is_some()
    }

    /// Whether triangles of a cell cross each other (none of no area) where they are placed.
    fn crosses(&self, triangles: &[[Key; 3]], interiors: &[Interior]) -> bool {
        let (keys, local) = number_locally(triangles.iter().copied());
        let positions: Vec<[f64; 3]> = keys
            .iter()
            .map(|&k| self.position(k, interiors).map(f64::from))
            .collect();
        crosses(&local, &positions)
    }

    /// Makes every diagonal of a face of four zero points that the cell's triangles use the one
    /// through the face's lowest point, by flipping the other where two of the cell's
    /// triangles share it. The cell on the other side of the face may use that diagonal too (or
    /// cover the face: a sheet of zero thickness when both sides lie below the level), and the
    /// tables of the two cells, each collapsing its own configuration, need not agree: two
    /// surface edges would cross in the face.
    fn face_diagonals(&self, first: usize, over: Option<usize>, patch: &mut Patch) {
        let n = patch.triangles.len();
        for i in first..n {
            for e in 0..3 {
                let ti = patch.triangles[i];
                let (a, c, b) = (ti[e], ti[(e + 1) % 3], ti[(e + 2) % 3]);
                if tag(a) != POINT || tag(c) != POINT || !self.off_canonical(a, c, over) {
                    continue;
                }
                // The triangle on the other side of a → c, in this cell.
                let Some((j, d)) = (first..n).filter(|&j| j != i).find_map(|j| {
                    let tj = patch.triangles[j];
                    (0..3)
                        .find(|&f| tj[f] == c && tj[(f + 1) % 3] == a)
                        .map(|f| (j, tj[(f + 2) % 3]))
                }) else {
                    continue;
                };
                let has_edge = patch.triangles[first..n].iter().any(|t| {
                    (0..3).any(|k| {
                        t[k] == b && t[(k + 1) % 3] == d || t[k] == d && t[(k + 1) % 3] == b
                    })
                });
                if b == d || has_edge {
                    continue;
                }
                // The quad runs c → b → a → d; the other diagonal is b–d.
                patch.triangles[i] = [c, b, d];
                patch.triangles[j] = [b, a, d];
            }
        }
    }

    /// Whether zero points `a` and `c` are opposite corners of a cell face whose four points
    /// are all zero, and the face's lowest point is not one of them.
    fn off_canonical(&self, a: Key, c: Key, over: Option<usize>) -> bool {
        let (pa, pc) = ((a & PAYLOAD) as usize, (c & PAYLOAD) as usize);
        let (xa, xc) = (self.coords(pa), self.coords(pc));
        let apart: Vec<usize> = (0..3).filter(|&d| xa[d] != xc[d]).collect();
        if apart.len() != 2 || apart.iter().any(|&d| xa[d].abs_diff(xc[d]) != 1) {
            return false;
        }
        let corner = |d: usize| {
            if xc[d] > xa[d] {
                pa + self.strides[d]
            } else {
                pa - self.strides[d]
            }
        };
        let (pb, pd) = (corner(apart[0]), corner(apart[1]));
        self.is_zero(pb, over) && self.is_zero(pd, over) && pb.min(pd) < pa.min(pc)
    }

    /// One loop of a cell by the triangulation strategy, after collapse onto zero points. A loop
    /// that stays simple is re-triangulated (diagonals only between corners sharing no face of
    /// the cell, or around an interior vertex): a disk with the same boundary as the triangulation
    /// the local check validated, so the topology is the same. A loop that pinches or that the
    /// strategy cannot split keeps the table's triangulation, collapsed.
    fn emit_polygon(
        &self,
        base: usize,
        l: usize,
        polygon: &[Corner],
        key: &dyn Fn(Corner) -> Key,
        patch: &mut Patch,
    ) {
        let mut keys: Vec<Key> = polygon.iter().map(|&c| key(c)).collect();
        keys.dedup();
        while keys.len() > 1 && keys.first() == keys.last() {
            keys.pop();
        }
        if keys.len() < 3 {
            return;
        }
        let mut sorted = keys.clone();
        sorted.sort_unstable();
        let simple = sorted.windows(2).all(|w| w[0] != w[1]);
        let interior_key = INTERIOR << TAG_SHIFT | (base * 8 + 4 + l) as u64;
        if simple {
            let faces = self.cell_faces(base);
            let masks: Vec<u8> = keys.iter().map(|&k| faces(k)).collect();
            let positions: Vec<[f64; 3]> = keys
                .iter()
                .map(|&k| self.position(k, &patch.interiors).map(f64::from))
                .collect();
            let c = self.coords(base);
            let cube = (
                self.grid.point(c[0], c[1], c[2]),
                self.grid.point(c[0] + 1, c[1] + 1, c[2] + 1),
            );
            let allowed = |a: usize, b: usize| may_join_on(masks[a] & masks[b], ALL_FACES);
            // An interior point the search pushes onto a face of the cell (where the
            // triangles are best) has its spokes in the face, where the cell across may draw
            // edges too, and they could cross: then it is sought again off the faces. On the
            // face as stored (`f32`): a point a rounding away from the face lands on it, and on
            // the grid's outer face a volume mesh's wall would pass through it.
            let on_face = |x: [f64; 3]| {
                (0..3).any(|d| {
                    let s = x[d] as f32;
                    s == cube.0[d] as f32 || s == cube.1[d] as f32
                })
            };
            let found = match triangulate(&positions, &allowed, self.strategy, cube) {
                Some(r) if r.interior.is_some_and(on_face) => {
                    let inside = self.interior_bounds(base);
                    triangulate(&positions, &allowed, self.strategy, inside)
                }
                found => found,
            };
            if let Some(result) = found {
                if let Some(x) = result.interior {
                    patch.interiors.push(Interior {
                        key: interior_key,
                        support: keys.clone(),
                        at: Some(x),
                    });
                }
                for t in result.triangles {
                    patch
                        .triangles
                        .push(t.map(|i| keys.get(usize::from(i)).copied().unwrap_or(interior_key)));
                }
                return;
            }
        }
        // Exactly the table's triangulation of this loop, which the local check validated.
        let star_from = match self.topology {
            Topology::Mc33 => CaseTable::MC33_STAR_CORNERS,
            Topology::Classic => usize::MAX,
        };
        let table_triangles = (polygon.len() < star_from)
            .then(|| safe_triangulation(polygon))
            .flatten()
            .unwrap_or_else(|| star(polygon));
        let mut centre_used = false;
        for t in table_triangles {
            let k = t.map(|c| {
                if c.as_interior().is_some() {
                    interior_key
                } else {
                    key(c)
                }
            });
            if k[0] == k[1] || k[1] == k[2] || k[0] == k[2] {
                continue;
            }
            centre_used |= k.contains(&interior_key);
            patch.triangles.push(k);
        }
        if centre_used {
            patch.interiors.push(Interior {
                key: interior_key,
                support: polygon.iter().map(|&c| key(c)).collect(),
                at: None,
            });
        }
    }

    /// Flips diagonals between the cell's triangles `first..` where that raises the smaller of the
    /// two triangles' smallest angles. Only diagonals strictly inside the cell (endpoints sharing
    /// no face of the cell) are created, so no other cell can ever use the same edge, and a flip
    /// is taken only when both new triangles face the same way as the pair they replace.
    fn improve_cell(&self, base: usize, first: usize, patch: &mut Patch) {
        let n = patch.triangles.len() - first;
        if n < 2 {
            return;
        }
        let faces = self.cell_faces(base);
        // Each vertex placed once, when a measure first needs it: the sweeps below look at
        // every triangle pair several times, and many cells have no pair that may flip.
        let mut placed = std::mem::take(&mut patch.placed);
        placed.clear();
        let interiors = &patch.interiors;
        let pos = |placed: &mut Vec<(Key, [f64; 3])>, k: Key| match placed.iter().find(|e| e.0 == k)
        {
            Some(e) => e.1,
            None => {
                let x = self.position(k, interiors).map(f64::from);
                placed.push((k, x));
                x
            }
        };
        // The largest cosine of a triangle's angles stands for its smallest angle.
        let max_cos = |placed: &mut Vec<(Key, [f64; 3])>, t: [Key; 3]| -> (f64, [f64; 3]) {
            let p = t.map(|k| pos(placed, k));
            let n = crate::mesh::cross(crate::mesh::sub(p[1], p[0]), crate::mesh::sub(p[2], p[0]));
            let mut worst = f64::NEG_INFINITY;
            for k in 0..3 {
                let a = crate::mesh::sub(p[(k + 1) % 3], p[k]);
                let b = crate::mesh::sub(p[(k + 2) % 3], p[k]);
                let norm = (crate::mesh::dot(a, a) * crate::mesh::dot(b, b)).sqrt();
                worst = worst.max(crate::mesh::dot(a, b) / norm);
            }
            (worst, n)
        };
        // Each triangle's measure is kept until a flip replaces the triangle: the sweeps meet
        // every pair again, and most triangles are never flipped.
        let mut measured = std::mem::take(&mut patch.measured);
        measured.clear();
        measured.resize(n, None);
        // A few sweeps settle every cell met in practice; the bound keeps the cost fixed.
        for _ in 0..3 {
            let mut flipped = false;
            for i in first..patch.triangles.len() {
                for j in i + 1..patch.triangles.len() {
                    let (t1, t2) = (patch.triangles[i], patch.triangles[j]);
                    let Some(k) = (0..3).find(|&k| {
                        let (a, b) = (t1[k], t1[(k + 1) % 3]);
                        (0..3).any(|m| t2[m] == b && t2[(m + 1) % 3] == a)
                    }) else {
                        continue;
                    };
                    let (a, b, c) = (t1[k], t1[(k + 1) % 3], t1[(k + 2) % 3]);
                    let d = *t2.iter().find(|&&x| x != a && x != b).expect("a triangle");
                    if c == d || faces(c) & faces(d) != 0 {
                        continue;
                    }
                    let exists = patch.triangles[first..].iter().any(|t| {
                        (0..3).any(|m| {
                            let (x, y) = (t[m], t[(m + 1) % 3]);
                            (x, y) == (c, d) || (x, y) == (d, c)
                        })
                    });
                    if exists {
                        continue;
                    }
                    let (o1, n1) =
                        *measured[i - first].get_or_insert_with(|| max_cos(&mut placed, t1));
                    let (o2, n2) =
                        *measured[j - first].get_or_insert_with(|| max_cos(&mut placed, t2));
                    let (new1, new2) = ([c, a, d], [d, b, c]);
                    let (m1, q1) = max_cos(&mut placed, new1);
                    let (m2, q2) = max_cos(&mut placed, new2);
                    let normal = [0, 1, 2].map(|x| n1[x] + n2[x]);
                    if m1.max(m2) < o1.max(o2) - 1e-12
                        && crate::mesh::dot(q1, normal) > 0.0
                        && crate::mesh::dot(q2, normal) > 0.0
                    {
                        patch.triangles[i] = new1;
                        patch.triangles[j] = new2;
                        measured[i - first] = Some((m1, q1));
                        measured[j - first] = Some((m2, q2));
                        flipped = true;
                    }
                }
            }
            if !flipped {
                break;
            }
        }
        patch.placed = placed;
        patch.measured = measured;
    }

    /// The cells around grid point `p`, by their first grid point.
    fn star(&self, p: usize) -> impl Iterator<Item = usize> + '_ {
        let c = self.coords(p);
        let dims = self.grid.dims();
        let range = move |a: usize| c[a].saturating_sub(1)..c[a].min(dims[a] - 2) + 1;
        range(2).flat_map(move |k| {
            range(1).flat_map(move |j| {
                range(0)
                    .map(move |i| i * self.strides[0] + j * self.strides[1] + k * self.strides[2])
            })
        })
    }

    /// The faces of the cell at `base` a key lies on, as bits numbered as [`Corner::faces`]
    /// (x, y, z low faces 3, 0, 4; high faces 1, 2, 5): two keys with a common bit are joined by
    /// a segment in a face, which the cell across it may draw too.
    fn cell_faces(&self, base: usize) -> impl Fn(Key) -> u8 + '_ {
        const LOW: [u8; 3] = [3, 0, 4];
        const HIGH: [u8; 3] = [1, 2, 5];
        let cell = self.coords(base).map(|c| 2 * c);
        move |k| {
            let c = self.key_coords(k);
            (0..3).fold(0u8, |m, a| {
                m | u8::from(c[a] == cell[a]) << LOW[a] | u8::from(c[a] == cell[a] + 2) << HIGH[a]
            })
        }
    }

    /// Doubled grid coordinates of a key: points even, crossings odd along their edge, interior
    /// points odd along every axis.
    fn key_coords(&self, k: Key) -> [usize; 3] {
        let payload = (k & PAYLOAD) as usize;
        match tag(k) {
            POINT => self.coords(payload).map(|c| 2 * c),
            EDGE => {
                let mut c = self.coords(payload / 3).map(|c| 2 * c);
                c[payload % 3] += 1;
                c
            }
            _ => self.coords(payload / 8).map(|c| 2 * c + 1),
        }
    }

    /// Whether making `p` zero keeps the mesh a manifold with the same topology and makes no
    /// zero-area triangle: [`Ternary::zero_keeps_topology`], answered from the memo of `p`'s
    /// neighbourhood when an identical one (same below / above / zero pattern of the 27 points)
    /// was checked before and its cells are unambiguous.
    fn snap_is_safe(
        &self,
        p: usize,
        before: &mut Patch,
        after: &mut Patch,
        neighbourhoods: &Neighbourhoods,
    ) -> bool {
        let Some(pattern) = self.pattern(p) else {
            return self.zero_keeps_topology(p, before, after);
        };
        if let Some(known) = neighbourhoods.get(pattern) {
            let safe = match known {
                Known::Values => return self.zero_keeps_topology(p, before, after),
                Known::Refused => false,
                Known::Accepted(new) => {
                    // Each corner is placed once: most new triangles share the snapped point.
                    let mut at = [[0.0f64; 3]; MAX_NEW_CORNERS];
                    let c = self.coords(p);
                    for (x, &code) in at
                        .iter_mut()
                        .zip(&new.corners[..usize::from(new.corner_count)])
                    {
                        *x = self.local_position(p, c, code).map(f64::from);
                        debug_assert_eq!(
                            self.local_position(p, c, code),
                            self.position(self.local_key(p, code), &[])
                        );
                    }
                    new.triangles[..usize::from(new.count)]
                        .iter()
                        .all(|t| positive_area(t.map(|c| at[usize::from(c)])))
                }
            };
            // Tests (debug assertions) check every reuse against the full check.
            debug_assert_eq!(safe, self.zero_keeps_topology(p, before, after));
            return safe;
        }
        let kept = self.topology_kept_by_class(p, pattern, before, after, neighbourhoods);
        neighbourhoods.insert(pattern, self.known(p, pattern, before, after, kept));
        kept && self.no_zero_area(before, after)
    }

    /// The below (0) / above (1) / zero (2) pattern of the 27 points around an interior point
    /// `p` (two bits each, `x` fastest), or `None` near the grid's boundary (where the block's
    /// planes are open) or next to a value that is not finite.
    fn pattern(&self, p: usize) -> Option<u64> {
        let c = self.coords(p);
        let dims = self.grid.dims();
        if (0..3).any(|a| c[a] < 2 || c[a] + 3 > dims[a]) {
            return None;
        }
        if !self.masks.all_finite() {
            return self.pattern_of_values(p);
        }
        // From the bit arrays (a few cache lines) rather than the values (nine rows of the
        // volume): the points are visited in sweeps over the whole grid, and the values' rows
        // would come from memory each time. A point is zero, or above as the masks say.
        let spread = |x: u64| (x & 1) | (x & 2) << 1 | (x & 4) << 2;
        let [sx, sy, sz] = self.strides;
        let ny = dims[1];
        let mut pattern = 0u64;
        for k in 0..3 {
            for j in 0..3 {
                let first = p - sx - sy - sz + j * sy + k * sz;
                let zero = super::binary::bits3(&self.zero, first);
                let above = self.masks.above3(c[0] - 1, c[1] + j - 1, c[2] + k - 1, ny) & !zero;
                pattern |= (spread(above) | spread(zero) << 1) << (6 * (j + 3 * k));
            }
        }
        debug_assert_eq!(Some(pattern), self.pattern_of_values(p));
        Some(pattern)
    }

    /// [`Ternary::pattern`] from the values, for grids with points that are not finite.
    fn pattern_of_values(&self, p: usize) -> Option<u64> {
        let [sx, sy, sz] = self.strides;
        let start = p - sx - sy - sz;
        let mut pattern = 0u64;
        let mut bit = 0;
        for k in 0..3 {
            for j in 0..3 {
                let row = start + j * sy + k * sz;
                for q in row..row + 3 {
                    let v = self.values[q];
                    if !v.is_finite() {
                        return None;
                    }
                    let trit = if self.zero_point(q) {
                        2
                    } else {
                        u64::from(is_above(v, self.level))
                    };
                    pattern |= trit << bit;
                    bit += 2;
                }
            }
        }
        Some(pattern)
    }

    /// What the full check of `p` (combinatorial verdict `kept`, patches `before` and `after`) says about
    /// every point with the same `pattern`. The patches are a function of the pattern when no
    /// cell has an ambiguous face or a tunnel to choose, before or after: then the combinatorial
    /// verdict carries over, and only the new triangles' areas (positions) remain to be checked.
    fn known(&self, p: usize, pattern: u64, before: &Patch, after: &Patch, kept: bool) -> Known {
        let table = CaseTable::binary();
        let above = |d: [usize; 3], p_above: bool| {
            let bits = pattern >> (2 * (d[0] + 3 * d[1] + 9 * d[2])) & 3;
            bits != 0 || (p_above && d == [1, 1, 1])
        };
        for o in 0..8usize {
            let origin = [o & 1, o >> 1 & 1, o >> 2];
            for p_above in [false, true] {
                let mut config = 0u8;
                for (v, corner) in crate::cube::VERTICES.iter().enumerate() {
                    let d = [0, 1, 2].map(|a| origin[a] + usize::from(corner[a]));
                    config |= u8::from(above(d, p_above)) << v;
                }
                if table.ambiguous_faces(config) != 0
                    || (self.topology == Topology::Mc33 && table.has_tunnel_candidates(config, 0))
                {
                    return Known::Values;
                }
            }
        }
        if !before.interiors.is_empty() || !after.interiors.is_empty() {
            return Known::Values;
        }
        let old = canonical_triangles(&before.triangles);
        let mut new = NewTriangles {
            corners: [0; MAX_NEW_CORNERS],
            corner_count: 0,
            triangles: [[0; 3]; MAX_NEW],
            count: 0,
        };
        let c = self.coords(p);
        for t in &after.triangles {
            if old.binary_search(&canonical(*t)).is_ok() {
                continue;
            }
            if usize::from(new.count) == MAX_NEW {
                return Known::Values;
            }
            let mut triangle = [0u8; 3];
            for (slot, &k) in triangle.iter_mut().zip(t) {
                let d = self.key_coords(k);
                let l = [0, 1, 2].map(|a| (d[a] + 2 - 2 * c[a]) as u8);
                let code = l[0] * 25 + l[1] * 5 + l[2];
                let len = usize::from(new.corner_count);
                *slot = match new.corners[..len].iter().position(|&x| x == code) {
                    Some(i) => i as u8,
                    None if len < MAX_NEW_CORNERS => {
                        new.corners[len] = code;
                        new.corner_count += 1;
                        len as u8
                    }
                    None => return Known::Values,
                };
            }
            // The codes name the same keys again around any point with this pattern.
            debug_assert_eq!(
                triangle.map(|c| self.local_key(p, new.corners[usize::from(c)])),
                *t
            );
            new.triangles[usize::from(new.count)] = triangle;
            new.count += 1;
        }
        if kept {
            Known::Accepted(new)
        } else {
            Known::Refused
        }
    }

    /// The key of the vertex at local doubled coordinates `code` (see [`Known`]) around `p`.
    fn local_key(&self, p: usize, code: u8) -> Key {
        let d = [code / 25, code / 5 % 5, code % 5].map(|x| isize::from(x) - 2);
        let mut q = p as isize;
        let mut axis = None;
        for (a, (&d, &stride)) in d.iter().zip(&self.strides).enumerate() {
            q += d.div_euclid(2) * stride as isize;
            if d % 2 != 0 {
                axis = Some(a);
            }
        }
        match axis {
            None => POINT << TAG_SHIFT | q as u64,
            Some(a) => EDGE << TAG_SHIFT | (q as u64 * 3 + a as u64),
        }
    }

    fn zero_keeps_topology(&self, p: usize, before: &mut Patch, after: &mut Patch) -> bool {
        self.topology_kept(p, before, after) && self.no_zero_area(before, after)
    }

    /// The combinatorial part of [`Ternary::zero_keeps_topology`], leaving the patches in
    /// `before` and `after`.
    fn topology_kept(&self, p: usize, before: &mut Patch, after: &mut Patch) -> bool {
        self.make_patches(p, before, after);
        self.patches_keep_topology(p, before, after)
    }

    /// The patches of the cells around `p` as they are (`before`) and with `p` a zero point.
    fn make_patches(&self, p: usize, before: &mut Patch, after: &mut Patch) {
        before.clear();
        after.clear();
        for cell in self.star(p) {
            // Flips change neither the combinatorics outside a cell nor its topology, and never
            // make a zero-area triangle, so the check can skip them.
            self.emit(cell, None, before, false);
            self.emit(cell, Some(p), after, false);
        }
    }

    /// [`Ternary::topology_kept`] on the patches [`Ternary::make_patches`] made, answered from
    /// the verdict of a rotation of them when one was checked before. The check looks only at
    /// how triangles share vertices and edges and which vertices lie on the block's faces (all
    /// six frozen around an interior point), so a rotation of the block, which maps all of that
    /// onto itself, keeps its verdict. Patterns that are rotations of each other usually have
    /// rotated patches, but not always (a table may split a symmetric cell along either
    /// diagonal), so the patches themselves are compared, in the rotation class's frame.
    fn topology_kept_by_class(
        &self,
        p: usize,
        pattern: u64,
        before: &mut Patch,
        after: &mut Patch,
        neighbourhoods: &Neighbourhoods,
    ) -> bool {
        self.make_patches(p, before, after);
        let rotations = &neighbourhoods.rotations;
        let (class, r) = rotations.canonical(pattern);
        let c = self.coords(p);
        let (mut old, mut new) = (Vec::new(), Vec::new());
        if !self.class_triangles(c, &rotations.codes[r], before, &mut old)
            || !self.class_triangles(c, &rotations.codes[r], after, &mut new)
        {
            return self.patches_keep_topology(p, before, after);
        }
        if let Some(kept) = neighbourhoods.class_verdict(class, &old, &new) {
            debug_assert_eq!(kept, self.patches_keep_topology(p, before, after));
            return kept;
        }
        let kept = self.patches_keep_topology(p, before, after);
        neighbourhoods.insert_class(class, old, new, kept);
        kept
    }

    /// A patch's triangles by the local codes of their corners around `p` (at `c`; see
    /// [`Known`]), each code turned by `turn`, each triangle started at its smallest code, in
    /// order. `false` for a patch with interior points, which codes cannot tell apart.
    fn class_triangles(
        &self,
        c: [usize; 3],
        turn: &[u8; 125],
        patch: &Patch,
        out: &mut Vec<[u8; 3]>,
    ) -> bool {
        out.clear();
        for t in &patch.triangles {
            let mut codes = [0u8; 3];
            for (code, &k) in codes.iter_mut().zip(t) {
                if tag(k) == INTERIOR {
                    return false;
                }
                let d = self.key_coords(k);
                let l = [0, 1, 2].map(|a| (d[a] + 2 - 2 * c[a]) as u8);
                *code = turn[usize::from(l[0] * 25 + l[1] * 5 + l[2])];
            }
            out.push(canonical(codes));
        }
        out.sort_unstable();
        true
    }

    /// The combinatorial check of [`Ternary::topology_kept`] on patches already made.
    fn patches_keep_topology(&self, p: usize, before: &mut Patch, after: &mut Patch) -> bool {
        let c = self.coords(p);
        let dims = self.grid.dims();
        // The block's boundary planes (doubled coordinates): frozen where cells lie beyond them,
        // open on the grid boundary.
        let mut frozen = Vec::with_capacity(6);
        let mut open = Vec::with_capacity(6);
        for a in 0..3 {
            for plane in [c[a].saturating_sub(1), (c[a] + 1).min(dims[a] - 1)] {
                if plane > 0 && plane < dims[a] - 1 {
                    frozen.push((a, 2 * plane));
                } else {
                    open.push((a, 2 * plane));
                }
            }
        }
        // The patches' keys, numbered in their order: the check then works on small numbers
        // that compare as the keys do, and a key's planes are an array lookup away.
        let keys = &mut before.keys;
        keys.clear();
        keys.extend(before.triangles.iter().chain(&after.triangles).flatten());
        keys.sort_unstable();
        keys.dedup();
        if keys.len() > usize::from(u8::MAX) {
            return self.topology_kept_on_keys(&frozen, &open, before, after);
        }
        // Which boundary planes each key lies on, as bit masks (frozen, open).
        let planes: Vec<(u8, u8)> = keys
            .iter()
            .map(|&k| {
                let c = self.key_coords(k);
                (plane_mask(c, &frozen), plane_mask(c, &open))
            })
            .collect();
        let id = |k: &Key| keys.binary_search(k).expect("every key is numbered") as u8;
        let old: Vec<[u8; 3]> = before
            .triangles
            .iter()
            .map(|t| t.each_ref().map(id))
            .collect();
        let new: Vec<[u8; 3]> = after
            .triangles
            .iter()
            .map(|t| t.each_ref().map(id))
            .collect();
        let n = keys.len();
        let Some(kept) = super::patch_check::accepts(n, &planes, &old, &new, &mut before.scratch)
        else {
            return self.topology_kept_on_keys(&frozen, &open, before, after);
        };
        debug_assert_eq!(
            kept,
            self.topology_kept_on_keys(&frozen, &open, before, after)
        );
        kept
    }

    /// [`Ternary::topology_kept`]'s check on the keys themselves (the reference the numbered
    /// check must agree with, and the way for patches with more than 255 keys).
    fn topology_kept_on_keys(
        &self,
        frozen: &[(usize, usize)],
        open: &[(usize, usize)],
        before: &Patch,
        after: &Patch,
    ) -> bool {
        let on = |keys: &[Key], list: &[(usize, usize)]| {
            keys.iter()
                .fold(u8::MAX, |m, &k| m & plane_mask(self.key_coords(k), list))
                != 0
        };
        let check = Check {
            frozen: &|keys: &[Key]| on(keys, frozen),
            open: &|keys: &[Key]| on(keys, open),
        };
        check.accepts(&before.triangles, &after.triangles)
    }

    fn no_zero_area(&self, before: &Patch, after: &Patch) -> bool {
        let old: Vec<[Key; 3]> = canonical_triangles(&before.triangles);
        // The new triangles share most corners (the snapped point above all): each is placed
        // once.
        let mut placed: Vec<(Key, [f64; 3])> = Vec::new();
        let mut at = |k: Key| match placed.iter().find(|e| e.0 == k) {
            Some(e) => e.1,
            None => {
                let x = self.position(k, &after.interiors).map(f64::from);
                placed.push((k, x));
                x
            }
        };
        after.triangles.iter().all(|t| {
            old.binary_search(&canonical(*t)).is_ok()
                || positive_area([at(t[0]), at(t[1]), at(t[2])])
        })
    }

    /// Where the vertex of zero point `p`, at coordinates `c`, goes: `(coordinates of the edge
    /// start, axis, fraction)`, and `(c, 0, 0.0)` for the grid point itself. Callers pass `c`
    /// so that the many who know it need no division to find it.
    fn snapped_place_at(&self, p: usize, c: [usize; 3]) -> ([usize; 3], usize, f64) {
        let values: &[f32] = &self.values;
        let level = f64::from(self.level);
        let v = f64::from(values[p]);
        if self.snapping.position == SnapPosition::GridPoint
            || (v - level).abs() <= f64::from(self.snapping.zero_threshold)
            || self.on_grid[p / 64] >> (p % 64) & 1 != 0
        {
            return (c, 0, 0.0);
        }
        let dims = self.grid.dims();
        let on_wall = |axis: usize| c[axis] == 0 || c[axis] + 1 == dims[axis];
        // A point on the grid's outer face keeps to that face's plane (and is snapped only for
        // crossings there): carried inward along the face's normal, the rim would bend the
        // volume mesh's wall, with no cell beyond the wall to fill the two together where the
        // wall crosses the surface; and the rim stays where a neighbouring volume's meets it.
        let mut best = (c, 0, 0.0, f64::INFINITY);
        for (axis, &stride) in self.strides.iter().enumerate() {
            if on_wall(axis) {
                continue;
            }
            for forward in [false, true] {
                let q = match forward {
                    true if c[axis] + 1 < dims[axis] => p + stride,
                    false if c[axis] > 0 => p - stride,
                    _ => continue,
                };
                let w = f64::from(values[q]);
                let side = |x: f32| is_above(x, self.level);
                if !w.is_finite() || side(values[p]) == side(values[q]) {
                    continue;
                }
                let t = (level - v) / (w - v);
                // Both ends of an edge may be snapped onto a crossing exactly halfway (at
                // `snap` = 0.5): two vertices in one place, which no triangle joins, so no
                // area check sees them, and a volume mesh gets flat elements between them. The
                // first end takes it (the same quotient as the candidates' pass).
                if !forward && (level - w) / (v - w) == 0.5 {
                    continue;
                }
                if t < best.3 && t <= f64::from(self.snapping.snap) {
                    best = if forward {
                        (c, axis, t, t)
                    } else {
                        let mut cq = c;
                        cq[axis] -= 1;
                        (cq, axis, 1.0 - t, t)
                    };
                }
            }
        }
        (best.0, best.1, best.2)
    }

    /// Position of the vertex of zero point `p` at coordinates `c`.
    fn point_position(&self, p: usize, c: [usize; 3]) -> [f32; 3] {
        let (c0, axis, t) = self.snapped_place_at(p, c);
        self.grid.edge_point(c0, axis, t).map(|c| c as f32)
    }

    /// Position of the crossing on the edge from point `a` (at coordinates `c`) along `axis`.
    fn edge_position(&self, a: usize, c: [usize; 3], axis: usize) -> [f32; 3] {
        let t = self.edge_t(a, axis);
        self.grid.edge_point(c, axis, t).map(|c| c as f32)
    }

    /// Position of the vertex at local doubled coordinates `code` (see [`Known`]) around point
    /// `p` at coordinates `c`: the position of [`Ternary::local_key`]'s key, found without
    /// numbering it and dividing the number back into coordinates.
    fn local_position(&self, p: usize, c: [usize; 3], code: u8) -> [f32; 3] {
        let d = [code / 25, code / 5 % 5, code % 5].map(|x| isize::from(x) - 2);
        let (mut q, mut cq, mut axis) = (p, c, None);
        for a in 0..3 {
            let step = d[a].div_euclid(2);
            q = q.wrapping_add_signed(step * self.strides[a] as isize);
            cq[a] = cq[a].wrapping_add_signed(step);
            if d[a] % 2 != 0 {
                axis = Some(a);
            }
        }
        match axis {
            None => self.point_position(q, cq),
            Some(a) => self.edge_position(q, cq, a),
        }
    }

    /// The box interior points of the cell at point `base` keep to.
    fn interior_bounds(&self, base: usize) -> Bounds {
        let [i, j, k] = self.coords(base);
        interior_bounds(
            self.grid.point(i, j, k),
            self.grid.point(i + 1, j + 1, k + 1),
        )
    }

    fn edge_t(&self, a: usize, axis: usize) -> f64 {
        let v0 = f64::from(self.g(a));
        let v1 = f64::from(self.g(a + self.strides[axis]));
        ((f64::from(self.level) - v0) / (v1 - v0)).clamp(MIN_OFFSET, 1.0 - MIN_OFFSET)
    }

    fn position(&self, k: Key, interiors: &[Interior]) -> [f32; 3] {
        let payload = (k & PAYLOAD) as usize;
        match tag(k) {
            POINT => self.point_position(payload, self.coords(payload)),
            EDGE => {
                let (a, axis) = (payload / 3, payload % 3);
                self.edge_position(a, self.coords(a), axis)
            }
            _ => {
                let interior = interiors
                    .iter()
                    .find(|i| i.key == k)
                    .expect("interior points come with their support");
                if let Some(x) = interior.at {
                    return x.map(|c| c as f32);
                }
                let corners = interior
                    .support
                    .iter()
                    .map(|&s| self.position(s, interiors));
                centroid_in(corners, &self.interior_bounds(payload / 8)).map(|c| c as f32)
            }
        }
    }

    /// Meshes one box of cells with the chosen zero points.
    pub(super) fn mesh_box(
        &self,
        placer: &Placer,
        flip: bool,
        cells: CellBox,
    ) -> Result<ChunkMesh, ExtractError> {
        let [nx, ny, _] = self.grid.dims();
        let mut ids = Ids::default();
        let mut patch = Patch::default();
        let mut out = ChunkMesh::new(cells);
        // Zero points hold the level, which counts as above (the masks say so): cells whose
        // eight values are all above or all below make nothing, and are ruled out 64 at a time.
        let masks = &self.masks;
        let [x0, y0, z0] = cells.min;
        let [x1, y1, z1] = cells.max;
        fn in_box(visit: &[u64], x0: usize, x1: usize) -> impl Iterator<Item = usize> + '_ {
            super::binary::set_bits(visit)
                .skip_while(move |&i| i < x0)
                .take_while(move |&i| i < x1)
        }
        // The cells to visit, row by row, found once: counted first to size the arrays (about
        // one vertex and two triangles per cell visited, so they are not copied as they grow),
        // then walked.
        let words = masks.words;
        let mut visits = vec![0u64; (y1 - y0) * (z1 - z0) * words];
        let mut rows = visits.chunks_exact_mut(words);
        for k in z0..z1 {
            for j in y0..y1 {
                let row = rows.next().expect("a row of visits per row of cells");
                masks.visit(j, k, ny, nx - 1, row);
            }
        }
        let candidates: usize = visits
            .chunks_exact(words)
            .map(|row| in_box(row, x0, x1).count())
            .sum();
        let mesh = &mut out.mesh;
        mesh.positions.reserve(candidates + candidates / 8);
        out.keys.reserve(candidates + candidates / 8);
        mesh.triangles.reserve(2 * candidates + candidates / 4);
        if placer.normals() {
            mesh.normals.reserve(candidates + candidates / 8);
        }
        let mut visit_rows = visits.chunks_exact(words);
        for k in z0..z1 {
            ids.next_plane();
            for j in y0..y1 {
                let visit = visit_rows.next().expect("a row of visits per row of cells");
                for i in in_box(visit, x0, x1) {
                    let base = self.index(i, j, k);
                    let pts = self.offsets.map(|o| base + o);
                    if pts.iter().any(|&p| !self.values[p].is_finite()) {
                        out.stats.skipped_cells += 1;
                        continue;
                    }
                    patch.clear();
                    let tunnel = self.emit(base, None, &mut patch, true);
                    if patch.triangles.is_empty() {
                        continue;
                    }
                    out.stats.active_cells += 1;
                    out.stats.tunnels += usize::from(tunnel);
                    for t in &patch.triangles {
                        let mut tri = [0u32; 3];
                        for (slot, &key) in tri.iter_mut().zip(t) {
                            *slot = self.vertex(key, &patch, placer, &mut ids, &mut out)?;
                        }
                        if flip {
                            tri.swap(1, 2);
                        }
                        out.mesh.triangles.push(tri);
                    }
                }
                out.end_row()?;
            }
        }
        Ok(out)
    }

    fn vertex(
        &self,
        key: Key,
        patch: &Patch,
        placer: &Placer,
        ids: &mut Ids,
        out: &mut ChunkMesh,
    ) -> Result<u32, ExtractError> {
        if let Some(id) = ids.get(key) {
            return Ok(id);
        }
        let payload = (key & PAYLOAD) as usize;
        let id = match tag(key) {
            POINT => match self.snapped_place_at(payload, self.coords(payload)) {
                (c0, _, 0.0) => placer.point_vertex(c0, &mut out.mesh)?,
                (c0, axis, t) => placer.vertex_on_edge(c0, axis, t, &mut out.mesh)?,
            },
            EDGE => {
                let (a, axis) = (payload / 3, payload % 3);
                placer.vertex_on_edge(self.coords(a), axis, self.edge_t(a, axis), &mut out.mesh)?
            }
            _ => {
                let interior = patch
                    .interiors
                    .iter()
                    .find(|i| i.key == key)
                    .expect("interior points come with their support");
                let mut corner_ids = Vec::with_capacity(interior.support.len());
                for &s in &interior.support {
                    corner_ids.push(self.vertex(s, patch, placer, ids, out)?);
                }
                out.stats.interior_vertices += 1;
                match interior.at {
                    Some(x) => placer.interior_vertex(x, &corner_ids, &mut out.mesh)?,
                    None => placer.centroid_vertex(
                        &corner_ids,
                        &self.interior_bounds(payload / 8),
                        &mut out.mesh,
                    )?,
                }
            }
        };
        out.keys.push(VertexKey::from_bits(key));
        ids.insert(key, id);
        Ok(id)
    }
}

/// Moves every *lone tie* — a value equal to the level with none of its six edge neighbours above
/// the level, and some point below it among the 26 around — halfway to the highest of those.
///
/// By the library's tie rule such a point counts as above, so binary Marching Cubes wraps it in
/// a closed surface of zero size (every crossing on its edges lies on the point itself), and so
/// it does a cluster of such ties. Under the ternary model the field only touches the level
/// there: the region above is a point, not a body. Snapping the point cannot remove that surface
/// (the topology check keeps every component), so it stayed as a speck of needle triangles, and a
/// volume mesh had to carve a hole around it. A tie beside a point above the level is joined to
/// that point's body along their edge and keeps its value; so does a tie among ties only (inside
/// a plateau at the level, which may be all there is: a mask at its lower value). The 26, not
/// the six, for the points below: the middle of a cross of ties settles with its arms. A settled tie
/// beside a kept tie makes a crossing at the kept tie (`t` = 1), the point the surface passes
/// through anyway; it never has a point above as a neighbour, so no other crossing moves. The
/// new value is a difference of the data's own values (exact for integer data), so the cell
/// decisions read it the same whatever the data's type or offset.
///
/// Returns the values as they were when any point moved.
fn settle_lone_ties<'a>(
    values: &mut Cow<'a, [f32]>,
    dims: [usize; 3],
    level: f32,
) -> Option<Cow<'a, [f32]>> {
    let [nx, ny, nz] = dims;
    let plane = nx * ny;
    let v: &[f32] = values;
    let lone: Vec<(usize, f32)> = (0..nz)
        .into_par_iter()
        .flat_map_iter(|k| {
            let mut lone = Vec::new();
            for j in 0..ny {
                let row = plane * k + nx * j;
                if !v[row..row + nx].contains(&level) {
                    continue;
                }
                'point: for i in (0..nx).filter(|&i| v[row + i] == level) {
                    let p = row + i;
                    let c = [i, j, k];
                    for a in 0..3 {
                        let stride = [1, nx, plane][a];
                        if (c[a] > 0 && v[p - stride] > level)
                            || (c[a] + 1 < dims[a] && v[p + stride] > level)
                        {
                            continue 'point;
                        }
                    }
                    // The largest value below the level among the 26 around.
                    let near = |c: usize, n: usize| c.saturating_sub(1)..(c + 2).min(n);
                    let mut below = f32::NEG_INFINITY;
                    for z in near(k, nz) {
                        for y in near(j, ny) {
                            for &w in &v[plane * z + nx * y..][near(i, nx)] {
                                if w < level {
                                    below = below.max(w);
                                }
                            }
                        }
                    }
                    if below > f32::NEG_INFINITY {
                        let halfway = level - (level - below) * 0.5;
                        // The next f32 below the level when the halfway point rounds onto it
                        // (`f32::next_down`, after our MSRV).
                        let settled = if halfway < level {
                            halfway
                        } else if level == 0.0 {
                            -f32::from_bits(1)
                        } else if level > 0.0 {
                            f32::from_bits(level.to_bits() - 1)
                        } else {
                            f32::from_bits(level.to_bits() + 1)
                        };
                        lone.push((p, settled));
                    }
                }
            }
            lone
        })
        .collect();
    if lone.is_empty() {
        return None;
    }
    let input = values.clone();
    let values = values.to_mut();
    for (p, settled) in lone {
        values[p] = settled;
    }
    Some(input)
}

/// `grid` with its lone ties settled as ternary extraction settles them: the field whose MC33
/// mesh has the ternary mesh's topology.
#[cfg(test)]
pub(super) fn without_lone_ties(grid: &crate::field::Grid, level: f32) -> crate::field::Grid {
    let mut values = Cow::Borrowed(grid.values());
    settle_lone_ties(&mut values, grid.dims(), level);
    crate::field::Grid::new(grid.dims(), values.into_owned())
        .and_then(|g| g.with_spacing(grid.spacing()))
        .and_then(|g| g.with_origin(grid.origin()))
        .unwrap()
}

/// The ids of the vertices made for the cells of the current plane and the plane before: a
/// cell's vertices lie on its own two point planes (or inside it), so no later cell can meet a
/// vertex made two planes back, and the maps stay the size of a plane.
#[derive(Default)]
struct Ids {
    below: HashMap<Key, u32, BuildHasherDefault<KeyHasher>>,
    here: HashMap<Key, u32, BuildHasherDefault<KeyHasher>>,
}

impl Ids {
    fn next_plane(&mut self) {
        std::mem::swap(&mut self.below, &mut self.here);
        self.here.clear();
    }

    fn get(&self, key: Key) -> Option<u32> {
        self.here
            .get(&key)
            .or_else(|| self.below.get(&key))
            .copied()
    }

    fn insert(&mut self, key: Key, id: u32) {
        self.here.insert(key, id);
    }
}

/// Bit `i` set when doubled coordinates `c` lie on plane `list[i]` (axis, coordinate).
fn plane_mask(c: [usize; 3], list: &[(usize, usize)]) -> u8 {
    list.iter()
        .enumerate()
        .fold(0u8, |m, (i, &(a, x))| m | u8::from(c[a] == x) << i)
}

/// A multiplicative hash: keys are already well spread integers.
#[derive(Default)]
pub(super) struct KeyHasher(u64);

impl Hasher for KeyHasher {
    fn finish(&self) -> u64 {
        self.0
    }

    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0.rotate_left(8) ^ u64::from(b)).wrapping_mul(0x9E37_79B9_7F4A_7C15);
        }
    }

    fn write_u64(&mut self, k: u64) {
        self.0 = (k ^ k >> 29).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    }
}

/// The most new triangles a [`Known::Accepted`] neighbourhood lists, and their most corners.
const MAX_NEW: usize = 24;
const MAX_NEW_CORNERS: usize = 24;

fn positive_area(p: [[f64; 3]; 3]) -> bool {
    let n = crate::mesh::cross(crate::mesh::sub(p[1], p[0]), crate::mesh::sub(p[2], p[0]));
    crate::mesh::dot(n, n) > 0.0
}

/// The triangles a snap makes, by corner number; corners by local code (see [`Known`]).
#[derive(Clone, Copy)]
struct NewTriangles {
    corners: [u8; MAX_NEW_CORNERS],
    corner_count: u8,
    triangles: [[u8; 3]; MAX_NEW],
    count: u8,
}

/// What one 27-point pattern tells about snapping its centre (see [`Ternary::snap_is_safe`]).
/// New triangles are listed by their corners' local doubled coordinates `d` (−2..=2 around the
/// centre; even for grid points, odd along an edge's axis for crossings), coded
/// `25 (d_x + 2) + 5 (d_y + 2) + d_z + 2`.
#[derive(Clone, Copy)]
enum Known {
    /// Some cell is ambiguous before or after: the patches depend on the values.
    Values,
    /// The combinatorial check refuses.
    Refused,
    /// The combinatorial check accepts; these triangles are new and need a positive area.
    Accepted(NewTriangles),
}

/// Known patterns, shared by the threads: what a pattern says does not depend on who found it
/// first, so neither does the mesh. And, by rotation class of pattern, the patches checked and
/// the check's verdict (see [`Ternary::topology_kept_by_class`]).
struct Neighbourhoods {
    known: std::sync::RwLock<rustc_hash::FxHashMap<u64, Known>>,
    classes: std::sync::RwLock<rustc_hash::FxHashMap<u64, Vec<ClassPatches>>>,
    rotations: Rotations,
}

/// A checked pair of patches in its rotation class's frame, and the verdict.
struct ClassPatches {
    before: Vec<[u8; 3]>,
    after: Vec<[u8; 3]>,
    kept: bool,
}

/// Different patches seen for one class are kept up to this many (classes whose patterns are
/// symmetric may meet a few).
const CLASS_VARIANTS: usize = 4;

impl Default for Neighbourhoods {
    fn default() -> Self {
        Neighbourhoods {
            known: Default::default(),
            classes: Default::default(),
            rotations: Rotations::new(),
        }
    }
}

/// The 24 rotations of the 3 × 3 × 3 block around a point: as maps of pattern places
/// (`x + 3y + 9z`, see [`Ternary::pattern`]) and of local codes (see [`Known`]).
struct Rotations {
    places: [[u8; 27]; 24],
    codes: [[u8; 125]; 24],
}

impl Rotations {
    fn new() -> Rotations {
        let mut out = Rotations {
            places: [[0; 27]; 24],
            codes: [[0; 125]; 24],
        };
        let mut r = 0;
        for perm in [
            [0, 1, 2],
            [0, 2, 1],
            [1, 0, 2],
            [1, 2, 0],
            [2, 0, 1],
            [2, 1, 0],
        ] {
            // A swap of two axes turns the block inside out unless one axis flips too: rotations
            // are the signed permutations of determinant +1.
            let odd = matches!(perm, [0, 2, 1] | [1, 0, 2] | [2, 1, 0]);
            for flips in 0..8usize {
                if odd != (flips.count_ones() % 2 == 1) {
                    continue;
                }
                let turn = |d: [usize; 3], top: usize| {
                    [0, 1, 2].map(|a| match flips >> a & 1 {
                        0 => d[perm[a]],
                        _ => top - d[perm[a]],
                    })
                };
                for (i, place) in out.places[r].iter_mut().enumerate() {
                    let e = turn([i % 3, i / 3 % 3, i / 9], 2);
                    *place = (e[0] + 3 * e[1] + 9 * e[2]) as u8;
                }
                for (i, code) in out.codes[r].iter_mut().enumerate() {
                    let e = turn([i / 25, i / 5 % 5, i % 5], 4);
                    *code = (25 * e[0] + 5 * e[1] + e[2]) as u8;
                }
                r += 1;
            }
        }
        debug_assert_eq!(r, 24);
        out
    }

    /// The smallest of a pattern's 24 rotations, and the first rotation that makes it.
    fn canonical(&self, pattern: u64) -> (u64, usize) {
        let mut best = (u64::MAX, 0);
        for (r, places) in self.places.iter().enumerate() {
            let mut turned = 0u64;
            for (i, &place) in places.iter().enumerate() {
                turned |= (pattern >> (2 * i) & 3) << (2 * u32::from(place));
            }
            if turned < best.0 {
                best = (turned, r);
            }
        }
        best
    }
}

impl Neighbourhoods {
    fn class_verdict(&self, class: u64, before: &[[u8; 3]], after: &[[u8; 3]]) -> Option<bool> {
        let classes = self.classes.read().unwrap_or_else(|e| e.into_inner());
        classes
            .get(&class)?
            .iter()
            .find(|v| v.before == before && v.after == after)
            .map(|v| v.kept)
    }

    fn insert_class(&self, class: u64, before: Vec<[u8; 3]>, after: Vec<[u8; 3]>, kept: bool) {
        let mut classes = self.classes.write().unwrap_or_else(|e| e.into_inner());
        let variants = classes.entry(class).or_default();
        if variants.len() < CLASS_VARIANTS
            && !variants
                .iter()
                .any(|v| v.before == before && v.after == after)
        {
            variants.push(ClassPatches {
                before,
                after,
                kept,
            });
        }
    }

    fn get(&self, pattern: u64) -> Option<Known> {
        self.known
            .read()
            .unwrap_or_else(|e| e.into_inner())
            .get(&pattern)
            .copied()
    }

    fn insert(&self, pattern: u64, known: Known) {
        self.known
            .write()
            .unwrap_or_else(|e| e.into_inner())
            .insert(pattern, known);
    }
}

/// The point of a candidate packed as in [`Ternary::choose_zeros_in_groups`].
fn point_of(candidate: u64) -> usize {
    (candidate & ((1 << 56) - 1)) as usize
}

/// Rotates a triangle to start at its smallest key (orientation kept).
fn canonical<T: Copy + Ord>(t: [T; 3]) -> [T; 3] {
    let i = (0..3).min_by_key(|&i| t[i]).unwrap_or(0);
    [t[i], t[(i + 1) % 3], t[(i + 2) % 3]]
}

fn canonical_triangles<T: Copy + Ord>(ts: &[[T; 3]]) -> Vec<[T; 3]> {
    let mut v: Vec<[T; 3]> = ts.iter().map(|&t| canonical(t)).collect();
    v.sort_unstable();
    v
}

/// The acceptance test for replacing a block's patch `before` by `after` (see the module docs).
/// Vertices are keys, or numbers that order as the keys do: the verdict is the same.
struct Check<'c, T> {
    /// Whether all the keys lie on one boundary face of the block with cells beyond it.
    frozen: &'c dyn Fn(&[T]) -> bool,
    /// Whether all the keys lie on one face of the grid's boundary.
    open: &'c dyn Fn(&[T]) -> bool,
}

impl<T: Copy + Ord> Check<'_, T> {
    fn accepts(&self, before: &[[T; 3]], after: &[[T; 3]]) -> bool {
        let old = canonical_triangles(before);
        let new = canonical_triangles(after);
        if old == new {
            return true;
        }
        // No triangle twice, in either orientation.
        let mut sets: Vec<[T; 3]> = after
            .iter()
            .map(|t| {
                let mut s = *t;
                s.sort_unstable();
                s
            })
            .collect();
        sets.sort_unstable();
        if sets.windows(2).any(|w| w[0] == w[1]) {
            return false;
        }
        self.edges_fit(&old, &new) && self.fans_fit(&old, &new) && self.components_fit(&old, &new)
    }

    fn edges_fit(&self, old: &[[T; 3]], new: &[[T; 3]]) -> bool {
        // (low, high, forward, in_new)
        let mut uses: Vec<(T, T, bool, bool)> = Vec::with_capacity(3 * (old.len() + new.len()));
        for (list, is_new) in [(old, false), (new, true)] {
            for t in list {
                for i in 0..3 {
                    let (a, b) = (t[i], t[(i + 1) % 3]);
                    uses.push((a.min(b), a.max(b), a < b, is_new));
                }
            }
        }
        uses.sort_unstable();
        for group in uses.chunk_by(|x, y| (x.0, x.1) == (y.0, y.1)) {
            let count = |is_new: bool, forward: bool| {
                group
                    .iter()
                    .filter(|u| u.3 == is_new && u.2 == forward)
                    .count()
            };
            let (nf, nb) = (count(true, true), count(true, false));
            let keys = [group[0].0, group[0].1];
            if (self.frozen)(&keys) {
                // Outside triangles may use the edge too. If the block used it both ways, they
                // do not, and the block may drop it; otherwise its use must stay as it was.
                let was = (count(false, true), count(false, false));
                if (nf, nb) != was && !(was == (1, 1) && (nf, nb) == (0, 0)) {
                    return false;
                }
            } else {
                let ok =
                    matches!((nf, nb), (0, 0) | (1, 1)) || (nf + nb == 1 && (self.open)(&keys));
                if !ok {
                    return false;
                }
            }
        }
        true
    }

    fn fans_fit(&self, old: &[[T; 3]], new: &[[T; 3]]) -> bool {
        // Only vertices of triangles that appear or disappear can change their fans (both lists
        // are sorted canonical triangles).
        let mut vertices: Vec<T> = Vec::new();
        let (mut i, mut j) = (0, 0);
        while i < old.len() || j < new.len() {
            match (old.get(i), new.get(j)) {
                (Some(a), Some(b)) if a == b => {
                    i += 1;
                    j += 1;
                }
                (Some(a), Some(b)) if a < b => {
                    vertices.extend(a);
                    i += 1;
                }
                (Some(a), None) => {
                    vertices.extend(a);
                    i += 1;
                }
                (_, Some(b)) => {
                    vertices.extend(b);
                    j += 1;
                }
                (None, None) => break,
            }
        }
        vertices.sort_unstable();
        vertices.dedup();
        for &u in &vertices {
            let after = fan(new, u);
            if (self.frozen)(&[u]) {
                // Path ends on frozen edges are where the fan continues outside the block and
                // must stay; ends on the grid boundary may move along it.
                let ends = |f: Option<(Vec<(T, T)>, usize)>| {
                    f.map(|(paths, cycles)| {
                        let end = |x: T| (self.frozen)(&[u, x]).then_some(x);
                        let mut p: Vec<(Option<T>, Option<T>)> =
                            paths.into_iter().map(|(a, b)| (end(a), end(b))).collect();
                        p.sort_unstable();
                        (p, cycles)
                    })
                };
                let after = ends(after);
                if after.is_none() || after != ends(fan(old, u)) {
                    return false;
                }
            } else {
                match after {
                    Some((paths, cycles)) => {
                        let one_disk = cycles == 1 && paths.is_empty();
                        let one_half_disk = cycles == 0 && paths.len() == 1 && (self.open)(&[u]);
                        if !(one_disk || one_half_disk || (cycles == 0 && paths.is_empty())) {
                            return false;
                        }
                    }
                    None => return false,
                }
            }
        }
        true
    }

    fn components_fit(&self, old: &[[T; 3]], new: &[[T; 3]]) -> bool {
        self.component_signatures(old) == self.component_signatures(new)
    }

    /// Per edge-connected component: its Euler characteristic and its interface edges.
    #[allow(clippy::type_complexity)]
    fn component_signatures(&self, ts: &[[T; 3]]) -> Vec<(i64, Vec<(T, T)>)> {
        fn find(parent: &mut [usize], mut x: usize) -> usize {
            while parent[x] != x {
                parent[x] = parent[parent[x]];
                x = parent[x];
            }
            x
        }
        let mut parent: Vec<usize> = (0..ts.len()).collect();
        let mut edges: Vec<(T, T, usize)> = Vec::with_capacity(3 * ts.len());
        for (i, t) in ts.iter().enumerate() {
            for j in 0..3 {
                let (a, b) = (t[j], t[(j + 1) % 3]);
                edges.push((a.min(b), a.max(b), i));
            }
        }
        edges.sort_unstable();
        for group in edges.chunk_by(|x, y| (x.0, x.1) == (y.0, y.1)) {
            for w in group.windows(2) {
                let (a, b) = (find(&mut parent, w[0].2), find(&mut parent, w[1].2));
                parent[a] = b;
            }
        }
        // Components by their root; all triangles of an edge's group share one.
        let mut roots: Vec<usize> = (0..ts.len()).map(|i| find(&mut parent, i)).collect();
        let mut out: Vec<(usize, i64, Vec<(T, T)>)> = Vec::new();
        let slot = |root: usize, out: &mut Vec<(usize, i64, Vec<(T, T)>)>| match out
            .iter()
            .position(|c| c.0 == root)
        {
            Some(i) => i,
            None => {
                out.push((root, 0, Vec::new()));
                out.len() - 1
            }
        };
        // χ = V − E + F: faces, then edges (and the interface: frozen edges used once) …
        for &r in &roots {
            let i = slot(r, &mut out);
            out[i].1 += 1;
        }
        for group in edges.chunk_by(|x, y| (x.0, x.1) == (y.0, y.1)) {
            let i = slot(roots[group[0].2], &mut out);
            out[i].1 -= 1;
            let edge = (group[0].0, group[0].1);
            // Uses by the component, counted as undirected edges: a triangle lists an edge once.
            if group.len() == 1 && (self.frozen)(&[edge.0, edge.1]) {
                out[i].2.push(edge);
            }
        }
        // … then vertices, each once per component.
        let mut verts: Vec<(usize, T)> = ts
            .iter()
            .zip(&roots)
            .flat_map(|(t, &r)| t.map(|k| (r, k)))
            .collect();
        verts.sort_unstable();
        verts.dedup();
        for &(r, _) in &verts {
            let i = slot(r, &mut out);
            out[i].1 += 1;
        }
        roots.clear();
        let mut out: Vec<(i64, Vec<(T, T)>)> = out
            .into_iter()
            .map(|(_, euler, mut interface)| {
                interface.sort_unstable();
                (euler, interface)
            })
            .collect();
        out.sort();
        out
    }
}

/// The fan of triangles around `u`: its link's paths (start, end) and number of cycles, or `None`
/// when the link branches (a non-manifold vertex).
#[allow(clippy::type_complexity)]
fn fan<T: Copy + Ord>(ts: &[[T; 3]], u: T) -> Option<(Vec<(T, T)>, usize)> {
    let mut link: Vec<(T, T)> = Vec::new();
    for t in ts {
        if let Some(i) = t.iter().position(|&k| k == u) {
            link.push((t[(i + 1) % 3], t[(i + 2) % 3]));
        }
    }
    if link.is_empty() {
        return Some((Vec::new(), 0));
    }
    link.sort_unstable();
    if link.windows(2).any(|w| w[0].0 == w[1].0) {
        return None;
    }
    let mut targets: Vec<T> = link.iter().map(|l| l.1).collect();
    targets.sort_unstable();
    if targets.windows(2).any(|w| w[0] == w[1]) {
        return None;
    }
    let successor = |b: T| link.binary_search_by_key(&b, |l| l.0).ok();
    let mut seen = vec![false; link.len()];
    let mut paths = Vec::new();
    for (i, &(a, _)) in link.iter().enumerate() {
        if targets.binary_search(&a).is_ok() {
            continue;
        }
        // Nothing leads to `a`: it starts a path.
        let mut idx = i;
        loop {
            seen[idx] = true;
            match successor(link[idx].1) {
                Some(j) => idx = j,
                None => {
                    paths.push((a, link[idx].1));
                    break;
                }
            }
        }
    }
    let mut cycles = 0;
    for i in 0..link.len() {
        if seen[i] {
            continue;
        }
        cycles += 1;
        let mut idx = i;
        while !seen[idx] {
            seen[idx] = true;
            match successor(link[idx].1) {
                Some(j) => idx = j,
                None => break,
            }
        }
    }
    Some((paths, cycles))
}

/// Whether triangles `b` make a surface like `a`'s: every edge of `b` in at most two triangles,
/// in opposite directions when in two; the same boundary (edges without their reverse, with
/// direction) and the same Euler characteristic; no edge that `a` lacks joining two vertices on
/// one face of the cell (`faces`: a vertex's faces as bits), where the cell across the face
/// may draw it too. Both are one cell's patch, so this keeps the mesh's topology when `b`
/// replaces `a`.
fn same_surface(a: &[[Key; 3]], b: &[[Key; 3]], faces: &dyn Fn(Key) -> u8) -> bool {
    let edges = |t: &[[Key; 3]]| -> Vec<(Key, Key)> {
        let mut e: Vec<(Key, Key)> = t
            .iter()
            .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
            .collect();
        e.sort_unstable();
        e
    };
    let (ea, eb) = (edges(a), edges(b));
    if eb.windows(2).any(|w| w[0] == w[1]) {
        return false;
    }
    let in_a =
        |x: Key, y: Key| ea.binary_search(&(x, y)).is_ok() || ea.binary_search(&(y, x)).is_ok();
    if eb
        .iter()
        .any(|&(x, y)| faces(x) & faces(y) != 0 && !in_a(x, y))
    {
        return false;
    }
    let boundary = |e: &[(Key, Key)]| -> Vec<(Key, Key)> {
        let open = e
            .iter()
            .filter(|&&(x, y)| e.binary_search(&(y, x)).is_err());
        open.copied().collect()
    };
    let euler = |t: &[[Key; 3]], e: &[(Key, Key)]| -> i64 {
        let mut v: Vec<Key> = t.iter().flatten().copied().collect();
        v.sort_unstable();
        v.dedup();
        let mut u: Vec<(Key, Key)> = e.iter().map(|&(x, y)| (x.min(y), x.max(y))).collect();
        u.sort_unstable();
        u.dedup();
        v.len() as i64 - u.len() as i64 + t.len() as i64
    };
    boundary(&ea) == boundary(&eb) && euler(a, &ea) == euler(b, &eb)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The rotations are 24 different bijections of the block that keep its centre, and turning
    /// the codes agrees with turning the places (a grid point's code is its place, doubled).
    #[test]
    fn rotations_are_the_cube_group() {
        let r = Rotations::new();
        let mut seen = std::collections::BTreeSet::new();
        for (places, codes) in r.places.iter().zip(&r.codes) {
            let mut p = places.to_vec();
            p.sort_unstable();
            assert_eq!(p, (0..27).collect::<Vec<u8>>());
            let mut c = codes.to_vec();
            c.sort_unstable();
            assert_eq!(c, (0..125).collect::<Vec<u8>>());
            assert_eq!(places[13], 13);
            for (i, &place) in places.iter().enumerate() {
                let (x, y, z) = (i % 3, i / 3 % 3, i / 9);
                let code = 25 * 2 * x + 5 * 2 * y + 2 * z;
                let turned = usize::from(codes[code]);
                let place = usize::from(place);
                assert_eq!(
                    turned,
                    25 * 2 * (place % 3) + 5 * 2 * (place / 3 % 3) + 2 * (place / 9)
                );
            }
            seen.insert(places.to_vec());
        }
        assert_eq!(seen.len(), 24);
    }

    proptest! {
        /// Every rotation of a pattern has the same class, and the rotation found takes the
        /// pattern to it.
        #[test]
        fn a_class_is_the_same_from_every_rotation(trits in proptest::collection::vec(0u64..3, 27)) {
            let r = Rotations::new();
            let pattern = trits.iter().enumerate().fold(0, |p, (i, &t)| p | t << (2 * i));
            let (class, turn) = r.canonical(pattern);
            let apply = |p: u64, places: &[u8; 27]| {
                (0..27).fold(0, |q, i| q | (p >> (2 * i) & 3) << (2 * places[i]))
            };
            prop_assert_eq!(apply(pattern, &r.places[turn]), class);
            for places in &r.places {
                prop_assert_eq!(r.canonical(apply(pattern, places)).0, class);
            }
        }
    }
}
