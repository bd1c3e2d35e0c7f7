//! The unit tests' pseudo-random numbers: a 64-bit LCG, reproducible without a dependency.

/// Uniform in [−0.5, 0.5), advancing `seed`.
pub fn uniform(seed: &mut u64) -> f64 {
    *seed = seed
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    ((*seed >> 11) as f64 / (1u64 << 53) as f64) - 0.5
}
