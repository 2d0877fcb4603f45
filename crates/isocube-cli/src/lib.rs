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

/// The command line's definition, with every typed value free to start with a minus:
/// `--origin -1.25,-1.25,-1.25` as users type it (clap takes a lone negative number, but reads
/// `-1.25,…` as an unknown flag `-1`). A value that names a file or is free text keeps clap's
/// rule, so `-o --level 2` is an error rather than a file named `--level`; an option taking
/// several values (`--cap extend DIST`) takes negative numbers, and one whose value is optional
/// (`--labels [LIST]`) a value starting with a minus after `=` (`--labels=-1,2`).
pub fn command() -> clap::Command {
    fn free(arg: clap::Arg) -> clap::Arg {
        let named = arg.get_long().is_some() || arg.get_short().is_some();
        if !named || !arg.get_action().takes_values() {
            return arg;
        }
        let kind = arg.get_value_parser().type_id();
        let text = kind == std::any::TypeId::of::<std::path::PathBuf>()
            || kind == std::any::TypeId::of::<String>();
        match arg.get_num_args().map(|n| (n.min_values(), n.max_values())) {
            None | Some((1, 1)) if !text => arg.allow_hyphen_values(true),
            // Several values (`--cap extend DIST`): only what reads as a negative number is a
            // value, so a following option stays an option.
            Some((1, _)) => arg.allow_negative_numbers(true),
            // An optional value (`--labels [LIST]`): clap would take the next option for it.
            _ => arg,
        }
    }
    fn walk(command: clap::Command) -> clap::Command {
        command.mut_args(free).mut_subcommands(walk)
    }
    walk(<Cli as clap::CommandFactory>::command())
}

/// Parses a command line with [`command`]'s rules.
fn parse<I, T>(args: I) -> Result<Cli, clap::Error>
where
    I: IntoIterator<Item = T>,
    T: Into<OsString> + Clone,
{
    let mut matches = command().try_get_matches_from(args)?;
    <Cli as clap::FromArgMatches>::from_arg_matches_mut(&mut matches)
}

/// Runs the command line and returns the process exit code.
pub fn run<I, T>(args: I) -> ExitCode
where
    I: IntoIterator<Item = T>,
    T: Into<OsString> + Clone,
{
    let cli = match parse(args) {
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
        command().debug_assert();
    }

    /// Every option of every command that takes a typed value (a number, a list of numbers, a
    /// level, a size) takes one starting with a minus as users type it: clap must not read it
    /// as a flag. What the value means is each option's own check, not tested here.
    #[test]
    fn every_typed_option_takes_a_leading_minus() {
        let root = command();
        let mut checked = Vec::new();
        for sub in root.get_subcommands() {
            // The command's required arguments, so that only the option under test can fail.
            let mut base = vec!["isocube".to_string(), sub.get_name().to_string()];
            for arg in sub.get_arguments().filter(|a| a.is_required_set()) {
                if let Some(long) = arg.get_long() {
                    base.push(format!("--{long}"));
                }
                base.push("x".to_string());
            }
            for arg in sub.get_arguments() {
                let Some(long) = arg.get_long() else { continue };
                let typed = arg.get_value_parser().type_id();
                let text = typed == std::any::TypeId::of::<std::path::PathBuf>()
                    || typed == std::any::TypeId::of::<String>();
                let optional = arg.get_num_args().is_some_and(|n| n.min_values() == 0);
                if !arg.get_action().takes_values() || text || optional {
                    continue;
                }
                for value in ["-1", "-1.25,-2.5,-3", "-2x3", "-.5"] {
                    let mut line = base.clone();
                    line.push(format!("--{long}"));
                    line.push(value.to_string());
                    if let Err(e) = parse(&line) {
                        use clap::error::ErrorKind;
                        assert!(
                            !matches!(e.kind(), ErrorKind::UnknownArgument | ErrorKind::NoEquals)
                                && !e.to_string().contains("a value is required"),
                            "{line:?}: {e}"
                        );
                    }
                }
                checked.push(format!("{} --{long}", sub.get_name()));
            }
        }
        for option in [
            "extract --origin",
            "extract --spacing",
            "extract --level",
            "extract --background",
            "tetmesh --origin",
            "tetmesh --layer-spacing",
            "view --origin",
            "view --level",
            "quality --level",
            "contours --cell",
        ] {
            assert!(checked.iter().any(|c| c == option), "{option} not checked");
        }
        // After an option taking an optional value or several, an option stays an option.
        for line in [
            "isocube extract v.npy -o o.ply --labels --quiet",
            "isocube contours c.csv -o o.ply --cap flat --quiet",
            "isocube contours c.csv -o o.ply --cap extend -2.5 --quiet",
        ] {
            let args: Vec<&str> = line.split_whitespace().collect();
            let cli = parse(args).unwrap_or_else(|e| panic!("{line}: {e}"));
            assert!(cli.quiet, "{line}");
        }
        // A file name is not taken from the next option.
        let args = ["isocube", "extract", "v.npy", "-o", "--level", "2"];
        assert!(parse(args).is_err());
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
            parse(args).unwrap_or_else(|e| panic!("{line}: {e}"));
        }
        for bad in [
            "isocube tables --binary --ternary",
            "isocube extract",
            "isocube tables --group odd",
        ] {
            let args: Vec<&str> = bad.split_whitespace().collect();
            assert!(parse(args).is_err(), "{bad}");
        }
    }
}
