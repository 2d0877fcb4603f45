//! `isocube view VOLUME`: a page in the browser to explore a volume — drag the level and see
//! the surface change at once.
//!
//! The binary serves one page (HTML and script embedded, no dependencies) and a small API on
//! 127.0.0.1. Every request must carry the random token printed in the URL and a `Host` of
//! this address (a page of another site cannot reach the server through DNS rebinding); only
//! the fixed routes exist, no path from the client names a file; requests are GETs without a
//! body and short URLs; they are answered one at a time (an extraction uses every core), and a
//! mesh request older than the latest one is answered at once with 409, so a fast slider never
//! queues work.

use std::sync::Arc;
use std::time::Instant;

use clap::Args as ClapArgs;
use isocube::cube::Topology;
use isocube::extract::{extract_into, ExtractOptions, SnapPosition};
use isocube::field::{Grid, Level, Orientation, ValueSummary};
use isocube::mesh::Mesh;
use isocube::quality::{quality_report, Strategy};
use isocube_io::{write_mesh_to, MeshFormat};
use tiny_http::{Header, Method as HttpMethod, Request, Response, Server};

use crate::commands::extract::Choices;
use crate::volume::VolumeArgs;
use crate::Failure;

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
}

/// Bins of the value histogram the page draws behind the level slider.
const BINS: usize = 256;
/// The longest request line accepted (routes and their parameters are short).
const MAX_URL: usize = 2048;

/// The page: its HTML with the script inlined (so one request brings the whole page).
const PAGE_HTML: &str = include_str!("view/index.html");
const PAGE_SCRIPT: &str = include_str!("view/view.js");

pub(crate) fn run(args: &Args, quiet: bool) -> Result<(), Failure> {
    let (grid, orientation) =
        crate::volume::in_frame(args.index_space, args.volume.load_oriented()?)?;
    let summary = ValueSummary::of(grid.values());
    let level = crate::volume::resolve_level(args.level, &args.volume.volume, || summary.clone())?;
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
        eprintln!(
            "isocube view: {} ({}×{}×{}) on {url} — Ctrl-C to stop",
            args.volume.volume,
            grid.dims()[0],
            grid.dims()[1],
            grid.dims()[2]
        );
    }
    if !args.no_open {
        open_browser(&url);
    }
    let mut state = State {
        name: args.volume.volume.clone(),
        grid,
        orientation,
        summary,
        level,
        max_memory: crate::volume::MemoryLimit::or_default(args.volume.max_memory),
        token,
        hosts: [format!("127.0.0.1:{port}"), format!("localhost:{port}")],
        latest: 0,
        cached: None,
        coarse: None,
    };
    for request in server.incoming_requests() {
        let response = state.answer(&request);
        // A client that went away is no error of the server's.
        let _ = request.respond(response);
    }
    Ok(())
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
    /// The preview: every other grid point along each axis (about a quarter the triangles),
    /// for the picture while the slider moves.
    coarse: bool,
    level: f32,
    method: String,
    topology: Topology,
    triangulate: Strategy,
    snap: f32,
}

struct State {
    name: String,
    grid: Grid,
    orientation: Orientation,
    summary: Option<ValueSummary>,
    level: f32,
    max_memory: Option<u64>,
    token: String,
    hosts: [String; 2],
    /// The highest `seq` of a mesh request seen.
    latest: u64,
    /// The last mesh made, and what it was made with.
    cached: Option<(Settings, Arc<Made>)>,
    /// The preview grid, made when first asked for.
    coarse: Option<Grid>,
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

/// Every other grid point along each axis (spacing doubled, an eighth of the cells): the same
/// box, less the last layer of cells where an axis has an even number of points.
fn every_other(grid: &Grid) -> Result<Grid, String> {
    let [nx, ny, nz] = grid.dims();
    let dims = [nx.div_ceil(2), ny.div_ceil(2), nz.div_ceil(2)];
    let mut values = Vec::with_capacity(dims.iter().product());
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                values.push(grid.value(2 * i, 2 * j, 2 * k));
            }
        }
    }
    let spacing = grid.spacing().map(|s| 2.0 * s);
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
}

/// Compares two strings in time independent of where they differ.
fn same(a: &str, b: &str) -> bool {
    a.len() == b.len() && a.bytes().zip(b.bytes()).fold(0u8, |d, (x, y)| d | (x ^ y)) == 0
}

impl State {
    fn answer(&mut self, request: &Request) -> Answer {
        let url = request.url();
        if url.len() > MAX_URL {
            return text(414, "request line too long");
        }
        if !matches!(request.method(), HttpMethod::Get) {
            return text(405, "only GET");
        }
        if request.body_length().is_some_and(|n| n > 0) {
            return text(413, "requests carry no body");
        }
        let host = request
            .headers()
            .iter()
            .find(|h| h.field.equiv("Host"))
            .map(|h| h.value.as_str().to_string());
        // DNS rebinding: a page of another site reaches 127.0.0.1 under its own name.
        if !host.is_some_and(|h| self.hosts.contains(&h)) {
            return text(403, "wrong Host");
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
        let get = |name: &str| query.get(name);
        if !get("token").is_some_and(|t| same(t, &self.token)) {
            return text(403, "missing or wrong token");
        }
        let result = match path {
            "/" => Ok(self.page()),
            "/api/volume" => Ok(self.volume()),
            "/api/mesh" => self.mesh_route(&query),
            "/api/slice" => self.slice(&query),
            "/api/topology" => self.topology(&query),
            "/api/quality" => self.quality(&query),
            "/api/download" => self.download(&query),
            _ => Err(text(404, "no such route")),
        };
        result.unwrap_or_else(|e| e)
    }

    fn page(&self) -> Answer {
        let html = PAGE_HTML.replace("/*SCRIPT*/", PAGE_SCRIPT);
        bytes(html.into_bytes(), "text/html; charset=utf-8")
            .with_header(header(
                "Content-Security-Policy",
                "default-src 'none'; script-src 'unsafe-inline'; style-src 'unsafe-inline'; \
                 connect-src 'self'; img-src 'self' data: blob:",
            ))
            .with_header(header("X-Frame-Options", "DENY"))
    }

    /// The volume's size, place, value range and histogram, and the opening level.
    fn volume(&self) -> Answer {
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
            "name": self.name,
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
            coarse: false,
            level,
            method,
            topology,
            triangulate,
            snap,
        })
    }

    /// The library's options for these settings: those `isocube extract` gives for the same
    /// arguments, so a download is the command's file.
    fn options(&self, s: &Settings) -> ExtractOptions {
        let room = self
            .max_memory
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

    /// The mesh for these settings: the last one again, or a new one.
    fn made(&mut self, s: &Settings) -> Result<Arc<Made>, Answer> {
        if let Some((cached, made)) = &self.cached {
            if cached == s {
                return Ok(made.clone());
            }
        }
        let options = self.options(s);
        let grid = match s.coarse {
            true => match &self.coarse {
                Some(g) => g,
                None => self
                    .coarse
                    .insert(every_other(&self.grid).map_err(|e| text(500, e))?),
            },
            false => &self.grid,
        };
        let view = grid.view().with_orientation(self.orientation);
        let started = Instant::now();
        let mut mesh = Mesh::new();
        extract_into(view, &options, &mut mesh, &mut |_, _| {
            std::ops::ControlFlow::Continue(())
        })
        .map_err(|e| text(422, e.to_string()))?;
        let made = Arc::new(Made {
            mesh,
            millis: started.elapsed().as_secs_f64() * 1e3,
        });
        self.cached = Some((s.clone(), made.clone()));
        Ok(made)
    }

    /// The mesh as the page draws it: a little-endian header (`ICM1`, vertices, triangles, the
    /// length of a JSON block of figures), the JSON padded to 4 bytes, then positions and
    /// normals (f32 × 3 per vertex) and triangles (u32 × 3).
    fn mesh_route(&mut self, q: &Query) -> Result<Answer, Answer> {
        let seq = q
            .get("seq")
            .and_then(|v| v.parse::<u64>().ok())
            .unwrap_or(0);
        if seq < self.latest {
            return Err(text(409, "superseded by a later request"));
        }
        self.latest = seq;
        let mut s = self.settings(q)?;
        s.coarse = q.get("coarse") == Some("1");
        let made = self.made(&s)?;
        let mesh = &made.mesh;
        // Counts only: the topology (an edge table) waits for /api/topology, so the picture
        // does not.
        let figures = serde_json::json!({
            "coarse": s.coarse,
            "level": s.level,
            "vertices": mesh.positions.len(),
            "triangles": mesh.triangles.len(),
            "millis": made.millis,
        })
        .to_string();
        let mut json = figures.into_bytes();
        while json.len() % 4 != 0 {
            json.push(b' ');
        }
        // The normals the writers write: zero ones (flat spots) filled from the triangles.
        let filled = mesh.filled_normals();
        let normals: &[[f32; 3]] = match &filled {
            Some(n) => n,
            None if mesh.normals.len() == mesh.positions.len() => &mesh.normals,
            None => &[],
        };
        let zeros = vec![[0.0f32; 3]; mesh.positions.len()];
        let normals = if normals.is_empty() {
            &zeros[..]
        } else {
            normals
        };
        let mut out = Vec::with_capacity(
            16 + json.len() + mesh.positions.len() * 24 + mesh.triangles.len() * 12,
        );
        out.extend(b"ICM1");
        for n in [mesh.positions.len(), mesh.triangles.len(), json.len()] {
            out.extend((n as u32).to_le_bytes());
        }
        out.extend(&json);
        out.extend(bytemuck::cast_slice::<[f32; 3], u8>(&mesh.positions));
        out.extend(bytemuck::cast_slice::<[f32; 3], u8>(normals));
        out.extend(bytemuck::cast_slice::<[u32; 3], u8>(&mesh.triangles));
        Ok(bytes(out, "application/octet-stream"))
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

    /// Whether the mesh for these settings is closed, its components and genus.
    fn topology(&mut self, q: &Query) -> Result<Answer, Answer> {
        let s = self.settings(q)?;
        let made = self.made(&s)?;
        let report = made.mesh.report();
        let json = serde_json::json!({
            "level": s.level,
            "watertight": report.watertight && report.oriented,
            "boundary_edges": report.boundary_edges,
            "nonmanifold_edges": report.nonmanifold_edges,
            "components": report.components,
            "genus": report.genus,
        });
        Ok(bytes(json.to_string().into_bytes(), "application/json"))
    }

    fn quality(&mut self, q: &Query) -> Result<Answer, Answer> {
        let s = self.settings(q)?;
        let made = self.made(&s)?;
        let q = quality_report(&made.mesh);
        let json = serde_json::json!({
            "triangles": q.triangles,
            "degenerate": q.degenerate,
            "min_angle": {"min": q.min_angle.min, "mean": q.min_angle.mean},
            "max_angle": {"max": q.max_angle.max, "mean": q.max_angle.mean},
            "below": q.below,
            "histogram": q.histogram.to_vec(),
        });
        Ok(bytes(json.to_string().into_bytes(), "application/json"))
    }

    /// The mesh as a file, written as `isocube extract -o NAME.FORMAT` writes it.
    fn download(&mut self, q: &Query) -> Result<Answer, Answer> {
        let ext = q.get("format").unwrap_or("ply");
        let format = match ext {
            "ply" | "stl" | "obj" | "glb" => {
                MeshFormat::from_path(std::path::Path::new(&format!("m.{ext}")))
            }
            _ => None,
        }
        .ok_or_else(|| text(400, "format: ply, stl, obj or glb"))?;
        let s = self.settings(q)?;
        let made = self.made(&s)?;
        let mut out = Vec::new();
        write_mesh_to(
            &mut out,
            format,
            &made.mesh,
            &crate::write_options(false, true),
        )
        .map_err(|e| text(500, e.to_string()))?;
        let stem = std::path::Path::new(&self.name)
            .file_stem()
            .and_then(|s| s.to_str())
            .map(|s| {
                s.chars()
                    .filter(|c| c.is_ascii_alphanumeric() || "-_.".contains(*c))
                    .collect::<String>()
            })
            .filter(|s| !s.is_empty())
            .unwrap_or_else(|| "isosurface".into());
        Ok(bytes(out, "application/octet-stream").with_header(header(
            "Content-Disposition",
            &format!("attachment; filename=\"{stem}-{}.{ext}\"", s.level),
        )))
    }
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
