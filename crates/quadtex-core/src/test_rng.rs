//! A deterministic pseudo-random sequence for unit tests: Knuth's MMIX
//! linear congruential generator, its top 53 bits as a float.

/// Uniform values in `[0, 1)`, the same sequence for the same `seed`.
pub(crate) fn uniform(seed: u64) -> impl FnMut() -> f64 {
    let mut state = seed;
    move || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    }
}
