//! Stacks of cross-section contours (mining sections, segmented slices): the input of surface
//! reconstruction between sections.
//!
//! A [`SectionStack`] is a list of [`Section`]s at strictly increasing heights `z`; a section holds
//! closed [`Contour`]s in its plane. Inside is decided by the even–odd rule, so a contour nested in
//! another is a hole. Every constructor validates: a contour has at least three points, no
//! repeated consecutive point, no non-finite coordinate, non-zero area, and does not cross
//! itself; contours of one section do not touch each other. Errors name the section and the
//! contour.
//!
//! The field of a section is the signed Euclidean distance to its contours: positive inside,
//! negative outside, zero on a contour ([`Section::signed_distance`]).
//!
//! ```
//! use isocube::contours::{Contour, Section};
//! let square = Contour::new(vec![[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]]).unwrap();
//! let section = Section::new(0.0, vec![square]).unwrap();
//! assert_eq!(section.signed_distance([1.0, 1.0]), 1.0);
//! assert_eq!(section.signed_distance([3.0, 1.0]), -1.0);
//! assert_eq!(section.signed_distance([2.0, 0.5]), 0.0);
//! ```

pub(crate) mod cap;
pub use cap::LoopError;
mod field;
mod plane;
mod reconstruct;
mod sectional;
mod sparse;
mod volume;

pub use field::{inside_flags, section_field, stacked_field, SectionField};
pub use plane::PlaneGrid;
pub use reconstruct::{
    cut_distance, reconstruct, reconstruct_with, Cap, CutDistance, MeshEstimate,
    ReconstructOptions, Reconstruction,
};
pub use sectional::Fidelity;
pub use volume::tetmesh;

use thiserror::Error;

/// A point in a section's plane.
pub type Point2 = [f64; 2];

/// Why a contour, section or stack was rejected. Sections and contours are numbered from 0 in
/// input order.
#[derive(Debug, Error, Clone, PartialEq)]
#[non_exhaustive]
pub enum ContourError {
    /// Fewer than three distinct points.
    #[error(
        "section {section}, contour {contour}: {points} points; a closed contour needs at least 3"
    )]
    TooFewPoints {
        /// Section.
        section: usize,
        /// Contour in the section.
        contour: usize,
        /// Points given.
        points: usize,
    },
    /// A coordinate is NaN or infinite.
    #[error("section {section}, contour {contour}: point {index} has a coordinate that is not a finite number")]
    NotFinite {
        /// Section.
        section: usize,
        /// Contour in the section.
        contour: usize,
        /// Point index.
        index: usize,
    },
    /// Two consecutive points coincide (a zero-length segment).
    #[error("section {section}, contour {contour}: points {index} and {next} coincide at ({}, {})", at[0], at[1])]
    RepeatedPoint {
        /// Section.
        section: usize,
        /// Contour in the section.
        contour: usize,
        /// First point.
        index: usize,
        /// The next point.
        next: usize,
        /// Where.
        at: Point2,
    },
    /// All points on one line: the contour encloses nothing.
    #[error("section {section}, contour {contour}: zero area (all points on one line)")]
    Degenerate {
        /// Section.
        section: usize,
        /// Contour in the section.
        contour: usize,
    },
    /// The contour crosses or touches itself.
    #[error("section {section}, contour {contour}: segments {} and {} meet at ({}, {})", segments.0, segments.1, at[0], at[1])]
    SelfIntersecting {
        /// Section.
        section: usize,
        /// Contour in the section.
        contour: usize,
        /// The two segments (segment `i` runs from point `i` to point `i + 1`).
        segments: (usize, usize),
        /// A point they share.
        at: Point2,
    },
    /// Two contours of one section cross or touch.
    #[error("section {section}: contours {} and {} meet at ({}, {})", contours.0, contours.1, at[0], at[1])]
    Crossing {
        /// Section.
        section: usize,
        /// The two contours.
        contours: (usize, usize),
        /// A point they share.
        at: Point2,
    },
    /// An input contour does not end where it starts.
    #[error("section {section}, contour {contour}: open — the last point is {gap} away from the first (repeat the first point to close it)")]
    Open {
        /// Section.
        section: usize,
        /// Contour in the section.
        contour: usize,
        /// Distance between the last and the first point.
        gap: f64,
    },
    /// Section heights are not finite or not strictly increasing.
    #[error("section {section}: height {z} is not above the previous section's {previous}")]
    Order {
        /// Section.
        section: usize,
        /// Its height.
        z: f64,
        /// The previous section's height.
        previous: f64,
    },
    /// A section height is not a finite number.
    #[error("section {section}: height {z} is not a finite number")]
    Height {
        /// Section.
        section: usize,
        /// The height given.
        z: f64,
    },
    /// No section at all.
    #[error("no sections")]
    Empty,
}

impl ContourError {
    /// The section and contour the error is about, where it names them.
    pub fn location(&self) -> (Option<usize>, Option<usize>) {
        use ContourError::*;
        match *self {
            TooFewPoints {
                section, contour, ..
            }
            | NotFinite {
                section, contour, ..
            }
            | RepeatedPoint {
                section, contour, ..
            }
            | Degenerate { section, contour }
            | SelfIntersecting {
                section, contour, ..
            }
            | Open {
                section, contour, ..
            } => (Some(section), Some(contour)),
            Crossing { section, .. } | Order { section, .. } | Height { section, .. } => {
                (Some(section), None)
            }
            Empty => (None, None),
        }
    }

    /// The same error, attributed to section `section` and (where it names one) contour
    /// `contour`.
    fn at(self, section: usize, contour: usize) -> ContourError {
        use ContourError::*;
        match self {
            TooFewPoints { points, .. } => TooFewPoints {
                section,
                contour,
                points,
            },
            NotFinite { index, .. } => NotFinite {
                section,
                contour,
                index,
            },
            RepeatedPoint {
                index, next, at, ..
            } => RepeatedPoint {
                section,
                contour,
                index,
                next,
                at,
            },
            Degenerate { .. } => Degenerate { section, contour },
            SelfIntersecting { segments, at, .. } => SelfIntersecting {
                section,
                contour,
                segments,
                at,
            },
            Open { gap, .. } => Open {
                section,
                contour,
                gap,
            },
            Crossing { contours, at, .. } => Crossing {
                section,
                contours,
                at,
            },
            other => other,
        }
    }
}

/// A closed contour: a simple polygon, stored without repeating its first point.
#[derive(Clone, Debug, PartialEq)]
pub struct Contour {
    points: Vec<Point2>,
}

impl Contour {
    /// A contour through `points` in order, closed back to the first. A repeated first point at
    /// the end is dropped.
    pub fn new(mut points: Vec<Point2>) -> Result<Contour, ContourError> {
        if points.len() > 1 && points.first() == points.last() {
            points.pop();
        }
        let located = |e: ContourError| e.at(0, 0);
        if let Some(index) = points
            .iter()
            .position(|p| !(p[0].is_finite() && p[1].is_finite()))
        {
            return Err(located(ContourError::NotFinite {
                section: 0,
                contour: 0,
                index,
            }));
        }
        let n = points.len();
        if n < 3 {
            return Err(located(ContourError::TooFewPoints {
                section: 0,
                contour: 0,
                points: n,
            }));
        }
        for i in 0..n {
            if points[i] == points[(i + 1) % n] {
                return Err(located(ContourError::RepeatedPoint {
                    section: 0,
                    contour: 0,
                    index: i,
                    next: (i + 1) % n,
                    at: points[i],
                }));
            }
        }
        let d0 = sub(points[1], points[0]);
        if points.iter().all(|&q| cross(d0, sub(q, points[0])) == 0.0) {
            return Err(located(ContourError::Degenerate {
                section: 0,
                contour: 0,
            }));
        }
        // A spike: the contour runs back along the segment it came by.
        for i in 0..n {
            let (a, p, b) = (points[(i + n - 1) % n], points[i], points[(i + 1) % n]);
            let (u, v) = (sub(p, a), sub(b, p));
            if cross(u, v) == 0.0 && u[0] * v[0] + u[1] * v[1] < 0.0 {
                return Err(located(ContourError::SelfIntersecting {
                    section: 0,
                    contour: 0,
                    segments: ((i + n - 1) % n, i),
                    at: p,
                }));
            }
        }
        let contour = Contour { points };
        let segments = contour.segments().collect::<Vec<_>>();
        if let Some((i, j, at)) = first_meeting(&segments, &segments, true, n) {
            return Err(located(ContourError::SelfIntersecting {
                section: 0,
                contour: 0,
                segments: (i, j),
                at,
            }));
        }
        if contour.signed_area() == 0.0 {
            return Err(located(ContourError::Degenerate {
                section: 0,
                contour: 0,
            }));
        }
        Ok(contour)
    }

    /// The points, first not repeated at the end.
    pub fn points(&self) -> &[Point2] {
        &self.points
    }

    /// The segments `(points[i], points[i + 1])`, the last closing back to the first point.
    pub fn segments(&self) -> impl Iterator<Item = (Point2, Point2)> + '_ {
        let n = self.points.len();
        (0..n).map(move |i| (self.points[i], self.points[(i + 1) % n]))
    }

    /// Signed area: positive for counter-clockwise contours.
    pub fn signed_area(&self) -> f64 {
        let n = self.points.len();
        (0..n)
            .map(|i| {
                let (a, b) = (self.points[i], self.points[(i + 1) % n]);
                a[0] * b[1] - b[0] * a[1]
            })
            .sum::<f64>()
            / 2.0
    }

    /// Bounding box `(min, max)`.
    pub fn bounds(&self) -> (Point2, Point2) {
        let mut lo = [f64::INFINITY; 2];
        let mut hi = [f64::NEG_INFINITY; 2];
        for p in &self.points {
            for a in 0..2 {
                lo[a] = lo[a].min(p[a]);
                hi[a] = hi[a].max(p[a]);
            }
        }
        (lo, hi)
    }
}

/// One section: a plane at height `z` and its contours.
#[derive(Clone, Debug, PartialEq)]
pub struct Section {
    z: f64,
    contours: Vec<Contour>,
}

impl Section {
    /// A section at height `z`; its contours must not touch each other (nesting is fine: an
    /// even number of enclosing contours means outside).
    pub fn new(z: f64, contours: Vec<Contour>) -> Result<Section, ContourError> {
        if !z.is_finite() {
            return Err(ContourError::Height { section: 0, z });
        }
        let segments: Vec<Vec<(Point2, Point2)>> =
            contours.iter().map(|c| c.segments().collect()).collect();
        for a in 0..contours.len() {
            for b in a + 1..contours.len() {
                let (la, ha) = contours[a].bounds();
                let (lb, hb) = contours[b].bounds();
                if la[0] > hb[0] || lb[0] > ha[0] || la[1] > hb[1] || lb[1] > ha[1] {
                    continue;
                }
                if let Some((_, _, at)) = first_meeting(&segments[a], &segments[b], false, 0) {
                    return Err(ContourError::Crossing {
                        section: 0,
                        contours: (a, b),
                        at,
                    });
                }
            }
        }
        Ok(Section { z, contours })
    }

    /// The height.
    pub fn z(&self) -> f64 {
        self.z
    }

    /// The contours.
    pub fn contours(&self) -> &[Contour] {
        &self.contours
    }

    /// Whether `p` is inside by the even–odd rule, or on a contour.
    pub fn contains(&self, p: Point2) -> bool {
        let mut inside = false;
        for c in &self.contours {
            for (a, b) in c.segments() {
                if on_segment(p, a, b) {
                    return true;
                }
                if (a[1] > p[1]) != (b[1] > p[1]) {
                    let x = a[0] + (p[1] - a[1]) / (b[1] - a[1]) * (b[0] - a[0]);
                    if x > p[0] {
                        inside = !inside;
                    }
                }
            }
        }
        inside
    }

    /// Distance from `p` to the nearest contour.
    pub fn distance(&self, p: Point2) -> f64 {
        self.contours
            .iter()
            .flat_map(|c| c.segments())
            .map(|(a, b)| segment_distance(p, a, b))
            .fold(f64::INFINITY, f64::min)
    }

    /// The section's field: the Euclidean distance to the nearest contour, positive inside and
    /// negative outside (even–odd rule), zero on a contour.
    pub fn signed_distance(&self, p: Point2) -> f64 {
        let d = self.distance(p);
        if d == 0.0 {
            0.0
        } else if self.contains(p) {
            d
        } else {
            -d
        }
    }
}

/// Sections at strictly increasing heights.
#[derive(Clone, Debug, PartialEq)]
pub struct SectionStack {
    sections: Vec<Section>,
}

impl SectionStack {
    /// A stack from sections in increasing height order.
    pub fn new(sections: Vec<Section>) -> Result<SectionStack, ContourError> {
        if sections.is_empty() {
            return Err(ContourError::Empty);
        }
        for k in 1..sections.len() {
            if sections[k].z <= sections[k - 1].z {
                return Err(ContourError::Order {
                    section: k,
                    z: sections[k].z,
                    previous: sections[k - 1].z,
                });
            }
        }
        Ok(SectionStack { sections })
    }

    /// Builds and validates a stack from raw point lists per section, attributing errors to the
    /// right section and contour. Sections are taken in the given order, which must be by
    /// increasing height.
    pub fn from_points(
        sections: Vec<(f64, Vec<Vec<Point2>>)>,
    ) -> Result<SectionStack, ContourError> {
        let mut out = Vec::with_capacity(sections.len());
        for (s, (z, contours)) in sections.into_iter().enumerate() {
            let mut cs = Vec::with_capacity(contours.len());
            for (c, points) in contours.into_iter().enumerate() {
                cs.push(Contour::new(points).map_err(|e| e.at(s, c))?);
            }
            out.push(Section::new(z, cs).map_err(|e| match e {
                ContourError::Height { z, .. } => ContourError::Height { section: s, z },
                other => other.at(s, 0),
            })?);
        }
        SectionStack::new(out)
    }

    /// The sections, lowest first.
    pub fn sections(&self) -> &[Section] {
        &self.sections
    }

    /// Bounding box of all contours in the plane, and the height range.
    pub fn bounds(&self) -> (Point2, Point2, [f64; 2]) {
        let mut lo = [f64::INFINITY; 2];
        let mut hi = [f64::NEG_INFINITY; 2];
        for c in self.sections.iter().flat_map(|s| &s.contours) {
            let (l, h) = c.bounds();
            for a in 0..2 {
                lo[a] = lo[a].min(l[a]);
                hi[a] = hi[a].max(h[a]);
            }
        }
        let z = [self.sections[0].z, self.sections[self.sections.len() - 1].z];
        (lo, hi, z)
    }
}

impl SectionStack {
    /// A built-in ore body: six unevenly spaced sections (z = 0, 12, 20, 35, 44, 60) of irregular
    /// lens-shaped contours. The lower three sections are rings (a hole runs through them and out
    /// between the branches), at z = 35 the body splits into two branches, and the right branch
    /// ends at z = 44. Reconstructed with extension caps it is one closed surface of genus 1.
    pub fn sample_orebody() -> SectionStack {
        // (z, [(centre x, centre y, semi-axis a, semi-axis b, phase, hole)])
        type Lens = (f64, f64, f64, f64, f64, bool);
        let sections: [(f64, &[Lens]); 6] = [
            (
                0.0,
                &[
                    (0.0, 0.0, 30.0, 18.0, 0.0, false),
                    (2.0, 1.0, 8.0, 5.0, 1.0, true),
                ],
            ),
            (
                12.0,
                &[
                    (3.0, 2.0, 34.0, 20.0, 0.7, false),
                    (4.0, 2.0, 9.0, 6.0, 2.0, true),
                ],
            ),
            (
                20.0,
                &[
                    (5.0, 1.0, 32.0, 22.0, 1.4, false),
                    (5.0, 2.0, 10.0, 6.0, 0.3, true),
                ],
            ),
            (
                35.0,
                &[
                    (-12.0, 3.0, 12.0, 14.0, 2.1, false),
                    (20.0, 0.0, 11.0, 12.0, 0.9, false),
                ],
            ),
            (
                44.0,
                &[
                    (-14.0, 5.0, 9.0, 10.0, 2.8, false),
                    (22.0, 2.0, 8.0, 9.0, 1.7, false),
                ],
            ),
            (60.0, &[(-15.0, 6.0, 6.0, 7.0, 0.5, false)]),
        ];
        let lens = |&(cx, cy, a, b, phase, hole): &Lens| -> Vec<Point2> {
            let n = 48;
            let mut points: Vec<Point2> = (0..n)
                .map(|i| {
                    let t = 2.0 * std::f64::consts::PI * i as f64 / n as f64;
                    // A lobed outline, as traced on a section.
                    let r = 1.0 + 0.08 * (3.0 * t + phase).sin() + 0.04 * (5.0 * t - phase).cos();
                    [cx + a * r * t.cos(), cy + b * r * t.sin()]
                })
                .collect();
            if hole {
                points.reverse();
            }
            points
        };
        SectionStack::from_points(
            sections
                .iter()
                .map(|(z, lenses)| (*z, lenses.iter().map(lens).collect()))
                .collect(),
        )
        .expect("the built-in ore body is valid")
    }
}

fn sub(a: Point2, b: Point2) -> Point2 {
    [a[0] - b[0], a[1] - b[1]]
}

fn cross(a: Point2, b: Point2) -> f64 {
    a[0] * b[1] - a[1] * b[0]
}

/// Splits a key-hole contour into the simple loops it traces. Planning systems (and scanners'
/// region tools) draw a region with a hole as one polygon that runs in to the hole along a
/// zero-width channel and back out along the same segment; [`Contour::new`] refuses that as
/// self-touching. Each pair of segments that are the same two points in opposite directions is
/// the channel: removing it leaves two loops (the outline and the hole), split further until
/// no pair is left. Loops of fewer than three points (a channel's dead end) are dropped;
/// consecutive repeated points are merged first. Holes are then found by even–odd, as for any
/// section.
///
/// ```
/// use isocube::contours::split_keyholes;
/// // A 4 × 4 square with a 2 × 2 hole, reached by a channel from (0, 2) to (1, 2).
/// let keyhole = vec![
///     [0.0, 0.0], [4.0, 0.0], [4.0, 4.0], [0.0, 4.0], [0.0, 2.0],
///     [1.0, 2.0], [1.0, 3.0], [3.0, 3.0], [3.0, 1.0], [1.0, 1.0], [1.0, 2.0],
///     [0.0, 2.0],
/// ];
/// let loops = split_keyholes(keyhole);
/// assert_eq!(loops.len(), 2);
/// // The outline (with the channel's end on its side) and the hole: 5 points each.
/// assert_eq!(loops.iter().map(Vec::len).collect::<Vec<_>>(), [5, 5]);
/// ```
pub fn split_keyholes(points: Vec<Point2>) -> Vec<Vec<Point2>> {
    let key = |p: Point2| (p[0].to_bits(), p[1].to_bits());
    let mut todo = vec![points];
    let mut loops = Vec::new();
    while let Some(mut p) = todo.pop() {
        p.dedup();
        while p.len() > 1 && p.first() == p.last() {
            p.pop();
        }
        let n = p.len();
        if n < 3 {
            continue;
        }
        // Each directed segment by its two ends; a segment whose reverse is there is a channel.
        let segments: std::collections::HashMap<_, usize> = (0..n)
            .map(|i| ((key(p[i]), key(p[(i + 1) % n])), i))
            .collect();
        let channel = (0..n).find_map(|i| {
            let j = *segments.get(&(key(p[(i + 1) % n]), key(p[i])))?;
            (j != i).then_some((i.min(j), i.max(j)))
        });
        match channel {
            None => loops.push(p),
            Some((i, j)) => {
                // Without segments i and j: the points from i + 1 to j, and from j + 1 round to
                // i (each closing on itself).
                todo.push(p[i + 1..=j].to_vec());
                todo.push(p[j + 1..].iter().chain(&p[..=i]).copied().collect());
            }
        }
    }
    loops
}

/// Distance from `p` to the segment `a–b`.
pub fn segment_distance(p: Point2, a: Point2, b: Point2) -> f64 {
    let ab = sub(b, a);
    let ap = sub(p, a);
    let len2 = ab[0] * ab[0] + ab[1] * ab[1];
    let t = if len2 > 0.0 {
        ((ap[0] * ab[0] + ap[1] * ab[1]) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let d = [ap[0] - t * ab[0], ap[1] - t * ab[1]];
    (d[0] * d[0] + d[1] * d[1]).sqrt()
}

fn on_segment(p: Point2, a: Point2, b: Point2) -> bool {
    cross(sub(b, a), sub(p, a)) == 0.0
        && p[0] >= a[0].min(b[0])
        && p[0] <= a[0].max(b[0])
        && p[1] >= a[1].min(b[1])
        && p[1] <= a[1].max(b[1])
}

/// A point shared by segments `a–b` and `c–d`, if any (exact orientation tests).
fn meeting(a: Point2, b: Point2, c: Point2, d: Point2) -> Option<Point2> {
    let d1 = cross(sub(b, a), sub(c, a));
    let d2 = cross(sub(b, a), sub(d, a));
    let d3 = cross(sub(d, c), sub(a, c));
    let d4 = cross(sub(d, c), sub(b, c));
    if ((d1 > 0.0 && d2 < 0.0) || (d1 < 0.0 && d2 > 0.0))
        && ((d3 > 0.0 && d4 < 0.0) || (d3 < 0.0 && d4 > 0.0))
    {
        let t = d3 / (d3 - d4);
        return Some([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]);
    }
    for (p, s, e) in [(c, a, b), (d, a, b), (a, c, d), (b, c, d)] {
        if on_segment(p, s, e) {
            return Some(p);
        }
    }
    None
}

/// The first pair of segments (one from `xs`, one from `ys`) that meet. With `same` the lists are
/// one contour's `n` segments, and neighbours sharing their common point are not a meeting.
/// Segments are bucketed on a grid so the cost follows the number of nearby pairs.
fn first_meeting(
    xs: &[(Point2, Point2)],
    ys: &[(Point2, Point2)],
    same: bool,
    n: usize,
) -> Option<(usize, usize, Point2)> {
    let all = xs.iter().chain(ys);
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    let mut total = 0.0;
    let mut count = 0usize;
    for (a, b) in all {
        for k in 0..2 {
            lo[k] = lo[k].min(a[k].min(b[k]));
            hi[k] = hi[k].max(a[k].max(b[k]));
        }
        total += ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)).sqrt();
        count += 1;
    }
    let size = (total / count.max(1) as f64 * 2.0).max(1e-300);
    let dims = [0, 1].map(|k| (((hi[k] - lo[k]) / size) as usize + 1).min(4096));
    let cell_range = |a: Point2, b: Point2| {
        let c = |v: f64, k: usize| (((v - lo[k]) / size) as usize).min(dims[k] - 1);
        (
            [c(a[0].min(b[0]), 0), c(a[1].min(b[1]), 1)],
            [c(a[0].max(b[0]), 0), c(a[1].max(b[1]), 1)],
        )
    };
    let mut buckets: std::collections::HashMap<(usize, usize), Vec<usize>> =
        std::collections::HashMap::new();
    for (j, (a, b)) in ys.iter().enumerate() {
        let (l, h) = cell_range(*a, *b);
        for x in l[0]..=h[0] {
            for y in l[1]..=h[1] {
                buckets.entry((x, y)).or_default().push(j);
            }
        }
    }
    let mut best: Option<(usize, usize, Point2)> = None;
    for (i, (a, b)) in xs.iter().enumerate() {
        let (l, h) = cell_range(*a, *b);
        for x in l[0]..=h[0] {
            for y in l[1]..=h[1] {
                for &j in buckets.get(&(x, y)).map_or(&[][..], |v| v) {
                    if same && (j <= i || j == (i + 1) % n || i == (j + 1) % n) {
                        continue;
                    }
                    let (c, d) = ys[j];
                    if let Some(at) = meeting(*a, *b, c, d) {
                        if !matches!(best, Some((bi, bj, _)) if (bi, bj) <= (i, j)) {
                            best = Some((i, j, at));
                        }
                    }
                }
            }
        }
        if best.is_some_and(|(bi, _, _)| bi == i) {
            break;
        }
    }
    best
}

/// A regular `n`-gon of radius `r` around `(cx, cy)`, counter-clockwise (for tests).
#[cfg(test)]
pub(crate) fn test_circle(cx: f64, cy: f64, r: f64, n: usize) -> Vec<Point2> {
    (0..n)
        .map(|i| {
            let a = 2.0 * std::f64::consts::PI * i as f64 / n as f64;
            [cx + r * a.cos(), cy + r * a.sin()]
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(x: f64, y: f64, s: f64) -> Vec<Point2> {
        vec![[x, y], [x + s, y], [x + s, y + s], [x, y + s]]
    }

    #[test]
    fn validation_names_section_and_contour() {
        let err = |sections: Vec<(f64, Vec<Vec<Point2>>)>| {
            SectionStack::from_points(sections).unwrap_err()
        };
        assert_eq!(
            err(vec![
                (0.0, vec![square(0.0, 0.0, 1.0)]),
                (
                    1.0,
                    vec![square(0.0, 0.0, 1.0), vec![[0.0, 0.0], [1.0, 0.0]]]
                )
            ]),
            ContourError::TooFewPoints {
                section: 1,
                contour: 1,
                points: 2
            }
        );
        // A bow tie crosses itself.
        let bow = vec![[0.0, 0.0], [2.0, 2.0], [2.0, 0.0], [0.0, 2.0]];
        assert!(matches!(
            err(vec![(0.0, vec![square(5.0, 5.0, 1.0), bow])]),
            ContourError::SelfIntersecting { section: 0, contour: 1, segments: (0, 2), at } if at == [1.0, 1.0]
        ));
        // A contour touching itself at a vertex.
        let touch = vec![[0.0, 0.0], [4.0, 0.0], [4.0, 4.0], [2.0, 0.0], [0.0, 4.0]];
        assert!(matches!(
            err(vec![(0.0, vec![touch])]),
            ContourError::SelfIntersecting { .. }
        ));
        assert!(matches!(
            err(vec![(0.0, vec![vec![[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]]])]),
            ContourError::Degenerate {
                section: 0,
                contour: 0
            }
        ));
        assert!(matches!(
            err(vec![(
                0.0,
                vec![vec![[0.0, 0.0], [1.0, 0.0], [1.0, 0.0], [0.0, 1.0]]]
            )]),
            ContourError::RepeatedPoint {
                index: 1,
                next: 2,
                ..
            }
        ));
        assert!(matches!(
            err(vec![(
                0.0,
                vec![vec![[0.0, 0.0], [f64::NAN, 0.0], [0.0, 1.0]]]
            )]),
            ContourError::NotFinite { index: 1, .. }
        ));
        // Two overlapping squares cross.
        assert!(matches!(
            err(vec![(
                0.0,
                vec![square(0.0, 0.0, 2.0), square(1.0, 1.0, 2.0)]
            )]),
            ContourError::Crossing {
                section: 0,
                contours: (0, 1),
                ..
            }
        ));
        assert!(matches!(
            err(vec![
                (1.0, vec![square(0.0, 0.0, 1.0)]),
                (1.0, vec![square(0.0, 0.0, 1.0)])
            ]),
            ContourError::Order { section: 1, .. }
        ));
        assert_eq!(
            SectionStack::from_points(vec![]).unwrap_err(),
            ContourError::Empty
        );
        let e = err(vec![(0.0, vec![bow_tie()])]);
        assert!(
            e.to_string().starts_with("section 0, contour 0: segments"),
            "{e}"
        );
    }

    fn bow_tie() -> Vec<Point2> {
        vec![[0.0, 0.0], [2.0, 2.0], [2.0, 0.0], [0.0, 2.0]]
    }

    #[test]
    fn nested_contours_are_holes() {
        let stack = SectionStack::from_points(vec![(
            0.0,
            vec![
                square(0.0, 0.0, 10.0),
                square(3.0, 3.0, 4.0),
                square(4.0, 4.0, 2.0),
            ],
        )])
        .unwrap();
        let s = &stack.sections()[0];
        assert!(s.signed_distance([1.0, 5.0]) > 0.0); // in the outer ring
        assert!(s.signed_distance([3.5, 5.0]) < 0.0); // in the hole
        assert!(s.signed_distance([5.0, 5.0]) > 0.0); // in the island inside the hole
        assert_eq!(s.signed_distance([3.0, 5.0]), 0.0);
        assert_eq!(s.signed_distance([1.0, 5.0]), 1.0);
        assert_eq!(s.signed_distance([12.0, 5.0]), -2.0);
    }

    #[test]
    fn closing_point_is_optional_and_long_contours_validate_fast() {
        let mut closed = square(0.0, 0.0, 1.0);
        closed.push([0.0, 0.0]);
        assert_eq!(Contour::new(closed).unwrap().points().len(), 4);
        // A 20 000-point circle: the bucketed test stays near linear.
        let n = 20_000;
        let circle: Vec<Point2> = (0..n)
            .map(|i| {
                let a = 2.0 * std::f64::consts::PI * i as f64 / n as f64;
                [a.cos(), a.sin()]
            })
            .collect();
        let c = Contour::new(circle).unwrap();
        assert!((c.signed_area() - std::f64::consts::PI).abs() < 1e-3);
    }

    #[test]
    fn segment_distance_cases() {
        assert_eq!(segment_distance([0.0, 1.0], [-1.0, 0.0], [1.0, 0.0]), 1.0);
        assert_eq!(segment_distance([3.0, 4.0], [0.0, 0.0], [-1.0, 0.0]), 5.0);
        assert_eq!(segment_distance([0.5, 0.0], [0.0, 0.0], [1.0, 0.0]), 0.0);
    }
}
