//! Faces with inner loops (a P-loop around one or more C-loops, as boolean operations on solids
//! produce), made ready for Catmull–Clark by the two methods of the solid-modelling paper.

use std::collections::HashMap;

use super::{Face, PolyMesh, SubdivError, INFINITELY_SHARP};
use crate::contours::cap::{area, bridge, chain_loops, ear_clip, LoopError};

/// How faces with inner loops are subdivided.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum HoleMethod {
    /// The paper's smooth shape: each vertex of the loop with fewer vertices is joined to the
    /// nearest vertex of the other loop, so every edge of that loop gets a face reaching across
    /// (its face point averages the edge's ends and the other loop's vertices it spans), the
    /// joining edges get ordinary edge points, and loop vertices gain a valence. The surface
    /// rounds over the loops. One inner loop per face.
    #[default]
    Smooth,
    /// The paper's sharp shape keeping the P–C relation: the loops' edges become infinitely
    /// sharp and their vertices corners, the face is split into triangles (holes bridged),
    /// refined with the crease rules, and the pieces of each original face are merged back into
    /// one face whose outer and inner loops are the refined loops. The face stays flat and the
    /// refined loops lie on the original loops' edges.
    Sharp,
}

/// Newell's normal of a loop.
fn normal(p: &[[f64; 3]], lp: &[u32]) -> [f64; 3] {
    let mut n = [0.0; 3];
    for i in 0..lp.len() {
        let (a, b) = (p[lp[i] as usize], p[lp[(i + 1) % lp.len()] as usize]);
        n[0] += (a[1] - b[1]) * (a[2] + b[2]);
        n[1] += (a[2] - b[2]) * (a[0] + b[0]);
        n[2] += (a[0] - b[0]) * (a[1] + b[1]);
    }
    n
}

/// A projection onto the plane of the face, keeping orientation (outer loop counter-clockwise).
fn projector(p: &[[f64; 3]], outer: &[u32]) -> impl Fn([f64; 3]) -> [f64; 2] {
    let n = normal(p, outer);
    let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2])
        .sqrt()
        .max(f64::MIN_POSITIVE);
    let n = n.map(|c| c / len);
    let seed = if n[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let cross = |a: [f64; 3], b: [f64; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    let u = {
        let c = cross(n, seed);
        let l = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
        c.map(|x| x / l)
    };
    let v = cross(n, u);
    move |q: [f64; 3]| {
        [
            q[0] * u[0] + q[1] * u[1] + q[2] * u[2],
            q[0] * v[0] + q[1] * v[1] + q[2] * v[2],
        ]
    }
}

/// Triangles covering a face with inner loops (projected on its plane, holes bridged, ears
/// clipped), with the face's orientation.
pub(super) fn triangulate_face(p: &[[f64; 3]], face: &Face) -> Result<Vec<[u32; 3]>, String> {
    flat_face(p, face).map_err(|e| format!("the face {e}"))
}

fn flat_face(p: &[[f64; 3]], face: &Face) -> Result<Vec<[u32; 3]>, LoopError> {
    let project = projector(p, &face.outer);
    let xy = |v: u32| project(p[v as usize]);
    let mut ring = face.outer.clone();
    let mut order: Vec<&Vec<u32>> = face.inner.iter().collect();
    let reach = |lp: &Vec<u32>| lp.iter().map(|&v| xy(v)[0]).fold(f64::MIN, f64::max);
    order.sort_by(|a, b| reach(b).total_cmp(&reach(a)));
    for lp in order {
        ring = bridge(&ring, lp, &xy)?;
    }
    let outer: Vec<[f64; 2]> = face.outer.iter().map(|&v| xy(v)).collect();
    ear_clip(&ring, &xy, area(&outer).signum())
}

/// The paper's method (a) for one face: faces reaching across from each edge of the smaller
/// loop to the span of the other loop between its ends' nearest vertices.
fn smooth_faces(p: &[[f64; 3]], face: &Face) -> Result<Vec<Vec<u32>>, String> {
    let [inner] = &face.inner[..] else {
        return Err(format!(
            "{} inner loops; the smooth method joins one inner loop to the outer one (use the \
             sharp method)",
            face.inner.len()
        ));
    };
    let (small, large) = if inner.len() <= face.outer.len() {
        (inner, &face.outer)
    } else {
        (&face.outer, inner)
    };
    let dist = |a: u32, b: u32| {
        let (x, y) = (p[a as usize], p[b as usize]);
        (x[0] - y[0]).powi(2) + (x[1] - y[1]).powi(2) + (x[2] - y[2]).powi(2)
    };
    let m = large.len();
    let nearest: Vec<usize> = small
        .iter()
        .map(|&a| {
            (0..m)
                .min_by(|&i, &j| dist(a, large[i]).total_cmp(&dist(a, large[j])))
                .expect("loops have vertices")
        })
        .collect();
    // Going forward along the small loop, the nearest vertices go backward along the large one
    // (the loops run opposite ways); the spans must cover the large loop exactly once.
    let n = small.len();
    let steps: usize = (0..n)
        .map(|i| (nearest[i] + m - nearest[(i + 1) % n]) % m)
        .sum();
    if steps != m {
        return Err(
            "the loops' nearest vertices do not pair up in order (loops too unlike in shape for \
             the smooth method; use the sharp method)"
                .into(),
        );
    }
    Ok((0..n)
        .map(|i| {
            let (a, b) = (small[i], small[(i + 1) % n]);
            let mut f = vec![a, b];
            let mut k = nearest[(i + 1) % n];
            loop {
                f.push(large[k]);
                if k == nearest[i] {
                    break;
                }
                k = (k + 1) % m;
            }
            f
        })
        .collect())
}

/// Replaces every face with inner loops by ordinary faces, by `method`; returns the mesh and,
/// for each of its faces, the face of `mesh` it comes from.
pub(super) fn remove_inner_loops(
    mesh: &PolyMesh,
    method: HoleMethod,
) -> Result<(PolyMesh, Vec<usize>), SubdivError> {
    let mut out = PolyMesh {
        positions: mesh.positions.clone(),
        creases: mesh.creases.clone(),
        corners: mesh.corners.clone(),
        boundary: mesh.boundary,
        ..PolyMesh::default()
    };
    let mut origin = Vec::with_capacity(mesh.faces.len());
    let mut holes = Vec::new();
    for (f, face) in mesh.faces.iter().enumerate() {
        let pieces: Vec<Vec<u32>> = if face.inner.is_empty() {
            vec![face.outer.clone()]
        } else {
            match method {
                HoleMethod::Smooth => smooth_faces(&mesh.positions, face),
                HoleMethod::Sharp => {
                    // Sharp edges alone would round the loops into B-spline curves; corners at
                    // their vertices keep the refined loops on the original edges.
                    for lp in std::iter::once(&face.outer).chain(&face.inner) {
                        for i in 0..lp.len() {
                            out.set_crease(lp[i], lp[(i + 1) % lp.len()], INFINITELY_SHARP);
                            out.corners.insert(lp[i], INFINITELY_SHARP);
                        }
                    }
                    triangulate_face(&mesh.positions, face)
                        .map(|t| t.into_iter().map(|t| t.to_vec()).collect())
                }
            }
            .map_err(|reason| SubdivError::Holes { face: f, reason })?
        };
        for piece in pieces {
            out.faces.push(Face::new(piece));
            origin.push(f);
            holes.push(mesh.is_hole(f));
        }
    }
    if holes.iter().any(|&h| h) {
        out.holes = holes;
    }
    Ok((out, origin))
}

/// After refinement: for [`HoleMethod::Sharp`], the pieces of each original face with inner
/// loops become one face again (outer loop and inner loops from the pieces' outline), and the
/// vertices only those pieces used are dropped. Nothing to do for the smooth method.
pub(super) fn restore_inner_loops(
    original: &PolyMesh,
    refined: PolyMesh,
    origin: &[usize],
    method: HoleMethod,
) -> Result<PolyMesh, SubdivError> {
    if method != HoleMethod::Sharp || original.faces.iter().all(|f| f.inner.is_empty()) {
        return Ok(refined);
    }
    let mut groups: HashMap<usize, Vec<usize>> = HashMap::new();
    for (f, &o) in origin.iter().enumerate() {
        if !original.faces[o].inner.is_empty() {
            groups.entry(o).or_default().push(f);
        }
    }
    let mut faces: Vec<Option<Face>> = refined.faces.iter().cloned().map(Some).collect();
    let mut holes: Vec<bool> = (0..refined.faces.len())
        .map(|f| refined.is_hole(f))
        .collect();
    let mut order: Vec<usize> = groups.keys().copied().collect();
    order.sort_unstable();
    for o in order {
        let members = &groups[&o];
        // The outline: directed edges of the pieces whose reverse is not in the group.
        let mut directed: HashMap<(u32, u32), usize> = HashMap::new();
        for &f in members {
            let lp = &refined.faces[f].outer;
            for i in 0..lp.len() {
                *directed.entry((lp[i], lp[(i + 1) % lp.len()])).or_insert(0) += 1;
            }
        }
        let mut outline: Vec<(u32, u32)> = directed
            .keys()
            .copied()
            .filter(|&(a, b)| !directed.contains_key(&(b, a)))
            .collect();
        outline.sort_unstable();
        let mut loops = chain_loops(&outline).map_err(|e| SubdivError::Holes {
            face: o,
            reason: format!("the refined pieces' outline {e}"),
        })?;
        // The outer loop: the one with the largest area in the face's plane.
        let project = projector(&refined.positions, &loops[0]);
        let signed = |lp: &Vec<u32>| {
            let pts: Vec<[f64; 2]> = lp
                .iter()
                .map(|&v| project(refined.positions[v as usize]))
                .collect();
            area(&pts)
        };
        let outer_index = (0..loops.len())
            .max_by(|&a, &b| signed(&loops[a]).abs().total_cmp(&signed(&loops[b]).abs()))
            .expect("an outline");
        let outer = loops.swap_remove(outer_index);
        let merged = Face {
            outer,
            inner: loops,
        };
        for &f in members {
            faces[f] = None;
        }
        faces[members[0]] = Some(merged);
        holes[members[0]] = original.is_hole(o);
    }
    // Keep the faces left, and the vertices they use, in order.
    let kept: Vec<(Face, bool)> = faces
        .into_iter()
        .zip(holes)
        .filter_map(|(f, h)| f.map(|f| (f, h)))
        .collect();
    let mut index = vec![u32::MAX; refined.positions.len()];
    let mut positions = Vec::new();
    for (face, _) in &kept {
        for lp in std::iter::once(&face.outer).chain(&face.inner) {
            for &v in lp {
                if index[v as usize] == u32::MAX {
                    index[v as usize] = positions.len() as u32;
                    positions.push(refined.positions[v as usize]);
                }
            }
        }
    }
    let remap = |lp: &Vec<u32>| lp.iter().map(|&v| index[v as usize]).collect::<Vec<u32>>();
    let mut out = PolyMesh {
        positions,
        boundary: refined.boundary,
        ..PolyMesh::default()
    };
    let any_hole = kept.iter().any(|(_, h)| *h);
    for (face, hole) in &kept {
        out.faces.push(Face {
            outer: remap(&face.outer),
            inner: face.inner.iter().map(remap).collect(),
        });
        if any_hole {
            out.holes.push(*hole);
        }
    }
    for (&(a, b), &s) in &refined.creases {
        let (a, b) = (index[a as usize], index[b as usize]);
        if a != u32::MAX && b != u32::MAX {
            out.set_crease(a, b, s);
        }
    }
    for (&v, &s) in &refined.corners {
        if index[v as usize] != u32::MAX {
            out.corners.insert(index[v as usize], s);
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::subdiv::{subdivide, SubdivOptions};

    use crate::subdiv::samples::{box_with_boss, circle, holed_prism, square};

    /// Whether any triangle of the mesh meets the vertical line through the origin.
    fn axis_blocked(mesh: &PolyMesh) -> bool {
        let t = mesh.triangulate().unwrap();
        t.triangles.iter().any(|tri| {
            let p = tri.map(|v| t.positions[v as usize]);
            let side = |a: [f32; 3], b: [f32; 3]| a[0] * b[1] - a[1] * b[0];
            let s = [side(p[0], p[1]), side(p[1], p[2]), side(p[2], p[0])];
            s.iter().all(|&x| x >= 0.0) || s.iter().all(|&x| x <= 0.0)
        })
    }

    fn distance_to_polyline(q: [f64; 3], pts: &[[f64; 3]]) -> f64 {
        (0..pts.len())
            .map(|i| {
                let (a, b) = (pts[i], pts[(i + 1) % pts.len()]);
                let ab = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
                let aq = [q[0] - a[0], q[1] - a[1], q[2] - a[2]];
                let len2 = ab.iter().map(|x| x * x).sum::<f64>();
                let t =
                    (ab.iter().zip(&aq).map(|(x, y)| x * y).sum::<f64>() / len2).clamp(0.0, 1.0);
                (0..3)
                    .map(|d| (aq[d] - t * ab[d]).powi(2))
                    .sum::<f64>()
                    .sqrt()
            })
            .fold(f64::INFINITY, f64::min)
    }

    /// Plate with a round hole, box with a square through-hole, box with a boss: with both
    /// methods the result is closed with the right genus, a through-hole stays open, and the
    /// sharp method keeps every refined loop vertex on the original loop.
    #[test]
    fn faces_with_holes_subdivide_by_both_methods() {
        let cases = [
            (
                "plate",
                holed_prism(&square(2.0), &circle(1.0, 16), 0.5),
                1,
                true,
            ),
            (
                "box-hole",
                holed_prism(&square(2.0), &square(0.8), 2.0),
                1,
                true,
            ),
            ("boss", box_with_boss(), 0, false),
        ];
        for (name, cage, genus, through) in cases {
            let original = cage.triangulate().unwrap().report();
            assert!(
                original.watertight && original.oriented,
                "{name}: {original:?}"
            );
            assert_eq!(original.genus, Some(genus), "{name}");
            for method in [HoleMethod::Smooth, HoleMethod::Sharp] {
                for levels in 1..=3 {
                    let options = SubdivOptions {
                        holes: method,
                        ..SubdivOptions::default()
                    };
                    let fine = subdivide(&cage, levels, &options).unwrap();
                    let rep = fine.triangulate().unwrap().report();
                    let what = format!("{name} {method:?} {levels}");
                    assert!(rep.watertight && rep.oriented, "{what}: {rep:?}");
                    assert_eq!(rep.genus, Some(genus), "{what}");
                    assert!(rep.volume.unwrap() > 0.0, "{what}");
                    // A through-hole stays open; the boss's body covers the axis.
                    assert_eq!(axis_blocked(&fine), !through, "{what}");
                    if method == HoleMethod::Sharp {
                        // Faces with inner loops come back, their loops on the original ones.
                        let holed: Vec<&Face> =
                            fine.faces.iter().filter(|f| !f.inner.is_empty()).collect();
                        let before: Vec<&Face> =
                            cage.faces.iter().filter(|f| !f.inner.is_empty()).collect();
                        assert_eq!(holed.len(), before.len(), "{what}");
                        for (f, g) in holed.iter().zip(&before) {
                            for (lp, orig) in std::iter::once(&f.outer)
                                .chain(&f.inner)
                                .zip(std::iter::once(&g.outer).chain(&g.inner))
                            {
                                assert_eq!(lp.len(), orig.len() << levels, "{what}");
                                let pts: Vec<[f64; 3]> =
                                    orig.iter().map(|&v| cage.positions[v as usize]).collect();
                                for &v in lp {
                                    let d = distance_to_polyline(fine.positions[v as usize], &pts);
                                    assert!(d < 1e-12, "{what}: loop vertex {d} off its edge");
                                }
                            }
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn the_smooth_method_takes_one_inner_loop() {
        let cage = holed_prism(&square(2.0), &square(0.5), 1.0);
        let two = Face {
            outer: cage.faces[0].outer.clone(),
            inner: vec![
                cage.faces[0].inner[0].clone(),
                cage.faces[0].inner[0].clone(),
            ],
        };
        let e = smooth_faces(&cage.positions, &two).unwrap_err();
        assert!(e.contains("2 inner loops"), "{e}");
    }
}
