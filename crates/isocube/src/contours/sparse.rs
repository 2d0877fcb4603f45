//! The sectional field kept sparse: what reconstruction touches grows with the cells the surface
//! passes through, not with the plane grid times the number of sections.
//!
//! - Each section's inside/outside state is a list of inside point ranges per grid row, from one
//!   scanline pass over its contour segments (cost: the rows each segment spans).
//! - The cells between two neighbouring layers that hold surface are found row by row from those
//!   ranges: a cell is empty when its eight corners agree, which the ranges of its four corner
//!   rows decide without visiting the cells in between.
//! - Distances are computed only at the corners of those cells, each once, with the nearest
//!   segment found through an R-tree, and stored as runs per row.
//!
//! Layers are the sections, plus, for extension caps, a virtual layer beyond each end whose value
//! is the end section's lowered by its largest inside distance (so the body tapers to a point
//! or ridge at the given distance).

use std::cell::OnceCell;

use rayon::prelude::*;
use rstar::primitives::Line;
use rstar::RTree;

use super::plane::PlaneGrid;
use super::{segment_distance, Point2, Section, SectionStack};

/// An inclusive range of point (or cell) indices along a grid row.
pub(super) type Span = [u32; 2];

/// Inside (or on-contour) points of each grid row of `plane`, as sorted, disjoint, non-adjacent
/// inclusive ranges. A point exactly on a contour counts as inside, as in the section-data paper.
pub(super) fn inside_spans(section: &Section, plane: &PlaneGrid) -> Vec<Vec<Span>> {
    let [nx, ny] = plane.dims;
    let mut crossings: Vec<Vec<f64>> = vec![Vec::new(); ny];
    for c in section.contours() {
        for (a, b) in c.segments() {
            if a[1] == b[1] {
                continue;
            }
            let (lo, hi) = if a[1] < b[1] { (a, b) } else { (b, a) };
            // Rows with lo.y ≤ y < hi.y (half-open, so shared vertices count once).
            let mut j = ((lo[1] - plane.origin[1]) / plane.spacing).ceil().max(0.0) as usize;
            while j < ny {
                let y = plane.origin[1] + j as f64 * plane.spacing;
                if y >= hi[1] {
                    break;
                }
                if y >= lo[1] {
                    crossings[j].push(lo[0] + (y - lo[1]) / (hi[1] - lo[1]) * (hi[0] - lo[0]));
                }
                j += 1;
            }
        }
    }
    let mut on: Vec<Vec<u32>> = vec![Vec::new(); ny];
    for c in section.contours() {
        for (a, b) in c.segments() {
            points_on_segment(plane, a, b, &mut |i, j| on[j].push(i as u32));
        }
    }
    let last = nx as i64 - 1;
    crossings
        .iter_mut()
        .zip(on)
        .map(|(xs, mut singles)| {
            xs.sort_by(f64::total_cmp);
            let mut spans: Vec<Span> = Vec::with_capacity(xs.len() / 2 + singles.len());
            for pair in xs.chunks(2) {
                let [x0, x1] = [pair[0], *pair.get(1).unwrap_or(&pair[0])];
                let i0 = (((x0 - plane.origin[0]) / plane.spacing).ceil() as i64).max(0);
                let i1 = (((x1 - plane.origin[0]) / plane.spacing).floor() as i64).min(last);
                if i0 <= i1 {
                    spans.push([i0 as u32, i1 as u32]);
                }
            }
            if !singles.is_empty() {
                singles.sort_unstable();
                spans.extend(singles.iter().map(|&i| [i, i]));
                spans.sort_unstable();
            }
            merge(&mut spans);
            spans
        })
        .collect()
}

/// Merges sorted ranges that overlap or touch, in place.
fn merge(spans: &mut Vec<Span>) {
    let mut out = 0;
    for k in 0..spans.len() {
        let s = spans[k];
        if out > 0 && s[0] <= spans[out - 1][1].saturating_add(1) {
            spans[out - 1][1] = spans[out - 1][1].max(s[1]);
        } else {
            spans[out] = s;
            out += 1;
        }
    }
    spans.truncate(out);
}

/// Calls `mark(i, j)` for every grid point lying exactly on the segment `a–b`.
pub(super) fn points_on_segment(
    plane: &PlaneGrid,
    a: Point2,
    b: Point2,
    mark: &mut dyn FnMut(usize, usize),
) {
    let [nx, ny] = plane.dims;
    let to = |p: Point2, k: usize| (p[k] - plane.origin[k]) / plane.spacing;
    let (i0, i1) = (
        to(a, 0).min(to(b, 0)).ceil().max(0.0),
        to(a, 0).max(to(b, 0)).floor().min(nx as f64 - 1.0),
    );
    let (j0, j1) = (
        to(a, 1).min(to(b, 1)).ceil().max(0.0),
        to(a, 1).max(to(b, 1)).floor().min(ny as f64 - 1.0),
    );
    if i0 > i1 || j0 > j1 {
        return;
    }
    if (i1 - i0 + 1.0) * (j1 - j0 + 1.0) > 64.0 && a[0] != b[0] && a[1] != b[1] {
        // Only axis-aligned segments can hold many grid points; a slanted one meets few, found
        // by walking its columns.
        let mut i = i0;
        while i <= i1 {
            let x = plane.origin[0] + i * plane.spacing;
            let y = a[1] + (x - a[0]) / (b[0] - a[0]) * (b[1] - a[1]);
            let j = to([x, y], 1);
            if j == j.round() && j >= 0.0 && (j as usize) < ny {
                let p = plane.point(i as usize, j as usize);
                if segment_distance(p, a, b) == 0.0 {
                    mark(i as usize, j as usize);
                }
            }
            i += 1.0;
        }
        return;
    }
    let mut j = j0;
    while j <= j1 {
        let mut i = i0;
        while i <= i1 {
            if segment_distance(plane.point(i as usize, j as usize), a, b) == 0.0 {
                mark(i as usize, j as usize);
            }
            i += 1.0;
        }
        j += 1.0;
    }
}

/// Whether point `i` lies in one of the sorted `spans`.
pub(super) fn contains(spans: &[Span], i: u32) -> bool {
    let k = spans.partition_point(|s| s[0] <= i);
    k > 0 && spans[k - 1][1] >= i
}

/// The cells of one row of a layer pair holding surface, from the inside ranges of the four
/// point rows that bound them: a cell is empty when all its corners are inside or all outside.
/// Returns inclusive cell ranges, sorted and disjoint.
fn active_cells(rows: [&[Span]; 4], cells: u32) -> Vec<Span> {
    // Where any row's membership changes: a range [a, b] starts at a and ends before b + 1.
    let mut breaks: Vec<u32> = Vec::with_capacity(rows.iter().map(|r| 2 * r.len()).sum());
    for row in rows {
        for s in row {
            breaks.push(s[0]);
            breaks.push(s[1] + 1);
        }
    }
    breaks.push(0);
    breaks.sort_unstable();
    breaks.dedup();
    let points = cells + 1;
    #[derive(PartialEq, Clone, Copy)]
    enum State {
        Out,
        In,
        Mixed,
    }
    let mut out: Vec<Span> = Vec::new();
    let mut push = |a: u32, b: u32| {
        let b = b.min(cells - 1);
        if a > b {
            return;
        }
        match out.last_mut() {
            Some(last) if a <= last[1] + 1 => last[1] = last[1].max(b),
            _ => out.push([a, b]),
        }
    };
    let mut cursor = [0usize; 4];
    let mut previous: Option<State> = None;
    for (k, &start) in breaks.iter().enumerate() {
        if start >= points {
            break;
        }
        let end = breaks.get(k + 1).map_or(points, |&b| b.min(points)) - 1;
        let mut inside = 0;
        for (r, row) in rows.iter().enumerate() {
            while cursor[r] < row.len() && row[cursor[r]][1] < start {
                cursor[r] += 1;
            }
            if cursor[r] < row.len() && row[cursor[r]][0] <= start {
                inside += 1;
            }
        }
        let state = match inside {
            0 => State::Out,
            4 => State::In,
            _ => State::Mixed,
        };
        if state == State::Mixed {
            // Cells touching any point of the run: from the one ending at `start`.
            push(start.saturating_sub(1), end);
        } else if previous.is_some_and(|p| p != state) {
            push(start - 1, start - 1);
        }
        previous = Some(state);
    }
    out
}

/// Nearest-segment queries for one section. Almost every query is within a cell or two of a
/// contour: a uniform bucket grid answers those by looking at a few buckets; the rare query far
/// from every contour (deep inside a wide body, under an extension cap) goes to an R-tree built
/// on first use.
struct SegmentIndex {
    segments: Vec<(Point2, Point2)>,
    origin: Point2,
    size: f64,
    dims: [usize; 2],
    /// Bucket `b` holds `items[starts[b]..starts[b + 1]]`.
    starts: Vec<u32>,
    items: Vec<u32>,
    far: OnceCell<RTree<Line<[f64; 2]>>>,
}

/// Rings of buckets searched before a query goes to the R-tree.
const RINGS: i64 = 3;

impl SegmentIndex {
    fn new(section: &Section, size: f64) -> SegmentIndex {
        let segments: Vec<(Point2, Point2)> = section
            .contours()
            .iter()
            .flat_map(|c| c.segments())
            .collect();
        let (mut lo, mut hi) = ([f64::MAX; 2], [f64::MIN; 2]);
        for (a, b) in &segments {
            for d in 0..2 {
                lo[d] = lo[d].min(a[d]).min(b[d]);
                hi[d] = hi[d].max(a[d]).max(b[d]);
            }
        }
        // Buckets of about `size`, but not many more than segments.
        let mut size = size;
        let count = |size: f64| [0, 1].map(|d| ((hi[d] - lo[d]) / size).floor() as usize + 1);
        while count(size)[0] * count(size)[1] > 4 * segments.len() + 64 {
            size *= 1.5;
        }
        let dims = count(size);
        let bucket =
            |p: Point2, d: usize| (((p[d] - lo[d]) / size).floor() as usize).min(dims[d] - 1);
        let mut starts = vec![0u32; dims[0] * dims[1] + 1];
        let ranges: Vec<[usize; 4]> = segments
            .iter()
            .map(|&(a, b)| {
                let (x0, x1) = (
                    bucket(a, 0).min(bucket(b, 0)),
                    bucket(a, 0).max(bucket(b, 0)),
                );
                let (y0, y1) = (
                    bucket(a, 1).min(bucket(b, 1)),
                    bucket(a, 1).max(bucket(b, 1)),
                );
                [x0, x1, y0, y1]
            })
            .collect();
        for r in &ranges {
            for y in r[2]..=r[3] {
                for x in r[0]..=r[1] {
                    starts[y * dims[0] + x + 1] += 1;
                }
            }
        }
        for b in 1..starts.len() {
            starts[b] += starts[b - 1];
        }
        let mut fill = starts.clone();
        let mut items = vec![0u32; starts[starts.len() - 1] as usize];
        for (k, r) in ranges.iter().enumerate() {
            for y in r[2]..=r[3] {
                for x in r[0]..=r[1] {
                    let b = y * dims[0] + x;
                    items[fill[b] as usize] = k as u32;
                    fill[b] += 1;
                }
            }
        }
        SegmentIndex {
            segments,
            origin: lo,
            size,
            dims,
            starts,
            items,
            far: OnceCell::new(),
        }
    }

    /// Exact distance to the nearest segment.
    fn distance(&self, p: Point2) -> f64 {
        let [nx, ny] = self.dims.map(|d| d as i64);
        // Bucket coordinates, clamped to just beyond the rings' reach so that points far outside
        // the grid do not overflow (their rings hold nothing anyway).
        let c = [0, 1].map(|d| {
            let b = ((p[d] - self.origin[d]) / self.size).floor();
            b.clamp(
                -(RINGS as f64) - 2.0,
                (self.dims[d] as f64) + RINGS as f64 + 2.0,
            ) as i64
        });
        let mut best = f64::INFINITY;
        for r in 0..=RINGS {
            for y in c[1] - r..=c[1] + r {
                if y < 0 || y >= ny {
                    continue;
                }
                let step = if (y - c[1]).abs() == r {
                    1
                } else {
                    2 * r.max(1)
                };
                let mut x = c[0] - r;
                while x <= c[0] + r {
                    if x >= 0 && x < nx {
                        let b = (y * nx + x) as usize;
                        for &k in &self.items[self.starts[b] as usize..self.starts[b + 1] as usize]
                        {
                            let (a, e) = self.segments[k as usize];
                            best = best.min(segment_distance(p, a, e));
                        }
                    }
                    x += step;
                }
            }
            // Whatever lies outside ring r is at least r bucket sizes away.
            if best <= r as f64 * self.size {
                return best;
            }
        }
        let tree = self.far.get_or_init(|| {
            RTree::bulk_load(
                self.segments
                    .iter()
                    .map(|&(a, b)| Line::new(a, b))
                    .collect(),
            )
        });
        tree.nearest_neighbor(&p).map_or(f64::INFINITY, |line| {
            segment_distance(p, line.from, line.to)
        })
    }
}

/// Distances of one layer at the corners of the active cells, as runs per row.
struct LayerValues {
    /// Per row: (first point, last point, offset into `data`) of each run, sorted.
    rows: Vec<Vec<(u32, u32, u32)>>,
    data: Vec<f64>,
    /// Whether the layer has no contour (a cap's virtual layer, or an empty section): then,
    /// next to a layer with contours, it takes that layer's values lowered by [`Self::drop`].
    empty: bool,
    /// How far a layer with no contour next to this one lowers this one's values: a little more
    /// than the deepest inside distance, so the body tapers to its innermost point there.
    drop: f64,
}

/// The sparse sectional field of a stack on a plane grid.
pub(super) struct SparseField {
    /// Plane grid points along x and y.
    pub(super) dims: [usize; 2],
    /// Height of each layer.
    pub(super) heights: Vec<f64>,
    /// The section of each layer (`None` for the virtual layers of extension caps).
    pub(super) section_of: Vec<Option<usize>>,
    /// Per layer pair, per cell row: the cells holding surface.
    pub(super) active: Vec<Vec<Vec<Span>>>,
    inside: Vec<Vec<Vec<Span>>>,
    values: Vec<LayerValues>,
    /// Grid points whose distance was computed.
    pub(super) evaluated: usize,
    /// Cells holding surface, all layer pairs.
    pub(super) active_cells: usize,
    /// Larger than every distance in the field.
    pub(super) far: f64,
}

impl SparseField {
    /// Builds the field; with `extend`, a virtual layer that far beyond each end section.
    pub(super) fn new(stack: &SectionStack, plane: &PlaneGrid, extend: Option<f64>) -> Self {
        let [nx, ny] = plane.dims;
        let sections = stack.sections();
        let mut heights: Vec<f64> = sections.iter().map(|s| s.z()).collect();
        let mut section_of: Vec<Option<usize>> = (0..sections.len()).map(Some).collect();
        if let Some(d) = extend {
            heights.insert(0, heights[0] - d);
            heights.push(heights[heights.len() - 1] + d);
            section_of.insert(0, None);
            section_of.push(None);
        }
        let layers = heights.len();
        let inside: Vec<Vec<Vec<Span>>> = section_of
            .par_iter()
            .map(|s| match s {
                Some(s) => inside_spans(&sections[*s], plane),
                None => vec![Vec::new(); ny],
            })
            .collect();
        let cells = (nx - 1) as u32;
        // One layer alone (a single section, no caps) pairs with itself.
        let active: Vec<Vec<Vec<Span>>> = (0..layers.saturating_sub(1).max(1))
            .into_par_iter()
            .map(|l| {
                let u = (l + 1).min(layers - 1);
                (0..ny - 1)
                    .map(|j| {
                        active_cells(
                            [
                                &inside[l][j],
                                &inside[l][j + 1],
                                &inside[u][j],
                                &inside[u][j + 1],
                            ],
                            cells,
                        )
                    })
                    .collect()
            })
            .collect();
        let active_cells = active
            .iter()
            .flatten()
            .flatten()
            .map(|s| (s[1] - s[0] + 1) as usize)
            .sum();
        let (lo, hi, _) = stack.bounds();
        let far = ((hi[0] - lo[0]).powi(2) + (hi[1] - lo[1]).powi(2)).sqrt()
            + 4.0 * plane.spacing * (nx + ny) as f64;
        let mut field = SparseField {
            dims: plane.dims,
            heights,
            section_of,
            active,
            inside,
            values: Vec::with_capacity(layers),
            evaluated: 0,
            active_cells,
            far,
        };
        let evaluated: Vec<(LayerValues, usize)> = (0..layers)
            .into_par_iter()
            .map(|l| match field.section_of[l] {
                Some(s) if !sections[s].contours().is_empty() => {
                    field.evaluate(l, &sections[s], plane)
                }
                _ => (
                    LayerValues {
                        rows: Vec::new(),
                        data: Vec::new(),
                        empty: true,
                        drop: 0.0,
                    },
                    0,
                ),
            })
            .collect();
        for (mut values, count) in evaluated {
            // Next to a layer with no contour every inside point of this one is a corner of an
            // active cell, so this is the deepest inside distance of the whole section then.
            let deepest = values
                .data
                .iter()
                .copied()
                .filter(|&v| v > 0.0)
                .fold(0.0, f64::max);
            // Strictly below zero everywhere, zero only in the limit at the deepest point.
            values.drop = deepest * (1.0 + 1e-6) + 1e-12 * far;
            field.values.push(values);
            field.evaluated += count;
        }
        field
    }

    /// Exact signed distances of layer `l` at the corners of the active cells next to it.
    /// Returns them with their number.
    fn evaluate(&self, l: usize, section: &Section, plane: &PlaneGrid) -> (LayerValues, usize) {
        let [_, ny] = self.dims;
        let index = SegmentIndex::new(section, 2.0 * plane.spacing);
        let mut rows = Vec::with_capacity(ny);
        let mut data = Vec::new();
        let mut needed: Vec<Span> = Vec::new();
        for j in 0..ny {
            needed.clear();
            // Cells of rows j − 1 and j, in the pairs below and above, have corners on row j.
            for pair in [l.wrapping_sub(1), l] {
                let Some(pair_rows) = self.active.get(pair) else {
                    continue;
                };
                for r in [j.wrapping_sub(1), j] {
                    if let Some(spans) = pair_rows.get(r) {
                        needed.extend(spans.iter().map(|s| [s[0], s[1] + 1]));
                    }
                }
            }
            needed.sort_unstable();
            merge(&mut needed);
            let inside = &self.inside[l][j];
            let mut runs = Vec::with_capacity(needed.len());
            for s in &needed {
                runs.push((s[0], s[1], data.len() as u32));
                for i in s[0]..=s[1] {
                    let d = index.distance(plane.point(i as usize, j));
                    data.push(if contains(inside, i) {
                        d
                    } else {
                        // Outside is strictly below the level, even on a contour up to rounding.
                        -d.max(f64::from(f32::MIN_POSITIVE))
                    });
                }
            }
            rows.push(runs);
        }
        let count = data.len();
        (
            LayerValues {
                rows,
                data,
                empty: false,
                drop: 0.0,
            },
            count,
        )
    }

    /// The values of layer `l`, row `j`, points `first..=last`, as seen from the layer pair it
    /// forms with `partner`: a slice and an amount to subtract from each (non-zero when `l` has
    /// no contour and takes `partner`'s values); `None` if they were not evaluated.
    pub(super) fn run(
        &self,
        l: usize,
        partner: usize,
        j: usize,
        first: u32,
        last: u32,
    ) -> Option<(&[f64], f64)> {
        let mut layer = &self.values[l];
        let mut drop = 0.0;
        if layer.empty {
            let other = &self.values[partner];
            if other.empty {
                return None;
            }
            (layer, drop) = (other, other.drop);
        }
        let runs = layer.rows.get(j)?;
        let k = runs.partition_point(|r| r.0 <= first);
        let (a, b, offset) = *runs.get(k.checked_sub(1)?)?;
        if last > b {
            return None;
        }
        let start = (offset + first - a) as usize;
        Some((&layer.data[start..=start + (last - first) as usize], drop))
    }

    /// The value at point `(i, j)` of layer `l` next to `partner` (see [`Self::run`]): the signed
    /// distance where evaluated, otherwise a placeholder of the right sign larger than any
    /// distance.
    pub(super) fn value(&self, l: usize, partner: usize, i: usize, j: usize) -> f64 {
        if let Some((v, d)) = self.run(l, partner, j, i as u32, i as u32) {
            return v[0] - d;
        }
        // Layers with no contour have no inside ranges: outside everywhere.
        if contains(&self.inside[l][j], i as u32) {
            self.far
        } else {
            -self.far
        }
    }

    /// The layer a layer with no contour borrows its values from when it stands alone (the dense
    /// view): the one below, or above at the bottom.
    pub(super) fn partner(&self, l: usize) -> usize {
        let layers = self.values.len();
        if l > 0 && !self.values[l - 1].empty {
            l - 1
        } else {
            (l + 1).min(layers - 1)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contours::test_circle as circle;

    /// The active cells from ranges equal the cells whose corners disagree, found densely.
    #[test]
    fn active_cells_match_the_dense_definition() {
        let mut rng = crate::TestRng::new(7);
        let mut next = || (rng.next_u64() >> 33) as u32;
        for _ in 0..2000 {
            let cells = 1 + next() % 20;
            let rows: Vec<Vec<Span>> = (0..4)
                .map(|_| {
                    let mut flags: Vec<bool> = (0..=cells).map(|_| next() % 3 == 0).collect();
                    if next() % 4 == 0 {
                        flags.iter_mut().for_each(|f| *f = true);
                    }
                    let mut spans = Vec::new();
                    for (i, &f) in flags.iter().enumerate() {
                        if f {
                            spans.push([i as u32, i as u32]);
                        }
                    }
                    merge(&mut spans);
                    spans
                })
                .collect();
            let got = active_cells([&rows[0], &rows[1], &rows[2], &rows[3]], cells);
            let mut want = Vec::new();
            for i in 0..cells {
                let states: Vec<bool> = rows
                    .iter()
                    .flat_map(|r| [contains(r, i), contains(r, i + 1)])
                    .collect();
                if states.iter().any(|&s| s != states[0]) {
                    want.push([i, i]);
                }
            }
            merge(&mut want);
            assert_eq!(got, want, "{rows:?}");
        }
    }

    /// Inside ranges agree with the even–odd point test at every grid point.
    #[test]
    fn inside_spans_match_the_point_test() {
        let stack = SectionStack::from_points(vec![(
            0.0,
            vec![
                circle(0.0, 0.0, 3.0, 40),
                circle(0.3, 0.0, 1.0, 12),
                vec![[4.0, 4.0], [6.0, 4.0], [6.0, 6.0], [4.0, 6.0]],
            ],
        )])
        .unwrap();
        let plane = PlaneGrid {
            origin: [-4.0, -4.0],
            spacing: 0.25,
            dims: [45, 45],
        };
        let section = &stack.sections()[0];
        let spans = inside_spans(section, &plane);
        for (j, row) in spans.iter().enumerate() {
            for i in 0..45 {
                let p = plane.point(i, j);
                assert_eq!(contains(row, i as u32), section.contains(p), "{p:?}");
            }
        }
    }
}
