//! Transmittance of a shadow ray from a scattering vertex inside the medium to the point light.
//!
//! The NEE contribution of channel c is β_c · f_p · T_c · I_c / r² with
//! T_c = exp(−σ_t,c · ℓ), ℓ the length of the shadow segment inside the closed mesh (re-entries of
//! a concave surface included). Two unbiased estimators of T_c:
//!
//! * [`ShadowTransmittance::Exact`]: ℓ from one all-hits query along the whole segment
//!   ([`geometry::Accel::inside_length`]), T_c evaluated in closed form. No variance, but the
//!   all-hits query cannot stop at the first crossing and costs about as much as the rest of the
//!   path together.
//! * [`ShadowTransmittance::Tracked`]: the estimator Mitsuba 3's `volpath` uses for homogeneous
//!   media (delta tracking with a null-free majorant): draw an optical budget
//!   b ~ Exp(σ̄) with σ̄ = min_c σ_t,c, walk the segment with closest-hit queries limited to the
//!   remaining budget while inside and to the light while outside; if the budget runs out inside
//!   the medium the estimate is 0, otherwise it is
//!
//!   T̂_c = exp(−σ_t,c ℓ) / P(b > ℓ) = exp(−(σ_t,c − σ̄) ℓ) ≤ 1,
//!
//!   whose expectation is exp(−σ_t,c ℓ) exactly (P(b > ℓ) = exp(−σ̄ ℓ)). Deep vertices, whose
//!   light is almost all absorbed, end after one short query (the budget is short) instead of a
//!   traversal of the whole segment; the price is variance where T is small.
//!
//! With σ̄ the smallest extinction every channel's weight is ≤ 1 and the survival probability is
//! the largest any exponential budget with rate ≥ min σ_t can give, so no channel gets fireflies.
//!
//! `Exact` reads ℓ from the light's per-direction triangle lists when the renderer built them
//! ([`geometry::LightBins`]: the same value as the BVH's, bit for bit, from a few triangle tests).
//!
//! Measured on the Mitsuba reference sphere (docs/notes/tracer-speed.md, "Shadow rays through the
//! light's triangle lists"): with the lists `Exact` renders as many paths per second as `Tracked`
//! (before them `Tracked` rendered 1.25–1.3× more), and its variance per path is 1.4–1.5× lower,
//! so `Exact` is the default; `Tracked` is what Mitsuba 3 runs, for like-for-like comparisons.

use geometry::{Accel, LightBins, bvh::offset_origin};
use glam::Vec3;

use crate::rng::Sampler;

/// Estimator of the shadow ray's transmittance (see the module documentation).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum ShadowTransmittance {
    /// exp(−σ_t ℓ) from the exact inside length: the least noise per second (default).
    ///
    /// Closed-form exp(−σ_t ℓ) from the exact inside length (one all-hits query). The default:
    /// the least noise per second of render time (measured in docs/notes/tracer-speed.md).
    #[default]
    Exact,
    /// Delta tracking, as Mitsuba 3: more paths per second, more noise per path.
    ///
    /// Delta tracking with the smallest extinction as the sampling rate (Mitsuba 3's scheme):
    /// more paths per second, more noise per path.
    Tracked,
}

impl ShadowTransmittance {
    /// Transmittance estimate per channel of the segment `p → light` for a vertex `p` inside the
    /// medium of extinction `sigma_t`. `Tracked` draws one uniform number from `s`. `bins`, when
    /// given, must be built for `light` over `accel`: `Exact` then reads the inside length from
    /// them (the same value as the BVH's, with a few triangle tests).
    #[inline]
    pub fn estimate(
        self,
        accel: &Accel,
        bins: Option<&LightBins>,
        sigma_t: &[f32; 3],
        p: Vec3,
        light: Vec3,
        s: &mut Sampler,
    ) -> [f32; 3] {
        self.estimate_with_length(accel, bins, sigma_t, p, light, s)
            .0
    }

    /// [`ShadowTransmittance::estimate`] and the inside length ℓ of the segment (0 where the
    /// tracked estimate is 0: its budget ran out before ℓ was known). For either estimator
    /// T̂_c·(−ℓ) is an unbiased estimate of ∂T_c/∂σ_t,c = −ℓ·exp(−σ_t,c ℓ) (for `Tracked` the
    /// majorant σ̄ is a sampling choice, held fixed).
    #[inline]
    pub fn estimate_with_length(
        self,
        accel: &Accel,
        bins: Option<&LightBins>,
        sigma_t: &[f32; 3],
        p: Vec3,
        light: Vec3,
        s: &mut Sampler,
    ) -> ([f32; 3], f32) {
        match self {
            ShadowTransmittance::Exact => {
                let len = match bins {
                    Some(b) => {
                        debug_assert_eq!(b.light(), light);
                        b.inside_length(accel, p)
                    }
                    None => accel.inside_length(p, light),
                };
                (sigma_t.map(|st| (-st * len).exp()), len)
            }
            ShadowTransmittance::Tracked => {
                let sigma_bar = sigma_t[0].min(sigma_t[1]).min(sigma_t[2]);
                let budget = -(1.0 - s.next_f32()).ln() / sigma_bar;
                match tracked_inside_length(accel, p, light, budget) {
                    Some(len) => (sigma_t.map(|st| (-(st - sigma_bar) * len).exp()), len),
                    None => ([0.0; 3], 0.0),
                }
            }
        }
    }
}

/// Upper bound on surface crossings followed along one shadow segment (a ray grazing a vertex
/// of a pathological mesh must not loop).
const MAX_CROSSINGS: u32 = 64;

/// Walk `p → light` from inside the medium with an in-medium length budget: the length ℓ of the
/// segment inside the mesh when it is at most `budget`, `None` when the budget runs out inside.
///
/// Inside, each query is a closest hit limited to min(budget left, distance left), so a
/// collision costs one short query. Outside, it is a closest hit to the light; a hit there is a
/// re-entry (a concave surface) and the walk goes on inside; after leaving through a triangle
/// whose plane supports the mesh ([`Accel::exit_is_final`]) there can be none, and that query is
/// skipped. Whether a crossing leaves or enters is read from the hit's facing, as everywhere in
/// the tracer.
pub fn tracked_inside_length(accel: &Accel, p: Vec3, light: Vec3, budget: f32) -> Option<f32> {
    let seg = light - p;
    let dist = seg.length();
    if !(dist > 0.0 && dist.is_finite()) {
        return Some(0.0);
    }
    let d = seg / dist;
    let mut o = p;
    let mut travelled = 0.0f32;
    let mut len_in = 0.0f32;
    let mut budget = budget;
    let mut inside = true;
    for _ in 0..MAX_CROSSINGS {
        let left = dist - travelled;
        if left <= 0.0 {
            return Some(len_in);
        }
        if inside {
            let tmax = budget.min(left);
            match accel.closest(o, d, 0.0, tmax) {
                None if budget < left => return None,
                // The light itself lies inside the mesh and the budget reaches it.
                None => return Some(len_in + left),
                Some(hit) => {
                    len_in += hit.t;
                    budget -= hit.t;
                    travelled += hit.t;
                    inside = hit.entering(d);
                    if !inside && accel.exit_is_final(hit.tri) {
                        // Left through a supporting plane: nothing of the mesh lies ahead.
                        return Some(len_in);
                    }
                    o = offset_origin(hit.p, hit.ng, d);
                }
            }
        } else {
            match accel.closest(o, d, 0.0, left) {
                None => return Some(len_in),
                Some(hit) => {
                    travelled += hit.t;
                    inside = hit.entering(d);
                    o = offset_origin(hit.p, hit.ng, d);
                }
            }
        }
    }
    Some(len_in)
}
