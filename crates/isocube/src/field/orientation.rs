//! Grid axes that are not the world's: the direction matrix of medical and microscopy volumes.

use crate::mesh::Mesh;

use super::Grid;

/// How a grid's axes lie in the world: column `a` of `direction` is the unit world vector of
/// grid axis `a`. A grid point `(i, j, k)` sits at
/// `origin + direction · (spacing_x i, spacing_y j, spacing_z k)`.
///
/// Extraction works in the grid's own frame (axes along x, y, z, with its spacing and origin);
/// [`Orientation::orient_mesh`] then turns the mesh into world coordinates. A direction with a
/// negative determinant (a reflection, as in many radiological files) reverses the triangles'
/// winding so that fronts still face increasing values.
///
/// ```
/// use isocube::field::Orientation;
/// use isocube::mesh::Mesh;
/// // Grid x along world y, grid y along world −x.
/// let o = Orientation::new([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]).unwrap();
/// let mut mesh = Mesh::new();
/// mesh.positions.push([2.0, 0.0, 0.0]);
/// o.orient_mesh(&mut mesh, [1.0, 0.0, 0.0]);
/// assert_eq!(mesh.positions[0], [1.0, 1.0, 0.0]);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Orientation {
    direction: [[f64; 3]; 3],
}

impl Default for Orientation {
    fn default() -> Self {
        Orientation::IDENTITY
    }
}

impl Orientation {
    /// Grid axes along world x, y, z.
    pub const IDENTITY: Orientation = Orientation {
        direction: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
    };

    /// A direction matrix (rows of a row-major 3 × 3 matrix whose columns are the axes). Each
    /// column is scaled to unit length; `None` when the matrix is not finite or singular.
    pub fn new(direction: [[f64; 3]; 3]) -> Option<Orientation> {
        let mut d = direction;
        for a in 0..3 {
            let len = (0..3).map(|r| d[r][a] * d[r][a]).sum::<f64>().sqrt();
            if !len.is_finite() || len == 0.0 {
                return None;
            }
            for row in d.iter_mut() {
                row[a] /= len;
            }
        }
        let o = Orientation { direction: d };
        (o.determinant().abs() > 1e-9).then_some(o)
    }

    /// Grid axis `a` along world axis `axes[a]`: a grid whose axes are the world's in another
    /// order (a permutation of 0, 1, 2; `None` otherwise). Meshing an array in its memory
    /// order and writing world coordinates uses this.
    ///
    /// ```
    /// use isocube::field::Orientation;
    /// let o = Orientation::axes([2, 1, 0]).unwrap();
    /// assert_eq!(o.direction(), [[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]]);
    /// assert!(o.determinant() < 0.0);
    /// ```
    pub fn axes(axes: [usize; 3]) -> Option<Orientation> {
        if axes.iter().any(|&a| a > 2)
            || axes[0] == axes[1]
            || axes[1] == axes[2]
            || axes[0] == axes[2]
        {
            return None;
        }
        let direction =
            std::array::from_fn(|r| std::array::from_fn(|a| f64::from(u8::from(axes[a] == r))));
        Some(Orientation { direction })
    }

    /// Splits an index-to-world linear map (rows of a 3 × 3 matrix, columns the axis steps) into
    /// its spacing (column lengths) and orientation.
    pub fn from_linear(linear: [[f64; 3]; 3]) -> Option<([f64; 3], Orientation)> {
        let spacing: [f64; 3] = std::array::from_fn(|a| {
            (0..3)
                .map(|r| linear[r][a] * linear[r][a])
                .sum::<f64>()
                .sqrt()
        });
        Some((spacing, Orientation::new(linear)?))
    }

    /// The matrix: rows of a row-major 3 × 3 matrix whose columns are the grid axes.
    pub fn direction(&self) -> [[f64; 3]; 3] {
        self.direction
    }

    /// Whether the axes are the world's.
    pub fn is_identity(&self) -> bool {
        *self == Orientation::IDENTITY
    }

    /// The determinant: negative for a reflection.
    pub fn determinant(&self) -> f64 {
        let d = &self.direction;
        d[0][0] * (d[1][1] * d[2][2] - d[1][2] * d[2][1])
            - d[0][1] * (d[1][0] * d[2][2] - d[1][2] * d[2][0])
            + d[0][2] * (d[1][0] * d[2][1] - d[1][1] * d[2][0])
    }

    fn apply(&self, v: [f64; 3]) -> [f64; 3] {
        std::array::from_fn(|r| (0..3).map(|c| self.direction[r][c] * v[c]).sum())
    }

    fn inverse(&self) -> [[f64; 3]; 3] {
        let d = &self.direction;
        let det = self.determinant();
        let c = |r0: usize, c0: usize, r1: usize, c1: usize| {
            d[r0][c0] * d[r1][c1] - d[r0][c1] * d[r1][c0]
        };
        [
            [c(1, 1, 2, 2), -c(0, 1, 2, 2), c(0, 1, 1, 2)],
            [-c(1, 0, 2, 2), c(0, 0, 2, 2), -c(0, 0, 1, 2)],
            [c(1, 0, 2, 1), -c(0, 0, 2, 1), c(0, 0, 1, 1)],
        ]
        .map(|row| row.map(|x| x / det))
    }

    /// The world position of grid point `(i, j, k)`.
    pub fn world(&self, grid: &Grid, ijk: [f64; 3]) -> [f64; 3] {
        let (o, h) = (grid.origin(), grid.spacing());
        let v = self.apply(std::array::from_fn(|a| h[a] * ijk[a]));
        std::array::from_fn(|a| o[a] + v[a])
    }

    /// A world position in the grid's own frame (where [`Grid::point`] and the extractor work):
    /// the inverse of what [`Orientation::orient_mesh`] does, about `origin`.
    pub fn to_grid_frame(&self, p: [f64; 3], origin: [f64; 3]) -> [f64; 3] {
        let inv = self.inverse();
        let d: [f64; 3] = std::array::from_fn(|a| p[a] - origin[a]);
        std::array::from_fn(|r| origin[r] + (0..3).map(|c| inv[r][c] * d[c]).sum::<f64>())
    }

    /// Turns a mesh made in the grid's frame (about `origin`, the grid's origin) into world
    /// coordinates: positions turned about the origin, normals by the inverse transpose (so
    /// they stay normal to the surface), and the winding reversed under a reflection.
    pub fn orient_mesh(&self, mesh: &mut Mesh, origin: [f64; 3]) {
        self.orient_parts(
            &mut mesh.positions,
            &mut mesh.normals,
            &mut mesh.triangles,
            origin,
        );
    }

    /// [`Orientation::orient_mesh`] on a mesh's parts: a streamed piece is turned as it goes.
    pub fn orient_parts(
        &self,
        positions: &mut [[f32; 3]],
        normals: &mut [[f32; 3]],
        triangles: &mut [[u32; 3]],
        origin: [f64; 3],
    ) {
        if self.is_identity() {
            return;
        }
        for p in positions {
            let d: [f64; 3] = std::array::from_fn(|a| f64::from(p[a]) - origin[a]);
            let w = self.apply(d);
            *p = std::array::from_fn(|a| (origin[a] + w[a]) as f32);
        }
        let inv = self.inverse();
        for n in normals {
            let v: [f64; 3] =
                std::array::from_fn(|c| (0..3).map(|r| inv[r][c] * f64::from(n[r])).sum());
            let len = v.iter().map(|x| x * x).sum::<f64>().sqrt();
            if len > 0.0 {
                *n = v.map(|x| crate::extract::unsigned_zero((x / len) as f32));
            }
        }
        if self.determinant() < 0.0 {
            for t in triangles {
                t.swap(1, 2);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::extract::{extract, ExtractOptions};
    use crate::field::Sample;

    /// A reflected, rotated, sheared grid: the oriented mesh stays closed and outward (its
    /// enclosed volume positive) and the normals still point along increasing values.
    #[test]
    fn oriented_meshes_stay_outward_with_normals_across_the_surface() {
        let grid = Sample::Sphere
            .grid(20)
            .with_origin([1.0, 2.0, 3.0])
            .unwrap();
        let (base, _) = extract(&grid, &ExtractOptions::default()).unwrap();
        let volume = base.report().volume.unwrap();
        assert!(volume > 0.0);
        let (c, s) = (0.6f64, 0.8f64);
        for direction in [
            [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]],
            [[-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            [[1.0, 0.3, 0.0], [0.0, 1.0, 0.0], [0.0, 0.2, -1.0]],
        ] {
            let o = Orientation::new(direction).unwrap();
            let mut mesh = base.clone();
            o.orient_mesh(&mut mesh, grid.origin());
            let r = mesh.report();
            assert!(r.watertight && r.oriented);
            // Rotations and reflections keep the volume; the shear scales it by its determinant.
            let expected = volume * o.determinant().abs();
            let got = r.volume.unwrap();
            assert!(
                (got - expected).abs() < 1e-3 * expected,
                "{got} vs {expected}"
            );
            // Normals agree with the faces' orientation.
            let agree = mesh.triangles.iter().filter(|t| {
                let p = t.map(|i| mesh.positions[i as usize].map(f64::from));
                let n =
                    crate::mesh::cross(crate::mesh::sub(p[1], p[0]), crate::mesh::sub(p[2], p[0]));
                let m: [f64; 3] = std::array::from_fn(|a| {
                    t.iter()
                        .map(|&i| f64::from(mesh.normals[i as usize][a]))
                        .sum::<f64>()
                });
                crate::mesh::dot(n, m) > 0.0
            });
            assert_eq!(agree.count(), mesh.triangles.len());
            // Back to the grid frame.
            let p = mesh.positions[0].map(f64::from);
            let q = o.to_grid_frame(p, grid.origin());
            for (x, y) in q.iter().zip(base.positions[0]) {
                assert!((x - f64::from(y)).abs() < 1e-5);
            }
        }
        assert!(Orientation::new([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]]).is_none());
        assert!(
            Orientation::new([[f64::NAN, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]).is_none()
        );
    }
}
