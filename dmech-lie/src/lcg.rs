//! A 64-bit linear congruential generator (Knuth's MMIX constants): reproducible
//! pseudo-random numbers from a seed with no dependency, for the random groups, systems
//! and stages that the tests and benchmarks draw.

/// The generator's state; `Lcg(seed)` starts it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Lcg(pub u64);

impl Lcg {
    /// The next state.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        self.0
    }

    /// Uniform in `[−0.5, 0.5)`, from the state's top 53 bits.
    pub fn uniform(&mut self) -> f64 {
        ((self.next_u64() >> 11) as f64 / (1u64 << 53) as f64) - 0.5
    }

    /// Uniform in `[lo, hi)`.
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * (self.uniform() + 0.5)
    }
}
