//! `isocube extract VOLUME -o MESH [--level L]`.

use std::path::PathBuf;
use std::time::Instant;

use crate::volume::SlabInput;
use clap::Args as ClapArgs;
use isocube::cube::Topology;
use isocube::extract::{
    extract_boxes_into, extract_into, extract_labels, extract_labels_boxes, extract_streamed,
    label_cells, streams_by_default, CellBox, ExtractError, ExtractOptions, ExtractStats,
    LabelOptions, LabelSelection, Method, SnapPosition, Snapping, StreamError,
};
use isocube::field::SampleSpec;
use isocube::field::{Grid, Level, Orientation, PlaneSource, ValueSummary};
use isocube::mesh::Mesh;
use isocube::quality::{Field, Strategy, Trilinear};
use isocube_io::{write_mesh_with_values, MeshFormat, PlyWriter, VertexValues};

use crate::progress::Progress;
use crate::volume::VolumeArgs;
use crate::Failure;

#[derive(Debug, ClapArgs)]
pub(crate) struct Args {
    #[command(flatten)]
    volume: VolumeArgs,
    /// Output mesh: .ply (binary unless --ascii), .obj, .stl, .off, .glb (binary glTF), .vtp or
    /// .vtk (VTK PolyData) or .msh (Gmsh 4.1).
    #[arg(long, short)]
    output: PathBuf,
    /// The iso-value (values equal to it count as above): a number, `auto` (Otsu's threshold
    /// of the values' histogram) or a percentage of the value range (`40%`: min + 0.4 ×
    /// (max − min)). The summary gives the level used.
    #[arg(long, default_value = "0", allow_negative_numbers = true)]
    level: Level,
    /// Write the mesh even when no cell crosses the level (by default that is an error naming
    /// the volume's value range).
    #[arg(long)]
    allow_empty: bool,
    /// Orient normals and winding toward decreasing values (default: toward increasing).
    #[arg(long)]
    flip: bool,
    /// Surface inside each cell: `mc33` follows the trilinear interpolant (tunnels included);
    /// `classic` is face-consistent Marching Cubes without the interior test.
    #[arg(long, default_value = "mc33")]
    topology: Topology,
    /// `mc`: binary Marching Cubes. `ternary`: grid points on or near the level become surface
    /// vertices (no degenerate or needle triangles), with the same topology as `mc`.
    #[arg(long, default_value = "mc", value_parser = ["mc", "ternary"])]
    method: String,
    /// Ternary: values within this distance of the level count as zero (on the surface).
    #[arg(long, default_value_t = 0.0)]
    zero_threshold: f32,
    /// Ternary: snap a grid point onto the surface when a crossing on one of its edges lies
    /// within this fraction of the edge (0 to 0.5).
    #[arg(long, default_value_t = 0.3)]
    snap: f32,
    /// Ternary: where a snapped point's vertex goes: `crossing` (the nearest crossing on its
    /// edges, keeping Marching Cubes' accuracy) or `grid` (the grid point itself).
    #[arg(long, default_value = "crossing")]
    snap_position: SnapPosition,
    /// How cell polygons become triangles: `fan` (the table's), `local` (the local-change paper:
    /// small angles cut off, interior vertex toward short sides, largest angle split) or `optimal`
    /// (the largest smallest angle per polygon).
    #[arg(long, default_value = "fan")]
    triangulate: Strategy,
    /// Relaxation sweeps: vertices slide along the level set to lift the smallest angles, never
    /// turning a triangle over; the level set of the exact function for built-in samples, of the
    /// trilinear interpolant otherwise.
    #[arg(long, default_value_t = 0)]
    relax: usize,
    /// Also write one value per vertex: this volume (same forms as VOLUME; raw files take the
    /// same --dims and --type) sampled trilinearly at each vertex in world coordinates, NaN
    /// outside it. For .ply, .glb, .vtp, .vtk and .msh.
    #[arg(long, value_name = "VOLUME")]
    values: Option<String>,
    #[command(flatten)]
    label: LabelArgs,
    /// Keep the mesh in grid index coordinates (point (i, j, k) at (i, j, k)) instead of the
    /// file's world coordinates (its spacing, origin and direction).
    #[arg(long)]
    index_space: bool,
    /// Do not compute or write vertex normals.
    #[arg(long)]
    no_normals: bool,
    /// Write ASCII PLY.
    #[arg(long)]
    ascii: bool,
    /// Extract slab by slab from the memory-mapped file (raw, .npy, .nii, .mha/.mhd, raw .nrrd
    /// or raw-appended .vti) straight into a binary PLY: memory stays at a few slabs whatever
    /// the volume's size. Chosen by itself for volumes whose
    /// values take more than 1 GiB as f32, when the options allow it (binary PLY output, `mc`,
    /// no relaxation). The mesh is the same, byte for byte.
    #[arg(long)]
    stream: bool,
    /// Mesh boxes of this many cells per axis (`NX,NY,NZ`), in parallel and in any order, and
    /// join them by their vertices' grid keys: the file is the same, byte for byte, as without
    /// it (a check of the chunk engine, and the unit of work for volumes cut into chunks). With
    /// --labels, the boxes cut the grid's cells and the layer of outside cells around them.
    #[arg(long, value_name = "NX,NY,NZ", value_parser = parse_chunk, conflicts_with = "stream")]
    chunk: Option<[usize; 3]>,
    /// Fail (exit code 2, nothing written) when any cell touches a NaN or infinite value. By
    /// default such cells are skipped, leaving a hole, and counted in the summary.
    #[arg(long)]
    strict: bool,
}

pub(crate) fn run(args: &Args, quiet: bool) -> Result<(), Failure> {
    crate::check_mesh_output(&args.output)?;
    if let (Some(_), Some(format)) = (&args.values, MeshFormat::from_path(&args.output)) {
        if !format.holds_vertex_data() {
            return Err(Failure::input(anyhow::anyhow!(
                "{}: --values needs a format with per-vertex data (.ply, .glb, .vtp, .vtk, .msh)",
                args.output.display()
            )));
        }
    }
    if !SampleSpec::is_sample(&args.volume.volume) {
        crate::refuse_overwrite(
            &args.output,
            &[(std::path::Path::new(&args.volume.volume), "input volume")],
        )?;
    }
    if let Some(values) = args.values.as_deref().filter(|v| !SampleSpec::is_sample(v)) {
        crate::refuse_overwrite(
            &args.output,
            &[(std::path::Path::new(values), "--values volume")],
        )?;
    }
    if let Some(selection) = &args.label.labels {
        return run_labels(args, selection, quiet);
    }
    // A file stored uncompressed is mapped, not read: `f32` values are meshed where they lie,
    // in whatever order its axes are stored; other types are converted slab by slab.
    let mapped = args.volume.try_map()?.map(|v| v.framed(args.index_space));
    // A Zarr store is decoded a layer of chunks at a time as the slabs need them.
    if mapped.is_none() && isocube_io::is_zarr_store(std::path::Path::new(&args.volume.volume)) {
        if let Some(volume) = args.volume.try_zarr()? {
            let volume = volume.framed(args.index_space);
            if let Some(volume) = streamable(args, Some(&volume))? {
                return run_streamed(args, volume, quiet);
            }
            if slab_obstacle(args).is_none() {
                return run_slabs_in_memory(args, volume, quiet);
            }
        }
    }
    if let Some(volume) = streamable(args, mapped.as_ref())? {
        return run_streamed(args, volume, quiet);
    }

    if slab_obstacle(args).is_none() {
        match mapped {
            Some(volume) if volume.view().is_none() => {
                return run_slabs_in_memory(args, volume, quiet);
            }
            Some(_) => {}
            // A gzipped NIfTI is inflated plane by plane as the slabs need them: never whole.
            None => {
                if let Some(volume) = args.volume.try_inflating()? {
                    let volume = volume.framed(args.index_space);
                    return run_slabs_in_memory(args, volume, quiet);
                }
            }
        }
    }
    // The view carries the file's direction, and a built-in sample its exact function: the
    // library orients the mesh and relaxes on the right field. Values that need converting are
    // read whole through the plane reader the slab paths use, so the cells are walked and cut
    // in the same frame: the same file makes the same mesh whichever path its options take.
    let mapped_view = mapped.as_ref().and_then(|v| v.view());
    let mut loaded = None;
    let view = match mapped_view {
        Some(view) => view,
        None => {
            let walked = args.volume.load_walked(args.index_space)?;
            let (grid, orientation) = loaded.insert(walked);
            grid.view().with_orientation(*orientation)
        }
    };
    // The mesh may use what the volume leaves of --max-memory (the machine's memory by default).
    let room = crate::volume::MemoryLimit::or_default(args.volume.max_memory)
        .map(|limit| limit.saturating_sub(std::mem::size_of_val(view.values()) as u64));
    let level = resolve_level(args, || ValueSummary::of(view.values()))?;
    let options = options(args, level).with_max_memory(room);
    let started = Instant::now();
    let mut mesh = Mesh::new();
    let mut progress = Progress::new("extracting", quiet);
    let stats = match args.chunk {
        Some(size) => CellBox::tile(view.dims(), size).and_then(|boxes| {
            extract_boxes_into(view, &options, &boxes, &mut mesh, &mut |d, t| {
                progress.update(d, t)
            })
        }),
        None => {
            // Slabs of whole layers are meshed in order, so a mapped file's pages behind the
            // last finished layer (less the plane the next layer's normals read) are not read
            // again: dropping them keeps the input's share of memory to the layers in work.
            // Relaxation reads the whole grid after the join, so it keeps them.
            let [nx, ny, _] = view.dims();
            let layer = (nx - 1) * (ny - 1);
            let release = mapped
                .as_ref()
                .filter(|_| mapped_view.is_some() && args.relax == 0);
            extract_into(view, &options, &mut mesh, &mut |d, t| {
                if let Some(volume) = release {
                    volume.release_before((d / layer.max(1)).saturating_sub(1));
                }
                progress.update(d, t)
            })
        }
    }
    .map_err(|e| match e {
        ExtractError::MeshMemory { .. } => Failure::input(anyhow::anyhow!(
            "{}: {e} (raise it with --max-memory)",
            args.volume.volume
        )),
        e => Failure::input(e),
    })?;
    progress.finish();
    if args.strict && stats.skipped_cells > 0 {
        let [nx, ny, nz] = view.dims();
        let first = (0..nx * ny * nz).find(|p| {
            let (i, j, k) = (p % nx, p / nx % ny, p / (nx * ny));
            !view.value(i, j, k).is_finite()
        });
        let at = first.map_or_else(String::new, |p| {
            let point = [p % nx, p / nx % ny, p / (nx * ny)];
            // A mapped file is walked in its memory order: name the point as the file does.
            let [i, j, k] = mapped.as_ref().map_or(point, |m| m.file_point(point));
            format!(", the first at point ({i}, {j}, {k})")
        });
        return Err(non_finite_failure(args, &stats, &at));
    }
    if mesh.triangles.is_empty() && !args.allow_empty {
        return Err(empty_failure(args, level, ValueSummary::of(view.values())));
    }
    // The input's pages count in the process's memory while it is mapped; the mesh is made,
    // so unmapping it before the writer runs keeps the peak to the larger of the two phases.
    drop((mapped, loaded));
    write_and_report(args, level, &mesh, &stats, started.elapsed(), quiet)
}

/// Writes the mesh (with `--values` when asked) and prints the summary.
fn write_and_report(
    args: &Args,
    level: f32,
    mesh: &Mesh,
    stats: &ExtractStats,
    elapsed: std::time::Duration,
    quiet: bool,
) -> Result<(), Failure> {
    let values = match &args.values {
        Some(spec) => Some(sample_at_vertices(args, spec, mesh)?),
        None => None,
    };
    // The summary's edge count runs beside the writer: both only read the mesh.
    let (written, edges) = std::thread::scope(|scope| {
        let edges = (!quiet).then(|| scope.spawn(|| mesh.edge_report()));
        let written = write_mesh_with_values(
            &args.output,
            mesh,
            &crate::write_options(args.ascii, !args.no_normals),
            values
                .as_ref()
                .map(|(name, v)| VertexValues { name, values: v }),
        );
        let edges = edges.map(|h| h.join().unwrap_or_else(|p| std::panic::resume_unwind(p)));
        (written, edges)
    });
    written.map_err(|e| crate::io_failure(e, false))?;
    if let Some(r) = edges {
        eprintln!(
            "{}: {} vertices, {} triangles, {} in {:.1} ms ({}{})",
            args.output.display(),
            mesh.positions.len(),
            mesh.triangles.len(),
            if r.watertight && r.oriented {
                "watertight".to_string()
            } else {
                format!("{} boundary edges", r.boundary_edges)
            },
            elapsed.as_secs_f64() * 1e3,
            cell_summary(level, stats),
            if let Method::Ternary(_) = options(args, level).method {
                format!(
                    ", {} points snapped, {} kept off to keep the topology",
                    stats.snapped_points, stats.refused_points
                )
            } else {
                String::new()
            }
        );
    }
    Ok(())
}

/// The input's failure, or `--strict` refusing what its caveat says; else the caveat to print.
fn input_checked(args: &Args, volume: &impl SlabInput) -> Result<Option<String>, Failure> {
    if let Some(e) = volume.failure() {
        return Err(crate::io_failure(e, true));
    }
    match volume.caveat() {
        Some(why) if args.strict => Err(Failure::input(anyhow::anyhow!(
            "{}: {why}; nothing written (--strict)",
            args.volume.volume
        ))),
        caveat => Ok(caveat),
    }
}

/// A volume converted or inflated slab by slab as the streamed path does, the mesh gathered in
/// memory and written in any format. The mesh is the one extraction of the whole grid gives,
/// without that grid.
fn run_slabs_in_memory(args: &Args, volume: impl SlabInput, quiet: bool) -> Result<(), Failure> {
    let level = resolve_level(args, || ValueSummary::of_source(&volume))?;
    let started = Instant::now();
    let mut mesh = Mesh::new();
    let mut progress = Progress::new("extracting", quiet);
    let stats = extract_streamed(&volume, &options(args, level), &mut mesh, &mut |d, t| {
        progress.update(d, t)
    })
    .map_err(|e| match e {
        StreamError::Extract(e) => Failure::input(e),
        StreamError::Sink(never) => match never {},
    })?;
    progress.finish();
    let caveat = input_checked(args, &volume)?;
    if args.strict && stats.skipped_cells > 0 {
        return Err(non_finite_failure(args, &stats, ""));
    }
    if let (Some(caveat), false) = (caveat, quiet) {
        eprintln!("note: {caveat}");
    }
    if mesh.triangles.is_empty() && !args.allow_empty {
        return Err(empty_failure(args, level, ValueSummary::of_source(&volume)));
    }
    // As in `run`: the input is unmapped before the mesh is written.
    drop(volume);
    write_and_report(args, level, &mesh, &stats, started.elapsed(), quiet)
}

/// The volume as meshed: in index space (spacing 1, origin 0, no direction) with
/// `--index-space`, else as the file places it.
fn in_frame(args: &Args, loaded: (Grid, Orientation)) -> Result<(Grid, Orientation), Failure> {
    crate::volume::in_frame(args.index_space, loaded)
}

fn parse_chunk(s: &str) -> Result<[usize; 3], String> {
    let sizes: Vec<usize> = s
        .split(',')
        .map(|w| w.trim().parse::<usize>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("'{s}' is not three cell counts (like 64,64,64)"))?;
    match sizes[..] {
        [x, y, z] if x > 0 && y > 0 && z > 0 => Ok([x, y, z]),
        _ => Err(format!(
            "'{s}' must be three cell counts of at least 1 (like 64,64,64)"
        )),
    }
}

/// A segmentation's labels, each its own surface (`extract --labels`, `view --labels`).
#[derive(Debug, ClapArgs)]
pub(crate) struct LabelArgs {
    /// The volume is a labelled image (a segmentation): mesh every label but the background
    /// (`--labels`), or the listed ones (`--labels 1,4,7`), each as its own closed surface with
    /// the same triangles where two labels touch. `extract` writes one file per label:
    /// OUTPUT's name with `-LABEL` before the extension.
    #[arg(long, value_name = "LIST", num_args = 0..=1, default_missing_value = "all", value_parser = parse_labels)]
    pub labels: Option<LabelSelection>,
    /// The label that is not meshed (with --labels).
    #[arg(long, default_value_t = 0, allow_negative_numbers = true)]
    pub background: i64,
    /// Smoothing sweeps for --labels (0 keeps the voxels' staircase); vertices never move more
    /// than one cell, and shared interfaces stay shared.
    #[arg(long, default_value_t = 60)]
    pub smooth: usize,
}

impl LabelArgs {
    /// The library's options for these arguments and the labels `selection`.
    pub(crate) fn options(&self, selection: &LabelSelection) -> LabelOptions {
        let mut options = LabelOptions::default();
        options.background = self.background;
        options.labels = selection.clone();
        options.smoothing = self.smooth;
        options
    }
}

pub(crate) fn parse_labels(s: &str) -> Result<LabelSelection, String> {
    if s == "all" {
        return Ok(LabelSelection::All);
    }
    s.split(',')
        .map(|w| w.trim().parse::<i64>())
        .collect::<Result<Vec<_>, _>>()
        .map(LabelSelection::Only)
        .map_err(|_| format!("'{s}' is not a list of integer labels (like 1,4,7)"))
}

/// `OUTPUT` with `-LABEL` before its extension.
fn label_path(output: &std::path::Path, label: i64) -> PathBuf {
    let stem = output
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or("mesh");
    let ext = output.extension().and_then(|s| s.to_str()).unwrap_or("ply");
    output.with_file_name(format!("{stem}-{label}.{ext}"))
}

/// `--labels`: one closed surface per label, in world coordinates unless `--index-space`.
fn run_labels(args: &Args, selection: &LabelSelection, quiet: bool) -> Result<(), Failure> {
    let (grid, orientation) = in_frame(args, args.volume.load_oriented()?)?;
    let view = grid.view().with_orientation(orientation);
    let started = Instant::now();
    let options = args.label.options(selection);
    let surfaces = match args.chunk {
        Some(size) => {
            let points = label_cells(grid.dims()).max.map(|c| c + 1);
            CellBox::tile(points, size)
                .and_then(|boxes| extract_labels_boxes(view, &options, &boxes))
        }
        None => extract_labels(view, &options),
    }
    .map_err(Failure::input)?;
    if surfaces.is_empty() {
        // The labels the volume holds, so the user sees what to ask for.
        let mut present: Vec<i64> = Vec::new();
        for &v in grid.values() {
            let label = v.round() as i64;
            if v.is_finite() && label != args.label.background && !present.contains(&label) {
                present.push(label);
                if present.len() > 20 {
                    break;
                }
            }
        }
        present.sort_unstable();
        let held = match present.len() {
            0 => "it holds only the background".to_string(),
            1..=20 => format!(
                "it holds labels {}",
                present
                    .iter()
                    .map(i64::to_string)
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
            _ => "it holds more than 20 labels".to_string(),
        };
        return Err(Failure::input(anyhow::anyhow!(
            "{}: no label to mesh (background {}{}): {held}",
            args.volume.volume,
            args.label.background,
            match selection {
                LabelSelection::All => String::new(),
                LabelSelection::Only(list) => format!(", asked for {list:?}"),
            }
        )));
    }
    let elapsed = started.elapsed();
    if !SampleSpec::is_sample(&args.volume.volume) {
        let input = std::path::Path::new(&args.volume.volume);
        for surface in &surfaces {
            crate::refuse_overwrite(
                &label_path(&args.output, surface.label),
                &[(input, "input volume")],
            )?;
        }
    }
    // A DICOM segmentation names its segments: the names go in the summary.
    let input = std::path::Path::new(&args.volume.volume);
    let names = if input.is_file() && isocube_io::is_dicom_file(input) {
        isocube_io::read_dicom_segments(input).unwrap_or_default()
    } else {
        Vec::new()
    };
    for mut surface in surfaces {
        if args.no_normals {
            surface.mesh.normals.clear();
        }
        let path = label_path(&args.output, surface.label);
        let name = names
            .iter()
            .find(|(n, _)| *n == surface.label)
            .map(|(_, name)| format!(" '{name}'"))
            .unwrap_or_default();
        write_mesh_with_values(
            &path,
            &surface.mesh,
            &crate::write_options(args.ascii, !args.no_normals),
            None,
        )
        .map_err(|e| crate::io_failure(e, false))?;
        if !quiet {
            let r = surface.mesh.report();
            eprintln!(
                "{}: label {}{name}, {} vertices, {} triangles, {}, {} components, Euler characteristic {}",
                path.display(),
                surface.label,
                r.vertices,
                r.triangles,
                if r.watertight && r.oriented { "watertight" } else { "open" },
                r.components,
                r.euler
            );
        }
    }
    if !quiet {
        eprintln!("labels meshed in {:.1} ms", elapsed.as_secs_f64() * 1e3);
    }
    Ok(())
}

/// The `--values` volume sampled at the mesh's vertices, with the array's name (the volume's
/// file stem, or the sample's name).
fn sample_at_vertices(args: &Args, spec: &str, mesh: &Mesh) -> Result<(String, Vec<f32>), Failure> {
    let volume = VolumeArgs {
        volume: spec.to_string(),
        ..args.volume.clone()
    };
    let (grid, orientation) = volume.load_walked(args.index_space)?;
    let field = Trilinear(grid.view());
    let dims = grid.dims();
    let (h, o) = (grid.spacing(), grid.origin());
    let values = mesh
        .positions
        .iter()
        .map(|p| {
            let p = orientation.to_grid_frame(p.map(f64::from), o);
            // Inside the grid (within rounding), else NaN rather than an extrapolation.
            let inside = (0..3).all(|a| {
                let u = (p[a] - o[a]) / h[a];
                u >= -1e-6 && u <= (dims[a] - 1) as f64 + 1e-6
            });
            match (inside, field.value_and_gradient(p)) {
                (true, Some((v, _))) => v as f32,
                _ => f32::NAN,
            }
        })
        .collect();
    let name = if SampleSpec::is_sample(spec) {
        spec.split(':').nth(1).unwrap_or("value").to_string()
    } else {
        std::path::Path::new(spec)
            .file_stem()
            .and_then(|s| s.to_str())
            .map(|s| s.split('.').next().unwrap_or(s).to_string())
            .filter(|s| !s.is_empty())
            .unwrap_or_else(|| "value".into())
    };
    Ok((name, values))
}

/// Why the options need the whole volume in memory (`None`: slab by slab works).
fn slab_obstacle(args: &Args) -> Option<&'static str> {
    if args.method != "mc" {
        Some("ternary extraction needs the whole volume")
    } else if args.relax > 0 {
        Some("relaxation needs the whole mesh")
    } else if args.label.labels.is_some() {
        Some("labels are meshed in memory")
    } else if args.chunk.is_some() {
        Some("--chunk meshes boxes in memory")
    } else {
        None
    }
}

/// The mapped volume, when extraction goes slab by slab straight into the file: asked for with
/// --stream (an error if the options need the whole volume), or chosen for a large volume
/// whose options allow it.
fn streamable<'a, V: PlaneSource>(
    args: &Args,
    mapped: Option<&'a V>,
) -> Result<Option<&'a V>, Failure> {
    let obstacle = if mapped.is_none() {
        Some("the volume must be stored uncompressed (raw, .npy, .nii, .mha/.mhd, raw .nrrd, raw-appended .vti)")
    } else if MeshFormat::from_path(&args.output) != Some(MeshFormat::Ply) || args.ascii {
        Some("the output must be a binary .ply")
    } else if args.values.is_some() {
        Some("vertex values need the whole mesh")
    } else {
        slab_obstacle(args)
    };
    match (args.stream, obstacle, mapped) {
        (true, Some(why), _) => Err(Failure::input(anyhow::anyhow!(
            "--stream cannot be used here: {why}"
        ))),
        (stream, None, Some(volume)) => {
            let by_default = streams_by_default(PlaneSource::dims(volume), &options(args, 0.0));
            Ok((stream || by_default).then_some(volume))
        }
        _ => Ok(None),
    }
}

fn run_streamed(args: &Args, volume: &impl SlabInput, quiet: bool) -> Result<(), Failure> {
    let level = resolve_level(args, || ValueSummary::of_source(volume))?;
    let options = options(args, level);
    let started = Instant::now();
    let mut ply = PlyWriter::create(&args.output, !args.no_normals)
        .map_err(|e| crate::io_failure(e, false))?;
    let mut progress = Progress::new("extracting (streamed)", quiet);
    let stats = extract_streamed(volume, &options, &mut ply, &mut |d, t| {
        progress.update(d, t)
    })
    .map_err(|e| match e {
        StreamError::Extract(e) => Failure::input(e),
        StreamError::Sink(e) => crate::io_failure(e, false),
    })?;
    progress.finish();
    // Dropping the writer removes its temporary file.
    let caveat = input_checked(args, volume)?;
    if args.strict && stats.skipped_cells > 0 {
        return Err(non_finite_failure(args, &stats, ""));
    }
    if let (Some(caveat), false) = (caveat, quiet) {
        eprintln!("note: {caveat}");
    }
    let (vertices, triangles) = (ply.vertex_count(), ply.triangle_count());
    if triangles == 0 && !args.allow_empty {
        // Dropping the writer removes its temporary file: nothing is written.
        return Err(empty_failure(args, level, ValueSummary::of_source(volume)));
    }
    ply.finish().map_err(|e| crate::io_failure(e, false))?;
    if !quiet {
        eprintln!(
            "{}: {vertices} vertices, {triangles} triangles in {:.1} ms, streamed slab by slab from {} ({})",
            args.output.display(),
            started.elapsed().as_secs_f64() * 1e3,
            volume.path().display(),
            cell_summary(level, &stats),
        );
    }
    Ok(())
}

/// `--strict` refusing a volume with NaN or infinite values; `at` says where the first is.
fn non_finite_failure(args: &Args, stats: &ExtractStats, at: &str) -> Failure {
    Failure::input(anyhow::anyhow!(
        "{}: {} cells touch NaN or infinite values{at}; nothing written (--strict)",
        args.volume.volume,
        stats.skipped_cells
    ))
}

/// "level L, N of M cells active, T tunnels[, S skipped for NaN/Inf values]".
fn cell_summary(level: f32, stats: &ExtractStats) -> String {
    let mut text = format!(
        "level {level}, {} of {} cells active, {} tunnels",
        stats.active_cells, stats.cells, stats.tunnels
    );
    if stats.skipped_cells > 0 {
        text += &format!(", {} skipped for NaN/Inf values", stats.skipped_cells);
    }
    text
}

/// The level `--level` asks for: its number, or one from the volume's values (`summary`,
/// computed only then).
fn resolve_level(
    args: &Args,
    summary: impl FnOnce() -> Option<ValueSummary>,
) -> Result<f32, Failure> {
    crate::volume::resolve_level(args.level, &args.volume.volume, summary)
}

/// No cell crosses the level: the error names the volume's value range.
fn empty_failure(args: &Args, level: f32, summary: Option<ValueSummary>) -> Failure {
    let empty = ExtractError::EmptySurface {
        level,
        range: summary.map(|s| (s.min, s.max)),
    };
    Failure::input(anyhow::anyhow!(
        "{}: {empty}; give a level inside (`--level auto` picks Otsu's threshold, `--level 50%` \
         the middle of the range), or --allow-empty to write the empty mesh; nothing written",
        args.volume.volume
    ))
}

/// The extraction choices `extract` and `view` share, as the command line spells them.
pub(crate) struct Choices<'a> {
    pub method: &'a str,
    pub topology: Topology,
    pub triangulate: Strategy,
    pub zero_threshold: f32,
    pub snap: f32,
    pub snap_position: SnapPosition,
    pub flip: bool,
    pub normals: bool,
    pub relax: usize,
}

impl Choices<'_> {
    /// The library's options at `level`: one conversion for every front end, so `view`'s
    /// downloads are `extract`'s files.
    pub(crate) fn options(&self, level: f32) -> ExtractOptions {
        ExtractOptions::default()
            .with_level(level)
            .with_flip(self.flip)
            .with_normals(self.normals)
            .with_topology(self.topology)
            .with_triangulation(self.triangulate)
            .with_relax(self.relax)
            .with_method(match self.method {
                "ternary" => Method::Ternary(
                    Snapping::default()
                        .with_zero_threshold(self.zero_threshold)
                        .with_snap(self.snap)
                        .with_position(self.snap_position),
                ),
                _ => Method::MarchingCubes,
            })
    }
}

/// The library's options from the arguments, at `level`.
fn options(args: &Args, level: f32) -> ExtractOptions {
    Choices {
        method: &args.method,
        topology: args.topology,
        triangulate: args.triangulate,
        zero_threshold: args.zero_threshold,
        snap: args.snap,
        snap_position: args.snap_position,
        flip: args.flip,
        normals: !args.no_normals,
        relax: args.relax,
    }
    .options(level)
}
