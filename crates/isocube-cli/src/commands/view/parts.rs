//! What `isocube view` shows other than one volume's level set: the labels of a segmentation,
//! a mesh file, a cage and its Catmull–Clark surface, the surfaces of a contour stack (or of an
//! RT Structure Set's regions) with the contours drawn over them. Each is a list of parts, each
//! part one surface the page colours and toggles on its own; downloads are the files the
//! command that makes the part writes (`extract --labels`, `subdivide`, `contours`).

use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

use isocube::contours::{reconstruct_with, SectionStack};
use isocube::extract::{extract_labels, LabelSelection};
use isocube::mesh::Mesh;
use isocube::quality::Strategy;
use isocube::subdiv::{samples, subdivide, PolyMesh, SubdivOptions};
use isocube_io::{read_mesh, read_poly_mesh, MeshFormat};

use super::Made;
use crate::commands::contours::{is_stack, load_stack, reconstruct_options, StackArgs};
use crate::Failure;

/// The most subdivision levels the page offers (each multiplies the faces by four).
pub(super) const MAX_LEVELS: usize = 6;
/// The most faces of a subdivided cage the page draws (isocube subdivide goes to 2^28).
const MAX_FACES: usize = 1 << 23;

/// What kind of input the parts come from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Kind {
    Labels,
    Mesh,
    Cage,
    Contours,
}

impl Kind {
    pub(super) fn name(self) -> &'static str {
        match self {
            Kind::Labels => "labels",
            Kind::Mesh => "mesh",
            Kind::Cage => "cage",
            Kind::Contours => "contours",
        }
    }
}

/// One surface of the scene.
pub(super) struct Part {
    /// What the page calls it: `label 3 'liver'`, the ROI's name, the file's name.
    pub name: String,
    /// The label or ROI number, for a download's file name.
    pub number: Option<i64>,
    /// The mesh as the command that makes it writes it, and how long it took.
    pub made: Arc<Made>,
}

/// A scene of parts.
pub(super) struct Parts {
    pub kind: Kind,
    pub parts: Vec<Part>,
    /// Segments drawn over the surfaces (pairs of points): a stack's contours, a cage's edges.
    pub lines: Vec<[f32; 3]>,
    /// A cage, to subdivide again when the page asks for other levels.
    pub cage: Option<PolyMesh>,
    /// The cage's current subdivision (levels, the refined polygons).
    pub refined: Option<(usize, PolyMesh)>,
    /// What was read but is not shown (an RT Structure Set's POINT regions, …).
    pub notes: Vec<String>,
}

/// Whether `input` names a cage sample of `isocube subdivide`.
fn cage_sample(input: &str) -> Option<PolyMesh> {
    samples::sample(input.strip_prefix("sample:")?)
}

/// Loads what `input` is when it is not a volume to take level sets of; `None` for a volume.
pub(super) fn load(
    args: &super::Args,
    max_memory: Option<u64>,
    quiet: bool,
) -> Result<Option<Parts>, Failure> {
    let input = args.volume.volume.as_str();
    let (levels, stack) = (args.levels, &args.stack);
    if let Some(selection) = &args.label.labels {
        return labelled(args, selection).map(Some);
    }
    if let Some(cage) = cage_sample(input) {
        return with_cage(cage, levels).map(Some);
    }
    if is_stack(input) {
        let read = load_stack(input, Path::new(""), stack, quiet)?;
        let name = Path::new(input)
            .file_name()
            .and_then(|n| n.to_str())
            .unwrap_or(input);
        return stacks(vec![(name.to_string(), None, read)], stack, max_memory).map(Some);
    }
    let path = Path::new(input);
    if path.is_file() && isocube_io::is_dicom_file(path) {
        // An RT Structure Set: its regions' contour stacks. Any other DICOM file is a volume.
        if let Ok(rois) = isocube_io::read_rt_structure_set(path) {
            let mut notes = Vec::new();
            let mut found = Vec::new();
            for roi in rois {
                match (roi.stack, roi.problem) {
                    (_, Some(problem)) => notes.push(format!("refused: {problem}")),
                    (Some(s), None) => found.push((roi.name.clone(), Some(roi.number), s)),
                    (None, None) => notes.push(format!(
                        "{} '{}': no CLOSED_PLANAR contours",
                        roi.number, roi.name
                    )),
                }
            }
            let mut parts = stacks(found, stack, max_memory)?;
            parts.notes = notes;
            return Ok(Some(parts));
        }
    }
    match MeshFormat::from_path(path) {
        Some(MeshFormat::Obj) => {
            let poly = read_poly_mesh(path).map_err(|e| crate::io_failure(e, true))?;
            // Polygons or subdivision tags make a cage; triangles alone are a mesh.
            let cage = poly
                .faces
                .iter()
                .any(|f| f.outer.len() != 3 || !f.inner.is_empty())
                || !poly.creases.is_empty()
                || !poly.corners.is_empty()
                || poly.holes.contains(&true)
                || poly.boundary.is_some();
            if cage {
                return with_cage(poly, levels).map(Some);
            }
            let mesh = read_mesh(path).map_err(|e| crate::io_failure(e, true))?;
            Ok(Some(one_mesh(input, mesh)))
        }
        Some(_) => {
            let mesh = read_mesh(path).map_err(|e| crate::io_failure(e, true))?;
            Ok(Some(one_mesh(input, mesh)))
        }
        None => Ok(None),
    }
}

fn one_mesh(input: &str, mesh: Mesh) -> Parts {
    let name = Path::new(input)
        .file_name()
        .and_then(|n| n.to_str())
        .unwrap_or(input)
        .to_string();
    Parts {
        kind: Kind::Mesh,
        parts: vec![Part {
            name,
            number: None,
            made: Arc::new(Made { mesh, millis: 0.0 }),
        }],
        lines: Vec::new(),
        cage: None,
        refined: None,
        notes: Vec::new(),
    }
}

/// Every label's closed surface, as `isocube extract --labels` makes them.
fn labelled(args: &super::Args, selection: &LabelSelection) -> Result<Parts, Failure> {
    let volume = &args.volume;
    let (grid, orientation) = crate::volume::in_frame(args.index_space, volume.load_oriented()?)?;
    let view = grid.view().with_orientation(orientation);
    let options = args.label.options(selection);
    let started = Instant::now();
    let surfaces = extract_labels(view, &options).map_err(Failure::input)?;
    let millis = started.elapsed().as_secs_f64() * 1e3;
    if surfaces.is_empty() {
        return Err(Failure::input(anyhow::anyhow!(
            "{}: no label to show (background {})",
            volume.volume,
            args.label.background
        )));
    }
    // A DICOM segmentation names its segments.
    let path = Path::new(&volume.volume);
    let names = if path.is_file() && isocube_io::is_dicom_file(path) {
        isocube_io::read_dicom_segments(path).unwrap_or_default()
    } else {
        Vec::new()
    };
    let parts = surfaces
        .into_iter()
        .map(|s| {
            let name = names.iter().find(|(n, _)| *n == s.label).map_or_else(
                || format!("label {}", s.label),
                |(_, n)| format!("{} {n}", s.label),
            );
            Part {
                name,
                number: Some(s.label),
                made: Arc::new(Made {
                    mesh: s.mesh,
                    millis,
                }),
            }
        })
        .collect();
    Ok(Parts {
        kind: Kind::Labels,
        parts,
        lines: Vec::new(),
        cage: None,
        refined: None,
        notes: Vec::new(),
    })
}

/// A cage: its edges as lines, its surface after `levels` subdivisions as the part.
fn with_cage(cage: PolyMesh, levels: usize) -> Result<Parts, Failure> {
    cage.validate()
        .map_err(|e| Failure::input(anyhow::anyhow!("the cage: {e}")))?;
    let rings = || {
        cage.faces
            .iter()
            .enumerate()
            .filter(|(f, _)| !cage.is_hole(*f))
            .flat_map(|(_, face)| std::iter::once(&face.outer).chain(&face.inner))
    };
    let walked: std::collections::HashSet<(u32, u32)> = rings()
        .flat_map(|ring| (0..ring.len()).map(|i| (ring[i], ring[(i + 1) % ring.len()])))
        .collect();
    let at = |v: u32| cage.positions[v as usize].map(|c| c as f32);
    let mut lines = Vec::new();
    for ring in rings() {
        for (i, &a) in ring.iter().enumerate() {
            let b = ring[(i + 1) % ring.len()];
            // An edge two faces share, once.
            if a < b || !walked.contains(&(b, a)) {
                lines.push(at(a));
                lines.push(at(b));
            }
        }
    }
    let mut parts = Parts {
        kind: Kind::Cage,
        parts: Vec::new(),
        lines,
        cage: Some(cage),
        refined: None,
        notes: Vec::new(),
    };
    parts
        .subdivide(levels)
        .map_err(|e| Failure::input(anyhow::anyhow!("--levels {e}")))?;
    Ok(parts)
}

/// Each stack's surface, as `isocube contours` makes it, and every contour as lines.
fn stacks(
    found: Vec<(String, Option<i64>, SectionStack)>,
    args: &StackArgs,
    max_memory: Option<u64>,
) -> Result<Parts, Failure> {
    let mut parts = Vec::new();
    let mut lines = Vec::new();
    for (name, number, stack) in found {
        let options = reconstruct_options(args.cap(&stack)?, false, Strategy::Local, max_memory);
        let plane = args.plane(&stack)?;
        let started = Instant::now();
        let r = reconstruct_with(&stack, &plane, &options)
            .map_err(|e| Failure::input(anyhow::anyhow!("{name}: {e}")))?;
        for section in stack.sections() {
            let z = section.z() as f32;
            for contour in section.contours() {
                for (a, b) in contour.segments() {
                    lines.push([a[0] as f32, a[1] as f32, z]);
                    lines.push([b[0] as f32, b[1] as f32, z]);
                }
            }
        }
        parts.push(Part {
            name,
            number,
            made: Arc::new(Made {
                mesh: r.mesh,
                millis: started.elapsed().as_secs_f64() * 1e3,
            }),
        });
    }
    if parts.is_empty() {
        return Err(Failure::input(anyhow::anyhow!(
            "no region with CLOSED_PLANAR contours to show"
        )));
    }
    Ok(Parts {
        kind: Kind::Contours,
        parts,
        lines,
        cage: None,
        refined: None,
        notes: Vec::new(),
    })
}

impl Parts {
    /// The cage subdivided `levels` times (as `isocube subdivide --levels N`), as part 0.
    pub(super) fn subdivide(&mut self, levels: usize) -> Result<(), String> {
        let Some(cage) = &self.cage else {
            return Ok(());
        };
        if self.refined.as_ref().is_some_and(|(l, _)| *l == levels) {
            return Ok(());
        }
        // Each level makes a face per corner of the faces before it.
        let corners: usize = cage.faces.iter().map(|f| f.outer.len()).sum();
        let faces = (corners as f64) * 4f64.powi(levels.max(1) as i32 - 1);
        if levels > MAX_LEVELS || faces > MAX_FACES as f64 {
            return Err(format!(
                "{levels}: about {faces:.0} faces; the page shows at most {MAX_LEVELS} levels and \
                 {MAX_FACES} faces"
            ));
        }
        let started = Instant::now();
        let fine = subdivide(cage, levels, &SubdivOptions::default())
            .map_err(|e| format!("{levels} levels: {e}"))?;
        let mesh = fine
            .triangulate()
            .map_err(|e| format!("{levels} levels: {e}"))?;
        let part = Part {
            name: "Catmull–Clark surface".into(),
            number: Some(levels as i64),
            made: Arc::new(Made {
                mesh,
                millis: started.elapsed().as_secs_f64() * 1e3,
            }),
        };
        self.parts = vec![part];
        self.refined = Some((levels, fine));
        Ok(())
    }
}
