//! Contour stacks from CSV and JSON files.
//!
//! **CSV**: a header naming the columns `section`, `z`, `contour`, `x`, `y` (any order, any case,
//! extra columns ignored), then one row per contour point. `section` and `contour` are labels:
//! rows with the same section label form a section (all at the same `z`), rows with the same
//! contour label within it form a contour, points in row order. Blank lines and lines starting
//! with `#` are skipped.
//!
//! **JSON**: `{"sections": [{"z": 0.0, "contours": [[[x, y], …], …]}, …]}` (or the bare array).
//!
//! **DXF** (ASCII): every `LWPOLYLINE` (elevation from group 38) and `POLYLINE` (elevation from
//! its group 30, or its vertices') is a contour; polylines at one elevation form a section. They
//! must be closed (flag 70 bit 1); other entities are ignored. Contours are named by their handle
//! (group 5) or line.
//!
//! A contour is a closed curve: in CSV and JSON its last point may repeat its first (as GeoJSON
//! rings do) or not, the segment back to the first point being implied either way
//! ([`ContourRead::closed_implicitly`] counts those). A DXF polyline says whether it is closed
//! (flag 70 bit 1): an open one is refused unless [`ContourOptions::close`] asks to close it.
//! Sections may come in any order and at any spacing; they are sorted by height, and two
//! sections at one height are an error.
//!
//! ```
//! use isocube_io::parse_contours_csv;
//! let csv = "section,z,contour,x,y\n\
//!            a,0,outer,0,0\na,0,outer,1,0\na,0,outer,1,1\na,0,outer,0,0\n";
//! let stack = parse_contours_csv(csv, std::path::Path::new("in.csv")).unwrap();
//! assert_eq!(stack.sections()[0].contours()[0].points().len(), 3);
//! ```

use std::path::Path;

use isocube::contours::{ContourError, Point2, SectionStack};

use super::{IoError, Position};

/// How contour files are read.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[non_exhaustive]
pub struct ContourOptions {
    /// Close open DXF polylines (the segment from the last vertex back to the first implied)
    /// instead of refusing them.
    pub close: bool,
}

impl ContourOptions {
    /// With [`ContourOptions::close`] set to `close`.
    pub fn with_close(mut self, close: bool) -> ContourOptions {
        self.close = close;
        self
    }
}

/// A contour stack read from a file, and what the reader did to it.
#[derive(Clone, Debug)]
pub struct ContourRead {
    /// The stack.
    pub stack: SectionStack,
    /// Contours closed by the reader: CSV and JSON contours whose last point is not their
    /// first, and open DXF polylines closed by [`ContourOptions::close`].
    pub closed_implicitly: usize,
}

/// Reads a contour stack, by extension: `.csv`, `.json` or `.dxf`.
pub fn read_contours(path: &Path) -> Result<SectionStack, IoError> {
    read_contours_with(path, &ContourOptions::default()).map(|r| r.stack)
}

/// [`read_contours`] with options, telling how many contours were closed implicitly.
///
/// ```
/// use std::path::Path;
/// // The square's last point does not repeat its first: the closing side is implied.
/// let csv = "section,z,contour,x,y\na,0,s,0,0\na,0,s,1,0\na,0,s,1,1\na,0,s,0,1\n";
/// let dir = tempfile::tempdir().unwrap();
/// let path = dir.path().join("square.csv");
/// std::fs::write(&path, csv).unwrap();
/// let read = isocube_io::read_contours_with(&path, &Default::default()).unwrap();
/// assert_eq!((read.closed_implicitly, read.stack.sections()[0].contours()[0].points().len()), (1, 4));
/// ```
pub fn read_contours_with(path: &Path, options: &ContourOptions) -> Result<ContourRead, IoError> {
    let bytes = std::fs::read(path).map_err(|source| IoError::Os {
        path: path.to_path_buf(),
        source,
    })?;
    read_contours_bytes_with(&bytes, path, options)
}

/// [`read_contours`] on a file's content already in memory; `name`'s extension chooses the
/// format and `name` appears in errors.
///
/// ```
/// use std::path::Path;
/// let mut csv = String::from("section,z,contour,x,y\n");
/// for (s, z) in [(0, 0), (1, 2)] {
///     for [x, y] in [[0, 0], [1, 0], [0, 1], [0, 0]] {
///         csv += &format!("{s},{z},0,{x},{y}\n");
///     }
/// }
/// let csv = csv.as_bytes();
/// let stack = isocube_io::read_contours_bytes(csv, Path::new("two.csv"))?;
/// assert_eq!(stack.sections().len(), 2);
/// # Ok::<(), isocube_io::IoError>(())
/// ```
pub fn read_contours_bytes(bytes: &[u8], name: &Path) -> Result<SectionStack, IoError> {
    read_contours_bytes_with(bytes, name, &ContourOptions::default()).map(|r| r.stack)
}

/// [`read_contours_bytes`] with options, telling how many contours were closed implicitly.
pub fn read_contours_bytes_with(
    bytes: &[u8],
    name: &Path,
    options: &ContourOptions,
) -> Result<ContourRead, IoError> {
    let path = name;
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let text = std::str::from_utf8(bytes).map_err(|e| IoError::Format {
        path: path.to_path_buf(),
        position: Position::Byte(e.valid_up_to() as u64),
        reason: "not UTF-8 text".into(),
    })?;
    match ext.as_deref() {
        Some("csv") => csv_contours(text, path),
        Some("json") => json_contours(text, path),
        Some("dxf") => dxf_contours(text, path, options),
        _ => Err(IoError::Unsupported {
            path: path.to_path_buf(),
            position: Position::File,
            reason: "contour files are .csv, .json or .dxf".into(),
        }),
    }
}

/// One section being read: its label, height, first line and contours (label, first line,
/// points).
struct RawSection {
    label: String,
    z: f64,
    contours: Vec<(String, usize, usize, Vec<Point2>)>,
}

/// Builds the stack, checking closure, ordering and validity; errors point at the input's
/// labels and lines through `describe`.
fn build(
    mut sections: Vec<RawSection>,
    path: &Path,
    where_is: &dyn Fn(&RawSection, Option<usize>) -> Position,
) -> Result<ContourRead, IoError> {
    let format = |position: Position, reason: String| IoError::Format {
        path: path.to_path_buf(),
        position,
        reason,
    };
    if sections.is_empty() {
        return Err(format(Position::File, "no contour points".into()));
    }
    sections.sort_by(|a, b| a.z.total_cmp(&b.z));
    for w in sections.windows(2) {
        if w[0].z == w[1].z {
            return Err(format(
                where_is(&w[1], None),
                format!(
                    "sections '{}' and '{}' are both at z = {}",
                    w[0].label, w[1].label, w[1].z
                ),
            ));
        }
    }
    // A contour whose last point is not its first is closed by the segment back to it.
    let mut closed_implicitly = 0;
    for s in &sections {
        if let Some(c) = s.contours.iter().position(|c| c.3.len() < 2) {
            return Err(format(
                where_is(s, Some(c)),
                format!(
                    "section '{}' (z = {}), contour '{}': a single point, not a curve",
                    s.label, s.z, s.contours[c].0
                ),
            ));
        }
    }
    for points in sections
        .iter_mut()
        .flat_map(|s| s.contours.iter_mut().map(|c| &mut c.3))
    {
        if points.first() != points.last() {
            points.push(points[0]);
            closed_implicitly += 1;
        }
    }
    let input: Vec<(f64, Vec<Vec<Point2>>)> = sections
        .iter()
        .map(|s| (s.z, s.contours.iter().map(|c| c.3.clone()).collect()))
        .collect();
    let stack = SectionStack::from_points(input).map_err(|e| {
        let (s, c) = e.location();
        let sec = &sections[s.unwrap_or(0)];
        let reason = match (&e, c) {
            (ContourError::Crossing { contours, at, .. }, _) => format!(
                "contours '{}' and '{}' meet at ({}, {})",
                sec.contours[contours.0].0, sec.contours[contours.1].0, at[0], at[1]
            ),
            (_, Some(c)) => format!("contour '{}': {}", sec.contours[c].0, detail(&e)),
            _ => detail(&e),
        };
        format(
            where_is(sec, c),
            format!("section '{}' (z = {}), {reason}", sec.label, sec.z),
        )
    })?;
    Ok(ContourRead {
        stack,
        closed_implicitly,
    })
}

/// The error's message without its "section i, contour j: " prefix.
fn detail(e: &ContourError) -> String {
    let text = e.to_string();
    match text.find(": ") {
        Some(i) if text.starts_with("section ") => text[i + 2..].to_string(),
        _ => text,
    }
}

/// Parses the CSV form (see the module documentation). `path` is only used in errors.
pub fn parse_contours_csv(text: &str, path: &Path) -> Result<SectionStack, IoError> {
    csv_contours(text, path).map(|r| r.stack)
}

fn csv_contours(text: &str, path: &Path) -> Result<ContourRead, IoError> {
    let format = |line: usize, reason: String| IoError::Format {
        path: path.to_path_buf(),
        position: Position::Line(line),
        reason,
    };
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));
    let Some((header_line, header)) = lines.next() else {
        return Err(IoError::Format {
            path: path.to_path_buf(),
            position: Position::File,
            reason: "empty file: expected a header section,z,contour,x,y".into(),
        });
    };
    let names: Vec<String> = header
        .split(',')
        .map(|h| h.trim().trim_matches('"').to_ascii_lowercase())
        .collect();
    let column = |name: &str| {
        names.iter().position(|n| n == name).ok_or_else(|| {
            format(
                header_line,
                format!("the header has no '{name}' column (expected section,z,contour,x,y)"),
            )
        })
    };
    let cols = [
        column("section")?,
        column("z")?,
        column("contour")?,
        column("x")?,
        column("y")?,
    ];
    let mut sections: Vec<RawSection> = Vec::new();
    for (line, row) in lines {
        let fields: Vec<&str> = row.split(',').map(|f| f.trim().trim_matches('"')).collect();
        if fields.len() < names.len() {
            return Err(format(
                line,
                format!("{} fields, the header has {}", fields.len(), names.len()),
            ));
        }
        let number = |k: usize, name: &str| -> Result<f64, IoError> {
            let v: f64 = fields[cols[k]].parse().map_err(|_| {
                format(
                    line,
                    format!("{name} '{}' is not a number", fields[cols[k]]),
                )
            })?;
            if v.is_finite() {
                Ok(v)
            } else {
                Err(format(line, format!("{name} {v} is not a finite number")))
            }
        };
        let (z, x, y) = (number(1, "z")?, number(3, "x")?, number(4, "y")?);
        let (slabel, clabel) = (fields[cols[0]], fields[cols[2]]);
        let s = match sections.iter().position(|s| s.label == slabel) {
            Some(s) => s,
            None => {
                sections.push(RawSection {
                    label: slabel.to_string(),
                    z,
                    contours: Vec::new(),
                });
                sections.len() - 1
            }
        };
        let sec = &mut sections[s];
        if sec.z != z {
            return Err(format(
                line,
                format!(
                    "section '{slabel}' is at z = {} but this row says {z}",
                    sec.z
                ),
            ));
        }
        match sec.contours.iter_mut().position(|c| c.0 == clabel) {
            Some(c) => {
                let contour = &mut sec.contours[c];
                if contour.3.len() > 1 && contour.3.first() == contour.3.last() {
                    return Err(format(
                        line,
                        format!(
                            "section '{slabel}', contour '{clabel}' continues after it was closed"
                        ),
                    ));
                }
                contour.2 = line;
                contour.3.push([x, y]);
            }
            None => sec
                .contours
                .push((clabel.to_string(), line, line, vec![[x, y]])),
        }
    }
    build(sections, path, &|s, c| {
        Position::Line(s.contours.get(c.unwrap_or(0)).map_or(0, |c| c.1))
    })
}

/// Parses the DXF form (see the module documentation); open polylines are refused. `path` is
/// only used in errors.
pub fn parse_contours_dxf(text: &str, path: &Path) -> Result<SectionStack, IoError> {
    dxf_contours(text, path, &ContourOptions::default()).map(|r| r.stack)
}

fn dxf_contours(text: &str, path: &Path, options: &ContourOptions) -> Result<ContourRead, IoError> {
    let format = |line: usize, reason: String| IoError::Format {
        path: path.to_path_buf(),
        position: Position::Line(line),
        reason,
    };
    let lines: Vec<&str> = text.lines().collect();
    if lines.len() % 2 == 1 && !lines[lines.len() - 1].trim().is_empty() {
        return Err(format(lines.len(), "a group code without a value".into()));
    }
    // (line of the code, code, value)
    let mut pairs = Vec::with_capacity(lines.len() / 2);
    for k in (0..lines.len().saturating_sub(1)).step_by(2) {
        let code: i32 = lines[k]
            .trim()
            .parse()
            .map_err(|_| format(k + 1, format!("'{}' is not a group code", lines[k].trim())))?;
        pairs.push((k + 1, code, lines[k + 1].trim()));
    }
    struct Polyline {
        line: usize,
        name: String,
        closed: bool,
        z: Option<f64>,
        points: Vec<Point2>,
    }
    let number = |line: usize, v: &str| -> Result<f64, IoError> {
        match v.parse::<f64>() {
            Ok(x) if x.is_finite() => Ok(x),
            _ => Err(format(line + 1, format!("'{v}' is not a finite number"))),
        }
    };
    let mut polylines: Vec<Polyline> = Vec::new();
    let mut k = 0;
    while k < pairs.len() {
        let (line, code, value) = pairs[k];
        k += 1;
        if code != 0 || !(value == "LWPOLYLINE" || value == "POLYLINE") {
            continue;
        }
        let old_style = value == "POLYLINE";
        let mut p = Polyline {
            line,
            name: format!("at line {line}"),
            closed: false,
            z: None,
            points: Vec::new(),
        };
        let mut pending_x: Option<f64> = None;
        // The entity's own groups, up to the next entity (or, for POLYLINE, its SEQEND).
        while k < pairs.len() {
            let (l, c, v) = pairs[k];
            if c == 0 {
                if old_style && v == "VERTEX" {
                    k += 1;
                    let (mut x, mut y, mut vz) = (None, None, None);
                    while k < pairs.len() && pairs[k].1 != 0 {
                        let (l2, c2, v2) = pairs[k];
                        match c2 {
                            10 => x = Some(number(l2, v2)?),
                            20 => y = Some(number(l2, v2)?),
                            30 => vz = Some(number(l2, v2)?),
                            _ => {}
                        }
                        k += 1;
                    }
                    match (x, y) {
                        (Some(x), Some(y)) => p.points.push([x, y]),
                        _ => return Err(format(l, "a VERTEX without x (10) and y (20)".into())),
                    }
                    if let (Some(vz), Some(z)) = (vz, p.z) {
                        if vz != z && z != 0.0 {
                            return Err(format(
                                l,
                                format!(
                                    "polyline {} is not flat: vertex at z = {vz}, polyline at {z}",
                                    p.name
                                ),
                            ));
                        }
                    }
                    if matches!(p.z, None | Some(0.0)) {
                        p.z = vz.or(p.z);
                    }
                    continue;
                }
                if old_style && v == "SEQEND" {
                    k += 1;
                }
                break;
            }
            match c {
                5 => p.name = format!("'{v}'"),
                70 => {
                    let flags: i64 = v
                        .parse()
                        .map_err(|_| format(l + 1, format!("flags '{v}' are not an integer")))?;
                    p.closed = flags & 1 == 1;
                }
                38 if !old_style => p.z = Some(number(l, v)?),
                30 if old_style => p.z = Some(number(l, v)?),
                10 if !old_style => pending_x = Some(number(l, v)?),
                20 if !old_style => {
                    let y = number(l, v)?;
                    let x = pending_x
                        .take()
                        .ok_or_else(|| format(l, "a y (20) without its x (10)".into()))?;
                    p.points.push([x, y]);
                }
                _ => {}
            }
            k += 1;
        }
        polylines.push(p);
    }
    if polylines.is_empty() {
        return Err(IoError::Format {
            path: path.to_path_buf(),
            position: Position::File,
            reason: "no LWPOLYLINE or POLYLINE entity".into(),
        });
    }
    let mut sections: Vec<RawSection> = Vec::new();
    let mut closed_by_option = 0;
    for p in polylines {
        if p.points.is_empty() {
            return Err(format(
                p.line,
                format!("polyline {} has no vertices", p.name),
            ));
        }
        let mut points = p.points;
        if p.closed || options.close {
            if points.first() != points.last() {
                points.push(points[0]);
                closed_by_option += usize::from(!p.closed);
            }
        } else if points.first() != points.last() {
            let (a, b) = (points[0], points[points.len() - 1]);
            let gap = ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt();
            return Err(format(
                p.line,
                format!(
                    "polyline {} is open (flag 70 bit 1 not set; the ends are {gap} apart): \
                     `--close` (Python: `close=True`) closes it",
                    p.name
                ),
            ));
        }
        let z = p.z.unwrap_or(0.0);
        let s = match sections.iter().position(|s| s.z == z) {
            Some(s) => s,
            None => {
                sections.push(RawSection {
                    label: format!("z = {z}"),
                    z,
                    contours: Vec::new(),
                });
                sections.len() - 1
            }
        };
        sections[s].contours.push((p.name, p.line, p.line, points));
    }
    let mut read = build(sections, path, &|s, c| {
        Position::Line(s.contours.get(c.unwrap_or(0)).map_or(0, |c| c.1))
    })?;
    read.closed_implicitly += closed_by_option;
    Ok(read)
}

/// Parses the JSON form (see the module documentation). `path` is only used in errors.
pub fn parse_contours_json(text: &str, path: &Path) -> Result<SectionStack, IoError> {
    json_contours(text, path).map(|r| r.stack)
}

fn json_contours(text: &str, path: &Path) -> Result<ContourRead, IoError> {
    let format = |position: Position, reason: String| IoError::Format {
        path: path.to_path_buf(),
        position,
        reason,
    };
    let value: serde_json::Value =
        serde_json::from_str(text).map_err(|e| format(Position::Line(e.line()), e.to_string()))?;
    let list = match &value {
        serde_json::Value::Array(a) => a,
        serde_json::Value::Object(o) => match o.get("sections") {
            Some(serde_json::Value::Array(a)) => a,
            _ => {
                return Err(format(
                    Position::Field("sections".into()),
                    "expected an array of sections".into(),
                ))
            }
        },
        _ => {
            return Err(format(
                Position::File,
                "expected {\"sections\": [...]} or an array of sections".into(),
            ))
        }
    };
    let mut sections = Vec::with_capacity(list.len());
    for (i, s) in list.iter().enumerate() {
        let field = |name: &str| Position::Field(format!("sections[{i}].{name}"));
        let z = s
            .get("z")
            .and_then(serde_json::Value::as_f64)
            .ok_or_else(|| format(field("z"), "expected a number".into()))?;
        let contours = s
            .get("contours")
            .and_then(serde_json::Value::as_array)
            .ok_or_else(|| format(field("contours"), "expected an array of contours".into()))?;
        let mut raw = Vec::with_capacity(contours.len());
        for (c, contour) in contours.iter().enumerate() {
            let at = |k: usize| Position::Field(format!("sections[{i}].contours[{c}][{k}]"));
            let points = contour.as_array().ok_or_else(|| {
                format(
                    Position::Field(format!("sections[{i}].contours[{c}]")),
                    "expected an array of [x, y] points".into(),
                )
            })?;
            let mut pts = Vec::with_capacity(points.len());
            for (k, p) in points.iter().enumerate() {
                let xy = p
                    .as_array()
                    .filter(|a| a.len() == 2)
                    .and_then(|a| Some([a[0].as_f64()?, a[1].as_f64()?]))
                    .ok_or_else(|| format(at(k), "expected [x, y] with two numbers".into()))?;
                pts.push(xy);
            }
            if pts.is_empty() {
                return Err(format(
                    Position::Field(format!("sections[{i}].contours[{c}]")),
                    "an empty contour".into(),
                ));
            }
            raw.push((c.to_string(), i, c, pts));
        }
        sections.push(RawSection {
            label: i.to_string(),
            z,
            contours: raw,
        });
    }
    build(sections, path, &|s, c| match c {
        Some(c) => Position::Field(format!("sections[{}].contours[{c}]", s.label)),
        None => Position::Field(format!("sections[{}].z", s.label)),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn csv(text: &str) -> Result<SectionStack, IoError> {
        parse_contours_csv(text, Path::new("in.csv"))
    }

    const SQUARE: &str = "0,0\n1,0\n1,1\n0,1\n0,0";

    fn csv_section(label: &str, z: f64, contour: &str, points: &str) -> String {
        points
            .lines()
            .map(|p| format!("{label},{z},{contour},{p}\n"))
            .collect()
    }

    #[test]
    fn csv_sections_contours_and_order() {
        let text = format!(
            "# two sections given top first\nsection,z,contour,x,y\n{}{}{}",
            csv_section("top", 5.0, "a", SQUARE),
            csv_section("bottom", 1.5, "a", SQUARE),
            csv_section("bottom", 1.5, "b", "3,3\n4,3\n4,4\n3,3"),
        );
        let stack = csv(&text).unwrap();
        let zs: Vec<f64> = stack.sections().iter().map(|s| s.z()).collect();
        assert_eq!(zs, [1.5, 5.0]);
        assert_eq!(stack.sections()[0].contours().len(), 2);
        // Columns in another order, with an extra one.
        let text =
            "Y,X,note,Contour,Section,Z\n0,0,-,c,s,2\n0,1,-,c,s,2\n1,1,-,c,s,2\n0,0,-,c,s,2\n";
        let s = csv(text).unwrap();
        assert_eq!(
            s.sections()[0].contours()[0].points(),
            &[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]]
        );
    }

    #[test]
    fn csv_and_json_contours_are_closed_whether_or_not_they_repeat_their_first_point() {
        let explicit = format!(
            "section,z,contour,x,y\n{}{}",
            csv_section("a", 0.0, "o", "0,0\n4,0\n4,4\n0,4\n0,0"),
            csv_section("b", 2.0, "o", "1,1\n3,1\n3,3\n1,3\n1,1")
        );
        let implicit = format!(
            "section,z,contour,x,y\n{}{}",
            csv_section("a", 0.0, "o", "0,0\n4,0\n4,4\n0,4"),
            csv_section("b", 2.0, "o", "1,1\n3,1\n3,3\n1,3\n1,1")
        );
        let read = |text: &str, name: &str| {
            read_contours_bytes_with(text.as_bytes(), Path::new(name), &ContourOptions::default())
                .unwrap()
        };
        let (e, i) = (read(&explicit, "e.csv"), read(&implicit, "i.csv"));
        assert_eq!((e.closed_implicitly, i.closed_implicitly), (0, 1));
        assert_eq!(e.stack, i.stack);
        let json = r#"{"sections": [{"z": 0, "contours": [[[0,0],[4,0],[4,4],[0,4]]]},
                                     {"z": 2, "contours": [[[1,1],[3,1],[3,3],[1,3],[1,1]]]}]}"#;
        let j = read(json, "j.json");
        assert_eq!((j.closed_implicitly, &j.stack), (1, &e.stack));
    }

    #[test]
    fn csv_errors_name_line_section_and_contour() {
        let message = |text: &str| csv(text).unwrap_err().to_string();
        let m = message(&format!(
            "section,z,contour,x,y\n{}",
            csv_section("s1", 0.0, "c1", "0,0")
        ));
        assert!(
            m.contains("line 2")
                && m.contains("section 's1'")
                && m.contains("contour 'c1'")
                && m.contains("a single point"),
            "{m}"
        );
        let m = message(&format!(
            "section,z,contour,x,y\n{}",
            csv_section("s1", 0.0, "bow", "0,0\n2,2\n2,0\n0,2\n0,0")
        ));
        assert!(
            m.contains("contour 'bow'") && m.contains("segments 0 and 2 meet at (1, 1)"),
            "{m}"
        );
        let m = message(&format!(
            "section,z,contour,x,y\n{}{}",
            csv_section("s", 0.0, "p", "0,0\n2,0\n2,2\n0,2\n0,0"),
            csv_section("s", 0.0, "q", "1,1\n3,1\n3,3\n1,3\n1,1")
        ));
        assert!(m.contains("contours 'p' and 'q' meet"), "{m}");
        assert!(message("section,z,contour,x\n").contains("no 'y' column"));
        assert!(message("section,z,contour,x,y\ns,0,c,1,zz\n")
            .contains("line 2: y 'zz' is not a number"));
        assert!(message("section,z,contour,x,y\ns,0,c,1,2\ns,1,c,1,2\n")
            .contains("line 3: section 's' is at z = 0"));
        assert!(message("").contains("empty file"));
        let m = message(&format!(
            "section,z,contour,x,y\n{}s,0,c,5,5\n",
            csv_section("s", 0.0, "c", SQUARE)
        ));
        assert!(
            m.contains("line 7") && m.contains("continues after it was closed"),
            "{m}"
        );
        let m = message(&format!(
            "section,z,contour,x,y\n{}{}",
            csv_section("a", 1.0, "c", SQUARE),
            csv_section("b", 1.0, "c", SQUARE)
        ));
        assert!(m.contains("both at z = 1"), "{m}");
    }

    /// A DXF with two sections: LWPOLYLINEs (elevation 38) and an old-style POLYLINE (vertex z),
    /// written the way CAD programs write them (code and value on alternate lines).
    #[test]
    fn dxf_form() {
        let lw = |handle: &str, z: f64, pts: &[[f64; 2]], flags: i32| {
            let mut s = format!(
                "0\nLWPOLYLINE\n5\n{handle}\n8\nore\n90\n{}\n70\n{flags}\n38\n{z}\n",
                pts.len()
            );
            for p in pts {
                s += &format!("10\n{}\n20\n{}\n", p[0], p[1]);
            }
            s
        };
        let square = [[0.0, 0.0], [4.0, 0.0], [4.0, 4.0], [0.0, 4.0]];
        let hole = [[1.0, 1.0], [1.0, 2.0], [2.0, 2.0], [2.0, 1.0]];
        let mut text = String::from("0\nSECTION\n2\nENTITIES\n");
        text += &lw("A1", 10.0, &square, 1);
        text += &lw("A2", 10.0, &hole, 1);
        text += "0\nPOLYLINE\n5\nB1\n66\n1\n70\n1\n10\n0\n20\n0\n30\n0\n";
        for p in square {
            text += &format!("0\nVERTEX\n10\n{}\n20\n{}\n30\n25.5\n", p[0], p[1]);
        }
        text += "0\nSEQEND\n0\nCIRCLE\n10\n0\n20\n0\n40\n1\n0\nENDSEC\n0\nEOF\n";
        let stack = parse_contours_dxf(&text, Path::new("in.dxf")).unwrap();
        let zs: Vec<f64> = stack.sections().iter().map(|s| s.z()).collect();
        assert_eq!(zs, [10.0, 25.5]);
        assert_eq!(stack.sections()[0].contours().len(), 2);
        assert_eq!(stack.sections()[1].contours()[0].points().len(), 4);
        // An open polyline is named by its handle and line.
        let open = format!(
            "0\nSECTION\n2\nENTITIES\n{}0\nENDSEC\n",
            lw("C7", 0.0, &square, 0)
        );
        let e = parse_contours_dxf(&open, Path::new("in.dxf"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("line 5") && e.contains("polyline 'C7' is open") && e.contains("--close"),
            "{e}"
        );
        // Closed when asked: the stack of the same polyline flagged closed, one closed so.
        let closing = ContourOptions::default().with_close(true);
        let read =
            read_contours_bytes_with(open.as_bytes(), Path::new("in.dxf"), &closing).unwrap();
        let flagged = format!(
            "0\nSECTION\n2\nENTITIES\n{}0\nENDSEC\n",
            lw("C7", 0.0, &square, 1)
        );
        assert_eq!(
            read.stack,
            parse_contours_dxf(&flagged, Path::new("in.dxf")).unwrap()
        );
        assert_eq!(read.closed_implicitly, 1);
        let e = parse_contours_dxf("0\nSECTION\nx\n1\n", Path::new("in.dxf"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("line 3: 'x' is not a group code"), "{e}");
        let e = parse_contours_dxf("0\nSECTION\n0\nEOF\n", Path::new("in.dxf"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("no LWPOLYLINE or POLYLINE"), "{e}");
    }

    #[test]
    fn json_form() {
        let text = r#"{"sections": [
            {"z": 2.0, "contours": [[[0,0],[1,0],[1,1],[0,0]]]},
            {"z": 0.0, "contours": [[[0,0],[2,0],[2,2],[0,2],[0,0]], [[0.5,0.5],[1,0.5],[1,1],[0.5,0.5]]]}
        ]}"#;
        let stack = parse_contours_json(text, Path::new("in.json")).unwrap();
        assert_eq!(stack.sections()[0].z(), 0.0);
        assert_eq!(stack.sections()[0].contours().len(), 2);
        let bad = |t: &str| {
            parse_contours_json(t, Path::new("in.json"))
                .unwrap_err()
                .to_string()
        };
        assert!(bad("{\"sections\": [").contains("line 1"));
        assert!(bad(r#"[{"z": 0, "contours": [[[0,0]]]}]"#).contains("sections[0].contours[0]"));
        assert!(
            bad(r#"[{"z": 0, "contours": [[[0,0],[1,0],["a",1],[0,0]]]}]"#)
                .contains("sections[0].contours[0][2]")
        );
        assert!(bad(r#"[{"contours": []}]"#).contains("sections[0].z"));
    }
}
