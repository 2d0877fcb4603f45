//! Quality improvement after the cells are filled. Where the surface cuts a cell thinly, the
//! cone points and splits of a single cell cannot always avoid flat tetrahedra; across cells, a
//! face or edge shared with a neighbour's tetrahedra often can be flipped away, and a Steiner
//! point moved. These operations, each taken only when it raises the worst dihedral score of the
//! tetrahedra it replaces and every new tetrahedron is positive by the exact predicate:
//!
//! - **2 → 3**: two tetrahedra sharing an interior face become three around the segment joining
//!   their far corners;
//! - **3 → 2**: three tetrahedra around an interior edge become two sharing the face of their
//!   far corners;
//! - **edge removal**: more generally, the `n` tetrahedra around an interior edge (up to
//!   [`RING`]) become `2n - 4`: the polygon of their far corners is triangulated and each
//!   triangle joined to both ends of the edge, the triangulation chosen for the best worst
//!   element by dynamic programming over the polygon's diagonals (Klincsek's algorithm, as in
//!   Shewchuk's edge removal);
//! - **move**: a Steiner point or a grid point inside the mesh walks (a pattern search) to where
//!   its worst tetrahedron is best. A grid point the surface passes close by (one kept off it to
//!   keep the topology) leaves thin elements between them that no flip removes; moving it away
//!   bends the lattice tetrahedra around it, which the search scores like any other;
//! - **insert**: the poor tetrahedron and its neighbours across its faces become a star of
//!   tetrahedra from a new Steiner point, placed by the same search; where that is not enough,
//!   the poor tetrahedron with some of those neighbours, or with the tetrahedra around one of
//!   its edges, whichever star is best.
//! - **take out**: a Steiner or grid point merged into one of its neighbours (the edge between
//!   them contracted), its tetrahedra re-made as a cone from that neighbour; a point on a wall
//!   merges within the wall's plane and its wall triangles follow. A point inserted where it
//!   helped once can later split a boundary edge's narrow wedge into two thin elements where
//!   one good one fits; only the extended sweeps and the second round try it (there it takes
//!   the default sweep from 27 to 23 runs with an element outside the range and 292 to 201
//!   such elements, and on 96 held-out runs 54 to 51 and 917 to 712);
//! - **re-make and move**: where none of these helps, a flip or edge removal that does not help
//!   alone together with a move of one of the new tetrahedra's corners (the worst of all the
//!   tetrahedra they touch must rise): a needle on the boundary (two corners close, the third
//!   far) wants its element's fourth corner beside its short edge, a point a flip can join to it
//!   only once the point that served the needle steps aside.
//!
//! The sweeps take the tetrahedra scoring under [`POOR`], a little inside the range aimed at.
//! Where one is left outside the range ([`AIM`]) and no sharp boundary edge forces it, a second
//! round takes every tetrahedron within two rings of it scoring under [`WIDE`]: the elements
//! around a poor one, fair but bent to fit it, are what block the flip or move it needs, and
//! lifting them first makes the room. The same margin everywhere would cost two to three times
//! the time (most of the mesh is fine); around the few elements left it costs little, and on
//! the sweep of the samples it leaves 7 unexplained elements where 38 were.
//!
//! Boundary triangles (the surface, the grid's walls) are faces of one tetrahedron only, so no
//! flip touches them; no surface vertex moves, and a point on a wall moves only within the
//! wall's plane; tetrahedra of grid points only (the lattice)
//! are never flipped or re-made (their corners may move); tetrahedra of different labels never
//! merge. The union of the tetrahedra is unchanged, so the
//! mesh stays conforming with the same boundary and volume. The work is sequential over the
//! poor tetrahedra in a fixed order, so the result does not depend on the thread count.
//! Points left in no tetrahedron (taken out, or swallowed by a cavity re-made from a new point)
//! are dropped at the end and the later points numbered down, walls renumbered with them: a
//! node in no element would leave a finite element system singular.

use std::ops::Range;

use rayon::prelude::*;
use rustc_hash::FxHashMap as HashMap;

use super::check::{angle_across, positive};
use super::quality::dihedral_extremes;
use super::TetError;

/// Tetrahedra scoring under this are worked on (a dihedral angle under 12° or over 162°): a score
/// of 10 is the edge of the range the volume meshes aim at, dihedral angles in [10°, 165°], and
/// a margin lets flips and moves around a poor element make room.
const POOR: f64 = 12.0;

/// The range volume meshes aim at, dihedral angles in [10°, 165°], as a score.
const AIM: f64 = 10.0;

/// Around a tetrahedron still under [`AIM`] after the sweeps, the tetrahedra within
/// [`RINGS`] rings are worked on again under this margin.
const WIDE: f64 = 18.0;

/// How far around an element left outside the range the second round reaches (rings of
/// vertices).
const RINGS: usize = 2;

/// Sweeps of the second round: plain ones only (extended ones there doubled its time for 5
/// fewer runs outside the range of 144).
const WIDE_SWEEPS: usize = SWEEPS;

/// Sweeps over the poor tetrahedra (each sweep also takes those the last one made), then as many
/// extended sweeps (more cavities for new points, longer searches) over what is left. Extended
/// moves taken first win a cell's worst element locally but can block the flips that would lift
/// it further, so they only work where the plain sweeps stopped.
const SWEEPS: usize = 4;

/// The steps of a point's search: the six along the axes, then the twenty diagonals.
const DIRECTIONS: [[i8; 3]; 26] = {
    let mut out = [[0i8; 3]; 26];
    let mut n = 6;
    let mut a = 0;
    while a < 3 {
        out[2 * a][a] = 1;
        out[2 * a + 1][a] = -1;
        a += 1;
    }
    let mut i = 0;
    while i < 27 {
        let d = [(i % 3) as i8 - 1, (i / 3 % 3) as i8 - 1, (i / 9) as i8 - 1];
        let nonzero = (d[0] != 0) as u8 + (d[1] != 0) as u8 + (d[2] != 0) as u8;
        if nonzero >= 2 {
            out[n] = d;
            n += 1;
        }
        i += 1;
    }
    out
};

/// Rounds of a point's search (each a step along the axes, or a halving of the step when none
/// helps); extended sweeps search until the step has been halved this often, within eight times
/// as many rounds.
const STEPS: usize = 10;

/// The most tetrahedra around an edge that edge removal takes on (the dynamic program is
/// cubic in it; rings of more than seven are rare and seldom removable).
const RING: usize = 7;

/// What the improvement step of [`super::tetmesh`] and [`super::tetmesh_labels`] did (see
/// [`super::TetStats::improve`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ImproveStats {
    /// Tetrahedra scoring under the threshold before.
    pub poor: usize,
    /// Two-to-three flips.
    pub flips_23: usize,
    /// Three-to-two flips.
    pub flips_32: usize,
    /// Edges removed from rings of four to seven tetrahedra (`n` become `2n - 4`).
    pub edge_removals: usize,
    /// Steiner points moved.
    pub moves: usize,
    /// Steiner points added (a few tetrahedra round a poor one re-made as a star from a new
    /// point).
    pub inserted: usize,
    /// Steiner points taken out: merged into a neighbour (their tetrahedra re-made as a cone
    /// from it), or left in no element by a cavity re-made from a new point. The mesh lists
    /// none of them.
    pub removed: usize,
    /// Grid points taken out likewise (never one of a tetrahedron of the lattice).
    pub removed_grid: usize,
    /// Tetrahedra around the elements still outside [10°, 165°] after the first round, worked
    /// on again under 18° (or over 153°).
    pub widened: usize,
}

/// The score a tetrahedron is improved by: its smallest dihedral angle in degrees, or two thirds
/// of 180° less its largest, whichever is smaller — so that both ends of [10°, 165°] score 10.
fn score(p: [[f64; 3]; 4]) -> f64 {
    let (lo, hi) = dihedral_extremes(p);
    lo.min((180.0 - hi) * (2.0 / 3.0))
}

/// The corners of tetrahedron `t` other than its `k`-th, in order.
fn face(t: [u32; 4], k: usize) -> [u32; 3] {
    std::array::from_fn(|i| t[if i < k { i } else { i + 1 }])
}

/// Improves the tetrahedra `tets` over `positions` in place (see the module documentation).
/// `grid` numbers the grid points (tetrahedra of grid points only are kept, and so are their
/// corners), `steiner` the Steiner points; `labels`, if given, holds each tetrahedron's
/// label and is kept in step.
pub(super) fn improve(
    positions: &mut Vec<[f32; 3]>,
    tets: &mut Vec<[u32; 4]>,
    labels: Option<&mut Vec<u32>>,
    grid: Range<u32>,
    steiner: Range<u32>,
) -> ImproveStats {
    let mut walls = Vec::new();
    improve_with(
        positions,
        tets,
        &mut walls,
        labels,
        grid,
        steiner,
        &mut || Ok(()),
    )
    .expect("no check to stop it")
}

/// [`improve`], asking `check` now and then (between stretches of the scan for poor elements,
/// between sweeps and every few hundred elements worked on) whether to stop: its error is
/// returned at once, the mesh then left half-improved for the caller to drop.
pub(super) fn improve_with(
    positions: &mut Vec<[f32; 3]>,
    tets: &mut Vec<[u32; 4]>,
    walls: &mut Vec<[u32; 3]>,
    labels: Option<&mut Vec<u32>>,
    grid: Range<u32>,
    steiner: Range<u32>,
    check: &mut dyn FnMut() -> Result<(), TetError>,
) -> Result<ImproveStats, TetError> {
    let at = |p: &[[f32; 3]], t: &[u32; 4]| t.map(|v| p[v as usize].map(f64::from));
    let lattice = |t: &[u32; 4]| t.iter().all(|v| grid.contains(v));
    // A scan of every element (a third of a second for 57 M): in stretches, in order.
    const STRETCH: usize = 1 << 22;
    let mut poor: Vec<u32> = Vec::new();
    for (s, stretch) in tets.chunks(STRETCH).enumerate() {
        check()?;
        poor.par_extend(
            stretch
                .par_iter()
                .enumerate()
                .filter(|(_, t)| !lattice(t) && score(at(positions, t)) < POOR)
                .map(|(i, _)| (s * STRETCH + i) as u32),
        );
    }
    let mut stats = ImproveStats {
        poor: poor.len(),
        ..ImproveStats::default()
    };
    if poor.is_empty() {
        return Ok(stats);
    }
    // The vertices of poor tetrahedra and of their neighbours are "known": every tetrahedron
    // holding one is listed with it, so faces and edges there can be looked up.
    let n = positions.len();
    let mut known = vec![false; n];
    let mut near = vec![false; n];
    for &t in &poor {
        for v in tets[t as usize] {
            near[v as usize] = true;
        }
    }
    // Few tetrahedra are near the poor ones: found in parallel, listed in order.
    let touching = |flags: &[bool]| -> Vec<u32> {
        tets.par_iter()
            .enumerate()
            .filter(|(_, t)| t.iter().any(|&v| flags[v as usize]))
            .map(|(i, _)| i as u32)
            .collect()
    };
    for t in touching(&near) {
        for v in tets[t as usize] {
            known[v as usize] = true;
        }
    }
    let mut incident: HashMap<u32, Vec<u32>> = HashMap::default();
    for i in touching(&known) {
        for v in tets[i as usize] {
            if known[v as usize] {
                incident.entry(v).or_default().push(i);
            }
        }
    }
    let mut labels = labels;
    let mut work = Work {
        positions,
        tets,
        labels: labels.as_deref_mut(),
        alive: Vec::new(),
        known,
        incident,
        grid,
        steiner,
        extended: false,
        axes: [true; 3],
        bar: POOR,
        merged: Vec::new(),
    };
    work.alive = vec![true; work.tets.len()];
    work.sweeps(poor, POOR, 2 * SWEEPS, check, &mut stats)?;
    // Where elements remain outside the range aimed at, the same work again with a wider
    // margin, in their neighbourhood only: lifting the elements around a poor one out of the
    // margin first makes the room a flip or a move there needs (a margin this wide everywhere
    // would cost twice to three times the time for the same gain).
    check()?;
    let around = work.around_outside();
    if !around.is_empty() {
        stats.widened = around.iter().filter(|&&t| work.score_of(t) < WIDE).count();
        work.sweeps(around, WIDE, WIDE_SWEEPS, check, &mut stats)?;
    }
    // Dead slots out, in order.
    let alive = std::mem::take(&mut work.alive);
    let grid = work.grid.clone();
    let merged = std::mem::take(&mut work.merged);
    drop(work);
    // Wall triangles follow the wall points taken out to where they merged (a point merged
    // into one merged later follows it on); those that held both are gone.
    if !merged.is_empty() {
        let into: HashMap<u32, u32> = merged.iter().map(|&[v, w]| (v, w)).collect();
        let follow = |mut v: u32| {
            while let Some(&w) = into.get(&v) {
                v = w;
            }
            v
        };
        walls.retain_mut(|t| {
            *t = t.map(follow);
            t[0] != t[1] && t[1] != t[2] && t[0] != t[2]
        });
    }
    let mut k = 0;
    tets.retain(|_| {
        k += 1;
        alive[k - 1]
    });
    if let Some(labels) = labels {
        let mut k = 0;
        labels.retain(|_| {
            k += 1;
            alive[k - 1]
        });
    }
    // Points taken out, and points a re-made cavity left in no element, leave no gap: the
    // later ones are numbered down, in order (an unused node would leave a finite element
    // system singular). Only new points and taking out can leave one unused.
    let removed = if stats.inserted + stats.removed > 0 {
        super::check::unused_points(positions.len(), tets, grid.start)
    } else {
        Vec::new()
    };
    stats.removed_grid = removed.iter().filter(|&v| grid.contains(v)).count();
    stats.removed = removed.len() - stats.removed_grid;
    super::check::drop_points(positions, tets, walls, &removed);
    Ok(stats)
}

/// The faces used by one tetrahedron of `tets` only, each sorted, in order: the boundary of
/// their union.
fn boundary(tets: &[[u32; 4]]) -> Vec<[u32; 3]> {
    let mut faces: Vec<[u32; 3]> = tets
        .iter()
        .flat_map(|t| {
            (0..4).map(move |k| {
                let mut f = face(*t, k);
                f.sort_unstable();
                f
            })
        })
        .collect();
    faces.sort_unstable();
    let mut out = Vec::new();
    let mut i = 0;
    while i < faces.len() {
        if faces.get(i + 1) == Some(&faces[i]) {
            i += 2;
        } else {
            out.push(faces[i]);
            i += 1;
        }
    }
    out
}

/// A change around a poor tetrahedron, weighed before it is made.
enum Plan {
    /// Tetrahedra re-made on the same points.
    Replace {
        old: Vec<u32>,
        new: Vec<[u32; 4]>,
        kind: Kind,
    },
    /// A point moved.
    Move { v: u32, at: [f32; 3] },
    /// Tetrahedra re-made as a star from a new point.
    Insert { cavity: Vec<u32>, star: Star },
    /// A Steiner point merged into a neighbour: the tetrahedra around it re-made.
    Remove {
        old: Vec<u32>,
        new: Vec<[u32; 4]>,
        /// For a point on a wall, it and the neighbour it merged into: the wall triangles at
        /// it move there too.
        merge: Option<[u32; 2]>,
    },
    /// Tetrahedra re-made on the same points, then one of their corners moved.
    Remake {
        old: Vec<u32>,
        new: Vec<[u32; 4]>,
        kind: Kind,
        v: u32,
        at: [f32; 3],
    },
}

/// Which re-making a [`Plan::Replace`] is (for the counts).
#[derive(Clone, Copy)]
enum Kind {
    Flip23,
    Flip32,
    EdgeRemoval,
}

/// Tetrahedra coned from a new Steiner point (numbered next), its position and their worst score.
struct Star {
    tets: Vec<[u32; 4]>,
    at: [f32; 3],
    worst: f64,
}

struct Work<'a> {
    positions: &'a mut Vec<[f32; 3]>,
    tets: &'a mut Vec<[u32; 4]>,
    labels: Option<&'a mut Vec<u32>>,
    alive: Vec<bool>,
    known: Vec<bool>,
    incident: HashMap<u32, Vec<u32>>,
    grid: Range<u32>,
    steiner: Range<u32>,
    extended: bool,
    /// The axes a point's search may step along (all but while a wall point slides).
    axes: [bool; 3],
    /// The score under which the tetrahedra of the current sweeps are worked on.
    bar: f64,
    /// Wall points taken out and the neighbours they merged into, in order.
    merged: Vec<[u32; 2]>,
}

impl Work<'_> {
    /// `sweeps` sweeps over the tetrahedra of `queue` scoring under `bar` (each sweep also
    /// takes those the last one made): the first [`SWEEPS`] plain, the rest extended.
    fn sweeps(
        &mut self,
        mut queue: Vec<u32>,
        bar: f64,
        sweeps: usize,
        check: &mut dyn FnMut() -> Result<(), TetError>,
        stats: &mut ImproveStats,
    ) -> Result<(), TetError> {
        self.bar = bar;
        for sweep in 0..sweeps {
            check()?;
            self.extended = sweep >= SWEEPS;
            let mut scored: Vec<(f64, u32)> = queue
                .iter()
                .filter(|&&t| self.alive[t as usize])
                .map(|&t| (self.score_of(t), t))
                .filter(|e| e.0 < bar)
                .collect();
            if scored.is_empty() {
                break;
            }
            scored.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            let first_new = self.tets.len();
            for (k, &(_, t)) in scored.iter().enumerate() {
                if k % 256 == 255 {
                    check()?;
                }
                if self.alive[t as usize] {
                    self.improve_tet(t, stats);
                }
            }
            queue = scored
                .iter()
                .map(|e| e.1)
                .chain(first_new as u32..self.tets.len() as u32)
                .collect();
            queue.sort_unstable();
            queue.dedup();
        }
        Ok(())
    }

    /// The tetrahedra (not of the lattice) within two rings of one still outside the range
    /// aimed at, in order, each of their corners and its neighbours made known. Every
    /// tetrahedron changed so far holds a known vertex, so the ones outside are found among
    /// those vertices' lists.
    fn around_outside(&mut self) -> Vec<u32> {
        let mut outside: Vec<u32> = self
            .incident
            .values()
            .flatten()
            .copied()
            .filter(|&t| self.alive[t as usize] && !self.frozen(t) && self.score_of(t) < AIM)
            .collect();
        outside.sort_unstable();
        outside.dedup();
        outside.retain(|&t| !self.forced(t));
        if outside.is_empty() {
            return outside;
        }
        let mut region: Vec<u32> = outside
            .iter()
            .flat_map(|&t| self.tets[t as usize])
            .collect();
        for _ in 0..RINGS {
            region = self.ring(&region);
        }
        let mut around: Vec<u32> = region
            .iter()
            .flat_map(|&v| self.holding(&[v]).unwrap_or_default())
            .filter(|&t| !self.frozen(t))
            .collect();
        around.sort_unstable();
        around.dedup();
        // As in the first round, the corners' neighbours known too.
        let corners = self.ring(&region);
        self.ring(&corners);
        around
    }

    /// Whether tetrahedron `t` has an edge on the boundary where the region is sharper than the
    /// range aimed at: the tetrahedra around the edge share its angle, so none of them can be
    /// lifted out (no work is spent there).
    fn forced(&self, t: u32) -> bool {
        let tet = self.tets[t as usize];
        (0..4).any(|i| {
            (i + 1..4).any(|j| {
                let Some(ring) = self.holding(&[tet[i], tet[j]]) else {
                    return false;
                };
                // Round an edge inside the mesh every far corner is shared by two tetrahedra.
                let mut far: Vec<u32> = ring
                    .iter()
                    .flat_map(|&r| self.tets[r as usize])
                    .filter(|&v| v != tet[i] && v != tet[j])
                    .collect();
                far.sort_unstable();
                let open = far.chunk_by(|x, y| x == y).any(|c| c.len() != 2);
                // The region's angle at the edge: its elements' dihedral angles there (an
                // element flat across the edge leaves it undecided: not forced).
                let angle = ring
                    .iter()
                    .map(|&r| {
                        let mut others = self.tets[r as usize]
                            .into_iter()
                            .filter(|&v| v != tet[i] && v != tet[j]);
                        let (p, q) = (others.next()?, others.next()?);
                        let [u, v, p, q] = [tet[i], tet[j], p, q].map(|v| self.point(v));
                        angle_across(u, v, p, q)
                    })
                    .sum::<Option<f64>>();
                open && angle.is_some_and(|a| a < AIM)
            })
        })
    }

    /// The vertices of the living tetrahedra holding one of `vs` (sorted, `vs` among them), each
    /// made known with the list of the tetrahedra holding it.
    fn ring(&mut self, vs: &[u32]) -> Vec<u32> {
        self.learn(vs);
        let mut out: Vec<u32> = vs
            .iter()
            .flat_map(|&v| self.holding(&[v]).unwrap_or_default())
            .flat_map(|t| self.tets[t as usize])
            .chain(vs.iter().copied())
            .collect();
        out.sort_unstable();
        out.dedup();
        self.learn(&out);
        out
    }

    /// Makes `vs` known: the living tetrahedra holding each are listed (one scan of the mesh
    /// for those not known yet).
    fn learn(&mut self, vs: &[u32]) {
        let mut new = vec![false; self.known.len()];
        let mut any = false;
        for &v in vs {
            if !self.known[v as usize] {
                new[v as usize] = true;
                any = true;
            }
        }
        if !any {
            return;
        }
        let alive = &self.alive;
        let found: Vec<(u32, u32)> = self
            .tets
            .par_iter()
            .enumerate()
            .filter(|&(i, _)| alive[i])
            .flat_map_iter(|(i, t)| {
                t.iter()
                    .filter(|&&v| new[v as usize])
                    .map(move |&v| (v, i as u32))
                    .collect::<Vec<_>>()
            })
            .collect();
        for (v, t) in found {
            self.incident.entry(v).or_default().push(t);
        }
        for (v, flag) in new.iter().enumerate() {
            if *flag {
                self.known[v] = true;
                self.incident.entry(v as u32).or_default();
            }
        }
    }

    fn point(&self, v: u32) -> [f64; 3] {
        self.positions[v as usize].map(f64::from)
    }

    /// The worst score of tetrahedra `ts` (infinity for none).
    fn worst_of(&self, ts: &[u32]) -> f64 {
        ts.iter()
            .map(|&t| self.score_of(t))
            .fold(f64::INFINITY, f64::min)
    }

    fn score_of(&self, t: u32) -> f64 {
        score(self.tets[t as usize].map(|v| self.point(v)))
    }

    fn label(&self, t: u32) -> u32 {
        self.labels.as_ref().map_or(0, |l| l[t as usize])
    }

    fn frozen(&self, t: u32) -> bool {
        self.tets[t as usize].iter().all(|v| self.grid.contains(v))
    }

    /// The living tetrahedra holding all of `vs`, looked up through a known vertex among them
    /// (`None` if none is known).
    fn holding(&self, vs: &[u32]) -> Option<Vec<u32>> {
        let &x = vs.iter().find(|&&v| self.known[v as usize])?;
        Some(
            self.incident
                .get(&x)
                .map(|list| {
                    list.iter()
                        .copied()
                        .filter(|&t| {
                            self.alive[t as usize]
                                && vs.iter().all(|v| self.tets[t as usize].contains(v))
                        })
                        .collect()
                })
                .unwrap_or_default(),
        )
    }

    /// Works on poor tetrahedron `t`: of the re-meshings around it that raise the worst score
    /// of what they replace, the one whose new worst is best. Flips and edge removals are
    /// cheap and looked at first; only when none of them lifts `t` out of the poor range are
    /// point moves and new points searched too (taking the first change that helps wins
    /// locally but often blocks a better one).
    fn improve_tet(&mut self, t: u32, stats: &mut ImproveStats) {
        let tet = self.tets[t as usize];
        let mut best: Option<(f64, Plan)> = None;
        let consider = |plan: Option<(f64, Plan)>, best: &mut Option<(f64, Plan)>| {
            if let Some((w, plan)) = plan {
                if best.as_ref().is_none_or(|b| w > b.0) {
                    *best = Some((w, plan));
                }
            }
        };
        for d in tet {
            consider(self.flip_23(t, d), &mut best);
        }
        for i in 0..4 {
            for j in i + 1..4 {
                consider(self.flip_32(tet[i], tet[j]), &mut best);
                consider(self.remove_edge(tet[i], tet[j]), &mut best);
            }
        }
        if best.as_ref().is_none_or(|b| b.0 < self.bar) {
            for v in tet {
                let free = self.steiner.contains(&v) || self.grid.contains(&v);
                if free && self.known[v as usize] {
                    consider(self.move_point(v), &mut best);
                }
            }
            consider(self.insert(t), &mut best);
            if self.extended || self.bar > POOR {
                for v in tet {
                    consider(self.remove_point(v), &mut best);
                }
            }
            if self.extended && best.as_ref().is_none_or(|b| b.0 < self.bar) {
                consider(self.remake_and_move(t), &mut best);
            }
        }
        let Some((_, plan)) = best else {
            return;
        };
        match plan {
            Plan::Replace { old, new, kind } => {
                match kind {
                    Kind::Flip23 => stats.flips_23 += 1,
                    Kind::Flip32 => stats.flips_32 += 1,
                    Kind::EdgeRemoval => stats.edge_removals += 1,
                }
                self.replace(&old, &new);
            }
            Plan::Move { v, at } => {
                stats.moves += 1;
                self.positions[v as usize] = at;
            }
            Plan::Remake {
                old,
                new,
                kind,
                v,
                at,
            } => {
                match kind {
                    Kind::Flip23 => stats.flips_23 += 1,
                    Kind::Flip32 => stats.flips_32 += 1,
                    Kind::EdgeRemoval => stats.edge_removals += 1,
                }
                stats.moves += 1;
                self.replace(&old, &new);
                self.positions[v as usize] = at;
            }
            Plan::Remove { old, new, merge } => {
                // Counted again once the unused points are found (see `improve_with`).
                stats.removed += 1;
                self.replace(&old, &new);
                self.merged.extend(merge);
            }
            Plan::Insert { cavity, star } => {
                stats.inserted += 1;
                let Star { mut tets, at, .. } = star;
                let v = self.positions.len() as u32;
                self.positions.push(at);
                self.known.push(true);
                self.steiner.end = self.steiner.end.max(v + 1);
                tets.sort_unstable();
                self.replace(&cavity, &tets);
            }
        }
    }

    /// Re-makes tetrahedron `t` and its neighbours across its faces as a star from a new
    /// Steiner point, if one can be placed where every new tetrahedron is positive and the worst
    /// of them beats the worst of the old. In the extended sweeps other cavities are tried too,
    /// the best star taken: `t` with any subset of those neighbours (a neighbour across a sliver
    /// face often pins the point where the sliver's other side needs it) and the tetrahedra
    /// around each of `t`'s edges (coning them removes the edge, or on the boundary the flat
    /// wedge between two boundary faces).
    fn insert(&mut self, t: u32) -> Option<(f64, Plan)> {
        let tet = self.tets[t as usize];
        let mut neighbours = Vec::new();
        for d in tet {
            let face: Vec<u32> = tet.iter().copied().filter(|&v| v != d).collect();
            if let Some(across) = self.holding(&face) {
                if let [a, b] = across[..] {
                    neighbours.push(if a == t { b } else { a });
                }
            }
        }
        let mut cavities: Vec<Vec<u32>> = vec![[t].into_iter().chain(neighbours.clone()).collect()];
        if self.extended {
            for mask in (0..(1u32 << neighbours.len()) - 1).rev() {
                let some = neighbours
                    .iter()
                    .enumerate()
                    .filter(|(k, _)| mask & (1 << k) != 0)
                    .map(|(_, &n)| n);
                cavities.push([t].into_iter().chain(some).collect());
            }
            for i in 0..4 {
                for j in i + 1..4 {
                    if let Some(ring) = self.holding(&[tet[i], tet[j]]) {
                        if ring.len() > 1 {
                            let others = ring.into_iter().filter(|&r| r != t);
                            cavities.push([t].into_iter().chain(others).collect());
                        }
                    }
                }
            }
        }
        let mut best: Option<(Vec<u32>, Star)> = None;
        for cavity in cavities {
            if let Some(star) = self.star_of(&cavity) {
                if best.as_ref().is_none_or(|b| star.worst > b.1.worst) {
                    best = Some((cavity, star));
                }
            }
        }
        best.map(|(cavity, star)| (star.worst, Plan::Insert { cavity, star }))
    }

    /// The star from a new Steiner point that would replace the tetrahedra `cavity`, if one
    /// beats the cavity's worst.
    fn star_of(&mut self, cavity: &[u32]) -> Option<Star> {
        if !self.may_replace(cavity) {
            return None;
        }
        let t = cavity[0];
        let tet = self.tets[t as usize];
        // The cavity's outer faces, each turned so the cavity lies on its positive side.
        let mut faces: Vec<([u32; 3], [u32; 3])> = Vec::new();
        for &c in cavity {
            let tet = self.tets[c as usize];
            for k in 0..4 {
                let mut f = face(tet, k);
                let p = |v: u32| self.point(v);
                if !positive(p(f[0]), p(f[1]), p(f[2]), p(tet[k])) {
                    f.swap(1, 2);
                }
                let mut sorted = f;
                sorted.sort_unstable();
                faces.push((sorted, f));
            }
        }
        faces.sort_unstable();
        let mut outer: Vec<[u32; 3]> = Vec::new();
        let mut i = 0;
        while i < faces.len() {
            if i + 1 < faces.len() && faces[i].0 == faces[i + 1].0 {
                i += 2;
            } else {
                outer.push(faces[i].1);
                i += 1;
            }
        }
        let old_worst = self.worst_of(cavity);
        // The new point, first at the centroid of the poor tetrahedron and of the cavity.
        let v = self.positions.len() as u32;
        let star: Vec<[u32; 4]> = outer.iter().map(|f| [f[0], f[1], f[2], v]).collect();
        let centroid = |vs: &mut dyn Iterator<Item = u32>, me: &Self| {
            let mut c = [0.0f64; 3];
            let mut n = 0.0;
            for w in vs {
                let p = me.point(w);
                for d in 0..3 {
                    c[d] += p[d];
                }
                n += 1.0;
            }
            c.map(|x| (x / n) as f32)
        };
        let starts = [
            centroid(&mut tet.iter().copied(), self),
            centroid(&mut outer.iter().flatten().copied(), self),
        ];
        self.positions.push(starts[0]);
        self.known.push(true);
        let mut best: Option<([f32; 3], f64)> = None;
        for start in starts {
            self.positions[v as usize] = start;
            if let Some(w) = self.worst(&star) {
                if best.is_none_or(|b| w > b.1) {
                    best = Some((start, w));
                }
            }
        }
        let found = best.map(|(at, worst)| self.search(v, &star, at, worst));
        self.positions.pop();
        self.known.pop();
        let (at, worst) = found?;
        (worst > old_worst).then_some(Star {
            tets: star,
            at,
            worst,
        })
    }

    /// Replaces tetrahedra `old` by `new` (all of one label), reusing their slots.
    fn replace(&mut self, old: &[u32], new: &[[u32; 4]]) {
        let label = self.label(old[0]);
        for &t in old {
            self.alive[t as usize] = false;
        }
        for (k, &tet) in new.iter().enumerate() {
            let slot = if let Some(&t) = old.get(k) {
                self.tets[t as usize] = tet;
                self.alive[t as usize] = true;
                t
            } else {
                self.tets.push(tet);
                self.alive.push(true);
                if let Some(l) = self.labels.as_mut() {
                    l.push(label);
                }
                (self.tets.len() - 1) as u32
            };
            for v in tet {
                if self.known[v as usize] {
                    let list = self.incident.entry(v).or_default();
                    if !list.contains(&slot) {
                        list.push(slot);
                    }
                }
            }
        }
    }

    /// Whether tetrahedra `old` may be replaced: none of the lattice, all of one label.
    fn may_replace(&self, old: &[u32]) -> bool {
        let label = self.label(old[0]);
        old.iter()
            .all(|&t| !self.frozen(t) && self.label(t) == label)
    }

    /// The worst score of `tets` when every one is positive and scores above `bound`, else
    /// `None`. A search keeps only what beats its best: it can stop at the first element that
    /// does not (most candidates fail at once).
    fn worst_above(&self, tets: &[[u32; 4]], bound: f64) -> Option<f64> {
        let mut worst = f64::INFINITY;
        for t in tets {
            let p = t.map(|v| self.point(v));
            if !positive(p[0], p[1], p[2], p[3]) {
                return None;
            }
            let s = score(p);
            if s <= bound {
                return None;
            }
            worst = worst.min(s);
        }
        Some(worst)
    }

    /// The worst score of `tets`, or `None` if one is not positive.
    fn worst(&self, tets: &[[u32; 4]]) -> Option<f64> {
        self.worst_above(tets, f64::NEG_INFINITY)
    }

    /// Flips the face of `t` opposite its corner `d` to the three tetrahedra around the segment
    /// from `d` to the far corner of the tetrahedron across it.
    fn flip_23(&self, t: u32, d: u32) -> Option<(f64, Plan)> {
        let (old, new) = self.flip_23_tets(t, d)?;
        let old_worst = self.score_of(old[0]).min(self.score_of(old[1]));
        self.plan(old, new, old_worst, Kind::Flip23)
    }

    /// The two tetrahedra a 2 → 3 flip of `t`'s face opposite `d` replaces, and the three it
    /// makes (not checked).
    fn flip_23_tets(&self, t: u32, d: u32) -> Option<(Vec<u32>, Vec<[u32; 4]>)> {
        let tet = self.tets[t as usize];
        let mut face: Vec<u32> = tet.iter().copied().filter(|&v| v != d).collect();
        let across = self.holding(&face)?;
        let [first, second] = across[..] else {
            return None;
        };
        let s = if first == t { second } else { first };
        if !self.may_replace(&[t, s]) {
            return None;
        }
        let e = *self.tets[s as usize]
            .iter()
            .find(|v| !face.contains(v))
            .expect("a tetrahedron has a corner off its face");
        let p = |v: u32| self.point(v);
        if !positive(p(face[0]), p(face[1]), p(face[2]), p(d)) {
            face.swap(1, 2);
        }
        let new: Vec<[u32; 4]> = (0..3).map(|k| [face[k], face[(k + 1) % 3], e, d]).collect();
        Some((vec![t, s], new))
    }

    /// Replacing tetrahedra `old` (whose worst scores `old_worst`) by `new`, if every new one is
    /// positive and their worst is better.
    fn plan(
        &self,
        old: Vec<u32>,
        new: Vec<[u32; 4]>,
        old_worst: f64,
        kind: Kind,
    ) -> Option<(f64, Plan)> {
        let w = self.worst(&new)?;
        (w > old_worst).then_some((w, Plan::Replace { old, new, kind }))
    }

    /// Flips the edge `a`–`b`, if exactly three tetrahedra surround it, to the two sharing the
    /// face of their far corners.
    fn flip_32(&self, a: u32, b: u32) -> Option<(f64, Plan)> {
        let (ring, new) = self.flip_32_tets(a, b)?;
        let old_worst = self.worst_of(&ring);
        self.plan(ring, new, old_worst, Kind::Flip32)
    }

    /// The three tetrahedra around edge `a`–`b` a 3 → 2 flip replaces, and the two it makes
    /// (not checked).
    fn flip_32_tets(&self, a: u32, b: u32) -> Option<(Vec<u32>, Vec<[u32; 4]>)> {
        let ring = self.holding(&[a, b])?;
        if ring.len() != 3 || !self.may_replace(&ring) {
            return None;
        }
        // Closed around the edge: three far corners, each in two of the tetrahedra.
        let mut far: Vec<u32> = ring
            .iter()
            .flat_map(|&t| self.tets[t as usize])
            .filter(|&v| v != a && v != b)
            .collect();
        far.sort_unstable();
        if far.len() != 6 || far.chunks(2).any(|c| c[0] != c[1]) {
            return None;
        }
        let (mut x, y, mut z) = (far[0], far[2], far[4]);
        let p = |v: u32| self.point(v);
        if !positive(p(x), p(y), p(z), p(a)) {
            std::mem::swap(&mut x, &mut z);
        }
        Some((ring, vec![[x, y, z, a], [x, z, y, b]]))
    }

    /// Removes the interior edge `a`–`b` if four to [`RING`] tetrahedra surround it: the ring of
    /// their far corners is triangulated (the triangulation whose worst element is best, by
    /// dynamic programming) and each triangle joined to `a` and to `b`.
    fn remove_edge(&self, a: u32, b: u32) -> Option<(f64, Plan)> {
        let (ring, new, worst) = self.edge_removal_tets(a, b)?;
        let old_worst = self.worst_of(&ring);
        (worst > old_worst).then_some((
            worst,
            Plan::Replace {
                old: ring,
                new,
                kind: Kind::EdgeRemoval,
            },
        ))
    }

    /// The tetrahedra around edge `a`–`b` its removal replaces, the best triangulation's
    /// tetrahedra (all positive) and their worst score.
    fn edge_removal_tets(&self, a: u32, b: u32) -> Option<(Vec<u32>, Vec<[u32; 4]>, f64)> {
        let ring = self.holding(&[a, b])?;
        let n = ring.len();
        if !(4..=RING).contains(&n) || !self.may_replace(&ring) {
            return None;
        }
        // The far corners in order around the edge: each tetrahedron joins two neighbours.
        let pairs: Vec<[u32; 2]> = ring
            .iter()
            .map(|&t| {
                let mut far = self.tets[t as usize]
                    .into_iter()
                    .filter(|&v| v != a && v != b);
                [far.next().unwrap_or(a), far.next().unwrap_or(a)]
            })
            .collect();
        let mut cycle = vec![pairs[0][0], pairs[0][1]];
        let mut used = vec![false; n];
        used[0] = true;
        while cycle.len() < n {
            let last = cycle[cycle.len() - 1];
            let k = (0..n).find(|&k| !used[k] && pairs[k].contains(&last))?;
            used[k] = true;
            cycle.push(if pairs[k][0] == last {
                pairs[k][1]
            } else {
                pairs[k][0]
            });
        }
        // Closed: the last unused tetrahedron joins the last corner back to the first.
        let k = (0..n).find(|&k| !used[k])?;
        let (first, last) = (cycle[0], cycle[n - 1]);
        if !(pairs[k].contains(&first) && pairs[k].contains(&last)) || first == last {
            return None;
        }
        // The tetrahedra of triangle (i, k, j), i < k < j along the cycle, with each end of the
        // edge, all turned one way: the way that makes them positive when the cycle turns
        // about the edge as the ring's tetrahedra say (the first of them holds corners 0
        // and 1). Any that is then not positive rules the triangle out.
        let turned = {
            let p = |v: u32| self.point(v);
            positive(p(cycle[0]), p(cycle[1]), p(a), p(b))
        };
        let pair = |i: usize, k: usize, j: usize| -> [[u32; 4]; 2] {
            let (x, y, z) = (cycle[i], cycle[k], cycle[j]);
            if turned {
                [[x, z, y, a], [x, y, z, b]]
            } else {
                [[x, y, z, a], [x, z, y, b]]
            }
        };
        let score_of = |i: usize, k: usize, j: usize, me: &Self| {
            me.worst(&pair(i, k, j)).unwrap_or(f64::NEG_INFINITY)
        };
        // best[i][j]: the best worst score of a triangulation of the polygon i..=j.
        let mut best = [[f64::INFINITY; RING]; RING];
        let mut split = [[0usize; RING]; RING];
        for len in 2..n {
            for i in 0..n - len {
                let j = i + len;
                best[i][j] = f64::NEG_INFINITY;
                for k in i + 1..j {
                    let w = best[i][k].min(best[k][j]).min(score_of(i, k, j, self));
                    if w > best[i][j] {
                        best[i][j] = w;
                        split[i][j] = k;
                    }
                }
            }
        }
        if !best[0][n - 1].is_finite() {
            return None;
        }
        let mut new: Vec<[u32; 4]> = Vec::with_capacity(2 * n - 4);
        let mut todo = vec![(0, n - 1)];
        while let Some((i, j)) = todo.pop() {
            if j < i + 2 {
                continue;
            }
            let k = split[i][j];
            new.extend(pair(i, k, j));
            todo.push((i, k));
            todo.push((k, j));
        }
        Some((ring, new, best[0][n - 1]))
    }

    /// Moves Steiner or grid point `v` by a pattern search to where the worst of its tetrahedra scores
    /// best, every one of them staying positive.
    fn move_point(&mut self, v: u32) -> Option<(f64, Plan)> {
        let star = self.holding(&[v])?;
        // No point on an interface between labels moves.
        let &first = star.first()?;
        let label = self.label(first);
        if star.iter().any(|&t| self.label(t) != label) {
            return None;
        }
        let star: Vec<[u32; 4]> = star.iter().map(|&t| self.tets[t as usize]).collect();
        let (at, w) = self.move_within(v, &star)?;
        Some((w, Plan::Move { v, at }))
    }

    /// Of the faces at point `v` (sorted, each sorted), those used once: walls, each in a plane
    /// of the grid's box through `v`. Returns which axes' planes hold them and the walls, or
    /// `None` when one lies in no such plane.
    fn wall_planes(&self, v: u32, faces: &[[u32; 3]]) -> Option<([bool; 3], Vec<[u32; 3]>)> {
        let at = self.positions[v as usize];
        let mut planes = [false; 3];
        let mut walls = Vec::new();
        let mut i = 0;
        while i < faces.len() {
            if faces.get(i + 1) == Some(&faces[i]) {
                i += 2;
                continue;
            }
            let f = faces[i];
            let a = (0..3).find(|&a| f.iter().all(|&w| self.positions[w as usize][a] == at[a]))?;
            planes[a] = true;
            walls.push(f);
            i += 1;
        }
        Some((planes, walls))
    }

    /// Where point `v` scores best with tetrahedra `star` around it (all of them holding it), if
    /// somewhere else than where it is, and the worst score there.
    fn move_within(&mut self, v: u32, star: &[[u32; 4]]) -> Option<([f32; 3], f64)> {
        // A point inside the mesh moves freely: every face at it is shared by two tetrahedra.
        // A face at it used once is on the boundary; a grid or Steiner point is no surface
        // vertex, so such a face is a wall, in a plane of the grid's box, and the point may
        // slide within that plane (along the line where two meet; a box corner stays): the
        // wall triangles stay in their plane and, every tetrahedron kept positive, tile the
        // same polygon. A face in no axis plane through the point (a grid turned by a
        // direction matrix) keeps it where it is.
        let mut faces: Vec<[u32; 3]> = star
            .iter()
            .flat_map(|t| {
                (0..4).filter(|&k| t[k] != v).map(move |k| {
                    let mut f = face(*t, k);
                    f.sort_unstable();
                    f
                })
            })
            .collect();
        faces.sort_unstable();
        let (fixed, _) = self.wall_planes(v, &faces)?;
        if fixed.iter().all(|&x| x) {
            return None;
        }
        let start = self.positions[v as usize];
        let before = self.worst(star)?;
        self.axes = [0, 1, 2].map(|a| !fixed[a]);
        let (here, w) = self.search(v, star, start, before);
        self.axes = [true; 3];
        self.positions[v as usize] = start;
        (here != start).then_some((here, w))
    }

    /// Steiner or grid point `v` taken out: the tetrahedra around it re-made as a cone from one of its
    /// neighbours `w` (the edge `vw` contracted onto `w`), the neighbour that gives the best
    /// worst score, if that beats theirs. A point inserted where it helped once can later hold
    /// two thin elements where one good one fits: a boundary edge whose region angle is under
    /// twice the bound wants a single element, and no flip takes the point away. A point on
    /// a wall merges only into a neighbour in the same plane(s) of the box, its wall triangles
    /// moving with it (those holding both go with their elements); the surface is never
    /// touched. The cone tiles the same polyhedron when every new tetrahedron is positive and
    /// the faces it leaves outside are the old ones (the walls at the point moved).
    fn remove_point(&self, v: u32) -> Option<(f64, Plan)> {
        if !(self.steiner.contains(&v) || self.grid.contains(&v)) || !self.known[v as usize] {
            return None;
        }
        let star = self.holding(&[v])?;
        if star.is_empty() || !self.may_replace(&star) {
            return None;
        }
        let tets: Vec<[u32; 4]> = star.iter().map(|&t| self.tets[t as usize]).collect();
        // The link: the faces opposite `v`, each sorted; and the faces at `v`, shared twice
        // inside the mesh, once on a wall.
        let mut at_v: Vec<[u32; 3]> = Vec::with_capacity(3 * tets.len());
        let mut outside: Vec<[u32; 3]> = Vec::with_capacity(tets.len());
        for t in &tets {
            let k = t.iter().position(|&x| x == v)?;
            for j in 0..4 {
                let mut f = face(*t, j);
                f.sort_unstable();
                if j == k {
                    outside.push(f);
                } else {
                    at_v.push(f);
                }
            }
        }
        at_v.sort_unstable();
        // Faces at `v` used once are walls: each in a plane of the grid's box through `v`,
        // which `w` must lie in too so that the walls keep their planes.
        let at = self.positions[v as usize];
        let (planes, walls) = self.wall_planes(v, &at_v)?;
        let old_worst = self.worst_of(&star);
        let mut neighbours: Vec<u32> = outside.iter().flatten().copied().collect();
        neighbours.sort_unstable();
        neighbours.dedup();
        let mut best: Option<(f64, u32, Vec<[u32; 4]>)> = None;
        for w in neighbours {
            if (0..3).any(|a| planes[a] && self.positions[w as usize][a] != at[a]) {
                continue;
            }
            let new: Vec<[u32; 4]> = tets
                .iter()
                .filter(|t| !t.contains(&w))
                .map(|t| t.map(|x| if x == v { w } else { x }))
                .collect();
            let bound = best.as_ref().map_or(old_worst, |b| b.0);
            let Some(worst) = self.worst_above(&new, bound) else {
                continue;
            };
            // The cone's outside faces are the link's faces away from `w`; with the faces at
            // `w` it covers, the old outside: the link, and the walls at `v` moved to `w`
            // (those at both end with the elements that held both).
            let mut expected: Vec<[u32; 3]> = walls
                .iter()
                .filter(|f| !f.contains(&w))
                .map(|f| {
                    let mut f = f.map(|x| if x == v { w } else { x });
                    f.sort_unstable();
                    f
                })
                .chain(outside.iter().copied())
                .collect();
            expected.sort_unstable();
            if boundary(&new) != expected {
                continue;
            }
            best = Some((worst, w, new));
        }
        let merge = !walls.is_empty();
        best.map(|(worst, w, new)| {
            let merge = merge.then_some([v, w]);
            (
                worst,
                Plan::Remove {
                    old: star,
                    new,
                    merge,
                },
            )
        })
    }

    /// A flip or edge removal at `t` that does not help alone, followed by a move of one of
    /// the new tetrahedra's free corners that makes the whole better than before. A boundary
    /// triangle with two corners close together (a needle, where the surface passes close by
    /// a grid point kept off it) needs its element's fourth corner beside its short edge; the
    /// point there is usually a neighbour's, and the flip that joins it to the needle leaves
    /// the Steiner point that served the needle in the way until that point moves too.
    fn remake_and_move(&mut self, t: u32) -> Option<(f64, Plan)> {
        let tet = self.tets[t as usize];
        let mut candidates: Vec<(Vec<u32>, Vec<[u32; 4]>, Kind)> = Vec::new();
        for d in tet {
            if let Some((old, new)) = self.flip_23_tets(t, d) {
                candidates.push((old, new, Kind::Flip23));
            }
        }
        for i in 0..4 {
            for j in i + 1..4 {
                if let Some((old, new)) = self.flip_32_tets(tet[i], tet[j]) {
                    candidates.push((old, new, Kind::Flip32));
                }
                if let Some((old, new, _)) = self.edge_removal_tets(tet[i], tet[j]) {
                    candidates.push((old, new, Kind::EdgeRemoval));
                }
            }
        }
        let mut best: Option<(f64, Plan)> = None;
        for (old, new, kind) in candidates {
            if self.worst(&new).is_none() {
                continue;
            }
            let old_worst = self.worst_of(&old);
            let mut corners: Vec<u32> = new.iter().flatten().copied().collect();
            corners.sort_unstable();
            corners.dedup();
            for v in corners {
                let free = self.steiner.contains(&v) || self.grid.contains(&v);
                if !free || !self.known[v as usize] {
                    continue;
                }
                let Some(around) = self.holding(&[v]) else {
                    continue;
                };
                let label = self.label(old[0]);
                if around.iter().any(|&a| self.label(a) != label) {
                    continue;
                }
                let before = around
                    .iter()
                    .map(|&a| self.score_of(a))
                    .fold(old_worst, f64::min);
                let mut star: Vec<[u32; 4]> = around
                    .iter()
                    .filter(|a| !old.contains(a))
                    .map(|&a| self.tets[a as usize])
                    .collect();
                star.extend(new.iter().filter(|n| n.contains(&v)));
                let Some((at, w)) = self.move_within(v, &star) else {
                    continue;
                };
                let rest: Vec<[u32; 4]> = new.iter().filter(|n| !n.contains(&v)).copied().collect();
                let w = self.worst(&rest).map_or(w, |r| w.min(r));
                if w > before && best.as_ref().is_none_or(|b| w > b.0) {
                    let (old, new) = (old.clone(), new.clone());
                    best = Some((
                        w,
                        Plan::Remake {
                            old,
                            new,
                            kind,
                            v,
                            at,
                        },
                    ));
                }
            }
        }
        best
    }

    /// A pattern search for `v`'s position, from `start` (where the worst of `star` scores
    /// `before`): steps along the axes, a quarter of the mean edge length at first, halved when
    /// no step helps ([`STEPS`]). Returns the best position and its score; leaves `v` there.
    /// The worst score is not smooth: where two elements' angles trade off, no axis step may
    /// raise both while a diagonal does, so the extended sweeps and the second round also step
    /// along the twenty diagonals (the default sweep: 31 → 27 runs outside the range; in
    /// every sweep it was 28, more time for less).
    fn search(
        &mut self,
        v: u32,
        star: &[[u32; 4]],
        start: [f32; 3],
        before: f64,
    ) -> ([f32; 3], f64) {
        self.positions[v as usize] = start;
        let mut length = 0.0f64;
        let mut count = 0.0f64;
        for t in star {
            for &w in t {
                if w != v {
                    let d = super::check::sub(self.point(w), self.point(v));
                    length += super::check::dot(d, d).sqrt();
                    count += 1.0;
                }
            }
        }
        let mut step = 0.25 * length / count.max(1.0);
        let mut best = before;
        let mut here = start;
        let rounds_at_most = if self.extended { 8 * STEPS } else { STEPS };
        let mut halvings = 0;
        let mut rounds = 0;
        while halvings < STEPS && rounds < rounds_at_most {
            rounds += 1;
            let mut moved = false;
            let diagonal = self.extended || self.bar > POOR;
            for d in DIRECTIONS.iter().take(if diagonal { 26 } else { 6 }) {
                if (0..3).any(|a| d[a] != 0 && !self.axes[a]) {
                    continue;
                }
                let norm = d.iter().map(|&c| f64::from(c * c)).sum::<f64>().sqrt();
                let mut q = here.map(f64::from);
                for a in 0..3 {
                    q[a] += step * f64::from(d[a]) / norm;
                }
                let q = q.map(|c| c as f32);
                self.positions[v as usize] = q;
                if let Some(w) = self.worst_above(star, best) {
                    best = w;
                    here = q;
                    moved = true;
                }
            }
            if !moved {
                step *= 0.5;
                halvings += 1;
            }
        }
        self.positions[v as usize] = here;
        (here, best)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn worst(positions: &[[f32; 3]], tets: &[[u32; 4]]) -> f64 {
        tets.iter()
            .map(|t| score(t.map(|v| positions[v as usize].map(f64::from))))
            .fold(f64::INFINITY, f64::min)
    }

    fn volume(positions: &[[f32; 3]], tets: &[[u32; 4]]) -> f64 {
        tets.iter()
            .map(|t| {
                let p = t.map(|v| positions[v as usize].map(f64::from));
                let [a, b, c] = [1, 2, 3].map(|k| super::super::check::sub(p[k], p[0]));
                super::super::check::dot(a, super::super::check::cross(b, c)) / 6.0
            })
            .sum()
    }

    /// A triangle `c, d, e` in the plane z = 0 with `a` just above it (off centre) and `b`
    /// well below.
    fn bipyramid() -> Vec<[f32; 3]> {
        vec![
            [0.3, 0.0, 0.1],
            [0.0, 0.0, -1.0],
            [1.0, 0.0, 0.0],
            [-0.5, 0.866, 0.0],
            [-0.5, -0.866, 0.0],
        ]
    }

    #[test]
    fn two_flat_tetrahedra_become_three_better_ones() {
        let mut positions = bipyramid();
        let (a, b, c, d, e) = (0, 1, 2, 3, 4);
        let mut tets = vec![[c, d, e, a], [c, e, d, b]];
        let before = worst(&positions, &tets);
        assert!(before < POOR, "{before}");
        let (outline, volume_before) = (boundary(&tets), volume(&positions, &tets));
        let stats = improve(&mut positions, &mut tets, None, 0..0, 5..5);
        assert_eq!((stats.flips_23, tets.len()), (1, 3), "{stats:?}");
        let after = worst(&positions, &tets);
        assert!(after > 15.0, "{after}");
        assert_eq!(boundary(&tets), outline);
        assert!((volume(&positions, &tets) - volume_before).abs() < 1e-12);
        assert!(tets.iter().all(|t| {
            let p = t.map(|v| positions[v as usize].map(f64::from));
            positive(p[0], p[1], p[2], p[3])
        }));
    }

    #[test]
    fn a_point_splitting_a_narrow_wedge_is_taken_out() {
        // One element with a 17° dihedral angle at a–b (fair on its own), cut into four from a
        // point inside it: the two at a–b share those 17°, one at 8.5° or less wherever the
        // point goes, and no flip of four elements around a point makes one.
        let angle = 17f32.to_radians();
        let mut positions = vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.5, 1.0, 0.0],
            [0.5, angle.cos(), angle.sin()],
            [0.45, 0.6, 0.08],
        ];
        let (a, b, c, d, s) = (0, 1, 2, 3, 4);
        let whole = [a, b, c, d];
        let p = whole.map(|v| positions[v as usize].map(f64::from));
        assert!(positive(p[0], p[1], p[2], p[3]));
        let mut tets: Vec<[u32; 4]> = (0..4)
            .map(|k| {
                let mut t = whole;
                t[k] = s;
                t
            })
            .collect();
        let before = worst(&positions, &tets);
        assert!(before < 8.6, "{before}");
        let (outline, volume_before) = (boundary(&tets), volume(&positions, &tets));
        let stats = improve(&mut positions, &mut tets, None, 4..4, 4..5);
        // The point is gone from the list too (and any new point that served it on the way),
        // the corners kept their numbers.
        assert!(stats.removed >= 1, "{stats:?}");
        assert_eq!(positions.len(), 4, "{stats:?} {positions:?} {tets:?}");
        assert_eq!(tets.len(), 1);
        assert!(worst(&positions, &tets) > 16.9);
        assert_eq!(boundary(&tets), outline);
        assert!((volume(&positions, &tets) - volume_before).abs() < 1e-12);
    }

    #[test]
    fn a_wall_point_splitting_a_narrow_wedge_is_taken_out_and_its_walls_follow() {
        // An element standing on a wall (the plane z = 0) with a 17° angle at its edge a–d
        // (d straight over a, so the angle is the wall triangle's at a), cut into three from a
        // point s on the wall, on the bisector: the two at a–d share the 17° evenly, so no
        // move of s within the wall and no new point helps. Taken out, it leaves the one
        // element and its wall triangle.
        let angle = 17f32.to_radians();
        let mut positions = vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [angle.cos(), angle.sin(), 0.0],
            [0.0, 0.0, 0.5],
            [0.6 * (angle / 2.0).cos(), 0.6 * (angle / 2.0).sin(), 0.0],
        ];
        let (a, b, c, d, s) = (0, 1, 2, 3, 4);
        let p = |v: u32, positions: &[[f32; 3]]| positions[v as usize].map(f64::from);
        let oriented = |t: [u32; 4], positions: &[[f32; 3]]| {
            let q = t.map(|v| p(v, positions));
            if positive(q[0], q[1], q[2], q[3]) {
                t
            } else {
                [t[1], t[0], t[2], t[3]]
            }
        };
        let mut tets: Vec<[u32; 4]> = [[s, a, b, d], [s, b, c, d], [s, c, a, d]]
            .into_iter()
            .map(|t| oriented(t, &positions))
            .collect();
        // The faces away from d, outward as the check orients a tetrahedron's faces.
        let walls_of = |tets: &[[u32; 4]]| -> Vec<[u32; 3]> {
            let mut out: Vec<[u32; 3]> = tets
                .iter()
                .flat_map(|&[i, j, k, l]| [[i, k, j], [i, j, l], [i, l, k], [j, k, l]])
                .filter(|f| !f.contains(&d))
                .map(|f| {
                    let r = f.iter().position(|v| v == f.iter().min().unwrap()).unwrap();
                    [f[r], f[(r + 1) % 3], f[(r + 2) % 3]]
                })
                .collect();
            out.sort_unstable();
            out
        };
        let mut walls = walls_of(&tets);
        assert_eq!(walls.len(), 3);
        let before = worst(&positions, &tets);
        assert!(before < 8.6, "{before}");
        let volume_before = volume(&positions, &tets);
        let stats = improve_with(
            &mut positions,
            &mut tets,
            &mut walls,
            None,
            4..4,
            4..5,
            &mut || Ok(()),
        )
        .unwrap();
        assert!(stats.removed >= 1, "{stats:?}");
        assert_eq!((positions.len(), tets.len()), (4, 1), "{stats:?}");
        assert!(worst(&positions, &tets) > 16.9);
        assert!((volume(&positions, &tets) - volume_before).abs() < 1e-12);
        let after = walls_of(&tets);
        assert_eq!(after.len(), 1);
        let r = walls[0].iter().position(|&v| v == a).unwrap();
        assert_eq!(
            [walls[0][r], walls[0][(r + 1) % 3], walls[0][(r + 2) % 3]],
            after[0]
        );
    }

    #[test]
    fn a_flip_that_would_make_things_worse_is_not_taken() {
        // Around the edge a–b: three tetrahedra scoring about 10.7°; the two of the 3 → 2 flip
        // would score 2.6°.
        let mut positions = bipyramid();
        positions[0] = [0.6, 0.0, 0.05];
        let (a, b, c, d, e) = (0, 1, 2, 3, 4);
        let mut tets = vec![[a, b, c, d], [a, b, d, e], [a, b, e, c]];
        let p = |v: usize| positions[v].map(f64::from);
        for t in &mut tets {
            if !positive(
                p(t[0] as usize),
                p(t[1] as usize),
                p(t[2] as usize),
                p(t[3] as usize),
            ) {
                t.swap(0, 1);
            }
        }
        let before = worst(&positions, &tets);
        let volume_before = volume(&positions, &tets);
        let stats = improve(&mut positions, &mut tets, None, 0..0, 5..5);
        assert_eq!(stats.flips_32, 0, "{stats:?}");
        assert!(worst(&positions, &tets) >= before);
        assert!((volume(&positions, &tets) - volume_before).abs() < 1e-9);
    }

    /// `n` tetrahedra around the edge from `a` (index 0) to `b` (index 1), the ring of far
    /// corners (indices 2..) at the given angles and radii, all turned positive.
    fn ring(
        a: [f32; 3],
        b: [f32; 3],
        corners: &[(f32, f32, f32)],
    ) -> (Vec<[f32; 3]>, Vec<[u32; 4]>) {
        let mut positions = vec![a, b];
        positions.extend(
            corners
                .iter()
                .map(|&(angle, radius, z)| [radius * angle.cos(), radius * angle.sin(), z]),
        );
        let n = corners.len() as u32;
        let tets = (0..n)
            .map(|i| {
                let t = [0, 1, 2 + i, 2 + (i + 1) % n];
                let p = t.map(|v| positions[v as usize].map(f64::from));
                if positive(p[0], p[1], p[2], p[3]) {
                    t
                } else {
                    [1, 0, t[2], t[3]]
                }
            })
            .collect();
        (positions, tets)
    }

    proptest::proptest! {
        /// Rings of four to seven tetrahedra around an edge, the corners scattered about a
        /// circle: whatever the improvement does (edge removals among it), the union, the volume
        /// and every element's sign are kept and the worst element gets no worse.
        #[test]
        fn edge_removal_keeps_the_ring_and_lifts_its_worst(
            n in 4usize..=7,
            jitter in proptest::collection::vec((-0.3f32..0.3, 0.6f32..1.4, -0.15f32..0.15), 7),
            height in 0.05f32..1.5,
            tilt in -0.4f32..0.4,
        ) {
            let corners: Vec<(f32, f32, f32)> = (0..n)
                .map(|i| {
                    let (da, r, z) = jitter[i];
                    (std::f32::consts::TAU * (i as f32 + da) / n as f32, r, z)
                })
                .collect();
            let (mut positions, mut tets) = ring([tilt, 0.0, height], [0.0, tilt, -height], &corners);
            let p = |ps: &[[f32; 3]], t: &[u32; 4]| t.map(|v| ps[v as usize].map(f64::from));
            // Only rings whose tetrahedra are all positive (around the edge, not folded).
            let around = tets.iter().all(|t| {
                let q = p(&positions, t);
                positive(q[0], q[1], q[2], q[3])
            });
            proptest::prop_assume!(around);
            let before = worst(&positions, &tets);
            let (outline, volume_before) = (boundary(&tets), volume(&positions, &tets));
            improve(&mut positions, &mut tets, None, 0..0, 0..0);
            proptest::prop_assert!(worst(&positions, &tets) >= before);
            proptest::prop_assert!((volume(&positions, &tets) - volume_before).abs() < 1e-9);
            let all_positive = tets.iter().all(|t| {
                let q = p(&positions, t);
                positive(q[0], q[1], q[2], q[3])
            });
            proptest::prop_assert!(all_positive);
            // New points may split the outer faces' neighbourhoods, never the faces themselves.
            let after = boundary(&tets);
            proptest::prop_assert_eq!(after, outline);
        }
    }

    #[test]
    fn an_edge_a_corner_nearly_touches_is_removed() {
        // An edge with one of the five corners around it almost on it: the two tetrahedra at
        // that corner are needles; the fan of the pentagon from that corner, joined to both
        // ends of the edge, has none.
        let corners: Vec<(f32, f32, f32)> = (0..5)
            .map(|i| {
                (
                    std::f32::consts::TAU * i as f32 / 5.0,
                    if i == 0 { 0.05 } else { 1.0 },
                    0.0,
                )
            })
            .collect();
        let (mut positions, mut tets) = ring([0.0, 0.0, 0.6], [0.0, 0.0, -0.6], &corners);
        let before = worst(&positions, &tets);
        let outline = boundary(&tets);
        let stats = improve(&mut positions, &mut tets, None, 0..0, 0..0);
        let after = worst(&positions, &tets);
        assert_eq!(
            (stats.edge_removals, tets.len()),
            (1, 6),
            "{stats:?} {before} {after}"
        );
        assert!(after > before, "{before} -> {after}");
        assert_eq!(boundary(&tets), outline);
    }

    #[test]
    fn tetrahedra_of_grid_points_and_interfaces_stay() {
        let mut positions = bipyramid();
        let (a, b, c, d, e) = (0, 1, 2, 3, 4);
        let original = vec![[c, d, e, a], [c, e, d, b]];
        // Every vertex a grid point: the lattice is kept.
        let mut tets = original.clone();
        let stats = improve(&mut positions, &mut tets, None, 0..5, 5..5);
        assert_eq!((stats.poor, tets.clone()), (0, original.clone()));
        // Two labels: the face between them is an interface.
        let mut tets = original.clone();
        let mut labels = vec![0, 1];
        improve(&mut positions, &mut tets, Some(&mut labels), 0..0, 5..5);
        assert_eq!((tets, labels), (original, vec![0, 1]));
    }
}
