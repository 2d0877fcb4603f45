//! The VOLUME argument: `sample:NAME:N[:SEED]` or a file, with the raw-layout flags.

use std::path::Path;

use clap::Args;
use isocube::field::{Grid, Orientation, PlaneSource, SampleSpec};
use isocube_io::{
    read_volume_oriented, Endian, InflatingVolume, IoError, MappedVolume, NpyAxes, RawOptions,
    ScalarType, VolumeOptions, ZarrVolume,
};

use crate::Failure;

/// How to read the volume.
#[derive(Clone, Debug, Args)]
pub(crate) struct VolumeArgs {
    /// `sample:NAME:N` (a built-in sample on N points per axis; noise takes `:SEED` too), or a
    /// file: .npy, .nrrd, .nhdr, .nii, .nii.gz (NIfTI-1 and -2), .mnc, .mnc.gz (MINC-1; MINC-2
    /// when built with the minc2 feature), .mha, .mhd, .vti, .tif/.tiff,
    /// DICOM (a series folder, or one .dcm: multi-frame enhanced CT/MR, RT Dose, SEG as labels;
    /// uncompressed, RLE, JPEG incl. 12-bit lossy, JPEG-LS, JPEG 2000), a Zarr array or OME-Zarr image folder (v2
    /// or v3), or raw (with --dims and --type). 4-d files: --frame, --channel.
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
    /// OME-Zarr images: the resolution level to read (0, the finest, by default).
    #[arg(long, value_name = "N")]
    pub scale: Option<usize>,
    /// Volumes with several channels: the channel to mesh (an OME-Zarr `c` axis, NIfTI's
    /// `dim[5]`, MetaImage's `ElementNumberOfChannels`, an NRRD `vector` axis, a TIFF's samples
    /// per pixel or an ImageJ hyperstack's channels).
    #[arg(long, value_name = "N")]
    pub channel: Option<usize>,
    /// Volumes over time: the time point to mesh (an OME-Zarr `t` axis, NIfTI's `dim[4]`, a
    /// fourth MetaImage axis, an NRRD `list` or `time` axis, an ImageJ hyperstack's frames, a
    /// DICOM series with several images at every slice position).
    #[arg(long, value_name = "N")]
    pub frame: Option<usize>,
    /// The most memory reading the volume may take: `512M`, `8G`, `1.5T` (binary units), a
    /// number of bytes, or `none`. Files whose header asks for more are refused before anything
    /// is allocated; `extract` gives the mesh what the volume leaves. [default: the machine's
    /// physical memory]
    #[arg(long, value_name = "SIZE", value_parser = parse_memory)]
    pub max_memory: Option<MemoryLimit>,
}

/// A `--max-memory` value: `None` for no limit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct MemoryLimit(pub Option<u64>);

impl MemoryLimit {
    /// The limit given, else the machine's physical memory (no limit where that is unknown).
    pub(crate) fn or_default(given: Option<MemoryLimit>) -> Option<u64> {
        match given {
            Some(MemoryLimit(limit)) => limit,
            None => physical_memory(),
        }
    }
}

/// `MemTotal` of `/proc/meminfo`: past it a read would only end in swapping or the OOM killer.
fn physical_memory() -> Option<u64> {
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = info.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    kib.checked_mul(1024)
}

/// `512M`, `8G`, `8GiB`, `1.5T`, `4096`, `none`.
pub(crate) fn parse_memory(s: &str) -> Result<MemoryLimit, String> {
    let t = s.trim();
    if t.eq_ignore_ascii_case("none") {
        return Ok(MemoryLimit(None));
    }
    let upper = t.to_ascii_uppercase();
    let number = upper.trim_end_matches("IB").trim_end_matches('B');
    let (digits, shift) = match number.chars().last() {
        Some('K') => (&number[..number.len() - 1], 10),
        Some('M') => (&number[..number.len() - 1], 20),
        Some('G') => (&number[..number.len() - 1], 30),
        Some('T') => (&number[..number.len() - 1], 40),
        _ => (number, 0),
    };
    let value: f64 = digits
        .trim()
        .parse()
        .ok()
        .filter(|v: &f64| v.is_finite() && *v > 0.0)
        .ok_or_else(|| format!("'{s}' is not a size such as 512M, 8G or 4096 (or none)"))?;
    let bytes = value * (1u64 << shift) as f64;
    if bytes >= u64::MAX as f64 {
        return Err(format!("'{s}' is too large"));
    }
    Ok(MemoryLimit(Some(bytes as u64)))
}

impl VolumeArgs {
    /// The volume and how its axes lie in the world (identity for samples and formats without a
    /// direction).
    pub(crate) fn load_oriented(&self) -> Result<(Grid, Orientation), Failure> {
        if SampleSpec::is_sample(&self.volume) {
            let spec: SampleSpec = self.volume.parse().map_err(Failure::input)?;
            // Samples are computed, not read, but take the same memory.
            let limit = MemoryLimit::or_default(self.max_memory);
            let needed = (spec.n as u64).pow(3) * 4;
            if limit.is_some_and(|l| needed > l) {
                let gib = |b: u64| b as f64 / f64::from(1u32 << 30);
                return Err(Failure::input(anyhow::anyhow!(
                    "{}: its values need {:.1} GiB, more than the limit of {:.1} GiB (raise it with --max-memory)",
                    self.volume,
                    gib(needed),
                    gib(limit.unwrap_or_default())
                )));
            }
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
        read_volume_oriented(Path::new(&self.volume), &options).map_err(volume_failure)
    }
}

impl VolumeArgs {
    /// The volume whole, in the frame every slab-wise path walks it: a file that maps (any value
    /// type), a Zarr store and a gzipped NIfTI are read through the same plane reader that
    /// `extract` streams from, so a command that needs the whole volume (ternary snapping,
    /// relaxation, `--chunk`, `tetmesh`, `view`) meshes the cells in the same order and cuts
    /// them the same way: one file, one mesh, whichever path its options take. In index space
    /// (spacing 1, origin 0, no direction) with `index_space`.
    pub(crate) fn load_walked(&self, index_space: bool) -> Result<(Grid, Orientation), Failure> {
        fn walked(
            volume: impl SlabInput,
            index_space: bool,
            limit: Option<u64>,
        ) -> Result<(Grid, Orientation), Failure> {
            let volume = volume.framed(index_space);
            Ok((volume.whole(limit)?, volume.orientation()))
        }
        let limit = MemoryLimit::or_default(self.max_memory);
        if let Some(volume) = self.try_map()? {
            return walked(volume, index_space, limit);
        }
        if isocube_io::is_zarr_store(Path::new(&self.volume)) {
            if let Some(volume) = self.try_zarr()? {
                return walked(volume, index_space, limit);
            }
        }
        if let Some(volume) = self.try_inflating()? {
            return walked(volume, index_space, limit);
        }
        in_frame(index_space, self.load_oriented()?)
    }
}

/// A volume read plane by plane: a mapped file (converted as it is read when its values are
/// not `f32`), a Zarr store decoded a layer of chunks at a time, or a gzipped NIfTI inflated
/// as it goes (whose read errors surface once the planes are read). Slab-wise extraction
/// walks it; whole-volume work reads it whole ([`SlabInput::whole`]) in the same frame.
pub(crate) trait SlabInput: PlaneSource + Sized {
    fn failure(&self) -> Option<IoError> {
        None
    }

    fn path(&self) -> &Path;

    /// What the summary should add about the input, and what `--strict` refuses.
    fn caveat(&self) -> Option<String> {
        None
    }

    /// The same volume in grid index space: spacing 1, origin 0, the file's own axes.
    fn into_index_space(self) -> Self;

    /// The volume in index space when `index_space` (`--index-space`), else as it is.
    fn framed(self, index_space: bool) -> Self {
        match index_space {
            true => self.into_index_space(),
            false => self,
        }
    }

    /// Every value, within `limit` bytes, or the reader's first error (it reads what it cannot
    /// decode as NaN and keeps the error).
    fn whole(&self, limit: Option<u64>) -> Result<Grid, Failure> {
        let points = self.dims().iter().map(|&d| d as u64).product::<u64>();
        let needed = points.saturating_mul(4);
        if let Some(limit) = limit.filter(|&l| needed > l) {
            return Err(volume_failure(IoError::TooLarge {
                path: self.path().to_path_buf(),
                position: isocube_io::Position::File,
                needed,
                limit,
            }));
        }
        let grid = Grid::from_source(self).map_err(Failure::input)?;
        match self.failure() {
            Some(e) => Err(crate::io_failure(e, true)),
            None => Ok(grid),
        }
    }
}

impl SlabInput for MappedVolume {
    fn path(&self) -> &Path {
        MappedVolume::path(self)
    }

    fn into_index_space(self) -> Self {
        MappedVolume::into_index_space(self)
    }

    /// Decoded in parallel straight from the map.
    fn whole(&self, limit: Option<u64>) -> Result<Grid, Failure> {
        self.read_whole(limit).map_err(volume_failure)
    }
}

impl SlabInput for InflatingVolume {
    fn failure(&self) -> Option<IoError> {
        self.take_error()
    }

    fn path(&self) -> &Path {
        InflatingVolume::path(self)
    }

    fn into_index_space(self) -> Self {
        InflatingVolume::into_index_space(self)
    }
}

impl SlabInput for ZarrVolume {
    fn failure(&self) -> Option<IoError> {
        self.take_error()
    }

    fn path(&self) -> &Path {
        ZarrVolume::path(self)
    }

    fn caveat(&self) -> Option<String> {
        let first = self.first_absent_chunk()?;
        let n = self.absent_chunks();
        Some(format!(
            "{n} chunk{} absent (the first '{first}'), read as the array's fill value",
            if n == 1 { "" } else { "s" }
        ))
    }

    fn into_index_space(self) -> Self {
        ZarrVolume::into_index_space(self)
    }
}

/// A loaded volume as meshed: in index space (spacing 1, origin 0, no direction) when
/// `index_space` (`--index-space`), else as the file places it.
pub(crate) fn in_frame(
    index_space: bool,
    (grid, orientation): (Grid, Orientation),
) -> Result<(Grid, Orientation), Failure> {
    if !index_space {
        return Ok((grid, orientation));
    }
    let grid = grid
        .with_spacing([1.0; 3])
        .and_then(|g| g.with_origin([0.0; 3]))
        .map_err(Failure::input)?;
    Ok((grid, Orientation::IDENTITY))
}

/// A failure to read a volume, with a hint where the memory limit refused it.
pub(crate) fn volume_failure(e: IoError) -> Failure {
    let context = match e {
        IoError::TooLarge { .. } => "cannot read the volume (raise the limit with --max-memory)",
        _ => "cannot read the volume",
    };
    let f = crate::io_failure(e, true);
    Failure {
        error: f.error.context(context),
        ..f
    }
}

impl VolumeArgs {
    /// How to read the volume file (not a sample).
    pub(crate) fn file_options(&self) -> Result<VolumeOptions, Failure> {
        let raw = match (self.dims, self.scalar) {
            (Some(dims), Some(scalar)) => {
                let mut raw = RawOptions::new(dims, scalar);
                raw.endian = self.endian;
                raw.header_bytes = self.header_bytes;
                Some(raw)
            }
            (None, None) => None,
            _ => {
                return Err(Failure::input(anyhow::anyhow!(
                    "raw volumes need both --dims and --type"
                )))
            }
        };
        let mut options = VolumeOptions::default();
        options.raw = raw;
        options.npy_axes = self.axes;
        options.spacing = self.spacing;
        options.origin = self.origin;
        options.max_memory = MemoryLimit::or_default(self.max_memory);
        options.scale = self.scale;
        options.channel = self.channel;
        options.frame = self.frame;
        Ok(options)
    }

    /// The volume file memory-mapped, when it is stored uncompressed (raw, `.npy`, `.nii`,
    /// MetaImage, raw NRRD, raw-appended `.vti`): `None` for samples and for files that must be read.
    pub(crate) fn try_map(&self) -> Result<Option<MappedVolume>, Failure> {
        self.try_open_with(MappedVolume::try_open)
    }

    /// The volume as an [`InflatingVolume`] when it is a gzipped NIfTI that can be read plane
    /// by plane, else `None`.
    pub(crate) fn try_inflating(&self) -> Result<Option<InflatingVolume>, Failure> {
        self.try_open_with(InflatingVolume::try_open)
    }

    /// The volume as a [`ZarrVolume`] (read a layer of chunks at a time) when it is a Zarr
    /// store, else `None`.
    pub(crate) fn try_zarr(&self) -> Result<Option<ZarrVolume>, Failure> {
        self.try_open_with(|path, options| {
            if isocube_io::is_zarr_store(path) {
                ZarrVolume::open(path, options).map(Some)
            } else {
                Ok(None)
            }
        })
    }

    /// The file opened by `open` (which answers `None` for what it does not take); `None` for
    /// a sample.
    fn try_open_with<T>(
        &self,
        open: impl FnOnce(&Path, &VolumeOptions) -> Result<Option<T>, IoError>,
    ) -> Result<Option<T>, Failure> {
        if SampleSpec::is_sample(&self.volume) {
            return Ok(None);
        }
        open(Path::new(&self.volume), &self.file_options()?)
            .map_err(|e| crate::io_failure(e, true))
            .map_err(|f| Failure {
                error: f.error.context("cannot read the volume"),
                ..f
            })
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

/// The number `level` stands for in the volume `input`: itself, or one from the volume's
/// values (`summary`, computed only then).
pub(crate) fn resolve_level(
    level: isocube::field::Level,
    input: &str,
    summary: impl FnOnce() -> Option<isocube::field::ValueSummary>,
) -> Result<f32, Failure> {
    if let isocube::field::Level::Value(v) = level {
        return Ok(v);
    }
    match summary() {
        Some(s) => Ok(level.resolve(&s)),
        None => Err(Failure::input(anyhow::anyhow!(
            "{input}: --level {level}: the volume has no finite value"
        ))),
    }
}
