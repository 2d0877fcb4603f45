//! `isocube extract VOLUME -o MESH [--level L]`.

use std::path::PathBuf;
use std::time::Instant;

use clap::Args as ClapArgs;
use isocube::cube::Topology;
use isocube::extract::{extract_into, ExtractOptions, Method, SnapPosition, Snapping};
use isocube::field::SampleSpec;
use isocube::io::{write_mesh, MeshWriteOptions};
use isocube::mesh::Mesh;
use isocube::quality::{relax, Implicit, Strategy};

use crate::progress::Progress;
use crate::volume::VolumeArgs;
use crate::Failure;

#[derive(Debug, ClapArgs)]
pub(crate) struct Args {
    #[command(flatten)]
    volume: VolumeArgs,
    /// Output mesh: .ply (binary unless --ascii), .obj or .stl.
    #[arg(long, short)]
    output: PathBuf,
    /// The iso-value. Values equal to it count as above.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    level: f32,
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
    /// Do not compute or write vertex normals.
    #[arg(long)]
    no_normals: bool,
    /// Write ASCII PLY.
    #[arg(long)]
    ascii: bool,
}

pub(crate) fn run(args: &Args, quiet: bool) -> Result<(), Failure> {
    crate::check_mesh_output(&args.output)?;
    if args.volume.is_file(&args.output) {
        return Err(Failure::input(anyhow::anyhow!(
            "{}: the output would overwrite the input volume",
            args.output.display()
        )));
    }
    let grid = args.volume.load()?;
    let exact = SampleSpec::is_sample(&args.volume.volume)
        .then(|| args.volume.volume.parse::<SampleSpec>().ok())
        .flatten()
        .map(|s| s.sample);
    let options = ExtractOptions::default()
        .with_level(args.level)
        .with_flip(args.flip)
        .with_normals(!args.no_normals)
        .with_topology(args.topology)
        .with_triangulation(args.triangulate)
        // Built-in samples relax on their exact function, after extraction; files in extract.
        .with_relax(if exact.is_some() { 0 } else { args.relax })
        .with_method(match args.method.as_str() {
            "ternary" => Method::Ternary(Snapping {
                zero_threshold: args.zero_threshold,
                snap: args.snap,
                position: args.snap_position,
            }),
            _ => Method::MarchingCubes,
        });
    let started = Instant::now();
    let mut mesh = Mesh::new();
    let mut progress = Progress::new("extracting", quiet);
    let stats = extract_into(&grid, &options, &mut mesh, &mut |d, t| {
        progress.update(d, t)
    })
    .map_err(Failure::input)?;
    progress.finish();
    if let (Some(sample), true) = (exact, args.relax > 0) {
        let h = grid.spacing().iter().copied().fold(f64::INFINITY, f64::min);
        relax(
            &mut mesh,
            &Implicit(|p| sample.eval(p), 1e-4 * h),
            f64::from(args.level),
            args.relax,
            h,
        );
    }
    let elapsed = started.elapsed();
    write_mesh(
        &args.output,
        &mesh,
        &MeshWriteOptions {
            ascii: args.ascii,
            normals: !args.no_normals,
        },
    )
    .map_err(|e| crate::io_failure(e, false))?;
    if !quiet {
        let r = mesh.report();
        eprintln!(
            "{}: {} vertices, {} triangles, {} in {:.1} ms ({} of {} cells active, {} tunnels{}{})",
            args.output.display(),
            r.vertices,
            r.triangles,
            if r.watertight && r.oriented {
                "watertight".to_string()
            } else {
                format!("{} boundary edges", r.boundary_edges)
            },
            elapsed.as_secs_f64() * 1e3,
            stats.active_cells,
            stats.cells,
            stats.tunnels,
            if stats.skipped_cells > 0 {
                format!(", {} skipped for NaN/Inf values", stats.skipped_cells)
            } else {
                String::new()
            },
            if let Method::Ternary(_) = options.method {
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
