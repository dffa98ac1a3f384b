//! The curvature table: the exact side's closed form at low albedo, the interpolation, and the
//! shipped table against a fresh batch.

use super::*;

/// Mean and standard error of `f(seed)` over seeds 0..k, per entry.
fn replicate(k: u64, f: impl Fn(u64) -> Vec<f64>) -> (Vec<f64>, Vec<f64>) {
    let runs: Vec<Vec<f64>> = (0..k).map(f).collect();
    let n = runs[0].len();
    let mean: Vec<f64> = (0..n)
        .map(|i| runs.iter().map(|r| r[i]).sum::<f64>() / k as f64)
        .collect();
    let se = (0..n)
        .map(|i| {
            let v = runs.iter().map(|r| (r[i] - mean[i]).powi(2)).sum::<f64>();
            (v / (k - 1) as f64 / k as f64).sqrt()
        })
        .collect();
    (mean, se)
}

/// The exact side in a half-space at a small albedo is single scattering, whose closed form
/// is α·p(θ)·μ_l/(μ_l + μ_c) per unit irradiance, p the phase function at the angle θ
/// between the camera ray and the light direction (1/4π for the paper's isotropic media;
/// multiple scattering adds O(α²), 0.1 % of it here); lights below the horizon get nothing.
#[test]
fn exact_side_is_single_scattering_at_low_albedo() {
    let albedo = 1e-3;
    let exit = ExitTable::index_matched_isotropic().slice(albedo);
    let inc = IncidenceTable::index_matched_isotropic().slice(albedo);
    let lights = [
        LightDir {
            mu_l: 1.0,
            phi: 0.0,
        },
        LightDir {
            mu_l: 0.3,
            phi: 1.0,
        },
        LightDir {
            mu_l: 0.05,
            phi: 3.0,
        },
        LightDir {
            mu_l: -0.2,
            phi: 0.0,
        },
    ];
    for (g, mu_c) in [(0.0f32, 0.2f32), (0.0, 0.9), (0.6, 0.2), (0.6, 0.9)] {
        let (mean, se) = replicate(12, |seed| {
            let r = ball_response(
                (albedo, g),
                mu_c,
                f32::INFINITY,
                &lights,
                &exit,
                &inc,
                20_000,
                seed,
            );
            r.0
        });
        let d0 = Vec3::new((1.0 - mu_c * mu_c).sqrt(), 0.0, -mu_c);
        for (k, l) in lights.iter().enumerate() {
            let p = HenyeyGreenstein { g }.eval(d0, l.direction()) as f64;
            let want = if l.mu_l > 0.0 {
                albedo as f64 * p * (l.mu_l / (l.mu_l + mu_c)) as f64
            } else {
                0.0
            };
            let tol = 4.0 * se[k] + 2e-3 * want;
            assert!(
                (mean[k] - want).abs() <= tol,
                "g {g}, μ_c {mu_c}, light {l:?}: {:.4e} ± {:.1e}, closed form {want:.4e}",
                mean[k],
                se[k]
            );
        }
    }
}

/// Node values come back at the nodes, linear interpolation in between, clamping outside;
/// concave curvatures use the half-space row.
#[test]
fn slices_interpolate_between_nodes() {
    let sizes = [MU_C.len(), KAPPA.len(), MU_L.len(), PHI.len()];
    let value = |i: [usize; 4]| MU_C[i[0]] + 2.0 * KAPPA[i[1]] + 3.0 * MU_L[i[2]] + PHI[i[3]];
    let mut c = Vec::with_capacity(PER_ALBEDO);
    for a in 0..sizes[0] {
        for b in 0..sizes[1] {
            for d in 0..sizes[2] {
                for e in 0..sizes[3] {
                    c.push(value([a, b, d, e]));
                }
            }
        }
    }
    let s = CurvatureSlice {
        dc: vec![0.5; c.len()],
        c,
    };
    let at = |mc: f32, k: f32, ml: f32, phi: f32| s.eval(mc, k, ml, phi.cos()).0;
    let lin = |mc: f32, k: f32, ml: f32, phi: f32| mc + 2.0 * k + 3.0 * ml + phi;
    for (mc, k, ml, phi) in [
        (0.3, 0.025, 0.2, 0.0),
        (0.4, 0.03, -0.07, 1.0),
        (0.95, 0.07, 0.9, 2.5),
    ] {
        // fast_acos is accurate to about 1e-4 rad.
        assert!(
            (at(mc, k, ml, phi) - lin(mc, k, ml, phi)).abs() < 2e-3,
            "{mc} {k} {ml} {phi}"
        );
    }
    assert!((at(0.01, 0.2, 1.0, 0.0) - lin(0.05, 0.1, 1.0, 0.0)).abs() < 2e-3);
    assert_eq!(at(0.5, -0.05, 0.2, 0.0), at(0.5, 0.0, 0.2, 0.0));
    assert!((s.eval(0.5, 0.01, 0.3, 0.2).1 - 0.5).abs() < 1e-5);
}

/// The shipped table holds what a fresh simulation of one of its batches gives (α = 0.88,
/// μ_c = 0.7, R = 20 mean free paths), within 4 standard errors of twelve replicates of 10⁵
/// collisions combined with the shipped batch's own (10⁶ collisions: the replicates' spread
/// over √10), plus the rounding to 4 decimals.
#[test]
fn shipped_table_matches_a_fresh_batch() {
    let (a, m, k) = (6, 4, 3);
    let albedo = 1.0 - ONE_MINUS_ALBEDO[a];
    let exit = ExitTable::index_matched_isotropic().slice(albedo);
    let inc = IncidenceTable::index_matched_isotropic().slice(albedo);
    let lights = batch_lights();
    let (mean, se) = replicate(12, |seed| {
        let (e, mo, _) = ball_response(
            (albedo, 0.0),
            MU_C[m],
            1.0 / KAPPA[k],
            &lights,
            &exit,
            &inc,
            100_000,
            1000 + seed,
        );
        let eps = REGULARISE * e.iter().chain(&mo).cloned().fold(0.0, f64::max);
        e.iter()
            .zip(&mo)
            .map(|(&e, &m)| (e + eps) / (m + eps))
            .collect()
    });
    let shipped = CurvatureTable::index_matched_isotropic().slice(albedo);
    let mut checked = 0;
    for (i, l) in lights.iter().enumerate() {
        let (c, _) = shipped.eval(MU_C[m], KAPPA[k], l.mu_l, l.phi.cos());
        let spread = se[i] * 12f64.sqrt();
        let shipped_se = spread / 10f64.sqrt();
        let tol = 4.0 * (se[i] * se[i] + shipped_se * shipped_se).sqrt() + 1e-4;
        assert!(
            (c as f64 - mean[i]).abs() <= tol,
            "{l:?}: shipped {c:.4}, fresh {:.4} ± {:.4}",
            mean[i],
            se[i]
        );
        checked += 1;
    }
    assert_eq!(checked, MU_L.len() * PHI.len());
}
