//! One file, one mesh: whichever path the command takes (mapped, converted slab by slab,
//! streamed, boxes of cells, whole-volume work), whatever type the values are stored as; and
//! numbers with a leading minus wherever a command takes numbers.

use std::path::Path;

mod common;
use common::{isocube, ok};

/// The types a `.npy` can hold the same small integers in, with the offset that keeps them
/// non-negative for unsigned types.
const TYPES: [(&str, &str, i32); 5] = [
    ("u8", "|u1", 2),
    ("i16", "<i2", 0),
    ("i32", "<i4", 0),
    ("f32", "<f4", 0),
    ("f64", "<f8", 0),
];

/// `value + offset` stored as `descr`.
fn encode(descr: &str, values: &[i32], offset: i32) -> Vec<u8> {
    let mut out = Vec::new();
    for &v in values {
        let v = v + offset;
        match descr {
            "|u1" => out.push(v as u8),
            "<i2" => out.extend((v as i16).to_le_bytes()),
            "<i4" => out.extend(v.to_le_bytes()),
            "<f4" => out.extend((v as f32).to_le_bytes()),
            _ => out.extend(f64::from(v).to_le_bytes()),
        }
    }
    out
}

/// Random integers in −2..=2, most of them exactly at one of the levels: every tie rule and
/// every frame difference shows.
fn tied(count: usize, seed: u64) -> Vec<i32> {
    let mut state = seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1;
    (0..count)
        .map(|_| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state % 5) as i32 - 2
        })
        .collect()
}

/// The reproduction and more: a tied integer volume stored as u8, i16, i32, f32 and f64
/// (C order, `a[x, y, z]`: the file's memory order is not the index order) meshes to the same
/// bytes through every path — in place or converted, one pass, slab by slab, `--stream`, boxes
/// of cells of several sizes, ternary (read whole), relaxation — at several levels, with a
/// negative origin.
#[test]
fn every_path_and_type_writes_the_same_file() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let shape = [17usize, 19, 23];
    let values = tied(shape.iter().product(), 49);
    let dims = format!("({}, {}, {})", shape[0], shape[1], shape[2]);
    for (name, descr, offset) in TYPES {
        let npy = common::npy(descr, &dims, &encode(descr, &values, offset));
        std::fs::write(d.join(format!("v-{name}.npy")), npy).unwrap();
    }
    let variants: [&[&str]; 9] = [
        &[],
        &["--stream"],
        &["--chunk", "7,5,3"],
        &["--chunk", "64,64,64"],
        &["--chunk", "1,200,13"],
        &["--method", "ternary"],
        &["--method", "ternary", "--chunk", "7,5,3"],
        &[
            "--method",
            "ternary",
            "--snap",
            "0.5",
            "--triangulate",
            "optimal",
        ],
        &["--relax", "1"],
    ];
    let mut compared = 0;
    for level in [-1, 0, 1] {
        for (v, extra) in variants.iter().enumerate() {
            let mut reference: Option<(String, Vec<u8>)> = None;
            for (name, _, offset) in TYPES {
                let input = format!("v-{name}.npy");
                let out = format!("{name}-{v}.ply");
                let level = (level + offset).to_string();
                let mut args = vec!["extract", &input, "-o", &out, "--level", &level, "--origin"];
                args.push("-1.25,-2.5,-0.75");
                args.extend_from_slice(extra);
                ok(d, &args);
                let bytes = std::fs::read(d.join(&out)).unwrap();
                match &reference {
                    None => reference = Some((name.to_string(), bytes)),
                    Some((first, want)) => {
                        assert!(
                            &bytes == want,
                            "{name} differs from {first}: level {level}, {extra:?}"
                        );
                        compared += 1;
                    }
                }
            }
            // Every variant but the ones that change the mesh is the one-pass file.
            let (_, bytes) = reference.unwrap();
            if v > 0 && v < 5 {
                let one = std::fs::read(d.join("f64-0.ply")).unwrap();
                assert!(
                    bytes == one,
                    "level {level}: {extra:?} differs from one pass"
                );
            }
            if v == 6 {
                let one = std::fs::read(d.join("f64-5.ply")).unwrap();
                assert!(
                    bytes == one,
                    "level {level}: ternary boxes differ from one pass"
                );
            }
        }
    }
    assert_eq!(compared, 3 * variants.len() * (TYPES.len() - 1));
}

/// The same integers stored `a[z, y, x]` (`--axes zyx`, x fastest) and as the `a[x, y, z]`
/// file read in index space: the frames agree between whole-volume and slab-wise work there too.
#[test]
fn index_space_and_zyx_files_agree_across_paths() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let shape = [9usize, 11, 13];
    let values = tied(shape.iter().product(), 7);
    std::fs::write(
        d.join("xyz.npy"),
        common::npy("<i2", "(9, 11, 13)", &encode("<i2", &values, 0)),
    )
    .unwrap();
    std::fs::write(
        d.join("zyx.npy"),
        common::npy("<i2", "(13, 11, 9)", &encode("<i2", &values, 0)),
    )
    .unwrap();
    for (input, extra) in [
        ("xyz.npy", &["--index-space"][..]),
        ("zyx.npy", &["--axes", "zyx"][..]),
    ] {
        let mut files = Vec::new();
        for (n, path) in [
            &[][..],
            &["--chunk", "4,3,5"][..],
            &["--stream"][..],
            &["--relax", "1", "--level", "0.5"][..],
            &["--relax", "1", "--level", "0.5", "--chunk", "2,2,2"][..],
        ]
        .iter()
        .enumerate()
        {
            let out = format!("{n}.ply");
            let mut args = vec!["extract", input, "-o", &out];
            args.extend_from_slice(extra);
            args.extend_from_slice(path);
            ok(d, &args);
            files.push(std::fs::read(d.join(&out)).unwrap());
        }
        assert!(files[0] == files[1] && files[0] == files[2], "{input}");
        assert!(files[3] == files[4], "{input}: relaxed");
    }
}

/// What a command made of an option's value: `Ok` with the run's stderr, or the error text.
fn run(dir: &Path, args: &[&str]) -> Result<String, String> {
    let out = isocube(dir, args);
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(
        !err.contains("unexpected argument") && !err.contains("a value is required"),
        "{args:?}: the minus was read as a flag: {err}"
    );
    match out.status.success() {
        true => Ok(err),
        false => Err(err),
    }
}

/// Every option that takes a number or a list of numbers takes a leading minus as users type
/// it (`--origin -1.25,-1.25,-1.25`, not only `--origin=…`), in every command: a value that
/// may be negative is used, one that may not is refused by its own check, naming it.
#[test]
fn negative_numbers_are_values_in_every_command() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let n = 12usize;
    let mut values = Vec::new();
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let r = [i, j, k].map(|c| c as f64 - 5.5);
                values.push((r.iter().map(|x| x * x).sum::<f64>().sqrt() - 4.0) as f32);
            }
        }
    }
    let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
    std::fs::write(
        d.join("ball.npy"),
        common::npy("<f4", "(12, 12, 12)", &bytes),
    )
    .unwrap();
    std::fs::write(d.join("ball.raw"), &bytes).unwrap();
    let labels: Vec<u8> = values
        .iter()
        .flat_map(|&v| (if v < 0.0 { -3i16 } else { 0 }).to_le_bytes())
        .collect();
    std::fs::write(
        d.join("seg.npy"),
        common::npy("<i2", "(12, 12, 12)", &labels),
    )
    .unwrap();
    ok(d, &["extract", "ball.npy", "-o", "plain.ply"]);

    // Used: the mesh moves by the origin, or the level is the negative one.
    let origin = run(
        d,
        &[
            "extract",
            "ball.npy",
            "--origin",
            "-1.25,-1.25,-1.25",
            "-o",
            "o.ply",
        ],
    );
    assert!(origin.is_ok(), "{origin:?}");
    let equals = run(
        d,
        &[
            "extract",
            "ball.npy",
            "--origin=-1.25,-1.25,-1.25",
            "-o",
            "e.ply",
        ],
    );
    assert!(equals.is_ok());
    assert_eq!(
        std::fs::read(d.join("o.ply")).unwrap(),
        std::fs::read(d.join("e.ply")).unwrap()
    );
    assert_ne!(
        std::fs::read(d.join("o.ply")).unwrap(),
        std::fs::read(d.join("plain.ply")).unwrap()
    );
    for args in [
        &["extract", "ball.npy", "--level", "-1.5", "-o", "l.ply"][..],
        &[
            "extract", "ball.npy", "--level", "-1", "--origin", "-3,-2,-1", "--chunk", "3,4,5",
            "-o", "c.ply",
        ][..],
        &[
            "extract", "ball.npy", "--origin", "-1,-1,-1", "--stream", "-o", "s.ply",
        ][..],
        &[
            "extract", "ball.npy", "--origin", "-1,-1,-1", "--method", "ternary", "-o", "t.ply",
        ][..],
        &[
            "extract", "ball.raw", "--dims", "12,12,12", "--type", "f32", "--origin", "-6,-6,-6",
            "-o", "r.ply",
        ][..],
        &[
            "extract",
            "seg.npy",
            "--labels",
            "--background",
            "0",
            "--origin",
            "-5,-5,-5",
            "-o",
            "lab.ply",
        ][..],
        &[
            "extract",
            "seg.npy",
            "--labels=-3",
            "--origin",
            "-5,-5,-5",
            "-o",
            "neg.ply",
        ][..],
        &[
            "extract",
            "seg.npy",
            "--labels",
            "--background",
            "-3",
            "-o",
            "bg.ply",
            "--allow-empty",
        ][..],
        &[
            "extract",
            "ball.npy",
            "--values",
            "ball.npy",
            "--origin",
            "-2.5,-2.5,-2.5",
            "-o",
            "v.ply",
        ][..],
        &[
            "tetmesh",
            "ball.npy",
            "--origin",
            "-1.25,-1.25,-1.25",
            "--level",
            "-1",
            "-o",
            "t.msh",
        ][..],
        &[
            "tetmesh",
            "seg.npy",
            "--labels",
            "--background",
            "0",
            "--origin",
            "-1,-2,-3",
            "-o",
            "tl.msh",
        ][..],
        // An option after one whose value is optional or several stays an option.
        &["tetmesh", "seg.npy", "-o", "tq.msh", "--labels", "--quiet"][..],
        &["extract", "seg.npy", "-o", "eq.ply", "--labels", "--quiet"][..],
        &[
            "contours",
            "sample:orebody",
            "--cap",
            "flat",
            "--quiet",
            "-o",
            "flat.ply",
        ][..],
        &[
            "quality",
            "plain.ply",
            "--field",
            "ball.npy",
            "--level",
            "-0.0",
        ][..],
    ] {
        assert!(run(d, args).is_ok(), "{args:?}: {:?}", run(d, args));
    }

    // Refused by the value's own check, which names it: not taken for a flag.
    for (args, says) in [
        (
            &["extract", "ball.npy", "--spacing", "-1,1,1", "-o", "x.ply"][..],
            "spacing",
        ),
        (
            &["extract", "ball.npy", "--chunk", "-7,5,3", "-o", "x.ply"][..],
            "-7",
        ),
        (
            &[
                "extract", "ball.npy", "--snap", "-0.5", "--method", "ternary", "-o", "x.ply",
            ][..],
            "snap",
        ),
        (
            &[
                "extract",
                "ball.npy",
                "--zero-threshold",
                "-0.1",
                "--method",
                "ternary",
                "-o",
                "x.ply",
            ][..],
            "threshold",
        ),
        (
            &["extract", "ball.npy", "--relax", "-1", "-o", "x.ply"][..],
            "-1",
        ),
        (
            &["extract", "ball.npy", "--max-memory", "-5G", "-o", "x.ply"][..],
            "-5G",
        ),
        (
            &["extract", "ball.npy", "--frame", "-1", "-o", "x.ply"][..],
            "-1",
        ),
        (
            &["extract", "ball.npy", "--channel", "-1", "-o", "x.ply"][..],
            "-1",
        ),
        (
            &["extract", "ball.npy", "--scale", "-1", "-o", "x.ply"][..],
            "-1",
        ),
        (
            &[
                "extract", "ball.npy", "--smooth", "-1", "--labels", "-o", "x.ply",
            ][..],
            "-1",
        ),
        (
            &[
                "extract",
                "ball.raw",
                "--dims",
                "-12,12,12",
                "--type",
                "f32",
                "-o",
                "x.ply",
            ][..],
            "-12",
        ),
        (
            &[
                "extract",
                "ball.raw",
                "--dims",
                "12,12,12",
                "--type",
                "f32",
                "--header-bytes",
                "-4",
                "-o",
                "x.ply",
            ][..],
            "-4",
        ),
        (
            &["tetmesh", "ball.npy", "--spacing", "-1,1,1", "-o", "x.msh"][..],
            "spacing",
        ),
        (
            &[
                "tetmesh",
                "sample:orebody",
                "--layer-spacing",
                "-1",
                "-o",
                "x.msh",
            ][..],
            "-1",
        ),
        (
            &["tetmesh", "sample:orebody", "--cell", "-0.5", "-o", "x.msh"][..],
            "-0.5",
        ),
        (
            &["tetmesh", "sample:orebody", "--grid", "-8x8", "-o", "x.msh"][..],
            "-8x8",
        ),
        (
            &[
                "contours",
                "sample:orebody",
                "--cell",
                "-0.5",
                "-o",
                "x.ply",
            ][..],
            "-0.5",
        ),
        (
            &[
                "contours",
                "sample:orebody",
                "--grid",
                "-8x8",
                "-o",
                "x.ply",
            ][..],
            "-8x8",
        ),
        (
            &[
                "contours",
                "sample:orebody",
                "--cap",
                "extend",
                "-5",
                "-o",
                "x.ply",
            ][..],
            "5",
        ),
        (
            &["subdivide", "sample:cube", "--levels", "-1", "-o", "x.obj"][..],
            "-1",
        ),
        (
            &["render", "plain.ply", "--size", "-8x8", "-o", "x.png"][..],
            "-8x8",
        ),
        (&["demo", "--size", "-8", "--out", "demo"][..], "-8"),
        (&["demo", "--picture", "-8x8", "--out", "demo"][..], "-8x8"),
        (&["view", "ball.npy", "--port", "-1"][..], "-1"),
        (
            &[
                "view",
                "ball.npy",
                "--origin",
                "-1,-1,-1",
                "--spacing",
                "-1,1,1",
            ][..],
            "spacing",
        ),
        (&["view", "ball.npy", "--levels", "-2"][..], "-2"),
        (
            &["view", "ball.npy", "--level", "-1e9", "--max-memory", "-1"][..],
            "-1",
        ),
    ] {
        match run(d, args) {
            Ok(err) => panic!("{args:?} was accepted: {err}"),
            Err(err) => assert!(err.contains(says), "{args:?}: {err}"),
        }
    }
    assert!(!d.join("x.ply").exists() && !d.join("x.msh").exists());
}
