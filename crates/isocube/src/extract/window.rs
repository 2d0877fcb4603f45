//! A window of point planes: what one slab of the binary engine reads.

use crate::field::Grid;

/// The values of point planes `first..` of a grid (as many as `values` holds), with the whole
/// grid's dimensions and geometry: indices are the whole grid's, so positions and gradients come
/// out exactly as on the whole grid as long as the planes asked for are in the window.
#[derive(Clone, Copy, Debug)]
pub(super) struct Window<'a> {
    dims: [usize; 3],
    spacing: [f64; 3],
    origin: [f64; 3],
    first: usize,
    values: &'a [f32],
}

impl<'a> Window<'a> {
    /// All of a grid.
    pub(super) fn whole(grid: &'a Grid) -> Window<'a> {
        Window::new(grid.dims(), grid.spacing(), grid.origin(), 0, grid.values())
    }

    /// Planes `first..first + values.len() / (nx · ny)` of a grid with this geometry.
    pub(super) fn new(
        dims: [usize; 3],
        spacing: [f64; 3],
        origin: [f64; 3],
        first: usize,
        values: &'a [f32],
    ) -> Window<'a> {
        debug_assert_eq!(values.len() % (dims[0] * dims[1]), 0);
        Window {
            dims,
            spacing,
            origin,
            first,
            values,
        }
    }

    /// The whole grid's dimensions.
    #[inline]
    pub(super) fn dims(&self) -> [usize; 3] {
        self.dims
    }

    #[inline]
    pub(super) fn spacing(&self) -> [f64; 3] {
        self.spacing
    }

    /// Offset in [`Window::values`] of point `(i, j, k)`.
    #[inline]
    pub(super) fn index(&self, i: usize, j: usize, k: usize) -> usize {
        i + self.dims[0] * (j + self.dims[1] * (k - self.first))
    }

    #[inline]
    pub(super) fn value(&self, i: usize, j: usize, k: usize) -> f32 {
        self.values[self.index(i, j, k)]
    }

    /// The grid's number for point `p` (`x + nx·(y + ny·z)`), wherever the window starts.
    #[inline]
    pub(super) fn point_index(&self, p: [usize; 3]) -> usize {
        p[0] + self.dims[0] * (p[1] + self.dims[1] * p[2])
    }

    /// Points `x0..=x1` of row `(j, k)`.
    #[inline]
    pub(super) fn row(&self, j: usize, k: usize, x0: usize, x1: usize) -> &'a [f32] {
        let start = self.index(0, j, k);
        &self.values[start + x0..=start + x1]
    }

    /// The window's values, from plane `first`.
    #[inline]
    pub(super) fn values(&self) -> &'a [f32] {
        self.values
    }

    /// The values of planes `k0..=k1`.
    pub(super) fn planes(&self, k0: usize, k1: usize) -> &'a [f32] {
        let plane = self.dims[0] * self.dims[1];
        &self.values[(k0 - self.first) * plane..(k1 + 1 - self.first) * plane]
    }

    /// World position of point `(i, j, k)`: the same arithmetic as [`Grid::point`], so the
    /// same bits.
    #[inline]
    pub(super) fn point(&self, i: usize, j: usize, k: usize) -> [f64; 3] {
        [
            self.origin[0] + i as f64 * self.spacing[0],
            self.origin[1] + j as f64 * self.spacing[1],
            self.origin[2] + k as f64 * self.spacing[2],
        ]
    }
}
