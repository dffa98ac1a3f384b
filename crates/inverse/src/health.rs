//! Whether a recovery can be trusted: the checks behind `result.json`'s `status`.
//!
//! A run *failed* when any of these holds:
//! * the estimate is not finite;
//! * a parameter that was free ends pinned at a clamp of [`crate::params`] (α at
//!   [`ALBEDO_MIN`]/[`ALBEDO_MAX`], σ_t at [`SIGMA_T_MIN`]);
//! * the loss keeps rising: the mean loss of the last fifth of the iterations exceeds that of
//!   the fifth before it by more than three standard errors of the difference (each iteration
//!   sees a random view, so single losses scatter by view; the windows' spread gives the
//!   standard errors);
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
    /// The loss rises at the end of the run.
    LossRising { earlier: f64, last: f64, z: f64 },
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
            Problem::LossRising { earlier, last, z } => format!(
                "the loss rose at the end of the run ({earlier:.4e} → {last:.4e}, {z:.1} standard \
                 errors): the optimisation diverged; lower the learning rates or add iterations"
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

/// The problems of a run with history `history`, final `estimate`, parameter spec `spec`,
/// phase-function asymmetry `g` and, when checked, its consistency (module docs).
pub fn assess(
    history: &[IterationRecord],
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
    if let Some(p) = loss_rising(history) {
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

/// The loss test of the module docs (`None` when it does not rise or the run is too short:
/// fewer than 10 iterations per window).
fn loss_rising(history: &[IterationRecord]) -> Option<Problem> {
    let w = history.len() / 5;
    if w < 10 {
        return None;
    }
    let n = history.len();
    let stats = |r: &[IterationRecord]| {
        let m = r.iter().map(|x| x.loss).sum::<f64>() / r.len() as f64;
        let v = r.iter().map(|x| (x.loss - m).powi(2)).sum::<f64>() / (r.len() as f64 - 1.0);
        (m, v / r.len() as f64)
    };
    let (last, se_last) = stats(&history[n - w..]);
    let (earlier, se_earlier) = stats(&history[n - 2 * w..n - w]);
    let z = (last - earlier) / (se_last + se_earlier).sqrt();
    (z > 3.0 || (!last.is_finite() && earlier.is_finite())).then_some(Problem::LossRising {
        earlier,
        last,
        z,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(k: u32, loss: f64) -> IterationRecord {
        IterationRecord {
            iteration: k,
            loss,
            params: Params {
                sigma_t: [50.0; 3],
                albedo: [0.9; 3],
            },
            d_sigma_t: [0.0; 3],
            d_albedo: [0.0; 3],
            views: vec![0],
            crop_origins: Vec::new(),
            seconds: 0.1,
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
        assert!(assess(&h, &params(60.0, 0.9), &ParamSpec::default(), 0.0, None).is_empty());
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
        let nan = assess(&flat, &params(f64::NAN, 0.9), &spec, 0.0, None);
        assert_eq!(kinds(&nan), ["non-finite"]);
        let pinned = assess(&flat, &params(60.0, ALBEDO_MAX), &spec, 0.0, None);
        assert_eq!(kinds(&pinned), ["at-clamp"; 3]);
        let tiny = assess(&flat, &params(SIGMA_T_MIN, 0.5), &spec, 0.0, None);
        assert_eq!(kinds(&tiny), ["at-clamp"; 3]);
        // A fixed parameter at its bound is the user's choice, not a failure.
        let fixed = ParamSpec {
            fix_albedo: true,
            ..ParamSpec::default()
        };
        assert!(assess(&flat, &params(60.0, ALBEDO_MAX), &fixed, 0.0, None).is_empty());
        let dark = assess(&flat, &params(60.0, 0.03), &spec, 0.0, None);
        assert_eq!(kinds(&dark), ["outside-training-range"; 3]);
        let rising: Vec<_> = (0..100)
            .map(|k| record(k, 0.2 + 0.01 * (k % 3) as f64 + 0.004 * k as f64))
            .collect();
        let r = assess(&rising, &params(60.0, 0.9), &spec, 0.0, None);
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
        let r = assess(&flat, &params(60.0, 0.9), &spec, 0.0, Some(&off));
        assert_eq!(kinds(&r), ["inconsistent"]);
        assert!(r[0].message().contains(" G "));
    }
}
