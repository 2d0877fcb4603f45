//! The sectional field: the signed distance of every section, sampled on one plane grid and
//! stacked at the sections' heights, evaluated only where the surface can pass.
//!
//! As in the section-data paper, each grid point first gets a state (inside or on a contour, or
//! outside) from a scanline pass over the section's contour segments; a cell between two
//! sections whose eight corners all share a state holds no surface, and its corners need no
//! distance. Only the corners of the other cells get the exact Euclidean distance to the
//! nearest contour segment (found through a bucket grid of segments), signed by the state. The
//! remaining points keep a placeholder of the right sign whose size exceeds every computed
//! distance, so extraction sees the same configuration everywhere.

use std::collections::HashMap;

use super::{segment_distance, Point2, Section, SectionStack};
use crate::field::Grid;

/// The grid in the sections' plane: `dims` points from `origin`, `spacing` apart on both axes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlaneGrid {
    /// The first point.
    pub origin: Point2,
    /// Distance between neighbouring points, both axes.
    pub spacing: f64,
    /// Points along x and y.
    pub dims: [usize; 2],
}

impl PlaneGrid {
    /// A grid with square cells of side `cell` covering every contour of the stack with one
    /// empty cell to spare on each side (so the surface closes inside the grid).
    pub fn with_cell(stack: &SectionStack, cell: f64) -> PlaneGrid {
        // The grid starts a little over one cell before the contours, offset by fractions that
        // input coordinates are unlikely to share, so that contour vertices and grid lines do not
        // coincide.
        PlaneGrid::with_cell_and_shift(stack, cell, [1.0719, 1.0437])
    }

    /// [`PlaneGrid::with_cell`] with the grid starting `shift` cells (each between 1 and 2)
    /// before the contours' bounding box.
    pub fn with_cell_and_shift(stack: &SectionStack, cell: f64, shift: [f64; 2]) -> PlaneGrid {
        let (lo, hi, _) = stack.bounds();
        let dims = [0, 1].map(|a| ((hi[a] - lo[a]) / cell + shift[a]).ceil() as usize + 2);
        PlaneGrid {
            origin: [lo[0] - shift[0] * cell, lo[1] - shift[1] * cell],
            spacing: cell,
            dims,
        }
    }

    /// A grid with about `cells` cells across the longer side of the contours' bounding box.
    pub fn across(stack: &SectionStack, cells: usize) -> PlaneGrid {
        let (lo, hi, _) = stack.bounds();
        let extent = (hi[0] - lo[0]).max(hi[1] - lo[1]);
        PlaneGrid::with_cell(stack, extent / cells.max(1) as f64)
    }

    /// Position of point `(i, j)`.
    pub fn point(&self, i: usize, j: usize) -> Point2 {
        [
            self.origin[0] + i as f64 * self.spacing,
            self.origin[1] + j as f64 * self.spacing,
        ]
    }
}

/// Inside (or on) flags of one section at every plane-grid point, by an even–odd scanline pass.
/// A point exactly on a contour counts as inside, as in the paper.
pub fn inside_flags(section: &Section, plane: &PlaneGrid) -> Vec<bool> {
    let [nx, ny] = plane.dims;
    let mut flags = vec![false; nx * ny];
    let mut crossings: Vec<Vec<f64>> = vec![Vec::new(); ny];
    for c in section.contours() {
        for (a, b) in c.segments() {
            if a[1] == b[1] {
                continue;
            }
            let (lo, hi) = if a[1] < b[1] { (a, b) } else { (b, a) };
            // Rows with lo.y ≤ y < hi.y (half-open, so shared vertices count once).
            let first = ((lo[1] - plane.origin[1]) / plane.spacing).ceil().max(0.0) as usize;
            let mut j = first;
            while j < ny {
                let y = plane.origin[1] + j as f64 * plane.spacing;
                if y >= hi[1] {
                    break;
                }
                if y >= lo[1] {
                    let x = lo[0] + (y - lo[1]) / (hi[1] - lo[1]) * (hi[0] - lo[0]);
                    crossings[j].push(x);
                }
                j += 1;
            }
        }
    }
    for (j, xs) in crossings.iter_mut().enumerate() {
        xs.sort_by(f64::total_cmp);
        for pair in xs.chunks(2) {
            let [x0, x1] = [pair[0], *pair.get(1).unwrap_or(&pair[0])];
            let i0 = ((x0 - plane.origin[0]) / plane.spacing).ceil().max(0.0) as usize;
            let i1 =
                (((x1 - plane.origin[0]) / plane.spacing).floor() as isize).min(nx as isize - 1);
            for i in i0 as isize..=i1 {
                flags[j * nx + i as usize] = true;
            }
        }
    }
    // Points exactly on a contour (on a horizontal segment, or a vertex) are inside too.
    for c in section.contours() {
        for (a, b) in c.segments() {
            mark_on_segment(&mut flags, plane, a, b);
        }
    }
    flags
}

fn mark_on_segment(flags: &mut [bool], plane: &PlaneGrid, a: Point2, b: Point2) {
    let [nx, ny] = plane.dims;
    let to = |p: Point2, k: usize| (p[k] - plane.origin[k]) / plane.spacing;
    let (i0, i1) = (
        to(a, 0).min(to(b, 0)).ceil(),
        to(a, 0).max(to(b, 0)).floor(),
    );
    let (j0, j1) = (
        to(a, 1).min(to(b, 1)).ceil(),
        to(a, 1).max(to(b, 1)).floor(),
    );
    if (i1 - i0 + 1.0) * (j1 - j0 + 1.0) > 64.0 && a[0] != b[0] && a[1] != b[1] {
        // Only axis-aligned segments can hold many grid points; a slanted one meets few, found
        // by walking its columns.
        let mut i = i0.max(0.0);
        while i <= i1.min(nx as f64 - 1.0) {
            let x = plane.origin[0] + i * plane.spacing;
            let y = a[1] + (x - a[0]) / (b[0] - a[0]) * (b[1] - a[1]);
            let j = to([x, y], 1);
            if j == j.round()
                && j >= 0.0
                && (j as usize) < ny
                && plane.point(i as usize, j as usize) == [x, y]
            {
                flags[j as usize * nx + i as usize] = true;
            }
            i += 1.0;
        }
        return;
    }
    let mut j = j0.max(0.0);
    while j <= j1.min(ny as f64 - 1.0) {
        let mut i = i0.max(0.0);
        while i <= i1.min(nx as f64 - 1.0) {
            let p = plane.point(i as usize, j as usize);
            if segment_distance(p, a, b) == 0.0 {
                flags[j as usize * nx + i as usize] = true;
            }
            i += 1.0;
        }
        j += 1.0;
    }
}

/// A bucket grid of one section's segments for nearest-segment queries.
struct SegmentIndex {
    segments: Vec<(Point2, Point2)>,
    buckets: HashMap<(i64, i64), Vec<u32>>,
    size: f64,
}

impl SegmentIndex {
    fn new(section: &Section, size: f64) -> SegmentIndex {
        let segments: Vec<(Point2, Point2)> = section
            .contours()
            .iter()
            .flat_map(|c| c.segments())
            .collect();
        let mut buckets: HashMap<(i64, i64), Vec<u32>> = HashMap::new();
        for (k, (a, b)) in segments.iter().enumerate() {
            let cell = |v: f64| (v / size).floor() as i64;
            for x in cell(a[0].min(b[0]))..=cell(a[0].max(b[0])) {
                for y in cell(a[1].min(b[1]))..=cell(a[1].max(b[1])) {
                    buckets.entry((x, y)).or_default().push(k as u32);
                }
            }
        }
        SegmentIndex {
            segments,
            buckets,
            size,
        }
    }

    /// Exact distance to the nearest segment: rings of buckets around the point until no
    /// farther ring can hold anything nearer.
    fn distance(&self, p: Point2) -> f64 {
        let (cx, cy) = (
            (p[0] / self.size).floor() as i64,
            (p[1] / self.size).floor() as i64,
        );
        let mut best = f64::INFINITY;
        let mut r = 0i64;
        loop {
            for x in cx - r..=cx + r {
                for y in cy - r..=cy + r {
                    if (x - cx).abs() != r && (y - cy).abs() != r {
                        continue;
                    }
                    if let Some(list) = self.buckets.get(&(x, y)) {
                        for &k in list {
                            let (a, b) = self.segments[k as usize];
                            best = best.min(segment_distance(p, a, b));
                        }
                    }
                }
            }
            // Everything outside ring r is at least r bucket sizes away.
            if best <= r as f64 * self.size || r > 1 << 20 {
                return best;
            }
            r += 1;
            if best.is_infinite() && r as usize > self.buckets.len() + 2 {
                // No segment at all nearby: fall back to all of them.
                return self
                    .segments
                    .iter()
                    .map(|&(a, b)| segment_distance(p, a, b))
                    .fold(f64::INFINITY, f64::min);
            }
        }
    }
}

/// The stacked field and how much of it was evaluated.
#[derive(Clone, Debug)]
pub struct SectionField {
    /// Values on the plane grid × sections, `x` fastest; grid `z` is the section index (spacing
    /// 1); map it to heights with the stack.
    pub grid: Grid,
    /// Grid points whose exact distance was computed.
    pub evaluated: usize,
    /// Cells (between neighbouring sections) that hold surface.
    pub active_cells: usize,
    /// The magnitude of the values not evaluated (larger than any distance in the field).
    pub placeholder: f32,
}

/// Samples the stack's signed distance (positive inside) on `plane`, section by section, exactly
/// at the corners of cells the surface passes through and as a placeholder of the right sign
/// elsewhere.
pub fn section_field(stack: &SectionStack, plane: &PlaneGrid) -> SectionField {
    stacked_field(stack, plane, None).0
}

/// [`section_field`] with, if `extend` is given, one more layer beyond each end section at that
/// distance: the end section's field lowered by its largest inside distance, so the body tapers
/// to a point (or ridge) exactly `extend` beyond the end, as geologists extrapolate ore bodies.
/// Returns the field and the heights of its layers.
pub fn stacked_field(
    stack: &SectionStack,
    plane: &PlaneGrid,
    extend: Option<f64>,
) -> (SectionField, Vec<f64>) {
    let [nx, ny] = plane.dims;
    let layer_size = nx * ny;
    let sections = stack.sections();
    let ns = sections.len();
    let mut heights: Vec<f64> = sections.iter().map(|s| s.z()).collect();
    let mut flags: Vec<Vec<bool>> = sections.iter().map(|s| inside_flags(s, plane)).collect();
    // Layer index of each real section.
    let mut real: Vec<usize> = (0..ns).collect();
    if let Some(d) = extend {
        heights.insert(0, heights[0] - d);
        heights.push(heights[heights.len() - 1] + d);
        flags.insert(0, vec![false; layer_size]);
        flags.push(vec![false; layer_size]);
        real = (1..=ns).collect();
    }
    let nz = flags.len();
    let (lo, hi, _) = stack.bounds();
    let far = ((hi[0] - lo[0]).powi(2) + (hi[1] - lo[1]).powi(2)).sqrt()
        + 4.0 * plane.spacing * (nx + ny) as f64;
    let mut values: Vec<f64> = Vec::with_capacity(layer_size * nz);
    for f in &flags {
        values.extend(f.iter().map(|&inside| if inside { far } else { -far }));
    }
    let mut needed = vec![false; layer_size * nz];
    let mut active_cells = 0;
    for k in 0..nz.saturating_sub(1).max(1) {
        let (f0, f1) = (&flags[k], &flags[(k + 1).min(nz - 1)]);
        for j in 0..ny - 1 {
            for i in 0..nx - 1 {
                let idx = [
                    j * nx + i,
                    j * nx + i + 1,
                    (j + 1) * nx + i,
                    (j + 1) * nx + i + 1,
                ];
                let first = f0[idx[0]];
                if idx.iter().all(|&q| f0[q] == first && f1[q] == first) {
                    continue;
                }
                active_cells += 1;
                for &q in &idx {
                    needed[k * layer_size + q] = true;
                    needed[(k + 1).min(nz - 1) * layer_size + q] = true;
                }
            }
        }
    }
    let mut evaluated = 0;
    for (s, section) in sections.iter().enumerate() {
        let k = real[s];
        let range = k * layer_size..(k + 1) * layer_size;
        if !needed[range.clone()].iter().any(|&n| n) {
            continue;
        }
        let index = SegmentIndex::new(section, 2.0 * plane.spacing);
        for q in 0..layer_size {
            if !needed[k * layer_size + q] {
                continue;
            }
            let d = index.distance(plane.point(q % nx, q / nx));
            values[k * layer_size + q] = if flags[k][q] { d } else { -d };
            evaluated += 1;
        }
    }
    if extend.is_some() {
        for (virtual_layer, end) in [(0, 1), (nz - 1, nz - 2)] {
            let end_values = &values[end * layer_size..(end + 1) * layer_size];
            let deepest = end_values
                .iter()
                .copied()
                .filter(|&v| v > 0.0 && v < far)
                .fold(0.0, f64::max);
            // Strictly below zero everywhere, zero only in the limit at the deepest point.
            let drop = deepest * (1.0 + 1e-6) + 1e-12 * far;
            let lowered: Vec<f64> = end_values
                .iter()
                .map(|&v| if v.abs() < far { v - drop } else { -far })
                .collect();
            values[virtual_layer * layer_size..(virtual_layer + 1) * layer_size]
                .copy_from_slice(&lowered);
        }
    }
    let mut values: Vec<f32> = values.into_iter().map(|v| v as f32).collect();
    let layers = if nz == 1 {
        // One section: a second, identical layer so the grid is three-dimensional.
        values.extend_from_within(..);
        2
    } else {
        nz
    };
    let grid = Grid::new([nx, ny, layers], values)
        .expect("dimensions and values agree")
        .with_spacing([plane.spacing, plane.spacing, 1.0])
        .expect("positive spacing")
        .with_origin([plane.origin[0], plane.origin[1], 0.0])
        .expect("finite origin");
    (
        SectionField {
            grid,
            evaluated,
            active_cells,
            placeholder: far as f32,
        },
        heights,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stack(sections: Vec<(f64, Vec<Vec<Point2>>)>) -> SectionStack {
        SectionStack::from_points(sections).unwrap()
    }

    use crate::contours::test_circle as circle;

    /// Flags and computed distances agree with the direct definition at every point.
    #[test]
    fn field_matches_the_section_definition_where_evaluated() {
        let s = stack(vec![
            (
                0.0,
                vec![circle(0.0, 0.0, 3.0, 40), circle(0.3, 0.0, 1.0, 12)],
            ),
            (2.5, vec![circle(0.5, 0.2, 2.5, 33)]),
            (
                4.0,
                vec![vec![[-2.0, -2.0], [2.0, -2.0], [2.0, 2.0], [-2.0, 2.0]]],
            ),
        ]);
        let plane = PlaneGrid::across(&s, 30);
        let field = section_field(&s, &plane);
        let [nx, ny] = plane.dims;
        for (k, section) in s.sections().iter().enumerate() {
            for j in 0..ny {
                for i in 0..nx {
                    let p = plane.point(i, j);
                    let v = f64::from(field.grid.value(i, j, k));
                    let exact = section.signed_distance(p);
                    if exact.abs() < 1e-9 {
                        // On a contour up to rounding: either side is right.
                        assert!(v.abs() < 1e-6 || v.abs() == f64::from(field.placeholder));
                        continue;
                    }
                    assert_eq!(v >= 0.0, exact >= 0.0, "sign at {p:?}, section {k}");
                    if v.abs() != f64::from(field.placeholder) {
                        assert!((v - exact).abs() < 1e-5, "{v} vs {exact} at {p:?}");
                    } else {
                        assert!(v.abs() > exact.abs());
                    }
                }
            }
        }
        // Only a fraction of the points needed a distance.
        assert!(
            field.evaluated < nx * ny * 3 / 2,
            "{} of {}",
            field.evaluated,
            nx * ny * 3
        );
        assert!(field.active_cells > 0);
    }

    /// Points exactly on a contour (grid-aligned square) count as inside, with distance 0.
    #[test]
    fn points_on_contours_are_inside() {
        let s = stack(vec![(
            0.0,
            vec![vec![[0.0, 0.0], [4.0, 0.0], [4.0, 4.0], [0.0, 4.0]]],
        )]);
        let plane = PlaneGrid {
            origin: [-1.0, -1.0],
            spacing: 1.0,
            dims: [7, 7],
        };
        let flags = inside_flags(&s.sections()[0], &plane);
        let [nx, _] = plane.dims;
        let at = |x: f64, y: f64| {
            let i = ((x - plane.origin[0]) / plane.spacing).round() as usize;
            let j = ((y - plane.origin[1]) / plane.spacing).round() as usize;
            flags[j * nx + i]
        };
        assert!(at(0.0, 0.0) && at(4.0, 4.0) && at(2.0, 0.0) && at(0.0, 3.0) && at(2.0, 2.0));
        assert!(!at(-1.0, 2.0) && !at(5.0, 2.0) && !at(2.0, 5.0));
    }
}
