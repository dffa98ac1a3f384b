//! The classical dipole's diffuse reflectance profile R_d(r) of one channel (Jensen et al. 2001,
//! eq. 4–5; docs/model.md §9) and its derivatives with respect to the channel's σ_t and α.
//!
//! With the reduced parameters of §2 (σ_t' = σ_t(1 − gα), σ_a = σ_t(1 − α),
//! α' = (1 − g)α/(1 − gα)):
//!
//!   D = 1/(3σ_t'),  A = (1 + 2·FM1(η))/(1 − 2·FM1(η)),  z_r = 1/σ_t',  z_v = z_r + 4AD,
//!   μ_tr = √(3σ_a σ_t'),  d_{r,v} = √(z_{r,v}² + r²),
//!   R_d(r) = α'/(4π) · [H(z_r) + H(z_v)],  H(z) = z (μ_tr d + 1) e^{−μ_tr d} / d³,
//!
//! (z_v is the height of the virtual source above the surface, the |z_v| of docs/model.md §9.)
//! Every length scales with 1/σ_t', so z_v = κ z_r with κ = 1 + 4A/3. Its integral over the plane
//! is closed: ∫ H(z) 2πr dr = 2π e^{−μ_tr z}, hence the total diffuse reflectance
//!
//!   R_d,total = (α'/2) · (e^{−μ_tr z_r} + e^{−μ_tr z_v})
//!             = (α'/2) · (1 + e^{−(4/3)A√(3(1 − α'))}) e^{−√(3(1 − α'))}   (Jensen eq. 5 integrated).
//!
//! Derivatives (θ = σ_t or α; positions fixed): with h(d) = (μd + 1)e^{−μd}/d³,
//! ∂h/∂d = h·(μ/(μd + 1) − μ − 3/d) and ∂h/∂μ = −h·μd²/(μd + 1),
//!
//!   ∂H/∂z = h + z·∂h/∂d·z/d,   ∂H/∂μ = z·∂h/∂μ,
//!   ∂R_d/∂θ = ∂α'/∂θ·R_d/α' + α'/(4π)·Σ_{z ∈ {z_r, z_v}} (∂H/∂z·∂z/∂θ + ∂H/∂μ·∂μ_tr/∂θ),
//!   ∂z/∂θ = −(z/σ_t')·∂σ_t'/∂θ,   ∂μ_tr/∂θ = (3/(2μ_tr))·(σ_t'·∂σ_a/∂θ + σ_a·∂σ_t'/∂θ),
//!
//! with ∂σ_t'/∂σ_t = 1 − gα, ∂σ_t'/∂α = −gσ_t, ∂σ_a/∂σ_t = 1 − α, ∂σ_a/∂α = −σ_t,
//! ∂α'/∂σ_t = 0, ∂α'/∂α = (1 − g)/(1 − gα)².

use std::f64::consts::PI;

use base::boundary::fresnel_moment1;

/// R_d below this fraction of its peak is cut off: the probe radius r_max = −ln(10⁻⁶)/μ_tr
/// (DLW22).
pub const CUTOFF: f64 = 1e-6;

/// One channel's dipole (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DipoleProfile {
    /// α'.
    albedo_red: f64,
    /// ∂α'/∂α.
    d_albedo_red: f64,
    /// μ_tr and its derivatives (σ_t, α).
    mu: f64,
    d_mu: [f64; 2],
    /// z_r and z_v (heights of the real source below and the virtual source above the surface)
    /// and their derivatives (σ_t, α).
    z: [f64; 2],
    d_z: [[f64; 2]; 2],
}

/// R_d at one distance with its derivatives.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProfileValue {
    pub value: f64,
    /// ∂R_d/∂σ_t.
    pub d_sigma_t: f64,
    /// ∂R_d/∂α.
    pub d_albedo: f64,
}

impl DipoleProfile {
    /// The dipole of a channel with extinction `sigma_t` > 0, albedo `albedo` ∈ [0, 1),
    /// anisotropy `g` and relative index `eta` (n_inside/n_outside).
    pub fn new(sigma_t: f64, albedo: f64, g: f64, eta: f64) -> Self {
        let st_red = sigma_t * (1.0 - g * albedo);
        let d_st_red = [1.0 - g * albedo, -g * sigma_t];
        let sa = sigma_t * (1.0 - albedo);
        let d_sa = [1.0 - albedo, -sigma_t];
        let albedo_red = (1.0 - g) * albedo / (1.0 - g * albedo);
        let d_albedo_red = (1.0 - g) / ((1.0 - g * albedo) * (1.0 - g * albedo));
        let c1 = fresnel_moment1(eta as f32) as f64;
        let a = (1.0 + 2.0 * c1) / (1.0 - 2.0 * c1);
        let kappa = 1.0 + 4.0 * a / 3.0;
        let z_r = 1.0 / st_red;
        let z = [z_r, kappa * z_r];
        let d_z = z.map(|zj| d_st_red.map(|ds| -zj / st_red * ds));
        let mu = (3.0 * sa * st_red).sqrt();
        let d_mu = std::array::from_fn(|k| 1.5 / mu * (st_red * d_sa[k] + sa * d_st_red[k]));
        DipoleProfile {
            albedo_red,
            d_albedo_red,
            mu,
            d_mu,
            z,
            d_z,
        }
    }

    /// μ_tr, the profile's decay rate (the rate of the probe radius).
    pub fn mu_tr(&self) -> f64 {
        self.mu
    }

    /// The probe radius r_max = −ln([`CUTOFF`])/μ_tr.
    pub fn r_max(&self) -> f64 {
        -CUTOFF.ln() / self.mu
    }

    /// R_d(r).
    #[inline]
    pub fn value(&self, r: f64) -> f64 {
        let sum: f64 = self.z.iter().map(|&z| z * self.h(z, r).0).sum();
        self.albedo_red / (4.0 * PI) * sum
    }

    /// R_d(r) and its derivatives (module docs).
    #[inline]
    pub fn with_derivatives(&self, r: f64) -> ProfileValue {
        let mu = self.mu;
        let mut sum = 0.0;
        let mut d_sum = [0.0; 2];
        for (j, &z) in self.z.iter().enumerate() {
            let (h, d) = self.h(z, r);
            let dh_dd = h * (mu / (mu * d + 1.0) - mu - 3.0 / d);
            let dh_dmu = -h * mu * d * d / (mu * d + 1.0);
            let d_hz_dz = h + z * dh_dd * z / d;
            let d_hz_dmu = z * dh_dmu;
            sum += z * h;
            for k in 0..2 {
                d_sum[k] += d_hz_dz * self.d_z[j][k] + d_hz_dmu * self.d_mu[k];
            }
        }
        let s = self.albedo_red / (4.0 * PI);
        ProfileValue {
            value: s * sum,
            d_sigma_t: s * d_sum[0],
            d_albedo: self.d_albedo_red / (4.0 * PI) * sum + s * d_sum[1],
        }
    }

    /// The total diffuse reflectance ∫ R_d dA over the plane, (α'/2)(e^{−μ_tr z_r} + e^{−μ_tr z_v}).
    pub fn total_reflectance(&self) -> f64 {
        0.5 * self.albedo_red * self.z.iter().map(|z| (-self.mu * z).exp()).sum::<f64>()
    }

    /// h(d) at d = √(z² + r²), and d.
    #[inline]
    fn h(&self, z: f64, r: f64) -> (f64, f64) {
        let d = (z * z + r * r).sqrt();
        let md = self.mu * d;
        ((md + 1.0) * (-md).exp() / (d * d * d), d)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The analytic derivatives against central differences of the profile (deterministic: the
    /// tolerance is the differences' truncation, O(Δ²) relative).
    #[test]
    fn derivatives_match_central_differences() {
        for &(st, a, g, eta) in &[
            (50.0, 0.9, 0.0, 1.0),
            (120.0, 0.6, 0.3, 1.3),
            (20.0, 0.99, -0.2, 1.5),
        ] {
            let p = DipoleProfile::new(st, a, g, eta);
            for &r in &[0.0, 0.3 / st, 2.0 / st, 10.0 / st] {
                let v = p.with_derivatives(r);
                assert!((v.value - p.value(r)).abs() <= 1e-12 * v.value.abs());
                let hs = 1e-4 * st;
                let fd_s = (DipoleProfile::new(st + hs, a, g, eta).value(r)
                    - DipoleProfile::new(st - hs, a, g, eta).value(r))
                    / (2.0 * hs);
                let ha = 1e-5;
                let fd_a = (DipoleProfile::new(st, a + ha, g, eta).value(r)
                    - DipoleProfile::new(st, a - ha, g, eta).value(r))
                    / (2.0 * ha);
                let scale_s = v.value / st;
                assert!(
                    (v.d_sigma_t - fd_s).abs() <= 1e-5 * (fd_s.abs() + scale_s),
                    "σ_t {st} α {a} r {r}: {} vs {fd_s}",
                    v.d_sigma_t
                );
                assert!(
                    (v.d_albedo - fd_a).abs() <= 1e-5 * (fd_a.abs() + v.value),
                    "σ_t {st} α {a} r {r}: {} vs {fd_a}",
                    v.d_albedo
                );
            }
        }
    }

    /// The closed-form total against Jensen's form and against a quadrature of R_d over the
    /// plane (substituting r = z_r·t/(1 − t) to map [0, ∞) onto [0, 1)).
    #[test]
    fn total_reflectance_is_the_integral_over_the_plane() {
        for &(st, a, g, eta) in &[(50.0, 0.9, 0.0, 1.0), (80.0, 0.7, 0.5, 1.4)] {
            let p = DipoleProfile::new(st, a, g, eta);
            let ar = (1.0 - g) * a / (1.0 - g * a);
            let c1 = fresnel_moment1(eta as f32) as f64;
            let big_a = (1.0 + 2.0 * c1) / (1.0 - 2.0 * c1);
            let s = (3.0 * (1.0 - ar)).sqrt();
            let jensen = 0.5 * ar * (1.0 + (-4.0 / 3.0 * big_a * s).exp()) * (-s).exp();
            assert!((p.total_reflectance() - jensen).abs() < 1e-12, "{st} {a}");
            let zr = 1.0 / (st * (1.0 - g * a));
            let n = 200_000;
            let quad: f64 = (0..n)
                .map(|i| {
                    let t = (i as f64 + 0.5) / n as f64;
                    let r = zr * t / (1.0 - t);
                    let dr = zr / ((1.0 - t) * (1.0 - t)) / n as f64;
                    p.value(r) * 2.0 * PI * r * dr
                })
                .sum();
            assert!(
                (quad - jensen).abs() < 1e-6 * jensen,
                "{st} {a}: {quad} vs {jensen}"
            );
        }
    }
}
