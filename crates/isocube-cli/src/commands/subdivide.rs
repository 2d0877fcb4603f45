//! `isocube subdivide MESH -o OUT --levels N [--holes smooth|sharp]
//! [--boundary edge-only|edge-and-corner|none] [--limit]`.

use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::{Args as ClapArgs, ValueEnum};
use isocube::subdiv::{
    limit_positions, samples, subdivide, BoundaryRule, HoleMethod, SubdivError, SubdivOptions,
    MAX_FACES,
};
use isocube_io::{read_poly_mesh, write_poly_mesh};

use crate::Failure;

#[derive(Clone, Copy, Debug, ValueEnum)]
enum Boundary {
    EdgeOnly,
    EdgeAndCorner,
    None,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum Holes {
    Smooth,
    Sharp,
}

#[derive(Debug, ClapArgs)]
pub(crate) struct Args {
    /// The cage: .obj (polygons, with OpenSubdiv's `t crease`, `t corner`, `t hole`,
    /// `t interpolateboundary` tags and isocube's `t innerloop`), a .ply/.stl triangle mesh
    /// such as `extract` writes, or a built-in cage `sample:cube|plate|box-hole|boss`.
    mesh: String,
    /// Output: .obj keeps polygons and tags; .ply or .stl get triangles.
    #[arg(long, short)]
    output: PathBuf,
    /// Refinement levels.
    #[arg(long, default_value_t = 1)]
    levels: usize,
    /// Faces with inner loops: `smooth` (the loops are joined and rounded over) or `sharp`
    /// (the loops stay sharp and the face keeps its holes).
    #[arg(long, default_value = "smooth")]
    holes: Holes,
    /// Boundary rule; overrides the file's `interpolateboundary` tag (default: the tag, else
    /// edge-only).
    #[arg(long)]
    boundary: Option<Boundary>,
    /// Move the refined vertices to their limit positions.
    #[arg(long)]
    limit: bool,
    /// Write ASCII PLY.
    #[arg(long)]
    ascii: bool,
}

pub(crate) fn run(args: &Args, quiet: bool) -> Result<(), Failure> {
    crate::check_mesh_output(&args.output)?;
    if !args.mesh.starts_with("sample:") {
        crate::refuse_overwrite(&args.output, &[(Path::new(&args.mesh), "input mesh")])?;
    }
    let cage = match args.mesh.strip_prefix("sample:") {
        Some(name) => samples::sample(name).ok_or_else(|| {
            Failure::input(anyhow::anyhow!(
                "unknown sample cage '{name}' (expected one of {})",
                samples::SAMPLES.join(", ")
            ))
        })?,
        None => read_poly_mesh(Path::new(&args.mesh)).map_err(|e| crate::io_failure(e, true))?,
    };
    let mut options = SubdivOptions::default();
    options.boundary = args.boundary.map(|b| match b {
        Boundary::EdgeOnly => BoundaryRule::EdgeOnly,
        Boundary::EdgeAndCorner => BoundaryRule::EdgeAndCorner,
        Boundary::None => BoundaryRule::None,
    });
    options.holes = match args.holes {
        Holes::Smooth => HoleMethod::Smooth,
        Holes::Sharp => HoleMethod::Sharp,
    };
    let started = Instant::now();
    let mut fine = subdivide(&cage, args.levels, &options).map_err(|e| match e {
        SubdivError::TooManyFaces { faces, .. } => Failure::input(anyhow::anyhow!(
            "--levels {}: about {faces} faces; at most {MAX_FACES} are supported",
            args.levels
        )),
        e => Failure::input(anyhow::anyhow!("{}: {e}", args.mesh)),
    })?;
    if args.limit {
        if let Some(b) = options.boundary {
            fine.boundary = Some(b);
        }
        fine.positions =
            limit_positions(&fine).map_err(|e| Failure::input(anyhow::anyhow!("--limit: {e}")))?;
    }
    let elapsed = started.elapsed();
    write_poly_mesh(&args.output, &fine, &crate::write_options(args.ascii, true))
        .map_err(|e| crate::io_failure(e, false))?;
    if !quiet {
        eprintln!(
            "{}: {} vertices, {} faces ({} levels from {} faces) in {:.1} ms",
            args.output.display(),
            fine.positions.len(),
            fine.faces.len(),
            args.levels,
            cage.faces.len(),
            elapsed.as_secs_f64() * 1e3
        );
    }
    Ok(())
}
