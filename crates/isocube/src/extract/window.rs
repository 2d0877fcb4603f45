//! A window of point planes: what one box of the binary engine reads.

use crate::field::GridView;

/// The values a cell mesher reads: a whole [`GridView`] (in any memory order), or only planes
/// `first..` of a grid (a streamed slab, `x` fastest). Indices are always the whole grid's, so
/// positions and gradients come out exactly as on the whole grid as long as the planes asked for
/// are in the window.
#[derive(Clone, Copy, Debug)]
pub(super) struct Window<'a> {
    view: GridView<'a>,
    /// Elements to subtract from a view index: the planes before the window's first.
    skipped: usize,
}

impl<'a> Window<'a> {
    /// All of a view.
    pub(super) fn whole(view: GridView<'a>) -> Window<'a> {
        Window { view, skipped: 0 }
    }

    /// Planes `first..first + values.len() / (nx · ny)` of a grid with this geometry.
    pub(super) fn new(
        dims: [usize; 3],
        spacing: [f64; 3],
        origin: [f64; 3],
        heights: Option<&'a [f64]>,
        first: usize,
        values: &'a [f32],
    ) -> Window<'a> {
        debug_assert_eq!(values.len() % (dims[0] * dims[1]), 0);
        Window {
            view: GridView::planes(values, dims, spacing, origin, heights),
            skipped: first * dims[0] * dims[1],
        }
    }

    /// The window of a block of a larger grid (see [`GridView::with_base`]).
    pub(super) fn with_base(self, base: [usize; 3]) -> Window<'a> {
        Window {
            view: self.view.with_base(base),
            ..self
        }
    }

    /// The whole grid's dimensions.
    #[inline]
    pub(super) fn dims(&self) -> [usize; 3] {
        self.view.dims()
    }

    /// See [`GridView::edge_point`].
    #[inline]
    pub(super) fn edge_point(&self, p: [usize; 3], axis: usize, t: f64) -> [f64; 3] {
        self.view.edge_point(p, axis, t)
    }

    /// See [`GridView::edge_length`].
    #[inline]
    pub(super) fn edge_length(&self, p: [usize; 3], axis: usize) -> f64 {
        self.view.edge_length(p, axis)
    }

    /// Whether the planes are evenly spaced along every axis (no [`GridView::with_heights`]).
    #[inline]
    pub(super) fn is_uniform(&self) -> bool {
        self.view.heights().is_none()
    }

    /// The spacing between planes along each axis (`z`'s ignored where there are heights).
    #[inline]
    pub(super) fn spacing(&self) -> [f64; 3] {
        self.view.spacing()
    }

    /// Elements between neighbouring points along each axis.
    #[inline]
    pub(super) fn strides(&self) -> [usize; 3] {
        self.view.strides()
    }

    /// Offset in [`Window::values`] of point `(i, j, k)`.
    #[inline]
    pub(super) fn index(&self, i: usize, j: usize, k: usize) -> usize {
        self.view.index(i, j, k) - self.skipped
    }

    #[inline]
    pub(super) fn value(&self, i: usize, j: usize, k: usize) -> f32 {
        self.view.values()[self.index(i, j, k)]
    }

    /// The grid's number for point `p` (`x + nx·(y + ny·z)`), wherever and however the values
    /// are stored: the key vertices are welded by.
    #[inline]
    pub(super) fn point_index(&self, p: [usize; 3]) -> usize {
        let [nx, ny, _] = self.dims();
        p[0] + nx * (p[1] + ny * p[2])
    }

    /// Calls `f` with the values of points `min..=max` row by row (`x` fastest, then `y`, then
    /// `z`): slices of the values where rows lie `x` fastest, else gathered into one buffer.
    pub(super) fn for_each_row(&self, min: [usize; 3], max: [usize; 3], mut f: impl FnMut(&[f32])) {
        let values = self.view.values();
        let sx = self.strides()[0];
        let mut gathered = Vec::new();
        for k in min[2]..=max[2] {
            for j in min[1]..=max[1] {
                let start = self.index(min[0], j, k);
                if sx == 1 {
                    f(&values[start..=start + (max[0] - min[0])]);
                } else {
                    gathered.clear();
                    gathered.extend((0..=max[0] - min[0]).map(|i| values[start + i * sx]));
                    f(&gathered);
                }
            }
        }
    }

    /// The window's values (point `(i, j, k)` at [`Window::index`]).
    #[inline]
    pub(super) fn values(&self) -> &'a [f32] {
        self.view.values()
    }

    /// World position of point `(i, j, k)` in the grid's frame: the same arithmetic as
    /// [`crate::field::Grid::point`], so the same bits.
    #[inline]
    pub(super) fn point(&self, i: usize, j: usize, k: usize) -> [f64; 3] {
        self.view.point(i, j, k)
    }
}
