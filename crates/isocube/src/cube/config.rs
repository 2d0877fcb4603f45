//! Configurations of the cube's vertex signs and their classes under symmetry groups.
//!
//! A binary configuration marks each vertex above (at or above the level) or below: index
//! `Σ 2^i` over the vertices above. A ternary configuration gives each vertex a digit
//! `d_i ∈ {0 below, 1 zero, 2 above}`: index `Σ d_i·3^i`.
//!
//! A [`ClassTable`] sorts every configuration into orbits under one of three groups
//! ([`Group`]): the 24 rotations; rotations with sign flip; or all 96 operations (rotations,
//! mirror, sign flip). The representative of a class is its smallest configuration index, and
//! classes are numbered from 1 in increasing order of their representatives, so class ids are
//! stable. Every configuration records the canonical [`Transform`] that maps its representative
//! onto it: the first one in [`Transform::all`] order.
//!
//! ```
//! use isocube::cube::{ClassTable, ConfigKind, Group};
//! let t = ClassTable::new(ConfigKind::Binary, Group::RotationsFlip);
//! assert_eq!(t.class_count(), 15); // the 15 cases of Lorensen and Cline
//! let e = t.entry(0b0000_0011); // vertices 0 and 1 above: one edge of the cube
//! assert_eq!(t.entry(e.representative as usize).class, e.class);
//! ```

use std::fmt;
use std::str::FromStr;
use std::sync::OnceLock;

use super::symmetry::Transform;

/// Binary (two signs) or ternary (below, zero, above) configurations.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ConfigKind {
    /// 256 configurations, digits 0 (below) and 1 (above).
    Binary,
    /// 6561 configurations, digits 0 (below), 1 (zero) and 2 (above).
    Ternary,
}

impl ConfigKind {
    /// The number base of a digit: 2 or 3.
    pub fn base(self) -> u8 {
        match self {
            ConfigKind::Binary => 2,
            ConfigKind::Ternary => 3,
        }
    }

    /// Number of configurations: 256 or 6561.
    pub fn count(self) -> usize {
        usize::from(self.base()).pow(8)
    }

    /// The per-vertex digits of a configuration index.
    pub fn digits(self, mut index: usize) -> [u8; 8] {
        let base = usize::from(self.base());
        let mut d = [0u8; 8];
        for digit in &mut d {
            *digit = (index % base) as u8;
            index /= base;
        }
        d
    }

    /// The configuration index of per-vertex digits.
    pub fn index(self, digits: [u8; 8]) -> usize {
        let base = usize::from(self.base());
        digits
            .iter()
            .rev()
            .fold(0, |acc, &d| acc * base + usize::from(d))
    }

    /// The sign-flipped configuration (above ↔ below; zero stays zero).
    pub fn flip(self, index: usize) -> usize {
        let b = self.base() - 1;
        self.index(self.digits(index).map(|d| b - d))
    }
}

/// The group a [`ClassTable`] is built for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum Group {
    /// The 24 rotations.
    Rotations,
    /// Rotations and sign flip (48 operations).
    #[default]
    RotationsFlip,
    /// Rotations, mirror and sign flip (96 operations).
    All,
}

impl Group {
    /// Whether a transform belongs to the group.
    pub fn contains(self, t: Transform) -> bool {
        match self {
            Group::Rotations => !t.mirror && !t.flip,
            Group::RotationsFlip => !t.mirror,
            Group::All => true,
        }
    }

    /// The group's transforms, in canonical order.
    pub fn transforms(self) -> impl Iterator<Item = Transform> {
        Transform::all().filter(move |&t| self.contains(t))
    }

    /// The name used on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Group::Rotations => "rotations",
            Group::RotationsFlip => "rotations+flip",
            Group::All => "all",
        }
    }
}

impl fmt::Display for Group {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Group {
    type Err = crate::ParseError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "rotations" => Ok(Group::Rotations),
            "rotations+flip" => Ok(Group::RotationsFlip),
            "all" => Ok(Group::All),
            _ => Err(crate::ParseError::new(
                "configuration kind",
                s,
                format!("unknown group '{s}': expected rotations, rotations+flip or all"),
            )),
        }
    }
}

/// What a [`ClassTable`] knows about one configuration.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ConfigEntry {
    /// 1-based class id.
    pub class: u16,
    /// The class representative (smallest configuration index in the orbit).
    pub representative: u16,
    /// Number of configurations in the class.
    pub orbit_size: u16,
    /// Class of the sign-flipped configuration.
    pub flip_class: u16,
    /// The canonical transform mapping the representative onto this configuration.
    pub transform: Transform,
}

impl ConfigEntry {
    /// The `perm` of the `tables` command: for every vertex `i`, this configuration's value at
    /// `i` equals the representative's value at `perm[i]` (sign-flipped when
    /// `transform.flip`).
    pub fn perm(&self) -> [u8; 8] {
        self.transform.inverse_vertex_map()
    }
}

/// Classes of all configurations of one kind under one group.
#[derive(Clone, Debug)]
pub struct ClassTable {
    kind: ConfigKind,
    group: Group,
    entries: Vec<ConfigEntry>,
    representatives: Vec<u16>,
}

impl ClassTable {
    /// Builds the table by enumerating orbits (fast: at most 6561 × 96 steps).
    pub fn new(kind: ConfigKind, group: Group) -> ClassTable {
        let n = kind.count();
        let base = kind.base();
        let unset = ConfigEntry {
            class: 0,
            representative: 0,
            orbit_size: 0,
            flip_class: 0,
            transform: Transform::IDENTITY,
        };
        let mut entries = vec![unset; n];
        let mut representatives = Vec::new();
        for rep in 0..n {
            if entries[rep].class != 0 {
                continue;
            }
            representatives.push(rep as u16);
            let class = representatives.len() as u16;
            let digits = kind.digits(rep);
            let mut members = Vec::new();
            for t in group.transforms() {
                let image = kind.index(t.apply_digits(digits, base));
                if entries[image].class == 0 {
                    entries[image] = ConfigEntry {
                        class,
                        representative: rep as u16,
                        orbit_size: 0,
                        flip_class: 0,
                        transform: t,
                    };
                    members.push(image);
                }
            }
            for &m in &members {
                entries[m].orbit_size = members.len() as u16;
            }
        }
        for c in 0..n {
            entries[c].flip_class = entries[kind.flip(c)].class;
        }
        ClassTable {
            kind,
            group,
            entries,
            representatives,
        }
    }

    /// The shared table of a kind and group, built once.
    pub fn get(kind: ConfigKind, group: Group) -> &'static ClassTable {
        static TABLES: [OnceLock<ClassTable>; 6] = [const { OnceLock::new() }; 6];
        let slot = match kind {
            ConfigKind::Binary => 0,
            ConfigKind::Ternary => 3,
        } + match group {
            Group::Rotations => 0,
            Group::RotationsFlip => 1,
            Group::All => 2,
        };
        TABLES[slot].get_or_init(|| ClassTable::new(kind, group))
    }

    /// Binary or ternary.
    pub fn kind(&self) -> ConfigKind {
        self.kind
    }

    /// The group the classes are orbits of.
    pub fn group(&self) -> Group {
        self.group
    }

    /// Number of classes.
    pub fn class_count(&self) -> usize {
        self.representatives.len()
    }

    /// Representatives in class order (class id `k` has representative `representatives()[k-1]`).
    pub fn representatives(&self) -> &[u16] {
        &self.representatives
    }

    /// The entry of one configuration. Panics if `config >= kind().count()`.
    pub fn entry(&self, config: usize) -> &ConfigEntry {
        &self.entries[config]
    }

    /// All entries, indexed by configuration.
    pub fn entries(&self) -> &[ConfigEntry] {
        &self.entries
    }

    /// Number of classes that are their own sign flip.
    pub fn flip_invariant_class_count(&self) -> usize {
        self.representatives
            .iter()
            .filter(|&&r| {
                let e = &self.entries[usize::from(r)];
                e.flip_class == e.class
            })
            .count()
    }

    /// Writes the table as TSV, one row per configuration, with the header
    /// `config representative class orbit_size flip_class perm flipped reversed`.
    pub fn write_tsv(&self, out: &mut impl std::io::Write) -> std::io::Result<()> {
        writeln!(
            out,
            "config\trepresentative\tclass\torbit_size\tflip_class\tperm\tflipped\treversed"
        )?;
        for (c, e) in self.entries.iter().enumerate() {
            let perm: String = e.perm().iter().map(|p| char::from(b'0' + p)).collect();
            writeln!(
                out,
                "{c}\t{}\t{}\t{}\t{}\t{perm}\t{}\t{}",
                e.representative,
                e.class,
                e.orbit_size,
                e.flip_class,
                u8::from(e.transform.flip),
                u8::from(e.transform.reverses_winding())
            )?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn binary_class_counts() {
        assert_eq!(
            ClassTable::new(ConfigKind::Binary, Group::Rotations).class_count(),
            23
        );
        assert_eq!(
            ClassTable::new(ConfigKind::Binary, Group::RotationsFlip).class_count(),
            15
        );
        assert_eq!(
            ClassTable::new(ConfigKind::Binary, Group::All).class_count(),
            14
        );
    }

    #[test]
    fn ternary_class_counts() {
        let rot = ClassTable::new(ConfigKind::Ternary, Group::Rotations);
        assert_eq!(rot.class_count(), 333);
        assert_eq!(rot.flip_invariant_class_count(), 33);
        assert_eq!(
            ClassTable::new(ConfigKind::Ternary, Group::RotationsFlip).class_count(),
            183
        );
        // (333 + 33) / 2: flip pairs up the non-invariant classes.
        assert_eq!((333 + 33) / 2, 183);
    }

    #[test]
    fn orbits_partition_and_sizes_divide_group_order() {
        for kind in [ConfigKind::Binary, ConfigKind::Ternary] {
            for (group, order) in [
                (Group::Rotations, 24),
                (Group::RotationsFlip, 48),
                (Group::All, 96),
            ] {
                let t = ClassTable::new(kind, group);
                let total: usize = t
                    .representatives()
                    .iter()
                    .map(|&r| usize::from(t.entry(usize::from(r)).orbit_size))
                    .sum();
                assert_eq!(total, kind.count());
                for (c, e) in t.entries().iter().enumerate() {
                    assert_eq!(order % usize::from(e.orbit_size), 0);
                    assert!(usize::from(e.representative) <= c);
                    assert_eq!(
                        t.representatives()[usize::from(e.class) - 1],
                        e.representative
                    );
                    assert!(group.contains(e.transform));
                    let members = t.entries().iter().filter(|x| x.class == e.class).count();
                    assert_eq!(members, usize::from(e.orbit_size));
                }
            }
        }
    }

    /// The `perm`/`flipped` definition of the `tables` command, checked for every configuration
    /// of every group: value at `i` = representative's value at `perm[i]`, flipped if set.
    #[test]
    fn perm_and_flipped_reproduce_every_configuration() {
        for kind in [ConfigKind::Binary, ConfigKind::Ternary] {
            let top = kind.base() - 1;
            for group in [Group::Rotations, Group::RotationsFlip, Group::All] {
                let t = ClassTable::new(kind, group);
                for (c, e) in t.entries().iter().enumerate() {
                    let rep = kind.digits(usize::from(e.representative));
                    let own = kind.digits(c);
                    let perm = e.perm();
                    for i in 0..8 {
                        let v = rep[usize::from(perm[i])];
                        let v = if e.transform.flip { top - v } else { v };
                        assert_eq!(own[i], v, "{kind:?} {group} config {c} vertex {i}");
                    }
                    assert_eq!(
                        e.transform.reverses_winding(),
                        e.transform.mirror ^ e.transform.flip
                    );
                }
            }
        }
    }

    #[test]
    fn flip_class_is_the_class_of_the_complement() {
        for kind in [ConfigKind::Binary, ConfigKind::Ternary] {
            let t = ClassTable::new(kind, Group::Rotations);
            for c in 0..kind.count() {
                let f = kind.flip(c);
                assert_eq!(kind.flip(f), c);
                assert_eq!(t.entry(c).flip_class, t.entry(f).class);
            }
            // With flip in the group, every class is its own flip class.
            let t = ClassTable::new(kind, Group::RotationsFlip);
            assert!(t.entries().iter().all(|e| e.flip_class == e.class));
        }
    }

    #[test]
    fn tsv_has_header_and_one_row_per_configuration() {
        let t = ClassTable::get(ConfigKind::Binary, Group::RotationsFlip);
        let mut buf = Vec::new();
        t.write_tsv(&mut buf).unwrap();
        let text = String::from_utf8(buf).unwrap();
        let mut lines = text.lines();
        assert_eq!(
            lines.next().unwrap(),
            "config\trepresentative\tclass\torbit_size\tflip_class\tperm\tflipped\treversed"
        );
        assert_eq!(lines.count(), 256);
    }
}
