//! `isocube info MESH [--json]`.

use std::path::PathBuf;

use clap::Args as ClapArgs;
use isocube::mesh::MeshReport;
use isocube_io::{read_mesh, read_poly_mesh};
use serde_json::json;

use crate::Failure;

#[derive(Debug, ClapArgs)]
pub(crate) struct Args {
    /// A .ply, .obj or .stl mesh.
    mesh: PathBuf,
    /// Print JSON instead of a table.
    #[arg(long)]
    json: bool,
}

pub(crate) fn run(args: &Args) -> Result<(), Failure> {
    // OBJ may hold polygons with inner loops and hole tags: read it as a polygon mesh when it can
    // be one (a file with, say, a face repeating a vertex is still reported, as triangles).
    let obj = isocube_io::MeshFormat::from_path(&args.mesh) == Some(isocube_io::MeshFormat::Obj);
    let mesh = match obj.then(|| read_poly_mesh(&args.mesh)) {
        Some(Ok(poly)) => match poly.triangulate() {
            Ok(mesh) => mesh,
            Err(_) => read_mesh(&args.mesh).map_err(|e| crate::io_failure(e, true))?,
        },
        _ => read_mesh(&args.mesh).map_err(|e| crate::io_failure(e, true))?,
    };
    let r = mesh.report();
    if args.json {
        println!("{}", to_json(&r));
    } else {
        print!("{}", to_table(&r));
    }
    Ok(())
}

fn angle(a: f64) -> serde_json::Value {
    if a.is_finite() {
        json!((a * 1e4).round() / 1e4)
    } else {
        serde_json::Value::Null
    }
}

pub(crate) fn to_json(r: &MeshReport) -> serde_json::Value {
    json!({
        "vertices": r.vertices,
        "triangles": r.triangles,
        "edges": r.edges,
        "boundary_edges": r.boundary_edges,
        "nonmanifold_edges": r.nonmanifold_edges,
        "watertight": r.watertight,
        "oriented": r.oriented,
        "components": r.components,
        "euler": r.euler,
        "genus": r.genus,
        "degenerate": r.degenerate,
        "min_angle": angle(r.min_angle),
        "max_angle": angle(r.max_angle),
        "area": r.area,
        "volume": r.volume,
    })
}

fn to_table(r: &MeshReport) -> String {
    let yes = |b: bool| if b { "yes" } else { "no" }.to_string();
    let deg = |a: f64| {
        if a.is_finite() {
            format!("{a:.2}")
        } else {
            "-".into()
        }
    };
    let rows = [
        ("vertices", r.vertices.to_string()),
        ("triangles", r.triangles.to_string()),
        ("edges", r.edges.to_string()),
        ("boundary_edges", r.boundary_edges.to_string()),
        ("nonmanifold_edges", r.nonmanifold_edges.to_string()),
        ("watertight", yes(r.watertight)),
        ("oriented", yes(r.oriented)),
        ("components", r.components.to_string()),
        ("euler", r.euler.to_string()),
        ("genus", r.genus.map_or("-".into(), |g| g.to_string())),
        ("degenerate", r.degenerate.to_string()),
        ("min_angle", deg(r.min_angle)),
        ("max_angle", deg(r.max_angle)),
        ("area", format!("{:.6}", r.area)),
        ("volume", r.volume.map_or("-".into(), |v| format!("{v:.6}"))),
    ];
    rows.iter().map(|(k, v)| format!("{k:<18} {v}\n")).collect()
}
