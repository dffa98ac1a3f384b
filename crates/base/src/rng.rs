//! Reproducible random streams. Every stream is derived from (seed, view, pixel, purpose) by a
//! SplitMix64-style hash, so results do not depend on thread scheduling (CONVENTIONS.md).

use rand::{Rng, SeedableRng};
use rand_pcg::Pcg32;

/// SplitMix64 finaliser: a bijective 64-bit mix.
#[inline]
pub fn mix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Hash a list of integers into one 64-bit key.
#[inline]
pub fn hash_key(parts: &[u64]) -> u64 {
    parts
        .iter()
        .fold(0x5851_F42D_4C95_7F2D, |h, &p| mix64(h ^ mix64(p)))
}

/// A per-pixel (or per-task) uniform random stream: PCG32 seeded from a hashed key.
pub struct Sampler {
    rng: Pcg32,
}

impl Sampler {
    /// Stream for `(seed, view, pixel)`; `purpose` separates independent uses of the same pixel.
    pub fn new(seed: u64, view: u64, pixel: u64, purpose: u64) -> Self {
        Sampler {
            rng: Pcg32::seed_from_u64(hash_key(&[seed, view, pixel, purpose])),
        }
    }

    /// Uniform in [0, 1) with 24 bits of resolution.
    #[inline]
    pub fn next_f32(&mut self) -> f32 {
        (self.rng.next_u32() >> 8) as f32 * (1.0 / 16_777_216.0)
    }

    /// Uniform integer in [0, n).
    #[inline]
    pub fn next_below(&mut self, n: u32) -> u32 {
        ((self.rng.next_u32() as u64 * n as u64) >> 32) as u32
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn streams_are_reproducible_and_distinct() {
        let mut a = Sampler::new(1, 2, 3, 0);
        let mut b = Sampler::new(1, 2, 3, 0);
        let mut c = Sampler::new(1, 2, 4, 0);
        let va: Vec<f32> = (0..8).map(|_| a.next_f32()).collect();
        let vb: Vec<f32> = (0..8).map(|_| b.next_f32()).collect();
        let vc: Vec<f32> = (0..8).map(|_| c.next_f32()).collect();
        assert_eq!(va, vb);
        assert_ne!(va, vc);
        assert!(va.iter().all(|&x| (0.0..1.0).contains(&x)));
    }

    #[test]
    fn next_below_is_in_range() {
        let mut s = Sampler::new(0, 0, 0, 0);
        let mut counts = [0u32; 3];
        for _ in 0..30_000 {
            counts[s.next_below(3) as usize] += 1;
        }
        // Binomial std of each count is sqrt(30000·(1/3)(2/3)) ≈ 82; 5σ bound.
        for c in counts {
            assert!((c as i64 - 10_000).abs() < 410, "{counts:?}");
        }
    }
}
