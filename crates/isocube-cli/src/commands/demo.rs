//! `isocube demo [--out DIR]`: extract the built-in samples, write them with a picture of each,
//! print a summary.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use clap::Args as ClapArgs;
use isocube::extract::{extract, ExtractOptions};
use isocube::field::Sample;
use isocube_io::{write_mesh, MeshWriteOptions};

use crate::commands::render;
use crate::Failure;
use isocube::render::View;

#[derive(Debug, ClapArgs)]
pub(crate) struct Args {
    /// Directory for the meshes (created if missing).
    #[arg(long, default_value = "isocube-demo")]
    out: PathBuf,
    /// Points per axis.
    #[arg(long, default_value_t = 64, value_parser = clap::value_parser!(u16).range(2..=512))]
    size: u16,
    /// Picture size in pixels (each mesh is also drawn as a .png beside it).
    #[arg(long, default_value = "640x480", value_parser = crate::commands::render::parse_size)]
    picture: (usize, usize),
}

pub(crate) fn run(args: &Args, quiet: bool) -> Result<(), Failure> {
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create {}", args.out.display()))
        .map_err(Failure::other)?;
    let n = usize::from(args.size);
    println!(
        "{:<12} {:>6} {:>9} {:>9} {:>10} {:>10} {:>6} {:>6} {:>9} {:>9}",
        "sample",
        "points",
        "vertices",
        "triangles",
        "watertight",
        "components",
        "euler",
        "genus",
        "min_angle",
        "ms"
    );
    for sample in Sample::ALL {
        let grid = sample.grid(n);
        let started = Instant::now();
        let (mesh, _) = extract(&grid, &ExtractOptions::default()).map_err(Failure::other)?;
        let ms = started.elapsed().as_secs_f64() * 1e3;
        let r = mesh.report();
        let path = args.out.join(format!("{}-{n}.ply", sample.name()));
        write_mesh(&path, &mesh, &MeshWriteOptions::default())
            .map_err(|e| crate::io_failure(e, false))?;
        let picture = render::picture(&mesh, View::ISO, args.picture, false);
        render::write_png(&path.with_extension("png"), &picture)?;
        println!(
            "{:<12} {:>6} {:>9} {:>9} {:>10} {:>10} {:>6} {:>6} {:>9.2} {:>9.1}",
            sample.name(),
            format!("{n}^3"),
            r.vertices,
            r.triangles,
            if r.watertight { "yes" } else { "open" },
            r.components,
            r.euler,
            r.genus.map_or("-".to_string(), |g| g.to_string()),
            r.min_angle,
            ms
        );
    }
    if !quiet {
        eprintln!("meshes and pictures written to {}", args.out.display());
    }
    Ok(())
}
