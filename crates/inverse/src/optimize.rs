//! Multi-view inverse rendering with the learned BSSRDF (Son et al. 2024 §5; docs/model.md §8.3,
//! A10–A12): Adam on the medium parameters with the gradient of the image loss from
//! [`bssrdf::diff::render_loss_gradient`].
//!
//! Iteration k: draw `views_per_iter` views (stream `hash(seed, k)`), render each at the current
//! parameters with `spp` samples per pixel and the iteration's seed (one render per view: the
//! single-render L2 gradient of SON24, A11), sum ∂ℓ/∂(σ_t, α) over the views, map it to the
//! optimiser's variables ([`crate::params`]), take one Adam step with per-parameter learning rates
//! (`lr_sigma_t` on σ_t/100 or ln σ_t, `lr_albedo` on α) decayed ×`decay` every `decay_every`
//! iterations, clamp. The vertex polynomials are fitted once at the initial parameters (A10) and,
//! if `refit_every` > 0, again every that many iterations at the current ones.
//!
//! Everything random derives from (seed, iteration, view, pixel), so a run is reproducible for a
//! given thread count and a resumed run continues exactly where the checkpoint left off.

use std::path::{Path, PathBuf};
use std::time::Instant;

use base::optim::{Adam, AdamConfig, AdamState};
use base::rng::{Sampler, hash_key};
use bssrdf::diff::{DiffImages, DiffMethod, DiffSettings, Loss, LossGradient, Primal};
use bssrdf::nn::ShapeAdaptiveModel;
use bssrdf::render::{LearnedSettings, RenderSettings};
use geometry::Accel;
use scene::{Camera, Image, Medium, PointLight};
use serde::{Deserialize, Serialize};

use crate::forward::dipole::Dipole;
use crate::forward::fd::Differencing;
use crate::forward::learned::Learned;
use crate::forward::volpath::Volpath;
use crate::forward::{ForwardModel, ModelKind};
use crate::params::{ParamSpec, Params};
use crate::uncertainty::{
    Accumulator, Uncertainty, UncertaintySettings, ViewRenders, add_covariances,
    iterate_covariance, iterate_drift,
};

/// Errors of the inverse loop.
#[derive(Debug, thiserror::Error)]
pub enum InverseError {
    /// Invalid settings or data.
    #[error("{0}")]
    Invalid(String),
    /// Rendering failed.
    #[error(transparent)]
    Render(#[from] bssrdf::render::RenderError),
    /// Writing failed.
    #[error(transparent)]
    Write(#[from] scene::SceneError),
    /// A checkpoint cannot be used.
    #[error("checkpoint {}: {reason}", .path.display())]
    Checkpoint {
        /// The file.
        path: PathBuf,
        /// Why.
        reason: String,
    },
    /// NaN or Inf appeared in iteration `iteration`: in the loss or gradient of one view, or in
    /// the parameters after the Adam step. The optimiser keeps its last finite state.
    #[error(
        "iteration {iteration}{}: {what} is not finite; the run stopped with the parameters of the \
         iteration before; check the target images and the learning rates",
        .view.map_or(String::new(), |v| format!(", view {v}"))
    )]
    NonFinite {
        /// The iteration (0-based) in which it appeared.
        iteration: u32,
        /// The target view (index among the optimiser's targets), when a view's render caused it.
        view: Option<usize>,
        /// What was not finite, with its value.
        what: String,
    },
}

/// Settings of a run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct OptimizeConfig {
    /// The forward model ([`crate::forward`]). (Left out of the JSON when it is the learned
    /// model, so runs written before the option compare equal.)
    #[serde(default, skip_serializing_if = "ModelKind::is_default")]
    pub model: ModelKind,
    /// The volumetric path tracer's maximum depth (Mitsuba `volpath` semantics) when it is the
    /// model: the dataset's own. `None` with the learned model.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub volpath_max_depth: Option<u32>,
    /// Gradient estimator (one of the model's, [`ModelKind::estimators`]).
    #[serde(with = "method_name")]
    pub method: DiffMethod,
    /// Iterations.
    pub iterations: u32,
    /// The last this many of `iterations` use the volumetric path tracer (estimator `ad`, depth
    /// `volpath_max_depth`) instead of `model`, from where the model's fit has got to: a
    /// refinement without the model's bias (docs/notes/default-model.md). 0: none. (Left out
    /// of the JSON when 0, so runs written before the option compare equal.)
    #[serde(default, skip_serializing_if = "is_zero")]
    pub refine_iterations: u32,
    /// Start Adam's moments again at the refinement's first iteration
    /// ([`base::optim::Adam::restart_moments`]; the learning-rate schedule runs on). The
    /// tracer's loss gradient is a median 2.3× (up to 7×) smaller than the learned model's at
    /// the switch, and second moments carried over (memory ~1/(1−β₂) = 1000 iterations)
    /// shrink the refinement's steps by that ratio throughout (docs/notes/default-model.md).
    /// (Left out of the JSON when off, so runs written before the option compare equal.)
    #[serde(default, skip_serializing_if = "is_false")]
    pub refine_restarts_moments: bool,
    /// Samples per pixel per iteration.
    pub spp: u32,
    /// Samples per pixel of the refinement's iterations ([`OptimizeConfig::spp_at`]); `None`:
    /// `spp`. The tracer's iteration costs about twice the learned model's at high albedo
    /// (its paths run to the depth limit), so fewer samples there trade gradient noise for
    /// time. (Left out of the JSON when `None`, so runs written before the option compare
    /// equal.)
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub refine_spp: Option<u32>,
    /// Views rendered per iteration.
    pub views_per_iter: usize,
    /// Render a random `crop × crop` window of each view per iteration instead of the whole
    /// image (as the paper's released optimiser does; clamped to the image). `None`: whole
    /// images.
    #[serde(default)]
    pub crop: Option<u32>,
    /// Image loss.
    #[serde(with = "loss_name")]
    pub loss: Loss,
    /// Decorrelated gradient: ∂ℓ/∂I from one render and ∂I/∂θ from another with independent
    /// samples (DLW22's two-buffer estimator, docs/model.md A11). The single-render product
    /// 2(I − T)·∂I/∂θ is biased by Cov(I, ∂I/∂θ); this one is not.
    #[serde(default)]
    pub two_renders: bool,
    /// With `two_renders`: the two renders are two derivative renders with half of `spp` each
    /// (∂ℓ/∂θ = ½[∂ℓ/∂I(I_A)·∂I_B/∂θ + ∂ℓ/∂I(I_B)·∂I_A/∂θ]): unbiased like two full renders
    /// at the cost of one. Off: a full value render and a full derivative render. (Files
    /// written before the option lack it and read as off.)
    #[serde(default)]
    pub split_samples: bool,
    /// Learning rate of σ_t's variable.
    pub lr_sigma_t: f32,
    /// Learning rate of α.
    pub lr_albedo: f32,
    /// Step decay factor.
    pub decay: f32,
    /// Iterations between decays.
    pub decay_every: u32,
    /// Refit the vertex polynomials every this many iterations (0: never).
    pub refit_every: u32,
    /// Also fit dR/d ln σ_n at every fit ([`bssrdf::render::VertexFeatures::fit_with_derivative`]), so that the
    /// descriptor at another σ_n, in the value and in the σ_t offsets, follows a refit to first
    /// order and not only the rescaling.
    #[serde(default)]
    pub fit_derivative: bool,
    /// Relative σ_t offset Δ/σ_t of the offset samples and of `fd`.
    pub delta_rel: f32,
    /// Where the value image of `ours` comes from (the offset pair by default).
    #[serde(default)]
    pub primal: Primal,
    /// Settings of the learned renderer (projection rule, descriptor handling, ablations).
    #[serde(default)]
    pub learned: LearnedSettings,
    /// Parameterisation, sharing and fixing.
    pub params: ParamSpec,
    /// Initial parameters.
    pub init: Params,
    /// Seed.
    pub seed: u64,
    /// Albedo first: for this many initial iterations σ_t stays at its initial value (zero
    /// gradient, no Adam moment), and only α moves. From σ_t = 50, α = 0.5 the images start far
    /// too dark; the joint gradient then pulls σ_t down (darker as σ_t grows) while α climbs,
    /// and Adam's memory of those steps keeps σ_t low (docs/notes/recovery-recipe.md, "Albedo
    /// first").
    #[serde(default)]
    pub albedo_warmup: u32,
    /// Normalise each view's loss, per channel, by the loss of a black image against its target
    /// ([`view_weights`]): dim views (light that crossed the object) then count as much as
    /// bright ones instead of vanishing beside them in Adam's second moment.
    /// (Left out of the JSON when off, so runs written before the option compare equal.)
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub normalize_views: bool,
    /// With `normalize_views`: the normaliser is at least this fraction of the mean over views,
    /// so no view weighs more than 1/floor times an average one.
    #[serde(
        default = "default_view_weight_floor",
        skip_serializing_if = "is_default_view_weight_floor"
    )]
    pub view_weight_floor: f64,
    /// The dataset views that are the targets, by their index in the dataset (`None`: all).
    /// The optimiser sees only the selected targets (renumbered from 0); the selection is kept
    /// here so that a resumed run uses the same views. (Left out of the JSON when `None`.)
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub view_subset: Option<Vec<usize>>,
}

fn is_zero(v: &u32) -> bool {
    *v == 0
}

fn is_false(v: &bool) -> bool {
    !*v
}

fn default_view_weight_floor() -> f64 {
    0.01
}

fn is_default_view_weight_floor(f: &f64) -> bool {
    *f == default_view_weight_floor()
}

/// The per-view, per-channel loss weights w_{v,c} = L̄_c / max(L_{v,c}, f·L̄_c), where
/// L_{v,c} = ℓ(0, T_v) is the loss of a black render against the target's channel c (mean T² for
/// L2, mean |T| for L1), L̄_c its mean over views and f the floor. All ones without
/// normalisation. The weights depend on the targets only, so the weighted loss is still a sum of
/// per-pixel losses and both gradient estimators (one render, two renders) keep their
/// properties; the weights only change which views the optimum balances.
pub fn view_weights(images: &[&Image], loss: Loss, normalize: bool, floor: f64) -> Vec<[f64; 3]> {
    if !normalize {
        return vec![[1.0; 3]; images.len()];
    }
    let black: Vec<[f64; 3]> = images
        .iter()
        .map(|im| {
            let mut s = [0.0; 3];
            for p in &im.data {
                for c in 0..3 {
                    s[c] += loss.element(0.0, p[c]).0;
                }
            }
            s.map(|v| v / im.data.len().max(1) as f64)
        })
        .collect();
    let n = black.len().max(1) as f64;
    let mean: [f64; 3] = std::array::from_fn(|c| black.iter().map(|b| b[c]).sum::<f64>() / n);
    black
        .iter()
        .map(|b| {
            std::array::from_fn(|c| {
                if mean[c] > 0.0 {
                    mean[c] / b[c].max(floor * mean[c])
                } else {
                    1.0
                }
            })
        })
        .collect()
}

mod method_name {
    use bssrdf::diff::DiffMethod;
    use serde::{Deserialize, Deserializer, Serializer};
    pub fn serialize<S: Serializer>(m: &DiffMethod, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(m.name())
    }
    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<DiffMethod, D::Error> {
        let s = String::deserialize(d)?;
        s.parse().map_err(serde::de::Error::custom)
    }
}

mod loss_name {
    use bssrdf::diff::Loss;
    use serde::{Deserialize, Deserializer, Serializer};
    pub fn serialize<S: Serializer>(l: &Loss, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(match l {
            Loss::L2 => "l2",
            Loss::L1 => "l1",
        })
    }
    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Loss, D::Error> {
        match String::deserialize(d)?.as_str() {
            "l2" => Ok(Loss::L2),
            "l1" => Ok(Loss::L1),
            o => Err(serde::de::Error::custom(format!("unknown loss {o:?}"))),
        }
    }
}

impl Default for OptimizeConfig {
    /// [`OptimizeConfig::new`] from the paper's initialisation σ_t = 50, α = 0.5.
    fn default() -> Self {
        Self::new(Params {
            sigma_t: [50.0; 3],
            albedo: [0.5; 3],
        })
    }
}

/// The share of a learned-model recovery's iterations that the defaults hand to the volumetric
/// path tracer ([`OptimizeConfig::refine_iterations`]): the learned model crosses the flat part
/// of the landscape cheaply, the tracer then removes the model's bias. Chosen on the robustness
/// suite (docs/notes/default-model.md).
pub const DEFAULT_REFINE_SHARE: f64 = 0.5;

/// Largest number of views rendered per iteration (the views are drawn with replacement, so
/// more than the targets is allowed; a bound keeps the per-iteration lists bounded).
pub const MAX_VIEWS_PER_ITER: usize = 1 << 16;

impl OptimizeConfig {
    /// Checks the settings that do not depend on the data: at least one view per iteration (at
    /// most [`MAX_VIEWS_PER_ITER`]) and one sample per pixel, finite learning rates and decay, a
    /// positive offset `delta_rel`, a crop of at least one pixel, a view-weight floor in (0, 1]
    /// when views are normalised, initial parameters that are a medium (σ_t finite and
    /// positive, α in [0, 1]) and a view subset that names each view once. Used by
    /// [`Optimizer::new`] and by [`Checkpoint::read`], whose configuration comes from a file.
    pub fn check(&self) -> Result<(), String> {
        if self.views_per_iter == 0 || self.spp == 0 {
            return Err("views per iteration and spp must be at least 1".into());
        }
        self.model.check_estimator(self.method)?;
        if self.refine_iterations > self.iterations {
            return Err(format!(
                "refine_iterations = {} is more than the run's {} iterations",
                self.refine_iterations, self.iterations
            ));
        }
        if let Some(r) = self.refine_spp {
            if r == 0 {
                return Err("refine_spp must be at least 1".into());
            }
            if self.refine_iterations == 0 {
                return Err(format!(
                    "refine_spp = {r} without a refinement (refine_iterations = 0)"
                ));
            }
        }
        if self.refine_iterations > 0 && self.model == ModelKind::Volpath {
            return Err(
                "refine_iterations with the volumetric model: the tracer is the model already"
                    .into(),
            );
        }
        if self.volpath_max_depth == Some(0) {
            return Err("volpath_max_depth = 0: the tracer needs a depth of at least 1".into());
        }
        if self.views_per_iter > MAX_VIEWS_PER_ITER {
            return Err(format!(
                "views_per_iter = {} is above the limit of {MAX_VIEWS_PER_ITER}",
                self.views_per_iter
            ));
        }
        if self.normalize_views && !(self.view_weight_floor > 0.0 && self.view_weight_floor <= 1.0)
        {
            return Err(format!(
                "view_weight_floor must be in (0, 1], got {}",
                self.view_weight_floor
            ));
        }
        for (name, v) in [
            ("lr_sigma_t", self.lr_sigma_t),
            ("lr_albedo", self.lr_albedo),
            ("decay", self.decay),
        ] {
            if !v.is_finite() {
                return Err(format!("{name} = {v} is not a finite number"));
            }
        }
        if !(self.delta_rel.is_finite() && self.delta_rel > 0.0) {
            return Err(format!("delta_rel = {} must be positive", self.delta_rel));
        }
        if self.crop == Some(0) {
            return Err("crop = 0: a crop needs at least one pixel".into());
        }
        let p = &self.init;
        if let Some(s) = p.sigma_t.iter().find(|s| !(s.is_finite() && **s > 0.0)) {
            return Err(format!("init.sigma_t holds {s}, σ_t must be positive"));
        }
        if let Some(a) = p.albedo.iter().find(|a| !(0.0..=1.0).contains(*a)) {
            return Err(format!("init.albedo holds {a}, α must be in [0, 1]"));
        }
        if let Some(subset) = &self.view_subset {
            if subset.is_empty() {
                return Err("view_subset is empty".into());
            }
            if let Some((k, i)) = subset
                .iter()
                .enumerate()
                .find(|(k, i)| subset[..*k].contains(i))
            {
                return Err(format!("view_subset names view {i} twice (entry {k})"));
            }
        }
        Ok(())
    }

    /// The forward model of iteration `k`: `model`, or the volumetric path tracer in the last
    /// `refine_iterations`.
    pub fn model_at(&self, k: u32) -> ModelKind {
        if self.refine_iterations > 0 && k >= self.iterations - self.refine_iterations {
            ModelKind::Volpath
        } else {
            self.model
        }
    }

    /// Samples per pixel of iteration `k`: [`OptimizeConfig::refine_spp`] in the refinement,
    /// else `spp`.
    pub fn spp_at(&self, k: u32) -> u32 {
        match self.refine_spp {
            Some(r)
                if self.refine_iterations > 0 && k >= self.iterations - self.refine_iterations =>
            {
                r
            }
            _ => self.spp,
        }
    }

    /// The forward model that makes the estimate: the model of the last iteration.
    pub fn final_model(&self) -> ModelKind {
        self.model_at(self.iterations.saturating_sub(1))
    }

    /// The α-first iterations actually used: `albedo_warmup`, but at most a third of the run.
    pub fn effective_albedo_warmup(&self) -> u32 {
        self.albedo_warmup.min(self.iterations / 3)
    }

    /// The refinement the defaults give a run of `iterations` with `model`: the last
    /// [`DEFAULT_REFINE_SHARE`] of them for the learned model, none for the others (the
    /// volumetric model is the tracer already; the dipole is a baseline, run as it is).
    pub fn default_refinement(model: ModelKind, iterations: u32) -> u32 {
        match model {
            ModelKind::Learned => (iterations as f64 * DEFAULT_REFINE_SHARE).floor() as u32,
            _ => 0,
        }
    }

    /// `iterations`, with the default refinement of a run that long
    /// ([`OptimizeConfig::default_refinement`]).
    pub fn with_iterations(mut self, iterations: u32) -> Self {
        self.iterations = iterations;
        self.refine_iterations = Self::default_refinement(self.model, iterations);
        self
    }

    /// The recovery's defaults from `init`, shared by `optimize`, `demo` and `experiment`: the
    /// budget of docs/model.md A12 (`ours`, 300 iterations, 32 spp, 1 view, L2, lr 0.015 and
    /// 0.02, ×0.85 every 50 iterations) with the settings that measured best
    /// (docs/notes/recovery-recipe.md, "Conclusions"): Adam on ln σ_t, the decorrelated
    /// two-render gradient, α alone for the first 30 iterations, and the last half of the
    /// iterations refined by the volumetric path tracer (docs/notes/default-model.md).
    pub fn new(init: Params) -> Self {
        Self {
            model: ModelKind::Learned,
            volpath_max_depth: None,
            method: DiffMethod::Ours,
            iterations: 300,
            refine_iterations: Self::default_refinement(ModelKind::Learned, 300),
            refine_restarts_moments: true,
            spp: 32,
            refine_spp: None,
            views_per_iter: 1,
            crop: None,
            loss: Loss::L2,
            two_renders: true,
            split_samples: true,
            lr_sigma_t: 0.015,
            lr_albedo: 0.02,
            decay: 0.85,
            decay_every: 50,
            refit_every: 0,
            fit_derivative: false,
            delta_rel: 0.02,
            primal: Primal::default(),
            learned: LearnedSettings::default(),
            params: ParamSpec {
                parameterisation: crate::params::Parameterisation::Log,
                ..ParamSpec::default()
            },
            init,
            seed: 0,
            albedo_warmup: 30,
            normalize_views: false,
            view_weight_floor: default_view_weight_floor(),
            view_subset: None,
        }
    }
}

/// One target view.
pub struct TargetView<'a> {
    /// Camera.
    pub camera: &'a Camera,
    /// Point light.
    pub light: &'a PointLight,
    /// Target image.
    pub image: &'a Image,
}

impl<'a> TargetView<'a> {
    /// Every view of `ds` with its image (`what` names the dataset in errors): an error names
    /// the first view without an image or with a non-finite pixel.
    pub fn of_dataset(ds: &'a scene::Dataset, what: &str) -> Result<Vec<Self>, InverseError> {
        ds.views
            .iter()
            .enumerate()
            .map(|(i, v)| {
                let image = v.image.as_ref().ok_or_else(|| {
                    InverseError::Invalid(format!("{what}: view {i} has no image to fit"))
                })?;
                image.check_finite(&format!("{what} view {i}"))?;
                Ok(TargetView {
                    camera: &v.camera,
                    light: &v.light,
                    image,
                })
            })
            .collect()
    }
}

/// One row of the per-iteration history.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct IterationRecord {
    /// Iteration (0-based).
    pub iteration: u32,
    /// Mean loss over the iteration's views.
    pub loss: f64,
    /// Parameters BEFORE the step.
    pub params: Params,
    /// ∂ℓ/∂σ_t per channel.
    pub d_sigma_t: [f64; 3],
    /// ∂ℓ/∂α per channel.
    pub d_albedo: [f64; 3],
    /// Views used.
    pub views: Vec<usize>,
    /// Top-left pixel (x0, y0) of each view's crop window (`--crop`; empty without crops).
    #[serde(default)]
    pub crop_origins: Vec<[u32; 2]>,
    /// Seconds of this iteration.
    pub seconds: f64,
    /// The misfit without the render's noise, [`cross_misfit`] (L2 with split samples only;
    /// `None` otherwise and in histories written before it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub misfit: Option<f64>,
}

/// The loss gradient of one iteration ([`Optimizer::gradient`]).
#[derive(Clone, Debug, PartialEq)]
pub struct IterationGradient {
    /// Mean (weighted) loss over the iteration's views.
    pub loss: f64,
    /// ∂ℓ/∂σ_t per channel.
    pub d_sigma_t: [f64; 3],
    /// ∂ℓ/∂α per channel.
    pub d_albedo: [f64; 3],
    /// Views used.
    pub views: Vec<usize>,
    /// Crop origins (empty without crops).
    pub crop_origins: Vec<[u32; 2]>,
    /// Mean (weighted) [`cross_misfit`] over the iteration's views, where the gradient has it.
    pub misfit: Option<f64>,
}

/// A run in progress.
pub struct Optimizer<'a> {
    config: OptimizeConfig,
    forward: Box<dyn ForwardModel + 'a>,
    /// Which model `forward` is ([`OptimizeConfig::model_at`]).
    forward_kind: ModelKind,
    accel: &'a Accel,
    networks: &'a ShapeAdaptiveModel,
    base: Medium,
    targets: Vec<TargetView<'a>>,
    adam: Adam,
    u: Vec<f32>,
    history: Vec<IterationRecord>,
    /// Per-view, per-channel loss weights ([`view_weights`]).
    weights: Vec<[f64; 3]>,
}

mod checkpoint;
pub use checkpoint::Checkpoint;

impl<'a> Optimizer<'a> {
    /// A new run. `base` supplies g and η (the parameters come from `config.init`); `config.model`
    /// chooses the forward model over `accel` (`model` is the learned model's networks, unused
    /// by the others).
    pub fn new(
        config: OptimizeConfig,
        accel: &'a Accel,
        model: &'a ShapeAdaptiveModel,
        base: Medium,
        targets: Vec<TargetView<'a>>,
    ) -> Result<Self, InverseError> {
        if targets.is_empty() {
            return Err(InverseError::Invalid("no target views".into()));
        }
        config.check().map_err(InverseError::Invalid)?;
        let init_medium = config.init.medium(&base);
        init_medium
            .validate("initial parameters")
            .map_err(|e| InverseError::Invalid(e.to_string()))?;
        let forward_kind = config.model_at(0);
        let mut forward = forward_model(&config, forward_kind, accel, model);
        forward.prepare(&init_medium)?;
        let u = config.params.encode(&config.init);
        let adam = Adam::new(u.len(), adam_config(&config));
        let parts = Parts {
            forward,
            forward_kind,
            accel,
            networks: model,
            adam,
            u,
            history: Vec::new(),
        };
        Ok(Self::assemble(config, base, targets, parts))
    }

    /// The run from its configuration, inputs and state.
    fn assemble(
        config: OptimizeConfig,
        base: Medium,
        targets: Vec<TargetView<'a>>,
        p: Parts<'a>,
    ) -> Self {
        let images: Vec<&Image> = targets.iter().map(|t| t.image).collect();
        let weights = view_weights(
            &images,
            config.loss,
            config.normalize_views,
            config.view_weight_floor,
        );
        Self {
            weights,
            config,
            forward: p.forward,
            forward_kind: p.forward_kind,
            accel: p.accel,
            networks: p.networks,
            base,
            targets,
            adam: p.adam,
            u: p.u,
            history: p.history,
        }
    }

    /// Iterations done.
    pub fn iteration(&self) -> u32 {
        self.history.len() as u32
    }

    /// Current parameters.
    pub fn params(&self) -> Params {
        self.config.params.decode(&self.u)
    }

    /// The history.
    pub fn history(&self) -> &[IterationRecord] {
        &self.history
    }

    /// The configuration.
    pub fn config(&self) -> &OptimizeConfig {
        &self.config
    }

    /// The image of one view rendered by the run's forward model at `p` (no derivatives).
    pub fn render(
        &self,
        p: &Params,
        camera: &Camera,
        light: &PointLight,
        rs: &RenderSettings,
    ) -> Result<Image, InverseError> {
        let at = self.forward.at(p.medium(&self.base))?;
        at.view(camera, light).value(rs)
    }

    /// The uncertainty of the current parameters from the target images
    /// ([`crate::uncertainty`]): two independent derivative renders of `s.views` views spread
    /// evenly over the targets, at `s.spp`, plus the spread and drift of the last iterates. Parameters the
    /// run keeps fixed get no interval.
    pub fn uncertainty(&self, s: &UncertaintySettings) -> Result<Uncertainty, InverseError> {
        let c = &self.config;
        let p = self.params();
        let at = self.forward.at(p.medium(&self.base))?;
        let n = self.targets.len();
        let k = s.views.clamp(1, n);
        let mut acc = Accumulator::default();
        for i in 0..k {
            let v = i * n / k;
            let t = &self.targets[v];
            let view = at.view(t.camera, t.light);
            let render = |stream: u64| {
                let rs = RenderSettings {
                    spp: s.spp.max(1),
                    seed: hash_key(&[c.seed, 0x5A4D_0000, stream]),
                    view: v as u64,
                };
                view.derivatives(&rs)
            };
            let (a, b) = (render(1)?, render(2)?);
            acc.add_view(
                &ViewRenders {
                    value: [&a.value, &b.value],
                    d_sigma_t: [&a.d_sigma_t, &b.d_sigma_t],
                    d_albedo: [&a.d_albedo, &b.d_albedo],
                    target: t.image,
                },
                p.sigma_t,
            );
        }
        let tail = ((self.history.len() as f64 * s.tail_fraction).ceil() as usize)
            .clamp(2.min(self.history.len()), self.history.len());
        let iterates: Vec<([f64; 3], [f64; 3])> = self.history[self.history.len() - tail..]
            .iter()
            .map(|r| (r.params.sigma_t, r.params.albedo))
            .chain(std::iter::once((p.sigma_t, p.albedo)))
            .collect();
        let (walk, drift) = (iterate_covariance(&iterates), iterate_drift(&iterates));
        let spread: [[f64; 3]; 3] =
            std::array::from_fn(|c| std::array::from_fn(|k| walk[c][k] + drift[c][k]));
        let fixed = [c.params.fix_sigma_t, c.params.fix_albedo];
        let cov = add_covariances(acc.covariance_fixed(s.model_brightness_sd, fixed), spread);
        let images = add_covariances(acc.covariance_fixed(0.0, fixed), spread);
        let mut u = Uncertainty::new(p.sigma_t, p.albedo, cov, images, k);
        u.view_bread = (0..k)
            .map(|i| i * n / k)
            .zip(acc.view_breads().iter().copied())
            .collect();
        u.fixed = fixed;
        if c.params.fix_sigma_t {
            u.sigma_t = [None; 3];
            u.sd_ln_sigma_t = [None; 3];
            u.determined_sigma_t = [false; 3];
        }
        if c.params.fix_albedo {
            u.albedo = [None; 3];
            u.sd_albedo = [None; 3];
            u.determined_albedo = [false; 3];
        }
        Ok(u)
    }

    /// The loss and its gradient of iteration `k` at the parameters `p` (the views, crops and
    /// random numbers of that iteration; no step). [`Optimizer::step`] at iteration k is this
    /// at the current parameters followed by the Adam step.
    pub fn gradient(&self, k: u32, p: &Params) -> Result<IterationGradient, InverseError> {
        let c = &self.config;
        let at = self.forward.at(p.medium(&self.base))?;
        let mut rng = Sampler::new(c.seed, 0x0AD1_0E55, k as u64, 0);
        let n = self.targets.len() as u32;
        let views: Vec<usize> = (0..c.views_per_iter)
            .map(|_| rng.next_below(n) as usize)
            .collect();
        // Crop windows, drawn after the views (so the views do not depend on the crop).
        let crops: Vec<Option<(Camera, Image, [u32; 2])>> = views
            .iter()
            .map(|&v| {
                let t = &self.targets[v];
                let Some(size) = c.crop else {
                    return Ok(None);
                };
                let (w, h) = (size.min(t.camera.width), size.min(t.camera.height));
                let x0 = rng.next_below(t.camera.width - w + 1);
                let y0 = rng.next_below(t.camera.height - h + 1);
                let camera = t
                    .camera
                    .cropped(x0, y0, w, h)
                    .map_err(|e| InverseError::Invalid(format!("view {v}: {e}")))?;
                Ok(Some((camera, t.image.crop(x0, y0, w, h), [x0, y0])))
            })
            .collect::<Result<_, InverseError>>()?;
        let (mut loss, mut ds_t, mut da) = (0.0, [0.0; 3], [0.0; 3]);
        let mut misfit = Some(0.0);
        for (&v, crop) in views.iter().zip(&crops) {
            let full = &self.targets[v];
            let t = match crop {
                Some((camera, image, _)) => TargetView {
                    camera,
                    light: full.light,
                    image,
                },
                None => TargetView { ..*full },
            };
            let spp = c.spp_at(k);
            let rs = RenderSettings {
                spp,
                seed: hash_key(&[c.seed, k as u64]),
                view: v as u64,
            };
            let mut view_misfit = None;
            let g = if c.two_renders && c.split_samples && spp >= 2 {
                // Two derivative renders with half the samples each and independent seeds:
                // ∂ℓ/∂θ = ½[∂ℓ/∂I(I_A)·∂I_B/∂θ + ∂ℓ/∂I(I_B)·∂I_A/∂θ], no covariance bias, the
                // cost of one render at `spp`.
                let half = spp / 2;
                let rs_a = RenderSettings { spp: half, ..rs };
                let rs_b = RenderSettings {
                    spp: spp - half,
                    seed: hash_key(&[c.seed, k as u64, 0xB]),
                    ..rs
                };
                let view = at.view(t.camera, t.light);
                let da = view.derivatives(&rs_a)?;
                let db = view.derivatives(&rs_b)?;
                if c.loss == Loss::L2 {
                    view_misfit = Some(cross_misfit(&da.value, &db.value, t.image));
                }
                split_sample_gradient(&da, &db, t.image, c.loss)
            } else if c.two_renders {
                // I₁ (seed A) gives ∂ℓ/∂I, the derivative images of a render with seed B give
                // ∂I/∂θ: two renders, independent samples (no covariance bias).
                let rs_b = RenderSettings {
                    seed: hash_key(&[c.seed, k as u64, 0xB]),
                    ..rs
                };
                // One set of camera rays (the view's triangle lists) for both renders.
                let view = at.view(t.camera, t.light);
                let i1 = view.value(&rs)?;
                let d2 = view.derivatives(&rs_b)?;
                decorrelated_gradient(&i1, &d2, t.image, c.loss)
            } else {
                at.view(t.camera, t.light)
                    .loss_gradient(&rs, t.image, c.loss)?
            };
            if let Some(what) = non_finite_part(&g) {
                return Err(InverseError::NonFinite {
                    iteration: k,
                    view: Some(v),
                    what,
                });
            }
            let w = self.weights[v];
            misfit = match (misfit, view_misfit) {
                (Some(m), Some(x)) => Some(
                    m + (0..3)
                        .map(|ch| w[ch] * x[ch] / views.len() as f64)
                        .sum::<f64>(),
                ),
                _ => None,
            };
            for ch in 0..3 {
                loss += w[ch] * g.loss_channels[ch] / views.len() as f64;
                ds_t[ch] += w[ch] * g.d_sigma_t[ch] / views.len() as f64;
                da[ch] += w[ch] * g.d_albedo[ch] / views.len() as f64;
            }
        }
        if !loss.is_finite() || ds_t.iter().chain(&da).any(|g| !g.is_finite()) {
            return Err(InverseError::NonFinite {
                iteration: k,
                view: None,
                what: format!("the loss or its gradient over the views (loss {loss})"),
            });
        }
        Ok(IterationGradient {
            loss,
            misfit,
            d_sigma_t: ds_t,
            d_albedo: da,
            views,
            crop_origins: crops.iter().flatten().map(|c| c.2).collect(),
        })
    }

    /// One iteration.
    pub fn step(&mut self) -> Result<&IterationRecord, InverseError> {
        let t0 = Instant::now();
        let k = self.iteration();
        let p = self.params();
        let c = &self.config;
        let kind = c.model_at(k);
        if kind != self.forward_kind {
            // The refinement begins: the tracer from here on, at the current parameters.
            let mut forward = forward_model(c, kind, self.accel, self.networks);
            forward.prepare(&p.medium(&self.base))?;
            (self.forward, self.forward_kind) = (forward, kind);
        } else if c.refit_every > 0 && k > 0 && k.is_multiple_of(c.refit_every) {
            self.forward.prepare(&p.medium(&self.base))?;
        }
        // On the refinement's first iteration, whether the run started before it or resumed
        // exactly there (its checkpoint then already holds the tracer, and `kind` matches).
        let restart_moments = c.refine_restarts_moments
            && c.refine_iterations > 0
            && k == c.iterations - c.refine_iterations;
        let IterationGradient {
            loss,
            misfit,
            d_sigma_t: ds_t,
            d_albedo: da,
            views,
            crop_origins,
        } = self.gradient(k, &p)?;
        let c = &self.config;
        let mut g = c.params.chain(&p, ds_t, da);
        let lr_t = if k < c.effective_albedo_warmup() {
            g[..3].fill(0.0);
            0.0
        } else {
            c.lr_sigma_t
        };
        let scale = [lr_t, lr_t, lr_t, c.lr_albedo, c.lr_albedo, c.lr_albedo];
        // The step is taken on copies and kept only when it is finite, so that a failure
        // leaves the optimiser (and a checkpoint written after it) at the last good state.
        let (mut adam, mut u) = (self.adam.clone(), self.u.clone());
        if restart_moments {
            adam.restart_moments();
        }
        adam.step_scaled(&mut u, &mut g, &scale);
        c.params.clamp(&mut u);
        if let Some(i) = u.iter().position(|x| !x.is_finite()) {
            return Err(InverseError::NonFinite {
                iteration: k,
                view: None,
                what: format!("parameter variable {i} after the Adam step ({})", u[i]),
            });
        }
        (self.adam, self.u) = (adam, u);
        self.history.push(IterationRecord {
            iteration: k,
            loss,
            params: p,
            d_sigma_t: ds_t,
            d_albedo: da,
            views,
            crop_origins,
            seconds: t0.elapsed().as_secs_f64(),
            misfit,
        });
        Ok(self.history.last().expect("just pushed"))
    }

    /// Runs to `config.iterations`, writing a checkpoint every `checkpoint_every` iterations
    /// (and at the end) when a path is given; `on_iter` sees every record.
    pub fn run(
        &mut self,
        checkpoint: Option<(&Path, u32)>,
        mut on_iter: impl FnMut(&IterationRecord, &Params),
    ) -> Result<(), InverseError> {
        while self.iteration() < self.config.iterations {
            self.step()?;
            let p = self.params();
            on_iter(self.history.last().expect("stepped"), &p);
            if let Some((path, every)) = checkpoint {
                let k = self.iteration();
                if k.is_multiple_of(every.max(1)) || k == self.config.iterations {
                    self.save_checkpoint(path)?;
                }
            }
        }
        Ok(())
    }
}

/// The first non-finite part of one view's loss gradient, named with its value.
fn non_finite_part(g: &LossGradient) -> Option<String> {
    if !g.loss.is_finite() {
        return Some(format!("the loss ({})", g.loss));
    }
    let rgb = ["R", "G", "B"];
    (0..3).find_map(|c| {
        if !g.d_sigma_t[c].is_finite() {
            Some(format!("∂ℓ/∂σ_t {} ({})", rgb[c], g.d_sigma_t[c]))
        } else if !g.d_albedo[c].is_finite() {
            Some(format!("∂ℓ/∂α {} ({})", rgb[c], g.d_albedo[c]))
        } else {
            None
        }
    })
}

/// The loss gradient of two independent derivative renders `a` and `b` (each with half of the
/// samples): ∂ℓ/∂θ = ½[∂ℓ/∂I(I_a)·∂I_b/∂θ + ∂ℓ/∂I(I_b)·∂I_a/∂θ] and ℓ = ½[ℓ(I_a) + ℓ(I_b)].
/// Each half pairs a loss derivative with derivative images of independent samples, so the
/// product has no covariance bias, at the cost of one render at the full sample count (the
/// default of [`OptimizeConfig::new`]). Any forward model's derivative images serve.
pub fn split_sample_gradient(
    a: &DiffImages,
    b: &DiffImages,
    target: &Image,
    loss: Loss,
) -> LossGradient {
    let ab = decorrelated_gradient(&a.value, b, target, loss);
    let ba = decorrelated_gradient(&b.value, a, target, loss);
    LossGradient {
        loss: 0.5 * (ab.loss + ba.loss),
        loss_channels: std::array::from_fn(|ch| {
            0.5 * (ab.loss_channels[ch] + ba.loss_channels[ch])
        }),
        d_sigma_t: std::array::from_fn(|ch| 0.5 * (ab.d_sigma_t[ch] + ba.d_sigma_t[ch])),
        d_albedo: std::array::from_fn(|ch| 0.5 * (ab.d_albedo[ch] + ba.d_albedo[ch])),
        images: None,
    }
}

/// The L2 misfit of two independent renders `a` and `b` of one view against `target`, without
/// the renders' noise: per channel, (1/3N) Σ_pixels (I_a − T)(I_b − T), whose expectation is
/// (1/3N) Σ (E\[I\] − T)² since the two renders' errors are independent (the loss ½[ℓ(I_a) +
/// ℓ(I_b)] adds their variance, which changes with the parameters). Summed over channels it is
/// on the scale of `loss`. A single draw can be negative where the renders are noisier than
/// the misfit.
pub fn cross_misfit(a: &Image, b: &Image, target: &Image) -> [f64; 3] {
    let mut out = [0.0f64; 3];
    for ((x, y), t) in a.data.iter().zip(&b.data).zip(&target.data) {
        for ch in 0..3 {
            out[ch] += (x[ch] as f64 - t[ch] as f64) * (y[ch] as f64 - t[ch] as f64);
        }
    }
    let n_inv = 1.0 / (3 * a.data.len()).max(1) as f64;
    out.map(|v| v * n_inv)
}

/// The decorrelated loss gradient: ℓ and ∂ℓ/∂I from the render `i1`, ∂I/∂θ from the derivative
/// images of an independent render `d2`: ∂ℓ/∂θ = (1/N) Σ ∂ℓ/∂I(I₁, T) · ∂I₂/∂θ.
pub(crate) fn decorrelated_gradient(
    i1: &Image,
    d2: &DiffImages,
    target: &Image,
    loss: Loss,
) -> LossGradient {
    let mut g = LossGradient {
        loss: 0.0,
        loss_channels: [0.0; 3],
        d_sigma_t: [0.0; 3],
        d_albedo: [0.0; 3],
        images: None,
    };
    let pixels = i1.data.iter().zip(&target.data);
    for ((a, t), (dt, da)) in pixels.zip(d2.d_sigma_t.data.iter().zip(&d2.d_albedo.data)) {
        for ch in 0..3 {
            let (l, dl) = loss.element(a[ch], t[ch]);
            g.loss_channels[ch] += l;
            g.d_sigma_t[ch] += dl * dt[ch] as f64;
            g.d_albedo[ch] += dl * da[ch] as f64;
        }
    }
    let n_inv = 1.0 / (3 * i1.data.len()).max(1) as f64;
    g.loss_channels = g.loss_channels.map(|v| v * n_inv);
    g.loss = g.loss_channels.iter().sum();
    g.d_sigma_t = g.d_sigma_t.map(|v| v * n_inv);
    g.d_albedo = g.d_albedo.map(|v| v * n_inv);
    g
}

/// The state of a run (what a fresh start and a resume provide differently).
struct Parts<'a> {
    forward: Box<dyn ForwardModel + 'a>,
    forward_kind: ModelKind,
    accel: &'a Accel,
    networks: &'a ShapeAdaptiveModel,
    adam: Adam,
    u: Vec<f32>,
    history: Vec<IterationRecord>,
}

/// Adam with learning rate 1 (the per-parameter rates are factors), the step decay, no clipping.
fn adam_config(c: &OptimizeConfig) -> AdamConfig {
    AdamConfig {
        lr: 1.0,
        decay: c.decay,
        decay_every: c.decay_every.max(1) as u64,
        floor_fraction: 0.0,
        clip_norm: 0.0,
        ..AdamConfig::default()
    }
}

/// Adam state accessors for the checkpoint module.
fn adam_parts(o: &Optimizer) -> AdamState {
    o.adam.state()
}

/// The forward model `kind` (`config.model`, or the refinement's tracer) over `accel`, not yet
/// prepared (`model`: the learned model's networks). The refinement's tracer differentiates
/// per path (`ad`).
pub(crate) fn forward_model<'a>(
    config: &OptimizeConfig,
    kind: ModelKind,
    accel: &'a Accel,
    model: &'a ShapeAdaptiveModel,
) -> Box<dyn ForwardModel + 'a> {
    let differencing = Differencing {
        method: if kind == config.model {
            config.method
        } else {
            DiffMethod::Ad
        },
        delta_rel: config.delta_rel,
        delta_albedo: DiffSettings::default().delta_albedo,
    };
    match kind {
        ModelKind::Learned => Box::new(Learned::new(
            accel,
            model,
            config.learned,
            DiffSettings {
                method: config.method,
                delta_rel: config.delta_rel,
                primal: config.primal,
                ..DiffSettings::default()
            },
            config.fit_derivative,
            config.seed,
        )),
        ModelKind::Volpath => Box::new(Volpath::new(
            accel,
            volpath::VolpathSettings {
                max_depth: config.volpath_max_depth.unwrap_or(32),
                ..volpath::VolpathSettings::default()
            },
            differencing,
        )),
        ModelKind::Dipole => Box::new(Dipole::new(accel, differencing)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The cross misfit of two independently noisy renders estimates (E[I] − T)² without their
    /// noise, while ½[ℓ(I_a) + ℓ(I_b)] adds the noise's variance: checked over 40,000 pixels
    /// against the cross term's standard error.
    #[test]
    fn the_cross_misfit_has_no_render_noise() {
        let (w, h) = (200u32, 200u32);
        let mut rng = base::rng::Sampler::new(17, 0, 0, 0);
        let mut normal = || {
            let u1 = (rng.next_f32() as f64).max(1e-12);
            let u2 = rng.next_f32() as f64;
            ((-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()) as f32
        };
        let (mean, target, sd) = ([0.5f32, 0.3, 0.2], [0.45f32, 0.3, 0.25], 0.2f32);
        let mut t = Image::new(w, h);
        let (mut a, mut b) = (Image::new(w, h), Image::new(w, h));
        for i in 0..t.data.len() {
            t.data[i] = target;
            for ch in 0..3 {
                a.data[i][ch] = mean[ch] + sd * normal();
                b.data[i][ch] = mean[ch] + sd * normal();
            }
        }
        let x = cross_misfit(&a, &b, &t);
        let n = t.data.len() as f64;
        for ch in 0..3 {
            let want = (mean[ch] - target[ch]).powi(2) as f64 / 3.0;
            // Var[(μ−T+e_a)(μ−T+e_b)] = 2(μ−T)²σ² + σ⁴ per pixel, over 3N for the channel's share.
            let d2 = ((mean[ch] - target[ch]) as f64).powi(2);
            let s2 = (sd as f64).powi(2);
            let se = ((2.0 * d2 * s2 + s2 * s2) / n).sqrt() / 3.0;
            assert!(
                (x[ch] - want).abs() < 4.0 * se,
                "channel {ch}: {} vs {want} ± {se}",
                x[ch]
            );
        }
        // The loss of one render holds σ² on top.
        let g = split_sample_gradient(
            &DiffImages {
                value: a.clone(),
                d_sigma_t: a.clone(),
                d_albedo: a.clone(),
            },
            &DiffImages {
                value: b.clone(),
                d_sigma_t: b.clone(),
                d_albedo: b.clone(),
            },
            &t,
            Loss::L2,
        );
        let noise = (sd as f64).powi(2) / 3.0;
        for ch in 0..3 {
            assert!(g.loss_channels[ch] - x[ch] > 0.9 * noise, "channel {ch}");
        }
    }
}
