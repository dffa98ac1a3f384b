//! The settings a front end exposes, as the library's errors name them.
//!
//! A library error that tells the user what to change names the setting by a [`Setting`], never
//! by a command-line flag: the library does not know whether it runs under the `translucent`
//! binary, the maintainers' `translucent-dev` or a Python session. A front end says once, at its
//! start, how its users spell each setting ([`name_settings`]); the binaries spell them as their
//! flags (`--overwrite`), and without a front end a setting is spelled by its configuration key
//! (`overwrite`, the field of the typed configuration that holds it).
//!
//! ```
//! use scene::setting::Setting;
//! // No front end has named the settings here: the configuration key.
//! assert_eq!(format!("pass {} to replace it", Setting::Overwrite), "pass overwrite to replace it");
//! ```

use std::fmt;
use std::sync::OnceLock;

/// A setting that a library error may ask the user to change.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Setting {
    /// Replace outputs that exist.
    Overwrite,
    /// Continue a run from its checkpoint.
    Resume,
    /// The output folder.
    Out,
    /// The views a recovery uses.
    ViewSubset,
    /// Samples per pixel.
    Spp,
    /// The tracer's maximum path depth.
    MaxDepth,
    /// The forward model.
    Model,
    /// A learned model's file.
    ModelFile,
    /// Samples per pixel of the tracer's refinement.
    RefineSpp,
    /// The learned model alone with the bias correction, instead of the refinement.
    BiasCorrection,
    /// The least weight of a view relative to an average one.
    ViewWeightFloor,
    /// The starting points of a multi-start recovery.
    Starts,
    /// The number of iterations.
    Iterations,
    /// The iterations refined with the tracer.
    Refine,
    /// The bias correction's steps.
    BiasCorrectionSteps,
    /// The starting σ_t.
    InitSigmaT,
    /// The starting albedo.
    InitAlbedo,
    /// Recovering the phase function's g besides σ_t and α.
    FreeG,
    /// Recovering one g per channel.
    FreeGRgb,
    /// The starting g of a recovery that frees it.
    InitG,
    /// Recovering a factor on the lights' stated intensity.
    FreeLightScale,
    /// The starting light scale of a recovery that frees it.
    InitLightScale,
    /// The learned renderer's entry-point sampler.
    EntrySampler,
    /// The gradient estimator.
    Estimator,
    /// The training network's layer widths.
    Widths,
    /// The model a training run starts from.
    Init,
    /// The training loss's weight of the exit position.
    PositionWeight,
    /// The training learning rate.
    Lr,
    /// The training gradient clipping threshold.
    Clip,
    /// Whether the training data keep VKJ19's c_19 = 0 quirk (the setting that turns it off).
    NoC19Quirk,
    /// Making training data into a folder (an action, not a value: the front end's command).
    MakeTrainingData,
    /// The one case of an experiment a job runs.
    Case,
    /// Listing an experiment's cases as jobs instead of running them.
    ListJobs,
    /// The cases of an experiment's suite to run.
    Cases,
    /// The perturbations of the capture-errors experiment to run.
    Perturbations,
    /// The shapes of an experiment's datasets.
    Shapes,
    /// The methods an experiment compares.
    Methods,
    /// The hidden media per shape of an experiment.
    Media,
    /// The random initialisations of an experiment.
    Inits,
    /// The case of an experiment's random initialisations.
    InitsCase,
    /// The independent repetitions of an experiment's cases.
    Seeds,
    /// Who renders an experiment's target images.
    Targets,
    /// The mesh file of an experiment's shape.
    Mesh,
    /// The script that renders with Mitsuba 3.
    MitsubaScript,
}

impl Setting {
    /// The configuration key: the field of the typed configuration that holds the setting.
    pub fn key(self) -> &'static str {
        match self {
            Setting::Overwrite => "overwrite",
            Setting::Resume => "resume",
            Setting::Out => "out",
            Setting::ViewSubset => "view_subset",
            Setting::Spp => "spp",
            Setting::MaxDepth => "max_depth",
            Setting::Model => "model",
            Setting::ModelFile => "model_file",
            Setting::RefineSpp => "refine_spp",
            Setting::BiasCorrection => "bias_correction",
            Setting::ViewWeightFloor => "view_weight_floor",
            Setting::Starts => "starts",
            Setting::Iterations => "iterations",
            Setting::Refine => "refine",
            Setting::BiasCorrectionSteps => "bias_correction_steps",
            Setting::InitSigmaT => "init_sigma_t",
            Setting::InitAlbedo => "init_albedo",
            Setting::FreeG => "free_g",
            Setting::FreeGRgb => "free_g_rgb",
            Setting::InitG => "init_g",
            Setting::FreeLightScale => "free_light_scale",
            Setting::InitLightScale => "init_light_scale",
            Setting::EntrySampler => "entry_sampler",
            Setting::Estimator => "estimator",
            Setting::Widths => "widths",
            Setting::Init => "init",
            Setting::PositionWeight => "position_weight",
            Setting::Lr => "lr",
            Setting::Clip => "clip",
            Setting::NoC19Quirk => "no_c19_quirk",
            Setting::MakeTrainingData => "make_training_data",
            Setting::Case => "case",
            Setting::ListJobs => "list_jobs",
            Setting::Cases => "cases",
            Setting::Perturbations => "perturbations",
            Setting::Shapes => "shapes",
            Setting::Methods => "methods",
            Setting::Media => "media",
            Setting::Inits => "inits",
            Setting::InitsCase => "inits_case",
            Setting::Seeds => "seeds",
            Setting::Targets => "targets",
            Setting::Mesh => "mesh",
            Setting::MitsubaScript => "mitsuba_script",
        }
    }
}

static NAMER: OnceLock<fn(Setting) -> &'static str> = OnceLock::new();

/// Says how this process's users spell each setting. The first call wins; a front end makes it
/// once before it runs anything.
pub fn name_settings(namer: fn(Setting) -> &'static str) {
    let _ = NAMER.set(namer);
}

/// The front end's spelling of the setting, or its configuration key.
impl fmt::Display for Setting {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let name = NAMER.get().map_or_else(|| self.key(), |namer| namer(*self));
        f.write_str(name)
    }
}
