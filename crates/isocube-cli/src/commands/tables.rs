//! `isocube tables --binary|--ternary [--group G] [--polygons]`.

use std::io::Write;

use clap::Args as ClapArgs;
use isocube::cube::{ClassTable, ConfigKind, Group, TernaryTable};

use crate::Failure;

#[derive(Debug, ClapArgs)]
#[command(group(clap::ArgGroup::new("kind").required(true).args(["binary", "ternary"])))]
pub(crate) struct Args {
    /// The 256 binary configurations.
    #[arg(long)]
    binary: bool,
    /// The 6561 ternary configurations.
    #[arg(long)]
    ternary: bool,
    /// Symmetry group: rotations, rotations+flip or all.
    #[arg(long, default_value = "rotations+flip")]
    group: Group,
    /// List each configuration's polygons (one row per face-decision pattern) instead of its
    /// class; classes are then those under rotations+flip.
    #[arg(long, conflicts_with = "group")]
    polygons: bool,
}

pub(crate) fn run(args: &Args) -> Result<(), Failure> {
    let kind = if args.ternary {
        ConfigKind::Ternary
    } else {
        ConfigKind::Binary
    };
    let stdout = std::io::stdout();
    let mut out = std::io::BufWriter::new(stdout.lock());
    let written = match (args.polygons, kind) {
        (true, ConfigKind::Ternary) => TernaryTable::get().write_tsv(&mut out),
        (true, ConfigKind::Binary) => TernaryTable::get().write_binary_tsv(&mut out),
        (false, _) => ClassTable::get(kind, args.group).write_tsv(&mut out),
    }
    .and_then(|()| out.flush());
    match written {
        Ok(()) => Ok(()),
        // A closed pipe (`| head`) is not a failure.
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        Err(e) => Err(Failure::other(e)),
    }
}
