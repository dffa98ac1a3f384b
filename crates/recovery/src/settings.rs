//! What a user chooses about a recovery, grouped as `optimize --help` groups it, with the
//! product's defaults: [`RecoverySettings`]. Every front end (the command line, the
//! experiments, a Python caller) starts from [`RecoverySettings::default`], changes what it
//! was asked to, and resolves the result into the [`RecoveryConfig`] that
//! [`super::run`] takes. The defaults of the loop itself are [`OptimizeConfig::default`]'s,
//! so each is written once.
//!
//! Resolution ([`RecoverySettings::resolve`]) decides what depends on more than one setting:
//! the refinement's length (half of the iterations with the learned model, none with the
//! others or when the bias correction is asked for instead), the tracer's depth (the dataset's
//! own unless given), which model file is read, and it refuses combinations that cannot run,
//! naming the settings ([`Setting`]) and the fix.

use std::path::PathBuf;

use bssrdf::diff::{Loss, Primal};
use bssrdf::render::LearnedSettings;
use scene::setting::Setting;

use super::{BiasCorrection, RecoveryConfig, RecoveryError};
use inverse::forward::{ModelChoice, ModelKind};
use inverse::optimize::OptimizeConfig;
use inverse::params::{OneOrRgb, ParamSpec};
use inverse::uncertainty::UncertaintySettings;

mod start;

pub use start::{DatasetFacts, StartSettings};

/// A recovery's settings, nested by concern; [`Default`] is the product's recovery.
#[derive(Clone, Debug, PartialEq)]
pub struct RecoverySettings {
    /// The forward model, its gradient estimator and its file.
    pub model: ModelSettings,
    /// Where the fit starts.
    pub start: StartSettings,
    /// The Adam loop every model shares: budget, learning rates, loss, views, seed.
    pub schedule: Schedule,
    /// The learned model's own settings (renderer, descriptor refits, offset samples).
    pub learned: LearnedSection,
    /// The volumetric path tracer's: its depth and the refinement it runs after the learned fit.
    pub tracer: TracerSection,
    /// Outputs and checks after the fit.
    pub checks: CheckSettings,
    /// The parametric-bootstrap bias correction of a learned-model run without refinement.
    pub bias_correction: BiasCorrectionSettings,
    /// Continue the run in the output folder from its checkpoint.
    pub resume: bool,
    /// Replace a run in the output folder.
    pub overwrite: bool,
}

/// Which forward model renders, and how its gradient is estimated.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ModelSettings {
    /// The model ([`ModelKind`]); the learned BSSRDF by default.
    pub kind: ModelKind,
    /// The gradient estimator by name (`None`: the model's default;
    /// [`ModelChoice::new`] lists the valid names).
    pub estimator: Option<String>,
    /// The learned model's networks from a file (`None`, `shipped` or `learned`: the shipped
    /// model). Only the learned model reads one.
    pub file: Option<PathBuf>,
}

/// The loop's schedule, shared by every model ([`OptimizeConfig`] documents each field).
#[derive(Clone, Debug, PartialEq)]
pub struct Schedule {
    pub iterations: u32,
    pub spp: u32,
    pub views_per_iter: usize,
    pub crop: Option<u32>,
    /// The dataset's views that are the targets (`None`: all).
    pub view_subset: Option<Vec<usize>>,
    pub seed: u64,
    pub lr_sigma_t: f32,
    pub lr_albedo: f32,
    pub lr_g: f32,
    pub lr_light_scale: f32,
    pub decay: f32,
    pub decay_every: u32,
    pub albedo_warmup: u32,
    pub params: ParamSpec,
    pub loss: Loss,
    /// The paper's single-render gradient 2(I − T)·∂I/∂θ instead of two independent renders.
    pub single_render: bool,
    /// The two renders as a full value and a full derivative render instead of two derivative
    /// renders at half the samples each.
    pub full_renders: bool,
    pub normalize_views: bool,
    pub view_weight_floor: f64,
}

/// The learned model's settings ([`OptimizeConfig`] documents each field).
#[derive(Clone, Debug, PartialEq)]
pub struct LearnedSection {
    /// The learned renderer's projection, descriptor handling and ablations.
    pub renderer: LearnedSettings,
    pub refit_every: u32,
    pub fit_derivative: bool,
    pub delta_rel: f32,
    pub primal: Primal,
}

/// The volumetric path tracer's settings.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TracerSection {
    /// Maximum path depth (Mitsuba `volpath` semantics; `None`: the dataset's own, else 32).
    pub max_depth: Option<u32>,
    /// The last this many iterations refine with the tracer (`None`: half of the iterations
    /// with the learned model, none with the others; 0: the learned model alone).
    pub refine: Option<u32>,
    /// Samples per pixel of the refinement's iterations (`None`: the schedule's).
    pub refine_spp: Option<u32>,
    /// Carry Adam's moments into the refinement instead of starting them again.
    pub refine_keeps_moments: bool,
}

/// Checkpoints, re-renders, intervals and the consistency check after the fit.
#[derive(Clone, Debug, PartialEq)]
pub struct CheckSettings {
    /// Iterations between checkpoints.
    pub checkpoint_every: u32,
    /// Samples per pixel of the re-renders in `OUT/final/`.
    pub final_spp: u32,
    /// The 95 % intervals (`views` 0: none).
    pub uncertainty: UncertaintySettings,
    /// Views re-rendered by the volumetric path tracer at the estimate (0: no check).
    pub consistency_views: usize,
}

/// The bias correction ([`super::bias_correction`]).
#[derive(Clone, Debug, PartialEq)]
pub struct BiasCorrectionSettings {
    /// Its steps, samples and whether it runs after a learned-model run without refinement.
    pub correction: BiasCorrection,
    /// The learned model alone with the correction, instead of the tracer's refinement.
    pub instead_of_refinement: bool,
}

/// The iterations and samples of a run (the part of [`Schedule`] that runs at another scale
/// change); by default the product's.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Budget {
    pub iterations: u32,
    pub spp: u32,
    pub views_per_iter: usize,
    pub crop: Option<u32>,
}

impl Default for Budget {
    fn default() -> Self {
        let s = RecoverySettings::default().schedule;
        Budget {
            iterations: s.iterations,
            spp: s.spp,
            views_per_iter: s.views_per_iter,
            crop: s.crop,
        }
    }
}

impl Budget {
    /// Sets the schedule's budget to this one.
    pub fn apply(&self, s: &mut Schedule) {
        s.iterations = self.iterations;
        s.spp = self.spp;
        s.views_per_iter = self.views_per_iter;
        s.crop = self.crop;
    }
}

/// The forward model, its learned networks' file and the learned renderer's settings (the
/// estimator aside); by default the product's.
#[derive(Clone, Debug, PartialEq)]
pub struct LearnedModel {
    pub kind: ModelKind,
    /// The learned model's networks from a file instead of the shipped ones.
    pub file: Option<PathBuf>,
    pub renderer: LearnedSettings,
}

impl Default for LearnedModel {
    fn default() -> Self {
        let s = RecoverySettings::default();
        LearnedModel {
            kind: s.model.kind,
            file: s.model.file,
            renderer: s.learned.renderer,
        }
    }
}

impl LearnedModel {
    /// Sets the model, its file and the learned renderer's settings of `s` to these (the
    /// estimator stays).
    pub fn apply(&self, s: &mut RecoverySettings) {
        s.model.kind = self.kind;
        s.model.file = self.file.clone();
        s.learned.renderer = self.renderer;
    }

    /// One line naming the model and the renderer's settings (report headers).
    pub fn describe(&self) -> String {
        let model = self
            .file
            .as_ref()
            .map_or("shipped".to_string(), |p| p.display().to_string());
        format!("model {model}, {}", self.renderer.describe())
    }
}

impl Default for RecoverySettings {
    /// The product's recovery: [`OptimizeConfig::default`]'s loop, one start, the shipped
    /// learned model refined by the tracer at the dataset's depth, checkpoints every 10
    /// iterations, re-renders at 64 spp, intervals and the consistency check on 4 views.
    fn default() -> Self {
        let c = OptimizeConfig::default();
        RecoverySettings {
            model: ModelSettings::default(),
            start: StartSettings {
                init: c.init,
                sigma_t_from_units: true,
                starts: 1,
            },
            schedule: Schedule {
                iterations: c.iterations,
                spp: c.spp,
                views_per_iter: c.views_per_iter,
                crop: c.crop,
                view_subset: c.view_subset,
                seed: c.seed,
                lr_sigma_t: c.lr_sigma_t,
                lr_albedo: c.lr_albedo,
                lr_g: c.lr_g,
                lr_light_scale: c.lr_light_scale,
                decay: c.decay,
                decay_every: c.decay_every,
                albedo_warmup: c.albedo_warmup,
                params: c.params,
                loss: c.loss,
                single_render: !c.two_renders,
                full_renders: !c.split_samples,
                normalize_views: c.normalize_views,
                view_weight_floor: c.view_weight_floor,
            },
            learned: LearnedSection {
                renderer: c.learned,
                refit_every: c.refit_every,
                fit_derivative: c.fit_derivative,
                delta_rel: c.delta_rel,
                primal: c.primal,
            },
            tracer: TracerSection::default(),
            checks: CheckSettings {
                checkpoint_every: 10,
                final_spp: 64,
                uncertainty: UncertaintySettings::default(),
                consistency_views: 4,
            },
            bias_correction: BiasCorrectionSettings {
                correction: BiasCorrection::default(),
                instead_of_refinement: false,
            },
            resume: false,
            overwrite: false,
        }
    }
}

impl RecoverySettings {
    /// The recovery of `dataset` into `out`, resolved. What it needs of the dataset (its own
    /// tracer depth when the tracer is used and no depth is given; the object's size when
    /// σ_t's start is scaled to it) is asked of `facts`, at most once.
    pub fn resolve(
        &self,
        dataset: PathBuf,
        out: PathBuf,
        facts: impl FnOnce() -> Result<DatasetFacts, RecoveryError>,
    ) -> Result<RecoveryConfig, RecoveryError> {
        let model_file = self.model_file()?;
        Ok(RecoveryConfig {
            dataset,
            out,
            optimize: self.optimize_config(facts)?,
            model_file,
            max_depth: self.tracer.max_depth,
            refine_given: self.tracer.refine.is_some(),
            checkpoint_every: self.checks.checkpoint_every,
            final_spp: self.checks.final_spp,
            uncertainty: self.checks.uncertainty,
            consistency_views: self.checks.consistency_views,
            starts: self.start.starts,
            resume: self.resume,
            overwrite: self.overwrite,
            bias_correction: self.bias_correction.correction,
        })
    }

    /// [`RecoverySettings::resolve`] with the facts read from the dataset's files when needed.
    pub fn resolve_for(
        &self,
        dataset: PathBuf,
        out: PathBuf,
    ) -> Result<RecoveryConfig, RecoveryError> {
        let facts = {
            let d = dataset.clone();
            move || DatasetFacts::read(&d)
        };
        self.resolve(dataset, out, facts)
    }

    /// The model file to read: `None` for the shipped model; an error for a file given to a
    /// model that has no networks.
    pub fn model_file(&self) -> Result<Option<PathBuf>, RecoveryError> {
        let Some(file) = &self.model.file else {
            return Ok(None);
        };
        if self.model.kind != ModelKind::Learned {
            return Err(RecoveryError::Invalid(format!(
                "{} {} with {} {}: only the learned model reads a model file; drop {} or use \
                 {} learned",
                Setting::ModelFile,
                file.display(),
                Setting::Model,
                self.model.kind,
                Setting::ModelFile,
                Setting::Model
            )));
        }
        Ok(match file.as_os_str().to_str() {
            Some("shipped" | "learned") => None,
            _ => Some(file.clone()),
        })
    }

    /// The loop's configuration: the schedule and the model's sections in the flat form that
    /// checkpoints and `result.json` record.
    pub fn optimize_config(
        &self,
        facts: impl FnOnce() -> Result<DatasetFacts, RecoveryError>,
    ) -> Result<OptimizeConfig, RecoveryError> {
        let (s, t) = (&self.schedule, &self.tracer);
        let kind = self.model.kind;
        let invalid = RecoveryError::Invalid;
        let mut c = OptimizeConfig::new(self.start.init);
        c.model = ModelChoice::new(kind, self.model.estimator.as_deref())
            .map_err(|e| invalid(format!("{}: {e}", Setting::Estimator)))?;
        c.iterations = s.iterations;
        let instead = self.bias_correction.instead_of_refinement;
        c.refine_iterations = match t.refine {
            Some(r) if r > 0 && instead => {
                return Err(invalid(format!(
                    "{} with {} {r}: the correction is for the learned model alone; fix: drop \
                     one of the two (the refinement replaces the correction)",
                    Setting::BiasCorrection,
                    Setting::Refine
                )));
            }
            Some(r) => r,
            None if instead => 0,
            None => OptimizeConfig::default_refinement(kind, s.iterations),
        };
        // Only a run with a refinement records the choice (runs without one compare equal to
        // those written before it existed).
        c.refine_restarts_moments = c.refine_iterations > 0 && !t.refine_keeps_moments;
        let traces = kind == ModelKind::Volpath || c.refine_iterations > 0;
        let facts = if (traces && t.max_depth.is_none()) || self.start.sigma_t_from_units {
            facts()?
        } else {
            DatasetFacts::default()
        };
        c.init = self.start.init_for(&facts);
        if traces {
            c.volpath_max_depth = t.max_depth.or(facts.depth);
        }
        c.spp = s.spp;
        if let Some(r) = t.refine_spp {
            if c.refine_iterations == 0 {
                return Err(invalid(format!(
                    "{} {r} without a refinement ({} 0, {} or a model other than the learned \
                     one); fix: drop {} or refine",
                    Setting::RefineSpp,
                    Setting::Refine,
                    Setting::BiasCorrection,
                    Setting::RefineSpp
                )));
            }
            c.refine_spp = Some(r);
        }
        c.views_per_iter = s.views_per_iter;
        c.view_subset = s.view_subset.clone();
        c.loss = s.loss;
        c.two_renders = !s.single_render;
        c.split_samples = !s.full_renders;
        if s.view_weight_floor.is_nan() || s.view_weight_floor <= 0.0 || s.view_weight_floor > 1.0 {
            return Err(invalid(format!(
                "{} must be in (0, 1], got {}",
                Setting::ViewWeightFloor,
                s.view_weight_floor
            )));
        }
        c.normalize_views = s.normalize_views;
        c.view_weight_floor = s.view_weight_floor;
        c.crop = s.crop;
        c.lr_sigma_t = s.lr_sigma_t;
        c.lr_albedo = s.lr_albedo;
        c.lr_g = s.lr_g;
        c.lr_light_scale = s.lr_light_scale;
        c.decay = s.decay;
        c.decay_every = s.decay_every;
        let l = &self.learned;
        c.refit_every = l.refit_every;
        c.fit_derivative = l.fit_derivative;
        c.delta_rel = l.delta_rel;
        c.primal = l.primal;
        c.learned = l.renderer;
        c.seed = s.seed;
        c.albedo_warmup = s.albedo_warmup;
        c.params = s.params.clone();
        self.check_free_g(&c)?;
        self.check_free_light_scale(&c)?;
        Ok(c)
    }

    /// A starting light scale needs a free one and must be positive; the learned model's
    /// single-render gradient keeps no value image for ∂ℓ/∂ln k, and its bias correction
    /// simulates the dataset with its lights as stated.
    fn check_free_light_scale(&self, c: &OptimizeConfig) -> Result<(), RecoveryError> {
        let invalid = RecoveryError::Invalid;
        if let Some(k) = self.start.init.light_scale {
            let positive = k.values().iter().all(|k| k.is_finite() && *k > 0.0);
            if !c.params.free_light_scale {
                return Err(invalid(format!(
                    "{} {k} without {}: the lights are as the dataset states them unless their \
                     scale is recovered; fix: add {} or drop {}",
                    Setting::InitLightScale,
                    Setting::FreeLightScale,
                    Setting::FreeLightScale,
                    Setting::InitLightScale
                )));
            }
            if !positive {
                return Err(invalid(format!(
                    "{} {k}: a factor on the lights' intensity must be positive",
                    Setting::InitLightScale
                )));
            }
        }
        if c.params.free_light_scale
            && c.final_model() == ModelKind::Learned
            && self.bias_correction.correction.enabled
        {
            return Err(invalid(format!(
                "{} with the bias correction of the learned model alone: its simulations \
                 render the lights as the dataset states them; fix: keep the refinement ({} \
                 above 0)",
                Setting::FreeLightScale,
                Setting::Refine
            )));
        }
        if c.params.free_light_scale
            && self.schedule.single_render
            && c.model.kind() == ModelKind::Learned
        {
            return Err(invalid(format!(
                "{} with the single-render gradient of the learned model: its fused render \
                 keeps no value image for the light scale's gradient; fix: drop the \
                 single-render gradient",
                Setting::FreeLightScale
            )));
        }
        Ok(())
    }

    /// A free g needs a model that differentiates g in the run's last iterations (the tracer
    /// with `ad`: the model, or the refinement after the learned fit, which holds g at its
    /// start); a starting g needs a free g.
    fn check_free_g(&self, c: &OptimizeConfig) -> Result<(), RecoveryError> {
        let invalid = RecoveryError::Invalid;
        if let Some(g) = self.start.init.g {
            if !c.params.free_g {
                return Err(invalid(format!(
                    "{} {g} without {}: g is the dataset's own unless it is recovered; fix: add \
                     {} or drop {}",
                    Setting::InitG,
                    Setting::FreeG,
                    Setting::FreeG,
                    Setting::InitG
                )));
            }
            if matches!(g, OneOrRgb::Rgb(_)) && !c.params.g_per_channel {
                return Err(invalid(format!(
                    "{} {g} gives a g per channel, but one g is recovered; fix: recover one per \
                     channel ({}), or give one value",
                    Setting::InitG,
                    Setting::FreeGRgb
                )));
            }
            if !g.values().iter().all(|g| g.is_finite() && g.abs() < 1.0) {
                return Err(invalid(format!(
                    "{} {g}: the phase function's g must be in (-1, 1)",
                    Setting::InitG
                )));
            }
        }
        let last = c.model_at(c.iterations.saturating_sub(1));
        if c.params.free_g && !last.differentiates_g() {
            let fix = match last.kind() {
                ModelKind::Learned => format!(
                    "the learned model does not differentiate g; fix: \
                     keep the refinement ({} above 0), which frees g after the learned fit",
                    Setting::Refine
                ),
                ModelKind::Dipole => format!(
                    "the dipole does not differentiate g; fix: {} volpath or the learned model \
                     with its refinement",
                    Setting::Model
                ),
                ModelKind::Volpath => format!(
                    "the tracer's estimator {} does not difference g; fix: {} ad",
                    last.estimator_name(),
                    Setting::Estimator
                ),
            };
            return Err(invalid(format!(
                "{} with model {}: {fix}",
                Setting::FreeG,
                c.model.kind()
            )));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests;
