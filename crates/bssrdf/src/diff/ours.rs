//! The paper's estimator, `ours` (Son et al. 2024 §4.2–4.3, eq. 15–17; docs/model.md §8.1–8.2,
//! A6). σ_t by correlated offset samples: x_i^± = Π(x_o + σ_n(σ_t ± Δ)·R·y^±) with the same z,
//! channel, projection rule and fixed polynomial, each with the full light evaluation (V, cos,
//! Sw, 1/r²):
//!
//!   ∂C/∂σ_t ≈ (1 − F)·(S_abs⁺·L(x_i⁺) − S_abs⁻·L(x_i⁻))/(2Δ),  Δ = `delta_rel`·σ_t (A7).
//!
//! With a frozen descriptor y^± = y and S_abs^± = S_abs (the paper exactly); with the rescaled
//! one y^± and S_abs^± come from the networks run again at σ_n(σ_t ± Δ). A miss or an occluded
//! offset sample contributes 0: that carries the boundary (visibility) term. α with the
//! positions detached: ∂C/∂α = −∂Absorb/∂α·(1 − F)·L(x_i) + S_abs·(1 − F)·∂L/∂α ([`super::row`]).

use super::row::{Sample, SampleEstimator};

/// The `ours` estimator.
pub(super) struct Ours;

impl SampleEstimator for Ours {
    const PAIR: bool = true;

    fn offset_sets(moving: bool) -> usize {
        if moving { 2 } else { 0 }
    }

    fn d_sigma_t(s: &Sample) -> f32 {
        let (cp, cm) = s.pair.expect("the offset pair of ours");
        s.p.t_cam * (cp - cm) * s.k.inv_2dt[s.c]
    }

    fn d_albedo(_: &Sample) -> Option<f32> {
        None
    }
}
