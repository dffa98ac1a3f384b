//! Whether a recovery can be trusted: the checks behind `result.json`'s `status`.
//!
//! A run *failed* when any of these holds:
//! * the estimate is not finite;
//! * a parameter that was free ends pinned at a clamp of [`crate::params`] (α at
//!   [`ALBEDO_MIN`]/[`ALBEDO_MAX`], σ_t at [`SIGMA_T_MIN`]);
//! * the loss keeps rising ([`loss_trend`]): over the last two fifths of the iterations, and
//!   within the final forward model's, the misfit to the images without the renders' noise
//!   ([`crate::optimize::cross_misfit`]; ln ℓ in runs without it), fitted with one level per
//!   view (set) and a common slope b, rises by more than [`RISE_FLOOR`] per [`RISE_SPAN`]
//!   iterations at more than three standard errors of b. Each iteration sees a random view and
//!   the views' losses differ by large factors, so comparing window means is fooled by which
//!   views fell in which window; the loss itself holds the renders' noise, which grows with σ_t
//!   and α, so it rises in runs whose every parameter approaches the truth; and rises of 1–2 %
//!   over a long window are significant yet far from divergence (docs/notes/default-model.md,
//!   "Rising losses");
//! * a reduced albedo α' = α(1 − g)/(1 − αg) below [`TRAINED_ALBEDO_RED_MIN`], the smallest
//!   the shipped model saw in training (its data clamp α' ≥ 0.05);
//! * the estimate, rendered by the volumetric path tracer, does not reproduce the targets
//!   ([`crate::consistency`]).
//!
//! Each check returns a [`Problem`] with a sentence for the user.

use serde::{Deserialize, Serialize};

use crate::consistency::Consistency;
use crate::optimize::IterationRecord;
use crate::params::{ALBEDO_MAX, ALBEDO_MIN, ParamSpec, Params, SIGMA_T_MIN};

/// The smallest rise of the loss, as a fraction per [`RISE_SPAN`] iterations, that fails a run.
pub const RISE_FLOOR: f64 = 0.05;

/// The span of iterations over which [`RISE_FLOOR`] is measured.
pub const RISE_SPAN: f64 = 60.0;

/// The smallest reduced albedo in the learned model's training data.
pub const TRAINED_ALBEDO_RED_MIN: f64 = 0.05;

/// One reason not to trust a recovery.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum Problem {
    /// The estimate holds NaN or Inf.
    NonFinite { detail: String },
    /// A free parameter ends at a clamp.
    AtClamp {
        parameter: String,
        channel: usize,
        value: f64,
    },
    /// The loss rises at the end of the run: by `rise` (a fraction) per [`RISE_SPAN`]
    /// iterations over the last `iterations`, `z` standard errors ([`loss_trend`] of `of`).
    LossRising {
        rise: f64,
        z: f64,
        iterations: u32,
        of: TrendOf,
    },
    /// The estimate lies outside the learned model's training range.
    OutsideTrainingRange { channel: usize, albedo_red: f64 },
    /// The volumetric path tracer's render of the estimate does not match the targets.
    Inconsistent {
        channels: Vec<usize>,
        mean_ratio: [f64; 3],
        l2_over_noise: [f64; 3],
    },
}

impl Problem {
    /// A sentence for the printed summary.
    pub fn message(&self) -> String {
        const CH: [&str; 3] = ["R", "G", "B"];
        match self {
            Problem::NonFinite { detail } => format!(
                "the estimate is not finite ({detail}); check the target images for NaN/Inf \
                 pixels and lower the learning rates"
            ),
            Problem::AtClamp {
                parameter,
                channel,
                value,
            } => format!(
                "{parameter} {} ended at its bound ({value}): the optimiser ran into the edge of \
                 the parameter range, so the value is not a minimum of the loss; check the \
                 dataset's units (σ_t is per scene unit) and exposure, or start elsewhere \
                 (--init-sigma-t, --init-albedo)",
                CH[*channel]
            ),
            Problem::LossRising {
                rise,
                z,
                iterations,
                of,
            } => format!(
                "the {} rose over the last {iterations} iterations, by {:.1} % per {RISE_SPAN} \
                 with each view's level removed ({z:.1} standard errors): the optimisation \
                 diverged or drifts along a flat direction; lower the learning rates, add \
                 iterations, or add views that determine σ_t",
                match of {
                    TrendOf::Misfit => "misfit to the images",
                    TrendOf::LnLoss => "loss",
                },
                100.0 * rise
            ),
            Problem::OutsideTrainingRange {
                channel,
                albedo_red,
            } => format!(
                "channel {}: reduced albedo {albedo_red:.3} lies below the learned model's \
                 training range (≥ {TRAINED_ALBEDO_RED_MIN}); its images there are extrapolated",
                CH[*channel]
            ),
            Problem::Inconsistent {
                channels,
                mean_ratio,
                l2_over_noise,
            } => format!(
                "the estimate does not reproduce the images in {} when rendered by the volumetric \
                 path tracer (brightness ratio {:.3?}, L2 {:.2?}× the noise floor): the \
                 recovery stopped at a medium that does not explain the images. With the learned \
                 model alone, its error can move the estimate: refine with the volumetric path \
                 tracer (--refine, on by default) or run more correction steps \
                 (--bias-correction-steps). With any model, views that determine σ_t and more \
                 iterations help",
                channels
                    .iter()
                    .map(|&c| CH[c])
                    .collect::<Vec<_>>()
                    .join(", "),
                mean_ratio,
                l2_over_noise
            ),
        }
    }
}

/// The problems of a run with history `history` (whose final forward model begins at record
/// `final_from`: the refinement's first iteration, else 0), final `estimate`, parameter spec
/// `spec`, phase-function asymmetry `g` and, when checked, its consistency (module docs).
pub fn assess(
    history: &[IterationRecord],
    final_from: usize,
    estimate: &Params,
    spec: &ParamSpec,
    g: f64,
    consistency: Option<&Consistency>,
) -> Vec<Problem> {
    let mut out = Vec::new();
    let values = estimate.sigma_t.iter().chain(&estimate.albedo);
    if values.clone().any(|v| !v.is_finite()) {
        out.push(Problem::NonFinite {
            detail: format!("σ_t {:?}, α {:?}", estimate.sigma_t, estimate.albedo),
        });
        return out;
    }
    for c in 0..3 {
        let a = estimate.albedo[c];
        if !spec.fix_albedo && (a <= ALBEDO_MIN * (1.0 + 1e-6) || a >= ALBEDO_MAX - 1e-7) {
            out.push(Problem::AtClamp {
                parameter: "α".into(),
                channel: c,
                value: a,
            });
        }
        let s = estimate.sigma_t[c];
        if !spec.fix_sigma_t && s <= SIGMA_T_MIN * (1.0 + 1e-6) {
            out.push(Problem::AtClamp {
                parameter: "σ_t".into(),
                channel: c,
                value: s,
            });
        }
        let red = a * (1.0 - g) / (1.0 - a * g);
        if red < TRAINED_ALBEDO_RED_MIN {
            out.push(Problem::OutsideTrainingRange {
                channel: c,
                albedo_red: red,
            });
        }
    }
    if let Some(p) = loss_rising(history, final_from) {
        out.push(p);
    }
    if let Some(c) = consistency {
        let channels = c.inconsistent_channels();
        if !channels.is_empty() {
            out.push(Problem::Inconsistent {
                channels,
                mean_ratio: c.mean_ratio,
                l2_over_noise: c.l2_over_noise,
            });
        }
    }
    out
}

/// What a [`LossTrend`] was fitted to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum TrendOf {
    /// The noise-free misfit ([`crate::optimize::cross_misfit`]) over its view's mean:
    /// y = m_k / m̄_v, so b is the change per iteration as a fraction of the level.
    Misfit,
    /// ln ℓ (runs without the misfit): b is the change of ln ℓ per iteration. ℓ holds the
    /// renders' noise, which changes with the parameters, so a rise can be the noise's.
    LnLoss,
}

/// The trend of a run's loss: y_k = a_v + b·k + e_k over records k, one level a_v per view set
/// v (the views an iteration rendered) and a common slope b, by least squares within view sets:
/// b = Σ (k − k̄_v)(y_k − ȳ_v) / Σ (k − k̄_v)², its standard error from the residuals with
/// n − V − 1 degrees of freedom. When fewer than 10 degrees of freedom remain (many views per
/// iteration: almost every set differs), one level for all. y is the misfit over its view's
/// mean where every record has a misfit and each view's mean is positive, else ln ℓ
/// ([`TrendOf`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LossTrend {
    /// b: the relative change per iteration.
    pub slope: f64,
    /// The standard error of b.
    pub se: f64,
    /// Residual degrees of freedom.
    pub dof: usize,
    /// What was fitted.
    pub of: TrendOf,
}

impl LossTrend {
    /// b / se(b).
    pub fn z(&self) -> f64 {
        self.slope / self.se
    }

    /// The relative rise over `span` iterations: b·span for the misfit, e^{b·span} − 1 for ln ℓ.
    pub fn rise(&self, span: f64) -> f64 {
        match self.of {
            TrendOf::Misfit => self.slope * span,
            TrendOf::LnLoss => (self.slope * span).exp_m1(),
        }
    }
}

/// The view set of a record, as a group key.
fn view_set(r: &IterationRecord, grouped: bool) -> Vec<usize> {
    if !grouped {
        return Vec::new();
    }
    let mut v = r.views.clone();
    v.sort_unstable();
    v
}

/// The within-group least-squares slope of (k, y, group) (`None` without degrees of freedom).
fn within_slope(points: &[(f64, f64, Vec<usize>)], of: TrendOf) -> Option<LossTrend> {
    let mut groups: std::collections::BTreeMap<&[usize], Vec<(f64, f64)>> = Default::default();
    for (k, y, g) in points {
        groups.entry(g.as_slice()).or_default().push((*k, *y));
    }
    let centred: Vec<(f64, f64)> = groups
        .values()
        .flat_map(|g| {
            let n = g.len() as f64;
            let (kx, ky) = g
                .iter()
                .fold((0.0, 0.0), |(a, b), (k, y)| (a + k / n, b + y / n));
            g.iter().map(move |(k, y)| (k - kx, y - ky))
        })
        .collect();
    let sxx: f64 = centred.iter().map(|(x, _)| x * x).sum();
    let sxy: f64 = centred.iter().map(|(x, y)| x * y).sum();
    let dof = points.len().checked_sub(groups.len() + 1)?;
    if sxx <= 0.0 || dof == 0 {
        return None;
    }
    let slope = sxy / sxx;
    let rss: f64 = centred.iter().map(|(x, y)| (y - slope * x).powi(2)).sum();
    Some(LossTrend {
        slope,
        se: (rss / dof as f64 / sxx).sqrt(),
        dof,
        of,
    })
}

/// [`LossTrend`] of `records` (`None` with a non-finite loss, a non-positive one where ln ℓ is
/// fitted, or too few records to fit a slope).
pub fn loss_trend(records: &[IterationRecord]) -> Option<LossTrend> {
    let fit = |grouped: bool| -> Option<LossTrend> {
        if let Some(misfits) = records
            .iter()
            .map(|r| r.misfit)
            .collect::<Option<Vec<f64>>>()
        {
            let mut sums: std::collections::BTreeMap<Vec<usize>, (f64, usize)> = Default::default();
            for (r, m) in records.iter().zip(&misfits) {
                let e = sums.entry(view_set(r, grouped)).or_default();
                (e.0, e.1) = (e.0 + m, e.1 + 1);
            }
            let points: Option<Vec<(f64, f64, Vec<usize>)>> = records
                .iter()
                .zip(&misfits)
                .map(|(r, m)| {
                    let key = view_set(r, grouped);
                    let (sum, n) = sums[&key];
                    let mean = sum / n as f64;
                    (m.is_finite() && mean > 0.0).then(|| (r.iteration as f64, m / mean, key))
                })
                .collect();
            if let Some(points) = points {
                return within_slope(&points, TrendOf::Misfit);
            }
        }
        if records
            .iter()
            .any(|r| !(r.loss.is_finite() && r.loss > 0.0))
        {
            return None;
        }
        let points: Vec<(f64, f64, Vec<usize>)> = records
            .iter()
            .map(|r| (r.iteration as f64, r.loss.ln(), view_set(r, grouped)))
            .collect();
        within_slope(&points, TrendOf::LnLoss)
    };
    match fit(true) {
        Some(t) if t.dof >= 10 => Some(t),
        _ => fit(false),
    }
}

/// The loss test of the module docs: over the last two fifths of `history`, from record
/// `final_from` (the final forward model's first iteration) on at the earliest (`None` when the
/// loss does not rise, or with fewer than 20 iterations in that window).
fn loss_rising(history: &[IterationRecord], final_from: usize) -> Option<Problem> {
    let n = history.len();
    let start = (n - 2 * (n / 5)).max(final_from);
    if n < start + 20 {
        return None;
    }
    let window = &history[start..];
    let w = window.len();
    if window.iter().any(|r| !r.loss.is_finite()) {
        return Some(Problem::LossRising {
            rise: f64::INFINITY,
            z: f64::INFINITY,
            iterations: w as u32,
            of: TrendOf::LnLoss,
        });
    }
    let t = loss_trend(window)?;
    let rise = t.rise(RISE_SPAN);
    (t.z() > 3.0 && rise > RISE_FLOOR).then_some(Problem::LossRising {
        rise,
        z: t.z(),
        iterations: w as u32,
        of: t.of,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

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
            },
            d_sigma_t: [0.0; 3],
            d_albedo: [0.0; 3],
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
        assert!(assess(&h, 0, &params(60.0, 0.9), &ParamSpec::default(), 0.0, None).is_empty());
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
        let nan = assess(&flat, 0, &params(f64::NAN, 0.9), &spec, 0.0, None);
        assert_eq!(kinds(&nan), ["non-finite"]);
        let pinned = assess(&flat, 0, &params(60.0, ALBEDO_MAX), &spec, 0.0, None);
        assert_eq!(kinds(&pinned), ["at-clamp"; 3]);
        let tiny = assess(&flat, 0, &params(SIGMA_T_MIN, 0.5), &spec, 0.0, None);
        assert_eq!(kinds(&tiny), ["at-clamp"; 3]);
        // A fixed parameter at its bound is the user's choice, not a failure.
        let fixed = ParamSpec {
            fix_albedo: true,
            ..ParamSpec::default()
        };
        assert!(assess(&flat, 0, &params(60.0, ALBEDO_MAX), &fixed, 0.0, None).is_empty());
        let dark = assess(&flat, 0, &params(60.0, 0.03), &spec, 0.0, None);
        assert_eq!(kinds(&dark), ["outside-training-range"; 3]);
        let rising: Vec<_> = (0..100)
            .map(|k| record(k, 0.2 + 0.01 * (k % 3) as f64 + 0.004 * k as f64))
            .collect();
        let r = assess(&rising, 0, &params(60.0, 0.9), &spec, 0.0, None);
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
        let r = assess(&flat, 0, &params(60.0, 0.9), &spec, 0.0, Some(&off));
        assert_eq!(kinds(&r), ["inconsistent"]);
        assert!(r[0].message().contains(" G "));
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
        assert!(assess(&h, 0, &params(60.0, 0.9), &ParamSpec::default(), 0.0, None).is_empty());
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
                0.0,
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
            0.0,
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
        assert_eq!(assess(&h, 0, &params(60.0, 0.9), &spec, 0.0, None).len(), 1);
        assert!(assess(&h, 70, &params(60.0, 0.9), &spec, 0.0, None).is_empty());
    }

    /// With no trend, |z| > 1.96 in 5 % of 400 independent runs of 120 iterations over 8 views
    /// (binomial s.d. 1.1 %, so 5 ± 3.3 % at three s.d.): the slope's standard error is
    /// calibrated for `of`. `draw` gives an iteration's record from its view and a N(0, 1) draw.
    fn assert_calibrated(
        seed: u64,
        of: TrendOf,
        draw: impl Fn(u32, usize, f64) -> IterationRecord,
    ) {
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
            match assess(h, 150, &params(60.0, 0.9), &spec, 0.0, None)[..] {
                [Problem::LossRising { of, .. }] => Some(of),
                _ => None,
            }
        };
        assert_eq!(rose(&by_loss), Some(TrendOf::LnLoss));
        assert!(assess(&flat, 150, &params(60.0, 0.9), &spec, 0.0, None).is_empty());
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
}
