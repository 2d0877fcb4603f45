//! Filling a part by an advancing front: the last resort for the parts that neither cones nor
//! splits fill (twisted parts of Marching Cubes 33's surface, whose long triangles cross the
//! cell and fold around each other).
//!
//! The front is the boundary of what is left to fill, outward. Each step adds one tetrahedron on
//! a front face: the best-shaped one with its apex at a vertex already on the front, or, when
//! none fits, at a new point inside, in front of a face. A tetrahedron fits when it is positive,
//! holds no front vertex, and its new faces meet the front only where they share its vertices
//! and edges (decided by exact orientation predicates on the stored coordinates). Its faces then
//! leave the front where they lie on it and join it otherwise (turned to face what is left).
//! When the front is empty the tetrahedra tile the part: every one lies in what was left when
//! it was added, and together they leave nothing.

use super::check;
use super::cones::Tiled;
use super::STEINER;
use crate::mesh::intersect::{orient, triangles_cross};

/// Steps allowed per triangle of the part before giving up (each adds a tetrahedron).
const STEPS_PER_TRIANGLE: usize = 6;

/// Pairs of triangles (and points) compared at most before giving up: a part the front cannot
/// close costs about a tenth of a second, not the minutes an open-ended search could take.
const WORK: usize = 4_000_000;

/// Fraction of a face's height above it, in turn, where a new apex is tried.
const HEIGHTS: [f64; 10] = [1.0, 0.7, 0.5, 0.35, 0.25, 0.15, 0.1, 0.05, 0.02, 0.005];

/// Tetrahedra tiling the closed outward part, their new points `STEINER | index` into the
/// returned points, or why not. `score` ranks a tetrahedron's shape (higher is better).
pub(super) fn advance(
    part: &[[u32; 3]],
    position: &dyn Fn(u32) -> [f64; 3],
    score: &dyn Fn([[f64; 3]; 4]) -> f64,
) -> Result<Tiled, &'static str> {
    let mut front = Front {
        faces: part.to_vec(),
        points: Vec::new(),
        position,
        work: std::cell::Cell::new(0),
    };
    if front
        .faces
        .iter()
        .any(|&f| check::collinear(f.map(|v| front.at(v))))
    {
        return Err("a triangle of no area on the front");
    }
    let mut tets: Vec<[u32; 4]> = Vec::new();
    for _ in 0..STEPS_PER_TRIANGLE * part.len() + 16 {
        if front.faces.is_empty() {
            return Ok((front.points, tets));
        }
        if front.work.get() > WORK {
            break;
        }
        let tet = front
            .best_closing(score)
            .or_else(|| front.new_apex(score))
            .ok_or("the advancing front found no tetrahedron to add")?;
        front.add(tet);
        tets.push(tet);
    }
    Err("the advancing front did not close")
}

struct Front<'a> {
    /// Outward faces of what is left.
    faces: Vec<[u32; 3]>,
    /// Points added (`STEINER | index`).
    points: Vec<[f64; 3]>,
    position: &'a dyn Fn(u32) -> [f64; 3],
    /// Comparisons made so far (see [`WORK`]).
    work: std::cell::Cell<usize>,
}

/// The tetrahedron on outward face `(a, b, c)` with apex `d`.
fn on_face(f: [u32; 3], d: u32) -> [u32; 4] {
    [f[0], f[2], f[1], d]
}

/// The outward faces of a positive tetrahedron `[a, b, c, d]`, the first the one it was built on
/// by [`on_face`].
fn faces_of([a, b, c, d]: [u32; 4]) -> [[u32; 3]; 4] {
    [[a, c, b], [a, b, d], [a, d, c], [b, c, d]]
}

/// Whether two faces have the same vertices in the same cyclic order.
fn same(x: [u32; 3], y: [u32; 3]) -> bool {
    x == y || x == [y[1], y[2], y[0]] || x == [y[2], y[0], y[1]]
}

impl Front<'_> {
    fn at(&self, v: u32) -> [f64; 3] {
        if v & STEINER != 0 {
            self.points[(v & !STEINER) as usize]
        } else {
            (self.position)(v)
        }
    }

    fn vertices(&self) -> Vec<u32> {
        let mut v: Vec<u32> = self.faces.iter().flatten().copied().collect();
        v.sort_unstable();
        v.dedup();
        v
    }

    /// The best-shaped tetrahedron that fits with its apex on the front.
    fn best_closing(&self, score: &dyn Fn([[f64; 3]; 4]) -> f64) -> Option<[u32; 4]> {
        let vertices = self.vertices();
        let mut candidates: Vec<(f64, [u32; 4])> = Vec::new();
        for &f in &self.faces {
            for &d in &vertices {
                if f.contains(&d) {
                    continue;
                }
                let tet = on_face(f, d);
                let p = tet.map(|v| self.at(v));
                if check::positive(p[0], p[1], p[2], p[3]) {
                    candidates.push((score(p), tet));
                }
            }
        }
        // Best first; ties by the vertices, so the choice does not depend on the order found.
        candidates.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        candidates
            .into_iter()
            .map(|(_, tet)| tet)
            .find(|&tet| self.fits(tet))
    }

    /// A tetrahedron on one of the front's faces (largest first) with a new apex in front of it.
    fn new_apex(&mut self, score: &dyn Fn([[f64; 3]; 4]) -> f64) -> Option<[u32; 4]> {
        let mut order: Vec<(f64, usize)> = self
            .faces
            .iter()
            .enumerate()
            .map(|(i, f)| {
                let p = f.map(|v| self.at(v));
                let n = check::cross(check::sub(p[1], p[0]), check::sub(p[2], p[0]));
                (check::dot(n, n), i)
            })
            .collect();
        order.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        let id = STEINER | self.points.len() as u32;
        for (_, i) in order {
            let f = self.faces[i];
            let p = f.map(|v| self.at(v));
            let n = check::cross(check::sub(p[1], p[0]), check::sub(p[2], p[0]));
            let len = check::dot(n, n).sqrt();
            let edge = (0..3)
                .map(|k| {
                    let e = check::sub(p[(k + 1) % 3], p[k]);
                    check::dot(e, e).sqrt()
                })
                .sum::<f64>()
                / 3.0;
            let centre: [f64; 3] = std::array::from_fn(|d| (p[0][d] + p[1][d] + p[2][d]) / 3.0);
            let mut best: Option<(f64, [f64; 3])> = None;
            for h in HEIGHTS {
                // Inward: against the outward normal; rounded to the stored precision.
                let apex: [f64; 3] = std::array::from_fn(|d| {
                    f64::from((centre[d] - h * 0.816 * edge * n[d] / len) as f32)
                });
                self.points.push(apex);
                let tet = on_face(f, id);
                let q = tet.map(|v| self.at(v));
                let fits = check::positive(q[0], q[1], q[2], q[3]) && self.fits(tet);
                self.points.pop();
                if fits {
                    let s = score(q);
                    if best.is_none_or(|b| s > b.0) {
                        best = Some((s, apex));
                    }
                    // Lower apexes only flatten it further once one fits.
                    break;
                }
            }
            if let Some((_, apex)) = best {
                self.points.push(apex);
                return Some(on_face(f, id));
            }
        }
        None
    }

    /// Whether the positive tetrahedron, built on its first face (a front face), lies in what is
    /// left and meets the front only in shared vertices, edges and faces.
    fn fits(&self, tet: [u32; 4]) -> bool {
        if self.work.get() > WORK {
            return false;
        }
        let vertices = self.vertices();
        self.work
            .set(self.work.get() + vertices.len() + 3 * self.faces.len());
        let p = tet.map(|v| self.at(v));
        // No front vertex inside or on it.
        for v in vertices {
            if tet.contains(&v) {
                continue;
            }
            let x = self.at(v);
            let inside = [
                orient(x, p[1], p[2], p[3]),
                orient(p[0], x, p[2], p[3]),
                orient(p[0], p[1], x, p[3]),
                orient(p[0], p[1], p[2], x),
            ];
            if inside.iter().all(|&o| o >= 0.0) {
                return false;
            }
        }
        let faces = faces_of(tet);
        for new in &faces[1..] {
            for &g in &self.faces {
                if same(g, faces[0]) {
                    continue;
                }
                let mut sorted_g = g;
                sorted_g.sort_unstable();
                let mut sorted_new = *new;
                sorted_new.sort_unstable();
                if sorted_g == sorted_new {
                    // On the front: only from inside, where it is the same face.
                    if !same(g, *new) {
                        return false;
                    }
                    continue;
                }
                if triangles_cross(new.map(|v| (v, self.at(v))), g.map(|v| (v, self.at(v)))) {
                    return false;
                }
            }
        }
        true
    }

    /// Adds a fitting tetrahedron: its faces on the front leave it, the others join it.
    fn add(&mut self, tet: [u32; 4]) {
        for face in faces_of(tet) {
            match self.faces.iter().position(|&g| same(g, face)) {
                Some(k) => {
                    self.faces.swap_remove(k);
                }
                None => self.faces.push([face[0], face[2], face[1]]),
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Fills the closed outward part and checks the tiling: every tetrahedron positive, every
    /// face matched but the part's own, the volume the part's. Returns the points added.
    fn fill_checked(faces: &[[u32; 3]], corners: &[[f64; 3]]) -> usize {
        let position = |v: u32| corners[v as usize];
        let score = |p: [[f64; 3]; 4]| super::super::tet_score(p);
        let (points, tets) = advance(faces, &position, &score).unwrap();
        let at = |v: u32| {
            if v & STEINER != 0 {
                points[(v & !STEINER) as usize]
            } else {
                corners[v as usize]
            }
        };
        assert!(tets.iter().all(|t| {
            let p = t.map(at);
            check::positive(p[0], p[1], p[2], p[3])
        }));
        assert!(super::super::cones::open_faces(&tets, faces).is_empty());
        let volume: f64 = tets
            .iter()
            .map(|t| {
                let p = t.map(at);
                let (u, v, w) = (
                    check::sub(p[1], p[0]),
                    check::sub(p[2], p[0]),
                    check::sub(p[3], p[0]),
                );
                check::dot(u, check::cross(v, w)) / 6.0
            })
            .sum();
        // The volume the outward triangles enclose (divergence theorem).
        let enclosed: f64 = faces
            .iter()
            .map(|f| {
                let p = f.map(position);
                check::dot(p[0], check::cross(p[1], p[2])) / 6.0
            })
            .sum();
        assert!(
            (volume - enclosed).abs() < 1e-12 * enclosed,
            "{volume} vs {enclosed}"
        );
        points.len()
    }

    #[test]
    fn fills_a_cube_exactly() {
        let corners: Vec<[f64; 3]> = (0..8).map(super::super::tests::cube_corner).collect();
        let added = fill_checked(&super::super::tests::cube_boundary(), &corners);
        assert_eq!(added, 0, "a cube needs no point inside");
    }

    #[test]
    fn fills_schonhardts_prism_with_a_point_inside() {
        // A triangular prism whose top is turned, its three sides split along diagonals: turned
        // one way the diagonals fold inward (Schönhardt's polyhedron) and no tetrahedron of its
        // six corners fits, so the front must add a point.
        let mut needed_points = 0;
        for turn in [0.5f64, -0.5] {
            let bottom = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.5, 0.9, 0.0]];
            let centre = [0.5, 0.3, 0.0];
            let top = bottom.map(|p| {
                let (x, y) = (p[0] - centre[0], p[1] - centre[1]);
                [
                    centre[0] + x * turn.cos() - y * turn.sin(),
                    centre[1] + x * turn.sin() + y * turn.cos(),
                    1.0,
                ]
            });
            let corners: Vec<[f64; 3]> = bottom
                .iter()
                .chain(&top)
                .map(|p| p.map(|x| f64::from(x as f32)))
                .collect();
            let mut faces = vec![[0, 2, 1], [3, 4, 5]];
            for a in 0..3u32 {
                let b = (a + 1) % 3;
                faces.push([a, b, b + 3]);
                faces.push([a, b + 3, a + 3]);
            }
            needed_points += fill_checked(&faces, &corners);
        }
        assert!(needed_points > 0, "Schönhardt's prism needs a point inside");
    }
}
