//! Checks of a tetrahedral mesh, exact where it matters: orientation by an exact predicate,
//! conformity by matching faces, and the volume against the boundary's.

use rayon::prelude::*;

use super::TetMesh;

/// Whether the tetrahedron `(a, b, c, d)` is positively oriented, `(b − a) · ((c − a) × (d − a))
/// > 0`, decided exactly on the given coordinates.
///
/// ```
/// use isocube::volume::positive;
/// let (a, b, c, d) = ([0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]);
/// assert!(positive(a, b, c, d));
/// assert!(!positive(a, c, b, d));
/// assert!(!positive(a, b, c, [0.5, 0.5, 0.0])); // flat
/// ```
pub fn positive(a: [f64; 3], b: [f64; 3], c: [f64; 3], d: [f64; 3]) -> bool {
    orientation(a, b, c, d) > 0.0
}

/// The sign of the tetrahedron's orientation, decided exactly: positive, negative or zero (flat).
fn orientation(a: [f64; 3], b: [f64; 3], c: [f64; 3], d: [f64; 3]) -> f64 {
    crate::mesh::intersect::orient(a, b, c, d)
}

/// Whether a triangle's corners lie on one line (exactly).
pub(super) fn collinear(t: [[f64; 3]; 3]) -> bool {
    crate::mesh::intersect::collinear(t)
}

/// Whether all the triangles' corners lie in one plane (exactly).
pub(super) fn coplanar(tris: &[[[f64; 3]; 3]]) -> bool {
    let points: Vec<[f64; 3]> = tris.iter().flatten().copied().collect();
    let Some(base) = tris.iter().find(|t| !collinear(**t)) else {
        return true;
    };
    points
        .iter()
        .all(|&x| orientation(base[0], base[1], base[2], x) == 0.0)
}

/// A point, rounded to `f32`, from which all of a closed part's outward triangles are seen from
/// inside: the centre of the largest ball in the kernel (a linear program, solved by trying every
/// set of four constraints: parts have a few dozen triangles, and this runs only when simple
/// guesses fail).
pub(super) fn kernel_point(tris: &[[[f64; 3]; 3]]) -> Option<[f32; 3]> {
    kernel_point_in(tris, None)
}

/// [`kernel_point`] for any set of triangles, optionally kept inside a box (`lo`, `hi`): for a
/// few triangles of a part, the region that sees them all is unbounded without it.
pub(super) fn kernel_point_in(
    tris: &[[[f64; 3]; 3]],
    bounds: Option<([f64; 3], [f64; 3])>,
) -> Option<[f32; 3]> {
    // Each constraint: n · x + t ≤ h, n the unit outward normal.
    let mut rows: Vec<([f64; 3], f64)> = tris
        .iter()
        .filter_map(|t| {
            let (u, w) = (sub(t[1], t[0]), sub(t[2], t[0]));
            let n = cross(u, w);
            let len = dot(n, n).sqrt();
            (len > 0.0).then(|| {
                let n = n.map(|x| x / len);
                (n, dot(n, t[0]))
            })
        })
        .collect();
    if let Some((lo, hi)) = bounds {
        for d in 0..3 {
            let mut n = [0.0; 3];
            n[d] = 1.0;
            rows.push((n, hi[d]));
            n[d] = -1.0;
            rows.push((n, -lo[d]));
        }
    }
    let m = rows.len();
    let mut best: Option<([f64; 3], f64)> = None;
    for a in 0..m {
        for b in a + 1..m {
            for c in b + 1..m {
                for d in c + 1..m {
                    let Some((x, t)) = solve4([rows[a], rows[b], rows[c], rows[d]]) else {
                        continue;
                    };
                    if best.is_some_and(|(_, bt)| t <= bt) {
                        continue;
                    }
                    let slack = 1e-12 * (1.0 + t.abs() + dot(x, x).sqrt());
                    if rows.iter().all(|(n, h)| dot(*n, x) + t <= h + slack) {
                        best = Some((x, t));
                    }
                }
            }
        }
    }
    let (x, t) = best?;
    if t <= 0.0 {
        return None;
    }
    let apex = x.map(|c| c as f32);
    tris.iter()
        .all(|tr| positive(tr[0], tr[2], tr[1], apex.map(f64::from)))
        .then_some(apex)
}

/// Solves n_i · x + t = h_i for four rows.
fn solve4(rows: [([f64; 3], f64); 4]) -> Option<([f64; 3], f64)> {
    let mut a: [[f64; 5]; 4] =
        std::array::from_fn(|i| [rows[i].0[0], rows[i].0[1], rows[i].0[2], 1.0, rows[i].1]);
    for col in 0..4 {
        let pivot = (col..4).max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))?;
        if a[pivot][col].abs() < 1e-12 {
            return None;
        }
        a.swap(col, pivot);
        for r in 0..4 {
            if r != col {
                let f = a[r][col] / a[col][col];
                let pivot_row = a[col];
                for (x, p) in a[r].iter_mut().zip(pivot_row).skip(col) {
                    *x -= f * p;
                }
            }
        }
    }
    let s: [f64; 4] = std::array::from_fn(|i| a[i][4] / a[i][i]);
    Some(([s[0], s[1], s[2]], s[3]))
}

pub(super) fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

pub(super) fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

pub(super) fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The angle, in degrees, at the edge from `u` to `v` between the half-planes through `p` and
/// through `q` (a tetrahedron's dihedral angle there, or the wedge two triangles make); `None`
/// when `p` or `q` lies on the edge's line.
pub(super) fn angle_across(u: [f64; 3], v: [f64; 3], p: [f64; 3], q: [f64; 3]) -> Option<f64> {
    let e = sub(v, u);
    // Each point's direction away from the edge, square to it.
    let away = |p: [f64; 3]| {
        let d = sub(p, u);
        let t = dot(d, e) / dot(e, e);
        [d[0] - t * e[0], d[1] - t * e[1], d[2] - t * e[2]]
    };
    let (x, y) = (away(p), away(q));
    let norm = (dot(x, x) * dot(y, y)).sqrt();
    (norm != 0.0).then(|| (dot(x, y) / norm).clamp(-1.0, 1.0).acos().to_degrees())
}

/// What [`TetMesh::check`] found.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TetCheck {
    /// Every face is shared by two tetrahedra, once each way, or is a boundary face; and the
    /// boundary faces are exactly the surface's and the walls' triangles, outward.
    pub conforming: bool,
    /// Faces used by more than two tetrahedra or twice the same way.
    pub bad_faces: usize,
    /// Boundary faces of the tetrahedra that are not surface or wall triangles, plus surface or
    /// wall triangles that bound no tetrahedron.
    pub boundary_mismatch: usize,
    /// Tetrahedra negatively oriented (exact predicate).
    pub inverted: usize,
    /// Tetrahedra with four coplanar vertices (exact predicate).
    pub flat: usize,
    /// Vertices other than the surface's that no tetrahedron uses (each would be a node with
    /// no element: a finite element system with one is singular).
    pub unused: usize,
    /// Sum of the tetrahedra's volumes.
    pub volume: f64,
    /// The volume the surface and walls enclose (divergence theorem).
    pub enclosed: f64,
}

impl TetMesh {
    /// Checks conformity, orientation and volume (see [`TetCheck`]).
    ///
    /// Conformity is first decided by a signature of the boundary chain: every oriented face
    /// of every tetrahedron is hashed (a 64-bit mix of its sorted corners, negated when its
    /// orientation is odd) and summed, and the sum must equal that of the boundary triangles.
    /// Faces shared by two tetrahedra the opposite ways cancel; any face left over or missing
    /// changes the sum except with probability about 2⁻⁶⁴. With every tetrahedron positive this
    /// is the whole of conformity: the tetrahedra's winding number is then 1 inside the
    /// boundary and 0 outside, so no two overlap and no face is used more than twice. Only when
    /// the signatures differ are the faces matched one by one to count what is wrong.
    ///
    /// ```
    /// use isocube::extract::ExtractOptions;
    /// use isocube::field::Sample;
    /// use isocube::volume::tetmesh;
    /// let mut mesh = tetmesh(&Sample::Sphere.grid(12), &ExtractOptions::default()).unwrap();
    /// assert!(mesh.check().conforming);
    /// mesh.tets.pop();
    /// let c = mesh.check();
    /// assert!(!c.conforming && c.boundary_mismatch == 4);
    /// ```
    pub fn check(&self) -> TetCheck {
        // Volumes are measured from a vertex of the mesh, not from a far origin.
        let o = self
            .positions
            .first()
            .map_or([0.0; 3], |x| x.map(f64::from));
        let p = |v: u32| sub(self.positions[v as usize].map(f64::from), o);
        // Sums are taken over fixed runs of elements, then in order: the same bits whatever
        // the number of threads.
        const RUN: usize = 1 << 14;
        let runs: Vec<(usize, usize, f64, u64)> = self
            .tets
            .par_chunks(RUN)
            .map(|run| {
                let mut out = (0, 0, 0.0, 0u64);
                for t in run {
                    let [a, b, c, d] = t.map(p);
                    out.2 += dot(sub(b, a), cross(sub(c, a), sub(d, a))) / 6.0;
                    let sign = orientation(a, b, c, d);
                    out.0 += usize::from(sign < 0.0);
                    out.1 += usize::from(sign == 0.0);
                    let [i, j, k, l] = *t;
                    out.3 = [[i, k, j], [i, j, l], [i, l, k], [j, k, l]]
                        .into_iter()
                        .fold(out.3, |s, f| s.wrapping_add(face_signature(f)));
                }
                out
            })
            .collect();
        let (inverted, flat, volume, chain) = runs.iter().fold((0, 0, 0.0, 0u64), |x, y| {
            (x.0 + y.0, x.1 + y.1, x.2 + y.2, x.3.wrapping_add(y.3))
        });
        let boundary = self.boundary_triangles();
        let expected = boundary
            .par_iter()
            .map(|&f| face_signature(f))
            .reduce(|| 0, u64::wrapping_add);
        let (bad_faces, boundary_mismatch) = if chain == expected {
            (0, 0)
        } else {
            self.match_boundary(&boundary)
        };
        let enclosed = boundary
            .par_chunks(RUN)
            .map(|run| {
                run.iter()
                    .map(|t| {
                        let [a, b, c] = t.map(p);
                        dot(a, cross(b, c)) / 6.0
                    })
                    .sum::<f64>()
            })
            .collect::<Vec<f64>>()
            .iter()
            .sum();
        TetCheck {
            conforming: bad_faces == 0 && boundary_mismatch == 0,
            bad_faces,
            boundary_mismatch,
            inverted,
            flat,
            unused: unused_points(
                self.positions.len(),
                &self.tets,
                self.surface_vertices as u32,
            )
            .len(),
            volume,
            enclosed,
        }
    }

    /// The triangles that bound the tetrahedra: the surface's but those beyond the grid, and
    /// the walls.
    pub(super) fn boundary_triangles(&self) -> Vec<[u32; 3]> {
        let mut beyond = self.beyond.clone();
        beyond.sort_unstable();
        self.surface
            .iter()
            .enumerate()
            .filter(|(t, _)| beyond.binary_search(&(*t as u32)).is_err())
            .map(|(_, &f)| f)
            .chain(self.walls.iter().copied())
            .collect()
    }

    /// Matches the tetrahedra's faces one by one: the faces used otherwise than once each way,
    /// and the mismatches between the faces used once and `boundary`.
    fn match_boundary(&self, boundary: &[[u32; 3]]) -> (usize, usize) {
        let canonical = |f: [u32; 3]| {
            let r = (0..3).min_by_key(|&r| f[r]).expect("three");
            [f[r], f[(r + 1) % 3], f[(r + 2) % 3]]
        };
        let (bad_faces, open) = match_faces(&self.tets, self.positions.len());
        let mut open: Vec<[u32; 3]> = open.into_iter().map(canonical).collect();
        let mut boundary: Vec<[u32; 3]> = boundary.iter().map(|&f| canonical(f)).collect();
        open.par_sort_unstable();
        boundary.par_sort_unstable();
        let mut boundary_mismatch = 0;
        let (mut a, mut b) = (0, 0);
        while a < open.len() || b < boundary.len() {
            match (open.get(a), boundary.get(b)) {
                (Some(x), Some(y)) if x == y => {
                    a += 1;
                    b += 1;
                }
                (Some(x), Some(y)) if x < y => {
                    boundary_mismatch += 1;
                    a += 1;
                }
                (Some(_), None) => {
                    boundary_mismatch += 1;
                    a += 1;
                }
                _ => {
                    boundary_mismatch += 1;
                    b += 1;
                }
            }
        }
        (bad_faces, boundary_mismatch)
    }
}

/// An oriented face's term in the boundary-chain signature: a hash of its corners in increasing
/// order, negated (mod 2⁶⁴) when sorting them takes an odd permutation, so that a face and its
/// reverse cancel.
fn face_signature(f: [u32; 3]) -> u64 {
    let [mut a, mut b, mut c] = f;
    let mut odd = false;
    if a > b {
        std::mem::swap(&mut a, &mut b);
        odd = !odd;
    }
    if b > c {
        std::mem::swap(&mut b, &mut c);
        odd = !odd;
    }
    if a > b {
        std::mem::swap(&mut a, &mut b);
        odd = !odd;
    }
    let h = mix(mix((u64::from(a) << 32) | u64::from(b)) ^ u64::from(c));
    if odd {
        h.wrapping_neg()
    } else {
        h
    }
}

/// SplitMix64's finaliser: a bijective mix of 64 bits.
fn mix(mut x: u64) -> u64 {
    x = x.wrapping_add(0x9e37_79b9_7f4a_7c15);
    x = (x ^ (x >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    x ^ (x >> 31)
}

/// Matches the tetrahedra's outward faces: each face is filed under its lowest vertex (a
/// counting sort, linear), each vertex's few faces are sorted on their own, in parallel. Returns
/// the faces used otherwise than once each way, and the faces used once (the boundary), as
/// oriented triangles.
pub(super) fn match_faces(tets: &[[u32; 4]], vertices: usize) -> (usize, Vec<[u32; 3]>) {
    /// The other two vertices of a face filed under its lowest, and its direction.
    type Filed = (u32, u32, bool);
    // A face (lowest vertex first, then the other two in order) and whether it runs that way.
    let faces_of = |&[a, b, c, d]: &[u32; 4]| {
        [[a, c, b], [a, b, d], [a, d, c], [b, c, d]].map(|f| {
            let r = (0..3).min_by_key(|&r| f[r]).expect("three");
            let (x, y) = (f[(r + 1) % 3], f[(r + 2) % 3]);
            (f[r], x.min(y), x.max(y), x < y)
        })
    };
    let mut start = vec![0usize; vertices + 1];
    for t in tets {
        for f in faces_of(t) {
            start[f.0 as usize + 1] += 1;
        }
    }
    for v in 0..vertices {
        start[v + 1] += start[v];
    }
    // (second, third, forward) per face, grouped by lowest vertex.
    let mut filed: Vec<Filed> = vec![(0, 0, false); start[vertices]];
    let mut next = start.clone();
    for t in tets {
        for (low, x, y, forward) in faces_of(t) {
            let at = &mut next[low as usize];
            filed[*at] = (x, y, forward);
            *at += 1;
        }
    }
    // Each vertex's faces, sorted and matched on their own.
    let mut slices: Vec<(u32, &mut [Filed])> = Vec::with_capacity(vertices);
    let mut rest = filed.as_mut_slice();
    for v in 0..vertices {
        let (head, tail) = std::mem::take(&mut rest).split_at_mut(start[v + 1] - start[v]);
        if !head.is_empty() {
            slices.push((v as u32, head));
        }
        rest = tail;
    }
    slices
        .into_par_iter()
        .map(|(low, faces)| {
            faces.sort_unstable();
            let mut bad = 0;
            let mut open = Vec::new();
            let mut i = 0;
            while i < faces.len() {
                let mut j = i + 1;
                while j < faces.len() && (faces[j].0, faces[j].1) == (faces[i].0, faces[i].1) {
                    j += 1;
                }
                let (x, y, forward) = faces[i];
                match j - i {
                    1 => open.push(if forward { [low, x, y] } else { [low, y, x] }),
                    2 if faces[i].2 != faces[i + 1].2 => {}
                    _ => bad += 1,
                }
                i = j;
            }
            (bad, open)
        })
        .reduce(
            || (0, Vec::new()),
            |mut a, mut b| {
                a.0 += b.0;
                a.1.append(&mut b.1);
                a
            },
        )
}

/// The points from `first` on that no tetrahedron of `tets` uses, in order.
pub(super) fn unused_points(count: usize, tets: &[[u32; 4]], first: u32) -> Vec<u32> {
    use std::sync::atomic::{AtomicBool, Ordering};
    let used: Vec<AtomicBool> = (first as usize..count)
        .map(|_| AtomicBool::new(false))
        .collect();
    tets.par_chunks(1 << 16).for_each(|chunk| {
        for &v in chunk.iter().flatten() {
            if v >= first {
                used[(v - first) as usize].store(true, Ordering::Relaxed);
            }
        }
    });
    used.iter()
        .enumerate()
        .filter(|(_, u)| !u.load(Ordering::Relaxed))
        .map(|(k, _)| first + k as u32)
        .collect()
}

/// Drops the points `removed` (sorted) from `positions`, numbering the later ones down in
/// `tets` and `walls` (none of which may use a dropped point).
pub(super) fn drop_points(
    positions: &mut Vec<[f32; 3]>,
    tets: &mut [[u32; 4]],
    walls: &mut [[u32; 3]],
    removed: &[u32],
) {
    let Some(&first) = removed.first() else {
        return;
    };
    let first = first as usize;
    let mut map: Vec<u32> = Vec::with_capacity(positions.len() - first);
    let (mut next, mut r) = (first as u32, 0);
    for old in first..positions.len() {
        if removed.get(r) == Some(&(old as u32)) {
            r += 1;
            map.push(u32::MAX);
        } else {
            map.push(next);
            next += 1;
        }
    }
    let renumber = |v: &mut u32| {
        if *v as usize >= first {
            *v = map[*v as usize - first];
            debug_assert_ne!(*v, u32::MAX, "a point taken out is used");
        }
    };
    tets.par_iter_mut()
        .for_each(|t| t.iter_mut().for_each(renumber));
    walls
        .par_iter_mut()
        .for_each(|t| t.iter_mut().for_each(renumber));
    let mut k = first;
    let mut r = 0;
    let kept = positions.split_off(first);
    positions.extend(kept.into_iter().filter(|_| {
        let gone = removed.get(r) == Some(&(k as u32));
        r += usize::from(gone);
        k += 1;
        !gone
    }));
}
