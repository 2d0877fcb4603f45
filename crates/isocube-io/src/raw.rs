//! Raw binary volumes and the scalar decoding shared by the other volume readers.

use std::fmt;
use std::path::Path;
use std::str::FromStr;

use super::{read_file, Budget, IoError, Position};
use isocube::field::Grid;

/// Scalar type of stored values.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ScalarType {
    /// Unsigned 8-bit.
    U8,
    /// Signed 8-bit.
    I8,
    /// Unsigned 16-bit.
    U16,
    /// Signed 16-bit.
    I16,
    /// Unsigned 32-bit.
    U32,
    /// Signed 32-bit.
    I32,
    /// Unsigned 64-bit.
    U64,
    /// Signed 64-bit.
    I64,
    /// 32-bit float.
    F32,
    /// 64-bit float.
    F64,
}

impl ScalarType {
    /// Bytes per value.
    pub fn size(self) -> usize {
        match self {
            ScalarType::U8 | ScalarType::I8 => 1,
            ScalarType::U16 | ScalarType::I16 => 2,
            ScalarType::U32 | ScalarType::I32 | ScalarType::F32 => 4,
            ScalarType::U64 | ScalarType::I64 | ScalarType::F64 => 8,
        }
    }

    /// The name used on the command line.
    pub fn name(self) -> &'static str {
        match self {
            ScalarType::U8 => "u8",
            ScalarType::I8 => "i8",
            ScalarType::U16 => "u16",
            ScalarType::I16 => "i16",
            ScalarType::U32 => "u32",
            ScalarType::I32 => "i32",
            ScalarType::U64 => "u64",
            ScalarType::I64 => "i64",
            ScalarType::F32 => "f32",
            ScalarType::F64 => "f64",
        }
    }

    /// Decodes one value from exactly `size()` bytes.
    #[inline]
    pub fn decode(self, b: &[u8], endian: Endian) -> f64 {
        macro_rules! get {
            ($t:ty) => {{
                let a: [u8; std::mem::size_of::<$t>()] = b.try_into().expect("value width");
                match endian {
                    Endian::Little => <$t>::from_le_bytes(a),
                    Endian::Big => <$t>::from_be_bytes(a),
                }
            }};
        }
        match self {
            ScalarType::U8 => f64::from(b[0]),
            ScalarType::I8 => f64::from(b[0] as i8),
            ScalarType::U16 => f64::from(get!(u16)),
            ScalarType::I16 => f64::from(get!(i16)),
            ScalarType::U32 => f64::from(get!(u32)),
            ScalarType::I32 => f64::from(get!(i32)),
            ScalarType::U64 => get!(u64) as f64,
            ScalarType::I64 => get!(i64) as f64,
            ScalarType::F32 => f64::from(get!(f32)),
            ScalarType::F64 => get!(f64),
        }
    }

    /// Parses a decimal number written in a text encoding into this type's range.
    pub fn parse_text(self, s: &str) -> Option<f64> {
        let v: f64 = s.parse().ok()?;
        match self {
            ScalarType::F32 | ScalarType::F64 => Some(v),
            _ if v.fract() != 0.0 => None,
            _ => Some(v),
        }
    }
}

impl fmt::Display for ScalarType {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for ScalarType {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Ok(match s {
            "u8" => ScalarType::U8,
            "i8" => ScalarType::I8,
            "u16" => ScalarType::U16,
            "i16" => ScalarType::I16,
            "u32" => ScalarType::U32,
            "i32" => ScalarType::I32,
            "u64" => ScalarType::U64,
            "i64" => ScalarType::I64,
            "f32" => ScalarType::F32,
            "f64" => ScalarType::F64,
            _ => {
                return Err(format!(
                    "unknown type '{s}': expected u8, i8, u16, i16, u32, i32, u64, i64, f32 or f64"
                ))
            }
        })
    }
}

/// Byte order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum Endian {
    /// Least significant byte first.
    #[default]
    Little,
    /// Most significant byte first.
    Big,
}

impl Endian {
    /// Whether values in this order can be read as they lie on this machine.
    pub(crate) fn is_native(self) -> bool {
        match self {
            Endian::Little => cfg!(target_endian = "little"),
            Endian::Big => cfg!(target_endian = "big"),
        }
    }
}

impl FromStr for Endian {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "little" | "le" => Ok(Endian::Little),
            "big" | "be" => Ok(Endian::Big),
            _ => Err(format!("unknown byte order '{s}': expected little or big")),
        }
    }
}

/// Layout of a raw volume file: `dims[0] × dims[1] × dims[2]` values, `x` fastest, no header
/// (or `header_bytes` skipped).
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub struct RawOptions {
    /// Points along x, y, z.
    pub dims: [usize; 3],
    /// Stored type.
    pub scalar: ScalarType,
    /// Byte order.
    pub endian: Endian,
    /// Bytes to skip before the data.
    pub header_bytes: u64,
    /// Spacing.
    pub spacing: [f64; 3],
    /// Origin.
    pub origin: [f64; 3],
}

impl RawOptions {
    /// Little-endian, no header, unit spacing, zero origin.
    pub fn new(dims: [usize; 3], scalar: ScalarType) -> RawOptions {
        RawOptions {
            dims,
            scalar,
            endian: Endian::Little,
            header_bytes: 0,
            spacing: [1.0; 3],
            origin: [0.0; 3],
        }
    }
}

/// Reads a raw volume. The file must hold exactly `header_bytes + product(dims) × size` bytes.
pub fn read_raw(path: &Path, options: &RawOptions) -> Result<Grid, IoError> {
    read_raw_within(path, options, Budget::UNLIMITED)
}

pub(super) fn read_raw_within(
    path: &Path,
    options: &RawOptions,
    budget: Budget,
) -> Result<Grid, IoError> {
    let count = Grid::point_count(options.dims).map_err(|e| IoError::grid(path, e))?;
    let len = std::fs::metadata(path)
        .map_err(|e| IoError::os(path, e))?
        .len();
    check_raw_size(path, options, count, len)?;
    budget.check_values(path, Position::File, len, count)?;
    read_raw_bytes(path, &read_file(path)?, options, budget)
}

/// [`read_raw_within`] on a file's bytes already in memory (`path` names it in errors).
pub(super) fn read_raw_bytes(
    path: &Path,
    bytes: &[u8],
    options: &RawOptions,
    budget: Budget,
) -> Result<Grid, IoError> {
    let count = Grid::point_count(options.dims).map_err(|e| IoError::grid(path, e))?;
    check_raw_size(path, options, count, bytes.len() as u64)?;
    budget.check_values(path, Position::File, bytes.len() as u64, count)?;
    let values = decode_all(
        &bytes[options.header_bytes as usize..],
        options.scalar,
        options.endian,
    );
    Grid::new(options.dims, values)
        .and_then(|g| g.with_spacing(options.spacing))
        .and_then(|g| g.with_origin(options.origin))
        .map_err(|e| IoError::grid(path, e))
}

/// Checks that a raw file of `len` bytes holds exactly the header and `count` values.
pub(super) fn check_raw_size(
    path: &Path,
    options: &RawOptions,
    count: usize,
    len: u64,
) -> Result<(), IoError> {
    let need = (count as u64)
        .checked_mul(options.scalar.size() as u64)
        .and_then(|n| n.checked_add(options.header_bytes))
        .ok_or_else(|| IoError::format(path, Position::File, "dimensions overflow"))?;
    if len == need {
        return Ok(());
    }
    Err(IoError::format(
        path,
        Position::File,
        format!(
            "{:?} {} values need {need} bytes{}, the file has {len}",
            options.dims,
            options.scalar,
            if options.header_bytes > 0 {
                format!(" (with {} header bytes)", options.header_bytes)
            } else {
                String::new()
            },
        ),
    ))
}

/// Decodes consecutive values (the slice length must be a multiple of the type size).
pub(crate) fn decode_all(bytes: &[u8], scalar: ScalarType, endian: Endian) -> Vec<f32> {
    let mut out = vec![0.0f32; bytes.len() / scalar.size()];
    decode_into(bytes, scalar, endian, &mut out);
    out
}

/// Decodes `out.len()` consecutive values into `out`, exactly as [`ScalarType::decode`]
/// rounded to `f32` (through `f64`, so 64-bit integers round once in the same way), with the
/// type resolved once rather than per value.
pub(crate) fn decode_into(bytes: &[u8], scalar: ScalarType, endian: Endian, out: &mut [f32]) {
    macro_rules! run {
        ($t:ty) => {{
            const N: usize = std::mem::size_of::<$t>();
            let chunks = bytes.chunks_exact(N);
            match endian {
                Endian::Little => {
                    for (o, b) in out.iter_mut().zip(chunks) {
                        *o = <$t>::from_le_bytes(b.try_into().expect("value width")) as f64 as f32;
                    }
                }
                Endian::Big => {
                    for (o, b) in out.iter_mut().zip(chunks) {
                        *o = <$t>::from_be_bytes(b.try_into().expect("value width")) as f64 as f32;
                    }
                }
            }
        }};
    }
    match scalar {
        ScalarType::U8 => run!(u8),
        ScalarType::I8 => run!(i8),
        ScalarType::U16 => run!(u16),
        ScalarType::I16 => run!(i16),
        ScalarType::U32 => run!(u32),
        ScalarType::I32 => run!(i32),
        ScalarType::U64 => run!(u64),
        ScalarType::I64 => run!(i64),
        ScalarType::F32 => run!(f32),
        ScalarType::F64 => run!(f64),
    }
}
