//! Borrowed grids: values read where they lie, in any memory order.

use super::{Grid, GridError, Orientation, Sample};

/// A grid whose values are borrowed, not owned: a [`Grid`], a NumPy array (C or Fortran order,
/// axes in any order), a memory-mapped file. Point `(i, j, k)` holds
/// `values[offset + i·strides[0] + j·strides[1] + k·strides[2]]` and sits at
/// `origin + direction · ((i, j, k) ⊙ spacing)` in world coordinates.
///
/// Every extraction entry point takes a view (a `&Grid` turns into one), so nothing is copied
/// to mesh data that is already in memory. The extractor works in the grid's own frame
/// (`origin + (i, j, k) ⊙ spacing`) and turns the finished mesh into the world with
/// [`GridView::orientation`] (winding reversed under a reflection, so fronts still face
/// increasing values).
///
/// ```
/// use isocube::extract::{extract, ExtractOptions};
/// use isocube::field::{GridView, Sample};
/// // The same values stored with z fastest (a C-order array `a[x, y, z]`).
/// let grid = Sample::Torus.grid(12);
/// let [nx, ny, nz] = grid.dims();
/// let mut zyx = vec![0.0; grid.values().len()];
/// for k in 0..nz {
///     for j in 0..ny {
///         for i in 0..nx {
///             zyx[k + nz * (j + ny * i)] = grid.value(i, j, k);
///         }
///     }
/// }
/// let view = GridView::strided(&zyx, grid.dims(), [ny * nz, nz, 1]).unwrap()
///     .with_spacing(grid.spacing()).unwrap()
///     .with_origin(grid.origin()).unwrap();
/// let options = ExtractOptions::default();
/// assert_eq!(extract(view, &options).unwrap(), extract(&grid, &options).unwrap());
/// ```
#[derive(Clone, Copy, Debug)]
pub struct GridView<'a> {
    values: &'a [f32],
    dims: [usize; 3],
    strides: [usize; 3],
    offset: usize,
    spacing: [f64; 3],
    origin: [f64; 3],
    orientation: Orientation,
    exact: Option<Sample>,
    /// The planes' `z` (before the origin) when they are unevenly spaced.
    heights: Option<&'a [f64]>,
    /// The whole grid's index of point `(0, 0, 0)` when the view is a block of a larger grid:
    /// positions are the whole grid's, to the bit.
    base: [usize; 3],
}

impl<'a> GridView<'a> {
    /// Values with `x` fastest, then `y`, then `z` (a Fortran-order `a[x, y, z]` or a C-order
    /// `a[z, y, x]`); unit spacing at the origin.
    pub fn new(values: &'a [f32], dims: [usize; 3]) -> Result<GridView<'a>, GridError> {
        let strides = [1, dims[0], dims[0].saturating_mul(dims[1])];
        GridView::strided(values, dims, strides)
    }

    /// Values at `strides` (in elements, per grid axis) from the start of `values`: any axis
    /// order and memory order. Every point must lie inside `values`.
    pub fn strided(
        values: &'a [f32],
        dims: [usize; 3],
        strides: [usize; 3],
    ) -> Result<GridView<'a>, GridError> {
        GridView::with_offset(values, dims, strides, 0)
    }

    /// [`GridView::strided`] with point `(0, 0, 0)` at `values[offset]`.
    pub fn with_offset(
        values: &'a [f32],
        dims: [usize; 3],
        strides: [usize; 3],
        offset: usize,
    ) -> Result<GridView<'a>, GridError> {
        let expected = Grid::point_count(dims)?;
        // The last point's index, checked: a view past the end is refused here so reads never
        // need a check of their own.
        let last = (0..3)
            .try_fold(offset, |acc, a| {
                (dims[a] - 1)
                    .checked_mul(strides[a])
                    .and_then(|s| acc.checked_add(s))
            })
            .ok_or(GridError::Overflow { dims })?;
        if last >= values.len() {
            return Err(GridError::ValueCount {
                dims,
                expected: expected.max(last.saturating_add(1)),
                actual: values.len(),
            });
        }
        Ok(GridView {
            values,
            dims,
            strides,
            offset,
            spacing: [1.0; 3],
            origin: [0.0; 3],
            orientation: Orientation::IDENTITY,
            exact: None,
            heights: None,
            base: [0; 3],
        })
    }

    /// The whole grid's geometry over the values of planes `first..` only, `x` fastest: what a
    /// slab of a streamed volume reads. Indices stay the whole grid's; reading a plane outside
    /// the buffer panics (the engine never does).
    pub(crate) fn planes(
        values: &'a [f32],
        dims: [usize; 3],
        spacing: [f64; 3],
        origin: [f64; 3],
        heights: Option<&'a [f64]>,
    ) -> GridView<'a> {
        GridView {
            values,
            dims,
            strides: [1, dims[0], dims[0] * dims[1]],
            offset: 0,
            spacing,
            origin,
            orientation: Orientation::IDENTITY,
            exact: None,
            heights,
            base: [0; 3],
        }
    }

    /// The larger grid's index of the view's point `(0, 0, 0)` (zero unless the view is a
    /// block of a larger grid, [`GridView::with_base`]).
    pub(crate) fn base(&self) -> [usize; 3] {
        self.base
    }

    /// The view as the block of a larger grid whose point `base` is the view's `(0, 0, 0)`:
    /// positions are computed from the larger grid's indices (its spacing and origin are the
    /// view's), so they come out as the larger grid's to the bit. Not with heights.
    pub(crate) fn with_base(mut self, base: [usize; 3]) -> GridView<'a> {
        debug_assert!(self.heights.is_none() || base == [0; 3]);
        self.base = base;
        self
    }

    /// Sets the spacing (each finite and positive).
    pub fn with_spacing(mut self, spacing: [f64; 3]) -> Result<GridView<'a>, GridError> {
        if spacing.iter().any(|s| !s.is_finite() || *s <= 0.0) {
            return Err(GridError::Spacing { spacing });
        }
        self.spacing = spacing;
        self.exact = None;
        Ok(self)
    }

    /// Sets the origin (finite).
    pub fn with_origin(mut self, origin: [f64; 3]) -> Result<GridView<'a>, GridError> {
        if origin.iter().any(|o| !o.is_finite()) {
            return Err(GridError::Origin { origin });
        }
        self.origin = origin;
        self.exact = None;
        Ok(self)
    }

    /// Places the `z` planes at `heights` (added to the origin's `z`) instead of `spacing[2]`
    /// apart: a rectilinear grid, as sections at uneven heights or an image series with uneven
    /// slice gaps are. One height per plane, finite and strictly increasing.
    ///
    /// ```
    /// use isocube::extract::{extract, ExtractOptions};
    /// use isocube::field::{GridView, Sample};
    /// let grid = Sample::Sphere.grid(12);
    /// let heights: Vec<f64> = (0..12).map(|k| (k as f64 / 11.0).powi(2)).collect();
    /// let view = grid.view().with_heights(&heights).unwrap();
    /// assert_eq!(view.point(0, 0, 11)[2], grid.origin()[2] + 1.0);
    /// let (mesh, _) = extract(view, &ExtractOptions::default()).unwrap();
    /// let z0 = grid.origin()[2] as f32;
    /// assert!(mesh.positions.iter().all(|p| p[2] >= z0 && p[2] <= z0 + 1.0));
    /// ```
    pub fn with_heights(mut self, heights: &'a [f64]) -> Result<GridView<'a>, GridError> {
        let increasing = heights.windows(2).all(|w| w[0] < w[1]);
        if heights.len() != self.dims[2] || !increasing || heights.iter().any(|h| !h.is_finite()) {
            return Err(GridError::Heights {
                planes: self.dims[2],
                heights: heights.len(),
            });
        }
        self.heights = Some(heights);
        self.exact = None;
        Ok(self)
    }

    /// The `z` planes' heights, if set ([`GridView::with_heights`]).
    pub fn heights(&self) -> Option<&'a [f64]> {
        self.heights
    }

    /// Sets how the grid's axes lie in the world.
    pub fn with_orientation(mut self, orientation: Orientation) -> GridView<'a> {
        self.orientation = orientation;
        self
    }

    pub(crate) fn with_exact(mut self, sample: Sample) -> GridView<'a> {
        self.exact = Some(sample);
        self
    }

    /// Points along x, y and z.
    #[inline]
    pub fn dims(&self) -> [usize; 3] {
        self.dims
    }

    /// Elements between neighbouring points along each axis.
    #[inline]
    pub fn strides(&self) -> [usize; 3] {
        self.strides
    }

    /// Distance between neighbouring points along each axis.
    #[inline]
    pub fn spacing(&self) -> [f64; 3] {
        self.spacing
    }

    /// World position of point (0, 0, 0).
    #[inline]
    pub fn origin(&self) -> [f64; 3] {
        self.origin
    }

    /// How the grid's axes lie in the world.
    pub fn orientation(&self) -> Orientation {
        self.orientation
    }

    /// The built-in sample these values were computed from, if any (and the geometry is still
    /// the sample's): relaxation then follows the exact function, not the interpolant.
    pub fn exact(&self) -> Option<Sample> {
        self.exact
    }

    /// The borrowed values (point `(i, j, k)` at [`GridView::index`]).
    #[inline]
    pub fn values(&self) -> &'a [f32] {
        self.values
    }

    /// Offset in [`GridView::values`] of point `(i, j, k)`.
    #[inline]
    pub fn index(&self, i: usize, j: usize, k: usize) -> usize {
        self.offset + i * self.strides[0] + j * self.strides[1] + k * self.strides[2]
    }

    /// Value at point `(i, j, k)`.
    #[inline]
    pub fn value(&self, i: usize, j: usize, k: usize) -> f32 {
        self.values[self.index(i, j, k)]
    }

    /// Position of point `(i, j, k)` in the grid's frame (before [`GridView::orientation`]);
    /// [`Grid::point`] is this.
    #[inline]
    pub fn point(&self, i: usize, j: usize, k: usize) -> [f64; 3] {
        let [i, j, k] = [i + self.base[0], j + self.base[1], k + self.base[2]];
        let z = match self.heights {
            None => k as f64 * self.spacing[2],
            Some(h) => h[k],
        };
        [
            self.origin[0] + i as f64 * self.spacing[0],
            self.origin[1] + j as f64 * self.spacing[1],
            self.origin[2] + z,
        ]
    }

    /// The point at fraction `t` of the way along the grid edge from point `p` along `axis`.
    #[inline]
    pub fn edge_point(&self, p: [usize; 3], axis: usize, t: f64) -> [f64; 3] {
        let mut x = self.point(p[0], p[1], p[2]);
        x[axis] += t * self.edge_length(p, axis);
        x
    }

    /// The length of the grid edge from point `p` along `axis`.
    #[inline]
    pub fn edge_length(&self, p: [usize; 3], axis: usize) -> f64 {
        match self.heights {
            Some(h) if axis == 2 => h[p[2] + 1] - h[p[2]],
            _ => self.spacing[axis],
        }
    }

    /// The shortest distance between neighbouring planes along any axis.
    pub fn min_spacing(&self) -> f64 {
        let z = match self.heights {
            Some(h) => h
                .windows(2)
                .map(|w| w[1] - w[0])
                .fold(f64::INFINITY, f64::min),
            None => self.spacing[2],
        };
        self.spacing[..2].iter().copied().fold(z, f64::min)
    }

    /// Whether the values lie `x` fastest with no gap, as in a [`Grid`].
    pub fn is_x_fastest(&self) -> bool {
        self.strides == [1, self.dims[0], self.dims[0] * self.dims[1]]
    }

    /// Number of cells (`(nx−1)(ny−1)(nz−1)`).
    pub fn cell_count(&self) -> usize {
        self.dims.iter().map(|d| d - 1).product()
    }

    /// The values `x` fastest: borrowed when they already lie so, else gathered.
    pub fn x_fastest(&self) -> std::borrow::Cow<'a, [f32]> {
        if self.is_x_fastest() {
            let n = self.dims.iter().product::<usize>();
            return std::borrow::Cow::Borrowed(&self.values[self.offset..self.offset + n]);
        }
        let [nx, ny, nz] = self.dims;
        let mut out = Vec::with_capacity(nx * ny * nz);
        for k in 0..nz {
            for j in 0..ny {
                let row = self.index(0, j, k);
                out.extend((0..nx).map(|i| self.values[row + i * self.strides[0]]));
            }
        }
        std::borrow::Cow::Owned(out)
    }

    /// An owned copy, `x` fastest, with the same spacing and origin (not the heights: a [`Grid`]
    /// is regular).
    pub fn to_grid(&self) -> Grid {
        Grid::new(self.dims, self.x_fastest().into_owned())
            .and_then(|g| g.with_spacing(self.spacing))
            .and_then(|g| g.with_origin(self.origin))
            .expect("a view's dimensions and geometry were checked when it was made")
    }
}

impl<'a> From<&'a Grid> for GridView<'a> {
    fn from(grid: &'a Grid) -> GridView<'a> {
        grid.view()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn views_past_the_end_are_refused() {
        let values = vec![0.0f32; 27];
        assert!(GridView::new(&values, [3, 3, 3]).is_ok());
        assert!(matches!(
            GridView::new(&values, [3, 3, 4]),
            Err(GridError::ValueCount { .. })
        ));
        assert!(GridView::with_offset(&values, [3, 3, 3], [1, 3, 9], 1).is_err());
        assert!(GridView::strided(&values, [3, 3, 3], [9, 3, 1]).is_ok());
        assert!(matches!(
            GridView::strided(&values, [3, 3, 3], [usize::MAX, 3, 1]),
            Err(GridError::Overflow { .. })
        ));
        assert!(GridView::new(&values, [1, 3, 9]).is_err());
    }

    #[test]
    fn strided_values_gather_into_the_grid() {
        let grid = Sample::Noise { seed: 3 }.grid(7);
        let [nx, ny, nz] = grid.dims();
        let mut zyx = vec![0.0; 1 + nx * ny * nz];
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    zyx[1 + k + nz * (j + ny * i)] = grid.value(i, j, k);
                }
            }
        }
        let view = GridView::with_offset(&zyx, grid.dims(), [ny * nz, nz, 1], 1).unwrap();
        assert!(!view.is_x_fastest());
        assert_eq!(view.x_fastest().as_ref(), grid.values());
        assert_eq!(view.value(2, 3, 4), grid.value(2, 3, 4));
        assert!(grid.view().is_x_fastest());
        assert_eq!(grid.view().exact(), Some(Sample::Noise { seed: 3 }));
    }
}
