//! Welding: each grid edge gets one vertex, shared by the up to four cells around it.
//!
//! Cells of a box are visited layer by layer along z. A layer touches the x- and y-edges of two
//! point slices (its bottom and top) and the z-edges between them, so five `nx × ny` index arrays
//! (the box's points per plane) suffice: when the layer is done the top slice becomes the next
//! bottom. Cells are named here by their place in the box.

use crate::cube::{EDGES, EDGE_AXIS, VERTICES};

use super::ExtractError;

const NONE: u32 = u32::MAX;

pub(super) struct EdgeCache {
    nx: usize,
    ny: usize,
    /// x-edges and y-edges of the bottom and top slices, z-edges of the layer.
    bottom: [Vec<u32>; 2],
    top: [Vec<u32>; 2],
    vertical: Vec<u32>,
    /// Slots set in each (`axis · nx · ny + index`, index alone for vertical), in the order
    /// they were set: clearing costs what was used, not the slice.
    bottom_set: Vec<u32>,
    top_set: Vec<u32>,
    vertical_set: Vec<u32>,
}

impl EdgeCache {
    pub(super) fn new(nx: usize, ny: usize) -> EdgeCache {
        let n = nx * ny;
        EdgeCache {
            nx,
            ny,
            bottom: [vec![NONE; n], vec![NONE; n]],
            top: [vec![NONE; n], vec![NONE; n]],
            vertical: vec![NONE; n],
            bottom_set: Vec::new(),
            top_set: Vec::new(),
            vertical_set: Vec::new(),
        }
    }

    /// The vertex on edge `e` of the box's cell `(i, j, ·)` of the current layer, created by
    /// `make` on first use.
    #[inline(always)]
    pub(super) fn vertex(
        &mut self,
        i: usize,
        j: usize,
        e: u8,
        make: impl FnOnce() -> Result<u32, ExtractError>,
    ) -> Result<u32, ExtractError> {
        let start = VERTICES[usize::from(EDGES[usize::from(e)][0])];
        let index = i + usize::from(start[0]) + self.nx * (j + usize::from(start[1]));
        let plane = self.nx * self.ny;
        let (slot, set, key) = match EDGE_AXIS[usize::from(e)] {
            2 => (&mut self.vertical[index], &mut self.vertical_set, index),
            axis => {
                let (slice, set) = if start[2] == 0 {
                    (&mut self.bottom, &mut self.bottom_set)
                } else {
                    (&mut self.top, &mut self.top_set)
                };
                let a = usize::from(axis);
                (&mut slice[a][index], set, a * plane + index)
            }
        };
        if *slot == NONE {
            *slot = make()?;
            set.push(key as u32);
        }
        Ok(*slot)
    }

    /// Ready for a box of `nx × ny` points per plane, every vertex forgotten (the slices are
    /// made again only when the size changes).
    pub(super) fn prepare(&mut self, nx: usize, ny: usize) {
        if (nx, ny) == (self.nx, self.ny) {
            self.reset();
        } else {
            *self = EdgeCache::new(nx, ny);
        }
    }

    /// Forgets every vertex (as new, without touching the whole slices).
    pub(super) fn reset(&mut self) {
        self.next_layer();
        self.next_layer();
    }

    pub(super) fn next_layer(&mut self) {
        let plane = self.nx * self.ny;
        std::mem::swap(&mut self.bottom, &mut self.top);
        std::mem::swap(&mut self.bottom_set, &mut self.top_set);
        for &key in &self.top_set {
            let k = key as usize;
            self.top[k / plane][k % plane] = NONE;
        }
        self.top_set.clear();
        for &k in &self.vertical_set {
            self.vertical[k as usize] = NONE;
        }
        self.vertical_set.clear();
    }
}
