//! Mesh files, chosen by extension: PLY, OBJ and STL (read and written), OFF (read and written),
//! binary glTF, VTK PolyData (XML and legacy) and Gmsh MSH 4.1 (written; see [`super::export`]).

use std::collections::HashMap;
use std::io::{BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

use super::blocks::{put_le, write_blocks};
use super::export::{self, VertexValues};
use super::{read_file, IoError, Position};
use isocube::extract::{MeshSink, PlacedPiece};
use isocube::mesh::Mesh;

/// A mesh file format.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MeshFormat {
    /// Stanford PLY.
    Ply,
    /// Wavefront OBJ.
    Obj,
    /// STL (written binary).
    Stl,
    /// Object File Format (ASCII).
    Off,
    /// Binary glTF 2.0 (`.glb`).
    Glb,
    /// VTK XML PolyData (`.vtp`).
    Vtp,
    /// Legacy VTK PolyData (`.vtk`, binary).
    Vtk,
    /// Gmsh MSH 4.1 (`.msh`, ASCII).
    Msh,
}

impl MeshFormat {
    /// The format a path's extension names (case-insensitive).
    pub fn from_path(path: &Path) -> Option<MeshFormat> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "ply" => Some(MeshFormat::Ply),
            "obj" => Some(MeshFormat::Obj),
            "stl" => Some(MeshFormat::Stl),
            "off" => Some(MeshFormat::Off),
            "glb" => Some(MeshFormat::Glb),
            "vtp" => Some(MeshFormat::Vtp),
            "vtk" => Some(MeshFormat::Vtk),
            "msh" => Some(MeshFormat::Msh),
            _ => None,
        }
    }

    /// Whether [`read_mesh`] reads this format.
    pub fn readable(self) -> bool {
        matches!(
            self,
            MeshFormat::Ply | MeshFormat::Obj | MeshFormat::Stl | MeshFormat::Off
        )
    }

    /// Whether the format stores per-vertex normals and values ([`VertexValues`]).
    pub fn holds_vertex_data(self) -> bool {
        matches!(
            self,
            MeshFormat::Ply | MeshFormat::Glb | MeshFormat::Vtp | MeshFormat::Vtk | MeshFormat::Msh
        )
    }
}

/// How to write a mesh.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub struct MeshWriteOptions {
    /// ASCII PLY instead of binary little-endian (PLY only).
    pub ascii: bool,
    /// Write vertex normals when the mesh has them (PLY and OBJ; STL stores face normals).
    pub normals: bool,
}

impl Default for MeshWriteOptions {
    fn default() -> Self {
        MeshWriteOptions {
            ascii: false,
            normals: true,
        }
    }
}

fn unknown_format(path: &Path) -> IoError {
    IoError::unsupported(
        path,
        Position::File,
        "unknown mesh extension (expected .ply, .obj, .stl, .off, .glb, .vtp, .vtk or .msh)",
    )
}

/// Writes a mesh atomically, in the format its extension names: the bytes go to a temporary
/// file beside the target and the file is renamed over the target (see
/// [`write_file_atomic`] for what that guards against). On any
/// error the target is untouched and the temporary file removed.
pub fn write_mesh(path: &Path, mesh: &Mesh, options: &MeshWriteOptions) -> Result<(), IoError> {
    write_mesh_with_values(path, mesh, options, None)
}

/// [`write_mesh`] with one scalar per vertex, for the formats that hold them
/// ([`MeshFormat::holds_vertex_data`]); asking another format for values is an error.
pub fn write_mesh_with_values(
    path: &Path,
    mesh: &Mesh,
    options: &MeshWriteOptions,
    values: Option<VertexValues>,
) -> Result<(), IoError> {
    let format = MeshFormat::from_path(path).ok_or_else(|| unknown_format(path))?;
    mesh.validate().map_err(|reason| {
        IoError::format(path, Position::File, format!("invalid mesh: {reason}"))
    })?;
    if let Some(v) = values {
        if !format.holds_vertex_data() {
            return Err(IoError::unsupported(
                path,
                Position::File,
                "this format has no per-vertex values (use .ply, .glb, .vtp, .vtk or .msh)",
            ));
        }
        if v.values.len() != mesh.positions.len() {
            return Err(IoError::format(
                path,
                Position::File,
                format!(
                    "{} values for {} vertices",
                    v.values.len(),
                    mesh.positions.len()
                ),
            ));
        }
    }
    write_atomic(path, &mut |w| {
        write_mesh_data_to(&mut &mut *w, format, mesh, options, values)
    })
}

/// Writes `bytes` to `path` atomically, as [`write_mesh`] does: for pictures, reports and any
/// other output that must not be left half-written.
///
/// Atomic against the process failing (a crash, an interrupt, a full disk): a reader finds the
/// old file or the whole new one. The bytes are not forced to the disk before returning (no
/// `fsync`, as no peer's writer does): that wait cost a third of a 256³ extraction end to end.
/// File systems that replace on rename, ext4's default among them, write the new file's data
/// before the rename lands.
pub fn write_file_atomic(path: &Path, bytes: &[u8]) -> Result<(), IoError> {
    write_atomic(path, &mut |w| w.write_all(bytes))
}

/// Writes a file atomically: a temporary file beside the target, renamed over it; on any error
/// the target is untouched and the temporary file removed.
pub(crate) fn write_atomic(
    path: &Path,
    write: &mut dyn FnMut(&mut dyn Write) -> std::io::Result<()>,
) -> Result<(), IoError> {
    let tmp = temp_beside(path, "").map_err(|e| IoError::os(path, e))?;
    {
        let mut w = BufWriter::with_capacity(1 << 16, tmp.as_file());
        write(&mut w).map_err(|e| IoError::os(path, e))?;
        w.flush().map_err(|e| IoError::os(path, e))?;
    }
    tmp.persist(path).map_err(|e| IoError::os(path, e.error))?;
    Ok(())
}

/// Writes a mesh in a format to any writer.
pub fn write_mesh_to(
    w: &mut impl Write,
    format: MeshFormat,
    mesh: &Mesh,
    options: &MeshWriteOptions,
) -> std::io::Result<()> {
    write_mesh_data_to(w, format, mesh, options, None)
}

/// [`write_mesh_to`] with optional per-vertex values (ignored by formats that cannot hold them).
pub fn write_mesh_data_to(
    w: &mut impl Write,
    format: MeshFormat,
    mesh: &Mesh,
    options: &MeshWriteOptions,
    values: Option<VertexValues>,
) -> std::io::Result<()> {
    let normals = options.normals && !mesh.normals.is_empty();
    match format {
        MeshFormat::Ply => write_ply(w, mesh, normals, values, options.ascii),
        MeshFormat::Obj => write_obj(w, mesh, normals),
        MeshFormat::Stl => write_stl(w, mesh),
        MeshFormat::Off => export::write_off(w, mesh),
        MeshFormat::Glb => export::write_glb(w, mesh, normals, values),
        MeshFormat::Vtp => export::write_vtp(w, mesh, normals, values),
        MeshFormat::Vtk => export::write_legacy_vtk(w, mesh, normals, values),
        MeshFormat::Msh => export::write_msh(w, mesh, normals, values),
    }
}

fn write_ply(
    w: &mut impl Write,
    mesh: &Mesh,
    normals: bool,
    values: Option<VertexValues>,
    ascii: bool,
) -> std::io::Result<()> {
    let format = if ascii {
        "ascii"
    } else {
        "binary_little_endian"
    };
    ply_header(
        w,
        format,
        mesh.positions.len(),
        mesh.triangles.len(),
        normals,
        values.map(|v| v.name),
    )?;
    let ply_vertex = |out: &mut Vec<u8>, i: usize| {
        let p = mesh.positions[i];
        // Writing to a Vec cannot fail.
        let _ = write!(out, "{} {} {}", p[0], p[1], p[2]);
        if normals {
            let n = mesh.normals[i];
            let _ = write!(out, " {} {} {}", n[0], n[1], n[2]);
        }
        if let Some(v) = values {
            let _ = write!(out, " {}", v.values[i]);
        }
        out.push(b'\n');
    };
    if ascii {
        write_blocks(w, mesh.positions.len(), |out, r| {
            r.for_each(|i| ply_vertex(out, i))
        })?;
        return write_blocks(w, mesh.triangles.len(), |out, r| {
            for t in &mesh.triangles[r] {
                let _ = writeln!(out, "3 {} {} {}", t[0], t[1], t[2]);
            }
        });
    }
    // Binary records have a fixed width: each block is sized once and filled in place.
    let width = 4 * (3 + if normals { 3 } else { 0 } + usize::from(values.is_some()));
    write_blocks(w, mesh.positions.len(), |out, r| {
        out.resize(r.len() * width, 0);
        for (record, i) in out.chunks_exact_mut(width).zip(r) {
            let mut at = 0;
            let mut put = |x: f32| {
                record[at..at + 4].copy_from_slice(&x.to_le_bytes());
                at += 4;
            };
            mesh.positions[i].into_iter().for_each(&mut put);
            if normals {
                mesh.normals[i].into_iter().for_each(&mut put);
            }
            if let Some(v) = values {
                put(v.values[i]);
            }
        }
    })?;
    write_blocks(w, mesh.triangles.len(), |out, r| {
        out.resize(r.len() * 13, 0);
        for (record, t) in out.chunks_exact_mut(13).zip(&mesh.triangles[r]) {
            record[0] = 3;
            for (c, v) in t.iter().enumerate() {
                record[1 + 4 * c..5 + 4 * c].copy_from_slice(&v.to_le_bytes());
            }
        }
    })
}

fn ply_header(
    w: &mut impl Write,
    format: &str,
    vertices: usize,
    faces: usize,
    normals: bool,
    value: Option<&str>,
) -> std::io::Result<()> {
    writeln!(w, "ply\nformat {format} 1.0\ncomment isocube")?;
    writeln!(w, "element vertex {vertices}")?;
    writeln!(w, "property float x\nproperty float y\nproperty float z")?;
    if normals {
        writeln!(w, "property float nx\nproperty float ny\nproperty float nz")?;
    }
    if let Some(name) = value {
        // PLY property names are single words.
        let name: String = name
            .chars()
            .map(|c| if c.is_whitespace() { '_' } else { c })
            .collect();
        writeln!(w, "property float {name}")?;
    }
    writeln!(w, "element face {faces}")?;
    writeln!(w, "property list uchar uint vertex_indices\nend_header")
}

/// A binary PLY file written piece by piece, as a [`MeshSink`] for
/// [`isocube::extract::extract_streamed`]: meshes larger than memory go straight to disk.
///
/// Vertices and triangles go to two temporary files beside the target; [`PlyWriter::finish`]
/// writes the header (whose counts are known only then) and both parts into a third and
/// renames it over the target. The bytes are those [`write_mesh`] writes for the same mesh
/// (binary, little-endian). If anything fails, or the writer is dropped unfinished, the target
/// is untouched and the temporary files are removed.
pub struct PlyWriter {
    path: PathBuf,
    normals: bool,
    vertices: BufWriter<tempfile::NamedTempFile>,
    faces: BufWriter<tempfile::NamedTempFile>,
    vertex_count: usize,
    face_count: usize,
}

impl PlyWriter {
    /// Starts a binary PLY file at `path`, with per-vertex normals if `normals`.
    pub fn create(path: &Path, normals: bool) -> Result<PlyWriter, IoError> {
        let part = |what: &str| {
            temp_beside(path, what)
                .map(|f| BufWriter::with_capacity(1 << 20, f))
                .map_err(|e| IoError::os(path, e))
        };
        Ok(PlyWriter {
            path: path.to_path_buf(),
            normals,
            vertices: part("vertices")?,
            faces: part("faces")?,
            vertex_count: 0,
            face_count: 0,
        })
    }

    /// Vertices written so far.
    pub fn vertex_count(&self) -> usize {
        self.vertex_count
    }

    /// Triangles written so far.
    pub fn triangle_count(&self) -> usize {
        self.face_count
    }

    /// Writes the file and renames it over the target.
    pub fn finish(self) -> Result<(), IoError> {
        let path = self.path;
        let os = |e| IoError::os(&path, e);
        let mut parts = [self.vertices, self.faces]
            .into_iter()
            .map(|w| w.into_inner().map_err(|e| os(e.into_error())))
            .collect::<Result<Vec<_>, _>>()?;
        let out = temp_beside(&path, "").map_err(os)?;
        {
            let mut w = BufWriter::new(out.as_file());
            ply_header(
                &mut w,
                "binary_little_endian",
                self.vertex_count,
                self.face_count,
                self.normals,
                None,
            )
            .map_err(os)?;
            w.flush().map_err(os)?;
        }
        for part in &mut parts {
            let file = part.as_file_mut();
            file.seek(SeekFrom::Start(0)).map_err(os)?;
            std::io::copy(file, &mut out.as_file()).map_err(os)?;
        }
        out.persist(&path)
            .map_err(|e| IoError::os(&path, e.error))?;
        Ok(())
    }
}

/// A binary PLY file filled in place by many writers at once: the tasks of a cluster, each
/// writing its own pieces of a mesh ([`isocube::extract::ChunkPlace::place`]) at their
/// offsets, so that a mesh larger than any one machine's memory is written without being
/// gathered. The file's bytes are those [`write_mesh`] writes for the whole mesh. Writers on
/// several machines need a filesystem they all see (NFS, Lustre, GPFS…); every write is a plain
/// positioned write of whole records, repeated identically if a task runs again.
///
/// ```
/// use isocube::extract::{extract, CellBox, ExtractOptions, Extractor, JoinLayout};
/// use isocube::field::Sample;
/// use isocube_io::{write_mesh, MeshWriteOptions, PlyLayout};
/// let dir = tempfile::tempdir().unwrap();
/// let grid = Sample::Torus.grid(24);
/// let extractor = Extractor::new(&grid, &ExtractOptions::default()).unwrap();
/// let chunks: Vec<_> = CellBox::tile(grid.dims(), [23, 8, 8]).unwrap().into_iter()
///     .map(|b| extractor.mesh_box(b).unwrap()).collect();
/// let outlines: Vec<_> = chunks.iter().map(|c| c.outline(grid.dims())).collect();
/// let layout = JoinLayout::new(grid.dims(), &outlines).unwrap();
/// let ply = PlyLayout::new(layout.vertices() as u64, layout.triangles() as u64, true);
/// let path = dir.path().join("torus.ply");
/// ply.create(&path).unwrap();
/// for (chunk, place) in chunks.iter().zip(layout.places()) {
///     ply.write_pieces(&path, &place.place(chunk).unwrap()).unwrap();
/// }
/// let whole = dir.path().join("whole.ply");
/// write_mesh(&whole, &extract(&grid, &ExtractOptions::default()).unwrap().0, &MeshWriteOptions::default()).unwrap();
/// assert_eq!(std::fs::read(&path).unwrap(), std::fs::read(&whole).unwrap());
/// ```
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PlyLayout {
    vertices: u64,
    triangles: u64,
    normals: bool,
    header: Vec<u8>,
}

impl PlyLayout {
    /// The layout of a binary PLY file of `vertices` vertices (with normals if `normals`) and
    /// `triangles` triangles.
    pub fn new(vertices: u64, triangles: u64, normals: bool) -> PlyLayout {
        let mut header = Vec::new();
        // Writing to a Vec cannot fail; counts print the same as `usize`s.
        let _ = ply_header(
            &mut header,
            "binary_little_endian",
            vertices as usize,
            triangles as usize,
            normals,
            None,
        );
        PlyLayout {
            vertices,
            triangles,
            normals,
            header,
        }
    }

    fn vertex_width(&self) -> u64 {
        if self.normals {
            24
        } else {
            12
        }
    }

    /// The file's length in bytes.
    pub fn file_len(&self) -> u64 {
        self.header.len() as u64 + self.vertices * self.vertex_width() + self.triangles * 13
    }

    /// Makes the file at `path` its full length with the header written, keeping what is
    /// already there (creating it again, as a retried task does, loses no piece written).
    pub fn create(&self, path: &Path) -> Result<(), IoError> {
        let os = |e| IoError::os(path, e);
        let mut file = std::fs::OpenOptions::new()
            .write(true)
            .create(true)
            .truncate(false)
            .open(path)
            .map_err(os)?;
        file.set_len(self.file_len()).map_err(os)?;
        file.write_all(&self.header).map_err(os)
    }

    /// Writes pieces of the mesh at their places in the file [`PlyLayout::create`] made.
    /// Pieces beyond the layout's counts, or without normals where the file has them, are
    /// refused before anything is written.
    pub fn write_pieces(&self, path: &Path, pieces: &[PlacedPiece]) -> Result<(), IoError> {
        for p in pieces {
            let fits = |first: u64, n: usize, total: u64| {
                first.checked_add(n as u64).is_some_and(|end| end <= total)
            };
            let normals_ok = !self.normals || p.normals.len() == p.positions.len();
            let indices_ok = p
                .triangles
                .iter()
                .flatten()
                .all(|&v| u64::from(v) < self.vertices);
            if !fits(p.first_vertex, p.positions.len(), self.vertices)
                || !fits(p.first_triangle, p.triangles.len(), self.triangles)
                || !normals_ok
                || !indices_ok
            {
                return Err(IoError::Format {
                    path: path.to_path_buf(),
                    position: Position::File,
                    reason: format!(
                        "a piece of vertices {}.. and triangles {}.. does not fit a mesh of {} vertices and {} triangles{}",
                        p.first_vertex,
                        p.first_triangle,
                        self.vertices,
                        self.triangles,
                        if normals_ok { "" } else { " with normals" }
                    ),
                });
            }
        }
        let os = |e| IoError::os(path, e);
        let mut file = std::fs::OpenOptions::new()
            .write(true)
            .open(path)
            .map_err(os)?;
        let width = self.vertex_width() as usize;
        let faces_at = self.header.len() as u64 + self.vertices * self.vertex_width();
        let mut buffer = Vec::new();
        for p in pieces {
            buffer.clear();
            buffer.resize(p.positions.len() * width, 0);
            for (i, record) in buffer.chunks_exact_mut(width).enumerate() {
                let mut words = p.positions[i].into_iter().chain(if self.normals {
                    p.normals[i]
                } else {
                    [f32::NAN; 3]
                });
                for x in record.chunks_exact_mut(4) {
                    x.copy_from_slice(&words.next().unwrap_or(0.0).to_le_bytes());
                }
            }
            let at = self.header.len() as u64 + p.first_vertex * self.vertex_width();
            file.seek(SeekFrom::Start(at)).map_err(os)?;
            file.write_all(&buffer).map_err(os)?;
            buffer.clear();
            buffer.resize(p.triangles.len() * 13, 0);
            for (record, t) in buffer.chunks_exact_mut(13).zip(&p.triangles) {
                record[0] = 3;
                for (c, v) in t.iter().enumerate() {
                    record[1 + 4 * c..5 + 4 * c].copy_from_slice(&v.to_le_bytes());
                }
            }
            file.seek(SeekFrom::Start(faces_at + p.first_triangle * 13))
                .map_err(os)?;
            file.write_all(&buffer).map_err(os)?;
        }
        Ok(())
    }
}

/// A temporary file in `path`'s directory, named after it.
pub(crate) fn temp_beside(path: &Path, what: &str) -> std::io::Result<tempfile::NamedTempFile> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("mesh");
    let prefix = if what.is_empty() {
        format!(".{name}.")
    } else {
        format!(".{name}.{what}.")
    };
    let mut builder = tempfile::Builder::new();
    builder.prefix(&prefix).suffix(".tmp");
    // Temporary files are private (0600); the file that takes the target's place gets the
    // usual mode for new files (0666 less the umask), as if it had been created directly.
    #[cfg(unix)]
    if what.is_empty() {
        use std::os::unix::fs::PermissionsExt;
        builder.permissions(std::fs::Permissions::from_mode(0o666));
    }
    builder.tempfile_in(dir)
}

impl MeshSink for PlyWriter {
    type Error = IoError;

    fn vertices(&mut self, positions: &[[f32; 3]], normals: &[[f32; 3]]) -> Result<(), IoError> {
        let mut record = [0u8; 24];
        let width = if self.normals { 24 } else { 12 };
        for (i, p) in positions.iter().enumerate() {
            for (c, x) in p.iter().enumerate() {
                record[4 * c..4 * c + 4].copy_from_slice(&x.to_le_bytes());
            }
            if self.normals {
                let n = normals.get(i).copied().unwrap_or([0.0; 3]);
                for (c, x) in n.iter().enumerate() {
                    record[12 + 4 * c..16 + 4 * c].copy_from_slice(&x.to_le_bytes());
                }
            }
            self.vertices
                .write_all(&record[..width])
                .map_err(|e| IoError::os(&self.path, e))?;
        }
        self.vertex_count += positions.len();
        Ok(())
    }

    fn triangles(&mut self, triangles: &[[u32; 3]]) -> Result<(), IoError> {
        let mut record = [3u8; 13];
        for t in triangles {
            for (c, v) in t.iter().enumerate() {
                record[1 + 4 * c..5 + 4 * c].copy_from_slice(&v.to_le_bytes());
            }
            self.faces
                .write_all(&record)
                .map_err(|e| IoError::os(&self.path, e))?;
        }
        self.face_count += triangles.len();
        Ok(())
    }
}

fn write_obj(w: &mut impl Write, mesh: &Mesh, normals: bool) -> std::io::Result<()> {
    writeln!(
        w,
        "# isocube: {} vertices, {} triangles",
        mesh.positions.len(),
        mesh.triangles.len()
    )?;
    // Writing to a Vec cannot fail.
    write_blocks(w, mesh.positions.len(), |out, r| {
        for p in &mesh.positions[r] {
            let _ = writeln!(out, "v {} {} {}", p[0], p[1], p[2]);
        }
    })?;
    if normals {
        write_blocks(w, mesh.normals.len(), |out, r| {
            for n in &mesh.normals[r] {
                let _ = writeln!(out, "vn {} {} {}", n[0], n[1], n[2]);
            }
        })?;
    }
    write_blocks(w, mesh.triangles.len(), |out, r| {
        for t in &mesh.triangles[r] {
            let [a, b, c] = t.map(|v| v + 1);
            let _ = if normals {
                writeln!(out, "f {a}//{a} {b}//{b} {c}//{c}")
            } else {
                writeln!(out, "f {a} {b} {c}")
            };
        }
    })
}

fn write_stl(w: &mut impl Write, mesh: &Mesh) -> std::io::Result<()> {
    let mut header = [b' '; 80];
    header[..7].copy_from_slice(b"isocube");
    w.write_all(&header)?;
    let count = u32::try_from(mesh.triangles.len())
        .map_err(|_| std::io::Error::other("more than 2^32 triangles do not fit in STL"))?;
    w.write_all(&count.to_le_bytes())?;
    write_blocks(w, mesh.triangles.len(), |out, r| {
        for t in &mesh.triangles[r] {
            let p = t.map(|v| mesh.positions[v as usize].map(f64::from));
            let n = isocube::mesh::cross(
                isocube::mesh::sub(p[1], p[0]),
                isocube::mesh::sub(p[2], p[0]),
            );
            let len = isocube::mesh::dot(n, n).sqrt();
            let n = if len > 0.0 {
                n.map(|c| (c / len) as f32)
            } else {
                [0.0; 3]
            };
            put_le(out, &n);
            for v in t {
                put_le(out, &mesh.positions[*v as usize]);
            }
            out.extend_from_slice(&[0, 0]);
        }
    })
}

/// Reads a mesh in the format its extension names. Polygons are fan-triangulated; STL
/// triangles are welded by exact position.
pub fn read_mesh(path: &Path) -> Result<Mesh, IoError> {
    MeshFormat::from_path(path).ok_or_else(|| unknown_format(path))?;
    read_mesh_bytes(&read_file(path)?, path)
}

/// [`read_mesh`] on a file's content already in memory; `name`'s extension chooses the format
/// and `name` appears in errors.
///
/// ```
/// use std::path::Path;
/// let off = b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
/// let mesh = isocube_io::read_mesh_bytes(off, Path::new("one.off"))?;
/// assert_eq!((mesh.positions.len(), mesh.triangles.len()), (3, 1));
/// # Ok::<(), isocube_io::IoError>(())
/// ```
pub fn read_mesh_bytes(bytes: &[u8], name: &Path) -> Result<Mesh, IoError> {
    let path = name;
    let format = MeshFormat::from_path(path).ok_or_else(|| unknown_format(path))?;
    let mesh = match format {
        MeshFormat::Ply => read_ply(path, bytes)?,
        MeshFormat::Obj => read_obj(path, bytes)?,
        MeshFormat::Stl => read_stl(path, bytes)?,
        MeshFormat::Off => read_off(path, bytes)?,
        other => {
            return Err(IoError::unsupported(
                path,
                Position::File,
                format!("isocube writes {other:?} meshes but reads only .ply, .obj, .stl and .off"),
            ))
        }
    };
    Ok(mesh)
}

fn check_coordinate(path: &Path, pos: impl Fn() -> Position, c: f64) -> Result<f32, IoError> {
    if c.is_finite() && c.abs() <= f64::from(f32::MAX) {
        Ok(c as f32)
    } else {
        Err(IoError::format(
            path,
            pos(),
            format!("coordinate {c} is not a finite number"),
        ))
    }
}

fn push_polygon(
    path: &Path,
    pos: impl Fn() -> Position,
    mesh: &mut Mesh,
    polygon: &[i64],
    vertex_count: usize,
) -> Result<(), IoError> {
    if polygon.len() < 3 {
        return Err(IoError::format(
            path,
            pos(),
            format!(
                "a face needs 3 or more vertices, this one has {}",
                polygon.len()
            ),
        ));
    }
    for &v in polygon {
        if v < 0 || v as u64 >= vertex_count as u64 {
            return Err(IoError::format(
                path,
                pos(),
                format!("vertex index {v} is outside 0..{vertex_count}"),
            ));
        }
    }
    for i in 1..polygon.len() - 1 {
        mesh.triangles
            .push([polygon[0] as u32, polygon[i] as u32, polygon[i + 1] as u32]);
    }
    Ok(())
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum PlyType {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl PlyType {
    fn parse(s: &str) -> Option<PlyType> {
        Some(match s {
            "char" | "int8" => PlyType::I8,
            "uchar" | "uint8" => PlyType::U8,
            "short" | "int16" => PlyType::I16,
            "ushort" | "uint16" => PlyType::U16,
            "int" | "int32" => PlyType::I32,
            "uint" | "uint32" => PlyType::U32,
            "float" | "float32" => PlyType::F32,
            "double" | "float64" => PlyType::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            PlyType::I8 | PlyType::U8 => 1,
            PlyType::I16 | PlyType::U16 => 2,
            PlyType::I32 | PlyType::U32 | PlyType::F32 => 4,
            PlyType::F64 => 8,
        }
    }

    fn decode(self, b: &[u8], big: bool) -> f64 {
        macro_rules! get {
            ($t:ty) => {{
                let a: [u8; std::mem::size_of::<$t>()] = b.try_into().expect("width");
                if big {
                    <$t>::from_be_bytes(a)
                } else {
                    <$t>::from_le_bytes(a)
                }
            }};
        }
        match self {
            PlyType::I8 => f64::from(b[0] as i8),
            PlyType::U8 => f64::from(b[0]),
            PlyType::I16 => f64::from(get!(i16)),
            PlyType::U16 => f64::from(get!(u16)),
            PlyType::I32 => f64::from(get!(i32)),
            PlyType::U32 => f64::from(get!(u32)),
            PlyType::F32 => f64::from(get!(f32)),
            PlyType::F64 => get!(f64),
        }
    }
}

struct PlyProperty {
    name: String,
    /// `Some(count type)` for a list property.
    list: Option<PlyType>,
    ty: PlyType,
}

struct PlyElement {
    name: String,
    count: usize,
    properties: Vec<PlyProperty>,
}

fn read_ply(path: &Path, bytes: &[u8]) -> Result<Mesh, IoError> {
    let end = find(bytes, b"end_header").ok_or_else(|| {
        IoError::format(
            path,
            Position::File,
            "no 'end_header' line: not a PLY file or a truncated header",
        )
    })?;
    let mut data_start = end + b"end_header".len();
    if bytes.get(data_start) == Some(&b'\r') {
        data_start += 1;
    }
    if bytes.get(data_start) == Some(&b'\n') {
        data_start += 1;
    }
    let header = std::str::from_utf8(&bytes[..end]).map_err(|e| {
        IoError::format(
            path,
            Position::Byte(e.valid_up_to() as u64),
            "header is not text",
        )
    })?;
    let mut lines = header.lines().enumerate();
    match lines.next() {
        Some((_, l)) if l.trim() == "ply" => {}
        _ => {
            return Err(IoError::format(
                path,
                Position::Line(1),
                "not a PLY file (first line is not 'ply')",
            ))
        }
    }
    let mut format = None;
    let mut elements: Vec<PlyElement> = Vec::new();
    for (n, line) in lines {
        let pos = || Position::Line(n + 1);
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.as_slice() {
            [] | ["comment", ..] | ["obj_info", ..] => {}
            ["format", ..] if format.is_some() => {
                return Err(IoError::format(path, pos(), "a second 'format' line"));
            }
            ["element", name, _] if elements.iter().any(|e| e.name == *name) => {
                return Err(IoError::format(
                    path,
                    pos(),
                    format!("a second '{name}' element"),
                ));
            }
            ["format", f, _] => {
                format = Some(match *f {
                    "ascii" => 0,
                    "binary_little_endian" => 1,
                    "binary_big_endian" => 2,
                    _ => return Err(IoError::unsupported(path, pos(), format!("format '{f}'"))),
                })
            }
            ["element", name, count] => elements.push(PlyElement {
                name: name.to_string(),
                count: count.parse().map_err(|_| {
                    IoError::format(path, pos(), format!("'{count}' is not an element count"))
                })?,
                properties: Vec::new(),
            }),
            ["property", "list", count_ty, ty, name] => {
                let e = elements
                    .last_mut()
                    .ok_or_else(|| IoError::format(path, pos(), "property before any element"))?;
                let ct =
                    PlyType::parse(count_ty).filter(|t| !matches!(t, PlyType::F32 | PlyType::F64));
                e.properties.push(PlyProperty {
                    name: name.to_string(),
                    list: Some(ct.ok_or_else(|| {
                        IoError::format(path, pos(), format!("list count type '{count_ty}'"))
                    })?),
                    ty: PlyType::parse(ty)
                        .ok_or_else(|| IoError::format(path, pos(), format!("type '{ty}'")))?,
                });
            }
            ["property", ty, name] => {
                let e = elements
                    .last_mut()
                    .ok_or_else(|| IoError::format(path, pos(), "property before any element"))?;
                e.properties.push(PlyProperty {
                    name: name.to_string(),
                    list: None,
                    ty: PlyType::parse(ty)
                        .ok_or_else(|| IoError::format(path, pos(), format!("type '{ty}'")))?,
                });
            }
            _ => {
                return Err(IoError::format(
                    path,
                    pos(),
                    format!("unexpected header line '{line}'"),
                ))
            }
        }
    }
    let format =
        format.ok_or_else(|| IoError::format(path, Position::Field("format".into()), "missing"))?;
    let mut mesh = Mesh::new();
    let vertex_count = elements
        .iter()
        .find(|e| e.name == "vertex")
        .map_or(0, |e| e.count);
    // Absurd counts are refused before allocating or looping: every property of an item takes
    // at least its size in binary, at least two characters (a digit and a separator) in ASCII.
    let data_len = bytes.len().saturating_sub(data_start);
    for e in &elements {
        let least: usize = e
            .properties
            .iter()
            .map(|p| match format {
                0 => 2,
                _ => p.list.unwrap_or(p.ty).size(),
            })
            .sum();
        // (The last ASCII token needs no separator.)
        let fits = (data_len + 1).checked_div(least).unwrap_or(e.count);
        if e.count > fits {
            return Err(IoError::format(
                path,
                Position::Field(format!("element {}", e.name)),
                format!(
                    "{} items cannot fit in the {data_len} bytes of data",
                    e.count
                ),
            ));
        }
    }
    let mut reader = PlyData {
        path,
        bytes,
        at: data_start,
        format,
        tokens: None,
    };
    if format == 0 {
        reader.tokens = Some(ascii_tokens(&bytes[data_start..]));
    }
    for e in &elements {
        let is_vertex = e.name == "vertex";
        let is_face = e.name == "face";
        let xyz = ["x", "y", "z"].map(|n| {
            e.properties
                .iter()
                .position(|p| p.name == n && p.list.is_none())
        });
        let nxyz = ["nx", "ny", "nz"].map(|n| {
            e.properties
                .iter()
                .position(|p| p.name == n && p.list.is_none())
        });
        if is_vertex && xyz.iter().any(Option::is_none) {
            return Err(IoError::format(
                path,
                Position::Field("element vertex".into()),
                "needs x, y and z properties",
            ));
        }
        let has_normals = is_vertex && nxyz.iter().all(Option::is_some);
        let face_list = e.properties.iter().position(|p| {
            (p.name == "vertex_indices" || p.name == "vertex_index") && p.list.is_some()
        });
        if is_face && face_list.is_none() {
            return Err(IoError::format(
                path,
                Position::Field("element face".into()),
                "needs a vertex_indices list",
            ));
        }
        let mut scalars = vec![0.0f64; e.properties.len()];
        let mut polygon: Vec<i64> = Vec::new();
        // Items without properties take no bytes: nothing to read, however many.
        let count = if e.properties.is_empty() { 0 } else { e.count };
        for _ in 0..count {
            for (pi, p) in e.properties.iter().enumerate() {
                match p.list {
                    None => scalars[pi] = reader.scalar(p.ty)?,
                    Some(ct) => {
                        let n = reader.scalar(ct)?;
                        if !(0.0..=1_000_000.0).contains(&n) {
                            return Err(reader.error(format!("list length {n}")));
                        }
                        let keep = is_face && Some(pi) == face_list;
                        if keep {
                            polygon.clear();
                        }
                        for _ in 0..n as usize {
                            let v = reader.scalar(p.ty)?;
                            if keep {
                                polygon.push(v as i64);
                            }
                        }
                    }
                }
            }
            if is_vertex {
                let pos = reader.position();
                let c = xyz.map(|i| scalars[i.expect("checked")]);
                mesh.positions.push([
                    check_coordinate(path, || pos.clone(), c[0])?,
                    check_coordinate(path, || pos.clone(), c[1])?,
                    check_coordinate(path, || pos.clone(), c[2])?,
                ]);
                if has_normals {
                    mesh.normals
                        .push(nxyz.map(|i| scalars[i.expect("checked")] as f32));
                }
            } else if is_face {
                let pos = reader.position();
                push_polygon(path, || pos.clone(), &mut mesh, &polygon, vertex_count)?;
            }
        }
    }
    Ok(mesh)
}

struct PlyData<'a> {
    path: &'a Path,
    bytes: &'a [u8],
    at: usize,
    format: u8,
    /// ASCII tokens with their line numbers (relative to the data start).
    tokens: Option<std::vec::IntoIter<(usize, &'a str)>>,
}

impl PlyData<'_> {
    fn position(&self) -> Position {
        if self.format == 0 {
            Position::File
        } else {
            Position::Byte(self.at as u64)
        }
    }

    fn error(&self, reason: String) -> IoError {
        IoError::format(self.path, self.position(), reason)
    }

    fn scalar(&mut self, ty: PlyType) -> Result<f64, IoError> {
        if let Some(tokens) = &mut self.tokens {
            let (line, tok) = tokens.next().ok_or_else(|| {
                IoError::format(
                    self.path,
                    Position::File,
                    "the data ends before the header's element counts are reached",
                )
            })?;
            return tok.parse::<f64>().map_err(|_| {
                IoError::format(
                    self.path,
                    Position::Field(format!("data line {line}")),
                    format!("'{tok}' is not a number"),
                )
            });
        }
        let n = ty.size();
        let b = self.bytes.get(self.at..self.at + n).ok_or_else(|| {
            IoError::format(
                self.path,
                Position::Byte(self.at as u64),
                "the data ends before the header's element counts are reached",
            )
        })?;
        self.at += n;
        Ok(ty.decode(b, self.format == 2))
    }
}

fn ascii_tokens(data: &[u8]) -> std::vec::IntoIter<(usize, &str)> {
    let text = match std::str::from_utf8(data) {
        Ok(t) => t,
        Err(e) => std::str::from_utf8(&data[..e.valid_up_to()]).unwrap_or(""),
    };
    text.lines()
        .enumerate()
        .flat_map(|(n, l)| l.split_whitespace().map(move |t| (n + 1, t)))
        .collect::<Vec<_>>()
        .into_iter()
}

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).position(|w| w == needle)
}

/// The first three words of a vertex line as checked coordinates.
fn vertex_from_words<'a>(
    path: &Path,
    pos: impl Fn() -> Position + Copy,
    words: impl Iterator<Item = &'a str>,
) -> Result<[f32; 3], IoError> {
    let c: Vec<f64> = words
        .take(3)
        .map(|w| {
            w.parse::<f64>()
                .map_err(|_| IoError::format(path, pos(), format!("'{w}' is not a number")))
        })
        .collect::<Result<_, _>>()?;
    if c.len() < 3 {
        return Err(IoError::format(
            path,
            pos(),
            "a vertex needs three coordinates",
        ));
    }
    Ok([
        check_coordinate(path, pos, c[0])?,
        check_coordinate(path, pos, c[1])?,
        check_coordinate(path, pos, c[2])?,
    ])
}

/// A text file's content, or an error naming the line where it stops being UTF-8.
fn utf8_text<'a>(path: &Path, bytes: &'a [u8]) -> Result<&'a str, IoError> {
    std::str::from_utf8(bytes).map_err(|e| {
        let line = bytes[..e.valid_up_to()]
            .iter()
            .filter(|&&b| b == b'\n')
            .count()
            + 1;
        IoError::format(path, Position::Line(line), "not valid UTF-8 text")
    })
}

/// OFF (and its `NOFF`/`COFF`/`CNOFF` headers, whose extra vertex columns are skipped):
/// `#` comments, counts, vertices, then faces as a count and indices (extra face colours are
/// skipped too).
fn read_off(path: &Path, bytes: &[u8]) -> Result<Mesh, IoError> {
    let text = utf8_text(path, bytes)?;
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(n, l)| (n + 1, l.split('#').next().unwrap_or("").trim()))
        .filter(|(_, l)| !l.is_empty());
    let end = |what: &str| IoError::format(path, Position::File, format!("ends before {what}"));
    let (n, header) = lines.next().ok_or_else(|| end("the OFF header"))?;
    let keyword = header.split_whitespace().next().unwrap_or("");
    match keyword {
        "OFF" | "NOFF" | "COFF" | "CNOFF" | "NCOFF" => {}
        _ => {
            return Err(IoError::format(
                path,
                Position::Line(n),
                format!("'{keyword}' is not an OFF header"),
            ))
        }
    }
    // The counts may follow the keyword on its line.
    let rest: Vec<&str> = header.split_whitespace().skip(1).collect();
    let (n, counts) = if rest.is_empty() {
        let (n, l) = lines.next().ok_or_else(|| end("the counts"))?;
        (n, l.split_whitespace().collect::<Vec<_>>())
    } else {
        (n, rest)
    };
    let count = |i: usize, what: &str| -> Result<usize, IoError> {
        counts
            .get(i)
            .and_then(|w| w.parse::<usize>().ok())
            .ok_or_else(|| IoError::format(path, Position::Line(n), format!("no {what} count")))
    };
    let (vertices, faces) = (count(0, "vertex")?, count(1, "face")?);
    // Each vertex and face takes a line: more than the file has lines is a lie, caught before
    // allocating.
    if vertices.saturating_add(faces) > text.len() {
        return Err(IoError::format(
            path,
            Position::Line(n),
            format!("{vertices} vertices and {faces} faces cannot fit in the file"),
        ));
    }
    let mut mesh = Mesh::new();
    mesh.positions.reserve(vertices);
    for _ in 0..vertices {
        let (n, l) = lines.next().ok_or_else(|| end("all vertices"))?;
        let pos = || Position::Line(n);
        mesh.positions
            .push(vertex_from_words(path, pos, l.split_whitespace())?);
    }
    for _ in 0..faces {
        let (n, l) = lines.next().ok_or_else(|| end("all faces"))?;
        let pos = || Position::Line(n);
        let mut words = l.split_whitespace();
        let k: usize = words
            .next()
            .and_then(|w| w.parse().ok())
            .ok_or_else(|| IoError::format(path, pos(), "a face starts with its vertex count"))?;
        let polygon: Vec<i64> = words
            .by_ref()
            .take(k)
            .map(|w| {
                w.parse::<i64>().map_err(|_| {
                    IoError::format(path, pos(), format!("'{w}' is not a vertex index"))
                })
            })
            .collect::<Result<_, _>>()?;
        if polygon.len() < k {
            return Err(IoError::format(
                path,
                pos(),
                format!("the face lists {} of its {k} vertices", polygon.len()),
            ));
        }
        push_polygon(path, pos, &mut mesh, &polygon, vertices)?;
    }
    Ok(mesh)
}

fn read_obj(path: &Path, bytes: &[u8]) -> Result<Mesh, IoError> {
    let text = utf8_text(path, bytes)?;
    let mut mesh = Mesh::new();
    let mut faces: Vec<(usize, Vec<i64>)> = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let pos = || Position::Line(n + 1);
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => {
                mesh.positions.push(vertex_from_words(path, pos, words)?);
            }
            Some("f") => {
                let count = mesh.positions.len() as i64;
                let polygon: Vec<i64> = words
                    .map(|w| {
                        let first = w.split('/').next().unwrap_or("");
                        let i: i64 = first.parse().map_err(|_| {
                            IoError::format(path, pos(), format!("'{w}' is not a vertex reference"))
                        })?;
                        match i {
                            0 => Err(IoError::format(
                                path,
                                pos(),
                                "vertex index 0 (OBJ counts from 1)",
                            )),
                            i if i < 0 => Ok(count + i),
                            i => Ok(i - 1),
                        }
                    })
                    .collect::<Result<_, _>>()?;
                faces.push((n + 1, polygon));
            }
            _ => {}
        }
    }
    let count = mesh.positions.len();
    for (line, polygon) in faces {
        push_polygon(path, || Position::Line(line), &mut mesh, &polygon, count)?;
    }
    Ok(mesh)
}

fn read_stl(path: &Path, bytes: &[u8]) -> Result<Mesh, IoError> {
    let binary_size = |n: u32| 84 + 50 * n as u64;
    let is_binary = bytes.len() >= 84
        && binary_size(u32::from_le_bytes([
            bytes[80], bytes[81], bytes[82], bytes[83],
        ])) == bytes.len() as u64;
    let mut triangles: Vec<[[f32; 3]; 3]> = Vec::new();
    if is_binary {
        for (t, rec) in bytes[84..].chunks_exact(50).enumerate() {
            let mut tri = [[0.0f32; 3]; 3];
            for (v, corner) in tri.iter_mut().enumerate() {
                for (a, c) in corner.iter_mut().enumerate() {
                    let o = 12 + 12 * v + 4 * a;
                    let x = f32::from_le_bytes([rec[o], rec[o + 1], rec[o + 2], rec[o + 3]]);
                    *c = check_coordinate(
                        path,
                        || Position::Byte((84 + 50 * t + o) as u64),
                        f64::from(x),
                    )?;
                }
            }
            triangles.push(tri);
        }
    } else if bytes.starts_with(b"solid") {
        let text = std::str::from_utf8(bytes).map_err(|e| {
            IoError::format(
                path,
                Position::Byte(e.valid_up_to() as u64),
                "ASCII STL is not valid text",
            )
        })?;
        let mut corners: Vec<[f32; 3]> = Vec::new();
        let mut ended = false;
        for (n, line) in text.lines().enumerate() {
            let pos = || Position::Line(n + 1);
            let mut words = line.split_whitespace();
            match words.next() {
                Some("vertex") => {
                    let c: Vec<f64> = words
                        .map(|w| {
                            w.parse::<f64>().map_err(|_| {
                                IoError::format(path, pos(), format!("'{w}' is not a number"))
                            })
                        })
                        .collect::<Result<_, _>>()?;
                    if c.len() != 3 {
                        return Err(IoError::format(
                            path,
                            pos(),
                            "a vertex needs three coordinates",
                        ));
                    }
                    corners.push([
                        check_coordinate(path, pos, c[0])?,
                        check_coordinate(path, pos, c[1])?,
                        check_coordinate(path, pos, c[2])?,
                    ]);
                }
                Some("endloop") => {
                    if corners.len() != 3 {
                        return Err(IoError::format(
                            path,
                            pos(),
                            format!("a facet needs 3 vertices, this one has {}", corners.len()),
                        ));
                    }
                    triangles.push([corners[0], corners[1], corners[2]]);
                    corners.clear();
                }
                Some("endsolid") => ended = true,
                _ => {}
            }
        }
        // A cut file would otherwise pass for a smaller mesh.
        if !corners.is_empty() || !ended {
            return Err(IoError::format(
                path,
                Position::Line(text.lines().count()),
                "the file ends before 'endsolid' (cut short?)",
            ));
        }
    } else {
        return Err(IoError::format(
            path,
            Position::File,
            format!("neither binary STL (size {} does not match the triangle count) nor ASCII STL (no 'solid')", bytes.len()),
        ));
    }
    // Weld corners with bit-identical coordinates (−0 and +0 are the same point).
    let mut mesh = Mesh::new();
    let mut index: HashMap<[u32; 3], u32> = HashMap::new();
    for tri in triangles {
        let ids = tri.map(|p| {
            let key = p.map(|c| if c == 0.0 { 0 } else { c.to_bits() });
            *index.entry(key).or_insert_with(|| {
                mesh.positions.push(p);
                (mesh.positions.len() - 1) as u32
            })
        });
        mesh.triangles.push(ids);
    }
    Ok(mesh)
}

#[cfg(test)]
mod tests {
    use super::*;
    use isocube::extract::{extract, ExtractOptions};
    use isocube::field::Sample;

    fn torus() -> Mesh {
        extract(&Sample::Torus.grid(20), &ExtractOptions::default())
            .unwrap()
            .0
    }

    /// Chunks meshed apart, outlined, laid out and written piece by piece into one PLY (their
    /// outlines and places passed as bytes, as between a cluster's processes, and the pieces
    /// written last chunk first) give the bytes of the whole mesh written at once: for boxes
    /// of every shape (runs of one row, of whole layers, one run), ternary and binary, with
    /// and without normals, on a smooth field and on random 0/1 voxels. (Flat shared vertices,
    /// whose normals the layout fills, are tested in the library.)
    #[test]
    fn ply_written_in_place_is_the_whole_file() {
        use isocube::extract::{
            CellBox, ChunkOutline, ChunkPlace, Extractor, JoinLayout, Method, Snapping,
        };
        use isocube::field::Grid;
        let dir = tempfile::tempdir().unwrap();
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        let noise: Vec<f32> = (0..26 * 24 * 22)
            .map(|_| {
                seed ^= seed << 13;
                seed ^= seed >> 7;
                seed ^= seed << 17;
                (seed >> 40 & 1) as f32
            })
            .collect();
        let grids = [
            ("tangle", Sample::Tangle.grid(30), 0.0),
            ("noise", Grid::new([26, 24, 22], noise).unwrap(), 0.5),
        ];
        let ternary = Method::Ternary(Snapping::default());
        for (name, grid, level) in &grids {
            let d = grid.dims();
            let cells = d.map(|n| n - 1);
            for (o, options) in [
                ExtractOptions::default(),
                ExtractOptions::default().with_normals(false),
                ExtractOptions::default().with_method(ternary),
            ]
            .into_iter()
            .enumerate()
            {
                let options = options.with_level(*level);
                let whole = extract(grid, &options).unwrap().0;
                let expected = dir.path().join(format!("{name}{o}.ply"));
                write_mesh(&expected, &whole, &MeshWriteOptions::default()).unwrap();
                let expected = std::fs::read(&expected).unwrap();
                let extractor = Extractor::new(grid, &options).unwrap();
                for tile in [
                    [7, 5, 3],
                    [cells[0], 6, 4],
                    [cells[0], cells[1], 5],
                    [9, 9, 9],
                ] {
                    let chunks: Vec<_> = CellBox::tile(d, tile)
                        .unwrap()
                        .into_iter()
                        .map(|b| extractor.mesh_box(b).unwrap())
                        .collect();
                    let outlines: Vec<_> = chunks
                        .iter()
                        .map(|c| ChunkOutline::from_bytes(&c.outline(d).to_bytes()).unwrap())
                        .collect();
                    let layout = JoinLayout::new(d, &outlines).unwrap();
                    assert_eq!(layout.vertices(), whole.vertex_count());
                    let ply = PlyLayout::new(
                        layout.vertices() as u64,
                        layout.triangles() as u64,
                        options.normals,
                    );
                    let path = dir.path().join("in-place.ply");
                    let _ = std::fs::remove_file(&path);
                    ply.create(&path).unwrap();
                    for (n, (chunk, place)) in chunks.iter().zip(layout.places()).enumerate().rev()
                    {
                        let place = ChunkPlace::from_bytes(&place.to_bytes()).unwrap();
                        ply.write_pieces(&path, &place.place(chunk).unwrap())
                            .unwrap();
                        if n == chunks.len() / 2 {
                            // A retried creation keeps the pieces written.
                            ply.create(&path).unwrap();
                        }
                    }
                    let got = std::fs::read(&path).unwrap();
                    assert!(
                        got == expected,
                        "{name}, options {o}, boxes of {tile:?}: the file differs from the whole mesh's"
                    );
                }
            }
        }
    }

    #[test]
    fn round_trip_every_format() {
        let dir = tempfile::tempdir().unwrap();
        let mesh = torus();
        for (name, ascii) in [
            ("a.ply", false),
            ("b.ply", true),
            ("c.obj", false),
            ("d.stl", false),
            ("e.off", false),
        ] {
            let p = dir.path().join(name);
            write_mesh(
                &p,
                &mesh,
                &MeshWriteOptions {
                    ascii,
                    normals: true,
                },
            )
            .unwrap();
            let back = read_mesh(&p).unwrap();
            assert_eq!(back.triangles.len(), mesh.triangles.len(), "{name}");
            assert_eq!(back.positions.len(), mesh.positions.len(), "{name}");
            if name.ends_with("stl") {
                assert_eq!(back.report().euler, mesh.report().euler);
                assert!(back.report().watertight);
            } else {
                assert_eq!(back.positions, mesh.positions, "{name}");
                assert_eq!(back.triangles, mesh.triangles, "{name}");
            }
            if name.ends_with("ply") {
                assert_eq!(back.normals, mesh.normals);
            }
        }
        // No temporary files left behind.
        let names: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names.len(), 5, "{names:?}");
    }

    #[test]
    fn off_headers_comments_and_errors() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("q.off");
        std::fs::write(
            &p,
            "# a square\nOFF 4 1 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0 # last\n4 0 1 2 3\n",
        )
        .unwrap();
        let m = read_mesh(&p).unwrap();
        assert_eq!((m.positions.len(), m.triangles.len()), (4, 2));
        std::fs::write(
            &p,
            "NOFF\n3 1 0\n0 0 0 0 0 1\n1 0 0 0 0 1\n0 1 0 0 0 1\n3 0 1 2\n",
        )
        .unwrap();
        assert_eq!(read_mesh(&p).unwrap().triangles.len(), 1);
        for (text, says) in [
            ("PLY\n", "not an OFF header"),
            ("OFF\n3 1 0\n0 0 0\n1 0 0\n", "ends before all vertices"),
            ("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n", "outside 0..3"),
            ("OFF\n3 1 0\n0 0 0\n1 0 x\n0 1 0\n3 0 1 2\n", "line 4"),
            ("OFF\n99999999 1 0\n", "cannot fit"),
            (
                "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1\n",
                "lists 2 of its 3",
            ),
        ] {
            std::fs::write(&p, text).unwrap();
            let e = read_mesh(&p).unwrap_err().to_string();
            assert!(e.contains(says) && e.contains("q.off"), "{text:?}: {e}");
        }
    }

    #[test]
    fn formats_without_a_reader_say_so_and_values_need_a_format_that_holds_them() {
        let dir = tempfile::tempdir().unwrap();
        let mesh = torus();
        let values: Vec<f32> = (0..mesh.positions.len()).map(|i| i as f32).collect();
        let v = Some(VertexValues {
            name: "index",
            values: &values,
        });
        let options = MeshWriteOptions::default();
        for name in ["a.glb", "a.vtp", "a.vtk", "a.msh", "a.ply"] {
            let p = dir.path().join(name);
            write_mesh_with_values(&p, &mesh, &options, v).unwrap();
            if !MeshFormat::from_path(&p).unwrap().readable() {
                let e = read_mesh(&p).unwrap_err().to_string();
                assert!(e.contains("reads only"), "{e}");
            }
        }
        let e = write_mesh_with_values(&dir.path().join("a.obj"), &mesh, &options, v)
            .unwrap_err()
            .to_string();
        assert!(e.contains("no per-vertex values"), "{e}");
        let short = Some(VertexValues {
            name: "index",
            values: &values[1..],
        });
        let e = write_mesh_with_values(&dir.path().join("b.vtp"), &mesh, &options, short)
            .unwrap_err()
            .to_string();
        assert!(e.contains("values for"), "{e}");
        assert!(!dir.path().join("a.obj").exists() && !dir.path().join("b.vtp").exists());
    }

    #[test]
    fn failed_write_leaves_target_untouched() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("keep.ply");
        std::fs::write(&p, b"precious").unwrap();
        let mut bad = torus();
        bad.triangles.push([0, 1, u32::MAX]);
        assert!(write_mesh(&p, &bad, &MeshWriteOptions::default()).is_err());
        assert_eq!(std::fs::read(&p).unwrap(), b"precious");
        let missing = dir.path().join("no/such/dir/m.ply");
        assert!(matches!(
            write_mesh(&missing, &torus(), &MeshWriteOptions::default()),
            Err(IoError::Os { .. })
        ));
    }

    #[test]
    fn malformed_meshes_are_rejected() {
        let dir = tempfile::tempdir().unwrap();
        let cases: [(&str, &[u8], &str); 8] = [
            ("a.ply", b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n", "outside 0..3"),
            ("b.ply", b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n0.0 0.0 0.0\n1.0 0.0\n", "ends before"),
            ("c.ply", b"plx\n", "end_header"),
            ("d.ply", b"ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nend_header\n\x00\x00", "2 items cannot fit in the 2 bytes"),
            ("e.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", "line 4"),
            ("f.obj", b"v 0 0 nan\n", "not a finite"),
            ("g.stl", b"garbage that is not an stl", "neither binary"),
            ("h.obj", b"v 0 0 0\nf 1 x 2\n", "'x' is not a vertex reference"),
        ];
        for (name, bytes, needle) in cases {
            let p = dir.path().join(name);
            std::fs::write(&p, bytes).unwrap();
            let err = read_mesh(&p).unwrap_err().to_string();
            assert!(err.contains(needle) && err.contains(name), "{name}: {err}");
        }
    }
}
