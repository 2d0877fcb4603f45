//! Splitting a closed part of a cell's region in two along a disc spanning a cycle of its
//! edges: the last resort of [`super::Context::fill`] for parts that fold so that no set of
//! cone points fills them whole.
//!
//! A simple cycle of edges on a part's boundary (a sphere) cuts it into two discs. Closing each
//! with the same spanning disc, once each way, gives two closed surfaces whose sum, as chains, is
//! the part's boundary: tetrahedra filling each, all positive, tile the part. Nothing about the
//! disc needs checking beyond its triangles having area: a disc that leaves the part, or crosses
//! its boundary, makes one side a surface no positive tetrahedra can fill. A cycle round a
//! handle (a part the surface's tunnel runs through) separates nothing: the part cut open along
//! the disc, closed by it on both sides, is one surface of lower genus, filled the same way.

use super::check;

/// The longest cycle tried.
const LONGEST: usize = 5;
/// How many (cycle, disc) splits are offered at most.
const MOST: usize = 96;

/// A part's edges and triangles, ready to offer splits.
pub(super) struct Splitter<'a> {
    part: &'a [[u32; 3]],
    /// Undirected edges (lower, upper), sorted, each with its two triangles.
    edges: Vec<((u32, u32), [usize; 2])>,
    /// Whether each edge of `edges` is reflex seen from inside.
    reflex: Vec<bool>,
    position: &'a dyn Fn(u32) -> [f64; 3],
}

impl<'a> Splitter<'a> {
    /// `None` when the part is not a closed surface whose every edge has two triangles.
    pub(super) fn new(part: &'a [[u32; 3]], position: &'a dyn Fn(u32) -> [f64; 3]) -> Option<Self> {
        let mut uses: Vec<((u32, u32), usize)> = part
            .iter()
            .enumerate()
            .flat_map(|(i, t)| {
                (0..3).map(move |k| {
                    let (a, b) = (t[k], t[(k + 1) % 3]);
                    ((a.min(b), a.max(b)), i)
                })
            })
            .collect();
        uses.sort_unstable();
        let mut edges = Vec::with_capacity(uses.len() / 2);
        for pair in uses.chunks(2) {
            if pair.len() != 2 || pair[0].0 != pair[1].0 {
                return None;
            }
            edges.push((pair[0].0, [pair[0].1, pair[1].1]));
        }
        if edges.windows(2).any(|w| w[0].0 == w[1].0) {
            return None;
        }
        let reflex = edges
            .iter()
            .map(|&((a, b), [i, j])| {
                // The far corner of the second triangle lies outside the first's plane.
                let t = part[i];
                let d = part[j]
                    .into_iter()
                    .find(|&v| v != a && v != b)
                    .expect("a triangle");
                let p = t.map(position);
                check::positive(p[0], p[1], p[2], position(d))
            })
            .collect();
        Some(Splitter {
            part,
            edges,
            reflex,
            position,
        })
    }

    fn edge(&self, a: u32, b: u32) -> Option<usize> {
        self.edges
            .binary_search_by(|e| e.0.cmp(&(a.min(b), a.max(b))))
            .ok()
    }

    /// Simple cycles of 3 to [`LONGEST`] vertices that are not one triangle's boundary, each
    /// once (starting at its lowest vertex, either direction), those through more reflex edges
    /// first, then shorter ones.
    fn cycles(&self) -> Vec<Vec<u32>> {
        let mut vertices: Vec<u32> = self.part.iter().flatten().copied().collect();
        vertices.sort_unstable();
        vertices.dedup();
        let neighbours = |v: u32| {
            self.edges.iter().filter_map(move |&((a, b), _)| {
                if a == v {
                    Some(b)
                } else if b == v {
                    Some(a)
                } else {
                    None
                }
            })
        };
        let mut out: Vec<Vec<u32>> = Vec::new();
        let mut path = Vec::with_capacity(LONGEST);
        fn walk(
            path: &mut Vec<u32>,
            out: &mut Vec<Vec<u32>>,
            neighbours: &dyn Fn(u32) -> Vec<u32>,
        ) {
            let (start, here) = (path[0], *path.last().expect("a path"));
            for next in neighbours(here) {
                if next == start && path.len() >= 3 && path[1] < here {
                    out.push(path.clone());
                } else if next > start && !path.contains(&next) && path.len() < LONGEST {
                    path.push(next);
                    walk(path, out, neighbours);
                    path.pop();
                }
            }
        }
        let lists: Vec<(u32, Vec<u32>)> = vertices
            .iter()
            .map(|&v| (v, neighbours(v).collect()))
            .collect();
        let lookup = |v: u32| {
            lists
                .binary_search_by_key(&v, |e| e.0)
                .map(|k| lists[k].1.clone())
                .unwrap_or_default()
        };
        for &v in &vertices {
            path.clear();
            path.push(v);
            walk(&mut path, &mut out, &lookup);
        }
        let is_triangle = |c: &[u32]| {
            c.len() == 3
                && self.part.iter().any(|t| {
                    let mut x = *t;
                    x.sort_unstable();
                    let mut y = [c[0], c[1], c[2]];
                    y.sort_unstable();
                    x == y
                })
        };
        out.retain(|c| !is_triangle(c));
        let reflex = |c: &Vec<u32>| {
            (0..c.len())
                .filter(|&k| {
                    self.edge(c[k], c[(k + 1) % c.len()])
                        .is_some_and(|e| self.reflex[e])
                })
                .count()
        };
        out.sort_by_key(|c| (std::cmp::Reverse(reflex(c)), c.len()));
        out
    }

    /// Pairs of closed surfaces, each pair adding up to the part, one per (cycle, disc) tried.
    pub(super) fn sides(&self) -> impl Iterator<Item = (Vec<[u32; 3]>, Vec<[u32; 3]>)> + '_ {
        self.cycles()
            .into_iter()
            .filter_map(|c| self.halves(&c))
            .flat_map(move |(a, rim, separates)| {
                let n = rim.len();
                (0..n).filter_map(move |apex| {
                    // The disc closing side `a`: its rim reversed, fanned from one vertex.
                    let closing: Vec<u32> = (0..n).map(|k| rim[(n - k) % n]).collect();
                    let disc: Vec<[u32; 3]> = (1..n - 1)
                        .map(|i| {
                            [
                                closing[apex],
                                closing[(apex + i) % n],
                                closing[(apex + i + 1) % n],
                            ]
                        })
                        .collect();
                    if disc
                        .iter()
                        .any(|t| check::collinear(t.map(|v| (self.position)(v))))
                    {
                        return None;
                    }
                    let reversed = disc.iter().map(|t| [t[0], t[2], t[1]]);
                    if !separates {
                        // A handle's cycle: the part cut open along the disc, one piece.
                        let mut cut = self.part.to_vec();
                        cut.extend_from_slice(&disc);
                        cut.extend(reversed);
                        return Some((cut, Vec::new()));
                    }
                    let mut first: Vec<[u32; 3]> = a.iter().map(|&i| self.part[i]).collect();
                    first.extend_from_slice(&disc);
                    let mut second: Vec<[u32; 3]> = (0..self.part.len())
                        .filter(|i| a.binary_search(i).is_err())
                        .map(|i| self.part[i])
                        .collect();
                    second.extend(reversed);
                    Some((first, second))
                })
            })
            .take(MOST)
    }

    /// The triangles on one side of the cycle (sorted), that side's rim in order, its own
    /// edges' direction, and whether the cycle separates the part at all (around a handle it
    /// does not: the side is then the whole part, and the rim follows one of the triangles at
    /// the cycle's first edge).
    fn halves(&self, cycle: &[u32]) -> Option<(Vec<usize>, Vec<u32>, bool)> {
        let n = cycle.len();
        let on_cycle: Vec<usize> = (0..n)
            .map(|k| self.edge(cycle[k], cycle[(k + 1) % n]))
            .collect::<Option<_>>()?;
        let mut side = vec![false; self.part.len()];
        let mut stack = vec![self.edges[on_cycle[0]].1[0]];
        side[stack[0]] = true;
        while let Some(t) = stack.pop() {
            let tri = self.part[t];
            for k in 0..3 {
                let e = self.edge(tri[k], tri[(k + 1) % 3]).expect("an edge");
                if on_cycle.contains(&e) {
                    continue;
                }
                for &u in &self.edges[e].1 {
                    if !side[u] {
                        side[u] = true;
                        stack.push(u);
                    }
                }
            }
        }
        // Separating: each cycle edge has one triangle on each side; else none on the other.
        let split = |e: &usize| side[self.edges[*e].1[0]] != side[self.edges[*e].1[1]];
        let separates = on_cycle.iter().all(split);
        if !separates && (on_cycle.iter().any(split) || side.contains(&false)) {
            return None;
        }
        // The rim in the side's own direction: the cycle as given, or reversed.
        let t = self.edges[on_cycle[0]].1.into_iter().find(|&t| side[t])?;
        let tri = self.part[t];
        let forward = (0..3).any(|k| tri[k] == cycle[0] && tri[(k + 1) % 3] == cycle[1]);
        let rim: Vec<u32> = if forward {
            cycle.to_vec()
        } else {
            cycle.iter().rev().copied().collect()
        };
        let members: Vec<usize> = (0..self.part.len()).filter(|&i| side[i]).collect();
        Some((members, rim, separates))
    }
}
