//! DICOM images as volumes: a folder holding a series of single-frame slices (CT, MR), a
//! multi-frame file (enhanced CT/MR with per-frame functional groups, classic multi-frame, RT
//! Dose with its Grid Frame Offset Vector), or a folder of multi-frame files of one series.
//!
//! Each file's data elements are walked by isocube itself ([`elements`]): implicit and explicit
//! VR little endian, explicit VR big endian, deflated, and encapsulated pixel data (RLE, JPEG
//! baseline/extended/lossless, JPEG-LS, JPEG 2000, decoded frame by frame in [`pixels`]).
//! Every length is checked against what the file holds before anything is taken from it.
//!
//! Planes (slices or frames) are sorted by their position along the normal of their
//! orientation; the slice spacing comes from the positions (and must be even), the in-plane
//! spacing from Pixel Spacing, the axes from Image Orientation (Patient), the origin from the
//! first plane's Image Position (Patient): patient coordinates, LPS. Stored values are masked
//! to Bits Stored, sign-extended when signed, and go through Rescale Slope and Intercept (per
//! frame in enhanced files) and Dose Grid Scaling (RT Dose: values in Gy).

mod dct;
mod elements;
mod pixels;
mod rtstruct;

pub use rtstruct::{read_rt_structure_set, read_rt_structure_set_bytes, RtRoi};

use std::path::{Path, PathBuf};

use super::{Budget, IoError, Pick, Position};
use elements::{find, DataSet, Node};
use isocube::field::{Grid, Orientation};
use isocube::mesh::{cross, dot, sub};
use pixels::PixelFormat;

/// One plane of a volume: a slice, or a frame of a multi-frame file.
struct Plane {
    /// The file it comes from, and its frame there (1-based, for messages).
    path: PathBuf,
    frame: usize,
    /// Image Position (Patient); `None` when the file gives none.
    position: Option<[f64; 3]>,
    values: Vec<f32>,
}

/// What every plane of a volume must share.
struct Layout {
    path: PathBuf,
    series: String,
    row: [f64; 3],
    column: [f64; 3],
    /// Pixel Spacing: between rows, between columns.
    pixel: [f64; 2],
    /// Rows, columns.
    size: (usize, usize),
    /// A segmentation (DICOM SEG): the spacing its frames sit at, when given (frames holding
    /// nothing are left out of SEG files).
    segmentation: Option<SegmentSpacing>,
}

/// The Spacing Between Slices of a segmentation's frames, when the file gives it.
struct SegmentSpacing(Option<f64>);

/// Reads a DICOM series (a folder; files that are not DICOM images are skipped) or one DICOM
/// file, single- or multi-frame, as one volume.
pub fn read_dicom_series(path: &Path) -> Result<(Grid, Orientation), IoError> {
    read_dicom_within(path, Budget::UNLIMITED, Pick::default())
}

pub(super) fn read_dicom_within(
    path: &Path,
    budget: Budget,
    pick: Pick,
) -> Result<(Grid, Orientation), IoError> {
    let files = if path.is_dir() {
        let entries = std::fs::read_dir(path).map_err(|e| IoError::os(path, e))?;
        let mut files: Vec<PathBuf> = Vec::new();
        for entry in entries {
            let file = entry.map_err(|e| IoError::os(path, e))?.path();
            if file.is_file() && super::has_dicom_marker(&file) {
                files.push(file);
            }
        }
        files.sort();
        files
    } else {
        vec![path.to_path_buf()]
    };
    // Files are parsed one by one, each data set kept (compressed pixel data stays compressed)
    // and its decoded values counted against the budget before any is decoded; then the
    // files' frames are decoded in parallel, the slow part of compressed series.
    let mut sets = Vec::new();
    let mut held = 0u64;
    for file in files {
        let len = std::fs::metadata(&file)
            .map_err(|e| IoError::os(&file, e))?
            .len();
        budget.check(&file, Position::File, held.saturating_add(2 * len))?;
        let bytes = super::read_file(&file)?;
        let set = elements::parse(&file, &bytes, budget.limit().saturating_sub(held))?;
        drop(bytes);
        // In a folder, files without pixel data (structure sets, plans, reports) are not
        // planes of the volume.
        if path.is_dir() && find(&set.nodes, PIXEL_DATA).is_none() {
            continue;
        }
        held = held
            .saturating_add(set.data.len() as u64)
            .saturating_add(4 * planned_values(&file, &set)?);
        budget.check(&file, Position::Field("Rows".into()), held)?;
        sets.push((file, set));
    }
    let images = {
        use rayon::prelude::*;
        sets.par_iter()
            .map(|(file, set)| read_image(file, set, Budget::UNLIMITED, 0))
            .collect::<Result<Vec<_>, IoError>>()?
    };
    drop(sets);
    let mut planes = Vec::new();
    let mut layouts: Vec<Layout> = Vec::new();
    for (layout, mut more) in images {
        planes.append(&mut more);
        layouts.push(layout);
    }
    finish(path, layouts, planes, budget, held, pick)
}

/// The segments of a DICOM SEG file (its Segment Number and Segment Label each), which
/// [`read_dicom_series`] reads as a labelled volume (each voxel its segment's number, 0
/// outside); empty for any other DICOM image.
///
/// ```no_run
/// let path = std::path::Path::new("liver.dcm");
/// for (number, label) in isocube_io::read_dicom_segments(path)? {
///     println!("label {number}: {label}");
/// }
/// # Ok::<(), isocube_io::IoError>(())
/// ```
pub fn read_dicom_segments(path: &Path) -> Result<Vec<(i64, String)>, IoError> {
    let bytes = super::read_file(path)?;
    let set = elements::parse(path, &bytes, 64 * bytes.len() as u64 + (1 << 20))?;
    let v = Values { path, set: &set };
    Ok(segmentation(&v, &set.nodes)?.map_or_else(Vec::new, |s| s.names))
}

/// [`read_dicom_series`] of one file's content in memory; `name` names it in errors.
pub(super) fn read_dicom_bytes(
    name: &Path,
    bytes: &[u8],
    budget: Budget,
    pick: Pick,
) -> Result<(Grid, Orientation), IoError> {
    budget.check(name, Position::File, 2 * bytes.len() as u64)?;
    let set = elements::parse(name, bytes, budget.limit())?;
    let (layout, planes) = read_image(name, &set, budget, bytes.len() as u64)?;
    finish(name, vec![layout], planes, budget, bytes.len() as u64, pick)
}

/// Checks that the files agree and assembles their planes.
fn finish(
    path: &Path,
    layouts: Vec<Layout>,
    planes: Vec<Plane>,
    budget: Budget,
    held: u64,
    pick: Pick,
) -> Result<(Grid, Orientation), IoError> {
    let Some(first) = layouts.first() else {
        return Err(IoError::format(
            path,
            Position::File,
            "no DICOM images (files with the DICM marker and pixel data) in the folder",
        ));
    };
    for l in &layouts {
        let differs = |a: &[f64], b: &[f64]| a.iter().zip(b).any(|(x, y)| (x - y).abs() > 1e-4);
        let problem = if l.series != first.series {
            Some((
                "SeriesInstanceUID",
                format!(
                    "series {} beside {}: give a folder with one series",
                    l.series, first.series
                ),
            ))
        } else if l.size != first.size {
            Some((
                "Rows",
                format!("{:?} pixels, the first file has {:?}", l.size, first.size),
            ))
        } else if differs(&l.row, &first.row) || differs(&l.column, &first.column) {
            Some((
                "ImageOrientationPatient",
                "differs from the first file's".to_string(),
            ))
        } else if differs(&l.pixel, &first.pixel) {
            Some(("PixelSpacing", "differs from the first file's".to_string()))
        } else {
            None
        };
        if let Some((field, reason)) = problem {
            return Err(IoError::format(
                &l.path,
                Position::Field(field.into()),
                reason,
            ));
        }
    }
    let planes = match &first.segmentation {
        Some(SegmentSpacing(step)) => merge_segment_planes(path, first, planes, *step)?,
        None => planes,
    };
    assemble(path, first, planes, budget, held, pick)
}

/// A segmentation's frames as planes of one labelled volume: frames at the same position (one
/// per segment) merged, the larger segment number where segments overlap, and planes holding
/// no segment (which SEG files leave out) put back as zeros at the frames' spacing — Spacing
/// Between Slices when given, else the smallest gap between frames.
fn merge_segment_planes(
    path: &Path,
    first: &Layout,
    planes: Vec<Plane>,
    step: Option<f64>,
) -> Result<Vec<Plane>, IoError> {
    let normal = cross(first.row, first.column);
    let Some(p0) = planes.first() else {
        return Ok(planes);
    };
    if let Some(p) = planes.iter().find(|p| p.position.is_none()) {
        return Err(IoError::format(
            &p.path,
            Position::Field(format!("ImagePositionPatient (frame {})", p.frame)),
            "missing: the frames of a segmentation cannot be placed without it",
        ));
    }
    let origin = p0.position.unwrap_or([0.0; 3]);
    let along = |p: &Plane| dot(sub(p.position.unwrap_or(origin), origin), normal);
    let mut at: Vec<f64> = planes.iter().map(along).collect();
    let low = at.iter().copied().fold(f64::INFINITY, f64::min);
    at.iter_mut().for_each(|a| *a -= low);
    let mut distinct = at.clone();
    distinct.sort_by(f64::total_cmp);
    distinct.dedup_by(|a, b| (*a - *b).abs() < 1e-4);
    let step = step.filter(|s| *s > 0.0).or_else(|| {
        distinct
            .windows(2)
            .map(|w| w[1] - w[0])
            .fold(None, |m: Option<f64>, g| Some(m.map_or(g, |m| m.min(g))))
    });
    let Some(step) = step else {
        return Ok(planes);
    };
    let span = (distinct.last().copied().unwrap_or(0.0) / step).round();
    // Checked as a float: a tiny spacing makes the span too large for any integer.
    if span.is_nan() || span >= f64::from(1u32 << 16) {
        return Err(IoError::format(
            path,
            Position::Field("SpacingBetweenSlices".into()),
            format!("{step}: the frames would span {span} planes"),
        ));
    }
    let count = span as usize + 1;
    let n = first.size.0 * first.size.1;
    let mut merged: Vec<Option<Plane>> = (0..count).map(|_| None).collect();
    let base = planes
        .iter()
        .zip(&at)
        .find(|(_, a)| **a == 0.0)
        .and_then(|(p, _)| p.position)
        .unwrap_or(origin);
    for (plane, a) in planes.into_iter().zip(at) {
        let slot = a / step;
        if (slot - slot.round()).abs() > 1e-3 {
            return Err(IoError::format(
                &plane.path,
                Position::Field(format!("ImagePositionPatient (frame {})", plane.frame)),
                format!("{a:.4} along the normal from the first frame: not a multiple of the frames' spacing {step:.4}"),
            ));
        }
        let slot = slot.round() as usize;
        match &mut merged[slot] {
            Some(m) => m
                .values
                .iter_mut()
                .zip(&plane.values)
                .for_each(|(v, w)| *v = v.max(*w)),
            empty => *empty = Some(plane),
        }
    }
    Ok(merged
        .into_iter()
        .enumerate()
        .map(|(k, m)| {
            m.unwrap_or_else(|| Plane {
                path: path.to_path_buf(),
                frame: 0,
                position: Some(std::array::from_fn(|i| {
                    base[i] + k as f64 * step * normal[i]
                })),
                values: vec![0.0; n],
            })
        })
        .collect())
}

/// Sorts the planes along the normal and makes the grid: x along a row, y down the columns, z
/// along the sorted planes.
fn assemble(
    path: &Path,
    first: &Layout,
    mut planes: Vec<Plane>,
    budget: Budget,
    held: u64,
    pick: Pick,
) -> Result<(Grid, Orientation), IoError> {
    let at = |p: &Plane, field: &str| {
        let frame = if p.frame > 0 {
            format!(" (frame {})", p.frame)
        } else {
            String::new()
        };
        (p.path.clone(), Position::Field(format!("{field}{frame}")))
    };
    if planes.len() > 1 {
        if let Some(p) = planes.iter().find(|p| p.position.is_none()) {
            let (path, pos) = at(p, "ImagePositionPatient");
            return Err(IoError::format(
                &path,
                pos,
                "missing: the planes of a series cannot be ordered without it",
            ));
        }
    }
    let normal = cross(first.row, first.column);
    let position = |p: &Plane| p.position.unwrap_or([0.0; 3]);
    let along = |p: &Plane| dot(position(p), normal);
    // A stable sort: planes at one position keep the order they were read in (files by name,
    // frames by number), which is their order in time.
    planes.sort_by(|a, b| along(a).total_cmp(&along(b)));
    // Several planes at every position: a series over time (cine, 4-D CT); one of them is
    // meshed, the one `pick.frame` says.
    let repeats = planes
        .iter()
        .take_while(|p| (along(p) - along(&planes[0])).abs() <= 1e-4)
        .count();
    if repeats > 1 && planes.len() % repeats == 0 {
        let groups_even = planes
            .chunks(repeats)
            .all(|g| g.iter().all(|p| (along(p) - along(&g[0])).abs() <= 1e-4))
            && planes
                .chunks(repeats)
                .collect::<Vec<_>>()
                .windows(2)
                .all(|w| along(&w[1][0]) - along(&w[0][0]) > 1e-4);
        if groups_even {
            let t = Pick::index(
                path,
                Position::Field("ImagePositionPatient".into()),
                pick.frame,
                repeats,
                "--frame",
                "frames at every slice position (a series over time)",
            )?;
            planes = planes
                .into_iter()
                .enumerate()
                .filter(|(i, _)| i % repeats == t)
                .map(|(_, p)| p)
                .collect();
        }
    }
    let (nx, ny, nz) = (first.size.1, first.size.0, planes.len());
    let step = if nz > 1 {
        along(&planes[1]) - along(&planes[0])
    } else {
        1.0
    };
    for w in planes.windows(2) {
        let gap = along(&w[1]) - along(&w[0]);
        if gap <= 1e-6 || (gap - step).abs() > 1e-3 * step.abs().max(1e-3) {
            let (path, pos) = at(&w[1], "ImagePositionPatient");
            return Err(IoError::format(
                &path,
                pos,
                format!("planes {gap:.4} apart where the first two are {step:.4}: uneven or repeated slices"),
            ));
        }
    }
    if nz == 1 {
        return Err(IoError::format(
            path,
            Position::File,
            format!(
                "one plane of {nx}×{ny} pixels: a volume needs two or more (give the folder \
                 holding the series' slices, or a multi-frame file)"
            ),
        ));
    }
    let count = Grid::point_count([nx, ny, nz]).map_err(|e| IoError::grid(path, e))?;
    budget.check_values(path, Position::Field("Rows".into()), held, count)?;
    let origin = position(&planes[0]);
    let slice_dir = {
        let d = sub(position(&planes[nz - 1]), origin);
        let len = dot(d, d).sqrt();
        if nz > 1 && len > 0.0 {
            d.map(|c| c / len)
        } else {
            normal
        }
    };
    let mut values = Vec::with_capacity(count);
    for p in planes {
        values.extend_from_slice(&p.values);
    }
    let axes = [first.row, first.column, slice_dir];
    let scale = [first.pixel[1], first.pixel[0], step];
    let linear: [[f64; 3]; 3] =
        std::array::from_fn(|r| std::array::from_fn(|c| axes[c][r] * scale[c]));
    let (spacing, orientation) = Orientation::from_linear(linear).ok_or_else(|| {
        IoError::format(
            &first.path,
            Position::Field("ImageOrientationPatient".into()),
            "the image axes are degenerate",
        )
    })?;
    let grid = Grid::new([nx, ny, nz], values)
        .and_then(|g| g.with_spacing(spacing))
        .and_then(|g| g.with_origin(origin))
        .map_err(|e| IoError::grid(path, e))?;
    Ok((grid, orientation))
}

const PIXEL_DATA: (u16, u16) = (0x7FE0, 0x0010);
const SHARED_GROUPS: (u16, u16) = (0x5200, 0x9229);
const PER_FRAME_GROUPS: (u16, u16) = (0x5200, 0x9230);
const PLANE_POSITION: (u16, u16) = (0x0020, 0x9113);
const PLANE_ORIENTATION: (u16, u16) = (0x0020, 0x9116);
const PIXEL_MEASURES: (u16, u16) = (0x0028, 0x9110);
const VALUE_TRANSFORMATION: (u16, u16) = (0x0028, 0x9145);
const POSITION: (u16, u16) = (0x0020, 0x0032);
const ORIENTATION: (u16, u16) = (0x0020, 0x0037);
const PIXEL_SPACING: (u16, u16) = (0x0028, 0x0030);
const SLICE_THICKNESS: (u16, u16) = (0x0018, 0x0050);
const SPACING_BETWEEN_SLICES: (u16, u16) = (0x0018, 0x0088);
const SLOPE: (u16, u16) = (0x0028, 0x1053);
const INTERCEPT: (u16, u16) = (0x0028, 0x1052);
const GRID_FRAME_OFFSETS: (u16, u16) = (0x3004, 0x000C);
const DOSE_GRID_SCALING: (u16, u16) = (0x3004, 0x000E);

/// Reads values of a data set's elements, naming the file and element in errors.
struct Values<'a> {
    path: &'a Path,
    set: &'a DataSet,
}

impl Values<'_> {
    fn field(name: &str) -> Position {
        Position::Field(name.into())
    }

    fn text(&self, node: &Node) -> String {
        String::from_utf8_lossy(&self.set.data[node.value.clone()])
            .trim_end_matches(['\0', ' '])
            .trim()
            .to_string()
    }

    /// Decimal or integer strings (DS, IS), `\`-separated.
    fn numbers(&self, node: &Node, name: &str) -> Result<Vec<f64>, IoError> {
        let t = self.text(node);
        if t.is_empty() {
            return Ok(Vec::new());
        }
        t.split('\\')
            .map(|w| {
                w.trim_matches(['\0', ' '])
                    .parse::<f64>()
                    .ok()
                    .filter(|x| x.is_finite())
            })
            .collect::<Option<Vec<_>>>()
            .ok_or_else(|| {
                IoError::format(
                    self.path,
                    Self::field(name),
                    format!("'{t}' is not a list of finite numbers"),
                )
            })
    }

    /// Exactly `n` numbers.
    fn floats(&self, node: &Node, name: &str, n: usize) -> Result<Vec<f64>, IoError> {
        let v = self.numbers(node, name)?;
        if v.len() != n {
            return Err(IoError::format(
                self.path,
                Self::field(name),
                format!("{v:?} is not {n} numbers"),
            ));
        }
        Ok(v)
    }

    /// A binary integer (US, UL, SS, SL) or an integer string.
    fn int(&self, node: &Node, name: &str) -> Result<i64, IoError> {
        let v = &self.set.data[node.value.clone()];
        let enc = self.set.encoding;
        Ok(match (&node.vr, v.len()) {
            (b"US", 2..) => i64::from(enc.u16(v)),
            (b"SS", 2..) => i64::from(enc.u16(v) as i16),
            (b"UL", 4..) => i64::from(enc.u32(v)),
            (b"SL", 4..) => i64::from(enc.u32(v) as i32),
            _ => self.text(node).parse::<i64>().map_err(|_| {
                IoError::format(
                    self.path,
                    Self::field(name),
                    format!("'{}' is not a whole number", self.text(node)),
                )
            })?,
        })
    }

    /// A required non-negative integer.
    fn count(&self, nodes: &[Node], tag: (u16, u16), name: &str) -> Result<usize, IoError> {
        let node = find(nodes, tag)
            .ok_or_else(|| IoError::format(self.path, Self::field(name), "missing"))?;
        let x = self.int(node, name)?;
        usize::try_from(x)
            .map_err(|_| IoError::format(self.path, Self::field(name), format!("{x} is negative")))
    }

    /// The first number of an optional element.
    fn optional(&self, node: Option<&Node>) -> Option<f64> {
        node.and_then(|n| self.text(n).split('\\').next()?.trim().parse::<f64>().ok())
            .filter(|x| x.is_finite())
    }
}

/// The element `tag` for frame `k`: in the frame's item of the per-frame functional groups, or
/// in the shared ones, inside the functional group sequence `group`.
fn in_groups<'a>(
    nodes: &'a [Node],
    k: usize,
    group: (u16, u16),
    tag: (u16, u16),
) -> Option<&'a Node> {
    let inside =
        |item: &'a [Node]| -> Option<&'a Node> { find(find(item, group)?.items.first()?, tag) };
    let per_frame = find(nodes, PER_FRAME_GROUPS).and_then(|s| s.items.get(k));
    let shared = find(nodes, SHARED_GROUPS).and_then(|s| s.items.first());
    per_frame
        .and_then(|item| inside(item))
        .or_else(|| shared.and_then(|item| inside(item)))
}

const SEGMENTS: (u16, u16) = (0x0062, 0x0002);
const SEGMENTATION_TYPE: (u16, u16) = (0x0062, 0x0001);
const SEGMENT_NUMBER: (u16, u16) = (0x0062, 0x0004);
const SEGMENT_LABEL: (u16, u16) = (0x0062, 0x0005);
const SEGMENT_IDENTIFICATION: (u16, u16) = (0x0062, 0x000A);
const REFERENCED_SEGMENT: (u16, u16) = (0x0062, 0x000B);
const MAXIMUM_FRACTIONAL: (u16, u16) = (0x0062, 0x000E);

/// How a segmentation's frames hold its segments.
enum SegKind {
    /// One bit per pixel: in the frame's segment or not.
    Binary,
    /// A fraction up to this maximum; half or more counts as inside.
    Fractional(f64),
    /// The pixel's value is its segment number (one frame per plane).
    Labelmap,
}

struct Segmentation {
    kind: SegKind,
    names: Vec<(i64, String)>,
}

/// A DICOM SEG's type and segment labels, or `None` for other images.
fn segmentation(v: &Values, nodes: &[Node]) -> Result<Option<Segmentation>, IoError> {
    let Some(segments) = find(nodes, SEGMENTS) else {
        return Ok(None);
    };
    let field = |name: &str| Position::Field(name.into());
    let kind = match find(nodes, SEGMENTATION_TYPE).map(|n| v.text(n)).as_deref() {
        Some("BINARY") => SegKind::Binary,
        Some("FRACTIONAL") => SegKind::Fractional(
            v.optional(find(nodes, MAXIMUM_FRACTIONAL))
                .filter(|m| *m > 0.0)
                .ok_or_else(|| {
                    IoError::format(
                        v.path,
                        field("MaximumFractionalValue"),
                        "missing or not positive",
                    )
                })?,
        ),
        Some("LABELMAP") => SegKind::Labelmap,
        other => {
            return Err(IoError::unsupported(
                v.path,
                field("SegmentationType"),
                format!("{other:?}: isocube reads BINARY, FRACTIONAL and LABELMAP segmentations"),
            ))
        }
    };
    let mut names = Vec::new();
    for item in &segments.items {
        if let Some(n) = find(item, SEGMENT_NUMBER) {
            let label = find(item, SEGMENT_LABEL)
                .map(|l| v.text(l))
                .unwrap_or_default();
            names.push((v.int(n, "SegmentNumber")?, label));
        }
    }
    Ok(Some(Segmentation { kind, names }))
}

/// How many values a file's frames decode to (Rows × Columns × Number of Frames), for the
/// budget before decoding.
fn planned_values(path: &Path, set: &DataSet) -> Result<u64, IoError> {
    let v = Values { path, set };
    let nodes = &set.nodes[..];
    let count = |tag, name| -> Result<u64, IoError> {
        match find(nodes, tag) {
            Some(n) => Ok(v.int(n, name)?.max(1) as u64),
            None => Ok(1),
        }
    };
    Ok(count((0x0028, 0x0010), "Rows")?
        .saturating_mul(count((0x0028, 0x0011), "Columns")?)
        .saturating_mul(count((0x0028, 0x0008), "NumberOfFrames")?))
}

/// One file's layout and planes.
fn read_image(
    path: &Path,
    set: &DataSet,
    budget: Budget,
    held: u64,
) -> Result<(Layout, Vec<Plane>), IoError> {
    let v = Values { path, set };
    let nodes = &set.nodes[..];
    let field = |name: &str| Position::Field(name.into());
    let (rows, cols) = (
        v.count(nodes, (0x0028, 0x0010), "Rows")?,
        v.count(nodes, (0x0028, 0x0011), "Columns")?,
    );
    let bits = v.count(nodes, (0x0028, 0x0100), "BitsAllocated")?;
    if !matches!(bits, 1 | 8 | 16 | 32) {
        return Err(IoError::unsupported(
            path,
            field("BitsAllocated"),
            format!("{bits} bits"),
        ));
    }
    let stored = match find(nodes, (0x0028, 0x0101)) {
        Some(_) => v.count(nodes, (0x0028, 0x0101), "BitsStored")?,
        None => bits,
    };
    if stored == 0 || stored > bits {
        return Err(IoError::format(
            path,
            field("BitsStored"),
            format!("{stored} bits stored in {bits} allocated"),
        ));
    }
    if find(nodes, (0x0028, 0x0002)).is_some()
        && v.count(nodes, (0x0028, 0x0002), "SamplesPerPixel")? != 1
    {
        return Err(IoError::unsupported(
            path,
            field("SamplesPerPixel"),
            "colour images: isocube meshes one value per voxel",
        ));
    }
    let frames = match find(nodes, (0x0028, 0x0008)) {
        Some(_) => v.count(nodes, (0x0028, 0x0008), "NumberOfFrames")?.max(1),
        None => 1,
    };
    let signed = find(nodes, (0x0028, 0x0103))
        .map(|n| v.int(n, "PixelRepresentation"))
        .transpose()?
        == Some(1);
    let pixel = find(nodes, PIXEL_DATA)
        .ok_or_else(|| IoError::format(path, field("PixelData"), "missing"))?;
    let fmt = PixelFormat {
        rows,
        cols,
        bits_allocated: bits,
        bits_stored: stored,
        signed,
        frames,
    };
    let count = rows
        .checked_mul(cols)
        .and_then(|n| n.checked_mul(frames))
        .ok_or_else(|| IoError::format(path, field("Rows"), "the image size overflows"))?;
    budget.check_values(path, field("NumberOfFrames"), held, count)?;
    if let Some(per_frame) = find(nodes, PER_FRAME_GROUPS) {
        // More items than frames happens (files cut down to fewer frames); fewer cannot place
        // every frame.
        if per_frame.items.len() < frames {
            return Err(IoError::format(
                path,
                field("PerFrameFunctionalGroupsSequence"),
                format!("{} items for {frames} frames", per_frame.items.len()),
            ));
        }
    }

    // Geometry: top-level elements, or the functional groups of enhanced files.
    let element =
        |k: usize, group, tag| find(nodes, tag).or_else(|| in_groups(nodes, k, group, tag));
    let orientation = match element(0, PLANE_ORIENTATION, ORIENTATION) {
        Some(n) => v.floats(n, "ImageOrientationPatient", 6)?,
        None => vec![1.0, 0.0, 0.0, 0.0, 1.0, 0.0],
    };
    let pixel_spacing = match element(0, PIXEL_MEASURES, PIXEL_SPACING) {
        Some(n) => v.floats(n, "PixelSpacing", 2)?,
        None => vec![1.0, 1.0],
    };
    if pixel_spacing.iter().any(|&s| s <= 0.0) {
        return Err(IoError::format(
            path,
            field("PixelSpacing"),
            format!("{pixel_spacing:?}: spacings are positive"),
        ));
    }
    let row = [orientation[0], orientation[1], orientation[2]];
    let column = [orientation[3], orientation[4], orientation[5]];
    let normal = cross(row, column);
    for k in 1..frames {
        if let Some(n) = in_groups(nodes, k, PLANE_ORIENTATION, ORIENTATION) {
            let o = v.floats(n, "ImageOrientationPatient", 6)?;
            if o.iter()
                .zip(&orientation)
                .any(|(a, b)| (a - b).abs() > 1e-4)
            {
                return Err(IoError::format(
                    path,
                    field(&format!("ImageOrientationPatient (frame {})", k + 1)),
                    "differs from the first frame's",
                ));
            }
        }
    }
    let top_position = find(nodes, POSITION)
        .map(|n| v.floats(n, "ImagePositionPatient", 3))
        .transpose()?;
    let offsets = find(nodes, GRID_FRAME_OFFSETS)
        .map(|n| v.numbers(n, "GridFrameOffsetVector"))
        .transpose()?;
    if let Some(o) = &offsets {
        if frames > 1 && o.len() != frames {
            return Err(IoError::format(
                path,
                field("GridFrameOffsetVector"),
                format!("{} offsets for {frames} frames", o.len()),
            ));
        }
    }
    // Frames of a classic multi-frame file without per-frame positions follow each other
    // along the normal, this far apart.
    let between = v
        .optional(element(0, PIXEL_MEASURES, SPACING_BETWEEN_SLICES))
        .or_else(|| v.optional(element(0, PIXEL_MEASURES, SLICE_THICKNESS)))
        .filter(|&s| s > 0.0)
        .unwrap_or(1.0);
    let dose = v.optional(find(nodes, DOSE_GRID_SCALING)).unwrap_or(1.0);
    let segmentation = segmentation(&v, nodes)?;
    let mut planes = Vec::with_capacity(frames);
    for k in 0..frames {
        let position = match in_groups(nodes, k, PLANE_POSITION, POSITION) {
            Some(n) => Some(v.floats(n, "ImagePositionPatient", 3)?),
            None => top_position.clone(),
        };
        let mut position = position.map(|p| [p[0], p[1], p[2]]);
        let shift = match &offsets {
            // Offsets along the normal from the first frame (relative, first 0) or as z
            // coordinates (absolute): either way, from the first entry (PS3.3 C.8.8.3.2).
            Some(o) if frames > 1 => Some(o[k] - o[0]),
            _ if frames > 1 && in_groups(nodes, k, PLANE_POSITION, POSITION).is_none() => {
                Some(k as f64 * between)
            }
            _ => None,
        };
        if let Some(shift) = shift {
            let p = position.unwrap_or([0.0; 3]);
            position = Some(std::array::from_fn(|i| p[i] + shift * normal[i]));
        }
        let slope = v
            .optional(element(k, VALUE_TRANSFORMATION, SLOPE))
            .unwrap_or(1.0);
        let intercept = v
            .optional(element(k, VALUE_TRANSFORMATION, INTERCEPT))
            .unwrap_or(0.0);
        let raw = pixels::frame(path, set, pixel, &fmt, k)?;
        let values = match &segmentation {
            None => raw
                .into_iter()
                .map(|r| ((slope * r + intercept) * dose) as f32)
                .collect(),
            Some(seg) => {
                let segment = match seg.kind {
                    SegKind::Labelmap => 0.0,
                    _ => {
                        let n = in_groups(nodes, k, SEGMENT_IDENTIFICATION, REFERENCED_SEGMENT)
                            .ok_or_else(|| {
                                IoError::format(
                                    path,
                                    field(&format!("ReferencedSegmentNumber (frame {})", k + 1)),
                                    "missing: which segment the frame shows is unknown",
                                )
                            })?;
                        v.int(n, "ReferencedSegmentNumber")? as f32
                    }
                };
                raw.into_iter()
                    .map(|r| match seg.kind {
                        SegKind::Labelmap => r as f32,
                        SegKind::Binary if r > 0.0 => segment,
                        SegKind::Fractional(max) if 2.0 * r >= max && r > 0.0 => segment,
                        _ => 0.0,
                    })
                    .collect()
            }
        };
        planes.push(Plane {
            path: path.to_path_buf(),
            frame: if frames > 1 { k + 1 } else { 0 },
            position,
            values,
        });
    }
    let series = find(nodes, (0x0020, 0x000E))
        .map(|n| v.text(n))
        .unwrap_or_default();
    let layout = Layout {
        path: path.to_path_buf(),
        series,
        row,
        column,
        pixel: [pixel_spacing[0], pixel_spacing[1]],
        size: (rows, cols),
        segmentation: segmentation.map(|_| {
            SegmentSpacing(v.optional(element(0, PIXEL_MEASURES, SPACING_BETWEEN_SLICES)))
        }),
    };
    Ok((layout, planes))
}
