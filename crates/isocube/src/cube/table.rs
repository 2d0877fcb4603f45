//! The binary case table: cell patches for every configuration, face-decision pattern and
//! interior (tunnel) decision, derived from the class representatives through the symmetry
//! group, and triangulated for both topologies.
//!
//! # Patches
//! A *patch* is a connected piece of surface inside a cell: a disk bounded by one loop, or, when
//! the trilinear interpolant joins two same-sign regions of the cell boundary through the
//! interior, a tunnel (annulus) bounded by the two loops around those regions. The loops are the
//! face-derived polygons of [`super::polygons`]; which regions may be joined is read off the
//! boundary [`Regions`]: any two distinct same-sign regions each bounded by a single loop.
//!
//! # Derivation through symmetry
//! Patches (disks and tunnels) are derived only for the 14 representatives of the full group
//! and every face-decision pattern; every other configuration obtains them through its transform:
//! corners by the edge map, decisions by the face map (inverted under flip), tunnels by the
//! vertex map of the regions they join, loops reversed when the transform reverses winding.
//!
//! # Topologies
//! - [`Topology::Classic`]: the face-consistent surface of Lorensen and Cline with the asymptotic
//!   decider on faces; disks only, each loop split into `n − 2` triangles.
//! - [`Topology::Mc33`]: the surface of the trilinear interpolant (the level of Chernyaev's
//!   Marching Cubes 33): tunnels where the interior joins two regions, and loops of seven or more
//!   corners (which only ambiguous faces produce) split around an interior vertex so the patch
//!   follows the surface through the cell's middle.

use std::collections::HashMap;
use std::fmt;
use std::str::FromStr;
use std::sync::OnceLock;

use rayon::prelude::*;

use super::config::{ClassTable, ConfigKind, Group};
use super::polygons::{
    ambiguous_faces, decision_patterns, derive_polygons, pack, transform_polygons, unpack, Corner,
    FaceDecisions, Regions,
};
use super::symmetry::Transform;
use super::triangulate::{band, band_through_ring, band_with_interior, safe_triangulation, star};

/// Which surface a cell gets.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum Topology {
    /// Face-consistent Marching Cubes (asymptotic decider on faces, no interior test).
    Classic,
    /// The topology of the trilinear interpolant, faces and interior (Marching Cubes 33 level).
    #[default]
    Mc33,
}

impl Topology {
    /// The name used on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Topology::Classic => "classic",
            Topology::Mc33 => "mc33",
        }
    }
}

impl fmt::Display for Topology {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Topology {
    type Err = crate::ParseError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "classic" => Ok(Topology::Classic),
            "mc33" => Ok(Topology::Mc33),
            _ => Err(crate::ParseError::new(
                "topology",
                s,
                format!("unknown topology '{s}': expected mc33 or classic"),
            )),
        }
    }
}

/// Where a triangulation's triangles are, and (a range of `interiors`) the supports of its
/// interior points: interior point `k` sits at the centroid of its support's corners.
#[derive(Clone, Copy, Debug, Default)]
struct Triangulation {
    triangles: (u32, u32),
    interiors: (u32, u32),
}

/// A tunnel the interior may open: the two same-sign regions it joins.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TunnelRegions {
    /// Vertices of the first region.
    pub first: u8,
    /// Vertices of the second region.
    pub second: u8,
}

#[derive(Clone, Copy, Debug)]
struct Tunnel {
    regions: TunnelRegions,
    /// Loops (indices into `polygon_ranges`) the tunnel joins.
    loops: (u32, u32),
    triangulation: Triangulation,
}

#[derive(Clone, Copy, Debug, Default)]
struct Variant {
    polygons: (u32, u32),
    classic: Triangulation,
    mc33: Triangulation,
    tunnels: (u32, u32),
}

/// The tube a tunnel puts between two loops.
enum Tube {
    /// Rungs between the loops.
    Band(Vec<[Corner; 3]>),
    /// Rungs across negative ambiguous faces are not admissible (see `may_join`); when they are
    /// needed, the tunnel passes through one interior point (the loops' centroid)…
    Interior(Vec<[Corner; 3]>),
    /// …or failing that through a ring of three, with their supports.
    Ring(Vec<[Corner; 3]>, Vec<Vec<Corner>>),
}

impl Tube {
    fn between(l1: &[Corner], l2: &[Corner]) -> Tube {
        if let Some(tube) = band(l1, l2) {
            Tube::Band(tube)
        } else if let Some(tube) = band_with_interior(l1, l2) {
            Tube::Interior(tube)
        } else {
            let (tube, supports) = band_through_ring(l1, l2);
            Tube::Ring(tube, supports)
        }
    }
}

/// What [`CaseTable::to_bytes`] writes first: a table of another layout is not read.
const STORED_MAGIC: &[u8] = b"isocube binary case table 1\n";

/// The binary case table as its derivation gives it (see [`CaseTable::binary`]); the test
/// `stored_binary_table_is_the_derived_one` fails when the derivation changes and rewrites the
/// file when run with `ISOCUBE_WRITE_TABLE=1`.
static STORED_BINARY: &[u8] = include_bytes!("mc33.table");

/// One representative's patches under one decision pattern: loops, and for each possible tunnel
/// the regions it joins and the two loops it connects.
struct RepresentativeCase {
    loops: Vec<Vec<Corner>>,
    tunnels: Vec<(TunnelRegions, usize, usize)>,
}

/// Patches and triangles of every binary configuration, face-decision pattern and tunnel.
///
/// Look-up at run time is a few array reads: the configuration's entry gives its ambiguous faces
/// and the first of its `2^k` variants (k ambiguous faces); the decisions of those faces, packed
/// in face order, select the variant; a variant lists the tunnels its interior may open (most
/// list none, and then no interior test is needed).
#[derive(Clone, Debug)]
pub struct CaseTable {
    ambiguous: [u8; 256],
    first_variant: [u32; 257],
    variants: Vec<Variant>,
    tunnels: Vec<Tunnel>,
    polygon_ranges: Vec<(u32, u32)>,
    corners: Vec<Corner>,
    triangles: Vec<[Corner; 3]>,
    /// Ranges of `support`, one per interior point.
    interiors: Vec<(u32, u32)>,
    support: Vec<Corner>,
}

/// A cell's patches as looked up: the triangles to emit and, for each interior point they use
/// ([`Corner::interior`]), the corners whose centroid places it (the loop it splits, or corners of
/// the tunnel it sits in).
#[derive(Clone, Copy, Debug)]
pub struct CellTriangles<'a> {
    /// Triangles over cell corners.
    pub triangles: &'a [[Corner; 3]],
    interiors: &'a [(u32, u32)],
    support: &'a [Corner],
}

impl<'a> CellTriangles<'a> {
    /// Number of interior points the triangles use.
    #[inline]
    pub fn interior_count(&self) -> usize {
        self.interiors.len()
    }

    /// The corners whose centroid places interior point `k`.
    #[inline]
    pub fn interior_support(&self, k: usize) -> &'a [Corner] {
        let (a, b) = self.interiors[k];
        &self.support[a as usize..b as usize]
    }
}

impl CaseTable {
    /// Loops of this many corners or more get an interior vertex under [`Topology::Mc33`].
    pub const MC33_STAR_CORNERS: usize = 7;

    /// The shared binary table. Its derivation (below) takes some ten milliseconds of search,
    /// so the table ships as the bytes that derivation gives (`mc33.table`, checked against it
    /// by the tests) and is only unpacked here; a build from source is the fallback should
    /// those bytes not unpack.
    pub fn binary() -> &'static CaseTable {
        static TABLE: OnceLock<CaseTable> = OnceLock::new();
        TABLE.get_or_init(|| {
            CaseTable::from_bytes(STORED_BINARY).unwrap_or_else(CaseTable::build_binary)
        })
    }

    /// The table as bytes: every field in order, lengths and numbers little-endian `u32`,
    /// corners as their codes (what the tests compare with, and write, `mc33.table`).
    #[cfg(test)]
    fn to_bytes(&self) -> Vec<u8> {
        let mut out = STORED_MAGIC.to_vec();
        let u32s = |out: &mut Vec<u8>, xs: &[u32]| {
            out.extend_from_slice(&(xs.len() as u32).to_le_bytes());
            xs.iter()
                .for_each(|x| out.extend_from_slice(&x.to_le_bytes()));
        };
        let t = |t: &Triangulation| [t.triangles.0, t.triangles.1, t.interiors.0, t.interiors.1];
        let pairs = |v: &[(u32, u32)]| v.iter().flat_map(|&(a, b)| [a, b]).collect::<Vec<u32>>();
        let codes = |v: &[Corner]| v.iter().map(|c| u32::from(c.code())).collect::<Vec<u32>>();
        u32s(&mut out, &self.ambiguous.map(u32::from));
        u32s(&mut out, &self.first_variant);
        let variants: Vec<u32> = self
            .variants
            .iter()
            .flat_map(|v| {
                let (p, k) = (v.polygons, v.tunnels);
                [[p.0, p.1], [k.0, k.1]]
                    .into_iter()
                    .flatten()
                    .chain(t(&v.classic))
                    .chain(t(&v.mc33))
            })
            .collect();
        u32s(&mut out, &variants);
        let tunnels: Vec<u32> = self
            .tunnels
            .iter()
            .flat_map(|k| {
                let r = k.regions;
                [
                    u32::from(r.first),
                    u32::from(r.second),
                    k.loops.0,
                    k.loops.1,
                ]
                .into_iter()
                .chain(t(&k.triangulation))
            })
            .collect();
        u32s(&mut out, &tunnels);
        u32s(&mut out, &pairs(&self.polygon_ranges));
        u32s(&mut out, &codes(&self.corners));
        u32s(&mut out, &codes(self.triangles.as_flattened()));
        u32s(&mut out, &pairs(&self.interiors));
        u32s(&mut out, &codes(&self.support));
        out
    }

    /// [`CaseTable::to_bytes`] read back, every range checked against what it points into
    /// (`None` for bytes that are not such a table).
    fn from_bytes(bytes: &[u8]) -> Option<CaseTable> {
        let mut rest = bytes.strip_prefix(STORED_MAGIC)?;
        let mut u32s = || -> Option<Vec<u32>> {
            let (len, tail) = rest.split_first_chunk::<4>()?;
            let len = u32::from_le_bytes(*len) as usize;
            let (body, tail) = tail.split_at_checked(len.checked_mul(4)?)?;
            rest = tail;
            Some(
                body.chunks_exact(4)
                    .map(|c| u32::from_le_bytes(c.try_into().expect("4 bytes")))
                    .collect(),
            )
        };
        let ambiguous: Vec<u32> = u32s()?;
        let first_variant = u32s()?;
        let variants = u32s()?;
        let tunnels = u32s()?;
        let polygon_ranges = u32s()?;
        let corners = u32s()?;
        let triangles = u32s()?;
        let interiors = u32s()?;
        let support = u32s()?;
        if !rest.is_empty() || variants.len() % 12 != 0 || tunnels.len() % 8 != 0 {
            return None;
        }
        let corner = |c: &u32| u8::try_from(*c).ok().and_then(Corner::from_code);
        let pairs = |v: &[u32]| -> Option<Vec<(u32, u32)>> {
            (v.len() % 2 == 0).then(|| v.chunks_exact(2).map(|p| (p[0], p[1])).collect())
        };
        let triangulation = |v: &[u32]| Triangulation {
            triangles: (v[0], v[1]),
            interiors: (v[2], v[3]),
        };
        let corners: Vec<Corner> = corners.iter().map(corner).collect::<Option<_>>()?;
        let flat: Vec<Corner> = triangles.iter().map(corner).collect::<Option<_>>()?;
        if flat.len() % 3 != 0 {
            return None;
        }
        let table = CaseTable {
            ambiguous: ambiguous
                .iter()
                .map(|&a| u8::try_from(a).ok())
                .collect::<Option<Vec<u8>>>()?
                .try_into()
                .ok()?,
            first_variant: first_variant.try_into().ok()?,
            variants: variants
                .chunks_exact(12)
                .map(|v| Variant {
                    polygons: (v[0], v[1]),
                    tunnels: (v[2], v[3]),
                    classic: triangulation(&v[4..8]),
                    mc33: triangulation(&v[8..12]),
                })
                .collect(),
            tunnels: tunnels
                .chunks_exact(8)
                .map(|k| {
                    Some(Tunnel {
                        regions: TunnelRegions {
                            first: u8::try_from(k[0]).ok()?,
                            second: u8::try_from(k[1]).ok()?,
                        },
                        loops: (k[2], k[3]),
                        triangulation: triangulation(&k[4..8]),
                    })
                })
                .collect::<Option<_>>()?,
            polygon_ranges: pairs(&polygon_ranges)?,
            corners,
            triangles: flat.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect(),
            interiors: pairs(&interiors)?,
            support: support.iter().map(corner).collect::<Option<_>>()?,
        };
        table.ranges_hold().then_some(table)
    }

    /// Whether every range in the table lies within what it indexes (look-ups index without
    /// checks of their own).
    fn ranges_hold(&self) -> bool {
        let within = |(a, b): (u32, u32), len: usize| a <= b && b as usize <= len;
        let triangulation = |t: &Triangulation| {
            within(t.triangles, self.triangles.len()) && within(t.interiors, self.interiors.len())
        };
        self.first_variant.windows(2).all(|w| w[0] <= w[1])
            && self.first_variant[256] as usize == self.variants.len()
            && (0..256).all(|c| {
                let count = 1u32 << self.ambiguous[c].count_ones();
                self.first_variant[c] + count == self.first_variant[c + 1]
            })
            && self.variants.iter().all(|v| {
                within(v.polygons, self.polygon_ranges.len())
                    && within(v.tunnels, self.tunnels.len())
                    && triangulation(&v.classic)
                    && triangulation(&v.mc33)
            })
            && self.tunnels.iter().all(|k| {
                (k.loops.0 as usize) < self.polygon_ranges.len()
                    && (k.loops.1 as usize) < self.polygon_ranges.len()
                    && triangulation(&k.triangulation)
            })
            && self
                .polygon_ranges
                .iter()
                .all(|&r| within(r, self.corners.len()))
            && self
                .interiors
                .iter()
                .all(|&r| within(r, self.support.len()))
    }

    fn build_binary() -> CaseTable {
        let classes = ClassTable::get(ConfigKind::Binary, Group::All);
        let mut representative_cases: HashMap<(u8, FaceDecisions), RepresentativeCase> =
            HashMap::new();
        for &rep in classes.representatives() {
            let rep = rep as u8;
            for d in decision_patterns(rep) {
                representative_cases.insert((rep, d), representative_case(rep, d));
            }
        }
        let mut table = CaseTable {
            ambiguous: [0; 256],
            first_variant: [0; 257],
            variants: Vec::new(),
            tunnels: Vec::new(),
            polygon_ranges: Vec::new(),
            corners: Vec::new(),
            triangles: Vec::new(),
            interiors: Vec::new(),
            support: Vec::new(),
        };
        // Each configuration's variants: the representative case and the transform that maps
        // it onto the configuration.
        let variants: Vec<Vec<(&RepresentativeCase, Transform)>> = (0..256usize)
            .map(|config| {
                let entry = classes.entry(config);
                let t = entry.transform;
                let rep = entry.representative as u8;
                let amb = ambiguous_faces(config as u8);
                let face_map = t.face_map();
                (0..(1u32 << amb.count_ones()))
                    .map(|packed| {
                        let decisions = unpack(amb, packed);
                        // Decision on the representative's face f is the configuration's
                        // decision on face g(f), inverted under flip (joined above ↔ joined
                        // below).
                        let mut rep_decisions = 0u8;
                        for (f, &image) in face_map.iter().enumerate() {
                            let bit = decisions >> image & 1;
                            rep_decisions |= (bit ^ u8::from(t.flip)) << f;
                        }
                        let case =
                            &representative_cases[&(rep, rep_decisions & ambiguous_faces(rep))];
                        (case, t)
                    })
                    .collect()
            })
            .collect();
        // The tunnels' tubes are nearly all of the work (a search per pair of loops). The same
        // pair comes back in many variants: each distinct pair is searched once, on every core,
        // then the table is laid out in order, so it is the same table.
        let mut pairs: HashMap<(Vec<Corner>, Vec<Corner>), usize> = HashMap::new();
        let mut order: Vec<(Vec<Corner>, Vec<Corner>)> = Vec::new();
        let wanted: Vec<Vec<Vec<usize>>> = variants
            .iter()
            .map(|list| {
                list.iter()
                    .map(|&(case, t)| {
                        let loops = transform_polygons(&case.loops, t);
                        case.tunnels
                            .iter()
                            .map(|&(_, i, j)| {
                                let key = (loops[i].clone(), loops[j].clone());
                                *pairs.entry(key.clone()).or_insert_with(|| {
                                    order.push(key);
                                    order.len() - 1
                                })
                            })
                            .collect()
                    })
                    .collect()
            })
            .collect();
        let tubes: Vec<Tube> = order
            .par_iter()
            .map(|(l1, l2)| Tube::between(l1, l2))
            .collect();
        for (config, (list, wanted)) in variants.iter().zip(wanted).enumerate() {
            table.ambiguous[config] = ambiguous_faces(config as u8);
            table.first_variant[config] = table.variants.len() as u32;
            for (&(case, t), wanted) in list.iter().zip(wanted) {
                table.push_variant(case, t, wanted.iter().map(|&k| &tubes[k]));
            }
        }
        table.first_variant[256] = table.variants.len() as u32;
        table
    }

    fn push_loops(&mut self, loops: &[Vec<Corner>]) -> (u32, u32) {
        let p0 = self.polygon_ranges.len() as u32;
        for p in loops {
            let c0 = self.corners.len() as u32;
            self.corners.extend_from_slice(p);
            self.polygon_ranges.push((c0, self.corners.len() as u32));
        }
        (p0, self.polygon_ranges.len() as u32)
    }

    /// Triangulates the loops `first..end` as disks, except those in `skip`; `star_from` is the
    /// corner count from which a loop is split around an interior point.
    fn push_disks(
        &mut self,
        (first, end): (u32, u32),
        skip: &[u32],
        star_from: usize,
    ) -> Triangulation {
        let t0 = self.triangles.len() as u32;
        let i0 = self.interiors.len() as u32;
        for p in first..end {
            if skip.contains(&p) {
                continue;
            }
            let (a, b) = self.polygon_ranges[p as usize];
            let polygon = self.corners[a as usize..b as usize].to_vec();
            let safe = (polygon.len() < star_from)
                .then(|| safe_triangulation(&polygon))
                .flatten();
            match safe {
                Some(tris) => self.triangles.extend(tris),
                None => {
                    // At most one loop per cell: two loops of 7+ corners would need 14 crossings
                    // and the few loops without a safe triangulation are 9-gons (checked by the
                    // tests).
                    assert_eq!(self.interiors.len() as u32, i0, "one split loop per cell");
                    self.push_support(&[&polygon]);
                    self.triangles.extend(star(&polygon));
                }
            }
        }
        Triangulation {
            triangles: (t0, self.triangles.len() as u32),
            interiors: (i0, self.interiors.len() as u32),
        }
    }

    /// Adds the support of one more interior point.
    fn push_support(&mut self, loops: &[&[Corner]]) {
        let s0 = self.support.len() as u32;
        for l in loops {
            self.support.extend_from_slice(l);
        }
        self.interiors.push((s0, self.support.len() as u32));
    }

    fn push_variant<'t>(
        &mut self,
        case: &RepresentativeCase,
        t: Transform,
        tubes: impl Iterator<Item = &'t Tube>,
    ) {
        let loops = transform_polygons(&case.loops, t);
        let range = self.push_loops(&loops);
        let classic = self.push_disks(range, &[], usize::MAX);
        let mc33 = self.push_disks(range, &[], Self::MC33_STAR_CORNERS);
        let map = t.vertex_map();
        let map_mask = |m: u8| {
            (0..8)
                .filter(|v| m >> v & 1 == 1)
                .fold(0u8, |acc, v| acc | 1 << map[v])
        };
        let k0 = self.tunnels.len() as u32;
        for (&(regions, i, j), tube) in case.tunnels.iter().zip(tubes) {
            let (li, lj) = (range.0 + i as u32, range.0 + j as u32);
            let mut triangulation = self.push_disks(range, &[li, lj], Self::MC33_STAR_CORNERS);
            match tube {
                Tube::Band(tube) => self.triangles.extend_from_slice(tube),
                Tube::Interior(tube) => {
                    assert_eq!(
                        triangulation.interiors.0, triangulation.interiors.1,
                        "disks beside a tunnel need no interior point"
                    );
                    self.push_support(&[&loops[i], &loops[j]]);
                    self.triangles.extend_from_slice(tube);
                }
                Tube::Ring(tube, supports) => {
                    assert_eq!(
                        triangulation.interiors.0, triangulation.interiors.1,
                        "disks beside a tunnel need no interior point"
                    );
                    for support in supports {
                        self.push_support(&[support]);
                    }
                    self.triangles.extend_from_slice(tube);
                }
            }
            triangulation.triangles.1 = self.triangles.len() as u32;
            triangulation.interiors.1 = self.interiors.len() as u32;
            self.tunnels.push(Tunnel {
                regions: TunnelRegions {
                    first: map_mask(regions.first),
                    second: map_mask(regions.second),
                },
                loops: (li, lj),
                triangulation,
            });
        }
        self.variants.push(Variant {
            polygons: range,
            classic,
            mc33,
            tunnels: (k0, self.tunnels.len() as u32),
        });
    }

    /// The ambiguous faces of a configuration (mask).
    #[inline]
    pub fn ambiguous_faces(&self, config: u8) -> u8 {
        self.ambiguous[usize::from(config)]
    }

    #[inline]
    fn variant(&self, config: u8, decisions: FaceDecisions) -> &Variant {
        let amb = self.ambiguous[usize::from(config)];
        let first = self.first_variant[usize::from(config)] as usize;
        &self.variants[first + pack(amb, decisions) as usize]
    }

    fn polygon(&self, p: u32) -> &[Corner] {
        let (a, b) = self.polygon_ranges[p as usize];
        &self.corners[a as usize..b as usize]
    }

    fn resolve(&self, t: &Triangulation) -> CellTriangles<'_> {
        CellTriangles {
            triangles: &self.triangles[t.triangles.0 as usize..t.triangles.1 as usize],
            interiors: &self.interiors[t.interiors.0 as usize..t.interiors.1 as usize],
            support: &self.support,
        }
    }

    /// The loops of a configuration under the given face decisions.
    pub fn polygons(
        &self,
        config: u8,
        decisions: FaceDecisions,
    ) -> impl Iterator<Item = &[Corner]> + '_ {
        let v = *self.variant(config, decisions);
        (v.polygons.0..v.polygons.1).map(move |p| self.polygon(p))
    }

    /// The tunnels the interior may open for this configuration and decisions (usually none).
    #[inline]
    pub fn tunnel_candidates(
        &self,
        config: u8,
        decisions: FaceDecisions,
    ) -> impl ExactSizeIterator<Item = TunnelRegions> + '_ {
        let v = self.variant(config, decisions);
        self.tunnels[v.tunnels.0 as usize..v.tunnels.1 as usize]
            .iter()
            .map(|t| t.regions)
    }

    /// Whether the interior may open a tunnel (so an interior test is worth running).
    #[inline]
    pub fn has_tunnel_candidates(&self, config: u8, decisions: FaceDecisions) -> bool {
        let v = self.variant(config, decisions);
        v.tunnels.0 != v.tunnels.1
    }

    /// The triangles of a cell: the classic surface, or under MC33 the disks and, if `tunnel`
    /// names one of [`CaseTable::tunnel_candidates`] by index, that tunnel.
    #[inline]
    pub fn cell_triangles(
        &self,
        config: u8,
        decisions: FaceDecisions,
        topology: Topology,
        tunnel: Option<usize>,
    ) -> CellTriangles<'_> {
        let v = self.variant(config, decisions);
        match (topology, tunnel) {
            (Topology::Classic, _) => self.resolve(&v.classic),
            (Topology::Mc33, None) => self.resolve(&v.mc33),
            (Topology::Mc33, Some(k)) => {
                let tunnel = &self.tunnels[v.tunnels.0 as usize + k];
                debug_assert!((v.tunnels.0 as usize + k) < v.tunnels.1 as usize);
                self.resolve(&tunnel.triangulation)
            }
        }
    }

    /// The two loops a tunnel joins.
    pub fn tunnel_loops(
        &self,
        config: u8,
        decisions: FaceDecisions,
        tunnel: usize,
    ) -> (&[Corner], &[Corner]) {
        let v = self.variant(config, decisions);
        let t = &self.tunnels[v.tunnels.0 as usize + tunnel];
        (self.polygon(t.loops.0), self.polygon(t.loops.1))
    }

    /// Total number of stored variants (configurations × decision patterns).
    pub fn variant_count(&self) -> usize {
        self.variants.len()
    }

    /// Total number of stored tunnel variants.
    pub fn tunnel_count(&self) -> usize {
        self.tunnels.len()
    }
}

/// Loops and possible tunnels of a representative, derived from face signs alone.
///
/// A tunnel joins two same-sign regions `Ra`, `Rb` through the interior. The tube around it
/// separates the channel from one opposite-sign region `P` that borders both, so its two loops
/// are the loop between `Ra` and `P` and the loop between `Rb` and `P`. Every such triple is a
/// candidate; the interior test says which pair (if any) is joined.
fn representative_case(rep: u8, decisions: FaceDecisions) -> RepresentativeCase {
    let loops = derive_polygons(rep, decisions);
    let regions = Regions::of(rep, decisions);
    let bounds: Vec<(u8, u8)> = loops.iter().map(|l| regions.of_loop(rep, l)).collect();
    let between = |above: u8, below: u8| bounds.iter().position(|&b| b == (above, below));
    let mut tunnels = Vec::new();
    for (same, other, above) in [
        (&regions.above, &regions.below, true),
        (&regions.below, &regions.above, false),
    ] {
        for x in 0..same.len() {
            for y in x + 1..same.len() {
                for &p in other.iter() {
                    let pair = |r: u8| if above { between(r, p) } else { between(p, r) };
                    if let (Some(i), Some(j)) = (pair(same[x]), pair(same[y])) {
                        tunnels.push((
                            TunnelRegions {
                                first: same[x],
                                second: same[y],
                            },
                            i,
                            j,
                        ));
                    }
                }
            }
        }
    }
    RepresentativeCase { loops, tunnels }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The shipped table is the derivation's, byte for byte, and reads back to it; bytes that
    /// are cut short or point out of range are refused.
    #[test]
    fn stored_binary_table_is_the_derived_one() {
        let derived = CaseTable::build_binary().to_bytes();
        if std::env::var_os("ISOCUBE_WRITE_TABLE").is_some() {
            let path = concat!(env!("CARGO_MANIFEST_DIR"), "/src/cube/mc33.table");
            std::fs::write(path, &derived).unwrap();
        }
        assert!(
            derived == STORED_BINARY,
            "src/cube/mc33.table is not what the derivation gives: rewrite it with \
             ISOCUBE_WRITE_TABLE=1 cargo test -p isocube --lib stored_binary_table"
        );
        let read = CaseTable::from_bytes(STORED_BINARY).expect("the stored table reads");
        assert_eq!(read.to_bytes(), derived);
        assert!(CaseTable::from_bytes(&derived[..derived.len() - 1]).is_none());
        // The last field is the support of interior points: a range past its end is refused.
        let mut table = read.clone();
        if let Some(last) = table.interiors.last_mut() {
            last.1 = table.support.len() as u32 + 1;
        }
        assert!(CaseTable::from_bytes(&table.to_bytes()).is_none());
    }
    use crate::cube::polygons::canonical;

    #[test]
    fn transformed_tunnels_equal_direct_tunnels() {
        let table = CaseTable::binary();
        for config in 0..=255u8 {
            for d in decision_patterns(config) {
                let direct = representative_case(config, d);
                let from_table: Vec<(TunnelRegions, Vec<Vec<Corner>>)> =
                    (0..table.tunnel_candidates(config, d).len())
                        .map(|k| {
                            let r = table.tunnel_candidates(config, d).nth(k).unwrap();
                            let (a, b) = table.tunnel_loops(config, d, k);
                            (r, canonical(&[a.to_vec(), b.to_vec()]))
                        })
                        .collect();
                let with_band: Vec<_> = direct.tunnels.iter().collect();
                assert_eq!(
                    from_table.len(),
                    with_band.len(),
                    "config {config} d {d:06b}"
                );
                for (regions, i, j) in with_band {
                    let loops = canonical(&[direct.loops[*i].clone(), direct.loops[*j].clone()]);
                    let found = from_table.iter().any(|(r, l)| {
                        let same = (r.first == regions.first && r.second == regions.second)
                            || (r.first == regions.second && r.second == regions.first);
                        same && *l == loops
                    });
                    assert!(
                        found,
                        "config {config} d {d:06b}: tunnel {regions:?} not derived"
                    );
                }
            }
        }
        assert!(table.tunnel_count() > 0);
    }

    /// Every stored triangulation is an oriented surface whose boundary is exactly the cell's
    /// loops: each loop edge used once in loop order, every other edge once each way.
    #[test]
    fn every_cell_patch_is_an_oriented_surface_bounded_by_its_loops() {
        let table = CaseTable::binary();
        for config in 0..=255u8 {
            for d in decision_patterns(config) {
                let loops: Vec<Vec<Corner>> =
                    table.polygons(config, d).map(<[Corner]>::to_vec).collect();
                let mut options = vec![(Topology::Classic, None), (Topology::Mc33, None)];
                options.extend(
                    (0..table.tunnel_candidates(config, d).len())
                        .map(|k| (Topology::Mc33, Some(k))),
                );
                for (topology, tunnel) in options {
                    let cell = table.cell_triangles(config, d, topology, tunnel);
                    let mut uses: HashMap<(Corner, Corner), i32> = HashMap::new();
                    for t in cell.triangles {
                        assert!(t[0] != t[1] && t[1] != t[2] && t[0] != t[2]);
                        for c in t {
                            if let Some(k) = c.as_interior() {
                                assert!(usize::from(k) < cell.interior_count());
                            }
                        }
                        for k in 0..3 {
                            *uses.entry((t[k], t[(k + 1) % 3])).or_insert(0) += 1;
                        }
                    }
                    let is_loop_edge = |a: Corner, b: Corner| {
                        loops
                            .iter()
                            .any(|l| (0..l.len()).any(|i| l[i] == a && l[(i + 1) % l.len()] == b))
                    };
                    for l in &loops {
                        for i in 0..l.len() {
                            let (a, b) = (l[i], l[(i + 1) % l.len()]);
                            assert_eq!(
                                uses.get(&(a, b)),
                                Some(&1),
                                "{config} {d:06b} {topology} {tunnel:?}: loop edge"
                            );
                            assert_eq!(
                                uses.get(&(b, a)),
                                None,
                                "{config} {d:06b} {topology} {tunnel:?}: loop edge reversed"
                            );
                        }
                    }
                    for (&(a, b), &n) in &uses {
                        assert_eq!(n, 1, "{config} {d:06b} {topology} {tunnel:?}: edge {a:?}-{b:?} used {n} times");
                        if !is_loop_edge(a, b) {
                            assert_eq!(
                                uses.get(&(b, a)),
                                Some(&1),
                                "{config} {d:06b} {topology} {tunnel:?}: open edge {a:?}-{b:?}"
                            );
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn topology_names_round_trip() {
        for t in [Topology::Classic, Topology::Mc33] {
            assert_eq!(t.name().parse::<Topology>().unwrap(), t);
        }
        assert!("mc34".parse::<Topology>().is_err());
    }
}
