//! VTK XML unstructured grids (`.vtu`) read back for their tetrahedra: points and cells given
//! inline (ASCII or base64) or appended raw, uncompressed, either byte order, 32- or 64-bit
//! block headers — what `isocube tetmesh` writes and what VTK and ParaView write uncompressed.

use std::path::Path;

use base64::Engine;
use quick_xml::events::Event;

use super::tet_read::Parsed;
use super::{IoError, Position};

/// One `DataArray` as the header describes it.
#[derive(Default)]
struct Array {
    kind: String,
    format: String,
    components: usize,
    offset: usize,
    text: String,
}

/// The points and the 4-node tetrahedra (cell type 10) of a `.vtu` file; other cells skipped.
pub(super) fn vtu(bytes: &[u8], name: &Path) -> Result<Parsed, IoError> {
    let field = |f: &str| Position::Field(f.into());
    let format = |f: &str, reason: String| IoError::format(name, field(f), reason);
    let appended = find(bytes, b"<AppendedData");
    let head = &bytes[..appended.unwrap_or(bytes.len())];
    let mut reader = quick_xml::Reader::from_reader(head);
    let mut buf = Vec::new();
    let (mut little, mut header, mut grid) = (true, 4usize, false);
    let (mut points, mut cells) = (None::<usize>, None::<usize>);
    let mut section = String::new();
    let mut arrays: Vec<(String, Array)> = Vec::new();
    let mut current: Option<(String, Array)> = None;
    loop {
        let pos = Position::Byte(reader.buffer_position());
        let event = reader
            .read_event_into(&mut buf)
            .map_err(|e| IoError::format(name, pos.clone(), format!("XML: {e}")))?;
        match event {
            Event::Start(ref e) | Event::Empty(ref e) => {
                let empty = matches!(event, Event::Empty(_));
                let mut attrs: Vec<(String, String)> = Vec::new();
                for a in e.attributes() {
                    let a =
                        a.map_err(|e| IoError::format(name, pos.clone(), format!("XML: {e}")))?;
                    let value = a
                        .unescape_value()
                        .map_err(|e| IoError::format(name, pos.clone(), format!("XML: {e}")))?;
                    attrs.push((
                        String::from_utf8_lossy(a.key.as_ref()).into_owned(),
                        value.into_owned(),
                    ));
                }
                let get = |k: &str| attrs.iter().find(|(n, _)| n == k).map(|(_, v)| v.clone());
                let count = |k: &str| -> Result<Option<usize>, IoError> {
                    get(k)
                        .map(|v| {
                            v.trim()
                                .parse::<usize>()
                                .map_err(|_| format(k, format!("'{v}' is not a count")))
                        })
                        .transpose()
                };
                match e.name().as_ref() {
                    b"VTKFile" => {
                        grid = get("type").as_deref() == Some("UnstructuredGrid");
                        little = get("byte_order").as_deref() != Some("BigEndian");
                        header = match get("header_type").as_deref() {
                            None | Some("UInt32") => 4,
                            Some("UInt64") => 8,
                            Some(other) => return Err(format("header_type", format!("'{other}'"))),
                        };
                        if get("compressor").is_some() {
                            return Err(IoError::unsupported(
                                name,
                                field("compressor"),
                                "compressed arrays",
                            ));
                        }
                    }
                    b"Piece" => {
                        if points.is_some() {
                            return Err(IoError::unsupported(name, pos, "more than one piece"));
                        }
                        points = count("NumberOfPoints")?;
                        cells = count("NumberOfCells")?;
                    }
                    b"Points" | b"Cells" | b"PointData" | b"CellData" if !empty => {
                        section = String::from_utf8_lossy(e.name().as_ref()).into_owned();
                    }
                    b"DataArray" => {
                        let which = match section.as_str() {
                            "Points" => "Points".to_string(),
                            "Cells" => get("Name").unwrap_or_default(),
                            _ => String::new(),
                        };
                        let array = Array {
                            kind: get("type").unwrap_or_default(),
                            format: get("format").unwrap_or_else(|| "ascii".into()),
                            components: count("NumberOfComponents")?.unwrap_or(1),
                            offset: count("offset")?.unwrap_or(0),
                            text: String::new(),
                        };
                        if empty {
                            arrays.push((which, array));
                        } else {
                            current = Some((which, array));
                        }
                    }
                    _ => {}
                }
            }
            Event::Text(t) => {
                if let Some((_, a)) = current.as_mut() {
                    a.text.push_str(&String::from_utf8_lossy(t.as_ref()));
                }
            }
            Event::End(ref e) => match e.name().as_ref() {
                b"DataArray" => arrays.extend(current.take()),
                b"Points" | b"Cells" | b"PointData" | b"CellData" => section.clear(),
                _ => {}
            },
            Event::Eof => break,
            _ => {}
        }
        buf.clear();
    }
    if !grid {
        return Err(IoError::unsupported(
            name,
            field("type"),
            "not an UnstructuredGrid",
        ));
    }
    let (Some(n), Some(c)) = (points, cells) else {
        return Err(format("Piece", "no piece with points and cells".into()));
    };
    let base = match appended {
        Some(start) => {
            let tag_end = find(&bytes[start..], b">").map(|i| start + i + 1);
            if tag_end
                .and_then(|e| find(&bytes[start..e], b"base64"))
                .is_some()
            {
                return Err(IoError::unsupported(
                    name,
                    field("AppendedData"),
                    "base64 appended data (raw is read)",
                ));
            }
            let underscore = tag_end.and_then(|e| find(&bytes[e..], b"_").map(|i| e + i + 1));
            Some(
                underscore
                    .ok_or_else(|| format("AppendedData", "no '_' before the data".into()))?,
            )
        }
        None => None,
    };
    let decode = |which: &str, expected: usize| -> Result<Vec<f64>, IoError> {
        let (_, a) = arrays
            .iter()
            .find(|(w, _)| w == which)
            .ok_or_else(|| format(which, "missing".into()))?;
        let size = match a.kind.as_str() {
            "Int8" | "UInt8" => 1,
            "Int16" | "UInt16" => 2,
            "Int32" | "UInt32" | "Float32" => 4,
            "Int64" | "UInt64" | "Float64" => 8,
            other => return Err(format(which, format!("type '{other}'"))),
        };
        let raw: Vec<u8> = match a.format.as_str() {
            "ascii" => {
                let values: Vec<f64> = a
                    .text
                    .split_whitespace()
                    .map(|w| w.parse::<f64>())
                    .collect::<Result<_, _>>()
                    .map_err(|_| format(which, "a value is not a number".into()))?;
                if values.len() != expected {
                    return Err(format(
                        which,
                        format!("{} values, {expected} expected", values.len()),
                    ));
                }
                return Ok(values);
            }
            "binary" => {
                let text: String = a.text.split_whitespace().collect();
                let block = base64::engine::general_purpose::STANDARD
                    .decode(text.as_bytes())
                    .map_err(|e| format(which, format!("base64: {e}")))?;
                block.get(header..).map(<[u8]>::to_vec).unwrap_or_default()
            }
            "appended" => {
                let base = base.ok_or_else(|| format(which, "no appended data".into()))?;
                let at = base
                    .checked_add(a.offset)
                    .filter(|&at| at.saturating_add(header) <= bytes.len())
                    .ok_or_else(|| format(which, "offset beyond the file".into()))?;
                let count = int(&bytes[at..at + header], little);
                let from = at + header;
                let to = usize::try_from(count)
                    .ok()
                    .and_then(|n| from.checked_add(n))
                    .filter(|&to| to <= bytes.len())
                    .ok_or_else(|| format(which, "a block runs past the end of the file".into()))?;
                bytes[from..to].to_vec()
            }
            other => return Err(format(which, format!("format '{other}'"))),
        };
        if raw.len() != expected.saturating_mul(size) {
            return Err(format(
                which,
                format!(
                    "{} bytes, {} expected",
                    raw.len(),
                    expected.saturating_mul(size)
                ),
            ));
        }
        Ok(raw
            .chunks_exact(size)
            .map(|b| number(&a.kind, b, little))
            .collect())
    };
    // Each count is bounded by the file before anything that size is decoded.
    if n.saturating_mul(3) > bytes.len() || c > bytes.len() {
        return Err(format(
            "Piece",
            "more points or cells than the file holds".into(),
        ));
    }
    let point_array = arrays.iter().find(|(w, _)| w == "Points");
    if point_array.is_some_and(|(_, a)| a.components != 3) {
        return Err(format("Points", "points need 3 components".into()));
    }
    let xyz = decode("Points", 3 * n)?;
    let offsets = decode("offsets", c)?;
    let types = decode("types", c)?;
    let total = offsets.last().copied().unwrap_or(0.0);
    if !(0.0..=bytes.len() as f64).contains(&total) || total.fract() != 0.0 {
        return Err(format("offsets", "offsets out of range".into()));
    }
    let connectivity = decode("connectivity", total as usize)?;
    let mut positions = Vec::with_capacity(n);
    for p in xyz.chunks_exact(3) {
        let q = [p[0] as f32, p[1] as f32, p[2] as f32];
        if q.iter().any(|x| !x.is_finite()) {
            return Err(format("Points", "a coordinate is not finite".into()));
        }
        positions.push(q);
    }
    let mut tets = Vec::new();
    let mut start = 0usize;
    for (end, kind) in offsets.iter().zip(&types) {
        let end_ok = (*end >= start as f64 && *end <= total && end.fract() == 0.0)
            .then_some(*end as usize)
            .ok_or_else(|| format("offsets", "offsets do not increase".into()))?;
        if *kind == 10.0 {
            if end_ok - start != 4 {
                return Err(format(
                    "connectivity",
                    "a tetrahedron without four points".into(),
                ));
            }
            let mut t = [0u32; 4];
            for (o, &v) in t.iter_mut().zip(&connectivity[start..end_ok]) {
                *o = Some(v)
                    .filter(|v| v.fract() == 0.0 && *v >= 0.0 && (*v as usize) < n)
                    .map(|v| v as u32)
                    .ok_or_else(|| format("connectivity", format!("point {v} does not exist")))?;
            }
            tets.push(t);
        }
        start = end_ok;
    }
    Ok((positions, tets))
}

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).position(|w| w == needle)
}

fn int(b: &[u8], little: bool) -> u64 {
    let mut x = [0u8; 8];
    if little {
        x[..b.len()].copy_from_slice(b);
        u64::from_le_bytes(x)
    } else {
        x[8 - b.len()..].copy_from_slice(b);
        u64::from_be_bytes(x)
    }
}

/// One value of a VTK scalar type from its bytes.
fn number(kind: &str, b: &[u8], little: bool) -> f64 {
    let mut x = [0u8; 8];
    x[..b.len()].copy_from_slice(b);
    if !little {
        x[..b.len()].reverse();
    }
    match kind {
        "Int8" => f64::from(x[0] as i8),
        "UInt8" => f64::from(x[0]),
        "Int16" => f64::from(i16::from_le_bytes([x[0], x[1]])),
        "UInt16" => f64::from(u16::from_le_bytes([x[0], x[1]])),
        "Int32" => f64::from(i32::from_le_bytes([x[0], x[1], x[2], x[3]])),
        "UInt32" => f64::from(u32::from_le_bytes([x[0], x[1], x[2], x[3]])),
        "Float32" => f64::from(f32::from_le_bytes([x[0], x[1], x[2], x[3]])),
        "Int64" => i64::from_le_bytes(x) as f64,
        "UInt64" => u64::from_le_bytes(x) as f64,
        _ => f64::from_le_bytes(x),
    }
}
