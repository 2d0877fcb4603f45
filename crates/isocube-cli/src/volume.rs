//! The VOLUME argument: `sample:NAME:N[:SEED]` or a file, with the raw-layout flags.

use std::path::Path;

use clap::Args;
use isocube::field::{Grid, Orientation, SampleSpec};
use isocube::io::{
    read_volume_oriented, Endian, MappedVolume, NpyAxes, RawOptions, ScalarType, VolumeOptions,
};

use crate::Failure;

/// How to read the volume.
#[derive(Clone, Debug, Args)]
pub(crate) struct VolumeArgs {
    /// `sample:NAME:N` (a built-in sample on N points per axis; noise takes `:SEED` too), or a
    /// file: .npy, .nrrd, .nhdr, .nii, .nii.gz, .mha, .mhd, or raw (with --dims and --type).
    pub volume: String,
    /// Raw files: points along x, y, z.
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_dims)]
    pub dims: Option<[usize; 3]>,
    /// Raw files: value type (u8, i8, u16, i16, u32, i32, u64, i64, f32, f64).
    #[arg(long = "type", value_name = "TYPE")]
    pub scalar: Option<ScalarType>,
    /// Raw files: byte order (little or big).
    #[arg(long, default_value = "little")]
    pub endian: Endian,
    /// Raw files: bytes to skip before the data.
    #[arg(long, default_value_t = 0)]
    pub header_bytes: u64,
    /// Grid spacing (overrides the file's).
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_triple)]
    pub spacing: Option<[f64; 3]>,
    /// Grid origin (overrides the file's).
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_triple)]
    pub origin: Option<[f64; 3]>,
    /// .npy files: array axes are x,y,z (`xyz`, default) or z,y,x (`zyx`).
    #[arg(long, default_value = "xyz")]
    pub axes: NpyAxes,
}

impl VolumeArgs {
    /// Whether the volume argument is this file path.
    pub(crate) fn is_file(&self, path: &Path) -> bool {
        if SampleSpec::is_sample(&self.volume) {
            return false;
        }
        match (
            std::fs::canonicalize(&self.volume),
            std::fs::canonicalize(path),
        ) {
            (Ok(a), Ok(b)) => a == b,
            _ => Path::new(&self.volume) == path,
        }
    }

    /// The volume and how its axes lie in the world (identity for samples and formats without a
    /// direction).
    pub(crate) fn load_oriented(&self) -> Result<(Grid, Orientation), Failure> {
        if SampleSpec::is_sample(&self.volume) {
            let spec: SampleSpec = self
                .volume
                .parse()
                .map_err(|e: String| Failure::input(anyhow::anyhow!(e)))?;
            let mut grid = spec.grid();
            if let Some(s) = self.spacing {
                grid = grid.with_spacing(s).map_err(Failure::input)?;
            }
            if let Some(o) = self.origin {
                grid = grid.with_origin(o).map_err(Failure::input)?;
            }
            return Ok((grid, Orientation::IDENTITY));
        }
        let options = self.file_options()?;
        read_volume_oriented(Path::new(&self.volume), &options)
            .map_err(|e| crate::io_failure(e, true))
            .map_err(|f| Failure {
                error: f.error.context("cannot read the volume"),
                ..f
            })
    }
}

impl VolumeArgs {
    /// How to read the volume file (not a sample).
    pub(crate) fn file_options(&self) -> Result<VolumeOptions, Failure> {
        let raw = match (self.dims, self.scalar) {
            (Some(dims), Some(scalar)) => Some(RawOptions {
                endian: self.endian,
                header_bytes: self.header_bytes,
                ..RawOptions::new(dims, scalar)
            }),
            (None, None) => None,
            _ => {
                return Err(Failure::input(anyhow::anyhow!(
                    "raw volumes need both --dims and --type"
                )))
            }
        };
        Ok(VolumeOptions {
            raw,
            npy_axes: self.axes,
            spacing: self.spacing,
            origin: self.origin,
        })
    }

    /// Maps the volume file for slab-wise reading (raw or .npy).
    pub(crate) fn map(&self) -> Result<MappedVolume, Failure> {
        MappedVolume::open(Path::new(&self.volume), &self.file_options()?)
            .map_err(|e| crate::io_failure(e, true))
            .map_err(|f| Failure {
                error: f.error.context("cannot read the volume"),
                ..f
            })
    }

    /// Whether the volume can be mapped: a .npy file, or a raw file (dims and type given).
    pub(crate) fn mappable(&self) -> bool {
        if SampleSpec::is_sample(&self.volume) {
            return false;
        }
        let ext = Path::new(&self.volume)
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .unwrap_or_default();
        match ext.as_str() {
            "npy" => true,
            "nrrd" | "nhdr" => false,
            _ => self.dims.is_some() && self.scalar.is_some(),
        }
    }
}

/// Three comma-separated values `X,Y,Z`, each checked by `one`.
fn parse_three<T>(s: &str, one: impl Fn(&str) -> Result<T, String>) -> Result<[T; 3], String> {
    let v: Vec<T> = s
        .split(',')
        .map(|t| one(t.trim()))
        .collect::<Result<_, _>>()?;
    <[T; 3]>::try_from(v).map_err(|_| format!("'{s}' needs three numbers X,Y,Z"))
}

fn parse_dims(s: &str) -> Result<[usize; 3], String> {
    parse_three(s, |t| {
        t.parse()
            .map_err(|_| format!("'{t}' is not a whole number"))
    })
}

fn parse_triple(s: &str) -> Result<[f64; 3], String> {
    parse_three(s, |t| {
        t.parse::<f64>()
            .ok()
            .filter(|x| x.is_finite())
            .ok_or_else(|| format!("'{t}' is not a finite number"))
    })
}
