//! Memory-mapped volumes: files stored uncompressed, meshed where they lie or read plane by
//! plane, for extraction slab by slab ([`isocube::extract::extract_streamed`]) from volumes
//! larger than memory.

use std::fs::File;
use std::path::{Path, PathBuf};

use memmap2::Mmap;

use super::npy::layout;
use super::raw::{check_raw_size, decode_into, Endian, ScalarType};
use super::{IoError, Position, VolumeOptions};
use isocube::field::{Grid, GridView, Orientation, PlaneSource};

/// A volume stored uncompressed (raw, `.npy`, `.nii`, MetaImage, raw NRRD, raw-appended `.vti`) mapped
/// into memory: meshed where it lies when its values are native `f32` ([`MappedVolume::view`]),
/// else decoded to `f32` a few planes at a time.
///
/// The file is checked when opened (header, size against the dimensions); the operating system
/// pages its bytes in as slabs read them, and [`PlaneSource::release_before`] lets it drop the
/// planes already meshed, so resident memory stays at a few slabs whatever the file's size.
/// The grid walks the file in its memory order, whatever the axis convention (a `.npy` saved
/// `a[x, y, z]` in C order has `x` slowest: the grid's first axis is then the file's `z`), and
/// its orientation ([`PlaneSource::orientation`]) puts each axis back where the convention says,
/// so the file is read in one sweep and the mesh lands in the right coordinates.
/// [`MappedVolume::file_point`] names a grid point as the file does.
///
/// As with any mapped file, the file must not be truncated while it is mapped.
///
/// ```no_run
/// use isocube::extract::{extract_streamed, ExtractOptions};
/// use isocube_io::{MappedVolume, PlyWriter, RawOptions, ScalarType, VolumeOptions};
/// use std::path::Path;
/// let mut options = VolumeOptions::default();
/// options.raw = Some(RawOptions::new([1024, 1024, 1024], ScalarType::U16));
/// let volume = MappedVolume::open(Path::new("ct.raw"), &options)?;
/// let mut ply = PlyWriter::create(Path::new("ct.ply"), true)?;
/// let extract = ExtractOptions::default().with_level(1200.0);
/// extract_streamed(&volume, &extract, &mut ply, &mut isocube::no_progress)?;
/// ply.finish()?;
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub struct MappedVolume {
    path: PathBuf,
    map: Mmap,
    scalar: ScalarType,
    endian: Endian,
    dims: [usize; 3],
    spacing: [f64; 3],
    origin: [f64; 3],
    orientation: Orientation,
    /// `stored * slope + intercept` (NIfTI's `scl_slope`, `scl_inter`), when not the identity.
    scale: Option<(f32, f32)>,
    /// Element strides of x, y and z.
    strides: [usize; 3],
    data_offset: usize,
    /// The file's axis (x, y, z) that each grid axis walks, fastest first.
    axes: [usize; 3],
}

/// Where a format keeps its values uncompressed (x fastest, then y, then z), and how its grid
/// lies in the world: what a header reader hands to [`MappedVolume`].
pub(crate) struct Placement {
    /// The file holding the values, when not the header's own (`.mhd` + `.raw`).
    pub(crate) data_file: Option<PathBuf>,
    /// Byte offset of the first value in that file.
    pub(crate) offset: usize,
    pub(crate) scalar: ScalarType,
    pub(crate) endian: Endian,
    pub(crate) dims: [usize; 3],
    pub(crate) spacing: [f64; 3],
    pub(crate) origin: [f64; 3],
    pub(crate) orientation: Orientation,
    pub(crate) scale: Option<(f32, f32)>,
}

/// The formats [`MappedVolume`] can hold, by a path's name.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Kind {
    Npy,
    Nifti,
    MetaImage,
    Vti,
    Nrrd,
    Other,
}

fn kind(path: &Path) -> Kind {
    let name = path
        .file_name()
        .and_then(|n| n.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    match name.rsplit('.').next().unwrap_or("") {
        "npy" => Kind::Npy,
        "nii" => Kind::Nifti,
        "mha" | "mhd" => Kind::MetaImage,
        "vti" => Kind::Vti,
        "nrrd" | "nhdr" => Kind::Nrrd,
        _ => Kind::Other,
    }
}

impl MappedVolume {
    /// Maps a volume whose values are stored uncompressed: `.npy`, a raw file laid out as
    /// [`VolumeOptions::raw`] says, NIfTI `.nii` (with the `nifti` feature), MetaImage
    /// (`.mha`, `.mhd`), raw NRRD (`.nrrd`, `.nhdr`) and VTK ImageData (`.vti` with raw
    /// appended data). Compressed files are refused (read them with [`super::read_volume`]);
    /// [`MappedVolume::try_open`] tells them apart without an error.
    pub fn open(path: &Path, options: &VolumeOptions) -> Result<MappedVolume, IoError> {
        MappedVolume::try_open(path, options)?.ok_or_else(|| {
            IoError::unsupported(
                path,
                Position::File,
                "only uncompressed raw, .npy, .nii, .mha/.mhd, raw .nrrd/.nhdr and raw-appended .vti volumes can be mapped",
            )
        })
    }

    /// [`MappedVolume::open`], or `None` for a file whose format or encoding cannot be mapped
    /// (compressed, ASCII, or a format without a mapped reader): read that one instead. Errors
    /// are those of a malformed header or a file too short for its data.
    pub fn try_open(path: &Path, options: &VolumeOptions) -> Result<Option<MappedVolume>, IoError> {
        let kind = kind(path);
        if options.raw.is_none() && kind == Kind::Other {
            return Ok(None);
        }
        let file = File::open(path).map_err(|e| IoError::os(path, e))?;
        // SAFETY: the map is read-only; the documented condition is that the file is not
        // truncated meanwhile, as for every reader of a mapped file.
        let map = unsafe { Mmap::map(&file) }.map_err(|e| IoError::os(path, e))?;
        let placement = match (kind, &options.raw) {
            (Kind::Npy, _) | (_, Some(_)) => None,
            #[cfg(feature = "nifti")]
            (Kind::Nifti, None) => super::nifti::placement(path, &map)?,
            (Kind::MetaImage, None) => super::metaimage::placement(path, &map)?,
            (Kind::Vti, None) => super::vti::placement(path, &map)?,
            (Kind::Nrrd, None) => super::nrrd::placement(path, &map)?,
            _ => return Ok(None),
        };
        let volume = match placement {
            Some(p) => MappedVolume::placed(path, map, p, options)?,
            None if kind == Kind::Npy || options.raw.is_some() => {
                MappedVolume::npy_or_raw(path, map, kind == Kind::Npy, options)?
            }
            None => return Ok(None),
        };
        if volume.planes_contiguous() {
            let _ = volume.map.advise(memmap2::Advice::Sequential);
        }
        Ok(Some(volume))
    }

    fn npy_or_raw(
        path: &Path,
        map: Mmap,
        is_npy: bool,
        options: &VolumeOptions,
    ) -> Result<MappedVolume, IoError> {
        let (scalar, endian, dims, strides, data_offset) = if is_npy {
            let l = layout(path, &map, options.npy_axes)?;
            (l.scalar, l.endian, l.dims, l.strides, l.data_offset)
        } else {
            let raw = options.raw.as_ref().ok_or_else(|| {
                IoError::unsupported(
                    path,
                    Position::File,
                    "only raw (with dims and type) and .npy volumes can be mapped",
                )
            })?;
            let count = Grid::point_count(raw.dims).map_err(|e| IoError::grid(path, e))?;
            check_raw_size(path, raw, count, map.len() as u64)?;
            let [nx, ny, _] = raw.dims;
            (
                raw.scalar,
                raw.endian,
                raw.dims,
                [1, nx, nx * ny],
                raw.header_bytes as usize,
            )
        };
        let (mut spacing, mut origin) = match (&options.raw, is_npy) {
            (Some(raw), false) => (raw.spacing, raw.origin),
            _ => ([1.0; 3], [0.0; 3]),
        };
        if let Some(s) = options.spacing {
            spacing = s;
        }
        if let Some(o) = options.origin {
            origin = o;
        }
        // The same checks as a grid's.
        Grid::new([2, 2, 2], vec![0.0; 8])
            .and_then(|g| g.with_spacing(spacing))
            .and_then(|g| g.with_origin(origin))
            .map_err(|e| IoError::grid(path, e))?;
        // The grid is walked in the file's memory order, whatever the axis convention: its
        // axes are the array's from the fastest to the slowest, and the orientation puts each
        // back on its world axis (the surface is the same; only the order of vertices and
        // triangles follows the walk).
        let mut axes = [0, 1, 2];
        axes.sort_by_key(|&a| strides[a]);
        let orientation = Orientation::axes(axes).expect("a permutation of the axes");
        Ok(MappedVolume {
            path: path.to_path_buf(),
            map,
            scalar,
            endian,
            dims: axes.map(|a| dims[a]),
            spacing: axes.map(|a| spacing[a]),
            origin,
            orientation,
            scale: None,
            strides: axes.map(|a| strides[a]),
            data_offset,
            axes,
        })
    }

    /// Where grid point `p` (in the order the volume is walked) lies in the file's own indices
    /// (x, y, z as the axis convention names them).
    pub fn file_point(&self, p: [usize; 3]) -> [usize; 3] {
        let mut out = [0; 3];
        for (a, &world) in self.axes.iter().enumerate() {
            out[world] = p[a];
        }
        out
    }

    /// The file's axis (x, y, z as the axis convention names them) that each grid axis walks,
    /// fastest first: `[0, 1, 2]` for every format but `.npy` files stored with `x` slowest.
    ///
    /// ```no_run
    /// use isocube_io::{MappedVolume, VolumeOptions};
    /// use std::path::Path;
    /// // An array saved by NumPy in C order: its last axis (z) is the fastest.
    /// let volume = MappedVolume::open(Path::new("ct.npy"), &VolumeOptions::default())?;
    /// assert_eq!(volume.file_axes(), [2, 1, 0]);
    /// # Ok::<(), isocube_io::IoError>(())
    /// ```
    pub fn file_axes(&self) -> [usize; 3] {
        self.axes
    }

    /// Every value as `f32` in a grid that walks the file as slab-wise extraction does (in the
    /// file's memory order, see [`MappedVolume::file_axes`]), with the volume's spacing and
    /// origin; the orientation ([`PlaneSource::orientation`]) turns it into the world. Meshing
    /// this grid, slab by slab from the map, or the map in place gives one mesh, to the byte:
    /// whole-volume work (ternary snapping, relaxation, boxes of cells) on a converted file
    /// must start here, not from the file read in its index order, whose frame cuts cells and
    /// orders vertices otherwise.
    ///
    /// Refused with [`IoError::TooLarge`] before anything is allocated when the values need
    /// more than `max_memory` bytes.
    ///
    /// ```no_run
    /// use isocube::extract::{extract, extract_streamed, ExtractOptions};
    /// use isocube::field::PlaneSource;
    /// use isocube::mesh::Mesh;
    /// use isocube_io::{MappedVolume, VolumeOptions};
    /// use std::path::Path;
    /// let volume = MappedVolume::open(Path::new("ct.npy"), &VolumeOptions::default())?;
    /// let grid = volume.read_whole(None)?;
    /// let options = ExtractOptions::default().with_level(300.0);
    /// let (whole, _) = extract(grid.view().with_orientation(volume.orientation()), &options)?;
    /// let mut slabs = Mesh::new();
    /// extract_streamed(&volume, &options, &mut slabs, &mut isocube::no_progress)?;
    /// assert_eq!(whole, slabs);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn read_whole(&self, max_memory: Option<u64>) -> Result<Grid, IoError> {
        let count = Grid::point_count(self.dims).map_err(|e| IoError::grid(&self.path, e))?;
        super::Budget::new(max_memory).check_values(&self.path, Position::File, 0, count)?;
        let mut values = vec![0.0f32; count];
        let plane = self.dims[0] * self.dims[1];
        // A few planes per task: decoding is the work, and it splits cleanly along z.
        let batch = ((1 << 20) / plane.max(1)).max(1);
        use rayon::prelude::*;
        values
            .par_chunks_mut(plane * batch)
            .enumerate()
            .for_each(|(n, out)| self.read_planes(n * batch, out));
        Grid::new(self.dims, values)
            .and_then(|g| g.with_spacing(self.spacing))
            .and_then(|g| g.with_origin(self.origin))
            .map_err(|e| IoError::grid(&self.path, e))
    }

    /// A volume a header placed (in the header's own file or a data file beside it), its size
    /// checked against the dimensions; `--spacing` and `--origin` override the header's.
    fn placed(
        path: &Path,
        map: Mmap,
        p: Placement,
        options: &VolumeOptions,
    ) -> Result<MappedVolume, IoError> {
        let (data_path, map) = match &p.data_file {
            None => (path.to_path_buf(), map),
            Some(file) => {
                let f = File::open(file).map_err(|e| IoError::os(file, e))?;
                // SAFETY: as for the header's file.
                let data = unsafe { Mmap::map(&f) }.map_err(|e| IoError::os(file, e))?;
                (file.clone(), data)
            }
        };
        let count = Grid::point_count(p.dims).map_err(|e| IoError::grid(path, e))?;
        let need = count.checked_mul(p.scalar.size());
        let end = need.and_then(|n| n.checked_add(p.offset));
        if end.is_none_or(|end| end > map.len()) {
            return Err(IoError::format(
                &data_path,
                Position::File,
                format!(
                    "{:?} {} values need {} bytes from byte {}, the file has {}",
                    p.dims,
                    p.scalar,
                    need.unwrap_or(usize::MAX),
                    p.offset,
                    map.len()
                ),
            ));
        }
        let spacing = options.spacing.unwrap_or(p.spacing);
        let origin = options.origin.unwrap_or(p.origin);
        // The same checks as a grid's.
        Grid::new([2, 2, 2], vec![0.0; 8])
            .and_then(|g| g.with_spacing(spacing))
            .and_then(|g| g.with_origin(origin))
            .map_err(|e| IoError::grid(path, e))?;
        let [nx, ny, _] = p.dims;
        Ok(MappedVolume {
            path: path.to_path_buf(),
            map,
            scalar: p.scalar,
            endian: p.endian,
            dims: p.dims,
            spacing,
            origin,
            orientation: p.orientation,
            scale: p.scale,
            strides: [1, nx, nx * ny],
            data_offset: p.offset,
            axes: [0, 1, 2],
        })
    }

    /// The same volume in grid index space: spacing 1, origin 0, no direction.
    pub fn into_index_space(self) -> MappedVolume {
        MappedVolume {
            spacing: [1.0; 3],
            origin: [0.0; 3],
            // The file's point (i, j, k) at (i, j, k), whichever order the grid walks.
            orientation: Orientation::axes(self.axes).expect("a permutation of the axes"),
            ..self
        }
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The stored value type.
    pub fn scalar(&self) -> ScalarType {
        self.scalar
    }

    /// Whether each `z` plane is one contiguous run of the file (read in one sweep).
    pub fn planes_contiguous(&self) -> bool {
        self.strides[0] == 1 && self.strides[2] == self.dims[0] * self.dims[1]
    }

    fn data(&self) -> &[u8] {
        &self.map[self.data_offset..]
    }

    /// The mapped values as a grid view, read where they lie (any axis convention and memory
    /// order), when they are `f32` in this machine's byte order at an aligned offset: `None`
    /// otherwise (other types are converted slab by slab by [`PlaneSource::read_planes`]).
    ///
    /// ```no_run
    /// use isocube::extract::{extract, ExtractOptions};
    /// use isocube_io::{MappedVolume, VolumeOptions};
    /// use std::path::Path;
    /// let volume = MappedVolume::open(Path::new("scan.npy"), &VolumeOptions::default())?;
    /// if let Some(view) = volume.view() {
    ///     let (mesh, _) = extract(view, &ExtractOptions::default().with_level(0.5))?;
    ///     println!("{} triangles, no copy of the volume", mesh.triangle_count());
    /// }
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn view(&self) -> Option<GridView<'_>> {
        if self.scalar != ScalarType::F32 || !self.endian.is_native() || self.scale.is_some() {
            return None;
        }
        // The map starts on a page; the data is aligned when its offset is.
        let values: &[f32] = bytemuck::try_cast_slice(self.data()).ok().or_else(|| {
            let data = self.data();
            bytemuck::try_cast_slice(&data[..data.len() / 4 * 4]).ok()
        })?;
        GridView::strided(values, self.dims, self.strides)
            .and_then(|v| v.with_spacing(self.spacing))
            .and_then(|v| v.with_origin(self.origin))
            .map(|v| v.with_orientation(self.orientation))
            .ok()
    }
}

impl MappedVolume {
    /// The stored values of planes `first, …` as `f32`, before any scale.
    fn read_stored_planes(&self, first: usize, out: &mut [f32]) {
        // Every layout is walked in memory order (`npy_or_raw`, `placed`): a plane is one run.
        debug_assert!(self.planes_contiguous());
        let size = self.scalar.size();
        let at = first * self.strides[2] * size;
        decode_into(
            &self.data()[at..at + out.len() * size],
            self.scalar,
            self.endian,
            out,
        );
    }
}

impl PlaneSource for MappedVolume {
    fn dims(&self) -> [usize; 3] {
        self.dims
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
        self.read_stored_planes(first, out);
        if let Some((slope, intercept)) = self.scale {
            for v in out.iter_mut() {
                *v = *v * slope + intercept;
            }
        }
    }

    fn release_before(&self, plane: usize) {
        if !self.planes_contiguous() || plane == 0 {
            return;
        }
        let len = plane * self.strides[2] * self.scalar.size();
        // SAFETY: the map is a read-only shared file mapping: dropped pages are read again from
        // the file if touched, with the same bytes; nothing refers into the released range.
        let _ = unsafe {
            self.map.unchecked_advise_range(
                memmap2::UncheckedAdvice::DontNeed,
                self.data_offset,
                len,
            )
        };
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{read_volume, write_mesh, MeshWriteOptions, NpyAxes, PlyWriter, RawOptions};
    use isocube::extract::{extract, extract_streamed, ExtractOptions};

    /// A u16 volume with blobs and integer ties at the level.
    fn values(dims: [usize; 3]) -> Vec<u16> {
        let mut out = Vec::new();
        for k in 0..dims[2] {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    let p = [i, j, k].map(|c| c as f64);
                    let v = 1000.0
                        + 400.0 * (p[0] * 0.31).sin() * (p[1] * 0.23).cos()
                        + 300.0 * (p[2] * 0.17).sin();
                    out.push(v.round() as u16);
                }
            }
        }
        out
    }

    fn npy(shape: [usize; 3], fortran: bool, data: &[u16]) -> Vec<u8> {
        let mut out = npy_header("<u2", shape, fortran);
        for v in data {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out
    }

    /// A version 1.0 `.npy` header, padded so the data start on a 64-byte boundary.
    fn npy_header(descr: &str, shape: [usize; 3], fortran: bool) -> Vec<u8> {
        let dict = format!(
            "{{'descr': '{descr}', 'fortran_order': {}, 'shape': ({}, {}, {}), }}",
            if fortran { "True" } else { "False" },
            shape[0],
            shape[1],
            shape[2]
        );
        let mut header = dict.into_bytes();
        while (10 + header.len() + 1) % 64 != 0 {
            header.push(b' ');
        }
        header.push(b'\n');
        let mut out = b"\x93NUMPY\x01\x00".to_vec();
        out.extend_from_slice(&(header.len() as u16).to_le_bytes());
        out.extend_from_slice(&header);
        out
    }

    /// Every mappable layout streams to the same PLY bytes as reading the volume, extracting in
    /// memory and writing the mesh.
    #[test]
    fn streamed_ply_equals_in_memory_ply() {
        let dir = tempfile::tempdir().unwrap();
        let dims = [23, 19, 41];
        let v = values(dims);
        // The same field in x-fastest order, and transposed to x-slowest (C-order `xyz`).
        let mut xyz = vec![0u16; v.len()];
        for k in 0..dims[2] {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    xyz[(i * dims[1] + j) * dims[2] + k] = v[i + dims[0] * (j + dims[1] * k)];
                }
            }
        }
        let raw_bytes: Vec<u8> = v.iter().flat_map(|x| x.to_le_bytes()).collect();
        let cases: Vec<(&str, Vec<u8>, VolumeOptions, bool)> = vec![
            (
                "v.raw",
                raw_bytes,
                VolumeOptions {
                    raw: Some(RawOptions {
                        spacing: [0.5, 0.7, 1.25],
                        origin: [-3.0, 2.0, 10.0],
                        ..RawOptions::new(dims, ScalarType::U16)
                    }),
                    ..VolumeOptions::default()
                },
                true,
            ),
            (
                "zyx.npy",
                npy([dims[2], dims[1], dims[0]], false, &v),
                VolumeOptions {
                    npy_axes: NpyAxes::Zyx,
                    spacing: Some([1.0, 1.0, 2.5]),
                    ..VolumeOptions::default()
                },
                true,
            ),
            (
                "zyx-plain.npy",
                npy([dims[2], dims[1], dims[0]], false, &v),
                VolumeOptions {
                    npy_axes: NpyAxes::Zyx,
                    ..VolumeOptions::default()
                },
                true,
            ),
            (
                "fortran.npy",
                npy(dims, true, &v),
                VolumeOptions::default(),
                true,
            ),
            (
                "c.npy",
                npy(dims, false, &xyz),
                VolumeOptions::default(),
                true,
            ),
        ];
        let extract_options = ExtractOptions::default().with_level(1000.0);
        let mut reference: Option<Vec<u8>> = None;
        for (name, bytes, options, contiguous) in cases {
            let input = dir.path().join(name);
            std::fs::write(&input, bytes).unwrap();
            let grid = read_volume(&input, &options).unwrap();
            let volume = MappedVolume::open(&input, &options).unwrap();
            assert_eq!(volume.planes_contiguous(), contiguous, "{name}");
            // The mapped volume walks the file in memory order: its grid axis `a` is the file's
            // axis `axes[a]`. The reader's grid seen in that order is the reference.
            let axes: [usize; 3] = std::array::from_fn(|a| {
                let mut p = [0; 3];
                p[a] = 1;
                volume.file_point(p).iter().position(|&c| c == 1).unwrap()
            });
            let g = grid.dims();
            let strides = [1, g[0], g[0] * g[1]];
            let walked =
                GridView::strided(grid.values(), axes.map(|a| g[a]), axes.map(|a| strides[a]))
                    .and_then(|v| v.with_spacing(axes.map(|a| grid.spacing()[a])))
                    .and_then(|v| v.with_origin(grid.origin()))
                    .unwrap()
                    .with_orientation(PlaneSource::orientation(&volume));
            assert_eq!(PlaneSource::dims(&volume), walked.dims());
            let mesh = extract(walked, &extract_options).unwrap().0;
            assert!(mesh.triangle_count() > 1000);
            let memory = dir.path().join("memory.ply");
            write_mesh(&memory, &mesh, &MeshWriteOptions::default()).unwrap();
            if axes != [0, 1, 2] {
                // The same surface as the reader's grid gives: the same vertices; the cells'
                // polygons are cut into triangles in the walk's frame.
                let direct = extract(&grid, &extract_options).unwrap().0;
                let mut a = direct.positions.clone();
                let mut b = mesh.positions.clone();
                let key = |p: &[f32; 3]| p.map(f32::to_bits);
                a.sort_by_key(key);
                b.sort_by_key(key);
                assert_eq!(a, b, "{name}");
                assert_eq!(direct.triangle_count(), mesh.triangle_count(), "{name}");
            }
            let out = dir.path().join("streamed.ply");
            let mut ply = PlyWriter::create(&out, true).unwrap();
            extract_streamed(
                &volume,
                &extract_options,
                &mut ply,
                &mut isocube::no_progress,
            )
            .unwrap();
            ply.finish().unwrap();
            let streamed = std::fs::read(&out).unwrap();
            assert_eq!(streamed, std::fs::read(&memory).unwrap(), "{name}");
            // Same field, same mesh, whatever the layout (geometry aside).
            if name.ends_with(".npy") && options.spacing.is_none() && axes == [0, 1, 2] {
                match &reference {
                    Some(r) => assert_eq!(&streamed, r, "{name}"),
                    None => reference = Some(streamed),
                }
            }
            volume.release_before(10);
        }
        // Only the outputs and inputs are left: no temporary files.
        let names: Vec<String> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        assert!(names.iter().all(|n| !n.ends_with(".tmp")), "{names:?}");
    }

    /// Meshing a mapped file (in place for `f32`, slab by slab otherwise) gives the mesh of
    /// the reader's grid, oriented: NIfTI with a reflected sform, its values scaled; MetaImage
    /// with a rotation, attached and detached; raw appended VTI. Compressed files are not
    /// mapped.
    #[test]
    fn mapped_formats_mesh_as_their_readers() {
        let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/volumes");
        let dir = tempfile::tempdir().unwrap();
        // flipped.nii with scl_slope 2 and scl_inter -3 (header bytes 112 and 116).
        let mut nii = std::fs::read(data.join("flipped.nii")).unwrap();
        nii[112..116].copy_from_slice(&2.0f32.to_le_bytes());
        nii[116..120].copy_from_slice(&(-3.0f32).to_le_bytes());
        let scaled = dir.path().join("scaled.nii");
        std::fs::write(&scaled, nii).unwrap();
        // A rotated, reflected MetaImage with its u16 values after the header.
        let dims = [9, 7, 6];
        let mut mha = format!(
            "ObjectType = Image\nNDims = 3\nDimSize = {} {} {}\nElementType = MET_USHORT\n\
             ElementSpacing = 0.5 0.75 1.25\nOffset = 1 2 3\n\
             TransformMatrix = 0 1 0 1 0 0 0 0 -1\nElementDataFile = LOCAL\n",
            dims[0], dims[1], dims[2]
        )
        .into_bytes();
        mha.extend(values(dims).iter().flat_map(|v| v.to_le_bytes()));
        let rotated = dir.path().join("rotated-raw.mha");
        std::fs::write(&rotated, mha).unwrap();
        // A raw NRRD with oblique axes, attached; and a detached one whose values end its
        // data file (`byte skip: -1`).
        let nrrd_head = format!(
            "NRRD0004\ntype: uint16\ndimension: 3\nspace: left-posterior-superior\n\
             sizes: {} {} {}\nspace directions: (0,0.5,0) (0.75,0,0) (0,0,-1.25)\n\
             space origin: (1,2,3)\nendian: little\n",
            dims[0], dims[1], dims[2]
        );
        let stored: Vec<u8> = values(dims).iter().flat_map(|v| v.to_le_bytes()).collect();
        let attached = dir.path().join("oblique-raw.nrrd");
        let mut bytes = format!("{nrrd_head}encoding: raw\n\n").into_bytes();
        bytes.extend_from_slice(&stored);
        std::fs::write(&attached, bytes).unwrap();
        let detached = dir.path().join("detached.nhdr");
        std::fs::write(
            &detached,
            format!("{nrrd_head}encoding: raw\nbyte skip: -1\ndata file: detached.raw\n"),
        )
        .unwrap();
        std::fs::write(
            dir.path().join("detached.raw"),
            [&[7u8; 13][..], &stored].concat(),
        )
        .unwrap();
        let options = VolumeOptions::default();
        for (path, level, in_place) in [
            (data.join("flipped.nii"), 455.5, true),
            (scaled, 900.0, false),
            (rotated, 1200.0, false),
            (data.join("plain.mhd"), 455.5, false),
            (data.join("appended-raw.vti"), 455.5, false),
            (attached, 1200.0, false),
            (detached, 1200.0, false),
        ] {
            // Without the `nifti` feature neither path reads NIfTI.
            if !cfg!(feature = "nifti") && path.extension().is_some_and(|e| e == "nii") {
                continue;
            }
            let (grid, orientation) = crate::read_volume_oriented(&path, &options).unwrap();
            let extract_options = ExtractOptions::default().with_level(level);
            let (expected, _) =
                extract(grid.view().with_orientation(orientation), &extract_options).unwrap();
            assert!(!expected.triangles.is_empty(), "{}", path.display());
            let volume = MappedVolume::open(&path, &options).unwrap();
            assert_eq!(volume.view().is_some(), in_place, "{}", path.display());
            let mesh = match volume.view() {
                Some(view) => extract(view, &extract_options).unwrap().0,
                None => {
                    let mut mesh = isocube::mesh::Mesh::new();
                    extract_streamed(
                        &volume,
                        &extract_options,
                        &mut mesh,
                        &mut isocube::no_progress,
                    )
                    .unwrap();
                    mesh
                }
            };
            assert_eq!(mesh, expected, "{}", path.display());
        }
        for compressed in [
            "rotated.mha",
            "binary-zlib.vti",
            "appended-base64.vti",
            "rotated.nii.gz",
        ] {
            let path = data.join(compressed);
            assert!(
                MappedVolume::try_open(&path, &options).unwrap().is_none(),
                "{compressed}"
            );
        }
    }

    #[test]
    fn bad_files_are_refused_before_mapping_is_used() {
        let dir = tempfile::tempdir().unwrap();
        let input = dir.path().join("short.raw");
        std::fs::write(&input, vec![0u8; 99]).unwrap();
        let options = VolumeOptions {
            raw: Some(RawOptions::new([5, 5, 2], ScalarType::U16)),
            ..VolumeOptions::default()
        };
        let e = MappedVolume::open(&input, &options)
            .err()
            .unwrap()
            .to_string();
        assert!(
            e.contains("short.raw") && e.contains("need 100 bytes"),
            "{e}"
        );
        let e = MappedVolume::open(&input, &VolumeOptions::default())
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("only uncompressed raw"), "{e}");
        let npy_path = dir.path().join("bad.npy");
        std::fs::write(&npy_path, b"\x93NUMPY\x01\x00\x05\x00{}").unwrap();
        assert!(MappedVolume::open(&npy_path, &VolumeOptions::default()).is_err());
        let missing = dir.path().join("missing.raw");
        assert!(MappedVolume::open(&missing, &options).is_err());
    }

    /// A `.npy` of `values` (x fastest in `values`) stored as `descr`, C order `a[x, y, z]`
    /// (`fortran`: x fastest) — small integers plus `offset`.
    fn npy_of(
        descr: &str,
        dims: [usize; 3],
        values: &[i32],
        offset: i32,
        fortran: bool,
    ) -> Vec<u8> {
        let mut out = npy_header(descr, dims, fortran);
        let [nx, ny, nz] = dims;
        let mut put = |v: i32| match descr {
            "|u1" => out.push(v as u8),
            "<i2" => out.extend((v as i16).to_le_bytes()),
            ">i4" => out.extend(v.to_be_bytes()),
            "<f4" => out.extend((v as f32).to_le_bytes()),
            _ => out.extend(f64::from(v).to_le_bytes()),
        };
        if fortran {
            values.iter().for_each(|&v| put(v + offset));
        } else {
            for i in 0..nx {
                for j in 0..ny {
                    for k in 0..nz {
                        put(values[i + nx * (j + ny * k)] + offset);
                    }
                }
            }
        }
        out
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig { cases: 48, ..Default::default() })]

        /// The same tied integers stored as any type, C or Fortran order: the file read in
        /// place (`f32`), converted slab by slab, read whole and cut into any boxes, and read
        /// whole for ternary snapping all give one mesh — the frame and the tie rule are the
        /// same on every path.
        #[test]
        fn converted_types_mesh_as_the_file_in_place_on_every_path(
            nx in 2usize..8, ny in 2usize..8, nz in 2usize..8, seed: u64, fortran: bool,
            level in -1i32..2, sizes in proptest::array::uniform3(1usize..5),
        ) {
            let dims = [nx, ny, nz];
            let mut state = seed | 1;
            let values: Vec<i32> = (0..nx * ny * nz)
                .map(|_| {
                    state ^= state << 13;
                    state ^= state >> 7;
                    state ^= state << 17;
                    (state % 5) as i32 - 2
                })
                .collect();
            let dir = tempfile::tempdir().unwrap();
            let options = VolumeOptions::default();
            let open = |descr: &str, offset: i32| {
                let path = dir.path().join(format!("{}.npy", descr.replace(['<', '>', '|'], "")));
                std::fs::write(&path, npy_of(descr, dims, &values, offset, fortran)).unwrap();
                MappedVolume::open(&path, &options).unwrap()
            };
            let float = open("<f4", 0);
            let view = float.view().expect("f32 is read in place");
            let mc = ExtractOptions::default().with_level(level as f32);
            let ternary = mc.with_method(isocube::extract::Method::Ternary(Default::default()));
            let in_place = extract(view, &mc).unwrap().0;
            let in_place_ternary = extract(view, &ternary).unwrap().0;
            let boxes = isocube::extract::CellBox::tile(view.dims(), sizes).unwrap();
            for (descr, offset) in [("|u1", 2), ("<i2", 0), (">i4", 0), ("<f8", 0), ("<f4", 0)] {
                let volume = open(descr, offset);
                let mc = mc.with_level((level + offset) as f32);
                let ternary = ternary.with_level((level + offset) as f32);
                let mut slabs = isocube::mesh::Mesh::new();
                extract_streamed(&volume, &mc, &mut slabs, &mut isocube::no_progress).unwrap();
                proptest::prop_assert_eq!(&slabs, &in_place, "{} slab by slab", descr);
                let grid = volume.read_whole(None).unwrap();
                let whole = grid.view().with_orientation(volume.orientation());
                let cut = isocube::extract::extract_boxes(whole, &mc, &boxes).unwrap().0;
                proptest::prop_assert_eq!(&cut, &in_place, "{} boxes {:?}", descr, sizes);
                let snapped = extract(whole, &ternary).unwrap().0;
                proptest::prop_assert_eq!(&snapped, &in_place_ternary, "{} ternary", descr);
            }
        }
    }

    /// A failed stream (the writer dropped before `finish`) leaves the target as it was.
    #[test]
    fn unfinished_stream_leaves_target_untouched() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("keep.ply");
        std::fs::write(&out, b"old").unwrap();
        {
            let mut ply = PlyWriter::create(&out, false).unwrap();
            let grid = isocube::field::Sample::Sphere.grid(12);
            extract_streamed(
                &grid,
                &ExtractOptions::default(),
                &mut ply,
                &mut isocube::no_progress,
            )
            .unwrap();
        }
        assert_eq!(std::fs::read(&out).unwrap(), b"old");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }
}
