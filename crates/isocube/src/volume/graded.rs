//! A graded interior: away from the surface, cells are gathered into cubes of 2, 4, 8, …
//! cells on a side, each cut into its six Kuhn tetrahedra like a single cell.
//!
//! Kuhn triangulations of the grid at spacings `h` and `2h` are nested: every Kuhn tetrahedron
//! of a cell lies inside one Kuhn tetrahedron of the cube of eight cells holding it (within a
//! cube, ordering the coordinates' offsets orders those of its cells), and so on up. A cube
//! meeting only cubes of its own size is its six Kuhn tetrahedra; one touching a finer cube
//! finds the finer cube's corners at midpoints of its edges and of its faces' Kuhn diagonals
//! (the cubes are balanced: neighbours across a face or an edge differ by one size at most, so
//! those midpoints are the only points there; a cube touching another at a corner only shares
//! a grid point with it). Such a *transition* cube cuts each face's two Kuhn triangles at the
//! midpoints present by a rule that reads only the face, so both sides of a face cut it alike
//! and a face next to a finer cube is cut into the finer cube's four triangles. It is then
//! coned over its faces from an apex: its lowest corner when no midpoint lies on an edge
//! ending there, else its highest corner likewise, else its centre (and from the centre too
//! where a corner's cone would leave [`CORNER_CONES`], on long cells). The Kuhn tetrahedra are
//! the cone from the lowest corner over the three faces away from it; a midpoint on one of
//! those faces' edges that the faces at the apex share splits a triangle there at the point
//! joined to the apex, as the face rule does. The mesh is conforming by construction, and its
//! elements come in a few shapes, whatever the sizes: the Kuhn tetrahedron (dihedral angles
//! 45°, 60°, 90°) and the cones of transition cubes, whose angles [`tests`] enumerates over
//! every pattern of midpoints (17.72° to 135.00° from a corner, 19.47° to 144.74° from the
//! centre). On long or flat cells the cones widen as the Kuhn tetrahedra do; up to 3:1 they
//! stay within [10°, 165°] ([`Grading::MAX_ASPECT`]; beyond, the interior stays uniform).
//!
//! Every corner and centre is a grid point, so a graded mesh adds no point: it leaves grid
//! points out (those strictly inside cubes, but the centres coned from).
//!
//! Where cubes may go: a cube of level `k` (side `2^k` cells, its corner a multiple of `2^k`)
//! when all its cells are filled whole (every corner inside, no surface), and so are all cubes
//! of its level within [`Grading::layers`] of it (cubes beyond the grid count as whole, cubes
//! the grid cuts do not). Each cell takes the largest such cube holding it; then cubes touching
//! cells more than one level finer across a face or an edge are split until none does.

use rayon::prelude::*;

use super::check::{cross, dot, sub};
use super::coords;
use super::quality::dihedral_extremes;

/// How the interior of a volume mesh coarsens away from the surface. The default
/// ([`Grading::DEFAULT`], as [`crate::extract::ExtractOptions`] and
/// [`crate::extract::LabelOptions`] start) grades, cubes up to 16 cells on a side;
/// [`Grading::UNIFORM`] cuts every inside cell into six tetrahedra.
///
/// ```
/// use isocube::volume::Grading;
/// let grading = Grading::default();
/// assert_eq!(grading.largest_cells(), 1 << grading.max_level);
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Grading {
    /// The largest cubes are `2^max_level` cells on a side (0: every cell on its own, the
    /// uniform mesh).
    pub max_level: u8,
    /// Cubes of each size keep this many cubes of their size between them and the cells the
    /// surface passes through (0: only the balance between neighbours, sizes doubling from
    /// one cube to the next).
    pub layers: u8,
}

impl Default for Grading {
    fn default() -> Self {
        Grading::DEFAULT
    }
}

impl Grading {
    /// No coarsening: every inside cell is cut into six Kuhn tetrahedra.
    pub const UNIFORM: Grading = Grading {
        max_level: 0,
        layers: 0,
    };

    /// The default: cubes up to 16 cells on a side, sizes doubling from one cube to the next.
    pub const DEFAULT: Grading = Grading {
        max_level: 4,
        layers: 0,
    };

    /// The deepest level a grading may ask for (cubes of 2^15 cells: more than any grid).
    pub const MAX_LEVEL: u8 = 15;

    /// The grading whose largest cubes are the largest power of two cells within `cells`
    /// (uniform under 2), cubes keeping `layers` cubes of their size from the cut cells.
    ///
    /// ```
    /// use isocube::volume::Grading;
    /// assert_eq!(Grading::within(20.0, 0).largest_cells(), 16);
    /// assert_eq!(Grading::within(1.5, 1), Grading { max_level: 0, layers: 1 });
    /// ```
    pub fn within(cells: f64, layers: u8) -> Grading {
        let max_level = if cells >= 2.0 {
            (cells.log2().floor().min(f64::from(Grading::MAX_LEVEL))) as u8
        } else {
            0
        };
        Grading { max_level, layers }
    }

    /// The side of the largest cubes, in cells.
    pub fn largest_cells(&self) -> usize {
        1 << self.max_level
    }

    /// The longest cells, side to side, whose transition cubes keep every element within
    /// [10°, 165°] (checked over every pattern of midpoints at 1:1:3, 3:3:1, 1:2:3; at 1:1:4
    /// the cones reach 9.45°, at 4:4:1 166.37°, where the Kuhn tetrahedra alone keep 14.04°).
    pub const MAX_ASPECT: f64 = 3.0;

    /// This grading on cells of sides `spacing`: itself, or [`Grading::UNIFORM`] on cells
    /// longer than [`Grading::MAX_ASPECT`] to one (there a graded interior would be worse
    /// shaped than the uniform one).
    ///
    /// ```
    /// use isocube::volume::Grading;
    /// let graded = Grading::default();
    /// assert_eq!(graded.on_cells([0.5, 0.5, 1.5]), graded);
    /// assert_eq!(graded.on_cells([0.5, 0.5, 2.0]), Grading::UNIFORM);
    /// ```
    pub fn on_cells(self, spacing: [f64; 3]) -> Grading {
        let sides = spacing.map(f64::abs);
        let longest = sides.iter().copied().fold(0.0, f64::max);
        let shortest = sides.iter().copied().fold(f64::INFINITY, f64::min);
        if longest <= Grading::MAX_ASPECT * shortest * (1.0 + 1e-9) {
            self
        } else {
            Grading::UNIFORM
        }
    }
}

/// The level of the cube holding each cell (0: the cell is filled alone, whole or cut).
pub(super) struct Cubes {
    cells: [usize; 3],
    level: Vec<u8>,
    /// The cells' sides (for the shapes of transition cones).
    spacing: [f64; 3],
}

impl Cubes {
    /// The cubes over a grid of `cells` cells of sides `spacing`, `whole[c]` telling whether
    /// cell `c` (x fastest) is filled with its six Kuhn tetrahedra on grid points alone.
    pub(super) fn new(
        cells: [usize; 3],
        spacing: [f64; 3],
        whole: Vec<bool>,
        grading: Grading,
    ) -> Cubes {
        let n = cells[0] * cells[1] * cells[2];
        debug_assert_eq!(whole.len(), n);
        let spacing = spacing.map(f64::abs);
        let top = grading.max_level.min(Grading::MAX_LEVEL);
        if top == 0 || n == 0 {
            return Cubes {
                cells,
                level: vec![0u8; n],
                spacing,
            };
        }
        // Whole cubes level by level (a cube the grid cuts is not whole).
        let mut whole_at: Vec<(Vec<bool>, [usize; 3])> = vec![(whole, cells)];
        for _ in 1..=top {
            let (below, d) = whole_at.last().expect("level 0 is there");
            let up = d.map(|x| x / 2);
            if up.contains(&0) {
                break;
            }
            let flags: Vec<bool> = (0..up[0] * up[1] * up[2])
                .into_par_iter()
                .map(|c| {
                    let [x, y, z] = coords(c, up);
                    (0..8).all(|o| {
                        let q = [2 * x + (o & 1), 2 * y + (o >> 1 & 1), 2 * z + (o >> 2 & 1)];
                        below[q[0] + d[0] * (q[1] + d[1] * q[2])]
                    })
                })
                .collect();
            whole_at.push((flags, up));
        }
        // The cells' own flags are done with before their levels are made (a byte a cell each).
        whole_at[0].0 = Vec::new();
        let mut level = vec![0u8; n];
        // Where a cube may go: whole with every cube of its level within the layers.
        let m = usize::from(grading.layers);
        let allowed: Vec<(Vec<bool>, [usize; 3])> = whole_at
            .iter()
            .enumerate()
            .skip(1)
            .map(|(k, (flags, d))| (spread(flags, *d, cells, k, m), *d))
            .collect();
        level.par_iter_mut().enumerate().for_each(|(c, l)| {
            let p = coords(c, cells);
            for (k, (flags, d)) in allowed.iter().enumerate().rev() {
                let q = p.map(|x| x >> (k + 1));
                if q.iter().zip(d).all(|(a, b)| a < b) && flags[q[0] + d[0] * (q[1] + d[1] * q[2])]
                {
                    *l = (k + 1) as u8;
                    break;
                }
            }
        });
        let mut cubes = Cubes {
            cells,
            level,
            spacing,
        };
        cubes.balance();
        cubes
    }

    /// Whether each grid point (x fastest, over the cells' corners) can be a vertex of the
    /// mesh: a corner of a single cell, or a corner or the centre of a cube.
    pub(super) fn grid_points(&self) -> Vec<bool> {
        let d = self.cells.map(|x| x + 1);
        let mut used: Vec<bool> = (0..d[0] * d[1] * d[2])
            .into_par_iter()
            .map(|p| {
                self.cells_around(coords(p, d))
                    .any(|cell| self.level(cell) == 0)
            })
            .collect();
        for (o, k) in self.origins(1) {
            let s = 1usize << k;
            let mut mark = |q: [usize; 3]| used[q[0] + d[0] * (q[1] + d[1] * q[2])] = true;
            for b in 0..8 {
                mark(std::array::from_fn(|a| o[a] + s * (b >> a & 1)));
            }
            mark(add(o, [s / 2; 3]));
        }
        used
    }

    /// About how many tetrahedra the mesh takes where the uniform mesh takes `uniform`: the
    /// cells gathered into cubes take six each there, and a cube takes six to 48 (24
    /// counted).
    pub(super) fn element_estimate(&self, uniform: usize) -> usize {
        let cubes = self.origins(1);
        let cells: usize = cubes.iter().map(|&(_, k)| 1usize << (3 * k)).sum();
        (uniform + 24 * cubes.len()).saturating_sub(6 * cells)
    }

    /// The cells of the grid that have grid point `p` as a corner (up to eight).
    fn cells_around(&self, p: [usize; 3]) -> impl Iterator<Item = [usize; 3]> + '_ {
        (0..8).filter_map(move |o| {
            let cell: [Option<usize>; 3] = std::array::from_fn(|a| {
                let x = (p[a] + (o >> a & 1)).checked_sub(1)?;
                (x < self.cells[a]).then_some(x)
            });
            match cell {
                [Some(x), Some(y), Some(z)] => Some([x, y, z]),
                _ => None,
            }
        })
    }

    /// The level of the cube holding `cell`.
    pub(super) fn level(&self, cell: [usize; 3]) -> u8 {
        self.level[cell[0] + self.cells[0] * (cell[1] + self.cells[1] * cell[2])]
    }

    /// Splits cubes touching a cell two or more levels finer until none does.
    fn balance(&mut self) {
        loop {
            let origins: Vec<([usize; 3], u8)> = self.origins(2);
            let split: Vec<([usize; 3], u8)> = origins
                .into_par_iter()
                .filter(|&(o, k)| self.touches_finer_than(o, k, k - 1))
                .collect();
            if split.is_empty() {
                return;
            }
            for (o, k) in split {
                let s = 1usize << k;
                for z in o[2]..o[2] + s {
                    for y in o[1]..o[1] + s {
                        let row = self.cells[0] * (y + self.cells[1] * z);
                        self.level[row + o[0]..row + o[0] + s].fill(k - 1);
                    }
                }
            }
        }
    }

    /// The corner cells of the cubes of level `from` or more, with their levels, in order.
    pub(super) fn origins(&self, from: u8) -> Vec<([usize; 3], u8)> {
        let c = self.cells;
        (0..c[2])
            .into_par_iter()
            .flat_map_iter(|z| {
                let mut out = Vec::new();
                for y in 0..c[1] {
                    for x in 0..c[0] {
                        let k = self.level([x, y, z]);
                        let mask = (1usize << k) - 1;
                        if k >= from && x & mask == 0 && y & mask == 0 && z & mask == 0 {
                            out.push(([x, y, z], k));
                        }
                    }
                }
                out
            })
            .collect()
    }

    /// Whether a cell touching the cube at `o` of level `k` across a face or an edge is of a
    /// level under `bound`.
    fn touches_finer_than(&self, o: [usize; 3], k: u8, bound: u8) -> bool {
        let s = 1usize << k;
        let lo = o.map(|x| x.saturating_sub(1));
        let hi: [usize; 3] = std::array::from_fn(|a| (o[a] + s + 1).min(self.cells[a]));
        for z in lo[2]..hi[2] {
            for y in lo[1]..hi[1] {
                let inner_yz = (o[1]..o[1] + s).contains(&y) && (o[2]..o[2] + s).contains(&z);
                let beside_yz = (o[1]..o[1] + s).contains(&y) || (o[2]..o[2] + s).contains(&z);
                for x in lo[0]..hi[0] {
                    let inner_x = (o[0]..o[0] + s).contains(&x);
                    // Inside, or touching at a corner only (a shared corner is a grid point
                    // both have: no point of the finer cube lies on the cube's edges).
                    if inner_yz && inner_x || !beside_yz && !inner_x {
                        continue;
                    }
                    if self.level([x, y, z]) < bound {
                        return true;
                    }
                }
            }
        }
        false
    }

    /// Whether grid point `p` is a corner of a cube finer than level `k` (for a midpoint of an
    /// edge or a face diagonal of a cube of level `k`: whether that point is in the mesh).
    fn finer_at(&self, p: [usize; 3], k: u8) -> bool {
        self.cells_around(p).any(|cell| self.level(cell) < k)
    }

    /// The tetrahedra of the cube at corner cell `o` of level `k` ≥ 1, over the vertices
    /// `id(p)` of its grid points `p`, each positive; and the triangles of its faces on the
    /// grid's outer faces, outward, into `walls`.
    pub(super) fn cube(
        &self,
        o: [usize; 3],
        k: u8,
        id: &dyn Fn([usize; 3]) -> u32,
        tets: &mut Vec<[u32; 4]>,
        walls: &mut Vec<[u32; 3]>,
    ) {
        let s = 1usize << k;
        let mid = |a: [usize; 3], b: [usize; 3]| -> [usize; 3] {
            std::array::from_fn(|i| (a[i] + b[i]) / 2)
        };
        // A finer cube's corner on one of the cube's edges or faces lies at a midpoint of an
        // edge or a Kuhn diagonal: each face triangle is cut at those present.
        let faces = cube_faces(s).map(|tris| {
            tris.map(|t| {
                let t = t.map(|q| add(o, q));
                let split: [Option<[usize; 3]>; 3] = std::array::from_fn(|e| {
                    let m = mid(t[e], t[(e + 1) % 3]);
                    self.finer_at(m, k).then_some(m)
                });
                (t, split)
            })
        });
        // The cube's side is even: its centre is a grid point.
        let centre = add(o, [s / 2; 3]);
        for (f, tris) in faces.iter().enumerate() {
            let (n, side) = (f / 2, f % 2);
            let on_wall = if side == 0 {
                o[n] == 0
            } else {
                o[n] + s == self.cells[n]
            };
            if on_wall {
                for &(t, split) in tris {
                    walls.extend(
                        cut(t, split, self.spacing)
                            .iter()
                            .map(|&p| away_from(p, centre).map(id)),
                    );
                }
            }
        }
        let apex = apex(&faces, [o, add(o, [s; 3])], centre, self.spacing);
        tets.extend(cone(&faces, apex, self.spacing).map(|t| t.map(id)));
    }
}

/// A face triangle of a cube and the midpoints of its edges present (`split[e]` on the edge
/// from corner `e` to corner `e + 1`).
type CutTriangle = ([[usize; 3]; 3], [Option<[usize; 3]>; 3]);

/// The dihedral angles a cube's cone from a corner must keep, or the cube is coned from its
/// centre.
const CORNER_CONES: (f64, f64) = (15.0, 150.0);

/// The point a cube whose faces' Kuhn triangles are cut as `faces` says is coned from: its
/// lowest corner (`ends[0]`) without midpoints (the Kuhn tetrahedra); else the lowest, then
/// the highest corner (`ends[1]`) where the cone from it can be made ([`split_at`]) and keeps
/// its dihedral angles within [`CORNER_CONES`] on cells of sides `spacing` (always on cubic
/// cells: 17.72° to 135°); else its `centre` (on long cells the centre's cones stay fuller at
/// the narrow end).
fn apex(
    faces: &[[CutTriangle; 2]; 6],
    ends: [[usize; 3]; 2],
    centre: [usize; 3],
    spacing: [f64; 3],
) -> [usize; 3] {
    let transition = faces
        .iter()
        .flatten()
        .any(|(_, split)| split.iter().any(Option::is_some));
    if !transition {
        return ends[0];
    }
    let world = |q: [usize; 3]| -> [f64; 3] { std::array::from_fn(|a| q[a] as f64 * spacing[a]) };
    let fits = |c: [usize; 3]| {
        !split_at(faces, c)
            && cone(faces, c, spacing).all(|t| {
                let (lo, hi) = dihedral_extremes(t.map(world));
                lo >= CORNER_CONES.0 && hi <= CORNER_CONES.1
            })
    };
    ends.into_iter().find(|&c| fits(c)).unwrap_or(centre)
}

/// Whether a midpoint in `faces` is on an edge ending at corner `c`.
fn split_at(faces: &[[CutTriangle; 2]; 6], c: [usize; 3]) -> bool {
    faces
        .iter()
        .flatten()
        .any(|(t, split)| (0..3).any(|e| split[e].is_some() && (t[e] == c || t[(e + 1) % 3] == c)))
}

/// The tetrahedra of a cube whose faces' Kuhn triangles are cut as `faces` says, coned from
/// `apex` over the faces away from it, each positive. The apex is the cube's centre, or its
/// lowest or highest corner when no midpoint is on an edge ending there ([`split_at`]): the
/// faces at that corner are not coned, each of their triangles cut at most at the midpoint of
/// its edge facing the corner, which the cone joins to the corner as `cut` does (without
/// midpoints, from the lowest corner: the Kuhn tetrahedra).
fn cone(
    faces: &[[CutTriangle; 2]; 6],
    apex: [usize; 3],
    spacing: [f64; 3],
) -> impl Iterator<Item = [[usize; 3]; 4]> + '_ {
    faces
        .iter()
        .flatten()
        .filter(move |(t, _)| !t.contains(&apex))
        .flat_map(move |&(t, split)| {
            cut(t, split, spacing).into_iter().map(move |piece| {
                // Turned to face away from the apex: the cone over it is positive.
                let piece = away_from(piece, apex);
                [piece[0], piece[2], piece[1], apex]
            })
        })
}

/// Whether each cube of level `k` (`flags` over `d` cubes, the grid `cells` cells) is whole
/// with every cube of its level within `m` cubes: cubes beyond the grid count as whole, the
/// one the grid cuts (where `2^k` does not divide a side) does not.
fn spread(flags: &[bool], d: [usize; 3], cells: [usize; 3], k: usize, m: usize) -> Vec<bool> {
    // The box around a cube, clipped to the grid's cubes, separably: a line at a time along
    // each axis, a window of `2m + 1` (counting the cubes that are not whole).
    let mut out = flags.to_vec();
    for a in 0..3 {
        let stride = [1, d[0], d[0] * d[1]][a];
        let n = d[a];
        let lines: Vec<usize> = (0..d[0] * d[1] * d[2])
            .filter(|&c| coords(c, d)[a] == 0)
            .collect();
        let current = out.clone();
        let updates: Vec<(usize, Vec<bool>)> = lines
            .into_par_iter()
            .map(|start| {
                let mut bad = vec![0usize; n + 1];
                for x in 0..n {
                    bad[x + 1] = bad[x] + usize::from(!current[start + x * stride]);
                }
                let line = (0..n)
                    .map(|x| bad[(x + m + 1).min(n)] == bad[x.saturating_sub(m)])
                    .collect();
                (start, line)
            })
            .collect();
        for (start, line) in updates {
            for (x, v) in line.into_iter().enumerate() {
                out[start + x * stride] = v;
            }
        }
    }
    // A cube within `m` of the cut cube at the grid's far end is not.
    for (c, v) in out.iter_mut().enumerate() {
        let p = coords(c, d);
        if (0..3).any(|a| cells[a] % (1 << k) != 0 && p[a] + m >= d[a]) {
            *v = false;
        }
    }
    out
}

fn add(a: [usize; 3], b: [usize; 3]) -> [usize; 3] {
    std::array::from_fn(|i| a[i] + b[i])
}

/// The Kuhn triangles of the six faces of a cube of side `s` at the origin, by face
/// `2 · axis + side`: each face cut along its diagonal from its lowest corner to its highest.
fn cube_faces(s: usize) -> [[[[usize; 3]; 3]; 2]; 6] {
    std::array::from_fn(|f| {
        let (n, side) = (f / 2, f % 2);
        let (a, b) = ((n + 1) % 3, (n + 2) % 3);
        let point = |u: usize, v: usize| {
            let mut p = [0; 3];
            p[n] = side * s;
            p[a] = u * s;
            p[b] = v * s;
            p
        };
        [
            [point(0, 0), point(1, 0), point(1, 1)],
            [point(0, 0), point(1, 1), point(0, 1)],
        ]
    })
}

/// Triangle `t` turned so that `centre` lies on its negative side.
fn away_from(t: [[usize; 3]; 3], centre: [usize; 3]) -> [[usize; 3]; 3] {
    let p = t.map(|q| q.map(|x| x as f64));
    if facing(p, centre.map(|x| x as f64)) > 0.0 {
        [t[0], t[2], t[1]]
    } else {
        t
    }
}

/// The signed volume of (`t`, `c`): positive when `c` lies on the side `t`'s normal
/// (right-hand rule) points to. Exact for grid coordinates under 2^17.
fn facing(t: [[f64; 3]; 3], c: [f64; 3]) -> f64 {
    dot(sub(t[1], t[0]), cross(sub(t[2], t[0]), sub(c, t[0])))
}

/// Triangle `t` cut at the midpoints of its edges that are present (`split[e]` on the edge from
/// corner `e` to corner `e + 1`), on cells of sides `spacing`. The rule reads only the
/// triangle's points, whatever their order, so the two cubes sharing a face cut it alike: one
/// midpoint joins the far corner; two cut off the corner between them, the quadrilateral left
/// cut along its diagonal shorter in world units (the one with the smaller end point on a tie;
/// on a cell 1:1:3, the diagonal shorter in cells would leave a sliver at 166.74°); three give
/// the four halves-sized triangles.
fn cut(
    t: [[usize; 3]; 3],
    split: [Option<[usize; 3]>; 3],
    spacing: [f64; 3],
) -> Vec<[[usize; 3]; 3]> {
    let present = split.iter().filter(|m| m.is_some()).count();
    match present {
        0 => vec![t],
        1 => {
            let e = (0..3).find(|&e| split[e].is_some()).expect("one is there");
            let m = split[e].expect("present");
            let (a, b, c) = (t[e], t[(e + 1) % 3], t[(e + 2) % 3]);
            vec![[a, m, c], [m, b, c]]
        }
        2 => {
            // The corner between the two cut edges: the end of edge `e` where edge `e + 1` starts.
            let e = (0..3)
                .find(|&e| split[e].is_some() && split[(e + 1) % 3].is_some())
                .expect("two adjacent edges");
            let (a, b, c) = (t[e], t[(e + 1) % 3], t[(e + 2) % 3]);
            let (m1, m2) = (
                split[e].expect("present"),
                split[(e + 1) % 3].expect("present"),
            );
            let corner = [m1, b, m2];
            // Quadrilateral a, m1, m2, c: diagonal a–m2 or m1–c.
            let length = |p: [usize; 3], q: [usize; 3]| -> f64 {
                (0..3)
                    .map(|i| (p[i].abs_diff(q[i]) as f64 * spacing[i]).powi(2))
                    .sum()
            };
            let (first, second) = (length(a, m2), length(m1, c));
            if first < second || (first == second && a.min(m2) <= m1.min(c)) {
                vec![corner, [a, m1, m2], [a, m2, c]]
            } else {
                vec![corner, [a, m1, c], [m1, m2, c]]
            }
        }
        _ => {
            let [m0, m1, m2] = split.map(|m| m.expect("present"));
            vec![[t[0], m0, m2], [m0, t[1], m1], [m2, m1, t[2]], [m0, m1, m2]]
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::quality::dihedral_extremes;
    use crate::volume::KUHN;
    use rustc_hash::FxHashMap as HashMap;

    /// Meshes the whole cells of a grid of `cells` with cubes and single cells' Kuhn
    /// tetrahedra, over grid point numbers.
    fn mesh(
        cells: [usize; 3],
        whole: &[bool],
        grading: Grading,
    ) -> (Cubes, Vec<[u32; 4]>, Vec<[u32; 3]>) {
        let cubes = Cubes::new(cells, [1.0; 3], whole.to_vec(), grading);
        let points = cells.map(|c| c + 1);
        let id = |p: [usize; 3]| (p[0] + points[0] * (p[1] + points[1] * p[2])) as u32;
        let mut tets = Vec::new();
        let mut walls = Vec::new();
        for z in 0..cells[2] {
            for y in 0..cells[1] {
                for x in 0..cells[0] {
                    let c = x + cells[0] * (y + cells[1] * z);
                    if !whole[c] || cubes.level([x, y, z]) > 0 {
                        continue;
                    }
                    let o = [x, y, z];
                    tets.extend(KUHN.iter().map(|t| {
                        t.map(|k| id(std::array::from_fn(|a| o[a] + (usize::from(k) >> a & 1))))
                    }));
                }
            }
        }
        for (o, k) in cubes.origins(1) {
            cubes.cube(o, k, &id, &mut tets, &mut walls);
        }
        (cubes, tets, walls)
    }

    fn point(v: u32, points: [usize; 3]) -> [f64; 3] {
        let v = v as usize;
        [
            v % points[0],
            v / points[0] % points[1],
            v / (points[0] * points[1]),
        ]
        .map(|x| x as f64)
    }

    fn volume6(p: [[f64; 3]; 4]) -> f64 {
        facing([p[0], p[1], p[2]], p[3])
    }

    /// Every face is shared by two tetrahedra but those on the region's boundary; the boundary
    /// is the whole cells' outer faces, cut as a single cell cuts them.
    fn assert_conforming(cells: [usize; 3], whole: &[bool], tets: &[[u32; 4]]) {
        let points = cells.map(|c| c + 1);
        let mut faces: HashMap<[u32; 3], u32> = HashMap::default();
        for t in tets {
            for k in 0..4 {
                let mut f: [u32; 3] = std::array::from_fn(|i| t[if i < k { i } else { i + 1 }]);
                f.sort_unstable();
                *faces.entry(f).or_default() += 1;
            }
        }
        assert!(
            faces.values().all(|&n| n <= 2),
            "a face of three tetrahedra"
        );
        let mut open: Vec<[u32; 3]> = faces
            .into_iter()
            .filter(|e| e.1 == 1)
            .map(|e| e.0)
            .collect();
        open.sort_unstable();
        // The uniform mesh's boundary.
        let mut uniform: HashMap<[u32; 3], u32> = HashMap::default();
        let id = |p: [usize; 3]| (p[0] + points[0] * (p[1] + points[1] * p[2])) as u32;
        for z in 0..cells[2] {
            for y in 0..cells[1] {
                for x in 0..cells[0] {
                    if !whole[x + cells[0] * (y + cells[1] * z)] {
                        continue;
                    }
                    for t in KUHN {
                        let t = t.map(|k| {
                            id(std::array::from_fn(|a| {
                                [x, y, z][a] + (usize::from(k) >> a & 1)
                            }))
                        });
                        for k in 0..4 {
                            let mut f: [u32; 3] =
                                std::array::from_fn(|i| t[if i < k { i } else { i + 1 }]);
                            f.sort_unstable();
                            *uniform.entry(f).or_default() += 1;
                        }
                    }
                }
            }
        }
        // Faces in the grid's outer faces are walls, which the cubes coarsen too.
        let inner = |f: &[u32; 3]| {
            let p = f.map(|v| point(v, points));
            !(0..3).any(|a| {
                (p[0][a] == 0.0 || p[0][a] == cells[a] as f64)
                    && p[1][a] == p[0][a]
                    && p[2][a] == p[0][a]
            })
        };
        open.retain(inner);
        let mut expected: Vec<[u32; 3]> = uniform
            .into_iter()
            .filter(|e| e.1 == 1)
            .map(|e| e.0)
            .collect();
        expected.retain(inner);
        expected.sort_unstable();
        assert!(open == expected, "the boundary is not the uniform mesh's");
        for t in tets {
            assert!(
                volume6(t.map(|v| point(v, points))) > 0.0,
                "{t:?} is not positive"
            );
        }
        let total: f64 = tets
            .iter()
            .map(|t| volume6(t.map(|v| point(v, points))))
            .sum::<f64>()
            / 6.0;
        let cubes = whole.iter().filter(|&&w| w).count() as f64;
        assert_eq!(total, cubes);
    }

    fn ball(cells: [usize; 3], radius: f64) -> Vec<bool> {
        let centre = cells.map(|c| c as f64 / 2.0);
        (0..cells[0] * cells[1] * cells[2])
            .map(|c| {
                let p = coords(c, cells);
                (0..8).all(|o| {
                    let d: f64 = (0..3)
                        .map(|a| (p[a] as f64 + (o >> a & 1) as f64 - centre[a]).powi(2))
                        .sum();
                    d.sqrt() < radius
                })
            })
            .collect()
    }

    #[test]
    fn a_graded_ball_is_conforming_with_the_uniform_boundary_and_fewer_elements() {
        let cells = [60, 57, 64];
        let whole = ball(cells, 27.5);
        let (cubes, tets, walls) = mesh(cells, &whole, Grading::default());
        assert!(walls.is_empty());
        assert!(cubes.level.iter().any(|&l| l >= 2));
        assert_conforming(cells, &whole, &tets);
        let uniform = 6 * whole.iter().filter(|&&w| w).count();
        // 2.6× fewer here (Kuhn tetrahedra of whole cells only; the cut cells come on top).
        assert!(tets.len() * 2 < uniform, "{} of {uniform}", tets.len());
    }

    #[test]
    fn random_regions_and_gradings_stay_conforming_and_balanced() {
        // Blocks of whole cells with holes: every pattern of finer neighbours turns up.
        let mut seed = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            seed
        };
        for round in 0..24 {
            let cells = [
                20 + (next() % 13) as usize,
                18 + (next() % 9) as usize,
                21 + (next() % 11) as usize,
            ];
            let mut whole = vec![true; cells[0] * cells[1] * cells[2]];
            for _ in 0..(next() % 6) {
                let c = (next() as usize) % whole.len();
                whole[c] = false;
            }
            let grading = Grading {
                max_level: 1 + (next() % 4) as u8,
                layers: 1 + (next() % 2) as u8,
            };
            let (cubes, tets, _) = mesh(cells, &whole, grading);
            for (o, k) in cubes.origins(1) {
                assert!(
                    !cubes.touches_finer_than(o, k, k - 1),
                    "round {round}: unbalanced at {o:?}"
                );
            }
            assert_conforming(cells, &whole, &tets);
        }
    }

    #[test]
    fn walls_of_cubes_on_the_grid_faces_are_outward_and_cover_them() {
        let cells = [16, 16, 16];
        let mut whole = vec![true; 16 * 16 * 16];
        whole[5 + 16 * (9 + 16 * 6)] = false;
        let grading = Grading {
            max_level: 3,
            layers: 1,
        };
        let (cubes, tets, walls) = mesh(cells, &whole, grading);
        assert!(cubes.level.iter().any(|&l| l >= 2));
        assert_conforming(cells, &whole, &tets);
        // The cubes' walls with the single cells' faces on the grid's faces: 6 · 16² squares.
        let points = [17; 3];
        let mut area2 = 0.0;
        for w in &walls {
            let p = w.map(|v| point(v, points));
            let u: [f64; 3] = std::array::from_fn(|i| p[1][i] - p[0][i]);
            let v: [f64; 3] = std::array::from_fn(|i| p[2][i] - p[0][i]);
            let n = [
                u[1] * v[2] - u[2] * v[1],
                u[2] * v[0] - u[0] * v[2],
                u[0] * v[1] - u[1] * v[0],
            ];
            let c: [f64; 3] = std::array::from_fn(|i| (p[0][i] + p[1][i] + p[2][i]) / 3.0 - 8.0);
            assert!(
                (0..3).map(|i| n[i] * c[i]).sum::<f64>() > 0.0,
                "{w:?} faces in"
            );
            area2 += (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        }
        let singles: usize = (0..16 * 16 * 16)
            .filter(|&c| cubes.level[c] == 0)
            .map(|c| {
                let p = coords(c, cells);
                p.iter()
                    .map(|&x| usize::from(x == 0) + usize::from(x == 15))
                    .sum::<usize>()
            })
            .sum();
        assert_eq!(area2 / 2.0 + singles as f64, 6.0 * 256.0);
    }

    /// The dihedral angle ranges of the cones from the corners and from the centre over every
    /// pattern of midpoints a cube can meet, on cells of sides `spacing`: the 12 edges and 6
    /// diagonals, each present or not, as far as a face's pattern allows (a face diagonal's
    /// midpoint comes with the finer cube across the face, so with that face's four edges).
    /// Checks on the way that each cone is positive and fills the cube, and that a cube
    /// without midpoints is its Kuhn tetrahedra.
    fn cone_ranges(spacing: [f64; 3]) -> [(f64, f64); 2] {
        let mut ranges = [(f64::INFINITY, 0.0f64); 2];
        let faces = cube_faces(2);
        let edges: Vec<[[usize; 3]; 2]> = {
            let mut e: Vec<[[usize; 3]; 2]> = faces
                .iter()
                .flatten()
                .flat_map(|t| {
                    (0..3).map(move |i| {
                        let mut pair = [t[i], t[(i + 1) % 3]];
                        pair.sort_unstable();
                        pair
                    })
                })
                .collect();
            e.sort_unstable();
            e.dedup();
            e
        };
        assert_eq!(edges.len(), 18);
        let ends = [[0; 3], [2; 3]];
        let mut cones = [0usize; 3];
        for mask in 0u32..1 << 18 {
            let has = |a: [usize; 3], b: [usize; 3]| {
                let mut pair = [a, b];
                pair.sort_unstable();
                mask >> edges.binary_search(&pair).expect("an edge") & 1 == 1
            };
            let consistent = faces.iter().all(|tris| {
                let diagonal = has(tris[0][0], tris[0][2]);
                !diagonal || tris.iter().all(|t| has(t[0], t[1]) && has(t[1], t[2]))
            });
            if !consistent {
                continue;
            }
            let cut_faces = faces.map(|tris| {
                tris.map(|t| {
                    let split = std::array::from_fn(|e| {
                        let (a, b) = (t[e], t[(e + 1) % 3]);
                        has(a, b).then(|| std::array::from_fn(|i| (a[i] + b[i]) / 2))
                    });
                    (t, split)
                })
            });
            let apex = apex(&cut_faces, ends, [1; 3], spacing);
            let tets: Vec<[[usize; 3]; 4]> = cone(&cut_faces, apex, spacing).collect();
            if mask == 0 {
                let corners = |t: [usize; 4]| {
                    let mut c = t;
                    c.sort_unstable();
                    c
                };
                let mut got: Vec<[usize; 4]> = tets
                    .iter()
                    .map(|t| corners(t.map(|p| p[0] / 2 + 2 * (p[1] / 2) + 4 * (p[2] / 2))))
                    .collect();
                let mut kuhn: Vec<[usize; 4]> =
                    KUHN.iter().map(|t| corners(t.map(usize::from))).collect();
                got.sort_unstable();
                kuhn.sort_unstable();
                assert_eq!(got, kuhn);
            }
            let from_centre = apex == [1; 3];
            cones[usize::from(apex == ends[1]) + 2 * usize::from(from_centre)] += 1;
            let mut volume = 0.0;
            for t in tets {
                let p = t.map(|q| q.map(|x| x as f64));
                let v = volume6(p);
                assert!(v > 0.0, "mask {mask:#x}: {t:?}");
                volume += v;
                let (a, b) =
                    dihedral_extremes(t.map(|q| std::array::from_fn(|i| q[i] as f64 * spacing[i])));
                let range = &mut ranges[usize::from(from_centre)];
                *range = (range.0.min(a), range.1.max(b));
            }
            // The cone fills the cube (of side 2: volume 8, six times over).
            assert_eq!(volume, 48.0, "mask {mask:#x}");
        }
        // Each apex turns up.
        assert!(cones.iter().all(|&n| n > 0), "{cones:?}");
        ranges
    }

    #[test]
    fn transition_cones_keep_their_angles_in_every_pattern() {
        // The bounds the module documentation and the README state.
        let [corner, centre] = cone_ranges([1.0; 3]);
        let near = |(lo, hi): (f64, f64), (a, b): (f64, f64)| {
            (lo - a).abs() < 0.01 && (hi - b).abs() < 0.01
        };
        assert!(near(corner, (17.72, 135.0)), "corners: {corner:?}");
        assert!(near(centre, (19.47, 144.74)), "centre: {centre:?}");
        // Long and flat cells up to 3:1: the corners' cones are kept to their range, the
        // centre's take the rest, and every transition element stays within [10°, 165°] (the
        // worst at 1:1:3, 11.98°–154.76°, and at 3:3:1, 12.92°–162.45°).
        for spacing in [
            [0.5, 0.25, 0.75],
            [1.0, 1.0, 3.0],
            [1.0, 1.0, 1.0 / 3.0],
            [1.0, 2.0, 3.0],
            [3.0, 1.0, 2.0],
        ] {
            let [corner, centre] = cone_ranges(spacing);
            assert!(
                corner.0 >= CORNER_CONES.0 && corner.1 <= CORNER_CONES.1,
                "{spacing:?}: corners {corner:?}"
            );
            assert!(
                centre.0 >= 10.0 && centre.1 <= 165.0,
                "{spacing:?}: centre {centre:?}"
            );
        }
        assert!(near(cone_ranges([1.0, 1.0, 3.0])[1], (11.98, 154.76)));
        assert!(near(cone_ranges([1.0, 1.0, 1.0 / 3.0])[1], (12.92, 162.45)));
    }
}
