//! NetCDF classic files (CDF-1, and CDF-2 with 64-bit offsets), the container of MINC-1: a
//! header of dimensions, attributes and variables, then each variable's values, big-endian, at
//! the offset its header gives (record variables interleaved along the unlimited dimension).
//! Every count and offset is checked against the file before use.

use std::path::Path;

use super::{Attr, Container, Stored, Variable};
use crate::{IoError, Position};

/// The external types (NetCDF classic's `nc_type`).
#[derive(Clone, Copy, Debug, PartialEq)]
enum NcType {
    Byte,
    Char,
    Short,
    Int,
    Float,
    Double,
}

impl NcType {
    fn of(code: u32) -> Option<NcType> {
        Some(match code {
            1 => NcType::Byte,
            2 => NcType::Char,
            3 => NcType::Short,
            4 => NcType::Int,
            5 => NcType::Float,
            6 => NcType::Double,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            NcType::Byte | NcType::Char => 1,
            NcType::Short => 2,
            NcType::Int | NcType::Float => 4,
            NcType::Double => 8,
        }
    }

    /// Big-endian value `b` (of `self.size()` bytes), unsigned where `unsigned` says.
    fn decode(self, b: &[u8], unsigned: bool) -> f64 {
        match (self, unsigned) {
            (NcType::Byte | NcType::Char, false) => f64::from(b[0] as i8),
            (NcType::Byte | NcType::Char, true) => f64::from(b[0]),
            (NcType::Short, false) => f64::from(i16::from_be_bytes([b[0], b[1]])),
            (NcType::Short, true) => f64::from(u16::from_be_bytes([b[0], b[1]])),
            (NcType::Int, false) => f64::from(i32::from_be_bytes([b[0], b[1], b[2], b[3]])),
            (NcType::Int, true) => f64::from(u32::from_be_bytes([b[0], b[1], b[2], b[3]])),
            (NcType::Float, _) => f64::from(f32::from_be_bytes([b[0], b[1], b[2], b[3]])),
            (NcType::Double, _) => f64::from_be_bytes(b[..8].try_into().unwrap_or([0; 8])),
        }
    }
}

struct NcVariable {
    name: String,
    dims: Vec<usize>,
    attrs: Vec<(String, Attr)>,
    nc_type: NcType,
    /// Bytes of one record (record variables) or of the whole variable, as the header says.
    vsize: u64,
    begin: u64,
}

/// A parsed NetCDF classic file, its bytes borrowed.
pub(crate) struct NetCdf<'a> {
    path: &'a Path,
    bytes: &'a [u8],
    dims: Vec<(String, usize)>,
    /// The unlimited (record) dimension's index, if any.
    record_dim: Option<usize>,
    records: u64,
    variables: Vec<NcVariable>,
}

/// A cursor over the header.
struct Header<'a> {
    path: &'a Path,
    bytes: &'a [u8],
    at: usize,
}

impl Header<'_> {
    fn fail(&self, reason: impl Into<String>) -> IoError {
        IoError::format(self.path, Position::Byte(self.at as u64), reason)
    }

    fn take(&mut self, n: usize) -> Result<&[u8], IoError> {
        let end = self
            .at
            .checked_add(n)
            .filter(|&e| e <= self.bytes.len())
            .ok_or_else(|| self.fail("the file ends inside its header"))?;
        let out = &self.bytes[self.at..end];
        self.at = end;
        Ok(out)
    }

    fn u32(&mut self) -> Result<u32, IoError> {
        let b = self.take(4)?;
        Ok(u32::from_be_bytes([b[0], b[1], b[2], b[3]]))
    }

    fn u64(&mut self) -> Result<u64, IoError> {
        let b = self.take(8)?;
        Ok(u64::from_be_bytes(b.try_into().unwrap_or([0; 8])))
    }

    /// A count of items of at least `min_bytes` each: no more than the rest of the file holds.
    fn count(&mut self, min_bytes: usize) -> Result<usize, IoError> {
        let n = self.u32()? as usize;
        if n.saturating_mul(min_bytes) > self.bytes.len() - self.at {
            return Err(self.fail(format!("a count of {n} entries the file cannot hold")));
        }
        Ok(n)
    }

    /// `n` bytes and the padding to a multiple of 4.
    fn padded(&mut self, n: usize) -> Result<&[u8], IoError> {
        let start = self.at;
        self.take(n.div_ceil(4).saturating_mul(4))?;
        Ok(&self.bytes[start..start + n])
    }

    fn name(&mut self) -> Result<String, IoError> {
        let n = self.count(1)?;
        let raw = self.padded(n)?;
        Ok(String::from_utf8_lossy(raw).into_owned())
    }

    /// A list's tag: absent (both words zero) or `tag` with its count.
    fn list(&mut self, tag: u32, min_bytes: usize) -> Result<usize, IoError> {
        let found = self.u32()?;
        match found {
            0 => match self.u32()? {
                0 => Ok(0),
                n => Err(self.fail(format!("an absent list with {n} entries"))),
            },
            t if t == tag => self.count(min_bytes),
            t => Err(self.fail(format!("list tag {t:#x} where {tag:#x} belongs"))),
        }
    }

    fn attributes(&mut self) -> Result<Vec<(String, Attr)>, IoError> {
        let n = self.list(0x0C, 12)?;
        let mut attrs = Vec::new();
        for _ in 0..n {
            let name = self.name()?;
            let code = self.u32()?;
            let nc_type =
                NcType::of(code).ok_or_else(|| self.fail(format!("attribute type {code}")))?;
            let count = self.count(0)?;
            let raw = self.padded(count.saturating_mul(nc_type.size()))?;
            let value = if nc_type == NcType::Char {
                Attr::Text(String::from_utf8_lossy(raw).into_owned())
            } else {
                Attr::Numbers(
                    raw.chunks_exact(nc_type.size())
                        .map(|b| nc_type.decode(b, false))
                        .collect(),
                )
            };
            attrs.push((name, value));
        }
        Ok(attrs)
    }
}

impl<'a> NetCdf<'a> {
    /// Parses the header of a NetCDF classic file.
    pub(crate) fn parse(path: &'a Path, bytes: &'a [u8]) -> Result<NetCdf<'a>, IoError> {
        let version = match bytes.get(..4) {
            Some([b'C', b'D', b'F', v @ (1 | 2)]) => *v,
            Some([b'C', b'D', b'F', 5]) => {
                return Err(IoError::unsupported(
                    path,
                    Position::Byte(3),
                    "NetCDF CDF-5 (64-bit data) is not MINC-1 and is not read",
                ))
            }
            _ => {
                return Err(IoError::format(
                    path,
                    Position::File,
                    "not a MINC file: neither NetCDF classic (MINC-1, `CDF`) nor HDF5 (MINC-2)",
                ))
            }
        };
        let mut h = Header { path, bytes, at: 4 };
        let records = u64::from(h.u32()?);
        let n = h.list(0x0A, 8)?;
        let mut dims = Vec::new();
        let mut record_dim = None;
        for d in 0..n {
            let name = h.name()?;
            let len = h.u32()? as usize;
            if len == 0 {
                if record_dim.is_some() {
                    return Err(h.fail("two unlimited dimensions"));
                }
                record_dim = Some(d);
            }
            dims.push((name, len));
        }
        // Streaming files (numrecs all ones) have no record count to trust.
        if records == u64::from(u32::MAX) {
            return Err(h.fail("a streaming NetCDF file (no record count)"));
        }
        h.attributes()?;
        let n = h.list(0x0B, 24)?;
        let mut variables = Vec::new();
        for _ in 0..n {
            let name = h.name()?;
            let rank = h.count(4)?;
            let mut var_dims = Vec::new();
            for _ in 0..rank {
                let d = h.u32()? as usize;
                if d >= dims.len() {
                    return Err(h.fail(format!("variable `{name}` names dimension {d}")));
                }
                var_dims.push(d);
            }
            if var_dims.iter().skip(1).any(|&d| Some(d) == record_dim) {
                return Err(h.fail(format!(
                    "variable `{name}` has the unlimited dimension after its first"
                )));
            }
            let attrs = h.attributes()?;
            let code = h.u32()?;
            let nc_type = NcType::of(code)
                .ok_or_else(|| h.fail(format!("variable `{name}` of type {code}")))?;
            let vsize = u64::from(h.u32()?);
            let begin = if version == 1 {
                u64::from(h.u32()?)
            } else {
                h.u64()?
            };
            variables.push(NcVariable {
                name,
                dims: var_dims,
                attrs,
                nc_type,
                vsize,
                begin,
            });
        }
        Ok(NetCdf {
            path,
            bytes,
            dims,
            record_dim,
            records,
            variables,
        })
    }

    fn find(&self, name: &str) -> Option<&NcVariable> {
        self.variables.iter().find(|v| v.name == name)
    }

    fn is_record(&self, v: &NcVariable) -> bool {
        v.dims.first().is_some_and(|&d| Some(d) == self.record_dim)
    }

    /// The length of dimension `d` (the record count for the unlimited one).
    fn len(&self, d: usize) -> usize {
        if Some(d) == self.record_dim {
            usize::try_from(self.records).unwrap_or(usize::MAX)
        } else {
            self.dims[d].1
        }
    }

    /// Bytes from one record to the next: the record variables' sizes, except that a lone
    /// record variable of bytes or shorts is not padded.
    fn record_size(&self) -> u64 {
        let record: Vec<&NcVariable> = self
            .variables
            .iter()
            .filter(|v| self.is_record(v))
            .collect();
        match record[..] {
            [v] if v.nc_type.size() < 4 => {
                let per = v.dims[1..]
                    .iter()
                    .fold(1u64, |n, &d| n.saturating_mul(self.len(d) as u64));
                per.saturating_mul(v.nc_type.size() as u64)
            }
            _ => record
                .iter()
                .map(|v| v.vsize)
                .fold(0u64, u64::saturating_add),
        }
    }
}

impl Container for NetCdf<'_> {
    fn variable(&self, name: &str) -> Result<Option<Variable>, IoError> {
        let Some(v) = self.find(name) else {
            return Ok(None);
        };
        let signtype = v.attrs.iter().find_map(|(n, a)| match (n.as_str(), a) {
            ("signtype", Attr::Text(t)) => Some(t.trim_end_matches('\0').trim().to_string()),
            _ => None,
        });
        // MINC-1: bytes are unsigned unless said otherwise, other integers signed.
        let signed = match signtype.as_deref() {
            Some("signed__") => true,
            Some("unsigned") => false,
            _ => v.nc_type != NcType::Byte,
        };
        let stored = match v.nc_type {
            NcType::Float | NcType::Double => Stored::Float,
            t => Stored::Int {
                bits: 8 * t.size() as u32,
                signed,
            },
        };
        Ok(Some(Variable {
            dims: v
                .dims
                .iter()
                .map(|&d| (self.dims[d].0.clone(), self.len(d)))
                .collect(),
            attrs: v.attrs.clone(),
            stored,
        }))
    }

    fn values(&self, name: &str, variable: &Variable) -> Result<Vec<f64>, IoError> {
        let v = self
            .find(name)
            .ok_or_else(|| IoError::format(self.path, Position::Field(name.into()), "missing"))?;
        let unsigned = matches!(variable.stored, Stored::Int { signed: false, .. });
        let size = v.nc_type.size() as u64;
        let fail = |at: u64| {
            IoError::format(
                self.path,
                Position::Byte(at),
                format!("the file ends inside variable `{name}`"),
            )
        };
        // Contiguous parts: the whole variable, or one per record.
        let per: u64 = v
            .dims
            .iter()
            .skip(usize::from(self.is_record(v)))
            .map(|&d| self.len(d) as u64)
            .fold(1u64, u64::saturating_mul);
        let part = per.saturating_mul(size);
        let (parts, step) = if self.is_record(v) {
            (self.records, self.record_size())
        } else {
            (1, 0)
        };
        let mut out = Vec::new();
        if part == 0 {
            return Ok(out);
        }
        if parts > 1 && step < part {
            // Records that overlap would let a small file claim any number of values.
            return Err(IoError::format(
                self.path,
                Position::Field(name.into()),
                format!("records of {step} bytes hold `{name}`'s {part} bytes each"),
            ));
        }
        for r in 0..parts {
            // Each part is checked to lie in the file before the next: a record count the
            // file cannot hold ends at its first missing record.
            let start = v.begin.saturating_add(r.saturating_mul(step));
            let end = start.saturating_add(part);
            let (Ok(s), Ok(e)) = (usize::try_from(start), usize::try_from(end)) else {
                return Err(fail(start));
            };
            let bytes = self.bytes.get(s..e).ok_or_else(|| fail(start))?;
            out.extend(
                bytes
                    .chunks_exact(size as usize)
                    .map(|b| v.nc_type.decode(b, unsigned)),
            );
        }
        Ok(out)
    }
}
