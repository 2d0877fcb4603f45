//! RT Structure Sets (radiotherapy planning): each region of interest's CLOSED_PLANAR contours,
//! in patient coordinates, as a stack of sections for `isocube contours`. Contours are grouped
//! into sections by their plane's z; a region drawn with holes as key-hole polygons is split
//! into its loops ([`split_keyholes`]); holes and islands then follow from even–odd, as in
//! every stack. POINT and OPEN contours are counted, not meshed.

use std::path::Path;

use super::elements::{self, find, Node};
use super::Values;
use crate::{IoError, Position};
use isocube::contours::{split_keyholes, Contour, Section, SectionStack};

/// A region of interest of an RT Structure Set.
#[derive(Clone, Debug, PartialEq)]
pub struct RtRoi {
    /// ROI Number, as the structure set numbers it.
    pub number: i64,
    /// ROI Name (empty when the file gives none).
    pub name: String,
    /// RT ROI Interpreted Type (`EXTERNAL`, `PTV`, `ORGAN`, `ISOCENTER`, …), when given.
    pub kind: String,
    /// The CLOSED_PLANAR contours as sections along z (x and y in each), or `None` when the
    /// region has none.
    pub stack: Option<SectionStack>,
    /// Contours of other geometric types (POINT, OPEN_PLANAR, OPEN_NONPLANAR), counted by type.
    pub other: Vec<(String, usize)>,
    /// Why the region's contours were refused (a contour that crosses itself, points off its
    /// plane, …), naming the file, region and contour; the other regions are read.
    pub problem: Option<String>,
}

/// A region's closed contours as a stack (if any), and its other contours counted by type.
type RoiContours = (Option<SectionStack>, Vec<(String, usize)>);

const STRUCTURE_SET_ROIS: (u16, u16) = (0x3006, 0x0020);
const ROI_NUMBER: (u16, u16) = (0x3006, 0x0022);
const ROI_NAME: (u16, u16) = (0x3006, 0x0026);
const ROI_CONTOURS: (u16, u16) = (0x3006, 0x0039);
const REFERENCED_ROI: (u16, u16) = (0x3006, 0x0084);
const CONTOURS: (u16, u16) = (0x3006, 0x0040);
const GEOMETRIC_TYPE: (u16, u16) = (0x3006, 0x0042);
const POINT_COUNT: (u16, u16) = (0x3006, 0x0046);
const CONTOUR_DATA: (u16, u16) = (0x3006, 0x0050);
const OBSERVATIONS: (u16, u16) = (0x3006, 0x0080);
const INTERPRETED_TYPE: (u16, u16) = (0x3006, 0x00A4);

/// Contours whose points lie this close in z (mm) share a section plane.
const PLANE: f64 = 1e-3;

/// Reads an RT Structure Set's regions of interest, in the order the file lists their
/// contours.
///
/// ```no_run
/// let rois = isocube_io::read_rt_structure_set(std::path::Path::new("plan.dcm"))?;
/// for roi in &rois {
///     let sections = roi.stack.as_ref().map_or(0, |s| s.sections().len());
///     println!("{} {}: {sections} sections", roi.number, roi.name);
/// }
/// # Ok::<(), isocube_io::IoError>(())
/// ```
pub fn read_rt_structure_set(path: &Path) -> Result<Vec<RtRoi>, IoError> {
    let bytes = crate::read_file(path)?;
    read_rt_structure_set_bytes(&bytes, path)
}

/// [`read_rt_structure_set`] of a file's content in memory; `name` names it in errors.
pub fn read_rt_structure_set_bytes(bytes: &[u8], name: &Path) -> Result<Vec<RtRoi>, IoError> {
    let set = elements::parse(name, bytes, 64 * bytes.len() as u64 + (1 << 20))?;
    let v = Values {
        path: name,
        set: &set,
    };
    let field = |s: String| Position::Field(s);
    let rois = find(&set.nodes, ROI_CONTOURS).ok_or_else(|| {
        IoError::format(
            name,
            field("ROIContourSequence".into()),
            "missing: not an RT Structure Set",
        )
    })?;
    let number_of = |item: &[Node], tag, what: &str| -> Result<Option<i64>, IoError> {
        find(item, tag).map(|n| v.int(n, what)).transpose()
    };
    // Names and interpreted types, by ROI number.
    let mut names = Vec::new();
    if let Some(seq) = find(&set.nodes, STRUCTURE_SET_ROIS) {
        for item in &seq.items {
            if let Some(number) = number_of(item, ROI_NUMBER, "ROINumber")? {
                let name = find(item, ROI_NAME).map(|n| v.text(n)).unwrap_or_default();
                names.push((number, name));
            }
        }
    }
    let mut kinds = Vec::new();
    if let Some(seq) = find(&set.nodes, OBSERVATIONS) {
        for item in &seq.items {
            if let Some(number) = number_of(item, REFERENCED_ROI, "ReferencedROINumber")? {
                let kind = find(item, INTERPRETED_TYPE)
                    .map(|n| v.text(n))
                    .unwrap_or_default();
                kinds.push((number, kind));
            }
        }
    }
    let lookup = |list: &[(i64, String)], n: i64| {
        list.iter()
            .find(|(k, _)| *k == n)
            .map(|(_, s)| s.clone())
            .unwrap_or_default()
    };
    let mut out = Vec::new();
    for (r, item) in rois.items.iter().enumerate() {
        let number = number_of(item, REFERENCED_ROI, "ReferencedROINumber")?.ok_or_else(|| {
            IoError::format(
                name,
                field(format!(
                    "ROIContourSequence item {}: ReferencedROINumber",
                    r + 1
                )),
                "missing",
            )
        })?;
        let roi_name = lookup(&names, number);
        let at = |what: String| field(format!("ROI {number} ('{roi_name}'), {what}"));
        // A region whose contours are refused does not stop the others: it comes back with
        // the reason.
        let build = || -> Result<RoiContours, IoError> {
            let mut planar: Vec<(f64, Vec<[f64; 2]>, usize)> = Vec::new();
            let mut other: Vec<(String, usize)> = Vec::new();
            let contours = find(item, CONTOURS).map_or(&[][..], |s| &s.items[..]);
            for (c, contour) in contours.iter().enumerate() {
                let kind = find(contour, GEOMETRIC_TYPE)
                    .map(|n| v.text(n))
                    .unwrap_or_default();
                if kind != "CLOSED_PLANAR" {
                    match other.iter_mut().find(|(k, _)| *k == kind) {
                        Some((_, count)) => *count += 1,
                        None => other.push((kind, 1)),
                    }
                    continue;
                }
                let data = find(contour, CONTOUR_DATA).ok_or_else(|| {
                    IoError::format(
                        name,
                        at(format!("contour {}: ContourData", c + 1)),
                        "missing",
                    )
                })?;
                let numbers = v.numbers(data, "ContourData")?;
                let declared = number_of(contour, POINT_COUNT, "NumberOfContourPoints")?;
                if numbers.len() % 3 != 0
                    || declared.is_some_and(|d| {
                        u64::try_from(d).ok().and_then(|d| d.checked_mul(3))
                            != Some(numbers.len() as u64)
                    })
                {
                    return Err(IoError::format(
                        name,
                        at(format!("contour {}: ContourData", c + 1)),
                        format!(
                            "{} numbers for {} points",
                            numbers.len(),
                            declared.map_or("x, y, z".into(), |d| d.to_string())
                        ),
                    ));
                }
                let points: Vec<[f64; 3]> = numbers
                    .chunks_exact(3)
                    .map(|p| [p[0], p[1], p[2]])
                    .collect();
                let Some(z) = points.first().map(|p| p[2]) else {
                    continue;
                };
                if let Some(p) = points.iter().find(|p| (p[2] - z).abs() > PLANE) {
                    return Err(IoError::unsupported(
                        name,
                        at(format!("contour {}", c + 1)),
                        format!(
                            "points at z {z} and {}: isocube reads contours in axial planes",
                            p[2]
                        ),
                    ));
                }
                planar.push((z, points.iter().map(|p| [p[0], p[1]]).collect(), c + 1));
            }
            planar.sort_by(|a, b| a.0.total_cmp(&b.0));
            let mut sections = Vec::new();
            let mut i = 0;
            while i < planar.len() {
                let z = planar[i].0;
                let mut loops = Vec::new();
                while i < planar.len() && planar[i].0 - z <= PLANE {
                    let (_, points, c) = &planar[i];
                    for points in split_keyholes(points.clone()) {
                        let contour = Contour::new(points).map_err(|e| {
                            IoError::format(name, at(format!("contour {c} (z {z})")), e.to_string())
                        })?;
                        loops.push(contour);
                    }
                    i += 1;
                }
                if !loops.is_empty() {
                    let section = Section::new(z, loops).map_err(|e| {
                        IoError::format(name, at(format!("the section at z {z}")), e.to_string())
                    })?;
                    sections.push(section);
                }
            }
            let stack = if sections.is_empty() {
                None
            } else {
                Some(
                    SectionStack::new(sections)
                        .map_err(|e| IoError::format(name, at("sections".into()), e.to_string()))?,
                )
            };
            Ok((stack, other))
        };
        let (stack, other, problem) = match build() {
            Ok((stack, other)) => (stack, other, None),
            Err(e) => (None, Vec::new(), Some(e.to_string())),
        };
        out.push(RtRoi {
            number,
            name: roi_name,
            kind: lookup(&kinds, number),
            stack,
            other,
            problem,
        });
    }
    Ok(out)
}
