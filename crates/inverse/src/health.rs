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

use scene::setting::Setting;
use serde::{Deserialize, Serialize};

use crate::consistency::Consistency;
use crate::optimize::IterationRecord;
use crate::params::{
    ALBEDO_MAX, ALBEDO_MIN, G_MAX, LIGHT_SCALE_MAX, LIGHT_SCALE_MIN, ParamSpec, Params, SIGMA_T_MIN,
};

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
    /// A recovered g ends at its bound, ±[`G_MAX`].
    GAtBound { value: f64 },
    /// A recovered light scale ends at its bound.
    LightScaleAtBound { value: f64 },
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
                 ({init_s}, {init_a})",
                CH[*channel],
                init_s = Setting::InitSigmaT,
                init_a = Setting::InitAlbedo,
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
            Problem::GAtBound { value } => format!(
                "g ended at its bound ({value}): the optimiser ran into the edge of the range \
                 ±{G_MAX} it allows, so the value is not a minimum of the loss; the images may \
                 not determine g (start elsewhere with {init}, or state g in the dataset)",
                init = Setting::InitG,
            ),
            Problem::LightScaleAtBound { value } => format!(
                "the light scale ended at its bound ({value}): the optimiser ran into the edge \
                 of the range [{LIGHT_SCALE_MIN}, {LIGHT_SCALE_MAX}] it allows; check the \
                 lights' stated intensities and the images' exposure, or start elsewhere \
                 ({init})",
                init = Setting::InitLightScale,
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
                 tracer ({refine}, on by default) or run more correction steps \
                 ({steps}). With any model, views that determine σ_t and more \
                 iterations help",
                channels
                    .iter()
                    .map(|&c| CH[c])
                    .collect::<Vec<_>>()
                    .join(", "),
                mean_ratio,
                l2_over_noise,
                refine = Setting::Refine,
                steps = Setting::BiasCorrectionSteps,
            ),
        }
    }
}

/// The problems of a run with history `history` (whose final forward model begins at record
/// `final_from`: the refinement's first iteration, else 0), final `estimate`, parameter spec
/// `spec`, phase-function asymmetry `g` (the object's; a recovered g is the estimate's) and,
/// when checked, its consistency (module docs).
pub fn assess(
    history: &[IterationRecord],
    final_from: usize,
    estimate: &Params,
    spec: &ParamSpec,
    g: scene::Anisotropy,
    consistency: Option<&Consistency>,
) -> Vec<Problem> {
    let mut out = Vec::new();
    let values = estimate
        .sigma_t
        .iter()
        .chain(&estimate.albedo)
        .chain(estimate.g.as_ref().map_or(&[][..], |g| g.values()))
        .chain(
            estimate
                .light_scale
                .as_ref()
                .map_or(&[][..], |k| k.values()),
        );
    if values.clone().any(|v| !v.is_finite()) {
        out.push(Problem::NonFinite {
            detail: format!("σ_t {:?}, α {:?}", estimate.sigma_t, estimate.albedo),
        });
        return out;
    }
    let g = estimate.g_or(g).channels().map(f64::from);
    if let Some(&value) = g.iter().find(|g| spec.free_g && g.abs() >= G_MAX - 1e-6) {
        out.push(Problem::GAtBound { value });
    }
    let at_bound =
        |k: &f64| *k <= LIGHT_SCALE_MIN * (1.0 + 1e-6) || *k >= LIGHT_SCALE_MAX * (1.0 - 1e-6);
    if let Some(&k) = estimate.light_scale.as_ref().and_then(|k| {
        k.values()
            .iter()
            .find(|k| spec.free_light_scale && at_bound(k))
    }) {
        out.push(Problem::LightScaleAtBound { value: k });
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
        let red = a * (1.0 - g[c]) / (1.0 - a * g[c]);
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
mod tests;
