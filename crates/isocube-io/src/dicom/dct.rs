//! Lossy JPEG of 12-bit samples (ISO/IEC 10918-1 process 4: extended sequential DCT, Huffman
//! coded), one component — what DICOM's JPEG Extended transfer syntax (1.2.840.10008.1.2.4.51)
//! holds for 12-bit CT and MR. The maintained Rust decoders (jpeg-decoder, zune-jpeg) read lossy
//! JPEG of 8 bits only, so this one is written here.
//!
//! Lossy JPEG leaves the inverse DCT's rounding to the decoder (10918-2 only bounds the error),
//! and decoders differ by one in a few pixels of a hundred. Which one a mesh should follow is
//! the one the user compares with: pydicom decodes this syntax with pylibjpeg-libjpeg, Thomas
//! Richter's libjpeg (the reference software of ISO/IEC 18477). [`idct`] reproduces its
//! fixed-point inverse DCT and its rounding integer for integer, so an isosurface of a decoded
//! image is the isosurface of the array pydicom shows.

use super::pixels::header_segments;

/// Sample precision of the frames decoded here.
const PRECISION: u32 = 12;
/// Fraction bits of the fixed-point constants (Richter's `FIX_BITS`).
const FIX: u32 = 9;
/// Fraction bits the output carries into the colour stage (Richter's `COLOR_BITS`): the
/// quantisers are scaled up by them, and the final rounding takes them off.
const COLOR: u32 = 4;

/// A decoded frame: `width × height` samples, row by row, each in 0 ..= 4095.
pub(super) struct Frame {
    pub width: usize,
    pub height: usize,
    pub samples: Vec<u16>,
}

/// Whether a JPEG stream's frame header is one this module decodes (and jpeg-decoder does
/// not): extended sequential Huffman DCT (SOF1) of 12-bit samples.
pub(super) fn is_extended_12bit(bytes: &[u8]) -> bool {
    header_segments(bytes).is_ok_and(|(segments, _)| {
        segments
            .iter()
            .any(|(m, s)| *m == 0xC1 && s.first() == Some(&(PRECISION as u8)))
    })
}

/// Bits of a code looked up at once; longer codes continue bit by bit.
const FAST: u32 = 9;

/// A Huffman table: a lookup of the first [`FAST`] bits, and for longer codes the form of
/// ISO/IEC 10918-1 F.2.2.3 (per code length, the largest code and where its values start).
#[derive(Clone)]
struct Huffman {
    /// Indexed by the next `FAST` bits: code length (0: longer than `FAST`) and value.
    fast: Vec<(u8, u8)>,
    /// Largest code of each length 1..=16 (index = length), −1 where a length has none.
    max_code: [i32; 17],
    /// `values` index of the first code of each length, minus that code.
    offset: [i32; 17],
    values: Vec<u8>,
}

impl Huffman {
    fn new(counts: &[u8], values: &[u8]) -> Result<Self, String> {
        let mut max_code = [-1; 17];
        let mut offset = [0; 17];
        let mut fast = vec![(0u8, 0u8); 1 << FAST];
        let mut code = 0i32;
        let mut k = 0i32;
        for len in 1..=16 {
            let n = i32::from(counts[len - 1]);
            offset[len] = k - code;
            // Codes of `len` bits run out at 2^len: more would not be prefix-free.
            if code + n > 1 << len {
                return Err(format!("a Huffman table with too many codes of {len} bits"));
            }
            for c in code..code + n {
                if len as u32 <= FAST {
                    // Every FAST-bit pattern that begins with this code.
                    let spread = FAST - len as u32;
                    let first = (c as usize) << spread;
                    let value = values[(k + c - code) as usize];
                    fast[first..first + (1 << spread)].fill((len as u8, value));
                }
            }
            if n > 0 {
                code += n;
                k += n;
                max_code[len] = code - 1;
            }
            code <<= 1;
        }
        Ok(Huffman {
            fast,
            max_code,
            offset,
            values: values.to_vec(),
        })
    }

    fn decode(&self, bits: &mut Bits) -> Result<u8, String> {
        bits.fill();
        let (len, value) = self.fast[bits.peek(FAST) as usize];
        if len > 0 {
            bits.consume(u32::from(len))?;
            return Ok(value);
        }
        let mut code = bits.peek(FAST) as i32;
        bits.consume(FAST)?;
        for len in FAST as usize + 1..=16 {
            code = (code << 1) | bits.take(1)?;
            if code <= self.max_code[len] {
                let at =
                    usize::try_from(code + self.offset[len]).map_err(|_| "a bad Huffman code")?;
                return self
                    .values
                    .get(at)
                    .copied()
                    .ok_or_else(|| "a bad Huffman code".to_string());
            }
        }
        Err("a Huffman code longer than 16 bits".into())
    }
}

/// The entropy-coded data of a scan as a stream of bits, stuffed zero bytes removed. Past a
/// marker or the end, zero bits are supplied so lookups can run ahead, but using one is an
/// error: the scan ended before its last block.
struct Bits<'a> {
    data: &'a [u8],
    at: usize,
    /// The next bits, first bit highest; `count` of them, the last `padding` of which are not
    /// in the stream.
    acc: u64,
    count: u32,
    padding: u32,
}

impl Bits<'_> {
    fn new(data: &[u8]) -> Bits<'_> {
        Bits {
            data,
            at: 0,
            acc: 0,
            count: 0,
            padding: 0,
        }
    }

    /// Tops the buffer up to at least 57 bits.
    fn fill(&mut self) {
        while self.count <= 56 {
            let byte = match self.data.get(self.at) {
                Some(&0xFF) if self.data.get(self.at + 1) == Some(&0) => {
                    self.at += 2;
                    0xFF
                }
                // A marker (or the end): supply zeros, and stay before it.
                Some(&0xFF) | None => {
                    self.padding += 8;
                    0
                }
                Some(&b) => {
                    self.at += 1;
                    b
                }
            };
            self.acc |= u64::from(byte) << (56 - self.count);
            self.count += 8;
        }
    }

    /// The next `n` bits (n ≤ 16) without taking them; the buffer must be filled.
    fn peek(&self, n: u32) -> u64 {
        self.acc >> (64 - n)
    }

    fn consume(&mut self, n: u32) -> Result<(), String> {
        if self.count - n < self.padding {
            return Err("the scan ends before its last block".into());
        }
        self.acc <<= n;
        self.count -= n;
        Ok(())
    }

    /// `n` bits (n ≤ 16) as an unsigned number, first bit highest.
    fn take(&mut self, n: u32) -> Result<i32, String> {
        if n == 0 {
            return Ok(0);
        }
        self.fill();
        let v = self.peek(n) as i32;
        self.consume(n)?;
        Ok(v)
    }

    /// A coefficient of magnitude category `s` (10918-1 F.2.2.1, EXTEND).
    fn value(&mut self, s: u32) -> Result<i32, String> {
        if s == 0 {
            return Ok(0);
        }
        let v = self.take(s)?;
        Ok(if v < 1 << (s - 1) {
            v - (1 << s) + 1
        } else {
            v
        })
    }

    /// Skips to the restart marker RSTm that must come next: the rest of the current byte is
    /// padding (and whole bytes before the marker are dropped, as libjpeg does).
    fn restart(&mut self, m: u8) -> Result<(), String> {
        self.acc = 0;
        self.count = 0;
        self.padding = 0;
        while self.data.get(self.at) == Some(&0xFF) && self.data.get(self.at + 1) == Some(&0xFF) {
            self.at += 1;
        }
        if self.data.get(self.at..self.at + 2) != Some(&[0xFF, 0xD0 + m]) {
            return Err(format!("restart marker RST{m} missing at byte {}", self.at));
        }
        self.at += 2;
        Ok(())
    }
}

/// Position in the 8×8 block (row by row) of the k-th coefficient in zig-zag order.
const ZIGZAG: [usize; 64] = [
    0, 1, 8, 16, 9, 2, 3, 10, 17, 24, 32, 25, 18, 11, 4, 5, 12, 19, 26, 33, 40, 48, 41, 34, 27, 20,
    13, 6, 7, 14, 21, 28, 35, 42, 49, 56, 57, 50, 43, 36, 29, 22, 15, 23, 30, 37, 44, 51, 58, 59,
    52, 45, 38, 31, 39, 46, 53, 60, 61, 54, 47, 55, 62, 63,
];

/// Decodes a 12-bit extended sequential JPEG stream of one component. Every table and header
/// field is checked before use; the caller has checked the frame size against the data set.
pub(super) fn decode(bytes: &[u8]) -> Result<Frame, String> {
    let (segments, scan_start) = header_segments(bytes)?;
    let mut quant: [Option<[i64; 64]>; 4] = [None; 4];
    let mut dc: [Option<Huffman>; 4] = Default::default();
    let mut ac: [Option<Huffman>; 4] = Default::default();
    let mut restart = 0usize;
    let mut frame = None;
    let mut scan = None;
    for (marker, s) in segments {
        match marker {
            0xDB => {
                let mut rest = s;
                while let Some((&pq_tq, tail)) = rest.split_first() {
                    let (wide, id) = (pq_tq >> 4, usize::from(pq_tq & 15));
                    let size = if wide == 1 { 128 } else { 64 };
                    if wide > 1 || id > 3 || tail.len() < size {
                        return Err(format!("a bad quantisation table (Pq/Tq {pq_tq:#04x})"));
                    }
                    let mut table = [0i64; 64];
                    for (k, &at) in ZIGZAG.iter().enumerate() {
                        let q = if wide == 1 {
                            u16::from_be_bytes([tail[2 * k], tail[2 * k + 1]])
                        } else {
                            u16::from(tail[k])
                        };
                        // Scaled up by the colour stage's fraction bits, as Richter's
                        // `DefineQuant` does for its `preshift`.
                        table[at] = i64::from(q) << COLOR;
                    }
                    quant[id] = Some(table);
                    rest = &tail[size..];
                }
            }
            0xC4 => {
                let mut rest = s;
                while let Some((&tc_th, tail)) = rest.split_first() {
                    let (class, id) = (tc_th >> 4, usize::from(tc_th & 15));
                    let counts = tail.get(..16).ok_or("a short Huffman table")?;
                    let n = counts.iter().map(|&c| usize::from(c)).sum::<usize>();
                    let values = tail.get(16..16 + n).ok_or("a short Huffman table")?;
                    if class > 1 || id > 3 || n > 256 {
                        return Err(format!("a bad Huffman table (Tc/Th {tc_th:#04x})"));
                    }
                    let table = Huffman::new(counts, values)?;
                    if class == 0 {
                        dc[id] = Some(table);
                    } else {
                        ac[id] = Some(table);
                    }
                    rest = &tail[16 + n..];
                }
            }
            0xDD => {
                let b = s.get(..2).ok_or("a short restart interval segment")?;
                restart = usize::from(u16::from_be_bytes([b[0], b[1]]));
            }
            0xC1 => {
                let h = s.get(..9).ok_or("a short frame header")?;
                let (p, height, width, nf) = (
                    u32::from(h[0]),
                    usize::from(u16::from_be_bytes([h[1], h[2]])),
                    usize::from(u16::from_be_bytes([h[3], h[4]])),
                    h[5],
                );
                if p != PRECISION || nf != 1 {
                    return Err(format!(
                        "an extended JPEG frame of {nf} components of {p} bits: isocube reads one component of 12 bits this way"
                    ));
                }
                if height == 0 || width == 0 {
                    return Err("a frame without lines (a DNL marker is not read)".into());
                }
                // The caller checked the first frame header against Rows × Columns: a second
                // one would size the image unchecked.
                if frame.is_some() {
                    return Err("two frame headers".into());
                }
                frame = Some((width, height, h[6], usize::from(h[8])));
            }
            0xC0 | 0xC2 | 0xC3 | 0xC5..=0xC7 | 0xC9..=0xCB | 0xCD..=0xCF => {
                return Err(format!(
                    "frame header SOF{}: only extended sequential Huffman frames (SOF1) are read here",
                    marker - 0xC0
                ));
            }
            0xDA => scan = Some(s),
            _ => {}
        }
    }
    let (width, height, component, tq) = frame.ok_or("no frame header before the scan")?;
    let scan = scan.ok_or("no scan header")?;
    let (td, ta) = match scan {
        [1, c, tables, 0, 63, 0] if *c == component => {
            (usize::from(tables >> 4), usize::from(tables & 15))
        }
        _ => {
            return Err(format!(
                "a scan header {scan:02X?}: isocube reads one full sequential scan of the frame's component"
            ))
        }
    };
    let quant = quant
        .get(tq)
        .copied()
        .flatten()
        .ok_or_else(|| format!("quantisation table {tq} is not defined"))?;
    let dc = dc
        .get(td)
        .and_then(Option::as_ref)
        .ok_or_else(|| format!("DC Huffman table {td} is not defined"))?;
    let ac = ac
        .get(ta)
        .and_then(Option::as_ref)
        .ok_or_else(|| format!("AC Huffman table {ta} is not defined"))?;

    let (across, down) = (width.div_ceil(8), height.div_ceil(8));
    let mut samples = vec![0u16; width * height];
    let mut bits = Bits::new(&bytes[scan_start..]);
    let mut predictor = 0i32;
    let mut block = [0i32; 64];
    let mut pixels = [0u16; 64];
    for n in 0..across * down {
        if restart > 0 && n > 0 && n % restart == 0 {
            bits.restart(((n / restart - 1) % 8) as u8)?;
            predictor = 0;
        }
        block.fill(0);
        let s = u32::from(dc.decode(&mut bits)?);
        if s > 15 {
            return Err(format!("a DC difference of category {s} in a 12-bit frame"));
        }
        predictor += bits.value(s)?;
        // A 12-bit block's DC coefficient lies within ±2^14 before quantisation; beyond 2^15
        // the stream is corrupt (and the transform's arithmetic would lose its bounds).
        if predictor.abs() > 1 << 15 {
            return Err(format!("a DC coefficient of {predictor} in block {n}"));
        }
        block[0] = predictor;
        let mut k = 1;
        while k < 64 {
            let rs = ac.decode(&mut bits)?;
            let (run, size) = (usize::from(rs >> 4), u32::from(rs & 15));
            if size == 0 {
                if run == 15 {
                    k += 16;
                    continue;
                }
                break;
            }
            k += run;
            let at = *ZIGZAG
                .get(k)
                .ok_or_else(|| format!("AC coefficients run past the end of block {n}"))?;
            block[at] = bits.value(size)?;
            k += 1;
        }
        if k > 64 {
            return Err(format!("AC coefficients run past the end of block {n}"));
        }
        idct(&block, &quant, &mut pixels);
        let (bx, by) = (8 * (n % across), 8 * (n / across));
        for y in 0..8.min(height - by) {
            let row = (by + y) * width + bx;
            let w = 8.min(width - bx);
            samples[row..row + w].copy_from_slice(&pixels[8 * y..8 * y + w]);
        }
    }
    Ok(Frame {
        width,
        height,
        samples,
    })
}

/// Richter's fixed-point constants: round(c · 2^9).
const C0_541: i64 = 277;
const C0_765: i64 = 392;
const C1_847: i64 = 946;
const C1_175: i64 = 602;
const C0_298: i64 = 153;
const C2_053: i64 = 1051;
const C3_072: i64 = 1573;
const C1_501: i64 = 769;
const C0_899: i64 = 461;
const C2_562: i64 = 1312;
const C1_961: i64 = 1004;
const C0_390: i64 = 200;

/// One 8-point inverse DCT (the LLM factorisation of libjpeg's `jidctint`, in Richter's
/// arrangement): `input` holds the eight coefficients, the result is scaled by 2^9.
#[inline]
fn idct8(input: [i64; 8]) -> [i64; 8] {
    let [c0, c1, c2, c3, c4, c5, c6, c7] = input;
    // Most lines of smooth images hold their first coefficient only; every product below is
    // then zero, and every output this (exactly as the full sums give it).
    if input[1..] == [0; 7] {
        return [c0 << FIX; 8];
    }
    // Even part.
    let z1 = (c2 + c6) * C0_541;
    let tmp2 = z1 - c6 * C1_847;
    let tmp3 = z1 + c2 * C0_765;
    let tmp0 = (c0 + c4) << FIX;
    let tmp1 = (c0 - c4) << FIX;
    let (tmp10, tmp13) = (tmp0 + tmp3, tmp0 - tmp3);
    let (tmp11, tmp12) = (tmp1 + tmp2, tmp1 - tmp2);
    // Odd part.
    let (t0, t1, t2, t3) = (c7, c5, c3, c1);
    let z5 = (t0 + t2 + t1 + t3) * C1_175;
    let z1 = -(t0 + t3) * C0_899;
    let z2 = -(t1 + t2) * C2_562;
    let z3 = -(t0 + t2) * C1_961 + z5;
    let z4 = -(t1 + t3) * C0_390 + z5;
    let o0 = t0 * C0_298 + z1 + z3;
    let o1 = t1 * C2_053 + z2 + z4;
    let o2 = t2 * C3_072 + z2 + z3;
    let o3 = t3 * C1_501 + z1 + z4;
    [
        tmp10 + o3,
        tmp11 + o2,
        tmp12 + o1,
        tmp13 + o0,
        tmp13 - o0,
        tmp12 - o1,
        tmp11 - o2,
        tmp10 - o3,
    ]
}

/// Dequantises and inverse-transforms one block (natural order) into 12-bit samples: rows of
/// coefficients first, rounding off the constants' fraction, then columns, rounding off those
/// and the transform's factor 8, then the colour stage's fraction, level shift and clamp —
/// the order and rounding of Richter's `IDCT::InverseTransformBlock` and `YCbCrTrafo`.
fn idct(block: &[i32; 64], quant: &[i64; 64], out: &mut [u16; 64]) {
    // The level shift (2^(P−1)), added to the DC term scaled like a dequantised coefficient.
    let shift = 1i64 << (PRECISION - 1) << (COLOR + 3);
    let mut rows = [0i64; 64];
    for r in 0..8 {
        let c = |i: usize| i64::from(block[8 * r + i]) * quant[8 * r + i];
        let dc = if r == 0 { shift } else { 0 };
        let line = idct8([c(0) + dc, c(1), c(2), c(3), c(4), c(5), c(6), c(7)]);
        for (i, v) in line.into_iter().enumerate() {
            rows[8 * r + i] = (v + (1 << (FIX - 1))) >> FIX;
        }
    }
    let max = (1i64 << PRECISION) - 1;
    for col in 0..8 {
        let line = idct8(std::array::from_fn(|r| rows[8 * r + col]));
        for (r, v) in line.into_iter().enumerate() {
            let v = (v + (1 << (FIX + 3 - 1))) >> (FIX + 3);
            let v = (v + (1 << (COLOR - 1))) >> COLOR;
            out[8 * r + col] = v.clamp(0, max) as u16;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::{Path, PathBuf};

    fn streams() -> Vec<(PathBuf, Vec<u8>)> {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/jpeg12");
        let mut all: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|e| e == "jpg"))
            .map(|p| {
                let bytes = std::fs::read(&p).unwrap();
                (p, bytes)
            })
            .collect();
        all.sort();
        assert!(all.len() >= 5);
        all
    }

    /// A 16-bit binary PGM: width, height, samples.
    fn pgm(path: &Path) -> (usize, usize, Vec<u16>) {
        let bytes = std::fs::read(path).unwrap();
        let text = String::from_utf8_lossy(&bytes[..20]).to_string();
        let fields: Vec<&str> = text.split_whitespace().take(4).collect();
        assert_eq!((fields[0], fields[3]), ("P5", "4095"));
        let header = format!("P5\n{} {}\n4095\n", fields[1], fields[2]).len();
        let samples = bytes[header..]
            .chunks_exact(2)
            .map(|b| u16::from_be_bytes([b[0], b[1]]))
            .collect();
        (
            fields[1].parse().unwrap(),
            fields[2].parse().unwrap(),
            samples,
        )
    }

    /// Every stream decodes to the image Richter's libjpeg (pydicom's decoder) makes of it,
    /// sample for sample: restart intervals of 1 and 5 blocks, two encoders, qualities 5 to
    /// 90, and stripes whose overshoot the clamp cuts.
    #[test]
    fn decodes_as_the_reference_decoder() {
        for (path, bytes) in streams() {
            assert!(is_extended_12bit(&bytes), "{}", path.display());
            let frame = decode(&bytes).unwrap();
            let (width, height, want) = pgm(&path.with_extension("pgm"));
            assert_eq!((frame.width, frame.height), (width, height));
            let differ = frame
                .samples
                .iter()
                .zip(&want)
                .filter(|(a, b)| a != b)
                .count();
            assert_eq!(differ, 0, "{}: {differ} samples differ", path.display());
        }
        let stripes = decode(
            &streams()
                .iter()
                .find(|(p, _)| p.ends_with("stripes-q10.jpg"))
                .unwrap()
                .1,
        )
        .unwrap();
        assert!(stripes.samples.contains(&0) && stripes.samples.contains(&4095));
    }

    /// Quantisation tables written with 16-bit entries (Pq = 1, which encoders use when an
    /// entry exceeds 255) give the same image as the same tables in 8 bits.
    #[test]
    fn wide_quantisation_tables_read_as_narrow_ones() {
        for (path, bytes) in streams() {
            let (segments, _) = header_segments(&bytes).unwrap();
            let mut wide = bytes[..2].to_vec();
            let mut at = 2;
            for (marker, segment) in segments {
                let len = segment.len() + 2;
                if marker == 0xDB {
                    let mut body = Vec::new();
                    for table in segment.chunks(65) {
                        assert_eq!(table[0] >> 4, 0, "{}", path.display());
                        body.push(0x10 | table[0]);
                        body.extend(table[1..].iter().flat_map(|&q| [0, q]));
                    }
                    wide.extend([0xFF, 0xDB]);
                    wide.extend(((body.len() + 2) as u16).to_be_bytes());
                    wide.extend(body);
                } else {
                    wide.extend(&bytes[at..at + 2 + len]);
                }
                at += 2 + len;
            }
            wide.extend(&bytes[at..]);
            assert!(wide.len() > bytes.len());
            assert_eq!(
                decode(&wide).unwrap().samples,
                decode(&bytes).unwrap().samples
            );
        }
    }

    /// Cut anywhere before its end marker, a stream is refused (no zero-filled image); with a
    /// byte changed, refused or decoded to samples in range — never a panic.
    #[test]
    fn damaged_streams_fail_cleanly() {
        for (path, bytes) in streams() {
            for cut in 0..bytes.len() - 2 {
                let result = decode(&bytes[..cut]);
                assert!(result.is_err(), "{} cut at {cut}", path.display());
            }
            for at in (0..bytes.len()).step_by(3) {
                for flip in [0x01u8, 0x80, 0xFF] {
                    let mut bad = bytes.clone();
                    bad[at] ^= flip;
                    if let Ok(frame) = decode(&bad) {
                        assert_eq!(frame.samples.len(), frame.width * frame.height);
                        assert!(frame.samples.iter().all(|&v| v <= 4095));
                    }
                }
            }
        }
    }
}
