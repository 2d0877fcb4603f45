//! The ternary mesher's acceptance test for a snap (see `ternary.rs`, `Check`), on patches whose
//! vertices are numbered `0..n` in the order of their keys.
//!
//! The test is the same as `Check::accepts` — same conditions, same verdict — but built on
//! tables indexed by vertex number instead of sorted lists of keys: a snap's first check in a
//! neighbourhood is on the hot path of ternary extraction (thousands per volume), and the
//! sorting and small allocations of the generic test cost most of its time. The generic test
//! remains the reference: debug builds run both and compare.

/// Reusable tables, kept zeroed between checks.
#[derive(Default)]
pub(super) struct Scratch {
    /// Per vertex pair `a · n + b` (`a < b`): uses as (old a→b, old b→a, new a→b, new b→a).
    uses: Vec<[u8; 4]>,
    /// The pairs `uses` holds counts for.
    touched: Vec<u16>,
    /// Per vertex pair: the first triangle using the edge, plus one (0: none yet).
    first: Vec<u8>,
    old: Vec<u32>,
    new: Vec<u32>,
    /// Triangles by vertex, of the old and the new patch.
    old_fans: Incidence,
    new_fans: Incidence,
}

/// The triangles of a list by vertex: `of(v)` are the places in the list of the triangles
/// that use `v`, in list order. Built once per check, so that each vertex's fan reads its
/// own few triangles rather than the whole list.
#[derive(Default)]
struct Incidence {
    start: Vec<usize>,
    triangles: Vec<u16>,
}

impl Incidence {
    fn build(&mut self, n: usize, ts: &[u32]) {
        // Patches have a few dozen triangles (eight cells' worth).
        debug_assert!(ts.len() <= usize::from(u16::MAX));
        let corners = |t: u32| {
            let t = unpack(t);
            // A vertex repeated in a triangle is listed once for it.
            [
                (t[0], true),
                (t[1], t[1] != t[0]),
                (t[2], t[2] != t[0] && t[2] != t[1]),
            ]
        };
        self.start.clear();
        self.start.resize(n + 1, 0);
        for &t in ts {
            for (v, listed) in corners(t) {
                self.start[usize::from(v) + 1] += usize::from(listed);
            }
        }
        for v in 0..n {
            self.start[v + 1] += self.start[v];
        }
        self.triangles.clear();
        self.triangles.resize(self.start[n], 0);
        let mut next = std::mem::take(&mut self.start);
        for (i, &t) in ts.iter().enumerate() {
            for (v, listed) in corners(t) {
                if listed {
                    self.triangles[next[usize::from(v)]] = i as u16;
                    next[usize::from(v)] += 1;
                }
            }
        }
        // `next[v]` is now where `v`'s list ends, which is where `v + 1`'s began.
        next.rotate_right(1);
        next[0] = 0;
        self.start = next;
    }

    fn of(&self, v: u8) -> &[u16] {
        &self.triangles[self.start[usize::from(v)]..self.start[usize::from(v) + 1]]
    }
}

/// A vertex set of up to 256 vertices.
#[derive(Clone, Copy, Default, PartialEq, Eq)]
struct Set([u64; 4]);

impl Set {
    fn insert(&mut self, v: u8) -> bool {
        let (w, b) = (usize::from(v) / 64, v % 64);
        let had = self.0[w] >> b & 1 != 0;
        self.0[w] |= 1 << b;
        !had
    }

    fn len(&self) -> i64 {
        self.0.iter().map(|w| i64::from(w.count_ones())).sum()
    }
}

fn pack(t: [u8; 3]) -> u32 {
    u32::from(t[0]) << 16 | u32::from(t[1]) << 8 | u32::from(t[2])
}

fn unpack(t: u32) -> [u8; 3] {
    [(t >> 16) as u8, (t >> 8) as u8, t as u8]
}

/// Rotated to start at the smallest vertex (orientation kept), packed so that integers order
/// as the triangles do.
fn canonical(t: [u8; 3]) -> u32 {
    let i = (0..3).min_by_key(|&i| t[i]).unwrap_or(0);
    pack([t[i], t[(i + 1) % 3], t[(i + 2) % 3]])
}

/// The test, for `n` vertices whose boundary planes are `planes[v] = (frozen, open)` bit masks
/// (vertices share a plane when their masks share a bit). `None` when a fan is too large for
/// the fixed-size tables here (the generic test then decides).
pub(super) fn accepts(
    n: usize,
    planes: &[(u8, u8)],
    before: &[[u8; 3]],
    after: &[[u8; 3]],
    scratch: &mut Scratch,
) -> Option<bool> {
    let frozen = |vs: &[u8]| {
        vs.iter()
            .fold(u8::MAX, |m, &v| m & planes[usize::from(v)].0)
            != 0
    };
    let open = |vs: &[u8]| {
        vs.iter()
            .fold(u8::MAX, |m, &v| m & planes[usize::from(v)].1)
            != 0
    };
    let Scratch {
        uses,
        touched,
        first,
        old,
        new,
        old_fans,
        new_fans,
    } = scratch;
    old.clear();
    old.extend(before.iter().map(|&t| canonical(t)));
    old.sort_unstable();
    new.clear();
    new.extend(after.iter().map(|&t| canonical(t)));
    new.sort_unstable();
    if old == new {
        return Some(true);
    }
    // No triangle twice, in either orientation.
    let mut sets: Vec<u32> = after
        .iter()
        .map(|t| {
            let mut s = *t;
            s.sort_unstable();
            pack(s)
        })
        .collect();
    sets.sort_unstable();
    if sets.windows(2).any(|w| w[0] == w[1]) {
        return Some(false);
    }
    if uses.len() < n * n {
        uses.resize(n * n, [0; 4]);
        first.resize(n * n, 0);
    }
    let edges = edges_fit(n, old, new, uses, touched, &frozen, &open);
    Some(
        edges && fans_fit(n, old, new, old_fans, new_fans, &frozen, &open)? && {
            let a = signatures(n, old, first, &frozen);
            let b = signatures(n, new, first, &frozen);
            a == b
        },
    )
}

fn edges_fit(
    n: usize,
    old: &[u32],
    new: &[u32],
    uses: &mut [[u8; 4]],
    touched: &mut Vec<u16>,
    frozen: &dyn Fn(&[u8]) -> bool,
    open: &dyn Fn(&[u8]) -> bool,
) -> bool {
    touched.clear();
    for (list, slot) in [(old, 0), (new, 2)] {
        for &t in list {
            let t = unpack(t);
            for i in 0..3 {
                let (a, b) = (t[i], t[(i + 1) % 3]);
                let pair = usize::from(a.min(b)) * n + usize::from(a.max(b));
                let u = &mut uses[pair];
                if *u == [0; 4] {
                    touched.push(pair as u16);
                }
                let count = &mut u[slot + usize::from(a >= b)];
                *count = count.saturating_add(1);
            }
        }
    }
    let mut ok = true;
    for &pair in touched.iter() {
        let pair = usize::from(pair);
        let [of, ob, nf, nb] = std::mem::take(&mut uses[pair]);
        if !ok {
            continue;
        }
        let keys = [(pair / n) as u8, (pair % n) as u8];
        ok = if frozen(&keys) {
            // Outside triangles may use the edge too. If the block used it both ways, they do
            // not, and the block may drop it; otherwise its use must stay as it was.
            (nf, nb) == (of, ob) || ((of, ob) == (1, 1) && (nf, nb) == (0, 0))
        } else {
            matches!((nf, nb), (0, 0) | (1, 1)) || (nf + nb == 1 && open(&keys))
        };
    }
    ok
}

/// The link of a vertex: (next, previous) around it, one entry per triangle; fans here have a
/// dozen triangles at most, far below this bound.
const MAX_FAN: usize = 48;

/// Paths (start, end) and cycles of a vertex's link, `Err(())` when the link branches
/// (a non-manifold vertex); as `ternary::fan`.
struct Fan {
    paths: [(u8, u8); MAX_FAN],
    path_count: usize,
    cycles: usize,
}

fn fan(ts: &[u32], of_u: &[u16], u: u8) -> Option<Result<Fan, ()>> {
    let mut link = [(0u8, 0u8); MAX_FAN];
    let mut len = 0;
    for &i in of_u {
        let t = unpack(ts[usize::from(i)]);
        if let Some(i) = t.iter().position(|&k| k == u) {
            if len == MAX_FAN {
                return None;
            }
            link[len] = (t[(i + 1) % 3], t[(i + 2) % 3]);
            len += 1;
        }
    }
    let link = &mut link[..len];
    let mut out = Fan {
        paths: [(0, 0); MAX_FAN],
        path_count: 0,
        cycles: 0,
    };
    if link.is_empty() {
        return Some(Ok(out));
    }
    link.sort_unstable();
    if link.windows(2).any(|w| w[0].0 == w[1].0) {
        return Some(Err(()));
    }
    let mut targets = [0u8; MAX_FAN];
    for (t, l) in targets.iter_mut().zip(link.iter()) {
        *t = l.1;
    }
    let targets = &mut targets[..len];
    targets.sort_unstable();
    if targets.windows(2).any(|w| w[0] == w[1]) {
        return Some(Err(()));
    }
    let successor = |b: u8| link.binary_search_by_key(&b, |l| l.0).ok();
    let mut seen = [false; MAX_FAN];
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
                    out.paths[out.path_count] = (a, link[idx].1);
                    out.path_count += 1;
                    break;
                }
            }
        }
    }
    for i in 0..len {
        if seen[i] {
            continue;
        }
        out.cycles += 1;
        let mut idx = i;
        while !seen[idx] {
            seen[idx] = true;
            match successor(link[idx].1) {
                Some(j) => idx = j,
                None => break,
            }
        }
    }
    Some(Ok(out))
}

fn fans_fit(
    n: usize,
    old: &[u32],
    new: &[u32],
    old_fans: &mut Incidence,
    new_fans: &mut Incidence,
    frozen: &dyn Fn(&[u8]) -> bool,
    open: &dyn Fn(&[u8]) -> bool,
) -> Option<bool> {
    // Only vertices of triangles that appear or disappear can change their fans (both lists
    // are sorted).
    let mut changed = Set::default();
    let (mut i, mut j) = (0, 0);
    while i < old.len() || j < new.len() {
        let t = match (old.get(i), new.get(j)) {
            (Some(a), Some(b)) if a == b => {
                i += 1;
                j += 1;
                continue;
            }
            (Some(&a), Some(&b)) if a < b => {
                i += 1;
                a
            }
            (Some(&a), None) => {
                i += 1;
                a
            }
            (_, Some(&b)) => {
                j += 1;
                b
            }
            (None, None) => break,
        };
        for v in unpack(t) {
            changed.insert(v);
        }
    }
    new_fans.build(n, new);
    let mut old_built = false;
    for u in 0..n as u8 {
        if changed.0[usize::from(u) / 64] >> (u % 64) & 1 == 0 {
            continue;
        }
        let Ok(after) = fan(new, new_fans.of(u), u)? else {
            return Some(false);
        };
        let paths = &after.paths[..after.path_count];
        if frozen(&[u]) {
            // Path ends on frozen edges are where the fan continues outside the block and must
            // stay; ends on the grid boundary may move along it.
            if !old_built {
                old_fans.build(n, old);
                old_built = true;
            }
            let Ok(before) = fan(old, old_fans.of(u), u)? else {
                return Some(false);
            };
            let ends = |f: &Fan| {
                let end = |x: u8| frozen(&[u, x]).then_some(x);
                let mut p = [(None, None); MAX_FAN];
                for (slot, &(a, b)) in p.iter_mut().zip(&f.paths[..f.path_count]) {
                    *slot = (end(a), end(b));
                }
                p[..f.path_count].sort_unstable();
                (p, f.path_count, f.cycles)
            };
            if ends(&after) != ends(&before) {
                return Some(false);
            }
        } else {
            let one_disk = after.cycles == 1 && paths.is_empty();
            let one_half_disk = after.cycles == 0 && paths.len() == 1 && open(&[u]);
            if !(one_disk || one_half_disk || (after.cycles == 0 && paths.is_empty())) {
                return Some(false);
            }
        }
    }
    Some(true)
}

/// (root triangle, F − E so far, vertices, interface edges) of one component.
type Component = (usize, i64, Set, Vec<(u8, u8)>);

/// Per edge-connected component: its Euler characteristic and its interface edges (frozen
/// edges used once), sorted; as `Check::component_signatures`.
fn signatures(
    n: usize,
    ts: &[u32],
    first: &mut [u8],
    frozen: &dyn Fn(&[u8]) -> bool,
) -> Vec<(i64, Vec<(u8, u8)>)> {
    fn find(parent: &mut [usize], mut x: usize) -> usize {
        while parent[x] != x {
            parent[x] = parent[parent[x]];
            x = parent[x];
        }
        x
    }
    let mut parent: Vec<usize> = (0..ts.len()).collect();
    // Distinct edges (pair, a triangle using it, uses), in order of first use.
    let mut edges: Vec<(usize, usize, u8)> = Vec::with_capacity(3 * ts.len());
    for (i, &t) in ts.iter().enumerate() {
        let t = unpack(t);
        for j in 0..3 {
            let (a, b) = (t[j], t[(j + 1) % 3]);
            let pair = usize::from(a.min(b)) * n + usize::from(a.max(b));
            match first[pair] {
                0 => {
                    edges.push((pair, i, 1));
                    // Edge numbers fit: a patch has fewer than 255 distinct edges here, or the
                    // counts below saturate and the slot is found by search.
                    first[pair] = u8::try_from(edges.len()).unwrap_or(u8::MAX);
                }
                e => {
                    let e = if e == u8::MAX {
                        edges
                            .iter()
                            .position(|x| x.0 == pair)
                            .expect("a used edge is listed")
                    } else {
                        usize::from(e) - 1
                    };
                    let (x, y) = (find(&mut parent, edges[e].1), find(&mut parent, i));
                    parent[x] = y;
                    edges[e].2 = edges[e].2.saturating_add(1);
                }
            }
        }
    }
    for e in &edges {
        first[e.0] = 0;
    }
    let mut out: Vec<Component> = Vec::new();
    let mut slot = |root: usize| match out.iter().position(|c| c.0 == root) {
        Some(i) => i,
        None => {
            out.push((root, 0, Set::default(), Vec::new()));
            out.len() - 1
        }
    };
    let mut at: Vec<usize> = Vec::with_capacity(ts.len());
    for i in 0..ts.len() {
        let s = slot(find(&mut parent, i));
        at.push(s);
    }
    for (&t, &s) in ts.iter().zip(&at) {
        out[s].1 += 1;
        for v in unpack(t) {
            out[s].2.insert(v);
        }
    }
    for &(pair, i, count) in &edges {
        let c = &mut out[at[i]];
        c.1 -= 1;
        let edge = ((pair / n) as u8, (pair % n) as u8);
        if count == 1 && frozen(&[edge.0, edge.1]) {
            c.3.push(edge);
        }
    }
    let mut out: Vec<(i64, Vec<(u8, u8)>)> = out
        .into_iter()
        .map(|(_, euler, vertices, mut interface)| {
            interface.sort_unstable();
            (euler + vertices.len(), interface)
        })
        .collect();
    out.sort();
    out
}
