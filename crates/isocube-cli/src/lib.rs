//! The `isocube` command line: argument parsing, progress, files. Algorithms live in the
//! `isocube` library; this crate turns arguments into library options in one place per
//! subcommand and reports results.
//!
//! Exit codes: 0 success, 2 bad arguments or bad input (malformed, unsupported or missing
//! files), 1 any other failure (for example an output that cannot be written).

use std::ffi::OsString;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

mod commands;
mod progress;
mod volume;

/// Scalar fields to triangle meshes that are correct, good and fast.
#[derive(Debug, Parser)]
#[command(name = "isocube", version, about, long_about = None)]
pub struct Cli {
    /// No progress bar and no summary on stderr.
    #[arg(long, short, global = true)]
    pub quiet: bool,
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Extract an isosurface from a volume and write it as a mesh.
    Extract(commands::extract::Args),
    /// Reconstruct a surface from a stack of cross-section contours.
    Contours(commands::contours::Args),
    /// Report a mesh's topology and triangle quality.
    Info(commands::info::Args),
    /// Triangle quality (Verdict measures), distance from the field's level set, angle histogram.
    Quality(commands::quality::Args),
    /// Draw a mesh into a PNG picture (software renderer: no GPU, no window).
    Render(commands::render::Args),
    /// Catmull–Clark subdivision (OpenSubdiv's rules; creases, corners, faces with holes).
    Subdivide(commands::subdivide::Args),
    /// Fill the region inside an isosurface with tetrahedra (for finite elements), bounded by
    /// the surface `extract` makes; or the body a stack of contour sections outlines (.csv,
    /// .json, .dxf, sample:orebody).
    Tetmesh(commands::tetmesh::Args),
    /// Print the symmetry-derived configuration tables as TSV.
    Tables(commands::tables::Args),
    /// Extract the built-in samples and print a summary table.
    Demo(commands::demo::Args),
    /// Explore a volume in the browser: drag the level and see the surface change at once (a
    /// local page on 127.0.0.1, guarded by a token). Also a segmentation's labels (--labels),
    /// a mesh (.ply, .obj, .stl, .off), a cage and its subdivision (.obj polygons,
    /// sample:cube|plate|box-hole|boss) and contour stacks (.csv, .json, .dxf, an RT Structure
    /// Set, sample:orebody) with their contours.
    View(commands::view::Args),
}

/// An error with the exit code it should produce.
#[derive(Debug)]
pub struct Failure {
    /// 2 for bad input or arguments, 1 otherwise.
    pub code: u8,
    /// What went wrong, with context.
    pub error: anyhow::Error,
}

impl Failure {
    /// Bad input: exit code 2.
    pub fn input(error: impl Into<anyhow::Error>) -> Failure {
        Failure {
            code: 2,
            error: error.into(),
        }
    }

    /// Any other failure: exit code 1.
    pub fn other(error: impl Into<anyhow::Error>) -> Failure {
        Failure {
            code: 1,
            error: error.into(),
        }
    }
}

/// Whether two paths name one file: the same path, the same file through symbolic links, or (on
/// Unix) hard links to one inode. A path that does not exist yet is no existing file.
pub(crate) fn same_file(a: &std::path::Path, b: &std::path::Path) -> bool {
    if a == b {
        return true;
    }
    let (Ok(ma), Ok(mb)) = (std::fs::metadata(a), std::fs::metadata(b)) else {
        return false;
    };
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        (ma.dev(), ma.ino()) == (mb.dev(), mb.ino())
    }
    #[cfg(not(unix))]
    {
        let _ = (ma, mb);
        matches!(
            (std::fs::canonicalize(a), std::fs::canonicalize(b)),
            (Ok(x), Ok(y)) if x == y
        )
    }
}

/// Refuses (exit code 2, before any work) an output that would replace one of the inputs.
pub(crate) fn refuse_overwrite(
    output: &std::path::Path,
    inputs: &[(&std::path::Path, &str)],
) -> Result<(), Failure> {
    for (input, what) in inputs {
        if same_file(input, output) {
            return Err(Failure::input(anyhow::anyhow!(
                "{}: the output would overwrite the {what}",
                output.display()
            )));
        }
    }
    Ok(())
}

/// Classifies a library I/O error: OS errors on output are failures, everything else is bad
/// input.
pub(crate) fn io_failure(e: isocube_io::IoError, reading: bool) -> Failure {
    match e {
        isocube_io::IoError::Os { .. } if !reading => Failure::other(e),
        _ => Failure::input(e),
    }
}

/// Rejects an output path whose extension names no mesh format (before any work is done).
pub(crate) fn check_mesh_output(path: &std::path::Path) -> Result<(), Failure> {
    if isocube_io::MeshFormat::from_path(path).is_none() {
        return Err(Failure::input(anyhow::anyhow!(
            "{}: unknown mesh extension (expected .ply, .obj, .stl, .off, .glb, .vtp, .vtk or .msh)",
            path.display()
        )));
    }
    Ok(())
}

/// Runs the command line and returns the process exit code.
pub fn run<I, T>(args: I) -> ExitCode
where
    I: IntoIterator<Item = T>,
    T: Into<OsString> + Clone,
{
    let cli = match Cli::try_parse_from(args) {
        Ok(cli) => cli,
        Err(e) => {
            let _ = e.print();
            return ExitCode::from(if e.use_stderr() { 2 } else { 0 });
        }
    };
    match dispatch(&cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(f) => {
            eprintln!("error: {}", message(&f.error));
            ExitCode::from(f.code)
        }
    }
}

/// The error and its causes joined by ": ", leaving out a cause whose text the message already
/// holds (the library's errors name their source in their own text).
fn message(error: &anyhow::Error) -> String {
    let mut out = String::new();
    for cause in error.chain() {
        let text = cause.to_string();
        if !out.contains(&text) {
            if !out.is_empty() {
                out.push_str(": ");
            }
            out.push_str(&text);
        }
    }
    out
}

fn dispatch(cli: &Cli) -> Result<(), Failure> {
    match &cli.command {
        Command::Extract(a) => commands::extract::run(a, cli.quiet),
        Command::Contours(a) => commands::contours::run(a, cli.quiet),
        Command::Info(a) => commands::info::run(a),
        Command::Quality(a) => commands::quality::run(a),
        Command::Render(a) => commands::render::run(a, cli.quiet),
        Command::Subdivide(a) => commands::subdivide::run(a, cli.quiet),
        Command::Tables(a) => commands::tables::run(a),
        Command::Tetmesh(a) => commands::tetmesh::run(a, cli.quiet),
        Command::Demo(a) => commands::demo::run(a, cli.quiet),
        Command::View(a) => commands::view::run(a, cli.quiet),
    }
}

/// How meshes are written: ASCII or binary, with or without normals.
pub(crate) fn write_options(ascii: bool, normals: bool) -> isocube_io::MeshWriteOptions {
    let mut options = isocube_io::MeshWriteOptions::default();
    options.ascii = ascii;
    options.normals = normals;
    options
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    #[test]
    fn command_definitions_are_valid() {
        Cli::command().debug_assert();
    }

    #[test]
    fn sample_command_lines_parse() {
        for line in [
            "isocube extract sample:sphere:10 -o s.ply",
            "isocube extract v.raw --dims 4,5,6 --type u16 --endian big --spacing 1,1,2 -o m.obj --level 100",
            "isocube extract v.npy --axes zyx -o m.stl --flip",
            "isocube extract sample:gyroid:40 -o g.ply --topology classic",
            "isocube info m.ply --json",
            "isocube contours sample:orebody -o o.ply --grid 80x60 --cap extend 5",
            "isocube contours c.csv -o o.obj --cell 0.5 --cap none",
            "isocube quality m.ply --field sample:sphere:40 --histogram h.svg --json",
            "isocube extract sample:torus:64 -o t.ply --method ternary --snap 0.5 --triangulate optimal --relax 10",
            "isocube tables --ternary --group rotations",
            "isocube demo --out d --size 32",
            "isocube --quiet demo",
        ] {
            let args: Vec<&str> = line.split_whitespace().collect();
            Cli::try_parse_from(args).unwrap_or_else(|e| panic!("{line}: {e}"));
        }
        for bad in [
            "isocube tables --binary --ternary",
            "isocube extract",
            "isocube tables --group odd",
        ] {
            let args: Vec<&str> = bad.split_whitespace().collect();
            assert!(Cli::try_parse_from(args).is_err(), "{bad}");
        }
    }
}
