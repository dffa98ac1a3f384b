//! The recovery's middle stages: the Adam loop with its progress and checkpoints ([`fit`]), the
//! 95 % intervals and the first record of the estimate ([`intervals`]), and the bias correction
//! of a learned-model fit ([`correct`]).

use std::time::Instant;

use serde_json::json;

use super::prepare::Prepared;
use super::{
    Observer, RecoveryConfig, RecoveryError, bias_correction, estimate_lines, outputs, write_result,
};
use crate::report;
use inverse::forward::ModelKind;
use inverse::optimize::{InverseError, Optimizer, Ran};
use inverse::params::Params;
use inverse::uncertainty::{CAPTURE_DRAWS, Uncertainty};

/// Runs the loop to the configured iterations, writing checkpoints and `iterations.csv`;
/// returns the loop's seconds. A run that breaks down numerically leaves its record (the
/// history and a `failed` result.json) and says so; one that the observer stops
/// ([`Observer::iteration`]) leaves its record, an `interrupted` result.json and a checkpoint.
pub(super) fn fit(
    cfg: &RecoveryConfig,
    opt: &mut Optimizer,
    p: &Prepared,
    obs: &dyn Observer,
) -> Result<f64, RecoveryError> {
    let t0 = Instant::now();
    let pb = obs.progress(opt.config().iterations as u64, "optimize");
    pb.set_position(opt.iteration() as u64);
    let csv = cfg.out.join("iterations.csv");
    let ran = opt.run_until(Some((&p.ckpt, cfg.checkpoint_every)), |r, p| {
        pb.set_position(r.iteration as u64 + 1);
        pb.set_message(format!(
            "loss {:.3e} σ_t ({:.1}, {:.1}, {:.1}) α ({:.3}, {:.3}, {:.3})",
            r.loss, p.sigma_t[0], p.sigma_t[1], p.sigma_t[2], p.albedo[0], p.albedo[1], p.albedo[2]
        ));
        obs.iteration(r, p)
    });
    pb.finish_and_clear();
    if let Ok(Ran::Stopped) = ran {
        // Stopped by the caller: the record so far, a result that says so, the checkpoint to
        // resume from (written by the loop).
        report::write_csv(opt.history(), &csv)?;
        let done = opt.history().len();
        let stopped = json!({
            "status": "interrupted",
            "complete": false,
            "iterations": done,
            "estimate": opt.params(),
            "config": opt.config(),
        });
        write_result(&cfg.out, &stopped)?;
        return Err(RecoveryError::Interrupted {
            iteration: done,
            of: opt.config().iterations as usize,
            checkpoint: p.ckpt.clone(),
        });
    }
    if let Err(e) = ran {
        if !matches!(e, InverseError::NonFinite { .. }) {
            // A failed write (disk full, permissions) or render: the outputs on disk stay as
            // they were (the last checkpoint included, written atomically); say what failed.
            return Err(RecoveryError::Stopped {
                iteration: opt.history().len(),
                checkpoint: p.ckpt.clone(),
                source: Box::new(e),
            });
        }
        // A run that broke down numerically still leaves its record: the history so far and a
        // failed status (the last good checkpoint stays as it was).
        report::write_csv(opt.history(), &csv)?;
        let failed = json!({
            "status": "failed",
            "problems": [inverse::health::Problem::NonFinite { detail: e.to_string() }],
            "iterations": opt.history().len(),
            "config": opt.config(),
        });
        write_result(&cfg.out, &failed)?;
        return Err(RecoveryError::Failed {
            iterations: opt.history().len(),
            result: cfg.out.join("result.json"),
            source: Box::new(e),
        });
    }
    let seconds = t0.elapsed().as_secs_f64();
    report::write_csv(opt.history(), &csv)?;
    Ok(seconds)
}

/// The estimate and its intervals (none when `cfg.uncertainty.views` is 0), recorded as a
/// result.json not yet complete, with the convergence plot and the re-renders; prints the
/// estimate.
pub(super) fn intervals(
    cfg: &RecoveryConfig,
    opt: &Optimizer,
    p: &Prepared,
    seconds_total: f64,
    obs: &dyn Observer,
) -> Result<(Params, Option<Uncertainty>, serde_json::Value), RecoveryError> {
    let estimate = opt.params();
    let uncertainty = if cfg.uncertainty.views > 0 {
        let pb = obs.progress(0, "95 % intervals");
        let capture = capture_deltas(cfg, opt, p)?;
        let u = opt.uncertainty(&cfg.uncertainty, &capture)?;
        pb.finish_and_clear();
        Some(u)
    } else {
        None
    };
    let truth = p.truth.as_ref();
    let mut result =
        report::result_json(opt.config(), opt.history(), &estimate, truth, seconds_total);
    report::add_assessment(&mut result, &[], uncertainty.as_ref());
    // Not final until the correction and the checks are in: an interrupted command is resumed
    // rather than reused (`run_or_reuse`).
    result["complete"] = json!(false);
    result["status"] = json!("incomplete");
    let (object, stated) = p.object;
    // The values as the dataset states them (1.33, not f32's 1.3300000429153442).
    let short = |x: f32| format!("{x}").parse::<f64>().unwrap_or(x as f64);
    // One number, or three where the channels' g differ.
    let short_g = |g: scene::Anisotropy| match g.as_uniform() {
        Some(g) => json!(short(g)),
        None => json!(g.channels().map(short)),
    };
    result["object"] = json!({
        "boundary": if object.eta == 1.0 {
            json!({ "type": "null" })
        } else {
            json!({
                "type": "dielectric",
                "eta": short(object.eta),
                "roughness": short(object.roughness),
            })
        },
        "phase": if opt.config().params.free_g {
            json!({ "type": "hg", "g": "recovered", "stated_g": short_g(object.g) })
        } else {
            json!({ "type": "hg", "g": short_g(object.g) })
        },
        "source": if stated { "dataset" } else { "assumed: the dataset states none" },
        "not_modelled": p.gaps,
    });
    write_result(&cfg.out, &result)?;
    report::write_plots(
        opt.history(),
        &estimate,
        truth,
        uncertainty.as_ref(),
        &cfg.out.join("convergence.png"),
    )?;
    outputs::rerender(cfg, opt, &p.ds, &estimate, obs)?;
    let spi = result["seconds_per_iteration"].as_f64().unwrap_or(f64::NAN);
    obs.say(&format!(
        "after {} iterations ({spi:.2} s/iteration):",
        opt.history().len()
    ));
    for line in estimate_lines(&estimate, truth) {
        obs.say(&line);
    }
    Ok((estimate, uncertainty, result))
}

/// δI of the stated mesh error's draws ([`inverse::uncertainty::capture`]): the run's mesh with
/// [`CAPTURE_DRAWS`] independent noises of the stated size, each rendered by the tracer at the
/// estimate; none where no error is stated.
fn capture_deltas(
    cfg: &RecoveryConfig,
    opt: &Optimizer,
    p: &Prepared,
) -> Result<Vec<Vec<scene::Image>>, RecoveryError> {
    let Some(f) = cfg.uncertainty.mesh_error else {
        return Ok(Vec::new());
    };
    let accels: Vec<geometry::Accel> = (0..CAPTURE_DRAWS)
        .map(|k| {
            let seed = base::rng::hash_key(&[cfg.optimize.seed, 0x3E5E_0000, k as u64]);
            geometry::Accel::new(scene::capture::noisy_mesh(p.accel.mesh(), f as f32, seed))
        })
        .collect();
    let refs: Vec<&geometry::Accel> = accels.iter().collect();
    Ok(opt.capture_deltas(&cfg.uncertainty, &refs)?)
}

/// The medium the run reports and its intervals: the estimate, or its bias-corrected value for a
/// learned-model fit when the correction is on (recorded in `result`).
pub(super) fn correct(
    cfg: &RecoveryConfig,
    opt: &Optimizer,
    p: &Prepared,
    (estimate, uncertainty): (&Params, Option<&Uncertainty>),
    result: &mut serde_json::Value,
    obs: &dyn Observer,
) -> Result<(Params, Option<Uncertainty>), RecoveryError> {
    let (mut shown, mut shown_u) = (*estimate, uncertainty.cloned());
    // The volumetric model is the simulator the correction would use: it has no bias of its own
    // to measure, and a correction would only add a second recovery's noise. The same holds
    // after a volumetric refinement.
    if !(cfg.bias_correction.enabled && opt.config().final_model() == ModelKind::Learned) {
        return Ok((shown, shown_u));
    }
    // The model's own fit stays in convergence.png and final/; result.json reports the
    // corrected medium.
    let truth = p.truth.as_ref();
    let c = bias_correction::correct(cfg, &p.ds, estimate, &p.base, obs)?;
    *result = bias_correction::corrected_result(result.take(), &c, truth, uncertainty);
    if let Some(last) = c.steps.last() {
        obs.say(&format!(
            "bias-corrected ({} step{}, simulations at {} spp):",
            c.steps.len(),
            if c.steps.len() == 1 { "" } else { "s" },
            c.spp
        ));
        for line in estimate_lines(&last.corrected, truth) {
            obs.say(&line);
        }
        shown = last.corrected;
        shown_u = uncertainty.map(|u| u.corrected(estimate, &shown));
    }
    Ok((shown, shown_u))
}
