//! Derivatives of the tracer's images with respect to the medium: ∂I/∂σ_t and ∂I/∂α per
//! channel, and ∂I/∂g per channel (channel c with respect to its own g_c; with one g for every
//! channel, ∂I_c/∂g), from the same paths as the image itself.
//!
//! A contribution of a path (a next-event estimate at a scattering vertex, or the environment
//! where the path escapes) after k real scatterings, with total length ℓ inside the medium (the
//! free flights, plus the shadow segment's inside length for a next-event estimate), has the
//! measurement contribution
//!
//!   f_c = σ_s,c^k · e^{−σ_t,c ℓ} · G = α_c^k σ_t,c^k e^{−σ_t,c ℓ} · G
//!
//! in channel c, where G (phase functions, 1/r², the light, Fresnel factors) does not depend on
//! σ_t or α. Of G, only the phase-function factors p_{g_c}(cos θ_i) depend on g: one per
//! sampled direction at a scattering vertex, and one for a connection's direction at the last.
//! The image is I_c = ∫ f_c dμ over path space; neither the space (vertex positions inside a
//! fixed mesh) nor its measure depends on the medium, so
//!
//!   ∂I_c/∂σ_t,c = ∫ f_c (k/σ_t,c − ℓ) dμ,    ∂I_c/∂α_c = ∫ f_c (k/α_c) dμ,
//!   ∂I_c/∂g_c = ∫ f_c Σ_i ∂ ln p_{g_c}(cos θ_i)/∂g_c dμ,
//!
//! and the tracer's own estimator f_c/p of each path, multiplied by the score in brackets, is an
//! unbiased estimate of them. The sampling density p (hero-channel free flights with spectral
//! MIS, Russian roulette, the tracked shadow estimator's majorant) depends on the medium too,
//! but it is the sampling, not the integrand: holding the sampled path fixed and differentiating
//! only f is exact, and no boundary term arises because the mesh, the domain of every free
//! flight, does not move with σ_t, α or g. The multiple-importance weights of the rough
//! boundary's guided connection are part of the sampling too: they sum to one whatever g they
//! were computed at. This is the derivative that path replay (Vicini et al.
//! 2021, "Path Replay Backpropagation", §4 and its volumetric form in Mitsuba 3's `prbvolpath`)
//! propagates for a homogeneous medium with detached sampling, written here in closed form per
//! path: the medium enters each path only through k and ℓ.
//!
//! Notes:
//! - The derivative of channel c depends only on channel c's parameters (the spectral MIS
//!   weights are part of p).
//! - At α_c = 0 a path that scattered carries no weight, so ∂I_c/∂α_c is not estimated there
//!   (reported as 0).
//! - The score k/σ_t − ℓ has mean zero over a path's flights and a spread that grows like √k,
//!   so the derivative images of long walks (high albedo, large objects in mean free paths) are
//!   noisier than the value image.

use scene::Image;

use crate::tally::{PathScore, Tally};

/// One path's radiance and its derivatives with respect to σ_t, α and g, per channel
/// ([`crate::trace`] with this tally).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PathDerivatives {
    /// The radiance (what [`crate::radiance`] returns for the same path).
    pub value: [f32; 3],
    /// ∂/∂σ_t,c of the radiance of channel c.
    pub d_sigma_t: [f32; 3],
    /// ∂/∂α_c of the radiance of channel c.
    pub d_albedo: [f32; 3],
    /// ∂/∂g_c of the radiance of channel c (∂/∂g with one g for every channel).
    pub d_g: [f32; 3],
}

impl Tally for PathDerivatives {
    /// Value, ∂/∂σ_t, ∂/∂α and ∂/∂g, per channel.
    type Sum = [[f64; 3]; 4];
    const SCORES_PHASE: bool = true;

    #[inline]
    fn add_to(&self, sum: &mut Self::Sum) {
        for c in 0..3 {
            sum[0][c] += self.value[c] as f64;
            sum[1][c] += self.d_sigma_t[c] as f64;
            sum[2][c] += self.d_albedo[c] as f64;
            sum[3][c] += self.d_g[c] as f64;
        }
    }

    #[inline]
    fn record(&mut self, c: [f32; 3], score: PathScore, sigma_t: &[f32; 3], albedo: &[f32; 3]) {
        let (k, len) = (score.k as f32, score.len);
        for ch in 0..3 {
            self.d_g[ch] += c[ch] * score.phase[ch];
            self.value[ch] += c[ch];
            self.d_sigma_t[ch] += c[ch] * (k / sigma_t[ch] - len);
            if albedo[ch] > 0.0 {
                self.d_albedo[ch] += c[ch] * (k / albedo[ch]);
            }
        }
    }

    #[inline]
    fn finish(&mut self) {
        for v in self
            .value
            .iter_mut()
            .chain(&mut self.d_sigma_t)
            .chain(&mut self.d_albedo)
            .chain(&mut self.d_g)
        {
            if !v.is_finite() {
                *v = 0.0;
            }
        }
    }
}

/// A view rendered with its derivatives ([`crate::render_derivatives`]).
#[derive(Clone, Debug)]
pub struct DerivativeImages {
    /// The image.
    pub value: Image,
    /// ∂I/∂σ_t per pixel and channel (channel c with respect to σ_t,c).
    pub d_sigma_t: Image,
    /// ∂I/∂α per pixel and channel.
    pub d_albedo: Image,
    /// ∂I/∂g per pixel and channel (channel c with respect to g_c).
    pub d_g: Image,
}
