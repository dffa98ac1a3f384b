//! The parametric-bootstrap correction of a recovered medium (`optimize --bias-correction`;
//! [`inverse::bootstrap`], where the estimator and its iteration are derived).
//!
//! The learned BSSRDF is not the light transport that made the images, so the optimiser's
//! estimate θ̂ carries a bias b(θ) = F(V(θ)) − θ. Step k simulates the dataset again with the
//! volumetric path tracer V at the current medium θ_{k−1} (θ₀ = θ̂) — same mesh, cameras, lights,
//! resolution, max depth, and by default the dataset's own spp and seed — recovers θ̂_k from those
//! images with exactly the settings of the main run, and moves to
//! θ_k = θ_{k−1} + θ̂ − θ̂_k in (ln σ_t, α). Each step costs one volumetric render of the dataset
//! and one optimisation.
//!
//! Folders: `OUT/bootstrap/step-<k>/data` (the simulated dataset) and
//! `OUT/bootstrap/step-<k>/run` (its recovery); both are reused by a later `--resume` (or by
//! the same command after an interruption), so an interrupted correction continues where it
//! stopped. `OUT/result.json` then reports the corrected medium as `estimate` (with `errors`
//! against the truth when known), the optimiser's own as `estimate_uncorrected`, and every step
//! under `bias_correction`.

use std::path::Path;

use scene::{Dataset, Medium};
use serde_json::json;

use super::reuse::run_or_reuse;
use super::{Observer, RecoveryConfig, RecoveryError};
use inverse::params::Params;
use inverse::views::{RenderOpts, render_dataset, total_rows};

/// Whether and how the correction runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BiasCorrection {
    /// Whether it runs (only after a learned-model run without refinement).
    pub enabled: bool,
    /// Steps of the iterated correction.
    pub steps: u32,
    /// Samples per pixel of the simulated images (`None`: the dataset's own, else 64).
    pub spp: Option<u32>,
}

impl Default for BiasCorrection {
    fn default() -> Self {
        Self {
            enabled: true,
            steps: inverse::bootstrap::DEFAULT_STEPS,
            spp: None,
        }
    }
}

impl BiasCorrection {
    /// No correction (the bootstrap recoveries themselves, and runs whose caller corrects).
    pub fn off() -> Self {
        Self {
            enabled: false,
            ..Self::default()
        }
    }
}

/// One step of the correction.
#[derive(Clone, Copy, Debug)]
pub struct Step {
    /// θ_{k−1}: the medium the dataset was simulated at.
    pub at: Params,
    /// θ̂_k: the recovery from the simulated images.
    pub refit: Params,
    /// θ_k = θ_{k−1} + θ̂ − θ̂_k.
    pub corrected: Params,
    pub seconds_per_iteration: f64,
}

/// The steps of a correction and the samples per pixel of its simulations.
#[derive(Clone, Debug)]
pub struct Correction {
    pub steps: Vec<Step>,
    pub spp: u32,
}

/// Run the steps of the correction of `estimate` (the main run of `cfg`, on `ds`). `base`
/// supplies g and η of the simulated media.
pub fn correct(
    cfg: &RecoveryConfig,
    ds: &Dataset,
    estimate: &Params,
    base: &Medium,
    obs: &dyn Observer,
) -> Result<Correction, RecoveryError> {
    let opts = RenderOpts {
        spp: cfg.bias_correction.spp.or(ds.render.spp).unwrap_or(64),
        seed: ds.render.seed.unwrap_or(cfg.optimize.seed),
        max_depth: ds.render.max_depth.unwrap_or(volpath::DEFAULT_MAX_DEPTH),
        shadow: Default::default(),
    };
    let root = cfg.out.join("bootstrap");
    let mut steps: Vec<Step> = Vec::new();
    for k in 1..=cfg.bias_correction.steps {
        let current = steps.last().map_or(*estimate, |s| s.corrected);
        let dir = root.join(format!("step-{k}"));
        let at = current.medium(base);
        let data = dir.join("data");
        ensure_simulated(ds, at, opts, &data, k, obs)?;
        let mut o = cfg.clone();
        o.dataset = data;
        o.out = dir.join("run");
        o.bias_correction = BiasCorrection::off();
        o.starts = 1;
        // The simulation holds only the fitted views already (renumbered). Its interval is
        // taken to equal the main run's, and its consistency is not checked.
        o.optimize.view_subset = None;
        o.uncertainty.views = 0;
        o.consistency_views = 0;
        let refit = run_or_reuse(&o, obs, &format!("bootstrap step {k}"))?;
        let corrected = inverse::bootstrap::bootstrap_step(&current, estimate, &refit.estimate)
            .ok_or_else(|| {
                RecoveryError::Invalid(format!(
                    "{}: the bootstrap recovery is not a valid medium ({:?})",
                    o.out.display(),
                    refit.estimate
                ))
            })?;
        let (bs, ba) = inverse::bootstrap::estimated_bias(&current, &refit.estimate);
        obs.say(&format!(
            "bootstrap step {k}: bias at σ_t = {:.2?}, α = {:.4?}: σ_t {:+.1?} %, α {:+.4?}; \
             corrected σ_t = {:.2?}, α = {:.4?}",
            current.sigma_t,
            current.albedo,
            bs.map(|v| 100.0 * v),
            ba,
            corrected.sigma_t,
            corrected.albedo
        ));
        steps.push(Step {
            at: current,
            refit: refit.estimate,
            corrected,
            seconds_per_iteration: refit.seconds_per_iteration,
        });
    }
    Ok(Correction {
        steps,
        spp: opts.spp,
    })
}

/// Render the dataset at `at` into `data`, unless it already holds that simulation. A
/// simulation at another medium is this run's own from before it was continued (a resume
/// with more iterations moves the estimate): it and its recovery are replaced.
fn ensure_simulated(
    ds: &Dataset,
    at: Medium,
    opts: RenderOpts,
    data: &Path,
    k: u32,
    obs: &dyn Observer,
) -> Result<(), RecoveryError> {
    if data.join("dataset.json").exists() {
        let old = Dataset::load(data)?;
        if old.truth == Some(at)
            && old.render.spp == Some(opts.spp)
            && old.render.seed == Some(opts.seed)
            && old.views.len() == ds.views.len()
        {
            obs.say(&format!("bootstrap step {k}: reusing {}", data.display()));
            return Ok(());
        }
        let step = data.parent().unwrap_or(data);
        obs.say(&format!(
            "bootstrap step {k}: {} was simulated at the run's earlier estimate; replacing it",
            step.display()
        ));
        std::fs::remove_dir_all(step).map_err(|source| RecoveryError::RemoveDir {
            path: step.to_path_buf(),
            source,
        })?;
    }
    obs.say(&format!(
        "bootstrap step {k}: rendering {} views at σ_t = {:.2?}, α = {:.4?} ({} spp, volumetric \
         path tracer)",
        ds.views.len(),
        at.sigma_t,
        at.albedo,
        opts.spp
    ));
    let desc = ds.scene(at);
    let pb = obs.progress(total_rows(&desc.views), "volpath");
    render_dataset(desc, opts, data, false, &pb)?;
    pb.finish_and_clear();
    Ok(())
}

/// `result` (the main run's `result.json`) with the corrected medium as `estimate` and
/// `errors`, the optimiser's own as `estimate_uncorrected`/`errors_uncorrected`, and the steps.
pub fn corrected_result(
    mut result: serde_json::Value,
    c: &Correction,
    truth: Option<&Params>,
    uncertainty: Option<&inverse::uncertainty::Uncertainty>,
) -> serde_json::Value {
    let Some(last) = c.steps.last() else {
        return result;
    };
    if let (Some(u), Some(est)) = (uncertainty, c.steps.first().map(|s| s.at)) {
        let corrected = u.corrected(&est, &last.corrected);
        if let serde_json::Value::Object(m) = corrected.to_json() {
            result
                .as_object_mut()
                .expect("result.json is an object")
                .extend(m);
        }
    }
    let p = |p: &Params| json!({ "sigma_t": p.sigma_t, "albedo": p.albedo });
    result["estimate_uncorrected"] = result["estimate"].take();
    result["errors_uncorrected"] = result["errors"].take();
    result["estimate"] = p(&last.corrected);
    result["errors"] = json!(truth.map(|t| crate::report::errors(&last.corrected, t)));
    result["bias_correction"] = json!({
        "method": "parametric bootstrap, iterated: θ_k = θ_{k−1} + θ̂ − θ̂_k in (ln σ_t, α)",
        "simulation_spp": c.spp,
        "steps": c.steps.iter().map(|s| json!({
            "simulated_at": p(&s.at),
            "recovered": p(&s.refit),
            "corrected": p(&s.corrected),
            "seconds_per_iteration": s.seconds_per_iteration,
        })).collect::<Vec<_>>(),
    });
    result
}
