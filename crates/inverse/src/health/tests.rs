use super::*;

const ISO: scene::Anisotropy = scene::Anisotropy::ISOTROPIC;

fn record(k: u32, loss: f64) -> IterationRecord {
    record_view(k, loss, 0)
}

fn record_view(k: u32, loss: f64, view: usize) -> IterationRecord {
    IterationRecord {
        iteration: k,
        loss,
        params: Params {
            sigma_t: [50.0; 3],
            albedo: [0.9; 3],
            g: None,
            light_scale: None,
        },
        d_sigma_t: [0.0; 3],
        d_albedo: [0.0; 3],
        d_g: None,
        d_ln_light_scale: None,
        views: vec![view],
        crop_origins: Vec::new(),
        seconds: 0.1,
        misfit: None,
    }
}

fn params(sigma_t: f64, albedo: f64) -> Params {
    Params {
        sigma_t: [sigma_t; 3],
        albedo: [albedo; 3],
        g: None,
        light_scale: None,
    }
}

/// A converged run whose per-view losses scatter (alternating views) is fine.
#[test]
fn a_healthy_run_has_no_problem() {
    let h: Vec<_> = (0..100)
        .map(|k| {
            record(
                k,
                1.0 / (1.0 + k as f64) + if k % 2 == 0 { 0.3 } else { 0.1 },
            )
        })
        .collect();
    assert!(assess(&h, 0, &params(60.0, 0.9), &ParamSpec::default(), ISO, None).is_empty());
}

#[test]
fn each_failure_is_detected() {
    let flat: Vec<_> = (0..100)
        .map(|k| record(k, 0.2 + 0.01 * (k % 3) as f64))
        .collect();
    let spec = ParamSpec::default();
    let kinds = |p: &[Problem]| -> Vec<String> {
        p.iter()
            .map(|p| {
                serde_json::to_value(p).unwrap()["kind"]
                    .as_str()
                    .unwrap()
                    .to_string()
            })
            .collect()
    };
    let nan = assess(&flat, 0, &params(f64::NAN, 0.9), &spec, ISO, None);
    assert_eq!(kinds(&nan), ["non-finite"]);
    let pinned = assess(&flat, 0, &params(60.0, ALBEDO_MAX), &spec, ISO, None);
    assert_eq!(kinds(&pinned), ["at-clamp"; 3]);
    let tiny = assess(&flat, 0, &params(SIGMA_T_MIN, 0.5), &spec, ISO, None);
    assert_eq!(kinds(&tiny), ["at-clamp"; 3]);
    // A fixed parameter at its bound is the user's choice, not a failure.
    let fixed = ParamSpec {
        fix_albedo: true,
        ..ParamSpec::default()
    };
    assert!(assess(&flat, 0, &params(60.0, ALBEDO_MAX), &fixed, ISO, None).is_empty());
    let dark = assess(&flat, 0, &params(60.0, 0.03), &spec, ISO, None);
    assert_eq!(kinds(&dark), ["outside-training-range"; 3]);
    let rising: Vec<_> = (0..100)
        .map(|k| record(k, 0.2 + 0.01 * (k % 3) as f64 + 0.004 * k as f64))
        .collect();
    let r = assess(&rising, 0, &params(60.0, 0.9), &spec, ISO, None);
    assert_eq!(kinds(&r), ["loss-rising"]);
    assert!(r[0].message().contains("diverged"));
    let off = Consistency {
        view_ratio: vec![[1.0, 0.93, 1.0]],
        mean_ratio: [1.0, 0.93, 1.0],
        l2_over_noise: [1.1, 3.0, 1.0],
        target_noise_ratio: [1.0; 3],
        views: vec![0],
        spp: 16,
    };
    let r = assess(&flat, 0, &params(60.0, 0.9), &spec, ISO, Some(&off));
    assert_eq!(kinds(&r), ["inconsistent"]);
    assert!(r[0].message().contains(" G "));
    // A recovered g at its bound; the object's g is not a parameter.
    let free_g = ParamSpec {
        free_g: true,
        ..ParamSpec::default()
    };
    let edge = Params {
        g: Some(crate::params::OneOrRgb::One(crate::params::G_MAX)),
        ..params(60.0, 0.9)
    };
    let r = assess(&flat, 0, &edge, &free_g, ISO, None);
    assert_eq!(kinds(&r), ["g-at-bound"]);
    assert!(r[0].message().contains("init_g"), "{}", r[0].message());
    // One g per channel: any channel at its bound.
    let per_channel = ParamSpec {
        g_per_channel: true,
        ..free_g.clone()
    };
    let one_edge = Params {
        g: Some(crate::params::OneOrRgb::Rgb([
            0.5,
            -crate::params::G_MAX,
            0.7,
        ])),
        ..params(60.0, 0.9)
    };
    assert_eq!(
        kinds(&assess(&flat, 0, &one_edge, &per_channel, ISO, None)),
        ["g-at-bound"]
    );
    assert!(
        assess(
            &flat,
            0,
            &params(60.0, 0.9),
            &spec,
            scene::Anisotropy::uniform(0.95),
            None
        )
        .is_empty()
    );
    let free_k = ParamSpec {
        free_light_scale: true,
        ..ParamSpec::default()
    };
    let bright = Params {
        light_scale: Some(crate::params::OneOrRgb::One(crate::params::LIGHT_SCALE_MAX)),
        ..params(60.0, 0.9)
    };
    let r = assess(&flat, 0, &bright, &free_k, ISO, None);
    assert_eq!(kinds(&r), ["light-scale-at-bound"]);
    assert!(
        r[0].message().contains("init_light_scale"),
        "{}",
        r[0].message()
    );
}

/// Gaussian noise from the workspace's sampler (Box–Muller).
fn normal(rng: &mut base::rng::Sampler) -> f64 {
    let u1 = (rng.next_f32() as f64).max(1e-12);
    let u2 = rng.next_f32() as f64;
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// A synthetic history of `n` iterations, each on a view drawn uniformly from `views`:
/// `draw(k, v, z)` makes iteration k's record from its view v and a N(0, 1) draw z.
fn synthetic(
    rng: &mut base::rng::Sampler,
    n: u32,
    views: u32,
    draw: impl Fn(u32, usize, f64) -> IterationRecord,
) -> Vec<IterationRecord> {
    (0..n)
        .map(|k| {
            let v = rng.next_below(views) as usize;
            draw(k, v, normal(rng))
        })
        .collect()
}

/// Views whose losses differ 1000-fold, drawn so that the last fifth holds mostly the
/// costly ones, and no trend: the window means differ many-fold, the trend with one level
/// per view is flat.
#[test]
fn view_levels_are_not_a_rise() {
    let mut rng = base::rng::Sampler::new(7, 0, 0, 0);
    let h: Vec<_> = (0..150u32)
        .map(|k| {
            let v = if k >= 120 {
                3 - (rng.next_below(4) / 3) as usize
            } else {
                rng.next_below(4) as usize
            };
            let level = 10f64.powi(v as i32);
            record_view(k, level * (0.05 * normal(&mut rng)).exp(), v)
        })
        .collect();
    let mean = |r: &[IterationRecord]| r.iter().map(|x| x.loss).sum::<f64>() / r.len() as f64;
    assert!(
        mean(&h[120..]) > 2.0 * mean(&h[90..120]),
        "the draw is not the confound"
    );
    let t = loss_trend(&h[90..]).unwrap();
    assert!(t.z().abs() < 3.0, "{t:?}");
    assert!(assess(&h, 0, &params(60.0, 0.9), &ParamSpec::default(), ISO, None).is_empty());
}

/// A significant rise below the floor passes; one above it fails.
#[test]
fn the_floor_separates_drift_from_divergence() {
    let run = |per_span: f64| {
        let mut rng = base::rng::Sampler::new(3, 0, 0, 0);
        synthetic(&mut rng, 300, 6, |k, v, z| {
            let trend = (1.0 + per_span).ln() / RISE_SPAN * k as f64;
            record_view(k, (v as f64 + 1.0) * (trend + 0.02 * z).exp(), v)
        })
    };
    let small = run(0.02);
    let t = loss_trend(&small[180..]).unwrap();
    assert!(
        t.z() > 3.0 && (t.rise(RISE_SPAN) - 0.02).abs() < 0.005,
        "{t:?}"
    );
    assert!(
        assess(
            &small,
            150,
            &params(60.0, 0.9),
            &ParamSpec::default(),
            ISO,
            None
        )
        .is_empty()
    );
    let large = run(0.08);
    let r = assess(
        &large,
        150,
        &params(60.0, 0.9),
        &ParamSpec::default(),
        ISO,
        None,
    );
    assert!(
        matches!(r[..], [Problem::LossRising { rise, iterations: 120, .. }] if (rise - 0.08).abs() < 0.005),
        "{r:?}"
    );
}

/// The window starts no earlier than the final forward model: a jump of the loss's level at
/// the switch of models is not a rise.
#[test]
fn the_switch_of_models_is_not_a_rise() {
    let h: Vec<_> = (0..100u32)
        .map(|k| record(k, if k < 70 { 0.1 } else { 0.3 } + 0.001 * (k % 2) as f64))
        .collect();
    let spec = ParamSpec::default();
    assert_eq!(assess(&h, 0, &params(60.0, 0.9), &spec, ISO, None).len(), 1);
    assert!(assess(&h, 70, &params(60.0, 0.9), &spec, ISO, None).is_empty());
}

/// With no trend, |z| > 1.96 in 5 % of 400 independent runs of 120 iterations over 8 views
/// (binomial s.d. 1.1 %, so 5 ± 3.3 % at three s.d.): the slope's standard error is
/// calibrated for `of`. `draw` gives an iteration's record from its view and a N(0, 1) draw.
fn assert_calibrated(seed: u64, of: TrendOf, draw: impl Fn(u32, usize, f64) -> IterationRecord) {
    let mut rng = base::rng::Sampler::new(seed, 0, 0, 0);
    let runs = 400;
    let outside = (0..runs)
        .filter(|_| {
            let t = loss_trend(&synthetic(&mut rng, 120, 8, &draw)).unwrap();
            assert_eq!(t.of, of);
            t.z().abs() > 1.96
        })
        .count();
    let p = outside as f64 / runs as f64;
    let sd = (0.05f64 * 0.95 / runs as f64).sqrt();
    assert!((p - 0.05).abs() < 3.0 * sd, "{outside} of {runs} outside");
}

/// The slope of ln ℓ (30 % log-normal scatter per draw).
#[test]
fn the_trend_standard_error_is_calibrated() {
    assert_calibrated(11, TrendOf::LnLoss, |k, v, n| {
        record_view(k, (v as f64 + 1.0) * (0.3 * n).exp(), v)
    });
}

/// The loss rises with the renders' noise while the misfit without it stays flat: no
/// failure. A misfit that rises fails, as the misfit's rise.
#[test]
fn the_misfit_decides_where_the_run_has_it() {
    let run = |misfit_per_span: f64| {
        let mut rng = base::rng::Sampler::new(5, 0, 0, 0);
        synthetic(&mut rng, 300, 6, |k, v, z| {
            let level = v as f64 + 1.0;
            let misfit = level * (1.0 + misfit_per_span / RISE_SPAN * k as f64 + 0.05 * z);
            // The renders' variance grows 15 % per 60 iterations.
            let noise = level * (0.15 / RISE_SPAN * k as f64).exp();
            let mut r = record_view(k, misfit + noise, v);
            r.misfit = Some(misfit);
            r
        })
    };
    let spec = ParamSpec::default();
    let flat = run(0.0);
    let by_loss: Vec<_> = flat
        .iter()
        .map(|r| IterationRecord {
            misfit: None,
            ..r.clone()
        })
        .collect();
    // What rose, when the run's only problem is a rising loss.
    let rose = |h: &[IterationRecord]| -> Option<TrendOf> {
        match assess(h, 150, &params(60.0, 0.9), &spec, ISO, None)[..] {
            [Problem::LossRising { of, .. }] => Some(of),
            _ => None,
        }
    };
    assert_eq!(rose(&by_loss), Some(TrendOf::LnLoss));
    assert!(assess(&flat, 150, &params(60.0, 0.9), &spec, ISO, None).is_empty());
    assert_eq!(rose(&run(0.1)), Some(TrendOf::Misfit));
}

/// The slope of the misfit over its view's mean (30 % scatter per draw).
#[test]
fn the_misfit_trend_standard_error_is_calibrated() {
    assert_calibrated(13, TrendOf::Misfit, |k, v, n| {
        let mut r = record_view(k, 1.0, v);
        r.misfit = Some((v as f64 + 1.0) * (1.0 + 0.3 * n));
        r
    });
}
