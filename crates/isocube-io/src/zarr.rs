//! Zarr arrays (v2 and v3, through the `zarrs` crate) and OME-Zarr multiscale images, read a
//! layer of chunks at a time.
//!
//! A volume is a 3-d selection of an N-d array: the three spatial axes, and one index on every
//! other axis (a channel, a time point). OME-Zarr names its axes and places them in the world
//! (`coordinateTransformations`: scale, then translation, per level and for the whole image);
//! a plain array's axes are `x, y, z` in the order its `dimension_names` give, or as
//! [`crate::NpyAxes`] says when it has none (the `.npy` convention: `a[x, y, z]` by default).
//!
//! Chunks are decoded a layer at a time along the grid's `z` — every chunk that meets the
//! layer's planes, in parallel — and a layer is dropped once extraction has passed it, so the
//! memory held is a few layers of chunks whatever the array's size.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

use isocube::field::{Grid, Orientation, PlaneSource};
use serde_json::Value;
use zarrs::array::{data_type, Array};
use zarrs::filesystem::FilesystemStore;
use zarrs::group::Group;

use super::{Budget, IoError, NpyAxes, Position, ScalarType, VolumeOptions};

/// The array's element type, when it is one of the ten isocube reads.
fn element_of(array: &Array<FilesystemStore>) -> Option<ScalarType> {
    let t = array.data_type();
    Some(if t.is::<data_type::UInt8DataType>() {
        ScalarType::U8
    } else if t.is::<data_type::Int8DataType>() {
        ScalarType::I8
    } else if t.is::<data_type::UInt16DataType>() {
        ScalarType::U16
    } else if t.is::<data_type::Int16DataType>() {
        ScalarType::I16
    } else if t.is::<data_type::UInt32DataType>() {
        ScalarType::U32
    } else if t.is::<data_type::Int32DataType>() {
        ScalarType::I32
    } else if t.is::<data_type::UInt64DataType>() {
        ScalarType::U64
    } else if t.is::<data_type::Int64DataType>() {
        ScalarType::I64
    } else if t.is::<data_type::Float32DataType>() {
        ScalarType::F32
    } else if t.is::<data_type::Float64DataType>() {
        ScalarType::F64
    } else {
        return None;
    })
}

/// A Zarr array (or an OME-Zarr image's level) as a [`PlaneSource`]: layers of chunks along
/// the grid's `z` decoded as they are first asked for and dropped when
/// [`PlaneSource::release_before`] says so.
///
/// A chunk that cannot be read (corrupt, the wrong size) cannot be reported by `read_planes`:
/// its layer reads as NaN from there on, and [`ZarrVolume::take_error`] tells which chunk and
/// why. Check it before using what was made from the planes. A chunk that is absent is the
/// array's fill value, as the Zarr specification says ([`ZarrVolume::absent_chunks`] counts
/// them).
///
/// ```
/// use isocube::extract::{extract_streamed, ExtractOptions};
/// use isocube::field::Sample;
/// use isocube::mesh::Mesh;
/// use isocube_io::{write_zarr, VolumeOptions, ZarrVolume};
/// let dir = tempfile::tempdir()?;
/// let path = dir.path().join("sphere.zarr");
/// let grid = Sample::Sphere.grid(40);
/// write_zarr(&path, &grid, [16, 16, 16])?;
/// let volume = ZarrVolume::open(&path, &VolumeOptions::default())?;
/// let mut mesh = Mesh::new();
/// extract_streamed(&volume, &ExtractOptions::default(), &mut mesh, &mut isocube::no_progress)?;
/// assert!(volume.take_error().is_none());
/// let whole = isocube::extract::extract(&grid, &ExtractOptions::default())?.0;
/// assert_eq!(mesh, whole);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub struct ZarrVolume {
    chunks: Arc<Chunks>,
    orientation: Orientation,
    spacing: [f64; 3],
    origin: [f64; 3],
    layers: Mutex<Layers>,
}

/// The array and the selection: what decoding a layer needs, shared with the thread that
/// decodes the next layer ahead.
struct Chunks {
    path: PathBuf,
    array: Array<FilesystemStore>,
    element: ScalarType,
    /// The array axis of each grid axis. The grid walks the array in its memory order (C order:
    /// its last spatial axis fastest), whatever the axes' names, and the orientation puts each
    /// grid axis back on its world axis, as [`crate::MappedVolume`] does for a `.npy`: the
    /// chunks are read in one sweep, and the mesh is the one of the same array in memory.
    axes: [usize; 3],
    /// The index taken on every array axis that is not spatial (ignored on spatial ones).
    fixed: Vec<u64>,
    dims: [usize; 3],
    /// Chunks along the array's axis of z.
    chunk_z: usize,
}

/// A layer's values (`x` fastest) and the keys of its absent chunks.
type Layer = Result<(Vec<f32>, Vec<String>), IoError>;

#[derive(Default)]
struct Layers {
    held: BTreeMap<usize, Arc<Vec<f32>>>,
    /// The next layer, decoded on a thread of its own while the slabs mesh this one.
    ahead: Option<(usize, std::thread::JoinHandle<Layer>)>,
    /// Layers below this one were released.
    released: usize,
    error: Option<IoError>,
    failed: bool,
    absent: usize,
    first_absent: Option<String>,
}

impl ZarrVolume {
    /// Opens the array (or OME-Zarr image) at `path`: `options.scale` picks an OME-Zarr level,
    /// `options.channel` and `options.frame` the index on a channel and a time axis;
    /// `options.spacing` and `options.origin` override what the metadata say.
    pub fn open(path: &Path, options: &VolumeOptions) -> Result<ZarrVolume, IoError> {
        let store = Arc::new(FilesystemStore::new(path).map_err(|e| {
            IoError::format(path, Position::File, format!("not a Zarr store: {e}"))
        })?);
        let (array_path, placement) = locate(path, &store, options)?;
        let (array, element) = open_array(path, store, &array_path)?;
        let shape: Vec<u64> = array.shape().to_vec();
        let names: Option<Vec<String>> = placement
            .as_ref()
            .map(|p| p.names.clone())
            .or_else(|| {
                array.dimension_names().as_ref().and_then(|n| {
                    n.iter()
                        .map(|d| d.as_ref().map(|s| s.to_ascii_lowercase()))
                        .collect()
                })
            })
            .filter(|n| ["x", "y", "z"].iter().all(|a| n.iter().any(|m| m == a)));
        let (world, fixed) = select_axes(path, &shape, names.as_deref(), options)?;
        let (mut spacing, mut origin) = match &placement {
            Some(p) => (world.map(|a| p.scale[a]), world.map(|a| p.translation[a])),
            None => ([1.0; 3], [0.0; 3]),
        };
        spacing = options.spacing.unwrap_or(spacing);
        origin = options.origin.unwrap_or(origin);
        // Grid axis g walks world axis walk[g]: the spatial array axes from the last.
        let mut walk = [0, 1, 2];
        walk.sort_by_key(|&w| std::cmp::Reverse(world[w]));
        let orientation = Orientation::axes(walk).expect("a permutation of the axes");
        let axes = walk.map(|w| world[w]);
        let spacing = walk.map(|w| spacing[w]);
        let dims = axes.map(|a| shape[a] as usize);
        Grid::point_count(dims).map_err(|e| IoError::grid(path, e))?;
        // The same checks as a grid's.
        Grid::new([2, 2, 2], vec![0.0; 8])
            .and_then(|g| g.with_spacing(spacing))
            .and_then(|g| g.with_origin(origin))
            .map_err(|e| IoError::grid(path, e))?;
        let chunk_z = array.chunk_shape(&vec![0; shape.len()]).map_err(|e| {
            IoError::format(path, Position::Field("chunk_grid".into()), e.to_string())
        })?[axes[2]]
            .get() as usize;
        let volume = ZarrVolume {
            chunks: Arc::new(Chunks {
                path: path.to_path_buf(),
                array,
                element,
                axes,
                fixed,
                dims,
                chunk_z,
            }),
            orientation,
            spacing,
            origin,
            layers: Mutex::new(Layers::default()),
        };
        // The layer in work, the one before it until released, the next being decoded.
        let layer = (dims[0] * dims[1]) as u64 * chunk_z as u64;
        let budget = Budget::new(options.max_memory);
        budget.check(path, Position::Field("chunk_grid".into()), layer * 4 * 3)?;
        Ok(volume)
    }

    /// The same volume in index space: spacing 1, origin 0.
    pub fn into_index_space(mut self) -> ZarrVolume {
        self.spacing = [1.0; 3];
        self.origin = [0.0; 3];
        self
    }

    /// The store.
    pub fn path(&self) -> &Path {
        &self.chunks.path
    }

    /// The first absent chunk met so far, by its key (`c/0/1/2`, `0.1.2`), if any.
    pub fn first_absent_chunk(&self) -> Option<String> {
        self.lock().first_absent.clone()
    }

    /// The error that made planes read as NaN, if any (taken: asked again, `None`).
    pub fn take_error(&self) -> Option<IoError> {
        self.lock().error.take()
    }

    /// Chunks found absent so far (read as the fill value).
    pub fn absent_chunks(&self) -> usize {
        self.lock().absent
    }

    /// Reads the whole selection into a grid.
    pub(crate) fn read_all(&self, budget: Budget) -> Result<(Grid, Orientation), IoError> {
        let [nx, ny, nz] = self.chunks.dims;
        let count = nx * ny * nz;
        budget.check_values(self.path(), Position::Field("shape".into()), 0, count)?;
        let mut values = vec![0.0f32; count];
        let layer_size = nx * ny * self.chunks.chunk_z;
        for (layer, out) in values.chunks_mut(layer_size).enumerate() {
            out.copy_from_slice(&self.layer(layer));
            self.release_before((layer + 1) * self.chunks.chunk_z);
        }
        if let Some(e) = self.take_error() {
            return Err(e);
        }
        let grid = Grid::new(self.chunks.dims, values)
            .and_then(|g| g.with_spacing(self.spacing))
            .and_then(|g| g.with_origin(self.origin))
            .map_err(|e| IoError::grid(self.path(), e))?;
        Ok((grid, self.orientation))
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Layers> {
        self.layers.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Layer `layer`: held, decoded ahead, or decoded now; the next one is then started on a
    /// thread of its own, so that decoding runs while the slabs of this one are meshed.
    fn layer(&self, layer: usize) -> Arc<Vec<f32>> {
        let mut state = self.lock();
        if let Some(held) = state.held.get(&layer) {
            return held.clone();
        }
        let size =
            self.chunks.dims[0] * self.chunks.dims[1] * self.chunks.layer_planes(layer).len();
        let decoded = match state.ahead.take() {
            Some((l, thread)) if l == layer => thread
                .join()
                .unwrap_or_else(|p| std::panic::resume_unwind(p)),
            // Decoded with the lock held: the slabs in flight want the same layer.
            other => {
                drop(other.map(|(_, t)| t.join()));
                if state.failed {
                    Ok((vec![f32::NAN; size], Vec::new()))
                } else {
                    self.chunks.decode_layer(layer)
                }
            }
        };
        let values = match decoded {
            Ok((values, absent)) => {
                state.absent += absent.len();
                if let Some(first) = absent.into_iter().next() {
                    state.first_absent.get_or_insert(first);
                }
                values
            }
            Err(e) => {
                state.failed = true;
                state.error.get_or_insert(e);
                vec![f32::NAN; size]
            }
        };
        let values = Arc::new(values);
        if layer >= state.released {
            state.held.insert(layer, values.clone());
        }
        let next = layer + 1;
        if !state.failed && next < self.chunks.layers() && !state.held.contains_key(&next) {
            let chunks = self.chunks.clone();
            let thread = std::thread::Builder::new()
                .name("zarr layer".into())
                .spawn(move || chunks.decode_layer(next));
            if let Ok(thread) = thread {
                state.ahead = Some((next, thread));
            }
        }
        values
    }
}

impl Chunks {
    /// Layers of chunks along the grid's `z`.
    fn layers(&self) -> usize {
        self.dims[2].div_ceil(self.chunk_z)
    }

    /// Grid planes of layer `layer` (`chunk_z` planes, fewer in the last).
    fn layer_planes(&self, layer: usize) -> std::ops::Range<usize> {
        let start = layer * self.chunk_z;
        start..(start + self.chunk_z).min(self.dims[2])
    }

    /// Decodes every chunk meeting layer `layer` into its planes' values, `x` fastest, each
    /// chunk put in place as soon as it is decoded (so that a layer's chunks are never all
    /// held beside it); absent chunks are the fill value, and their keys are returned.
    fn decode_layer(&self, layer: usize) -> Layer {
        use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
        let [nx, ny, _] = self.dims;
        let planes = self.layer_planes(layer);
        let grid_shape = self.array.chunk_grid_shape().to_vec();
        let rank = grid_shape.len();
        let zero = vec![0u64; rank];
        let first_shape = self
            .array
            .chunk_shape(&zero)
            .map_err(|e| self.chunk_error(&zero, e))?;
        // Every chunk of the layer: chunk indices over the x and y axes, the layer on z's,
        // the chunk holding the fixed index elsewhere.
        let mut base: Vec<u64> = (0..rank)
            .map(|a| self.fixed[a] / first_shape[a].get())
            .collect();
        base[self.axes[2]] = layer as u64;
        let [ax, ay, _] = self.axes;
        let mut chunks = Vec::new();
        for cy in 0..grid_shape[ay] {
            for cx in 0..grid_shape[ax] {
                let mut c = base.clone();
                c[ax] = cx;
                c[ay] = cy;
                chunks.push(c);
            }
        }
        let out = Mutex::new(vec![0.0f32; nx * ny * planes.len()]);
        let fill = self.fill_value();
        let next = AtomicUsize::new(0);
        let failed = AtomicBool::new(false);
        let threads = std::thread::available_parallelism()
            .map_or(1, |n| n.get())
            .min(chunks.len())
            .max(1);
        type Outcome = Option<Result<bool, IoError>>;
        let mut outcomes: Vec<Outcome> = Vec::new();
        outcomes.resize_with(chunks.len(), || None);
        let outcomes = Mutex::new(outcomes);
        let work = || {
            while !failed.load(Ordering::Relaxed) {
                let i = next.fetch_add(1, Ordering::Relaxed);
                let Some(c) = chunks.get(i) else {
                    return;
                };
                let outcome = self.decode_chunk(c).and_then(|values| {
                    let shape = self
                        .array
                        .chunk_shape(c)
                        .map_err(|e| self.chunk_error(c, e))?;
                    let shape: Vec<u64> = shape.iter().map(|n| n.get()).collect();
                    let mut out = out.lock().unwrap_or_else(|p| p.into_inner());
                    self.place(c, &shape, values.as_deref(), fill, planes.clone(), &mut out);
                    Ok(values.is_some())
                });
                failed.fetch_or(outcome.is_err(), Ordering::Relaxed);
                outcomes.lock().unwrap_or_else(|p| p.into_inner())[i] = Some(outcome);
            }
        };
        std::thread::scope(|scope| {
            for _ in 1..threads {
                scope.spawn(work);
            }
            work();
        });
        // The first failure in chunk order, whichever thread met it first.
        let mut absent = Vec::new();
        for (c, outcome) in chunks
            .iter()
            .zip(outcomes.into_inner().unwrap_or_else(|p| p.into_inner()))
        {
            match outcome {
                Some(Err(e)) => return Err(e),
                Some(Ok(false)) => absent.push(self.array.chunk_key(c).to_string()),
                _ => {}
            }
        }
        if failed.load(Ordering::Relaxed) {
            return Err(self.chunk_error(&zero, "a chunk could not be read"));
        }
        Ok((out.into_inner().unwrap_or_else(|p| p.into_inner()), absent))
    }

    /// Copies chunk `c` (its `values` in C order over its full `shape`, or the fill value when
    /// absent) into the planes `planes` of a layer, `x` fastest.
    fn place(
        &self,
        c: &[u64],
        shape: &[u64],
        values: Option<&[f32]>,
        fill: f32,
        planes: std::ops::Range<usize>,
        out: &mut [f32],
    ) {
        let [nx, ny, _] = self.dims;
        let [ax, ay, az] = self.axes;
        let rank = shape.len();
        // Element strides in the chunk (C order over the array's axes).
        let mut strides = vec![1u64; rank];
        for a in (0..rank.saturating_sub(1)).rev() {
            strides[a] = strides[a + 1] * shape[a + 1];
        }
        let origin: Vec<u64> = (0..rank).map(|a| c[a] * shape[a]).collect();
        let x0 = origin[ax] as usize;
        let y0 = origin[ay] as usize;
        let x1 = (x0 + shape[ax] as usize).min(nx);
        let y1 = (y0 + shape[ay] as usize).min(ny);
        let (sx, sy) = (strides[ax] as usize, strides[ay] as usize);
        for (p, z) in planes.clone().enumerate() {
            let plane = &mut out[p * nx * ny..(p + 1) * nx * ny];
            let mut offset = 0u64;
            for a in 0..rank {
                let at = if a == az {
                    z as u64
                } else if a == ax || a == ay {
                    origin[a]
                } else {
                    self.fixed[a]
                };
                offset += (at - origin[a]) * strides[a];
            }
            let offset = offset as usize;
            for y in y0..y1 {
                let row = &mut plane[nx * y + x0..nx * y + x1];
                match values {
                    Some(v) => {
                        let start = offset + (y - y0) * sy;
                        if sx == 1 {
                            row.copy_from_slice(&v[start..start + row.len()]);
                        } else {
                            for (i, r) in row.iter_mut().enumerate() {
                                *r = v[start + i * sx];
                            }
                        }
                    }
                    None => row.fill(fill),
                }
            }
        }
    }

    /// The array's fill value as `f32` (what an absent chunk holds).
    fn fill_value(&self) -> f32 {
        let bytes = self.array.fill_value().as_ne_bytes();
        convert(self.element, bytes).first().copied().unwrap_or(0.0)
    }

    /// One chunk's values as `f32` (C order over its full shape), `None` when it is absent.
    fn decode_chunk(&self, c: &[u64]) -> Result<Option<Vec<f32>>, IoError> {
        macro_rules! chunk {
            ($t:ty) => {
                self.array
                    .retrieve_chunk_if_exists::<Vec<$t>>(c)
                    .map(|v| v.map(|v| v.into_iter().map(|x| x as f32).collect()))
            };
        }
        let decoded = match self.element {
            ScalarType::U8 => chunk!(u8),
            ScalarType::I8 => chunk!(i8),
            ScalarType::U16 => chunk!(u16),
            ScalarType::I16 => chunk!(i16),
            ScalarType::U32 => chunk!(u32),
            ScalarType::I32 => chunk!(i32),
            ScalarType::U64 => chunk!(u64),
            ScalarType::I64 => chunk!(i64),
            ScalarType::F32 => chunk!(f32),
            ScalarType::F64 => chunk!(f64),
        };
        decoded.map_err(|e| self.chunk_error(c, e))
    }

    fn chunk_error(&self, c: &[u64], e: impl std::fmt::Display) -> IoError {
        IoError::format(
            &self.path,
            Position::Chunk {
                key: self.array.chunk_key(c).to_string(),
                indices: c.to_vec(),
            },
            e.to_string(),
        )
    }
}

/// The array at `array_path` in the store at `path`, and its element type; errors name the
/// metadata file.
fn open_array(
    path: &Path,
    store: Arc<FilesystemStore>,
    array_path: &str,
) -> Result<(Array<FilesystemStore>, ScalarType), IoError> {
    let array = Array::open(store, array_path).map_err(|e| {
        let folder = path.join(array_path.trim_start_matches('/'));
        let metadata = match folder.join(".zarray").is_file() {
            true => folder.join(".zarray"),
            false => folder.join("zarr.json"),
        };
        IoError::format(
            &metadata,
            Position::File,
            format!("not a readable Zarr array: {e}"),
        )
    })?;
    let element = element_of(&array).ok_or_else(|| {
        IoError::unsupported(
            path,
            Position::Field("data_type".into()),
            format!(
                "element type {:?}: isocube reads u8, i8, u16, i16, u32, i32, u64, i64, f32 and f64",
                array.data_type()
            ),
        )
    })?;
    Ok((array, element))
}

/// Points `start .. start + shape` of the 3-d Zarr array at `path` (or at `component` inside
/// the group there), in the array's own axis order, as `f32` in C order: what a task of a
/// cluster reads for its chunk. Absent chunks are the fill value, or with `strict` an error
/// naming the first; a chunk that cannot be decoded is named in the error.
///
/// ```
/// use isocube::field::Sample;
/// let dir = tempfile::tempdir().unwrap();
/// let grid = Sample::Sphere.grid(12);
/// let path = dir.path().join("sphere.zarr");
/// isocube_io::write_zarr(&path, &grid, [5, 5, 5]).unwrap();
/// // An OME-Zarr image: level "0", axes (z, y, x); points 3..9 along each, across chunks.
/// let block = isocube_io::read_zarr_block(&path, Some("0"), [3, 3, 3], [6, 6, 6], false).unwrap();
/// assert_eq!(block[0], grid.value(3, 3, 3));
/// assert_eq!(block[6 * 6 * 6 - 1], grid.value(8, 8, 8));
/// assert_eq!(block[1], grid.value(4, 3, 3)); // x, the last axis, fastest
/// ```
pub fn read_zarr_block(
    path: &Path,
    component: Option<&str>,
    start: [u64; 3],
    shape: [u64; 3],
    strict: bool,
) -> Result<Vec<f32>, IoError> {
    let store =
        Arc::new(FilesystemStore::new(path).map_err(|e| {
            IoError::format(path, Position::File, format!("not a Zarr store: {e}"))
        })?);
    let array_path = format!("/{}", component.unwrap_or("").trim_matches('/'));
    let (array, element) = open_array(path, store, &array_path)?;
    let dims = array.shape().to_vec();
    let inside = dims.len() == 3
        && (0..3)
            .all(|a| shape[a] > 0 && start[a].checked_add(shape[a]).is_some_and(|e| e <= dims[a]));
    if !inside {
        return Err(IoError::format(
            path,
            Position::File,
            format!("points {start:?} + {shape:?} are not inside the array's shape {dims:?}"),
        ));
    }
    let chunks = Chunks {
        path: path.to_path_buf(),
        array,
        element,
        axes: [2, 1, 0],
        fixed: vec![0; 3],
        dims: [dims[2] as usize, dims[1] as usize, dims[0] as usize],
        chunk_z: 1,
    };
    let size = chunks
        .array
        .chunk_shape(&[0, 0, 0])
        .map_err(|e| chunks.chunk_error(&[0, 0, 0], e))?;
    let size: Vec<u64> = size.iter().map(|n| n.get()).collect();
    let fill = chunks.fill_value();
    let n = shape.iter().product::<u64>() as usize;
    let mut out = vec![0.0f32; n];
    let ranges: Vec<std::ops::RangeInclusive<u64>> = (0..3)
        .map(|a| start[a] / size[a]..=(start[a] + shape[a] - 1) / size[a])
        .collect();
    for c0 in ranges[0].clone() {
        for c1 in ranges[1].clone() {
            for c2 in ranges[2].clone() {
                let c = [c0, c1, c2];
                let values = chunks.decode_chunk(&c)?;
                if values.is_none() && strict {
                    return Err(chunks.chunk_error(
                        &c,
                        format!("absent (strict: not read as the fill value {fill})"),
                    ));
                }
                // The chunk's points that the block holds, per axis.
                let lo: [u64; 3] = std::array::from_fn(|a| (c[a] * size[a]).max(start[a]));
                let hi: [u64; 3] =
                    std::array::from_fn(|a| ((c[a] + 1) * size[a]).min(start[a] + shape[a]));
                for i in lo[0]..hi[0] {
                    for j in lo[1]..hi[1] {
                        let row = ((i - start[0]) * shape[1] + (j - start[1])) * shape[2];
                        let to =
                            (row + lo[2] - start[2]) as usize..(row + hi[2] - start[2]) as usize;
                        match &values {
                            Some(v) => {
                                let at = (((i - c[0] * size[0]) * size[1] + (j - c[1] * size[1]))
                                    * size[2]
                                    + (lo[2] - c[2] * size[2]))
                                    as usize;
                                out[to.clone()].copy_from_slice(&v[at..at + to.len()]);
                            }
                            None => out[to].fill(fill),
                        }
                    }
                }
            }
        }
    }
    Ok(out)
}

/// `bytes` (native order) of `element`s as `f32`.
fn convert(element: ScalarType, bytes: &[u8]) -> Vec<f32> {
    macro_rules! each {
        ($t:ty) => {
            bytes
                .chunks_exact(std::mem::size_of::<$t>())
                .map(|b| <$t>::from_ne_bytes(b.try_into().expect("sized")) as f32)
                .collect()
        };
    }
    match element {
        ScalarType::U8 => each!(u8),
        ScalarType::I8 => each!(i8),
        ScalarType::U16 => each!(u16),
        ScalarType::I16 => each!(i16),
        ScalarType::U32 => each!(u32),
        ScalarType::I32 => each!(i32),
        ScalarType::U64 => each!(u64),
        ScalarType::I64 => each!(i64),
        ScalarType::F32 => each!(f32),
        ScalarType::F64 => each!(f64),
    }
}

impl PlaneSource for ZarrVolume {
    fn dims(&self) -> [usize; 3] {
        self.chunks.dims
    }

    fn spacing(&self) -> [f64; 3] {
        self.spacing
    }

    fn origin(&self) -> [f64; 3] {
        self.origin
    }

    fn orientation(&self) -> Orientation {
        self.orientation
    }

    fn read_planes(&self, first: usize, out: &mut [f32]) {
        let chunk_z = self.chunks.chunk_z;
        let plane = self.chunks.dims[0] * self.chunks.dims[1];
        let mut z = first;
        let mut written = 0;
        while written < out.len() {
            let layer = z / chunk_z;
            let values = self.layer(layer);
            let start = (z - layer * chunk_z) * plane;
            let n = (values.len() - start).min(out.len() - written);
            out[written..written + n].copy_from_slice(&values[start..start + n]);
            written += n;
            z += n / plane;
        }
    }

    fn release_before(&self, plane: usize) {
        let mut state = self.lock();
        let layer = plane / self.chunks.chunk_z;
        state.released = state.released.max(layer);
        state.held.retain(|&l, _| l >= layer);
    }
}

/// Where an OME-Zarr image places the level read: axis names (lower case) and, per array axis,
/// scale and translation.
struct Placement {
    names: Vec<String>,
    scale: Vec<f64>,
    translation: Vec<f64>,
}

/// The array to read inside the store (`/` for an array at `path`) and, for an OME-Zarr image,
/// how it is placed.
fn locate(
    path: &Path,
    store: &Arc<FilesystemStore>,
    options: &VolumeOptions,
) -> Result<(String, Option<Placement>), IoError> {
    if path.join(".zarray").is_file()
        || std::fs::read_to_string(path.join("zarr.json"))
            .ok()
            .and_then(|s| serde_json::from_str::<Value>(&s).ok())
            .is_some_and(|v| v["node_type"] == "array")
    {
        if options.scale.is_some_and(|s| s > 0) {
            return Err(IoError::unsupported(
                path,
                Position::File,
                "a single array has one scale: --scale needs an OME-Zarr image (a group with multiscales)",
            ));
        }
        return Ok(("/".into(), None));
    }
    let group = Group::open(store.clone(), "/").map_err(|e| {
        IoError::format(
            path,
            Position::File,
            format!("not a readable Zarr group: {e}"),
        )
    })?;
    let attributes = group.attributes();
    // OME-Zarr 0.5 (Zarr v3) nests its metadata under "ome"; 0.4 and earlier (Zarr v2) do not.
    let multiscales = attributes
        .get("ome")
        .and_then(|o| o.get("multiscales"))
        .or_else(|| attributes.get("multiscales"))
        .and_then(Value::as_array)
        .and_then(|m| m.first())
        .ok_or_else(|| {
            IoError::unsupported(
                path,
                Position::Field("multiscales".into()),
                "a Zarr group that is not an OME-Zarr image: give the path of the array inside it",
            )
        })?;
    let field = |name: &str| Position::Field(format!("multiscales/{name}"));
    let bad = |name: &str, why: &str| IoError::format(path, field(name), why.to_string());
    let names: Vec<String> = multiscales
        .get("axes")
        .and_then(Value::as_array)
        .ok_or_else(|| bad("axes", "missing (OME-Zarr 0.4 and later name their axes)"))?
        .iter()
        .map(|a| {
            a.get("name")
                .and_then(Value::as_str)
                .or_else(|| a.as_str())
                .map(str::to_ascii_lowercase)
                .ok_or_else(|| bad("axes", "an axis without a name"))
        })
        .collect::<Result<_, _>>()?;
    let datasets = multiscales
        .get("datasets")
        .and_then(Value::as_array)
        .filter(|d| !d.is_empty())
        .ok_or_else(|| bad("datasets", "missing or empty"))?;
    let scale = options.scale.unwrap_or(0);
    let dataset = datasets.get(scale).ok_or_else(|| {
        IoError::format(
            path,
            field("datasets"),
            format!(
                "--scale {scale}: the image has {} levels (0 to {})",
                datasets.len(),
                datasets.len() - 1
            ),
        )
    })?;
    let array_path = dataset
        .get("path")
        .and_then(Value::as_str)
        .ok_or_else(|| bad("datasets", "a level without a path"))?;
    let rank = names.len();
    let mut placement = Placement {
        names,
        scale: vec![1.0; rank],
        translation: vec![0.0; rank],
    };
    // The level's transformations, then the image's: each a scale, then a translation.
    for transforms in [
        dataset.get("coordinateTransformations"),
        multiscales.get("coordinateTransformations"),
    ]
    .into_iter()
    .flatten()
    {
        let list = transforms
            .as_array()
            .ok_or_else(|| bad("coordinateTransformations", "not a list"))?;
        for t in list {
            let numbers = |key: &str| -> Result<Vec<f64>, IoError> {
                let v: Vec<f64> = t
                    .get(key)
                    .and_then(Value::as_array)
                    .map(|a| a.iter().filter_map(Value::as_f64).collect())
                    .unwrap_or_default();
                if v.len() != rank {
                    return Err(bad(
                        "coordinateTransformations",
                        &format!("a {key} of {} numbers for {rank} axes", v.len()),
                    ));
                }
                Ok(v)
            };
            match t.get("type").and_then(Value::as_str) {
                Some("scale") => {
                    let s = numbers("scale")?;
                    for (a, s) in s.into_iter().enumerate() {
                        placement.scale[a] *= s;
                        placement.translation[a] *= s;
                    }
                }
                Some("translation") => {
                    let t = numbers("translation")?;
                    for (p, t) in placement.translation.iter_mut().zip(t) {
                        *p += t;
                    }
                }
                Some("identity") | None => {}
                Some(other) => {
                    return Err(IoError::unsupported(
                        path,
                        field("coordinateTransformations"),
                        format!("transformation '{other}' (isocube reads scale and translation)"),
                    ))
                }
            }
        }
    }
    Ok((
        format!("/{}", array_path.trim_matches('/')),
        Some(placement),
    ))
}

/// The array axes of world x, y and z, and the index taken on every other axis.
fn select_axes(
    path: &Path,
    shape: &[u64],
    names: Option<&[String]>,
    options: &VolumeOptions,
) -> Result<([usize; 3], Vec<u64>), IoError> {
    let rank = shape.len();
    let field = || Position::Field("shape".into());
    if rank < 3 {
        return Err(IoError::unsupported(
            path,
            field(),
            format!("a {rank}-d array: isocube meshes 3-d volumes"),
        ));
    }
    let mut fixed = vec![0u64; rank];
    let (axes, others): ([usize; 3], Vec<(usize, &str)>) = match names {
        Some(names) => {
            if names.len() != rank {
                return Err(IoError::format(
                    path,
                    Position::Field("axes".into()),
                    format!("{} axis names for a {rank}-d array", names.len()),
                ));
            }
            let find = |n: &str| names.iter().position(|m| m == n).expect("checked");
            let axes = [find("x"), find("y"), find("z")];
            let others = (0..rank)
                .filter(|a| !axes.contains(a))
                .map(|a| (a, names[a].as_str()))
                .collect();
            (axes, others)
        }
        None => {
            let lead = rank - 3;
            let spatial = match options.npy_axes {
                NpyAxes::Xyz => [lead, lead + 1, lead + 2],
                NpyAxes::Zyx => [lead + 2, lead + 1, lead],
            };
            // Unnamed leading axes: time first, then channel, as OME-Zarr orders them.
            let others = match lead {
                0 => vec![],
                1 => vec![(0, "t")],
                _ => (0..lead)
                    .map(|a| (a, if a + 1 == lead { "c" } else { "t" }))
                    .collect(),
            };
            (spatial, others)
        }
    };
    for (a, name) in others {
        let (chosen, flag, what) = match name {
            "c" => (options.channel, "--channel", "channels"),
            "t" => (options.frame, "--frame", "frames"),
            _ => (options.frame.or(options.channel), "--frame", "entries"),
        };
        let n = shape[a];
        let index = match chosen {
            Some(i) if (i as u64) < n => i as u64,
            Some(i) => {
                return Err(IoError::format(
                    path,
                    field(),
                    format!("{flag} {i}: axis '{name}' has {n} {what} (0 to {})", n - 1),
                ))
            }
            None if n == 1 => 0,
            None => {
                return Err(IoError::unsupported(
                    path,
                    field(),
                    format!(
                        "axis '{name}' has {n} {what}: choose one with {flag} (0 to {})",
                        n - 1
                    ),
                ))
            }
        };
        fixed[a] = index;
    }
    Ok((axes, fixed))
}

/// Reads a Zarr array or OME-Zarr image whole (see [`ZarrVolume`] for the selection).
pub(crate) fn read_zarr_within(
    path: &Path,
    options: &VolumeOptions,
    budget: Budget,
) -> Result<(Grid, Orientation), IoError> {
    ZarrVolume::open(path, options)?.read_all(budget)
}

/// Writes `grid` as an OME-Zarr 0.5 image (Zarr v3) at `path`, a new folder: one level, `0`,
/// of `float32` values stored `z, y, x` (x fastest), placed by a scale (the spacing) and a
/// translation (the origin), in chunks of `chunk` points along x, y and z compressed with zstd.
/// Read back by [`ZarrVolume`] (and napari, zarr-python, Fiji's OME-Zarr readers) with the same
/// values and geometry.
///
/// ```
/// use isocube::field::Sample;
/// use isocube_io::{read_volume, write_zarr, VolumeOptions};
/// let dir = tempfile::tempdir()?;
/// let path = dir.path().join("torus.zarr");
/// let grid = Sample::Torus.grid(20);
/// write_zarr(&path, &grid, [8, 8, 8])?;
/// let read = read_volume(&path, &VolumeOptions::default())?;
/// assert_eq!((read.values(), read.spacing()), (grid.values(), grid.spacing()));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn write_zarr(path: &Path, grid: &Grid, chunk: [usize; 3]) -> Result<(), IoError> {
    use zarrs::array::{codec::ZstdCodec, ArrayBuilder};
    use zarrs::group::GroupBuilder;
    let failed =
        |e: &dyn std::fmt::Display| IoError::os(path, std::io::Error::other(e.to_string()));
    if chunk.contains(&0) {
        return Err(IoError::format(path, Position::File, "chunks of 0 points"));
    }
    std::fs::create_dir_all(path).map_err(|e| IoError::os(path, e))?;
    let store = Arc::new(FilesystemStore::new(path).map_err(|e| failed(&e))?);
    let [nx, ny, nz] = grid.dims();
    let [sx, sy, sz] = grid.spacing();
    let [ox, oy, oz] = grid.origin();
    let axis = |name: &str| serde_json::json!({"name": name, "type": "space"});
    let ome = serde_json::json!({
        "version": "0.5",
        "multiscales": [{
            "axes": [axis("z"), axis("y"), axis("x")],
            "datasets": [{
                "path": "0",
                "coordinateTransformations": [
                    {"type": "scale", "scale": [sz, sy, sx]},
                    {"type": "translation", "translation": [oz, oy, ox]},
                ],
            }],
        }],
    });
    let mut attributes = serde_json::Map::new();
    attributes.insert("ome".into(), ome);
    let group = GroupBuilder::new()
        .attributes(attributes)
        .build(store.clone(), "/")
        .map_err(|e| failed(&e))?;
    group.store_metadata().map_err(|e| failed(&e))?;
    let array = ArrayBuilder::new(
        vec![nz as u64, ny as u64, nx as u64],
        vec![chunk[2] as u64, chunk[1] as u64, chunk[0] as u64],
        data_type::float32(),
        f32::NAN,
    )
    .bytes_to_bytes_codecs(vec![Arc::new(ZstdCodec::new(3, false))])
    .dimension_names(Some(["z", "y", "x"]))
    .build(store, "/0")
    .map_err(|e| failed(&e))?;
    array.store_metadata().map_err(|e| failed(&e))?;
    array
        .store_array_subset(&array.subset_all(), grid.values())
        .map_err(|e| failed(&e))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::read_volume_oriented;
    use isocube::extract::{extract, extract_streamed, ExtractOptions};
    use isocube::field::Sample;
    use isocube::mesh::Mesh;
    use std::io::Write;

    fn streamed(volume: &ZarrVolume, options: &ExtractOptions, threads: usize) -> Mesh {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let mut mesh = Mesh::new();
        pool.install(|| extract_streamed(volume, options, &mut mesh, &mut isocube::no_progress))
            .unwrap();
        assert!(volume.take_error().is_none());
        mesh
    }

    /// Chunks that divide the grid evenly or not (the last ones short), 1 and 2 threads: the
    /// streamed mesh is the one of the grid in memory, to the bit, and so is the whole read.
    #[test]
    fn streamed_and_whole_reads_equal_the_grid() {
        let dir = tempfile::tempdir().unwrap();
        let grid = Sample::Gyroid.grid(41);
        let options = ExtractOptions::default();
        let whole = extract(&grid, &options).unwrap().0;
        assert!(!whole.triangles.is_empty());
        for chunk in [[16, 16, 16], [7, 9, 11], [41, 41, 3]] {
            let path = dir.path().join(format!("g{}.zarr", chunk[0]));
            write_zarr(&path, &grid, chunk).unwrap();
            let volume = ZarrVolume::open(&path, &VolumeOptions::default()).unwrap();
            assert_eq!(volume.orientation(), Orientation::IDENTITY);
            for threads in [1, 2] {
                assert_eq!(streamed(&volume, &options, threads), whole, "{chunk:?}");
            }
            let (read, _) = read_volume_oriented(&path, &VolumeOptions::default()).unwrap();
            assert_eq!(read.values(), grid.values());
            assert_eq!(
                (read.spacing(), read.origin()),
                (grid.spacing(), grid.origin())
            );
        }
    }

    /// A Zarr v2 array written by hand as other tools write them: `<u2` values, gzip, no axis
    /// names (so `a[x, y, z]` as a `.npy`), a missing chunk (the fill value), an uneven grid.
    /// The values are the `.npy` reader's for the same array, walked in the same order.
    #[test]
    fn version_2_arrays_read_as_the_npy_of_the_same_array() {
        let dir = tempfile::tempdir().unwrap();
        let shape = [9usize, 7, 5];
        let value = |x: usize, y: usize, z: usize| (x * 100 + y * 10 + z) as u16;
        let path = dir.path().join("v2.zarr");
        std::fs::create_dir_all(&path).unwrap();
        std::fs::write(
            path.join(".zarray"),
            r#"{"zarr_format": 2, "shape": [9, 7, 5], "chunks": [4, 4, 4], "dtype": "<u2",
                "compressor": {"id": "gzip", "level": 1}, "fill_value": 7, "order": "C",
                "filters": null}"#,
        )
        .unwrap();
        for cx in 0..3 {
            for cy in 0..2 {
                for cz in 0..2 {
                    if [cx, cy, cz] == [2, 1, 1] {
                        continue; // absent: the fill value
                    }
                    let mut bytes = Vec::new();
                    for x in 0..4 {
                        for y in 0..4 {
                            for z in 0..4 {
                                let (x, y, z) = (cx * 4 + x, cy * 4 + y, cz * 4 + z);
                                let v = if x < 9 && y < 7 && z < 5 {
                                    value(x, y, z)
                                } else {
                                    0
                                };
                                bytes.extend(v.to_le_bytes());
                            }
                        }
                    }
                    let mut gz = flate2::write::GzEncoder::new(Vec::new(), Default::default());
                    gz.write_all(&bytes).unwrap();
                    std::fs::write(path.join(format!("{cx}.{cy}.{cz}")), gz.finish().unwrap())
                        .unwrap();
                }
            }
        }
        let mut data = Vec::new();
        for x in 0..9 {
            for y in 0..7 {
                for z in 0..5 {
                    let absent = x >= 8 && y >= 4 && z >= 4;
                    data.extend((if absent { 7 } else { value(x, y, z) }).to_le_bytes());
                }
            }
        }
        let npy = dir.path().join("same.npy");
        std::fs::write(
            &npy,
            crate::npy::tests::npy_bytes("<u2", false, &shape, &data),
        )
        .unwrap();
        let options = VolumeOptions::default();
        let (from_npy, o_npy) = read_volume_oriented(&npy, &options).unwrap();
        let mapped = crate::MappedVolume::open(&npy, &options).unwrap();
        let volume = ZarrVolume::open(&path, &options).unwrap();
        assert_eq!(volume.dims(), PlaneSource::dims(&mapped));
        assert_eq!(volume.orientation(), PlaneSource::orientation(&mapped));
        let mut planes = vec![0.0; 9 * 7 * 5];
        volume.read_planes(0, &mut planes);
        let mut expected = vec![0.0; 9 * 7 * 5];
        mapped.read_planes(0, &mut expected);
        assert_eq!(planes, expected);
        assert_eq!(
            (volume.absent_chunks(), volume.first_absent_chunk()),
            (1, Some("2.1.1".into()))
        );
        // Read whole: walked as the mapped file is, where the .npy reader turns it x fastest.
        let (from_zarr, o_zarr) = read_volume_oriented(&path, &options).unwrap();
        assert_eq!(o_zarr, PlaneSource::orientation(&mapped));
        assert_eq!((from_zarr.dims(), from_npy.dims()), ([5, 7, 9], [9, 7, 5]));
        assert_eq!(o_npy, Orientation::IDENTITY);
        for (i, j, k) in [(0, 0, 0), (4, 6, 8), (3, 5, 8), (1, 2, 3)] {
            assert_eq!(from_zarr.value(i, j, k), from_npy.value(k, j, i));
        }
    }

    /// An OME-Zarr 0.4 image (Zarr v2): two channels and two levels, each placed by a scale and
    /// a translation. `scale`, `channel` pick the array and index; spacing and origin follow the
    /// transformations; the choices the image needs are asked for by name.
    #[test]
    fn ome_zarr_levels_channels_and_placement() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("ome.zarr");
        std::fs::create_dir_all(&path).unwrap();
        std::fs::write(path.join(".zgroup"), r#"{"zarr_format": 2}"#).unwrap();
        let axes = r#"[{"name": "c", "type": "channel"}, {"name": "z", "type": "space"},
                       {"name": "y", "type": "space"}, {"name": "x", "type": "space"}]"#;
        let level = |path: &str, s: [f64; 3], t: [f64; 3]| {
            format!(
                r#"{{"path": "{path}", "coordinateTransformations": [
                    {{"type": "scale", "scale": [1, {}, {}, {}]}},
                    {{"type": "translation", "translation": [0, {}, {}, {}]}}]}}"#,
                s[0], s[1], s[2], t[0], t[1], t[2]
            )
        };
        std::fs::write(
            path.join(".zattrs"),
            format!(
                r#"{{"multiscales": [{{"version": "0.4", "axes": {axes}, "datasets": [{}, {}]}}]}}"#,
                level("0", [0.5, 0.25, 0.125], [10.0, 20.0, 30.0]),
                level("1", [1.0, 0.5, 0.25], [10.25, 20.125, 30.0625])
            ),
        )
        .unwrap();
        // Level n: 2 channels × (6 / (n + 1)) × 5 × 4 points, raw f4 chunks (no compressor).
        for (n, [nz, ny, nx]) in [(0usize, [6usize, 5, 4]), (1, [3, 3, 2])] {
            let folder = path.join(n.to_string());
            std::fs::create_dir_all(&folder).unwrap();
            std::fs::write(
                folder.join(".zarray"),
                format!(
                    r#"{{"zarr_format": 2, "shape": [2, {nz}, {ny}, {nx}], "chunks": [1, 4, 4, 4],
                        "dtype": "<f4", "compressor": null, "fill_value": "NaN", "order": "C",
                        "filters": null}}"#
                ),
            )
            .unwrap();
            for c in 0..2u64 {
                for cz in 0..nz.div_ceil(4) {
                    for cy in 0..ny.div_ceil(4) {
                        let mut bytes = Vec::new();
                        for z in 0..4 {
                            for y in 0..4 {
                                for x in 0..4 {
                                    let v = (c * 1000 + (cz * 4 + z) as u64 * 100) as f32
                                        + ((cy * 4 + y) * 10 + x + n * 10000) as f32;
                                    bytes.extend(v.to_le_bytes());
                                }
                            }
                        }
                        std::fs::write(folder.join(format!("{c}.{cz}.{cy}.0")), bytes).unwrap();
                    }
                }
            }
        }
        let mut options = VolumeOptions::default();
        let needs = ZarrVolume::open(&path, &options).err().unwrap().to_string();
        assert!(
            needs.contains("axis 'c' has 2 channels: choose one with --channel"),
            "{needs}"
        );
        options.channel = Some(1);
        let volume = ZarrVolume::open(&path, &options).unwrap();
        assert_eq!(volume.dims(), [4, 5, 6]);
        assert_eq!(volume.spacing(), [0.125, 0.25, 0.5]);
        assert_eq!(volume.origin(), [30.0, 20.0, 10.0]);
        let mut plane = vec![0.0; 20];
        volume.read_planes(2, &mut plane);
        assert_eq!(
            plane[0..6],
            [1200.0, 1201.0, 1202.0, 1203.0, 1210.0, 1211.0]
        );
        options.scale = Some(1);
        options.channel = Some(0);
        let coarse = ZarrVolume::open(&path, &options).unwrap();
        assert_eq!(coarse.dims(), [2, 3, 3]);
        assert_eq!(coarse.spacing(), [0.25, 0.5, 1.0]);
        assert_eq!(coarse.origin(), [30.0625, 20.125, 10.25]);
        let mut plane = vec![0.0; 6];
        coarse.read_planes(1, &mut plane);
        assert_eq!(
            plane,
            [10100.0, 10101.0, 10110.0, 10111.0, 10120.0, 10121.0]
        );
        options.scale = Some(2);
        let err = ZarrVolume::open(&path, &options).err().unwrap().to_string();
        assert!(
            err.contains("--scale 2: the image has 2 levels (0 to 1)"),
            "{err}"
        );
        options.scale = None;
        options.channel = Some(2);
        let err = ZarrVolume::open(&path, &options).err().unwrap().to_string();
        assert!(
            err.contains("--channel 2: axis 'c' has 2 channels (0 to 1)"),
            "{err}"
        );
    }

    /// A chunk that does not decode, and one of the wrong size: the planes read as NaN, and the
    /// error names the store and the chunk; reading whole fails the same way.
    #[test]
    fn damaged_chunks_are_named() {
        let dir = tempfile::tempdir().unwrap();
        let grid = Sample::Sphere.grid(20);
        let path = dir.path().join("s.zarr");
        write_zarr(&path, &grid, [8, 8, 8]).unwrap();
        std::fs::write(path.join("0/c/1/1/1"), b"not zstd").unwrap();
        let volume = ZarrVolume::open(&path, &VolumeOptions::default()).unwrap();
        let mut planes = vec![0.0; 20 * 20 * 20];
        volume.read_planes(0, &mut planes);
        assert!(planes[..20 * 20 * 8].iter().all(|v| v.is_finite()));
        assert!(planes[20 * 20 * 8..].iter().all(|v| v.is_nan()));
        let err = volume.take_error().unwrap().to_string();
        assert!(
            err.contains("s.zarr: chunk '0/c/1/1/1' (chunk grid indices 1, 1, 1)"),
            "{err}"
        );
        let whole = read_volume_oriented(&path, &VolumeOptions::default());
        assert!(whole
            .err()
            .unwrap()
            .to_string()
            .contains("chunk '0/c/1/1/1'"));
        // An uncompressed chunk of the wrong size.
        let metadata = path.join("0/zarr.json");
        let mut json: Value = serde_json::from_slice(&std::fs::read(&metadata).unwrap()).unwrap();
        json["codecs"]
            .as_array_mut()
            .unwrap()
            .retain(|c| c["name"] != "zstd");
        std::fs::write(&metadata, json.to_string()).unwrap();
        std::fs::write(path.join("0/c/0/0/0"), [0u8; 12]).unwrap();
        let err = read_volume_oriented(&path, &VolumeOptions::default())
            .err()
            .unwrap();
        assert!(err.to_string().contains("chunk '0/c/0/0/0'"), "{err}");
    }
}
