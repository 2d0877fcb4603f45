//! Multi-page TIFF stacks (microscopy, exported CT slices) through the `tiff` crate: page `k`
//! is plane `z = k`, rows `y`, columns `x`. The pixel size comes from the resolution tags
//! (pixels per unit), the slice spacing from an ImageJ description (`spacing=`); without them
//! the spacing is 1. Every page must have the first one's size and a single grey channel.

use std::io::{BufReader, Read, Seek};
use std::path::Path;

use tiff::decoder::{ifd::Value, Decoder, DecodingResult, Limits};
use tiff::tags::Tag;
use tiff::ColorType;

use super::{Budget, IoError, Position};
use isocube::field::Grid;

/// Reads a multi-page TIFF as a volume.
pub fn read_tiff_stack(path: &Path) -> Result<Grid, IoError> {
    read_tiff_within(path, Budget::UNLIMITED)
}

pub(super) fn read_tiff_within(path: &Path, budget: Budget) -> Result<Grid, IoError> {
    let file = std::fs::File::open(path).map_err(|e| IoError::os(path, e))?;
    let len = file.metadata().map_err(|e| IoError::os(path, e))?.len();
    read_tiff_from(path, BufReader::new(file), len, budget)
}

/// [`read_tiff_within`] from any seekable source of `len` bytes (`path` names it in errors).
pub(super) fn read_tiff_from<R: Read + Seek>(
    path: &Path,
    source: R,
    len: u64,
    budget: Budget,
) -> Result<Grid, IoError> {
    let page_error = |page: usize, e: tiff::TiffError| {
        IoError::format(path, Position::Field(format!("page {page}")), e.to_string())
    };
    // Decoded pages cannot be larger than the file could describe uncompressed many times
    // over; the crate's default limits are too small for big slices.
    let limits = {
        let mut l = Limits::default();
        l.decoding_buffer_size = (len as usize).saturating_mul(64).max(1 << 26);
        l.decoding_buffer_size = l
            .decoding_buffer_size
            .min(usize::try_from(budget.limit()).unwrap_or(usize::MAX));
        l.intermediate_buffer_size = l.decoding_buffer_size;
        l
    };
    let mut decoder = Decoder::new(source)
        .map_err(|e| IoError::format(path, Position::File, format!("not a readable TIFF: {e}")))?
        .with_limits(limits);
    let (width, height) = decoder.dimensions().map_err(|e| page_error(0, e))?;
    let (nx, ny) = (width as usize, height as usize);
    let pixel = |d: &mut Decoder<R>, tag| -> Option<f64> {
        match d.find_tag(tag).ok()?? {
            Value::Rational(n, d) if n > 0 && d > 0 => Some(f64::from(d) / f64::from(n)),
            Value::Float(x) if x > 0.0 => Some(1.0 / f64::from(x)),
            Value::Double(x) if x > 0.0 => Some(1.0 / x),
            _ => None,
        }
    };
    let sx = pixel(&mut decoder, Tag::XResolution).unwrap_or(1.0);
    let sy = pixel(&mut decoder, Tag::YResolution).unwrap_or(sx);
    let sz = decoder
        .get_tag_ascii_string(Tag::ImageDescription)
        .ok()
        .and_then(|d| {
            d.lines().find_map(|l| {
                l.strip_prefix("spacing=")
                    .and_then(|v| v.trim().parse::<f64>().ok())
            })
        })
        .filter(|s| s.is_finite() && *s > 0.0)
        .unwrap_or(1.0);
    let mut values: Vec<f32> = Vec::new();
    let mut page = 0;
    loop {
        let (w, h) = decoder.dimensions().map_err(|e| page_error(page, e))?;
        if (w as usize, h as usize) != (nx, ny) {
            return Err(IoError::format(
                path,
                Position::Field(format!("page {page}")),
                format!("{w}×{h} pixels, the first page has {nx}×{ny}"),
            ));
        }
        match decoder.colortype().map_err(|e| page_error(page, e))? {
            ColorType::Gray(_) => {}
            other => {
                return Err(IoError::unsupported(
                    path,
                    Position::Field(format!("page {page}")),
                    format!("{other:?} pixels: isocube reads one grey channel"),
                ))
            }
        }
        // The values so far and this page's, plus its decoded samples (at most 8 bytes each).
        budget.check_values(
            path,
            Position::Field(format!("page {page}")),
            (nx * ny) as u64 * 8,
            values.len().saturating_add(nx * ny),
        )?;
        let image = decoder.read_image().map_err(|e| page_error(page, e))?;
        let before = values.len();
        match image {
            DecodingResult::U8(v) => values.extend(v.iter().map(|&x| f32::from(x))),
            DecodingResult::U16(v) => values.extend(v.iter().map(|&x| f32::from(x))),
            DecodingResult::U32(v) => values.extend(v.iter().map(|&x| x as f32)),
            DecodingResult::U64(v) => values.extend(v.iter().map(|&x| x as f32)),
            DecodingResult::I8(v) => values.extend(v.iter().map(|&x| f32::from(x))),
            DecodingResult::I16(v) => values.extend(v.iter().map(|&x| f32::from(x))),
            DecodingResult::I32(v) => values.extend(v.iter().map(|&x| x as f32)),
            DecodingResult::I64(v) => values.extend(v.iter().map(|&x| x as f32)),
            DecodingResult::F16(v) => values.extend(v.iter().map(|&x| x.to_f32())),
            DecodingResult::F32(v) => values.extend(v),
            DecodingResult::F64(v) => values.extend(v.iter().map(|&x| x as f32)),
        }
        if values.len() - before != nx * ny {
            return Err(IoError::format(
                path,
                Position::Field(format!("page {page}")),
                format!("{} samples for {nx}×{ny} pixels", values.len() - before),
            ));
        }
        page += 1;
        if !decoder.more_images() {
            break;
        }
        decoder.next_image().map_err(|e| page_error(page, e))?;
    }
    Grid::new([nx, ny, page], values)
        .and_then(|g| g.with_spacing([sx, sy, sz]))
        .map_err(|e| IoError::grid(path, e))
}
