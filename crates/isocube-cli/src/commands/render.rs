//! `isocube render MESH -o PICTURE.png [--view iso|x|y|z|AZ,EL] [--size WxH] [--wireframe]`.

use std::path::{Path, PathBuf};

use clap::Args as ClapArgs;
use isocube::mesh::Mesh;
use isocube::render::{render, Picture, RenderOptions, View};
use isocube_io::read_mesh;

use crate::Failure;

#[derive(Debug, ClapArgs)]
pub(crate) struct Args {
    /// A .ply, .obj, .stl or .off mesh.
    mesh: PathBuf,
    /// The picture to write (.png).
    #[arg(long, short)]
    output: PathBuf,
    /// Camera direction: iso, x, y, z (looking from that axis) or AZIMUTH,ELEVATION in degrees.
    #[arg(long, default_value = "iso", allow_hyphen_values = true)]
    view: View,
    /// Picture size in pixels.
    #[arg(long, default_value = "800x600", value_parser = parse_size)]
    size: (usize, usize),
    /// Draw every triangle's edges, to see the triangulation's quality.
    #[arg(long)]
    wireframe: bool,
}

pub(crate) fn parse_size(s: &str) -> Result<(usize, usize), String> {
    let parsed = s
        .split_once(['x', 'X'])
        .and_then(|(w, h)| Some((w.parse::<usize>().ok()?, h.parse::<usize>().ok()?)));
    match parsed {
        Some((w, h)) if (1..=16384).contains(&w) && (1..=16384).contains(&h) => Ok((w, h)),
        _ => Err(format!(
            "'{s}' is not a size: expected WIDTHxHEIGHT, each 1 to 16384 pixels"
        )),
    }
}

pub(crate) fn run(args: &Args, quiet: bool) -> Result<(), Failure> {
    check_png(&args.output)?;
    crate::refuse_overwrite(&args.output, &[(&args.mesh, "mesh")])?;
    let mesh = read_mesh(&args.mesh).map_err(|e| crate::io_failure(e, true))?;
    let picture = picture(&mesh, args.view, args.size, args.wireframe);
    write_png(&args.output, &picture)?;
    if !quiet {
        eprintln!(
            "{}: {}×{} pixels, the mesh covers {:.1} %",
            args.output.display(),
            picture.width,
            picture.height,
            100.0 * picture.coverage()
        );
    }
    Ok(())
}

/// The picture of a mesh (also used by `isocube demo`).
pub(crate) fn picture(mesh: &Mesh, view: View, size: (usize, usize), wireframe: bool) -> Picture {
    let options = RenderOptions::new(size.0, size.1)
        .with_view(view)
        .with_wireframe(wireframe);
    render(mesh, &options)
}

pub(crate) fn check_png(path: &Path) -> Result<(), Failure> {
    let png = path
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("png"));
    if png {
        Ok(())
    } else {
        Err(Failure::input(anyhow::anyhow!(
            "{}: pictures are written as .png",
            path.display()
        )))
    }
}

/// Encodes and writes a picture atomically.
pub(crate) fn write_png(path: &Path, picture: &Picture) -> Result<(), Failure> {
    let mut bytes = Vec::new();
    {
        let mut encoder =
            png::Encoder::new(&mut bytes, picture.width as u32, picture.height as u32);
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        let mut writer = encoder.write_header().map_err(Failure::other)?;
        writer
            .write_image_data(&picture.rgb)
            .map_err(Failure::other)?;
    }
    isocube_io::write_file_atomic(path, &bytes).map_err(|e| crate::io_failure(e, false))
}
