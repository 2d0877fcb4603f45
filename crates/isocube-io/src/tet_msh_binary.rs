//! Gmsh MSH 4.1 binary (`4.1 1 8`): the nodes and the 4-node tetrahedra, read with every count
//! checked against the bytes left before anything is reserved.

use std::collections::HashMap;
use std::path::Path;

use super::tet_read::Parsed;
use super::{IoError, Position};

/// How a binary MSH 4.1 file with 8-byte numbers starts.
pub(super) const HEADER: &[u8] = b"$MeshFormat\n4.1 1 8\n";

/// Nodes per element of Gmsh's element types 1 to 19.
const NODES: [usize; 19] = [
    2, 3, 4, 4, 8, 6, 5, 3, 6, 9, 10, 27, 18, 14, 1, 8, 20, 15, 13,
];

struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
    name: &'a Path,
    /// The file was written big-endian (its `int` 1 reads as 1 << 24).
    swap: bool,
}

impl<'a> Reader<'a> {
    fn error(&self, reason: impl Into<String>) -> IoError {
        IoError::format(self.name, Position::Byte(self.at as u64), reason)
    }

    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8], IoError> {
        let end = self
            .at
            .checked_add(n)
            .filter(|&e| e <= self.bytes.len())
            .ok_or_else(|| self.error(format!("the file ends inside {what}")))?;
        let out = &self.bytes[self.at..end];
        self.at = end;
        Ok(out)
    }

    fn array<const N: usize>(&mut self, what: &str) -> Result<[u8; N], IoError> {
        let mut b: [u8; N] = self.take(N, what)?.try_into().expect("N bytes taken");
        if self.swap {
            b.reverse();
        }
        Ok(b)
    }

    fn int(&mut self, what: &str) -> Result<i32, IoError> {
        Ok(i32::from_le_bytes(self.array(what)?))
    }

    fn size(&mut self, what: &str) -> Result<u64, IoError> {
        Ok(u64::from_le_bytes(self.array(what)?))
    }

    fn double(&mut self, what: &str) -> Result<f64, IoError> {
        Ok(f64::from_le_bytes(self.array(what)?))
    }

    /// A count of items of at least `min_bytes` each, which the bytes left must hold.
    fn count(&mut self, what: &str, min_bytes: usize) -> Result<usize, IoError> {
        let n = self.size(what)?;
        let left = (self.bytes.len() - self.at) as u64;
        if n.saturating_mul(min_bytes as u64) > left {
            return Err(self.error(format!(
                "{what} {n}: more than the {left} bytes left can hold"
            )));
        }
        Ok(n as usize)
    }

    fn expect(&mut self, text: &str) -> Result<(), IoError> {
        if self.bytes[self.at..].starts_with(text.as_bytes()) {
            self.at += text.len();
            Ok(())
        } else {
            Err(self.error(format!("expected {:?}", text.trim())))
        }
    }

    /// The next line's text (without its newline), for section names and ASCII sections.
    fn line(&mut self) -> Result<&'a str, IoError> {
        let rest = &self.bytes[self.at..];
        let len = rest
            .iter()
            .position(|&b| b == b'\n')
            .ok_or_else(|| self.error("the file ends inside a line"))?;
        let line = std::str::from_utf8(&rest[..len])
            .map_err(|_| self.error("a section line that is not text"))?;
        self.at += len + 1;
        Ok(line.trim_end_matches('\r'))
    }

    /// Skips the entity records of `$Entities`.
    fn entities(&mut self) -> Result<(), IoError> {
        let counts = [
            self.count("point count", 32)?,
            self.count("curve count", 64)?,
            self.count("surface count", 64)?,
            self.count("volume count", 64)?,
        ];
        for (dim, &count) in counts.iter().enumerate() {
            for _ in 0..count {
                self.int("entity tag")?;
                let coordinates = if dim == 0 { 3 } else { 6 };
                self.take(8 * coordinates, "entity bounds")?;
                let physicals = self.count("physical tag count", 4)?;
                self.take(4 * physicals, "physical tags")?;
                if dim > 0 {
                    let bounding = self.count("bounding entity count", 4)?;
                    self.take(4 * bounding, "bounding entities")?;
                }
            }
        }
        Ok(())
    }
}

/// Gmsh MSH 4.1 binary with 8-byte numbers: `$Nodes` and the type-4 blocks of `$Elements`;
/// `$PhysicalNames` and `$Entities` skipped, other sections refused.
pub(super) fn msh_binary(bytes: &[u8], name: &Path) -> Result<Parsed, IoError> {
    let mut r = Reader {
        bytes,
        at: HEADER.len(),
        name,
        swap: false,
    };
    match r.int("the byte-order check")? {
        1 => {}
        0x0100_0000 => r.swap = true,
        x => return Err(r.error(format!("byte-order check {x}, not 1"))),
    }
    r.expect("\n$EndMeshFormat\n")?;
    let mut positions: Vec<[f32; 3]> = Vec::new();
    let mut index: HashMap<u64, u32> = HashMap::new();
    let mut raw: Vec<[u64; 4]> = Vec::new();
    while r.at < bytes.len() {
        match r.line()? {
            "" => {}
            "$PhysicalNames" => {
                // Text: a count, then one line per group.
                let count: usize = r
                    .line()?
                    .trim()
                    .parse()
                    .map_err(|_| r.error("physical name count is not a number"))?;
                if count > bytes.len() - r.at {
                    return Err(
                        r.error(format!("{count} physical names: more than the file holds"))
                    );
                }
                for _ in 0..count {
                    r.line()?;
                }
                r.expect("$EndPhysicalNames\n")?;
            }
            "$Entities" => {
                r.entities()?;
                r.expect("\n$EndEntities\n")?;
            }
            "$Nodes" => {
                let blocks = r.count("node block count", 20)?;
                let total = r.count("node count", 32)?;
                r.size("node tag")?;
                r.size("node tag")?;
                positions.reserve(total);
                for _ in 0..blocks {
                    r.int("entity dimension")?;
                    r.int("entity tag")?;
                    if r.int("parametric flag")? != 0 {
                        return Err(IoError::unsupported(
                            name,
                            Position::Byte(r.at as u64),
                            "parametric node coordinates",
                        ));
                    }
                    let count = r.count("nodes in block", 32)?;
                    let first = positions.len();
                    for k in 0..count {
                        let tag = r.size("node tag")?;
                        let v = u32::try_from(first + k)
                            .map_err(|_| r.error("too many nodes for 32-bit numbers"))?;
                        if index.insert(tag, v).is_some() {
                            return Err(r.error(format!("node {tag} appears twice")));
                        }
                    }
                    for _ in 0..count {
                        let mut p = [0f32; 3];
                        for c in &mut p {
                            let x = r.double("a coordinate")?;
                            if !x.is_finite() || x.abs() > f64::from(f32::MAX) {
                                return Err(r.error(format!("coordinate {x} is not a finite f32")));
                            }
                            *c = x as f32;
                        }
                        positions.push(p);
                    }
                }
                if positions.len() != total {
                    return Err(r.error(format!(
                        "{} nodes in the blocks, {total} announced",
                        positions.len()
                    )));
                }
                r.expect("\n$EndNodes\n")?;
            }
            "$Elements" => {
                let blocks = r.count("element block count", 20)?;
                r.size("element count")?;
                r.size("element tag")?;
                r.size("element tag")?;
                for _ in 0..blocks {
                    r.int("entity dimension")?;
                    r.int("entity tag")?;
                    let kind = r.int("element type")?;
                    let nodes = match kind {
                        1..=19 => NODES[kind as usize - 1],
                        _ => {
                            return Err(IoError::unsupported(
                                name,
                                Position::Byte(r.at as u64),
                                format!("element type {kind}"),
                            ))
                        }
                    };
                    let count = r.count("elements in block", 8 * (1 + nodes))?;
                    if kind == 4 {
                        raw.reserve(count);
                    }
                    for _ in 0..count {
                        r.size("element tag")?;
                        let mut corner = [0u64; 4];
                        for k in 0..nodes {
                            let tag = r.size("node tag")?;
                            if let Some(c) = corner.get_mut(k).filter(|_| kind == 4) {
                                *c = tag;
                            }
                        }
                        if kind == 4 {
                            raw.push(corner);
                        }
                    }
                }
                r.expect("\n$EndElements\n")?;
            }
            other => {
                return Err(IoError::unsupported(
                    name,
                    Position::Byte(r.at as u64),
                    format!("section {other:?} in binary MSH (nodes and elements are read)"),
                ))
            }
        }
    }
    let n = positions.len();
    let mut tets = Vec::with_capacity(raw.len());
    for t in raw {
        let mut out = [0u32; 4];
        for (o, tag) in out.iter_mut().zip(t) {
            *o = *index
                .get(&tag)
                .ok_or_else(|| r.error(format!("element node {tag} is not a node")))?;
            debug_assert!((*o as usize) < n);
        }
        tets.push(out);
    }
    Ok((positions, tets))
}
