//! Built-in cages with faces with inner loops, as boolean operations on solids make them: a
//! plate with a round hole, a box with a square through-hole, a box with a boss, and a cube.
//! `isocube subdivide sample:NAME` uses them.

use super::{Face, PolyMesh};

/// The built-in cages' names.
pub const SAMPLES: [&str; 4] = ["cube", "plate", "box-hole", "boss"];

/// A built-in cage by name (see [`SAMPLES`]).
///
/// ```
/// use isocube::subdiv::samples::sample;
/// let plate = sample("plate").unwrap();
/// assert_eq!(plate.faces[0].inner.len(), 1); // the top face has the hole
/// assert_eq!(plate.triangulate().unwrap().report().genus, Some(1));
/// ```
pub fn sample(name: &str) -> Option<PolyMesh> {
    Some(match name {
        "cube" => {
            let mut m = PolyMesh::default();
            let (b, t) = (
                ring(&mut m, &square(1.0), -1.0),
                ring(&mut m, &square(1.0), 1.0),
            );
            m.faces.push(Face::new(b.iter().rev().copied().collect()));
            m.faces.push(Face::new(t.clone()));
            for i in 0..4 {
                let j = (i + 1) % 4;
                m.faces.push(Face::new(vec![b[i], b[j], t[j], t[i]]));
            }
            m
        }
        "plate" => holed_prism(&square(2.0), &circle(1.0, 16), 0.5),
        "box-hole" => holed_prism(&square(2.0), &square(0.8), 2.0),
        "boss" => box_with_boss(),
        _ => return None,
    })
}

fn ring(m: &mut PolyMesh, pts: &[[f64; 2]], z: f64) -> Vec<u32> {
    pts.iter()
        .map(|p| {
            m.positions.push([p[0], p[1], z]);
            (m.positions.len() - 1) as u32
        })
        .collect()
}

/// A prism between z = 0 and z = h over a polygon with one polygonal hole (both
/// counter-clockwise in the plane): the top and bottom faces have inner loops, the sides and
/// the hole's wall are quads. Genus 1.
pub fn holed_prism(outer: &[[f64; 2]], hole: &[[f64; 2]], h: f64) -> PolyMesh {
    let mut m = PolyMesh::default();
    let (ob, ot) = (ring(&mut m, outer, 0.0), ring(&mut m, outer, h));
    let (hb, ht) = (ring(&mut m, hole, 0.0), ring(&mut m, hole, h));
    let rev = |v: &Vec<u32>| v.iter().rev().copied().collect::<Vec<u32>>();
    // Top: outer counter-clockwise seen from +z, hole clockwise. Bottom: the other way.
    m.faces.push(Face {
        outer: ot.clone(),
        inner: vec![rev(&ht)],
    });
    m.faces.push(Face {
        outer: rev(&ob),
        inner: vec![hb.clone()],
    });
    let n = outer.len();
    for i in 0..n {
        let j = (i + 1) % n;
        m.faces.push(Face::new(vec![ob[i], ob[j], ot[j], ot[i]]));
    }
    let k = hole.len();
    for i in 0..k {
        let j = (i + 1) % k;
        // The wall faces the hole's axis.
        m.faces.push(Face::new(vec![hb[j], hb[i], ht[i], ht[j]]));
    }
    m
}

/// `n` points on a circle of radius `r`, counter-clockwise.
pub fn circle(r: f64, n: usize) -> Vec<[f64; 2]> {
    (0..n)
        .map(|i| {
            let a = 2.0 * std::f64::consts::PI * (i as f64 + 0.5) / n as f64;
            [r * a.cos(), r * a.sin()]
        })
        .collect()
}

/// The square of half-side `s`, counter-clockwise.
pub fn square(s: f64) -> Vec<[f64; 2]> {
    vec![[-s, -s], [s, -s], [s, s], [-s, s]]
}

/// A box with a smaller box standing on its top face: the top face has the boss's footprint
/// as inner loop, shared with the boss's sides. Genus 0.
pub fn box_with_boss() -> PolyMesh {
    let mut m = PolyMesh::default();
    let (b0, b1) = (
        ring(&mut m, &square(2.0), 0.0),
        ring(&mut m, &square(2.0), 1.0),
    );
    let (f1, f2) = (
        ring(&mut m, &square(0.5), 1.0),
        ring(&mut m, &square(0.5), 1.5),
    );
    let rev = |v: &Vec<u32>| v.iter().rev().copied().collect::<Vec<u32>>();
    m.faces.push(Face::new(rev(&b0)));
    m.faces.push(Face {
        outer: b1.clone(),
        inner: vec![rev(&f1)],
    });
    m.faces.push(Face::new(f2.clone()));
    for (lo, hi) in [(&b0, &b1), (&f1, &f2)] {
        for i in 0..4 {
            let j = (i + 1) % 4;
            m.faces.push(Face::new(vec![lo[i], lo[j], hi[j], hi[i]]));
        }
    }
    m
}

/// A torus (radii 3 and 1) of `nu × nv` quads, or twice as many triangles: a large cage for
/// benchmarks.
pub fn torus(nu: usize, nv: usize, triangles: bool) -> PolyMesh {
    let mut m = PolyMesh::default();
    for i in 0..nu {
        for j in 0..nv {
            let (u, v) = (
                2.0 * std::f64::consts::PI * i as f64 / nu as f64,
                2.0 * std::f64::consts::PI * j as f64 / nv as f64,
            );
            let r = 3.0 + v.cos();
            m.positions.push([r * u.cos(), r * u.sin(), v.sin()]);
        }
    }
    let at = |i: usize, j: usize| ((i % nu) * nv + j % nv) as u32;
    for i in 0..nu {
        for j in 0..nv {
            let q = [at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)];
            if triangles {
                m.faces.push(Face::new(vec![q[0], q[1], q[2]]));
                m.faces.push(Face::new(vec![q[0], q[2], q[3]]));
            } else {
                m.faces.push(Face::new(q.to_vec()));
            }
        }
    }
    m
}
