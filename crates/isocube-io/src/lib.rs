//! File formats for isocube: volume readers and mesh readers and writers, from paths or bytes.
//!
//! The core library ([`isocube`]) does no file I/O and pulls in no format crates; this crate
//! holds every format, the heavy ones behind features (`nifti`, `tiff`, `dicom`, `zarr`).
//!
//! ```
//! use isocube::extract::{extract, ExtractOptions};
//! use isocube::field::Sample;
//! use isocube_io::{read_mesh, write_mesh, MeshWriteOptions};
//! let (mesh, _) = extract(&Sample::Torus.grid(24), &ExtractOptions::default()).unwrap();
//! let dir = tempfile::tempdir().unwrap();
//! let path = dir.path().join("torus.ply");
//! write_mesh(&path, &mesh, &MeshWriteOptions::default()).unwrap();
//! assert_eq!(read_mesh(&path).unwrap().triangles, mesh.triangles);
//! ```
//!
//! Volumes: raw binary ([`RawOptions`]), NumPy `.npy` ([`NpyAxes`]), NRRD (attached `.nrrd`
//! or detached `.nhdr` headers; raw, gzip or ASCII encodings), MetaImage (`.mha`, `.mhd`; raw or
//! zlib), VTK ImageData (`.vti`: ASCII, binary or appended, raw or zlib), MINC-1 (`.mnc`,
//! `.mnc.gz`; MINC-2, which is HDF5, with the `minc2` feature), and with the `nifti`,
//! `tiff` and `dicom` features NIfTI-1 (`.nii`, `.nii.gz`), multi-page TIFF stacks and DICOM
//! series (a folder of uncompressed slices), and with `zarr` Zarr v2/v3 arrays and OME-Zarr
//! images (`ZarrVolume`, read a layer of chunks at a time). Readers of formats that
//! carry a direction return it as an [`Orientation`] ([`read_volume_oriented`]). Every reader returns a
//! [`Grid`] with `f32` values (integers above 2^24 lose precision),
//! `x` fastest.
//!
//! Meshes, chosen by file extension: PLY (binary little-endian by default, ASCII on request),
//! OBJ, binary STL, OFF, binary glTF (`.glb`), VTK PolyData (`.vtp` XML and legacy `.vtk`) and
//! Gmsh MSH 4.1 (`.msh`), with optional vertex normals and one scalar per vertex
//! ([`VertexValues`]) where the format holds them. Readers accept PLY (ASCII and both binary
//! byte orders), OBJ, STL (binary or ASCII, welded by exact position) and OFF, and
//! fan-triangulate polygons.
//!
//! Volumes larger than memory: [`MappedVolume`] maps a raw or `.npy` file and hands out planes;
//! [`PlyWriter`] writes a binary PLY piece by piece; together with
//! [`isocube::extract::extract_streamed`] the volume is never held whole.
//!
//! Writes are atomic: the mesh goes to a temporary file in the target's directory, is flushed to
//! disk, then renamed over the target. A failed write leaves the target as it was.
//!
//! Contour stacks: CSV (`section,z,contour,x,y`) and JSON ([`read_contours`]).
//!
//! Every error names the file, the position (line, byte or header field) and the reason.
#![cfg_attr(docsrs, feature(doc_cfg))]
#![warn(missing_docs)]

mod blocks;
mod contours;
#[cfg(feature = "dicom")]
mod dicom;
mod export;
#[cfg(feature = "nifti")]
mod inflating;
mod mapped;
mod mesh_io;
mod metaimage;
mod minc;
#[cfg(feature = "nifti")]
mod nifti;
mod npy;
mod nrrd;
mod poly;
mod raw;
mod tet_io;
mod tet_msh_binary;
mod tet_read;
mod tet_vtu;
#[cfg(feature = "tiff")]
mod tiff_stack;
mod vti;
#[cfg(feature = "zarr")]
mod zarr;

use std::fmt;
use std::path::{Path, PathBuf};

use thiserror::Error;

use isocube::field::{Grid, GridError, Orientation};

pub use contours::{
    parse_contours_csv, parse_contours_dxf, parse_contours_json, read_contours,
    read_contours_bytes, read_contours_bytes_with, read_contours_with, ContourOptions, ContourRead,
};
#[cfg(feature = "dicom")]
#[cfg_attr(docsrs, doc(cfg(feature = "dicom")))]
pub use dicom::{
    read_dicom_segments, read_dicom_series, read_rt_structure_set, read_rt_structure_set_bytes,
    RtRoi,
};
pub use export::VertexValues;
#[cfg(feature = "nifti")]
pub use inflating::InflatingVolume;
pub use mapped::MappedVolume;
pub use mesh_io::{
    read_mesh, read_mesh_bytes, write_file_atomic, write_mesh, write_mesh_data_to, write_mesh_to,
    write_mesh_with_values, MeshFormat, MeshWriteOptions, PlyLayout, PlyWriter,
};
pub use metaimage::read_metaimage;
#[cfg(feature = "nifti")]
#[cfg_attr(docsrs, doc(cfg(feature = "nifti")))]
pub use nifti::read_nifti;
pub use npy::{read_npy, NpyAxes};
pub use nrrd::{read_nrrd, read_nrrd_oriented};
pub use poly::{read_poly_mesh, read_poly_mesh_bytes, write_poly_mesh};
pub use raw::{read_raw, Endian, RawOptions, ScalarType};
pub use tet_io::{write_tet_mesh, write_tet_mesh_as, TetFormat};
pub use tet_read::{read_tet_mesh, read_tet_mesh_bytes};
#[cfg(feature = "tiff")]
#[cfg_attr(docsrs, doc(cfg(feature = "tiff")))]
pub use tiff_stack::read_tiff_stack;
pub use vti::read_vti;
#[cfg(feature = "zarr")]
#[cfg_attr(docsrs, doc(cfg(feature = "zarr")))]
pub use zarr::{read_zarr_block, write_zarr, ZarrVolume};

/// Where in a file a problem was found.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Position {
    /// The whole file (size, missing parts).
    File,
    /// A 1-based line of a text file or header.
    Line(usize),
    /// A byte offset.
    Byte(u64),
    /// A named header field.
    Field(String),
    /// A chunk of a chunked store, by its key (`c/0/1/2`, `0.1.2`) and its indices in the
    /// chunk grid.
    Chunk {
        /// The chunk's key in the store.
        key: String,
        /// Its indices in the chunk grid, in the array's axis order.
        indices: Vec<u64>,
    },
}

impl fmt::Display for Position {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Position::File => f.write_str("file"),
            Position::Line(n) => write!(f, "line {n}"),
            Position::Byte(n) => write!(f, "byte {n}"),
            Position::Field(name) => write!(f, "header field '{name}'"),
            Position::Chunk { key, indices } => {
                let indices: Vec<String> = indices.iter().map(u64::to_string).collect();
                write!(
                    f,
                    "chunk '{key}' (chunk grid indices {})",
                    indices.join(", ")
                )
            }
        }
    }
}

/// Why reading or writing a file failed.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum IoError {
    /// The operating system refused (missing file, permissions, full disk, …).
    #[error("{}: {source}", path.display())]
    Os {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// The file's content is malformed.
    #[error("{}: {position}: {reason}", path.display())]
    Format {
        /// The file.
        path: PathBuf,
        /// Where.
        position: Position,
        /// What is wrong.
        reason: String,
    },
    /// The file is well formed but uses something isocube does not read.
    #[error("{}: {position}: unsupported: {reason}", path.display())]
    Unsupported {
        /// The file.
        path: PathBuf,
        /// Where.
        position: Position,
        /// What is not supported.
        reason: String,
    },
    /// Reading the file would take more memory than allowed ([`VolumeOptions::max_memory`]).
    /// Checked before anything large is allocated.
    #[error(
        "{}: {position}: reading it needs {}",
        path.display(),
        over_limit(*needed, *limit)
    )]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// What sets the size (usually the dimensions field).
        position: Position,
        /// Bytes the reader would hold at its peak.
        needed: u64,
        /// The limit.
        limit: u64,
    },
    /// The file describes an invalid grid.
    #[error("{}: {source}", path.display())]
    Grid {
        /// The file.
        path: PathBuf,
        /// The grid problem.
        #[source]
        source: GridError,
    },
}

impl IoError {
    pub(crate) fn os(path: &Path, source: std::io::Error) -> IoError {
        IoError::Os {
            path: path.to_path_buf(),
            source,
        }
    }

    pub(crate) fn format(path: &Path, position: Position, reason: impl Into<String>) -> IoError {
        IoError::Format {
            path: path.to_path_buf(),
            position,
            reason: reason.into(),
        }
    }

    pub(crate) fn unsupported(
        path: &Path,
        position: Position,
        reason: impl Into<String>,
    ) -> IoError {
        IoError::Unsupported {
            path: path.to_path_buf(),
            position,
            reason: reason.into(),
        }
    }

    pub(crate) fn grid(path: &Path, source: GridError) -> IoError {
        IoError::Grid {
            path: path.to_path_buf(),
            source,
        }
    }
}

/// How to read a volume file.
#[derive(Clone, Debug, Default, PartialEq)]
#[non_exhaustive]
pub struct VolumeOptions {
    /// Layout of a raw file (required for raw files, ignored otherwise).
    pub raw: Option<RawOptions>,
    /// How `.npy` array axes map to x, y, z.
    pub npy_axes: NpyAxes,
    /// Overrides the file's spacing.
    pub spacing: Option<[f64; 3]>,
    /// Overrides the file's origin.
    pub origin: Option<[f64; 3]>,
    /// OME-Zarr images: the level to read (0, the finest, by default).
    pub scale: Option<usize>,
    /// Volumes with channels (an OME-Zarr `c` axis): the channel to read; needed where there
    /// are several.
    pub channel: Option<usize>,
    /// Volumes over time (an OME-Zarr `t` axis): the time point to read; needed where there
    /// are several.
    pub frame: Option<usize>,
    /// The most memory, in bytes, the reader may hold at its peak (file bytes, unpacked data and
    /// the `f32` values). Headers claiming more are refused with [`IoError::TooLarge`] before
    /// anything that size is allocated, and compressed data is never unpacked beyond it.
    /// `None`: no limit beyond what the file's own header asks for.
    pub max_memory: Option<u64>,
}

/// Which 3-d volume of a file holding several (frames over time, channels): the options'
/// `frame` and `channel`.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Pick {
    pub frame: Option<usize>,
    pub channel: Option<usize>,
}

impl Pick {
    pub(crate) fn of(options: &VolumeOptions) -> Pick {
        Pick {
            frame: options.frame,
            channel: options.channel,
        }
    }

    /// The index along an axis of `n` entries (`--frame` or `--channel`, as `flag` says),
    /// refusing a choice out of range, or none where there are several.
    pub(crate) fn index(
        path: &Path,
        position: Position,
        chosen: Option<usize>,
        n: usize,
        flag: &str,
        what: &str,
    ) -> Result<usize, IoError> {
        match chosen {
            Some(i) if i < n => Ok(i),
            Some(i) if n <= 1 => Err(IoError::format(
                path,
                position,
                format!("{flag} {i}: the file holds a single volume, with no {what}"),
            )),
            Some(i) => Err(IoError::format(
                path,
                position,
                format!(
                    "{flag} {i}: the file has {n} {what} (0 to {})",
                    n.max(1) - 1
                ),
            )),
            None if n <= 1 => Ok(0),
            None => Err(IoError::unsupported(
                path,
                position,
                format!("{n} {what}: choose one with {flag} (0 to {})", n - 1),
            )),
        }
    }
}

/// The memory a volume reader may take, checked before each large allocation.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Budget {
    limit: Option<u64>,
}

impl Budget {
    pub(crate) const UNLIMITED: Budget = Budget { limit: None };

    pub(crate) fn new(limit: Option<u64>) -> Budget {
        Budget { limit }
    }

    /// The limit, or `u64::MAX`.
    pub(crate) fn limit(self) -> u64 {
        self.limit.unwrap_or(u64::MAX)
    }

    /// Errs when holding `needed` bytes would pass the limit.
    pub(crate) fn check(self, path: &Path, position: Position, needed: u64) -> Result<(), IoError> {
        match self.limit {
            Some(limit) if needed > limit => Err(IoError::TooLarge {
                path: path.to_path_buf(),
                position,
                needed,
                limit,
            }),
            _ => Ok(()),
        }
    }

    /// Errs when `held` bytes plus `count` values of `f32` would pass the limit.
    pub(crate) fn check_values(
        self,
        path: &Path,
        position: Position,
        held: u64,
        count: usize,
    ) -> Result<(), IoError> {
        let needed = (count as u64).saturating_mul(4).saturating_add(held);
        self.check(path, position, needed)
    }

    /// Reads a whole file, refusing first one larger than the limit.
    pub(crate) fn read_file(self, path: &Path) -> Result<Vec<u8>, IoError> {
        self.read_file_holding(path, 0)
    }

    /// Reads a whole file while `held` bytes are already held, refusing first one that would
    /// take the total past the limit.
    pub(crate) fn read_file_holding(self, path: &Path, held: u64) -> Result<Vec<u8>, IoError> {
        if self.limit.is_some() {
            let len = std::fs::metadata(path)
                .map_err(|e| IoError::os(path, e))?
                .len();
            self.check(path, Position::File, held.saturating_add(len))?;
        }
        read_file(path)
    }
}

/// "X of memory, more than the limit of Y", exact where rounding would make the two look equal.
fn over_limit(needed: u64, limit: u64) -> String {
    let (mut n, mut l) = (human_bytes(needed), human_bytes(limit));
    if n == l {
        (n, l) = (format!("{needed} bytes"), format!("{limit} bytes"));
    }
    format!("{n} of memory, more than the limit of {l}")
}

/// `1536` → "1.5 KiB": sizes in messages.
pub(crate) fn human_bytes(n: u64) -> String {
    const UNITS: [&str; 6] = ["bytes", "KiB", "MiB", "GiB", "TiB", "PiB"];
    let mut v = n as f64;
    let mut unit = 0;
    while v >= 1024.0 && unit + 1 < UNITS.len() {
        v /= 1024.0;
        unit += 1;
    }
    if unit == 0 {
        format!("{n} bytes")
    } else {
        format!("{v:.1} {}", UNITS[unit])
    }
}

/// Reads a volume, choosing the reader by extension (see [`read_volume_oriented`]), and drops
/// its orientation: the grid's own frame, right for axis-aligned files.
pub fn read_volume(path: &Path, options: &VolumeOptions) -> Result<Grid, IoError> {
    read_volume_oriented(path, options).map(|(grid, _)| grid)
}

/// Reads a volume and how its axes lie in the world: a folder is a DICOM series (feature
/// `dicom`); files by extension: `.npy`, `.nrrd`/`.nhdr`, `.nii`/`.nii.gz` (feature `nifti`),
/// `.mnc` (MINC-1, also `.mnc.gz`; MINC-2 with feature `minc2`), `.mha`/`.mhd`, `.tif`/`.tiff` (feature `tiff`), `.vti`, otherwise raw (which needs
/// [`VolumeOptions::raw`]). Formats without a direction give [`Orientation::IDENTITY`].
pub fn read_volume_oriented(
    path: &Path,
    options: &VolumeOptions,
) -> Result<(Grid, Orientation), IoError> {
    let identity = |grid| (grid, Orientation::IDENTITY);
    let budget = Budget::new(options.max_memory);
    let read = match VolumeFormat::of(path, options)? {
        VolumeFormat::Zarr => read_zarr_volume(path, options, budget)?,
        VolumeFormat::Dicom => read_dicom_volume(path, budget, Pick::of(options))?,
        VolumeFormat::Npy => identity(npy::read_npy_within(path, options.npy_axes, budget)?),
        VolumeFormat::Nrrd => nrrd::read_nrrd_within(path, budget, Pick::of(options))?,
        VolumeFormat::MetaImage => {
            metaimage::read_metaimage_within(path, budget, Pick::of(options))?
        }
        VolumeFormat::Vti => vti::read_vti_within(path, budget)?,
        VolumeFormat::Nifti => read_nifti_volume(path, budget, Pick::of(options))?,
        VolumeFormat::Minc => minc::read_minc_within(path, budget, Pick::of(options))?,
        VolumeFormat::Tiff => identity(read_tiff_volume(path, budget, Pick::of(options))?),
        VolumeFormat::Raw(raw) => identity(raw::read_raw_within(path, raw, budget)?),
    };
    with_overrides(path, read, options)
}

/// [`read_volume_oriented`] on a file's content already in memory: an upload, an object from a
/// store, a decompressed archive member. `name` chooses the format by its extension and names
/// the volume in errors; a detached header (`.nhdr`, `.mhd`) finds its data file beside `name`.
/// A DICOM series (a folder) is read from files only.
///
/// ```
/// use std::path::Path;
/// use isocube_io::{read_volume_bytes, VolumeOptions};
/// // A 2 × 2 × 2 `.npy` of float32, written by hand.
/// let mut npy = b"\x93NUMPY\x01\x00".to_vec();
/// let header = "{'descr': '<f4', 'fortran_order': False, 'shape': (2, 2, 2), }";
/// let padded = format!("{header:<117}\n");
/// npy.extend((padded.len() as u16).to_le_bytes());
/// npy.extend(padded.as_bytes());
/// for v in 0..8 {
///     npy.extend((v as f32).to_le_bytes());
/// }
/// let (grid, _) = read_volume_bytes(&npy, Path::new("cube.npy"), &VolumeOptions::default())?;
/// assert_eq!((grid.dims(), grid.value(1, 0, 0)), ([2, 2, 2], 4.0));
/// # Ok::<(), isocube_io::IoError>(())
/// ```
pub fn read_volume_bytes(
    bytes: &[u8],
    name: &Path,
    options: &VolumeOptions,
) -> Result<(Grid, Orientation), IoError> {
    let identity = |grid| (grid, Orientation::IDENTITY);
    let budget = Budget::new(options.max_memory);
    let read = match VolumeFormat::of(name, options)? {
        VolumeFormat::Zarr => {
            return Err(IoError::unsupported(
                name,
                Position::File,
                "a Zarr store is a folder of files: read it with read_volume_oriented",
            ))
        }
        VolumeFormat::Dicom if name.is_dir() => {
            return Err(IoError::unsupported(
                name,
                Position::File,
                "a DICOM series is a folder of files: read it with read_volume_oriented",
            ))
        }
        VolumeFormat::Dicom => read_dicom_bytes(name, bytes, budget, Pick::of(options))?,
        VolumeFormat::Npy => identity(npy::read_npy_bytes(name, bytes, options.npy_axes, budget)?),
        VolumeFormat::Nrrd => nrrd::read_nrrd_bytes(name, bytes, budget, Pick::of(options))?,
        VolumeFormat::MetaImage => {
            metaimage::read_metaimage_bytes(name, bytes, budget, Pick::of(options))?
        }
        VolumeFormat::Vti => vti::read_vti_bytes(name, bytes, budget)?,
        VolumeFormat::Nifti => read_nifti_bytes(name, bytes, budget, Pick::of(options))?,
        VolumeFormat::Minc => minc::read_minc_bytes(name, bytes, budget, Pick::of(options))?,
        VolumeFormat::Tiff => identity(read_tiff_bytes(name, bytes, budget, Pick::of(options))?),
        VolumeFormat::Raw(raw) => identity(raw::read_raw_bytes(name, bytes, raw, budget)?),
    };
    with_overrides(name, read, options)
}

/// [`read_volume_bytes`] from any seekable source (a file opened elsewhere, a cursor, a
/// network stream buffered to disk): its length is checked against
/// [`VolumeOptions::max_memory`] before anything is read.
///
/// ```
/// use std::io::Cursor;
/// use std::path::Path;
/// use isocube_io::{read_volume_from, RawOptions, ScalarType, VolumeOptions};
/// let bytes: Vec<u8> = (0..27u8).collect();
/// let mut options = VolumeOptions::default();
/// options.raw = Some(RawOptions::new([3, 3, 3], ScalarType::U8));
/// let (grid, _) = read_volume_from(Cursor::new(bytes), Path::new("ramp.raw"), &options)?;
/// assert_eq!(grid.value(2, 2, 2), 26.0);
/// # Ok::<(), isocube_io::IoError>(())
/// ```
pub fn read_volume_from<R: std::io::Read + std::io::Seek>(
    mut source: R,
    name: &Path,
    options: &VolumeOptions,
) -> Result<(Grid, Orientation), IoError> {
    use std::io::SeekFrom;
    let os = |e| IoError::os(name, e);
    let len = source.seek(SeekFrom::End(0)).map_err(os)?;
    let start = source.seek(SeekFrom::Start(0)).map_err(os)?;
    Budget::new(options.max_memory).check(name, Position::File, len - start)?;
    let mut bytes = Vec::with_capacity(usize::try_from(len).unwrap_or(0));
    source.read_to_end(&mut bytes).map_err(os)?;
    read_volume_bytes(&bytes, name, options)
}

/// Which reader a volume's name (or a folder) calls for.
enum VolumeFormat<'a> {
    Zarr,
    Dicom,
    Npy,
    Nrrd,
    MetaImage,
    Vti,
    Nifti,
    Minc,
    Tiff,
    Raw(&'a RawOptions),
}

impl<'a> VolumeFormat<'a> {
    fn of(path: &Path, options: &'a VolumeOptions) -> Result<VolumeFormat<'a>, IoError> {
        let name = path
            .file_name()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .unwrap_or_default();
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .unwrap_or_default();
        Ok(match ext.as_str() {
            _ if is_zarr_store(path) => VolumeFormat::Zarr,
            _ if path.is_dir() => VolumeFormat::Dicom,
            "npy" => VolumeFormat::Npy,
            "nrrd" | "nhdr" => VolumeFormat::Nrrd,
            "mha" | "mhd" => VolumeFormat::MetaImage,
            "vti" => VolumeFormat::Vti,
            _ if name.ends_with(".nii") || name.ends_with(".nii.gz") => VolumeFormat::Nifti,
            _ if name.ends_with(".mnc") || name.ends_with(".mnc.gz") => VolumeFormat::Minc,
            "tif" | "tiff" => VolumeFormat::Tiff,
            "dcm" | "dicom" | "ima" => VolumeFormat::Dicom,
            // DICOM files often have no extension at all: they carry a marker.
            _ if options.raw.is_none() && has_dicom_marker(path) => VolumeFormat::Dicom,
            _ => match &options.raw {
                Some(raw) => VolumeFormat::Raw(raw),
                None => {
                    return Err(IoError::unsupported(
                        path,
                        Position::File,
                        "unknown volume extension: give the raw layout (dims and type) or use .npy, .nrrd, .nhdr, .nii, .nii.gz, .mnc, .mnc.gz, .mha, .mhd, .vti, .tif, .tiff, .dcm (or a DICOM folder) or a Zarr store",
                    ))
                }
            },
        })
    }
}

/// Whether a file has DICOM's "DICM" after its 128-byte preamble.
pub(crate) fn has_dicom_marker(path: &Path) -> bool {
    let mut magic = [0u8; 132];
    std::fs::File::open(path)
        .and_then(|mut f| std::io::Read::read_exact(&mut f, &mut magic))
        .is_ok()
        && &magic[128..] == b"DICM"
}

/// Whether `path` is a DICOM file, as the readers decide: named `.dcm`, `.dicom` or `.ima`, or
/// a file with DICOM's marker whatever its name.
///
/// ```
/// assert!(isocube_io::is_dicom_file(std::path::Path::new("plan.dcm")));
/// assert!(!isocube_io::is_dicom_file(std::path::Path::new("ct.nii.gz")));
/// ```
pub fn is_dicom_file(path: &Path) -> bool {
    let by_name = path
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| ["dcm", "dicom", "ima"].contains(&e.to_ascii_lowercase().as_str()));
    by_name || (path.is_file() && has_dicom_marker(path))
}

/// The read volume with the spacing and origin the options override.
fn with_overrides(
    path: &Path,
    (grid, orientation): (Grid, Orientation),
    options: &VolumeOptions,
) -> Result<(Grid, Orientation), IoError> {
    let grid = match options.spacing {
        Some(s) => grid.with_spacing(s).map_err(|e| IoError::grid(path, e))?,
        None => grid,
    };
    let grid = match options.origin {
        Some(o) => grid.with_origin(o).map_err(|e| IoError::grid(path, e))?,
        None => grid,
    };
    Ok((grid, orientation))
}

/// Whether `path` is a Zarr array or group (a folder with `zarr.json`, `.zarray` or `.zgroup`).
///
/// ```
/// assert!(!isocube_io::is_zarr_store(std::path::Path::new("/")));
/// ```
pub fn is_zarr_store(path: &Path) -> bool {
    path.is_dir()
        && ["zarr.json", ".zarray", ".zgroup"]
            .iter()
            .any(|f| path.join(f).is_file())
}

#[cfg(feature = "zarr")]
fn read_zarr_volume(
    path: &Path,
    options: &VolumeOptions,
    budget: Budget,
) -> Result<(Grid, Orientation), IoError> {
    zarr::read_zarr_within(path, options, budget)
}

#[cfg(not(feature = "zarr"))]
fn read_zarr_volume(
    path: &Path,
    _: &VolumeOptions,
    _: Budget,
) -> Result<(Grid, Orientation), IoError> {
    Err(IoError::unsupported(
        path,
        Position::File,
        "Zarr stores need isocube-io's `zarr` feature",
    ))
}

#[cfg(feature = "dicom")]
fn read_dicom_volume(
    path: &Path,
    budget: Budget,
    pick: Pick,
) -> Result<(Grid, Orientation), IoError> {
    dicom::read_dicom_within(path, budget, pick)
}

#[cfg(feature = "dicom")]
fn read_dicom_bytes(
    name: &Path,
    bytes: &[u8],
    budget: Budget,
    pick: Pick,
) -> Result<(Grid, Orientation), IoError> {
    dicom::read_dicom_bytes(name, bytes, budget, pick)
}

#[cfg(not(feature = "dicom"))]
fn read_dicom_bytes(
    name: &Path,
    _: &[u8],
    budget: Budget,
    pick: Pick,
) -> Result<(Grid, Orientation), IoError> {
    read_dicom_volume(name, budget, pick)
}

#[cfg(not(feature = "dicom"))]
fn read_dicom_volume(path: &Path, _: Budget, _: Pick) -> Result<(Grid, Orientation), IoError> {
    Err(IoError::unsupported(
        path,
        Position::File,
        "DICOM files and folders need isocube built with the `dicom` feature",
    ))
}

#[cfg(feature = "tiff")]
fn read_tiff_volume(path: &Path, budget: Budget, pick: Pick) -> Result<Grid, IoError> {
    tiff_stack::read_tiff_within(path, budget, pick)
}

#[cfg(not(feature = "tiff"))]
fn read_tiff_volume(path: &Path, _: Budget, _: Pick) -> Result<Grid, IoError> {
    Err(IoError::unsupported(
        path,
        Position::File,
        "TIFF stacks need isocube built with the `tiff` feature",
    ))
}

#[cfg(feature = "nifti")]
fn read_nifti_bytes(
    path: &Path,
    bytes: &[u8],
    budget: Budget,
    pick: Pick,
) -> Result<(Grid, Orientation), IoError> {
    nifti::read_nifti_bytes(path, bytes, budget, pick)
}

#[cfg(not(feature = "nifti"))]
fn read_nifti_bytes(
    path: &Path,
    _: &[u8],
    budget: Budget,
    pick: Pick,
) -> Result<(Grid, Orientation), IoError> {
    read_nifti_volume(path, budget, pick)
}

#[cfg(feature = "tiff")]
fn read_tiff_bytes(path: &Path, bytes: &[u8], budget: Budget, pick: Pick) -> Result<Grid, IoError> {
    tiff_stack::read_tiff_from(
        path,
        std::io::Cursor::new(bytes),
        bytes.len() as u64,
        budget,
        pick,
    )
}

#[cfg(not(feature = "tiff"))]
fn read_tiff_bytes(path: &Path, _: &[u8], budget: Budget, pick: Pick) -> Result<Grid, IoError> {
    read_tiff_volume(path, budget, pick)
}

#[cfg(feature = "nifti")]
fn read_nifti_volume(
    path: &Path,
    budget: Budget,
    pick: Pick,
) -> Result<(Grid, Orientation), IoError> {
    nifti::read_nifti_within(path, budget, pick)
}

#[cfg(not(feature = "nifti"))]
fn read_nifti_volume(path: &Path, _: Budget, _: Pick) -> Result<(Grid, Orientation), IoError> {
    Err(IoError::unsupported(
        path,
        Position::File,
        "NIfTI needs isocube built with the `nifti` feature",
    ))
}

/// Reads a whole file, mapping errors to [`IoError::Os`].
pub(crate) fn read_file(path: &Path) -> Result<Vec<u8>, IoError> {
    std::fs::read(path).map_err(|e| IoError::os(path, e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sources_larger_than_the_budget_are_refused_before_reading() {
        let options = VolumeOptions {
            raw: Some(RawOptions::new([4, 4, 4], ScalarType::F32)),
            max_memory: Some(100),
            ..VolumeOptions::default()
        };
        let source = std::io::Cursor::new(vec![0u8; 256]);
        assert!(matches!(
            read_volume_from(source, Path::new("big.raw"), &options),
            Err(IoError::TooLarge { .. })
        ));
        // Bytes that are not the format they are named as: a typed error naming them.
        let e = read_volume_bytes(b"not a volume", Path::new("x.nrrd"), &options).unwrap_err();
        assert!(e.to_string().starts_with("x.nrrd"), "{e}");
        let e = read_volume_bytes(b"", Path::new("series"), &options).unwrap_err();
        assert!(e.to_string().contains("series"), "{e}");
    }

    /// Volumes written by nibabel and SimpleITK (`tests/interop/make_volumes.py`): every value at
    /// its index, and every grid corner at the world position the writing program was given.
    #[test]
    fn volumes_from_other_programs_keep_values_and_world_geometry() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/volumes");
        let expected: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.join("expected.json")).unwrap())
                .unwrap();
        let dims: Vec<usize> = expected["dims"]
            .as_array()
            .unwrap()
            .iter()
            .map(|d| d.as_u64().unwrap() as usize)
            .collect();
        let mut checked = 0;
        for (name, file) in expected["files"].as_object().unwrap() {
            if (name.contains(".nii") && cfg!(not(feature = "nifti")))
                || (name.contains(".tif") && cfg!(not(feature = "tiff")))
                || (name.starts_with("dicom") && cfg!(not(feature = "dicom")))
            {
                continue;
            }
            let path = dir.join(name);
            let (grid, orientation) =
                read_volume_oriented(&path, &VolumeOptions::default()).unwrap();
            assert_eq!(grid.dims().to_vec(), dims, "{name}");
            // From the bytes in memory and from a seekable source: the same volume. A detached
            // header finds its data beside the name.
            if !path.is_dir() {
                let bytes = std::fs::read(&path).unwrap();
                let from_bytes = read_volume_bytes(&bytes, &path, &VolumeOptions::default());
                assert_eq!(from_bytes.unwrap(), (grid.clone(), orientation), "{name}");
                let cursor = std::io::Cursor::new(bytes);
                let from = read_volume_from(cursor, &path, &VolumeOptions::default());
                assert_eq!(from.unwrap(), (grid.clone(), orientation), "{name}");
            }
            let num = |v: &serde_json::Value| v.as_f64().unwrap();
            let (scale, offset) = (num(&file["scale"]), num(&file["offset"]));
            let linear: Vec<Vec<f64>> = file["linear"]
                .as_array()
                .unwrap()
                .iter()
                .map(|r| r.as_array().unwrap().iter().map(num).collect())
                .collect();
            let origin: Vec<f64> = file["origin"].as_array().unwrap().iter().map(num).collect();
            // Lossy encodings carry their coding error.
            let tolerance = file.get("tolerance").map_or(1e-4, num);
            for k in 0..dims[2] {
                for j in 0..dims[1] {
                    for i in 0..dims[0] {
                        let stored = (100 + i + 10 * j + 100 * k) as f64;
                        let v = f64::from(grid.values()[grid.index(i, j, k)]);
                        assert!(
                            (v - (scale * stored + offset)).abs() <= tolerance,
                            "{name} {i} {j} {k}: {v}"
                        );
                    }
                }
            }
            for corner in 0..8 {
                let ijk = [0, 1, 2].map(|a| {
                    if corner >> a & 1 == 1 {
                        (dims[a] - 1) as f64
                    } else {
                        0.0
                    }
                });
                let got = orientation.world(&grid, ijk);
                for r in 0..3 {
                    let want = origin[r] + (0..3).map(|c| linear[r][c] * ijk[c]).sum::<f64>();
                    // NIfTI keeps its map in f32.
                    assert!(
                        (got[r] - want).abs() < 1e-4 * (1.0 + want.abs()),
                        "{name} corner {corner}: {got:?}"
                    );
                }
            }
            checked += 1;
        }
        let all = expected["files"].as_object().unwrap().len();
        assert!(
            checked == all
                || cfg!(not(all(
                    feature = "nifti",
                    feature = "tiff",
                    feature = "dicom"
                )))
        );
        assert!(checked >= 2);
    }

    /// The 12-bit lossy JPEG series (`tests/interop/make_dicom.py`) gives exactly the values
    /// pydicom decodes from it (with Richter's libjpeg), kept beside it as `dicom-jpeg12.npy`:
    /// the meshes of the two are then one mesh.
    #[cfg(feature = "dicom")]
    #[test]
    fn lossy_12bit_jpeg_series_reads_as_pydicom_decodes_it() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/volumes");
        let options = VolumeOptions::default();
        let (grid, _) = read_volume_oriented(&dir.join("dicom-jpeg12"), &options).unwrap();
        let (reference, _) = read_volume_oriented(&dir.join("dicom-jpeg12.npy"), &options).unwrap();
        assert_eq!(grid.dims(), reference.dims());
        let rescaled: Vec<f32> = reference
            .values()
            .iter()
            .map(|v| 2.0 * v - 1024.0)
            .collect();
        assert_eq!(grid.values(), &rescaled[..]);
    }

    /// Every fixture cut short at many places, and with bytes flipped: readers return an error
    /// (or, for a flip in a value, a volume), never panic.
    #[test]
    fn damaged_fixtures_fail_cleanly() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/volumes");
        let work = tempfile::tempdir().unwrap();
        let mut errors = 0;
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            let name = path.file_name().unwrap().to_str().unwrap().to_string();
            if name.ends_with(".json") || name.ends_with(".raw") || path.is_dir() {
                continue;
            }
            let bytes = std::fs::read(&path).unwrap();
            let target = work.path().join(&name);
            if name.ends_with(".mhd") {
                std::fs::copy(dir.join("plain.raw"), work.path().join("plain.raw")).unwrap();
            }
            let step = (bytes.len() / 97).max(1);
            for cut in (0..bytes.len()).step_by(step) {
                std::fs::write(&target, &bytes[..cut]).unwrap();
                if read_volume_oriented(&target, &VolumeOptions::default()).is_err() {
                    errors += 1;
                }
            }
            for at in (0..bytes.len()).step_by(step) {
                let mut damaged = bytes.clone();
                damaged[at] ^= 0x5a;
                std::fs::write(&target, &damaged).unwrap();
                let _ = read_volume_oriented(&target, &VolumeOptions::default());
            }
        }
        assert!(errors > 500, "{errors}");
        // A DICOM series with one slice cut short or damaged.
        #[cfg(feature = "dicom")]
        {
            let series = work.path().join("series");
            std::fs::create_dir(&series).unwrap();
            let mut names: Vec<_> = std::fs::read_dir(dir.join("dicom"))
                .unwrap()
                .map(|e| e.unwrap().path())
                .collect();
            names.sort();
            for n in &names {
                std::fs::copy(n, series.join(n.file_name().unwrap())).unwrap();
            }
            // Slice 2 of 8: without it the others are unevenly spaced.
            let victim = series.join(names[2].file_name().unwrap());
            let bytes = std::fs::read(&victim).unwrap();
            for cut in (0..bytes.len()).step_by(7) {
                std::fs::write(&victim, &bytes[..cut]).unwrap();
                let r = read_volume_oriented(&series, &VolumeOptions::default());
                // Cut before the marker, the file is no slice: the rest are uneven.
                assert!(r.is_err(), "cut at {cut}");
            }
            for at in (0..bytes.len()).step_by(3) {
                let mut damaged = bytes.clone();
                damaged[at] ^= 0x5a;
                std::fs::write(&victim, &damaged).unwrap();
                let _ = read_volume_oriented(&series, &VolumeOptions::default());
            }
        }
    }

    /// 4-d and 5-d NIfTI (`tests/interop/make_nifti.py`): `frame` and `channel` pick one 3-d
    /// volume, from the file, its bytes and a gzip file alike; without a choice the error names
    /// `--frame` (or `--channel`) and the range, and a choice out of range is refused.
    #[test]
    #[cfg(feature = "nifti")]
    fn nifti_frames_and_channels_are_picked() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/volumes");
        let at = |g: &Grid, i: usize, j: usize, k: usize| g.values()[g.index(i, j, k)];
        let pick = |frame: Option<usize>, channel: Option<usize>| VolumeOptions {
            frame,
            channel,
            ..VolumeOptions::default()
        };
        let frames = dir.join("frames.nii");
        let bytes = std::fs::read(&frames).unwrap();
        for t in 0..3 {
            let (g, _) = read_volume_oriented(&frames, &pick(Some(t), None)).unwrap();
            assert_eq!(g.dims(), [12, 10, 8]);
            assert_eq!(g.spacing(), [1.0, 2.0, 3.0]);
            assert_eq!(at(&g, 3, 2, 1), (100 + 3 + 20 + 100 + 1000 * t) as f32);
            let (b, _) = read_volume_bytes(&bytes, &frames, &pick(Some(t), None)).unwrap();
            assert_eq!(b, g);
        }
        let e = read_volume_oriented(&frames, &pick(None, None))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("3 frames (dim[4]): choose one with --frame (0 to 2)"),
            "{e}"
        );
        let e = read_volume_oriented(&frames, &pick(Some(3), None))
            .unwrap_err()
            .to_string();
        assert!(e.contains("--frame 3: the file has 3 frames"), "{e}");
        let channels = dir.join("channels.nii.gz");
        for (t, c) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
            let (g, _) = read_volume_oriented(&channels, &pick(Some(t), Some(c))).unwrap();
            let want = 100 + 11 + 10 * 9 + 100 * 7 + 1000 * t + 10000 * c;
            assert_eq!(at(&g, 11, 9, 7), want as f32, "{t} {c}");
        }
        let e = read_volume_oriented(&channels, &pick(Some(0), None))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("2 channels (dim[5]): choose one with --channel (0 to 1)"),
            "{e}"
        );
    }

    /// 4-d MetaImage (SimpleITK: `NDims = 4`, zlib; `ElementNumberOfChannels = 2`) and NRRD
    /// (pynrrd: a `list` axis last, gzip; a `vector` axis first, interleaved) from
    /// `tests/interop/make_frames.py`: `frame` and `channel` pick the volume, the same from the
    /// bytes; without a choice the error names it.
    #[test]
    fn metaimage_and_nrrd_frames_and_channels_are_picked() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/volumes");
        let pick = |frame: Option<usize>, channel: Option<usize>| VolumeOptions {
            frame,
            channel,
            ..VolumeOptions::default()
        };
        for (name, frames, step) in [
            ("frames.mha", true, 1000),
            ("frames.nrrd", true, 1000),
            ("vectors.mha", false, 10000),
            ("vectors.nrrd", false, 10000),
        ] {
            let path = dir.join(name);
            let bytes = std::fs::read(&path).unwrap();
            let n = if frames { 3 } else { 2 };
            for t in 0..n {
                let options = if frames {
                    pick(Some(t), None)
                } else {
                    pick(None, Some(t))
                };
                let (g, _) = read_volume_oriented(&path, &options).unwrap();
                assert_eq!(g.dims(), [12, 10, 8], "{name}");
                for (i, j, k) in [(0, 0, 0), (11, 9, 7), (3, 2, 5)] {
                    let want = 100 + i + 10 * j + 100 * k + step * t;
                    assert_eq!(g.values()[g.index(i, j, k)], want as f32, "{name} {t}");
                }
                let (b, _) = read_volume_bytes(&bytes, &path, &options).unwrap();
                assert_eq!(b, g, "{name}");
            }
            let e = read_volume_oriented(&path, &pick(None, None))
                .unwrap_err()
                .to_string();
            let flag = if frames { "--frame" } else { "--channel" };
            assert!(
                e.contains(&format!("choose one with {flag} (0 to {})", n - 1)),
                "{e}"
            );
        }
    }

    /// TIFF (`tests/interop/make_frames.py`, tifffile): an ImageJ hyperstack's pages of one
    /// channel and frame make the volume (slice spacing from its description); of RGB pages
    /// one sample; without a choice the error names it.
    #[test]
    #[cfg(feature = "tiff")]
    fn tiff_channels_and_frames_are_picked() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/volumes");
        let pick = |frame: Option<usize>, channel: Option<usize>| VolumeOptions {
            frame,
            channel,
            ..VolumeOptions::default()
        };
        let points = [(0, 0, 0), (11, 9, 7), (3, 2, 5)];
        let hyper = dir.join("hyperstack.tif");
        for (t, c) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
            let (g, _) = read_volume_oriented(&hyper, &pick(Some(t), Some(c))).unwrap();
            assert_eq!((g.dims(), g.spacing()[2]), ([12, 10, 8], 2.5));
            for (i, j, k) in points {
                let want = 100 + i + 10 * j + 100 * k + 1000 * t + 10000 * c;
                assert_eq!(g.values()[g.index(i, j, k)], want as f32, "{t} {c}");
            }
        }
        let e = read_volume_oriented(&hyper, &pick(Some(0), None))
            .unwrap_err()
            .to_string();
        assert!(e.contains("choose one with --channel (0 to 1)"), "{e}");
        let e = read_volume_oriented(&hyper, &pick(None, Some(0)))
            .unwrap_err()
            .to_string();
        assert!(e.contains("choose one with --frame (0 to 1)"), "{e}");
        let rgb = dir.join("rgb.tif");
        let bytes = std::fs::read(&rgb).unwrap();
        for c in 0..3 {
            let (g, _) = read_volume_oriented(&rgb, &pick(None, Some(c))).unwrap();
            for (i, j, k) in points {
                let want = (100 + i + 10 * j + 100 * k + 40 * c) % 256;
                assert_eq!(g.values()[g.index(i, j, k)], want as f32, "{c}");
            }
            let (b, _) = read_volume_bytes(&bytes, &rgb, &pick(None, Some(c))).unwrap();
            assert_eq!(b, g);
        }
        let e = read_volume_oriented(&rgb, &pick(None, None))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("3 samples per pixel: choose one with --channel (0 to 2)"),
            "{e}"
        );
    }

    /// A DICOM SEG (`tests/interop/make_dicom.py`): five shuffled 1-bit frames of two segments
    /// become one labelled volume on the series' grid, the three slices holding neither
    /// segment put back as background; the segments' names come with it.
    #[test]
    #[cfg(feature = "dicom")]
    fn dicom_segmentations_are_labelled_volumes() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/volumes");
        let (seg, orientation) =
            read_volume_oriented(&dir.join("seg.dcm"), &VolumeOptions::default()).unwrap();
        let (series, series_orientation) =
            read_volume_oriented(&dir.join("dicom"), &VolumeOptions::default()).unwrap();
        assert_eq!(seg.dims(), series.dims());
        assert_eq!(orientation, series_orientation);
        for a in 0..3 {
            assert!((seg.spacing()[a] - series.spacing()[a]).abs() < 1e-9);
            assert!((seg.origin()[a] - series.origin()[a]).abs() < 1e-9);
        }
        let [nx, ny, nz] = seg.dims();
        let mut counts = [0usize; 3];
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    let stored = 100 + i + 10 * j + 100 * k;
                    let want = if stored < 350 {
                        1.0
                    } else if stored > 750 {
                        2.0
                    } else {
                        0.0
                    };
                    let got = seg.values()[seg.index(i, j, k)];
                    assert_eq!(got, want, "{i} {j} {k}");
                    counts[got as usize] += 1;
                }
            }
        }
        assert!(counts.iter().all(|&c| c > 50), "{counts:?}");
        let names = read_dicom_segments(&dir.join("seg.dcm")).unwrap();
        assert_eq!(names, [(1, "low".to_string()), (2, "high".to_string())]);
        assert!(read_dicom_segments(&dir.join("rtdose.dcm"))
            .unwrap()
            .is_empty());
    }

    #[test]
    fn malformed_metaimage_headers_say_where() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("bad.mha");
        let good = "ObjectType = Image\nNDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\nElementDataFile = LOCAL\n";
        std::fs::write(&p, [good.as_bytes(), &[7u8; 8]].concat()).unwrap();
        assert_eq!(read_metaimage(&p).unwrap().0.values(), &[7.0; 8]);
        for (header, data, says) in [
            (good, &[7u8; 7][..], "need 8 bytes"),
            ("NDims = 3\nDimSize = 2 2\nElementType = MET_UCHAR\nElementDataFile = LOCAL\n", &[0u8; 8][..], "line 2"),
            ("NDims = 5\n", &[][..], "NDims 5"),
            ("NDims = 3\nDimSize = 2 2 2\nElementType = MET_RGB\nElementDataFile = LOCAL\n", &[][..], "MET_RGB"),
            ("NDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\n", &[][..], "without ElementDataFile"),
            ("NDims = 3\nElementType = MET_UCHAR\nElementDataFile = LOCAL\n", &[][..], "DimSize"),
            ("NDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\nCompressedData = True\nElementDataFile = LOCAL\n", &[1u8, 2, 3][..], "zlib"),
            ("NDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\nTransformMatrix = 1 0 0 1 0 0 0 0 1\nElementDataFile = LOCAL\n", &[0u8; 8][..], "singular"),
            ("NDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\nElementDataFile = missing.raw\n", &[][..], "missing.raw"),
        ] {
            std::fs::write(&p, [header.as_bytes(), data].concat()).unwrap();
            let e = read_metaimage(&p).unwrap_err().to_string();
            assert!(e.contains(says), "{header:?}: {e}");
        }
    }
}
