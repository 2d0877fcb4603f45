//! DICOM data sets walked by isocube itself: the file meta group, then every data element of
//! the data set, nested sequences and encapsulated pixel data included, in any of the
//! transfer syntaxes isocube reads. Every length is checked against what the file holds before
//! anything is taken from it, and nesting is bounded, so a hostile file can make the walk
//! neither allocate what it declares nor recurse without end.

use std::ops::Range;
use std::path::Path;

use crate::{IoError, Position};

/// How the data set after the file meta group is encoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Encoding {
    /// VRs written in the element headers (else the dictionary's).
    pub explicit: bool,
    /// Big-endian numbers (headers and binary values).
    pub big: bool,
}

impl Encoding {
    const IMPLICIT_LE: Encoding = Encoding {
        explicit: false,
        big: false,
    };
    const EXPLICIT_LE: Encoding = Encoding {
        explicit: true,
        big: false,
    };

    pub(super) fn u16(self, b: &[u8]) -> u16 {
        let b = [b[0], b[1]];
        if self.big {
            u16::from_be_bytes(b)
        } else {
            u16::from_le_bytes(b)
        }
    }

    pub(super) fn u32(self, b: &[u8]) -> u32 {
        let b = [b[0], b[1], b[2], b[3]];
        if self.big {
            u32::from_be_bytes(b)
        } else {
            u32::from_le_bytes(b)
        }
    }
}

/// How the pixel data of a transfer syntax is stored.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Compression {
    /// Native pixel data, in the data set's byte order.
    None,
    /// RLE Lossless (PS3.5 annex G).
    Rle,
    /// JPEG baseline, extended and lossless (processes 1, 2–4, 14).
    Jpeg,
    /// JPEG-LS, lossless or near-lossless.
    JpegLs,
    /// JPEG 2000, lossless or not.
    Jpeg2000,
}

/// The transfer syntaxes isocube reads: their encoding, whether the data set is deflated, and
/// how the pixel data is compressed.
pub(super) fn transfer_syntax(uid: &str) -> Option<(Encoding, bool, Compression)> {
    let le = Encoding::EXPLICIT_LE;
    Some(match uid {
        "1.2.840.10008.1.2" => (Encoding::IMPLICIT_LE, false, Compression::None),
        "1.2.840.10008.1.2.1" => (le, false, Compression::None),
        "1.2.840.10008.1.2.1.99" => (le, true, Compression::None),
        "1.2.840.10008.1.2.2" => (
            Encoding {
                explicit: true,
                big: true,
            },
            false,
            Compression::None,
        ),
        "1.2.840.10008.1.2.5" => (le, false, Compression::Rle),
        "1.2.840.10008.1.2.4.50"
        | "1.2.840.10008.1.2.4.51"
        | "1.2.840.10008.1.2.4.57"
        | "1.2.840.10008.1.2.4.70" => (le, false, Compression::Jpeg),
        "1.2.840.10008.1.2.4.80" | "1.2.840.10008.1.2.4.81" => (le, false, Compression::JpegLs),
        "1.2.840.10008.1.2.4.90" | "1.2.840.10008.1.2.4.91" => (le, false, Compression::Jpeg2000),
        _ => return None,
    })
}

/// A data element: its tag, VR, value, and the items of a sequence or the fragments of
/// encapsulated pixel data.
pub(super) struct Node {
    pub tag: (u16, u16),
    pub vr: [u8; 2],
    pub value: Range<usize>,
    pub items: Vec<Vec<Node>>,
    /// Encapsulated pixel data: the basic offset table first, then the fragments.
    pub fragments: Option<Vec<Range<usize>>>,
}

/// A parsed file: its data set's bytes (unpacked when deflated), encoding and elements.
pub(super) struct DataSet {
    pub data: Vec<u8>,
    pub encoding: Encoding,
    pub syntax: String,
    pub compression: Compression,
    pub nodes: Vec<Node>,
}

/// Sequences may nest this deep; real files use a handful of levels.
const MAX_DEPTH: usize = 24;

/// Reads a DICOM file (preamble, `DICM`, file meta group, data set). Refuses an unsupported
/// transfer syntax by name. `limit` caps what a deflated data set may unpack to.
pub(super) fn parse(path: &Path, bytes: &[u8], limit: u64) -> Result<DataSet, IoError> {
    if bytes.len() < 132 || &bytes[128..132] != b"DICM" {
        // Without the Part 10 header (preamble, marker, meta group) a file may still be a bare
        // data set, as older systems and some planning exports write them: in the default
        // transfer syntax, implicit VR little endian, or explicit. It opens with group 0008.
        if bytes.len() >= 8 && bytes[..2] == [8, 0] {
            let explicit = VRS.chunks(2).any(|v| v == &bytes[4..6]);
            let (encoding, syntax) = if explicit {
                (Encoding::EXPLICIT_LE, "1.2.840.10008.1.2.1")
            } else {
                (Encoding::IMPLICIT_LE, "1.2.840.10008.1.2")
            };
            let walker = Walker {
                path,
                data: bytes,
                base: 0,
            };
            let mut pos = 0;
            let nodes = walker.nodes(&mut pos, End::Eof, encoding, 0)?;
            return Ok(DataSet {
                data: bytes.to_vec(),
                encoding,
                syntax: syntax.to_string(),
                compression: Compression::None,
                nodes,
            });
        }
        return Err(IoError::format(
            path,
            Position::Byte(128),
            "no DICM marker (and not a bare data set opening with group 0008)",
        ));
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
        let e = header(path, bytes, at, Encoding::EXPLICIT_LE, 0)?;
        if e.len.is_none() || e.vr == *b"SQ" {
            return Err(IoError::format(
                path,
                Position::Byte(at as u64),
                "a file meta element without a defined length",
            ));
        }
        let end = e.value + e.len.unwrap_or(0);
        if e.tag == (2, 0x10) {
            syntax = Some(
                String::from_utf8_lossy(&bytes[e.value..end])
                    .trim_end_matches(['\0', ' '])
                    .to_string(),
            );
        }
        at = end;
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
    let (encoding, deflated, compression) = transfer_syntax(&syntax).ok_or_else(|| {
        IoError::unsupported(
            path,
            Position::Field("TransferSyntaxUID".into()),
            format!(
                "transfer syntax {syntax}: isocube reads implicit and explicit VR little and big \
                 endian, deflated, RLE, JPEG (baseline, extended, lossless), JPEG-LS and JPEG 2000"
            ),
        )
    })?;
    let (data, base) = if deflated {
        use std::io::Read;
        let mut data = Vec::new();
        flate2::read::DeflateDecoder::new(&bytes[at..])
            .take(limit.saturating_add(1))
            .read_to_end(&mut data)
            .map_err(|e| {
                IoError::format(
                    path,
                    Position::Byte(at as u64),
                    format!("deflated data set: {e}"),
                )
            })?;
        if data.len() as u64 > limit {
            return Err(IoError::TooLarge {
                path: path.to_path_buf(),
                position: Position::Byte(at as u64),
                needed: data.len() as u64,
                limit,
            });
        }
        (data, 0)
    } else {
        (bytes[at..].to_vec(), at)
    };
    let walker = Walker {
        path,
        data: &data,
        base,
    };
    let mut pos = 0;
    let nodes = walker.nodes(&mut pos, End::Eof, encoding, 0)?;
    Ok(DataSet {
        data,
        encoding,
        syntax,
        compression,
        nodes,
    })
}

/// The value representations of the standard (PS3.5 6.2), two letters each.
const VRS: &[u8] = b"AEASATCSDADSDTFDFLISLOLTOBODOFOLOVOWPNSHSLSQSSSTSVTMUCUIULUNURUSUTUV";

/// The VRs written with a 4-byte length (after two reserved bytes) in explicit VR.
const LONG: &[u8] = b"OBODOFOLOVOWSQSVUCUNURUTUV";

/// A data element's header.
struct Header {
    tag: (u16, u16),
    /// The VR, written or the dictionary's; `[0, 0]` for items and delimiters.
    vr: [u8; 2],
    value: usize,
    /// `None` when undefined.
    len: Option<usize>,
}

/// Reads the element header at `at` of `data` (which starts at byte `base` of the file); a
/// defined length must fit in what follows.
fn header(
    path: &Path,
    data: &[u8],
    at: usize,
    enc: Encoding,
    base: usize,
) -> Result<Header, IoError> {
    use dicom_core::dictionary::{DataDictionary, DataDictionaryEntry, VirtualVr};
    let here = Position::Byte((base + at) as u64);
    let ends = || {
        IoError::format(
            path,
            here.clone(),
            "the file ends inside a data element's header",
        )
    };
    let u16_at = |i: usize| data.get(i..i + 2).map(|b| enc.u16(b)).ok_or_else(ends);
    let u32_at = |i: usize| data.get(i..i + 4).map(|b| enc.u32(b)).ok_or_else(ends);
    let tag = (u16_at(at)?, u16_at(at + 2)?);
    let name = format!("({:04X},{:04X})", tag.0, tag.1);
    // The VR: written (explicit) or the dictionary's (implicit; unknown tags are UN).
    let vr: [u8; 2] = if tag.0 == 0xFFFE {
        [0, 0]
    } else if enc.explicit {
        let vr = data.get(at + 4..at + 6).ok_or_else(ends)?;
        // With an unknown VR the size of the length field is unknown too.
        if !VRS.chunks(2).any(|v| v == vr) {
            return Err(IoError::format(
                path,
                here,
                format!(
                    "element {name} has an unknown value representation {:?}",
                    String::from_utf8_lossy(vr)
                ),
            ));
        }
        [vr[0], vr[1]]
    } else {
        let dictionary = dicom_dictionary_std::StandardDataDictionary;
        match dictionary
            .by_tag(dicom_core::Tag(tag.0, tag.1))
            .map(|e| e.vr())
        {
            Some(VirtualVr::Exact(vr)) => vr.to_bytes(),
            // As dicom-core relaxes the context-dependent VRs (2-byte values either way).
            Some(VirtualVr::Xs) => *b"US",
            Some(VirtualVr::Ox | VirtualVr::Px | VirtualVr::Lt) => *b"OW",
            _ => *b"UN",
        }
    };
    // The standard allows only OB and OW for Pixel Data.
    if tag == (0x7FE0, 0x0010) && enc.explicit && vr != *b"OB" && vr != *b"OW" {
        return Err(IoError::format(
            path,
            here,
            format!(
                "Pixel Data (7FE0,0010) of {}: only OB and OW are valid",
                String::from_utf8_lossy(&vr)
            ),
        ));
    }
    let (len, value) = if vr == [0, 0] || !enc.explicit {
        (u32_at(at + 4)?, at + 8)
    } else if LONG.chunks(2).any(|v| v == vr) {
        (u32_at(at + 8)?, at + 12)
    } else {
        (u32::from(u16_at(at + 6)?), at + 8)
    };
    // A value of a fixed-size VR is a whole number of values.
    let size = match &vr {
        b"SS" | b"US" | b"OW" => 2,
        b"AT" | b"FL" | b"SL" | b"UL" | b"OF" | b"OL" => 4,
        b"FD" | b"SV" | b"UV" | b"OD" | b"OV" => 8,
        _ => 1,
    };
    let len = (len != u32::MAX).then_some(len as usize);
    if let Some(len) = len {
        if len % size != 0 {
            return Err(IoError::format(
                path,
                here,
                format!(
                    "element {name} of {} has {len} bytes, not a whole number of {size}-byte values",
                    String::from_utf8_lossy(&vr)
                ),
            ));
        }
        if len > data.len().saturating_sub(value) {
            return Err(IoError::format(
                path,
                here,
                format!(
                    "element {name} declares {len} bytes, only {} remain (the file is cut short or the length is wrong)",
                    data.len().saturating_sub(value)
                ),
            ));
        }
    }
    Ok(Header {
        tag,
        vr,
        value,
        len,
    })
}

/// Where a run of elements ends.
#[derive(Clone, Copy)]
enum End {
    /// The end of the data set.
    Eof,
    /// A defined length: this offset.
    At(usize),
    /// An undefined-length item: its Item Delimitation Item.
    Delimiter,
}

struct Walker<'a> {
    path: &'a Path,
    data: &'a [u8],
    base: usize,
}

impl Walker<'_> {
    fn error(&self, at: usize, reason: impl Into<String>) -> IoError {
        IoError::format(
            self.path,
            Position::Byte((self.base + at) as u64),
            reason.into(),
        )
    }

    /// The elements from `*at` to `end`; leaves `*at` after them (and after a closing
    /// delimiter).
    fn nodes(
        &self,
        at: &mut usize,
        end: End,
        enc: Encoding,
        depth: usize,
    ) -> Result<Vec<Node>, IoError> {
        if depth > MAX_DEPTH {
            return Err(self.error(*at, format!("sequences nested deeper than {MAX_DEPTH}")));
        }
        let mut nodes = Vec::new();
        loop {
            match end {
                End::Eof if *at >= self.data.len() => break,
                End::At(e) if *at == e => break,
                End::At(e) if *at > e => {
                    return Err(self.error(*at, "an element runs past the end of its item"))
                }
                End::Delimiter if *at >= self.data.len() => {
                    return Err(self.error(*at, "an item without its delimiter"))
                }
                _ => {}
            }
            let start = *at;
            let h = header(self.path, self.data, start, enc, self.base)?;
            let name = format!("({:04X},{:04X})", h.tag.0, h.tag.1);
            if h.tag == (0xFFFE, 0xE00D) {
                if h.len != Some(0) {
                    return Err(self.error(start, "a delimiter's length must be 0"));
                }
                if matches!(end, End::Delimiter) {
                    *at = h.value;
                    break;
                }
                return Err(self.error(start, "an item delimiter outside an item"));
            }
            if h.tag.0 == 0xFFFE {
                return Err(self.error(
                    start,
                    format!("{name}: an item or delimiter outside a sequence"),
                ));
            }
            let mut node = Node {
                tag: h.tag,
                vr: h.vr,
                value: h.value..h.value,
                items: Vec::new(),
                fragments: None,
            };
            if h.tag == (0x7FE0, 0x0010) && h.len.is_none() {
                *at = h.value;
                node.fragments = Some(self.fragments(at)?);
            } else if h.vr == *b"SQ" || (h.vr == *b"UN" && h.len.is_none()) {
                // A UN of undefined length is a sequence in implicit VR little endian
                // (PS3.5 6.2.2).
                let inner = if h.vr == *b"UN" {
                    Encoding::IMPLICIT_LE
                } else {
                    enc
                };
                *at = h.value;
                let close = h.len.map(|l| h.value + l);
                node.items = self.items(at, close, inner, depth + 1)?;
            } else {
                let len = h.len.ok_or_else(|| {
                    self.error(
                        start,
                        format!("{name}: an undefined length outside a sequence or pixel data"),
                    )
                })?;
                node.value = h.value..h.value + len;
                *at = h.value + len;
            }
            nodes.push(node);
        }
        Ok(nodes)
    }

    /// A sequence's items, to `close` (a defined length) or its Sequence Delimitation Item.
    fn items(
        &self,
        at: &mut usize,
        close: Option<usize>,
        enc: Encoding,
        depth: usize,
    ) -> Result<Vec<Vec<Node>>, IoError> {
        let mut items = Vec::new();
        loop {
            if let Some(c) = close {
                if *at == c {
                    break;
                }
                if *at > c {
                    return Err(self.error(*at, "an item runs past the end of its sequence"));
                }
            }
            let start = *at;
            let h = header(self.path, self.data, start, enc, self.base)?;
            match (h.tag, h.len) {
                ((0xFFFE, 0xE0DD), Some(0)) if close.is_none() => {
                    *at = h.value;
                    break;
                }
                ((0xFFFE, 0xE000), len) => {
                    *at = h.value;
                    let end = len.map_or(End::Delimiter, |l| End::At(h.value + l));
                    items.push(self.nodes(at, end, enc, depth)?);
                }
                (tag, _) => {
                    return Err(self.error(
                        start,
                        format!(
                            "({:04X},{:04X}) where a sequence item belongs",
                            tag.0, tag.1
                        ),
                    ))
                }
            }
        }
        Ok(items)
    }

    /// Encapsulated pixel data: its items (the basic offset table, then the fragments), to the
    /// Sequence Delimitation Item.
    fn fragments(&self, at: &mut usize) -> Result<Vec<Range<usize>>, IoError> {
        let mut fragments = Vec::new();
        loop {
            let start = *at;
            // Items of encapsulated pixel data are little endian in every syntax that has them.
            let h = header(
                self.path,
                self.data,
                start,
                Encoding::EXPLICIT_LE,
                self.base,
            )?;
            match (h.tag, h.len) {
                ((0xFFFE, 0xE0DD), Some(0)) => {
                    *at = h.value;
                    return Ok(fragments);
                }
                ((0xFFFE, 0xE000), Some(len)) => {
                    fragments.push(h.value..h.value + len);
                    *at = h.value + len;
                }
                _ => {
                    return Err(self.error(
                        start,
                        "encapsulated pixel data holds something other than fragments of a defined length",
                    ))
                }
            }
        }
    }
}

/// The element `tag` among `nodes`.
pub(super) fn find(nodes: &[Node], tag: (u16, u16)) -> Option<&Node> {
    nodes.iter().find(|n| n.tag == tag)
}
