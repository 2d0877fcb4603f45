//! Tetrahedral mesh files for finite-element codes: Gmsh MSH 4.1, VTK XML unstructured grids
//! (`.vtu`), MEDIT (`.mesh`) and Abaqus input (`.inp`), chosen by extension.
//!
//! Every format carries the same groups: the region's tetrahedra (physical group 1, "region"),
//! the isosurface's triangles (2, "surface") and the triangles on the grid's outer faces (3,
//! "walls"). Vertex numbers are the mesh's, from 1 where the format counts from 1.

use std::io::{self, Write};
use std::path::Path;

use super::blocks::write_blocks;
use super::export::bbox;
use super::mesh_io::write_atomic;
use super::IoError;
use isocube::volume::{TetMesh, TetQuality};

/// A tetrahedral mesh file format.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TetFormat {
    /// Gmsh MSH 4.1 (`.msh`, ASCII), physical groups for the region and both boundaries.
    Msh,
    /// VTK XML unstructured grid (`.vtu`), arrays appended raw; region, quality as cell data.
    Vtu,
    /// MEDIT (`.mesh`, ASCII), references 1 (region), 2 (surface), 3 (walls).
    Medit,
    /// Abaqus input (`.inp`): C3D4 elements in the element set `REGION`, the boundary as the
    /// element-based surfaces `SURFACE` and `WALLS`.
    Inp,
}

impl TetFormat {
    /// The format a path's extension names (case-insensitive).
    ///
    /// ```
    /// use isocube_io::TetFormat;
    /// assert_eq!(TetFormat::from_path("a/b.VTU".as_ref()), Some(TetFormat::Vtu));
    /// assert_eq!(TetFormat::from_path("b.ply".as_ref()), None);
    /// ```
    pub fn from_path(path: &Path) -> Option<TetFormat> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "msh" => Some(TetFormat::Msh),
            "vtu" => Some(TetFormat::Vtu),
            "mesh" => Some(TetFormat::Medit),
            "inp" => Some(TetFormat::Inp),
            _ => None,
        }
    }
}

/// Items encoded per write in `.vtu` arrays.
const STRETCH: usize = 1 << 16;

/// Physical group numbers (and MEDIT references).
const REGION: u32 = 1;
const SURFACE: u32 = 2;
const WALLS: u32 = 3;

/// Writes `mesh` to `path` in the format its extension names, atomically (a temporary file
/// renamed over the target). `quality`, one entry per tetrahedron, is written as cell data where
/// the format has it (`.vtu`).
pub fn write_tet_mesh(
    path: &Path,
    mesh: &TetMesh,
    quality: Option<&[TetQuality]>,
) -> Result<(), IoError> {
    let format = TetFormat::from_path(path).ok_or_else(|| {
        IoError::unsupported(
            path,
            super::Position::File,
            "tetrahedral mesh extension (expected .msh, .vtu, .mesh or .inp)",
        )
    })?;
    write_atomic(path, &mut |w| {
        let mut w = io::BufWriter::with_capacity(1 << 20, w);
        match format {
            TetFormat::Msh => write_msh(&mut w, mesh),
            TetFormat::Vtu => write_vtu(&mut w, mesh, quality),
            TetFormat::Medit => write_medit(&mut w, mesh),
            TetFormat::Inp => write_inp(&mut w, mesh),
        }?;
        w.flush()
    })
}

/// Gmsh MSH 4.1: entities surface 2 (the isosurface), surface 3 (the walls, when there are
/// any) and volume 1, each in its physical group; all nodes on the volume entity.
fn write_msh(w: &mut impl Write, mesh: &TetMesh) -> io::Result<()> {
    let n = mesh.positions.len();
    let (lo, hi) = bbox(&mesh.positions);
    let bounds = format!(
        "{} {} {} {} {} {}",
        lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]
    );
    let walls = !mesh.walls.is_empty();
    writeln!(w, "$MeshFormat\n4.1 0 8\n$EndMeshFormat")?;
    writeln!(w, "$PhysicalNames\n{}", if walls { 3 } else { 2 })?;
    writeln!(w, "3 {REGION} \"region\"\n2 {SURFACE} \"surface\"")?;
    if walls {
        writeln!(w, "2 {WALLS} \"walls\"")?;
    }
    writeln!(w, "$EndPhysicalNames")?;
    let surfaces: Vec<u32> = if walls {
        vec![SURFACE, WALLS]
    } else {
        vec![SURFACE]
    };
    writeln!(w, "$Entities\n0 0 {} 1", surfaces.len())?;
    for &s in &surfaces {
        writeln!(w, "{s} {bounds} 1 {s} 0")?;
    }
    let bounding: Vec<String> = surfaces.iter().map(u32::to_string).collect();
    writeln!(
        w,
        "{REGION} {bounds} 1 {REGION} {} {}",
        surfaces.len(),
        bounding.join(" ")
    )?;
    writeln!(w, "$EndEntities")?;
    writeln!(w, "$Nodes\n1 {n} 1 {n}\n3 {REGION} 0 {n}")?;
    write_blocks(w, n, |out, r| {
        for tag in r {
            let _ = writeln!(out, "{}", tag + 1);
        }
    })?;
    write_blocks(w, n, |out, r| {
        for p in &mesh.positions[r] {
            let _ = writeln!(out, "{} {} {}", p[0], p[1], p[2]);
        }
    })?;
    writeln!(w, "$EndNodes")?;
    let (s, f, t) = (mesh.surface.len(), mesh.walls.len(), mesh.tets.len());
    let total = s + f + t;
    writeln!(w, "$Elements\n{} {total} 1 {total}", 1 + surfaces.len())?;
    let triangles = |w: &mut dyn Write, entity: u32, tris: &[[u32; 3]], first: usize| {
        writeln!(w, "2 {entity} 2 {}", tris.len())?;
        write_blocks(w, tris.len(), |out, r| {
            for i in r {
                let x = tris[i];
                let _ = writeln!(
                    out,
                    "{} {} {} {}",
                    first + i + 1,
                    x[0] + 1,
                    x[1] + 1,
                    x[2] + 1
                );
            }
        })
    };
    triangles(w, SURFACE, &mesh.surface, 0)?;
    if walls {
        triangles(w, WALLS, &mesh.walls, s)?;
    }
    writeln!(w, "3 {REGION} 4 {t}")?;
    write_blocks(w, t, |out, r| {
        for i in r {
            let x = mesh.tets[i];
            let _ = writeln!(
                out,
                "{} {} {} {} {}",
                s + f + i + 1,
                x[0] + 1,
                x[1] + 1,
                x[2] + 1,
                x[3] + 1
            );
        }
    })?;
    writeln!(w, "$EndElements")
}

/// VTK XML unstructured grid: tetrahedra only (cell type 10), appended raw with 64-bit block
/// headers; cell data `region` and, when given, `min_dihedral`, `max_dihedral`,
/// `radius_ratio`.
fn write_vtu(w: &mut impl Write, mesh: &TetMesh, quality: Option<&[TetQuality]>) -> io::Result<()> {
    let n = mesh.positions.len();
    let t = mesh.tets.len();
    let quality = quality.filter(|q| q.len() == t);
    let mut offset = 0u64;
    let mut next = |bytes: u64| {
        let at = offset;
        offset += 8 + bytes;
        at
    };
    // Int32 indices while they fit (half the size), Int64 beyond.
    let wide = n > i32::MAX as usize || 4 * t > i32::MAX as usize;
    let (int, int_size) = if wide { ("Int64", 8) } else { ("Int32", 4) };
    let points = next(12 * n as u64);
    let connectivity = next(4 * int_size * t as u64);
    let offsets = next(int_size * t as u64);
    let types = next(t as u64);
    let region = next(4 * t as u64);
    let measures = quality.map(|_| [next(8 * t as u64), next(8 * t as u64), next(8 * t as u64)]);
    writeln!(w, r#"<?xml version="1.0"?>"#)?;
    writeln!(
        w,
        r#"<VTKFile type="UnstructuredGrid" version="1.0" byte_order="LittleEndian" header_type="UInt64">"#
    )?;
    writeln!(w, "  <UnstructuredGrid>")?;
    writeln!(w, r#"    <Piece NumberOfPoints="{n}" NumberOfCells="{t}">"#)?;
    writeln!(w, r#"      <CellData Scalars="region">"#)?;
    writeln!(
        w,
        r#"        <DataArray type="Int32" Name="region" format="appended" offset="{region}"/>"#
    )?;
    if let Some(at) = measures {
        for (name, at) in ["min_dihedral", "max_dihedral", "radius_ratio"]
            .iter()
            .zip(at)
        {
            writeln!(
                w,
                r#"        <DataArray type="Float64" Name="{name}" format="appended" offset="{at}"/>"#
            )?;
        }
    }
    writeln!(w, "      </CellData>")?;
    writeln!(w, "      <Points>")?;
    writeln!(
        w,
        r#"        <DataArray type="Float32" Name="Points" NumberOfComponents="3" format="appended" offset="{points}"/>"#
    )?;
    writeln!(w, "      </Points>")?;
    writeln!(w, "      <Cells>")?;
    writeln!(
        w,
        r#"        <DataArray type="{int}" Name="connectivity" format="appended" offset="{connectivity}"/>"#
    )?;
    writeln!(
        w,
        r#"        <DataArray type="{int}" Name="offsets" format="appended" offset="{offsets}"/>"#
    )?;
    writeln!(
        w,
        r#"        <DataArray type="UInt8" Name="types" format="appended" offset="{types}"/>"#
    )?;
    writeln!(w, "      </Cells>")?;
    writeln!(w, "    </Piece>")?;
    writeln!(w, "  </UnstructuredGrid>")?;
    write!(w, r#"  <AppendedData encoding="raw">"#)?;
    w.write_all(b"\n   _")?;
    // Each array: its byte count, then its items, encoded a stretch at a time so that no array
    // is ever held whole a second time.
    let array = |w: &mut dyn Write,
                 count: usize,
                 size: usize,
                 item: &dyn Fn(usize, &mut Vec<u8>)|
     -> io::Result<()> {
        w.write_all(&((count * size) as u64).to_le_bytes())?;
        let mut buf = Vec::with_capacity(STRETCH * size);
        for start in (0..count).step_by(STRETCH) {
            buf.clear();
            for i in start..(start + STRETCH).min(count) {
                item(i, &mut buf);
            }
            w.write_all(&buf)?;
        }
        Ok(())
    };
    array(w, n, 12, &|i, b| {
        for x in mesh.positions[i] {
            b.extend_from_slice(&x.to_le_bytes());
        }
    })?;
    if wide {
        array(w, t, 32, &|i, b| {
            for v in mesh.tets[i] {
                b.extend_from_slice(&i64::from(v).to_le_bytes());
            }
        })?;
        array(w, t, 8, &|i, b| {
            b.extend_from_slice(&(4 * (i as i64 + 1)).to_le_bytes())
        })?;
    } else {
        array(w, t, 16, &|i, b| {
            for v in mesh.tets[i] {
                b.extend_from_slice(&(v as i32).to_le_bytes());
            }
        })?;
        array(w, t, 4, &|i, b| {
            b.extend_from_slice(&(4 * (i as i32 + 1)).to_le_bytes())
        })?;
    }
    array(w, t, 1, &|_, b| b.push(10))?;
    array(w, t, 4, &|_, b| {
        b.extend_from_slice(&(REGION as i32).to_le_bytes())
    })?;
    if let Some(q) = quality {
        let fields: [fn(&TetQuality) -> f64; 3] =
            [|q| q.min_dihedral, |q| q.max_dihedral, |q| q.radius_ratio];
        for field in fields {
            array(w, t, 8, &|i, b| {
                b.extend_from_slice(&field(&q[i]).to_le_bytes())
            })?;
        }
    }
    writeln!(w, "\n  </AppendedData>")?;
    writeln!(w, "</VTKFile>")
}

/// MEDIT `.mesh` (ASCII, version 2: single-precision coordinates' shortest forms).
fn write_medit(w: &mut impl Write, mesh: &TetMesh) -> io::Result<()> {
    let n = mesh.positions.len();
    writeln!(w, "MeshVersionFormatted 2\nDimension 3\nVertices\n{n}")?;
    write_blocks(w, n, |out, r| {
        for p in &mesh.positions[r] {
            let _ = writeln!(out, "{} {} {} 0", p[0], p[1], p[2]);
        }
    })?;
    let s = mesh.surface.len() + mesh.walls.len();
    writeln!(w, "Triangles\n{s}")?;
    for (tris, reference) in [(&mesh.surface, SURFACE), (&mesh.walls, WALLS)] {
        write_blocks(w, tris.len(), |out, r| {
            for x in &tris[r] {
                let _ = writeln!(out, "{} {} {} {reference}", x[0] + 1, x[1] + 1, x[2] + 1);
            }
        })?;
    }
    let t = mesh.tets.len();
    writeln!(w, "Tetrahedra\n{t}")?;
    write_blocks(w, t, |out, r| {
        for x in &mesh.tets[r] {
            let _ = writeln!(
                out,
                "{} {} {} {} {REGION}",
                x[0] + 1,
                x[1] + 1,
                x[2] + 1,
                x[3] + 1
            );
        }
    })?;
    writeln!(w, "End")
}

/// The faces of an Abaqus C3D4 element, S1 to S4, as corner positions (each seen from outside
/// counterclockwise for a positive element).
const C3D4_FACES: [[usize; 3]; 4] = [[0, 1, 2], [0, 3, 1], [1, 3, 2], [2, 3, 0]];

/// Abaqus input: nodes, C3D4 elements (isocube's positive orientation is Abaqus's: the fourth
/// node on the side of face 1-2-3 its right-hand normal points to), the element set `REGION`,
/// and each boundary as an element-based surface: the element and side of every boundary
/// triangle, sides gathered in element sets `SURFACE_S1` … `WALLS_S4`.
fn write_inp(w: &mut impl Write, mesh: &TetMesh) -> io::Result<()> {
    writeln!(w, "*Heading")?;
    writeln!(
        w,
        "isocube tetmesh: {} C3D4 elements (REGION); boundary surfaces SURFACE and WALLS",
        mesh.tets.len()
    )?;
    writeln!(w, "*Node")?;
    write_blocks(w, mesh.positions.len(), |out, r| {
        for (i, p) in mesh.positions[r.clone()].iter().enumerate() {
            let _ = writeln!(out, "{}, {}, {}, {}", r.start + i + 1, p[0], p[1], p[2]);
        }
    })?;
    writeln!(w, "*Element, type=C3D4, elset=REGION")?;
    write_blocks(w, mesh.tets.len(), |out, r| {
        for (k, t) in mesh.tets[r.clone()].iter().enumerate() {
            let _ = writeln!(
                out,
                "{}, {}, {}, {}, {}",
                r.start + k + 1,
                t[0] + 1,
                t[1] + 1,
                t[2] + 1,
                t[3] + 1
            );
        }
    })?;
    // Each boundary triangle's element and side: only faces whose corners all lie on the
    // boundary are looked up.
    let mut on_boundary = vec![false; mesh.positions.len()];
    let mut boundary: std::collections::HashMap<[u32; 3], usize> = std::collections::HashMap::new();
    for (group, tris) in [&mesh.surface, &mesh.walls].into_iter().enumerate() {
        for t in tris {
            let mut key = *t;
            key.sort_unstable();
            boundary.insert(key, group);
            for &v in t {
                on_boundary[v as usize] = true;
            }
        }
    }
    // sides[group][side]: element numbers (from 1).
    let mut sides: [[Vec<usize>; 4]; 2] = Default::default();
    for (k, t) in mesh.tets.iter().enumerate() {
        for (side, face) in C3D4_FACES.iter().enumerate() {
            let mut key = face.map(|c| t[c]);
            if !key.iter().all(|&v| on_boundary[v as usize]) {
                continue;
            }
            key.sort_unstable();
            if let Some(&group) = boundary.get(&key) {
                sides[group][side].push(k + 1);
            }
        }
    }
    for (name, group) in ["SURFACE", "WALLS"].iter().zip(&sides) {
        if group.iter().all(|s| s.is_empty()) {
            continue;
        }
        for (side, elements) in group.iter().enumerate() {
            if elements.is_empty() {
                continue;
            }
            writeln!(w, "*Elset, elset={name}_S{}", side + 1)?;
            for line in elements.chunks(16) {
                let text: Vec<String> = line.iter().map(|e| e.to_string()).collect();
                writeln!(w, "{}", text.join(", "))?;
            }
        }
        writeln!(w, "*Surface, type=ELEMENT, name={name}")?;
        for (side, elements) in group.iter().enumerate() {
            if !elements.is_empty() {
                writeln!(w, "{name}_S{}, S{}", side + 1, side + 1)?;
            }
        }
    }
    Ok(())
}
