//! The recovery's last stage: the reported medium rendered by the volumetric path tracer against
//! the targets ([`inverse::consistency`]), the tracer's own curvature along the σ_t valley
//! ([`inverse::sensitivity`]), which widens the intervals where the learned model is too sure, the
//! health checks ([`inverse::health`]), and the complete result.json with its summary lines.

use serde_json::json;

use super::prepare::Prepared;
use super::{Observer, RecoveryConfig, RecoveryError, write_result};
use crate::report;
use crate::report::advice::{self, Advice};
use inverse::consistency::{CheckView, Consistency};
use inverse::forward::ModelKind;
use inverse::health::Problem;
use inverse::optimize::{Optimizer, TargetView};
use inverse::params::Params;
use inverse::sensitivity::Sensitivity;
use inverse::uncertainty::Uncertainty;

/// The checks of the reported medium `shown` (intervals `shown_u`; `uncertainty`: the fit's
/// own), folded into `result`, which is written complete; prints the summary.
pub(super) fn check(
    cfg: &RecoveryConfig,
    opt: &Optimizer,
    p: &Prepared,
    (shown, mut shown_u): (Params, Option<Uncertainty>),
    uncertainty: Option<&Uncertainty>,
    mut result: serde_json::Value,
    obs: &dyn Observer,
) -> Result<(), RecoveryError> {
    let targets = TargetView::of_dataset(&p.ds, &cfg.dataset.display().to_string())?;
    // The lights as the estimate has them (a recovered scale on their stated intensity).
    let lights: Vec<_> = p.ds.views.iter().map(|v| shown.light(&v.light)).collect();
    let n = p.ds.views.len();
    let k = cfg.consistency_views.min(n);
    let check_views: Vec<(usize, CheckView)> = (0..k)
        .map(|i| i * n / k)
        .map(|v| {
            let view = CheckView {
                camera: &p.ds.views[v].camera,
                light: &lights[v],
                target: targets[v].image,
                index: opt.config().view_subset.as_ref().map_or(v, |s| s[v]),
            };
            (v, view)
        })
        .collect();
    let consistency = (k > 0)
        .then(|| {
            let views: Vec<_> = check_views.iter().map(|(_, v)| *v).collect();
            let pb = obs.progress(0, "consistency (volumetric path tracer)");
            let c = inverse::consistency::check(
                &p.accel,
                &shown.medium(&p.base),
                &views,
                check_spp(p),
                check_depth(p),
                cfg.optimize.seed ^ 0xC0_5157,
            );
            pb.finish_and_clear();
            c
        })
        .transpose()?;
    // The tracer's own curvature against the learned model's: nothing to check when the
    // tracer is the model.
    let learned_model = opt.config().final_model() == ModelKind::Learned;
    let sensitivity = match uncertainty {
        // With σ_t fixed there is no interval of σ_t to widen.
        Some(u) if learned_model && !u.fixed[0] => {
            sensitivity(cfg, p, &shown, u, &check_views, obs)?
        }
        _ => None,
    };
    if let (Some(u), Some(s)) = (&shown_u, &sensitivity) {
        let widened = u.with_sensitivity(&shown, s);
        if let serde_json::Value::Object(m) = widened.to_json() {
            result
                .as_object_mut()
                .expect("result.json is an object")
                .extend(m);
        }
        result["sensitivity"] = serde_json::to_value(s)?;
        shown_u = Some(widened);
    }
    let advice = match &shown_u {
        Some(u) => advice(cfg, opt, p, u, obs)?,
        None => None,
    };
    if let Some(a) = &advice {
        result["advice"] = a.to_json();
    }
    let c = &cfg.optimize;
    let final_from = match c.refine_iterations {
        0 => 0,
        r => c.iterations.saturating_sub(r) as usize,
    };
    let mut problems = inverse::health::assess(
        opt.history(),
        final_from,
        &shown,
        &opt.config().params,
        p.base.g,
        consistency.as_ref(),
    );
    if !learned_model {
        // The training range is the learned model's; the tracer has none.
        problems.retain(|p| !matches!(p, Problem::OutsideTrainingRange { .. }));
    }
    report::add_assessment(&mut result, &problems, None);
    if let Some(c) = &consistency {
        result["consistency"] = serde_json::to_value(c)?;
    }
    let units = p.ds.metadata.length_unit.map(|unit| {
        let (lines, block) = report::real_units(&shown, shown_u.as_ref(), p.base.g, unit);
        result["real_units"] = block;
        lines
    });
    result["complete"] = json!(true);
    write_result(&cfg.out, &result)?;
    super::outputs::mitsuba(cfg, &p.ds, &shown, &p.base, obs)?;
    let summary = Summary {
        shown: &shown,
        shown_u: shown_u.as_ref(),
        sensitivity: sensitivity.as_ref(),
        consistency: consistency.as_ref(),
        problems: &problems,
        units: units.unwrap_or_default(),
        advice: advice.as_ref(),
    };
    summary.say(cfg, obs);
    Ok(())
}

/// Samples per pixel of the checks' renders: the targets' own.
fn check_spp(p: &Prepared) -> u32 {
    p.ds.render.spp.unwrap_or(64)
}

/// The tracer renders the checks at the targets' own path depth.
fn check_depth(p: &Prepared) -> u32 {
    p.ds.render.max_depth.unwrap_or(volpath::DEFAULT_MAX_DEPTH)
}

/// The tracer's sensitivity at `shown` on the checked views whose learned bread the intervals
/// `u` measured; `None` when there are none.
fn sensitivity(
    cfg: &RecoveryConfig,
    p: &Prepared,
    shown: &Params,
    u: &Uncertainty,
    check_views: &[(usize, CheckView)],
    obs: &dyn Observer,
) -> Result<Option<Sensitivity>, RecoveryError> {
    let (views, breads): (Vec<_>, Vec<_>) = check_views
        .iter()
        .filter_map(|(v, view)| {
            let bread = u.view_bread.iter().find(|(i, _)| i == v)?.1;
            Some((*view, bread))
        })
        .unzip();
    if views.is_empty() {
        return Ok(None);
    }
    let pb = obs.progress(
        0,
        "sensitivity along the σ_t valley (volumetric path tracer)",
    );
    let s = inverse::sensitivity::measure(
        &p.accel,
        &shown.medium(&p.base),
        &views,
        &breads,
        // With α fixed there is no valley: the direction is σ_t alone.
        if u.fixed[1] {
            [0.0; 3]
        } else {
            inverse::sensitivity::valley_slope(&u.bread())
        },
        check_spp(p),
        check_depth(p),
        cfg.optimize.seed ^ 0x5E_4517,
    )?;
    pb.finish_and_clear();
    Ok(Some(s))
}

/// Which capture would determine σ_t for this rig where the intervals `u` leave it open
/// ([`report::advice`]): each used view's share of the information, and views with the light
/// beside or behind the object rendered at the estimate where the capture has none.
fn advice(
    cfg: &RecoveryConfig,
    opt: &Optimizer,
    p: &Prepared,
    u: &Uncertainty,
    obs: &dyn Observer,
) -> Result<Option<Advice>, RecoveryError> {
    if u.fixed[0] || u.view_bread.is_empty() || u.determined_sigma_t.iter().all(|d| *d) {
        return Ok(None);
    }
    let (lo, hi) = p.accel.mesh().bounds();
    let centre = 0.5 * (lo + hi);
    let view = |i: usize| &p.ds.views[i];
    let angle = |i: usize| advice::light_angle(&view(i).camera, &view(i).light, centre);
    let angles: Vec<f64> = u.view_bread.iter().map(|(i, _)| angle(*i)).collect();
    // A candidate for each angle class no captured view is in.
    let class = |a: f64| advice::CLASSES.iter().position(|(hi, _)| a < *hi);
    let missing: Vec<f64> = advice::CANDIDATE_ANGLES
        .into_iter()
        .filter(|&a| angles.iter().all(|&b| class(b) != class(a)))
        .collect();
    let of_view = u.view_bread[0].0;
    let pb = obs.progress(
        missing.len() as u64,
        "advice: views this capture lacks, rendered at the estimate",
    );
    let candidates = missing
        .iter()
        .enumerate()
        .map(|(i, &a)| {
            let v = view(of_view);
            let light = advice::moved_light(&v.camera, &v.light, centre, a);
            let bread = opt.candidate_bread(&v.camera, &light, &cfg.uncertainty, i)?;
            pb.inc(1);
            Ok(advice::Candidate {
                of_view,
                angle_deg: a,
                bread,
            })
        })
        .collect::<Result<Vec<_>, RecoveryError>>()?;
    pb.finish_and_clear();
    // The views as the dataset numbers them.
    let original = |v: usize| opt.config().view_subset.as_ref().map_or(v, |s| s[v]);
    Ok(advice::advise(u, &angles, &candidates).map(|mut a| {
        for g in &mut a.groups {
            g.views.iter_mut().for_each(|v| *v = original(*v));
        }
        for c in &mut a.candidates {
            c.of_view = original(c.of_view);
        }
        a
    }))
}

/// What the run prints after its checks.
struct Summary<'a> {
    shown: &'a Params,
    shown_u: Option<&'a Uncertainty>,
    sensitivity: Option<&'a Sensitivity>,
    consistency: Option<&'a Consistency>,
    problems: &'a [Problem],
    /// The estimate in real units, where the dataset states its length unit.
    units: Vec<String>,
    /// Which capture would determine σ_t, where it is not determined.
    advice: Option<&'a Advice>,
}

impl Summary<'_> {
    fn say(&self, cfg: &RecoveryConfig, obs: &dyn Observer) {
        if let Some(u) = self.shown_u {
            for line in report::interval_lines(self.shown, u) {
                obs.say(&format!("  {line}"));
            }
        }
        for line in self.advice.iter().flat_map(|a| a.lines()) {
            obs.say(&format!("  {line}"));
        }
        for line in &self.units {
            obs.say(&format!("  {line}"));
        }
        if let Some(s) = self.sensitivity {
            let rel = |c: usize| {
                format!(
                    "{:.2} ± {:.2}",
                    s.volpath[c] / s.learned[c],
                    (2.0 * s.volpath_se[c] / s.learned[c]).abs()
                )
            };
            let along = if cfg.optimize.params.fix_albedo {
                "σ_t (α fixed)"
            } else {
                "σ_t along the σ_t–α valley"
            };
            obs.say(&format!(
                "  sensitivity to {along} (volumetric path tracer, {} views): the images curve \
                 ({}, {}, {})× as much as the learned model says (± two standard errors); the \
                 intervals widen by up to √ρ = ({:.2}, {:.2}, {:.2}) from the lower end, to at \
                 most a factor 10 either way",
                s.views.len(),
                rel(0),
                rel(1),
                rel(2),
                s.ratio[0].sqrt(),
                s.ratio[1].sqrt(),
                s.ratio[2].sqrt()
            ));
        }
        if let Some(c) = self.consistency {
            obs.say(&format!(
                "  consistency (the estimate rendered by the volumetric path tracer, {} views): \
                 brightness ratio ({:.3}, {:.3}, {:.3}), L2 ({:.2}, {:.2}, {:.2})× the noise \
                 floor (the targets' own pixel variance {:.1}, {:.1}, {:.1}× our renders')",
                c.views.len(),
                c.mean_ratio[0],
                c.mean_ratio[1],
                c.mean_ratio[2],
                c.l2_over_noise[0],
                c.l2_over_noise[1],
                c.l2_over_noise[2],
                c.target_noise_ratio[0],
                c.target_noise_ratio[1],
                c.target_noise_ratio[2]
            ));
        }
        if self.problems.is_empty() {
            obs.say("  status: ok");
        }
        for p in self.problems {
            obs.say(&format!("  FAILED: {}", p.message()));
        }
        obs.say(&format!(
            "wrote {} (result.json, convergence.png/.svg, final/contact-sheet.png: every target \
             beside its re-render and difference)",
            cfg.out.display()
        ));
    }
}
