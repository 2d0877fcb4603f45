//! `tetmesh F OPTS`'s boundary is `extract F OPTS`'s file: the same vertex positions and the
//! same triangles, for every option both commands take; with no method given, `tetmesh`'s is
//! ternary extraction's (`extract --method ternary`).

use std::collections::BTreeSet;
use std::path::Path;

mod common;
use common::{isocube, ok};

/// A triangle as its corners' bits, rotated to start at the smallest (orientation kept).
type Key = [[u32; 3]; 3];

fn key(t: [[f32; 3]; 3]) -> Key {
    let p = t.map(|x| x.map(f32::to_bits));
    let r = (0..3).min_by_key(|&r| p[r]).unwrap();
    [p[r], p[(r + 1) % 3], p[(r + 2) % 3]]
}

fn extracted(path: &Path) -> BTreeSet<Key> {
    let mesh = isocube_io::read_mesh(path).unwrap();
    mesh.triangles
        .iter()
        .map(|t| key(t.map(|v| mesh.positions[v as usize])))
        .collect()
}

/// The surface triangles (reference 2) of a MEDIT file `tetmesh` wrote.
fn boundary(path: &Path) -> BTreeSet<Key> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let mut positions: Vec<[f32; 3]> = Vec::new();
    let mut out = BTreeSet::new();
    while let Some(line) = lines.next() {
        let section = line.trim();
        if section != "Vertices" && section != "Triangles" {
            continue;
        }
        let count: usize = lines.next().unwrap().trim().parse().unwrap();
        for _ in 0..count {
            let f: Vec<&str> = lines.next().unwrap().split_whitespace().collect();
            if section == "Vertices" {
                positions.push([0, 1, 2].map(|d| f[d].parse().unwrap()));
            } else if f[3] == "2" {
                let v = [0, 1, 2].map(|d| f[d].parse::<usize>().unwrap() - 1);
                out.insert(key(v.map(|v| positions[v])));
            }
        }
    }
    out
}

#[test]
fn the_boundary_is_the_extracted_surface() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // A ball off the grid's centre, with spacing and a negative origin; and small integers,
    // many of them exactly at the level.
    let n = 18usize;
    let mut ball = Vec::new();
    let mut tied = Vec::new();
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    for i in 0..n {
        for j in 0..n {
            for k in 0..n {
                let c = [i, j, k].map(|x| x as f32 / (n - 1) as f32 * 2.0 - 1.0);
                let r = ((c[0] - 0.07).powi(2) + (c[1] + 0.03).powi(2) + c[2].powi(2)).sqrt();
                ball.extend((r - 0.71).to_le_bytes());
                // Rounded waves: whole sheets and lines of points exactly at the level, a
                // little random jitter in the rounding (random values everywhere, an
                // adversarial input, are meshed too, but take the improvement step seconds).
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                let jitter = (state % 1000) as f32 / 1000.0 - 0.5;
                let wave = (0.9 * i as f32).sin() + (0.7 * j as f32).cos() + (0.8 * k as f32).sin();
                tied.extend(((0.8 * wave + 0.3 * jitter).round() as i16).to_le_bytes());
            }
        }
    }
    let shape = format!("({n}, {n}, {n})");
    std::fs::write(d.join("ball.npy"), common::npy("<f4", &shape, &ball)).unwrap();
    std::fs::write(d.join("tied.npy"), common::npy("<i2", &shape, &tied)).unwrap();
    let inputs: [&[&str]; 5] = [
        &["sample:sphere:16"],
        &["sample:torus:20"],
        &["sample:packed-spheres:20:3"],
        &[
            "ball.npy",
            "--spacing",
            "0.5,0.25,0.75",
            "--origin",
            "-3,-1.5,-7",
        ],
        &["tied.npy", "--origin", "-1,-2,-3"],
    ];
    let options: [&[&str]; 9] = [
        &[],
        &["--flip"],
        &["--method", "mc"],
        &["--method", "mc", "--flip", "--topology", "classic"],
        &[
            "--method",
            "ternary",
            "--snap",
            "0.5",
            "--triangulate",
            "local",
        ],
        &["--snap-position", "grid"],
        &[
            "--snap-position",
            "grid",
            "--flip",
            "--triangulate",
            "optimal",
        ],
        &["--level", "0.1", "--snap", "0.1"],
        &["--topology", "classic", "--flip", "--level", "-0.05"],
    ];
    let mut compared = 0;
    for input in inputs {
        for opts in &options {
            let mut tet = vec!["tetmesh"];
            tet.extend_from_slice(input);
            tet.extend_from_slice(&["-o", "t.mesh"]);
            tet.extend_from_slice(opts);
            let mut ext = vec!["extract"];
            ext.extend_from_slice(input);
            ext.extend_from_slice(&["-o", "s.ply"]);
            ext.extend_from_slice(opts);
            if !opts.contains(&"--method") {
                ext.extend_from_slice(&["--method", "ternary"]);
            }
            let what = format!("{tet:?}");
            let out = isocube(d, &tet);
            let err = String::from_utf8_lossy(&out.stderr).to_string();
            if input[0] == "tied.npy" && opts.contains(&"mc") && !out.status.success() {
                // Marching Cubes on ties may not bound a region: it says why, and the remedy.
                assert!(err.contains("--method ternary"), "{what}: {err}");
                continue;
            }
            assert!(out.status.success(), "{what}: {err}");
            assert!(
                err.contains("check: conforming, 0 inverted"),
                "{what}: {err}"
            );
            ok(d, &ext);
            let (want, got) = (extracted(&d.join("s.ply")), boundary(&d.join("t.mesh")));
            assert!(!want.is_empty(), "{what}");
            assert_eq!(want.len(), got.len(), "{what}");
            assert!(
                want == got,
                "{what}: {} triangles differ",
                want.difference(&got).count()
            );
            compared += 1;
        }
    }
    assert!(compared >= 43, "{compared}");
}
