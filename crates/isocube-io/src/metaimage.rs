//! MetaImage volumes (ITK's `.mha` with the data after the header, `.mhd` with the data in a
//! separate file), raw or zlib-compressed, with spacing, offset and direction
//! (`TransformMatrix`, whose nine numbers are the three axis directions one after the other).
//! World coordinates are the file's (LPS by ITK's convention).

use std::io::Read;
use std::path::Path;

use super::mapped::Placement;
use super::raw::{decode_all, Endian, ScalarType};
use super::{Budget, IoError, Pick, Position};
use isocube::field::{Grid, Orientation};

/// Reads a MetaImage volume and its orientation.
pub fn read_metaimage(path: &Path) -> Result<(Grid, Orientation), IoError> {
    read_metaimage_within(path, Budget::UNLIMITED, Pick::default())
}

pub(super) fn read_metaimage_within(
    path: &Path,
    budget: Budget,
    pick: Pick,
) -> Result<(Grid, Orientation), IoError> {
    let bytes = budget.read_file(path)?;
    read_metaimage_bytes(path, &bytes, budget, pick)
}

/// [`read_metaimage_within`] on a file's bytes already in memory (`path` names it in errors and, for a
/// detached header, locates its data).
pub(super) fn read_metaimage_bytes(
    path: &Path,
    bytes: &[u8],
    budget: Budget,
    pick: Pick,
) -> Result<(Grid, Orientation), IoError> {
    let header = Header::parse(path, bytes)?;
    let volume = header.pick(path, pick)?;
    let (count, need) = header.sizes(path)?;
    // The file, the unpacked data when compressed, and the values.
    let unpacked = if header.compressed { need as u64 } else { 0 };
    let held = bytes.len() as u64 + unpacked;
    let dim_size = Position::Field("DimSize".into());
    budget.check_values(path, dim_size.clone(), held, count)?;
    match &header.data_file {
        None => finish(
            path,
            &header,
            path,
            &bytes[header.length..],
            count,
            need,
            volume,
        ),
        Some(name) => {
            // `.mhd` + `.raw`: errors about the data name the data file.
            let file = path.parent().unwrap_or(Path::new(".")).join(name);
            let data = budget.read_file_holding(&file, held + 4 * count as u64)?;
            finish(path, &header, &file, &data, count, need, volume)
        }
    }
}

/// Where an uncompressed MetaImage keeps its values (for [`super::MappedVolume`]), from the
/// mapped header file; `None` when they are zlib-compressed.
pub(super) fn placement(path: &Path, bytes: &[u8]) -> Result<Option<Placement>, IoError> {
    let header = Header::parse(path, bytes)?;
    if header.compressed || header.frames > 1 || header.channels > 1 {
        return Ok(None);
    }
    let (_, need) = header.sizes(path)?;
    let (data_file, start, len) = match &header.data_file {
        None => (None, header.length, bytes.len()),
        Some(name) => {
            let file = path.parent().unwrap_or(Path::new(".")).join(name);
            let len = std::fs::metadata(&file)
                .map_err(|e| IoError::os(&file, e))?
                .len() as usize;
            (Some(file), 0, len)
        }
    };
    let skip = match header.header_size {
        // −1: the data are the file's last bytes.
        Some(-1) => len.saturating_sub(start).saturating_sub(need),
        Some(n) if n >= 0 => n as usize,
        _ => 0,
    };
    let (spacing, orientation) = world(path, &header)?;
    Ok(Some(Placement {
        data_file,
        offset: start.saturating_add(skip),
        scalar: header.scalar,
        endian: header.endian,
        dims: header.dims,
        spacing,
        origin: header.offset,
        orientation,
        scale: None,
    }))
}

/// Spacing and orientation from `ElementSpacing` and `TransformMatrix`.
fn world(path: &Path, header: &Header) -> Result<([f64; 3], Orientation), IoError> {
    let linear: [[f64; 3]; 3] = std::array::from_fn(|r| {
        std::array::from_fn(|c| header.direction[c][r] * header.spacing[c])
    });
    Orientation::from_linear(linear).ok_or_else(|| {
        IoError::format(
            path,
            Position::Field("TransformMatrix".into()),
            "the direction matrix is singular or not finite",
        )
    })
}

fn finish(
    path: &Path,
    header: &Header,
    data_path: &Path,
    stored: &[u8],
    count: usize,
    need: usize,
    (frame, channel): (usize, usize),
) -> Result<(Grid, Orientation), IoError> {
    let raw: std::borrow::Cow<[u8]> = if header.compressed {
        // Never trust the declared size for the allocation: read at most what the dims need,
        // then check that exactly that much came out.
        let mut out = Vec::with_capacity(need);
        flate2::read::ZlibDecoder::new(stored)
            .take(need as u64 + 1)
            .read_to_end(&mut out)
            .map_err(|e| IoError::format(data_path, Position::File, format!("zlib data: {e}")))?;
        std::borrow::Cow::Owned(out)
    } else {
        let skip = match header.header_size {
            // −1: the data are the file's last bytes.
            Some(-1) => stored.len().saturating_sub(need),
            Some(n) if n >= 0 => n as usize,
            _ => 0,
        };
        std::borrow::Cow::Borrowed(stored.get(skip..).unwrap_or(&[]))
    };
    if raw.len() != need {
        return Err(IoError::format(
            data_path,
            Position::File,
            format!(
                "{:?} {} values need {need} bytes of data, {} {}",
                header.dims,
                header.scalar,
                if header.compressed {
                    "the zlib stream gives"
                } else {
                    "the file has"
                },
                raw.len()
            ),
        ));
    }
    let size = header.scalar.size();
    let values = if header.frames == 1 && header.channels == 1 {
        decode_all(&raw, header.scalar, header.endian)
    } else {
        // The picked volume's elements: frames one after another, channels interleaved.
        let first = frame * count * header.channels + channel;
        let picked: Vec<u8> = (0..count)
            .flat_map(|p| {
                let at = (first + p * header.channels) * size;
                raw[at..at + size].iter().copied()
            })
            .collect();
        decode_all(&picked, header.scalar, header.endian)
    };
    debug_assert_eq!(values.len(), count);
    let (spacing, orientation) = world(path, header)?;
    let grid = Grid::new(header.dims, values)
        .and_then(|g| g.with_spacing(spacing))
        .and_then(|g| g.with_origin(header.offset))
        .map_err(|e| IoError::grid(path, e))?;
    Ok((grid, orientation))
}

struct Header {
    /// The spatial axes' points.
    dims: [usize; 3],
    /// Volumes along a fourth axis (NDims = 4: time), 1 otherwise.
    frames: usize,
    /// Values per element (ElementNumberOfChannels), interleaved.
    channels: usize,
    scalar: ScalarType,
    endian: Endian,
    spacing: [f64; 3],
    offset: [f64; 3],
    /// The axis directions, one per row.
    direction: [[f64; 3]; 3],
    compressed: bool,
    header_size: Option<i64>,
    /// `None` for `LOCAL`.
    data_file: Option<String>,
    /// Bytes of the header, up to and including the `ElementDataFile` line.
    length: usize,
}

impl Header {
    /// The values of one volume, and the bytes of the data (every frame and channel).
    fn sizes(&self, path: &Path) -> Result<(usize, usize), IoError> {
        let count = self.dims.iter().try_fold(1usize, |n, &d| n.checked_mul(d));
        let need = count
            .and_then(|n| n.checked_mul(self.frames))
            .and_then(|n| n.checked_mul(self.channels))
            .and_then(|n| n.checked_mul(self.scalar.size()));
        match (count, need) {
            (Some(count), Some(need)) => Ok((count, need)),
            _ => Err(IoError::format(
                path,
                Position::Field("DimSize".into()),
                "dimensions overflow",
            )),
        }
    }

    /// The frame and channel `pick` chooses (each 0 where the file has one).
    fn pick(&self, path: &Path, pick: Pick) -> Result<(usize, usize), IoError> {
        let frame = Pick::index(
            path,
            Position::Field("DimSize".into()),
            pick.frame,
            self.frames,
            "--frame",
            "frames (a fourth axis)",
        )?;
        let channel = Pick::index(
            path,
            Position::Field("ElementNumberOfChannels".into()),
            pick.channel,
            self.channels,
            "--channel",
            "channels",
        )?;
        Ok((frame, channel))
    }

    fn parse(path: &Path, bytes: &[u8]) -> Result<Header, IoError> {
        let mut h = Header {
            dims: [0; 3],
            frames: 1,
            channels: 1,
            scalar: ScalarType::U8,
            endian: Endian::Little,
            spacing: [1.0; 3],
            offset: [0.0; 3],
            direction: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            compressed: false,
            header_size: None,
            data_file: None,
            length: 0,
        };
        let (mut seen_dims, mut seen_type, mut ndims) = (false, false, None);
        let mut at = 0;
        let mut line_no = 0;
        loop {
            line_no += 1;
            let Some(end) = bytes[at..].iter().position(|&b| b == b'\n') else {
                return Err(IoError::format(
                    path,
                    Position::Line(line_no),
                    "the header ends without ElementDataFile",
                ));
            };
            let raw = &bytes[at..at + end];
            at += end + 1;
            let line = std::str::from_utf8(raw)
                .map_err(|_| IoError::format(path, Position::Line(line_no), "not UTF-8 text"))?
                .trim();
            if line.is_empty() {
                continue;
            }
            let Some((key, value)) = line.split_once('=') else {
                return Err(IoError::format(
                    path,
                    Position::Line(line_no),
                    format!("'{line}' is not a 'Key = Value' line"),
                ));
            };
            let (key, value) = (key.trim(), value.trim());
            let pos = || Position::Line(line_no);
            let numbers = |n: usize| -> Result<Vec<f64>, IoError> {
                let v: Vec<f64> = value
                    .split_whitespace()
                    .map(|w| w.parse::<f64>())
                    .collect::<Result<_, _>>()
                    .map_err(|_| {
                        IoError::format(path, pos(), format!("{key}: '{value}' is not {n} numbers"))
                    })?;
                if v.len() != n || v.iter().any(|x| !x.is_finite()) {
                    return Err(IoError::format(
                        path,
                        pos(),
                        format!("{key}: '{value}' is not {n} finite numbers"),
                    ));
                }
                Ok(v)
            };
            let yes = || value.eq_ignore_ascii_case("true");
            match key {
                "ObjectType" if !value.eq_ignore_ascii_case("image") => {
                    return Err(IoError::unsupported(
                        path,
                        pos(),
                        format!("ObjectType {value}"),
                    ));
                }
                "NDims" => {
                    if !matches!(value, "1" | "2" | "3" | "4") {
                        return Err(IoError::unsupported(
                            path,
                            pos(),
                            format!(
                                "NDims {value}: isocube reads 1 to 3 dimensions, and a fourth \
                                 (time) picked by --frame"
                            ),
                        ));
                    }
                    ndims = Some(value.to_string());
                }
                "DimSize" => {
                    let v = numbers(ndims_of(&ndims))?;
                    for (a, &d) in v.iter().enumerate() {
                        if d < 1.0 || d.fract() != 0.0 || d > 1e12 {
                            return Err(IoError::format(
                                path,
                                pos(),
                                format!("DimSize: {d} is not a size"),
                            ));
                        }
                        if a < 3 {
                            h.dims[a] = d as usize;
                        } else {
                            h.frames = d as usize;
                        }
                    }
                    for a in v.len()..3 {
                        h.dims[a] = 1;
                    }
                    seen_dims = true;
                }
                // Of a fourth (time) axis only the spatial three count.
                "ElementSpacing" | "ElementSize" => {
                    let v = numbers(ndims_of(&ndims))?;
                    let n = v.len().min(3);
                    h.spacing[..n].copy_from_slice(&v[..n]);
                }
                "Offset" | "Origin" | "Position" => {
                    let v = numbers(ndims_of(&ndims))?;
                    let n = v.len().min(3);
                    h.offset[..n].copy_from_slice(&v[..n]);
                }
                "TransformMatrix" | "Rotation" | "Orientation" => {
                    let n = ndims_of(&ndims);
                    let v = numbers(n * n)?;
                    for a in 0..n.min(3) {
                        for r in 0..n.min(3) {
                            h.direction[a][r] = v[a * n + r];
                        }
                    }
                }
                "BinaryData" if !yes() => {
                    return Err(IoError::unsupported(
                        path,
                        pos(),
                        "ASCII MetaImage data (BinaryData = False)",
                    ));
                }
                "BinaryDataByteOrderMSB" | "ElementByteOrderMSB" => {
                    h.endian = if yes() { Endian::Big } else { Endian::Little };
                }
                "CompressedData" => h.compressed = yes(),
                "HeaderSize" => {
                    h.header_size = Some(value.parse().map_err(|_| {
                        IoError::format(
                            path,
                            pos(),
                            format!("HeaderSize: '{value}' is not a number"),
                        )
                    })?);
                }
                "ElementNumberOfChannels" => {
                    h.channels = value
                        .parse::<usize>()
                        .ok()
                        .filter(|&c| (1..=1 << 16).contains(&c))
                        .ok_or_else(|| {
                            IoError::format(
                                path,
                                pos(),
                                format!(
                                    "ElementNumberOfChannels: '{value}' is not a channel count"
                                ),
                            )
                        })?;
                }
                "ElementType" => {
                    h.scalar = match value {
                        "MET_CHAR" => ScalarType::I8,
                        "MET_UCHAR" => ScalarType::U8,
                        "MET_SHORT" => ScalarType::I16,
                        "MET_USHORT" => ScalarType::U16,
                        "MET_INT" | "MET_LONG" => ScalarType::I32,
                        "MET_UINT" | "MET_ULONG" => ScalarType::U32,
                        "MET_LONG_LONG" => ScalarType::I64,
                        "MET_ULONG_LONG" => ScalarType::U64,
                        "MET_FLOAT" => ScalarType::F32,
                        "MET_DOUBLE" => ScalarType::F64,
                        other => {
                            return Err(IoError::unsupported(
                                path,
                                pos(),
                                format!("ElementType {other}"),
                            ))
                        }
                    };
                    seen_type = true;
                }
                "ElementDataFile" => {
                    if value.eq_ignore_ascii_case("LOCAL") {
                        h.data_file = None;
                    } else if value.starts_with("LIST") || value.contains('%') {
                        return Err(IoError::unsupported(
                            path,
                            pos(),
                            "data split over several files (LIST or a file pattern)",
                        ));
                    } else {
                        h.data_file = Some(value.to_string());
                    }
                    h.length = at;
                    break;
                }
                _ => {}
            }
        }
        if !seen_dims || !seen_type {
            return Err(IoError::format(
                path,
                Position::Field(if seen_dims { "ElementType" } else { "DimSize" }.into()),
                "missing before ElementDataFile",
            ));
        }
        Ok(h)
    }
}

fn ndims_of(ndims: &Option<String>) -> usize {
    ndims.as_deref().and_then(|s| s.parse().ok()).unwrap_or(3)
}
