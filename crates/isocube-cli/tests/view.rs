//! `isocube view`'s server, over raw HTTP: what it refuses (no token, a wrong token, another
//! Host, paths outside its routes, bodies, long URLs, stale mesh requests) and what it serves
//! (the page; meshes and downloads equal to `isocube extract`'s).

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
    let mut child = Command::new(env!("CARGO_BIN_EXE_isocube"))
        .args(["view", volume, "--no-open", "--quiet"])
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
        assert_eq!(&mesh[..4], b"ICM1");
        let word = |i: usize| u32::from_le_bytes(mesh[i..i + 4].try_into().unwrap()) as usize;
        let (vertices, triangles, json) = (word(4), word(8), word(12));
        assert_eq!(mesh.len(), 16 + json + vertices * 24 + triangles * 12);
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
