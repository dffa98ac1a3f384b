/// The drift term is the outer product of the movement between the window's halves: a
/// steady trend of 0.01 in ln σ_t and −0.001 in α per iteration over 20 iterates moves the
/// halves' means by 10 steps; iterates that only alternate about a point give none.
#[test]
fn drift_is_the_movement_between_the_halves_of_the_window() {
    let trend: Vec<([f64; 3], [f64; 3])> = (0..20)
        .map(|k| {
            let k = k as f64;
            ([50.0 * (0.01 * k).exp(); 3], [0.9 - 0.001 * k; 3])
        })
        .collect();
    let d = iterate_drift(&trend);
    for c in d {
        assert!((c[0] - 0.01).abs() < 1e-12, "{c:?}");
        assert!((c[1] + 0.001).abs() < 1e-12, "{c:?}");
        assert!((c[2] - 1e-4).abs() < 1e-12, "{c:?}");
    }
    let still: Vec<([f64; 3], [f64; 3])> = (0..20)
        .map(|k| ([if k % 2 == 0 { 49.0 } else { 51.0 }; 3], [0.9; 3]))
        .collect();
    assert!(
        iterate_drift(&still)
            .iter()
            .flatten()
            .all(|v| v.abs() < 1e-20)
    );
}

use super::*;
use base::rng::Sampler;

/// One trial's data of a linear model I_p(θ) = J_p·θ: per view, `pixels` rows (Jacobian
/// row from `jacobian`, target with Gaussian noise whose scale differs between views).
fn linear_views(
    rng: &mut Sampler,
    truth: [f64; 2],
    views: usize,
    pixels: usize,
    jacobian: fn(&mut dyn FnMut() -> f64) -> [f64; 2],
) -> Vec<Vec<([f64; 2], f64)>> {
    let mut gauss = || {
        let (u1, u2) = (rng.next_f32().max(1e-7) as f64, rng.next_f32() as f64);
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    };
    (0..views)
        .map(|v| {
            let noise = 0.05 * (1.0 + (v % 5) as f64);
            (0..pixels)
                .map(|_| {
                    let j = jacobian(&mut gauss);
                    (j, j[0] * truth[0] + j[1] * truth[1] + noise * gauss())
                })
                .collect()
        })
        .collect()
}

/// A linear model I_p(θ) = J_p·θ with Gaussian target noise of per-view scale (views
/// differ in noise, as real views differ in brightness): the least-squares estimate's
/// 95 % intervals from the sandwich must cover the truth in 95 % of trials. Binomial
/// tolerance: over 400 trials × 2 parameters the coverage of each parameter has s.d.
/// √(0.95·0.05/400) ≈ 0.011; the sandwich with 30 clusters is slightly optimistic
/// (Cameron & Miller 2015), so the check is coverage ≥ 0.95 − 0.01 − 3·0.011 ≈ 0.907 and
/// ≤ 0.95 + 3·0.011.
#[test]
fn sandwich_intervals_cover_a_linear_model() {
    let truth = [0.3, -0.2];
    let (trials, views, pixels) = (400, 30, 40);
    let mut covered = [0usize; 2];
    let mut rng = Sampler::new(1, 2, 3, 4);
    for _ in 0..trials {
        let data = linear_views(&mut rng, truth, views, pixels, |g| {
            [1.0 + 0.5 * g(), 0.8 * g()]
        });
        // The least-squares estimate.
        let (mut a, mut b) = ([0.0; 3], [0.0; 2]);
        for rows in &data {
            for (j, t) in rows {
                a[0] += j[0] * j[0];
                a[1] += j[0] * j[1];
                a[2] += j[1] * j[1];
                b[0] += j[0] * t;
                b[1] += j[1] * t;
            }
        }
        let det = a[0] * a[2] - a[1] * a[1];
        let est = [
            (a[2] * b[0] - a[1] * b[1]) / det,
            (a[0] * b[1] - a[1] * b[0]) / det,
        ];
        let mut acc = Accumulator::default();
        for rows in &data {
            acc.add_rows(rows.iter().map(|(j, t)| {
                let v = j[0] * est[0] + j[1] * est[1];
                (0, [*j, *j], [v, v], *t)
            }));
        }
        let cov = acc.covariance(0.0)[0].expect("positive definite");
        let sd = [cov[0].sqrt(), cov[2].sqrt()];
        for k in 0..2 {
            if (est[k] - truth[k]).abs() <= Z95 * sd[k] {
                covered[k] += 1;
            }
        }
    }
    for k in 0..2 {
        let f = covered[k] as f64 / trials as f64;
        assert!((0.907..=0.983).contains(&f), "parameter {k}: coverage {f}");
    }
}

/// The first parameter alone, the second held at its truth (as `fix_albedo` holds α): the
/// least-squares estimate of the first and its interval from [`Accumulator::covariance_fixed`]
/// must cover the truth in 95 % of trials (the same binomial tolerance as above), on
/// columns so correlated (ρ ≈ 0.9) that the pair's marginal interval would be about 2.3×
/// wider: the fixed parameter's valley must not widen the interval.
#[test]
fn a_fixed_parameter_leaves_the_other_s_own_interval() {
    let truth = [0.3, -0.2];
    let (trials, views, pixels) = (400, 30, 40);
    let mut covered = 0usize;
    let mut widening = Vec::new();
    let mut rng = Sampler::new(5, 6, 7, 8);
    for _ in 0..trials {
        let data = linear_views(&mut rng, truth, views, pixels, |g| {
            let x = 1.0 + 0.5 * g();
            [x, 0.9 * x + 0.2 * g()]
        });
        let (mut a00, mut b0) = (0.0, 0.0);
        for rows in &data {
            for (j, t) in rows {
                a00 += j[0] * j[0];
                b0 += j[0] * (t - j[1] * truth[1]);
            }
        }
        let est = b0 / a00;
        let mut acc = Accumulator::default();
        for rows in &data {
            acc.add_rows(rows.iter().map(|(j, t)| {
                let v = j[0] * est + j[1] * truth[1];
                (0, [*j, *j], [v, v], *t)
            }));
        }
        let own = acc.covariance_fixed(0.0, [false, true])[0].expect("a00 > 0");
        assert_eq!(
            (own[1], own[2]),
            (0.0, 0.0),
            "the fixed parameter has no variance"
        );
        let pair = acc.covariance(0.0)[0].expect("positive definite");
        widening.push((pair[0] / own[0]).sqrt());
        if (est - truth[0]).abs() <= Z95 * own[0].sqrt() {
            covered += 1;
        }
    }
    let f = covered as f64 / trials as f64;
    assert!((0.907..=0.983).contains(&f), "coverage {f}");
    let w = widening.iter().sum::<f64>() / trials as f64;
    assert!(w > 2.0, "the marginal interval is only {w:.2}× wider");
    assert!(
        acc_none_when_both_fixed(),
        "both fixed: no interval to give"
    );
}

fn acc_none_when_both_fixed() -> bool {
    let mut acc = Accumulator::default();
    for v in 0..3 {
        acc.add_rows((0..10).map(|p| {
            let j = [1.0 + p as f64, 2.0 - p as f64];
            (0, [j, j], [1.0; 2], v as f64)
        }));
    }
    acc.covariance_fixed(0.0, [true, true])[0].is_none()
        && acc.covariance_fixed(0.0, [false, true])[0].is_some()
}

/// A direction the images do not see (the second parameter has no effect): no interval.
#[test]
fn an_unseen_parameter_has_no_interval() {
    let mut acc = Accumulator::default();
    for v in 0..5 {
        acc.add_rows((0..10).map(|p| {
            let j = [1.0 + p as f64, 0.0];
            (1, [j, j], [1.0; 2], v as f64)
        }));
    }
    assert!(acc.covariance(0.03)[1].is_none());
    let u = Uncertainty::new(
        [50.0; 3],
        [0.5; 3],
        acc.covariance(0.03),
        acc.covariance(0.0),
        5,
    );
    assert_eq!(u.determined_sigma_t, [false; 3]);
    assert!(u.sigma_t[1].is_none());
}

/// The interval in σ_t is the exponential of the one in ln σ_t; determined follows the
/// width.
#[test]
fn intervals_and_determination() {
    let narrow = Some([0.02f64.powi(2), 0.0, 0.001f64.powi(2)]);
    let wide = Some([0.3f64.powi(2), 0.0, 0.05f64.powi(2)]);
    let u = Uncertainty::new(
        [50.0; 3],
        [0.95; 3],
        [narrow, wide, None],
        [narrow, wide, None],
        8,
    );
    let [lo, hi] = u.sigma_t[0].unwrap();
    assert!((lo - 50.0 * (-Z95 * 0.02f64).exp()).abs() < 1e-9);
    assert!((hi - 50.0 * (Z95 * 0.02f64).exp()).abs() < 1e-9);
    assert_eq!(u.determined_sigma_t, [true, false, false]);
    assert_eq!(u.determined_albedo, [true, false, false]);
    assert_eq!(u.albedo[1].unwrap()[1], 1.0);
}

/// Along a valley the widening scales the profile variance of ln σ_t (its variance with α
/// refitted, 1/(uᵀAu) for a Fisher covariance A⁻¹) by ρ and leaves α's conditional
/// variance at fixed ln σ_t unchanged; ρ = 1 changes nothing. A narrow interval turns
/// undetermined when ρ is large, a fixed parameter keeps no interval.
#[test]
fn widening_along_the_valley() {
    // A of J = (2, 1) plus a little curvature across the valley.
    let a = [4.0 + 0.1, 2.0, 1.0 + 0.1];
    let det = a[0] * a[2] - a[1] * a[1];
    let c = [a[2] / det, -a[1] / det, a[0] / det];
    let slope = -a[1] / a[2];
    let same = along_valley(c, slope, 1.0);
    for k in 0..3 {
        assert!((same[k] - c[k]).abs() < 1e-12 * c[k].abs().max(1.0));
    }
    let rho = 9.0;
    let w = along_valley(c, slope, rho);
    // Profile variance of ln σ_t = c00; conditional variance of α = c11 − c01²/c00.
    assert!((w[0] - rho * c[0]).abs() < 1e-9 * w[0]);
    let cond = |m: [f64; 3]| m[2] - m[1] * m[1] / m[0];
    assert!((cond(w) - cond(c)).abs() < 1e-9 * cond(c));
    // The same as the Fisher covariance of A with its profile curvature divided by ρ.
    let p = a[0] - a[1] * a[1] / a[2];
    let a2 = [a[0] - (1.0 - 1.0 / rho) * p, a[1], a[2]];
    let det2 = a2[0] * a2[2] - a2[1] * a2[1];
    let c2 = [a2[2] / det2, -a2[1] / det2, a2[0] / det2];
    for k in 0..3 {
        assert!((w[k] - c2[k]).abs() < 1e-9 * c2[k].abs(), "{w:?} {c2:?}");
    }

    let narrow = Some([0.02f64.powi(2), 0.0, 0.001f64.powi(2)]);
    let mut u = Uncertainty::new([50.0; 3], [0.95; 3], [narrow; 3], [narrow; 3], 8);
    u.sigma_t[2] = None;
    let at = crate::params::Params {
        sigma_t: [50.0; 3],
        albedo: [0.95; 3],
        g: None,
        light_scale: None,
    };
    let s = Sensitivity {
        slope: [0.0; 3],
        learned: [1.0; 3],
        volpath: [1.0, 0.01, 0.01],
        volpath_se: [0.0; 3],
        ratio: [1.0, 100.0, 100.0],
        views: vec![0],
        spp: 16,
    };
    let w = u.with_sensitivity(&at, &s);
    assert_eq!(w.determined_sigma_t, [true, false, false]);
    // An interval already wider than a factor 10 either way is not widened further; one
    // close to it only up to it.
    let wide = Some([2.0f64.powi(2), 0.0, 0.001f64.powi(2)]);
    let near = Some([1.0f64.powi(2), 0.0, 0.001f64.powi(2)]);
    let v = Uncertainty::new(
        [50.0; 3],
        [0.95; 3],
        [wide, near, narrow],
        [wide, near, narrow],
        8,
    )
    .with_sensitivity(
        &at,
        &Sensitivity {
            ratio: [100.0; 3],
            ..s.clone()
        },
    );
    assert!((v.sd_ln_sigma_t[0].unwrap() - 2.0).abs() < 1e-12);
    assert!((v.sd_ln_sigma_t[1].unwrap() - WIDEST_SD_LN_SIGMA_T).abs() < 1e-12);
    assert!((v.sd_ln_sigma_t[2].unwrap() - 0.2).abs() < 1e-12);
    assert_eq!(w.sigma_t[0], u.sigma_t[0]);
    let [lo, hi] = w.sigma_t[1].unwrap();
    assert!((hi / lo - (2.0 * Z95 * 0.2f64).exp()).abs() < 1e-9);
    assert!(w.sigma_t[2].is_none());
}
