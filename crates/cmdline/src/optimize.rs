//! `optimize`'s options ([`OptimizeArgs`]) and their one conversion into the library's settings
//! ([`recovery::RecoverySettings`], whose defaults are the options' defaults); the
//! experiments describe their runs with the same settings, so that every run they publish is one
//! a user can type.

use std::path::PathBuf;

use bssrdf::diff::{Loss, Primal};
use clap::Args;
use inverse::optimize::OptimizeConfig;
use inverse::params::{OneOrRgb, ParamSpec, Parameterisation, Params};
use inverse::uncertainty::UncertaintySettings;
use recovery::RecoveryConfig;
use recovery::settings::{
    CheckSettings, LearnedSection, ModelSettings, RecoverySettings, Schedule, StartSettings,
    TracerSection,
};

use crate::{LearnedArgs, Result, parse_rgb};

mod bias_correction;

pub use bias_correction::BiasCorrectionArgs;

/// A parameter that `optimize` can recover besides σ_t and α.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum FreeParam {
    /// The phase function's Henyey–Greenstein g (one for all channels).
    G,
    /// One Henyey–Greenstein g per channel (a chromatic medium; it includes `g`).
    GRgb,
    /// A factor on every light's stated intensity (one for all lights and channels).
    LightScale,
    /// A factor per channel on every light's stated intensity (the light's strength and the
    /// camera's white balance unknown).
    LightScaleRgb,
}

#[derive(Args, Clone)]
#[command(mut_arg("out", crate::groups::default("out/optimize")))]
#[command(mut_arg("overwrite", crate::groups::help("Replace an existing run in --out")))]
pub struct OptimizeArgs {
    /// Dataset folder: ours (dataset.json) or a Mitsuba reference folder (scene.json); its
    /// truth medium, when present, is only used to report errors.
    #[arg(long)]
    pub dataset: PathBuf,
    #[command(flatten)]
    pub out: crate::Output,
    /// Gradient estimator of the model (`--model`). The learned BSSRDF takes ours (default),
    /// ours-alpha-offsets, naive and fd; `volpath` and `dipole` take ad (default) and fd.
    #[arg(help_heading = crate::RESEARCH_OPTIONS, long, alias = "method", value_name = "ESTIMATOR")]
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
    #[arg(help_heading = crate::RESEARCH_OPTIONS, long, default_value_t = OptimizeConfig::default().view_weight_floor, value_name = "FLOOR")]
    pub view_weight_floor: f64,
    /// Initial σ_t (1/unit; one value or R,G,B). Default: 50, or where the dataset states its
    /// length unit a typical real material's, 1.50 mm⁻¹ at g = 0 (the geometric mean of Jensen
    /// et al. 2001's twelve, at the object's g, in its unit).
    #[arg(long, value_parser = parse_rgb, allow_negative_numbers = true)]
    pub init_sigma_t: Option<[f32; 3]>,
    /// Initial albedo (one value or R,G,B).
    #[arg(long, default_value = "0.5", value_parser = parse_rgb, allow_negative_numbers = true)]
    pub init_albedo: [f32; 3],
    /// Recover these besides σ_t and α, each with its own 95 % interval: `g`, the
    /// Henyey–Greenstein anisotropy (one value for all channels; it starts at the dataset's
    /// stated g or --init-g and moves where the volumetric path tracer renders: the refinement
    /// of the default recovery, the learned model holding it during its fit, or --model
    /// volpath); `g-rgb`, one g per channel, for a medium whose forward scattering depends on
    /// the wavelength (as milks' does); `light-scale`, a factor k on every light's stated intensity, for a light of
    /// unknown strength (one for all lights and channels, from 1 or --init-light-scale);
    /// `light-scale-rgb`, one such factor per channel, for a camera whose white balance is
    /// unknown too (it includes `light-scale`).
    #[arg(long, value_enum, value_delimiter = ',', value_name = "PARAM")]
    pub free: Vec<FreeParam>,
    /// Initial g with --free g or g-rgb, one value or R,G,B (default: the dataset's stated g).
    #[arg(help_heading = crate::RESEARCH_OPTIONS, long, value_parser = parse_rgb, allow_negative_numbers = true)]
    pub init_g: Option<[f32; 3]>,
    /// Initial light scale with --free light-scale or light-scale-rgb, every channel's (default
    /// 1: the lights as stated).
    #[arg(help_heading = crate::RESEARCH_OPTIONS, long)]
    pub init_light_scale: Option<f64>,
    /// Learning rate on ln k with --free light-scale.
    #[arg(help_heading = crate::RESEARCH_OPTIONS, long, default_value_t = OptimizeConfig::default().lr_light_scale)]
    pub lr_light_scale: f32,
    /// Learning rate on g with --free g.
    #[arg(help_heading = crate::RESEARCH_OPTIONS, long, default_value_t = OptimizeConfig::default().lr_g)]
    pub lr_g: f32,
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
    #[arg(help_heading = crate::RESEARCH_OPTIONS, long, default_value_t = OptimizeConfig::default().refit_every)]
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
    #[arg(help_heading = crate::CHECK_OPTIONS, long, default_value_t = RecoverySettings::default().checks.checkpoint_every)]
    pub checkpoint_every: u32,
    /// Samples per pixel of the final re-renders.
    #[arg(help_heading = crate::CHECK_OPTIONS, long, default_value_t = RecoverySettings::default().checks.final_spp)]
    pub final_spp: u32,
    /// Views for the 95 % intervals at the end (two derivative renders each, spread evenly
    /// over the dataset; 0: no intervals).
    #[arg(help_heading = crate::CHECK_OPTIONS, long, default_value_t = inverse::uncertainty::UncertaintySettings::default().views)]
    pub uncertainty_views: usize,
    /// Samples per pixel of the interval renders (two per view). Their noise is kept out of the
    /// intervals: each view's gradient takes one render's values against the other's
    /// derivatives (BENCHMARKS.md, "The intervals' own render noise"); more samples make the
    /// intervals' own estimate less noisy, at a proportional cost.
    #[arg(help_heading = crate::CHECK_OPTIONS, long, default_value_t = inverse::uncertainty::UncertaintySettings::default().spp)]
    pub uncertainty_spp: u32,
    /// The mesh's accuracy, for a scanned or reconstructed mesh: the RMS distance of its
    /// vertices from the true surface, along the normals, as a fraction of its bounding box's
    /// diagonal (0.002: 0.2 %). The intervals then include what a mesh error of that size
    /// moves the estimate by (8 noisy copies of the mesh rendered by the volumetric path
    /// tracer at the estimate), to first order: on a mesh with 0.2 % noise that step was
    /// measured at a third to a half of the error's actual effect. Default: the mesh is exact.
    #[arg(help_heading = crate::CHECK_OPTIONS, long, value_name = "FRACTION", value_parser = parse_mesh_error)]
    pub mesh_error: Option<f64>,
    /// Views re-rendered at the estimate by the volumetric path tracer (twice, at the dataset's
    /// samples per pixel) to check that the estimate reproduces the images without the learned
    /// model (0: no check).
    #[arg(help_heading = crate::CHECK_OPTIONS, long, default_value_t = RecoverySettings::default().checks.consistency_views)]
    pub consistency_views: usize,
    #[command(flatten)]
    pub seed: crate::Seed,
    /// Several initialisations first: N shorter runs (a third of --iterations each) from σ_t
    /// between a third and three times σ_t's start; the one with the lowest loss starts the
    /// run. For images that may leave σ_t open; costs N/3 more runs. Listed in
    /// OUT/starts/starts.json and result.json.
    #[arg(long, default_value_t = RecoverySettings::default().start.starts, value_parser = clap::value_parser!(u32).range(1..=16))]
    pub starts: u32,
    /// Continue the run in --out from its checkpoint (--iterations may extend it).
    #[arg(long)]
    pub resume: bool,
    #[command(flatten)]
    pub overwrite: crate::Overwrite,
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
            out: out.into(),
            ..crate::arg_defaults(&["--dataset", "d"])
        }
    }
}

impl IterationArgs {
    /// The budget these options set.
    pub fn budget(&self) -> recovery::settings::Budget {
        recovery::settings::Budget {
            iterations: self.iterations,
            spp: self.spp,
            views_per_iter: self.views_per_iter,
            crop: self.crop,
        }
    }

    /// Sets the schedule's budget to these options.
    pub fn apply(&self, s: &mut Schedule) {
        self.budget().apply(s);
    }
}

impl OptimizeArgs {
    /// The options as the library's settings (the one conversion; every default is the
    /// library's [`RecoverySettings::default`]).
    pub fn settings(&self) -> RecoverySettings {
        let rgb = |v: [f32; 3]| v.map(f64::from);
        let mut s = RecoverySettings {
            model: ModelSettings {
                estimator: self.estimator.clone(),
                ..ModelSettings::default()
            },
            start: StartSettings {
                init: Params {
                    sigma_t: self
                        .init_sigma_t
                        .map_or(RecoverySettings::default().start.init.sigma_t, rgb),
                    albedo: rgb(self.init_albedo),
                    g: self.init_g.map(|g| match g {
                        [r, g, b] if r == g && g == b => OneOrRgb::One(f64::from(r)),
                        g => OneOrRgb::Rgb(rgb(g)),
                    }),
                    light_scale: self.init_light_scale.map(OneOrRgb::One),
                },
                sigma_t_from_units: self.init_sigma_t.is_none(),
                starts: self.starts,
            },
            schedule: Schedule {
                view_subset: self.view_subset.clone(),
                seed: *self.seed,
                lr_sigma_t: self.lr_sigma_t,
                lr_albedo: self.lr_albedo,
                lr_g: self.lr_g,
                lr_light_scale: self.lr_light_scale,
                decay: self.decay,
                decay_every: self.decay_every,
                albedo_warmup: self.albedo_warmup,
                params: ParamSpec {
                    parameterisation: if self.scaled_sigma_t {
                        Parameterisation::Scaled
                    } else {
                        Parameterisation::Log
                    },
                    monochrome: self.monochrome,
                    fix_sigma_t: self.fix_sigma_t,
                    fix_albedo: self.fix_albedo,
                    free_g: self.free.contains(&FreeParam::G)
                        || self.free.contains(&FreeParam::GRgb),
                    g_per_channel: self.free.contains(&FreeParam::GRgb),
                    free_light_scale: self.free.contains(&FreeParam::LightScale)
                        || self.free.contains(&FreeParam::LightScaleRgb),
                    light_scale_per_channel: self.free.contains(&FreeParam::LightScaleRgb),
                },
                loss: self.loss,
                single_render: self.single_render,
                full_renders: self.full_renders,
                normalize_views: self.normalize_views,
                view_weight_floor: self.view_weight_floor,
                ..RecoverySettings::default().schedule
            },
            learned: LearnedSection {
                refit_every: self.refit_every,
                fit_derivative: self.fit_derivative,
                delta_rel: self.delta_rel,
                primal: self.primal,
                ..RecoverySettings::default().learned
            },
            tracer: TracerSection {
                max_depth: self.max_depth,
                refine: self.refine,
                refine_spp: self.refine_spp,
                refine_keeps_moments: self.refine_keeps_moments,
            },
            checks: CheckSettings {
                checkpoint_every: self.checkpoint_every,
                final_spp: self.final_spp,
                uncertainty: UncertaintySettings {
                    views: self.uncertainty_views,
                    spp: self.uncertainty_spp,
                    mesh_error: self.mesh_error,
                    ..Default::default()
                },
                consistency_views: self.consistency_views,
            },
            bias_correction: self.bc.settings(),
            resume: self.resume,
            overwrite: *self.overwrite,
        };
        self.budget.apply(&mut s.schedule);
        self.learned.apply(&mut s);
        s
    }
}

/// The library's recovery for `a` ([`recovery`]): the flags as a typed configuration.
pub fn recovery_config(a: &OptimizeArgs) -> Result<RecoveryConfig> {
    Ok(a.settings()
        .resolve_for(a.dataset.clone(), a.out.to_path_buf())?)
}

/// `--mesh-error`: a fraction in (0, 0.1].
pub fn parse_mesh_error(s: &str) -> Result<f64, String> {
    let f: f64 = s
        .parse()
        .map_err(|_| format!("{s:?} is not a number; write e.g. 0.002 for 0.2 %"))?;
    if f > 0.0 && f <= 0.1 {
        Ok(f)
    } else {
        Err(format!(
            "{f} is outside (0, 0.1]: the fraction of the mesh's diagonal, e.g. 0.002 for 0.2 %"
        ))
    }
}
