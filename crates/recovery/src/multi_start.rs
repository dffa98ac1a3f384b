//! Several initialisations before the run (`optimize --starts N`), for images that leave a
//! parameter open (a flat loss along σ_t, e.g. a light beside the camera).
//!
//! Start i of N begins at σ_t = s·3^{2i/(N−1) − 1} per channel (s the configured initial σ_t:
//! from s/3 to 3s, log-spaced, the given value in the middle when N is odd) and the configured
//! initial α, and runs a third of the run's iterations (at least 30) without the refinement,
//! with the run's other settings, without the work after the loop. All starts draw the same
//! views and random numbers per iteration (one seed), so their losses over the last third of
//! their iterations compare like for like; the start with the lowest mean loss there is the
//! initialisation of the run. The starts live in `OUT/starts/start-I` (reused when the command
//! is run again) and `OUT/starts/starts.json` lists each one's initialisation, estimate and
//! loss; when the estimates of starts whose losses are within their noise disagree, the images
//! do not decide between them, which the run's intervals then say too.

use super::reuse::{read_json, run_or_reuse};
use scene::setting::Setting;

use super::{BiasCorrection, Observer, RecoveryConfig, RecoveryError};
use inverse::forward::ModelKind;
use inverse::params::Params;

/// One start's outcome.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Start {
    pub init_sigma_t: [f32; 3],
    pub estimate: Params,
    /// Mean loss over the last third of the start's iterations.
    pub loss: f64,
    /// Its standard error (iteration-to-iteration spread / √n).
    pub loss_se: f64,
}

/// The initialisations of `n` starts around `init` (module docs).
pub fn initialisations(init: [f32; 3], n: usize) -> Vec<[f32; 3]> {
    (0..n)
        .map(|i| {
            let e = if n == 1 {
                0.0
            } else {
                2.0 * i as f32 / (n - 1) as f32 - 1.0
            };
            init.map(|s| s * 3f32.powf(e))
        })
        .collect()
}

/// The recovery of start `i` from σ_t = `init`: `iterations` without the refinement (the
/// starts are compared by the model's loss; the chosen one's run refines), without the work
/// after the loop.
fn start_config(cfg: &RecoveryConfig, i: usize, init: [f32; 3], iterations: u32) -> RecoveryConfig {
    let mut o = cfg.clone();
    o.starts = 1;
    o.out = cfg.out.join("starts").join(format!("start-{i}"));
    o.optimize.init.sigma_t = init.map(|v| v as f64);
    o.optimize.iterations = iterations;
    o.optimize.refine_iterations = 0;
    o.refine_given = true;
    if o.optimize.model.kind() != ModelKind::Volpath {
        // Without a refinement the tracer's depth is not part of the run.
        o.optimize.volpath_max_depth = None;
    }
    o.bias_correction = BiasCorrection::off();
    o.uncertainty.views = 0;
    o.consistency_views = 0;
    o.final_spp = 1;
    o.resume = false;
    o.overwrite = false;
    o
}

/// Run (or reuse) the starts of `cfg` and return them with the index of the best.
pub fn run_starts(
    cfg: &RecoveryConfig,
    obs: &dyn Observer,
) -> Result<(Vec<Start>, usize), RecoveryError> {
    let total = cfg.optimize.iterations;
    let iterations = (total / 3).max(30).min(total);
    let init = cfg.optimize.init.sigma_t.map(|v| v as f32);
    let mut starts = Vec::new();
    for (i, init) in initialisations(init, cfg.starts as usize)
        .into_iter()
        .enumerate()
    {
        let o = start_config(cfg, i, init, iterations);
        let label = format!("start {i} of {} (σ_t from {:.1?})", cfg.starts, init);
        let r = run_or_reuse(&o, obs, &label)?;
        let ckpt = o.out.join("checkpoint.json");
        let history = read_json(&ckpt)?;
        let losses: Vec<f64> = history["history"]
            .as_array()
            .ok_or_else(|| RecoveryError::Invalid(format!("{}: no history", ckpt.display())))?
            .iter()
            .filter_map(|r| r["loss"].as_f64())
            .collect();
        let tail = &losses[losses.len() - (losses.len() / 3).max(1)..];
        let n = tail.len() as f64;
        let mean = tail.iter().sum::<f64>() / n;
        let var = tail.iter().map(|l| (l - mean).powi(2)).sum::<f64>() / (n - 1.0).max(1.0);
        starts.push(Start {
            init_sigma_t: init,
            estimate: r.estimate,
            loss: mean,
            loss_se: (var / n).sqrt(),
        });
    }
    let best = (0..starts.len())
        .min_by(|&i, &j| starts[i].loss.total_cmp(&starts[j].loss))
        .ok_or_else(|| RecoveryError::Invalid(format!("{}: no start", Setting::Starts)))?;
    let json = serde_json::json!({
        "starts": starts,
        "chosen": best,
        "iterations_per_start": iterations,
    });
    scene::fsutil::atomic_write(
        &cfg.out.join("starts").join("starts.json"),
        serde_json::to_string_pretty(&json)?.as_bytes(),
        true,
    )?;
    obs.say(&format!(
        "starts (loss over the last third of {iterations} iterations, ± its standard error):"
    ));
    for (i, s) in starts.iter().enumerate() {
        obs.say(&format!(
            "  {} start {i}: from σ_t {:.1?} to σ_t ({:.1}, {:.1}, {:.1}) α ({:.3}, {:.3}, {:.3}), loss {:.4e} ± {:.1e}",
            if i == best { "*" } else { " " },
            s.init_sigma_t,
            s.estimate.sigma_t[0],
            s.estimate.sigma_t[1],
            s.estimate.sigma_t[2],
            s.estimate.albedo[0],
            s.estimate.albedo[1],
            s.estimate.albedo[2],
            s.loss,
            s.loss_se
        ));
    }
    Ok((starts, best))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn initialisations_span_a_third_to_three_times_the_given_value() {
        let v = initialisations([50.0, 60.0, 90.0], 3);
        assert_eq!(v.len(), 3);
        for c in 0..3 {
            let s = [50.0f32, 60.0, 90.0][c];
            assert!((v[0][c] - s / 3.0).abs() < 1e-3 * s);
            assert_eq!(v[1][c], s);
            assert!((v[2][c] - 3.0 * s).abs() < 1e-3 * s);
        }
        assert_eq!(initialisations([50.0; 3], 1), vec![[50.0; 3]]);
    }
}
