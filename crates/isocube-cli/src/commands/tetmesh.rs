//! `isocube tetmesh VOLUME|CONTOURS -o MESH [--level L]`: tetrahedra of the region inside the
//! surface, or of the body between sections.

use std::path::PathBuf;
use std::time::Instant;

use clap::Args as ClapArgs;
use isocube::cube::Topology;
use isocube::extract::{
    ExtractOptions, LabelOptions, LabelSelection, Method, SnapPosition, Snapping,
};
use isocube::field::{Level, SampleSpec, ValueSummary};
use isocube::quality::Strategy;
use isocube::volume::{tetmesh, tetmesh_labels, Grading, TetError};
use isocube_io::{write_tet_mesh_as, TetFormat};

use crate::volume::VolumeArgs;
use crate::Failure;

#[derive(Debug, ClapArgs)]
pub(crate) struct Args {
    #[command(flatten)]
    volume: VolumeArgs,
    #[command(flatten)]
    stack: super::contours::StackArgs,
    /// Contour stacks: the largest distance between neighbouring planes; gaps between sections
    /// (and caps) longer than it get planes in between where the distances are interpolated
    /// linearly (the cut by every section stays the same), so elements are about as tall as
    /// wide. `sections` keeps the sections only (the surface is then `contours --plain`'s, and
    /// the elements as long as the sections are apart). [default: the plane grid's cell]
    #[arg(long, value_name = "DIST", value_parser = parse_layer_spacing)]
    layer_spacing: Option<LayerSpacing>,
    /// Output: .msh (Gmsh 4.1), .vtu (VTK unstructured grid, quality as cell data), .mesh
    /// (MEDIT) or .inp (Abaqus: C3D4 in REGION, element surfaces SURFACE and WALLS). Physical
    /// groups: 1 the region, 2 the isosurface, 3 the grid's outer faces; with --labels, one per
    /// label (Abaqus LABEL_L), then each label's boundary (BOUNDARY_L) and each interface
    /// (INTERFACE_A_B).
    #[arg(long, short)]
    output: PathBuf,
    /// The iso-value: a number, `auto` (Otsu's threshold of the values' histogram) or a
    /// percentage of the value range (`40%`). The region is the values below it (values equal
    /// to it are outside).
    #[arg(long, default_value = "0", allow_negative_numbers = true)]
    level: Level,
    /// Mesh the other side: the values at or above the level.
    #[arg(long)]
    flip: bool,
    /// The surface inside each cell, as `extract --topology`: `mc33` or `classic`.
    #[arg(long, default_value = "mc33")]
    topology: Topology,
    /// `ternary` (the default: grid points on or near the level become surface vertices, so no
    /// tetrahedron is squeezed against a crossing next to a corner; the boundary is `extract
    /// --method ternary`'s surface) or `mc` (binary Marching Cubes, as `extract`'s default: its
    /// crossings next to corners make slivers, dihedral angles from under 1° to over 178°).
    #[arg(long, default_value = "ternary", value_parser = ["mc", "ternary"])]
    method: String,
    /// Ternary: values within this distance of the level count as zero (on the surface).
    #[arg(long, default_value_t = 0.0)]
    zero_threshold: f32,
    /// Ternary: snap a grid point onto the surface when a crossing on one of its edges lies
    /// within this fraction of the edge (0 to 0.5).
    #[arg(long, default_value_t = 0.3)]
    snap: f32,
    /// Ternary: where a snapped point's vertex goes, as `extract --snap-position`: `crossing`
    /// (the default: the nearest crossing on its edges, the cells around it following the
    /// point there; the boundary is on the level set and finite element errors fall like h²)
    /// or `grid` (the grid point itself: the surface moves by up to the snap distance, errors
    /// fall like h).
    #[arg(long, default_value = "crossing")]
    snap_position: SnapPosition,
    /// How the surface's cell polygons become triangles, as `extract --triangulate`.
    #[arg(long, default_value = "fan")]
    triangulate: Strategy,
    /// The volume is a labelled image (a segmentation): mesh every label but the background
    /// (`--labels`), or the listed ones (`--labels 1,4,7`), each its own region (physical group
    /// "label L"), conforming where labels meet (groups "interface A|B"); the boundary is
    /// `extract --labels --smooth 0`'s surfaces (groups "label L boundary").
    #[arg(long, value_name = "LIST", num_args = 0..=1, default_missing_value = "all", value_parser = super::extract::parse_labels)]
    labels: Option<LabelSelection>,
    /// The label that is not meshed (with --labels).
    #[arg(long, default_value_t = 0, allow_negative_numbers = true)]
    background: i64,
    /// The graded interior's largest cubes: away from the surface, cells are gathered into
    /// cubes of 2, 4, 8, … cells on a side (each six Kuhn tetrahedra, or coned from a corner
    /// or its centre where it meets finer cubes: dihedral angles 17.72°–144.74° on cubic
    /// cells), up to this size: `16c` (cells) or a distance in the file's units. The boundary
    /// is the same (with --labels, every label's interior; the interfaces are the same too).
    /// On cells longer than 3:1 the interior is uniform. [default: 16c]
    #[arg(long, value_name = "SIZE", value_parser = parse_max_size)]
    max_size: Option<MaxSize>,
    /// Every inside cell six tetrahedra, no graded interior (refused with --max-size).
    #[arg(long, conflicts_with = "max_size")]
    uniform: bool,
    /// Cubes of each size keep this many cubes of their size from the cells the surface
    /// passes through (0: sizes may double from one cube to the next).
    #[arg(long, value_name = "LAYERS", default_value_t = 0)]
    grading: u8,
    /// Keep the mesh in grid index coordinates instead of the file's world coordinates.
    #[arg(long)]
    index_space: bool,
    /// Write `.msh` as Gmsh's binary form (`4.1 1 8`): no digits formatted, so several times
    /// faster on large meshes (about as many bytes: Gmsh spends 8 on every number). `.vtu` is
    /// binary already; MEDIT and Abaqus files are text.
    #[arg(long)]
    binary: bool,
    /// Skip the check of the written mesh (conformity, orientation by an exact predicate, the
    /// volume against the boundary's).
    #[arg(long)]
    no_check: bool,
}

/// The output format: the extension's, binary MSH with --binary.
fn output_format(args: &Args) -> Result<TetFormat, Failure> {
    match (TetFormat::from_path(&args.output), args.binary) {
        (None, _) => Err(Failure::input(anyhow::anyhow!(
            "{}: unknown tetrahedral mesh extension (expected .msh, .vtu, .mesh or .inp)",
            args.output.display()
        ))),
        (Some(TetFormat::Medit | TetFormat::Inp), true) => Err(Failure::input(anyhow::anyhow!(
            "--binary: {} is written as text (binary: .msh or .vtu)",
            args.output.display()
        ))),
        (Some(TetFormat::Msh), true) => Ok(TetFormat::MshBinary),
        (Some(format), _) => Ok(format),
    }
}

pub(crate) fn run(args: &Args, quiet: bool) -> Result<(), Failure> {
    output_format(args)?;
    if super::contours::is_stack(&args.volume.volume) {
        return run_stack(args, quiet);
    }
    // Options meant for the other kind of input are refused, not silently ignored.
    let for_stacks = args
        .layer_spacing
        .as_ref()
        .map(|_| "--layer-spacing")
        .or_else(|| args.stack.given());
    if let Some(option) = for_stacks {
        return Err(Failure::input(anyhow::anyhow!(
            "{option} is for contour stacks (.csv, .json, .dxf, sample:orebody)"
        )));
    }
    if !SampleSpec::is_sample(&args.volume.volume) {
        crate::refuse_overwrite(
            &args.output,
            &[(std::path::Path::new(&args.volume.volume), "input volume")],
        )?;
    }
    let started = Instant::now();
    // A file stored uncompressed with `f32` values is mapped and meshed where its values lie,
    // in the order the file stores them, as `extract` does (so the boundary is its surface):
    // no copy, nor a transpose of arrays stored z-fastest. Labels are read whole, as by
    // `extract --labels`.
    let mapped = match args.labels {
        Some(_) => None,
        None => args.volume.try_map()?,
    };
    let mapped = mapped.map(|v| crate::volume::SlabInput::framed(v, args.index_space));
    let mut loaded_grid = None;
    let view = match mapped.as_ref().and_then(|v| v.view()) {
        Some(view) => view,
        None => {
            // Other stored types are converted whole, walked as `extract` walks them; labels
            // in their index order, as by `extract --labels`.
            let loaded = match args.labels {
                Some(_) => crate::volume::in_frame(args.index_space, args.volume.load_oriented()?)?,
                None => args.volume.load_walked(args.index_space)?,
            };
            let (grid, orientation) = loaded_grid.insert(loaded);
            grid.view().with_orientation(*orientation)
        }
    };
    let room = crate::volume::MemoryLimit::or_default(args.volume.max_memory)
        .map(|limit| limit.saturating_sub(std::mem::size_of_val(view.values()) as u64));
    let level = match args.labels {
        Some(_) => 0.0,
        None => crate::volume::resolve_level(args.level, &args.volume.volume, || {
            ValueSummary::of(view.values())
        })?,
    };
    let cell = view
        .spacing()
        .into_iter()
        .map(f64::abs)
        .fold(f64::INFINITY, f64::min);
    let options = extract_options(args, room, level).with_grading(grading(args, cell));
    let loaded = started.elapsed();
    let meshed = match &args.labels {
        Some(selection) => tetmesh_labels(
            view,
            &LabelOptions::default()
                .with_smoothing(0)
                .with_background(args.background)
                .with_labels(selection.clone())
                .with_grading(options.grading),
            room,
        ),
        None => tetmesh(view, &options),
    };
    let detail = isocube::volume::snap_detail(&options);
    finish(args, quiet, meshed, (cell, detail), started, loaded)
}

/// The contour stack's body (or, with --flip, the space around it in the grid's box).
fn run_stack(args: &Args, quiet: bool) -> Result<(), Failure> {
    let started = Instant::now();
    if args.labels.is_some() {
        return Err(Failure::input(anyhow::anyhow!(
            "--labels is for labelled volumes: a contour stack outlines one body"
        )));
    }
    let v = &args.volume;
    let for_volumes = [
        (v.dims.is_some(), "--dims"),
        (v.scalar.is_some(), "--type"),
        (v.header_bytes != 0, "--header-bytes"),
        (v.spacing.is_some(), "--spacing"),
        (v.origin.is_some(), "--origin"),
        (args.index_space, "--index-space"),
        (args.background != 0, "--background"),
    ];
    if let Some((_, option)) = for_volumes.iter().find(|(given, _)| *given) {
        return Err(Failure::input(anyhow::anyhow!(
            "{option} is for volumes: a contour stack's coordinates are its own (--cell and \
             --grid set the plane grid)"
        )));
    }
    let stack = super::contours::load_stack(&args.volume.volume, &args.output, &args.stack, quiet)?;
    let plane = args.stack.plane(&stack)?;
    let cap = args.stack.cap(&stack)?;
    let layer_spacing = match args.layer_spacing {
        None => Some(plane.spacing),
        Some(LayerSpacing::Sections) => None,
        Some(LayerSpacing::At(d)) => Some(d),
    };
    let room = crate::volume::MemoryLimit::or_default(args.volume.max_memory);
    let Level::Value(level) = args.level else {
        return Err(Failure::input(anyhow::anyhow!(
            "--level {}: contour stacks are meshed at their contours (level 0)",
            args.level
        )));
    };
    let options = extract_options(args, room, level).with_grading(grading(args, plane.spacing));
    let loaded = started.elapsed();
    let meshed = isocube::contours::tetmesh(&stack, &plane, cap, layer_spacing, &options);
    let detail = isocube::volume::snap_detail(&options);
    finish(
        args,
        quiet,
        meshed,
        (plane.spacing, detail),
        started,
        loaded,
    )?;
    if !quiet {
        eprintln!(
            "{} sections, {}×{} plane grid (cell {:.4}), {}",
            stack.sections().len(),
            plane.dims[0],
            plane.dims[1],
            plane.spacing,
            layer_spacing.map_or("planes at the sections only".to_string(), |d| format!(
                "planes at most {d:.4} apart"
            ))
        );
    }
    Ok(())
}

/// `--layer-spacing`: a distance between planes, or the sections only.
#[derive(Clone, Copy, Debug, PartialEq)]
enum LayerSpacing {
    At(f64),
    Sections,
}

fn parse_layer_spacing(s: &str) -> Result<LayerSpacing, String> {
    if s.trim() == "sections" {
        return Ok(LayerSpacing::Sections);
    }
    match s.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(LayerSpacing::At(v)),
        _ => Err(format!("'{s}': expected a distance > 0 or `sections`")),
    }
}

/// The largest element size asked for (`--max-size`).
#[derive(Clone, Copy, Debug)]
enum MaxSize {
    /// In cells.
    Cells(f64),
    /// In the file's units.
    Distance(f64),
}

fn parse_max_size(s: &str) -> Result<MaxSize, String> {
    let s = s.trim();
    let (number, cells) = match s.strip_suffix('c') {
        Some(n) => (n, true),
        None => (s, false),
    };
    match number.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(if cells {
            MaxSize::Cells(v)
        } else {
            MaxSize::Distance(v)
        }),
        _ => Err(format!(
            "'{s}': expected a size > 0, in cells (`16c`) or in the file's units"
        )),
    }
}

/// The grading `--max-size` and `--grading` ask for, over cells `cell` wide: the largest
/// power of two cells within the size (by default [`Grading::DEFAULT`]'s).
fn grading(args: &Args, cell: f64) -> Grading {
    if args.uniform {
        return Grading::UNIFORM;
    }
    let Some(size) = args.max_size else {
        return Grading {
            layers: args.grading,
            ..Grading::DEFAULT
        };
    };
    let cells = match size {
        MaxSize::Cells(n) => n,
        MaxSize::Distance(d) => d / cell,
    };
    Grading::within(cells, args.grading)
}

/// The volume mesher's options from the command line.
fn extract_options(args: &Args, room: Option<u64>, level: f32) -> ExtractOptions {
    ExtractOptions::default()
        .with_level(level)
        .with_flip(args.flip)
        .with_normals(false)
        .with_topology(args.topology)
        .with_triangulation(args.triangulate)
        .with_max_memory(room)
        .with_method(match args.method.as_str() {
            "ternary" => Method::Ternary(
                Snapping::default()
                    .with_snap(args.snap)
                    .with_zero_threshold(args.zero_threshold)
                    .with_position(args.snap_position),
            ),
            _ => Method::MarchingCubes,
        })
}

/// Writes the mesh (checking it alongside) and reports, weighing the elements outside the
/// range against surface detail (`cell` wide cells, detail under `detail` of one).
fn finish(
    args: &Args,
    quiet: bool,
    meshed: Result<isocube::volume::TetMesh, TetError>,
    (cell, detail): (f64, f64),
    started: Instant,
    loaded: std::time::Duration,
) -> Result<(), Failure> {
    let format = output_format(args)?;
    let mesh = meshed.map_err(|e| match e {
        TetError::Cell { .. } => Failure::other(e),
        e => Failure::input(e),
    })?;
    let meshed = started.elapsed();
    // Only `.vtu` files hold each element's quality (single precision, 12 bytes a
    // tetrahedron); for the other formats the report is summed stretch by stretch, never
    // holding them all.
    let (qualities, report) = if format == TetFormat::Vtu {
        let (columns, report) = mesh.quality_columns();
        (Some(columns), Some(report))
    } else {
        (None, (!quiet).then(|| mesh.quality_report()))
    };
    let measured = started.elapsed();
    // The check (all cores) runs while the file is written (mostly the disk's time).
    let (write, check) = rayon::join(
        || {
            let result = write_tet_mesh_as(&args.output, format, &mesh, qualities.as_ref());
            (result, started.elapsed())
        },
        || {
            let check_started = Instant::now();
            (!args.no_check && !quiet).then(|| (mesh.check(), check_started.elapsed()))
        },
    );
    let (result, written) = write;
    result.map_err(|e| crate::io_failure(e, false))?;
    drop(qualities);
    let Some(report) = report.filter(|_| !quiet) else {
        return Ok(());
    };
    let s = &mesh.stats;
    eprintln!(
        "{}: {} tetrahedra, {} vertices ({} on the surface, {} grid points, {} inside cut cells); \
         boundary {} surface + {} wall triangles",
        args.output.display(),
        mesh.tets.len(),
        mesh.positions.len(),
        mesh.surface_vertices,
        s.grid_points,
        s.steiner_points,
        mesh.surface.len(),
        mesh.walls.len()
    );
    if s.cells_too_long {
        eprintln!(
            "graded: no, the cells are longer than {}:1 (where the transition cubes' elements \
             would leave [10°, 165°]): every inside cell six tetrahedra",
            Grading::MAX_ASPECT
        );
    }
    if s.cubes > 0 {
        eprintln!(
            "graded: {} cubes of 2 to {} cells on a side hold {} of the tetrahedra ({:.1} %); \
             single cells (those the surface passes through, and whole ones beside them) hold \
             the rest",
            s.cubes,
            s.largest_cube,
            s.cube_tets,
            100.0 * s.cube_tets as f64 / mesh.tets.len().max(1) as f64
        );
    }
    if let Some(labels) = &mesh.labels {
        let mut counts = vec![0usize; labels.names.len()];
        for &l in &labels.tets {
            counts[l as usize] += 1;
        }
        let each: Vec<String> = labels
            .names
            .iter()
            .zip(&counts)
            .map(|(name, count)| format!("label {name}: {count}"))
            .collect();
        eprintln!(
            "regions: {}; {} interface triangles",
            each.join(", "),
            labels.interfaces.len()
        );
    }
    if s.grouped_cells > 0 {
        eprintln!(
            "grouped: {} cut cells filled together with a neighbour (their surface passes \
             through a face bent by corners snapped onto crossings)",
            s.grouped_cells
        );
    }
    let improve = &s.improve;
    if improve.poor > 0 {
        eprintln!(
            "improved: {} elements under 12° (or over 162°) worked on{}: {} + {} flips, {} edges \
             removed, {} points moved, {} added, {} taken out",
            improve.poor,
            if improve.widened > 0 {
                format!(
                    ", then {} around those left outside [10°, 165°] under 18° (or over 153°)",
                    improve.widened
                )
            } else {
                String::new()
            },
            improve.flips_23,
            improve.flips_32,
            improve.edge_removals,
            improve.moves,
            improve.inserted,
            improve.removed + improve.removed_grid
        );
    }
    eprintln!(
        "quality: dihedral angles {:.2}°..{:.2}°, radius ratio mean {:.3}, worst {:.3}",
        report.min_dihedral, report.max_dihedral, report.mean_radius_ratio, report.max_radius_ratio
    );
    if report.min_dihedral < 10.0 {
        if let Some(sharpest) = mesh.sharpest_boundary_edge() {
            eprintln!(
                "{}",
                crate::commands::quality::sharpest_line(&mesh, &sharpest)
            );
        }
    }
    if report.min_dihedral < 10.0 || report.max_dihedral > 165.0 {
        eprintln!(
            "{}",
            crate::commands::quality::poor_line(
                &mesh,
                &mesh.poor_elements(cell, detail),
                cell,
                detail
            )
        );
    }
    if let Some((c, _)) = &check {
        eprintln!(
            "check: {}, {} inverted, {} flat{}, volume {:.6e} (the boundary encloses {:.6e})",
            if c.conforming {
                "conforming".to_string()
            } else {
                format!(
                    "NOT conforming ({} bad faces, {} boundary mismatches)",
                    c.bad_faces, c.boundary_mismatch
                )
            },
            c.inverted,
            c.flat,
            if c.unused > 0 {
                format!(", {} points in no element", c.unused)
            } else {
                String::new()
            },
            c.volume,
            c.enclosed
        );
    }
    let ms = |d: std::time::Duration| d.as_secs_f64() * 1e3;
    let checked = check.map_or(String::new(), |(_, took)| {
        format!(", checked {:.1} ms (while writing)", ms(took))
    });
    eprintln!(
        "read {:.1} ms, meshed {:.1} ms, qualities {:.1} ms, written {:.1} ms{checked}",
        ms(loaded),
        ms(meshed - loaded),
        ms(measured - meshed),
        ms(written - measured),
    );
    Ok(())
}
