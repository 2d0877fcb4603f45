//! Tetrahedral mesh files for finite-element codes: Gmsh MSH 4.1, VTK XML unstructured grids
//! (`.vtu`), MEDIT (`.mesh`) and Abaqus input (`.inp`), chosen by extension.
//!
//! Every format carries the same groups: the region's tetrahedra (physical group 1, "region"),
//! the isosurface's triangles (2, "surface") and the triangles on the grid's outer faces (3,
//! "walls"). A multi-material mesh ([`isocube::volume::tetmesh_labels`]) has one 3-D group per
//! label ("label L", numbered from 1 in increasing label order), then one 2-D group per label's
//! boundary ("label L boundary") and per interface ("interface A|B"). Vertex numbers are the
//! mesh's, from 1 where the format counts from 1.

use std::io::{self, Write};
use std::ops::Range;
use std::path::Path;

use super::blocks::{put_float, put_int, put_ints, put_le, write_blocks};
use super::export::bbox;
use super::mesh_io::write_atomic;
use super::IoError;
use isocube::volume::{QualityColumns, TetMesh};

/// A tetrahedral mesh file format.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TetFormat {
    /// Gmsh MSH 4.1 (`.msh`, ASCII), physical groups for the region and both boundaries.
    Msh,
    /// Gmsh MSH 4.1 binary (`.msh`, little-endian, 8-byte tags and coordinates): the same
    /// content as [`TetFormat::Msh`], about as many bytes on large meshes (Gmsh's binary form
    /// spends 8 bytes on every number) but written without formatting a digit. Chosen
    /// explicitly ([`write_tet_mesh_as`]); the extension alone means ASCII.
    MshBinary,
    /// VTK XML unstructured grid (`.vtu`), arrays appended raw; region, quality as cell data.
    Vtu,
    /// MEDIT (`.mesh`, ASCII), references 1 (region), 2 (surface), 3 (walls), or the labels'
    /// group numbers.
    Medit,
    /// Abaqus input (`.inp`): C3D4 elements in the element set `REGION` (or `LABEL_<l>`), the
    /// boundary as the element-based surfaces `SURFACE` and `WALLS` (or `BOUNDARY_<l>` and
    /// `INTERFACE_<a>_<b>`).
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

/// A mesh's physical groups: the 3-D ones (the region, or one per label) numbered from 1, then
/// the 2-D ones (the surface and the walls, or each label's boundary and each interface), each
/// with the 3-D group its triangles face out of.
struct Groups<'a> {
    mesh: &'a TetMesh,
    /// Names of the 3-D groups: as written where names may hold anything, and for Abaqus.
    volumes: Vec<(String, String)>,
    surfaces: Vec<SurfaceGroup>,
}

struct SurfaceGroup {
    name: String,
    abaqus: String,
    triangles: Vec<[u32; 3]>,
    /// The 3-D group (index) the triangles face out of.
    owner: u32,
    /// For an interface, the 3-D group on the other side.
    other: Option<u32>,
}

impl<'a> Groups<'a> {
    fn of(mesh: &'a TetMesh) -> Groups<'a> {
        let Some(labels) = &mesh.labels else {
            let mut surfaces = vec![SurfaceGroup {
                name: "surface".into(),
                abaqus: "SURFACE".into(),
                triangles: mesh.surface.clone(),
                owner: 0,
                other: None,
            }];
            if !mesh.walls.is_empty() {
                surfaces.push(SurfaceGroup {
                    name: "walls".into(),
                    abaqus: "WALLS".into(),
                    triangles: mesh.walls.clone(),
                    owner: 0,
                    other: None,
                });
            }
            return Groups {
                mesh,
                volumes: vec![("region".into(), "REGION".into())],
                surfaces,
            };
        };
        // Abaqus names: letters, digits and underscores; a minus sign becomes M.
        let abaqus = |l: i64| l.to_string().replace('-', "M");
        let volumes = labels
            .names
            .iter()
            .map(|&l| (format!("label {l}"), format!("LABEL_{}", abaqus(l))))
            .collect();
        let mut surfaces = Vec::new();
        for (i, &l) in labels.names.iter().enumerate() {
            let triangles: Vec<[u32; 3]> = mesh
                .surface
                .iter()
                .zip(&labels.surface)
                .filter(|(_, &s)| s as usize == i)
                .map(|(t, _)| *t)
                .collect();
            if !triangles.is_empty() {
                surfaces.push(SurfaceGroup {
                    name: format!("label {l} boundary"),
                    abaqus: format!("BOUNDARY_{}", abaqus(l)),
                    triangles,
                    owner: i as u32,
                    other: None,
                });
            }
        }
        let mut pairs: Vec<[u32; 2]> = labels.pairs.clone();
        pairs.sort_unstable();
        pairs.dedup();
        for pair in pairs {
            let [a, b] = pair.map(|x| labels.names[x as usize]);
            surfaces.push(SurfaceGroup {
                name: format!("interface {a}|{b}"),
                abaqus: format!("INTERFACE_{}_{}", abaqus(a), abaqus(b)),
                triangles: labels
                    .interfaces
                    .iter()
                    .zip(&labels.pairs)
                    .filter(|(_, &p)| p == pair)
                    .map(|(t, _)| *t)
                    .collect(),
                owner: pair[0],
                other: Some(pair[1]),
            });
        }
        Groups {
            mesh,
            volumes,
            surfaces,
        }
    }

    /// The 3-D group (index) of tetrahedron `t`.
    /// Gmsh's `$PhysicalNames` section (text in both forms of the format).
    fn write_physical_names(&self, w: &mut impl Write) -> io::Result<()> {
        writeln!(
            w,
            "$PhysicalNames\n{}",
            self.volumes.len() + self.surfaces.len()
        )?;
        for (i, (name, _)) in self.volumes.iter().enumerate() {
            writeln!(w, "3 {} \"{name}\"", self.volume_tag(i))?;
        }
        for (i, g) in self.surfaces.iter().enumerate() {
            writeln!(w, "2 {} \"{}\"", self.surface_tag(i), g.name)?;
        }
        writeln!(w, "$EndPhysicalNames")
    }

    /// The surface entities bounding volume group `i`, signed by orientation: out of it, or
    /// into it.
    fn bounding(&self, i: usize) -> Vec<i64> {
        self.surfaces
            .iter()
            .enumerate()
            .filter_map(|(k, g)| {
                let tag = self.surface_tag(k) as i64;
                (g.owner as usize == i)
                    .then_some(tag)
                    .or((g.other == Some(i as u32)).then_some(-tag))
            })
            .collect()
    }

    fn tet_group(&self, t: usize) -> u32 {
        self.mesh.labels.as_ref().map_or(0, |l| l.tets[t])
    }

    /// Tetrahedra (indices) by 3-D group, in mesh order within each.
    fn tets_by_group(&self) -> Vec<Vec<u32>> {
        let mut out = vec![Vec::new(); self.volumes.len()];
        for t in 0..self.mesh.tets.len() {
            out[self.tet_group(t) as usize].push(t as u32);
        }
        out
    }

    /// The tag (physical group number, MEDIT reference) of 3-D group `i`.
    fn volume_tag(&self, i: usize) -> usize {
        i + 1
    }

    /// The tag of 2-D group `i`: after the 3-D groups'.
    fn surface_tag(&self, i: usize) -> usize {
        self.volumes.len() + i + 1
    }
}

/// Writes `mesh` to `path` in the format its extension names, atomically (a temporary file
/// renamed over the target). `quality` ([`TetMesh::quality_columns`]), one entry per
/// tetrahedron, is written as cell data where the format has it (`.vtu`).
pub fn write_tet_mesh(
    path: &Path,
    mesh: &TetMesh,
    quality: Option<&QualityColumns>,
) -> Result<(), IoError> {
    let format = TetFormat::from_path(path).ok_or_else(|| {
        IoError::unsupported(
            path,
            super::Position::File,
            "tetrahedral mesh extension (expected .msh, .vtu, .mesh or .inp)",
        )
    })?;
    write_tet_mesh_as(path, format, mesh, quality)
}

/// [`write_tet_mesh`] in a format given, whatever the extension: [`TetFormat::MshBinary`] is
/// chosen so.
///
/// ```
/// use isocube::{field::Sample, volume::tetmesh, extract::ExtractOptions};
/// use isocube_io::{read_tet_mesh, write_tet_mesh_as, TetFormat};
/// let mesh = tetmesh(&Sample::Sphere.grid(10), &ExtractOptions::default()).unwrap();
/// let path = std::env::temp_dir().join("isocube-doc-binary.msh");
/// write_tet_mesh_as(&path, TetFormat::MshBinary, &mesh, None).unwrap();
/// assert_eq!(read_tet_mesh(&path).unwrap().tets, mesh.tets);
/// # std::fs::remove_file(&path).unwrap();
/// ```
pub fn write_tet_mesh_as(
    path: &Path,
    format: TetFormat,
    mesh: &TetMesh,
    quality: Option<&QualityColumns>,
) -> Result<(), IoError> {
    write_atomic(path, &mut |w| {
        let mut w = io::BufWriter::with_capacity(1 << 20, w);
        match format {
            TetFormat::Msh => write_msh(&mut w, mesh),
            TetFormat::MshBinary => write_msh_binary(&mut w, mesh),
            TetFormat::Vtu => write_vtu(&mut w, mesh, quality),
            TetFormat::Medit => write_medit(&mut w, mesh),
            TetFormat::Inp => write_inp(&mut w, mesh),
        }?;
        w.flush()
    })
}

/// Appends a point's three coordinates separated by `sep`.
fn put_coordinates(out: &mut Vec<u8>, p: &[f32; 3], sep: &[u8]) {
    put_float(out, p[0]);
    out.extend_from_slice(sep);
    put_float(out, p[1]);
    out.extend_from_slice(sep);
    put_float(out, p[2]);
}

/// Gmsh MSH 4.1: one entity per physical group (surfaces, then volumes); all nodes on the first
/// volume entity.
fn write_msh(w: &mut impl Write, mesh: &TetMesh) -> io::Result<()> {
    let groups = Groups::of(mesh);
    let n = mesh.positions.len();
    let (lo, hi) = bbox(&mesh.positions);
    let bounds = format!(
        "{} {} {} {} {} {}",
        lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]
    );
    let (v, s) = (groups.volumes.len(), groups.surfaces.len());
    writeln!(w, "$MeshFormat\n4.1 0 8\n$EndMeshFormat")?;
    groups.write_physical_names(w)?;
    writeln!(w, "$Entities\n0 0 {s} {v}")?;
    for i in 0..s {
        let tag = groups.surface_tag(i);
        writeln!(w, "{tag} {bounds} 1 {tag} 0")?;
    }
    for i in 0..v {
        let bounding = groups.bounding(i);
        let tag = groups.volume_tag(i);
        let list: String = bounding.iter().map(|b| format!(" {b}")).collect();
        writeln!(w, "{tag} {bounds} 1 {tag} {}{list}", bounding.len())?;
    }
    writeln!(w, "$EndEntities")?;
    writeln!(w, "$Nodes\n1 {n} 1 {n}\n3 1 0 {n}")?;
    write_blocks(w, n, |out, r| {
        for tag in r {
            put_ints(out, &[tag + 1], b"");
        }
    })?;
    write_blocks(w, n, |out, r| {
        for p in &mesh.positions[r] {
            put_coordinates(out, p, b" ");
            out.push(b'\n');
        }
    })?;
    writeln!(w, "$EndNodes")?;
    let triangles: usize = groups.surfaces.iter().map(|g| g.triangles.len()).sum();
    let total = triangles + mesh.tets.len();
    writeln!(w, "$Elements\n{} {total} 1 {total}", v + s)?;
    let mut first = 0;
    for (k, g) in groups.surfaces.iter().enumerate() {
        let tris = &g.triangles;
        writeln!(w, "2 {} 2 {}", groups.surface_tag(k), tris.len())?;
        write_blocks(w, tris.len(), |out, r| {
            for i in r {
                let x = tris[i].map(|v| v as usize + 1);
                put_ints(out, &[first + i + 1, x[0], x[1], x[2]], b" ");
            }
        })?;
        first += tris.len();
    }
    for (k, tets) in groups.tets_by_group().iter().enumerate() {
        writeln!(w, "3 {} 4 {}", groups.volume_tag(k), tets.len())?;
        write_blocks(w, tets.len(), |out, r| {
            for i in r {
                let x = mesh.tets[tets[i] as usize].map(|v| v as usize + 1);
                put_ints(out, &[first + i + 1, x[0], x[1], x[2], x[3]], b" ");
            }
        })?;
        first += tets.len();
    }
    writeln!(w, "$EndElements")
}

/// Gmsh MSH 4.1 binary: [`write_msh`]'s sections, numbers as little-endian `int` (4 bytes),
/// `size_t` (8) and `double` (8), each binary part closed by a newline before its `$End` line.
fn write_msh_binary(w: &mut impl Write, mesh: &TetMesh) -> io::Result<()> {
    let groups = Groups::of(mesh);
    let n = mesh.positions.len();
    let (lo, hi) = bbox(&mesh.positions);
    let bounds: Vec<u8> = lo
        .iter()
        .chain(&hi)
        .flat_map(|&x| f64::from(x).to_le_bytes())
        .collect();
    let int = |x: i64| (x as i32).to_le_bytes();
    let size = |x: usize| (x as u64).to_le_bytes();
    let (v, s) = (groups.volumes.len(), groups.surfaces.len());
    w.write_all(b"$MeshFormat\n4.1 1 8\n")?;
    w.write_all(&int(1))?;
    w.write_all(b"\n$EndMeshFormat\n")?;
    groups.write_physical_names(w)?;
    w.write_all(b"$Entities\n")?;
    for count in [0, 0, s, v] {
        w.write_all(&size(count))?;
    }
    for i in 0..s {
        let tag = groups.surface_tag(i) as i64;
        w.write_all(&int(tag))?;
        w.write_all(&bounds)?;
        w.write_all(&size(1))?;
        w.write_all(&int(tag))?;
        w.write_all(&size(0))?;
    }
    for i in 0..v {
        let bounding = groups.bounding(i);
        let tag = groups.volume_tag(i) as i64;
        w.write_all(&int(tag))?;
        w.write_all(&bounds)?;
        w.write_all(&size(1))?;
        w.write_all(&int(tag))?;
        w.write_all(&size(bounding.len()))?;
        for b in bounding {
            w.write_all(&int(b))?;
        }
    }
    w.write_all(b"\n$EndEntities\n$Nodes\n")?;
    for x in [1, n, 1, n] {
        w.write_all(&size(x))?;
    }
    w.write_all(&int(3))?;
    w.write_all(&int(1))?;
    w.write_all(&int(0))?;
    w.write_all(&size(n))?;
    write_blocks(w, n, |out, r| {
        for tag in r {
            out.extend_from_slice(&size(tag + 1));
        }
    })?;
    write_blocks(w, n, |out, r| {
        for p in &mesh.positions[r] {
            for x in p {
                out.extend_from_slice(&f64::from(*x).to_le_bytes());
            }
        }
    })?;
    w.write_all(b"\n$EndNodes\n$Elements\n")?;
    let triangles: usize = groups.surfaces.iter().map(|g| g.triangles.len()).sum();
    let total = triangles + mesh.tets.len();
    for x in [v + s, total, 1, total] {
        w.write_all(&size(x))?;
    }
    let mut first = 0;
    for (k, g) in groups.surfaces.iter().enumerate() {
        let tris = &g.triangles;
        w.write_all(&int(2))?;
        w.write_all(&int(groups.surface_tag(k) as i64))?;
        w.write_all(&int(2))?;
        w.write_all(&size(tris.len()))?;
        write_blocks(w, tris.len(), |out, r| {
            for i in r {
                out.extend_from_slice(&size(first + i + 1));
                for v in tris[i] {
                    out.extend_from_slice(&size(v as usize + 1));
                }
            }
        })?;
        first += tris.len();
    }
    for (k, tets) in groups.tets_by_group().iter().enumerate() {
        w.write_all(&int(3))?;
        w.write_all(&int(groups.volume_tag(k) as i64))?;
        w.write_all(&int(4))?;
        w.write_all(&size(tets.len()))?;
        write_blocks(w, tets.len(), |out, r| {
            for i in r {
                out.extend_from_slice(&size(first + i + 1));
                for v in mesh.tets[tets[i] as usize] {
                    out.extend_from_slice(&size(v as usize + 1));
                }
            }
        })?;
        first += tets.len();
    }
    w.write_all(b"\n$EndElements\n")
}

/// VTK XML unstructured grid: tetrahedra only (cell type 10), appended raw with 64-bit block
/// headers; cell data `region` and, when given, `min_dihedral`, `max_dihedral`,
/// `radius_ratio` (`Float32`).
fn write_vtu(
    w: &mut impl Write,
    mesh: &TetMesh,
    quality: Option<&QualityColumns>,
) -> io::Result<()> {
    let n = mesh.positions.len();
    let t = mesh.tets.len();
    let quality = quality.filter(|q| {
        [&q.min_dihedral, &q.max_dihedral, &q.radius_ratio]
            .iter()
            .all(|c| c.len() == t)
    });
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
    let label = mesh.labels.as_ref().map(|_| next(8 * t as u64));
    // Qualities in single precision: half the bytes, and more digits than any reader of a
    // report or a picture needs.
    let measures = quality.map(|_| [next(4 * t as u64), next(4 * t as u64), next(4 * t as u64)]);
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
    if let Some(at) = label {
        writeln!(
            w,
            r#"        <DataArray type="Int64" Name="label" format="appended" offset="{at}"/>"#
        )?;
    }
    if let Some(at) = measures {
        for (name, at) in ["min_dihedral", "max_dihedral", "radius_ratio"]
            .iter()
            .zip(at)
        {
            writeln!(
                w,
                r#"        <DataArray type="Float32" Name="{name}" format="appended" offset="{at}"/>"#
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
    // is ever held whole a second time (arrays whose bytes are the mesh's own on a
    // little-endian machine go out as they are).
    let array = |w: &mut dyn Write,
                 count: usize,
                 size: usize,
                 fill: &dyn Fn(Range<usize>, &mut Vec<u8>)|
     -> io::Result<()> {
        w.write_all(&((count * size) as u64).to_le_bytes())?;
        let mut buf = Vec::with_capacity(STRETCH * size);
        for start in (0..count).step_by(STRETCH) {
            buf.clear();
            fill(start..(start + STRETCH).min(count), &mut buf);
            w.write_all(&buf)?;
        }
        Ok(())
    };
    let raw = |w: &mut dyn Write, bytes: &[u8]| -> io::Result<()> {
        w.write_all(&(bytes.len() as u64).to_le_bytes())?;
        w.write_all(bytes)
    };
    if cfg!(target_endian = "little") {
        raw(w, bytemuck::cast_slice(&mesh.positions))?;
    } else {
        array(w, n, 12, &|r, b| {
            for p in &mesh.positions[r] {
                put_le(b, p);
            }
        })?;
    }
    if wide {
        array(w, t, 32, &|r, b| {
            for tet in &mesh.tets[r] {
                for v in tet {
                    b.extend_from_slice(&i64::from(*v).to_le_bytes());
                }
            }
        })?;
        array(w, t, 8, &|r, b| {
            for i in r {
                b.extend_from_slice(&(4 * (i as i64 + 1)).to_le_bytes());
            }
        })?;
    } else {
        // Indices below 2³¹: the same bytes as `Int32`.
        if cfg!(target_endian = "little") {
            raw(w, bytemuck::cast_slice(&mesh.tets))?;
        } else {
            array(w, t, 16, &|r, b| {
                for tet in &mesh.tets[r] {
                    for v in tet {
                        b.extend_from_slice(&(*v as i32).to_le_bytes());
                    }
                }
            })?;
        }
        array(w, t, 4, &|r, b| {
            for i in r {
                b.extend_from_slice(&(4 * (i as i32 + 1)).to_le_bytes());
            }
        })?;
    }
    array(w, t, 1, &|r, b| b.resize(b.len() + r.len(), 10))?;
    // The region: 1, or the label's group number (as in the other formats).
    let groups = mesh.labels.as_ref().map(|l| &l.tets);
    array(w, t, 4, &|r, b| {
        for i in r {
            let group = groups.map_or(0, |g| g[i]) as i32 + 1;
            b.extend_from_slice(&group.to_le_bytes());
        }
    })?;
    if let Some(l) = &mesh.labels {
        array(w, t, 8, &|r, b| {
            for &label in &l.tets[r] {
                b.extend_from_slice(&l.names[label as usize].to_le_bytes());
            }
        })?;
    }
    if let Some(q) = quality {
        for column in [&q.min_dihedral, &q.max_dihedral, &q.radius_ratio] {
            array(w, t, 4, &|r, b| {
                for x in &column[r] {
                    b.extend_from_slice(&x.to_le_bytes());
                }
            })?;
        }
    }
    writeln!(w, "\n  </AppendedData>")?;
    writeln!(w, "</VTKFile>")
}

/// MEDIT `.mesh` (ASCII, version 2: single-precision coordinates' shortest forms); references
/// are the physical group numbers.
fn write_medit(w: &mut impl Write, mesh: &TetMesh) -> io::Result<()> {
    let groups = Groups::of(mesh);
    let n = mesh.positions.len();
    writeln!(w, "MeshVersionFormatted 2\nDimension 3\nVertices\n{n}")?;
    write_blocks(w, n, |out, r| {
        for p in &mesh.positions[r] {
            put_coordinates(out, p, b" ");
            out.extend_from_slice(b" 0\n");
        }
    })?;
    let s: usize = groups.surfaces.iter().map(|g| g.triangles.len()).sum();
    writeln!(w, "Triangles\n{s}")?;
    for (k, g) in groups.surfaces.iter().enumerate() {
        let reference = groups.surface_tag(k);
        write_blocks(w, g.triangles.len(), |out, r| {
            for x in &g.triangles[r] {
                let x = x.map(|v| v as usize + 1);
                put_ints(out, &[x[0], x[1], x[2], reference], b" ");
            }
        })?;
    }
    let t = mesh.tets.len();
    writeln!(w, "Tetrahedra\n{t}")?;
    write_blocks(w, t, |out, r| {
        for i in r {
            let x = mesh.tets[i].map(|v| v as usize + 1);
            let reference = groups.volume_tag(groups.tet_group(i) as usize);
            put_ints(out, &[x[0], x[1], x[2], x[3], reference], b" ");
        }
    })?;
    writeln!(w, "End")
}

/// The faces of an Abaqus C3D4 element, S1 to S4, as corner positions (each seen from outside
/// counterclockwise for a positive element).
const C3D4_FACES: [[usize; 3]; 4] = [[0, 1, 2], [0, 3, 1], [1, 3, 2], [2, 3, 0]];

/// Abaqus input: nodes, C3D4 elements (isocube's positive orientation is Abaqus's: the fourth
/// node on the side of face 1-2-3 its right-hand normal points to) in an element set per 3-D
/// group (`REGION`, or `LABEL_<label>`), and each 2-D group as an element-based surface: the
/// element and side of every triangle (in the group it faces out of), sides gathered in element
/// sets `<SURFACE>_S1` … `<SURFACE>_S4` (`SURFACE` and `WALLS`, or `BOUNDARY_<label>` and
/// `INTERFACE_<a>_<b>`).
fn write_inp(w: &mut impl Write, mesh: &TetMesh) -> io::Result<()> {
    let groups = Groups::of(mesh);
    writeln!(w, "*Heading")?;
    let volumes: Vec<&str> = groups.volumes.iter().map(|v| v.1.as_str()).collect();
    let surfaces: Vec<&str> = groups.surfaces.iter().map(|g| g.abaqus.as_str()).collect();
    writeln!(
        w,
        "isocube tetmesh: {} C3D4 elements ({}); boundary surfaces {}",
        mesh.tets.len(),
        volumes.join(", "),
        surfaces.join(", ")
    )?;
    writeln!(w, "*Node")?;
    write_blocks(w, mesh.positions.len(), |out, r| {
        for (i, p) in mesh.positions[r.clone()].iter().enumerate() {
            put_int(out, r.start + i + 1);
            out.extend_from_slice(b", ");
            put_coordinates(out, p, b", ");
            out.push(b'\n');
        }
    })?;
    // Elements numbered group by group; `number[t]` is tetrahedron t's.
    let mut number = vec![0usize; mesh.tets.len()];
    let mut next = 1;
    for (k, tets) in groups.tets_by_group().iter().enumerate() {
        writeln!(w, "*Element, type=C3D4, elset={}", groups.volumes[k].1)?;
        let first = next;
        write_blocks(w, tets.len(), |out, r| {
            for i in r {
                let x = mesh.tets[tets[i] as usize].map(|v| v as usize + 1);
                put_ints(out, &[first + i, x[0], x[1], x[2], x[3]], b", ");
            }
        })?;
        for &t in tets {
            number[t as usize] = next;
            next += 1;
        }
    }
    // Each 2-D group's triangles by their element and side: only faces whose corners all lie
    // on some group's triangles are looked up.
    let mut on_surface = vec![false; mesh.positions.len()];
    let mut owner: std::collections::HashMap<[u32; 3], usize> = std::collections::HashMap::new();
    for (k, g) in groups.surfaces.iter().enumerate() {
        for t in &g.triangles {
            let mut key = *t;
            key.sort_unstable();
            owner.insert(key, k);
            for &v in t {
                on_surface[v as usize] = true;
            }
        }
    }
    // sides[group][side]: element numbers.
    let mut sides: Vec<[Vec<usize>; 4]> = vec![Default::default(); groups.surfaces.len()];
    for (t, tet) in mesh.tets.iter().enumerate() {
        for (side, face) in C3D4_FACES.iter().enumerate() {
            let mut key = face.map(|c| tet[c]);
            if !key.iter().all(|&v| on_surface[v as usize]) {
                continue;
            }
            key.sort_unstable();
            if let Some(&k) = owner.get(&key) {
                if groups.surfaces[k].owner == groups.tet_group(t) {
                    sides[k][side].push(number[t]);
                }
            }
        }
    }
    for (g, group) in groups.surfaces.iter().zip(&mut sides) {
        let name = &g.abaqus;
        if group.iter().all(|s| s.is_empty()) {
            continue;
        }
        for (side, elements) in group.iter_mut().enumerate() {
            if elements.is_empty() {
                continue;
            }
            elements.sort_unstable();
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
