use super::{cross, dot, sub, Mesh};

/// Topology and quality of a triangle mesh.
///
/// Edges are undirected vertex pairs. A *boundary* edge has one triangle, a *non-manifold* edge
/// three or more. The mesh is *watertight* when it has triangles and neither kind of edge, and
/// *oriented* when every edge with two triangles is traversed in opposite directions by them and
/// no edge is traversed twice in the same direction. `euler` is `V − E + F` over the vertices
/// that triangles use; `genus` is `(2·components − euler) / 2`, given only for watertight,
/// oriented meshes. `components` counts groups of triangles connected through shared vertices.
/// A triangle is *degenerate* when it repeats a vertex or has zero area; angles are measured
/// over the others, in degrees. `area` is the total surface area; `volume` is the enclosed
/// volume (positive when the triangles face outward), given only for watertight, oriented meshes.
///
/// ```
/// use isocube::mesh::Mesh;
/// // A tetrahedron: closed, oriented, genus 0.
/// let mesh = Mesh {
///     positions: vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
///     normals: vec![],
///     triangles: vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]],
/// };
/// let r = mesh.report();
/// assert!(r.watertight && r.oriented);
/// assert_eq!((r.euler, r.genus), (2, Some(0)));
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct MeshReport {
    /// Vertices stored.
    pub vertices: usize,
    /// Triangles stored.
    pub triangles: usize,
    /// Distinct undirected edges.
    pub edges: usize,
    /// Edges with exactly one triangle.
    pub boundary_edges: usize,
    /// Edges with three or more triangles.
    pub nonmanifold_edges: usize,
    /// No boundary and no non-manifold edges (and at least one triangle).
    pub watertight: bool,
    /// Neighbouring triangles agree on orientation everywhere.
    pub oriented: bool,
    /// Connected components (through shared vertices).
    pub components: usize,
    /// `V − E + F` over used vertices.
    pub euler: i64,
    /// Total genus, for watertight oriented meshes.
    pub genus: Option<i64>,
    /// Triangles with a repeated vertex or zero area.
    pub degenerate: usize,
    /// Smallest angle of a non-degenerate triangle, in degrees (NaN without any).
    pub min_angle: f64,
    /// Largest angle of a non-degenerate triangle, in degrees (NaN without any).
    pub max_angle: f64,
    /// Total surface area.
    pub area: f64,
    /// Enclosed volume, for watertight oriented meshes (negative when triangles face inward).
    pub volume: Option<f64>,
}

impl MeshReport {
    /// Measures a mesh. `O(F log F)`.
    pub fn of(mesh: &Mesh) -> MeshReport {
        let nv = mesh.positions.len();
        let mut used = vec![false; nv];
        for t in &mesh.triangles {
            for &v in t {
                used[v as usize] = true;
            }
        }
        let EdgeReport {
            edges,
            boundary_edges: boundary,
            nonmanifold_edges: nonmanifold,
            oriented,
            ..
        } = EdgeReport::of(mesh);

        let mut uf = UnionFind::new(nv);
        for t in &mesh.triangles {
            uf.union(t[0] as usize, t[1] as usize);
            uf.union(t[0] as usize, t[2] as usize);
        }
        let used_count = used.iter().filter(|&&u| u).count();
        let components = (0..nv).filter(|&v| used[v] && uf.find(v) == v).count();
        let euler = used_count as i64 - edges as i64 + mesh.triangles.len() as i64;
        let watertight = !mesh.triangles.is_empty() && boundary == 0 && nonmanifold == 0;
        let genus = (watertight && oriented).then(|| (2 * components as i64 - euler) / 2);

        let mut degenerate = 0;
        let (mut min_angle, mut max_angle) = (f64::INFINITY, f64::NEG_INFINITY);
        let (mut area, mut volume) = (0.0, 0.0);
        // Volumes of tetrahedra to a point near the mesh keep the sum well conditioned.
        let centre = mesh.bounds().map_or([0.0; 3], |(lo, hi)| {
            [0, 1, 2].map(|a| (f64::from(lo[a]) + f64::from(hi[a])) / 2.0)
        });
        for t in &mesh.triangles {
            if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
                degenerate += 1;
                continue;
            }
            let p = t.map(|v| mesh.positions[v as usize].map(f64::from));
            let n = cross(sub(p[1], p[0]), sub(p[2], p[0]));
            area += dot(n, n).sqrt() / 2.0;
            volume += dot(
                sub(p[0], centre),
                cross(sub(p[1], centre), sub(p[2], centre)),
            ) / 6.0;
            if dot(n, n) == 0.0 {
                degenerate += 1;
                continue;
            }
            for angle in super::triangle_angles(p).into_iter().flatten() {
                min_angle = min_angle.min(angle);
                max_angle = max_angle.max(angle);
            }
        }
        if min_angle > max_angle {
            min_angle = f64::NAN;
            max_angle = f64::NAN;
        }
        MeshReport {
            vertices: nv,
            triangles: mesh.triangles.len(),
            edges,
            boundary_edges: boundary,
            nonmanifold_edges: nonmanifold,
            watertight,
            oriented,
            components,
            euler,
            genus,
            degenerate,
            min_angle,
            max_angle,
            area,
            volume: (watertight && oriented).then_some(volume),
        }
    }

    /// Watertight and consistently oriented: a closed orientable surface.
    pub fn is_closed_manifold(&self) -> bool {
        self.watertight && self.oriented
    }
}

/// The edge part of [`MeshReport`]: whether a mesh is closed and consistently oriented, without
/// the angles, area, volume and components. Linear in the mesh's size and parallel, so a command
/// can say "watertight" about every mesh it writes at a small fraction of the meshing's cost.
///
/// ```
/// use isocube::mesh::Mesh;
/// let mut mesh = Mesh {
///     positions: vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
///     normals: vec![],
///     triangles: vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]],
/// };
/// let e = mesh.edge_report();
/// assert!(e.watertight && e.oriented && e.edges == 6);
/// mesh.triangles.pop();
/// assert_eq!(mesh.edge_report().boundary_edges, 3);
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EdgeReport {
    /// Distinct undirected edges.
    pub edges: usize,
    /// Edges with exactly one triangle.
    pub boundary_edges: usize,
    /// Edges with three or more triangles.
    pub nonmanifold_edges: usize,
    /// No boundary and no non-manifold edges (and at least one triangle).
    pub watertight: bool,
    /// Neighbouring triangles agree on orientation everywhere.
    pub oriented: bool,
}

impl EdgeReport {
    /// Counts a mesh's edges. `O(F)` plus a sort of each vertex's few edges.
    pub fn of(mesh: &Mesh) -> EdgeReport {
        // Entries of 32 bits where the vertex numbers allow: half the memory to touch.
        if mesh.positions.len() < 1 << 31 {
            Self::filed::<u32>(mesh)
        } else {
            Self::filed::<u64>(mesh)
        }
    }

    /// [`EdgeReport::of`] with each directed edge filed under its lower vertex (a counting
    /// sort), as `higher << 1 | direction` in an `E`: a vertex's edges are then few and local.
    fn filed<E>(mesh: &Mesh) -> EdgeReport
    where
        E: Copy + Ord + Default + Send + Sync + TryFrom<u64> + Into<u64>,
    {
        use rayon::prelude::*;
        let nv = mesh.positions.len();
        let directed = |t: &[u32; 3]| {
            [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])]
                .into_iter()
                .filter(|(a, b)| a != b)
        };
        // `end[v]` counts the edges of vertices up to `v`, then (as the edges are filed) is
        // where the next edge of `v` goes, and at last where `v`'s edges end.
        let mut end = vec![0usize; nv];
        for t in &mesh.triangles {
            for (a, b) in directed(t) {
                end[a.min(b) as usize] += 1;
            }
        }
        let mut total = 0;
        for e in &mut end {
            (total, *e) = (total + *e, total);
        }
        let mut filed = vec![E::default(); total];
        for t in &mesh.triangles {
            for (a, b) in directed(t) {
                let (lo, hi, dir) = if a < b { (a, b, 0) } else { (b, a, 1) };
                let slot = &mut end[lo as usize];
                // The caller chose `E` wide enough for every vertex number.
                filed[*slot] = E::try_from(u64::from(hi) << 1 | dir).unwrap_or_default();
                *slot += 1;
            }
        }
        #[derive(Clone, Copy)]
        struct Counts {
            edges: usize,
            boundary: usize,
            nonmanifold: usize,
            oriented: bool,
        }
        let none = Counts {
            edges: 0,
            boundary: 0,
            nonmanifold: 0,
            oriented: true,
        };
        let counts = (0..nv)
            .into_par_iter()
            .with_min_len(1 << 12)
            .fold(
                || (none, Vec::new()),
                |(mut c, mut keys): (Counts, Vec<E>), v| {
                    let begin = if v == 0 { 0 } else { end[v - 1] };
                    keys.clear();
                    keys.extend_from_slice(&filed[begin..end[v]]);
                    keys.sort_unstable();
                    for group in keys.chunk_by(|x, y| (*x).into() >> 1 == (*y).into() >> 1) {
                        let forward = group.iter().filter(|&&k| k.into() & 1 == 0).count();
                        c.edges += 1;
                        match group.len() {
                            1 => c.boundary += 1,
                            2 => c.oriented &= forward == 1,
                            _ => c.nonmanifold += 1,
                        }
                        if forward > 1 || group.len() - forward > 1 {
                            c.oriented = false;
                        }
                    }
                    (c, keys)
                },
            )
            .map(|(c, _)| c)
            .reduce(
                || none,
                |a, b| Counts {
                    edges: a.edges + b.edges,
                    boundary: a.boundary + b.boundary,
                    nonmanifold: a.nonmanifold + b.nonmanifold,
                    oriented: a.oriented && b.oriented,
                },
            );
        EdgeReport {
            edges: counts.edges,
            boundary_edges: counts.boundary,
            nonmanifold_edges: counts.nonmanifold,
            watertight: !mesh.triangles.is_empty()
                && counts.boundary == 0
                && counts.nonmanifold == 0,
            oriented: counts.oriented,
        }
    }
}

struct UnionFind {
    parent: Vec<u32>,
}

impl UnionFind {
    fn new(n: usize) -> UnionFind {
        UnionFind {
            parent: (0..n as u32).collect(),
        }
    }

    fn find(&mut self, mut v: usize) -> usize {
        while self.parent[v] as usize != v {
            let grand = self.parent[self.parent[v] as usize];
            self.parent[v] = grand;
            v = grand as usize;
        }
        v
    }

    fn union(&mut self, a: usize, b: usize) {
        let (ra, rb) = (self.find(a), self.find(b));
        if ra != rb {
            // Keep the smaller index as root so results do not depend on union order.
            let (lo, hi) = if ra < rb { (ra, rb) } else { (rb, ra) };
            self.parent[hi] = lo as u32;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tetra() -> Mesh {
        Mesh {
            positions: vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 0.0, 1.0],
            ],
            normals: vec![],
            triangles: vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]],
        }
    }

    #[test]
    fn open_mesh_has_boundary() {
        let mut m = tetra();
        m.triangles.pop();
        let r = m.report();
        assert_eq!(r.boundary_edges, 3);
        assert!(!r.watertight && r.oriented);
        assert_eq!(r.genus, None);
        assert_eq!(r.euler, 1);
    }

    #[test]
    fn misoriented_and_nonmanifold_are_detected() {
        let mut m = tetra();
        m.triangles[0] = [0, 1, 2];
        assert!(!m.report().oriented);
        let mut m = tetra();
        m.triangles.push([0, 1, 2]);
        let r = m.report();
        assert_eq!(r.nonmanifold_edges, 3);
        assert!(!r.watertight);
    }

    #[test]
    fn degenerate_and_angles() {
        let m = Mesh {
            positions: vec![[0.0; 3], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            normals: vec![],
            triangles: vec![[0, 1, 2], [0, 1, 3], [1, 1, 3]],
        };
        let r = m.report();
        assert_eq!(r.degenerate, 2);
        assert!((r.min_angle - 45.0).abs() < 1e-9 && (r.max_angle - 90.0).abs() < 1e-9);
        assert_eq!(r.components, 1);
    }

    #[test]
    fn two_components() {
        let mut m = tetra();
        let off = m.positions.len() as u32;
        m.positions
            .extend(tetra().positions.iter().map(|p| [p[0] + 5.0, p[1], p[2]]));
        m.triangles
            .extend(tetra().triangles.iter().map(|t| t.map(|v| v + off)));
        let r = m.report();
        assert_eq!((r.components, r.euler, r.genus), (2, 4, Some(0)));
    }

    proptest::proptest! {
        /// The counting-sort edge report agrees with sorting every directed edge at once, on
        /// triangle soups with repeated, reversed, degenerate and shared edges.
        #[test]
        fn edge_report_matches_a_global_sort(
            nv in 1usize..12,
            raw in proptest::collection::vec((0u32..12, 0u32..12, 0u32..12), 0..40),
        ) {
            let triangles: Vec<[u32; 3]> = raw
                .iter()
                .map(|&(a, b, c)| [a, b, c].map(|v| v % nv as u32))
                .collect();
            let m = Mesh { positions: vec![[0.0; 3]; nv], normals: vec![], triangles };
            let mut keys: Vec<(u32, u32, bool)> = Vec::new();
            for t in &m.triangles {
                for i in 0..3 {
                    let (a, b) = (t[i], t[(i + 1) % 3]);
                    if a != b {
                        keys.push((a.min(b), a.max(b), a < b));
                    }
                }
            }
            keys.sort_unstable();
            let (mut edges, mut boundary, mut nonmanifold, mut oriented) = (0, 0, 0, true);
            for g in keys.chunk_by(|x, y| (x.0, x.1) == (y.0, y.1)) {
                let forward = g.iter().filter(|k| k.2).count();
                let backward = g.len() - forward;
                edges += 1;
                boundary += usize::from(g.len() == 1);
                nonmanifold += usize::from(g.len() > 2);
                oriented &= forward <= 1 && backward <= 1;
            }
            let e = m.edge_report();
            proptest::prop_assert_eq!(
                (e.edges, e.boundary_edges, e.nonmanifold_edges, e.oriented),
                (edges, boundary, nonmanifold, oriented)
            );
            proptest::prop_assert_eq!(
                e.watertight,
                !m.triangles.is_empty() && boundary == 0 && nonmanifold == 0
            );
        }
    }
}
