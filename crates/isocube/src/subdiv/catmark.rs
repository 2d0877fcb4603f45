//! Catmull–Clark refinement with OpenSubdiv's rules (its Catmark scheme, uniform crease
//! method).
//!
//! One level: a face point at each face's centroid; an edge point at the midpoint of a sharp
//! edge, at (v0 + v1 + f0 + f1) / 4 for a smooth one, blended by the sharpness for a
//! semi-sharp one (0 < s < 1); a vertex point by the rule its sharp edges and corner sharpness
//! call for — smooth (and dart, one sharp edge): ((n − 2) v + Σ e / n + Σ f / n) / n; crease (two
//! sharp edges a, b): (6 v + a + b) / 8; corner (more, or corner sharpness): v — blended by the
//! transition weight where the rule changes from one level to the next. Sharpness decreases by
//! one per level (10 and above stays infinitely sharp). Boundary edges and non-manifold edges
//! are infinitely sharp unless the boundary rule is `None`; with `EdgeAndCorner`, boundary
//! vertices with one face are corners. Every face of n sides becomes n quads.
//!
//! Levels are kept compact (faces, edges and adjacency as flat arrays). Only the cage's edges
//! are found by hashing; a refined level's edges follow from its parent's (each edge splits in
//! two, each face corner adds one), as OpenSubdiv does. The point rules run in parallel; the
//! result does not depend on the number of threads.

use rayon::prelude::*;
use rustc_hash::FxHashMap as HashMap;

use super::holes::{remove_inner_loops, restore_inner_loops};
use super::{BoundaryRule, Face, PolyMesh, SubdivError, SubdivOptions, INFINITELY_SHARP};

/// Sharpness one level down.
fn decrement(s: f32) -> f32 {
    if s >= INFINITELY_SHARP {
        s
    } else {
        (s - 1.0).max(0.0)
    }
}

#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Rule {
    Smooth,
    Crease,
    Corner,
}

fn rule(vertex_sharpness: f32, sharp_edges: usize) -> Rule {
    if vertex_sharpness > 0.0 || sharp_edges > 2 {
        Rule::Corner
    } else if sharp_edges == 2 {
        Rule::Crease
    } else {
        // Dart (one sharp edge) uses the smooth rule.
        Rule::Smooth
    }
}

fn csr(count: usize, pairs: impl Iterator<Item = (usize, u32)> + Clone) -> (Vec<u32>, Vec<u32>) {
    let mut start = vec![0u32; count + 1];
    for (k, _) in pairs.clone() {
        start[k + 1] += 1;
    }
    for k in 0..count {
        start[k + 1] += start[k];
    }
    let mut fill = start.clone();
    let mut items = vec![0u32; start[count] as usize];
    for (k, x) in pairs {
        items[fill[k] as usize] = x;
        fill[k] += 1;
    }
    (start, items)
}

/// One level of a mesh without inner loops, with its adjacency.
struct Level {
    positions: Vec<[f64; 3]>,
    /// Faces as CSR: face f is `verts[start[f]..start[f + 1]]`.
    start: Vec<u32>,
    verts: Vec<u32>,
    /// Edge from each face corner to the next corner.
    corner_edge: Vec<u32>,
    edges: Vec<[u32; 2]>,
    /// Tagged sharpness of edges and vertices (boundary sharpness is derived per level).
    edge_tag: Vec<f32>,
    vertex_tag: Vec<f32>,
    holes: Vec<bool>,
    /// Adjacency, built when needed (the last level never needs it).
    adjacency: std::sync::OnceLock<Adjacency>,
}

/// Faces of each edge, edges and faces of each vertex (CSR).
struct Adjacency {
    edge_face_start: Vec<u32>,
    edge_faces: Vec<u32>,
    vertex_edge_start: Vec<u32>,
    vertex_edges: Vec<u32>,
    vertex_face_start: Vec<u32>,
    vertex_faces: Vec<u32>,
}

impl Level {
    /// The cage's level: edges found by hashing vertex pairs.
    fn from_mesh(mesh: &PolyMesh) -> Level {
        let mut start = Vec::with_capacity(mesh.faces.len() + 1);
        let mut verts = Vec::new();
        start.push(0u32);
        for f in &mesh.faces {
            verts.extend_from_slice(&f.outer);
            start.push(verts.len() as u32);
        }
        let mut edge_of: HashMap<(u32, u32), u32> = HashMap::default();
        edge_of.reserve(verts.len());
        let mut edges = Vec::new();
        let mut corner_edge = vec![0u32; verts.len()];
        for f in 0..mesh.faces.len() {
            let (a, b) = (start[f] as usize, start[f + 1] as usize);
            for c in a..b {
                let (u, v) = (verts[c], verts[if c + 1 == b { a } else { c + 1 }]);
                let key = (u.min(v), u.max(v));
                corner_edge[c] = *edge_of.entry(key).or_insert_with(|| {
                    edges.push([key.0, key.1]);
                    (edges.len() - 1) as u32
                });
            }
        }
        let edge_tag = edges.iter().map(|&[a, b]| mesh.crease(a, b)).collect();
        let vertex_tag = (0..mesh.positions.len() as u32)
            .map(|v| mesh.corners.get(&v).copied().unwrap_or(0.0))
            .collect();
        let holes = (0..mesh.faces.len()).map(|f| mesh.is_hole(f)).collect();
        Level {
            positions: mesh.positions.clone(),
            start,
            verts,
            corner_edge,
            edges,
            edge_tag,
            vertex_tag,
            holes,
            adjacency: std::sync::OnceLock::new(),
        }
    }

    fn adjacency(&self) -> &Adjacency {
        self.adjacency.get_or_init(|| {
            let nf = self.start.len() - 1;
            let corner_face: Vec<u32> = (0..nf)
                .flat_map(|f| {
                    std::iter::repeat_n(f as u32, (self.start[f + 1] - self.start[f]) as usize)
                })
                .collect();
            let (edge_face_start, edge_faces) = csr(
                self.edges.len(),
                self.corner_edge
                    .iter()
                    .zip(&corner_face)
                    .map(|(&e, &f)| (e as usize, f)),
            );
            let (vertex_edge_start, vertex_edges) = csr(
                self.positions.len(),
                self.edges
                    .iter()
                    .enumerate()
                    .flat_map(|(e, &[a, b])| [(a as usize, e as u32), (b as usize, e as u32)]),
            );
            let (vertex_face_start, vertex_faces) = csr(
                self.positions.len(),
                self.verts
                    .iter()
                    .zip(&corner_face)
                    .map(|(&v, &f)| (v as usize, f)),
            );
            Adjacency {
                edge_face_start,
                edge_faces,
                vertex_edge_start,
                vertex_edges,
                vertex_face_start,
                vertex_faces,
            }
        })
    }

    fn face_count(&self) -> usize {
        self.start.len() - 1
    }

    fn face(&self, f: usize) -> &[u32] {
        &self.verts[self.start[f] as usize..self.start[f + 1] as usize]
    }

    fn edge_faces(&self, e: usize) -> &[u32] {
        let a = self.adjacency();
        &a.edge_faces[a.edge_face_start[e] as usize..a.edge_face_start[e + 1] as usize]
    }

    fn vertex_edges(&self, v: usize) -> &[u32] {
        let a = self.adjacency();
        &a.vertex_edges[a.vertex_edge_start[v] as usize..a.vertex_edge_start[v + 1] as usize]
    }

    fn vertex_faces(&self, v: usize) -> &[u32] {
        let a = self.adjacency();
        &a.vertex_faces[a.vertex_face_start[v] as usize..a.vertex_face_start[v + 1] as usize]
    }

    fn other(&self, e: usize, v: u32) -> u32 {
        let [a, b] = self.edges[e];
        if a == v {
            b
        } else {
            a
        }
    }

    fn is_boundary_vertex(&self, v: usize) -> bool {
        self.vertex_edges(v)
            .iter()
            .any(|&e| self.edge_faces(e as usize).len() == 1)
    }

    /// Sharpness of every edge and vertex: the tags, plus what the boundary rule and
    /// non-manifold edges make sharp.
    fn sharpness(&self, boundary: BoundaryRule) -> (Vec<f32>, Vec<f32>) {
        let edge = (0..self.edges.len())
            .into_par_iter()
            .map(|e| {
                let faces = self.edge_faces(e).len();
                if faces > 2 || (faces == 1 && boundary != BoundaryRule::None) {
                    INFINITELY_SHARP.max(self.edge_tag[e])
                } else {
                    self.edge_tag[e]
                }
            })
            .collect();
        let vertex = (0..self.positions.len())
            .into_par_iter()
            .map(|v| {
                if boundary == BoundaryRule::EdgeAndCorner
                    && self.vertex_faces(v).len() == 1
                    && self.is_boundary_vertex(v)
                {
                    INFINITELY_SHARP.max(self.vertex_tag[v])
                } else {
                    self.vertex_tag[v]
                }
            })
            .collect();
        (edge, vertex)
    }

    /// One level of refinement.
    fn refine(&self, boundary: BoundaryRule) -> Level {
        let (edge_sharp, vertex_sharp) = self.sharpness(boundary);
        let p = &self.positions;
        let (nf, ne, nv) = (self.face_count(), self.edges.len(), p.len());

        let face_points: Vec<[f64; 3]> = (0..nf)
            .into_par_iter()
            .map(|f| {
                let vs = self.face(f);
                let sum = vs.iter().fold([0.0; 3], |s, &v| add(s, p[v as usize]));
                scale(sum, 1.0 / vs.len() as f64)
            })
            .collect();
        let edge_points: Vec<[f64; 3]> = (0..ne)
            .into_par_iter()
            .map(|e| {
                let [a, b] = self.edges[e];
                let mid = scale(add(p[a as usize], p[b as usize]), 0.5);
                let faces = self.edge_faces(e);
                let s = f64::from(edge_sharp[e]);
                if faces.len() != 2 || s >= 1.0 {
                    return mid;
                }
                let smooth = scale(
                    add(
                        add(p[a as usize], p[b as usize]),
                        add(
                            face_points[faces[0] as usize],
                            face_points[faces[1] as usize],
                        ),
                    ),
                    0.25,
                );
                if s > 0.0 {
                    lerp(smooth, mid, s)
                } else {
                    smooth
                }
            })
            .collect();
        let vertex_points: Vec<[f64; 3]> = (0..nv)
            .into_par_iter()
            .map(|v| self.vertex_point(v, &face_points, &edge_sharp, &vertex_sharp))
            .collect();

        // Children: face points, then edge points, then vertex points (OpenSubdiv's order).
        let mut positions = Vec::with_capacity(nf + ne + nv);
        positions.extend(face_points);
        positions.extend(edge_points);
        positions.extend(vertex_points);
        let (fp, ep, vp) = (
            |f: usize| f as u32,
            |e: u32| nf as u32 + e,
            |v: u32| (nf + ne) as u32 + v,
        );
        // Child edges: the halves of each parent edge (2e from its first vertex, 2e + 1 from
        // its second), then one per face corner, from the face point to the corner's edge point.
        let corners = self.verts.len();
        let mut edges = Vec::with_capacity(2 * ne + corners);
        let mut edge_tag = Vec::with_capacity(2 * ne + corners);
        for e in 0..ne {
            let [a, b] = self.edges[e];
            edges.push([vp(a), ep(e as u32)]);
            edges.push([ep(e as u32), vp(b)]);
            let s = decrement(self.edge_tag[e]);
            edge_tag.push(s);
            edge_tag.push(s);
        }
        for f in 0..nf {
            for c in self.start[f]..self.start[f + 1] {
                edges.push([fp(f), ep(self.corner_edge[c as usize])]);
                edge_tag.push(0.0);
            }
        }
        let half = |e: u32, v: u32| 2 * e + u32::from(self.edges[e as usize][0] != v);
        let mut start = Vec::with_capacity(corners + 1);
        let mut verts = Vec::with_capacity(4 * corners);
        let mut corner_edge = Vec::with_capacity(4 * corners);
        let mut holes = Vec::with_capacity(corners);
        start.push(0u32);
        let none_holes = boundary == BoundaryRule::None;
        for f in 0..nf {
            let (a, b) = (self.start[f] as usize, self.start[f + 1] as usize);
            let n = b - a;
            let hole = self.holes[f]
                || (none_holes
                    && self
                        .face(f)
                        .iter()
                        .any(|&v| self.is_boundary_vertex(v as usize)));
            for i in 0..n {
                let c = a + i;
                let prev = a + (i + n - 1) % n;
                let (v, e, e_prev) = (self.verts[c], self.corner_edge[c], self.corner_edge[prev]);
                verts.extend_from_slice(&[vp(v), ep(e), fp(f), ep(e_prev)]);
                corner_edge.extend_from_slice(&[
                    half(e, v),
                    (2 * ne + c) as u32,
                    (2 * ne + prev) as u32,
                    half(e_prev, v),
                ]);
                start.push(verts.len() as u32);
                holes.push(hole);
            }
        }
        let mut vertex_tag = vec![0.0f32; nf + ne];
        vertex_tag.extend(self.vertex_tag.iter().map(|&s| decrement(s)));
        Level {
            positions,
            start,
            verts,
            corner_edge,
            edges,
            edge_tag,
            vertex_tag,
            holes,
            adjacency: std::sync::OnceLock::new(),
        }
    }

    /// The vertex point of `v`, blending the rules of this level and the next where they differ.
    fn vertex_point(
        &self,
        v: usize,
        face_points: &[[f64; 3]],
        edge_sharp: &[f32],
        vertex_sharp: &[f32],
    ) -> [f64; 3] {
        let p = &self.positions;
        let edges = self.vertex_edges(v);
        if edges.is_empty() {
            return p[v];
        }
        let vs = vertex_sharp[v];
        let sharp_now = edges
            .iter()
            .filter(|&&e| edge_sharp[e as usize] > 0.0)
            .count();
        let sharp_next = edges
            .iter()
            .filter(|&&e| decrement(edge_sharp[e as usize]) > 0.0)
            .count();
        let parent = rule(vs, sharp_now);
        let child = rule(decrement(vs), sharp_next);
        let at_parent = self.rule_point(v, parent, face_points, &|e| edge_sharp[e] > 0.0);
        if parent == child {
            return at_parent;
        }
        let at_child = self.rule_point(v, child, face_points, &|e| decrement(edge_sharp[e]) > 0.0);
        // Where the rule changes, blend by the mean sharpness of what turns smooth.
        let mut count = 0;
        let mut sum = 0.0f64;
        if vs > 0.0 && decrement(vs) <= 0.0 {
            count += 1;
            sum += f64::from(vs);
        }
        for &e in edges {
            let s = edge_sharp[e as usize];
            if s > 0.0 && decrement(s) <= 0.0 {
                count += 1;
                sum += f64::from(s);
            }
        }
        let w = if count == 0 {
            0.0
        } else {
            (sum / f64::from(count)).min(1.0)
        };
        lerp(at_child, at_parent, w)
    }

    /// A vertex point by one rule; `sharp(e)` says which incident edges count as sharp for it.
    fn rule_point(
        &self,
        v: usize,
        r: Rule,
        face_points: &[[f64; 3]],
        sharp: &dyn Fn(usize) -> bool,
    ) -> [f64; 3] {
        let p = &self.positions;
        let edges = self.vertex_edges(v);
        let faces = self.vertex_faces(v);
        let crease = |ends: &mut dyn Iterator<Item = u32>| -> [f64; 3] {
            let s = ends.fold(scale(p[v], 6.0), |s, o| add(s, p[o as usize]));
            scale(s, 1.0 / 8.0)
        };
        match r {
            Rule::Corner => p[v],
            Rule::Crease => crease(
                &mut edges
                    .iter()
                    .filter(|&&e| sharp(e as usize))
                    .map(|&e| self.other(e as usize, v as u32)),
            ),
            Rule::Smooth => {
                if faces.len() != edges.len() {
                    // A boundary vertex under the `None` rule: its faces are holes; follow the
                    // boundary so the inner faces next to it stay well shaped.
                    let ends: Vec<u32> = edges
                        .iter()
                        .filter(|&&e| self.edge_faces(e as usize).len() == 1)
                        .map(|&e| self.other(e as usize, v as u32))
                        .collect();
                    return if ends.len() == 2 {
                        crease(&mut ends.into_iter())
                    } else {
                        p[v]
                    };
                }
                let n = edges.len() as f64;
                let e_sum = edges.iter().fold([0.0; 3], |s, &e| {
                    add(s, p[self.other(e as usize, v as u32) as usize])
                });
                let f_sum = faces
                    .iter()
                    .fold([0.0; 3], |s, &f| add(s, face_points[f as usize]));
                scale(
                    add(scale(p[v], n - 2.0), scale(add(e_sum, f_sum), 1.0 / n)),
                    1.0 / n,
                )
            }
        }
    }

    fn into_mesh(self, boundary: Option<BoundaryRule>) -> PolyMesh {
        let mut mesh = PolyMesh {
            faces: (0..self.face_count())
                .map(|f| Face::new(self.face(f).to_vec()))
                .collect(),
            boundary,
            ..PolyMesh::default()
        };
        for (e, &s) in self.edge_tag.iter().enumerate() {
            if s > 0.0 {
                let [a, b] = self.edges[e];
                mesh.set_crease(a, b, s);
            }
        }
        for (v, &s) in self.vertex_tag.iter().enumerate() {
            if s > 0.0 {
                mesh.corners.insert(v as u32, s);
            }
        }
        if self.holes.iter().any(|&h| h) {
            mesh.holes = self.holes;
        }
        mesh.positions = self.positions;
        mesh
    }
}

fn add(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

fn scale(a: [f64; 3], s: f64) -> [f64; 3] {
    [a[0] * s, a[1] * s, a[2] * s]
}

fn lerp(a: [f64; 3], b: [f64; 3], t: f64) -> [f64; 3] {
    add(scale(a, 1.0 - t), scale(b, t))
}

/// One level of uniform Catmull–Clark refinement of a mesh without inner loops.
///
/// The mesh's own boundary rule applies unless `boundary` is given.
pub fn refine(mesh: &PolyMesh, boundary: Option<BoundaryRule>) -> Result<PolyMesh, SubdivError> {
    mesh.validate()?;
    if let Some(f) = mesh.faces.iter().position(|f| !f.inner.is_empty()) {
        return Err(SubdivError::Holes {
            face: f,
            reason: "refine takes faces without inner loops; subdivide converts them first".into(),
        });
    }
    let rule = boundary.or(mesh.boundary).unwrap_or_default();
    Ok(Level::from_mesh(mesh).refine(rule).into_mesh(mesh.boundary))
}

/// Refines `levels` times. Faces with inner loops are first made ordinary by
/// `options.holes` (and, for [`super::HoleMethod::Sharp`], restored afterwards: each original
/// face with inner loops comes back as one face with its refined loops).
pub fn subdivide(
    mesh: &PolyMesh,
    levels: usize,
    options: &SubdivOptions,
) -> Result<PolyMesh, SubdivError> {
    mesh.validate()?;
    // The first level makes a quad per face corner, every later one four per quad.
    let sides: usize = mesh.faces.iter().map(|f| f.outer.len()).sum();
    let faces = sides.saturating_mul(4usize.saturating_pow(levels.saturating_sub(1) as u32));
    if levels > 0 && faces > super::MAX_FACES {
        return Err(SubdivError::TooManyFaces { levels, faces });
    }
    let (cage, mut origin) = remove_inner_loops(mesh, options.holes)?;
    let rule = options.boundary.or(mesh.boundary).unwrap_or_default();
    let mut level = Level::from_mesh(&cage);
    for _ in 0..levels {
        // The original face each face comes from, followed through the levels.
        origin = (0..level.face_count())
            .flat_map(|f| {
                let n = (level.start[f + 1] - level.start[f]) as usize;
                std::iter::repeat_n(origin[f], n)
            })
            .collect();
        level = level.refine(rule);
    }
    restore_inner_loops(mesh, level.into_mesh(mesh.boundary), &origin, options.holes)
}

/// The limit positions of a quad mesh's vertices (a mesh refined at least once): smooth
/// vertices by the Catmull–Clark limit mask (n² v + 4 Σ e + Σ d) / (n (n + 5)), crease
/// vertices by (4 v + a + b) / 6, corners stay. Sharpness still left at this level counts as
/// sharp.
pub fn limit_positions(mesh: &PolyMesh) -> Result<Vec<[f64; 3]>, SubdivError> {
    mesh.validate()?;
    if let Some(f) = mesh
        .faces
        .iter()
        .position(|f| f.outer.len() != 4 || !f.inner.is_empty())
    {
        return Err(SubdivError::Face {
            face: f,
            reason: "limit positions need a quad mesh: refine at least once".into(),
        });
    }
    let level = Level::from_mesh(mesh);
    let (edge_sharp, vertex_sharp) = level.sharpness(mesh.boundary.unwrap_or_default());
    let p = &level.positions;
    Ok((0..p.len())
        .into_par_iter()
        .map(|v| {
            let edges = level.vertex_edges(v);
            let faces = level.vertex_faces(v);
            if edges.is_empty() {
                return p[v];
            }
            let sharp: Vec<u32> = edges
                .iter()
                .filter(|&&e| edge_sharp[e as usize] > 0.0)
                .map(|&e| level.other(e as usize, v as u32))
                .collect();
            match rule(vertex_sharp[v], sharp.len()) {
                Rule::Corner => p[v],
                Rule::Crease => scale(
                    add(
                        scale(p[v], 4.0),
                        add(p[sharp[0] as usize], p[sharp[1] as usize]),
                    ),
                    1.0 / 6.0,
                ),
                Rule::Smooth if faces.len() != edges.len() => p[v],
                Rule::Smooth => {
                    let n = edges.len() as f64;
                    let e_sum = edges.iter().fold([0.0; 3], |s, &e| {
                        add(s, p[level.other(e as usize, v as u32) as usize])
                    });
                    // The corner of each quad opposite the vertex.
                    let d_sum = faces.iter().fold([0.0; 3], |s, &f| {
                        let q = level.face(f as usize);
                        let k = q.iter().position(|&x| x as usize == v).unwrap_or(0);
                        add(s, p[q[(k + 2) % 4] as usize])
                    });
                    scale(
                        add(scale(p[v], n * n), add(scale(e_sum, 4.0), d_sum)),
                        1.0 / (n * (n + 5.0)),
                    )
                }
            }
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::subdiv::samples::sample;
    use proptest::prelude::*;

    /// The mesh after `k` more levels, and how far vertex indices shift meanwhile: a vertex
    /// point keeps its parent's index after the face and edge points of each level.
    fn descendants(mut mesh: PolyMesh, k: usize) -> (PolyMesh, usize) {
        let mut shift = 0;
        for _ in 0..k {
            let level = Level::from_mesh(&mesh);
            shift += level.face_count() + level.edges.len();
            mesh = refine(&mesh, None).unwrap();
        }
        (mesh, shift)
    }

    /// Limit positions agree with where refinement takes the vertices: smooth, crease (an
    /// infinitely sharp loop) and corner vertices, closed and with a boundary.
    #[test]
    fn limit_positions_are_where_refinement_converges() {
        let mut cube = sample("cube").unwrap();
        for (a, b) in [(4, 5), (5, 6), (6, 7), (7, 4)] {
            cube.set_crease(a, b, INFINITELY_SHARP);
        }
        cube.corners.insert(0, INFINITELY_SHARP);
        let mut open = sample("cube").unwrap();
        open.faces.remove(1);
        for (name, cage) in [("creased cube", cube), ("open cube", open)] {
            let once = refine(&cage, None).unwrap();
            let limit = limit_positions(&once).unwrap();
            let (fine, shift) = descendants(once.clone(), 7);
            let worst = limit
                .iter()
                .enumerate()
                .map(|(v, l)| {
                    let far = fine.positions[v + shift];
                    (0..3).map(|k| (far[k] - l[k]).powi(2)).sum::<f64>().sqrt()
                })
                .fold(0.0, f64::max);
            assert!(worst < 2e-3, "{name}: {worst}");
            // And the refined positions themselves are not the limit (the test can tell).
            let moved = (0..once.positions.len())
                .map(|v| {
                    (0..3)
                        .map(|k| (once.positions[v][k] - limit[v][k]).abs())
                        .sum::<f64>()
                })
                .fold(0.0, f64::max);
            assert!(moved > 0.05, "{name}: {moved}");
        }
        assert!(limit_positions(&sample("plate").unwrap()).is_err());
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 200, failure_persistence: None, ..ProptestConfig::default() })]

        /// Random prisms over n-gons (closed, or with the top removed), random creases and
        /// corners, any boundary rule: V' = V + E + F, F' = Σ sides, closed stays closed with
        /// the same Euler characteristic, open keeps its boundary loop (doubled), all finite.
        #[test]
        fn refinement_keeps_topology(
            n in 3usize..9,
            open: bool,
            creases in proptest::collection::vec((0usize..64, 0.0f32..12.0), 0..6),
            corners in proptest::collection::vec((0usize..64, 0.0f32..12.0), 0..3),
            rule in 0u8..3,
            levels in 1usize..4,
        ) {
            let pts: Vec<[f64; 2]> = (0..n)
                .map(|i| {
                    let a = 2.0 * std::f64::consts::PI * i as f64 / n as f64;
                    [a.cos(), a.sin()]
                })
                .collect();
            let mut m = PolyMesh::default();
            for z in [0.0, 1.0] {
                for p in &pts {
                    m.positions.push([p[0], p[1], z]);
                }
            }
            let n32 = n as u32;
            m.faces.push(Face::new((0..n32).rev().collect()));
            if !open {
                m.faces.push(Face::new((n32..2 * n32).collect()));
            }
            for i in 0..n32 {
                let j = (i + 1) % n32;
                m.faces.push(Face::new(vec![i, j, j + n32, i + n32]));
            }
            for (k, s) in creases {
                let i = (k % n) as u32;
                let (a, b) = match k % 3 {
                    0 => (i, (i + 1) % n32),
                    1 => (i, i + n32),
                    _ => (i + n32, (i + 1) % n32 + n32),
                };
                m.set_crease(a, b, s);
            }
            for (k, s) in corners {
                m.corners.insert((k % (2 * n)) as u32, s);
            }
            m.boundary = Some([BoundaryRule::None, BoundaryRule::EdgeAndCorner, BoundaryRule::EdgeOnly][rule as usize]);
            let before = m.triangulate().unwrap().report();
            let mut current = m.clone();
            for _ in 0..levels {
                let level = Level::from_mesh(&current);
                let (v, e, f) = (current.positions.len(), level.edges.len(), current.faces.len());
                let sides: usize = current.faces.iter().map(|f| f.outer.len()).sum();
                let next = refine(&current, None).unwrap();
                prop_assert_eq!(next.positions.len(), v + e + f);
                prop_assert_eq!(next.faces.len(), sides);
                prop_assert!(next.positions.iter().all(|p| p.iter().all(|c| c.is_finite())));
                current = next;
            }
            // Hole tags only hide faces; count the whole surface.
            current.holes.clear();
            let after = current.triangulate().unwrap().report();
            prop_assert_eq!(after.watertight, before.watertight);
            prop_assert!(after.oriented);
            prop_assert_eq!(after.euler, before.euler);
            prop_assert_eq!(after.boundary_edges, before.boundary_edges << levels);
        }
    }
}
