//! MINC volumes (`.mnc`; MINC-1 also `.mnc.gz`), the format of the Montreal Neurological
//! Institute's tools (and of BrainWeb, the MNI templates, CIVET, ...).
//!
//! MINC is a set of conventions over a container: MINC-1 over NetCDF classic, read here by hand
//! ([`netcdf`]; a small, fully specified format), MINC-2 over HDF5, read through the HDF5 C
//! library (`hdf5-metno`) behind the opt-in feature `minc2`, since HDF5 is far too large a
//! format to rewrite and the library must be installed (Debian: `libhdf5-dev`). Both
//! containers give the same [`Variable`]s, and the conventions are applied once, here:
//!
//! - the image's dimensions, slowest first: three spatial ones (`xspace`, `yspace`, `zspace`,
//!   in any order), and optionally `time` (chosen with `--frame`) and `vector_dimension`
//!   (chosen with `--channel`);
//! - each spatial dimension's `step`, `start` and `direction_cosines` (defaults 1, 0 and its
//!   own axis) give the world position `Σ cosines · (start + step · index)`, as libminc and
//!   nibabel place voxels; irregular spacing is refused;
//! - integer voxels are real values through `image-min`/`image-max` (per slice, per volume or
//!   one pair; absent: 0 and 1, libminc's defaults) and the valid range (`valid_range`, or
//!   `valid_min`/`valid_max`, or the type's range): clamped to the valid range, then mapped
//!   linearly onto [image-min, image-max]. Floating-point voxels are the values themselves.

pub(crate) mod netcdf;

#[cfg(feature = "minc2")]
mod hdf5;

use std::path::Path;

use isocube::field::{Grid, Orientation};

use crate::{Budget, IoError, Pick, Position};

/// How a variable's values are stored.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Stored {
    Float,
    Int { bits: u32, signed: bool },
}

impl Stored {
    /// The range of values the type holds.
    fn range(self) -> [f64; 2] {
        match self {
            Stored::Float => [f64::NEG_INFINITY, f64::INFINITY],
            Stored::Int { bits, signed: true } => {
                let half = 2f64.powi(bits as i32 - 1);
                [-half, half - 1.0]
            }
            Stored::Int { bits, .. } => [0.0, 2f64.powi(bits as i32) - 1.0],
        }
    }
}

/// An attribute's value: text, or numbers.
#[derive(Clone, Debug)]
pub(crate) enum Attr {
    Text(String),
    Numbers(Vec<f64>),
}

/// A variable as a MINC container describes it.
#[derive(Clone, Debug)]
pub(crate) struct Variable {
    /// Its dimensions, slowest first: name and length.
    pub dims: Vec<(String, usize)>,
    pub attrs: Vec<(String, Attr)>,
    pub stored: Stored,
}

impl Variable {
    fn attr(&self, name: &str) -> Option<&Attr> {
        self.attrs.iter().find(|(n, _)| n == name).map(|(_, a)| a)
    }

    fn numbers(&self, name: &str) -> Option<&[f64]> {
        match self.attr(name) {
            Some(Attr::Numbers(v)) => Some(v),
            _ => None,
        }
    }

    fn text(&self, name: &str) -> Option<&str> {
        match self.attr(name) {
            Some(Attr::Text(t)) => Some(t.trim_end_matches('\0').trim()),
            _ => None,
        }
    }

    fn count(&self) -> u64 {
        self.dims
            .iter()
            .fold(1u64, |n, (_, len)| n.saturating_mul(*len as u64))
    }
}

/// What the MINC conventions need of a container.
pub(crate) trait Container {
    /// The variable of that MINC name (`image`, `image-min`, `image-max`, a dimension's
    /// name), if the file has it.
    fn variable(&self, name: &str) -> Result<Option<Variable>, IoError>;
    /// All of a variable's values, slowest dimension first, as its [`Stored`] type says.
    fn values(&self, name: &str, variable: &Variable) -> Result<Vec<f64>, IoError>;
}

/// Reads a MINC file (either kind, by its first bytes).
pub(crate) fn read_minc_within(
    path: &Path,
    budget: Budget,
    pick: Pick,
) -> Result<(Grid, Orientation), IoError> {
    let mut magic = [0u8; 4];
    let opened =
        std::fs::File::open(path).and_then(|mut f| std::io::Read::read_exact(&mut f, &mut magic));
    if opened.is_ok() && magic == *b"\x89HDF" {
        return read_minc2(path, budget, pick);
    }
    let bytes = budget.read_file(path)?;
    read_minc_bytes(path, &bytes, budget, pick)
}

/// Reads a MINC-1 file (or a gzip-compressed one) from memory; MINC-2 (HDF5) is read from a
/// file only, since the HDF5 library opens files.
pub(crate) fn read_minc_bytes(
    path: &Path,
    bytes: &[u8],
    budget: Budget,
    pick: Pick,
) -> Result<(Grid, Orientation), IoError> {
    if bytes.starts_with(b"\x89HDF") {
        return Err(IoError::unsupported(
            path,
            Position::File,
            "a MINC-2 (HDF5) file is read from a file path, not from memory: the HDF5 library opens files",
        ));
    }
    let inflated;
    let bytes = if bytes.starts_with(&[0x1F, 0x8B]) {
        inflated = inflate(path, bytes, budget)?;
        &inflated[..]
    } else {
        bytes
    };
    let file = netcdf::NetCdf::parse(path, bytes)?;
    volume(path, &file, budget, pick)
}

/// A gzip stream's content, refused once it passes the memory limit.
fn inflate(path: &Path, bytes: &[u8], budget: Budget) -> Result<Vec<u8>, IoError> {
    use std::io::Read;
    let mut out = Vec::new();
    flate2::read::MultiGzDecoder::new(bytes)
        .take(budget.limit().saturating_add(1))
        .read_to_end(&mut out)
        .map_err(|e| {
            IoError::format(
                path,
                Position::File,
                format!("the gzip stream is damaged: {e}"),
            )
        })?;
    budget.check(path, Position::File, out.len() as u64)?;
    Ok(out)
}

#[cfg(feature = "minc2")]
fn read_minc2(path: &Path, budget: Budget, pick: Pick) -> Result<(Grid, Orientation), IoError> {
    let file = hdf5::Hdf5::open(path)?;
    volume(path, &file, budget, pick)
}

#[cfg(not(feature = "minc2"))]
fn read_minc2(path: &Path, _: Budget, _: Pick) -> Result<(Grid, Orientation), IoError> {
    Err(IoError::unsupported(
        path,
        Position::File,
        "a MINC-2 file (HDF5): this isocube was built without the `minc2` feature, which links \
         the HDF5 library (Debian: apt-get install libhdf5-dev; then cargo install isocube-cli \
         --features minc2), or convert it to MINC-1 first (mincconvert, no -2)",
    ))
}

/// One spatial axis of the image: its place among the image's dimensions and where it runs.
struct Axis {
    dim: usize,
    len: usize,
    step: f64,
    start: f64,
    cosines: [f64; 3],
}

/// Applies the MINC conventions to a container's variables.
pub(crate) fn volume(
    path: &Path,
    file: &impl Container,
    budget: Budget,
    pick: Pick,
) -> Result<(Grid, Orientation), IoError> {
    let field = |name: &str| Position::Field(name.to_string());
    let image = file.variable("image")?.ok_or_else(|| {
        IoError::format(
            path,
            Position::File,
            "no `image` variable: not a MINC volume",
        )
    })?;
    // Sort the image's dimensions into space, time and vector components.
    let mut axes = Vec::new();
    let (mut time, mut vector) = (None, None);
    for (d, (name, len)) in image.dims.iter().enumerate() {
        match name.as_str() {
            "xspace" | "yspace" | "zspace" => {
                let own = match name.as_str() {
                    "xspace" => [1.0, 0.0, 0.0],
                    "yspace" => [0.0, 1.0, 0.0],
                    _ => [0.0, 0.0, 1.0],
                };
                let var = file.variable(name)?;
                let number = |attr: &str, default: f64| -> Result<f64, IoError> {
                    match var.as_ref().and_then(|v| v.numbers(attr)) {
                        None => Ok(default),
                        Some([v]) if v.is_finite() => Ok(*v),
                        Some(v) => Err(IoError::format(
                            path,
                            field(&format!("{name}:{attr}")),
                            format!("{v:?} is not one finite number"),
                        )),
                    }
                };
                if let Some(spacing) = var.as_ref().and_then(|v| v.text("spacing")) {
                    if spacing == "irregular" {
                        return Err(IoError::unsupported(
                            path,
                            field(&format!("{name}:spacing")),
                            "irregularly spaced samples (a grid of varying steps) are not read",
                        ));
                    }
                }
                let cosines = match var.as_ref().and_then(|v| v.numbers("direction_cosines")) {
                    None => own,
                    Some(&[a, b, c]) if [a, b, c].iter().all(|v| v.is_finite()) => [a, b, c],
                    Some(v) => {
                        return Err(IoError::format(
                            path,
                            field(&format!("{name}:direction_cosines")),
                            format!("{v:?} is not three finite numbers"),
                        ))
                    }
                };
                axes.push(Axis {
                    dim: d,
                    len: *len,
                    step: number("step", 1.0)?,
                    start: number("start", 0.0)?,
                    cosines,
                });
            }
            "time" if time.is_none() => time = Some((d, *len)),
            "vector_dimension" if vector.is_none() => vector = Some((d, *len)),
            other => {
                return Err(IoError::unsupported(
                    path,
                    field("image"),
                    format!(
                        "dimension `{other}` of the image ({}): isocube reads xspace, yspace and \
                         zspace, with time (--frame) and vector_dimension (--channel)",
                        names(&image)
                    ),
                ))
            }
        }
    }
    if axes.len() != 3 {
        return Err(IoError::unsupported(
            path,
            field("image"),
            format!(
                "an image of {} spatial dimensions ({}): isocube meshes 3-d volumes",
                axes.len(),
                names(&image)
            ),
        ));
    }
    if image.dims.iter().any(|(_, len)| *len == 0) {
        return Err(IoError::format(path, field("image"), "an empty dimension"));
    }
    // The whole variable is read as f64 beside the f32 volume. Held within the budget and
    // addressable, every product of dimensions below fits a usize.
    let total = image.count();
    let held = total
        .checked_mul(12)
        .filter(|&n| usize::try_from(n).is_ok());
    let Some(held) = held else {
        return Err(IoError::format(
            path,
            field("image"),
            format!(
                "dimensions {} hold more values than memory can address",
                names(&image)
            ),
        ));
    };
    budget.check(path, field("image"), held)?;
    // Without a time or vector dimension, the file holds one of each (0 may still be asked).
    let frame = Pick::index(
        path,
        field("time"),
        pick.frame,
        time.map_or(1, |(_, n)| n),
        "--frame",
        "frames (time)",
    )?;
    let channel = Pick::index(
        path,
        field("vector_dimension"),
        pick.channel,
        vector.map_or(1, |(_, n)| n),
        "--channel",
        "channels (vector_dimension)",
    )?;
    // isocube's x (fastest) is the image's fastest spatial dimension.
    axes.reverse();
    let dims = [axes[0].len, axes[1].len, axes[2].len];
    let count = dims.iter().product::<usize>();
    let raw = file.values("image", &image)?;
    if raw.len() as u64 != image.count() {
        return Err(IoError::format(
            path,
            field("image"),
            format!("{} values for dimensions {}", raw.len(), names(&image)),
        ));
    }
    let strides: Vec<usize> = (0..image.dims.len())
        .map(|d| image.dims[d + 1..].iter().map(|(_, n)| n).product())
        .collect();
    let fixed = time.map_or(0, |(d, _)| frame * strides[d])
        + vector.map_or(0, |(d, _)| channel * strides[d]);
    let scale = Scale::of(path, file, &image)?;
    let mut values = Vec::with_capacity(count);
    let mut at = vec![0usize; image.dims.len()];
    if let Some((d, _)) = time {
        at[d] = frame;
    }
    if let Some((d, _)) = vector {
        at[d] = channel;
    }
    for k in 0..dims[2] {
        at[axes[2].dim] = k;
        for j in 0..dims[1] {
            at[axes[1].dim] = j;
            let row = fixed + k * strides[axes[2].dim] + j * strides[axes[1].dim];
            for i in 0..dims[0] {
                at[axes[0].dim] = i;
                let v = raw[row + i * strides[axes[0].dim]];
                values.push(scale.real(v, &at) as f32);
            }
        }
    }
    let linear: [[f64; 3]; 3] =
        std::array::from_fn(|r| std::array::from_fn(|a| axes[a].cosines[r] * axes[a].step));
    let origin: [f64; 3] =
        std::array::from_fn(|r| axes.iter().map(|a| a.cosines[r] * a.start).sum());
    let (spacing, orientation) = Orientation::from_linear(linear).ok_or_else(|| {
        IoError::format(
            path,
            field("direction_cosines"),
            "the axes' steps and direction cosines make a singular or infinite map",
        )
    })?;
    let grid = Grid::new(dims, values)
        .and_then(|g| g.with_spacing(spacing))
        .and_then(|g| g.with_origin(origin))
        .map_err(|e| IoError::grid(path, e))?;
    Ok((grid, orientation))
}

fn names(image: &Variable) -> String {
    image
        .dims
        .iter()
        .map(|(n, len)| format!("{n} {len}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The voxel-to-real map of integer images.
enum Scale {
    Float,
    Int {
        valid: [f64; 2],
        /// image-min and image-max, over the image's slowest `over` dimensions.
        min: Vec<f64>,
        max: Vec<f64>,
        strides: Vec<usize>,
    },
}

impl Scale {
    fn of(path: &Path, file: &impl Container, image: &Variable) -> Result<Scale, IoError> {
        if image.stored == Stored::Float {
            return Ok(Scale::Float);
        }
        let field = |name: &str| Position::Field(name.to_string());
        let valid = match (
            image.numbers("valid_range"),
            image.numbers("valid_min"),
            image.numbers("valid_max"),
        ) {
            (Some(&[a, b]), _, _) | (None, Some(&[a]), Some(&[b])) => [a.min(b), a.max(b)],
            (Some(v), _, _) => {
                return Err(IoError::format(
                    path,
                    field("image:valid_range"),
                    format!("{v:?} is not two numbers"),
                ))
            }
            _ => image.stored.range(),
        };
        if !(valid[0].is_finite() && valid[1].is_finite() && valid[1] > valid[0]) {
            return Err(IoError::format(
                path,
                field("image:valid_range"),
                format!("an empty valid range {valid:?}"),
            ));
        }
        let read = |name: &str, default: f64| -> Result<(Vec<String>, Vec<f64>), IoError> {
            let Some(var) = file.variable(name)? else {
                return Ok((Vec::new(), vec![default]));
            };
            let dims: Vec<String> = var.dims.iter().map(|(n, _)| n.clone()).collect();
            let over = &image.dims[..dims.len().min(image.dims.len())];
            if dims.len() > image.dims.len() || var.dims.iter().zip(over).any(|(a, b)| a != b) {
                return Err(IoError::format(
                    path,
                    field(name),
                    format!(
                        "it varies over {dims:?}, not over the image's slowest dimensions ({})",
                        names(image)
                    ),
                ));
            }
            let values = file.values(name, &var)?;
            if values.len() as u64 != var.count() || values.iter().any(|v| !v.is_finite()) {
                return Err(IoError::format(
                    path,
                    field(name),
                    "its values are missing or not finite",
                ));
            }
            Ok((dims, values))
        };
        let (min_dims, min) = read("image-min", 0.0)?;
        let (max_dims, max) = read("image-max", 1.0)?;
        if min_dims != max_dims {
            return Err(IoError::format(
                path,
                field("image-max"),
                format!("image-min varies over {min_dims:?} and image-max over {max_dims:?}"),
            ));
        }
        let over = &image.dims[..min_dims.len()];
        let strides = (0..over.len())
            .map(|d| over[d + 1..].iter().map(|(_, n)| n).product())
            .collect();
        Ok(Scale::Int {
            valid,
            min,
            max,
            strides,
        })
    }

    /// The real value of voxel `v` at image indices `at`.
    fn real(&self, v: f64, at: &[usize]) -> f64 {
        match self {
            Scale::Float => v,
            Scale::Int {
                valid,
                min,
                max,
                strides,
            } => {
                let s: usize = strides.iter().zip(at).map(|(s, i)| s * i).sum();
                let (lo, hi) = (min[s], max[s]);
                let slope = (hi - lo) / (valid[1] - valid[0]);
                v.clamp(valid[0], valid[1]) * slope + (lo - valid[0] * slope)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use std::path::{Path, PathBuf};

    use crate::{read_volume_bytes, read_volume_oriented, VolumeOptions};

    fn dir() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/minc")
    }

    fn hdf5(path: &Path) -> bool {
        std::fs::read(path).unwrap().starts_with(b"\x89HDF")
    }

    /// Every file of `tests/data/minc` (nibabel's MINC-1 and MINC-2 test files, and two written
    /// by scipy: oblique, negative step, two scaling dimensions, a record dimension) gives
    /// nibabel's values, value for value, and nibabel's affine at every grid corner.
    #[test]
    fn minc_files_read_as_nibabel_reads_them() {
        let expected: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir().join("expected.json")).unwrap())
                .unwrap();
        let mut checked = 0;
        for (key, entry) in expected.as_object().unwrap() {
            let path = dir().join(entry["file"].as_str().unwrap());
            let options = VolumeOptions {
                frame: entry["frame"].as_u64().map(|f| f as usize),
                ..VolumeOptions::default()
            };
            let read = read_volume_oriented(&path, &options);
            if hdf5(&path) && cfg!(not(feature = "minc2")) {
                let e = read.unwrap_err().to_string();
                assert!(e.contains("`minc2` feature"), "{key}: {e}");
                continue;
            }
            let (grid, orientation) = read.unwrap_or_else(|e| panic!("{key}: {e}"));
            let (want, _) = read_volume_oriented(
                &dir().join(entry["values"].as_str().unwrap()),
                &VolumeOptions::default(),
            )
            .unwrap();
            assert_eq!(grid.dims(), want.dims(), "{key}");
            assert_eq!(grid.values(), want.values(), "{key}");
            let affine: Vec<Vec<f64>> = entry["affine"]
                .as_array()
                .unwrap()
                .iter()
                .map(|r| {
                    r.as_array()
                        .unwrap()
                        .iter()
                        .map(|v| v.as_f64().unwrap())
                        .collect()
                })
                .collect();
            let dims = grid.dims();
            for corner in 0..8 {
                let ijk = [0, 1, 2].map(|a| {
                    if corner >> a & 1 == 1 {
                        (dims[a] - 1) as f64
                    } else {
                        0.0
                    }
                });
                // nibabel's axes are the file's, slowest first: isocube's reversed.
                let file = [ijk[2], ijk[1], ijk[0]];
                let got = orientation.world(&grid, ijk);
                for r in 0..3 {
                    let want = affine[r][3] + (0..3).map(|c| affine[r][c] * file[c]).sum::<f64>();
                    assert!(
                        (got[r] - want).abs() < 1e-9 * (1.0 + want.abs()),
                        "{key}: {got:?}"
                    );
                }
            }
            checked += 1;
        }
        assert!(checked >= 7);
    }

    /// A 4-d file without `--frame` names the choice; from memory, plain or gzip-compressed, a
    /// MINC-1 file is the file read from disk.
    #[test]
    fn frames_are_chosen_and_memory_reads_equal_file_reads() {
        let options = VolumeOptions::default();
        let e = read_volume_oriented(&dir().join("records.mnc"), &options).unwrap_err();
        assert!(
            e.to_string()
                .contains("2 frames (time): choose one with --frame (0 to 1)"),
            "{e}"
        );
        for name in ["oblique.mnc", "tiny.mnc", "minc1_1_scale.mnc"] {
            let path = dir().join(name);
            let from_file = read_volume_oriented(&path, &options).unwrap();
            let bytes = std::fs::read(&path).unwrap();
            assert_eq!(
                read_volume_bytes(&bytes, &path, &options).unwrap(),
                from_file
            );
            let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
            std::io::Write::write_all(&mut gz, &bytes).unwrap();
            let gz = gz.finish().unwrap();
            let named = dir().join(format!("{name}.gz"));
            assert_eq!(read_volume_bytes(&gz, &named, &options).unwrap(), from_file);
        }
    }

    /// A `vector_dimension` (fastest, here) is a channel: each one chosen with `--channel`
    /// gives that component's volume; without the choice the file is refused naming it.
    #[test]
    fn vector_components_are_channels() {
        let path = dir().join("vector.mnc");
        let e = read_volume_oriented(&path, &VolumeOptions::default()).unwrap_err();
        assert!(
            e.to_string()
                .contains("3 channels (vector_dimension): choose one with --channel (0 to 2)"),
            "{e}"
        );
        for c in 0..3 {
            let options = VolumeOptions {
                channel: Some(c),
                ..VolumeOptions::default()
            };
            let (grid, _) = read_volume_oriented(&path, &options).unwrap();
            assert_eq!(grid.dims(), [5, 3, 4]);
            for k in 0..4 {
                for j in 0..3 {
                    for i in 0..5 {
                        let want = (1000 * c + i + 10 * j + 100 * k) as f32;
                        assert_eq!(grid.value(i, j, k), want);
                    }
                }
            }
        }
    }

    /// MINC-1 files cut short anywhere or with bytes changed: an error or a volume, never a
    /// panic; cut short, an error unless only trailing bytes no voxel uses are gone.
    #[test]
    fn damaged_minc1_files_fail_cleanly() {
        let options = VolumeOptions {
            max_memory: Some(64 << 20),
            ..VolumeOptions::default()
        };
        for name in ["oblique.mnc", "records.mnc", "minc1_4d.mnc"] {
            let path = dir().join(name);
            let bytes = std::fs::read(&path).unwrap();
            let mut frame = options.clone();
            frame.frame = Some(1).filter(|_| name != "oblique.mnc");
            let whole = read_volume_bytes(&bytes, &path, &frame).unwrap();
            for cut in (0..bytes.len()).step_by(7) {
                // Only bytes no voxel depends on (the dimension variables' own values) may go.
                if let Ok(read) = read_volume_bytes(&bytes[..cut], &path, &frame) {
                    assert!(read == whole && cut > bytes.len() - 32, "{name} {cut}");
                }
            }
            for at in (0..bytes.len().min(4096)).step_by(3) {
                for flip in [0x01u8, 0x80, 0xFF] {
                    let mut bad = bytes.clone();
                    bad[at] ^= flip;
                    if let Ok((grid, _)) = read_volume_bytes(&bad, &path, &frame) {
                        let [nx, ny, nz] = grid.dims();
                        assert_eq!(grid.values().len(), nx * ny * nz);
                    }
                }
            }
        }
    }
}
