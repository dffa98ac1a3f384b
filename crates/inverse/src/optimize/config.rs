//! The settings of a run ([`OptimizeConfig`]): the model and its estimator, the schedule, the
//! gradient estimator's options, the parameterisation and the initialisation, with their checks
//! and the defaults of `optimize` ([`OptimizeConfig::new`]); and the description of the forward
//! model a configuration renders with at a given iteration ([`model_spec`]).

use bssrdf::diff::{DiffSettings, Loss, Primal};
use bssrdf::nn::ShapeAdaptiveModel;
use bssrdf::render::LearnedSettings;
use serde::{Deserialize, Serialize};

use super::InverseError;
use crate::forward::fd::Differencing;
use crate::forward::learned::LearnedSpec;
use crate::forward::{ModelChoice, ModelKind, ModelSpec, TracerEstimator};
use crate::params::{ParamSpec, Params};

/// Settings of a run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct OptimizeConfig {
    /// The forward model and its gradient estimator ([`crate::forward`]). In the JSON as
    /// `model` (left out for the learned model, so runs written before the option compare
    /// equal) and `method`, the estimator.
    #[serde(flatten)]
    pub model: ModelChoice,
    /// The volumetric path tracer's maximum depth (Mitsuba `volpath` semantics) when it is the
    /// model: the dataset's own. `None` with the learned model.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub volpath_max_depth: Option<u32>,
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
    /// `spp`. The tracer's iteration costs about 2.5× the learned model's at high albedo
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
    /// Learning rate of g where the run recovers it ([`ParamSpec::free_g`]). (Left out of the
    /// JSON at its default, so runs written before the option compare equal.)
    #[serde(default = "default_lr_g", skip_serializing_if = "is_default_lr_g")]
    pub lr_g: f32,
    /// Learning rate of ln k, the light scale's variable, where the run recovers it
    /// ([`ParamSpec::free_light_scale`]). (Left out of the JSON at its default.)
    #[serde(
        default = "default_lr_light_scale",
        skip_serializing_if = "is_default_lr_light_scale"
    )]
    pub lr_light_scale: f32,
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

/// The default learning rate of g: Adam moves a variable by about its learning rate per
/// iteration, so g crosses its range [0, 0.9] in about 100 of the refinement's iterations and
/// then settles as the steps decay.
pub const DEFAULT_LR_G: f32 = 0.01;

/// The default learning rate of ln k: as α's, the other brightness variable.
pub const DEFAULT_LR_LIGHT_SCALE: f32 = 0.02;

fn default_lr_light_scale() -> f32 {
    DEFAULT_LR_LIGHT_SCALE
}

fn is_default_lr_light_scale(v: &f32) -> bool {
    *v == DEFAULT_LR_LIGHT_SCALE
}

fn default_lr_g() -> f32 {
    DEFAULT_LR_G
}

fn is_default_lr_g(v: &f32) -> bool {
    *v == DEFAULT_LR_G
}

fn default_view_weight_floor() -> f64 {
    0.01
}

fn is_default_view_weight_floor(f: &f64) -> bool {
    *f == default_view_weight_floor()
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
            g: None,
            light_scale: None,
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
        if self.refine_iterations > 0 && self.model.kind() == ModelKind::Volpath {
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
            ("lr_g", self.lr_g),
            ("lr_light_scale", self.lr_light_scale),
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
        if let Some(g) = p.g.and_then(|g| {
            g.values()
                .iter()
                .copied()
                .find(|g| !(g.is_finite() && g.abs() < 1.0))
        }) {
            return Err(format!(
                "init.g holds {g}, the phase function's g must be in (-1, 1)"
            ));
        }
        let positive = |k: &f64| k.is_finite() && *k > 0.0;
        if let Some(k) = p.light_scale.filter(|k| !k.values().iter().all(positive)) {
            return Err(format!(
                "init.light_scale = {:?}, a light scale must be positive",
                k.values()
            ));
        }
        if self.params.free_light_scale
            && !self.two_renders
            && self.model.kind() == ModelKind::Learned
        {
            return Err(
                "a free light scale with the learned model's single-render gradient: its fused \
                 render keeps no value image for ∂ℓ/∂ln k; use the two-render gradient"
                    .into(),
            );
        }
        if self.params.free_g
            && !self
                .model_at(self.iterations.saturating_sub(1))
                .differentiates_g()
        {
            return Err(format!(
                "a free g needs a model that differentiates g (the volumetric path tracer with \
                 its estimator ad, as the model or in a refinement); this run ends with {} \
                 ({})",
                self.final_model(),
                self.model_at(self.iterations.saturating_sub(1))
                    .estimator_name()
            ));
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
    pub fn model_at(&self, k: u32) -> ModelChoice {
        if self.refine_iterations > 0 && k >= self.iterations.saturating_sub(self.refine_iterations)
        {
            ModelChoice::Volpath(TracerEstimator::Ad)
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
        self.model_at(self.iterations.saturating_sub(1)).kind()
    }

    /// The tracer's maximum depth: the dataset's ([`OptimizeConfig::volpath_max_depth`]) or
    /// the tracer's default.
    pub fn tracer_depth(&self) -> u32 {
        self.volpath_max_depth.unwrap_or(volpath::DEFAULT_MAX_DEPTH)
    }

    /// The α-first iterations actually used: `albedo_warmup`, but at most a third of the run.
    pub fn effective_albedo_warmup(&self) -> u32 {
        self.albedo_warmup.min(self.iterations / 3)
    }

    /// The first iteration in which a free light scale moves: the refinement's first where the
    /// run has one, else the middle of the run, and never inside the α-first iterations. Until
    /// then σ_t and α fit the images under the lights as stated.
    pub fn light_scale_start(&self) -> u32 {
        let start = if self.refine_iterations > 0 {
            self.iterations.saturating_sub(self.refine_iterations)
        } else {
            self.iterations / 2
        };
        start.max(self.effective_albedo_warmup())
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
        self.refine_iterations = Self::default_refinement(self.model.kind(), iterations);
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
            model: ModelChoice::default(),
            volpath_max_depth: None,
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
            lr_g: DEFAULT_LR_G,
            lr_light_scale: DEFAULT_LR_LIGHT_SCALE,
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

/// The description of the forward model `choice` (`config.model`, or the refinement's tracer)
/// with the run's settings (`networks`: the learned model's, needed by it alone).
pub(crate) fn model_spec<'a>(
    config: &OptimizeConfig,
    choice: ModelChoice,
    networks: Option<&'a ShapeAdaptiveModel>,
) -> Result<ModelSpec<'a>, InverseError> {
    let differencing = |estimator| Differencing {
        estimator,
        delta_rel: config.delta_rel,
        delta_albedo: DiffSettings::default().delta_albedo,
    };
    Ok(match choice {
        ModelChoice::Learned(estimator) => ModelSpec::Learned(LearnedSpec {
            networks: networks.ok_or_else(|| {
                InverseError::Invalid("the learned model was given no networks".into())
            })?,
            settings: config.learned,
            diff: DiffSettings {
                estimator,
                delta_rel: config.delta_rel,
                primal: config.primal,
                ..DiffSettings::default()
            },
            fit_derivative: config.fit_derivative,
            seed: config.seed,
        }),
        ModelChoice::Volpath(e) => ModelSpec::Volpath {
            settings: volpath::VolpathSettings {
                max_depth: config.tracer_depth(),
                ..volpath::VolpathSettings::default()
            },
            estimator: differencing(e),
        },
        ModelChoice::Dipole(e) => ModelSpec::Dipole {
            estimator: differencing(e),
        },
    })
}
