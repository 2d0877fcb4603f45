//! Runs the real `isocube` binary in temporary directories.

use std::collections::{HashMap, HashSet};
use std::path::Path;

mod common;
use common::{isocube, ok};

fn info(dir: &Path, mesh: &str) -> serde_json::Value {
    serde_json::from_str(&ok(dir, &["info", mesh, "--json"])).unwrap()
}

/// Checks the TSV of `tables` against its own definition: for every configuration, the value at
/// vertex i equals the representative's value at perm[i], flipped when `flipped` is 1.
fn check_tables(kind: &str, group: &str, classes: usize) {
    let dir = tempfile::tempdir().unwrap();
    let text = ok(dir.path(), &["tables", kind, "--group", group]);
    let mut lines = text.lines();
    assert_eq!(
        lines.next().unwrap(),
        "config\trepresentative\tclass\torbit_size\tflip_class\tperm\tflipped\treversed"
    );
    let base: usize = if kind == "--binary" { 2 } else { 3 };
    let digits = |mut c: usize| {
        let mut d = [0usize; 8];
        for x in &mut d {
            *x = c % base;
            c /= base;
        }
        d
    };
    let mut seen = HashSet::new();
    let mut orbit: HashMap<usize, usize> = HashMap::new();
    let mut rows = 0;
    for line in lines {
        let f: Vec<&str> = line.split('\t').collect();
        assert_eq!(f.len(), 8);
        let config: usize = f[0].parse().unwrap();
        let rep: usize = f[1].parse().unwrap();
        let class: usize = f[2].parse().unwrap();
        let perm: Vec<usize> = f[5].bytes().map(|b| usize::from(b - b'0')).collect();
        let flipped = f[6] == "1";
        assert_eq!(config, rows);
        assert!(rep <= config && (1..=classes).contains(&class));
        let (own, r) = (digits(config), digits(rep));
        for i in 0..8 {
            let v = r[perm[i]];
            assert_eq!(own[i], if flipped { base - 1 - v } else { v });
        }
        seen.insert(class);
        *orbit.entry(class).or_default() += 1;
        assert_eq!(orbit.len(), seen.len());
        rows += 1;
    }
    assert_eq!(rows, base.pow(8));
    assert_eq!(seen.len(), classes, "{kind} {group}");
}

#[test]
fn tables_rows_satisfy_their_definition() {
    check_tables("--binary", "rotations", 23);
    check_tables("--binary", "rotations+flip", 15);
    check_tables("--binary", "all", 14);
    check_tables("--ternary", "rotations", 333);
    check_tables("--ternary", "rotations+flip", 183);
}

#[test]
fn extract_sphere_and_report() {
    let dir = tempfile::tempdir().unwrap();
    ok(
        dir.path(),
        &["extract", "sample:sphere:10", "-o", "s.ply", "--quiet"],
    );
    let r = info(dir.path(), "s.ply");
    assert_eq!(r["triangles"], 524);
    assert_eq!(r["watertight"], true);
    assert_eq!(r["oriented"], true);
    assert_eq!(r["euler"], 2);
    assert_eq!(r["genus"], 0);
    for ext in ["obj", "stl"] {
        let name = format!("s.{ext}");
        ok(dir.path(), &["extract", "sample:sphere:10", "-o", &name]);
        let r = info(dir.path(), &name);
        assert_eq!(r["triangles"], 524);
        assert_eq!(r["watertight"], true);
    }
    let table = ok(dir.path(), &["info", "s.ply"]);
    assert!(table.contains("watertight         yes"));
}

#[test]
fn extract_raw_big_endian_with_level() {
    let dir = tempfile::tempdir().unwrap();
    // A 6×5×4 u16 ramp along z: values 0, 100, 200, 300; the level 150 cuts between z=1 and 2.
    let mut bytes = Vec::new();
    for z in 0..4u16 {
        for _ in 0..5 * 6 {
            bytes.extend_from_slice(&(z * 100).to_be_bytes());
        }
    }
    std::fs::write(dir.path().join("ramp.raw"), bytes).unwrap();
    ok(
        dir.path(),
        &[
            "extract",
            "ramp.raw",
            "--dims",
            "6,5,4",
            "--type",
            "u16",
            "--endian",
            "big",
            "--spacing",
            "1,1,2",
            "--level",
            "150",
            "-o",
            "ramp.obj",
        ],
    );
    let text = std::fs::read_to_string(dir.path().join("ramp.obj")).unwrap();
    let zs: HashSet<String> = text
        .lines()
        .filter(|l| l.starts_with("v "))
        .map(|l| l.split(' ').nth(3).unwrap().to_string())
        .collect();
    assert_eq!(zs.into_iter().collect::<Vec<_>>(), vec!["3".to_string()]);
    let r = info(dir.path(), "ramp.obj");
    assert_eq!(r["triangles"], 2 * 5 * 4);
    assert_eq!(r["euler"], 1);
}

/// `--stream` (memory-mapped input, slab-wise extraction, PLY written piece by piece) gives the
/// same bytes as the in-memory path, with spacing, origin, flip and MC33; and it is refused with
/// a reason where the options need the whole volume.
#[test]
fn a_mesh_past_max_memory_is_refused_and_nothing_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let out = isocube(
        dir.path(),
        &[
            "extract",
            "sample:gyroid:64",
            "--max-memory",
            "3M",
            "-o",
            "g.ply",
        ],
    );
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("sample:gyroid:64") && err.contains("--max-memory"),
        "{err}"
    );
    assert!(!dir.path().join("g.ply").exists());
    ok(
        dir.path(),
        &[
            "extract",
            "sample:gyroid:64",
            "--max-memory",
            "64M",
            "-o",
            "g.ply",
        ],
    );
    assert!(dir.path().join("g.ply").exists());
}

#[test]
fn streamed_extraction_matches_in_memory() {
    let dir = tempfile::tempdir().unwrap();
    let n = 48usize;
    let mut bytes = Vec::new();
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let p = [i, j, k].map(|c| c as f64 / n as f64 * 6.0 - 3.0);
                let tangle = p.iter().map(|x| x.powi(4) - 5.0 * x * x).sum::<f64>() + 11.8;
                bytes.extend_from_slice(&((tangle * 100.0 + 2000.0).round() as u16).to_le_bytes());
            }
        }
    }
    std::fs::write(dir.path().join("t.raw"), bytes).unwrap();
    let dims = format!("{n},{n},{n}");
    let common = [
        "extract",
        "t.raw",
        "--dims",
        &dims,
        "--type",
        "u16",
        "--level",
        "2000",
        "--spacing",
        "0.5,0.5,0.8",
        "--origin",
        "1,2,3",
        "--flip",
    ];
    let run = |out: &str, extra: &[&str]| {
        let mut args = common.to_vec();
        args.extend_from_slice(&["-o", out]);
        args.extend_from_slice(extra);
        let out = isocube(dir.path(), &args);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    let said = run("streamed.ply", &["--stream"]);
    assert!(said.contains("streamed slab by slab"), "{said}");
    run("memory.ply", &[]);
    let streamed = std::fs::read(dir.path().join("streamed.ply")).unwrap();
    assert_eq!(
        streamed,
        std::fs::read(dir.path().join("memory.ply")).unwrap()
    );
    let r = info(dir.path(), "streamed.ply");
    assert_eq!(r["watertight"], true);
    assert!(r["triangles"].as_u64().unwrap() > 5000);
    for (extra, reason) in [
        (&["-o", "s.obj"][..], "binary .ply"),
        (&["-o", "s.ply", "--ascii"][..], "binary .ply"),
        (&["-o", "s.ply", "--method", "ternary"][..], "ternary"),
        (&["-o", "s.ply", "--relax", "2"][..], "relaxation"),
    ] {
        let mut args = common.to_vec();
        args.extend_from_slice(extra);
        args.push("--stream");
        let out = isocube(dir.path(), &args);
        assert_eq!(out.status.code(), Some(2));
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(reason), "{err}");
        assert!(!dir.path().join("s.ply").exists() && !dir.path().join("s.obj").exists());
    }
    let out = isocube(
        dir.path(),
        &["extract", "sample:sphere:10", "-o", "s.ply", "--stream"],
    );
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("stored uncompressed"));
}

/// An OME-Zarr store (chunks not dividing the grid) gives the file the same values give from
/// memory, byte for byte: in memory, streamed to a PLY, and ternary (read whole). An absent
/// chunk is the fill value with a note (refused by --strict); a damaged one fails naming it.
#[test]
fn zarr_stores_mesh_as_the_same_values_in_memory() {
    let dir = tempfile::tempdir().unwrap();
    let grid: isocube::field::SampleSpec = "sample:tangle:45".parse().unwrap();
    let grid = grid.grid();
    isocube_io::write_zarr(&dir.path().join("t.zarr"), &grid, [16, 16, 16]).unwrap();
    let same = |a: &str, b: &str| {
        std::fs::read(dir.path().join(a)).unwrap() == std::fs::read(dir.path().join(b)).unwrap()
    };
    for extra in [
        &[][..],
        &["--method", "ternary"],
        &["--triangulate", "local"],
    ] {
        let mut args = vec!["extract", "t.zarr", "-o", "z.ply"];
        args.extend_from_slice(extra);
        ok(dir.path(), &args);
        let mut args = vec!["extract", "sample:tangle:45", "-o", "s.ply"];
        args.extend_from_slice(extra);
        ok(dir.path(), &args);
        assert!(same("z.ply", "s.ply"), "{extra:?}");
    }
    ok(
        dir.path(),
        &["extract", "t.zarr", "-o", "streamed.ply", "--stream"],
    );
    ok(dir.path(), &["extract", "sample:tangle:45", "-o", "s.ply"]);
    assert!(same("streamed.ply", "s.ply"));
    let out = isocube(
        dir.path(),
        &["extract", "t.zarr", "-o", "x.ply", "--scale", "1"],
    );
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("the image has 1 levels"));

    std::fs::remove_file(dir.path().join("t.zarr/0/c/1/1/1")).unwrap();
    let out = isocube(dir.path(), &["extract", "t.zarr", "-o", "gap.ply"]);
    assert!(out.status.success());
    let said = String::from_utf8_lossy(&out.stderr);
    assert!(
        said.contains("1 chunk absent (the first '0/c/1/1/1')"),
        "{said}"
    );
    let out = isocube(
        dir.path(),
        &["extract", "t.zarr", "-o", "strict.ply", "--strict"],
    );
    assert_eq!(out.status.code(), Some(2));
    assert!(!dir.path().join("strict.ply").exists());

    std::fs::write(dir.path().join("t.zarr/0/c/2/0/1"), b"damaged").unwrap();
    for extra in [&[][..], &["--stream"], &["--method", "ternary"]] {
        let mut args = vec!["extract", "t.zarr", "-o", "bad.ply"];
        args.extend_from_slice(extra);
        let out = isocube(dir.path(), &args);
        assert_eq!(out.status.code(), Some(2), "{extra:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains("t.zarr: chunk '0/c/2/0/1' (chunk grid indices 2, 0, 1)"),
            "{err}"
        );
        assert!(!dir.path().join("bad.ply").exists());
    }
}

#[test]
fn a_large_gzipped_nifti_inflated_plane_by_plane_matches_the_whole_read() {
    use std::io::Write;
    // 256 × 128 × 132 u8 points (past the size from which a .nii.gz is inflated as the slabs
    // go), a scale, a shear-free direction; meshed as it inflates by default, and read whole
    // with --chunk (which meshes boxes in memory): the same bytes, and as much as written.
    let [nx, ny, nz] = [256usize, 128, 132];
    let mut head = vec![0u8; 352];
    head[0..4].copy_from_slice(&348i32.to_le_bytes());
    for (i, d) in [3u16, nx as u16, ny as u16, nz as u16, 1, 1, 1, 1]
        .iter()
        .enumerate()
    {
        head[40 + 2 * i..42 + 2 * i].copy_from_slice(&d.to_le_bytes());
    }
    head[70..72].copy_from_slice(&2i16.to_le_bytes()); // uint8
    head[72..74].copy_from_slice(&8i16.to_le_bytes());
    for (i, v) in [-1.0f32, 0.5, 0.75, 1.25].iter().enumerate() {
        head[76 + 4 * i..80 + 4 * i].copy_from_slice(&v.to_le_bytes()); // qfac, pixdim
    }
    head[108..112].copy_from_slice(&352f32.to_le_bytes());
    head[112..116].copy_from_slice(&2f32.to_le_bytes()); // scl_slope
    head[116..120].copy_from_slice(&(-10f32).to_le_bytes()); // scl_inter
    head[344..348].copy_from_slice(b"n+1\0");
    let mut values = Vec::with_capacity(nx * ny * nz);
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let p = [
                    i as f64 / nx as f64,
                    j as f64 / ny as f64,
                    k as f64 / nz as f64,
                ];
                let r = p.iter().map(|x| (x - 0.5) * (x - 0.5)).sum::<f64>().sqrt();
                values.push((255.0 * (1.0 - 2.0 * r).clamp(0.0, 1.0)) as u8);
            }
        }
    }
    let dir = tempfile::tempdir().unwrap();
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    gz.write_all(&head).unwrap();
    gz.write_all(&values).unwrap();
    std::fs::write(dir.path().join("ball.nii.gz"), gz.finish().unwrap()).unwrap();
    let mesh = |out: &str, extra: &[&str]| {
        let mut args = vec!["extract", "ball.nii.gz", "--level", "200", "-o", out];
        args.extend_from_slice(extra);
        ok(dir.path(), &args);
        std::fs::read(dir.path().join(out)).unwrap()
    };
    let inflated = mesh("inflated.ply", &[]);
    let whole = mesh("whole.ply", &["--chunk", "255,127,131"]);
    assert_eq!(inflated, whole);
    let r = info(dir.path(), "inflated.ply");
    assert_eq!(r["watertight"], true);
    assert!(r["triangles"].as_u64().unwrap() > 10000);
    // Cut short: a typed error naming the file, and nothing written.
    let bytes = std::fs::read(dir.path().join("ball.nii.gz")).unwrap();
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    gz.write_all(&head).unwrap();
    gz.write_all(&values[..values.len() - 1000]).unwrap();
    std::fs::write(dir.path().join("short.nii.gz"), gz.finish().unwrap()).unwrap();
    assert!(bytes.len() > 1000);
    let out = isocube(
        dir.path(),
        &["extract", "short.nii.gz", "--level", "200", "-o", "s.ply"],
    );
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("short.nii.gz") && err.contains("ends inside its data"),
        "{err}"
    );
    assert!(!dir.path().join("s.ply").exists());
}

#[test]
fn bad_input_exits_2_without_output() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("short.raw"), [0u8; 10]).unwrap();
    std::fs::write(
        dir.path().join("in.ply"),
        b"ply\nformat ascii 1.0\nend_header\n",
    )
    .unwrap();
    let cases: [&[&str]; 9] = [
        &[
            "extract",
            "sample:sphere:10",
            "--method",
            "ternary",
            "--snap",
            "0.7",
            "-o",
            "out.ply",
        ],
        &[
            "extract",
            "sample:sphere:10",
            "--method",
            "ternary",
            "--zero-threshold",
            "-1",
            "-o",
            "out.ply",
        ],
        &["extract", "missing.npy", "-o", "out.ply"],
        &[
            "extract",
            "short.raw",
            "--dims",
            "4,4,4",
            "--type",
            "u8",
            "-o",
            "out.ply",
        ],
        &["extract", "short.raw", "-o", "out.ply"],
        &["extract", "sample:sphere:10", "-o", "out.xyz"],
        &["extract", "sample:nothing:10", "-o", "out.ply"],
        &[
            "extract", "in.ply", "--dims", "2,2,2", "--type", "u8", "-o", "in.ply",
        ],
        &["info", "missing.ply"],
    ];
    for args in cases {
        let out = isocube(dir.path(), args);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.starts_with("error:"), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        assert!(!dir.path().join("out.ply").exists() && !dir.path().join("out.xyz").exists());
    }
    // The input was not touched.
    assert_eq!(
        std::fs::read(dir.path().join("in.ply")).unwrap(),
        b"ply\nformat ascii 1.0\nend_header\n"
    );
}

#[test]
fn demo_writes_every_sample() {
    let dir = tempfile::tempdir().unwrap();
    let out = ok(
        dir.path(),
        &["demo", "--out", "d", "--size", "24", "--quiet"],
    );
    assert_eq!(out.lines().count(), 1 + 9);
    let files: Vec<String> = std::fs::read_dir(dir.path().join("d"))
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    assert_eq!(files.len(), 18, "{files:?}");
    for f in files.iter().filter(|f| f.ends_with(".ply")) {
        assert!(
            files.contains(&f.replace(".ply", ".png")),
            "no picture of {f}"
        );
    }
    assert!(out.lines().nth(1).unwrap().starts_with("sphere"));
}

/// Width, height and the share of pixels that differ from the white background.
fn png_stats(path: &Path) -> (u32, u32, f64) {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    let px = &buf[..info.buffer_size()];
    let channels = px.len() / (info.width * info.height) as usize;
    let drawn = px
        .chunks(channels)
        .filter(|p| p[..3].iter().any(|&v| v != 255))
        .count();
    (
        info.width,
        info.height,
        drawn as f64 / (info.width * info.height) as f64,
    )
}

#[test]
fn render_draws_pictures_of_the_requested_size() {
    let dir = tempfile::tempdir().unwrap();
    ok(
        dir.path(),
        &["extract", "sample:torus:32", "-o", "t.ply", "--quiet"],
    );
    ok(
        dir.path(),
        &["extract", "sample:sphere:32", "-o", "s.off", "--quiet"],
    );
    for (mesh, args, size, share) in [
        ("t.ply", vec![], (800, 600), (0.3, 0.7)),
        (
            "t.ply",
            vec!["--view", "z", "--size", "300x300"],
            (300, 300),
            (0.4, 0.8),
        ),
        (
            "t.ply",
            vec!["--view", "x", "--size", "300x300"],
            (300, 300),
            (0.1, 0.4),
        ),
        (
            "s.off",
            vec!["--view", "-30,60", "--size", "200x100", "--wireframe"],
            (200, 100),
            (0.25, 0.5),
        ),
    ] {
        let mut all = vec!["render", mesh, "-o", "p.png", "--quiet"];
        all.extend(&args);
        ok(dir.path(), &all);
        let (w, h, drawn) = png_stats(&dir.path().join("p.png"));
        assert_eq!((w, h), size, "{args:?}");
        assert!(drawn > share.0 && drawn < share.1, "{args:?}: {drawn}");
    }
    for bad in [
        vec!["render", "t.ply", "-o", "p.jpg"],
        vec!["render", "t.ply", "-o", "t.ply"],
        vec!["render", "t.ply", "-o", "q.png", "--size", "10"],
        vec!["render", "t.ply", "-o", "q.png", "--view", "up"],
        vec!["render", "missing.ply", "-o", "q.png"],
    ] {
        let out = isocube(dir.path(), &bad);
        assert_eq!(out.status.code(), Some(2), "{bad:?}");
        assert!(!dir.path().join("q.png").exists() && !dir.path().join("p.jpg").exists());
    }
}

/// Every `isocube …` line in the README's shell examples runs successfully, in order, in one
/// temporary directory.
#[test]
fn readme_examples_run() {
    let readme =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("../../README.md"))
            .unwrap();
    let dir = tempfile::tempdir().unwrap();
    // The file the streaming example reads: a small u16 `a[z, y, x]` volume with a bright ball.
    let n = 24usize;
    let mut data = Vec::with_capacity(2 * n * n * n);
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let r2 = [i, j, k]
                    .map(|c| (c as f64 - 11.5).powi(2))
                    .iter()
                    .sum::<f64>();
                data.extend_from_slice(&(if r2 < 64.0 { 1700u16 } else { 1000 }).to_le_bytes());
            }
        }
    }
    let npy = common::npy("<u2", &format!("({n}, {n}, {n})"), &data);
    std::fs::write(dir.path().join("ct.npy"), npy).unwrap();
    // The same ball as a Zarr store, and an OME-Zarr image (Zarr v2, written by hand as other
    // tools write it) with two channels and two levels for the `--scale`/`--channel` example.
    let ball = |i: usize, j: usize, k: usize, h: f64| {
        let r2 = [i, j, k]
            .map(|c| (c as f64 * h - 11.5).powi(2))
            .iter()
            .sum::<f64>();
        8.0 - r2.sqrt()
    };
    let grid = isocube::field::Grid::from_fn([n, n, n], [1.0; 3], [0.0; 3], |p| {
        if ball(p[0] as usize, p[1] as usize, p[2] as usize, 1.0) > 0.0 {
            1700.0
        } else {
            1000.0
        }
    });
    isocube_io::write_zarr(&dir.path().join("ct.zarr"), &grid, [16, 16, 16]).unwrap();
    let ome = dir.path().join("image.ome.zarr");
    std::fs::create_dir_all(&ome).unwrap();
    std::fs::write(ome.join(".zgroup"), r#"{"zarr_format": 2}"#).unwrap();
    let axes = r#"[{"name": "c", "type": "channel"}, {"name": "z", "type": "space"},
        {"name": "y", "type": "space"}, {"name": "x", "type": "space"}]"#;
    let level = |path: &str, s: f64| {
        format!(
            r#"{{"path": "{path}", "coordinateTransformations":
                [{{"type": "scale", "scale": [1, {s}, {s}, {s}]}}]}}"#
        )
    };
    std::fs::write(
        ome.join(".zattrs"),
        format!(
            r#"{{"multiscales": [{{"version": "0.4", "axes": {axes}, "datasets": [{}, {}]}}]}}"#,
            level("0", 1.0),
            level("1", 2.0)
        ),
    )
    .unwrap();
    for (name, m) in [("0", n), ("1", n / 2)] {
        let folder = ome.join(name);
        std::fs::create_dir_all(&folder).unwrap();
        std::fs::write(
            folder.join(".zarray"),
            format!(
                r#"{{"zarr_format": 2, "shape": [2, {m}, {m}, {m}], "chunks": [1, {m}, {m}, {m}],
                    "dtype": "<f4", "compressor": null, "fill_value": 0.0, "order": "C",
                    "filters": null}}"#
            ),
        )
        .unwrap();
        let h = (n / m) as f64;
        for c in 0..2 {
            let mut bytes = Vec::new();
            for k in 0..m {
                for j in 0..m {
                    for i in 0..m {
                        let v = ball(i, j, k, h) as f32 * if c == 0 { 1.0 } else { -1.0 };
                        bytes.extend(v.to_le_bytes());
                    }
                }
            }
            std::fs::write(folder.join(format!("{c}.0.0.0")), bytes).unwrap();
        }
    }
    // The volumes in tests/data, at the same relative paths as in a clone.
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/volumes");
    let copy = dir.path().join("tests/data/volumes");
    let mut subs = vec![std::path::PathBuf::new()];
    for entry in std::fs::read_dir(&data).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            subs.push(path.file_name().unwrap().into());
        }
    }
    for sub in subs {
        std::fs::create_dir_all(copy.join(&sub)).unwrap();
        for entry in std::fs::read_dir(data.join(&sub)).unwrap() {
            let path = entry.unwrap().path();
            if path.is_file() {
                std::fs::copy(&path, copy.join(&sub).join(path.file_name().unwrap())).unwrap();
            }
        }
    }
    let mut in_block = false;
    let mut ran = 0;
    for line in readme.lines() {
        if line.starts_with("```") {
            in_block = line.trim() == "```sh";
            continue;
        }
        if !in_block {
            continue;
        }
        let Some(rest) = line.trim().strip_prefix("isocube ") else {
            continue;
        };
        let command = rest.split(" #").next().unwrap();
        let args: Vec<&str> = command.split_whitespace().collect();
        let out = isocube(dir.path(), &args);
        assert!(
            out.status.success(),
            "README line failed: {line}\n{}",
            String::from_utf8_lossy(&out.stderr)
        );
        ran += 1;
    }
    assert!(ran >= 5, "only {ran} README examples found");
}

#[test]
fn topology_option_changes_a_tunnel_cell() {
    let dir = tempfile::tempdir().unwrap();
    // One cell, f32, x fastest: vertices (0,0,0) and (1,1,1) strongly above, the rest weakly
    // below: the trilinear interpolant joins them by a tunnel.
    let values: [f32; 8] = [1.0, -0.1, -0.1, -0.1, -0.1, -0.1, -0.1, 1.0];
    let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
    std::fs::write(dir.path().join("cell.raw"), bytes).unwrap();
    let common = ["extract", "cell.raw", "--dims", "2,2,2", "--type", "f32"];
    let mut mc33 = common.to_vec();
    mc33.extend(["-o", "mc33.ply"]);
    ok(dir.path(), &mc33);
    let mut classic = common.to_vec();
    classic.extend(["-o", "classic.ply", "--topology", "classic"]);
    ok(dir.path(), &classic);
    let (a, b) = (
        info(dir.path(), "mc33.ply"),
        info(dir.path(), "classic.ply"),
    );
    assert_eq!(
        (a["components"].as_u64(), a["euler"].as_i64()),
        (Some(1), Some(0))
    );
    assert_eq!(
        (b["components"].as_u64(), b["euler"].as_i64()),
        (Some(2), Some(2))
    );
}

/// `extract --method ternary`: no zero-area triangles where plain Marching Cubes makes over a
/// thousand, same topology, fewer triangles; snapped vertices on grid points when asked.
#[test]
fn extract_ternary_schwarz_p() {
    let dir = tempfile::tempdir().unwrap();
    ok(
        dir.path(),
        &["extract", "sample:schwarz-p:40", "-o", "mc.ply"],
    );
    let mc = info(dir.path(), "mc.ply");
    assert!(mc["degenerate"].as_u64().unwrap() > 1000);
    for extra in [&[][..], &["--snap", "0.5", "--snap-position", "grid"][..]] {
        let mut args = vec![
            "extract",
            "sample:schwarz-p:40",
            "--method",
            "ternary",
            "-o",
            "t.ply",
        ];
        args.extend_from_slice(extra);
        ok(dir.path(), &args);
        let t = info(dir.path(), "t.ply");
        assert_eq!(t["degenerate"], 0);
        assert_eq!(t["nonmanifold_edges"], 0);
        assert_eq!(t["oriented"], true);
        assert_eq!(
            (&t["components"], &t["euler"]),
            (&mc["components"], &mc["euler"])
        );
        assert!(t["triangles"].as_u64() < mc["triangles"].as_u64());
    }
}

/// `tables --ternary --polygons` lists all 6561 configurations, from 183 classes, with loops
/// whose corners are crossings on edges with a sign change or zero vertices.
#[test]
fn ternary_polygon_table() {
    let dir = tempfile::tempdir().unwrap();
    let text = ok(dir.path(), &["tables", "--ternary", "--polygons"]);
    let mut lines = text.lines();
    assert_eq!(
        lines.next().unwrap(),
        "config\tdigits\tclass\trepresentative\ttransform\tdecisions\tpolygons"
    );
    let edges = [
        [0, 1],
        [1, 2],
        [3, 2],
        [0, 3],
        [4, 5],
        [5, 6],
        [7, 6],
        [4, 7],
        [0, 4],
        [1, 5],
        [2, 6],
        [3, 7],
    ];
    let mut configs = HashSet::new();
    let mut classes = HashSet::new();
    for line in lines {
        let f: Vec<&str> = line.split('\t').collect();
        assert_eq!(f.len(), 7);
        configs.insert(f[0].parse::<usize>().unwrap());
        classes.insert(f[2].to_string());
        let digits: Vec<char> = f[1].chars().collect();
        if f[6] == "-" {
            continue;
        }
        for l in f[6].split(" | ") {
            let corners: Vec<&str> = l.split(' ').collect();
            assert!(corners.len() >= 3, "{line}");
            for c in corners {
                let n: usize = c[1..].parse().unwrap();
                if c.starts_with('v') {
                    assert_eq!(digits[n], '0', "{line}");
                } else {
                    let [a, b] = edges[n];
                    let pair = [digits[a], digits[b]];
                    assert!(pair == ['-', '+'] || pair == ['+', '-'], "{line}");
                }
            }
        }
    }
    assert_eq!(configs.len(), 6561);
    assert_eq!(classes.len(), 183);
    let binary = ok(dir.path(), &["tables", "--binary", "--polygons"]);
    let configs: HashSet<&str> = binary
        .lines()
        .skip(1)
        .map(|l| l.split('\t').next().unwrap())
        .collect();
    assert_eq!(configs.len(), 256);
}

/// `isocube quality`: Verdict measures, distance from the sample's zero set, histograms as SVG
/// and PNG; a bad picture extension is bad input.
#[test]
fn quality_report_and_histograms() {
    let dir = tempfile::tempdir().unwrap();
    ok(
        dir.path(),
        &["extract", "sample:sphere:10", "-o", "s.ply", "--quiet"],
    );
    let text = ok(
        dir.path(),
        &[
            "quality",
            "s.ply",
            "--field",
            "sample:sphere:10",
            "--json",
            "--histogram",
            "h.svg",
        ],
    );
    let q: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_eq!(q["triangles"], 524);
    let bins: u64 = q["histogram_5deg"]
        .as_array()
        .unwrap()
        .iter()
        .map(|b| b.as_u64().unwrap())
        .sum();
    assert_eq!(bins, 3 * 524);
    let min = q["min_angle"]["min"].as_f64().unwrap();
    assert!(min > 0.0 && min < 10.0);
    assert!(q["radius_ratio"]["min"].as_f64().unwrap() >= 1.0);
    let d = q["distance"]["max"].as_f64().unwrap();
    assert!(d > 0.0 && d < 0.2, "{d}");
    let svg = std::fs::read_to_string(dir.path().join("h.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
    assert_eq!(svg.matches("<rect x=").count(), 36);
    ok(dir.path(), &["quality", "s.ply", "--histogram", "h.png"]);
    let png = std::fs::read(dir.path().join("h.png")).unwrap();
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    let be = |i: usize| u32::from_be_bytes(png[i..i + 4].try_into().unwrap());
    assert_eq!((be(16), be(20)), (760, 380));
    let out = isocube(dir.path(), &["quality", "s.ply", "--histogram", "h.gif"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(!dir.path().join("h.gif").exists());
    let table = ok(dir.path(), &["quality", "s.ply"]);
    assert!(table.contains("radius_ratio") && table.contains("edge_ratio"));
}

/// `--triangulate` and `--relax`: every strategy keeps the sphere watertight; ternary snapping
/// with optimal triangles and relaxation lifts the smallest angle past 30°.
#[test]
fn triangulation_strategies_and_relaxation() {
    let dir = tempfile::tempdir().unwrap();
    for t in ["fan", "local", "optimal"] {
        ok(
            dir.path(),
            &[
                "extract",
                "sample:sphere:20",
                "--triangulate",
                t,
                "-o",
                "s.ply",
            ],
        );
        let r = info(dir.path(), "s.ply");
        assert_eq!(
            (r["watertight"].clone(), r["euler"].clone()),
            (true.into(), 2.into()),
            "{t}"
        );
    }
    ok(
        dir.path(),
        &[
            "extract",
            "sample:torus:40",
            "--method",
            "ternary",
            "--snap",
            "0.5",
            "--triangulate",
            "optimal",
            "--relax",
            "10",
            "-o",
            "t.ply",
        ],
    );
    let r = info(dir.path(), "t.ply");
    assert_eq!(
        (r["watertight"].clone(), r["genus"].clone()),
        (true.into(), 1.into())
    );
    assert!(r["min_angle"].as_f64().unwrap() >= 30.0 && r["max_angle"].as_f64().unwrap() <= 110.0);
}

/// `isocube contours`: the built-in ore body closes into one surface of genus 1; a CSV stack
/// reconstructs; an open contour is bad input naming the line, section and contour, with no
/// output written.
/// A level that no cell crosses is an error naming the value range (nothing written, in memory
/// or streamed) unless --allow-empty; `--level auto` and `--level P%` pick one from the data and
/// the summary gives it.
#[test]
fn levels_outside_the_data_are_named_and_levels_from_the_data() {
    let dir = tempfile::tempdir().unwrap();
    // 8-bit data of two classes (a bright ball on a dim background), as scanners write.
    let n = 24;
    let mut data = Vec::with_capacity(n * n * n);
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let r2 = [i, j, k]
                    .iter()
                    .map(|&c| (c as f64 - 11.5).powi(2))
                    .sum::<f64>();
                data.push(if r2 < 64.0 {
                    180 + (i % 5) as u8
                } else {
                    30 + (j % 4) as u8
                });
            }
        }
    }
    let volume = common::npy("|u1", &format!("({n}, {n}, {n})"), &data);
    std::fs::write(dir.path().join("two.npy"), volume).unwrap();
    for extra in [&[][..], &["--stream"][..]] {
        let mut args = vec!["extract", "two.npy", "-o", "none.ply"];
        args.extend_from_slice(extra);
        let out = isocube(dir.path(), &args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{extra:?}: {err}");
        assert!(
            err.contains("no cell crosses the level 0: its values range from 30 to 184")
                && err.contains("--level auto")
                && err.contains("--allow-empty"),
            "{err}"
        );
        let left: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
        assert_eq!(left.len(), 1, "{extra:?}: only the input is left");
    }
    let out = isocube(
        dir.path(),
        &["extract", "two.npy", "-o", "e.ply", "--allow-empty"],
    );
    assert!(out.status.success());
    assert_eq!(info(dir.path(), "e.ply")["triangles"], 0);
    // Otsu's threshold lies between the classes: the ball's surface, closed.
    for (level, name) in [("auto", "a.ply"), ("50%", "m.ply")] {
        let out = isocube(
            dir.path(),
            &["extract", "two.npy", "-o", name, "--level", level],
        );
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{err}");
        let used: f64 = err
            .split("level ")
            .nth(1)
            .and_then(|t| t.split(',').next())
            .and_then(|t| t.parse().ok())
            .unwrap_or_else(|| panic!("no level in the summary: {err}"));
        assert!(used > 34.0 && used <= 180.0, "{level}: {used}");
        let r = info(dir.path(), name);
        assert_eq!(
            (r["watertight"].clone(), r["components"].clone()),
            (true.into(), 1.into())
        );
    }
    // The same level given as a number gives the same file as `50%` (min 30, max 184).
    ok(
        dir.path(),
        &["extract", "two.npy", "-o", "n.ply", "--level", "107"],
    );
    let read = |name: &str| std::fs::read(dir.path().join(name)).unwrap();
    assert_eq!(read("n.ply"), read("m.ply"));
    // tetmesh takes the same levels; `50%` is `107` there too.
    ok(
        dir.path(),
        &["tetmesh", "two.npy", "-o", "a.msh", "--level", "50%"],
    );
    ok(
        dir.path(),
        &["tetmesh", "two.npy", "-o", "b.msh", "--level", "107"],
    );
    assert_eq!(read("a.msh"), read("b.msh"));
}

/// Contours whose last point does not repeat their first are closed curves all the same (CSV,
/// JSON): the mesh is the explicitly closed file's, byte for byte, with a note. An open DXF
/// polyline is refused naming `--close`, and meshed with it.
#[test]
fn contours_are_closed_implicitly_and_open_dxf_needs_close() {
    let dir = tempfile::tempdir().unwrap();
    let square = |s: f64| [[-s, -s], [s, -s], [s, s], [-s, s]];
    let mut explicit = String::from("section,z,contour,x,y\n");
    let mut implicit = explicit.clone();
    for (label, z, s) in [("a", 0.0, 2.0), ("b", 1.0, 1.5), ("c", 3.0, 2.5)] {
        let points = square(s);
        for [x, y] in points.iter().chain(&points[..1]) {
            explicit += &format!("{label},{z},outer,{x},{y}\n");
        }
        for [x, y] in points {
            implicit += &format!("{label},{z},outer,{x},{y}\n");
        }
    }
    std::fs::write(dir.path().join("explicit.csv"), &explicit).unwrap();
    std::fs::write(dir.path().join("implicit.csv"), &implicit).unwrap();
    ok(dir.path(), &["contours", "explicit.csv", "-o", "e.ply"]);
    let out = isocube(dir.path(), &["contours", "implicit.csv", "-o", "i.ply"]);
    assert!(out.status.success());
    let note = String::from_utf8_lossy(&out.stderr);
    assert!(
        note.contains("3 contours closed by the segment back"),
        "{note}"
    );
    let read = |n: &str| std::fs::read(dir.path().join(n)).unwrap();
    assert_eq!(read("e.ply"), read("i.ply"));
    // DXF: open polylines (flag 70 = 0) at three elevations.
    let mut dxf = String::from("0\nSECTION\n2\nENTITIES\n");
    for (n, (z, s)) in [(0.0, 2.0), (1.0, 1.5), (3.0, 2.5)].into_iter().enumerate() {
        dxf += &format!("0\nLWPOLYLINE\n5\nP{n}\n38\n{z}\n90\n4\n70\n0\n");
        for [x, y] in square(s) {
            dxf += &format!("10\n{x}\n20\n{y}\n");
        }
    }
    dxf += "0\nENDSEC\n0\nEOF\n";
    std::fs::write(dir.path().join("open.dxf"), &dxf).unwrap();
    let out = isocube(dir.path(), &["contours", "open.dxf", "-o", "d.ply"]);
    let message = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{message}");
    assert!(
        message.contains("is open") && message.contains("--close"),
        "{message}"
    );
    assert!(!dir.path().join("d.ply").exists());
    ok(
        dir.path(),
        &["contours", "open.dxf", "-o", "d.ply", "--close"],
    );
    assert_eq!(read("d.ply"), read("e.ply"));
}

#[test]
fn contours_command() {
    let dir = tempfile::tempdir().unwrap();
    ok(
        dir.path(),
        &[
            "contours",
            "sample:orebody",
            "-o",
            "ore.ply",
            "--grid",
            "40x40",
        ],
    );
    let r = info(dir.path(), "ore.ply");
    assert_eq!(
        (
            r["watertight"].clone(),
            r["genus"].clone(),
            r["components"].clone()
        ),
        (true.into(), 1.into(), 1.into())
    );
    let mut csv = String::from("section,z,contour,x,y\n");
    for (label, z, s) in [("a", 0.0, 2.0), ("b", 1.0, 1.5), ("c", 3.0, 2.5)] {
        for [x, y] in [[-s, -s], [s, -s], [s, s], [-s, s], [-s, -s]] {
            csv += &format!("{label},{z},outer,{x},{y}\n");
        }
    }
    std::fs::write(dir.path().join("stack.csv"), &csv).unwrap();
    ok(
        dir.path(),
        &[
            "contours",
            "stack.csv",
            "-o",
            "stack.obj",
            "--cell",
            "0.25",
            "--cap",
            "extend",
            "0.5",
        ],
    );
    let r = info(dir.path(), "stack.obj");
    assert_eq!(
        (r["watertight"].clone(), r["genus"].clone()),
        (true.into(), 0.into())
    );
    ok(
        dir.path(),
        &["contours", "stack.csv", "-o", "flat.ply", "--cap", "flat"],
    );
    let r = info(dir.path(), "flat.ply");
    assert_eq!(
        (r["watertight"].clone(), r["genus"].clone()),
        (true.into(), 0.into())
    );
    ok(
        dir.path(),
        &["contours", "stack.csv", "-o", "open.ply", "--cap", "none"],
    );
    assert!(
        info(dir.path(), "open.ply")["boundary_edges"]
            .as_u64()
            .unwrap()
            > 0
    );
    // Every triangulation closes the same body.
    for t in ["fan", "local", "optimal"] {
        let name = format!("tri-{t}.ply");
        ok(
            dir.path(),
            &["contours", "stack.csv", "-o", &name, "--triangulate", t],
        );
        let r = info(dir.path(), &name);
        assert_eq!(
            (r["watertight"].clone(), r["genus"].clone()),
            (true.into(), 0.into()),
            "{t}"
        );
    }
    // A contour smaller than a cell is reported as missing.
    let mut tiny = csv.clone();
    for [x, y] in [[5.0, 5.0], [5.1, 5.0], [5.1, 5.1], [5.0, 5.1], [5.0, 5.0]] {
        tiny += &format!("c,3,speck,{x},{y}\n");
    }
    std::fs::write(dir.path().join("tiny.csv"), &tiny).unwrap();
    let out = isocube(
        dir.path(),
        &["contours", "tiny.csv", "-o", "tiny.ply", "--cell", "1"],
    );
    assert!(out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("1 contour encloses no grid point and is missing"),
        "{err}"
    );
    let single = "section,z,contour,x,y\ns,0,c,0,0\ns,0,c,1,0\ns,0,c,1,1\ns,0,c,0,0\n";
    std::fs::write(dir.path().join("single.csv"), single).unwrap();
    let point = "section,z,contour,x,y\ns,0,c,0,0\nt,1,c,1,1\nt,1,c,2,1\nt,1,c,2,2\n";
    std::fs::write(dir.path().join("point.csv"), point).unwrap();
    for (args, needle) in [
        (
            &["contours", "point.csv", "-o", "bad.ply"][..],
            "line 2: section 's' (z = 0), contour 'c': a single point",
        ),
        (
            &["contours", "stack.csv", "-o", "bad.ply", "--cap", "round"][..],
            "--cap round",
        ),
        (
            &[
                "contours",
                "stack.csv",
                "-o",
                "bad.ply",
                "--cap",
                "extend",
                "-1",
            ][..],
            "not a distance",
        ),
        (
            &["contours", "single.csv", "-o", "bad.ply", "--cap", "flat"][..],
            "a single section makes a closed surface only with an extension cap",
        ),
    ] {
        let out = isocube(dir.path(), args);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(needle), "{err}");
        assert!(!dir.path().join("bad.ply").exists());
    }
}

#[test]
fn subdivide_command() {
    let dir = tempfile::tempdir().unwrap();
    for (holes, name) in [("smooth", "plate-smooth.obj"), ("sharp", "plate-sharp.obj")] {
        ok(
            dir.path(),
            &[
                "subdivide",
                "sample:plate",
                "-o",
                name,
                "--levels",
                "2",
                "--holes",
                holes,
            ],
        );
        let r = info(dir.path(), name);
        assert_eq!(
            (r["watertight"].clone(), r["genus"].clone()),
            (true.into(), 1.into()),
            "{holes}"
        );
    }
    // The sharp method keeps faces with inner loops, written with isocube's tag.
    let text = std::fs::read_to_string(dir.path().join("plate-sharp.obj")).unwrap();
    assert_eq!(
        text.lines()
            .filter(|l| l.starts_with("t innerloop"))
            .count(),
        2
    );
    // A mesh that extract wrote: 2 levels give 16 quads per triangle, written as triangles.
    ok(dir.path(), &["extract", "sample:torus:12", "-o", "t.ply"]);
    let before = info(dir.path(), "t.ply")["triangles"].as_u64().unwrap();
    ok(
        dir.path(),
        &[
            "subdivide",
            "t.ply",
            "-o",
            "t2.ply",
            "--levels",
            "2",
            "--limit",
        ],
    );
    let r = info(dir.path(), "t2.ply");
    assert_eq!(r["triangles"].as_u64().unwrap(), before * 3 * 4 * 2);
    assert_eq!(
        (r["watertight"].clone(), r["genus"].clone()),
        (true.into(), 1.into())
    );
    // A boundary rule override on an open cage, and a file's tags.
    let open = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\nt crease 2/1/0 0 1 10\n";
    std::fs::write(dir.path().join("open.obj"), open).unwrap();
    for rule in ["edge-only", "edge-and-corner", "none"] {
        ok(
            dir.path(),
            &[
                "subdivide",
                "open.obj",
                "-o",
                "open2.obj",
                "--boundary",
                rule,
            ],
        );
    }
    // `info` still reports an OBJ that is no valid cage (a face repeating a vertex).
    std::fs::write(
        dir.path().join("degenerate.obj"),
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3 3\n",
    )
    .unwrap();
    assert_eq!(info(dir.path(), "degenerate.obj")["vertices"], 3);
    std::fs::write(dir.path().join("bad.obj"), "v 0 0 0\nv 1 0 0\nf 1 2 7\n").unwrap();
    for (args, needle) in [
        (
            &["subdivide", "sample:teapot", "-o", "out.obj"][..],
            "unknown sample cage 'teapot'",
        ),
        (
            &["subdivide", "bad.obj", "-o", "out.obj"][..],
            "vertex 7 does not exist",
        ),
        (
            &[
                "subdivide",
                "sample:cube",
                "-o",
                "out.obj",
                "--levels",
                "40",
            ][..],
            "--levels 40",
        ),
    ] {
        let out = isocube(dir.path(), args);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(needle), "{err}");
        assert!(!err.contains("panicked"), "{err}");
        assert!(!dir.path().join("out.obj").exists());
    }
}

/// Vertices and triangles of an ASCII PLY written by isocube (positions, normals, faces).
fn ascii_ply(path: &Path) -> (Vec<[f64; 3]>, Vec<[usize; 3]>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let mut vertices = 0;
    for line in lines.by_ref() {
        if let Some(n) = line.strip_prefix("element vertex ") {
            vertices = n.parse().unwrap();
        }
        if line == "end_header" {
            break;
        }
    }
    let mut positions = Vec::new();
    for _ in 0..vertices {
        let v: Vec<f64> = lines
            .next()
            .unwrap()
            .split_whitespace()
            .map(|w| w.parse().unwrap())
            .collect();
        positions.push([v[0], v[1], v[2]]);
    }
    let triangles = lines
        .map(|l| {
            let v: Vec<usize> = l.split_whitespace().map(|w| w.parse().unwrap()).collect();
            [v[1], v[2], v[3]]
        })
        .collect();
    (positions, triangles)
}

/// Volumes written by nibabel and SimpleITK: the mesh in world coordinates is the index-space
/// mesh carried by the file's index-to-world map, with the winding reversed under a reflection.
#[test]
fn oriented_volumes_give_meshes_in_world_coordinates() {
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/volumes");
    let expected: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(data.join("expected.json")).unwrap())
            .unwrap();
    let dir = tempfile::tempdir().unwrap();
    for (name, file) in expected["files"].as_object().unwrap() {
        let input = data.join(name);
        let input = input.to_str().unwrap();
        // The level where the stored values are 712 (a doubled CT's 400 HU, a dose's 1.78 Gy).
        let level = file["scale"].as_f64().unwrap() * 712.0 + file["offset"].as_f64().unwrap();
        let level = &level.to_string();
        ok(
            dir.path(),
            &[
                "extract", input, "--level", level, "-o", "w.ply", "--ascii", "--quiet",
            ],
        );
        ok(
            dir.path(),
            &[
                "extract",
                input,
                "--level",
                level,
                "-o",
                "i.ply",
                "--ascii",
                "--quiet",
                "--index-space",
            ],
        );
        // Measured against the file itself, the world mesh lies on the level set.
        let q: serde_json::Value = serde_json::from_str(&ok(
            dir.path(),
            &[
                "quality", "w.ply", "--field", input, "--level", level, "--json",
            ],
        ))
        .unwrap();
        let far = q["distance"]["max"].as_f64().unwrap();
        // The fixtures' values are linear in the indices, so the level set is a plane the
        // triangles lie in; a lossy encoding's coding error bends it, and the triangles'
        // interiors (sampled too) leave the curved surface by a little (in grid spacings).
        let bound = if file.get("tolerance").is_some() {
            0.02
        } else {
            1e-3
        };
        assert!(far < bound, "{name}: {far}");
        let (world, wt) = ascii_ply(&dir.path().join("w.ply"));
        let (index, it) = ascii_ply(&dir.path().join("i.ply"));
        assert!(world.len() > 50 && world.len() == index.len(), "{name}");
        let m: Vec<Vec<f64>> = file["linear"]
            .as_array()
            .unwrap()
            .iter()
            .map(|r| {
                r.as_array()
                    .unwrap()
                    .iter()
                    .map(|x| x.as_f64().unwrap())
                    .collect()
            })
            .collect();
        let o: Vec<f64> = file["origin"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect();
        for (w, p) in world.iter().zip(&index) {
            for r in 0..3 {
                let want = o[r] + (0..3).map(|c| m[r][c] * p[c]).sum::<f64>();
                assert!((w[r] - want).abs() < 1e-3, "{name}: {w:?} vs index {p:?}");
            }
        }
        let det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
        for (a, b) in wt.iter().zip(&it) {
            let expect = if det < 0.0 { [b[0], b[2], b[1]] } else { *b };
            assert_eq!(*a, expect, "{name}");
        }
    }
}

#[test]
fn labels_give_one_closed_surface_each() {
    let dir = tempfile::tempdir().unwrap();
    let seg = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/volumes/labels.nii.gz");
    let seg = seg.to_str().unwrap();
    ok(
        dir.path(),
        &["extract", seg, "--labels", "-o", "organs.ply", "--quiet"],
    );
    for label in 1..=3 {
        let r = info(dir.path(), &format!("organs-{label}.ply"));
        assert_eq!(r["watertight"], true, "{label}: {r}");
        assert_eq!(r["components"], 1);
        assert_eq!(r["euler"], 2);
    }
    ok(
        dir.path(),
        &[
            "extract", seg, "--labels", "2", "-o", "two.obj", "--quiet", "--smooth", "0",
        ],
    );
    assert!(dir.path().join("two-2.obj").exists() && !dir.path().join("two-1.obj").exists());
    for bad in [
        vec!["extract", seg, "--labels", "x", "-o", "bad.ply"],
        vec!["extract", seg, "--labels", "9", "-o", "bad.ply"],
        vec!["extract", "sample:sphere:12", "--labels", "-o", "bad.ply"],
    ] {
        let out = isocube(dir.path(), &bad);
        assert_eq!(out.status.code(), Some(2), "{bad:?}");
    }
    let names: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    assert!(names.iter().all(|n| !n.starts_with("bad")), "{names:?}");
}

/// `tetmesh` writes every tetrahedral format with the same counts; the boundary it reports is
/// the surface `extract` writes (same triangle count); the check line says conforming; bad
/// outputs and empty regions exit 2 with nothing written.
#[test]
fn tetmesh_writes_checked_meshes_and_refuses_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    let mut firsts = HashSet::new();
    for ext in ["msh", "vtu", "mesh", "inp", "bin.msh"] {
        let name = format!("t.{ext}");
        let mut args = vec!["tetmesh", "sample:torus:24", "-o", &name];
        if ext == "bin.msh" {
            args.push("--binary");
        }
        let out = isocube(dir.path(), &args);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let err = String::from_utf8_lossy(&out.stderr).to_string();
        assert!(
            err.contains("check: conforming, 0 inverted, 0 flat"),
            "{err}"
        );
        let first = err.lines().next().unwrap();
        firsts.insert(first.split_once(": ").unwrap().1.to_string());
        assert!(dir.path().join(format!("t.{ext}")).exists());
    }
    assert_eq!(firsts.len(), 1, "{firsts:?}");
    // The binary MSH file holds what the ASCII one does (read back by `quality`).
    let quality = |file: &str| {
        let out = isocube(dir.path(), &["quality", file]);
        assert!(out.status.success(), "{file}");
        String::from_utf8_lossy(&out.stdout).to_string()
    };
    assert_eq!(quality("t.msh"), quality("t.bin.msh"));
    let line = firsts.into_iter().next().unwrap();
    let surface: usize = line
        .split("boundary ")
        .nth(1)
        .and_then(|s| s.split(' ').next())
        .unwrap()
        .parse()
        .unwrap();
    // Abaqus names every boundary triangle by its element and side, in SURFACE_S1..S4.
    let inp = std::fs::read_to_string(dir.path().join("t.inp")).unwrap();
    let mut sides = 0;
    let mut counting = false;
    for l in inp.lines() {
        if l.starts_with('*') {
            counting = l.starts_with("*Elset, elset=SURFACE_S");
        } else if counting {
            sides += l.split(',').count();
        }
    }
    assert_eq!(sides, surface);
    ok(
        dir.path(),
        &[
            "extract",
            "sample:torus:24",
            "-o",
            "s.ply",
            "--method",
            "ternary",
        ],
    );
    let report = info(dir.path(), "s.ply");
    assert_eq!(report["triangles"].as_u64().unwrap() as usize, surface);

    for args in [
        &["tetmesh", "sample:torus:24", "-o", "t.ply"][..],
        &["tetmesh", "sample:torus:24", "--binary", "-o", "b.inp"][..],
        &[
            "tetmesh",
            "sample:torus:24",
            "--level",
            "-5",
            "-o",
            "empty.msh",
        ][..],
        // Options for contour stacks are refused on volumes, not ignored.
        &[
            "tetmesh",
            "sample:torus:24",
            "--cell",
            "0.1",
            "-o",
            "cell.msh",
        ][..],
        &[
            "tetmesh",
            "sample:torus:24",
            "--grid",
            "10x10",
            "-o",
            "grid.msh",
        ][..],
        &[
            "tetmesh",
            "sample:torus:24",
            "--cap",
            "flat",
            "-o",
            "cap.msh",
        ][..],
    ] {
        let out = isocube(dir.path(), args);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        let named = args
            .iter()
            .any(|a| a.starts_with("--cell") || a.starts_with("--grid") || a.starts_with("--cap"));
        if named {
            assert!(String::from_utf8_lossy(&out.stderr).contains("for contour stacks"));
        }
    }
    for name in ["cell.msh", "grid.msh", "cap.msh"] {
        assert!(!dir.path().join(name).exists(), "{name}");
    }
    assert!(!dir.path().join("t.ply").exists() && !dir.path().join("empty.msh").exists());
    assert!(!dir.path().join("b.inp").exists());
}

/// The smallest and largest dihedral angles of `tetmesh`'s summary (`dihedral angles lo°..hi°`).
fn dihedral_range(summary: &str) -> (f64, f64) {
    let angles = summary
        .split("dihedral angles ")
        .nth(1)
        .and_then(|s| s.split(',').next())
        .unwrap();
    let (lo, hi) = angles.split_once("..").unwrap();
    let degrees = |s: &str| s.trim_end_matches('°').parse::<f64>().unwrap();
    (degrees(lo), degrees(hi))
}

/// `tetmesh --method ternary`: the boundary is `extract --method ternary --snap-position grid`'s
/// surface, and the dihedral angles stay within [10°, 165°] on the torus.
#[test]
fn tetmesh_ternary_keeps_the_angles_moderate() {
    let dir = tempfile::tempdir().unwrap();
    let out = isocube(
        dir.path(),
        &[
            "tetmesh",
            "sample:torus:32",
            "--method",
            "ternary",
            "--snap",
            "0.5",
            "-o",
            "t.vtu",
        ],
    );
    let err = String::from_utf8_lossy(&out.stderr).to_string();
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains("check: conforming, 0 inverted, 0 flat"),
        "{err}"
    );
    let (lo, hi) = dihedral_range(&err);
    assert!(lo > 10.0 && hi < 165.0, "{lo}..{hi}");
    let surface: usize = err
        .split("boundary ")
        .nth(1)
        .and_then(|s| s.split(' ').next())
        .unwrap()
        .parse()
        .unwrap();
    ok(
        dir.path(),
        &[
            "extract",
            "sample:torus:32",
            "--method",
            "ternary",
            "--snap",
            "0.5",
            "--snap-position",
            "grid",
            "-o",
            "s.ply",
        ],
    );
    let report = info(dir.path(), "s.ply");
    assert_eq!(report["triangles"].as_u64().unwrap() as usize, surface);
}

/// The summary sorts the elements outside [10°, 165°] by what lies beside them: the classes add
/// up to the count, and the line is there exactly when the angles leave the range.
#[test]
fn tetmesh_sorts_the_elements_outside_the_range() {
    let dir = tempfile::tempdir().unwrap();
    let mut seen = 0;
    for (spec, flip) in [
        ("sample:noise:16:1", false),
        ("sample:noise:16:2", true),
        ("sample:packed-spheres:16:3", true),
        ("sample:sphere:16", false),
    ] {
        let mut args = vec!["tetmesh", spec, "-o", "t.msh"];
        if flip {
            args.push("--flip");
        }
        let out = isocube(dir.path(), &args);
        let err = String::from_utf8_lossy(&out.stderr).to_string();
        assert!(out.status.success(), "{err}");
        let (lo, hi) = dihedral_range(&err);
        let outside = lo < 10.0 || hi > 165.0;
        let line = err.lines().find(|l| l.starts_with("outside [10°, 165°]: "));
        assert_eq!(line.is_some(), outside, "{spec}: {err}");
        let Some(line) = line else { continue };
        seen += 1;
        // "N elements: A at …, B within …, C others"
        let number_before = |word: &str| -> usize {
            let head = line.split(word).next().unwrap();
            head.rsplit(|c: char| !c.is_ascii_digit())
                .find(|s| !s.is_empty())
                .unwrap()
                .parse()
                .unwrap()
        };
        let count = number_before(" elements:");
        let forced = number_before(" at a boundary edge");
        let fine = number_before(" within 1.5 cells");
        let others = number_before(" others");
        assert!(count > 0, "{line}");
        assert_eq!(count, forced + fine + others, "{line}");
        assert_eq!(line.contains("(worst "), others > 0, "{line}");
        // `quality` on the file, told the cell, sorts the elements the same way (the file
        // knows no surface or walls: the faces in its bounding box's faces are the walls).
        let grid: isocube::field::SampleSpec = spec.parse().unwrap();
        let cell = grid.grid().spacing()[0].to_string();
        let out = isocube(dir.path(), &["quality", "t.msh", "--cell", &cell]);
        let text = String::from_utf8_lossy(&out.stdout).to_string();
        assert!(out.status.success(), "{spec}: {text}");
        let again = text
            .lines()
            .find(|l| l.starts_with("outside [10°, 165°]: ") && l.contains(" elements: "));
        assert_eq!(again, Some(line), "{spec}: {text}");
        let out = isocube(dir.path(), &["quality", "t.msh", "--cell", &cell, "--json"]);
        let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(json["outside_elements"], count, "{spec}");
        assert_eq!(json["others"], others, "{spec}");
    }
    assert!(
        seen > 0,
        "no input left the range: the test looks at nothing"
    );
    // Without a positive cell width, or on a surface, --cell is refused.
    let out = isocube(dir.path(), &["quality", "t.msh", "--cell", "0"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--cell 0"));
    ok(dir.path(), &["extract", "sample:sphere:12", "-o", "s.ply"]);
    let out = isocube(dir.path(), &["quality", "s.ply", "--cell", "0.1"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("holds triangles"));
}

/// `tetmesh` on a contour stack: the body between the sections (caps extended or flat), with
/// planes between the sections by default; with the sections only, its boundary has
/// `contours --plain`'s triangles; an open stack, another level or labels are refused with
/// nothing written.
#[test]
fn tetmesh_fills_contour_stacks() {
    let dir = tempfile::tempdir().unwrap();
    let mut csv = String::from("section,z,contour,x,y\n");
    for (label, z, s) in [("a", 0.0, 2.0), ("b", 1.5, 1.5), ("c", 4.0, 2.5)] {
        let ring: Vec<[f64; 2]> = (0..24)
            .map(|i| {
                let a = i as f64 * std::f64::consts::TAU / 24.0;
                [s * a.cos() + 0.3 * z, s * a.sin()]
            })
            .collect();
        for [x, y] in ring.iter().chain(&ring[..1]) {
            csv += &format!("{label},{z},outer,{x},{y}\n");
        }
    }
    std::fs::write(dir.path().join("stack.csv"), &csv).unwrap();
    let summary = |args: &[&str]| {
        let out = isocube(dir.path(), args);
        let err = String::from_utf8_lossy(&out.stderr).to_string();
        assert!(out.status.success(), "{args:?}: {err}");
        assert!(
            err.contains("check: conforming, 0 inverted, 0 flat"),
            "{err}"
        );
        let count = |after: &str| -> usize {
            let tail = err.split(after).nth(1).unwrap();
            tail.split(' ').next().unwrap().parse().unwrap()
        };
        (count(": "), count("boundary "), err)
    };
    let base = ["tetmesh", "stack.csv", "--cell", "0.25"];
    let with =
        |extra: &[&'static str]| -> Vec<&str> { base.iter().chain(extra).copied().collect() };
    let (split, _, err) = summary(&with(&["-o", "split.msh", "--method", "ternary"]));
    assert!(err.contains("planes at most 0.2500 apart"), "{err}");
    let angles = err.split("dihedral angles ").nth(1).unwrap();
    let (lo, rest) = angles.split_once("°..").unwrap();
    let hi = rest.split('°').next().unwrap();
    assert!(
        lo.parse::<f64>().unwrap() > 10.0 && hi.parse::<f64>().unwrap() < 165.0,
        "{err}"
    );
    let (coarse, surface, _) = summary(&with(&[
        "-o",
        "coarse.vtu",
        "--layer-spacing",
        "sections",
        "--triangulate",
        "local",
        "--method",
        "mc",
    ]));
    assert!(split > 2 * coarse, "{split} {coarse}");
    ok(
        dir.path(),
        &[
            "contours",
            "stack.csv",
            "--cell",
            "0.25",
            "--plain",
            "-o",
            "plain.ply",
        ],
    );
    assert_eq!(
        info(dir.path(), "plain.ply")["triangles"].as_u64().unwrap() as usize,
        surface
    );
    let (_, _, err) = summary(&with(&["-o", "flat.inp", "--cap", "flat", "--flip"]));
    assert!(!err.contains("+ 0 wall triangles"), "{err}");
    for (args, name) in [
        (with(&["-o", "open.msh", "--cap", "none"]), "open.msh"),
        (with(&["-o", "level.msh", "--level", "0.5"]), "level.msh"),
        (with(&["-o", "labels.msh", "--labels"]), "labels.msh"),
        (with(&["-o", "bad.msh", "--layer-spacing", "-1"]), "bad.msh"),
        // Options for volumes are refused on stacks, not ignored.
        (with(&["-o", "dims.msh", "--dims", "4,4,4"]), "dims.msh"),
        (
            with(&["-o", "spacing.msh", "--spacing", "1,1,2"]),
            "spacing.msh",
        ),
        (with(&["-o", "index.msh", "--index-space"]), "index.msh"),
    ] {
        let out = isocube(dir.path(), &args);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        assert!(!dir.path().join(name).exists(), "{name}");
    }
}

/// `tetmesh --labels`: one region per label, conforming; a label that does not occur exits 2
/// with nothing written.
#[test]
fn tetmesh_labels_meshes_each_label() {
    let dir = tempfile::tempdir().unwrap();
    let n = 10usize;
    let mut data = Vec::new();
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let inside = (2..8).contains(&j) && (2..8).contains(&k);
                data.push(match i {
                    2..=4 if inside => 1u8,
                    5..=7 if inside => 2,
                    _ => 0,
                });
            }
        }
    }
    std::fs::write(
        dir.path().join("labels.npy"),
        common::npy("|u1", &format!("({n}, {n}, {n})"), &data),
    )
    .unwrap();
    let out = isocube(
        dir.path(),
        &["tetmesh", "labels.npy", "--labels", "-o", "l.msh"],
    );
    let err = String::from_utf8_lossy(&out.stderr).to_string();
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains("check: conforming, 0 inverted, 0 flat"),
        "{err}"
    );
    let regions = err.lines().find(|l| l.starts_with("regions:")).unwrap();
    assert!(
        regions.contains("label 1: ") && regions.contains("label 2: "),
        "{regions}"
    );
    let msh = std::fs::read_to_string(dir.path().join("l.msh")).unwrap();
    assert!(msh.contains("\"label 1\"") && msh.contains("\"interface 1|2\""));

    let out = isocube(
        dir.path(),
        &["tetmesh", "labels.npy", "--labels", "9", "-o", "none.msh"],
    );
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("label 9 does not occur"));
    assert!(!dir.path().join("none.msh").exists());
    let out = isocube(
        dir.path(),
        &[
            "tetmesh",
            "labels.npy",
            "--labels",
            "--max-memory",
            "20K",
            "-o",
            "big.msh",
        ],
    );
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("the volume mesh needs about"));
    assert!(!dir.path().join("big.msh").exists());
}

/// `quality` on tetrahedral meshes: the counts and angles `tetmesh` reported, a histogram.
#[test]
fn quality_reads_tetrahedral_meshes() {
    let dir = tempfile::tempdir().unwrap();
    for ext in ["msh", "vtu", "mesh", "inp"] {
        let out = isocube(
            dir.path(),
            &[
                "tetmesh",
                "sample:sphere:16",
                "--method",
                "ternary",
                "--snap",
                "0.5",
                "-o",
                &format!("t.{ext}"),
            ],
        );
        assert!(out.status.success());
        let err = String::from_utf8_lossy(&out.stderr).to_string();
        let tets: u64 = err
            .split(": ")
            .nth(1)
            .and_then(|s| s.split(' ').next())
            .unwrap()
            .parse()
            .unwrap();
        let out = isocube(
            dir.path(),
            &[
                "quality",
                &format!("t.{ext}"),
                "--json",
                "--histogram",
                &format!("h-{ext}.svg"),
            ],
        );
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(report["tetrahedra"].as_u64(), Some(tets));
        assert_eq!(report["inverted"].as_u64(), Some(0));
        // The total beside the elements' own volumes (smallest, mean, largest).
        let total = report["total_volume"].as_f64().unwrap();
        let mean = report["volume"]["mean"].as_f64().unwrap();
        assert!(
            (total / tets as f64 - mean).abs() < 1e-5 * total,
            "{total} {mean}"
        );
        assert!(report["min_dihedral"]["min"].as_f64().unwrap() > 10.0);
        assert!(report["max_dihedral"]["max"].as_f64().unwrap() < 165.0);
        // The sphere's boundary has no edge sharper than the elements' angles allow.
        let sharpest = report["sharpest_boundary_edge"].as_f64().unwrap();
        assert!(sharpest >= report["min_dihedral"]["min"].as_f64().unwrap() && sharpest < 180.0);
        let svg = std::fs::read_to_string(dir.path().join(format!("h-{ext}.svg"))).unwrap();
        assert!(svg.contains(&format!("{tets} tetrahedra")));
    }
    let out = isocube(
        dir.path(),
        &["quality", "t.msh", "--field", "sample:sphere:16"],
    );
    assert_eq!(out.status.code(), Some(2));
    // The pores between packed spheres at 24: an element under 10° is shown beside the
    // boundary's sharpest edge, which bounds it.
    let out = isocube(
        dir.path(),
        &[
            "tetmesh",
            "sample:packed-spheres:24",
            "--flip",
            "-o",
            "p.msh",
        ],
    );
    assert!(out.status.success());
    let err = String::from_utf8_lossy(&out.stderr).to_string();
    let angle = |prefix: &str| -> f64 {
        let line = err.lines().find(|l| l.starts_with(prefix)).expect(prefix);
        line[prefix.len()..]
            .split('°')
            .next()
            .unwrap()
            .parse()
            .unwrap()
    };
    let (worst, sharpest) = (
        angle("quality: dihedral angles "),
        angle("sharpest boundary edge: "),
    );
    assert!(worst < 10.0 && worst <= sharpest, "{err}");
}

/// `tetmesh` on a file is bounded by exactly the surface `extract` makes of the same file, also
/// when the file stores its axes z-fastest (a C-order `.npy`, mapped and meshed in its own order
/// by both: before, `tetmesh` read such a file into x-fastest order, and its boundary matched
/// only a sixth of `extract`'s triangles).
#[test]
fn tetmesh_on_a_file_is_bounded_by_extracts_surface() {
    let dir = tempfile::tempdir().unwrap();
    let shape = [13usize, 17, 21];
    let (mut data, mut stored) = (Vec::new(), Vec::new());
    for a in 0..shape[0] {
        for b in 0..shape[1] {
            for c in 0..shape[2] {
                let d = [a, b, c].map(|x| x as f32);
                let v = ((d[0] - 6.2) / 5.0).powi(2)
                    + ((d[1] - 8.1) / 6.5).powi(2)
                    + ((d[2] - 10.3) / 8.0).powi(2)
                    + 0.1 * (d[0] * 0.9 + d[2] * 0.4).sin()
                    - 1.0;
                data.extend_from_slice(&v.to_le_bytes());
                // The same field as integers (converted to f32 whole by `tetmesh`).
                stored.extend_from_slice(&(((v + 2.0) * 1000.0) as u16).to_le_bytes());
            }
        }
    }
    let shape_text = format!("({}, {}, {})", shape[0], shape[1], shape[2]);
    for (name, descr, bytes) in [("v.npy", "<f4", &data), ("w.npy", "<u2", &stored)] {
        std::fs::write(
            dir.path().join(name),
            common::npy(descr, &shape_text, bytes),
        )
        .unwrap();
    }
    let triangle = |p: [[f32; 3]; 3]| {
        let mut t = p.map(|x| x.map(f32::to_bits));
        t.sort_unstable();
        t
    };
    // `tetmesh` keeps snapped points on their grid points by default; `extract` is told so.
    let ternary = [
        "--method",
        "ternary",
        "--snap",
        "0.3",
        "--snap-position",
        "grid",
    ];
    let integers = ["--level", "2000", "--method", "ternary"];
    for (file, method) in [
        ("v.npy", &["--method", "mc"][..]),
        ("v.npy", &ternary),
        ("w.npy", &integers),
    ] {
        let mut args = vec!["extract", file, "-o", "e.ply"];
        args.extend_from_slice(method);
        ok(dir.path(), &args);
        let mut args = vec!["tetmesh", file, "-o", "t.vtu"];
        args.extend_from_slice(method);
        ok(dir.path(), &args);
        let surface = isocube_io::read_mesh(&dir.path().join("e.ply")).unwrap();
        let tets = isocube_io::read_tet_mesh(&dir.path().join("t.vtu")).unwrap();
        let expected: HashSet<[[u32; 3]; 3]> = surface
            .triangles
            .iter()
            .map(|t| triangle(t.map(|v| surface.positions[v as usize])))
            .collect();
        // The tetrahedra's faces used once: the region's boundary (no walls: the region lies
        // inside the grid).
        let mut uses: HashMap<[[u32; 3]; 3], usize> = HashMap::new();
        for t in &tets.tets {
            for skip in 0..4 {
                let mut f = [[0.0f32; 3]; 3];
                for (slot, k) in (0..4).filter(|&k| k != skip).enumerate() {
                    f[slot] = tets.positions[t[k] as usize];
                }
                *uses.entry(triangle(f)).or_default() += 1;
            }
        }
        let boundary: HashSet<[[u32; 3]; 3]> = uses
            .into_iter()
            .filter(|&(_, n)| n == 1)
            .map(|(f, _)| f)
            .collect();
        assert!(expected.len() > 500, "{method:?}");
        let differ = boundary.symmetric_difference(&expected).count();
        assert_eq!(
            differ,
            0,
            "{method:?}: {} boundary triangles",
            boundary.len()
        );
    }
}

/// An RT Structure Set (pydicom, `tests/interop/make_dicom.py`): the key-hole ring ROI becomes a
/// closed surface of genus 1 through every contour vertex (in patient coordinates), written to
/// `NAME-ring.ply`; the POINT ROI is listed as skipped; `--roi` picks by name or number and an
/// unknown one is refused with the ROIs listed.
#[test]
fn rt_structure_sets_mesh_each_roi() {
    let plan = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/volumes/rtstruct.dcm");
    let plan = plan.to_str().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let out = isocube(
        dir.path(),
        &[
            "contours", plan, "-o", "plan.ply", "--cap", "flat", "--ascii",
        ],
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains("ROI 1 'ring'") && err.contains("watertight, genus 1"),
        "{err}"
    );
    assert!(
        err.contains("skipped (no CLOSED_PLANAR contours): 7 'marker' (1 POINT)"),
        "{err}"
    );
    assert!(!dir.path().join("plan-marker.ply").exists());
    let (positions, _) = ascii_ply(&dir.path().join("plan-ring.ply"));
    // The contour vertices (make_dicom.py's key-hole squares about (10, -20)).
    for (k, z) in [-5.0, 0.0, 5.0].into_iter().enumerate() {
        let (o, i) = (30.0 - k as f64, 12.0 + k as f64);
        for (x, y) in [
            (-o, -o),
            (o, -o),
            (o, o),
            (-o, o),
            (-i, i),
            (i, i),
            (i, -i),
            (-i, -i),
        ] {
            let p = [x + 10.0, y - 20.0, z];
            let near = positions
                .iter()
                .map(|q| (0..3).map(|a| (q[a] - p[a]).powi(2)).sum::<f64>().sqrt())
                .fold(f64::INFINITY, f64::min);
            // ASCII PLY's printed floats: well inside 1e-6 of the 85 mm diagonal.
            assert!(near < 1e-5, "{p:?}: {near}");
        }
    }
    let first = std::fs::read(dir.path().join("plan-ring.ply")).unwrap();
    for pick in ["ring", "1", "RING"] {
        ok(
            dir.path(),
            &[
                "contours",
                plan,
                "-o",
                "again.ply",
                "--cap",
                "flat",
                "--ascii",
                "--roi",
                pick,
            ],
        );
        assert_eq!(
            std::fs::read(dir.path().join("again-ring.ply")).unwrap(),
            first
        );
    }
    let out = isocube(
        dir.path(),
        &["contours", plan, "-o", "x.ply", "--roi", "liver"],
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("--roi liver") && err.contains("1 'ring', 7 'marker'"),
        "{err}"
    );
    let out = isocube(
        dir.path(),
        &["contours", plan, "-o", "x.ply", "--roi", "marker"],
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("no region of interest with CLOSED_PLANAR contours"),
        "{err}"
    );
}

/// A DICOM SEG meshed with `--labels`: a closed surface per segment, named in the summary; a
/// label it does not hold is refused with the labels it does.
#[test]
fn dicom_segmentations_mesh_per_segment() {
    let seg = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/volumes/seg.dcm");
    let seg = seg.to_str().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let out = isocube(dir.path(), &["extract", seg, "--labels", "-o", "seg.ply"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains("seg-1.ply: label 1 'low'") && err.contains("seg-2.ply: label 2 'high'"),
        "{err}"
    );
    for label in ["seg-1.ply", "seg-2.ply"] {
        let r = info(dir.path(), label);
        assert_eq!(r["watertight"], true, "{label}: {r}");
    }
    let out = isocube(
        dir.path(),
        &["extract", seg, "--labels", "5", "-o", "x.ply"],
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("it holds labels 1, 2"), "{err}");
}

/// `contours --reference`: the plane grid takes the image's pixels (a 0.5 mm image gives twice
/// the cells of a 1 mm one over the same contours), the surface is still closed through the
/// contours; an oblique series and non-square pixels are refused by name.
#[test]
fn contours_take_the_reference_image_pixels() {
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/volumes");
    let plan = data.join("rtstruct.dcm");
    let plan = plan.to_str().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let image = |name: &str, spacing: &str| {
        let header = format!(
            "ObjectType = Image\nNDims = 3\nDimSize = 4 4 3\nElementSpacing = {spacing} 5\nOffset = -30 -60 -5\nElementType = MET_UCHAR\nElementDataFile = LOCAL\n"
        );
        std::fs::write(
            dir.path().join(name),
            [header.as_bytes(), &[0u8; 48]].concat(),
        )
        .unwrap();
    };
    image("fine.mha", "0.5 0.5");
    image("coarse.mha", "1 1");
    image("oblong.mha", "1 0.5");
    let mut grids = Vec::new();
    for reference in ["fine.mha", "coarse.mha"] {
        let out = isocube(
            dir.path(),
            &[
                "contours",
                plan,
                "-o",
                "r.ply",
                "--cap",
                "flat",
                "--reference",
                reference,
            ],
        );
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            out.status.success() && err.contains("watertight, genus 1"),
            "{err}"
        );
        let grid = err
            .split(" plane grid")
            .next()
            .unwrap()
            .rsplit(", ")
            .next()
            .unwrap();
        let n: usize = grid.split('×').next().unwrap().parse().unwrap();
        grids.push(n);
    }
    // 60 mm of contours and a cell to spare each side.
    assert!(
        grids[0] >= 120 && grids[0] <= 125 && grids[1] >= 60 && grids[1] <= 63,
        "{grids:?}"
    );
    for (reference, says) in [
        ("oblong.mha", "pixels are 1 × 0.5"),
        (data.join("dicom").to_str().unwrap(), "not axial"),
    ] {
        let out = isocube(
            dir.path(),
            &["contours", plan, "-o", "x.ply", "--reference", reference],
        );
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{err}");
        assert!(err.contains(says), "{err}");
    }
}

/// A structure set with one region whose contour crosses itself: the other regions are written
/// and the command exits 2 naming the refused one; asked for by `--roi`, it is the error and
/// nothing is written.
#[test]
fn a_refused_roi_does_not_stop_the_others() {
    let plan =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/volumes/rtstruct-bowtie.dcm");
    let plan = plan.to_str().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let out = isocube(
        dir.path(),
        &["contours", plan, "-o", "plan.ply", "--cap", "flat"],
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("1 region of interest refused, the others written"),
        "{err}"
    );
    assert!(
        err.contains("ROI 9 ('bowtie'), contour 1 (z 0)") && err.contains("meet at (10, 10)"),
        "{err}"
    );
    assert_eq!(info(dir.path(), "plan-ring.ply")["watertight"], true);
    assert!(!dir.path().join("plan-bowtie.ply").exists());
    let out = isocube(
        dir.path(),
        &[
            "contours", plan, "-o", "x.ply", "--roi", "bowtie", "--roi", "ring",
        ],
    );
    assert_eq!(out.status.code(), Some(2));
    assert!(!dir.path().join("x-ring.ply").exists() && !dir.path().join("x-bowtie.ply").exists());
}
