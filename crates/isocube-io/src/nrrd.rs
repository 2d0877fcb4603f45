//! NRRD volumes: attached (`.nrrd`) and detached (`.nhdr` + data file) headers, raw, gzip and
//! ASCII encodings, 3-D scalar data.
//!
//! Spacing comes from `spacings` or from the lengths of the `space directions` vectors, the
//! orientation from those vectors' directions ([`read_nrrd_oriented`]), the origin from
//! `space origin`.

use std::io::Read;
use std::path::{Path, PathBuf};

use super::mapped::Placement;
use super::raw::{decode_all, Endian, ScalarType};
use super::{Budget, IoError, Pick, Position};
use isocube::field::{Grid, Orientation};

/// Reads an NRRD file (attached or detached header) in its grid frame (see
/// [`read_nrrd_oriented`]).
pub fn read_nrrd(path: &Path) -> Result<Grid, IoError> {
    read_nrrd_oriented(path).map(|(grid, _)| grid)
}

/// Reads an NRRD file and the orientation of its `space directions`.
pub fn read_nrrd_oriented(path: &Path) -> Result<(Grid, Orientation), IoError> {
    read_nrrd_within(path, Budget::UNLIMITED, Pick::default())
}

pub(super) fn read_nrrd_within(
    path: &Path,
    budget: Budget,
    pick: Pick,
) -> Result<(Grid, Orientation), IoError> {
    let bytes = budget.read_file(path)?;
    read_nrrd_bytes(path, &bytes, budget, pick)
}

/// [`read_nrrd_within`] on a file's bytes already in memory (`path` names it in errors and, for a
/// detached header, locates its data).
pub(super) fn read_nrrd_bytes(
    path: &Path,
    bytes: &[u8],
    budget: Budget,
    pick: Pick,
) -> Result<(Grid, Orientation), IoError> {
    let header = Header::parse(path, bytes)?;
    let index = header.pick(path, pick)?;
    let grid = read_data(path, bytes, &header, budget, index)?;
    Ok((grid, header.orientation))
}

/// Where a raw-encoded NRRD keeps its values (for [`super::MappedVolume`]), attached or in a
/// detached data file, from the mapped header file; `None` for gzip and ASCII data and for
/// `line skip`, which the reader handles.
pub(super) fn placement(path: &Path, bytes: &[u8]) -> Result<Option<Placement>, IoError> {
    let header = Header::parse(path, bytes)?;
    if header.encoding != Encoding::Raw || header.line_skip > 0 || header.extra.is_some() {
        return Ok(None);
    }
    let (data_file, start, len) = match &header.data_file {
        None => (None, header.data_offset, bytes.len()),
        Some(name) => {
            let file = path
                .parent()
                .map(|d| d.join(name))
                .unwrap_or_else(|| PathBuf::from(name));
            let len = std::fs::metadata(&file)
                .map_err(|e| IoError::os(&file, e))?
                .len() as usize;
            (Some(file), 0, len)
        }
    };
    let need = Grid::point_count(header.dims)
        .ok()
        .and_then(|n| n.checked_mul(header.scalar.size()));
    let offset = match (header.byte_skip, need) {
        // −1: the values are the data's last bytes.
        (-1, Some(need)) if len >= start + need => len - need,
        (skip, _) if skip >= 0 => start.saturating_add(skip as usize),
        // Too short for its values: the reader says so.
        _ => return Ok(None),
    };
    Ok(Some(Placement {
        data_file,
        offset,
        scalar: header.scalar,
        endian: header.endian,
        dims: header.dims,
        spacing: header.spacing,
        origin: header.origin,
        orientation: header.orientation,
        scale: None,
    }))
}

/// The picked volume's values out of all the elements' (`extra` entries each voxel, along the
/// first axis — interleaved — or the last — one volume after another).
fn pick_values(all: Vec<f32>, count: usize, extra: Option<Extra>, index: usize) -> Vec<f32> {
    match extra {
        None => all,
        Some(e) if e.axis == 0 => all
            .into_iter()
            .skip(index)
            .step_by(e.n)
            .take(count)
            .collect(),
        Some(_) => all.into_iter().skip(index * count).take(count).collect(),
    }
}

fn read_data(
    path: &Path,
    bytes: &[u8],
    header: &Header,
    budget: Budget,
    index: usize,
) -> Result<Grid, IoError> {
    let dims = header.dims;
    let voxels = Grid::point_count(dims).map_err(|e| IoError::grid(path, e))?;
    let sizes = Position::Field("sizes".into());
    // Every element is read (and decoded), then the picked volume's kept.
    let n = header.extra.map_or(1, |e| e.n);
    let count = voxels
        .checked_mul(n)
        .ok_or_else(|| IoError::format(path, sizes.clone(), "the sizes overflow"))?;
    // The header and the stored data are held while the values are decoded; gzip data also
    // holds what it unpacks to.
    let unpacked = match header.encoding {
        Encoding::Gzip => (count as u64)
            .saturating_mul(header.scalar.size() as u64)
            .saturating_add(header.byte_skip.max(0) as u64),
        _ => 0,
    };
    let held = 2 * bytes.len() as u64 + unpacked;
    budget.check_values(path, sizes.clone(), held, count)?;
    let (data_path, data): (PathBuf, Vec<u8>) = match &header.data_file {
        Some(name) => {
            let p = path
                .parent()
                .map(|d| d.join(name))
                .unwrap_or_else(|| PathBuf::from(name));
            let d = budget.read_file_holding(&p, held + 4 * count as u64)?;
            (p, d)
        }
        None => (path.to_path_buf(), bytes[header.data_offset..].to_vec()),
    };
    let data = if header.line_skip > 0 {
        let mut at = 0;
        for _ in 0..header.line_skip {
            at += data[at..].iter().position(|&b| b == b'\n').ok_or_else(|| {
                IoError::format(&data_path, Position::File, "fewer lines than 'line skip'")
            })? + 1;
        }
        data[at..].to_vec()
    } else {
        data
    };
    let data = match header.encoding {
        Encoding::Raw => data,
        Encoding::Gzip => {
            // Decompress no more than the values need (after a known byte skip): a small file
            // cannot unpack into gigabytes the header never asked for.
            // With `byte skip: -1` the values are the stream's last bytes, so all of it is
            // unpacked, within what the memory limit leaves.
            let others = held - unpacked + data.len() as u64 + 4 * count as u64;
            let room = budget.limit().saturating_sub(others);
            let whole = header.byte_skip < 0;
            let limit = if whole {
                room.saturating_add(1)
            } else {
                unpacked
            };
            let out = gunzip(&data, limit).map_err(|e| {
                IoError::format(&data_path, Position::File, format!("gzip data: {e}"))
            })?;
            if whole && out.len() as u64 > room {
                // Count the rest without keeping it, so the message gives the real size.
                let mut rest = flate2::read::MultiGzDecoder::new(&data[..]);
                let total =
                    std::io::copy(&mut rest, &mut std::io::sink()).unwrap_or(out.len() as u64);
                return Err(IoError::TooLarge {
                    path: data_path,
                    position: Position::Field("byte skip".into()),
                    needed: others.saturating_add(total),
                    limit: budget.limit(),
                });
            }
            out
        }
        Encoding::Ascii => return ascii_grid(&data_path, &data, header, count, index),
    };
    let size = header.scalar.size();
    let need = count * size;
    let data: &[u8] = match header.byte_skip {
        -1 if data.len() >= need => &data[data.len() - need..],
        skip if skip >= 0 && (skip as usize) <= data.len() => &data[skip as usize..],
        _ => {
            return Err(IoError::format(
                &data_path,
                Position::File,
                format!("byte skip {} runs past the data", header.byte_skip),
            ))
        }
    };
    if data.len() < need {
        return Err(IoError::format(
            &data_path,
            Position::Byte(data.len() as u64),
            format!(
                "{dims:?} {} values need {need} bytes, the data has {}",
                header.scalar,
                data.len()
            ),
        ));
    }
    let values = decode_all(&data[..need], header.scalar, header.endian);
    let values = pick_values(values, voxels, header.extra, index);
    finish(path, dims, values, header)
}

/// The first `limit` bytes a gzip stream unpacks to (all of it when it is shorter).
fn gunzip(data: &[u8], limit: u64) -> std::io::Result<Vec<u8>> {
    let mut out = Vec::new();
    flate2::read::MultiGzDecoder::new(data)
        .take(limit)
        .read_to_end(&mut out)?;
    Ok(out)
}

fn ascii_grid(
    path: &Path,
    data: &[u8],
    header: &Header,
    count: usize,
    index: usize,
) -> Result<Grid, IoError> {
    let text = std::str::from_utf8(data)
        .map_err(|e| IoError::format(path, Position::Byte(e.valid_up_to() as u64), "not text"))?;
    let mut values = Vec::with_capacity(count);
    for (n, line) in text.lines().enumerate() {
        for tok in line
            .split(|c: char| c.is_whitespace() || c == ',')
            .filter(|t| !t.is_empty())
        {
            let v = header.scalar.parse_text(tok).ok_or_else(|| {
                IoError::format(
                    path,
                    Position::Line(n + 1),
                    format!("'{tok}' is not a {}", header.scalar),
                )
            })?;
            values.push(v as f32);
        }
    }
    if values.len() < count {
        return Err(IoError::format(
            path,
            Position::File,
            format!(
                "{:?} needs {count} values, found {}",
                header.dims,
                values.len()
            ),
        ));
    }
    values.truncate(count);
    let voxels = count / header.extra.map_or(1, |e| e.n);
    let values = pick_values(values, voxels, header.extra, index);
    finish(path, header.dims, values, header)
}

fn finish(path: &Path, dims: [usize; 3], values: Vec<f32>, h: &Header) -> Result<Grid, IoError> {
    Grid::new(dims, values)
        .and_then(|g| g.with_spacing(h.spacing))
        .and_then(|g| g.with_origin(h.origin))
        .map_err(|e| IoError::grid(path, e))
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Encoding {
    Raw,
    Gzip,
    Ascii,
}

/// A fourth, non-spatial axis: its place (0: the values of each voxel interleaved, as
/// `vector` kinds are; 3: whole volumes one after another, as `list` and `time` are), its
/// entries, and whether they are channels (else frames).
#[derive(Clone, Copy, Debug)]
struct Extra {
    axis: usize,
    n: usize,
    channels: bool,
}

struct Header {
    /// The spatial axes' points.
    dims: [usize; 3],
    extra: Option<Extra>,
    scalar: ScalarType,
    endian: Endian,
    encoding: Encoding,
    spacing: [f64; 3],
    origin: [f64; 3],
    orientation: Orientation,
    data_file: Option<String>,
    line_skip: usize,
    byte_skip: i64,
    data_offset: usize,
}

impl Header {
    /// The entry of the non-spatial axis `pick` chooses (0 without one).
    fn pick(&self, path: &Path, pick: Pick) -> Result<usize, IoError> {
        let Some(extra) = self.extra else {
            return Pick::index(
                path,
                Position::Field("sizes".into()),
                pick.frame.or(pick.channel),
                1,
                "--frame",
                "frames or channels",
            );
        };
        let (chosen, flag, what) = if extra.channels {
            (pick.channel, "--channel", "channels")
        } else {
            (pick.frame, "--frame", "frames")
        };
        Pick::index(
            path,
            Position::Field("kinds".into()),
            chosen,
            extra.n,
            flag,
            what,
        )
    }

    fn parse(path: &Path, bytes: &[u8]) -> Result<Header, IoError> {
        if !bytes.starts_with(b"NRRD000") {
            return Err(IoError::format(
                path,
                Position::Line(1),
                "not an NRRD file (missing the NRRD000x magic)",
            ));
        }
        let mut sizes: Option<Vec<usize>> = None;
        let mut kinds: Option<Vec<String>> = None;
        let mut spacings: Option<Vec<f64>> = None;
        let mut direction_list: Option<(Vec<Option<Vec<f64>>>, usize)> = None;
        let mut dimension = None;
        let mut scalar = None;
        let mut endian = None;
        let mut encoding = None;
        let mut origin = [0.0; 3];
        let mut data_file = None;
        let mut line_skip = 0;
        let mut byte_skip = 0i64;
        let mut at = 0usize;
        let mut line_no = 0;
        let data_offset = loop {
            let Some(len) = bytes[at..].iter().position(|&b| b == b'\n') else {
                // A detached header may end without a blank line.
                if data_file.is_some() {
                    break bytes.len();
                }
                return Err(IoError::format(
                    path,
                    Position::Line(line_no + 1),
                    "header ends before the blank line that starts the data",
                ));
            };
            line_no += 1;
            let line = std::str::from_utf8(&bytes[at..at + len])
                .map_err(|_| {
                    IoError::format(path, Position::Line(line_no), "header line is not text")
                })?
                .trim_end_matches('\r');
            at += len + 1;
            if line_no == 1 || line.starts_with('#') {
                continue;
            }
            if line.is_empty() {
                break at;
            }
            if line.contains(":=") {
                continue; // key/value pairs carry no geometry
            }
            let Some((key, value)) = line.split_once(": ") else {
                return Err(IoError::format(
                    path,
                    Position::Line(line_no),
                    format!("expected 'field: value', got '{line}'"),
                ));
            };
            let value = value.trim();
            let pos = || Position::Line(line_no);
            let numbers = |v: &str| -> Result<Vec<f64>, IoError> {
                v.split_whitespace()
                    .map(|t| {
                        t.parse::<f64>().map_err(|_| {
                            IoError::format(
                                path,
                                pos(),
                                format!("'{t}' is not a number in '{key}'"),
                            )
                        })
                    })
                    .collect()
            };
            match key {
                "dimension" => {
                    dimension =
                        Some(value.parse::<usize>().map_err(|_| {
                            IoError::format(path, pos(), "dimension is not a number")
                        })?);
                }
                "type" => {
                    scalar = Some(parse_type(value).ok_or_else(|| {
                        IoError::unsupported(path, pos(), format!("type '{value}'"))
                    })?);
                }
                "sizes" => {
                    let s: Vec<usize> = value
                        .split_whitespace()
                        .map(|t| {
                            t.parse().map_err(|_| {
                                IoError::format(path, pos(), format!("'{t}' is not a size"))
                            })
                        })
                        .collect::<Result<_, _>>()?;
                    if !(3..=4).contains(&s.len()) {
                        return Err(IoError::unsupported(
                            path,
                            pos(),
                            format!(
                                "{} axes (3-D volumes are read, and 4-D ones with one \
                                 non-spatial axis, picked by --frame or --channel)",
                                s.len()
                            ),
                        ));
                    }
                    sizes = Some(s);
                }
                "kinds" => {
                    kinds = Some(value.split_whitespace().map(str::to_string).collect());
                }
                "endian" => {
                    endian = Some(match value {
                        "little" => Endian::Little,
                        "big" => Endian::Big,
                        _ => return Err(IoError::format(path, pos(), format!("endian '{value}'"))),
                    })
                }
                "encoding" => {
                    encoding = Some(match value {
                        "raw" => Encoding::Raw,
                        "gzip" | "gz" => Encoding::Gzip,
                        "ascii" | "text" | "txt" => Encoding::Ascii,
                        _ => {
                            return Err(IoError::unsupported(
                                path,
                                pos(),
                                format!("encoding '{value}'"),
                            ))
                        }
                    })
                }
                "spacings" => {
                    // A non-spatial axis's spacing is NaN.
                    spacings = Some(numbers(value)?);
                }
                "space directions" => {
                    // One `(x,y,z)` per axis, `none` for a non-spatial one.
                    let mut list = Vec::new();
                    let mut rest = value.trim();
                    while !rest.is_empty() {
                        if let Some(after) = rest.strip_prefix("none") {
                            list.push(None);
                            rest = after.trim_start();
                        } else if let Some(after) = rest.strip_prefix('(') {
                            let end = after.find(')').ok_or_else(|| {
                                IoError::format(
                                    path,
                                    pos(),
                                    "an unclosed vector in space directions",
                                )
                            })?;
                            list.push(Some(numbers(&after[..end].replace(',', " "))?));
                            rest = after[end + 1..].trim_start();
                        } else {
                            return Err(IoError::format(
                                path,
                                pos(),
                                format!("space directions: '{rest}' is neither a vector nor none"),
                            ));
                        }
                    }
                    direction_list = Some((list, line_no));
                }
                "space origin" => {
                    let o = numbers(
                        &value
                            .trim_matches(|c| c == '(' || c == ')')
                            .replace(',', " "),
                    )?;
                    if o.len() != 3 {
                        return Err(IoError::format(path, pos(), "space origin needs 3 numbers"));
                    }
                    origin = [o[0], o[1], o[2]];
                }
                "data file" | "datafile" => {
                    if value.starts_with("LIST") || value.split_whitespace().count() > 1 {
                        return Err(IoError::unsupported(path, pos(), "multi-file data"));
                    }
                    data_file = Some(value.to_string());
                }
                "line skip" | "lineskip" => {
                    line_skip = value
                        .parse()
                        .map_err(|_| IoError::format(path, pos(), "line skip is not a number"))?;
                }
                "byte skip" | "byteskip" => {
                    byte_skip = value
                        .parse()
                        .map_err(|_| IoError::format(path, pos(), "byte skip is not a number"))?;
                    if byte_skip < -1 {
                        return Err(IoError::format(path, pos(), "byte skip must be -1 or more"));
                    }
                }
                _ => {}
            }
        };
        let field = |name: &str| Position::Field(name.into());
        let sizes = sizes.ok_or_else(|| IoError::format(path, field("sizes"), "missing"))?;
        if let Some(d) = dimension {
            if d != sizes.len() {
                return Err(IoError::format(
                    path,
                    field("dimension"),
                    format!("dimension {d} with {} sizes", sizes.len()),
                ));
            }
        }
        // Which axis is not spatial: by its kind, or by `none` among the space directions.
        let spatial_kind = |k: &str| matches!(k, "domain" | "space" | "???" | "none");
        let extra_axis = if sizes.len() == 4 {
            let by_kind = kinds
                .as_ref()
                .filter(|k| k.len() == 4)
                .and_then(|k| k.iter().position(|k| !spatial_kind(k)));
            let by_direction = direction_list
                .as_ref()
                .and_then(|(l, _)| l.iter().position(Option::is_none));
            match by_kind.or(by_direction) {
                Some(a @ (0 | 3)) => Some(a),
                Some(a) => {
                    return Err(IoError::unsupported(
                        path,
                        field("kinds"),
                        format!("the non-spatial axis is axis {a}: isocube reads it first (interleaved) or last"),
                    ))
                }
                None => {
                    return Err(IoError::unsupported(
                        path,
                        field("kinds"),
                        "4 axes without kinds or space directions telling which is not spatial",
                    ))
                }
            }
        } else {
            None
        };
        let spatial: Vec<usize> = (0..sizes.len())
            .filter(|&a| Some(a) != extra_axis)
            .collect();
        let dims = [sizes[spatial[0]], sizes[spatial[1]], sizes[spatial[2]]];
        let extra = extra_axis.map(|axis| {
            let kind = kinds
                .as_ref()
                .and_then(|k| k.get(axis))
                .map_or("", String::as_str);
            Extra {
                axis,
                n: sizes[axis],
                channels: !matches!(kind, "list" | "time"),
            }
        });
        let spacing = match spacings {
            Some(v) if v.len() == sizes.len() => {
                Some([v[spatial[0]], v[spatial[1]], v[spatial[2]]])
            }
            Some(_) => {
                return Err(IoError::format(
                    path,
                    field("spacings"),
                    format!("needs {} numbers", sizes.len()),
                ))
            }
            None => None,
        };
        let directions = match direction_list {
            Some((list, line)) => {
                let vectors: Vec<&Vec<f64>> = spatial
                    .iter()
                    .filter_map(|&a| list.get(a).and_then(Option::as_ref))
                    .collect();
                if list.len() != sizes.len()
                    || vectors.len() != 3
                    || vectors.iter().any(|v| v.len() != 3)
                {
                    return Err(IoError::format(
                        path,
                        Position::Line(line),
                        "space directions needs a 3-vector for each spatial axis",
                    ));
                }
                // Each vector is one axis's step: the columns of the index-to-world map.
                let linear: [[f64; 3]; 3] =
                    std::array::from_fn(|r| std::array::from_fn(|c| vectors[c][r]));
                Some(Orientation::from_linear(linear).ok_or_else(|| {
                    IoError::format(
                        path,
                        Position::Line(line),
                        "the space directions are singular",
                    )
                })?)
            }
            None => None,
        };
        let scalar = scalar.ok_or_else(|| IoError::format(path, field("type"), "missing"))?;
        let encoding =
            encoding.ok_or_else(|| IoError::format(path, field("encoding"), "missing"))?;
        let endian = match endian {
            Some(e) => e,
            None if scalar.size() == 1 || encoding == Encoding::Ascii => Endian::Little,
            None => {
                return Err(IoError::format(
                    path,
                    field("endian"),
                    "missing (needed for multi-byte types)",
                ))
            }
        };
        Ok(Header {
            dims,
            extra,
            scalar,
            endian,
            encoding,
            spacing: spacing.or(directions.map(|d| d.0)).unwrap_or([1.0; 3]),
            origin,
            orientation: directions.map_or(Orientation::IDENTITY, |d| d.1),
            data_file,
            line_skip,
            byte_skip,
            data_offset,
        })
    }
}

fn parse_type(t: &str) -> Option<ScalarType> {
    Some(match t {
        "signed char" | "int8" | "int8_t" => ScalarType::I8,
        "uchar" | "unsigned char" | "uint8" | "uint8_t" => ScalarType::U8,
        "short" | "short int" | "signed short" | "signed short int" | "int16" | "int16_t" => {
            ScalarType::I16
        }
        "ushort" | "unsigned short" | "unsigned short int" | "uint16" | "uint16_t" => {
            ScalarType::U16
        }
        "int" | "signed int" | "int32" | "int32_t" => ScalarType::I32,
        "uint" | "unsigned int" | "uint32" | "uint32_t" => ScalarType::U32,
        "longlong"
        | "long long"
        | "long long int"
        | "signed long long"
        | "signed long long int"
        | "int64"
        | "int64_t" => ScalarType::I64,
        "ulonglong" | "unsigned long long" | "unsigned long long int" | "uint64" | "uint64_t" => {
            ScalarType::U64
        }
        "float" => ScalarType::F32,
        "double" => ScalarType::F64,
        _ => return None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    fn header(encoding: &str, extra: &str) -> String {
        format!(
            "NRRD0004\n# written by the test\ntype: short\ndimension: 3\nsizes: 3 2 2\nendian: big\nencoding: {encoding}\nspace dimension: 3\nspace directions: (0.5,0,0) (0,0.25,0) (0,0,2)\nspace origin: (1,2,3)\n{extra}"
        )
    }

    fn values() -> Vec<i16> {
        (0..12).map(|v| v * 3 - 10).collect()
    }

    fn check(g: &Grid) {
        assert_eq!(g.dims(), [3, 2, 2]);
        assert_eq!(g.spacing(), [0.5, 0.25, 2.0]);
        assert_eq!(g.origin(), [1.0, 2.0, 3.0]);
        let expect: Vec<f32> = values().iter().map(|&v| f32::from(v)).collect();
        assert_eq!(g.values(), &expect[..]);
    }

    #[test]
    fn attached_raw_gzip_and_ascii() {
        let dir = tempfile::tempdir().unwrap();
        let raw: Vec<u8> = values().iter().flat_map(|v| v.to_be_bytes()).collect();
        let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
        gz.write_all(&raw).unwrap();
        let gz = gz.finish().unwrap();
        let ascii: String = values().iter().map(|v| format!("{v}\n")).collect();
        for (enc, data) in [
            ("raw", raw.clone()),
            ("gzip", gz.clone()),
            ("ascii", ascii.into_bytes()),
        ] {
            let p = dir.path().join(format!("{enc}.nrrd"));
            let mut bytes = header(enc, "\n").into_bytes();
            bytes.extend_from_slice(&data);
            std::fs::write(&p, bytes).unwrap();
            check(&read_nrrd(&p).unwrap_or_else(|e| panic!("{enc}: {e}")));
        }
        // Detached header with the data beside it.
        std::fs::write(dir.path().join("vol.raw.gz"), &gz).unwrap();
        let p = dir.path().join("vol.nhdr");
        std::fs::write(&p, header("gzip", "data file: vol.raw.gz\n")).unwrap();
        check(&read_nrrd(&p).unwrap());
    }

    /// A few hundred bytes of gzip that would unpack to 64 MiB: only the 8 bytes the header
    /// asks for are unpacked.
    #[test]
    fn gzip_data_is_unpacked_only_as_far_as_needed() {
        use std::io::Write;
        let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::best());
        let zeros = vec![1u8; 1 << 20];
        for _ in 0..64 {
            e.write_all(&zeros).unwrap();
        }
        let packed = e.finish().unwrap();
        assert!(packed.len() < 100_000);
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("bomb.nrrd");
        let head = b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: gzip\n\n";
        std::fs::write(&p, [&head[..], &packed].concat()).unwrap();
        let grid = read_nrrd(&p).unwrap();
        assert_eq!(grid.values(), &[1.0; 8]);
        assert_eq!(gunzip(&packed, 8).unwrap().len(), 8);
        assert_eq!(gunzip(&packed, u64::MAX).unwrap().len(), 64 << 20);
    }

    #[test]
    fn malformed_headers_name_the_problem() {
        let dir = tempfile::tempdir().unwrap();
        let raw: Vec<u8> = values().iter().flat_map(|v| v.to_be_bytes()).collect();
        let cases = [
            ("magic", "NRRX0004\n\n".to_string(), "magic"),
            (
                "type",
                header("raw", "\n").replace("type: short", "type: complex"),
                "type 'complex'",
            ),
            (
                "sizes",
                header("raw", "\n").replace("sizes: 3 2 2", "sizes: 3 2"),
                "2 axes",
            ),
            (
                "endian",
                header("raw", "\n").replace("endian: big\n", ""),
                "endian",
            ),
            ("noblank", header("raw", ""), "blank line"),
            (
                "number",
                header("raw", "\n").replace("(0.5,0,0)", "(x,0,0)"),
                "'x' is not a number",
            ),
        ];
        for (name, text, needle) in cases {
            let p = dir.path().join(format!("{name}.nrrd"));
            let mut bytes = text.into_bytes();
            bytes.extend_from_slice(&raw);
            std::fs::write(&p, bytes).unwrap();
            let err = read_nrrd(&p).unwrap_err().to_string();
            assert!(err.contains(needle), "{name}: {err}");
        }
        let p = dir.path().join("short.nrrd");
        let mut bytes = header("raw", "\n").into_bytes();
        bytes.extend_from_slice(&raw[..10]);
        std::fs::write(&p, bytes).unwrap();
        let err = read_nrrd(&p).unwrap_err().to_string();
        assert!(err.contains("need 24 bytes"), "{err}");
        let p = dir.path().join("missing.nhdr");
        std::fs::write(&p, header("raw", "data file: nowhere.raw\n")).unwrap();
        let err = read_nrrd(&p).unwrap_err().to_string();
        assert!(err.contains("nowhere.raw"), "{err}");
    }
}
