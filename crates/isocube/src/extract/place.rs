//! Vertex placement: linear interpolation of the crossing on a grid edge, normals from the
//! interpolated central-difference gradient.

use crate::cube::{EDGES, EDGE_AXIS, VERTICES};
use crate::mesh::Mesh;

use super::window::Window;
use super::{ExtractError, ExtractOptions};

pub(super) struct Placer<'a> {
    grid: Window<'a>,
    level: f64,
    normals: bool,
    flip: bool,
    /// Twice the spacing per axis, on a grid whose planes are evenly spaced: the central
    /// difference's denominator (`below + above` of [`Placer::gradient`], the same bits).
    twice_spacing: Option<[f64; 3]>,
}

impl<'a> Placer<'a> {
    /// Whether vertices get normals.
    pub(super) fn normals(&self) -> bool {
        self.normals
    }

    pub(super) fn new(grid: Window<'a>, options: &ExtractOptions) -> Placer<'a> {
        Placer {
            grid,
            level: f64::from(options.level),
            normals: options.normals,
            flip: options.flip,
            twice_spacing: grid.is_uniform().then(|| grid.spacing().map(|h| h + h)),
        }
    }

    /// Creates the vertex where the surface crosses edge `e` of cell `cell`, from the cell's eight
    /// values (cube vertex order).
    #[inline]
    pub(super) fn edge_vertex_of(
        &self,
        cell: [usize; 3],
        v: &[f32; 8],
        e: u8,
        mesh: &mut Mesh,
    ) -> Result<u32, ExtractError> {
        let [a, b] = EDGES[usize::from(e)];
        let off = VERTICES[usize::from(a)];
        let p0 = [0, 1, 2].map(|d| cell[d] + usize::from(off[d]));
        let axis = usize::from(EDGE_AXIS[usize::from(e)]);
        let (v0, v1) = (f64::from(v[usize::from(a)]), f64::from(v[usize::from(b)]));
        // One end is at or above the level and the other below, so v1 ≠ v0.
        let t = ((self.level - v0) / (v1 - v0)).clamp(0.0, 1.0);
        self.vertex_on_edge(p0, axis, t, mesh)
    }

    /// The position at fraction `t` along the grid edge from `p0` along `axis`.
    pub(super) fn edge_point(&self, p0: [usize; 3], axis: usize, t: f64) -> [f32; 3] {
        self.grid.edge_point(p0, axis, t).map(|c| c as f32)
    }

    /// Creates the vertex at fraction `t` along the grid edge from `p0` along `axis`.
    pub(super) fn vertex_on_edge(
        &self,
        p0: [usize; 3],
        axis: usize,
        t: f64,
        mesh: &mut Mesh,
    ) -> Result<u32, ExtractError> {
        let id = next_id(mesh)?;
        mesh.positions.push(self.edge_point(p0, axis, t));
        if self.normals {
            let mut p1 = p0;
            p1[axis] += 1;
            let g0 = self.gradient(p0);
            let g1 = self.gradient(p1);
            let mut g = [0, 1, 2].map(|d| g0[d] + t * (g1[d] - g0[d]));
            if g.iter().all(|&c| c == 0.0) {
                // A flat spot: the edge itself, toward its higher end, is the best guess.
                let v0 = f64::from(self.grid.value(p0[0], p0[1], p0[2]));
                let v1 = f64::from(self.grid.value(p1[0], p1[1], p1[2]));
                g = [0.0; 3];
                g[axis] = if v1 >= v0 { 1.0 } else { -1.0 };
            }
            mesh.normals.push(self.unit(g));
        }
        Ok(id)
    }

    /// Creates a vertex on grid point `p` (a snapped vertex of ternary extraction).
    pub(super) fn point_vertex(&self, p: [usize; 3], mesh: &mut Mesh) -> Result<u32, ExtractError> {
        let id = next_id(mesh)?;
        mesh.positions
            .push(self.grid.point(p[0], p[1], p[2]).map(|c| c as f32));
        if self.normals {
            let g = self.gradient(p);
            mesh.normals.push(if g.iter().all(|&c| c == 0.0) {
                [0.0; 3]
            } else {
                self.unit(g)
            });
        }
        Ok(id)
    }

    /// Creates a vertex at the centroid of existing vertices (a cell's interior point), kept
    /// within `bounds` (see [`interior_bounds`]).
    pub(super) fn centroid_vertex(
        &self,
        ids: &[u32],
        bounds: &Bounds,
        mesh: &mut Mesh,
    ) -> Result<u32, ExtractError> {
        let p = centroid_in(ids.iter().map(|&v| mesh.positions[v as usize]), bounds);
        self.interior_vertex(p, ids, mesh)
    }

    /// Creates a vertex at `p` inside a cell, its normal the mean of the normals of `ids`.
    pub(super) fn interior_vertex(
        &self,
        p: [f64; 3],
        ids: &[u32],
        mesh: &mut Mesh,
    ) -> Result<u32, ExtractError> {
        let id = next_id(mesh)?;
        mesh.positions.push(p.map(|c| c as f32));
        if self.normals {
            let mut g = [0.0f64; 3];
            for &v in ids {
                for (c, x) in g.iter_mut().zip(mesh.normals[v as usize]) {
                    *c += f64::from(x);
                }
            }
            // Normals of the corners already carry the flip.
            let len = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt();
            mesh.normals.push(if len > 0.0 {
                g.map(|c| unsigned_zero((c / len) as f32))
            } else {
                [0.0; 3]
            });
        }
        Ok(id)
    }

    fn unit(&self, g: [f64; 3]) -> [f32; 3] {
        let len = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt();
        let s = if self.flip { -1.0 / len } else { 1.0 / len };
        g.map(|c| unsigned_zero((c * s) as f32))
    }

    /// Central differences in world units; one-sided at the grid boundary or next to a
    /// non-finite value.
    #[inline]
    fn gradient(&self, p: [usize; 3]) -> [f64; 3] {
        let dims = self.grid.dims();
        // Most points: inside the grid, six finite neighbours, even planes. Read directly;
        // the general case below gives the same bits for them.
        if let Some(twice) = self.twice_spacing {
            if (0..3).all(|d| p[d] > 0 && p[d] + 1 < dims[d]) {
                let values = self.grid.values();
                let [sx, sy, sz] = self.grid.strides();
                let c = self.grid.index(p[0], p[1], p[2]);
                let n = [
                    values[c - sx],
                    values[c + sx],
                    values[c - sy],
                    values[c + sy],
                    values[c - sz],
                    values[c + sz],
                ];
                if n.iter().all(|v| v.is_finite()) {
                    let d = |a: usize| (f64::from(n[2 * a + 1]) - f64::from(n[2 * a])) / twice[a];
                    return [d(0), d(1), d(2)];
                }
            }
        }
        self.gradient_anywhere(p)
    }

    /// [`Placer::gradient`] at any point: one-sided differences where a neighbour is missing
    /// or not finite, uneven planes.
    #[inline(never)]
    fn gradient_anywhere(&self, p: [usize; 3]) -> [f64; 3] {
        let dims = self.grid.dims();
        let at = |q: [usize; 3]| f64::from(self.grid.value(q[0], q[1], q[2]));
        let centre = at(p);
        // A plain loop, not `array::map`: this runs for every vertex, and the closures of a map
        // were not always inlined.
        let mut g = [0.0f64; 3];
        for d in 0..3 {
            let mut before = None;
            if p[d] > 0 {
                let mut q = p;
                q[d] -= 1;
                before = Some(at(q)).filter(|v| v.is_finite());
            }
            let mut after = None;
            if p[d] + 1 < dims[d] {
                let mut q = p;
                q[d] += 1;
                after = Some(at(q)).filter(|v| v.is_finite());
            }
            // Uneven planes: the distances on each side (equal on a regular grid, where this is
            // the usual central difference).
            let below = || {
                let mut q = p;
                q[d] -= 1;
                self.grid.edge_length(q, d)
            };
            let above = || self.grid.edge_length(p, d);
            g[d] = match (before, after) {
                (Some(a), Some(b)) => (b - a) / (below() + above()),
                (None, Some(b)) => (b - centre) / above(),
                (Some(a), None) => (centre - a) / below(),
                (None, None) => 0.0,
            };
        }
        g
    }
}

fn next_id(mesh: &Mesh) -> Result<u32, ExtractError> {
    match u32::try_from(mesh.positions.len()) {
        Ok(id) if id != u32::MAX => Ok(id),
        _ => Err(ExtractError::TooManyVertices),
    }
}

/// A box, lower and upper corner, in the grid's own frame.
pub(super) type Bounds = ([f64; 3], [f64; 3]);

/// The box a cell's interior vertices keep to: the cell between grid points `a` and `b` shrunk
/// by a hundredth of its size per side. A vertex in a face would lie in the neighbouring cell's
/// face too, where that cell's surface does not expect it: two surface edges could cross there
/// (the centroid of two crossings on one face lies in that face), and the region inside could
/// not be tetrahedralised around it.
pub(super) fn interior_bounds(a: [f64; 3], b: [f64; 3]) -> Bounds {
    let margin = |d: usize| 0.01 * (b[d] - a[d]).abs();
    (
        std::array::from_fn(|d| a[d].min(b[d]) + margin(d)),
        std::array::from_fn(|d| a[d].max(b[d]) - margin(d)),
    )
}

/// `p` moved into `bounds`, coordinate by coordinate.
/// The centroid of `points` kept within `bounds`: where [`Placer::centroid_vertex`] puts an
/// interior point (before it is stored as `f32`). Callers that predict a position use this so
/// their prediction is the stored one, bit for bit.
pub(super) fn centroid_in(
    points: impl ExactSizeIterator<Item = [f32; 3]>,
    bounds: &Bounds,
) -> [f64; 3] {
    let n = points.len() as f64;
    let mut p = [0.0f64; 3];
    for q in points {
        for (c, x) in p.iter_mut().zip(q) {
            *c += f64::from(x) / n;
        }
    }
    clamp_into(p, bounds)
}

pub(super) fn clamp_into(p: [f64; 3], (lo, hi): &Bounds) -> [f64; 3] {
    std::array::from_fn(|d| p[d].clamp(lo[d], hi[d]))
}

/// `x`, with a zero always `+0.0`. A normal component is zero where the gradient is flat along
/// an axis, and its sign then depends on how the values' zeros were signed (`-0.0` in a float
/// file, `0` in an integer one) and on the order of the sums: the same field must give the same
/// bytes, so zeros leave without a sign.
#[inline(always)]
pub(crate) fn unsigned_zero(x: f32) -> f32 {
    // IEEE addition: −0 + +0 = +0, and every other value is unchanged.
    x + 0.0
}
