//! Volumes read plane by plane, for extraction from data larger than memory.

use super::{Grid, Orientation};

/// A volume that hands out its values a few `z` planes at a time: a memory-mapped file
/// (`io::MappedVolume`) or a [`Grid`]. Slab-wise extraction
/// ([`crate::extract::extract_streamed`]) asks each slab's planes of it when the slab is
/// meshed, so the whole volume never has to be in memory as `f32`.
///
/// Implementations check everything (sizes, types) when they are made: reading planes cannot
/// fail.
pub trait PlaneSource: Sync {
    /// Points along x, y and z (each at least 2).
    fn dims(&self) -> [usize; 3];
    /// Distance between neighbouring points along each axis.
    fn spacing(&self) -> [f64; 3];
    /// World position of point (0, 0, 0).
    fn origin(&self) -> [f64; 3];
    /// How the grid's axes lie in the world (see [`Orientation`]); the mesh is made in the
    /// grid's frame and turned into the world's.
    fn orientation(&self) -> Orientation {
        Orientation::IDENTITY
    }
    /// Writes the values of planes `first, first + 1, …` into `out`, `x` fastest; `out.len()` is
    /// a whole number of planes, all within the volume.
    fn read_planes(&self, first: usize, out: &mut [f32]);
    /// A hint that planes below `plane` will not be asked for again (a mapped file lets the
    /// system drop their pages).
    fn release_before(&self, _plane: usize) {}
}

impl PlaneSource for Grid {
    fn dims(&self) -> [usize; 3] {
        Grid::dims(self)
    }

    fn spacing(&self) -> [f64; 3] {
        Grid::spacing(self)
    }

    fn origin(&self) -> [f64; 3] {
        Grid::origin(self)
    }

    fn read_planes(&self, first: usize, out: &mut [f32]) {
        let start = self.index(0, 0, first);
        out.copy_from_slice(&self.values()[start..start + out.len()]);
    }
}
