use thiserror::Error;

use super::{GridView, PlaneSource, Sample};

/// Why a grid could not be built.
#[derive(Debug, Error, Clone, PartialEq)]
#[non_exhaustive]
pub enum GridError {
    /// Fewer than two points along some axis (no cell).
    #[error("grid dimensions {dims:?} need at least 2 points along every axis")]
    TooSmall {
        /// The dimensions given.
        dims: [usize; 3],
    },
    /// The product of the dimensions overflows.
    #[error("grid dimensions {dims:?} are too large (the point count overflows)")]
    Overflow {
        /// The dimensions given.
        dims: [usize; 3],
    },
    /// The number of values does not match the dimensions.
    #[error("grid dimensions {dims:?} need {expected} values, got {actual}")]
    ValueCount {
        /// The dimensions given.
        dims: [usize; 3],
        /// Product of the dimensions.
        expected: usize,
        /// Values supplied.
        actual: usize,
    },
    /// A spacing that is not finite and positive.
    #[error("invalid geometry: spacing {spacing:?} must be finite and positive")]
    Spacing {
        /// The spacing given.
        spacing: [f64; 3],
    },
    /// Plane heights that are not one per plane, finite and increasing.
    #[error("invalid geometry: {heights} plane heights for {planes} planes (they must be one per plane, finite and strictly increasing)")]
    Heights {
        /// Planes along z.
        planes: usize,
        /// Heights given.
        heights: usize,
    },
    /// An origin that is not finite.
    #[error("invalid geometry: origin {origin:?} must be finite")]
    Origin {
        /// The origin given.
        origin: [f64; 3],
    },
}

/// Values on a regular lattice: `dims[0] × dims[1] × dims[2]` points, `x` fastest.
///
/// The point `(i, j, k)` holds `values[i + dims[0] * (j + dims[1] * k)]` and sits at
/// `origin + (i, j, k) ⊙ spacing` in world coordinates.
///
/// ```
/// use isocube::field::Grid;
/// let g = Grid::from_fn([3, 3, 3], [0.5; 3], [-0.5; 3], |p| p[0] + p[1] + p[2]);
/// assert_eq!(g.value(2, 2, 2), 1.5);
/// assert_eq!(g.point(0, 0, 0), [-0.5, -0.5, -0.5]);
/// ```
#[derive(Clone, Debug)]
pub struct Grid {
    dims: [usize; 3],
    spacing: [f64; 3],
    origin: [f64; 3],
    values: Vec<f32>,
    /// The sample the values were computed from, while the grid is still exactly that.
    exact: Option<Sample>,
}

/// Grids are equal when their points and values are: how the values were made does not count.
impl PartialEq for Grid {
    fn eq(&self, other: &Grid) -> bool {
        self.dims == other.dims
            && self.spacing == other.spacing
            && self.origin == other.origin
            && self.values == other.values
    }
}

impl Grid {
    /// A grid with unit spacing at the origin. `values.len()` must equal the product of `dims`,
    /// and every dimension must be at least 2.
    pub fn new(dims: [usize; 3], values: Vec<f32>) -> Result<Grid, GridError> {
        let expected = Self::point_count(dims)?;
        if values.len() != expected {
            return Err(GridError::ValueCount {
                dims,
                expected,
                actual: values.len(),
            });
        }
        Ok(Grid {
            dims,
            spacing: [1.0; 3],
            origin: [0.0; 3],
            values,
            exact: None,
        })
    }

    /// Checks dimensions and returns the number of points.
    pub fn point_count(dims: [usize; 3]) -> Result<usize, GridError> {
        if dims.iter().any(|&d| d < 2) {
            return Err(GridError::TooSmall { dims });
        }
        dims.iter()
            .try_fold(1usize, |acc, &d| acc.checked_mul(d))
            .ok_or(GridError::Overflow { dims })
    }

    /// Sets the spacing (each finite and positive).
    pub fn with_spacing(mut self, spacing: [f64; 3]) -> Result<Grid, GridError> {
        if spacing.iter().any(|s| !s.is_finite() || *s <= 0.0) {
            return Err(GridError::Spacing { spacing });
        }
        self.spacing = spacing;
        self.exact = None;
        Ok(self)
    }

    /// Sets the origin (finite).
    pub fn with_origin(mut self, origin: [f64; 3]) -> Result<Grid, GridError> {
        if origin.iter().any(|o| !o.is_finite()) {
            return Err(GridError::Origin { origin });
        }
        self.origin = origin;
        self.exact = None;
        Ok(self)
    }

    /// Every value of a volume read plane by plane ([`PlaneSource`]: a mapped file, a stream
    /// inflated as it goes, a chunked store), in the order the source walks it, with its spacing
    /// and origin; its orientation stays the source's to give. The grid is the frame slab-wise
    /// extraction meshes the source in, so whole-volume work on it (ternary snapping, relaxation,
    /// boxes of cells) makes the mesh [`crate::extract::extract_streamed`] makes, to the bit.
    /// Planes are asked for in order, a few at a time, and released once read
    /// ([`PlaneSource::release_before`]): a stream need not go back, nor a reader hold what it
    /// decoded beside the grid.
    ///
    /// ```
    /// use isocube::field::{Grid, Sample};
    /// let sample = Sample::Gyroid.grid(9);
    /// assert_eq!(Grid::from_source(&sample).unwrap(), sample);
    /// ```
    pub fn from_source(source: &dyn PlaneSource) -> Result<Grid, GridError> {
        let dims = source.dims();
        let count = Self::point_count(dims)?;
        let mut values = vec![0.0f32; count];
        let plane = dims[0] * dims[1];
        let batch = ((1 << 22) / plane).max(1);
        for (n, out) in values.chunks_mut(plane * batch).enumerate() {
            source.read_planes(n * batch, out);
            source.release_before(((n + 1) * batch).min(dims[2]));
        }
        Grid::new(dims, values)?
            .with_spacing(source.spacing())?
            .with_origin(source.origin())
    }

    /// Samples `f` at every point. Panics if some dimension is below 2 or spacing is not
    /// positive (use [`Grid::new`] for checked construction).
    pub fn from_fn(
        dims: [usize; 3],
        spacing: [f64; 3],
        origin: [f64; 3],
        f: impl Fn([f64; 3]) -> f64,
    ) -> Grid {
        let n = Self::point_count(dims).expect("valid dimensions");
        let mut values = Vec::with_capacity(n);
        for k in 0..dims[2] {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    let p = [
                        origin[0] + i as f64 * spacing[0],
                        origin[1] + j as f64 * spacing[1],
                        origin[2] + k as f64 * spacing[2],
                    ];
                    values.push(f(p) as f32);
                }
            }
        }
        Grid::new(dims, values)
            .and_then(|g| g.with_spacing(spacing))
            .and_then(|g| g.with_origin(origin))
            .expect("valid grid")
    }

    /// Points along x, y and z.
    pub fn dims(&self) -> [usize; 3] {
        self.dims
    }

    /// Distance between neighbouring points along each axis.
    pub fn spacing(&self) -> [f64; 3] {
        self.spacing
    }

    /// World position of point (0, 0, 0).
    pub fn origin(&self) -> [f64; 3] {
        self.origin
    }

    /// All values, `x` fastest.
    pub fn values(&self) -> &[f32] {
        &self.values
    }

    /// Mutable access to the values (the dimensions stay fixed).
    pub fn values_mut(&mut self) -> &mut [f32] {
        self.exact = None;
        &mut self.values
    }

    /// Takes the values out.
    pub fn into_values(self) -> Vec<f32> {
        self.values
    }

    /// Linear index of point (i, j, k).
    #[inline]
    pub fn index(&self, i: usize, j: usize, k: usize) -> usize {
        i + self.dims[0] * (j + self.dims[1] * k)
    }

    /// Value at point (i, j, k).
    #[inline]
    pub fn value(&self, i: usize, j: usize, k: usize) -> f32 {
        self.values[self.index(i, j, k)]
    }

    /// World position of point (i, j, k).
    #[inline]
    pub fn point(&self, i: usize, j: usize, k: usize) -> [f64; 3] {
        self.view().point(i, j, k)
    }

    /// Number of cells (`(nx−1)(ny−1)(nz−1)`).
    pub fn cell_count(&self) -> usize {
        self.view().cell_count()
    }

    /// The same trilinear field sampled `k` times finer along each axis: `(n − 1)·k + 1` points
    /// per axis, spacing divided by `k`, values interpolated trilinearly within each cell (so the
    /// original points keep their values). Used to find the true topology of the trilinear
    /// interpolant, and to upsample coarse data.
    ///
    /// ```
    /// use isocube::field::Grid;
    /// let g = Grid::new([2, 2, 2], vec![0.0, 1.0, 0.0, 1.0, 0.0, 1.0, 0.0, 1.0]).unwrap();
    /// let fine = g.upsample(4);
    /// assert_eq!(fine.dims(), [5, 5, 5]);
    /// assert_eq!(fine.value(1, 3, 2), 0.25);
    /// ```
    pub fn upsample(&self, k: usize) -> Grid {
        let k = k.max(1);
        let dims = self.dims.map(|n| (n - 1) * k + 1);
        let mut values = Vec::with_capacity(dims.iter().product());
        let split = |i: usize, n: usize| -> (usize, f64) {
            let cell = (i / k).min(n - 2);
            (cell, (i - cell * k) as f64 / k as f64)
        };
        for z in 0..dims[2] {
            let (ck, tz) = split(z, self.dims[2]);
            for y in 0..dims[1] {
                let (cj, ty) = split(y, self.dims[1]);
                for x in 0..dims[0] {
                    let (ci, tx) = split(x, self.dims[0]);
                    let v = |di: usize, dj: usize, dk: usize| {
                        f64::from(self.value(ci + di, cj + dj, ck + dk))
                    };
                    // Exact at both ends, so grid points keep their values bit for bit.
                    let lerp = |a: f64, b: f64, t: f64| a * (1.0 - t) + b * t;
                    let x00 = lerp(v(0, 0, 0), v(1, 0, 0), tx);
                    let x10 = lerp(v(0, 1, 0), v(1, 1, 0), tx);
                    let x01 = lerp(v(0, 0, 1), v(1, 0, 1), tx);
                    let x11 = lerp(v(0, 1, 1), v(1, 1, 1), tx);
                    let value = lerp(lerp(x00, x10, ty), lerp(x01, x11, ty), tz);
                    values.push(value as f32);
                }
            }
        }
        Grid {
            dims,
            spacing: self.spacing.map(|h| h / k as f64),
            origin: self.origin,
            values,
            exact: None,
        }
    }

    /// The grid as a borrowed view (what every extraction entry point takes).
    #[inline]
    pub fn view(&self) -> GridView<'_> {
        let view = GridView::planes(&self.values, self.dims, self.spacing, self.origin, None);
        match self.exact {
            Some(sample) => view.with_exact(sample),
            None => view,
        }
    }

    /// Marks the values as computed from `sample` at these points, so relaxation follows its
    /// exact function.
    pub(crate) fn with_exact(mut self, sample: Sample) -> Grid {
        self.exact = Some(sample);
        self
    }

    /// The built-in sample the values were computed from, if the grid is still exactly that.
    pub fn exact(&self) -> Option<Sample> {
        self.exact
    }

    /// Smallest and largest finite value, if any value is finite.
    pub fn finite_range(&self) -> Option<(f32, f32)> {
        self.values
            .iter()
            .filter(|v| v.is_finite())
            .fold(None, |acc, &v| match acc {
                None => Some((v, v)),
                Some((lo, hi)) => Some((lo.min(v), hi.max(v))),
            })
    }
}
