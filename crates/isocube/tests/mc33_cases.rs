//! The 33 configurations of Marching Cubes 33, each instantiated with concrete values.
//!
//! A configuration here is an orbit of (binary configuration, decisions on its ambiguous faces,
//! tunnel) under the 24 rotations and the sign flip. Cells with random values are classified
//! with `classify_cell` until every reachable orbit has an instance; each instance must give the
//! documented components and Euler characteristic with MC33, and agree with the refined truth.

use std::collections::BTreeMap;

use isocube::cube::polygons::ambiguous_faces;
use isocube::cube::{ClassTable, ConfigKind, Group, Topology, Transform};
use isocube::extract::{classify_cell, extract, ExtractOptions};
use isocube::field::Grid;

mod common;

use common::{Rng, GRID_INDEX};

fn map_mask(t: Transform, m: u8) -> u8 {
    let map = t.vertex_map();
    (0..8)
        .filter(|v| m >> v & 1 == 1)
        .fold(0, |acc, v| acc | 1 << map[v])
}

/// An orbit of cells: (configuration, decisions on its ambiguous faces, joined region masks).
type Key = (u8, u8, (u8, u8));

/// A documented configuration: name, key, components, Euler characteristic.
struct Documented {
    name: &'static str,
    key: Key,
    components: usize,
    euler: i64,
}

const fn doc(
    name: &'static str,
    config: u8,
    decisions: u8,
    tunnel: (u8, u8),
    components: usize,
    euler: i64,
) -> Documented {
    Documented {
        name,
        key: (config, decisions, tunnel),
        components,
        euler,
    }
}

/// The orbit key: the smallest (config, decisions, tunnel masks) over rotations and flip.
fn key(config: u8, decisions: u8, tunnel: Option<(u8, u8)>) -> Key {
    Group::RotationsFlip
        .transforms()
        .map(|t| {
            let c = ConfigKind::Binary
                .index(t.apply_digits(ConfigKind::Binary.digits(config.into()), 2))
                as u8;
            let fm = t.face_map();
            let mut d = 0u8;
            for (f, &image) in fm.iter().enumerate() {
                d |= ((decisions >> f & 1) ^ u8::from(t.flip)) << image;
            }
            let tunnel = tunnel.map_or((0, 0), |(a, b)| {
                let (a, b) = (map_mask(t, a), map_mask(t, b));
                (a.min(b), a.max(b))
            });
            (c, d & ambiguous_faces(c), tunnel)
        })
        .min()
        .unwrap()
}

/// Marching Cubes case number (Lorensen and Cline) of a class, from a member of each.
fn case_number(config: u8) -> u8 {
    let table = ClassTable::get(ConfigKind::Binary, Group::RotationsFlip);
    let set = |vs: &[u8]| vs.iter().fold(0usize, |acc, v| acc | 1 << v);
    let members = [
        (0, set(&[])),
        (1, set(&[0])),
        (2, set(&[0, 1])),
        (3, set(&[0, 2])),
        (4, set(&[0, 6])),
        (5, set(&[0, 1, 2])),
        (6, set(&[0, 1, 6])),
        (7, set(&[1, 3, 6])),
        (8, set(&[0, 1, 2, 3])),
        (9, set(&[0, 1, 3, 4])),
        (10, set(&[0, 1, 6, 7])),
        (11, set(&[0, 1, 3, 7])),
        (12, set(&[0, 1, 2, 7])),
        (13, set(&[0, 2, 5, 7])),
        (14, set(&[0, 1, 2, 6])),
    ];
    let class = table.entry(config.into()).class;
    members
        .iter()
        .find(|(_, m)| table.entry(*m).class == class)
        .map(|(n, _)| *n)
        .expect("15 classes")
}

fn topology(values: &[f32; 8], topology: Topology, k: usize) -> (usize, i64) {
    let grid = Grid::new([2, 2, 2], GRID_INDEX.iter().map(|&v| values[v]).collect()).unwrap();
    let grid = grid.upsample(k);
    let (mesh, _) = extract(&grid, &ExtractOptions::default().with_topology(topology)).unwrap();
    let r = mesh.report();
    (r.components, r.euler)
}

/// The documented table: name (Chernyaev's numbering, subcases in order of faces joined and
/// then tunnel), orbit key (configuration, ambiguous-face decisions, joined regions), and the
/// components and Euler characteristic of the cell's surface (a disk counts 1, a tunnel 0).
const CONFIGURATIONS: [Documented; 33] = [
    doc("0", 0, 0b000000, (0, 0), 0, 0),
    doc("1", 1, 0b000000, (0, 0), 1, 1),
    doc("2", 3, 0b000000, (0, 0), 1, 1),
    doc("3.1", 5, 0b000000, (0, 0), 2, 2),
    doc("3.2", 5, 0b010000, (0, 0), 1, 1),
    doc("4.1.1", 20, 0b000000, (0, 0), 2, 2),
    doc("4.1.2", 20, 0b000000, (4, 16), 1, 0),
    doc("5", 7, 0b000000, (0, 0), 1, 1),
    doc("6.1.1", 21, 0b000000, (0, 0), 2, 2),
    doc("6.1.2", 21, 0b000000, (4, 17), 1, 0),
    doc("6.2", 21, 0b010000, (0, 0), 1, 1),
    doc("7.1", 26, 0b000000, (0, 0), 3, 3),
    doc("7.2", 26, 0b000001, (0, 0), 2, 2),
    doc("7.3", 26, 0b001001, (0, 0), 1, 1),
    doc("7.4.1", 26, 0b011001, (0, 0), 2, 2),
    doc("7.4.2", 26, 0b011001, (1, 228), 1, 0),
    doc("8", 15, 0b000000, (0, 0), 1, 1),
    doc("9", 27, 0b000000, (0, 0), 1, 1),
    doc("10.1.1", 60, 0b000000, (0, 0), 2, 2),
    doc("10.1.2", 60, 0b000000, (12, 48), 1, 0),
    doc("10.2", 60, 0b000010, (0, 0), 1, 1),
    doc("11", 23, 0b000000, (0, 0), 1, 1),
    doc("12.1.1", 30, 0b000000, (0, 0), 2, 2),
    doc("12.1.2", 30, 0b000000, (14, 16), 1, 0),
    doc("12.2", 30, 0b000001, (0, 0), 1, 1),
    doc("12.3", 30, 0b001000, (0, 0), 1, 1),
    doc("13.1", 90, 0b000000, (0, 0), 4, 4),
    doc("13.2", 90, 0b000001, (0, 0), 3, 3),
    doc("13.3", 90, 0b000011, (0, 0), 2, 2),
    doc("13.4", 90, 0b010011, (0, 0), 1, 1),
    doc("13.5.1", 90, 0b010110, (0, 0), 3, 3),
    doc("13.5.2", 90, 0b010110, (4, 161), 2, 1),
    doc("14", 29, 0b000000, (0, 0), 1, 1),
];

#[test]
fn the_33_configurations() {
    let mut rng = Rng(33);
    // Up to four instances of every orbit met.
    let mut found: BTreeMap<Key, Vec<[f32; 8]>> = BTreeMap::new();
    let powers = [0.25f32, 0.5, 1.0, 2.0, 4.0];
    for _ in 0..200_000 {
        let config = (rng.next() % 256) as u8;
        let pa = powers[(rng.next() % 5) as usize];
        let pb = powers[(rng.next() % 5) as usize];
        let values: [f32; 8] = std::array::from_fn(|v| {
            let m = rng.unit().max(1e-3);
            if config >> v & 1 == 1 {
                m.powf(pa)
            } else {
                -m.powf(pb)
            }
        });
        let case = classify_cell(&values, 0.0, Topology::Mc33);
        let k = key(
            case.config,
            case.decisions,
            case.tunnel.map(|t| (t.first, t.second)),
        );
        let list = found.entry(k).or_default();
        if list.len() < 4 {
            list.push(values);
        }
    }
    // Exactly the 33 documented configurations occur.
    let documented: BTreeMap<Key, &Documented> =
        CONFIGURATIONS.iter().map(|d| (d.key, d)).collect();
    assert_eq!(documented.len(), 33);
    let keys: Vec<_> = found.keys().copied().collect();
    let expected: Vec<_> = documented.keys().copied().collect();
    assert_eq!(keys, expected, "the orbits met are not the documented 33");
    for (k, instances) in &found {
        let Documented {
            name,
            components: comps,
            euler,
            ..
        } = *documented[k];
        assert_eq!(
            case_number(k.0).to_string(),
            name.split('.').next().unwrap(),
            "{name}"
        );
        let mut confirmed = 0;
        for values in instances {
            assert_eq!(
                topology(values, Topology::Mc33, 1),
                (comps, euler),
                "{name}: {values:?}"
            );
            let (t16, t32) = (
                topology(values, Topology::Classic, 16),
                topology(values, Topology::Classic, 32),
            );
            if t16 == t32 {
                assert_eq!(t32, (comps, euler), "{name}: truth differs for {values:?}");
                confirmed += 1;
            }
        }
        assert!(confirmed > 0, "{name}: no stable instance");
    }
}
