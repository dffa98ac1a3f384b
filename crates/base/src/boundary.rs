//! Boundary factors of the BSSRDF estimator (docs/model.md §1).
//!
//! C = (1 − F_η(cos θ_cam)) · S_abs · Sw(w_l) · max(0, n_i·w_l) · V · I/r², with
//! Sw(w) = (1 − F_η(cos θ_w)) / (π (1 − 2 FM1(1/η))) and FM1 the first Fresnel moment polynomial
//! (identical in VKJ19, SON24 and DLW22). F is the exact dielectric Fresnel reflectance (not the
//! squared-instead-of-square-root helper of the released code). For η = 1 both Fresnel terms
//! vanish and Sw = 1/(π(1 − 2·FM1(1))) ≈ 0.3197.

use crate::fresnel::fresnel_dielectric;

/// First Fresnel moment polynomial FM1(e) (docs/model.md §1).
pub fn fresnel_moment1(e: f32) -> f32 {
    let (e2, e3, e4, e5) = (e * e, e * e * e, e * e * e * e, e * e * e * e * e);
    if e < 1.0 {
        0.45966 - 1.73965 * e + 3.37668 * e2 - 3.904945 * e3 + 2.49277 * e4 - 0.68441 * e5
    } else {
        -4.61686 + 11.1136 * e - 10.4646 * e2 + 5.11455 * e3 - 1.27198 * e4 + 0.12746 * e5
    }
}

/// Fresnel transmittance 1 − F for a ray crossing a boundary of relative IOR `eta`
/// (n_inside/n_outside) at cosine `cos` from outside.
pub fn transmittance(cos: f32, eta: f32) -> f32 {
    1.0 - fresnel_dielectric(cos.abs(), eta)
}

/// The directional factor Sw(w) for the light direction at the entry point.
pub fn sw(cos_light: f32, eta: f32) -> f32 {
    transmittance(cos_light, eta)
        / (std::f32::consts::PI * (1.0 - 2.0 * fresnel_moment1(1.0 / eta)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn index_matched_limits() {
        assert!((fresnel_moment1(1.0) - 0.00221).abs() < 1e-4);
        assert_eq!(transmittance(0.3, 1.0), 1.0);
        let s = sw(0.5, 1.0);
        assert!(
            (s - 1.0 / (std::f32::consts::PI * (1.0 - 2.0 * 0.00221))).abs() < 1e-4,
            "{s}"
        );
        // η > 1: less light gets through at grazing angles.
        assert!(sw(0.1, 1.5) < sw(0.9, 1.5));
    }
}
