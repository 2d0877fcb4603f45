//! DICOM series: a folder of single-frame slices of one series (CT, MR), through the dicom-rs
//! crates. Slices are sorted by their position along the normal of their orientation; the slice
//! spacing comes from the positions (and must be even), the in-plane spacing from
//! `PixelSpacing`, the axes from `ImageOrientationPatient`, the origin from the first slice's
//! `ImagePositionPatient` (patient coordinates, LPS). Stored values go through `RescaleSlope`
//! and `RescaleIntercept`. Pixel data must be uncompressed (the little-endian transfer syntaxes);
//! compressed series are refused by name.

use std::path::{Path, PathBuf};

use dicom_dictionary_std::tags;
use dicom_object::{open_file, DefaultDicomObject};

use super::{Budget, IoError, Position};
use crate::field::{Grid, Orientation};
use crate::mesh::{cross, dot, sub};

/// Uncompressed little-endian transfer syntaxes: implicit VR, explicit VR, deflated explicit VR.
const UNCOMPRESSED: [&str; 3] = [
    "1.2.840.10008.1.2",
    "1.2.840.10008.1.2.1",
    "1.2.840.10008.1.2.1.99",
];

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

/// Walks a slice's data elements before dicom-rs reads it. dicom-rs allocates every value at its
/// declared length before reading it, so a few bytes declaring a gigabyte would be allocated:
/// here each defined length must fit in the bytes that follow it. Refuses an unsupported
/// transfer syntax at once. `limit` caps what a deflated data set may unpack to.
fn check_lengths(path: &Path, bytes: &[u8], limit: u64) -> Result<(), IoError> {
    if bytes.len() < 132 || &bytes[128..132] != b"DICM" {
        return Err(IoError::format(path, Position::Byte(128), "no DICM marker"));
    }
    // The file meta group (0002) is always explicit VR little endian, and opens with its length
    // (UL), which dicom-rs uses to find where the data set starts: it must be exact.
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
        "1.2.840.10008.1.2" => walk(path, &bytes[at..], at, false),
        "1.2.840.10008.1.2.1" => walk(path, &bytes[at..], at, true),
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
            walk(path, &data, 0, true)
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
        // dicom-rs reads an unknown VR with a 4-byte length: refuse it here instead.
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
        // dicom-rs 0.8 reads these three (64-bit values, added in 2019) with a 2-byte length
        // where the standard has 4 bytes: it would lose its place.
        if matches!(vr, b"OV" | b"SV" | b"UV") {
            return Err(IoError::unsupported(
                path,
                Position::Byte((base + at) as u64),
                format!(
                    "element ({:04X},{:04X}) of {}: 64-bit value representations are not read",
                    tag.0,
                    tag.1,
                    String::from_utf8_lossy(vr)
                ),
            ));
        }
        // dicom-rs reads Pixel Data its own way whatever the VR says: only OB and OW are valid.
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
    // dicom-rs reads whole numbers of a fixed-size value, then skips the declared length without
    // reading the rest: a remainder would shift every later element.
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
        value,
        len,
        sequence,
    })
}

/// Checks every element of a data set (see [`check_lengths`]).
fn walk(path: &Path, data: &[u8], base: usize, explicit: bool) -> Result<(), IoError> {
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
            _ => e.value + e.len,
        };
    }
    Ok(())
}

fn read_slice(path: &Path, limit: u64) -> Result<Slice, IoError> {
    let bytes = super::read_file(path)?;
    check_lengths(path, &bytes, limit)?;
    drop(bytes);
    let obj: DefaultDicomObject = open_file(path).map_err(|e| {
        IoError::format(
            path,
            Position::File,
            format!("not a readable DICOM file: {e}"),
        )
    })?;
    let ts = obj
        .meta()
        .transfer_syntax()
        .trim_end_matches('\0')
        .to_string();
    if !UNCOMPRESSED.contains(&ts.as_str()) {
        return Err(IoError::unsupported(
            path,
            Position::Field("TransferSyntaxUID".into()),
            format!("transfer syntax {ts} (compressed or big-endian pixel data): isocube reads uncompressed little-endian series"),
        ));
    }
    let field = |name: &str| Position::Field(name.into());
    let floats = |tag, name: &str, n: usize| -> Result<Vec<f64>, IoError> {
        let v = obj
            .element(tag)
            .map_err(|_| IoError::format(path, field(name), "missing"))?
            .to_multi_float64()
            .map_err(|e| IoError::format(path, field(name), e.to_string()))?;
        if v.len() != n || v.iter().any(|x| !x.is_finite()) {
            return Err(IoError::format(
                path,
                field(name),
                format!("{v:?} is not {n} finite numbers"),
            ));
        }
        Ok(v)
    };
    let int = |tag, name: &str| -> Result<usize, IoError> {
        obj.element(tag)
            .map_err(|_| IoError::format(path, field(name), "missing"))?
            .to_int::<u32>()
            .map(|x| x as usize)
            .map_err(|e| IoError::format(path, field(name), e.to_string()))
    };
    let optional = |tag| -> Option<f64> {
        obj.element_opt(tag)
            .ok()
            .flatten()
            .and_then(|e| e.to_float64().ok())
            .filter(|x| x.is_finite())
    };
    let position = floats(tags::IMAGE_POSITION_PATIENT, "ImagePositionPatient", 3)?;
    let orientation = floats(
        tags::IMAGE_ORIENTATION_PATIENT,
        "ImageOrientationPatient",
        6,
    )?;
    let pixel = floats(tags::PIXEL_SPACING, "PixelSpacing", 2)?;
    let (rows, columns) = (int(tags::ROWS, "Rows")?, int(tags::COLUMNS, "Columns")?);
    let bits = int(tags::BITS_ALLOCATED, "BitsAllocated")?;
    if !matches!(bits, 8 | 16 | 32) {
        return Err(IoError::unsupported(
            path,
            field("BitsAllocated"),
            format!("{bits} bits"),
        ));
    }
    if obj
        .element_opt(tags::SAMPLES_PER_PIXEL)
        .ok()
        .flatten()
        .and_then(|e| e.to_int::<u32>().ok())
        .unwrap_or(1)
        != 1
    {
        return Err(IoError::unsupported(
            path,
            field("SamplesPerPixel"),
            "colour images",
        ));
    }
    if obj
        .element_opt(tags::NUMBER_OF_FRAMES)
        .ok()
        .flatten()
        .and_then(|e| e.to_int::<u32>().ok())
        .unwrap_or(1)
        > 1
    {
        return Err(IoError::unsupported(
            path,
            field("NumberOfFrames"),
            "multi-frame files",
        ));
    }
    let signed = int(tags::PIXEL_REPRESENTATION, "PixelRepresentation").unwrap_or(0) == 1;
    let data = obj
        .element(tags::PIXEL_DATA)
        .map_err(|_| IoError::format(path, field("PixelData"), "missing"))?
        .to_bytes()
        .map_err(|e| IoError::format(path, field("PixelData"), e.to_string()))?
        .into_owned();
    let need = rows * columns * bits / 8;
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
    let series = obj
        .element_opt(tags::SERIES_INSTANCE_UID)
        .ok()
        .flatten()
        .and_then(|e| {
            e.to_str()
                .ok()
                .map(|s| s.trim_end_matches('\0').trim().to_string())
        })
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
        slope: optional(tags::RESCALE_SLOPE).unwrap_or(1.0),
        intercept: optional(tags::RESCALE_INTERCEPT).unwrap_or(0.0),
        data,
    })
}
