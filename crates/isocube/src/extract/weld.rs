//! Welding: each grid edge gets one vertex, shared by the up to four cells around it.
//!
//! Cells are visited layer by layer along z. A layer touches the x- and y-edges of two point
//! slices (its bottom and top) and the z-edges between them, so five `nx × ny` index arrays
//! suffice: when the layer is done the top slice becomes the next bottom.

use crate::cube::{EDGES, EDGE_AXIS, VERTICES};

use super::ExtractError;

const NONE: u32 = u32::MAX;

pub(super) struct EdgeCache {
    nx: usize,
    /// x-edges and y-edges of the bottom and top slices, z-edges of the layer.
    bottom: [Vec<u32>; 2],
    top: [Vec<u32>; 2],
    vertical: Vec<u32>,
}

impl EdgeCache {
    pub(super) fn new(nx: usize, ny: usize) -> EdgeCache {
        let n = nx * ny;
        EdgeCache {
            nx,
            bottom: [vec![NONE; n], vec![NONE; n]],
            top: [vec![NONE; n], vec![NONE; n]],
            vertical: vec![NONE; n],
        }
    }

    /// The vertex on edge `e` of cell `(i, j, ·)` of the current layer, created by `make` on
    /// first use.
    #[inline]
    pub(super) fn vertex(
        &mut self,
        i: usize,
        j: usize,
        e: u8,
        make: impl FnOnce() -> Result<u32, ExtractError>,
    ) -> Result<u32, ExtractError> {
        let start = VERTICES[usize::from(EDGES[usize::from(e)][0])];
        let index = i + usize::from(start[0]) + self.nx * (j + usize::from(start[1]));
        let slot = match EDGE_AXIS[usize::from(e)] {
            2 => &mut self.vertical[index],
            axis => {
                let slice = if start[2] == 0 {
                    &mut self.bottom
                } else {
                    &mut self.top
                };
                &mut slice[usize::from(axis)][index]
            }
        };
        if *slot == NONE {
            *slot = make()?;
        }
        Ok(*slot)
    }

    pub(super) fn next_layer(&mut self) {
        std::mem::swap(&mut self.bottom, &mut self.top);
        for a in &mut self.top {
            a.fill(NONE);
        }
        self.vertical.fill(NONE);
    }
}
