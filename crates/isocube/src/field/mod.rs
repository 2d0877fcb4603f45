//! Scalar fields: sampled grids and the built-in sample functions.
//!
//! A [`Grid`] holds `f32` values at the points of a regular lattice, `x` varying fastest, then
//! `y`, then `z`, with a spacing and an origin giving world coordinates. [`Sample`] is a set of
//! implicit functions with default bounds, sampled with [`Sample::grid`] or parsed from the
//! command line's `sample:NAME:N[:SEED]`.

mod grid;
mod level;
mod orientation;
mod samples;
mod source;
mod view;

pub use grid::{Grid, GridError};
pub use level::{is_above, Level, ValueSummary};
pub use orientation::Orientation;
pub use samples::{sphere_packing, Ball, Sample, SampleSpec};
pub use source::PlaneSource;
pub use view::GridView;
