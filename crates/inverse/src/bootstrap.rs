//! Parametric-bootstrap bias correction of a recovered medium.
//!
//! The learned BSSRDF is an approximation of the light transport that made the images (the
//! volumetric path tracer, or the real world), so the minimum of the image loss under the learned
//! model does not lie at the true medium: the recovery F(images) has a systematic error, a bias
//! b(θ) = F(V(θ)) − θ that depends smoothly on the medium θ (docs/notes/bias-correction.md: with
//! decoder v1 every σ_t of the accuracy experiment ended 9–35 % low, by an amount that depends on
//! the shape, not on the noise).
//!
//! The parametric bootstrap (Efron & Tibshirani, *An Introduction to the Bootstrap*, 1993, §10.6;
//! in econometrics "indirect inference", Gouriéroux, Monfort & Renault 1993) estimates that bias
//! with the same estimator on data simulated at the estimate itself:
//!
//! ```text
//! θ̂   = F(D)                 the recovery from the observed images D
//! θ̂₂  = F(V(θ̂))             the same recovery from images simulated at θ̂ (same views, light, spp)
//! b̂   = θ̂₂ − θ̂ ≈ b(θ̂)      the bias at θ̂
//! θ_c = θ̂ − b̂ = 2θ̂ − θ̂₂     the bias-corrected estimate
//! ```
//!
//! If b is constant near the truth, θ_c is unbiased; otherwise its error is b'(θ)·b to first
//! order (b' the slope of the bias), i.e. the correction removes the part of the bias that does not
//! change between θ̂ and the truth. The correction is taken in the coordinates in which the bias is
//! closest to constant: ln σ_t (the errors are relative: a −20 % error at σ_t = 40 and at σ_t = 90
//! alike) and α itself (errors of ±0.01–0.02 anywhere in the range), i.e.
//! σ_t,c = σ̂_t² / σ̂_t,₂ and α_c = 2α̂ − α̂₂, clamped to the parameters' valid ranges.
//!
//! **Iterated correction.** When the slope b' is not small, the step is repeated (the iterated
//! bootstrap; in indirect inference the fixed point θ* with F(V(θ*)) = θ̂):
//!
//! ```text
//! θ₀ = θ̂,   θ_{k+1} = θ_k + θ̂ − F(V(θ_k))
//! ```
//!
//! θ₁ is the correction above. For a bias with constant slope the error is multiplied by −b' at
//! every step (e_{k+1} = e_k − (1 + b')·e_k), so K steps leave (−b')^K of the original bias;
//! each step costs one simulation and one recovery.
//!
//! V must be a simulator of the observed images — in this project the volumetric path tracer,
//! which is the ground truth of every dataset it made. For a real capture the correction is only
//! as good as that simulator's agreement with the camera.

use crate::params::Params;

/// Smallest σ_t a correction may return (1/unit): the correction of an estimate is never allowed
/// to leave the parameter domain σ_t > 0.
pub const MIN_SIGMA_T: f64 = 1e-3;
/// Steps of the correction that `optimize`, `demo` and `experiment` run by default.
pub const DEFAULT_STEPS: u32 = 1;

/// Albedo range a correction may return: the optimiser's own clamp, (0, 0.99995].
pub const ALBEDO_RANGE: (f64, f64) = (1e-4, 0.99995);

/// The bias-corrected parameters θ_c = 2θ̂ − θ̂₂ in (ln σ_t, α) from the estimate `estimate` (θ̂)
/// and the recovery `refit` (θ̂₂) from images simulated at θ̂ (see the module documentation).
/// Returns `None` when either input is not a valid medium (σ_t ≤ 0 or not finite, α not finite).
pub fn bias_corrected(estimate: &Params, refit: &Params) -> Option<Params> {
    bootstrap_step(estimate, estimate, refit)
}

/// One step of the iterated correction (module documentation): θ_{k+1} = θ_k + θ̂ − θ̂_k in
/// (ln σ_t, α), with `current` = θ_k, `estimate` = θ̂ and `refit` = θ̂_k = F(V(θ_k)), the recovery
/// from images simulated at θ_k. `bootstrap_step(θ̂, θ̂, θ̂₂)` is [`bias_corrected`]. Returns
/// `None` when an input is not a valid medium.
pub fn bootstrap_step(current: &Params, estimate: &Params, refit: &Params) -> Option<Params> {
    let valid = |p: &Params| {
        p.sigma_t.iter().all(|s| s.is_finite() && *s > 0.0)
            && p.albedo.iter().all(|a| a.is_finite())
    };
    if !valid(current) || !valid(estimate) || !valid(refit) {
        return None;
    }
    let sigma_t = std::array::from_fn(|c| {
        let ln = current.sigma_t[c].ln() + estimate.sigma_t[c].ln() - refit.sigma_t[c].ln();
        ln.exp().max(MIN_SIGMA_T)
    });
    let albedo = std::array::from_fn(|c| {
        (current.albedo[c] + estimate.albedo[c] - refit.albedo[c])
            .clamp(ALBEDO_RANGE.0, ALBEDO_RANGE.1)
    });
    Some(Params {
        sigma_t,
        albedo,
        g: current.g,
        light_scale: current.light_scale,
    })
}

/// The estimated bias b̂ = θ̂₂ − θ̂ of the recovery at θ̂: relative for σ_t (σ̂_t,₂/σ̂_t − 1),
/// absolute for α. What `experiment accuracy --bias-correction` reports beside the corrected
/// estimate.
pub fn estimated_bias(estimate: &Params, refit: &Params) -> ([f64; 3], [f64; 3]) {
    (
        std::array::from_fn(|c| refit.sigma_t[c] / estimate.sigma_t[c] - 1.0),
        std::array::from_fn(|c| refit.albedo[c] - estimate.albedo[c]),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(sigma_t: [f64; 3], albedo: [f64; 3]) -> Params {
        Params::new(sigma_t, albedo)
    }

    /// A recovery whose bias is constant in (ln σ_t, α) is corrected exactly.
    #[test]
    fn a_constant_bias_is_removed_exactly() {
        let truth = p([42.0, 44.2, 96.9], [0.858, 0.888, 0.803]);
        let recover = |t: &Params| {
            p(
                [t.sigma_t[0] * 0.8, t.sigma_t[1] * 0.9, t.sigma_t[2] * 0.7],
                [t.albedo[0] + 0.01, t.albedo[1] - 0.02, t.albedo[2]],
            )
        };
        let est = recover(&truth);
        let refit = recover(&est);
        let c = bias_corrected(&est, &refit).unwrap();
        for k in 0..3 {
            assert!(
                (c.sigma_t[k] / truth.sigma_t[k] - 1.0).abs() < 1e-12,
                "{c:?}"
            );
            assert!((c.albedo[k] - truth.albedo[k]).abs() < 1e-12, "{c:?}");
        }
        let (bs, ba) = estimated_bias(&est, &refit);
        assert!((bs[0] + 0.2).abs() < 1e-12 && (bs[2] + 0.3).abs() < 1e-12);
        assert!((ba[0] - 0.01).abs() < 1e-12 && (ba[1] + 0.02).abs() < 1e-12);
    }

    /// With a bias that changes with σ_t (ln F = (1 + s)·ln θ + c), the corrected error is the
    /// first-order remainder s·b: smaller than the uncorrected error by the factor |s|.
    #[test]
    fn a_sloped_bias_leaves_the_first_order_remainder() {
        let (s, c0) = (0.2f64, -0.25f64);
        let f = |ln: f64| (1.0 + s) * ln + c0;
        let truth_ln = 60.0f64.ln();
        let est_ln = f(truth_ln);
        let refit_ln = f(est_ln);
        let est = p([est_ln.exp(); 3], [0.9; 3]);
        let refit = p([refit_ln.exp(); 3], [0.9; 3]);
        let c = bias_corrected(&est, &refit).unwrap();
        let err_before = est_ln - truth_ln;
        let err_after = c.sigma_t[0].ln() - truth_ln;
        assert!(
            (err_after - (-s * err_before)).abs() < 1e-12,
            "{err_before} {err_after}"
        );
        assert!(err_after.abs() < err_before.abs());
    }

    /// The iterated correction with a sloped bias in both coordinates: K steps leave (−s)^K of
    /// the original error, i.e. the iteration converges to the truth for |s| < 1.
    #[test]
    fn iterated_steps_shrink_the_error_by_the_slope() {
        let (s, c0, sa, ca) = (0.3f64, -0.3f64, -0.4f64, 0.02f64);
        let truth = p([42.0, 60.0, 96.9], [0.86, 0.9, 0.8]);
        let recover = |t: &Params| Params {
            sigma_t: t
                .sigma_t
                .map(|x| ((1.0 + s) * x.ln() + c0 - s * 60f64.ln()).exp()),
            albedo: t.albedo.map(|a| a + ca + sa * (a - 0.85)),
            g: None,
            light_scale: None,
        };
        let est = recover(&truth);
        let mut cur = est;
        let e0 = (
            est.sigma_t[2].ln() - truth.sigma_t[2].ln(),
            est.albedo[0] - truth.albedo[0],
        );
        for k in 1..=4 {
            cur = bootstrap_step(&cur, &est, &recover(&cur)).unwrap();
            if k == 1 {
                assert_eq!(cur, bias_corrected(&est, &recover(&est)).unwrap());
            }
            let e = (
                cur.sigma_t[2].ln() - truth.sigma_t[2].ln(),
                cur.albedo[0] - truth.albedo[0],
            );
            assert!(
                (e.0 - (-s).powi(k) * e0.0).abs() < 1e-9,
                "step {k}: {e:?} {e0:?}"
            );
            assert!(
                (e.1 - (-sa).powi(k) * e0.1).abs() < 1e-9,
                "step {k}: {e:?} {e0:?}"
            );
        }
    }

    #[test]
    fn invalid_inputs_and_clamps() {
        let ok = p([50.0; 3], [0.9; 3]);
        assert!(bias_corrected(&p([0.0, 50.0, 50.0], [0.9; 3]), &ok).is_none());
        assert!(bias_corrected(&ok, &p([50.0; 3], [f64::NAN, 0.9, 0.9])).is_none());
        assert!(bias_corrected(&ok, &p([f64::INFINITY, 50.0, 50.0], [0.9; 3])).is_none());
        // An albedo pushed past 1 by the correction stays in the optimiser's range.
        let c = bias_corrected(&p([50.0; 3], [0.99; 3]), &p([50.0; 3], [0.95; 3])).unwrap();
        assert_eq!(c.albedo, [ALBEDO_RANGE.1; 3]);
        let c = bias_corrected(&p([50.0; 3], [0.01; 3]), &p([50.0; 3], [0.2; 3])).unwrap();
        assert_eq!(c.albedo, [ALBEDO_RANGE.0; 3]);
    }
}
