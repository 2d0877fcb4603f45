//! OBJ text with OpenSubdiv's tag lines, and isocube's tag for inner loops.
//!
//! Read: `v x y z`; `f a b c …` (1-based, negative indices count back, `a/t/n` forms take the
//! vertex); tags `t NAME nint/nfloat/nstring ints… floats… strings…`:
//! - `t crease N/M/0 v0 v1 … s…`: the edges of the vertex chain v0–v1–…, one sharpness for all
//!   or one per edge (0-based vertices);
//! - `t corner N/M/0 v… s…`: corner sharpness, one for all or one per vertex;
//! - `t hole N/0/0 f…`: hole faces (0-based, in file order);
//! - `t interpolateboundary 1/0/0 R`: 0 none, 1 edge-and-corner, 2 edge-only;
//! - `t innerloop N/0/0 f v…` (isocube's): an inner loop (hole in the face) of face f, its
//!   vertices clockwise seen from outside; programs that do not know the tag ignore it;
//! - `t creasemethod 0/0/1 normal` is accepted, `chaikin` is not (only the uniform rule is
//!   implemented); `t facevaryinginterpolateboundary` is ignored (no face-varying data).
//!
//! Written back the same way, so meshes round-trip.

use std::fmt::Write as _;

use super::{BoundaryRule, Face, PolyMesh, SubdivError};

impl PolyMesh {
    /// Reads OBJ text (see the module documentation for the tags understood).
    pub fn from_obj(text: &str) -> Result<PolyMesh, SubdivError> {
        let mut mesh = PolyMesh::default();
        let mut holes: Vec<usize> = Vec::new();
        let mut inner: Vec<(usize, usize, Vec<u32>)> = Vec::new();
        for (k, raw) in text.lines().enumerate() {
            let line = k + 1;
            let err = |reason: String| SubdivError::Parse { line, reason };
            let content = raw.split('#').next().unwrap_or("").trim();
            let mut words = content.split_whitespace();
            let Some(kind) = words.next() else {
                continue;
            };
            match kind {
                "v" => {
                    let c: Vec<f64> = words
                        .take(3)
                        .map(|w| w.parse::<f64>())
                        .collect::<Result<_, _>>()
                        .map_err(|_| err(format!("`{content}`: a vertex needs numbers")))?;
                    if c.len() != 3 || c.iter().any(|x| !x.is_finite()) {
                        return Err(err(format!(
                            "`{content}`: a vertex needs three finite coordinates"
                        )));
                    }
                    mesh.positions.push([c[0], c[1], c[2]]);
                }
                "f" => {
                    let n = mesh.positions.len() as i64;
                    let mut lp = Vec::new();
                    for w in words {
                        let first = w.split('/').next().unwrap_or("");
                        let i: i64 = first
                            .parse()
                            .map_err(|_| err(format!("`{w}` is not a vertex index")))?;
                        let index = if i > 0 { i - 1 } else { n + i };
                        if i == 0 || index < 0 {
                            return Err(err(format!("vertex index {i} is out of range")));
                        }
                        lp.push(index as u32);
                    }
                    if lp.len() < 3 {
                        return Err(err(format!("a face needs 3 vertices, got {}", lp.len())));
                    }
                    mesh.faces.push(Face::new(lp));
                }
                "t" => parse_tag(&mut mesh, content, line, &mut words, &mut holes, &mut inner)?,
                // Texture coordinates, normals, groups, smoothing and materials carry nothing
                // subdivision needs.
                _ => {}
            }
        }
        for (f, line, lp) in inner {
            let face = mesh.faces.get_mut(f).ok_or(SubdivError::Parse {
                line,
                reason: format!("innerloop: face {f} does not exist"),
            })?;
            face.inner.push(lp);
        }
        if !holes.is_empty() {
            mesh.holes = vec![false; mesh.faces.len()];
            for f in holes {
                *mesh.holes.get_mut(f).ok_or(SubdivError::Tag {
                    tag: "hole".into(),
                    reason: format!("face {f} does not exist"),
                })? = true;
            }
        }
        mesh.validate()?;
        Ok(mesh)
    }

    /// Writes OBJ text with tag lines for creases, corners, holes, inner loops and the boundary
    /// rule; [`PolyMesh::from_obj`] reads it back to the same mesh.
    pub fn to_obj(&self) -> String {
        let mut out = String::new();
        let _ = writeln!(out, "# isocube polygon mesh");
        for p in &self.positions {
            let _ = writeln!(out, "v {} {} {}", p[0], p[1], p[2]);
        }
        for face in &self.faces {
            out.push('f');
            for v in &face.outer {
                let _ = write!(out, " {}", v + 1);
            }
            out.push('\n');
        }
        for (f, face) in self.faces.iter().enumerate() {
            for lp in &face.inner {
                let _ = write!(out, "t innerloop {}/0/0 {f}", lp.len() + 1);
                for v in lp {
                    let _ = write!(out, " {v}");
                }
                out.push('\n');
            }
        }
        for (&(a, b), &s) in &self.creases {
            let _ = writeln!(out, "t crease 2/1/0 {a} {b} {s}");
        }
        for (&v, &s) in &self.corners {
            let _ = writeln!(out, "t corner 1/1/0 {v} {s}");
        }
        let holes: Vec<usize> = (0..self.faces.len()).filter(|&f| self.is_hole(f)).collect();
        if !holes.is_empty() {
            let _ = write!(out, "t hole {}/0/0", holes.len());
            for f in holes {
                let _ = write!(out, " {f}");
            }
            out.push('\n');
        }
        if let Some(rule) = self.boundary {
            let _ = writeln!(out, "t interpolateboundary 1/0/0 {}", rule.tag());
        }
        out
    }
}

fn parse_tag<'a>(
    mesh: &mut PolyMesh,
    content: &str,
    line: usize,
    words: &mut impl Iterator<Item = &'a str>,
    holes: &mut Vec<usize>,
    inner: &mut Vec<(usize, usize, Vec<u32>)>,
) -> Result<(), SubdivError> {
    let err = |reason: String| SubdivError::Parse { line, reason };
    let name = words
        .next()
        .ok_or_else(|| err("a tag needs a name".into()))?;
    let counts: Vec<usize> = words
        .next()
        .ok_or_else(|| err(format!("tag {name}: counts nint/nfloat/nstring missing")))?
        .split('/')
        .map(|c| c.parse::<usize>())
        .collect::<Result<_, _>>()
        .map_err(|_| err(format!("tag {name}: counts must be nint/nfloat/nstring")))?;
    let [ni, nf, ns] = counts[..] else {
        return Err(err(format!(
            "tag {name}: counts must be nint/nfloat/nstring"
        )));
    };
    let rest: Vec<&str> = words.collect();
    if rest.len() != ni + nf + ns {
        return Err(err(format!(
            "`{content}`: {} values for {ni} integers, {nf} numbers and {ns} strings",
            rest.len()
        )));
    }
    let ints: Vec<u32> = rest[..ni]
        .iter()
        .map(|w| w.parse::<u32>())
        .collect::<Result<_, _>>()
        .map_err(|_| err(format!("tag {name}: integers expected")))?;
    let floats: Vec<f32> = rest[ni..ni + nf]
        .iter()
        .map(|w| w.parse::<f32>())
        .collect::<Result<_, _>>()
        .map_err(|_| err(format!("tag {name}: numbers expected")))?;
    let strings = &rest[ni + nf..];
    let per = |count: usize| -> Result<Vec<f32>, SubdivError> {
        match floats.len() {
            1 => Ok(vec![floats[0]; count]),
            n if n == count => Ok(floats.clone()),
            n => Err(err(format!(
                "tag {name}: {n} sharpness values for {count} items"
            ))),
        }
    };
    match name {
        "crease" => {
            if ints.len() < 2 {
                return Err(err("crease: at least two vertices".into()));
            }
            let s = per(ints.len() - 1)?;
            for (w, s) in ints.windows(2).zip(s) {
                mesh.set_crease(w[0], w[1], s);
            }
        }
        "corner" => {
            let s = per(ints.len())?;
            for (&v, s) in ints.iter().zip(s) {
                mesh.corners.insert(v, s);
            }
        }
        "hole" => holes.extend(ints.iter().map(|&f| f as usize)),
        "interpolateboundary" => {
            mesh.boundary = Some(match ints.first() {
                Some(0) => BoundaryRule::None,
                Some(1) => BoundaryRule::EdgeAndCorner,
                Some(2) => BoundaryRule::EdgeOnly,
                other => {
                    return Err(err(format!(
                        "interpolateboundary: {other:?} is not 0, 1 or 2"
                    )))
                }
            })
        }
        "innerloop" => {
            let (&f, lp) = ints
                .split_first()
                .ok_or_else(|| err("innerloop: a face and its loop".into()))?;
            inner.push((f as usize, line, lp.to_vec()));
        }
        "creasemethod" => match strings.first().copied() {
            Some("normal") | None => {}
            Some(other) => {
                return Err(SubdivError::Tag {
                    tag: name.into(),
                    reason: format!("crease method `{other}` is not supported (only `normal`)"),
                })
            }
        },
        // Face-varying data, and other tags, carry nothing the positions need.
        _ => {}
    }
    Ok(())
}
