//! Headless pictures of meshes: an orthographic software rasteriser with a depth buffer, Lambert
//! shading from a light over the viewer's shoulder, and an optional edge overlay that shows
//! every triangle (how the quality figures are drawn). No GPU, no window, the same pixels on
//! every machine.
//!
//! ```
//! use isocube::extract::{extract, ExtractOptions};
//! use isocube::field::Sample;
//! use isocube::render::{render, RenderOptions, View};
//!
//! let (mesh, _) = extract(&Sample::Torus.grid(24), &ExtractOptions::default()).unwrap();
//! let options = RenderOptions::new(160, 120).with_view(View::ISO).with_wireframe(true);
//! let picture = render(&mesh, &options);
//! assert_eq!(picture.rgb.len(), 160 * 120 * 3);
//! assert!(picture.coverage() > 0.1);
//! ```

use crate::mesh::{cross, dot, sub, Mesh};

/// Where the camera looks from: azimuth around +z from +x and elevation above the xy plane, in
/// degrees. The camera looks at the mesh's centre; +z is up on the picture (+y when looking
/// straight along z).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct View {
    /// Degrees around +z, from +x toward +y.
    pub azimuth: f64,
    /// Degrees above the xy plane.
    pub elevation: f64,
}

impl View {
    /// The isometric view: from (+1, +1, +1).
    pub const ISO: View = View {
        azimuth: 45.0,
        elevation: 35.264_389_682_754_654,
    };
    /// From +x.
    pub const X: View = View {
        azimuth: 0.0,
        elevation: 0.0,
    };
    /// From +y.
    pub const Y: View = View {
        azimuth: 90.0,
        elevation: 0.0,
    };
    /// From +z (above).
    pub const Z: View = View {
        azimuth: 0.0,
        elevation: 90.0,
    };
}

impl std::str::FromStr for View {
    type Err = crate::ParseError;

    /// `iso`, `x`, `y`, `z` or `AZIMUTH,ELEVATION` in degrees.
    fn from_str(s: &str) -> Result<View, crate::ParseError> {
        match s {
            "iso" => Ok(View::ISO),
            "x" => Ok(View::X),
            "y" => Ok(View::Y),
            "z" => Ok(View::Z),
            _ => {
                let parts: Vec<&str> = s.split(',').collect();
                let parsed: Vec<f64> = parts
                    .iter()
                    .filter_map(|p| p.trim().parse::<f64>().ok())
                    .filter(|x| x.is_finite())
                    .collect();
                match parsed[..] {
                    [azimuth, elevation] if parts.len() == 2 && elevation.abs() <= 90.0 => {
                        Ok(View {
                            azimuth,
                            elevation,
                        })
                    }
                    _ => Err(crate::ParseError::new("view", s, format!(
                        "unknown view '{s}': expected iso, x, y, z or AZIMUTH,ELEVATION in degrees (elevation within ±90)"
                    ))),
                }
            }
        }
    }
}

/// What to draw.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub struct RenderOptions {
    /// Picture width in pixels.
    pub width: usize,
    /// Picture height in pixels.
    pub height: usize,
    /// Camera direction.
    pub view: View,
    /// Draw every triangle's edges over the shading.
    pub wireframe: bool,
}

impl RenderOptions {
    /// A picture of `width × height` pixels, the other settings as [`RenderOptions::default`].
    pub fn new(width: usize, height: usize) -> RenderOptions {
        RenderOptions {
            width,
            height,
            ..RenderOptions::default()
        }
    }

    /// Sets the view direction.
    pub fn with_view(mut self, view: View) -> RenderOptions {
        self.view = view;
        self
    }

    /// Draws the triangles' edges over the shading, or not.
    pub fn with_wireframe(mut self, wireframe: bool) -> RenderOptions {
        self.wireframe = wireframe;
        self
    }
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            width: 800,
            height: 600,
            view: View::ISO,
            wireframe: false,
        }
    }
}

/// An RGB picture, rows from the top, 3 bytes a pixel.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Picture {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// `width · height · 3` bytes.
    pub rgb: Vec<u8>,
    /// Per pixel: whether the mesh covers it.
    pub covered: Vec<bool>,
}

impl Picture {
    /// The share of pixels the mesh covers.
    pub fn coverage(&self) -> f64 {
        if self.covered.is_empty() {
            return 0.0;
        }
        self.covered.iter().filter(|&&c| c).count() as f64 / self.covered.len() as f64
    }
}

const BACKGROUND: [f64; 3] = [1.0, 1.0, 1.0];
const FRONT: [f64; 3] = [0.55, 0.68, 0.85];
const BACK: [f64; 3] = [0.90, 0.62, 0.40];
const EDGE: [f64; 3] = [0.12, 0.14, 0.18];
/// The share of the picture's width or height the mesh spans.
const MARGIN: f64 = 0.9;
/// Samples per pixel along each axis (the picture is drawn 3× larger and averaged down).
const SUPER: usize = 3;

fn normalize(v: [f64; 3]) -> [f64; 3] {
    let l = dot(v, v).sqrt();
    if l > 0.0 {
        v.map(|c| c / l)
    } else {
        v
    }
}

/// Renders a mesh. Triangles facing away from the camera are drawn in a warm colour, so the
/// inside of an open surface is told from its outside; an empty mesh gives a blank picture.
pub fn render(mesh: &Mesh, options: &RenderOptions) -> Picture {
    let (w, h) = (options.width.max(1), options.height.max(1));
    let (sw, sh) = (w * SUPER, h * SUPER);
    // Camera frame: `forward` from the camera to the scene.
    let (az, el) = (
        options.view.azimuth.to_radians(),
        options.view.elevation.to_radians(),
    );
    let toward_camera = [el.cos() * az.cos(), el.cos() * az.sin(), el.sin()];
    let forward = toward_camera.map(|c| -c);
    let up_hint = if el.cos().abs() < 1e-6 {
        [-az.cos(), -az.sin(), 0.0].map(|c| c * el.sin().signum())
    } else {
        [0.0, 0.0, 1.0]
    };
    let right = normalize(cross(forward, up_hint));
    let up = cross(right, forward);
    // Fit the vertices' extent on the picture plane into the picture with a margin.
    let mut lo = [f64::INFINITY; 2];
    let mut hi = [f64::NEG_INFINITY; 2];
    for p in &mesh.positions {
        let p = p.map(f64::from);
        if p.iter().all(|c| c.is_finite()) {
            for (d, axis) in [right, up].into_iter().enumerate() {
                lo[d] = lo[d].min(dot(p, axis));
                hi[d] = hi[d].max(dot(p, axis));
            }
        }
    }
    let mut depth = vec![f32::INFINITY; sw * sh];
    let mut colour = vec![BACKGROUND; sw * sh];
    let mut hit = vec![false; sw * sh];
    if lo[0] <= hi[0] {
        let centre = [0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1])];
        let extent = [hi[0] - lo[0], hi[1] - lo[1]];
        let scale =
            MARGIN * (sw as f64 / extent[0].max(1e-30)).min(sh as f64 / extent[1].max(1e-30));
        let project = |p: [f32; 3]| -> [f64; 3] {
            let q = p.map(f64::from);
            [
                0.5 * sw as f64 + scale * (dot(q, right) - centre[0]),
                0.5 * sh as f64 - scale * (dot(q, up) - centre[1]),
                dot(q, forward),
            ]
        };
        let screen: Vec<[f64; 3]> = mesh.positions.iter().map(|&p| project(p)).collect();
        // A light over the viewer's left shoulder, and a little ambient.
        let light = normalize([0, 1, 2].map(|d| toward_camera[d] + 0.45 * up[d] - 0.35 * right[d]));
        let edge_width = 0.6 * SUPER as f64;
        for t in &mesh.triangles {
            let [a, b, c] = t.map(|i| screen[i as usize]);
            if [a, b, c].iter().flatten().any(|x| !x.is_finite()) {
                continue;
            }
            let world = t.map(|i| mesh.positions[i as usize].map(f64::from));
            let n = normalize(cross(sub(world[1], world[0]), sub(world[2], world[0])));
            let facing = dot(n, toward_camera);
            let (base, n) = if facing >= 0.0 {
                (FRONT, n)
            } else {
                (BACK, n.map(|c| -c))
            };
            let shade = 0.25 + 0.75 * dot(n, light).max(0.0);
            let lit = base.map(|c| (c * shade).min(1.0));
            // Signed doubled area in screen space; degenerate triangles draw nothing.
            let area = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
            if area.abs() < 1e-12 {
                continue;
            }
            let x0 = a[0].min(b[0]).min(c[0]).floor().max(0.0) as usize;
            let x1 = (a[0].max(b[0]).max(c[0]).ceil() as usize).min(sw - 1);
            let y0 = a[1].min(b[1]).min(c[1]).floor().max(0.0) as usize;
            let y1 = (a[1].max(b[1]).max(c[1]).ceil() as usize).min(sh - 1);
            if x0 > x1 || y0 > y1 {
                continue;
            }
            // Distances to the three edges, for the overlay: an edge's barycentric weight over
            // its height gives pixels.
            let side = |p: [f64; 3], q: [f64; 3]| ((q[0] - p[0]).hypot(q[1] - p[1])).max(1e-12);
            let heights = [
                area.abs() / side(b, c),
                area.abs() / side(c, a),
                area.abs() / side(a, b),
            ];
            for y in y0..=y1 {
                let py = y as f64 + 0.5;
                for x in x0..=x1 {
                    let px = x as f64 + 0.5;
                    let wa = ((b[0] - px) * (c[1] - py) - (b[1] - py) * (c[0] - px)) / area;
                    let wb = ((c[0] - px) * (a[1] - py) - (c[1] - py) * (a[0] - px)) / area;
                    let wc = 1.0 - wa - wb;
                    if wa < 0.0 || wb < 0.0 || wc < 0.0 {
                        continue;
                    }
                    let z = (wa * a[2] + wb * b[2] + wc * c[2]) as f32;
                    let i = y * sw + x;
                    if z >= depth[i] {
                        continue;
                    }
                    depth[i] = z;
                    hit[i] = true;
                    let on_edge = options.wireframe
                        && [wa, wb, wc]
                            .iter()
                            .zip(&heights)
                            .any(|(wt, ht)| wt * ht < edge_width);
                    colour[i] = if on_edge { EDGE } else { lit };
                }
            }
        }
    }
    // Average each SUPER × SUPER block.
    let mut rgb = vec![0u8; w * h * 3];
    let mut covered = vec![false; w * h];
    let samples = (SUPER * SUPER) as f64;
    for y in 0..h {
        for x in 0..w {
            let mut sum = [0.0f64; 3];
            let mut any = 0;
            for sy in 0..SUPER {
                for sx in 0..SUPER {
                    let i = (y * SUPER + sy) * sw + x * SUPER + sx;
                    for d in 0..3 {
                        sum[d] += colour[i][d];
                    }
                    any += usize::from(hit[i]);
                }
            }
            let o = (y * w + x) * 3;
            for d in 0..3 {
                rgb[o + d] = (255.0 * sum[d] / samples).round().clamp(0.0, 255.0) as u8;
            }
            covered[y * w + x] = 2 * any > SUPER * SUPER;
        }
    }
    Picture {
        width: w,
        height: h,
        rgb,
        covered,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::extract::{extract, ExtractOptions};
    use crate::field::Sample;

    #[test]
    fn a_sphere_fills_a_disc_of_the_expected_size() {
        let (mesh, _) = extract(&Sample::Sphere.grid(32), &ExtractOptions::default()).unwrap();
        for view in [
            View::ISO,
            View::X,
            View::Y,
            View::Z,
            View {
                azimuth: 200.0,
                elevation: -60.0,
            },
        ] {
            let p = render(
                &mesh,
                &RenderOptions {
                    width: 120,
                    height: 90,
                    view,
                    wireframe: false,
                },
            );
            assert_eq!((p.width, p.height, p.rgb.len()), (120, 90, 120 * 90 * 3));
            // A sphere looks like a disc 0.9 · 90 pixels across (the margin), π/4 of its square.
            let d = MARGIN * 90.0;
            let expected = std::f64::consts::FRAC_PI_4 * d * d / (120.0 * 90.0);
            let c = p.coverage();
            assert!(
                (c - expected).abs() < 0.1 * expected,
                "{view:?}: {c} vs {expected}"
            );
            // Shaded, not flat: the lit side is brighter than the rim.
            let lum: Vec<u32> = p
                .rgb
                .chunks(3)
                .zip(&p.covered)
                .filter(|(_, &c)| c)
                .map(|(px, _)| px.iter().map(|&v| u32::from(v)).sum())
                .collect();
            let (lo, hi) = (lum.iter().min().unwrap(), lum.iter().max().unwrap());
            assert!(hi - lo > 150, "{view:?}: shading range {lo}..{hi}");
        }
    }

    #[test]
    fn wireframe_draws_edges_and_views_differ() {
        let (mesh, _) = extract(&Sample::Torus.grid(24), &ExtractOptions::default()).unwrap();
        let options = RenderOptions {
            width: 100,
            height: 100,
            view: View::ISO,
            wireframe: false,
        };
        let plain = render(&mesh, &options);
        let wire = render(
            &mesh,
            &RenderOptions {
                wireframe: true,
                ..options
            },
        );
        let dark = |p: &Picture| {
            p.rgb
                .chunks(3)
                .filter(|px| px.iter().all(|&v| v < 110))
                .count()
        };
        assert!(
            dark(&wire) > dark(&plain) + 500,
            "{} vs {}",
            dark(&wire),
            dark(&plain)
        );
        assert_eq!(plain.covered, wire.covered);
        // The torus lies in the xy plane: seen from above it is a ring, from the side a band.
        let top = render(
            &mesh,
            &RenderOptions {
                view: View::Z,
                ..options
            },
        );
        let side = render(
            &mesh,
            &RenderOptions {
                view: View::X,
                ..options
            },
        );
        assert!(
            top.coverage() > 1.5 * side.coverage(),
            "{} {}",
            top.coverage(),
            side.coverage()
        );
        assert!(!top.covered[50 * 100 + 50], "the hole in the middle");
    }

    #[test]
    fn empty_meshes_and_bad_views() {
        let p = render(
            &Mesh::new(),
            &RenderOptions {
                width: 10,
                height: 5,
                ..RenderOptions::default()
            },
        );
        assert_eq!(p.coverage(), 0.0);
        assert!(p.rgb.iter().all(|&v| v == 255));
        assert_eq!(
            "30,20".parse::<View>().unwrap(),
            View {
                azimuth: 30.0,
                elevation: 20.0
            }
        );
        for bad in ["", "1", "1,2,3", "a,b", "0,91", "nan,0"] {
            assert!(bad.parse::<View>().is_err(), "{bad}");
        }
    }
}
