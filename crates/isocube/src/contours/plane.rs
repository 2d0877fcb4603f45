//! The grid in the sections' plane, which every sectional stage samples on.

use super::{Point2, SectionStack};

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

    /// A grid of square cells, at most `counts[0]` × `counts[1]` of them over the contours'
    /// bounding box (the cell fits the tighter axis).
    ///
    /// ```
    /// use isocube::contours::{PlaneGrid, SectionStack};
    /// let stack = SectionStack::sample_orebody();
    /// let plane = PlaneGrid::with_counts(&stack, [60, 60]);
    /// assert_eq!(plane.spacing, PlaneGrid::across(&stack, 60).spacing);
    /// ```
    pub fn with_counts(stack: &SectionStack, counts: [usize; 2]) -> PlaneGrid {
        let (lo, hi, _) = stack.bounds();
        let [nx, ny] = counts.map(|n| n.max(1) as f64);
        let cell = ((hi[0] - lo[0]) / nx).max((hi[1] - lo[1]) / ny);
        PlaneGrid::with_cell(stack, cell)
    }

    /// Whether a stack of `sections` can be sampled on this grid: only the cells the surface
    /// crosses are stored, but every grid row of every section (and the caps) has an entry,
    /// and indices along a row are 32-bit.
    pub fn indexable(&self, sections: usize) -> bool {
        let rows = self.dims[1].saturating_mul(sections + 2);
        self.dims[0] <= 1 << 30 && rows <= 1 << 28
    }

    /// A grid with about `cells` cells across the longer side of the contours' bounding box.
    pub fn across(stack: &SectionStack, cells: usize) -> PlaneGrid {
        let (lo, hi, _) = stack.bounds();
        let extent = (hi[0] - lo[0]).max(hi[1] - lo[1]);
        PlaneGrid::with_cell(stack, extent / cells.max(1) as f64)
    }

    /// The same cells with empty grid around them: `factor` times the points along each axis
    /// (at least 1×). Reconstruction visits only the cells the surface crosses, so this costs
    /// nothing; benchmarks use it to show that.
    pub fn padded(&self, factor: usize) -> PlaneGrid {
        let pad = self.dims.map(|d| factor.saturating_sub(1) * d / 2);
        PlaneGrid {
            origin: [
                self.origin[0] - pad[0] as f64 * self.spacing,
                self.origin[1] - pad[1] as f64 * self.spacing,
            ],
            spacing: self.spacing,
            dims: [self.dims[0] + 2 * pad[0], self.dims[1] + 2 * pad[1]],
        }
    }

    /// Position of point `(i, j)`.
    pub fn point(&self, i: usize, j: usize) -> Point2 {
        [
            self.origin[0] + i as f64 * self.spacing,
            self.origin[1] + j as f64 * self.spacing,
        ]
    }
}
