//! Mesh writers for the programs people take meshes to: binary glTF (`.glb`: web viewers,
//! Blender), VTK PolyData (`.vtp` XML and legacy `.vtk`: ParaView), OFF (geometry tools) and
//! Gmsh MSH 4.1 (`.msh`: FEM pipelines).
//!
//! Each writes positions and triangles, and, when asked and the format can hold them, unit
//! vertex normals and one scalar per vertex ([`VertexValues`]). Byte orders, index widths and
//! size limits are those of the format's specification; a mesh too large for a format is an
//! error, never a truncated file.

use std::borrow::Cow;
use std::io::{self, Write};

use super::blocks::write_blocks;
use isocube::mesh::Mesh;

/// One scalar per vertex, written under `name` (for example the value of a second volume at
/// each vertex).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VertexValues<'a> {
    /// The array's name in the file.
    pub name: &'a str,
    /// One value per vertex, in vertex order.
    pub values: &'a [f32],
}

fn too_large(what: &str) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidInput, what.to_string())
}

/// The bounding box of positions (zeros when there are none).
pub(crate) fn bbox(positions: &[[f32; 3]]) -> ([f32; 3], [f32; 3]) {
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for p in positions {
        for d in 0..3 {
            lo[d] = lo[d].min(p[d]);
            hi[d] = hi[d].max(p[d]);
        }
    }
    if positions.is_empty() {
        ([0.0; 3], [0.0; 3])
    } else {
        (lo, hi)
    }
}

/// Binary glTF 2.0: one node, one mesh, one triangle primitive with `POSITION` (and its bounds,
/// which the specification requires), optionally `NORMAL`, and the values as the application
/// attribute `_VALUE` (custom attribute names start with an underscore). Indices are
/// `UNSIGNED_INT`. Coordinates are written as they are; glTF viewers take +y as up.
pub(crate) fn write_glb(
    w: &mut impl Write,
    mesh: &Mesh,
    normals: bool,
    values: Option<VertexValues>,
) -> io::Result<()> {
    let n = mesh.positions.len();
    let mut bin: Vec<u8> = Vec::new();
    let mut views = Vec::new();
    let mut accessors = Vec::new();
    let mut attributes = Vec::new();
    // Each block starts on a 4-byte boundary (every component here is 4 bytes wide).
    let mut block = |bin: &mut Vec<u8>, bytes: &[u8], target: u32| -> usize {
        let offset = bin.len();
        bin.extend_from_slice(bytes);
        views.push(format!(
            r#"{{"buffer":0,"byteOffset":{offset},"byteLength":{},"target":{target}}}"#,
            bytes.len()
        ));
        views.len() - 1
    };
    let (lo, hi) = bbox(&mesh.positions);
    let view = block(&mut bin, &le_bytes(mesh.positions.as_flattened()), 34962);
    accessors.push(format!(
        r#"{{"bufferView":{view},"componentType":5126,"count":{n},"type":"VEC3","min":[{},{},{}],"max":[{},{},{}]}}"#,
        json_f32(lo[0]),
        json_f32(lo[1]),
        json_f32(lo[2]),
        json_f32(hi[0]),
        json_f32(hi[1]),
        json_f32(hi[2])
    ));
    attributes.push(format!(r#""POSITION":{}"#, accessors.len() - 1));
    if normals {
        let view = block(&mut bin, &le_bytes(mesh.normals.as_flattened()), 34962);
        accessors.push(format!(
            r#"{{"bufferView":{view},"componentType":5126,"count":{n},"type":"VEC3"}}"#
        ));
        attributes.push(format!(r#""NORMAL":{}"#, accessors.len() - 1));
    }
    if let Some(v) = values {
        let view = block(&mut bin, &le_bytes(v.values), 34962);
        accessors.push(format!(
            r#"{{"bufferView":{view},"componentType":5126,"count":{n},"type":"SCALAR"}}"#
        ));
        attributes.push(format!(r#""_VALUE":{}"#, accessors.len() - 1));
    }
    let indices: Vec<u8> = mesh
        .triangles
        .as_flattened()
        .iter()
        .flat_map(|i| i.to_le_bytes())
        .collect();
    let view = block(&mut bin, &indices, 34963);
    accessors.push(format!(
        r#"{{"bufferView":{view},"componentType":5125,"count":{},"type":"SCALAR"}}"#,
        3 * mesh.triangles.len()
    ));
    let indices_accessor = accessors.len() - 1;
    let mut json = format!(
        r#"{{"asset":{{"version":"2.0","generator":"isocube {}"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],"meshes":[{{"primitives":[{{"attributes":{{{}}},"indices":{indices_accessor},"mode":4}}]}}],"buffers":[{{"byteLength":{}}}],"bufferViews":[{}],"accessors":[{}]}}"#,
        env!("CARGO_PKG_VERSION"),
        attributes.join(","),
        bin.len(),
        views.join(","),
        accessors.join(",")
    );
    while json.len() % 4 != 0 {
        json.push(' ');
    }
    while bin.len() % 4 != 0 {
        bin.push(0);
    }
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let total = u32::try_from(total).map_err(|_| too_large("a .glb file holds at most 4 GiB"))?;
    w.write_all(b"glTF")?;
    w.write_all(&2u32.to_le_bytes())?;
    w.write_all(&total.to_le_bytes())?;
    w.write_all(&(json.len() as u32).to_le_bytes())?;
    w.write_all(b"JSON")?;
    w.write_all(json.as_bytes())?;
    w.write_all(&(bin.len() as u32).to_le_bytes())?;
    w.write_all(b"BIN\0")?;
    w.write_all(&bin)
}

/// Little-endian bytes of `f32`s (borrowed on little-endian machines).
fn le_bytes(values: &[f32]) -> Cow<'_, [u8]> {
    if cfg!(target_endian = "little") {
        Cow::Borrowed(bytemuck::cast_slice(values))
    } else {
        Cow::Owned(values.iter().flat_map(|x| x.to_le_bytes()).collect())
    }
}

/// A finite `f32` as JSON (shortest round-trip form; JSON has no infinities).
fn json_f32(x: f32) -> String {
    if x.is_finite() {
        format!("{x:?}")
    } else {
        "0.0".into()
    }
}

/// VTK XML PolyData (`.vtp`), with the arrays appended raw (little-endian, 64-bit block
/// headers): points, triangles as `connectivity` and `offsets`, and optional point data.
pub(crate) fn write_vtp(
    w: &mut impl Write,
    mesh: &Mesh,
    normals: bool,
    values: Option<VertexValues>,
) -> io::Result<()> {
    let n = mesh.positions.len();
    let f = mesh.triangles.len();
    // Int32 indices while they fit (half the size), Int64 beyond.
    let wide = n > i32::MAX as usize || 3 * f > i32::MAX as usize;
    let int = if wide { "Int64" } else { "Int32" };
    let int_size = if wide { 8 } else { 4 };
    let mut offset = 0u64;
    let mut next = |bytes: u64| {
        let at = offset;
        offset += 8 + bytes;
        at
    };
    let points = next(12 * n as u64);
    let normals_at = normals.then(|| next(12 * n as u64));
    let values_at = values.map(|_| next(4 * n as u64));
    let connectivity = next(3 * f as u64 * int_size);
    let offsets = next(f as u64 * int_size);
    writeln!(w, r#"<?xml version="1.0"?>"#)?;
    writeln!(
        w,
        r#"<VTKFile type="PolyData" version="1.0" byte_order="LittleEndian" header_type="UInt64">"#
    )?;
    writeln!(w, "  <PolyData>")?;
    writeln!(
        w,
        r#"    <Piece NumberOfPoints="{n}" NumberOfVerts="0" NumberOfLines="0" NumberOfStrips="0" NumberOfPolys="{f}">"#
    )?;
    let mut point_data = String::new();
    if normals {
        point_data.push_str(r#" Normals="Normals""#);
    }
    if let Some(v) = values {
        point_data.push_str(&format!(r#" Scalars="{}""#, xml_escape(v.name)));
    }
    writeln!(w, "      <PointData{point_data}>")?;
    if let Some(at) = normals_at {
        writeln!(
            w,
            r#"        <DataArray type="Float32" Name="Normals" NumberOfComponents="3" format="appended" offset="{at}"/>"#
        )?;
    }
    if let (Some(v), Some(at)) = (values, values_at) {
        writeln!(
            w,
            r#"        <DataArray type="Float32" Name="{}" format="appended" offset="{at}"/>"#,
            xml_escape(v.name)
        )?;
    }
    writeln!(w, "      </PointData>")?;
    writeln!(w, "      <Points>")?;
    writeln!(
        w,
        r#"        <DataArray type="Float32" Name="Points" NumberOfComponents="3" format="appended" offset="{points}"/>"#
    )?;
    writeln!(w, "      </Points>")?;
    writeln!(w, "      <Polys>")?;
    writeln!(
        w,
        r#"        <DataArray type="{int}" Name="connectivity" format="appended" offset="{connectivity}"/>"#
    )?;
    writeln!(
        w,
        r#"        <DataArray type="{int}" Name="offsets" format="appended" offset="{offsets}"/>"#
    )?;
    writeln!(w, "      </Polys>")?;
    writeln!(w, "    </Piece>")?;
    writeln!(w, "  </PolyData>")?;
    write!(w, r#"  <AppendedData encoding="raw">"#)?;
    w.write_all(b"\n   _")?;
    let block = |w: &mut dyn Write, bytes: &[u8]| -> io::Result<()> {
        w.write_all(&(bytes.len() as u64).to_le_bytes())?;
        w.write_all(bytes)
    };
    block(w, &le_bytes(mesh.positions.as_flattened()))?;
    if normals {
        block(w, &le_bytes(mesh.normals.as_flattened()))?;
    }
    if let Some(v) = values {
        block(w, &le_bytes(v.values))?;
    }
    let ints = |it: &mut dyn Iterator<Item = u64>| -> Vec<u8> {
        if wide {
            it.flat_map(|x| (x as i64).to_le_bytes()).collect()
        } else {
            it.flat_map(|x| (x as i32).to_le_bytes()).collect()
        }
    };
    block(
        w,
        &ints(&mut mesh.triangles.as_flattened().iter().map(|&i| u64::from(i))),
    )?;
    block(w, &ints(&mut (1..=f as u64).map(|t| 3 * t)))?;
    writeln!(w, "\n  </AppendedData>")?;
    writeln!(w, "</VTKFile>")
}

fn xml_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('"', "&quot;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// Legacy VTK (`.vtk`, version 4.2, binary: big-endian as the format requires): `POLYDATA` with
/// `POINTS`, `POLYGONS` and optional `POINT_DATA` (`NORMALS`, `SCALARS`).
pub(crate) fn write_legacy_vtk(
    w: &mut impl Write,
    mesh: &Mesh,
    normals: bool,
    values: Option<VertexValues>,
) -> io::Result<()> {
    let n = mesh.positions.len();
    let f = mesh.triangles.len();
    if n > i32::MAX as usize || 4 * f > i32::MAX as usize {
        return Err(too_large(
            "legacy .vtk stores 32-bit indices: use .vtp for a mesh this large",
        ));
    }
    let be = |w: &mut dyn Write, xs: &[f32]| -> io::Result<()> {
        let bytes: Vec<u8> = xs.iter().flat_map(|x| x.to_be_bytes()).collect();
        w.write_all(&bytes)
    };
    writeln!(w, "# vtk DataFile Version 4.2")?;
    writeln!(w, "isocube {} surface", env!("CARGO_PKG_VERSION"))?;
    writeln!(w, "BINARY\nDATASET POLYDATA")?;
    writeln!(w, "POINTS {n} float")?;
    be(w, mesh.positions.as_flattened())?;
    writeln!(w, "\nPOLYGONS {f} {}", 4 * f)?;
    let mut bytes = Vec::with_capacity(16 * f);
    for t in &mesh.triangles {
        bytes.extend_from_slice(&3i32.to_be_bytes());
        for &v in t {
            bytes.extend_from_slice(&(v as i32).to_be_bytes());
        }
    }
    w.write_all(&bytes)?;
    writeln!(w)?;
    if normals || values.is_some() {
        writeln!(w, "POINT_DATA {n}")?;
    }
    if normals {
        writeln!(w, "NORMALS Normals float")?;
        be(w, mesh.normals.as_flattened())?;
        writeln!(w)?;
    }
    if let Some(v) = values {
        // Legacy names cannot hold spaces.
        let name: String = v
            .name
            .chars()
            .map(|c| if c.is_whitespace() { '_' } else { c })
            .collect();
        writeln!(w, "SCALARS {name} float 1\nLOOKUP_TABLE default")?;
        be(w, v.values)?;
        writeln!(w)?;
    }
    Ok(())
}

/// OFF: `OFF`, the counts, positions, then `3 a b c` per triangle (ASCII; the format has no
/// normals or scalars in its plain form).
pub(crate) fn write_off(w: &mut impl Write, mesh: &Mesh) -> io::Result<()> {
    writeln!(w, "OFF")?;
    writeln!(w, "{} {} 0", mesh.positions.len(), mesh.triangles.len())?;
    positions_text(w, &mesh.positions)?;
    // Writing to a Vec cannot fail.
    write_blocks(w, mesh.triangles.len(), |out, r| {
        for t in &mesh.triangles[r] {
            let _ = writeln!(out, "3 {} {} {}", t[0], t[1], t[2]);
        }
    })
}

/// One `x y z` line per position, as Rust prints each `f32` (the shortest text that reads back
/// to the same value).
fn positions_text(w: &mut impl Write, positions: &[[f32; 3]]) -> io::Result<()> {
    write_blocks(w, positions.len(), |out, r| {
        for p in &positions[r] {
            let _ = writeln!(out, "{} {} {}", p[0], p[1], p[2]);
        }
    })
}

/// Gmsh MSH 4.1 (ASCII): one surface entity holding every node and every 3-node triangle
/// (element type 2), tags from 1; normals and values as `$NodeData` views.
pub(crate) fn write_msh(
    w: &mut impl Write,
    mesh: &Mesh,
    normals: bool,
    values: Option<VertexValues>,
) -> io::Result<()> {
    let n = mesh.positions.len();
    let f = mesh.triangles.len();
    let (lo, hi) = bbox(&mesh.positions);
    writeln!(w, "$MeshFormat\n4.1 0 8\n$EndMeshFormat")?;
    writeln!(w, "$Entities\n0 0 1 0")?;
    writeln!(
        w,
        "1 {} {} {} {} {} {} 0 0",
        lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]
    )?;
    writeln!(w, "$EndEntities")?;
    writeln!(w, "$Nodes\n1 {n} 1 {n}")?;
    writeln!(w, "2 1 0 {n}")?;
    write_blocks(w, n, |out, r| {
        for tag in r {
            let _ = writeln!(out, "{}", tag + 1);
        }
    })?;
    positions_text(w, &mesh.positions)?;
    writeln!(w, "$EndNodes")?;
    writeln!(w, "$Elements\n1 {f} 1 {f}")?;
    writeln!(w, "2 1 2 {f}")?;
    write_blocks(w, f, |out, r| {
        for i in r {
            let t = mesh.triangles[i];
            let _ = writeln!(out, "{} {} {} {}", i + 1, t[0] + 1, t[1] + 1, t[2] + 1);
        }
    })?;
    writeln!(w, "$EndElements")?;
    let mut view = |name: &str, components: usize, data: &[f32]| -> io::Result<()> {
        writeln!(w, "$NodeData\n1\n\"{}\"\n1\n0.0", name.replace('"', "'"))?;
        writeln!(w, "3\n0\n{components}\n{n}")?;
        write_blocks(w, data.len() / components, |out, r| {
            for i in r {
                let _ = write!(out, "{}", i + 1);
                for x in &data[i * components..(i + 1) * components] {
                    let _ = write!(out, " {x}");
                }
                out.push(b'\n');
            }
        })?;
        writeln!(w, "$EndNodeData")
    };
    if normals {
        view("Normals", 3, mesh.normals.as_flattened())?;
    }
    if let Some(v) = values {
        view(v.name, 1, v.values)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use isocube::extract::{extract, ExtractOptions};
    use isocube::field::Sample;

    fn mesh() -> (Mesh, Vec<f32>) {
        let m = extract(&Sample::Gyroid.grid(16), &ExtractOptions::default())
            .unwrap()
            .0;
        let values = m.positions.iter().map(|p| p[0] - p[2]).collect();
        (m, values)
    }

    fn u32_at(b: &[u8], at: usize) -> usize {
        u32::from_le_bytes(b[at..at + 4].try_into().unwrap()) as usize
    }

    /// The GLB container: lengths add up, chunks are aligned, and every accessor fits its view
    /// and its view the buffer (what glTF validators check first).
    #[test]
    fn glb_container_and_accessors_are_consistent() {
        let (m, values) = mesh();
        let mut out = Vec::new();
        let v = VertexValues {
            name: "v",
            values: &values,
        };
        write_glb(&mut out, &m, true, Some(v)).unwrap();
        assert_eq!(&out[..4], b"glTF");
        assert_eq!(u32_at(&out, 8), out.len());
        let json_len = u32_at(&out, 12);
        assert_eq!(&out[16..20], b"JSON");
        assert_eq!(json_len % 4, 0);
        let json: serde_json::Value = serde_json::from_slice(&out[20..20 + json_len]).unwrap();
        let bin_at = 20 + json_len;
        let bin_len = u32_at(&out, bin_at);
        assert_eq!(&out[bin_at + 4..bin_at + 8], b"BIN\0");
        assert_eq!(bin_at + 8 + bin_len, out.len());
        assert!(json["buffers"][0]["byteLength"].as_u64().unwrap() as usize <= bin_len);
        let views = json["bufferViews"].as_array().unwrap();
        for a in json["accessors"].as_array().unwrap() {
            let view = &views[a["bufferView"].as_u64().unwrap() as usize];
            let width = match a["type"].as_str().unwrap() {
                "VEC3" => 12,
                _ => 4,
            };
            let count = a["count"].as_u64().unwrap() as usize;
            assert_eq!(view["byteLength"].as_u64().unwrap() as usize, width * count);
            assert_eq!(view["byteOffset"].as_u64().unwrap() % 4, 0);
        }
        let primitive = &json["meshes"][0]["primitives"][0];
        assert_eq!(primitive["mode"], 4);
        for attribute in ["POSITION", "NORMAL", "_VALUE"] {
            let a =
                &json["accessors"][primitive["attributes"][attribute].as_u64().unwrap() as usize];
            assert_eq!(a["count"].as_u64().unwrap() as usize, m.positions.len());
        }
        let indices = &json["accessors"][primitive["indices"].as_u64().unwrap() as usize];
        assert_eq!(
            indices["count"].as_u64().unwrap() as usize,
            3 * m.triangles.len()
        );
        // The bounds the specification requires are the positions' own.
        let pos =
            &json["accessors"][primitive["attributes"]["POSITION"].as_u64().unwrap() as usize];
        let (lo, hi) = bbox(&m.positions);
        for d in 0..3 {
            assert_eq!(pos["min"][d].as_f64().unwrap() as f32, lo[d]);
            assert_eq!(pos["max"][d].as_f64().unwrap() as f32, hi[d]);
        }
    }

    /// VTK XML: each appended block sits at its declared offset, behind its byte count.
    #[test]
    fn vtp_appended_blocks_sit_at_their_offsets() {
        let (m, values) = mesh();
        let mut out = Vec::new();
        let v = VertexValues {
            name: "a<b",
            values: &values,
        };
        write_vtp(&mut out, &m, true, Some(v)).unwrap();
        let text = String::from_utf8_lossy(&out);
        assert!(text.contains(r#"Name="a&lt;b""#));
        let start = text.find("   _").unwrap() + 4;
        let offsets: Vec<usize> = text
            .match_indices("offset=\"")
            .map(|(i, _)| {
                let rest = &text[i + 8..];
                rest[..rest.find('"').unwrap()].parse().unwrap()
            })
            .collect();
        assert_eq!(offsets.len(), 5);
        let n = m.positions.len();
        let f = m.triangles.len();
        // Normals, values, points, connectivity, offsets (document order).
        let expected = [12 * n, 4 * n, 12 * n, 12 * f, 4 * f];
        for (&at, &bytes) in offsets.iter().zip(&expected) {
            let len = u64::from_le_bytes(out[start + at..start + at + 8].try_into().unwrap());
            assert_eq!(len as usize, bytes);
        }
        let points = start + offsets[2] + 8;
        let x = f32::from_le_bytes(out[points..points + 4].try_into().unwrap());
        assert_eq!(x, m.positions[0][0]);
    }

    #[test]
    fn legacy_vtk_is_big_endian_and_counts_match() {
        let (m, values) = mesh();
        let mut out = Vec::new();
        let v = VertexValues {
            name: "my value",
            values: &values,
        };
        write_legacy_vtk(&mut out, &m, true, Some(v)).unwrap();
        let text = String::from_utf8_lossy(&out);
        let n = m.positions.len();
        let f = m.triangles.len();
        let header = format!("POINTS {n} float\n");
        let at = text.find(&header).unwrap() + header.len();
        let x = f32::from_be_bytes(out[at..at + 4].try_into().unwrap());
        assert_eq!(x, m.positions[0][0]);
        assert!(text.contains(&format!("POLYGONS {f} {}", 4 * f)));
        assert!(text.contains(&format!("POINT_DATA {n}")));
        assert!(text.contains("SCALARS my_value float 1"));
    }

    #[test]
    fn msh_lists_every_node_and_triangle_once() {
        let (m, values) = mesh();
        let mut out = Vec::new();
        let v = VertexValues {
            name: "v",
            values: &values,
        };
        write_msh(&mut out, &m, true, Some(v)).unwrap();
        let text = String::from_utf8(out).unwrap();
        let n = m.positions.len();
        let f = m.triangles.len();
        assert!(text.contains(&format!("$Nodes\n1 {n} 1 {n}\n2 1 0 {n}\n")));
        assert!(text.contains(&format!("$Elements\n1 {f} 1 {f}\n2 1 2 {f}\n")));
        assert_eq!(text.matches("$NodeData").count(), 2);
        let t = m.triangles[f - 1];
        assert!(text.contains(&format!("\n{f} {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1)));
    }
}
