//! `isocube view INPUT`: a page in the browser to explore a volume — drag the level and see
//! the surface change at once — or to look at a segmentation's labels, a mesh, a cage and its
//! subdivision, a contour stack's surface (`view/parts.rs`).
//!
//! The binary serves one page (HTML and script embedded, no dependencies) and a small API on
//! 127.0.0.1. Every request must carry the random token printed in the URL and a `Host` of
//! this address (a page of another site cannot reach the server through DNS rebinding); only
//! the fixed routes exist, no path from the client names a file; requests are GETs without a
//! body and short URLs; they are answered one at a time (an extraction uses every core), and a
//! mesh request older than the latest one is answered at once with 409, so a fast slider never
//! queues work.

use std::io::Write;
use std::ops::ControlFlow;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Instant;

use clap::Args as ClapArgs;
use isocube::cube::Topology;
use isocube::extract::{extract_into, ExtractError, ExtractOptions, SnapPosition};
use isocube::field::{Grid, Level, Orientation, ValueSummary};
use isocube::mesh::Mesh;
use isocube::quality::{quality_report, Strategy};
use isocube_io::{write_mesh_to, MeshFormat};
use tiny_http::{Header, Method as HttpMethod, Request, Response, Server};

use crate::commands::contours::StackArgs;
use crate::commands::extract::{Choices, LabelArgs};
use crate::volume::VolumeArgs;
use crate::Failure;

mod parts;
use parts::{Kind, Parts, MAX_LEVELS};

#[derive(Debug, ClapArgs)]
pub(crate) struct Args {
    #[command(flatten)]
    volume: VolumeArgs,
    /// The level the page opens at: a number, `auto` (Otsu's threshold) or a percentage of the
    /// value range.
    #[arg(long, default_value = "auto", allow_negative_numbers = true)]
    level: Level,
    /// Port on 127.0.0.1 (0: any free port).
    #[arg(long, default_value_t = 0)]
    port: u16,
    /// Print the URL but do not open a browser.
    #[arg(long)]
    no_open: bool,
    /// Mesh in grid indices rather than the file's world coordinates.
    #[arg(long)]
    index_space: bool,
    #[command(flatten)]
    label: LabelArgs,
    /// Cages (.obj polygons, `sample:cube|plate|box-hole|boss`): the subdivision levels the page
    /// opens at (0 to 6; the page changes them).
    #[arg(long, default_value_t = 2)]
    levels: usize,
    #[command(flatten)]
    stack: StackArgs,
}

/// Bins of the value histogram the page draws behind the level slider.
const BINS: usize = 256;
/// The longest request line accepted (routes and their parameters are short).
const MAX_URL: usize = 2048;
/// Requests admitted and waiting for their answer; more wait in the listening socket.
const QUEUE: usize = 64;

/// The page's HTML and script (inlined into it when served).
const PAGE_HTML: &str = include_str!("view/index.html");
const PAGE_SCRIPT: &str = include_str!("view/view.js");

pub(crate) fn run(args: &Args, quiet: bool) -> Result<(), Failure> {
    let max_memory = crate::volume::MemoryLimit::or_default(args.volume.max_memory);
    let loaded = parts::load(args, max_memory, quiet)?;
    let scene = match loaded {
        Some(parts) => Scene::Parts(parts),
        None => {
            if let Some(flag) = args.stack.given() {
                return Err(Failure::input(anyhow::anyhow!(
                    "{flag} applies to contour stacks; {} is a volume",
                    args.volume.volume
                )));
            }
            // Walked as `extract` walks the file, so downloads are its files.
            let (grid, orientation) = args.volume.load_walked(args.index_space)?;
            let summary = ValueSummary::of(grid.values());
            let level =
                crate::volume::resolve_level(args.level, &args.volume.volume, || summary.clone())?;
            Scene::Volume(Volume {
                grid,
                orientation,
                summary,
                level,
                cached: None,
                coarse: None,
            })
        }
    };
    let server = Server::http(("127.0.0.1", args.port)).map_err(|e| {
        Failure::input(anyhow::anyhow!(
            "cannot listen on 127.0.0.1:{}: {e}",
            args.port
        ))
    })?;
    let port = server
        .server_addr()
        .to_ip()
        .map(|a| a.port())
        .ok_or_else(|| Failure::input(anyhow::anyhow!("the server has no TCP address")))?;
    let token = token().map_err(|e| Failure::input(anyhow::anyhow!("no random token: {e}")))?;
    let url = format!("http://127.0.0.1:{port}/?token={token}");
    // The URL on stdout (one line, for scripts), the rest on stderr.
    println!("{url}");
    if !quiet {
        let what = match &scene {
            Scene::Volume(v) => {
                let [x, y, z] = v.grid.dims();
                format!("{x}×{y}×{z}")
            }
            Scene::Parts(p) => format!(
                "{}, {} surface{}",
                p.kind.name(),
                p.parts.len(),
                if p.parts.len() == 1 { "" } else { "s" }
            ),
        };
        eprintln!(
            "isocube view: {} ({what}) on {url} — Ctrl-C to stop",
            args.volume.volume
        );
        if let Scene::Parts(p) = &scene {
            for note in &p.notes {
                eprintln!("note: {note}");
            }
        }
    }
    if !args.no_open {
        open_browser(&url);
    }
    let gate = Gate {
        token,
        hosts: [format!("127.0.0.1:{port}"), format!("localhost:{port}")],
    };
    let newest = Arc::new(AtomicU64::new(0));
    // One thread takes requests in, refuses what the gate refuses at once, and notes the newest
    // mesh request as it arrives, so the extraction running for an older one stops; another
    // answers the admitted ones in turn (an extraction uses every core). At most QUEUE wait.
    let (queue, admitted) = std::sync::mpsc::sync_channel::<(Request, String, Query)>(QUEUE);
    let noted = newest.clone();
    std::thread::spawn(move || {
        for request in server.incoming_requests() {
            match gate.admit(&request) {
                Ok((path, query)) => {
                    if path == "/api/mesh" {
                        noted.fetch_max(query.seq(), Ordering::SeqCst);
                    }
                    if queue.send((request, path, query)).is_err() {
                        break;
                    }
                }
                Err(answer) => reply(request, answer),
            }
        }
    });
    let mut state = State {
        name: args.volume.volume.clone(),
        scene,
        max_memory,
        newest,
    };
    for (request, path, query) in admitted {
        let response = state.answer(&path, &query);
        reply(request, response);
    }
    Ok(())
}

/// Answers a request and closes its connection.
///
/// tiny_http serves each connection on a thread of its pool, and its pool can leave a new
/// connection queued behind connections the browser keeps alive (two connections accepted at
/// once can both be handed to one waiting thread; measured: about one page load in twenty
/// under load never got its mesh). One request per connection frees the thread at once, so
/// a queued connection waits for milliseconds at most. tiny_http drops a `Connection` header
/// from a `Response`, hence the response is written here.
fn reply(request: Request, answer: Answer) {
    let status = answer.status_code();
    let mut head = format!(
        "HTTP/1.1 {} {}\r\n",
        status.0,
        status.default_reason_phrase()
    );
    for h in answer.headers() {
        head.push_str(&format!("{}: {}\r\n", h.field, h.value));
    }
    let body = answer.into_reader().into_inner();
    head.push_str(&format!(
        "Content-Length: {}\r\nConnection: close\r\n\r\n",
        body.len()
    ));
    let mut writer = request.into_writer();
    // A client that went away is no error of the server's.
    let _ = writer
        .write_all(head.as_bytes())
        .and_then(|()| writer.write_all(&body))
        .and_then(|()| writer.flush());
}

/// 128 random bits as hex.
fn token() -> Result<String, getrandom::Error> {
    let mut bytes = [0u8; 16];
    getrandom::fill(&mut bytes)?;
    Ok(bytes.iter().map(|b| format!("{b:02x}")).collect())
}

fn open_browser(url: &str) {
    let opener = if cfg!(target_os = "macos") {
        "open"
    } else if cfg!(windows) {
        "explorer"
    } else {
        "xdg-open"
    };
    // No browser (a server, CI) is fine: the URL is printed.
    let _ = std::process::Command::new(opener)
        .arg(url)
        .stdin(std::process::Stdio::null())
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn();
}

type Answer = Response<std::io::Cursor<Vec<u8>>>;

/// What the mesh routes are asked for.
#[derive(Clone, Debug, PartialEq)]
struct Settings {
    /// The preview while the slider moves: every `coarse`-th grid point along each axis (2:
    /// about a quarter of the triangles); 1 for the full surface.
    coarse: usize,
    level: f32,
    method: String,
    topology: Topology,
    triangulate: Strategy,
    snap: f32,
}

/// What the page shows.
enum Scene {
    /// A volume's level set, re-extracted as the level moves.
    Volume(Volume),
    /// Fixed surfaces: labels, a mesh, a cage's subdivision, contour stacks.
    Parts(Parts),
}

struct Volume {
    grid: Grid,
    orientation: Orientation,
    summary: Option<ValueSummary>,
    level: f32,
    /// The last mesh made, and what it was made with.
    cached: Option<(Settings, Arc<Made>)>,
    /// The preview grid (its stride and points), made when first asked for.
    coarse: Option<(usize, Grid)>,
}

/// Checks every request before any work: the token, the Host, the method, the size.
struct Gate {
    token: String,
    hosts: [String; 2],
}

struct State {
    name: String,
    scene: Scene,
    max_memory: Option<u64>,
    /// The highest `seq` of a mesh request received (set by the thread taking requests in).
    newest: Arc<AtomicU64>,
}

/// A mesh and its figures.
struct Made {
    mesh: Mesh,
    millis: f64,
}

fn text(status: u16, body: impl Into<String>) -> Answer {
    Response::from_string(body.into())
        .with_status_code(status)
        .with_header(header("Content-Type", "text/plain; charset=utf-8"))
}

fn header(name: &str, value: &str) -> Header {
    Header::from_bytes(name.as_bytes(), value.as_bytes()).unwrap_or_else(|_| {
        Header::from_bytes(&b"X-Invalid"[..], &b"1"[..]).expect("a constant header")
    })
}

fn bytes(body: Vec<u8>, kind: &str) -> Answer {
    // A length rather than chunks: the size is known, and the page can tell a cut reply.
    Response::from_data(body)
        .with_chunked_threshold(usize::MAX)
        .with_header(header("Content-Type", kind))
        .with_header(header("Cache-Control", "no-store"))
}

/// Every `n`-th grid point along each axis (spacing × n, 1/n³ of the cells): the same box, less
/// the last cells of an axis whose point count is not 1 more than a multiple of n.
fn every_nth(grid: &Grid, n: usize) -> Result<Grid, String> {
    let [nx, ny, nz] = grid.dims();
    let dims = [nx.div_ceil(n), ny.div_ceil(n), nz.div_ceil(n)];
    let mut values = Vec::with_capacity(dims.iter().product());
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                values.push(grid.value(n * i, n * j, n * k));
            }
        }
    }
    let spacing = grid.spacing().map(|s| n as f64 * s);
    Grid::new(dims, values)
        .and_then(|g| g.with_spacing(spacing))
        .and_then(|g| g.with_origin(grid.origin()))
        .map_err(|e| e.to_string())
}

/// A request's query parameters, decoded.
struct Query(Vec<(String, String)>);

impl Query {
    fn get(&self, name: &str) -> Option<&str> {
        self.0
            .iter()
            .find(|(k, _)| k == name)
            .map(|(_, v)| v.as_str())
    }

    /// The mesh request's number (the page counts them; 0 when not given).
    fn seq(&self) -> u64 {
        self.get("seq")
            .and_then(|v| v.parse::<u64>().ok())
            .unwrap_or(0)
    }
}

/// Compares two strings in time independent of where they differ.
fn same(a: &str, b: &str) -> bool {
    a.len() == b.len() && a.bytes().zip(b.bytes()).fold(0u8, |d, (x, y)| d | (x ^ y)) == 0
}

impl Volume {
    /// The volume's size, place, value range and histogram, and the opening level.
    fn describe(&self, name: &str) -> Answer {
        let [nx, ny, nz] = self.grid.dims();
        let (min, max) = self
            .summary
            .as_ref()
            .map_or((0.0, 0.0), |s| (f64::from(s.min), f64::from(s.max)));
        let mut counts = vec![0u64; BINS];
        if max > min {
            for &v in self.grid.values() {
                if v.is_finite() {
                    let b = ((f64::from(v) - min) / (max - min) * BINS as f64) as usize;
                    counts[b.min(BINS - 1)] += 1;
                }
            }
        }
        let json = serde_json::json!({
            "kind": "volume",
            "name": name,
            "dims": [nx, ny, nz],
            "spacing": self.grid.spacing(),
            "origin": self.grid.origin(),
            "direction": self.orientation.direction(),
            "min": min,
            "max": max,
            "level": self.level,
            "histogram": counts,
        });
        bytes(json.to_string().into_bytes(), "application/json")
    }

    fn settings(&self, q: &Query) -> Result<Settings, Answer> {
        let bad = |what: &str, v: &str| text(400, format!("{what}: '{v}' is not accepted"));
        let level = match q.get("level") {
            Some(v) => v
                .parse::<f32>()
                .ok()
                .filter(|l| l.is_finite())
                .ok_or_else(|| bad("level", v))?,
            None => self.level,
        };
        let method = match q.get("method").unwrap_or("mc") {
            m @ ("mc" | "ternary") => m.to_string(),
            m => return Err(bad("method", m)),
        };
        let topology = q
            .get("topology")
            .unwrap_or("mc33")
            .parse::<Topology>()
            .map_err(|_| bad("topology", q.get("topology").unwrap_or("")))?;
        let triangulate = q
            .get("triangulate")
            .unwrap_or("fan")
            .parse::<Strategy>()
            .map_err(|_| bad("triangulate", q.get("triangulate").unwrap_or("")))?;
        let snap = match q.get("snap") {
            Some(v) => v
                .parse::<f32>()
                .ok()
                .filter(|s| (0.0..=0.5).contains(s))
                .ok_or_else(|| bad("snap", v))?,
            None => 0.3,
        };
        Ok(Settings {
            coarse: 1,
            level,
            method,
            topology,
            triangulate,
            snap,
        })
    }

    /// The library's options for these settings: those `isocube extract` gives for the same
    /// arguments, so a download is the command's file.
    fn options(&self, s: &Settings, max_memory: Option<u64>) -> ExtractOptions {
        let room = max_memory
            .map(|limit| limit.saturating_sub(std::mem::size_of_val(self.grid.values()) as u64));
        // `isocube extract`'s defaults for what the page does not offer.
        Choices {
            method: &s.method,
            topology: s.topology,
            triangulate: s.triangulate,
            zero_threshold: 0.0,
            snap: s.snap,
            snap_position: SnapPosition::NearestCrossing,
            flip: false,
            normals: true,
            relax: 0,
        }
        .options(s.level)
        .with_max_memory(room)
    }

    /// The mesh for these settings: the last one again, or a new one. With `cancel` (the
    /// newest request's number, and this one's), the extraction stops once a newer request
    /// has arrived, answered 409.
    fn made(
        &mut self,
        s: &Settings,
        max_memory: Option<u64>,
        cancel: Option<(&AtomicU64, u64)>,
    ) -> Result<Arc<Made>, Answer> {
        if let Some((cached, made)) = &self.cached {
            if cached == s {
                return Ok(made.clone());
            }
        }
        let options = self.options(s, max_memory);
        if s.coarse > 1 && self.coarse.as_ref().is_none_or(|(k, _)| *k != s.coarse) {
            let grid = every_nth(&self.grid, s.coarse).map_err(|e| text(500, e))?;
            self.coarse = Some((s.coarse, grid));
        }
        let grid = match &self.coarse {
            Some((_, g)) if s.coarse > 1 => g,
            _ => &self.grid,
        };
        let view = grid.view().with_orientation(self.orientation);
        let started = Instant::now();
        let mut mesh = Mesh::new();
        let mut progress = |_, _| match cancel {
            Some((newest, seq)) if newest.load(Ordering::SeqCst) > seq => ControlFlow::Break(()),
            _ => ControlFlow::Continue(()),
        };
        extract_into(view, &options, &mut mesh, &mut progress).map_err(|e| match e {
            ExtractError::Cancelled => text(409, "superseded by a later request"),
            e => text(422, e.to_string()),
        })?;
        let made = Arc::new(Made {
            mesh,
            millis: started.elapsed().as_secs_f64() * 1e3,
        });
        self.cached = Some((s.clone(), made.clone()));
        Ok(made)
    }

    /// The mesh for the page ([`encode`]); a request older than the newest received is
    /// answered 409 at once, and one overtaken while its extraction runs stops early.
    fn mesh_route(
        &mut self,
        q: &Query,
        max_memory: Option<u64>,
        newest: &AtomicU64,
    ) -> Result<Answer, Answer> {
        let seq = q.seq();
        if seq < newest.load(Ordering::SeqCst) {
            return Err(text(409, "superseded by a later request"));
        }
        let mut s = self.settings(q)?;
        s.coarse = match q.get("coarse") {
            None => 1,
            Some(v) => v
                .parse::<usize>()
                .ok()
                .filter(|k| (1..=8).contains(k))
                .ok_or_else(|| text(400, "coarse: a stride from 1 to 8"))?,
        };
        let made = self.made(&s, max_memory, Some((newest, seq)))?;
        // Counts only: the topology (an edge table) waits for /api/topology, so the picture
        // does not.
        let figures = serde_json::json!({
            "coarse": s.coarse > 1,
            "level": s.level,
            "vertices": made.mesh.positions.len(),
            "triangles": made.mesh.triangles.len(),
            "millis": made.millis,
        });
        Ok(bytes(
            encode(&made.mesh, figures),
            "application/octet-stream",
        ))
    }

    /// One plane of the volume across `axis` (0 x, 1 y, 2 z) at `index`: width and height (u32)
    /// then the values row by row (f32), for the page's slice views.
    fn slice(&self, q: &Query) -> Result<Answer, Answer> {
        let dims = self.grid.dims();
        let axis = q
            .get("axis")
            .and_then(|v| v.parse::<usize>().ok())
            .filter(|&a| a < 3)
            .ok_or_else(|| text(400, "axis: 0, 1 or 2"))?;
        let index = q
            .get("index")
            .and_then(|v| v.parse::<usize>().ok())
            .filter(|&i| i < dims[axis])
            .ok_or_else(|| text(400, format!("index: 0 to {}", dims[axis] - 1)))?;
        let (u, v) = match axis {
            0 => (1, 2),
            1 => (0, 2),
            _ => (0, 1),
        };
        let mut out = Vec::with_capacity(8 + dims[u] * dims[v] * 4);
        out.extend((dims[u] as u32).to_le_bytes());
        out.extend((dims[v] as u32).to_le_bytes());
        for b in 0..dims[v] {
            for a in 0..dims[u] {
                let mut p = [0; 3];
                p[axis] = index;
                p[u] = a;
                p[v] = b;
                out.extend(self.grid.value(p[0], p[1], p[2]).to_le_bytes());
            }
        }
        Ok(bytes(out, "application/octet-stream"))
    }
}

impl Gate {
    /// The request's route and parameters, or the refusal to send at once.
    fn admit(&self, request: &Request) -> Result<(String, Query), Answer> {
        let url = request.url();
        if url.len() > MAX_URL {
            return Err(text(414, "request line too long"));
        }
        if !matches!(request.method(), HttpMethod::Get) {
            return Err(text(405, "only GET"));
        }
        if request.body_length().is_some_and(|n| n > 0) {
            return Err(text(413, "requests carry no body"));
        }
        let host = request
            .headers()
            .iter()
            .find(|h| h.field.equiv("Host"))
            .map(|h| h.value.as_str().to_string());
        // DNS rebinding: a page of another site reaches 127.0.0.1 under its own name.
        if !host.is_some_and(|h| self.hosts.contains(&h)) {
            return Err(text(403, "wrong Host"));
        }
        let (path, query) = url.split_once('?').unwrap_or((url, ""));
        let query = Query(
            query
                .split('&')
                .filter(|p| !p.is_empty())
                .map(|p| {
                    let (k, v) = p.split_once('=').unwrap_or((p, ""));
                    (decode(k), decode(v))
                })
                .collect(),
        );
        if !query.get("token").is_some_and(|t| same(t, &self.token)) {
            return Err(text(403, "missing or wrong token"));
        }
        Ok((path.to_string(), query))
    }
}

/// The page: its HTML with the script inlined (one request brings the whole page).
fn page() -> Answer {
    let html = PAGE_HTML.replace("/*SCRIPT*/", PAGE_SCRIPT);
    bytes(html.into_bytes(), "text/html; charset=utf-8")
        .with_header(header(
            "Content-Security-Policy",
            "default-src 'none'; script-src 'unsafe-inline'; style-src 'unsafe-inline'; \
             connect-src 'self'; img-src 'self' data: blob:",
        ))
        .with_header(header("X-Frame-Options", "DENY"))
}

/// A mesh as the page draws it, quantised (the picture needs no more, and the bytes are
/// what a slider move waits for): a little-endian header (`ICM2`, vertices, triangles, the
/// length of a JSON block of figures), the JSON padded to 4 bytes, then positions as u16 × 3
/// on the mesh's bounding box (`origin + scale × q`, both in the JSON; padded to 4 bytes),
/// normals as i8 × 4 (× 1/127; the fourth byte 0) and triangles as u32 × 3. Downloads are
/// the exact files.
fn encode(mesh: &Mesh, mut figures: serde_json::Value) -> Vec<u8> {
    let (lo, hi) = mesh.bounds().unwrap_or(([0.0; 3], [0.0; 3]));
    let scale: [f32; 3] = std::array::from_fn(|a| match (hi[a] - lo[a]) / 65535.0 {
        s if s > 0.0 && s.is_finite() => s,
        _ => 1.0,
    });
    figures["origin"] = serde_json::json!(lo);
    figures["scale"] = serde_json::json!(scale);
    figures["bounds"] = serde_json::json!([lo, hi]);
    let mut json = figures.to_string().into_bytes();
    while json.len() % 4 != 0 {
        json.push(b' ');
    }
    // The normals the writers write (zero ones, at flat spots, filled from the triangles);
    // meshes read without normals get the triangles' area-weighted ones.
    let normals: std::borrow::Cow<[[f32; 3]]> = match mesh.filled_normals() {
        Some(n) => n.into(),
        None if mesh.normals.len() == mesh.positions.len() => (&mesh.normals[..]).into(),
        None => {
            let mut shaded = Mesh::new();
            shaded.positions.clone_from(&mesh.positions);
            shaded.triangles.clone_from(&mesh.triangles);
            shaded.compute_normals();
            shaded.normals.into()
        }
    };
    let n = mesh.positions.len();
    let positions_len = (n * 6).next_multiple_of(4);
    let mut out =
        Vec::with_capacity(16 + json.len() + positions_len + n * 4 + mesh.triangles.len() * 12);
    out.extend(b"ICM2");
    for count in [n, mesh.triangles.len(), json.len()] {
        out.extend((count as u32).to_le_bytes());
    }
    out.extend(&json);
    let start = out.len();
    for p in &mesh.positions {
        for a in 0..3 {
            let q = ((p[a] - lo[a]) / scale[a]).round().clamp(0.0, 65535.0) as u16;
            out.extend(q.to_le_bytes());
        }
    }
    out.resize(start + positions_len, 0);
    for v in normals.iter() {
        for c in v {
            out.push(((c * 127.0).round().clamp(-127.0, 127.0) as i8) as u8);
        }
        out.push(0);
    }
    out.extend(bytemuck::cast_slice::<[u32; 3], u8>(&mesh.triangles));
    out
}

fn json(value: serde_json::Value) -> Answer {
    bytes(value.to_string().into_bytes(), "application/json")
}

/// Whether the mesh is closed, its components and genus.
fn topology_of(mesh: &Mesh) -> serde_json::Value {
    let report = mesh.report();
    serde_json::json!({
        "watertight": report.watertight && report.oriented,
        "boundary_edges": report.boundary_edges,
        "nonmanifold_edges": report.nonmanifold_edges,
        "components": report.components,
        "genus": report.genus,
    })
}

/// `isocube quality`'s figures.
fn quality_of(mesh: &Mesh) -> serde_json::Value {
    let q = quality_report(mesh);
    serde_json::json!({
        "triangles": q.triangles,
        "degenerate": q.degenerate,
        "min_angle": {"min": q.min_angle.min, "mean": q.min_angle.mean},
        "max_angle": {"max": q.max_angle.max, "mean": q.max_angle.mean},
        "below": q.below,
        "histogram": q.histogram.to_vec(),
    })
}

/// The file's stem, reduced to characters safe in a download's name.
fn safe_stem(name: &str) -> String {
    std::path::Path::new(name)
        .file_stem()
        .and_then(|s| s.to_str())
        .map(|s| {
            s.chars()
                .filter(|c| c.is_ascii_alphanumeric() || "-_.".contains(*c))
                .collect::<String>()
        })
        .filter(|s| !s.is_empty())
        .unwrap_or_else(|| "isosurface".into())
}

/// The format a download asks for.
fn download_format(q: &Query) -> Result<(&str, MeshFormat), Answer> {
    let ext = q.get("format").unwrap_or("ply");
    match ext {
        "ply" | "stl" | "obj" | "glb" => {
            MeshFormat::from_path(std::path::Path::new(&format!("m.{ext}"))).map(|f| (ext, f))
        }
        _ => None,
    }
    .ok_or_else(|| text(400, "format: ply, stl, obj or glb"))
}

/// `mesh` as `isocube extract` (and `contours`, `subdivide` to PLY, STL, GLB) writes it.
fn mesh_file(mesh: &Mesh, format: MeshFormat) -> Result<Vec<u8>, Answer> {
    let mut out = Vec::new();
    write_mesh_to(&mut out, format, mesh, &crate::write_options(false, true))
        .map_err(|e| text(500, e.to_string()))?;
    Ok(out)
}

fn attachment(body: Vec<u8>, file: &str) -> Answer {
    bytes(body, "application/octet-stream").with_header(header(
        "Content-Disposition",
        &format!("attachment; filename=\"{file}\""),
    ))
}

impl State {
    fn answer(&mut self, path: &str, q: &Query) -> Answer {
        let name = self.name.as_str();
        let result = match (path, &mut self.scene) {
            ("/", _) => Ok(page()),
            ("/api/volume", Scene::Volume(v)) => Ok(v.describe(name)),
            ("/api/volume", Scene::Parts(p)) => Ok(describe_parts(p, name)),
            ("/api/mesh", Scene::Volume(v)) => v.mesh_route(q, self.max_memory, &self.newest),
            ("/api/mesh", Scene::Parts(p)) => part_of(p, q).map(|(_, made)| {
                let figures = serde_json::json!({
                    "vertices": made.mesh.positions.len(),
                    "triangles": made.mesh.triangles.len(),
                    "millis": made.millis,
                });
                bytes(encode(&made.mesh, figures), "application/octet-stream")
            }),
            ("/api/slice", Scene::Volume(v)) => v.slice(q),
            ("/api/lines", Scene::Parts(p)) => {
                let mut out = Vec::with_capacity(8 + p.lines.len() * 12);
                out.extend(b"ICL1");
                out.extend((p.lines.len() as u32).to_le_bytes());
                out.extend(bytemuck::cast_slice::<[f32; 3], u8>(&p.lines));
                Ok(bytes(out, "application/octet-stream"))
            }
            ("/api/topology" | "/api/quality", scene) => {
                let made = match scene {
                    Scene::Volume(v) => match v.settings(q) {
                        Ok(s) => v
                            .made(&s, self.max_memory, None)
                            .map(|m| (Some(s.level), m)),
                        Err(e) => Err(e),
                    },
                    Scene::Parts(p) => part_of(p, q).map(|(_, m)| (None, m)),
                };
                made.map(|(level, made)| {
                    let mut value = if path == "/api/topology" {
                        topology_of(&made.mesh)
                    } else {
                        quality_of(&made.mesh)
                    };
                    if let Some(level) = level {
                        value["level"] = serde_json::json!(level);
                    }
                    json(value)
                })
            }
            ("/api/download", Scene::Volume(v)) => download_format(q).and_then(|(ext, format)| {
                let s = v.settings(q)?;
                let made = v.made(&s, self.max_memory, None)?;
                let file = format!("{}-{}.{ext}", safe_stem(name), s.level);
                Ok(attachment(mesh_file(&made.mesh, format)?, &file))
            }),
            ("/api/download", Scene::Parts(p)) => download_format(q).and_then(|(ext, format)| {
                let (number, made) = part_of(p, q)?;
                let file = format!("{}-{number}.{ext}", safe_stem(name));
                // A cage's subdivision as OBJ keeps its polygons and tags, as `isocube
                // subdivide -o NAME.obj` writes it.
                let body = match (&p.refined, format) {
                    (Some((_, fine)), MeshFormat::Obj) => fine.to_obj().into_bytes(),
                    _ => mesh_file(&made.mesh, format)?,
                };
                Ok(attachment(body, &file))
            }),
            ("/api/slice" | "/api/lines", _) => Err(text(400, "not a route for this input")),
            _ => Err(text(404, "no such route")),
        };
        result.unwrap_or_else(|e| e)
    }
}

/// What the page shows of fixed surfaces: their kind, names and sizes.
fn describe_parts(p: &Parts, name: &str) -> Answer {
    let parts: Vec<_> = p
        .parts
        .iter()
        .map(|part| {
            serde_json::json!({
                "name": part.name,
                "number": part.number,
                "vertices": part.made.mesh.positions.len(),
                "triangles": part.made.mesh.triangles.len(),
            })
        })
        .collect();
    json(serde_json::json!({
        "kind": p.kind.name(),
        "name": name,
        "parts": parts,
        "lines": p.lines.len() / 2,
        "levels": p.refined.as_ref().map(|(l, _)| *l),
        "max_levels": MAX_LEVELS,
        "notes": p.notes,
    }))
}

/// The part a request names (`part`, default 0; a cage's `levels` subdivide it again), with
/// the number its download is named by.
fn part_of(p: &mut Parts, q: &Query) -> Result<(String, Arc<Made>), Answer> {
    if p.kind == Kind::Cage {
        if let Some(v) = q.get("levels") {
            let levels = v
                .parse::<usize>()
                .ok()
                .filter(|&l| l <= MAX_LEVELS)
                .ok_or_else(|| text(400, format!("levels: 0 to {MAX_LEVELS}")))?;
            p.subdivide(levels).map_err(|e| text(422, e))?;
        }
    }
    let index = match q.get("part") {
        Some(v) => v
            .parse::<usize>()
            .ok()
            .filter(|&i| i < p.parts.len())
            .ok_or_else(|| text(400, format!("part: 0 to {}", p.parts.len() - 1)))?,
        None => 0,
    };
    let part = &p.parts[index];
    let number = part
        .number
        .map_or_else(|| "mesh".to_string(), |n| n.to_string());
    Ok((number, part.made.clone()))
}

/// `%XX` and `+` decoded (the page encodes its parameters with `encodeURIComponent`).
fn decode(s: &str) -> String {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' {
            let hex = b
                .get(i + 1..i + 3)
                .and_then(|h| std::str::from_utf8(h).ok());
            if let Some(v) = hex.and_then(|h| u8::from_str_radix(h, 16).ok()) {
                out.push(v);
                i += 3;
                continue;
            }
        }
        out.push(if b[i] == b'+' { b' ' } else { b[i] });
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}
