//! The sectional field: the signed distance of every section, sampled on one plane grid and
//! stacked at the sections' heights, evaluated only where the surface can pass.
//!
//! As in the section-data paper, each grid point first gets a state (inside or on a contour, or
//! outside) from a scanline pass over the section's contour segments; a cell between two
//! sections whose eight corners all share a state holds no surface, and its corners need no
//! distance. Only the corners of the other cells get the exact Euclidean distance to the
//! nearest contour segment (found through an R-tree of segments), signed by the state. The
//! remaining points keep a placeholder of the right sign whose size exceeds every computed
//! distance, so extraction sees the same configuration everywhere.

use super::plane::PlaneGrid;
use super::sparse::{inside_spans, SparseField};
use super::{Section, SectionStack};
use crate::field::Grid;

/// Inside (or on) flags of one section at every plane-grid point, by an even–odd scanline pass.
/// A point exactly on a contour counts as inside, as in the paper.
pub fn inside_flags(section: &Section, plane: &PlaneGrid) -> Vec<bool> {
    let [nx, ny] = plane.dims;
    let mut flags = vec![false; nx * ny];
    for (j, row) in inside_spans(section, plane).iter().enumerate() {
        for s in row {
            flags[j * nx + s[0] as usize..=j * nx + s[1] as usize].fill(true);
        }
    }
    flags
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
    let sparse = SparseField::new(stack, plane, extend);
    let [nx, ny] = plane.dims;
    let layers = sparse.heights.len();
    let mut values: Vec<f32> = Vec::with_capacity(nx * ny * layers.max(2));
    for l in 0..layers {
        for j in 0..ny {
            let partner = sparse.partner(l);
            values.extend((0..nx).map(|i| sparse.value(l, partner, i, j) as f32));
        }
    }
    if layers == 1 {
        // One section: a second, identical layer so the grid is three-dimensional.
        values.extend_from_within(..);
    }
    let grid = Grid::new([nx, ny, layers.max(2)], values)
        .expect("dimensions and values agree")
        .with_spacing([plane.spacing, plane.spacing, 1.0])
        .expect("positive spacing")
        .with_origin([plane.origin[0], plane.origin[1], 0.0])
        .expect("finite origin");
    (
        SectionField {
            grid,
            evaluated: sparse.evaluated,
            active_cells: sparse.active_cells,
            placeholder: sparse.far as f32,
        },
        sparse.heights,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contours::Point2;

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
