//! Reading tetrahedral meshes back: Gmsh MSH 4.1 (ASCII and binary), VTK `.vtu` (uncompressed), MEDIT
//! `.mesh` (ASCII) and Abaqus `.inp` — what `isocube tetmesh` writes, and what other meshers
//! write in those formats. Only the vertices and the 4-node tetrahedra are kept; other
//! elements are skipped.

use std::path::Path;

use isocube::volume::TetMesh;

use super::{IoError, Position};

/// Reads the tetrahedra of a `.msh`, `.vtu`, `.mesh` or `.inp` file.
///
/// ```no_run
/// let mesh = isocube_io::read_tet_mesh("sphere.msh".as_ref()).unwrap();
/// println!("{} tetrahedra", mesh.tets.len());
/// ```
pub fn read_tet_mesh(path: &Path) -> Result<TetMesh, IoError> {
    let bytes = std::fs::read(path).map_err(|e| IoError::os(path, e))?;
    read_tet_mesh_bytes(&bytes, path)
}

/// [`read_tet_mesh`] from bytes in memory; `name` gives the format (by extension) and names the
/// file in errors.
///
/// ```
/// let medit = b"MeshVersionFormatted 2\nDimension 3\nVertices\n4\n\
///     0 0 0 0\n1 0 0 0\n0 1 0 0\n0 0 1 0\nTetrahedra\n1\n1 2 3 4 1\nEnd\n";
/// let mesh = isocube_io::read_tet_mesh_bytes(medit, "t.mesh".as_ref()).unwrap();
/// assert_eq!((mesh.positions.len(), mesh.tets), (4, vec![[0, 1, 2, 3]]));
/// ```
pub fn read_tet_mesh_bytes(bytes: &[u8], name: &Path) -> Result<TetMesh, IoError> {
    let ext = name
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    if ext == "vtu" {
        let (positions, tets) = super::tet_vtu::vtu(bytes, name)?;
        return finish(positions, tets, name);
    }
    if ext == "msh" && bytes.starts_with(super::tet_msh_binary::HEADER) {
        let (positions, tets) = super::tet_msh_binary::msh_binary(bytes, name)?;
        return finish(positions, tets, name);
    }
    let text = std::str::from_utf8(bytes).map_err(|e| {
        IoError::unsupported(
            name,
            Position::Byte(e.valid_up_to() as u64),
            "binary content (only the ASCII forms are read)",
        )
    })?;
    let (positions, tets) = match ext.as_str() {
        "msh" => msh(text, name)?,
        "mesh" => medit(text, name)?,
        "inp" => inp(text, name)?,
        _ => {
            return Err(IoError::unsupported(
                name,
                Position::File,
                "tetrahedral mesh extension (expected .msh, .vtu, .mesh or .inp)",
            ))
        }
    };
    finish(positions, tets, name)
}

fn finish(positions: Vec<[f32; 3]>, tets: Vec<[u32; 4]>, name: &Path) -> Result<TetMesh, IoError> {
    if tets.is_empty() {
        return Err(IoError::format(name, Position::File, "no tetrahedra"));
    }
    Ok(TetMesh {
        positions,
        tets,
        ..TetMesh::default()
    })
}

/// Whitespace-separated words with their line numbers.
struct Words<'a> {
    lines: std::iter::Peekable<std::iter::Enumerate<std::str::Lines<'a>>>,
    current: std::str::SplitWhitespace<'a>,
    line: usize,
    name: &'a Path,
}

impl<'a> Words<'a> {
    fn new(text: &'a str, name: &'a Path) -> Words<'a> {
        Words {
            lines: text.lines().enumerate().peekable(),
            current: "".split_whitespace(),
            line: 0,
            name,
        }
    }

    fn next(&mut self) -> Option<&'a str> {
        loop {
            if let Some(w) = self.current.next() {
                return Some(w);
            }
            let (n, line) = self.lines.next()?;
            self.line = n + 1;
            // MEDIT comments.
            let line = line.split('#').next().unwrap_or("");
            self.current = line.split_whitespace();
        }
    }

    fn word(&mut self) -> Result<&'a str, IoError> {
        self.next()
            .ok_or_else(|| IoError::format(self.name, Position::Line(self.line), "ends early"))
    }

    fn error(&self, reason: impl Into<String>) -> IoError {
        IoError::format(self.name, Position::Line(self.line), reason)
    }

    fn number<T: std::str::FromStr>(&mut self, what: &str) -> Result<T, IoError> {
        let w = self.word()?;
        w.parse()
            .map_err(|_| self.error(format!("'{w}' is not a valid {what}")))
    }

    fn coordinate(&mut self) -> Result<f32, IoError> {
        let x: f32 = self.number("coordinate")?;
        if x.is_finite() {
            Ok(x)
        } else {
            Err(self.error("a coordinate is not finite in single precision"))
        }
    }

    /// A count of items, each at least `min_bytes` long in the text: more than the rest of the
    /// file can hold is an error before anything is allocated.
    fn count(&mut self, text_len: usize, min_bytes: usize) -> Result<usize, IoError> {
        let n: usize = self.number("count")?;
        if n.saturating_mul(min_bytes) > text_len {
            return Err(self.error(format!("a count of {n} is more than the file holds")));
        }
        Ok(n)
    }
}

/// Checks a tetrahedron's vertex numbers against the vertex count.
fn corners(words: &Words, t: [u64; 4], n: usize) -> Result<[u32; 4], IoError> {
    let mut out = [0u32; 4];
    for (o, v) in out.iter_mut().zip(t) {
        *o = u32::try_from(v)
            .ok()
            .filter(|&v| (v as usize) < n)
            .ok_or_else(|| words.error(format!("vertex {} does not exist", v + 1)))?;
    }
    Ok(out)
}

pub(super) type Parsed = (Vec<[f32; 3]>, Vec<[u32; 4]>);

/// Gmsh MSH 4.1, ASCII: `$Nodes` and the type-4 blocks of `$Elements`; other sections skipped.
fn msh(text: &str, name: &Path) -> Result<Parsed, IoError> {
    let mut w = Words::new(text, name);
    let len = text.len();
    let mut positions: Vec<[f32; 3]> = Vec::new();
    let mut index: std::collections::HashMap<u64, u32> = std::collections::HashMap::new();
    let mut raw_tets: Vec<[u64; 4]> = Vec::new();
    let mut format_seen = false;
    while let Some(section) = w.next() {
        match section {
            "$MeshFormat" => {
                let version = w.word()?;
                let file_type = w.word()?;
                let _data_size = w.word()?;
                if version != "4.1" {
                    return Err(IoError::unsupported(
                        name,
                        Position::Line(w.line),
                        format!("MSH version {version} (4.1 is read)"),
                    ));
                }
                if file_type != "0" {
                    return Err(IoError::unsupported(
                        name,
                        Position::Line(w.line),
                        "binary MSH other than `4.1 1 8` with newline line ends",
                    ));
                }
                format_seen = true;
                expect(&mut w, "$EndMeshFormat")?;
            }
            "$Nodes" => {
                let blocks = w.count(len, 8)?;
                let total = w.count(len, 8)?;
                let _min: u64 = w.number("node tag")?;
                let _max: u64 = w.number("node tag")?;
                positions.reserve(total);
                for _ in 0..blocks {
                    let _dim: u32 = w.number("entity dimension")?;
                    let _entity: i64 = w.number("entity tag")?;
                    let parametric: u32 = w.number("parametric flag")?;
                    if parametric != 0 {
                        return Err(IoError::unsupported(
                            name,
                            Position::Line(w.line),
                            "parametric node coordinates",
                        ));
                    }
                    let count = w.count(len, 8)?;
                    let first = positions.len();
                    let mut tags = Vec::with_capacity(count);
                    for _ in 0..count {
                        tags.push(w.number::<u64>("node tag")?);
                    }
                    for (k, tag) in tags.into_iter().enumerate() {
                        let v = u32::try_from(first + k)
                            .map_err(|_| w.error("too many nodes for 32-bit numbers"))?;
                        if index.insert(tag, v).is_some() {
                            return Err(w.error(format!("node {tag} appears twice")));
                        }
                    }
                    for _ in 0..count {
                        positions.push([w.coordinate()?, w.coordinate()?, w.coordinate()?]);
                    }
                }
                if positions.len() != total {
                    return Err(w.error(format!(
                        "{} nodes in the blocks, {total} announced",
                        positions.len()
                    )));
                }
                expect(&mut w, "$EndNodes")?;
            }
            "$Elements" => {
                let blocks = w.count(len, 8)?;
                let _total: u64 = w.number("element count")?;
                let _min: u64 = w.number("element tag")?;
                let _max: u64 = w.number("element tag")?;
                for _ in 0..blocks {
                    let _dim: u32 = w.number("entity dimension")?;
                    let _entity: i64 = w.number("entity tag")?;
                    let kind: u32 = w.number("element type")?;
                    let count = w.count(len, 4)?;
                    // Nodes per element of Gmsh's element types 1 to 19.
                    const NODES: [usize; 19] = [
                        2, 3, 4, 4, 8, 6, 5, 3, 6, 9, 10, 27, 18, 14, 1, 8, 20, 15, 13,
                    ];
                    let nodes = match kind {
                        1..=19 => NODES[kind as usize - 1],
                        _ => {
                            return Err(IoError::unsupported(
                                name,
                                Position::Line(w.line),
                                format!("element type {kind}"),
                            ))
                        }
                    };
                    for _ in 0..count {
                        let _tag: u64 = w.number("element tag")?;
                        let mut corner = [0u64; 4];
                        for k in 0..nodes {
                            let tag: u64 = w.number("node tag")?;
                            if let Some(c) = corner.get_mut(k).filter(|_| kind == 4) {
                                *c = tag;
                            }
                        }
                        if kind == 4 {
                            raw_tets.push(corner);
                        }
                    }
                }
                expect(&mut w, "$EndElements")?;
            }
            s if s.starts_with("$End") => {
                return Err(w.error(format!("{s} without its section")));
            }
            s if s.starts_with('$') => {
                // A section we do not need: skip to its end.
                let end = format!("$End{}", &s[1..]);
                loop {
                    if w.word()? == end {
                        break;
                    }
                }
            }
            other => return Err(w.error(format!("'{other}' outside any section"))),
        }
    }
    if !format_seen {
        return Err(IoError::format(
            name,
            Position::File,
            "no $MeshFormat section",
        ));
    }
    let n = positions.len();
    let mut tets = Vec::with_capacity(raw_tets.len());
    for t in raw_tets {
        let mut out = [0u64; 4];
        for (o, tag) in out.iter_mut().zip(t) {
            *o = u64::from(
                *index
                    .get(&tag)
                    .ok_or_else(|| w.error(format!("element node {tag} is not a node")))?,
            );
        }
        tets.push(corners(&w, out, n)?);
    }
    Ok((positions, tets))
}

fn expect(w: &mut Words, end: &str) -> Result<(), IoError> {
    let got = w.word()?;
    if got == end {
        Ok(())
    } else {
        Err(w.error(format!("expected {end}, found '{got}'")))
    }
}

/// MEDIT `.mesh`, ASCII: `Vertices` and `Tetrahedra`; the other keywords of the format skipped.
fn medit(text: &str, name: &Path) -> Result<Parsed, IoError> {
    let mut w = Words::new(text, name);
    let len = text.len();
    let mut positions = Vec::new();
    let mut raw: Vec<[u64; 4]> = Vec::new();
    while let Some(keyword) = w.next() {
        // Words per entry of the keywords that list entries.
        let per_entry = match keyword {
            "MeshVersionFormatted" | "Dimension" => {
                let value: u32 = w.number("value")?;
                if keyword == "Dimension" && value != 3 {
                    return Err(IoError::unsupported(
                        name,
                        Position::Line(w.line),
                        format!("dimension {value} (3 is read)"),
                    ));
                }
                continue;
            }
            "End" => break,
            "Vertices" => 4,
            "Tetrahedra" => 5,
            "Triangles" => 4,
            "Edges" => 3,
            "Quadrilaterals" => 5,
            "Hexahedra" => 9,
            "Prisms" => 7,
            "Pyramids" => 6,
            "Corners" | "RequiredVertices" | "Ridges" | "RequiredEdges" => 1,
            "Normals" | "Tangents" => 3,
            "NormalAtVertices" | "TangentAtVertices" => 2,
            "NormalAtTriangleVertices" | "TangentAtEdges" => 3,
            other => {
                return Err(IoError::unsupported(
                    name,
                    Position::Line(w.line),
                    format!("MEDIT keyword '{other}'"),
                ))
            }
        };
        let count = w.count(len, 2 * per_entry)?;
        match keyword {
            "Vertices" => {
                positions.reserve(count);
                for _ in 0..count {
                    positions.push([w.coordinate()?, w.coordinate()?, w.coordinate()?]);
                    let _reference: i64 = w.number("reference")?;
                }
            }
            "Tetrahedra" => {
                raw.reserve(count);
                for _ in 0..count {
                    let mut t = [0u64; 4];
                    for c in &mut t {
                        let v: u64 = w.number("vertex number")?;
                        *c = v
                            .checked_sub(1)
                            .ok_or_else(|| w.error("vertex numbers count from 1"))?;
                    }
                    let _reference: i64 = w.number("reference")?;
                    raw.push(t);
                }
            }
            _ => {
                for _ in 0..count * per_entry {
                    w.word()?;
                }
            }
        }
    }
    let n = positions.len();
    let tets = raw
        .into_iter()
        .map(|t| corners(&w, t, n))
        .collect::<Result<_, _>>()?;
    Ok((positions, tets))
}

/// Abaqus input: `*Node` lines and `*Element, type=C3D4` lines (node numbers may be sparse);
/// other keywords' data lines skipped.
fn inp(text: &str, name: &Path) -> Result<Parsed, IoError> {
    #[derive(PartialEq)]
    enum Block {
        Nodes,
        Tets,
        Other,
    }
    let mut block = Block::Other;
    let mut positions = Vec::new();
    let mut index: std::collections::HashMap<u64, u32> = std::collections::HashMap::new();
    let mut raw: Vec<([u64; 4], usize)> = Vec::new();
    let error = |line: usize, reason: String| IoError::format(name, Position::Line(line), reason);
    for (n, line) in text.lines().enumerate() {
        let line_no = n + 1;
        let trimmed = line.trim();
        if trimmed.is_empty() || trimmed.starts_with("**") {
            continue;
        }
        if let Some(keyword) = trimmed.strip_prefix('*') {
            let lower = keyword.to_ascii_lowercase();
            let mut parts = lower.split(',').map(str::trim);
            block = match parts.next() {
                Some("node") => Block::Nodes,
                Some("element") => {
                    let kind = parts
                        .find_map(|p| p.strip_prefix("type"))
                        .map(|p| p.trim_start().trim_start_matches('=').trim());
                    if kind == Some("c3d4") {
                        Block::Tets
                    } else {
                        Block::Other
                    }
                }
                _ => Block::Other,
            };
            continue;
        }
        let fields: Vec<&str> = trimmed
            .split(',')
            .map(str::trim)
            .filter(|f| !f.is_empty())
            .collect();
        match block {
            Block::Nodes => {
                if fields.len() < 4 {
                    return Err(error(line_no, "a node needs a number and x, y, z".into()));
                }
                let id: u64 = fields[0]
                    .parse()
                    .map_err(|_| error(line_no, format!("'{}' is not a node number", fields[0])))?;
                let mut p = [0f32; 3];
                for (c, f) in p.iter_mut().zip(&fields[1..4]) {
                    *c = f
                        .parse()
                        .map_err(|_| error(line_no, format!("'{f}' is not a coordinate")))?;
                    if !c.is_finite() {
                        return Err(error(line_no, "a coordinate is not finite".into()));
                    }
                }
                let v = u32::try_from(positions.len())
                    .map_err(|_| error(line_no, "too many nodes".into()))?;
                if index.insert(id, v).is_some() {
                    return Err(error(line_no, format!("node {id} appears twice")));
                }
                positions.push(p);
            }
            Block::Tets => {
                if fields.len() != 5 {
                    return Err(error(
                        line_no,
                        "a C3D4 element needs a number and four nodes".into(),
                    ));
                }
                let mut t = [0u64; 4];
                for (c, f) in t.iter_mut().zip(&fields[1..]) {
                    *c = f
                        .parse()
                        .map_err(|_| error(line_no, format!("'{f}' is not a node number")))?;
                }
                raw.push((t, line_no));
            }
            Block::Other => {}
        }
    }
    let tets = raw
        .into_iter()
        .map(|(t, line)| {
            let mut out = [0u32; 4];
            for (o, id) in out.iter_mut().zip(t) {
                *o = *index
                    .get(&id)
                    .ok_or_else(|| error(line, format!("node {id} is not defined")))?;
            }
            Ok(out)
        })
        .collect::<Result<_, IoError>>()?;
    Ok((positions, tets))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::write_tet_mesh;
    use isocube::extract::{ExtractOptions, LabelOptions};
    use isocube::field::{Grid, Sample};
    use isocube::volume::{tetmesh, tetmesh_labels};

    fn sorted(tets: &[[u32; 4]]) -> Vec<[u32; 4]> {
        let mut t = tets.to_vec();
        t.sort_unstable();
        t
    }

    /// What `tetmesh` writes reads back: the same positions, bit for bit, and the same
    /// tetrahedra (in order for one region; as a set for labels, written label by label).
    #[test]
    fn written_meshes_read_back() {
        let dir = tempfile::tempdir().unwrap();
        let single = tetmesh(
            &Sample::Gyroid.grid(12),
            &ExtractOptions::default().with_flip(true),
        )
        .unwrap();
        let values = (0..512)
            .map(|p| ((p % 8) / 3 + (p / 64) / 4) as f32)
            .collect();
        let grid = Grid::new([8, 8, 8], values).unwrap();
        let labelled =
            tetmesh_labels(&grid, &LabelOptions::default().with_smoothing(0), None).unwrap();
        for (name, mesh) in [("single", &single), ("labels", &labelled)] {
            for ext in ["msh", "vtu", "mesh", "inp"] {
                let path = dir.path().join(format!("{name}.{ext}"));
                write_tet_mesh(&path, mesh, None).unwrap();
                let back = read_tet_mesh(&path).unwrap();
                let bits = |p: &[[f32; 3]]| -> Vec<[u32; 3]> {
                    p.iter().map(|x| x.map(f32::to_bits)).collect()
                };
                assert_eq!(bits(&back.positions), bits(&mesh.positions), "{name}.{ext}");
                if mesh.labels.is_none() {
                    assert_eq!(back.tets, mesh.tets, "{name}.{ext}");
                } else {
                    assert_eq!(sorted(&back.tets), sorted(&mesh.tets), "{name}.{ext}");
                }
            }
            // Binary MSH: the same mesh as the ASCII file.
            let (text, binary) = (
                dir.path().join(format!("{name}.msh")),
                dir.path().join(format!("{name}-binary.msh")),
            );
            crate::write_tet_mesh_as(&binary, crate::TetFormat::MshBinary, mesh, None).unwrap();
            assert_eq!(
                read_tet_mesh(&binary).unwrap(),
                read_tet_mesh(&text).unwrap()
            );
        }
    }

    /// Every truncation and many single-byte changes of a binary MSH file are an error or a
    /// valid mesh, never a panic; a big-endian file (as Gmsh writes on such machines) reads the
    /// same.
    #[test]
    fn binary_msh_survives_damage() {
        let mesh = tetmesh(&Sample::Sphere.grid(6), &ExtractOptions::default()).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("b.msh");
        crate::write_tet_mesh_as(&path, crate::TetFormat::MshBinary, &mesh, None).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let name: &Path = "b.msh".as_ref();
        for len in 0..bytes.len() {
            assert!(read_tet_mesh_bytes(&bytes[..len], name).is_err(), "{len}");
        }
        for at in (0..bytes.len()).step_by(7) {
            for x in [0u8, 0xff, 0x80, 1] {
                let mut b = bytes.clone();
                b[at] ^= x;
                let _ = read_tet_mesh_bytes(&b, name);
            }
        }
    }

    /// Broken files are errors naming the line, never a panic or a huge allocation.
    #[test]
    fn broken_files_are_refused() {
        let msh = "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 4 1 4\n3 1 0 4\n1\n2\n3\n4\n\
                   0 0 0\n1 0 0\n0 1 0\n0 0 1\n$EndNodes\n$Elements\n1 1 1 1\n3 1 4 1\n1 1 2 3 4\n\
                   $EndElements\n";
        let good = read_tet_mesh_bytes(msh.as_bytes(), "a.msh".as_ref()).unwrap();
        assert_eq!(good.tets, vec![[0, 1, 2, 3]]);
        let vtu = r#"<?xml version="1.0"?>
<VTKFile type="UnstructuredGrid" version="1.0" byte_order="LittleEndian">
  <UnstructuredGrid><Piece NumberOfPoints="4" NumberOfCells="2">
    <Points><DataArray type="Float64" NumberOfComponents="3" format="ascii">
      0 0 0  1 0 0  0 1 0  0 0 1</DataArray></Points>
    <Cells>
      <DataArray type="Int32" Name="connectivity" format="ascii">0 1 2 0 1 2 3</DataArray>
      <DataArray type="Int32" Name="offsets" format="ascii">3 7</DataArray>
      <DataArray type="UInt8" Name="types" format="ascii">5 10</DataArray>
    </Cells>
  </Piece></UnstructuredGrid>
</VTKFile>"#;
        let good = read_tet_mesh_bytes(vtu.as_bytes(), "a.vtu".as_ref()).unwrap();
        assert_eq!((good.positions.len(), good.tets), (4, vec![[0, 1, 2, 3]]));
        let cases: Vec<(String, &str)> = vec![
            (vtu.replace("0 1 2 0 1 2 3", "0 1 2 0 1 2 9"), "vtu"),
            (vtu.replace("3 7", "3 6"), "vtu"),
            (vtu.replace("3 7", "7 3"), "vtu"),
            (
                vtu.replace("NumberOfPoints=\"4\"", "NumberOfPoints=\"400000000\""),
                "vtu",
            ),
            (
                vtu.replace("type=\"UnstructuredGrid\"", "type=\"ImageData\""),
                "vtu",
            ),
            (
                vtu.replace(
                    "byte_order",
                    "compressor=\"vtkZLibDataCompressor\" byte_order",
                ),
                "vtu",
            ),
            (vtu[..vtu.len() / 2].to_string(), "vtu"),
            (msh.replace("1 1 2 3 4", "1 1 2 3 9"), "msh"),
            (msh.replace("4.1 0 8", "2.2 0 8"), "msh"),
            (msh.replace("4.1 0 8", "4.1 1 8"), "msh"),
            (msh.replace("1 4 1 4\n", "1 400000000000 1 4\n"), "msh"),
            (msh[..msh.len() / 2].to_string(), "msh"),
            (msh.replace("$EndNodes", ""), "msh"),
            (
                "Vertices\n1\n0 0 0 0\nTetrahedra\n1\n1 1 1 2 0\nEnd\n".into(),
                "mesh",
            ),
            (
                "Vertices\n1\n0 0 0 0\nTetrahedra\n1\n0 1 1 1 0\nEnd\n".into(),
                "mesh",
            ),
            ("Vertices\n99999999999\n".into(), "mesh"),
            ("Nonsense 3\n".into(), "mesh"),
            (
                "*Node\n1, 0, 0, 0\n*Element, type=C3D4\n1, 1, 1, 1, 7\n".into(),
                "inp",
            ),
            ("*Node\n1, 0, 0\n".into(), "inp"),
            ("*Node\n1, 0, 0, 0\n".into(), "inp"),
            ("*Node\n1, 1e99, 0, 0\n".into(), "inp"),
        ];
        for (text, ext) in cases {
            let name = format!("bad.{ext}");
            assert!(
                read_tet_mesh_bytes(text.as_bytes(), name.as_ref()).is_err(),
                "{text}"
            );
        }
        assert!(read_tet_mesh_bytes(&[0xff, 0xfe], "b.msh".as_ref()).is_err());
    }
}
