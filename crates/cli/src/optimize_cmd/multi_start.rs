//! `optimize --starts N`: several initialisations before the run, for images that leave a
//! parameter open (a flat loss along σ_t, e.g. a light beside the camera).
//!
//! Start i of N begins at σ_t = s·3^{2i/(N−1) − 1} per channel (s = `--init-sigma-t`: from s/3
//! to 3s, log-spaced, the given value in the middle when N is odd) and α = `--init-albedo`,
//! and runs a third of `--iterations` (at least 30) with the command's other settings, without
//! the work after the loop. All starts draw the same views and random numbers per iteration
//! (one seed), so their losses over the last third of their iterations compare like for like;
//! the start with the lowest mean loss there is the initialisation of the run. The starts live
//! in `OUT/starts/start-I` (reused when the command is run again) and `OUT/starts/starts.json`
//! lists each one's initialisation, estimate and loss; when the estimates of starts whose
//! losses are within their noise disagree, the images do not decide between them, which the
//! run's intervals then say too.

use anyhow::{Context, Result};
use inverse::params::Params;

use super::OptimizeArgs;
use super::reuse::{read_json, run_or_reuse};

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

/// Run (or reuse) the starts of `a` and return them with the index of the best.
pub fn run_starts(a: &OptimizeArgs) -> Result<(Vec<Start>, usize)> {
    let iterations = (a.budget.iterations / 3).max(30).min(a.budget.iterations);
    let mut starts = Vec::new();
    for (i, init) in initialisations(a.init_sigma_t, a.starts as usize)
        .into_iter()
        .enumerate()
    {
        let mut o = a.clone();
        o.starts = 1;
        o.out = a.out.join("starts").join(format!("start-{i}"));
        o.init_sigma_t = init;
        o.budget.iterations = iterations;
        o.bc = super::bias_correction::BiasCorrectionArgs::off();
        // The starts are compared by the model's loss; the chosen one's run refines.
        o.refine = Some(0);
        o.uncertainty_views = 0;
        o.consistency_views = 0;
        o.final_spp = 1;
        o.resume = false;
        o.overwrite = false;
        let label = format!("start {i} of {} (σ_t from {:.1?})", a.starts, init);
        let r = run_or_reuse(&o, &label)?;
        let ckpt = o.out.join("checkpoint.json");
        let history = read_json(&ckpt)?;
        let losses: Vec<f64> = history["history"]
            .as_array()
            .with_context(|| format!("{}: no history", ckpt.display()))?
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
        .context("--starts: no start")?;
    let json = serde_json::json!({
        "starts": starts,
        "chosen": best,
        "iterations_per_start": iterations,
    });
    scene::fsutil::atomic_write(
        &a.out.join("starts").join("starts.json"),
        serde_json::to_string_pretty(&json)?.as_bytes(),
        true,
    )?;
    println!("starts (loss over the last third of {iterations} iterations, ± its standard error):");
    for (i, s) in starts.iter().enumerate() {
        println!(
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
        );
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
