//! The rough dielectric's sampler against its density (χ²), its weights against eval/pdf, and
//! its energy: a lossless interface up to the single-scattering microfacet model's loss.

use std::f64::consts::PI;

use glam::Vec3;
use testkit::{MeanEstimate, chi2_test};

use super::*;
use crate::rng::Sampler;

/// Significance of each χ² test (fixed seeds make every run deterministic).
const ALPHA: f64 = 1e-3;

fn dir(theta_deg: f32, phi_deg: f32) -> Vec3 {
    let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
    Vec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
}

/// (wi, α, η) covering both sides, grazing incidence and total internal reflection.
fn cases() -> Vec<(Vec3, f32, f32)> {
    vec![
        (dir(30.0, 20.0), 0.3, 1.5),
        (dir(75.0, 200.0), 0.6, 1.33),
        (dir(160.0, 45.0), 0.3, 1.5),
        // 50° inside glass: beyond the critical angle of the macro surface.
        (dir(130.0, 300.0), 0.3, 1.5),
        (dir(40.0, 0.0), 0.2, 1.4),
    ]
}

#[test]
fn sampling_matches_its_density() {
    let (n_mu, n_phi) = (32usize, 16usize);
    let n = 300_000;
    for (k, (wi, alpha, eta)) in cases().into_iter().enumerate() {
        let b = RoughDielectric::new(eta, alpha);
        let mut s = Sampler::new(3, k as u64, 0, 0);
        let bin = |w: Vec3| {
            let mu = (w.z as f64).clamp(-1.0, 1.0);
            let phi = (w.y as f64).atan2(w.x as f64).rem_euclid(2.0 * PI);
            let i = (((mu + 1.0) / 2.0 * n_mu as f64) as usize).min(n_mu - 1);
            let j = ((phi / (2.0 * PI) * n_phi as f64) as usize).min(n_phi - 1);
            i * n_phi + j
        };
        let mut obs = vec![0.0; n_mu * n_phi];
        for _ in 0..n {
            if let Some(x) = b.sample(wi, s.next_f32(), s.next_f32(), s.next_f32()) {
                assert!((x.wo.length() - 1.0).abs() < 1e-4);
                obs[bin(x.wo)] += 1.0;
            }
        }
        // ∫ pdf over each bin (midpoint rule on 12 × 12 cells of (μ, φ)).
        let sub = 12;
        let mut exp = vec![0.0; n_mu * n_phi];
        for (idx, e) in exp.iter_mut().enumerate() {
            let (i, j) = (idx / n_phi, idx % n_phi);
            let (dmu, dphi) = (2.0 / n_mu as f64, 2.0 * PI / n_phi as f64);
            let mut acc = 0.0;
            for a in 0..sub {
                for c in 0..sub {
                    let mu = -1.0 + (i as f64 + (a as f64 + 0.5) / sub as f64) * dmu;
                    let phi = (j as f64 + (c as f64 + 0.5) / sub as f64) * dphi;
                    let st = (1.0 - mu * mu).max(0.0).sqrt();
                    let w = Vec3::new((st * phi.cos()) as f32, (st * phi.sin()) as f32, mu as f32);
                    acc += b.pdf(wi, w) as f64;
                }
            }
            *e = acc * dmu * dphi / (sub * sub) as f64 * n as f64;
        }
        let r = chi2_test(&obs, &exp, 5.0);
        assert!(
            r.p_value > ALPHA,
            "case {k} (wi {wi}, α {alpha}, η {eta}): χ² {} dof {} p {}",
            r.statistic,
            r.dof,
            r.p_value
        );
    }
}

#[test]
fn sample_weights_are_eval_over_pdf() {
    for (k, (wi, alpha, eta)) in cases().into_iter().enumerate() {
        let b = RoughDielectric::new(eta, alpha);
        let mut s = Sampler::new(5, k as u64, 0, 0);
        let mut checked = 0;
        for _ in 0..20_000 {
            let Some(x) = b.sample(wi, s.next_f32(), s.next_f32(), s.next_f32()) else {
                continue;
            };
            let (f, p) = (b.eval(wi, x.wo), b.pdf(wi, x.wo));
            if p < 1e-3 {
                continue; // far in the tail, where f32 rounding dominates
            }
            let want = f / p;
            assert!(
                (x.weight - want).abs() <= 2e-3 * want.max(1e-3),
                "case {k}: weight {} vs eval/pdf {want} (wo {})",
                x.weight,
                x.wo
            );
            assert_eq!(x.transmitted, x.wo.z * wi.z < 0.0);
            checked += 1;
        }
        assert!(checked > 10_000, "case {k}: only {checked} samples checked");
    }
}

/// Flux is conserved up to the microfacets' own loss: E[weight · (η'² if refracted)] ≤ 1, within
/// 1 % of 1 for a nearly smooth surface, and the nearly smooth surface reflects the Fresnel
/// fraction.
#[test]
fn energy_is_conserved_up_to_the_microfacet_loss() {
    for (wi, alpha, eta) in cases()
        .into_iter()
        .chain([(dir(0.0, 0.0), 0.01, 1.5), (dir(155.0, 0.0), 0.01, 1.5)])
    {
        let b = RoughDielectric::new(eta, alpha);
        let mut s = Sampler::new(9, 0, 0, 0);
        let (mut flux, mut reflected) = (MeanEstimate::default(), MeanEstimate::default());
        let eta_t = if wi.z > 0.0 { eta } else { 1.0 / eta };
        for _ in 0..100_000 {
            let (f, r) = match b.sample(wi, s.next_f32(), s.next_f32(), s.next_f32()) {
                Some(x) if x.transmitted => (x.weight * eta_t * eta_t, 0.0),
                Some(x) => (x.weight, 1.0),
                None => (0.0, 0.0),
            };
            flux.push(f as f64);
            reflected.push(r);
        }
        let tol = 4.5 * flux.std_error();
        assert!(
            flux.mean() <= 1.0 + tol,
            "wi {wi} α {alpha}: flux {} > 1",
            flux.mean()
        );
        if alpha <= 0.01 {
            assert!(
                flux.mean() > 0.99 - tol,
                "wi {wi}: nearly smooth flux {}",
                flux.mean()
            );
            let f = crate::fresnel::fresnel_dielectric(wi.z.abs(), eta_t) as f64;
            assert!(
                (reflected.mean() - f).abs() < 4.5 * reflected.std_error() + 0.005,
                "wi {wi}: reflected {} vs Fresnel {f}",
                reflected.mean()
            );
        } else {
            assert!(flux.mean() > 0.6, "wi {wi} α {alpha}: flux {}", flux.mean());
        }
    }
}

/// The visible normals integrate to one: ∫ D_wi(h) dh = 1 (Heitz 2014, eq. 16), by quadrature.
#[test]
fn visible_normals_are_normalised() {
    for (wi, alpha) in [
        (dir(0.0, 0.0), 0.3),
        (dir(60.0, 30.0), 0.5),
        (dir(85.0, 0.0), 0.1),
    ] {
        let g = Ggx { alpha };
        let (n_mu, n_phi) = (2000, 64);
        let mut acc = 0.0f64;
        for i in 0..n_mu {
            let mu = (i as f64 + 0.5) / n_mu as f64;
            for j in 0..n_phi {
                let phi = (j as f64 + 0.5) / n_phi as f64 * 2.0 * PI;
                let st = (1.0 - mu * mu).sqrt();
                let h = Vec3::new((st * phi.cos()) as f32, (st * phi.sin()) as f32, mu as f32);
                acc += g.pdf_visible(wi, h) as f64;
            }
        }
        let integral = acc * (1.0 / n_mu as f64) * (2.0 * PI / n_phi as f64);
        assert!(
            (integral - 1.0).abs() < 5e-3,
            "wi {wi} α {alpha}: ∫ D_wi = {integral}"
        );
    }
}

/// The transmittance by quadrature equals the mean transmitted flux of the sampler (each
/// crossing weighted by η'², within 4.5 standard errors plus the quadrature's 1e-3), tends to
/// the smooth 1 − F(μ) as α → 0, and loses energy at grazing angles for a large α.
#[test]
fn transmittance_is_the_sampled_transmitted_flux() {
    for (mu, alpha, eta) in [(0.9f32, 0.3f32, 1.5f32), (0.3, 0.3, 1.5), (0.6, 0.1, 1.33)] {
        let b = RoughDielectric::new(eta, alpha);
        let wi = Vec3::new((1.0 - mu * mu).sqrt(), 0.0, mu);
        let mut s = Sampler::new(4, 1, 0, 0);
        let mut flux = MeanEstimate::default();
        for _ in 0..100_000 {
            let f = match b.sample(wi, s.next_f32(), s.next_f32(), s.next_f32()) {
                Some(x) if x.transmitted => x.weight * eta * eta,
                _ => 0.0,
            };
            flux.push(f as f64);
        }
        let t = b.transmittance(mu, 64) as f64;
        assert!(
            (t - flux.mean()).abs() < 4.5 * flux.std_error() + 1e-3,
            "μ {mu} α {alpha} η {eta}: quadrature {t} against sampled {}",
            flux.mean()
        );
    }
    for mu in [0.2f32, 0.7, 1.0] {
        let smooth = 1.0 - crate::fresnel::fresnel_dielectric(mu, 1.5);
        let t = RoughDielectric::new(1.5, 0.002).transmittance(mu, 32);
        assert!(
            (t - smooth).abs() < 2e-3,
            "μ {mu}: {t} against 1 − F = {smooth}"
        );
    }
    let rough = RoughDielectric::new(1.5, 0.6);
    let smooth = 1.0 - crate::fresnel::fresnel_dielectric(0.2, 1.5);
    assert!(rough.transmittance(0.2, 32) < smooth);
}
