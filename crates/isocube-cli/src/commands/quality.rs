//! `isocube quality MESH [--field VOLUME] [--level L] [--cell WIDTH [--snap CELLS]] [--json]
//! [--histogram FILE.png|FILE.svg]`.

use std::path::{Path, PathBuf};

use clap::Args as ClapArgs;
use isocube::field::{Grid, SampleSpec};
use isocube::mesh::Mesh;
use isocube::quality::{
    level_set_distance, quality_report, Distance, Field, QualityReport, Range, Trilinear,
};
use isocube::volume::{BoundaryEdge, PoorElements, TetMesh, TetReport};
use isocube_io::{read_mesh, read_tet_mesh, read_volume_oriented, TetFormat, VolumeOptions};
use serde_json::json;

use crate::volume::{parse_memory, volume_failure, MemoryLimit};
use crate::Failure;

#[derive(Debug, ClapArgs)]
pub(crate) struct Args {
    /// A surface mesh (.ply, .obj, .stl, .off) or a tetrahedral one (.msh, .vtu, .mesh, .inp):
    /// for tetrahedra, dihedral angles, radius ratio and volumes.
    mesh: PathBuf,
    /// The field the mesh came from, to measure its distance from the level set: a built-in
    /// sample (`sample:NAME:N`, evaluated exactly) or a .npy/.nrrd/.nhdr volume (trilinear).
    /// Distances are `|f − level| / |∇f|` in units of the grid spacing.
    #[arg(long, value_name = "VOLUME")]
    field: Option<String>,
    /// The level of the field.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    level: f64,
    /// Print JSON instead of a table.
    #[arg(long)]
    json: bool,
    /// Write the angle histogram (5° bins) as a picture: .svg or .png.
    #[arg(long, value_name = "FILE")]
    histogram: Option<PathBuf>,
    /// For a tetrahedral mesh: the width of the grid cells it was made on (world units; the
    /// smallest spacing). With it the elements outside [10°, 165°] are sorted as `tetmesh`
    /// sorts them: at a boundary edge sharper than 10° (forced), beside surface detail under
    /// --snap cells, and the others.
    #[arg(long, value_name = "WIDTH")]
    cell: Option<f64>,
    /// With --cell: the snap distance the mesh was made with, in cells (0.3 is `tetmesh`'s
    /// default, and the weight for a mesh made by plain Marching Cubes).
    #[arg(long, value_name = "CELLS", default_value_t = 0.3, requires = "cell")]
    snap: f64,
    /// The most memory reading the --field volume may take (as for `extract`).
    #[arg(long, value_name = "SIZE", value_parser = parse_memory)]
    max_memory: Option<MemoryLimit>,
}

pub(crate) fn run(args: &Args) -> Result<(), Failure> {
    if let Some(path) = &args.histogram {
        let field = args.field.as_deref().filter(|f| !SampleSpec::is_sample(f));
        let mut inputs = vec![(args.mesh.as_path(), "mesh")];
        inputs.extend(field.map(|f| (Path::new(f), "--field volume")));
        crate::refuse_overwrite(path, &inputs)?;
        if picture_format(path).is_none() {
            return Err(Failure::input(anyhow::anyhow!(
                "{}: unknown picture extension (expected .svg or .png)",
                path.display()
            )));
        }
    }
    if let Some(cell) = args.cell {
        if !(cell.is_finite() && cell > 0.0) {
            return Err(Failure::input(anyhow::anyhow!(
                "--cell {cell}: the cell width must be a positive number"
            )));
        }
        if !(args.snap.is_finite() && (0.0..=1.0).contains(&args.snap)) {
            return Err(Failure::input(anyhow::anyhow!(
                "--snap {}: the snap distance is in cells, from 0 to 1",
                args.snap
            )));
        }
    }
    if TetFormat::from_path(&args.mesh).is_some() {
        return run_tets(args);
    }
    if args.cell.is_some() {
        return Err(Failure::input(anyhow::anyhow!(
            "--cell sorts a volume mesh's elements: {} holds triangles",
            args.mesh.display()
        )));
    }
    let mesh = read_mesh(&args.mesh).map_err(|e| crate::io_failure(e, true))?;
    let report = quality_report(&mesh);
    let distance = match &args.field {
        Some(spec) => Some(distance(&mesh, spec, args.level, args.max_memory)?),
        None => None,
    };
    if let Some(path) = &args.histogram {
        let title = format!(
            "{}: {} triangles, angles {:.1}°–{:.1}°",
            args.mesh
                .file_name()
                .map_or_else(String::new, |n| n.to_string_lossy().into_owned()),
            report.triangles,
            report.min_angle.min,
            report.max_angle.max
        );
        write_picture(path, &report.histogram, &title)?;
    }
    if args.json {
        println!("{}", to_json(&report, distance.as_ref()));
    } else {
        print!("{}", to_table(&report, distance.as_ref()));
    }
    Ok(())
}

/// `quality` on a tetrahedral mesh: dihedral angles, radius ratio and volumes of every
/// tetrahedron, inverted and flat ones by the exact predicate.
fn run_tets(args: &Args) -> Result<(), Failure> {
    if args.field.is_some() {
        return Err(Failure::input(anyhow::anyhow!(
            "--field measures a surface's distance from a level set: {} holds tetrahedra",
            args.mesh.display()
        )));
    }
    let mesh = read_tet_mesh(&args.mesh).map_err(|e| crate::io_failure(e, true))?;
    let qualities = mesh.qualities();
    let report = TetReport::of(&qualities);
    let check = mesh.check();
    let volumes: Vec<f64> = mesh
        .tets
        .iter()
        .map(|t| {
            let p = t.map(|v| mesh.positions[v as usize].map(f64::from));
            let d: [[f64; 3]; 3] =
                std::array::from_fn(|k| std::array::from_fn(|a| p[k + 1][a] - p[0][a]));
            (d[0][0] * (d[1][1] * d[2][2] - d[1][2] * d[2][1])
                - d[0][1] * (d[1][0] * d[2][2] - d[1][2] * d[2][0])
                + d[0][2] * (d[1][0] * d[2][1] - d[1][1] * d[2][0]))
                / 6.0
        })
        .collect();
    let stats = |xs: &mut dyn Iterator<Item = f64>| {
        let (mut lo, mut hi, mut sum, mut n) = (f64::INFINITY, f64::NEG_INFINITY, 0.0, 0usize);
        for x in xs {
            lo = lo.min(x);
            hi = hi.max(x);
            sum += x;
            n += 1;
        }
        Range {
            min: lo,
            max: hi,
            mean: sum / n.max(1) as f64,
        }
    };
    let rows = [
        (
            "min_dihedral",
            stats(&mut qualities.iter().map(|q| q.min_dihedral)),
        ),
        (
            "max_dihedral",
            stats(&mut qualities.iter().map(|q| q.max_dihedral)),
        ),
        (
            "radius_ratio",
            stats(&mut qualities.iter().map(|q| q.radius_ratio)),
        ),
        ("volume", stats(&mut volumes.iter().copied())),
    ];
    let outside = qualities
        .iter()
        .filter(|q| q.min_dihedral < 10.0 || q.max_dihedral > 165.0)
        .count();
    if let Some(path) = &args.histogram {
        // Each tetrahedron's smallest and largest dihedral angle, in 5° bins.
        let mut bins = [0usize; 36];
        for q in &qualities {
            for a in [q.min_dihedral, q.max_dihedral] {
                bins[((a / 5.0) as usize).min(35)] += 1;
            }
        }
        let title = format!(
            "{}: {} tetrahedra, smallest and largest dihedral angles {:.1}°–{:.1}°",
            args.mesh
                .file_name()
                .map_or_else(String::new, |n| n.to_string_lossy().into_owned()),
            report.tets,
            report.min_dihedral,
            report.max_dihedral
        );
        write_picture(path, &bins, &title)?;
    }
    let share = outside as f64 / report.tets.max(1) as f64;
    let sharpest = mesh.sharpest_boundary_edge();
    let sorted = args
        .cell
        .map(|cell| (cell, mesh.poor_elements(cell, args.snap)));
    if args.json {
        let mut fields = serde_json::Map::new();
        fields.insert("tetrahedra".into(), json!(report.tets));
        fields.insert("inverted".into(), json!(check.inverted));
        fields.insert("flat".into(), json!(check.flat));
        fields.insert("unused_nodes".into(), json!(check.unused));
        fields.insert("total_volume".into(), number(check.volume));
        for (name, r) in &rows {
            fields.insert((*name).into(), range(r));
        }
        fields.insert("outside_10_165".into(), number(share));
        if let Some((_, poor)) = &sorted {
            fields.insert("outside_elements".into(), json!(poor.count));
            fields.insert("at_sharp_edges".into(), json!(poor.at_sharp_edges));
            fields.insert("beside_fine_detail".into(), json!(poor.beside_fine_detail));
            fields.insert("others".into(), json!(poor.others));
        }
        if let Some(e) = &sharpest {
            fields.insert("sharpest_boundary_edge".into(), number(e.angle));
        }
        println!("{}", serde_json::Value::Object(fields));
    } else {
        let mut s = format!(
            "tetrahedra     {}\ninverted       {}\nflat           {}\ntotal volume   {:.6e}\n{:<14} {:>12} {:>12} {:>12}\n",
            report.tets, check.inverted, check.flat, check.volume, "measure", "min", "mean", "max"
        );
        for (name, r) in &rows {
            s += &format!(
                "{name:<14} {:>12.6} {:>12.6} {:>12.6}\n",
                r.min, r.mean, r.max
            );
        }
        s += &format!("outside [10°, 165°]: {:.4} %\n", 100.0 * share);
        if let Some(e) = &sharpest {
            s += &format!("{}\n", sharpest_line(&mesh, e));
        }
        if let Some((cell, poor)) = &sorted {
            if poor.count > 0 {
                s += &format!("{}\n", poor_line(&mesh, poor, *cell, args.snap));
            }
        }
        print!("{s}");
    }
    Ok(())
}

/// The sharpest boundary edge, where it is, and what it means for the elements there.
pub(crate) fn sharpest_line(mesh: &TetMesh, e: &BoundaryEdge) -> String {
    let [a, b] = e.edge.map(|v| mesh.positions[v as usize]);
    let middle: [f32; 3] = std::array::from_fn(|d| 0.5 * (a[d] + b[d]));
    format!(
        "sharpest boundary edge: {:.2}° at ({:.6}, {:.6}, {:.6}): no element there can have a \
         larger smallest dihedral angle",
        e.angle, middle[0], middle[1], middle[2]
    )
}

/// The elements outside [10°, 165°] and what lies beside them, in cells of width `cell`, with
/// surface detail under `detail` cells.
pub(crate) fn poor_line(mesh: &TetMesh, poor: &PoorElements, cell: f64, detail: f64) -> String {
    let at = |v: u32| mesh.positions[v as usize].map(f64::from);
    let mut s = format!(
        "outside [10°, 165°]: {} elements: {} at a boundary edge sharper than 10° (forced), {} \
         within 1.5 cells of surface detail under the snap distance, {detail:.2} cells (surface \
         vertices that close, or one that close to a wall)",
        poor.count, poor.at_sharp_edges, poor.beside_fine_detail
    );
    if let Some((d, [a, b])) = poor.closest {
        // The same vertex twice: it and the wall nearest to it.
        let (a, b) = (at(a), at(b));
        s += &format!(
            " (closest {:.3} cells, at ({:.6}, {:.6}, {:.6}))",
            d / cell,
            0.5 * (a[0] + b[0]),
            0.5 * (a[1] + b[1]),
            0.5 * (a[2] + b[2])
        );
    }
    s += &format!(", {} others", poor.others);
    if let Some(w) = poor.worst_other {
        let p = mesh.tets[w as usize].map(at);
        let q = isocube::volume::TetQuality::of(p);
        let centre: [f64; 3] = std::array::from_fn(|d| p.iter().map(|c| c[d]).sum::<f64>() / 4.0);
        s += &format!(
            " (worst {:.2}°..{:.2}° at ({:.6}, {:.6}, {:.6}))",
            q.min_dihedral, q.max_dihedral, centre[0], centre[1], centre[2]
        );
    }
    s
}

fn distance(
    mesh: &Mesh,
    spec: &str,
    level: f64,
    max_memory: Option<MemoryLimit>,
) -> Result<Distance, Failure> {
    if SampleSpec::is_sample(spec) {
        let s: SampleSpec = spec.parse().map_err(Failure::input)?;
        let grid = s.grid();
        let sample = s.sample;
        return Ok(level_set_distance(
            mesh,
            |p| sample.eval(p),
            level,
            min_spacing(&grid),
        ));
    }
    let mut options = VolumeOptions::default();
    options.max_memory = MemoryLimit::or_default(max_memory);
    let (grid, orientation) =
        read_volume_oriented(Path::new(spec), &options).map_err(volume_failure)?;
    let field = Trilinear(grid.view());
    // The mesh is in the file's world coordinates: evaluate in the grid's own frame (a
    // rotation or reflection keeps distances).
    let f = |p: [f64; 3]| {
        let q = orientation.to_grid_frame(p, grid.origin());
        field.value_and_gradient(q).map_or(f64::NAN, |(v, _)| v)
    };
    Ok(level_set_distance(mesh, f, level, min_spacing(&grid)))
}

fn min_spacing(grid: &Grid) -> f64 {
    grid.spacing().iter().copied().fold(f64::INFINITY, f64::min)
}

fn number(x: f64) -> serde_json::Value {
    if x.is_finite() {
        json!((x * 1e6).round() / 1e6)
    } else {
        serde_json::Value::Null
    }
}

fn range(r: &Range) -> serde_json::Value {
    json!({"min": number(r.min), "max": number(r.max), "mean": number(r.mean)})
}

fn to_json(r: &QualityReport, d: Option<&Distance>) -> serde_json::Value {
    json!({
        "triangles": r.triangles,
        "degenerate": r.degenerate,
        "min_angle": range(&r.min_angle),
        "max_angle": range(&r.max_angle),
        "radius_ratio": range(&r.radius_ratio),
        "aspect_ratio": range(&r.aspect_ratio),
        "edge_ratio": range(&r.edge_ratio),
        "area": range(&r.area),
        "below_10": number(r.below[0]),
        "below_20": number(r.below[1]),
        "below_30": number(r.below[2]),
        "distance": d.map(|d| json!({"max": number(d.max), "mean": number(d.mean), "samples": d.samples})),
        "histogram_5deg": r.histogram.to_vec(),
    })
}

fn to_table(r: &QualityReport, d: Option<&Distance>) -> String {
    let mut s = format!(
        "triangles      {}\ndegenerate     {}\n{:<14} {:>12} {:>12} {:>12}\n",
        r.triangles, r.degenerate, "measure", "min", "mean", "max"
    );
    for (name, x) in [
        ("min_angle", &r.min_angle),
        ("max_angle", &r.max_angle),
        ("radius_ratio", &r.radius_ratio),
        ("aspect_ratio", &r.aspect_ratio),
        ("edge_ratio", &r.edge_ratio),
        ("area", &r.area),
    ] {
        s += &format!(
            "{name:<14} {:>12.4} {:>12.4} {:>12.4}\n",
            x.min, x.mean, x.max
        );
    }
    s += &format!(
        "min angle < 10°: {:.2} %, < 20°: {:.2} %, < 30°: {:.2} %\n",
        100.0 * r.below[0],
        100.0 * r.below[1],
        100.0 * r.below[2]
    );
    if let Some(d) = d {
        s += &format!(
            "distance to the level set (grid spacings): max {:.4}, mean {:.4} ({} samples)\n",
            d.max, d.mean, d.samples
        );
    }
    s
}

#[derive(Clone, Copy)]
enum Picture {
    Svg,
    Png,
}

fn picture_format(path: &Path) -> Option<Picture> {
    match path.extension()?.to_str()?.to_ascii_lowercase().as_str() {
        "svg" => Some(Picture::Svg),
        "png" => Some(Picture::Png),
        _ => None,
    }
}

/// Writes through a temporary file in the target's directory, renamed into place once complete.
fn write_atomically(path: &Path, bytes: &[u8]) -> Result<(), Failure> {
    isocube_io::write_file_atomic(path, bytes).map_err(|e| crate::io_failure(e, false))
}

const WIDTH: usize = 760;
const HEIGHT: usize = 380;
const LEFT: usize = 70;
const RIGHT: usize = 20;
const TOP: usize = 40;
const BOTTOM: usize = 50;

fn write_picture(path: &Path, bins: &[usize; 36], title: &str) -> Result<(), Failure> {
    let bytes = match picture_format(path) {
        Some(Picture::Svg) => svg(bins, title).into_bytes(),
        Some(Picture::Png) => png_bytes(bins).map_err(Failure::other)?,
        None => unreachable!("checked before reading the mesh"),
    };
    write_atomically(path, &bytes)
}

/// A round upper bound for the y axis.
fn y_max(bins: &[usize; 36]) -> usize {
    let m = bins.iter().copied().max().unwrap_or(0).max(1);
    let magnitude = 10usize.pow((m as f64).log10().floor() as u32);
    m.div_ceil(magnitude) * magnitude
}

fn svg(bins: &[usize; 36], title: &str) -> String {
    let (pw, ph) = (
        (WIDTH - LEFT - RIGHT) as f64,
        (HEIGHT - TOP - BOTTOM) as f64,
    );
    let ymax = y_max(bins) as f64;
    let bar = pw / 36.0;
    let mut s = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{WIDTH}\" height=\"{HEIGHT}\" viewBox=\"0 0 {WIDTH} {HEIGHT}\" font-family=\"sans-serif\" font-size=\"12\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n<text x=\"{}\" y=\"22\" text-anchor=\"middle\" font-size=\"14\">{}</text>\n",
        WIDTH / 2,
        escape(title)
    );
    for (i, &n) in bins.iter().enumerate() {
        let h = ph * n as f64 / ymax;
        s += &format!(
            "<rect x=\"{:.2}\" y=\"{:.2}\" width=\"{:.2}\" height=\"{:.2}\" fill=\"#3b6ea5\"><title>{}–{}°: {n}</title></rect>\n",
            LEFT as f64 + bar * i as f64 + 1.0,
            TOP as f64 + ph - h,
            bar - 2.0,
            h,
            5 * i,
            5 * i + 5
        );
    }
    let (x0, y0) = (LEFT as f64, (TOP as f64) + ph);
    s += &format!(
        "<path d=\"M{x0} {TOP} V{y0} H{}\" stroke=\"black\" fill=\"none\"/>\n",
        x0 + pw
    );
    for deg in (0..=180).step_by(30) {
        let x = x0 + pw * f64::from(deg) / 180.0;
        s += &format!(
            "<line x1=\"{x:.2}\" y1=\"{y0}\" x2=\"{x:.2}\" y2=\"{}\" stroke=\"black\"/><text x=\"{x:.2}\" y=\"{}\" text-anchor=\"middle\">{deg}°</text>\n",
            y0 + 5.0,
            y0 + 20.0
        );
    }
    for k in 0..=4 {
        let v = ymax * f64::from(k) / 4.0;
        let y = y0 - ph * f64::from(k) / 4.0;
        s += &format!(
            "<line x1=\"{}\" y1=\"{y:.2}\" x2=\"{x0}\" y2=\"{y:.2}\" stroke=\"black\"/><text x=\"{}\" y=\"{:.2}\" text-anchor=\"end\">{}</text>\n",
            x0 - 5.0,
            x0 - 8.0,
            y + 4.0,
            v.round()
        );
    }
    s += &format!(
        "<text x=\"{}\" y=\"{}\" text-anchor=\"middle\">angle (degrees)</text>\n<text x=\"16\" y=\"{}\" text-anchor=\"middle\" transform=\"rotate(-90 16 {})\">number of angles</text>\n</svg>\n",
        x0 + pw / 2.0,
        HEIGHT - 8,
        TOP as f64 + ph / 2.0,
        TOP as f64 + ph / 2.0
    );
    s
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// Digits 0–9 in a 3×5 bitmap, rows top to bottom, bit 2 the left column.
const DIGITS: [[u8; 5]; 10] = [
    [7, 5, 5, 5, 7],
    [2, 6, 2, 2, 7],
    [7, 1, 7, 4, 7],
    [7, 1, 7, 1, 7],
    [5, 5, 7, 1, 1],
    [7, 4, 7, 1, 7],
    [7, 4, 7, 5, 7],
    [7, 1, 1, 1, 1],
    [7, 5, 7, 5, 7],
    [7, 5, 7, 1, 7],
];

struct Canvas {
    rgb: Vec<u8>,
}

impl Canvas {
    fn fill(&mut self, x0: usize, y0: usize, x1: usize, y1: usize, c: [u8; 3]) {
        for y in y0.min(HEIGHT)..y1.min(HEIGHT) {
            for x in x0.min(WIDTH)..x1.min(WIDTH) {
                let i = 3 * (y * WIDTH + x);
                self.rgb[i..i + 3].copy_from_slice(&c);
            }
        }
    }

    /// Draws a number with its centre at `cx`, top at `y` (scale 2: 6×10 pixels per digit).
    fn number(&mut self, n: usize, cx: usize, y: usize, right_aligned: bool) {
        let text = n.to_string();
        let w = text.len() * 8;
        let x0 = if right_aligned {
            cx.saturating_sub(w)
        } else {
            cx.saturating_sub(w / 2)
        };
        for (k, ch) in text.bytes().enumerate() {
            let glyph = DIGITS[usize::from(ch - b'0')];
            for (row, bits) in glyph.iter().enumerate() {
                for col in 0..3 {
                    if bits >> (2 - col) & 1 == 1 {
                        let x = x0 + 8 * k + 2 * col;
                        let yy = y + 2 * row;
                        self.fill(x, yy, x + 2, yy + 2, [0, 0, 0]);
                    }
                }
            }
        }
    }
}

fn png_bytes(bins: &[usize; 36]) -> Result<Vec<u8>, png::EncodingError> {
    let mut c = Canvas {
        rgb: vec![255; 3 * WIDTH * HEIGHT],
    };
    let (pw, ph) = (WIDTH - LEFT - RIGHT, HEIGHT - TOP - BOTTOM);
    let ymax = y_max(bins);
    let y0 = TOP + ph;
    for (i, &n) in bins.iter().enumerate() {
        let h = ph * n / ymax;
        let x = LEFT + pw * i / 36;
        let x1 = LEFT + pw * (i + 1) / 36;
        c.fill(x + 1, y0 - h, x1.saturating_sub(1), y0, [0x3b, 0x6e, 0xa5]);
    }
    c.fill(LEFT, TOP, LEFT + 1, y0 + 1, [0, 0, 0]);
    c.fill(LEFT, y0, LEFT + pw, y0 + 1, [0, 0, 0]);
    for deg in (0..=180).step_by(30) {
        let x = LEFT + pw * deg / 180;
        c.fill(x, y0, x + 1, y0 + 6, [0, 0, 0]);
        c.number(deg, x, y0 + 10, false);
    }
    for k in 0..=4 {
        let y = y0 - ph * k / 4;
        c.fill(LEFT - 5, y, LEFT, y + 1, [0, 0, 0]);
        c.number(ymax * k / 4, LEFT - 8, y.saturating_sub(5), true);
    }
    let mut out = Vec::new();
    {
        let mut encoder = png::Encoder::new(&mut out, WIDTH as u32, HEIGHT as u32);
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        let mut writer = encoder.write_header()?;
        writer.write_image_data(&c.rgb)?;
    }
    Ok(out)
}
