//! `isocube contours INPUT -o MESH [--grid NXxNY | --cell SIZE] [--cap flat | none | extend [DIST]]`.

use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::Args as ClapArgs;
use isocube::contours::{
    reconstruct_with, Cap, Fidelity, PlaneGrid, ReconstructOptions, SectionStack,
};
use isocube::extract::ExtractError;
use isocube::quality::Strategy;
use isocube_io::{read_contours_with, write_mesh, ContourOptions};

use crate::volume::{parse_memory, MemoryLimit};
use crate::Failure;

#[derive(Debug, ClapArgs)]
pub(crate) struct Args {
    /// A contour file (.csv with columns section,z,contour,x,y; .json; or .dxf with closed
    /// LWPOLYLINE/POLYLINE entities, elevation as z), a DICOM RT Structure Set (.dcm: each
    /// region of interest's CLOSED_PLANAR contours, in patient coordinates), or
    /// `sample:orebody`.
    input: String,
    /// Output mesh: .ply, .obj or .stl. An RT Structure Set writes one mesh per region of
    /// interest, named after it: `-o plan.ply` gives `plan-patient.ply`, …
    #[arg(long, short)]
    output: PathBuf,
    /// RT Structure Sets: mesh only these regions of interest, by name or ROI number
    /// (repeatable; default: every region with CLOSED_PLANAR contours).
    #[arg(long, value_name = "NAME|NUMBER")]
    roi: Vec<String>,
    /// The image the contours were drawn on (a DICOM series folder, or any volume file, in the
    /// contours' coordinates): the plane grid takes its pixels — their spacing, and points on
    /// its pixel lattice (shifted by 7 % and 4 % of a pixel, so that contours traced through
    /// pixel centres do not put vertices on grid points) — instead of --grid or --cell. Its
    /// slices must be axial and its pixels square.
    #[arg(long, value_name = "VOLUME", conflicts_with_all = ["grid", "cell"])]
    reference: Option<PathBuf>,
    #[command(flatten)]
    stack: StackArgs,
    /// The section-data paper's plain approach: crossings interpolated from the distances and no
    /// contour points inserted (by default the mesh's cut by every section is the contour).
    #[arg(long)]
    plain: bool,
    /// How each cell's polygon (with the contour points inserted in it) becomes triangles:
    /// `local` (the local-change paper's rules), `optimal` (the largest smallest angle per
    /// polygon, about 2.5× slower) or `fan` (from the polygon's centre).
    #[arg(long, default_value = "local")]
    triangulate: Strategy,
    /// Write ASCII PLY.
    #[arg(long)]
    ascii: bool,
    /// The most memory the reconstruction may take, estimated from the surface's area and the
    /// cell size before any work: `512M`, `8G`, a number of bytes, or `none`. [default: the
    /// machine's physical memory]
    #[arg(long, value_name = "SIZE", value_parser = parse_memory)]
    max_memory: Option<MemoryLimit>,
}

/// The plane grid and the caps: how a stack of sections becomes a volume to mesh (`contours`
/// and `tetmesh`).
#[derive(Debug, ClapArgs)]
#[command(group(clap::ArgGroup::new("resolution").args(["grid", "cell"])))]
pub(crate) struct StackArgs {
    /// Contour stacks: at most NX × NY square cells over the contours' bounding box. [default:
    /// 100 across the longer side]
    #[arg(long, value_name = "NXxNY", value_parser = parse_grid)]
    grid: Option<[usize; 2]>,
    /// Contour stacks: square cells of this size (in the contours' units).
    #[arg(long, value_name = "SIZE")]
    cell: Option<f64>,
    /// Contour stacks: how the ends close: `extend [DIST]` extrapolates the body DIST beyond
    /// each end section (default: half the mean section spacing); `flat` fills the end
    /// contours in their planes (holes kept open); `none` leaves them open (surfaces only).
    #[arg(long, num_args = 1..=2, value_names = ["KIND", "DIST"], default_values = ["extend"], allow_negative_numbers = true)]
    cap: Vec<String>,
    /// Contour stacks: close open DXF polylines (the segment back to the first vertex
    /// implied) instead of refusing them. (CSV and JSON contours are always closed curves,
    /// whether or not the last point repeats the first.)
    #[arg(long)]
    close: bool,
}

/// Whether a command's input names a contour stack rather than a volume.
pub(crate) fn is_stack(input: &str) -> bool {
    input == "sample:orebody"
        || Path::new(input)
            .extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| ["csv", "json", "dxf"].contains(&e.to_ascii_lowercase().as_str()))
}

/// Reads the stack `input` names (refusing to write over it), noting the contours the reader
/// closed unless `quiet`.
pub(crate) fn load_stack(
    input: &str,
    output: &Path,
    stack: &StackArgs,
    quiet: bool,
) -> Result<SectionStack, Failure> {
    if input == "sample:orebody" {
        return Ok(SectionStack::sample_orebody());
    }
    let input = Path::new(input);
    crate::refuse_overwrite(output, &[(input, "input")])?;
    let options = ContourOptions::default().with_close(stack.close);
    let read = read_contours_with(input, &options).map_err(|e| crate::io_failure(e, true))?;
    if read.closed_implicitly > 0 && !quiet {
        let n = read.closed_implicitly;
        eprintln!(
            "note: {n} contour{} closed by the segment back to {} first point",
            if n == 1 { "" } else { "s" },
            if n == 1 { "its" } else { "their" }
        );
    }
    Ok(read.stack)
}

impl StackArgs {
    /// The first of these options given, to refuse for an input that is not a stack. (`--cap
    /// extend`, the default, cannot be told from no `--cap`.)
    pub(crate) fn given(&self) -> Option<&'static str> {
        if self.grid.is_some() {
            Some("--grid")
        } else if self.cell.is_some() {
            Some("--cell")
        } else if self.cap != ["extend"] {
            Some("--cap")
        } else if self.close {
            Some("--close")
        } else {
            None
        }
    }

    /// The plane grid asked for (100 cells across by default), refused when too large to index.
    pub(crate) fn plane(&self, stack: &SectionStack) -> Result<PlaneGrid, Failure> {
        let plane = match (self.grid, self.cell) {
            (_, Some(c)) if c.is_finite() && c > 0.0 => PlaneGrid::with_cell(stack, c),
            (_, Some(c)) => {
                return Err(Failure::input(anyhow::anyhow!(
                    "--cell {c}: expected a size > 0"
                )))
            }
            (Some(counts), None) => PlaneGrid::with_counts(stack, counts),
            (None, None) => PlaneGrid::across(stack, 100),
        };
        if !plane.indexable(stack.sections().len()) {
            return Err(Failure::input(anyhow::anyhow!(
                "the plane grid would be {}×{} points over {} sections; use a coarser --grid or \
                 a larger --cell",
                plane.dims[0],
                plane.dims[1],
                stack.sections().len()
            )));
        }
        Ok(plane)
    }

    /// The caps asked for.
    pub(crate) fn cap(&self, stack: &SectionStack) -> Result<Cap, Failure> {
        let bad = |m: String| Failure::input(anyhow::anyhow!(m));
        match self
            .cap
            .iter()
            .map(String::as_str)
            .collect::<Vec<_>>()
            .as_slice()
        {
            ["none"] => Ok(Cap::Open),
            ["extend"] => Ok(Cap::extended(stack)),
            ["extend", d] => match d.parse::<f64>() {
                Ok(v) if v.is_finite() && v > 0.0 => Ok(Cap::Extend(v)),
                _ => Err(bad(format!("--cap extend: '{d}' is not a distance > 0"))),
            },
            ["flat"] => Ok(Cap::Flat),
            other => Err(bad(format!(
                "--cap {}: expected `flat`, `none` or `extend [DIST]`",
                other.join(" ")
            ))),
        }
    }
}

fn parse_grid(s: &str) -> Result<[usize; 2], String> {
    let (a, b) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("'{s}': expected NXxNY, for example 100x80"))?;
    let n = |t: &str| match t.trim().parse::<usize>() {
        Ok(v) if (1..=1 << 16).contains(&v) => Ok(v),
        _ => Err(format!("'{t}' is not a cell count between 1 and 65536")),
    };
    Ok([n(a)?, n(b)?])
}

pub(crate) fn run(args: &Args, quiet: bool) -> Result<(), Failure> {
    crate::check_mesh_output(&args.output)?;
    if isocube_io::is_dicom_file(Path::new(&args.input)) {
        return run_structure_set(args, quiet);
    }
    if !args.roi.is_empty() {
        return Err(Failure::input(anyhow::anyhow!(
            "--roi picks regions of a DICOM RT Structure Set; {} is not one",
            args.input
        )));
    }
    let stack = load_stack(&args.input, &args.output, &args.stack, quiet)?;
    mesh_stack(args, &stack, &args.output, "", quiet)
}

/// Each region of interest of an RT Structure Set (or those `--roi` names) to its own mesh.
fn run_structure_set(args: &Args, quiet: bool) -> Result<(), Failure> {
    let input = Path::new(&args.input);
    let rois = isocube_io::read_rt_structure_set(input).map_err(|e| crate::io_failure(e, true))?;
    let listing = || {
        rois.iter()
            .map(|r| format!("{} '{}'", r.number, r.name))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let mut chosen = Vec::new();
    for pick in &args.roi {
        let found = rois.iter().position(|r| {
            r.name.eq_ignore_ascii_case(pick) || pick.parse::<i64>().is_ok_and(|n| n == r.number)
        });
        match found {
            Some(i) if !chosen.contains(&i) => chosen.push(i),
            Some(_) => {}
            None => {
                return Err(Failure::input(anyhow::anyhow!(
                    "--roi {pick}: {} has no such region of interest (it has {})",
                    args.input,
                    listing()
                )))
            }
        }
    }
    if chosen.is_empty() {
        chosen = (0..rois.len()).collect();
    }
    let mut skipped = Vec::new();
    let mut refused = Vec::new();
    let mut outputs = Vec::new();
    for &i in &chosen {
        let roi = &rois[i];
        if let Some(problem) = &roi.problem {
            // Asked for by name, a refused region is the error; otherwise the others are
            // written and the command fails after them, naming it.
            if !args.roi.is_empty() {
                return Err(Failure::input(anyhow::anyhow!("{problem}")));
            }
            refused.push(problem.clone());
            continue;
        }
        if roi.stack.is_none() {
            let what = roi
                .other
                .iter()
                .map(|(kind, n)| format!("{n} {kind}"))
                .collect::<Vec<_>>()
                .join(", ");
            let what = if what.is_empty() {
                "no contours".to_string()
            } else {
                what
            };
            skipped.push(format!("{} '{}' ({what})", roi.number, roi.name));
            continue;
        }
        let output = roi_output(&args.output, roi);
        crate::refuse_overwrite(&output, &[(input, "input")])?;
        if outputs.contains(&output) {
            return Err(Failure::input(anyhow::anyhow!(
                "two regions of interest would both be written to {}",
                output.display()
            )));
        }
        outputs.push(output);
    }
    if outputs.is_empty() && refused.is_empty() {
        return Err(Failure::input(anyhow::anyhow!(
            "{}: no region of interest with CLOSED_PLANAR contours among {}",
            args.input,
            skipped.join(", ")
        )));
    }
    let meshed = chosen.iter().filter(|&&i| rois[i].stack.is_some());
    for (&i, output) in meshed.zip(&outputs) {
        let roi = &rois[i];
        let stack = roi.stack.as_ref().expect("chosen with contours");
        mesh_stack(
            args,
            stack,
            output,
            &format!("ROI {} '{}': ", roi.number, roi.name),
            quiet,
        )?;
    }
    if !skipped.is_empty() && !quiet {
        eprintln!(
            "skipped (no CLOSED_PLANAR contours): {}",
            skipped.join(", ")
        );
    }
    if !refused.is_empty() {
        let n = refused.len();
        return Err(Failure::input(anyhow::anyhow!(
            "{n} region{} of interest refused, {} (--roi picks regions): {}",
            if n == 1 { "" } else { "s" },
            if outputs.is_empty() {
                "nothing else to write"
            } else {
                "the others written"
            },
            refused.join("; ")
        )));
    }
    Ok(())
}

/// `plan.ply` and ROI 'GTV 1' → `plan-GTV_1.ply` (the number when the name is empty).
fn roi_output(output: &Path, roi: &isocube_io::RtRoi) -> PathBuf {
    let name: String = roi
        .name
        .trim()
        .chars()
        .map(|c| {
            if c.is_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect();
    let name = if name.is_empty() {
        roi.number.to_string()
    } else {
        name
    };
    let stem = output.file_stem().and_then(|s| s.to_str()).unwrap_or("roi");
    let ext = output.extension().and_then(|s| s.to_str()).unwrap_or("ply");
    output.with_file_name(format!("{stem}-{name}.{ext}"))
}

/// Reconstructs a stack's surface and writes it to `output`, with a summary line (after
/// `label`) unless `quiet`.
fn mesh_stack(
    args: &Args,
    stack: &SectionStack,
    output: &Path,
    label: &str,
    quiet: bool,
) -> Result<(), Failure> {
    let plane = match &args.reference {
        Some(reference) => reference_plane(reference, stack)?,
        None => args.stack.plane(stack)?,
    };
    let cap = args.stack.cap(stack)?;
    let started = Instant::now();
    let options = reconstruct_options(
        cap,
        args.plain,
        args.triangulate,
        MemoryLimit::or_default(args.max_memory),
    );
    let r = reconstruct_with(stack, &plane, &options).map_err(|e| match e {
        ExtractError::MemoryLimit { .. } => Failure::input(anyhow::anyhow!(
            "{e}; use a coarser --grid or a larger --cell (or raise --max-memory)"
        )),
        e => Failure::input(e),
    })?;
    let elapsed = started.elapsed();
    write_mesh(output, &r.mesh, &crate::write_options(args.ascii, true))
        .map_err(|e| crate::io_failure(e, false))?;
    if !quiet {
        let rep = r.mesh.report();
        eprintln!(
            "{label}{}: {} vertices, {} triangles, {} in {:.1} ms ({} sections, {}×{} plane grid, distance evaluated at {} of {} points){}",
            output.display(),
            rep.vertices,
            rep.triangles,
            if rep.watertight && rep.oriented {
                format!("watertight, genus {}", rep.genus.unwrap_or(0))
            } else {
                format!("{} boundary edges", rep.boundary_edges)
            },
            elapsed.as_secs_f64() * 1e3,
            stack.sections().len(),
            r.plane.dims[0],
            r.plane.dims[1],
            r.evaluated,
            r.points,
            unresolved_note(r.unresolved_edges, r.missed_contours)
        );
    }
    Ok(())
}

/// The reconstruction `isocube contours` runs (and `view` shows): these caps, the contour
/// points inserted unless `plain`, this triangulation, the memory budget.
pub(crate) fn reconstruct_options(
    cap: Cap,
    plain: bool,
    triangulate: Strategy,
    max_memory: Option<u64>,
) -> ReconstructOptions {
    let fidelity = if plain {
        Fidelity::Plain
    } else {
        Fidelity::Exact
    };
    let options = ReconstructOptions::new(cap)
        .with_fidelity(fidelity)
        .with_triangulation(triangulate);
    match max_memory {
        Some(limit) => options.with_max_memory(limit),
        None => options,
    }
}

/// The plane grid on a reference image's pixel lattice: its pixel spacing, points at its
/// pixel centres, covering the contours with a cell to spare.
fn reference_plane(reference: &Path, stack: &SectionStack) -> Result<PlaneGrid, Failure> {
    let options = isocube_io::VolumeOptions::default();
    let (grid, orientation) = isocube_io::read_volume_oriented(reference, &options)
        .map_err(|e| crate::io_failure(e, true))?;
    let d = orientation.direction();
    // Rows along x and columns along y, either way round: axial slices.
    let axial =
        (0..2).all(|a| (d[a][a].abs() - 1.0).abs() < 1e-6) && (d[2][2].abs() - 1.0).abs() < 1e-6;
    let [sx, sy, _] = grid.spacing();
    let bad = |why: String| {
        Failure::input(anyhow::anyhow!(
            "--reference {}: {why}",
            reference.display()
        ))
    };
    if !axial {
        return Err(bad(
            "its slices are not axial (rows along x, columns along y)".into(),
        ));
    }
    if (sx - sy).abs() > 1e-6 * sx.max(sy) {
        return Err(bad(format!(
            "its pixels are {sx} × {sy}: the plane grid needs square cells"
        )));
    }
    // The image's pixel lattice along each axis, shifted by a small odd fraction of a pixel:
    // contours traced on pixel centres would otherwise put their vertices on grid points,
    // where cells degenerate (the same fractions as `PlaneGrid::with_cell` uses).
    let origin = grid.origin();
    let (lo, hi, _) = stack.bounds();
    let first = |a: usize, shift: f64| {
        let o = origin[a];
        o + ((lo[a] - o) / sx).floor() * sx - sx + shift * sx
    };
    let start = [first(0, 0.0719), first(1, 0.0437)];
    let dims = [0, 1].map(|a| ((hi[a] - start[a]) / sx).ceil() as usize + 2);
    let plane = PlaneGrid {
        origin: start,
        spacing: sx,
        dims,
    };
    if !plane.indexable(stack.sections().len()) {
        return Err(bad(format!(
            "its {sx} pixels make a {}×{} plane grid, too large to index",
            dims[0], dims[1]
        )));
    }
    Ok(plane)
}

/// What the grid could not follow, for the summary line.
fn unresolved_note(edges: usize, missed: usize) -> String {
    let mut note = String::new();
    if edges > 0 {
        let what = if edges == 1 {
            "grid edge is"
        } else {
            "grid edges are"
        };
        note += &format!(
            "; {edges} {what} crossed by two parts of the contours closer than a cell, where the \
             cut cannot follow them"
        );
    }
    if missed > 0 {
        note += &if missed == 1 {
            "; 1 contour encloses no grid point and is missing".to_string()
        } else {
            format!("; {missed} contours enclose no grid point and are missing")
        };
    }
    if !note.is_empty() {
        note += " (use a finer --grid or --cell)";
    }
    note
}
