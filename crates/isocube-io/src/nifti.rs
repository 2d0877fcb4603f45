//! NIfTI-1 volumes (`.nii`, `.nii.gz`, and `.hdr`/`.img` pairs) through the `nifti` crate, and
//! single-file NIfTI-2 (`.nii`, `.nii.gz`: 540-byte header, 64-bit sizes, double-precision
//! geometry), which that crate does not read, by hand. The file's index-to-world map: the
//! `sform` when its code is set, else the `qform` (quaternion, `qfac`, voxel sizes and offset),
//! else the voxel sizes alone (NIfTI's "method 1"). World coordinates are the file's (RAS+ by
//! the format's convention). Values go through `scl_slope` and `scl_inter` when the slope is
//! not zero. Of a 4-d or 5-d file one 3-d volume is read: the frame (`dim[4]`, time) and
//! channel (`dim[5]`, vector components) the caller picks.

use std::io::Read;
use std::path::Path;

use nifti::{InMemNiftiObject, IntoNdArray, NiftiHeader, NiftiObject, ReaderOptions};

use super::mapped::Placement;
use super::raw::{decode_into, Endian, ScalarType};
use super::{Budget, IoError, Pick, Position};
use isocube::field::{Grid, Orientation};

/// Reads a NIfTI-1 volume and its orientation. The grid's spacing and origin are the lengths of
/// the index-to-world map's columns and its translation; the orientation is the rest.
pub fn read_nifti(path: &Path) -> Result<(Grid, Orientation), IoError> {
    read_nifti_within(path, Budget::UNLIMITED, Pick::default())
}

/// Reads the header on its own (from a `.nii.gz`, only the bytes it takes are unpacked) and
/// refuses a volume that the file cannot hold or that passes the budget, before the crate
/// reserves the space its header asks for.
pub(super) fn check_size(path: &Path, budget: Budget) -> Result<(), IoError> {
    let file = std::fs::File::open(path).map_err(|e| IoError::os(path, e))?;
    let len = file.metadata().map_err(|e| IoError::os(path, e))?.len();
    check_header(path, std::io::BufReader::new(file), len, budget)
}

/// Whether `path` names a gzip-compressed file.
fn gzipped(path: &Path) -> bool {
    path.file_name()
        .and_then(|n| n.to_str())
        .is_some_and(|n| n.to_ascii_lowercase().ends_with(".gz"))
}

/// [`check_size`] on the file's content (`len` bytes as stored, compressed or not).
fn check_header(path: &Path, reader: impl Read, len: u64, budget: Budget) -> Result<(), IoError> {
    check_stream(path, gzipped(path), reader, len, budget)
}

/// [`check_header`] on a stream that is gzip-compressed or not (`gz`), whatever the name says.
fn check_stream(
    path: &Path,
    gz: bool,
    reader: impl Read,
    len: u64,
    budget: Budget,
) -> Result<(), IoError> {
    let mut reader: Box<dyn Read> = if gz {
        Box::new(flate2::read::MultiGzDecoder::new(reader))
    } else {
        Box::new(reader)
    };
    let mut first = [0u8; 4];
    if reader.read_exact(&mut first).is_ok() && is_nifti2(first) {
        // NIfTI-2's reader makes its own checks as it reads the header.
        return Ok(());
    }
    let mut reader = std::io::Cursor::new(first).chain(reader);
    let header = NiftiHeader::from_reader(&mut reader).map_err(|e| match e {
        nifti::NiftiError::Io(io) if io.kind() == std::io::ErrorKind::UnexpectedEof => {
            IoError::format(path, Position::File, "the file ends inside its header")
        }
        nifti::NiftiError::Io(io) if gz => {
            IoError::format(path, Position::File, format!("corrupt gzip data: {io}"))
        }
        other => IoError::format(
            path,
            Position::File,
            format!("not a readable NIfTI-1 file: {other}"),
        ),
    })?;
    // The crate neither checks the header's size field nor always the rank before trusting the
    // rest: only headers that pass here reach it.
    if header.sizeof_hdr != 348 {
        return Err(IoError::format(
            path,
            Position::Field("sizeof_hdr".into()),
            format!(
                "{} (a NIfTI-1 header has 348 bytes; NIfTI-2 is not read)",
                header.sizeof_hdr
            ),
        ));
    }
    if &header.magic == b"n+1\0" {
        check_extensions(path, &header, &mut reader)?;
    }
    let rank = usize::from(header.dim[0]);
    if !(1..=7).contains(&rank) {
        return Err(IoError::format(
            path,
            Position::Field("dim".into()),
            format!("dim[0] = {rank}: the rank must be 1 to 7"),
        ));
    }
    // The crate trusts datatype and bitpix to agree (and panics where they do not): check them.
    let bits = match header.datatype {
        2 | 256 => 8,
        4 | 512 => 16,
        8 | 16 | 768 => 32,
        64 | 1024 | 1280 => 64,
        other => {
            return Err(IoError::unsupported(
                path,
                Position::Field("datatype".into()),
                format!("datatype {other}: isocube reads one integer or real scalar per voxel"),
            ))
        }
    };
    if header.bitpix != bits {
        return Err(IoError::format(
            path,
            Position::Field("bitpix".into()),
            format!(
                "{} bits, datatype {} has {bits}",
                header.bitpix, header.datatype
            ),
        ));
    }
    // The crate's own view of the dimensions, which is what it reserves space for.
    let dims = header.dim().map_err(|_| {
        IoError::format(
            path,
            Position::Field("dim".into()),
            format!(
                "{:?}: every axis up to dim[0] needs at least one point",
                header.dim
            ),
        )
    })?;
    let count = dims
        .iter()
        .fold(1u64, |n, &d| n.saturating_mul(u64::from(d)));
    let bytes = count.saturating_mul(header.bitpix as u64 / 8);
    let dim = || Position::Field("dim".into());
    let single_file = &header.magic == b"n+1\0";
    let offset = f64::from(header.vox_offset).max(352.0);
    if single_file && !gz && offset + bytes as f64 > len as f64 {
        return Err(IoError::format(
            path,
            dim(),
            format!(
                "{:?} voxels of {} bits need {bytes} bytes from byte {offset}, the file has {len}",
                &header.dim[1..=rank],
                header.bitpix
            ),
        ));
    }
    // The stored bytes, the crate's f32 array and the grid's copy.
    budget.check(path, dim(), bytes.saturating_add(count.saturating_mul(8)))
}

/// The crate reserves each extension's declared size before reading it, and trusts sizes below
/// 8 or past the data's start: walk the extensions (between the 352-byte header and
/// `vox_offset`) first and refuse such sizes.
fn check_extensions(
    path: &Path,
    header: &NiftiHeader,
    reader: &mut dyn Read,
) -> Result<(), IoError> {
    let mut extender = [0u8; 4];
    if reader.read_exact(&mut extender).is_err() || extender[0] == 0 {
        return Ok(());
    }
    let len = (header.vox_offset as usize).saturating_sub(352);
    let big = header.endianness == nifti::Endianness::Big;
    let mut offset = 0usize;
    while offset < len {
        let mut head = [0u8; 8];
        if reader.read_exact(&mut head).is_err() {
            // Cut short: the crate says so.
            return Ok(());
        }
        let esize = if big {
            i32::from_be_bytes([head[0], head[1], head[2], head[3]])
        } else {
            i32::from_le_bytes([head[0], head[1], head[2], head[3]])
        };
        let fits = usize::try_from(esize)
            .ok()
            .filter(|&n| n >= 8 && offset + n <= len);
        let Some(esize) = fits else {
            return Err(IoError::format(
                path,
                Position::Byte((352 + offset) as u64),
                format!(
                    "an extension of {esize} bytes: extensions take at least 8 bytes each and end at vox_offset {}",
                    header.vox_offset
                ),
            ));
        };
        std::io::copy(&mut reader.take(esize as u64 - 8), &mut std::io::sink())
            .map_err(|e| IoError::os(path, e))?;
        offset += esize;
    }
    Ok(())
}

pub(super) fn read_nifti_within(
    path: &Path,
    budget: Budget,
    pick: Pick,
) -> Result<(Grid, Orientation), IoError> {
    let file = std::fs::File::open(path).map_err(|e| IoError::os(path, e))?;
    let len = file.metadata().map_err(|e| IoError::os(path, e))?.len();
    let reader = std::io::BufReader::with_capacity(1 << 20, file);
    if let Some(read) = try_nifti2(path, reader, len, budget, pick)? {
        return Ok(read);
    }
    check_size(path, budget)?;
    if pick.frame.unwrap_or(0) == 0 && pick.channel.unwrap_or(0) == 0 {
        let file = std::fs::File::open(path).map_err(|e| IoError::os(path, e))?;
        if let Some(read) = read_stored(path, std::io::BufReader::with_capacity(1 << 20, file))? {
            return Ok(read);
        }
    }
    let object = ReaderOptions::new()
        .read_file(path)
        .map_err(|e| nifti_error(path, e))?;
    finish(path, object, pick)
}

/// [`read_nifti_within`] on a single-file NIfTI (`.nii`, or `.nii.gz` when `path` ends so)
/// already in memory.
pub(super) fn read_nifti_bytes(
    path: &Path,
    bytes: &[u8],
    budget: Budget,
    pick: Pick,
) -> Result<(Grid, Orientation), IoError> {
    if let Some(read) = try_nifti2(path, bytes, bytes.len() as u64, budget, pick)? {
        return Ok(read);
    }
    check_header(path, bytes, bytes.len() as u64, budget)?;
    if pick.frame.unwrap_or(0) == 0 && pick.channel.unwrap_or(0) == 0 {
        if let Some(read) = read_stored(path, bytes)? {
            return Ok(read);
        }
    }
    let object = if gzipped(path) {
        InMemNiftiObject::from_reader(flate2::read::MultiGzDecoder::new(bytes))
    } else {
        InMemNiftiObject::from_reader(bytes)
    }
    .map_err(|e| nifti_error(path, e))?;
    finish(path, object, pick)
}

/// A file's bytes as stored, inflated on the way when `path` names a gzip file.
fn stored<'a>(path: &Path, reader: impl Read + 'a) -> Box<dyn Read + 'a> {
    if gzipped(path) {
        Box::new(flate2::read::MultiGzDecoder::new(reader))
    } else {
        Box::new(reader)
    }
}

/// A NIfTI-2 file's volume from `reader` (its `len` bytes as stored, gzip or not), or `None`
/// when its header is NIfTI-1's.
fn try_nifti2(
    path: &Path,
    reader: impl Read,
    len: u64,
    budget: Budget,
    pick: Pick,
) -> Result<Option<(Grid, Orientation)>, IoError> {
    let mut stream = stored(path, reader);
    let mut first = [0u8; 4];
    stream
        .read_exact(&mut first)
        .map_err(|e| stream_error(path, e))?;
    if !is_nifti2(first) {
        return Ok(None);
    }
    let known = (!gzipped(path)).then_some(len);
    let whole = std::io::Cursor::new(first).chain(stream);
    read_nifti2(path, whole, known, budget, pick).map(Some)
}

/// Whether a header's first four bytes (`sizeof_hdr`) say NIfTI-2, in either byte order.
fn is_nifti2(first: [u8; 4]) -> bool {
    i32::from_le_bytes(first) == 540 || i32::from_be_bytes(first) == 540
}

/// The 3-d volume `pick` chooses among the frames (`dim[4]`) and channels (`dim[5]`) that
/// follow the spatial axes (`extra`: `dim[4..=rank]`): its index in the file's order of
/// volumes (frames fastest).
fn volume_index(path: &Path, extra: &[u64], pick: Pick) -> Result<u64, IoError> {
    let dim = || Position::Field("dim".into());
    let n = |a: usize| extra.get(a).copied().unwrap_or(1).max(1);
    if let Some(a) = (2..extra.len()).find(|&a| n(a) > 1) {
        return Err(IoError::unsupported(
            path,
            dim(),
            format!(
                "dim[{}] = {}: isocube picks a volume by frame (dim[4]) and channel (dim[5]) only",
                a + 4,
                n(a)
            ),
        ));
    }
    let to = |x: u64| usize::try_from(x).unwrap_or(usize::MAX);
    let frame = Pick::index(
        path,
        dim(),
        pick.frame,
        to(n(0)),
        "--frame",
        "frames (dim[4])",
    )?;
    let channel = Pick::index(
        path,
        dim(),
        pick.channel,
        to(n(1)),
        "--channel",
        "channels (dim[5])",
    )?;
    Ok(frame as u64 + n(0) * channel as u64)
}

/// A single-file NIfTI-2 volume from its stream (inflating when gzip): header, extensions
/// skipped to `vox_offset`, the picked volume's values. `len` is the file's length when known
/// (not compressed), to refuse data the file cannot hold before reading.
fn read_nifti2(
    path: &Path,
    mut stream: impl Read,
    len: Option<u64>,
    budget: Budget,
    pick: Pick,
) -> Result<(Grid, Orientation), IoError> {
    let field = |name: &str| Position::Field(name.into());
    let mut h = [0u8; 540];
    stream
        .read_exact(&mut h)
        .map_err(|e| stream_error(path, e))?;
    let big = i32::from_be_bytes([h[0], h[1], h[2], h[3]]) == 540;
    let endian = if big { Endian::Big } else { Endian::Little };
    let b8 = |at: usize| -> [u8; 8] { std::array::from_fn(|i| h[at + i]) };
    let i64_at = |at: usize| {
        if big {
            i64::from_be_bytes(b8(at))
        } else {
            i64::from_le_bytes(b8(at))
        }
    };
    let f64_at = |at: usize| {
        if big {
            f64::from_be_bytes(b8(at))
        } else {
            f64::from_le_bytes(b8(at))
        }
    };
    let i16_at = |at: usize| {
        let b = [h[at], h[at + 1]];
        if big {
            i16::from_be_bytes(b)
        } else {
            i16::from_le_bytes(b)
        }
    };
    let i32_at = |at: usize| {
        let b = [h[at], h[at + 1], h[at + 2], h[at + 3]];
        if big {
            i32::from_be_bytes(b)
        } else {
            i32::from_le_bytes(b)
        }
    };
    match &h[4..12] {
        b"n+2\0\r\n\x1a\n" => {}
        b"ni2\0\r\n\x1a\n" => return Err(IoError::unsupported(
            path,
            field("magic"),
            "a NIfTI-2 header with its data in a separate .img: isocube reads single-file NIfTI-2",
        )),
        other => {
            return Err(IoError::format(
                path,
                field("magic"),
                format!("{other:?}: not NIfTI-2's \"n+2\\0\\r\\n\\x1a\\n\""),
            ))
        }
    }
    let dim: [i64; 8] = std::array::from_fn(|i| i64_at(16 + 8 * i));
    let rank = dim[0];
    if !(1..=7).contains(&rank) {
        return Err(IoError::format(
            path,
            field("dim"),
            format!("dim[0] = {rank}: the rank must be 1 to 7"),
        ));
    }
    let rank = rank as usize;
    if dim[1..=rank].iter().any(|&d| d < 1) {
        return Err(IoError::format(
            path,
            field("dim"),
            format!(
                "{:?}: every axis up to dim[0] needs at least one point",
                &dim[1..=rank]
            ),
        ));
    }
    let (datatype, bitpix) = (i16_at(12), i16_at(14));
    let scalar = scalar_of(datatype).ok_or_else(|| {
        IoError::unsupported(
            path,
            field("datatype"),
            format!("datatype {datatype}: isocube reads one integer or real scalar per voxel"),
        )
    })?;
    if bitpix as usize != 8 * scalar.size() {
        return Err(IoError::format(
            path,
            field("bitpix"),
            format!(
                "{bitpix} bits, datatype {datatype} has {}",
                8 * scalar.size()
            ),
        ));
    }
    let axis = |a: usize| if a <= rank { dim[a] as u64 } else { 1 };
    let extra: Vec<u64> = (4..=rank).map(|a| dim[a] as u64).collect();
    let index = volume_index(path, &extra, pick)?;
    let count = (1..=3).try_fold(1u64, |n, a| n.checked_mul(axis(a)));
    let volumes = extra.iter().try_fold(1u64, |n, &d| n.checked_mul(d));
    let too_big = || IoError::format(path, field("dim"), "the volume's size overflows");
    let count = count.ok_or_else(too_big)?;
    let volume_bytes = count
        .checked_mul(scalar.size() as u64)
        .ok_or_else(too_big)?;
    let all_bytes = volumes
        .and_then(|v| v.checked_mul(volume_bytes))
        .ok_or_else(too_big)?;
    let vox_offset = i64_at(168);
    if vox_offset < 544 {
        return Err(IoError::format(
            path,
            field("vox_offset"),
            format!("{vox_offset}: NIfTI-2 data start at byte 544 or later"),
        ));
    }
    let vox_offset = vox_offset as u64;
    if let Some(len) = len {
        if vox_offset.saturating_add(all_bytes) > len {
            return Err(IoError::format(
                path,
                field("dim"),
                format!(
                    "{:?} voxels of {bitpix} bits need {all_bytes} bytes from byte {vox_offset}, the file has {len}",
                    &dim[1..=rank]
                ),
            ));
        }
    }
    budget.check(
        path,
        field("dim"),
        volume_bytes.saturating_add(count.saturating_mul(4)),
    )?;
    let dims = [1, 2, 3].map(|a| axis(a) as usize);
    let count = Grid::point_count(dims).map_err(|e| IoError::grid(path, e))?;
    let geometry = Geometry {
        sform_code: i32_at(348),
        qform_code: i32_at(344),
        srow: std::array::from_fn(|r| std::array::from_fn(|c| f64_at(400 + 32 * r + 8 * c))),
        quatern: [f64_at(352), f64_at(360), f64_at(368)],
        qoffset: [f64_at(376), f64_at(384), f64_at(392)],
        pixdim: std::array::from_fn(|i| f64_at(104 + 8 * i)),
    };
    let (slope, intercept) = (f64_at(176), f64_at(184));
    let skip = vox_offset - 540 + index * volume_bytes;
    let skipped = std::io::copy(&mut (&mut stream).take(skip), &mut std::io::sink())
        .map_err(|e| stream_error(path, e))?;
    if skipped < skip {
        return Err(IoError::format(
            path,
            Position::File,
            "the file ends before its data",
        ));
    }
    let mut raw = vec![0u8; count * scalar.size()];
    stream
        .read_exact(&mut raw)
        .map_err(|e| stream_error(path, e))?;
    let mut values = vec![0.0f32; count];
    decode_into(&raw, scalar, endian, &mut values);
    if slope != 0.0
        && slope.is_finite()
        && intercept.is_finite()
        && (slope != 1.0 || intercept != 0.0)
    {
        values
            .iter_mut()
            .for_each(|v| *v = (f64::from(*v) * slope + intercept) as f32);
    }
    let (linear, origin) = geometry.index_to_world();
    let (spacing, orientation) = Orientation::from_linear(linear).ok_or_else(|| {
        IoError::format(
            path,
            field(if geometry.sform_code > 0 {
                "srow"
            } else {
                "pixdim"
            }),
            "the index-to-world map is singular or not finite",
        )
    })?;
    let grid = Grid::new(dims, values)
        .and_then(|g| g.with_spacing(spacing))
        .and_then(|g| g.with_origin(origin))
        .map_err(|e| IoError::grid(path, e))?;
    Ok((grid, orientation))
}

fn nifti_error(path: &Path, e: nifti::NiftiError) -> IoError {
    let fail = |reason: String| IoError::format(path, Position::File, reason);
    match e {
        nifti::NiftiError::Io(io) if io.kind() == std::io::ErrorKind::UnexpectedEof => {
            fail("the file ends inside its header or data".into())
        }
        nifti::NiftiError::Io(io) if io.kind() == std::io::ErrorKind::NotFound => {
            IoError::os(path, io)
        }
        nifti::NiftiError::NoVolumeData => fail(
            "a header without its data (a .hdr/.img pair is read from files, not bytes)".into(),
        ),
        nifti::NiftiError::Io(io) => fail(format!("not a readable NIfTI-1 file: {io}")),
        other => fail(format!("not a readable NIfTI-1 file: {other}")),
    }
}

/// Where a single-file `.nii` keeps its voxels (for [`super::MappedVolume`]), from the mapped
/// file; `None` for what the mapped path does not cover (more than one frame, a `.hdr`/`.img`
/// pair): the reader handles those, or says why not.
pub(super) fn placement(path: &Path, bytes: &[u8]) -> Result<Option<Placement>, IoError> {
    placement_within(path, bytes, bytes.len() as u64)
}

/// [`placement`] from the header's bytes (up to `vox_offset`) of a file holding `len` bytes.
fn placement_within(path: &Path, bytes: &[u8], len: u64) -> Result<Option<Placement>, IoError> {
    // NIfTI-2 is read whole (its reader picks the volume on the way).
    if bytes.len() >= 4 && is_nifti2([bytes[0], bytes[1], bytes[2], bytes[3]]) {
        return Ok(None);
    }
    check_stream(path, false, bytes, len, Budget::UNLIMITED)?;
    let header = NiftiHeader::from_reader(bytes).map_err(|e| nifti_error(path, e))?;
    let dim = header.dim;
    let rank = usize::from(dim[0]);
    let frames: usize = dim[4..=rank.max(3)]
        .iter()
        .map(|&d| usize::from(d.max(1)))
        .product();
    if &header.magic != b"n+1\0" || frames != 1 {
        return Ok(None);
    }
    let Some(scalar) = scalar_of(header.datatype) else {
        return Ok(None);
    };
    let endian = match header.endianness {
        nifti::Endianness::Little => Endian::Little,
        nifti::Endianness::Big => Endian::Big,
    };
    let dims: [usize; 3] = std::array::from_fn(|a| {
        if a < rank {
            usize::from(dim[a + 1]).max(1)
        } else {
            1
        }
    });
    let (spacing, orientation) = world(path, &header)?;
    let (slope, intercept) = (header.scl_slope, header.scl_inter);
    // As the reader applies them: a zero slope means no scaling.
    let scale = (slope != 0.0 && (slope != 1.0 || intercept != 0.0)).then_some((slope, intercept));
    Ok(Some(Placement {
        data_file: None,
        offset: f64::from(header.vox_offset).max(352.0) as usize,
        scalar,
        endian,
        dims,
        spacing,
        origin: Geometry::of(&header).index_to_world().1,
        orientation,
        scale,
    }))
}

/// [`read_into_grid`] on a file's bytes as stored: inflated on the way when `path` names a
/// gzip file.
fn read_stored(path: &Path, stored: impl Read) -> Result<Option<(Grid, Orientation)>, IoError> {
    if gzipped(path) {
        read_into_grid(path, flate2::read::MultiGzDecoder::new(stored))
    } else {
        read_into_grid(path, stored)
    }
}

/// A single-file NIfTI read once from `stream` (a `.nii`, or a `.nii.gz` inflating), straight
/// into the grid's values (for `f32`, into the grid's own memory): `None` for what
/// [`placement`] does not cover, which the crate's reader then handles or explains. Errors are
/// the stream's (corrupt, or ending before the data do).
fn read_into_grid(
    path: &Path,
    mut stream: impl Read,
) -> Result<Option<(Grid, Orientation)>, IoError> {
    let corrupt = |e| stream_error(path, e);
    let Some(p) = read_head(path, &mut stream)? else {
        return Ok(None);
    };
    let count = Grid::point_count(p.dims).map_err(|e| IoError::grid(path, e))?;
    let mut values = vec![0.0f32; count];
    if p.scalar == ScalarType::F32 {
        stream
            .read_exact(bytemuck::cast_slice_mut(&mut values))
            .map_err(corrupt)?;
        if !p.endian.is_native() {
            values
                .iter_mut()
                .for_each(|v| *v = f32::from_bits(v.to_bits().swap_bytes()));
        }
    } else {
        let mut raw = vec![0u8; count * p.scalar.size()];
        stream.read_exact(&mut raw).map_err(corrupt)?;
        decode_into(&raw, p.scalar, p.endian, &mut values);
    }
    if let Some((slope, intercept)) = p.scale {
        values.iter_mut().for_each(|v| *v = *v * slope + intercept);
    }
    let grid = Grid::new(p.dims, values)
        .and_then(|g| g.with_spacing(p.spacing))
        .and_then(|g| g.with_origin(p.origin))
        .map_err(|e| IoError::grid(path, e))?;
    Ok(Some((grid, p.orientation)))
}

/// A read error of a NIfTI stream, as a typed error naming the file.
pub(super) fn stream_error(path: &Path, e: std::io::Error) -> IoError {
    match e.kind() {
        std::io::ErrorKind::UnexpectedEof => {
            IoError::format(path, Position::File, "the file ends inside its data")
        }
        _ if gzipped(path) => {
            IoError::format(path, Position::File, format!("corrupt gzip data: {e}"))
        }
        _ => IoError::os(path, e),
    }
}

/// Reads a single-file NIfTI header from `stream`, up to the first value: where the values
/// are and how to read them, or `None` for what [`placement`] does not cover.
pub(super) fn read_head(path: &Path, stream: &mut impl Read) -> Result<Option<Placement>, IoError> {
    let corrupt = |e| stream_error(path, e);
    let mut head = vec![0u8; 348];
    stream.read_exact(&mut head).map_err(corrupt)?;
    if is_nifti2([head[0], head[1], head[2], head[3]]) {
        return Ok(None);
    }
    let vox_offset = f32::from_le_bytes([head[108], head[109], head[110], head[111]]);
    let swapped = f32::from_be_bytes([head[108], head[109], head[110], head[111]]);
    // The header's byte order is not known yet: take the offset that makes sense.
    let offset = [vox_offset, swapped]
        .into_iter()
        .find(|o| o.is_finite() && (352.0..=(1u32 << 24) as f32).contains(o))
        .unwrap_or(352.0) as usize;
    head.resize(offset, 0);
    stream.read_exact(&mut head[348..]).map_err(corrupt)?;
    // The stream's length is not known: a short one fails later, when its data run out.
    Ok(placement_within(path, &head, u64::MAX)?.filter(|p| p.offset == offset))
}

/// Spacing and orientation from the index-to-world map.
fn world(path: &Path, header: &NiftiHeader) -> Result<([f64; 3], Orientation), IoError> {
    let (linear, _) = Geometry::of(header).index_to_world();
    Orientation::from_linear(linear).ok_or_else(|| {
        IoError::format(
            path,
            Position::Field(
                if header.sform_code > 0 {
                    "srow"
                } else {
                    "pixdim"
                }
                .into(),
            ),
            "the index-to-world map is singular or not finite",
        )
    })
}

/// The grid and orientation of a NIfTI object the checks above let through: its one 3-d
/// volume, or the one `pick` chooses of a 4-d or 5-d file.
fn finish(
    path: &Path,
    object: InMemNiftiObject,
    pick: Pick,
) -> Result<(Grid, Orientation), IoError> {
    let fail = |reason: String| IoError::format(path, Position::File, reason);
    let header = object.header().clone();
    let dim = header.dim;
    let rank = usize::from(dim[0]);
    if !(1..=7).contains(&rank) {
        return Err(IoError::format(
            path,
            Position::Field("dim".into()),
            format!("dim[0] = {rank}: the rank must be 1 to 7"),
        ));
    }
    let extra: Vec<u64> = (4..=rank).map(|a| u64::from(dim[a].max(1))).collect();
    let index = volume_index(path, &extra, pick)?;
    let dims: [usize; 3] = std::array::from_fn(|a| {
        if a < rank {
            usize::from(dim[a + 1]).max(1)
        } else {
            1
        }
    });
    let array = object
        .into_volume()
        .into_ndarray::<f32>()
        .map_err(|e| fail(format!("cannot decode the voxels: {e}")))?;
    // The array's axes are the file's (x fastest on disk); walking the transposed view visits
    // the volumes in turn (frames fastest, then channels), each k, then j, then i, whatever the
    // memory order.
    let count = dims[0] * dims[1] * dims[2];
    let volume: Vec<f32> = array
        .t()
        .iter()
        .skip(index as usize * count)
        .take(count)
        .copied()
        .collect();
    let values: Vec<f32> = volume;
    let geometry = Geometry::of(&header);
    let origin = geometry.index_to_world().1;
    let (spacing, orientation) = world(path, &header)?;
    let grid = Grid::new(dims, values)
        .and_then(|g| g.with_spacing(spacing))
        .and_then(|g| g.with_origin(origin))
        .map_err(|e| IoError::grid(path, e))?;
    Ok((grid, orientation))
}

/// The scalar type of a NIfTI `datatype` code (both versions share them), for the types isocube
/// reads.
fn scalar_of(datatype: i16) -> Option<ScalarType> {
    Some(match datatype {
        2 => ScalarType::U8,
        256 => ScalarType::I8,
        4 => ScalarType::I16,
        512 => ScalarType::U16,
        8 => ScalarType::I32,
        768 => ScalarType::U32,
        1024 => ScalarType::I64,
        1280 => ScalarType::U64,
        16 => ScalarType::F32,
        64 => ScalarType::F64,
        _ => return None,
    })
}

/// A header's geometry fields (NIfTI-1's in `f32`, NIfTI-2's in `f64`).
struct Geometry {
    sform_code: i32,
    qform_code: i32,
    srow: [[f64; 4]; 3],
    quatern: [f64; 3],
    qoffset: [f64; 3],
    pixdim: [f64; 8],
}

impl Geometry {
    fn of(h: &NiftiHeader) -> Geometry {
        let f = f64::from;
        Geometry {
            sform_code: i32::from(h.sform_code),
            qform_code: i32::from(h.qform_code),
            srow: [h.srow_x, h.srow_y, h.srow_z].map(|r| r.map(f)),
            quatern: [f(h.quatern_b), f(h.quatern_c), f(h.quatern_d)],
            qoffset: [f(h.quatern_x), f(h.quatern_y), f(h.quatern_z)],
            pixdim: h.pixdim.map(f),
        }
    }

    /// The index-to-world map: rows of its 3 × 3 part, and its translation.
    fn index_to_world(&self) -> ([[f64; 3]; 3], [f64; 3]) {
        if self.sform_code > 0 {
            return (
                self.srow.map(|r| [r[0], r[1], r[2]]),
                self.srow.map(|r| r[3]),
            );
        }
        let pixdim = self.pixdim;
        if self.qform_code > 0 {
            let [b, c, d] = self.quatern;
            let a = (1.0 - b * b - c * c - d * d).max(0.0).sqrt();
            let r = [
                [
                    a * a + b * b - c * c - d * d,
                    2.0 * (b * c - a * d),
                    2.0 * (b * d + a * c),
                ],
                [
                    2.0 * (b * c + a * d),
                    a * a + c * c - b * b - d * d,
                    2.0 * (c * d - a * b),
                ],
                [
                    2.0 * (b * d - a * c),
                    2.0 * (c * d + a * b),
                    a * a + d * d - b * b - c * c,
                ],
            ];
            let qfac = if pixdim[0] < 0.0 { -1.0 } else { 1.0 };
            let scale = [pixdim[1], pixdim[2], qfac * pixdim[3]];
            return (
                r.map(|row| std::array::from_fn(|col| row[col] * scale[col])),
                self.qoffset,
            );
        }
        // Voxel sizes alone; a size left at zero (as some writers do) counts as 1.
        let size = |x: f64| {
            if x.is_finite() && x != 0.0 {
                x.abs()
            } else {
                1.0
            }
        };
        (
            [
                [size(pixdim[1]), 0.0, 0.0],
                [0.0, size(pixdim[2]), 0.0],
                [0.0, 0.0, size(pixdim[3])],
            ],
            [0.0; 3],
        )
    }
}
