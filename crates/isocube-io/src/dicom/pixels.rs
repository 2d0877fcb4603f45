//! Pixel data to stored values, frame by frame: native pixel data in either byte order (1, 8,
//! 16 or 32 bits allocated), and encapsulated frames decoded by well-kept crates — JPEG
//! (baseline, lossless) by `jpeg-decoder` (12-bit extended lossy JPEG in [`dct`]), JPEG-LS by `pure_jpegls`, JPEG 2000 by `jpeg2k` on
//! `openjp2` (OpenJPEG ported to Rust) — or, for RLE Lossless, here: the one crate adapter
//! (dicom-rs's) stops at 16 bits and RT doses are 32-bit. Values are masked to Bits Stored
//! and sign-extended when Pixel Representation says signed, as every DICOM viewer shows them.

use std::ops::Range;
use std::path::Path;

use super::dct;
use super::elements::{Compression, DataSet, Node};
use crate::{IoError, Position};

/// What the image pixel module says about the pixel data.
#[derive(Clone, Debug)]
pub(super) struct PixelFormat {
    pub rows: usize,
    pub cols: usize,
    pub bits_allocated: usize,
    pub bits_stored: usize,
    pub signed: bool,
    pub frames: usize,
}

impl PixelFormat {
    pub(super) fn pixels(&self) -> usize {
        self.rows * self.cols
    }

    /// A stored value as the image means it: its low `bits_stored` bits, signed or not.
    fn value(&self, raw: u32) -> f64 {
        let bits = self.bits_stored.min(32);
        let masked = if bits >= 32 {
            raw
        } else {
            raw & ((1u32 << bits) - 1)
        };
        if self.signed && bits > 0 && masked >> (bits - 1) & 1 == 1 {
            f64::from(masked) - 2f64.powi(bits as i32)
        } else {
            f64::from(masked)
        }
    }
}

/// The stored values of frame `k` (row by row), `fmt.pixels()` of them.
pub(super) fn frame(
    path: &Path,
    set: &DataSet,
    pixel: &Node,
    fmt: &PixelFormat,
    k: usize,
) -> Result<Vec<f64>, IoError> {
    let field = || Position::Field("PixelData".into());
    match (&pixel.fragments, set.compression) {
        (None, Compression::None) => native(path, set, pixel, fmt, k),
        (Some(fragments), c) if c != Compression::None => {
            let bytes = frame_bytes(path, &set.data, fragments, fmt.frames, k)?;
            let decoded = match c {
                Compression::Rle => rle(&bytes, fmt),
                Compression::Jpeg => jpeg(&bytes, fmt),
                Compression::JpegLs => jpeg_ls(&bytes, fmt),
                _ => jpeg2000(&bytes, fmt),
            };
            decoded.map_err(|reason| {
                IoError::format(
                    path,
                    field(),
                    format!("frame {} of {}: {reason}", k + 1, set.syntax),
                )
            })
        }
        (None, _) => Err(IoError::format(
            path,
            field(),
            format!("native pixel data in a file of transfer syntax {} (compressed data is encapsulated)", set.syntax),
        )),
        (Some(_), _) => Err(IoError::format(
            path,
            field(),
            format!("encapsulated pixel data in a file of transfer syntax {} (uncompressed data is native)", set.syntax),
        )),
    }
}

fn native(
    path: &Path,
    set: &DataSet,
    pixel: &Node,
    fmt: &PixelFormat,
    k: usize,
) -> Result<Vec<f64>, IoError> {
    let data = &set.data[pixel.value.clone()];
    let n = fmt.pixels();
    let bits = fmt.bits_allocated;
    // Frames of 1-bit data (segmentations) are packed without padding between them.
    let first_bit = k * n * bits;
    let last_bit = first_bit + n * bits;
    if last_bit.div_ceil(8) > data.len() {
        return Err(IoError::format(
            path,
            Position::Field("PixelData".into()),
            format!(
                "{} bytes for {} frames of {}×{} pixels of {bits} bits ({} needed)",
                data.len(),
                fmt.frames,
                fmt.rows,
                fmt.cols,
                (fmt.frames * n * bits).div_ceil(8)
            ),
        ));
    }
    let enc = set.encoding;
    Ok(match bits {
        1 => (first_bit..last_bit)
            .map(|b| fmt.value(u32::from(data[b / 8] >> (b % 8) & 1)))
            .collect(),
        8 => data[first_bit / 8..last_bit / 8]
            .iter()
            .map(|&v| fmt.value(u32::from(v)))
            .collect(),
        16 => data[first_bit / 8..last_bit / 8]
            .chunks_exact(2)
            .map(|b| fmt.value(u32::from(enc.u16(b))))
            .collect(),
        _ => data[first_bit / 8..last_bit / 8]
            .chunks_exact(4)
            .map(|b| fmt.value(enc.u32(b)))
            .collect(),
    })
}

/// The bytes of frame `k` of encapsulated pixel data: one fragment per frame, all fragments
/// for a single frame, or the fragments the basic offset table assigns to it.
fn frame_bytes(
    path: &Path,
    data: &[u8],
    fragments: &[Range<usize>],
    frames: usize,
    k: usize,
) -> Result<Vec<u8>, IoError> {
    let error = |reason: String| IoError::format(path, Position::Field("PixelData".into()), reason);
    let (table, pieces) = fragments
        .split_first()
        .ok_or_else(|| error("encapsulated pixel data without its basic offset table".into()))?;
    if pieces.len() == frames {
        return Ok(data[pieces[k].clone()].to_vec());
    }
    if frames == 1 {
        return Ok(pieces
            .iter()
            .flat_map(|r| &data[r.clone()])
            .copied()
            .collect());
    }
    // The offsets count from the first fragment's item header (8 bytes each).
    let offsets: Vec<usize> = data[table.clone()]
        .chunks_exact(4)
        .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize)
        .collect();
    if offsets.len() != frames {
        return Err(error(format!(
            "{} fragments for {frames} frames and a basic offset table of {} entries: which fragments make a frame is unknown",
            pieces.len(),
            offsets.len()
        )));
    }
    let (start, end) = (
        offsets[k],
        offsets.get(k + 1).copied().unwrap_or(usize::MAX),
    );
    let mut at = 0usize;
    let mut bytes = Vec::new();
    for r in pieces {
        if at >= start && at < end {
            bytes.extend_from_slice(&data[r.clone()]);
        }
        at += 8 + r.len();
    }
    if bytes.is_empty() {
        return Err(error(format!(
            "the basic offset table's entry {} ({start}) starts no fragment",
            k + 1
        )));
    }
    Ok(bytes)
}

/// RLE Lossless (PS3.5 annex G): a 64-byte header of segment offsets, one PackBits segment per
/// byte of a sample, most significant first.
fn rle(bytes: &[u8], fmt: &PixelFormat) -> Result<Vec<f64>, String> {
    let width = fmt.bits_allocated / 8;
    if !(1..=4).contains(&width) || fmt.bits_allocated % 8 != 0 {
        return Err(format!("{} bits allocated", fmt.bits_allocated));
    }
    let header = bytes
        .get(..64)
        .ok_or("shorter than the 64-byte RLE header")?;
    let word = |i: usize| {
        u32::from_le_bytes([
            header[4 * i],
            header[4 * i + 1],
            header[4 * i + 2],
            header[4 * i + 3],
        ]) as usize
    };
    let segments = word(0);
    if segments != width {
        return Err(format!("{segments} RLE segments for {width}-byte samples"));
    }
    let n = fmt.pixels();
    let mut raw = vec![0u32; n];
    for s in 0..segments {
        let start = word(1 + s);
        let end = if s + 1 < segments {
            word(2 + s)
        } else {
            bytes.len()
        };
        let segment = (start >= 64 && start <= end)
            .then(|| bytes.get(start..end))
            .flatten()
            .ok_or_else(|| {
                format!(
                    "RLE segment {} at {start}..{end} of {} bytes",
                    s + 1,
                    bytes.len()
                )
            })?;
        let shift = 8 * (width - 1 - s);
        let mut out = 0usize;
        let mut i = 0usize;
        let mut put = |v: u8, out: &mut usize| {
            if *out < n {
                raw[*out] |= u32::from(v) << shift;
            }
            *out += 1;
        };
        while out < n {
            let Some(&h) = segment.get(i) else {
                return Err(format!(
                    "RLE segment {} ends after {out} of {n} bytes",
                    s + 1
                ));
            };
            i += 1;
            let h = h as i8;
            if h >= 0 {
                let run = segment
                    .get(i..i + h as usize + 1)
                    .ok_or_else(|| format!("RLE segment {} ends inside a literal run", s + 1))?;
                for &v in run {
                    put(v, &mut out);
                }
                i += run.len();
            } else if h != -128 {
                let &v = segment
                    .get(i)
                    .ok_or_else(|| format!("RLE segment {} ends inside a repeat", s + 1))?;
                i += 1;
                for _ in 0..(1 - i32::from(h)) {
                    put(v, &mut out);
                }
            }
        }
    }
    Ok(raw.into_iter().map(|v| fmt.value(v)).collect())
}

/// Checks a decoder's image size against the data set's.
fn check_size(fmt: &PixelFormat, width: usize, height: usize) -> Result<(), String> {
    if (width, height) != (fmt.cols, fmt.rows) {
        return Err(format!(
            "the codestream holds {width}×{height} pixels where Columns × Rows say {}×{}",
            fmt.cols, fmt.rows
        ));
    }
    Ok(())
}

/// A JPEG marker and its segment's bytes (after the length).
pub(super) type Segment<'a> = (u8, &'a [u8]);

/// The marker segments of a JPEG or JPEG-LS stream's header, in order, up to and including
/// its first scan header (SOS); and where the scan's entropy-coded data begins.
pub(super) fn header_segments(bytes: &[u8]) -> Result<(Vec<Segment<'_>>, usize), String> {
    if bytes.get(..2) != Some(&[0xFF, 0xD8]) {
        return Err("the stream does not open with a JPEG start of image".into());
    }
    let mut segments = Vec::new();
    let mut at = 2;
    loop {
        // Markers may be preceded by fill bytes (0xFF).
        while bytes.get(at) == Some(&0xFF) && bytes.get(at + 1) == Some(&0xFF) {
            at += 1;
        }
        let (Some(&0xFF), Some(&marker)) = (bytes.get(at), bytes.get(at + 1)) else {
            return Err(format!("no scan header before byte {at}"));
        };
        if marker == 0xD9 {
            return Err("the stream ends before its scan".into());
        }
        let len = bytes
            .get(at + 2..at + 4)
            .map(|b| usize::from(u16::from_be_bytes([b[0], b[1]])))
            .filter(|&len| len >= 2)
            .ok_or("the stream ends inside a marker segment")?;
        let segment = bytes
            .get(at + 4..at + 2 + len)
            .ok_or("the stream ends inside a marker segment")?;
        segments.push((marker, segment));
        if marker == 0xDA {
            return Ok((segments, at + 2 + len));
        }
        at += 2 + len;
    }
}

/// The image size a JPEG or JPEG-LS stream's frame header declares (width, height), read
/// before any decoder sees the stream: decoders reserve what the header says, so a frame
/// header that disagrees with Rows and Columns is refused first.
fn jpeg_frame_size(bytes: &[u8]) -> Result<(usize, usize), String> {
    let frame = |m: u8| matches!(m, 0xC0..=0xC3 | 0xC5..=0xC7 | 0xC9..=0xCB | 0xCD..=0xCF | 0xF7);
    let (_, header) = header_segments(bytes)?
        .0
        .into_iter()
        .find(|(m, _)| frame(*m))
        .ok_or("no frame header before the scan")?;
    let header = header
        .get(..5)
        .ok_or("the stream ends inside its frame header")?;
    let height = usize::from(u16::from_be_bytes([header[1], header[2]]));
    let width = usize::from(u16::from_be_bytes([header[3], header[4]]));
    Ok((width, height))
}

/// The image size a JPEG 2000 codestream's SIZ segment declares, read before decoding (see
/// [`jpeg_frame_size`]).
fn j2k_size(bytes: &[u8]) -> Result<(usize, usize), String> {
    let siz = match bytes.get(..4) {
        Some([0xFF, 0x4F, 0xFF, 0x51]) => bytes.get(4..24),
        _ => return Err("not a JPEG 2000 codestream (SOC, SIZ)".into()),
    }
    .ok_or("the codestream ends inside its SIZ segment")?;
    let word = |i: usize| {
        u64::from(u32::from_be_bytes([
            siz[i],
            siz[i + 1],
            siz[i + 2],
            siz[i + 3],
        ]))
    };
    let (x, y, x0, y0) = (word(4), word(8), word(12), word(16));
    let size = |a: u64, b: u64| usize::try_from(a.saturating_sub(b)).unwrap_or(usize::MAX);
    Ok((size(x, x0), size(y, y0)))
}

fn jpeg(bytes: &[u8], fmt: &PixelFormat) -> Result<Vec<f64>, String> {
    let (width, height) = jpeg_frame_size(bytes).map_err(|e| format!("JPEG: {e}"))?;
    check_size(fmt, width, height)?;
    if dct::is_extended_12bit(bytes) {
        let frame = dct::decode(bytes).map_err(|e| format!("JPEG (12-bit extended): {e}"))?;
        check_size(fmt, frame.width, frame.height)?;
        return Ok(frame
            .samples
            .into_iter()
            .map(|v| fmt.value(u32::from(v)))
            .collect());
    }
    let mut decoder = jpeg_decoder::Decoder::new(bytes);
    let pixels = decoder.decode().map_err(|e| match e {
        // jpeg-decoder reads lossy JPEG of 8 bits, and 12-bit extended frames are decoded
        // above; this is progressive or arithmetic-coded 12-bit JPEG.
        jpeg_decoder::Error::Unsupported(jpeg_decoder::UnsupportedFeature::SamplePrecision(p)) => {
            format!(
                "lossy JPEG of {p}-bit samples other than extended sequential Huffman (SOF1) \
                 is not read; decompress it first (gdcmconv --raw, dcmdjpeg)"
            )
        }
        e => format!("JPEG: {e}"),
    })?;
    let info = decoder.info().ok_or("JPEG: no frame header")?;
    check_size(fmt, usize::from(info.width), usize::from(info.height))?;
    Ok(match info.pixel_format {
        jpeg_decoder::PixelFormat::L8 => pixels.iter().map(|&v| fmt.value(u32::from(v))).collect(),
        // jpeg-decoder gives 16-bit samples in native byte order.
        jpeg_decoder::PixelFormat::L16 => pixels
            .chunks_exact(2)
            .map(|b| fmt.value(u32::from(u16::from_ne_bytes([b[0], b[1]]))))
            .collect(),
        other => {
            return Err(format!(
                "JPEG of {other:?}: isocube reads one sample per pixel"
            ))
        }
    })
}

/// Checks a JPEG-LS stream's header segments against the bounds ITU-T T.87 sets, before the
/// decoder sees them: `pure_jpegls` trusts them, and its context arithmetic overflows on
/// streams that break them. One component, no mapping tables, no point transform (what DICOM
/// writes); preset parameters (LSE 1) within C.2.4.1.1's ranges; NEAR within A.2.1's.
fn jpeg_ls_header(bytes: &[u8]) -> Result<(), String> {
    let mut precision = None;
    let mut maxval = None;
    for (marker, segment) in header_segments(bytes)?.0 {
        let word = |i: usize| {
            segment
                .get(i..i + 2)
                .map(|b| u32::from(u16::from_be_bytes([b[0], b[1]])))
        };
        match marker {
            0xF7 => {
                let (Some(&p), Some(&nf)) = (segment.first(), segment.get(5)) else {
                    return Err("a short frame header".into());
                };
                if !(2..=16).contains(&p) || nf != 1 || segment.get(7) != Some(&0x11) {
                    return Err(format!(
                        "a frame of {nf} components, {p}-bit, sampling {:?}: isocube reads one 2- to 16-bit component",
                        segment.get(7)
                    ));
                }
                precision = Some(u32::from(p));
            }
            0xF8 => {
                let id = *segment.first().ok_or("a short preset parameters segment")?;
                if id != 1 {
                    return Err(format!(
                        "preset parameters of kind {id} (mapping tables) are not read"
                    ));
                }
                let p = precision.ok_or("preset parameters before the frame header")?;
                let (max, t1, t2, t3, reset) = match (word(1), word(3), word(5), word(7), word(9)) {
                    (Some(a), Some(b), Some(c), Some(d), Some(e)) => (a, b, c, d, e),
                    _ => return Err("a short preset parameters segment".into()),
                };
                let full = (1u32 << p) - 1;
                let max = if max == 0 { full } else { max };
                // Zero thresholds and reset mean the defaults.
                let ordered = [t1, t2, t3].iter().all(|&t| t <= max)
                    && (t1 == 0 || t2 == 0 || t1 <= t2)
                    && (t2 == 0 || t3 == 0 || t2 <= t3);
                if max > full || !ordered || !(reset == 0 || (3..=max.max(255)).contains(&reset)) {
                    return Err(format!("preset parameters MAXVAL {max}, T1 {t1}, T2 {t2}, T3 {t3}, RESET {reset} outside T.87's ranges for {p}-bit samples"));
                }
                maxval = Some(max);
            }
            0xDA => {
                let p = precision.ok_or("a scan before the frame header")?;
                let ns = *segment.first().ok_or("a short scan header")?;
                let near = segment.get(3).copied().map(u32::from);
                let (ilv, pt) = (segment.get(4).copied(), segment.get(5).copied());
                let max = maxval.unwrap_or((1u32 << p) - 1);
                return match (ns, segment.get(2), near, ilv, pt) {
                    (1, Some(0), Some(near), Some(0), Some(0)) if near <= 255.min(max / 2) => Ok(()),
                    _ => Err(format!(
                        "a scan of {ns} components, mapping table {:?}, NEAR {near:?}, interleave {ilv:?}, point transform {pt:?}: isocube reads one component, no table, no point transform",
                        segment.get(2)
                    )),
                };
            }
            _ => {}
        }
    }
    Err("no scan header".into())
}

fn jpeg_ls(bytes: &[u8], fmt: &PixelFormat) -> Result<Vec<f64>, String> {
    let (width, height) = jpeg_frame_size(bytes).map_err(|e| format!("JPEG-LS: {e}"))?;
    check_size(fmt, width, height)?;
    jpeg_ls_header(bytes).map_err(|e| format!("JPEG-LS: {e}"))?;
    let (samples, width, height) = jpegls::decode(bytes, fmt.cols as u32, fmt.rows as u32)
        .map_err(|e| format!("JPEG-LS: {e}"))?;
    check_size(fmt, width as usize, height as usize)?;
    if samples.len() != fmt.pixels() {
        return Err(format!(
            "JPEG-LS: {} samples for {} pixels",
            samples.len(),
            fmt.pixels()
        ));
    }
    Ok(samples
        .into_iter()
        .map(|v| fmt.value(u32::from(v)))
        .collect())
}

fn jpeg2000(bytes: &[u8], fmt: &PixelFormat) -> Result<Vec<f64>, String> {
    let (width, height) = j2k_size(bytes).map_err(|e| format!("JPEG 2000: {e}"))?;
    check_size(fmt, width, height)?;
    let image = jpeg2k::Image::from_bytes(bytes).map_err(|e| format!("JPEG 2000: {e}"))?;
    let [component] = image.components() else {
        return Err(format!(
            "JPEG 2000 of {} components: isocube reads one sample per pixel",
            image.components().len()
        ));
    };
    check_size(fmt, component.width() as usize, component.height() as usize)?;
    let data = component.data();
    if data.len() != fmt.pixels() {
        return Err(format!(
            "JPEG 2000: {} samples for {} pixels",
            data.len(),
            fmt.pixels()
        ));
    }
    // A codestream that says signed holds the values themselves; otherwise the bits are read
    // as the data set says (Pixel Representation wins, as in pydicom and GDCM).
    Ok(if component.is_signed() {
        data.iter().map(|&v| f64::from(v)).collect()
    } else {
        data.iter().map(|&v| fmt.value(v as u32)).collect()
    })
}
