//! Volume readers and mesh readers/writers (feature `io`).
//!
//! Volumes: raw binary ([`RawOptions`]), NumPy `.npy` ([`NpyAxes`]) and NRRD (attached `.nrrd`
//! or detached `.nhdr` headers; raw, gzip or ASCII encodings). Every reader returns a
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
//! [`crate::extract::extract_streamed`] the volume is never held whole.
//!
//! Writes are atomic: the mesh goes to a temporary file in the target's directory, is flushed to
//! disk, then renamed over the target. A failed write leaves the target as it was.
//!
//! Contour stacks: CSV (`section,z,contour,x,y`) and JSON ([`read_contours`]).
//!
//! Every error names the file, the position (line, byte or header field) and the reason.

mod contours;
mod export;
mod mapped;
mod mesh_io;
mod npy;
mod nrrd;
mod poly;
mod raw;

use std::fmt;
use std::path::{Path, PathBuf};

use thiserror::Error;

use crate::field::{Grid, GridError};

pub use contours::{parse_contours_csv, parse_contours_json, read_contours};
pub use export::VertexValues;
pub use mapped::MappedVolume;
pub use mesh_io::{
    read_mesh, write_file_atomic, write_mesh, write_mesh_data_to, write_mesh_to,
    write_mesh_with_values, MeshFormat, MeshWriteOptions, PlyWriter,
};
pub use npy::{read_npy, NpyAxes};
pub use nrrd::read_nrrd;
pub use poly::{read_poly_mesh, write_poly_mesh};
pub use raw::{read_raw, Endian, RawOptions, ScalarType};

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
}

impl fmt::Display for Position {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Position::File => f.write_str("file"),
            Position::Line(n) => write!(f, "line {n}"),
            Position::Byte(n) => write!(f, "byte {n}"),
            Position::Field(name) => write!(f, "header field '{name}'"),
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
pub struct VolumeOptions {
    /// Layout of a raw file (required for raw files, ignored otherwise).
    pub raw: Option<RawOptions>,
    /// How `.npy` array axes map to x, y, z.
    pub npy_axes: NpyAxes,
    /// Overrides the file's spacing.
    pub spacing: Option<[f64; 3]>,
    /// Overrides the file's origin.
    pub origin: Option<[f64; 3]>,
}

/// Reads a volume, choosing the reader by extension: `.npy`, `.nrrd`/`.nhdr`, otherwise raw
/// (which needs [`VolumeOptions::raw`]).
pub fn read_volume(path: &Path, options: &VolumeOptions) -> Result<Grid, IoError> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    let grid = match ext.as_str() {
        "npy" => read_npy(path, options.npy_axes)?,
        "nrrd" | "nhdr" => read_nrrd(path)?,
        _ => match &options.raw {
            Some(raw) => read_raw(path, raw)?,
            None => {
                return Err(IoError::unsupported(
                    path,
                    Position::File,
                    "unknown volume extension: give the raw layout (dims and type) or use .npy, .nrrd or .nhdr",
                ))
            }
        },
    };
    let grid = match options.spacing {
        Some(s) => grid.with_spacing(s).map_err(|e| IoError::grid(path, e))?,
        None => grid,
    };
    match options.origin {
        Some(o) => grid.with_origin(o).map_err(|e| IoError::grid(path, e)),
        None => Ok(grid),
    }
}

/// Reads a whole file, mapping errors to [`IoError::Os`].
pub(crate) fn read_file(path: &Path) -> Result<Vec<u8>, IoError> {
    std::fs::read(path).map_err(|e| IoError::os(path, e))
}
