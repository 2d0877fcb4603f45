//! Polygon meshes for subdivision: OBJ with OpenSubdiv's tags (and isocube's inner-loop tag),
//! or the triangle meshes of PLY/STL/OBJ files as the cage.

use std::path::Path;

use super::mesh_io::{read_mesh_bytes, write_atomic, write_mesh, MeshFormat, MeshWriteOptions};
use super::{read_file, IoError, Position};
use isocube::subdiv::{Face, PolyMesh, SubdivError};

/// Errors found after parsing name the line of the face or tag they are about.
fn subdiv_error(path: &Path, text: &str, e: SubdivError) -> IoError {
    // The 1-based line of the `n`-th line (from 0) whose first word is `word`, and for tags
    // whose second word is `name`.
    let find = |word: &str, name: Option<&str>, n: usize| {
        text.lines()
            .enumerate()
            .filter(|(_, l)| {
                let mut w = l.split_whitespace();
                w.next() == Some(word) && name.is_none_or(|name| w.next() == Some(name))
            })
            .nth(n)
            .map(|(k, _)| k + 1)
    };
    let line = match &e {
        SubdivError::Parse { line, reason } => {
            return IoError::format(path, Position::Line(*line), reason.clone())
        }
        SubdivError::Face { face, .. } | SubdivError::Holes { face, .. } => find("f", None, *face),
        SubdivError::Tag { tag, .. } => find("t", Some(tag), 0),
        _ => None,
    };
    let position = line.map_or(Position::File, Position::Line);
    IoError::format(path, position, e.to_string())
}

/// Reads a polygon mesh: OBJ keeps its polygons and tags (creases, corners, holes, boundary
/// rule, inner loops); PLY and STL give their triangles (STL welded by exact position).
pub fn read_poly_mesh(path: &Path) -> Result<PolyMesh, IoError> {
    read_poly_mesh_bytes(&read_file(path)?, path)
}

/// [`read_poly_mesh`] on a file's content already in memory; `name`'s extension chooses the
/// format and `name` appears in errors.
pub fn read_poly_mesh_bytes(bytes: &[u8], name: &Path) -> Result<PolyMesh, IoError> {
    let path = name;
    match MeshFormat::from_path(path) {
        Some(MeshFormat::Obj) => {
            let text = std::str::from_utf8(bytes).map_err(|e| {
                IoError::format(
                    path,
                    Position::Byte(e.valid_up_to() as u64),
                    "not UTF-8 text",
                )
            })?;
            PolyMesh::from_obj(text).map_err(|e| subdiv_error(path, text, e))
        }
        _ => {
            let mesh = read_mesh_bytes(bytes, path)?;
            Ok(PolyMesh {
                positions: mesh.positions.iter().map(|p| p.map(f64::from)).collect(),
                faces: mesh
                    .triangles
                    .iter()
                    .map(|t| Face::new(t.to_vec()))
                    .collect(),
                ..PolyMesh::default()
            })
        }
    }
}

/// Writes a polygon mesh atomically: OBJ with its polygons and tags (read back by
/// [`read_poly_mesh`] to the same mesh); PLY or STL as the triangles of its faces that are not
/// holes.
pub fn write_poly_mesh(
    path: &Path,
    mesh: &PolyMesh,
    options: &MeshWriteOptions,
) -> Result<(), IoError> {
    match MeshFormat::from_path(path) {
        Some(MeshFormat::Obj) => {
            let text = mesh.to_obj();
            write_atomic(path, &mut |w| w.write_all(text.as_bytes()))
        }
        _ => {
            let triangles = mesh.triangulate().map_err(|e| subdiv_error(path, "", e))?;
            write_mesh(path, &triangles, options)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::read_mesh;

    #[test]
    fn obj_round_trips_tags_and_inner_loops() {
        let text = "v 0 0 0\nv 4 0 0\nv 4 4 0\nv 0 4 0\nv 1 1 0\nv 1 3 0\nv 3 3 0\nv 3 1 0\n\
                    f 1 2 3 4\nt innerloop 5/0/0 0 4 5 6 7\nt crease 2/1/0 0 1 2.5\n\
                    t corner 1/1/0 2 10\nt interpolateboundary 1/0/0 1\n";
        let mesh = PolyMesh::from_obj(text).unwrap();
        assert_eq!(mesh.faces[0].inner, vec![vec![4, 5, 6, 7]]);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.obj");
        write_poly_mesh(&path, &mesh, &MeshWriteOptions::default()).unwrap();
        assert_eq!(read_poly_mesh(&path).unwrap(), mesh);
        // As triangles: the face with its hole is 8 triangles.
        let ply = dir.path().join("m.ply");
        write_poly_mesh(&ply, &mesh, &MeshWriteOptions::default()).unwrap();
        assert_eq!(read_mesh(&ply).unwrap().triangles.len(), 8);
        // Errors name the line.
        std::fs::write(&path, "v 0 0 0\nf 1 2 x\n").unwrap();
        let e = read_poly_mesh(&path).unwrap_err().to_string();
        assert!(e.contains("line 2"), "{e}");
    }
}
