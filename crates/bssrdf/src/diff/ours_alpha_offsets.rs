//! `ours-alpha-offsets` (docs/model.md A6): σ_t as [`super::ours`]; α entirely by offset samples,
//! as σ_t: the networks run again with the albedo input and the descriptor at α ± Δα (y^±,
//! S_abs^±, z reused), x_i^± = Π(x_o + σ_n(α ± Δα)·R·y^±), and the light side (exit law,
//! incidence factor) at α ± Δα:
//!
//!   ∂C/∂α ≈ (1 − F)·(S_abs⁺·L⁺(x_i⁺) − S_abs⁻·L⁻(x_i⁻))/(2Δα).
//!
//! Unlike `ours` it keeps the dependence of the sample positions on α.

use super::ours::Ours;
use super::row::{Sample, SampleEstimator, offset_light};

/// The `ours-alpha-offsets` estimator.
pub(super) struct OursAlphaOffsets;

impl SampleEstimator for OursAlphaOffsets {
    const PAIR: bool = true;

    /// The α offsets change the network inputs (albedo) even with a fixed descriptor.
    fn offset_sets(_moving: bool) -> usize {
        4
    }

    fn d_sigma_t(s: &Sample) -> f32 {
        Ours::d_sigma_t(s)
    }

    fn d_albedo(s: &Sample) -> Option<f32> {
        // Every α-dependence by the offset pair at α ± Δα (same z): networks, σ_n and the
        // light-side tables of the offset scenes.
        let c = s.c;
        let [hi, lo] = s.k.sn_a[c];
        let ((yp, sp), (ym, sm)) = (s.offsets[2], s.offsets[3]);
        let st = s.scene.medium.sigma_t[c];
        let (vp, _) = offset_light(&s.k.alpha[c][0], s.view, s.p, yp, (hi, st));
        let (vm, _) = offset_light(&s.k.alpha[c][1], s.view, s.p, ym, (lo, st));
        Some(s.p.t_cam * (sp * vp - sm * vm) * s.k.inv_2da[c])
    }
}
