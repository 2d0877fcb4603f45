//! The vertex numbers of grid points, a few bits a point: the mesh's grid points are numbered
//! in grid order after the surface's vertices, and the zero points the surface passes through
//! (ternary) are its vertices there. A dense table of numbers would take four bytes a point,
//! more than the values themselves for a large, mostly empty grid.

/// Which grid points are numbered, and their numbers.
pub(super) struct Numbering {
    /// The first grid point's vertex number.
    base: u32,
    /// Numbered grid points, a bit each (x fastest).
    inside: Vec<u64>,
    /// Numbered grid points before each word of `inside`.
    before: Vec<u32>,
    /// Grid points that are surface vertices, a bit each.
    zero_bits: Vec<u64>,
    /// Those points and their vertices, by point.
    zero: Vec<(u32, u32)>,
}

impl Numbering {
    /// `zero` the surface's vertices at grid points (point, vertex), over `points` points.
    pub(super) fn new(points: usize, base: u32, mut zero: Vec<(u32, u32)>) -> Numbering {
        let words = points.div_ceil(64);
        let mut zero_bits = vec![0u64; words];
        zero.sort_unstable();
        for &(p, _) in &zero {
            zero_bits[p as usize / 64] |= 1 << (p % 64);
        }
        Numbering {
            base,
            inside: vec![0; words],
            before: vec![0; words],
            zero_bits,
            zero,
        }
    }

    /// Whether grid point `p` is a surface vertex.
    pub(super) fn is_zero(&self, p: usize) -> bool {
        self.zero_bits[p / 64] >> (p % 64) & 1 == 1
    }

    /// Numbers the grid points `points` (increasing), and no other.
    pub(super) fn number(&mut self, points: &[u32]) {
        self.inside.fill(0);
        for &p in points {
            self.inside[p as usize / 64] |= 1 << (p % 64);
        }
        let mut sum = 0u32;
        for (b, w) in self.before.iter_mut().zip(&self.inside) {
            *b = sum;
            sum += w.count_ones();
        }
    }

    /// The vertex of grid point `p` (`u32::MAX` for none).
    pub(super) fn get(&self, p: usize) -> u32 {
        let (w, b) = (p / 64, p % 64);
        let word = self.inside[w];
        if word >> b & 1 == 1 {
            self.base + self.before[w] + (word & ((1u64 << b) - 1)).count_ones()
        } else if self.zero_bits[w] >> b & 1 == 1 {
            let i = self
                .zero
                .binary_search_by_key(&(p as u32), |e| e.0)
                .expect("a zero point is listed");
            self.zero[i].1
        } else {
            u32::MAX
        }
    }

    /// The grid points numbered, in order.
    #[cfg(test)]
    fn numbered(&self) -> Vec<u32> {
        self.inside
            .iter()
            .enumerate()
            .flat_map(|(w, &word)| {
                (0..64)
                    .filter(move |b| word >> b & 1 == 1)
                    .map(move |b| (w * 64 + b) as u32)
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_follow_grid_order_after_the_surface() {
        let mut rng = crate::TestRng::new(7);
        for points in [1usize, 63, 64, 65, 1000, 4097] {
            let zero: Vec<(u32, u32)> = (0..points)
                .filter(|_| rng.next_u64() % 5 == 0)
                .enumerate()
                .map(|(v, p)| (p as u32, v as u32))
                .collect();
            let base = zero.len() as u32;
            let mut numbering = Numbering::new(points, base, zero.clone());
            let inside: Vec<u32> = (0..points as u32)
                .filter(|&p| zero.binary_search_by_key(&p, |e| e.0).is_err())
                .filter(|_| rng.next_u64() % 2 == 0)
                .collect();
            numbering.number(&inside);
            assert_eq!(numbering.numbered(), inside);
            for p in 0..points {
                let expected = if let Ok(r) = inside.binary_search(&(p as u32)) {
                    base + r as u32
                } else if let Ok(z) = zero.binary_search_by_key(&(p as u32), |e| e.0) {
                    zero[z].1
                } else {
                    u32::MAX
                };
                assert_eq!(numbering.get(p), expected, "{points} points, point {p}");
                assert_eq!(numbering.is_zero(p), zero.iter().any(|e| e.0 as usize == p));
            }
        }
    }
}
