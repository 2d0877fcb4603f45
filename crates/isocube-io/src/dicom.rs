//! DICOM series: a folder of single-frame slices of one series (CT, MR). Each slice's data
//! elements are walked by isocube itself (explicit and implicit VR little endian, deflated
//! explicit VR), using dicom-rs's standard dictionary for implicit VRs; every length is checked
//! against what the file holds before anything is taken from it, so a hostile file cannot make
//! the reader allocate what it declares. Slices are sorted by their position along the normal of their orientation; the slice
//! spacing comes from the positions (and must be even), the in-plane spacing from
//! `PixelSpacing`, the axes from `ImageOrientationPatient`, the origin from the first slice's
//! `ImagePositionPatient` (patient coordinates, LPS). Stored values go through `RescaleSlope`
//! and `RescaleIntercept`. Pixel data must be uncompressed (the little-endian transfer syntaxes);
//! compressed series are refused by name.

use std::path::{Path, PathBuf};

use super::{Budget, IoError, Position};
use isocube::field::{Grid, Orientation};
use isocube::mesh::{cross, dot, sub};

struct Slice {
    path: PathBuf,
    series: String,
    position: [f64; 3],
    row: [f64; 3],
    column: [f64; 3],
    pixel: [f64; 2],
    size: (usize, usize),
    signed: bool,
    bits: usize,
    slope: f64,
    intercept: f64,
    data: Vec<u8>,
}

/// Reads every DICOM file of a folder (files that are not DICOM are skipped) as one volume.
pub fn read_dicom_series(dir: &Path) -> Result<(Grid, Orientation), IoError> {
    read_dicom_within(dir, Budget::UNLIMITED)
}

pub(super) fn read_dicom_within(
    dir: &Path,
    budget: Budget,
) -> Result<(Grid, Orientation), IoError> {
    let entries = std::fs::read_dir(dir).map_err(|e| IoError::os(dir, e))?;
    let mut files: Vec<PathBuf> = Vec::new();
    for entry in entries {
        let path = entry.map_err(|e| IoError::os(dir, e))?.path();
        if path.is_file() {
            files.push(path);
        }
    }
    files.sort();
    let mut slices = Vec::new();
    let mut held = 0u64;
    for path in files {
        // A DICOM file has "DICM" after its 128-byte preamble; anything else is not a slice.
        let mut magic = [0u8; 132];
        let is_dicom = std::fs::File::open(&path)
            .and_then(|mut f| std::io::Read::read_exact(&mut f, &mut magic))
            .is_ok()
            && &magic[128..] == b"DICM";
        if is_dicom {
            // A slice is held whole while it is parsed, then its pixel data stays.
            let len = std::fs::metadata(&path)
                .map_err(|e| IoError::os(&path, e))?
                .len();
            budget.check(&path, Position::File, held.saturating_add(2 * len))?;
            let slice = read_slice(&path, budget.limit().saturating_sub(held))?;
            held += slice.data.len() as u64;
            slices.push(slice);
        }
    }
    let first = slices.first().ok_or_else(|| {
        IoError::format(
            dir,
            Position::File,
            "no DICOM files (with the DICM marker) in the folder",
        )
    })?;
    let at = |s: &Slice, field: &str| (s.path.clone(), Position::Field(field.into()));
    for s in &slices {
        let differs = |a: &[f64], b: &[f64]| a.iter().zip(b).any(|(x, y)| (x - y).abs() > 1e-4);
        let problem = if s.series != first.series {
            Some((
                "SeriesInstanceUID",
                format!(
                    "series {} beside {}: give a folder with one series",
                    s.series, first.series
                ),
            ))
        } else if s.size != first.size {
            Some((
                "Rows",
                format!("{:?} pixels, the first slice has {:?}", s.size, first.size),
            ))
        } else if differs(&s.row, &first.row) || differs(&s.column, &first.column) {
            Some((
                "ImageOrientationPatient",
                "differs from the first slice's".to_string(),
            ))
        } else if differs(&s.pixel, &first.pixel) {
            Some(("PixelSpacing", "differs from the first slice's".to_string()))
        } else {
            None
        };
        if let Some((field, reason)) = problem {
            let (path, pos) = at(s, field);
            return Err(IoError::format(&path, pos, reason));
        }
    }
    let normal = cross(first.row, first.column);
    let along = |s: &Slice| dot(s.position, normal);
    slices.sort_by(|a, b| along(a).total_cmp(&along(b)));
    // Every slice has the first one's size, axes and pixel spacing (checked above).
    let first = &slices[0];
    let (nx, ny, nz) = (first.size.1, first.size.0, slices.len());
    let step = if nz > 1 {
        along(&slices[1]) - along(&slices[0])
    } else {
        1.0
    };
    for w in slices.windows(2) {
        let gap = along(&w[1]) - along(&w[0]);
        if gap <= 1e-6 || (gap - step).abs() > 1e-3 * step.abs().max(1e-3) {
            let (path, pos) = at(&w[1], "ImagePositionPatient");
            return Err(IoError::format(
                &path,
                pos,
                format!("slices {gap:.4} apart where the first two are {step:.4}: uneven or repeated slices"),
            ));
        }
    }
    let count = Grid::point_count([nx, ny, nz]).map_err(|e| IoError::grid(dir, e))?;
    budget.check_values(dir, Position::Field("Rows".into()), held, count)?;
    let mut values = Vec::with_capacity(count);
    for s in &slices {
        let width = s.bits / 8;
        for px in s.data.chunks_exact(width).take(nx * ny) {
            let raw = match (width, s.signed) {
                (1, false) => f64::from(px[0]),
                (1, true) => f64::from(px[0] as i8),
                (2, false) => f64::from(u16::from_le_bytes([px[0], px[1]])),
                (2, true) => f64::from(i16::from_le_bytes([px[0], px[1]])),
                (4, false) => f64::from(u32::from_le_bytes([px[0], px[1], px[2], px[3]])),
                _ => f64::from(i32::from_le_bytes([px[0], px[1], px[2], px[3]])),
            };
            values.push((s.slope * raw + s.intercept) as f32);
        }
    }
    // Grid x runs along a row (the row direction cosine), y down the columns, z along the sorted
    // slices; the columns of the map are those directions times the spacings.
    let slice_dir = {
        let d = sub(
            slices.last().map_or(first.position, |s| s.position),
            slices[0].position,
        );
        let len = dot(d, d).sqrt();
        if nz > 1 && len > 0.0 {
            d.map(|c| c / len)
        } else {
            normal
        }
    };
    let spacing_z = if nz > 1 { step } else { 1.0 };
    let axes = [first.row, first.column, slice_dir];
    let scale = [first.pixel[1], first.pixel[0], spacing_z];
    let linear: [[f64; 3]; 3] =
        std::array::from_fn(|r| std::array::from_fn(|c| axes[c][r] * scale[c]));
    let (spacing, orientation) = Orientation::from_linear(linear).ok_or_else(|| {
        let (path, pos) = at(first, "ImageOrientationPatient");
        IoError::format(&path, pos, "the slice axes are degenerate")
    })?;
    let grid = Grid::new([nx, ny, nz], values)
        .and_then(|g| g.with_spacing(spacing))
        .and_then(|g| g.with_origin(first.position))
        .map_err(|e| IoError::grid(dir, e))?;
    Ok((grid, orientation))
}

/// Walks a slice's data elements, checking every length against what follows it, and returns
/// the data set with its top-level elements. Refuses an unsupported transfer syntax at once.
/// `limit` caps what a deflated data set may unpack to.
fn parse(path: &Path, bytes: &[u8], limit: u64) -> Result<(Vec<u8>, Vec<Element>), IoError> {
    if bytes.len() < 132 || &bytes[128..132] != b"DICM" {
        return Err(IoError::format(path, Position::Byte(128), "no DICM marker"));
    }
    // The file meta group (0002) is always explicit VR little endian, and opens with its length
    // (UL), which says where the data set starts: it must be exact.
    let group_length = Position::Field("FileMetaInformationGroupLength".into());
    let declared = match (bytes.get(132..140), bytes.get(140..144)) {
        (Some(b"\x02\x00\x00\x00UL\x04\x00"), Some(&[a, b, c, d])) => {
            u32::from_le_bytes([a, b, c, d]) as usize
        }
        _ => {
            return Err(IoError::format(
                path,
                group_length,
                "missing or not a 4-byte UL",
            ))
        }
    };
    let mut at = 144;
    let mut syntax = None;
    while bytes.get(at..at + 2) == Some(&[2, 0]) {
        let e = element(path, bytes, at, true, 0)?;
        if e.len == u32::MAX as usize || e.sequence {
            return Err(IoError::format(
                path,
                Position::Byte(at as u64),
                "a file meta element without a defined length",
            ));
        }
        if e.tag == (2, 0x10) {
            let value = &bytes[e.value..e.value + e.len];
            syntax = Some(
                String::from_utf8_lossy(value)
                    .trim_end_matches(['\0', ' '])
                    .to_string(),
            );
        }
        at = e.value + e.len;
    }
    if at - 144 != declared {
        return Err(IoError::format(
            path,
            group_length,
            format!("{declared} bytes, the group has {}", at - 144),
        ));
    }
    let syntax = syntax.ok_or_else(|| {
        IoError::format(path, Position::Field("TransferSyntaxUID".into()), "missing")
    })?;
    match syntax.as_str() {
        "1.2.840.10008.1.2" => Ok((bytes[at..].to_vec(), walk(path, &bytes[at..], at, false)?)),
        "1.2.840.10008.1.2.1" => Ok((bytes[at..].to_vec(), walk(path, &bytes[at..], at, true)?)),
        "1.2.840.10008.1.2.1.99" => {
            use std::io::Read;
            let mut data = Vec::new();
            flate2::read::DeflateDecoder::new(&bytes[at..])
                .take(limit.saturating_add(1))
                .read_to_end(&mut data)
                .map_err(|e| IoError::format(path, Position::Byte(at as u64), format!("deflated data set: {e}")))?;
            if data.len() as u64 > limit {
                return Err(IoError::TooLarge {
                    path: path.to_path_buf(),
                    position: Position::Byte(at as u64),
                    needed: data.len() as u64,
                    limit,
                });
            }
            // Offsets in errors are in the unpacked data set.
            let elements = walk(path, &data, 0, true)?;
            Ok((data, elements))
        }
        other => Err(IoError::unsupported(
            path,
            Position::Field("TransferSyntaxUID".into()),
            format!("transfer syntax {other} (compressed or big-endian pixel data): isocube reads uncompressed little-endian series"),
        )),
    }
}

/// The value representations of the standard (PS3.5 6.2), two letters each.
const VRS: &[u8] = b"AEASATCSDADSDTFDFLISLOLTOBODOFOLOVOWPNSHSLSQSSSTSVTMUCUIULUNURUSUTUV";

/// The VRs written with a 4-byte length (after two reserved bytes) in explicit VR.
const LONG: &[u8] = b"OBODOFOLOVOWSQSVUCUNURUTUV";

/// A data element's header: its tag, where its value starts, its length (`u32::MAX` as usize
/// when undefined) and whether it holds a sequence.
struct Element {
    tag: (u16, u16),
    /// The VR, written or the dictionary's; `None` for items and delimiters.
    vr: Option<[u8; 2]>,
    value: usize,
    len: usize,
    sequence: bool,
}

/// Reads the element header at `at` of `data` (which starts at byte `base` of the file); a
/// defined length must fit in what follows.
fn element(
    path: &Path,
    data: &[u8],
    at: usize,
    explicit: bool,
    base: usize,
) -> Result<Element, IoError> {
    use dicom_core::dictionary::{DataDictionary, DataDictionaryEntry, VirtualVr};
    let ends = || {
        IoError::format(
            path,
            Position::Byte((base + at) as u64),
            "the file ends inside a data element's header",
        )
    };
    let u16_at = |i: usize| -> Result<u16, IoError> {
        data.get(i..i + 2)
            .map(|b| u16::from_le_bytes([b[0], b[1]]))
            .ok_or_else(ends)
    };
    let u32_at = |i: usize| -> Result<u32, IoError> {
        data.get(i..i + 4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .ok_or_else(ends)
    };
    let tag = (u16_at(at)?, u16_at(at + 2)?);
    // The VR: written (explicit) or the dictionary's (implicit; unknown tags are UN).
    let vr: Option<[u8; 2]> = if tag.0 == 0xFFFE {
        None
    } else if explicit {
        let vr = data.get(at + 4..at + 6).ok_or_else(ends)?;
        // With an unknown VR the size of the length field is unknown too.
        if !VRS.chunks(2).any(|v| v == vr) {
            return Err(IoError::format(
                path,
                Position::Byte((base + at) as u64),
                format!(
                    "element ({:04X},{:04X}) has an unknown value representation {:?}",
                    tag.0,
                    tag.1,
                    String::from_utf8_lossy(vr)
                ),
            ));
        }
        // The standard allows only OB and OW for Pixel Data.
        if tag == (0x7FE0, 0x0010) && vr != b"OB" && vr != b"OW" {
            return Err(IoError::format(
                path,
                Position::Byte((base + at) as u64),
                format!(
                    "Pixel Data (7FE0,0010) of {}: only OB and OW are valid",
                    String::from_utf8_lossy(vr)
                ),
            ));
        }
        Some([vr[0], vr[1]])
    } else {
        let dictionary = dicom_dictionary_std::StandardDataDictionary;
        let known = dictionary
            .by_tag(dicom_core::Tag(tag.0, tag.1))
            .map(|e| e.vr());
        Some(match known {
            Some(VirtualVr::Exact(vr)) => vr.to_bytes(),
            // As dicom-core relaxes the context-dependent VRs (2-byte values either way).
            Some(VirtualVr::Xs) => *b"US",
            Some(VirtualVr::Ox | VirtualVr::Px | VirtualVr::Lt) => *b"OW",
            _ => *b"UN",
        })
    };
    let (len, value) = match vr {
        // Items and delimiters: no VR; an item's contents are elements, walked in turn.
        None => (u32_at(at + 4)?, at + 8),
        Some(_) if !explicit => (u32_at(at + 4)?, at + 8),
        Some(vr) if LONG.chunks(2).any(|v| v == vr) => (u32_at(at + 8)?, at + 12),
        Some(_) => (u32::from(u16_at(at + 6)?), at + 8),
    };
    // A value of a fixed-size VR is a whole number of values.
    let size = match vr.as_ref().map(|v| &v[..]) {
        Some(b"SS" | b"US" | b"OW") => 2,
        Some(b"AT" | b"FL" | b"SL" | b"UL" | b"OF" | b"OL") => 4,
        Some(b"FD" | b"SV" | b"UV" | b"OD" | b"OV") => 8,
        _ => 1,
    };
    if len != u32::MAX && len % size != 0 {
        return Err(IoError::format(
            path,
            Position::Byte((base + at) as u64),
            format!(
                "element ({:04X},{:04X}) of {} has {len} bytes, not a whole number of {size}-byte values",
                tag.0,
                tag.1,
                String::from_utf8_lossy(&vr.unwrap_or_default())
            ),
        ));
    }
    let sequence = vr.is_none_or(|v| &v == b"SQ");
    let len = len as usize;
    if len != u32::MAX as usize && tag.0 != 0xFFFE && len > data.len().saturating_sub(value) {
        return Err(IoError::format(
            path,
            Position::Byte((base + at) as u64),
            format!(
                "element ({:04X},{:04X}) declares {len} bytes, only {} remain (the file is cut short or the length is wrong)",
                tag.0,
                tag.1,
                data.len().saturating_sub(value)
            ),
        ));
    }
    Ok(Element {
        tag,
        vr,
        value,
        len,
        sequence,
    })
}

/// Checks every element of a data set (see [`parse`]) and returns its top-level elements (those
/// outside any sequence), for their values.
fn walk(path: &Path, data: &[u8], base: usize, explicit: bool) -> Result<Vec<Element>, IoError> {
    let mut top = Vec::new();
    // The sequences (and undefined-length values) the walk is inside: where each ends, `None`
    // until its delimiter. Items and delimiters are valid only inside one.
    let mut open: Vec<Option<usize>> = Vec::new();
    let mut at = 0;
    while at < data.len() {
        while open
            .last()
            .is_some_and(|end| end.is_some_and(|end| at >= end))
        {
            open.pop();
        }
        let e = element(path, data, at, explicit, base)?;
        let bad = |reason: &str| {
            Err(IoError::format(
                path,
                Position::Byte((base + at) as u64),
                format!("({:04X},{:04X}): {reason}", e.tag.0, e.tag.1),
            ))
        };
        let undefined = e.len == u32::MAX as usize;
        let delimiter = matches!(e.tag, (0xFFFE, 0xE00D | 0xE0DD));
        if delimiter && e.len != 0 {
            return bad("a delimiter's length must be 0");
        }
        if e.tag == (0xFFFE, 0xE000) && !undefined && e.len > data.len() - e.value.min(data.len()) {
            return bad("the item runs past the end of the file");
        }
        at = match e.tag {
            (0xFFFE, 0xE000) if !open.is_empty() => e.value,
            (0xFFFE, 0xE00D) if !open.is_empty() => e.value,
            (0xFFFE, 0xE0DD) if open.last() == Some(&None) => {
                open.pop();
                e.value
            }
            (0xFFFE, 0xE000 | 0xE00D | 0xE0DD) => {
                return bad("an item or delimiter outside a sequence")
            }
            (0xFFFE, _) => return bad("not an item or delimiter tag"),
            _ if e.sequence || undefined => {
                // Sequences and undefined lengths (encapsulated data) hold items of their own.
                open.push((!undefined).then_some(e.value + e.len));
                e.value
            }
            _ => {
                let next = e.value + e.len;
                if open.is_empty() {
                    top.push(e);
                }
                next
            }
        };
    }
    Ok(top)
}

fn read_slice(path: &Path, limit: u64) -> Result<Slice, IoError> {
    let bytes = super::read_file(path)?;
    let (data, elements) = parse(path, &bytes, limit)?;
    drop(bytes);
    let field = |name: &str| Position::Field(name.into());
    let get = |tag: (u16, u16)| -> Option<(&[u8], [u8; 2])> {
        elements
            .iter()
            .find(|e| e.tag == tag)
            .map(|e| (&data[e.value..e.value + e.len], e.vr.unwrap_or(*b"UN")))
    };
    let text = |v: &[u8]| -> String {
        String::from_utf8_lossy(v)
            .trim_end_matches(['\0', ' '])
            .trim()
            .to_string()
    };
    // Decimal strings (DS, IS), `\`-separated.
    let numbers = |tag, name: &str| -> Result<Vec<f64>, IoError> {
        let (v, _) = get(tag).ok_or_else(|| IoError::format(path, field(name), "missing"))?;
        let t = text(v);
        t.split('\\')
            .map(|w| w.trim_matches(['\0', ' ']).parse::<f64>())
            .collect::<Result<Vec<_>, _>>()
            .map_err(|_| {
                IoError::format(path, field(name), format!("'{t}' is not a list of numbers"))
            })
    };
    let floats = |tag, name: &str, n: usize| -> Result<Vec<f64>, IoError> {
        let v = numbers(tag, name)?;
        if v.len() != n || v.iter().any(|x| !x.is_finite()) {
            return Err(IoError::format(
                path,
                field(name),
                format!("{v:?} is not {n} finite numbers"),
            ));
        }
        Ok(v)
    };
    // Binary integers (US, UL, SS, SL) or an integer string.
    let int = |tag, name: &str| -> Result<usize, IoError> {
        let (v, vr) = get(tag).ok_or_else(|| IoError::format(path, field(name), "missing"))?;
        let x = match (&vr, v.len()) {
            (b"US", 2..) => i64::from(u16::from_le_bytes([v[0], v[1]])),
            (b"SS", 2..) => i64::from(i16::from_le_bytes([v[0], v[1]])),
            (b"UL", 4..) => i64::from(u32::from_le_bytes([v[0], v[1], v[2], v[3]])),
            (b"SL", 4..) => i64::from(i32::from_le_bytes([v[0], v[1], v[2], v[3]])),
            _ => text(v).parse::<i64>().map_err(|_| {
                IoError::format(
                    path,
                    field(name),
                    format!("'{}' is not a whole number", text(v)),
                )
            })?,
        };
        usize::try_from(x)
            .map_err(|_| IoError::format(path, field(name), format!("{x} is negative")))
    };
    let optional = |tag| -> Option<f64> {
        get(tag)
            .and_then(|(v, _)| text(v).split('\\').next()?.trim().parse::<f64>().ok())
            .filter(|x| x.is_finite())
    };
    let position = floats((0x0020, 0x0032), "ImagePositionPatient", 3)?;
    let orientation = floats((0x0020, 0x0037), "ImageOrientationPatient", 6)?;
    let pixel = floats((0x0028, 0x0030), "PixelSpacing", 2)?;
    let (rows, columns) = (
        int((0x0028, 0x0010), "Rows")?,
        int((0x0028, 0x0011), "Columns")?,
    );
    let bits = int((0x0028, 0x0100), "BitsAllocated")?;
    if !matches!(bits, 8 | 16 | 32) {
        return Err(IoError::unsupported(
            path,
            field("BitsAllocated"),
            format!("{bits} bits"),
        ));
    }
    if get((0x0028, 0x0002)).is_some() && int((0x0028, 0x0002), "SamplesPerPixel")? != 1 {
        return Err(IoError::unsupported(
            path,
            field("SamplesPerPixel"),
            "colour images",
        ));
    }
    if get((0x0028, 0x0008)).is_some() && int((0x0028, 0x0008), "NumberOfFrames")? > 1 {
        return Err(IoError::unsupported(
            path,
            field("NumberOfFrames"),
            "multi-frame files",
        ));
    }
    let signed = int((0x0028, 0x0103), "PixelRepresentation").unwrap_or(0) == 1;
    let data = get((0x7FE0, 0x0010))
        .ok_or_else(|| IoError::format(path, field("PixelData"), "missing"))?
        .0
        .to_vec();
    let need = rows
        .checked_mul(columns)
        .and_then(|n| n.checked_mul(bits / 8))
        .ok_or_else(|| IoError::format(path, field("Rows"), "the image size overflows"))?;
    if data.len() < need {
        return Err(IoError::format(
            path,
            field("PixelData"),
            format!(
                "{} bytes for {rows}×{columns} pixels of {bits} bits ({need} needed)",
                data.len()
            ),
        ));
    }
    let series = get((0x0020, 0x000E))
        .map(|(v, _)| text(v))
        .unwrap_or_default();
    Ok(Slice {
        path: path.to_path_buf(),
        series,
        position: [position[0], position[1], position[2]],
        row: [orientation[0], orientation[1], orientation[2]],
        column: [orientation[3], orientation[4], orientation[5]],
        pixel: [pixel[0], pixel[1]],
        size: (rows, columns),
        signed,
        bits,
        slope: optional((0x0028, 0x1053)).unwrap_or(1.0),
        intercept: optional((0x0028, 0x1052)).unwrap_or(0.0),
        data,
    })
}
