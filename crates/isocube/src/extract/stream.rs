//! Slab-wise extraction for volumes larger than memory: planes read from a [`PlaneSource`] a
//! batch of slabs at a time, slabs meshed in parallel, and the mesh handed to a [`MeshSink`] in
//! order, slab by slab. Memory holds a batch of slabs and their meshes, never the volume; the
//! vertices and triangles are the ones [`super::extract`] makes on the same grid, in the same
//! order, to the bit.

use std::convert::Infallible;

use rayon::prelude::*;
use thiserror::Error;

use super::binary::{slabs, BinaryCells};
use super::chunk::{ChunkMesh, LayerJoiner};
use super::weld::EdgeCache;
use super::window::Window;
use super::CellBox;
use super::{ExtractError, ExtractOptions, ExtractStats, Method};
use std::ops::ControlFlow;

use crate::field::{Grid, PlaneSource};
use crate::mesh::Mesh;

/// Volumes whose values take more than this many bytes as `f32` are better meshed slab by slab
/// ([`extract_streamed`]) than loaded whole, when the options allow it ([`streams_by_default`]).
pub const STREAM_ABOVE_BYTES: u64 = 1 << 30;

/// Whether a volume of `dims` points is best meshed slab by slab with `options`: its values take
/// more than [`STREAM_ABOVE_BYTES`] as `f32`, and the options need neither the whole volume
/// (ternary snapping) nor the whole mesh (relaxation).
///
/// ```
/// use isocube::extract::{streams_by_default, ExtractOptions};
/// assert!(streams_by_default([1024, 1024, 512], &ExtractOptions::default()));
/// assert!(!streams_by_default([512, 512, 512], &ExtractOptions::default()));
/// assert!(!streams_by_default([1024, 1024, 512], &ExtractOptions::default().with_relax(2)));
/// ```
pub fn streams_by_default(dims: [usize; 3], options: &ExtractOptions) -> bool {
    let points: u64 = dims.iter().map(|&d| d as u64).product();
    options.method == Method::MarchingCubes
        && options.relax == 0
        && points.saturating_mul(4) > STREAM_ABOVE_BYTES
}

/// Where [`extract_streamed`] puts the mesh: vertices and triangles in order, a slab at a time.
///
/// Vertices are numbered in the order they are given, from 0; triangles only use vertices
/// given before them.
pub trait MeshSink {
    /// Why the sink failed (a write error, for a file).
    type Error;
    /// New vertices; `normals` is empty or as long as `positions`.
    fn vertices(&mut self, positions: &[[f32; 3]], normals: &[[f32; 3]])
        -> Result<(), Self::Error>;
    /// Triangles over the vertices given so far.
    fn triangles(&mut self, triangles: &[[u32; 3]]) -> Result<(), Self::Error>;
    /// A hint that about this many more vertices and triangles will come (projected from the
    /// slabs done so far). A sink that gathers the mesh in memory makes room, so that its
    /// arrays are not copied again and again as they grow; the default does nothing.
    fn reserve(&mut self, vertices: usize, triangles: usize) {
        let _ = (vertices, triangles);
    }
}

/// Collects the whole mesh in memory.
impl MeshSink for Mesh {
    type Error = Infallible;

    fn vertices(&mut self, positions: &[[f32; 3]], normals: &[[f32; 3]]) -> Result<(), Infallible> {
        self.positions.extend_from_slice(positions);
        self.normals.extend_from_slice(normals);
        Ok(())
    }

    fn triangles(&mut self, triangles: &[[u32; 3]]) -> Result<(), Infallible> {
        self.triangles.extend_from_slice(triangles);
        Ok(())
    }

    /// Room reserved is not memory used until it is written, so a projection that comes out
    /// high costs address space only.
    fn reserve(&mut self, vertices: usize, triangles: usize) {
        self.positions.reserve_exact(vertices);
        if !self.normals.is_empty() {
            self.normals.reserve_exact(vertices);
        }
        self.triangles.reserve_exact(triangles);
    }
}

/// Why [`extract_streamed`] failed.
#[derive(Debug, Error)]
pub enum StreamError<E> {
    /// The extraction itself (options, too many vertices).
    #[error(transparent)]
    Extract(#[from] ExtractError),
    /// The sink refused the mesh.
    #[error("{0}")]
    Sink(E),
}

/// Extracts the isosurface slab by slab from `source` into `sink`, calling `progress(done,
/// total)` per slab of cell layers.
///
/// Binary Marching Cubes only (MC33 or classic, any [`crate::quality::Strategy`], normals or
/// not): ternary extraction and relaxation need the whole volume and are refused. The output is
/// exactly what [`super::extract`] makes from the same values.
///
/// ```
/// use isocube::extract::{extract, extract_streamed, ExtractOptions};
/// use isocube::field::Sample;
/// use isocube::mesh::Mesh;
/// let grid = Sample::Tangle.grid(30);
/// let options = ExtractOptions::default();
/// let mut streamed = Mesh::new();
/// extract_streamed(&grid, &options, &mut streamed, &mut isocube::no_progress).unwrap();
/// assert_eq!(streamed, extract(&grid, &options).unwrap().0);
/// ```
pub fn extract_streamed<S: MeshSink>(
    source: &dyn PlaneSource,
    options: &ExtractOptions,
    sink: &mut S,
    progress: &mut dyn FnMut(usize, usize) -> ControlFlow<()>,
) -> Result<ExtractStats, StreamError<S::Error>> {
    if !options.level.is_finite() {
        return Err(ExtractError::Level(options.level).into());
    }
    if options.method != Method::MarchingCubes || options.relax > 0 {
        return Err(ExtractError::WholeVolume.into());
    }
    let dims = source.dims();
    Grid::point_count(dims).map_err(ExtractError::Grid)?;
    let (spacing, origin) = (source.spacing(), source.origin());
    let orientation = source.orientation();
    let [nx, ny, nz] = dims;
    let boxes = slabs(dims);
    // Slabs in flight: enough to keep every core busy; memory is this many windows and meshes.
    let batch = (2 * rayon::current_num_threads()).max(2);
    let mut states: Vec<(EdgeCache, Vec<f32>)> = (0..batch.min(boxes.len()))
        .map(|_| (EdgeCache::new(0, 0), Vec::new()))
        .collect();
    let mut joiner = LayerJoiner::new(dims);
    let mut stats = ExtractStats::default();
    let mesh_group = |states: &mut [(EdgeCache, Vec<f32>)], group: &[CellBox]| {
        states[..group.len()]
            .par_iter_mut()
            .zip(group)
            .map(|((cache, buffer), &cells)| {
                // One plane beyond the cells on each side, for the normals' differences.
                let p0 = cells.min[2].saturating_sub(1);
                let p1 = (cells.max[2] + 1).min(nz - 1);
                buffer.resize((p1 + 1 - p0) * nx * ny, 0.0);
                source.read_planes(p0, buffer);
                let window = Window::new(dims, spacing, origin, None, p0, buffer);
                BinaryCells::new(window, options).mesh_box(cache, cells)
            })
            .collect::<Vec<Result<ChunkMesh, ExtractError>>>()
    };
    // A batch's parts are joined and handed to the sink (in order, on this thread) while the
    // next batch is meshed: the joining is serial, and would otherwise leave cores idle.
    let (mut vertices, mut triangles) = (0usize, 0usize);
    let mut groups = boxes.chunks(batch);
    let mut meshed = groups.next().map(|group| mesh_group(&mut states, group));
    while let Some(parts) = meshed.take() {
        let next = groups.next();
        if let Some(done) = parts.iter().flatten().map(|p| p.cells.max[2]).max() {
            // The next batch reads from the plane below its cells, the last batch's top.
            source.release_before(done.saturating_sub(1));
        }
        let mut pushed: Result<(), StreamError<S::Error>> = Ok(());
        rayon::in_place_scope(|scope| {
            if let Some(group) = next {
                let (states, out) = (&mut states, &mut meshed);
                scope.spawn(move |_| *out = Some(mesh_group(states, group)));
            }
            pushed = (|| {
                for part in parts {
                    let part = part?;
                    // As extraction in memory does; the vertices concerned are inside one
                    // cell, so the part holds all their triangles.
                    let filled = part.mesh.filled_normals();
                    let mut joined = joiner.push(&part, filled.as_deref())?;
                    // As extraction in memory does at the end: the mesh is made in the grid's
                    // frame.
                    orientation.orient_parts(
                        &mut joined.positions,
                        &mut joined.normals,
                        &mut joined.triangles,
                        origin,
                    );
                    sink.vertices(&joined.positions, &joined.normals)
                        .map_err(StreamError::Sink)?;
                    sink.triangles(&joined.triangles)
                        .map_err(StreamError::Sink)?;
                    stats.add(&joined.chunk.stats);
                    vertices += joined.positions.len();
                    triangles += joined.triangles.len();
                    if progress(part.cells.max[2], nz - 1).is_break() {
                        return Err(ExtractError::Cancelled.into());
                    }
                }
                Ok(())
            })();
        });
        pushed?;
        if let Some(done) = next.and_then(|g| g.first()).map(|b| b.min[2]) {
            // The rest, projected from the layers done at the rate so far, with a quarter more.
            let project = |n: usize| (n / done).saturating_mul((nz - 1 - done) / 4 * 5 + 1) + 1024;
            sink.reserve(project(vertices), project(triangles));
        }
    }
    Ok(stats)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cube::Topology;
    use crate::field::Sample;
    use crate::quality::Strategy;
    use proptest::prelude::*;

    fn streamed(grid: &Grid, options: &ExtractOptions, threads: usize) -> Mesh {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let mut mesh = Mesh::new();
        pool.install(|| extract_streamed(grid, options, &mut mesh, &mut crate::no_progress))
            .unwrap();
        mesh
    }

    /// The streamed mesh is the in-memory one, to the bit: several slabs (tall grids), NaN
    /// values, normals or none, classic and MC33, quality triangulation, 1 and 2 threads.
    #[test]
    fn streamed_equals_in_memory() {
        let holey = crate::with_nan_holes(Sample::Gyroid.grid(30), 811);
        let tall = Grid::from_fn([20, 17, 150], [0.1; 3], [-1.0, -0.8, -7.5], |p| {
            (p[0] * 3.0).sin() + (p[1] * 2.0).cos() + (p[2] * 1.3).sin() - 0.2
        });
        for grid in [Sample::Tangle.grid(36), holey, tall] {
            for options in [
                ExtractOptions::default(),
                ExtractOptions::default()
                    .with_topology(Topology::Classic)
                    .with_normals(false)
                    .with_flip(true),
                ExtractOptions::default().with_triangulation(Strategy::Local),
            ] {
                let whole = super::super::extract(&grid, &options).unwrap().0;
                assert!(!whole.triangles.is_empty());
                for threads in [1, 2] {
                    assert_eq!(streamed(&grid, &options, threads), whole, "{threads}");
                }
            }
        }
    }

    #[test]
    fn whole_volume_methods_are_refused() {
        let grid = Sample::Sphere.grid(8);
        let mut mesh = Mesh::new();
        for options in [
            ExtractOptions::default().with_relax(2),
            ExtractOptions::default().with_method(Method::Ternary(Default::default())),
            ExtractOptions::default().with_level(f32::NAN),
        ] {
            assert!(matches!(
                extract_streamed(&grid, &options, &mut mesh, &mut crate::no_progress),
                Err(StreamError::Extract(_))
            ));
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        /// Random small integer fields (many ties at the level, sign changes everywhere):
        /// streamed and in-memory agree.
        #[test]
        fn random_fields_stream_the_same(
            nx in 2usize..9, ny in 2usize..9, nz in 2usize..40, seed in any::<u64>(),
        ) {
            let mut rng = crate::TestRng::new(seed);
            let values: Vec<f32> = (0..nx * ny * nz)
                .map(|_| ((rng.next_u64() >> 40) % 5) as f32 - 2.0)
                .collect();
            let grid = Grid::new([nx, ny, nz], values).unwrap();
            let options = ExtractOptions::default();
            let whole = super::super::extract(&grid, &options).unwrap().0;
            prop_assert_eq!(streamed(&grid, &options, 2), whole);
        }
    }
}
