//! Per-render settings and the pixel samples: pixel positions use Owen-scrambled Sobol points
//! (Burley 2020) per pixel for the first 2¹⁶ samples, then the pixel's PCG32 stream.

use crate::rng::Sampler;

/// Per-render settings.
#[derive(Clone, Copy, Debug)]
pub struct RenderSettings {
    pub spp: u32,
    pub seed: u64,
    /// Index of the view (part of every random stream's key).
    pub view: u64,
}

/// Pixel jitter for sample `i` of the pixel with scramble key `key`.
#[inline]
pub fn pixel_jitter(i: u32, key: u64, s: &mut Sampler) -> (f32, f32) {
    if i < (1 << 16) {
        // Dimensions 0 and 1 of `sobol_burley::sample`, computed together (the same values;
        // the index scramble is shared and the dimensions run in SIMD lanes).
        let [x, y, _, _] = sobol_burley::sample_4d(i, 0, key as u32);
        (x, y)
    } else {
        (s.next_f32(), s.next_f32())
    }
}
