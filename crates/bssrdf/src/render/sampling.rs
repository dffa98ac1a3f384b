//! How a pixel's samples are spread over the colour channels and the sample space (film jitter,
//! the decoder's latent z).
//!
//! The learned BSSRDF is sampled per channel (the decoder's proposal depends on σ_n,c and α_c),
//! so a camera sample of a medium whose channels differ serves one channel c, and the pixel
//! estimate of channel c is
//!
//!   I_c ≈ (1/spp) Σ_{s : c_s = c} w_s · f_c(X_s)
//!
//! with weights w_s that make it unbiased. Two schemes ([`PixelSampling`]):
//!
//! * [`PixelSampling::OneHot`] (docs/model.md A13, the paper): c_s uniform and independent per
//!   sample, w_s = 3. The number of samples a channel gets is binomial(spp, 1/3), which adds a
//!   relative variance of 2/spp per pixel on top of the BSSRDF's own (the "chromatic speckle").
//! * [`PixelSampling::Stratified`] (default): the channels take turns, c_s = (s + o) mod 3 with
//!   one uniform offset o ∈ {0, 1, 2} per pixel, so channel c gets exactly n_c ∈ {⌊spp/3⌋,
//!   ⌈spp/3⌉} samples and w_s = spp/n_c (conditionally unbiased given o; for spp < 3, where some
//!   n_c = 0, w_s = 3, unbiased because P(c_s = c) = 1/3 for every s). The j-th sample of channel
//!   c takes its film jitter and its four latent uniforms from point j of an Owen-scrambled Sobol
//!   sequence (Burley 2020) seeded per pixel and channel: dimensions 0–1 jitter, 2–5 the latent.
//!   Each channel's samples are then a stratified set in (jitter, z) rather than independent
//!   draws. A grey medium, whose every sample serves all three channels, uses the same sequence
//!   with j = s (its jitter is that of [`pixel_jitter`], bit for bit).
//!
//! Past 2¹⁶ samples per channel the sequence falls back to independent uniforms.

use base::pixel::pixel_jitter;
use base::rng::{Sampler, hash_key};

use crate::nn::LATENT_DIM;

/// How the samples of a pixel are assigned to channels and placed in the sample space.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "kebab-case")]
pub enum PixelSampling {
    /// The channels take turns, with scrambled Sobol samples per channel (default).
    ///
    /// Channels in turn with a random offset per pixel, weights spp/n_c, and per-channel
    /// Owen-scrambled Sobol jitter and latents (module docs).
    #[default]
    Stratified,
    /// A random channel per sample (the paper's scheme; noisier on coloured media).
    ///
    /// A uniformly random channel per sample with weight 3 and independent latents
    /// (docs/model.md A13; the paper's scheme).
    OneHot,
}

impl PixelSampling {
    /// The value of a settings file without the field (written before the choice existed).
    pub(super) fn absent() -> Self {
        PixelSampling::OneHot
    }

    /// The scheme named `name` (`stratified`, `one-hot`).
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "stratified" => Some(PixelSampling::Stratified),
            "one-hot" => Some(PixelSampling::OneHot),
            _ => None,
        }
    }
}

/// One camera sample's random numbers: film jitter, channel and its weight, latent uniforms.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct SampleDraw {
    pub(crate) jitter: (f32, f32),
    pub(crate) channel: usize,
    /// w_s of the module docs (unused for a grey medium, whose samples serve every channel).
    pub(crate) weight: f32,
    pub(crate) u: [f32; LATENT_DIM],
}

/// The draws of one pixel: [`PixelPlan::draw`] for s = 0, 1, …, spp − 1 in order.
pub(crate) struct PixelPlan {
    scheme: PixelSampling,
    grey: bool,
    spp: u32,
    /// The (seed, view, pixel) key of the jitter sequence.
    key: u64,
    /// Channel offset o (stratified).
    offset: u32,
    /// Weight spp/n_c per channel (stratified).
    weights: [f32; 3],
    /// Sobol seed per channel (stratified, coloured medium).
    seeds: [u32; 3],
    /// The pixel's sequential stream (one-hot; the fallback past 2¹⁶ samples).
    stream: Sampler,
}

const SOBOL_LIMIT: u32 = 1 << 16;

impl PixelPlan {
    pub(crate) fn new(scheme: PixelSampling, grey: bool, spp: u32, ids: [u64; 3]) -> Self {
        let [seed, view, pixel] = ids;
        let key = hash_key(&[seed, view, pixel, 1]);
        let stream = Sampler::new(seed, view, pixel, 0);
        let offset = (hash_key(&[seed, view, pixel, 3]) % 3) as u32;
        // n_c: the samples s < spp with s ≡ c − o (mod 3).
        let n_c = |c: u32| spp / 3 + u32::from((c + 3 - offset) % 3 < spp % 3);
        let weights = std::array::from_fn(|c| match n_c(c as u32) {
            n if spp >= 3 => spp as f32 / n as f32,
            _ => 3.0,
        });
        let seeds = std::array::from_fn(|c| hash_key(&[key, 4, c as u64]) as u32);
        PixelPlan {
            scheme,
            grey,
            spp,
            key,
            offset,
            weights,
            seeds,
            stream,
        }
    }

    /// The draw of sample `s` (call in order s = 0, 1, …: the one-hot scheme reads a stream).
    #[inline]
    pub(crate) fn draw(&mut self, s: u32) -> SampleDraw {
        debug_assert!(s < self.spp);
        match self.scheme {
            PixelSampling::OneHot => {
                let jitter = pixel_jitter(s, self.key, &mut self.stream);
                let channel = self.stream.next_below(3) as usize;
                let u = std::array::from_fn(|_| self.stream.next_f32());
                SampleDraw {
                    jitter,
                    channel,
                    weight: 3.0,
                    u,
                }
            }
            PixelSampling::Stratified => {
                let (channel, j, seed) = if self.grey {
                    (0, s, self.key as u32)
                } else {
                    let q = s + self.offset;
                    let c = (q % 3) as usize;
                    // Index within the channel: its samples are s ≡ c − o (mod 3), from 0 on.
                    let j = q / 3 - u32::from((c as u32) < self.offset);
                    (c, j, self.seeds[c])
                };
                let (jitter, u) = if j < SOBOL_LIMIT {
                    let [x, y, u0, u1] = sobol_burley::sample_4d(j, 0, seed);
                    let [u2, u3, _, _] = sobol_burley::sample_4d(j, 1, seed);
                    ((x, y), [u0, u1, u2, u3])
                } else {
                    let s = &mut self.stream;
                    let jitter = (s.next_f32(), s.next_f32());
                    (jitter, std::array::from_fn(|_| s.next_f32()))
                };
                SampleDraw {
                    jitter,
                    channel,
                    weight: self.weights[channel],
                    u,
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plan(scheme: PixelSampling, grey: bool, spp: u32, pixel: u64) -> Vec<SampleDraw> {
        let mut p = PixelPlan::new(scheme, grey, spp, [7, 2, pixel]);
        (0..spp).map(|s| p.draw(s)).collect()
    }

    /// Every channel gets ⌊spp/3⌋ or ⌈spp/3⌉ samples, and the weights of a channel's samples
    /// add up to spp (each channel's estimate is a plain mean of its samples).
    #[test]
    fn stratified_channels_take_turns() {
        for spp in 3..40 {
            for pixel in 0..30 {
                let d = plan(PixelSampling::Stratified, false, spp, pixel);
                for c in 0..3 {
                    let mine: Vec<_> = d.iter().filter(|d| d.channel == c).collect();
                    let n = mine.len() as u32;
                    assert!(n == spp / 3 || n == spp.div_ceil(3), "spp {spp}: {n}");
                    let total: f32 = mine.iter().map(|d| d.weight).sum();
                    assert!((total - spp as f32).abs() < 1e-3 * spp as f32);
                }
            }
        }
    }

    /// Each channel's samples are the first n_c points of its own sequence: their jitter is
    /// stratified (one point per 1/n_c-wide stratum of x for n_c a power of two).
    #[test]
    fn stratified_channel_points_are_a_sobol_prefix() {
        let d = plan(PixelSampling::Stratified, false, 48, 11);
        for c in 0..3 {
            let mut xs: Vec<f32> = d
                .iter()
                .filter(|d| d.channel == c)
                .map(|d| d.jitter.0)
                .collect();
            assert_eq!(xs.len(), 16);
            xs.sort_by(f32::total_cmp);
            for (k, x) in xs.iter().enumerate() {
                assert!(
                    (k as f32 / 16.0..(k + 1) as f32 / 16.0).contains(x),
                    "{xs:?}"
                );
            }
        }
    }

    /// Channel offsets are uniform over pixels (the unbiasedness of w = 3 for spp < 3).
    #[test]
    fn offsets_cover_the_channels() {
        let mut count = [0u32; 3];
        for pixel in 0..3000 {
            count[plan(PixelSampling::Stratified, false, 1, pixel)[0].channel] += 1;
        }
        // Binomial(3000, 1/3): s.d. 25.8; 5 s.d.
        for n in count {
            assert!((n as f64 - 1000.0).abs() < 5.0 * 25.8, "{count:?}");
        }
    }

    /// The grey scheme keeps `pixel_jitter`'s film positions.
    #[test]
    fn grey_jitter_is_the_pixel_jitter() {
        let d = plan(PixelSampling::Stratified, true, 16, 5);
        let key = hash_key(&[7, 2, 5, 1]);
        let mut s = Sampler::new(7, 2, 5, 0);
        for (i, d) in d.iter().enumerate() {
            assert_eq!(d.jitter, pixel_jitter(i as u32, key, &mut s));
        }
    }
}
