//! The accuracy experiment's settings.

use std::path::PathBuf;

use recovery::BiasCorrection;
use recovery::settings::{Budget, LearnedModel};

use crate::jobs;

/// The accuracy experiment's settings; [`Default`] is the command's defaults.
#[derive(Clone, Debug, PartialEq)]
pub struct AccuracyConfig {
    /// The output folder (datasets in `OUT/data`, runs in `OUT/runs`; reused by a later run).
    pub out: PathBuf,
    /// Built-in shapes, each with optional parameters as NAME[:KEY=VALUE]… (the keys of a
    /// scene file's `shape` table, e.g. `blob:amplitude=0.05`; its cases are named
    /// `blob-amplitude-0.05-m0`, …).
    pub shapes: Vec<String>,
    /// The shapes at a smoke test's resolution ([`geometry::Shape::coarse`]).
    pub coarse_meshes: bool,
    /// Hidden media per shape, drawn from the paper's ranges.
    pub media: u64,
    /// Views per dataset.
    pub views: usize,
    /// Image width and height.
    pub res: u32,
    /// Samples per pixel of the volumetric target renders.
    pub target_spp: u32,
    /// Optimisation methods: estimators of the learned model, or baseline models.
    pub methods: Vec<String>,
    pub budget: Budget,
    /// Optimise σ_t/100 (the paper's parameterisation) instead of ln σ_t (as `optimize`).
    pub scaled_sigma_t: bool,
    /// Albedo first: σ_t stays at its initial value for this many initial iterations.
    pub albedo_warmup: u32,
    /// Random initialisations on one case ([`Self::inits_case`]) with the first method.
    pub inits: u32,
    /// The case of the random initialisations (default: the first case).
    pub inits_case: Option<String>,
    /// Seed of the media, the renders and the runs.
    pub seed: u64,
    /// Bias correction: after each run the case's dataset is rendered again at the recovered
    /// medium and recovered with the same settings; the rows `<method>+bc` (step 1) and
    /// `<method>+bc<k>` report θ_k.
    pub bc: BiasCorrection,
    pub learned: LearnedModel,
    pub jobs: jobs::Jobs,
}

impl Default for AccuracyConfig {
    fn default() -> Self {
        AccuracyConfig {
            out: PathBuf::from("out/experiment-accuracy"),
            shapes: ["blob", "torus", "cone"].map(String::from).to_vec(),
            coarse_meshes: false,
            media: 2,
            views: 40,
            res: 256,
            target_spp: 128,
            methods: ["ours", "naive"].map(String::from).to_vec(),
            budget: Budget::default(),
            scaled_sigma_t: false,
            albedo_warmup: inverse::optimize::OptimizeConfig::default().albedo_warmup,
            inits: 8,
            inits_case: None,
            seed: 0,
            bc: BiasCorrection::default(),
            learned: LearnedModel::default(),
            jobs: jobs::Jobs::default(),
        }
    }
}
