//! `optimize`'s options ([`OptimizeArgs`]) and their conversion into the library's typed
//! recovery ([`inverse::recovery::RecoveryConfig`]); the experiments describe their runs with the
//! same options, so that every run they publish is one a user can type.

use std::path::PathBuf;

use bssrdf::diff::{Loss, Primal};
use clap::Args;
use inverse::forward::{ModelChoice, ModelKind};
use inverse::optimize::OptimizeConfig;
use inverse::params::{ParamSpec, Parameterisation, Params};
use inverse::recovery::{self, Observer, RecoveryConfig};
use inverse::uncertainty::UncertaintySettings;
use scene::Dataset;

use crate::{CmdlineError, LearnedArgs, Result, parse_rgb};

mod bias_correction;

pub use bias_correction::BiasCorrectionArgs;

#[derive(Args, Clone)]
pub struct OptimizeArgs {
    /// Dataset folder: ours (dataset.json) or a Mitsuba reference folder (scene.json); its
    /// truth medium, when present, is only used to report errors.
    #[arg(long)]
    pub dataset: PathBuf,
    /// Output folder.
    #[arg(long, default_value = "out/optimize")]
    pub out: PathBuf,
    /// Gradient estimator of the model (`--model`). The learned BSSRDF takes ours (default),
    /// ours-alpha-offsets, naive and fd; `volpath` and `dipole` take ad (default) and fd.
    #[arg(long, alias = "method", value_name = "ESTIMATOR")]
    pub estimator: Option<String>,
    /// Maximum depth of the volumetric path tracer when it is the model (Mitsuba `volpath`
    /// semantics; default: the dataset's own, else 32).
    #[arg(help_heading = crate::RESEARCH_OPTIONS, long)]
    pub max_depth: Option<u32>,
    /// The volumetric refinement: the last N of --iterations use the volumetric path tracer
    /// (estimator `ad`, depth --max-depth) from where the learned model's fit has got to, in
    /// place of the bias correction (docs/notes/default-model.md). Default: half of
    /// --iterations with the learned model, none with the others; 0: the learned model alone.
    #[arg(help_heading = crate::RESEARCH_OPTIONS, long, value_name = "N")]
    pub refine: Option<u32>,
    /// Samples per pixel of the refinement's iterations (default: --spp). The tracer's
    /// iteration costs about 2.5× the learned model's at high albedo (3.06 against 1.23 s at
    /// α ≈ 0.97); fewer samples there trade gradient noise for time.
    #[arg(help_heading = crate::RESEARCH_OPTIONS, long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..))]
    pub refine_spp: Option<u32>,
    /// Carry Adam's moments into the refinement instead of starting them again. The tracer's
    /// gradient is smaller than the learned model's, so carried moments shrink the
    /// refinement's steps (docs/notes/default-model.md).
    #[arg(help_heading = crate::RESEARCH_OPTIONS, long)]
    pub refine_keeps_moments: bool,
    #[command(flatten)]
    pub budget: IterationArgs,
    /// Image loss.
    #[arg(help_heading = crate::RESEARCH_OPTIONS, long, value_enum, default_value_t)]
    pub loss: Loss,
    /// The single-render gradient 2(I − T)·∂I/∂θ (the paper's; biased by the covariance of I and
    /// ∂I/∂θ) instead of the default: ∂ℓ/∂I from one render and ∂I/∂θ from an independent one.
    #[arg(help_heading = crate::RESEARCH_OPTIONS, long)]
    pub single_render: bool,
    /// (The default; accepted for older scripts.)
    #[arg(long, hide = true, conflicts_with = "single_render")]
    pub two_renders: bool,
    /// The two renders of the gradient as a full value render and a full derivative render at
    /// --spp each, instead of two derivative renders at half of --spp each (the default: as
    /// unbiased, at the cost of one render).
    #[arg(help_heading = crate::RESEARCH_OPTIONS, long, conflicts_with = "single_render")]
    pub full_renders: bool,
    /// Normalise each view's loss, per channel, by the loss of a black image against its target,
    /// so that dim views (light that crossed the object) count as much as bright ones.
    #[arg(help_heading = crate::RESEARCH_OPTIONS, long)]
    pub normalize_views: bool,
    /// With --normalize-views: no view weighs more than 1/FLOOR times an average view.
    #[arg(help_heading = crate::RESEARCH_OPTIONS, long, default_value_t = 0.01, value_name = "FLOOR")]
    pub view_weight_floor: f64,
    /// Initial σ_t (1/unit; one value or R,G,B).
    #[arg(long, default_value = "50", value_parser = parse_rgb, allow_negative_numbers = true)]
    pub init_sigma_t: [f32; 3],
    /// Initial albedo (one value or R,G,B).
    #[arg(long, default_value = "0.5", value_parser = parse_rgb, allow_negative_numbers = true)]
    pub init_albedo: [f32; 3],
    /// Learning rate on ln σ_t (or on σ_t/100 with --scaled-sigma-t).
    #[arg(help_heading = crate::RESEARCH_OPTIONS, long, default_value_t = OptimizeConfig::default().lr_sigma_t)]
    pub lr_sigma_t: f32,
    /// Learning rate on α.
    #[arg(help_heading = crate::RESEARCH_OPTIONS, long, default_value_t = OptimizeConfig::default().lr_albedo)]
    pub lr_albedo: f32,
    /// Learning-rate decay factor.
    #[arg(help_heading = crate::RESEARCH_OPTIONS, long, default_value_t = OptimizeConfig::default().decay)]
    pub decay: f32,
    /// Iterations between decays.
    #[arg(help_heading = crate::RESEARCH_OPTIONS, long, default_value_t = OptimizeConfig::default().decay_every)]
    pub decay_every: u32,
    /// Optimise σ_t/100 (the paper's parameterisation) instead of ln σ_t.
    #[arg(help_heading = crate::RESEARCH_OPTIONS, long)]
    pub scaled_sigma_t: bool,
    /// (The default; accepted for older scripts.)
    #[arg(long, hide = true, conflicts_with = "scaled_sigma_t")]
    pub log_sigma_t: bool,
    /// Albedo first: keep σ_t at its initial value for this many initial iterations (at most a
    /// third of the run) while α converges.
    #[arg(help_heading = crate::RESEARCH_OPTIONS, long, default_value_t = OptimizeConfig::default().albedo_warmup)]
    pub albedo_warmup: u32,
    /// One σ_t and one α for all channels.
    #[arg(help_heading = crate::RESEARCH_OPTIONS, long)]
    pub monochrome: bool,
    /// Keep σ_t at its initial value.
    #[arg(help_heading = crate::RESEARCH_OPTIONS, long)]
    pub fix_sigma_t: bool,
    /// Keep α at its initial value.
    #[arg(help_heading = crate::RESEARCH_OPTIONS, long)]
    pub fix_albedo: bool,
    /// Refit the polynomial features every K iterations (0: once, at the initial parameters).
    #[arg(help_heading = crate::RESEARCH_OPTIONS, long, default_value_t = 0)]
    pub refit_every: u32,
    /// Also fit the polynomial's σ_n-derivative at every fit, so that the descriptor at another
    /// σ_n (in the value and in the σ_t offsets) follows a refit, not only the rescaling. Three
    /// fits instead of one; use with --refit-every.
    #[arg(help_heading = crate::RESEARCH_OPTIONS, long)]
    pub fit_derivative: bool,
    /// Relative offset Δ/σ_t of the correlated offset samples.
    #[arg(help_heading = crate::RESEARCH_OPTIONS, long, default_value_t = OptimizeConfig::default().delta_rel)]
    pub delta_rel: f32,
    /// Value image of `ours`: `offset-mean` (mean of the two σ_t offset samples, O(Δ²) bias,
    /// a third less work) or `sample` (an unperturbed sample of its own).
    #[arg(help_heading = crate::RESEARCH_OPTIONS, long, default_value = "offset-mean")]
    pub primal: Primal,
    /// Fit only these views of the dataset (indices, e.g. `0,3,5`; default: all). The
    /// re-renders and the bias correction use the same views; `--resume` keeps the run's own.
    #[arg(help_heading = crate::CHECK_OPTIONS, long, value_delimiter = ',', value_name = "I,J,…")]
    pub view_subset: Option<Vec<usize>>,
    /// Checkpoint every N iterations.
    #[arg(help_heading = crate::CHECK_OPTIONS, long, default_value_t = 10)]
    pub checkpoint_every: u32,
    /// Samples per pixel of the final re-renders.
    #[arg(help_heading = crate::CHECK_OPTIONS, long, default_value_t = 64)]
    pub final_spp: u32,
    /// Views for the 95 % intervals at the end (two derivative renders each, spread evenly
    /// over the dataset; 0: no intervals).
    #[arg(help_heading = crate::CHECK_OPTIONS, long, default_value_t = inverse::uncertainty::UncertaintySettings::default().views)]
    pub uncertainty_views: usize,
    /// Samples per pixel of the interval renders.
    #[arg(help_heading = crate::CHECK_OPTIONS, long, default_value_t = inverse::uncertainty::UncertaintySettings::default().spp)]
    pub uncertainty_spp: u32,
    /// Views re-rendered at the estimate by the volumetric path tracer (twice, at the dataset's
    /// samples per pixel) to check that the estimate reproduces the images without the learned
    /// model (0: no check).
    #[arg(help_heading = crate::CHECK_OPTIONS, long, default_value_t = 4)]
    pub consistency_views: usize,
    /// Seed.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Several initialisations first: N shorter runs (a third of --iterations each) from σ_t
    /// between a third and three times --init-sigma-t; the one with the lowest loss starts the
    /// run. For images that may leave σ_t open; costs N/3 more runs. Listed in
    /// OUT/starts/starts.json and result.json.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=16))]
    pub starts: u32,
    /// Continue the run in --out from its checkpoint (--iterations may extend it).
    #[arg(long)]
    pub resume: bool,
    /// Replace an existing run in --out.
    #[arg(long)]
    pub overwrite: bool,
    #[command(flatten)]
    pub bc: BiasCorrectionArgs,
    #[command(flatten)]
    pub learned: LearnedArgs,
}

/// The work of an optimisation run (shared by `optimize` and `experiment`).
#[derive(Args, Clone, Copy, Debug)]
pub struct IterationArgs {
    /// Iterations (per run).
    #[arg(long, default_value_t = OptimizeConfig::default().iterations)]
    pub iterations: u32,
    /// Samples per pixel per iteration.
    #[arg(long, default_value_t = OptimizeConfig::default().spp)]
    pub spp: u32,
    /// Views rendered per iteration (drawn at random).
    #[arg(help_heading = crate::RESEARCH_OPTIONS, long, default_value_t = OptimizeConfig::default().views_per_iter)]
    pub views_per_iter: usize,
    /// Render a random N×N crop of each chosen view per iteration instead of the whole image
    /// (the paper's released optimiser; clamped to the image size).
    #[arg(help_heading = crate::RESEARCH_OPTIONS, long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..))]
    pub crop: Option<u32>,
}

impl OptimizeArgs {
    /// The command's defaults for `--dataset dataset --out out`.
    pub fn with_defaults(dataset: PathBuf, out: PathBuf) -> Self {
        Self {
            dataset,
            out,
            ..crate::arg_defaults(&["--dataset", "d"])
        }
    }
}

pub fn config_of(a: &OptimizeArgs) -> Result<OptimizeConfig> {
    config_for(a, || Ok(Dataset::load(&a.dataset)?.render.max_depth))
}

/// [`config_of`] with the dataset's own tracer depth from `dataset_depth`, asked only when the
/// tracer is used and `--max-depth` is not given.
pub fn config_for(
    a: &OptimizeArgs,
    dataset_depth: impl FnOnce() -> Result<Option<u32>>,
) -> Result<OptimizeConfig> {
    let model = a.learned.kind();
    let mut c = OptimizeConfig::new(Params {
        sigma_t: a.init_sigma_t.map(|v| v as f64),
        albedo: a.init_albedo.map(|v| v as f64),
    });
    c.model = ModelChoice::new(model, a.estimator.as_deref())
        .map_err(|e| CmdlineError::Invalid(format!("--estimator: {e}")))?;
    c.iterations = a.budget.iterations;
    c.refine_iterations = match a.refine {
        Some(r) if r > 0 && a.bc.bias_correction => {
            return Err(CmdlineError::Invalid(format!(
                "--bias-correction with --refine {r}: the correction is for the learned model \
                 alone; fix: drop one of the two (the refinement replaces the correction)"
            )));
        }
        Some(r) => r,
        // `--bias-correction` asks for the learned model alone with the correction.
        None if a.bc.bias_correction => 0,
        None => OptimizeConfig::default_refinement(model, a.budget.iterations),
    };
    // Only a run with a refinement records the choice (runs without one compare equal to those
    // written before the option).
    c.refine_restarts_moments = c.refine_iterations > 0 && !a.refine_keeps_moments;
    if model == ModelKind::Volpath || c.refine_iterations > 0 {
        c.volpath_max_depth = match a.max_depth {
            Some(d) => Some(d),
            None => dataset_depth()?,
        };
    }
    c.spp = a.budget.spp;
    if let Some(r) = a.refine_spp {
        if c.refine_iterations == 0 {
            return Err(CmdlineError::Invalid(format!(
                "--refine-spp {r} without a refinement (--refine 0, --bias-correction or a \
                 model other than the learned one); fix: drop --refine-spp or refine"
            )));
        }
        c.refine_spp = Some(r);
    }
    c.views_per_iter = a.budget.views_per_iter;
    c.view_subset = a.view_subset.clone();
    c.loss = a.loss;
    c.two_renders = !a.single_render;
    c.split_samples = !a.full_renders;
    if !(a.view_weight_floor > 0.0 && a.view_weight_floor <= 1.0) {
        return Err(CmdlineError::Invalid(format!(
            "--view-weight-floor must be in (0, 1], got {}",
            a.view_weight_floor
        )));
    }
    c.normalize_views = a.normalize_views;
    c.view_weight_floor = a.view_weight_floor;
    c.crop = a.budget.crop;
    c.lr_sigma_t = a.lr_sigma_t;
    c.lr_albedo = a.lr_albedo;
    c.decay = a.decay;
    c.decay_every = a.decay_every;
    c.refit_every = a.refit_every;
    c.fit_derivative = a.fit_derivative;
    c.delta_rel = a.delta_rel;
    c.primal = a.primal;
    c.learned = a.learned.settings();
    c.seed = a.seed;
    c.albedo_warmup = a.albedo_warmup;
    c.params = ParamSpec {
        parameterisation: if a.scaled_sigma_t {
            Parameterisation::Scaled
        } else {
            Parameterisation::Log
        },
        monochrome: a.monochrome,
        fix_sigma_t: a.fix_sigma_t,
        fix_albedo: a.fix_albedo,
    };
    Ok(c)
}

/// The library's recovery for `a` ([`inverse::recovery`]): the flags as a typed configuration.
pub fn recovery_config(a: &OptimizeArgs) -> Result<RecoveryConfig> {
    let model_file = match a.learned.model_file_of(a.learned.kind())? {
        Some(p) if !matches!(p.as_os_str().to_str(), Some("shipped" | "learned")) => Some(p),
        _ => None,
    };
    Ok(RecoveryConfig {
        dataset: a.dataset.clone(),
        out: a.out.clone(),
        optimize: config_of(a)?,
        model_file,
        max_depth: a.max_depth,
        refine_given: a.refine.is_some(),
        checkpoint_every: a.checkpoint_every,
        final_spp: a.final_spp,
        uncertainty: UncertaintySettings {
            views: a.uncertainty_views,
            spp: a.uncertainty_spp,
            ..Default::default()
        },
        consistency_views: a.consistency_views,
        starts: a.starts,
        resume: a.resume,
        overwrite: a.overwrite,
        bias_correction: a.bc.settings(),
    })
}

/// The result of the recovery `o` if its folder holds it finished ([`recovery::reuse::finished`]);
/// runs nothing.
pub fn finished_run(o: &OptimizeArgs) -> Result<Option<recovery::RunResult>> {
    if !o.out.join("result.json").exists() {
        // Nothing to read (and its dataset, which the settings may need, may not exist yet).
        return Ok(None);
    }
    Ok(recovery::reuse::finished(&recovery_config(o)?))
}

/// Run the recovery `o` into `o.out`, resume it, or reuse it when it has finished
/// ([`recovery::run_or_reuse`]).
pub fn run_or_reuse(
    o: &OptimizeArgs,
    observer: &dyn Observer,
    label: &str,
) -> Result<recovery::RunResult> {
    Ok(recovery::run_or_reuse(
        &recovery_config(o)?,
        observer,
        label,
    )?)
}
