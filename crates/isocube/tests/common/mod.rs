//! Helpers shared by the integration tests.

/// A small deterministic generator (xorshift64*), so failures reproduce from the seed alone.
pub struct Rng(pub u64);

impl Rng {
    pub fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }

    /// Uniform in (0, 1].
    pub fn unit(&mut self) -> f32 {
        ((self.next() >> 40) as f32 + 1.0) / (1u64 << 24) as f32
    }

    /// Uniform in (−1, 1].
    #[allow(dead_code)]
    pub fn signed(&mut self) -> f32 {
        self.unit() * 2.0 - 1.0
    }
}

/// Cube vertex `v` sits at grid index `GRID_INDEX[v]` of a 2×2×2 grid (x fastest), and grid
/// index `g` holds cube vertex `GRID_INDEX[g]` (the map is its own inverse).
#[allow(dead_code)]
pub const GRID_INDEX: [usize; 8] = [0, 1, 3, 2, 4, 5, 7, 6];
