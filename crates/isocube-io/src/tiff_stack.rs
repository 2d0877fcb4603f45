//! Multi-page TIFF stacks (microscopy, exported CT slices) through the `tiff` crate: page `k`
//! is plane `z = k`, rows `y`, columns `x`. The pixel size comes from the resolution tags
//! (pixels per unit), the slice spacing from an ImageJ description (`spacing=`); without them
//! the spacing is 1. Every page must have the first one's size. Of pixels with several samples
//! (RGB, multi-band) one is read, the channel picked; of an ImageJ hyperstack (`channels=`,
//! `slices=`, `frames=` in its description; pages channel fastest, then slice, then frame) the
//! pages of the picked channel and frame.

use std::io::{BufReader, Read, Seek};
use std::path::Path;

use tiff::decoder::{ifd::Value, Decoder, DecodingResult, Limits};
use tiff::tags::Tag;
use tiff::ColorType;

use super::{Budget, IoError, Pick, Position};
use isocube::field::Grid;

/// Reads a multi-page TIFF as a volume.
pub fn read_tiff_stack(path: &Path) -> Result<Grid, IoError> {
    read_tiff_within(path, Budget::UNLIMITED, Pick::default())
}

pub(super) fn read_tiff_within(path: &Path, budget: Budget, pick: Pick) -> Result<Grid, IoError> {
    let file = std::fs::File::open(path).map_err(|e| IoError::os(path, e))?;
    let len = file.metadata().map_err(|e| IoError::os(path, e))?.len();
    read_tiff_from(path, BufReader::new(file), len, budget, pick)
}

/// [`read_tiff_within`] from any seekable source of `len` bytes (`path` names it in errors).
pub(super) fn read_tiff_from<R: Read + Seek>(
    path: &Path,
    source: R,
    len: u64,
    budget: Budget,
    pick: Pick,
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
    let description = decoder
        .get_tag_ascii_string(Tag::ImageDescription)
        .unwrap_or_default();
    let imagej = |key: &str| {
        description.lines().find_map(|l| {
            l.strip_prefix(key)
                .and_then(|v| v.strip_prefix('='))
                .map(str::trim)
        })
    };
    let sz = imagej("spacing")
        .and_then(|v| v.parse::<f64>().ok())
        .filter(|s| s.is_finite() && *s > 0.0)
        .unwrap_or(1.0);
    // An ImageJ hyperstack's pages: channel fastest, then slice, then frame.
    let count = |key: &str| {
        imagej(key)
            .and_then(|v| v.parse::<usize>().ok())
            .filter(|&n| n >= 1)
            .unwrap_or(1)
    };
    let (hyper_channels, hyper_frames) = if description.starts_with("ImageJ=") {
        (count("channels"), count("frames"))
    } else {
        (1, 1)
    };
    let samples = {
        let colour = decoder.colortype().map_err(|e| page_error(0, e))?;
        match colour {
            ColorType::Gray(_) => 1,
            ColorType::GrayA(_) => 2,
            ColorType::RGB(_) | ColorType::YCbCr(_) | ColorType::Lab(_) => 3,
            ColorType::RGBA(_) | ColorType::CMYK(_) => 4,
            ColorType::CMYKA(_) => 5,
            ColorType::Multiband { num_samples, .. } => usize::from(num_samples),
            other => {
                return Err(IoError::unsupported(
                    path,
                    Position::Field("page 0".into()),
                    format!("{other:?} pixels"),
                ))
            }
        }
    };
    let planar = matches!(
        decoder.find_tag(Tag::PlanarConfiguration).ok().flatten(),
        Some(Value::Short(2) | Value::Unsigned(2))
    );
    if samples > 1 && planar {
        return Err(IoError::unsupported(
            path,
            Position::Field("PlanarConfiguration".into()),
            "samples stored plane by plane (planar configuration 2): isocube reads interleaved samples",
        ));
    }
    let position = || Position::Field("ImageDescription".into());
    let (sample, channel) = if samples > 1 {
        let c = Pick::index(
            path,
            Position::Field("SamplesPerPixel".into()),
            pick.channel,
            samples,
            "--channel",
            "samples per pixel",
        )?;
        (c, 0)
    } else {
        let c = Pick::index(
            path,
            position(),
            pick.channel,
            hyper_channels,
            "--channel",
            "channels (an ImageJ hyperstack)",
        )?;
        (0, c)
    };
    let frame = Pick::index(
        path,
        position(),
        pick.frame,
        hyper_frames,
        "--frame",
        "frames (an ImageJ hyperstack)",
    )?;
    let wanted = |page: usize| {
        let c = page % hyper_channels;
        let t = page / hyper_channels / count("slices").max(1);
        c == channel && (hyper_frames == 1 || t == frame)
    };
    let mut values: Vec<f32> = Vec::new();
    let mut page = 0;
    let mut kept = 0;
    loop {
        let (w, h) = decoder.dimensions().map_err(|e| page_error(page, e))?;
        if (w as usize, h as usize) != (nx, ny) {
            return Err(IoError::format(
                path,
                Position::Field(format!("page {page}")),
                format!("{w}×{h} pixels, the first page has {nx}×{ny}"),
            ));
        }
        let here = decoder.colortype().map_err(|e| page_error(page, e))?;
        if here.num_samples() as usize != samples {
            return Err(IoError::format(
                path,
                Position::Field(format!("page {page}")),
                format!("{here:?} pixels, the first page's have {samples} samples"),
            ));
        }
        if wanted(page) {
            // The values so far and this page's, plus its decoded samples (at most 8 bytes
            // each).
            budget.check_values(
                path,
                Position::Field(format!("page {page}")),
                (nx * ny * samples) as u64 * 8,
                values.len().saturating_add(nx * ny),
            )?;
            let image = decoder.read_image().map_err(|e| page_error(page, e))?;
            let before = values.len();
            // The picked sample of every pixel.
            macro_rules! take {
                ($v:expr, $f:expr) => {
                    values.extend($v.iter().skip(sample).step_by(samples).map($f))
                };
            }
            match image {
                DecodingResult::U8(v) => take!(v, |&x| f32::from(x)),
                DecodingResult::U16(v) => take!(v, |&x| f32::from(x)),
                DecodingResult::U32(v) => take!(v, |&x| x as f32),
                DecodingResult::U64(v) => take!(v, |&x| x as f32),
                DecodingResult::I8(v) => take!(v, |&x| f32::from(x)),
                DecodingResult::I16(v) => take!(v, |&x| f32::from(x)),
                DecodingResult::I32(v) => take!(v, |&x| x as f32),
                DecodingResult::I64(v) => take!(v, |&x| x as f32),
                DecodingResult::F16(v) => take!(v, |&x| x.to_f32()),
                DecodingResult::F32(v) => take!(v, |&x| x),
                DecodingResult::F64(v) => take!(v, |&x| x as f32),
            }
            if values.len() - before != nx * ny {
                return Err(IoError::format(
                    path,
                    Position::Field(format!("page {page}")),
                    format!("{} samples for {nx}×{ny} pixels", values.len() - before),
                ));
            }
            kept += 1;
        }
        page += 1;
        if !decoder.more_images() {
            break;
        }
        decoder.next_image().map_err(|e| page_error(page, e))?;
    }
    Grid::new([nx, ny, kept], values)
        .and_then(|g| g.with_spacing([sx, sy, sz]))
        .map_err(|e| IoError::grid(path, e))
}
