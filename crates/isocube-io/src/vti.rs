//! VTK ImageData (`.vti`, VTK's XML format): a single piece with point data in ASCII, inline
//! base64 binary, or appended data (raw or base64), uncompressed or zlib-compressed, with 32- or
//! 64-bit block headers; `Origin`, `Spacing`, `Direction` (row-major, columns the axes) and the
//! extent's start place the points in the world. The array is the point data's active scalars,
//! else its first array.

use std::io::Read;
use std::path::Path;

use base64::Engine;
use quick_xml::events::{BytesStart, Event};

use super::mapped::Placement;
use super::raw::{decode_all, Endian, ScalarType};
use super::{Budget, IoError, Position};
use isocube::field::{Grid, Orientation};

/// Reads a VTK ImageData file and its orientation.
pub fn read_vti(path: &Path) -> Result<(Grid, Orientation), IoError> {
    read_vti_within(path, Budget::UNLIMITED)
}

pub(super) fn read_vti_within(path: &Path, budget: Budget) -> Result<(Grid, Orientation), IoError> {
    let bytes = budget.read_file(path)?;
    read_vti_bytes(path, &bytes, budget)
}

/// [`read_vti_within`] on a file's bytes already in memory (`path` names it in errors and, for a
/// detached header, locates its data).
pub(super) fn read_vti_bytes(
    path: &Path,
    bytes: &[u8],
    budget: Budget,
) -> Result<(Grid, Orientation), IoError> {
    // Raw appended data is not XML: parse only what comes before it.
    let appended_tag = find(bytes, b"<AppendedData");
    let head = &bytes[..appended_tag.unwrap_or(bytes.len())];
    let doc = Document::parse(path, head)?;
    let whole_extent = || Position::Field("WholeExtent".into());
    let dims = doc.dims(path)?;
    let count = Grid::point_count(dims).map_err(|e| IoError::grid(path, e))?;
    let array = doc.array.as_ref().ok_or_else(|| {
        IoError::format(
            path,
            Position::Field("PointData".into()),
            "no point data array",
        )
    })?;
    let at = |what: &str| Position::Field(format!("DataArray '{}' {what}", array.name));
    if array.components != 1 {
        return Err(IoError::unsupported(
            path,
            at("NumberOfComponents"),
            format!("{} components: isocube meshes one scalar", array.components),
        ));
    }
    let need = count
        .checked_mul(array.scalar.size())
        .ok_or_else(|| IoError::format(path, whole_extent(), "the extent overflows"))?;
    // The file, a copy of its encoded text, the decoded bytes and the values.
    budget.check_values(
        path,
        whole_extent(),
        2 * bytes.len() as u64 + need as u64,
        count,
    )?;
    let raw: Vec<u8> = match array.format.as_str() {
        "ascii" => {
            let values: Vec<f32> = array
                .text
                .split_whitespace()
                .map(|w| w.parse::<f64>().map(|x| x as f32))
                .collect::<Result<_, _>>()
                .map_err(|_| IoError::format(path, at("text"), "not a list of numbers"))?;
            return finish(path, &doc, dims, values, count);
        }
        "binary" => {
            let text: Vec<u8> = array
                .text
                .bytes()
                .filter(|b| !b.is_ascii_whitespace())
                .collect();
            doc.decode_base64(path, &text, need, &at("data"))?
        }
        "appended" => {
            let start = appended_tag.ok_or_else(|| {
                IoError::format(
                    path,
                    at("format"),
                    "appended, but the file has no AppendedData",
                )
            })?;
            let (base, encoding) = appended_base(path, bytes, start)?;
            let from = base
                .checked_add(array.offset)
                .filter(|&f| f <= bytes.len())
                .ok_or_else(|| {
                    IoError::format(
                        path,
                        at("offset"),
                        format!("offset {} is past the end", array.offset),
                    )
                })?;
            if encoding.as_deref() == Some("base64") {
                let text: Vec<u8> = bytes[from..]
                    .iter()
                    .copied()
                    .take_while(|&b| b != b'<')
                    .filter(|b| !b.is_ascii_whitespace())
                    .collect();
                doc.decode_base64(path, &text, need, &at("data"))?
            } else {
                doc.decode_blocks(path, &bytes[from..], need, &at("data"))?
            }
        }
        other => {
            return Err(IoError::unsupported(
                path,
                at("format"),
                format!("format '{other}'"),
            ));
        }
    };
    let values = decode_all(&raw, array.scalar, doc.endian);
    finish(path, &doc, dims, values, count)
}

/// Where the appended data begin (after the `_`), and their encoding.
fn appended_base(
    path: &Path,
    bytes: &[u8],
    start: usize,
) -> Result<(usize, Option<String>), IoError> {
    let tag_end = find(&bytes[start..], b">").map(|i| start + i + 1);
    let underscore = tag_end.and_then(|e| find(&bytes[e..], b"_").map(|i| e + i + 1));
    let base = underscore.ok_or_else(|| {
        IoError::format(
            path,
            Position::Field("AppendedData".into()),
            "no '_' before the data",
        )
    })?;
    Ok((
        base,
        attribute_in(&bytes[start..tag_end.unwrap_or(start)], "encoding"),
    ))
}

/// Where a `.vti` keeps its values when they are raw appended data, uncompressed, one
/// component (for [`super::MappedVolume`]), from the mapped file; `None` for every other
/// encoding, which the reader decodes.
pub(super) fn placement(path: &Path, bytes: &[u8]) -> Result<Option<Placement>, IoError> {
    let Some(start) = find(bytes, b"<AppendedData") else {
        return Ok(None);
    };
    let doc = Document::parse(path, &bytes[..start])?;
    let Some(array) = doc.array.as_ref() else {
        return Ok(None);
    };
    if array.format != "appended" || array.components != 1 || doc.compressed {
        return Ok(None);
    }
    let (base, encoding) = appended_base(path, bytes, start)?;
    if encoding.as_deref() == Some("base64") {
        return Ok(None);
    }
    let dims = doc.dims(path)?;
    let need = Grid::point_count(dims)
        .ok()
        .and_then(|n| n.checked_mul(array.scalar.size()));
    let from = base.checked_add(array.offset);
    let header = from.and_then(|f| bytes.get(f..f.checked_add(doc.header)?));
    // A block whose byte count is not what the extent needs is the reader's to report.
    match (header, need) {
        (Some(h), Some(need)) if doc.int(h) == need => {}
        _ => return Ok(None),
    }
    let (spacing, origin, orientation) = doc.world(path)?;
    Ok(Some(Placement {
        data_file: None,
        offset: from.unwrap_or(0) + doc.header,
        scalar: array.scalar,
        endian: doc.endian,
        dims,
        spacing,
        origin,
        orientation,
        scale: None,
    }))
}

fn finish(
    path: &Path,
    doc: &Document,
    dims: [usize; 3],
    values: Vec<f32>,
    count: usize,
) -> Result<(Grid, Orientation), IoError> {
    if values.len() != count {
        return Err(IoError::format(
            path,
            Position::Field("DataArray".into()),
            format!("{} values for {dims:?} points", values.len()),
        ));
    }
    let (spacing, origin, orientation) = doc.world(path)?;
    let grid = Grid::new(dims, values)
        .and_then(|g| g.with_spacing(spacing))
        .and_then(|g| g.with_origin(origin))
        .map_err(|e| IoError::grid(path, e))?;
    Ok((grid, orientation))
}

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).position(|w| w == needle)
}

/// An attribute of the first tag in `tag` (a few bytes of raw XML).
fn attribute_in(tag: &[u8], name: &str) -> Option<String> {
    let text = String::from_utf8_lossy(tag);
    let key = format!("{name}=\"");
    let at = text.find(&key)? + key.len();
    Some(text[at..].split('"').next()?.to_string())
}

struct Array {
    name: String,
    scalar: ScalarType,
    format: String,
    offset: usize,
    components: usize,
    text: String,
}

struct Document {
    endian: Endian,
    /// Bytes per block-header integer.
    header: usize,
    compressed: bool,
    extent: [i64; 6],
    origin: [f64; 3],
    spacing: [f64; 3],
    direction: [[f64; 3]; 3],
    array: Option<Array>,
}

impl Document {
    /// Points per axis, from the extent.
    fn dims(&self, path: &Path) -> Result<[usize; 3], IoError> {
        let mut dims = [0usize; 3];
        for (a, d) in dims.iter_mut().enumerate() {
            *d = self.extent[2 * a + 1]
                .checked_sub(self.extent[2 * a])
                .and_then(|n| n.checked_add(1))
                .and_then(|n| usize::try_from(n).ok())
                .ok_or_else(|| {
                    IoError::format(
                        path,
                        Position::Field("WholeExtent".into()),
                        "the extent overflows",
                    )
                })?;
        }
        Ok(dims)
    }

    /// Spacing, origin (of the extent's first point) and orientation.
    fn world(&self, path: &Path) -> Result<([f64; 3], [f64; 3], Orientation), IoError> {
        let d = self.direction;
        let linear: [[f64; 3]; 3] =
            std::array::from_fn(|r| std::array::from_fn(|c| d[r][c] * self.spacing[c]));
        let (spacing, orientation) = Orientation::from_linear(linear).ok_or_else(|| {
            IoError::format(
                path,
                Position::Field("Direction".into()),
                "singular or zero spacing",
            )
        })?;
        // The first point is the extent's start, not index 0.
        let start: [f64; 3] = std::array::from_fn(|a| self.extent[2 * a] as f64);
        let origin: [f64; 3] = std::array::from_fn(|r| {
            self.origin[r] + (0..3).map(|c| linear[r][c] * start[c]).sum::<f64>()
        });
        Ok((spacing, origin, orientation))
    }

    fn parse(path: &Path, head: &[u8]) -> Result<Document, IoError> {
        let mut doc = Document {
            endian: Endian::Little,
            header: 4,
            compressed: false,
            extent: [0; 6],
            origin: [0.0; 3],
            spacing: [1.0; 3],
            direction: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            array: None,
        };
        let mut reader = quick_xml::Reader::from_reader(head);
        let mut buf = Vec::new();
        let (mut seen_file, mut seen_image, mut in_point_data) = (false, false, false);
        let mut active: Option<String> = None;
        let mut current: Option<Array> = None;
        let mut candidates: Vec<Array> = Vec::new();
        loop {
            let pos = Position::Byte(reader.buffer_position());
            let event = reader
                .read_event_into(&mut buf)
                .map_err(|e| IoError::format(path, pos.clone(), format!("XML: {e}")))?;
            let empty = matches!(event, Event::Empty(_));
            match event {
                Event::Start(ref e) | Event::Empty(ref e) => {
                    let attrs = attributes(path, e, &pos)?;
                    let get = |k: &str| attrs.iter().find(|(n, _)| n == k).map(|(_, v)| v.as_str());
                    let numbers = |k: &str, n: usize| -> Result<Option<Vec<f64>>, IoError> {
                        let Some(v) = get(k) else { return Ok(None) };
                        let xs: Vec<f64> = v
                            .split_whitespace()
                            .map(str::parse)
                            .collect::<Result<_, _>>()
                            .map_err(|_| {
                                IoError::format(
                                    path,
                                    Position::Field(k.into()),
                                    format!("'{v}' is not {n} numbers"),
                                )
                            })?;
                        if xs.len() != n || xs.iter().any(|x: &f64| !x.is_finite()) {
                            return Err(IoError::format(
                                path,
                                Position::Field(k.into()),
                                format!("'{v}' is not {n} finite numbers"),
                            ));
                        }
                        Ok(Some(xs))
                    };
                    match e.local_name().as_ref() {
                        b"VTKFile" => {
                            seen_file = true;
                            if get("type") != Some("ImageData") {
                                return Err(IoError::unsupported(
                                    path,
                                    Position::Field("type".into()),
                                    format!(
                                        "VTK file type {:?} (isocube reads ImageData)",
                                        get("type").unwrap_or("")
                                    ),
                                ));
                            }
                            doc.endian = match get("byte_order") {
                                Some("BigEndian") => Endian::Big,
                                _ => Endian::Little,
                            };
                            doc.header = match get("header_type") {
                                None | Some("UInt32") => 4,
                                Some("UInt64") => 8,
                                Some(other) => {
                                    return Err(IoError::unsupported(
                                        path,
                                        Position::Field("header_type".into()),
                                        other.to_string(),
                                    ))
                                }
                            };
                            doc.compressed = match get("compressor") {
                                None | Some("") => false,
                                Some("vtkZLibDataCompressor") => true,
                                Some(other) => {
                                    return Err(IoError::unsupported(
                                        path,
                                        Position::Field("compressor".into()),
                                        format!("{other} (isocube reads zlib)"),
                                    ))
                                }
                            };
                        }
                        b"ImageData" => {
                            seen_image = true;
                            let whole = numbers("WholeExtent", 6)?.ok_or_else(|| {
                                IoError::format(
                                    path,
                                    Position::Field("WholeExtent".into()),
                                    "missing",
                                )
                            })?;
                            for (slot, x) in doc.extent.iter_mut().zip(&whole) {
                                if x.fract() != 0.0 || x.abs() > 1e12 {
                                    return Err(IoError::format(
                                        path,
                                        Position::Field("WholeExtent".into()),
                                        "not integers",
                                    ));
                                }
                                *slot = *x as i64;
                            }
                            if (0..3).any(|a| doc.extent[2 * a + 1] < doc.extent[2 * a]) {
                                return Err(IoError::format(
                                    path,
                                    Position::Field("WholeExtent".into()),
                                    "an empty extent",
                                ));
                            }
                            if let Some(o) = numbers("Origin", 3)? {
                                doc.origin = [o[0], o[1], o[2]];
                            }
                            if let Some(s) = numbers("Spacing", 3)? {
                                doc.spacing = [s[0], s[1], s[2]];
                            }
                            if let Some(d) = numbers("Direction", 9)? {
                                doc.direction =
                                    std::array::from_fn(|r| std::array::from_fn(|c| d[3 * r + c]));
                            }
                        }
                        b"Piece" => {
                            if let Some(p) = numbers("Extent", 6)? {
                                if p.iter().zip(&doc.extent).any(|(a, &b)| *a != b as f64) {
                                    return Err(IoError::unsupported(
                                        path,
                                        Position::Field("Piece".into()),
                                        "a piece smaller than the whole extent (several pieces)",
                                    ));
                                }
                            }
                        }
                        b"PointData" => {
                            in_point_data = !empty;
                            active = get("Scalars").map(str::to_string);
                        }
                        b"DataArray" if in_point_data => {
                            let scalar = match get("type").unwrap_or("") {
                                "Int8" | "Char" => ScalarType::I8,
                                "UInt8" | "UnsignedChar" => ScalarType::U8,
                                "Int16" | "Short" => ScalarType::I16,
                                "UInt16" | "UnsignedShort" => ScalarType::U16,
                                "Int32" | "Int" => ScalarType::I32,
                                "UInt32" | "UnsignedInt" => ScalarType::U32,
                                "Int64" | "Long" => ScalarType::I64,
                                "UInt64" | "UnsignedLong" => ScalarType::U64,
                                "Float32" | "Float" => ScalarType::F32,
                                "Float64" | "Double" => ScalarType::F64,
                                other => {
                                    return Err(IoError::unsupported(
                                        path,
                                        Position::Field("DataArray type".into()),
                                        format!("type '{other}'"),
                                    ))
                                }
                            };
                            let array = Array {
                                name: get("Name").unwrap_or("").to_string(),
                                scalar,
                                format: get("format").unwrap_or("ascii").to_string(),
                                offset: get("offset")
                                    .and_then(|o| o.trim().parse().ok())
                                    .unwrap_or(0),
                                components: get("NumberOfComponents")
                                    .and_then(|o| o.parse().ok())
                                    .unwrap_or(1),
                                text: String::new(),
                            };
                            if empty {
                                candidates.push(array);
                            } else {
                                current = Some(array);
                            }
                        }
                        _ => {}
                    }
                }
                Event::Text(t) => {
                    if let Some(a) = current.as_mut() {
                        a.text.push_str(
                            &t.decode()
                                .map_err(|e| IoError::format(path, pos, format!("text: {e}")))?,
                        );
                    }
                }
                Event::End(e) => match e.local_name().as_ref() {
                    b"DataArray" => candidates.extend(current.take()),
                    b"PointData" => in_point_data = false,
                    _ => {}
                },
                Event::Eof => break,
                _ => {}
            }
            buf.clear();
        }
        if !seen_file || !seen_image {
            return Err(IoError::format(
                path,
                Position::File,
                "not a VTK ImageData file (no VTKFile or ImageData element)",
            ));
        }
        let pick = match &active {
            Some(name) => candidates.iter().position(|a| &a.name == name),
            None => None,
        }
        .unwrap_or(0);
        doc.array = (pick < candidates.len()).then(|| candidates.swap_remove(pick));
        Ok(doc)
    }

    fn int(&self, b: &[u8]) -> usize {
        let v = match (self.header, self.endian) {
            (4, Endian::Little) => {
                u64::from(u32::from_le_bytes(b[..4].try_into().expect("4 bytes")))
            }
            (4, Endian::Big) => u64::from(u32::from_be_bytes(b[..4].try_into().expect("4 bytes"))),
            (_, Endian::Little) => u64::from_le_bytes(b[..8].try_into().expect("8 bytes")),
            (_, Endian::Big) => u64::from_be_bytes(b[..8].try_into().expect("8 bytes")),
        };
        usize::try_from(v).unwrap_or(usize::MAX)
    }

    /// The header integers: one (the byte count) uncompressed; `[blocks, block size, last
    /// block size, compressed sizes…]` compressed. `bytes` must hold at least the first one.
    fn header_len(&self, first: usize) -> usize {
        if self.compressed {
            self.header * (3 + first.min(1 << 40))
        } else {
            self.header
        }
    }

    /// Raw (appended) data: header integers, then the bytes.
    fn decode_blocks(
        &self,
        path: &Path,
        data: &[u8],
        need: usize,
        at: &Position,
    ) -> Result<Vec<u8>, IoError> {
        let short = || IoError::format(path, at.clone(), "the data end early");
        let first = self.int(data.get(..self.header).ok_or_else(short)?);
        let header = data.get(..self.header_len(first)).ok_or_else(short)?;
        let body = &data[header.len()..];
        self.unpack(path, header, body, need, at)
    }

    /// Base64 data: the header encoded on its own, then the data.
    fn decode_base64(
        &self,
        path: &Path,
        text: &[u8],
        need: usize,
        at: &Position,
    ) -> Result<Vec<u8>, IoError> {
        let engine = base64::engine::general_purpose::STANDARD;
        let bad =
            |e: base64::DecodeError| IoError::format(path, at.clone(), format!("base64: {e}"));
        let chars = |bytes: usize| bytes.div_ceil(3) * 4;
        let short = || IoError::format(path, at.clone(), "the data end early");
        // The first integer tells the header's length; decode enough characters for it.
        let lead = text.get(..chars(self.header).max(8)).ok_or_else(short)?;
        let lead = engine
            .decode(lead)
            .or_else(|_| {
                // A lone header: its own padding ends the first group.
                engine.decode(text.get(..chars(self.header)).unwrap_or(&[]))
            })
            .map_err(bad)?;
        let first = self.int(lead.get(..self.header).ok_or_else(short)?);
        let header_chars = chars(self.header_len(first));
        let header = engine
            .decode(text.get(..header_chars).ok_or_else(short)?)
            .map_err(bad)?;
        let header = &header[..self.header_len(first).min(header.len())];
        let body = engine
            .decode(text.get(header_chars..).ok_or_else(short)?)
            .map_err(bad)?;
        self.unpack(path, header, &body, need, at)
    }

    fn unpack(
        &self,
        path: &Path,
        header: &[u8],
        body: &[u8],
        need: usize,
        at: &Position,
    ) -> Result<Vec<u8>, IoError> {
        let fail = |what: String| IoError::format(path, at.clone(), what);
        if !self.compressed {
            let n = self.int(header);
            if n != need || body.len() < n {
                return Err(fail(format!(
                    "{n} bytes declared, {} present, {need} needed",
                    body.len()
                )));
            }
            return Ok(body[..n].to_vec());
        }
        let h: Vec<usize> = header
            .chunks_exact(self.header)
            .map(|c| self.int(c))
            .collect();
        let (blocks, size, last) = (h[0], h[1], h[2]);
        let total = if blocks == 0 {
            0
        } else {
            size.saturating_mul(blocks - 1)
                .saturating_add(if last == 0 { size } else { last })
        };
        if total != need {
            return Err(fail(format!("{total} bytes declared, {need} needed")));
        }
        let mut out = Vec::with_capacity(need);
        let mut from = 0usize;
        for (b, &csize) in h[3..].iter().enumerate() {
            let chunk = body
                .get(from..from.saturating_add(csize))
                .ok_or_else(|| fail(format!("block {b} ends early")))?;
            from += csize;
            let expect = if b + 1 == blocks && last != 0 {
                last
            } else {
                size
            };
            let before = out.len();
            flate2::read::ZlibDecoder::new(chunk)
                .take(expect as u64 + 1)
                .read_to_end(&mut out)
                .map_err(|e| fail(format!("block {b}: zlib: {e}")))?;
            if out.len() - before != expect {
                return Err(fail(format!(
                    "block {b} gives {} bytes, {expect} declared",
                    out.len() - before
                )));
            }
        }
        Ok(out)
    }
}

fn attributes(
    path: &Path,
    e: &BytesStart,
    pos: &Position,
) -> Result<Vec<(String, String)>, IoError> {
    e.attributes()
        .map(|a| {
            let a = a.map_err(|err| {
                IoError::format(path, pos.clone(), format!("XML attribute: {err}"))
            })?;
            let key = String::from_utf8_lossy(a.key.local_name().as_ref()).into_owned();
            let value = a
                .unescape_value()
                .map_err(|err| IoError::format(path, pos.clone(), format!("XML attribute: {err}")))?
                .into_owned();
            Ok((key, value))
        })
        .collect()
}
