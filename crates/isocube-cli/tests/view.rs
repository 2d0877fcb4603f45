//! `isocube view`'s server, over raw HTTP: what it refuses (no token, a wrong token, another
//! Host, paths outside its routes, bodies, long URLs, stale mesh requests) and what it serves
//! (the page; meshes and downloads equal to `isocube extract`'s, and for labels, cages, contour
//! stacks and mesh files to `extract --labels`, `subdivide` and `contours` files).

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::process::{Child, Command, Stdio};

/// A running `isocube view` and the address and token it printed.
struct Viewer {
    child: Child,
    port: u16,
    token: String,
}

impl Drop for Viewer {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn start(volume: &str) -> Viewer {
    start_with(&[volume])
}

fn start_with(args: &[&str]) -> Viewer {
    let mut child = Command::new(env!("CARGO_BIN_EXE_isocube"))
        .arg("view")
        .args(args)
        .args(["--no-open", "--quiet"])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("the binary runs");
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    // http://127.0.0.1:PORT/?token=TOKEN
    let rest = line.trim().strip_prefix("http://127.0.0.1:").expect(&line);
    let (port, token) = rest.split_once("/?token=").expect(&line);
    Viewer {
        child,
        port: port.parse().unwrap(),
        token: token.to_string(),
    }
}

/// Status and body of one request (written as given: no normalisation of the path).
fn request(port: u16, head: &str) -> (u16, Vec<u8>) {
    let mut stream = TcpStream::connect(("127.0.0.1", port)).unwrap();
    stream.write_all(head.as_bytes()).unwrap();
    let mut reply = Vec::new();
    stream.read_to_end(&mut reply).unwrap();
    let split = reply
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .expect("a header");
    let status = std::str::from_utf8(&reply[9..12]).unwrap().parse().unwrap();
    (status, reply[split + 4..].to_vec())
}

fn get(v: &Viewer, target: &str, host: Option<&str>) -> (u16, Vec<u8>) {
    let host = host.map_or_else(
        || format!("Host: 127.0.0.1:{}\r\n", v.port),
        |h| format!("Host: {h}\r\n"),
    );
    request(
        v.port,
        &format!("GET {target} HTTP/1.1\r\n{host}Connection: close\r\n\r\n"),
    )
}

#[test]
fn the_server_refuses_what_it_does_not_serve() {
    let v = start("sample:sphere:16");
    let t = &v.token;
    let (status, page) = get(&v, &format!("/?token={t}"), None);
    assert_eq!(status, 200);
    assert!(String::from_utf8_lossy(&page).contains("<canvas id=\"gl\""));
    // The token: on every request, exactly.
    assert_eq!(get(&v, "/", None).0, 403);
    assert_eq!(get(&v, "/api/volume", None).0, 403);
    assert_eq!(
        get(&v, &format!("/?token={}", &t[..t.len() - 1]), None).0,
        403
    );
    assert_eq!(get(&v, &format!("/?token={t}0"), None).0, 403);
    // The Host: this address only (no DNS rebinding), and one must be given.
    for host in [
        format!("evil.example:{}", v.port),
        "127.0.0.1".into(),
        format!("127.0.0.1:{}", v.port + 1),
    ] {
        assert_eq!(
            get(&v, &format!("/?token={t}"), Some(&host)).0,
            403,
            "{host}"
        );
    }
    assert_eq!(
        request(v.port, &format!("GET /?token={t} HTTP/1.0\r\n\r\n")).0,
        403
    );
    assert_eq!(
        get(
            &v,
            &format!("/?token={t}"),
            Some(&format!("localhost:{}", v.port))
        )
        .0,
        200
    );
    // No paths from the client: only the routes.
    for path in [
        "/../etc/passwd",
        "/%2e%2e/%2e%2e/etc/passwd",
        "/api/../Cargo.toml",
        "/index.html",
        "/api/slice/../../x",
    ] {
        assert_eq!(get(&v, &format!("{path}?token={t}"), None).0, 404, "{path}");
    }
    // GETs only, without bodies; short request lines.
    let post = format!(
        "POST /api/volume?token={t} HTTP/1.1\r\nHost: 127.0.0.1:{}\r\nContent-Length: 5\r\nConnection: close\r\n\r\nhello",
        v.port
    );
    assert_eq!(request(v.port, &post).0, 405);
    let long = format!("/api/mesh?token={t}&level={}", "1".repeat(3000));
    assert_eq!(get(&v, &long, None).0, 414);
    // Parameters are checked.
    assert_eq!(
        get(&v, &format!("/api/mesh?token={t}&method=nonsense"), None).0,
        400
    );
    assert_eq!(
        get(&v, &format!("/api/slice?token={t}&axis=2&index=99"), None).0,
        400
    );
    assert_eq!(
        get(&v, &format!("/api/download?token={t}&format=exe"), None).0,
        400
    );
}

#[test]
fn meshes_and_downloads_are_the_commands() {
    let dir = tempfile::tempdir().unwrap();
    let v = start("sample:sphere:24");
    let t = &v.token;
    for (seq, level) in [(2, "0.3"), (3, "0.55")] {
        let cli = dir.path().join(format!("{level}.ply"));
        let out = Command::new(env!("CARGO_BIN_EXE_isocube"))
            .args(["extract", "sample:sphere:24", "--level", level, "-o"])
            .arg(&cli)
            .output()
            .unwrap();
        assert!(out.status.success());
        let (status, mesh) = get(
            &v,
            &format!("/api/mesh?token={t}&level={level}&seq={seq}"),
            None,
        );
        assert_eq!(status, 200);
        let triangles = triangles_of(&mesh);
        let json = u32::from_le_bytes(mesh[12..16].try_into().unwrap()) as usize;
        let figures: serde_json::Value = serde_json::from_slice(&mesh[16..16 + json]).unwrap();
        assert_eq!(figures["triangles"], triangles);
        let summary = String::from_utf8_lossy(&out.stderr).to_string();
        let (status, topology) = get(&v, &format!("/api/topology?token={t}&level={level}"), None);
        assert_eq!(status, 200);
        let topology: serde_json::Value = serde_json::from_slice(&topology).unwrap();
        assert_eq!(
            topology["watertight"],
            summary.contains(" watertight "),
            "{summary}"
        );
        // Quantised for the picture: within half a step of the command's vertices and
        // normals (same vertex order).
        let exact = isocube_io::read_mesh(&cli).unwrap();
        let origin: Vec<f32> = serde_json::from_value(figures["origin"].clone()).unwrap();
        let scale: Vec<f32> = serde_json::from_value(figures["scale"].clone()).unwrap();
        let vertices = exact.positions.len();
        assert_eq!(figures["vertices"], vertices);
        let at = 16 + json;
        let normals_at = at + (vertices * 6).next_multiple_of(4);
        for (i, (p, n)) in exact.positions.iter().zip(&exact.normals).enumerate() {
            for a in 0..3 {
                let q =
                    u16::from_le_bytes([mesh[at + 6 * i + 2 * a], mesh[at + 6 * i + 2 * a + 1]]);
                let decoded = origin[a] + scale[a] * f32::from(q);
                assert!(
                    (decoded - p[a]).abs() <= 0.5001 * scale[a] + 1e-6,
                    "vertex {i}"
                );
                let m = f32::from(mesh[normals_at + 4 * i + a] as i8) / 127.0;
                assert!(
                    (m - n[a]).abs() <= 0.5 / 127.0 + 1e-6,
                    "normal {i}: {m} {}",
                    n[a]
                );
            }
        }
        let file = std::fs::read(&cli).unwrap();
        let header = String::from_utf8_lossy(&file[..300]).to_string();
        assert!(
            header.contains(&format!("element face {triangles}\n")),
            "{header}"
        );
        let (status, download) = get(
            &v,
            &format!("/api/download?token={t}&level={level}&format=ply"),
            None,
        );
        assert_eq!(status, 200);
        assert!(
            download == file,
            "the download differs from isocube extract's file"
        );
    }
    // An older mesh request than one already answered is refused at once.
    assert_eq!(
        get(&v, &format!("/api/mesh?token={t}&level=0.4&seq=1"), None).0,
        409
    );
    // A slice: its size and the volume's values.
    let (status, slice) = get(&v, &format!("/api/slice?token={t}&axis=2&index=12"), None);
    assert_eq!(status, 200);
    assert_eq!(slice.len(), 8 + 24 * 24 * 4);
}

fn isocube(args: &[&str]) -> std::process::Output {
    let out = Command::new(env!("CARGO_BIN_EXE_isocube"))
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "isocube {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

fn data(path: &str) -> String {
    format!("{}/../../tests/data/{path}", env!("CARGO_MANIFEST_DIR"))
}

/// `/api/volume`'s description of a viewer's surfaces.
fn describe(v: &Viewer) -> serde_json::Value {
    let (status, body) = get(v, &format!("/api/volume?token={}", v.token), None);
    assert_eq!(status, 200);
    serde_json::from_slice(&body).unwrap()
}

/// The triangle count of a mesh reply, its size checked: the header, the JSON, positions
/// (u16 × 3, padded to 4 bytes), normals (i8 × 4), triangles (u32 × 3).
fn triangles_of(mesh: &[u8]) -> usize {
    assert_eq!(&mesh[..4], b"ICM2");
    let word = |i: usize| u32::from_le_bytes(mesh[i..i + 4].try_into().unwrap()) as usize;
    let (vertices, triangles) = (word(4), word(8));
    assert_eq!(
        mesh.len(),
        16 + word(12) + (vertices * 6).next_multiple_of(4) + vertices * 4 + triangles * 12
    );
    triangles
}

#[test]
fn labels_cages_stacks_and_meshes_are_the_commands_files() {
    let dir = tempfile::tempdir().unwrap();
    let out = |name: &str| dir.path().join(name).to_string_lossy().into_owned();

    // A segmentation: one surface per label, each `extract --labels`'s file.
    let labels = data("volumes/labels.nii.gz");
    isocube(&["extract", &labels, "--labels", "-o", &out("l.ply")]);
    let v = start_with(&[&labels, "--labels"]);
    let scene = describe(&v);
    assert_eq!(scene["kind"], "labels");
    let parts = scene["parts"].as_array().unwrap();
    assert!(parts.len() >= 2, "{scene}");
    for (i, part) in parts.iter().enumerate() {
        let file = std::fs::read(out(&format!("l-{}.ply", part["number"]))).unwrap();
        let (status, body) = get(
            &v,
            &format!("/api/download?token={}&part={i}", v.token),
            None,
        );
        assert_eq!(status, 200);
        assert!(
            body == file,
            "label {}: the download differs",
            part["number"]
        );
        let (_, mesh) = get(&v, &format!("/api/mesh?token={}&part={i}", v.token), None);
        assert_eq!(triangles_of(&mesh), part["triangles"]);
    }
    let t = &v.token;
    assert_eq!(
        get(&v, &format!("/api/mesh?token={t}&part=99"), None).0,
        400
    );
    assert_eq!(
        get(&v, &format!("/api/slice?token={t}&axis=0&index=0"), None).0,
        400
    );
    drop(v);

    // A cage: its edges as lines, its subdivision at the levels asked for, `subdivide`'s files.
    let v = start_with(&["sample:cube", "--levels", "1"]);
    let scene = describe(&v);
    assert_eq!(scene["kind"], "cage");
    assert_eq!(scene["levels"], 1);
    assert_eq!(scene["lines"], 12, "a cube's edges, each once");
    let t = v.token.clone();
    for levels in ["2", "3"] {
        for ext in ["obj", "ply"] {
            let name = out(&format!("c{levels}.{ext}"));
            isocube(&["subdivide", "sample:cube", "--levels", levels, "-o", &name]);
            let (status, body) = get(
                &v,
                &format!("/api/download?token={t}&levels={levels}&format={ext}"),
                None,
            );
            assert_eq!(status, 200);
            assert!(
                body == std::fs::read(&name).unwrap(),
                "{levels} levels, {ext}"
            );
        }
    }
    let (_, mesh) = get(&v, &format!("/api/mesh?token={t}&levels=2"), None);
    assert_eq!(triangles_of(&mesh), 6 * 16 * 2, "quads split in two");
    assert_eq!(
        get(&v, &format!("/api/mesh?token={t}&levels=7"), None).0,
        400
    );
    drop(v);

    // Contour stacks: `contours`'s surface, the contours as lines; an RT Structure Set's
    // regions each a surface, its POINT regions noted.
    isocube(&["contours", "sample:orebody", "-o", &out("ore.ply")]);
    let v = start("sample:orebody");
    let scene = describe(&v);
    assert_eq!(scene["kind"], "contours");
    assert!(scene["lines"].as_u64().unwrap() > 100, "{scene}");
    let (_, body) = get(&v, &format!("/api/download?token={}", v.token), None);
    assert!(body == std::fs::read(out("ore.ply")).unwrap());
    let (status, lines) = get(&v, &format!("/api/lines?token={}", v.token), None);
    assert_eq!(status, 200);
    assert_eq!(&lines[..4], b"ICL1");
    assert_eq!(
        lines.len(),
        8 + scene["lines"].as_u64().unwrap() as usize * 24
    );
    drop(v);
    let plan = data("volumes/rtstruct.dcm");
    isocube(&["contours", &plan, "-o", &out("plan.ply")]);
    let v = start(&plan);
    let scene = describe(&v);
    assert_eq!(scene["kind"], "contours");
    assert_eq!(scene["parts"][0]["name"], "ring", "{scene}");
    assert!(
        scene["notes"][0].as_str().unwrap().contains("'marker'"),
        "{scene}"
    );
    let (_, body) = get(&v, &format!("/api/download?token={}", v.token), None);
    assert!(body == std::fs::read(out("plan-ring.ply")).unwrap());
    drop(v);

    // A mesh file: shown as read; converted by the downloads.
    let v = start(&out("ore.ply"));
    let scene = describe(&v);
    assert_eq!(scene["kind"], "mesh");
    let ply = std::fs::read(out("ore.ply")).unwrap();
    let header = String::from_utf8_lossy(&ply[..300]).to_string();
    assert!(
        header.contains(&format!(
            "element face {}\n",
            scene["parts"][0]["triangles"]
        )),
        "{header}"
    );
    let (status, topology) = get(&v, &format!("/api/topology?token={}", v.token), None);
    assert_eq!(status, 200);
    let topology: serde_json::Value = serde_json::from_slice(&topology).unwrap();
    assert_eq!(topology["watertight"], true);
}

#[test]
fn an_extraction_overtaken_by_a_newer_request_stops() {
    let v = start("sample:tangle:256");
    let (port, t) = (v.port, v.token.clone());
    let target = |level: &str, seq: u32| format!("/api/mesh?token={t}&level={level}&seq={seq}");
    // Warm: the volume's first extraction, alone, is served.
    assert_eq!(get(&v, &target("0.5", 1), None).0, 200);
    let older = {
        let head = format!(
            "GET {} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nConnection: close\r\n\r\n",
            target("0.7", 2)
        );
        std::thread::spawn(move || {
            let status = request(port, &head).0;
            (status, std::time::Instant::now())
        })
    };
    std::thread::sleep(std::time::Duration::from_millis(15));
    let sent = std::time::Instant::now();
    assert_eq!(get(&v, &target("0.9", 3), None).0, 200);
    let (status, answered) = older.join().unwrap();
    // Stopped (or refused on arrival) once the newer one came in, unless it was done before.
    assert!(
        status == 409 || (status == 200 && answered < sent),
        "the older request got {status} after the newer one was sent"
    );
}
