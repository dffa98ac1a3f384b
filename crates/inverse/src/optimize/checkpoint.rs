//! Checkpoints of an inverse run: one JSON file (configuration, optimiser variables, Adam state,
//! history), written atomically; resume continues bit-identically.

use std::path::Path;

use base::optim::{Adam, AdamState};
use bssrdf::nn::ShapeAdaptiveModel;
use geometry::Accel;
use scene::Medium;
use scene::setting::Setting;
use serde::{Deserialize, Serialize};

use super::{
    InverseError, IterationRecord, OptimizeConfig, Optimizer, Parts, TargetView, adam_config,
    adam_parts,
};

const FORMAT: &str = "translucent-optimize-checkpoint";
const VERSION: u32 = 1;

/// What a checkpoint file holds.
#[derive(Serialize, Deserialize)]
pub struct Checkpoint {
    format: String,
    version: u32,
    /// The run's configuration.
    pub config: OptimizeConfig,
    u: Vec<f32>,
    adam_step: u64,
    adam_m: Vec<f32>,
    adam_v: Vec<f32>,
    /// The step at which the moments last restarted (absent in checkpoints of runs that never
    /// restarted them).
    #[serde(default)]
    adam_moments_from: u64,
    /// The history so far.
    pub history: Vec<IterationRecord>,
}

fn err(path: &Path, reason: impl Into<String>) -> InverseError {
    InverseError::Checkpoint {
        path: path.to_path_buf(),
        reason: reason.into(),
    }
}

impl Checkpoint {
    /// Reads and checks a checkpoint file: format and version, six finite variables with
    /// finite Adam moments (second moments ≥ 0) and at most one Adam step per recorded
    /// iteration, and a configuration that passes
    /// [`OptimizeConfig::check`], so that resuming from it cannot fail later on a damaged
    /// setting. Errors name the file.
    pub fn read(path: &Path) -> Result<Self, InverseError> {
        let text = std::fs::read_to_string(path).map_err(|e| err(path, e.to_string()))?;
        let c: Checkpoint = serde_json::from_str(&text)
            .map_err(|e| err(path, format!("malformed ({e}); the file is damaged")))?;
        if c.format != FORMAT || c.version != VERSION {
            return Err(err(
                path,
                format!(
                    "format {} v{}, expected {FORMAT} v{VERSION}",
                    c.format, c.version
                ),
            ));
        }
        let n = c.u.len();
        if n != c.config.params.len() || c.adam_m.len() != n || c.adam_v.len() != n {
            return Err(err(path, "wrong number of variables; the file is damaged"));
        }
        if c.u.iter().any(|v| !v.is_finite()) {
            return Err(err(path, "non-finite parameters"));
        }
        if c.adam_m.iter().chain(&c.adam_v).any(|v| !v.is_finite())
            || c.adam_v.iter().any(|v| *v < 0.0)
        {
            return Err(err(
                path,
                "non-finite or negative optimiser moments; the file is damaged",
            ));
        }
        // One Adam step per iteration at most, one history record per iteration.
        if c.adam_step > c.history.len() as u64 || c.history.len() > u32::MAX as usize {
            return Err(err(
                path,
                format!(
                    "adam_step = {} with {} iterations recorded; the file is damaged",
                    c.adam_step,
                    c.history.len()
                ),
            ));
        }
        if c.adam_moments_from > c.adam_step {
            return Err(err(
                path,
                format!(
                    "adam_moments_from = {} after adam_step = {}; the file is damaged",
                    c.adam_moments_from, c.adam_step
                ),
            ));
        }
        c.config
            .check()
            .map_err(|e| err(path, format!("config: {e}; the file is damaged")))?;
        Ok(c)
    }
}

impl<'a> Optimizer<'a> {
    /// Writes the checkpoint (atomically).
    pub fn save_checkpoint(&self, path: &Path) -> Result<(), InverseError> {
        let s = adam_parts(self);
        let c = Checkpoint {
            format: FORMAT.into(),
            version: VERSION,
            config: self.config.clone(),
            u: self.u.clone(),
            adam_step: s.step,
            adam_m: s.m,
            adam_v: s.v,
            adam_moments_from: s.moments_from,
            history: self.history.clone(),
        };
        let json = serde_json::to_vec(&c).map_err(|e| err(path, e.to_string()))?;
        scene::fsutil::atomic_write(path, &json, true)?;
        Ok(())
    }

    /// Resumes the run of `checkpoint` (its configuration wins). `budget` = (iterations,
    /// refine_iterations) may change the run's length and its refinement, as long as the
    /// iterations done keep their forward model: the refinement may move only where the run has
    /// not reached either start.
    pub fn resume(
        checkpoint: Checkpoint,
        budget: Option<(u32, u32)>,
        accel: &'a Accel,
        model: Option<&'a ShapeAdaptiveModel>,
        base: Medium,
        targets: Vec<TargetView<'a>>,
    ) -> Result<Self, InverseError> {
        let mut config = checkpoint.config;
        let k = checkpoint.history.len() as u32;
        if let Some((n, r)) = budget {
            // The first iteration of the refinement (none: the run's length).
            let start = |n: u32, r: u32| if r > 0 { n.saturating_sub(r) } else { u32::MAX };
            let (was, will) = (
                start(config.iterations, config.refine_iterations),
                start(n, r),
            );
            if was.min(k) != will.min(k) {
                let at = |s: u32| match s {
                    u32::MAX => "never".to_string(),
                    s => format!("from iteration {s}"),
                };
                return Err(InverseError::Invalid(format!(
                    "the run has done {k} iterations and refines with the tracer {}; {n} \
                     iterations with a refinement of {r} would refine {}, which changes \
                     iterations already done; fix: resume with the run's own refinement \
                     ({} {}) or start a new run",
                    at(was),
                    at(will),
                    Setting::Refine,
                    n.saturating_sub(was.min(n)),
                )));
            }
            config.iterations = n;
            config.refine_iterations = r;
            config.check().map_err(InverseError::Invalid)?;
        }
        // The features of the last refit before iteration k (or of the initial parameters).
        let fit_at = if config.refit_every > 0 && k > 0 {
            let r = ((k - 1) / config.refit_every) * config.refit_every;
            if r > 0 {
                checkpoint.history[r as usize].params
            } else {
                config.init
            }
        } else {
            config.init
        };
        let forward_kind = config.model_at(k);
        let mut forward = super::model_spec(&config, forward_kind, model)?.build(accel);
        // In the refinement the tracer needs no fit; it is prepared at the current parameters.
        let prepare_at = if forward_kind == config.model {
            fit_at
        } else {
            config.params.decode(&checkpoint.u)
        };
        forward.prepare(&prepare_at.medium(&base))?;
        let adam = Adam::from_state(
            adam_config(&config),
            AdamState {
                step: checkpoint.adam_step,
                m: checkpoint.adam_m,
                v: checkpoint.adam_v,
                moments_from: checkpoint.adam_moments_from,
            },
        );
        if targets.is_empty() {
            return Err(InverseError::Invalid("no target views".into()));
        }
        let parts = Parts {
            forward,
            forward_kind,
            accel,
            networks: model,
            adam,
            u: checkpoint.u,
            history: checkpoint.history,
        };
        Ok(Self::assemble(config, base, targets, parts))
    }
}
