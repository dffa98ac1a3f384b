//! The options of the accuracy experiment and of the two built on it (`inits`, `planar`).

use clap::Args;
use experiment::accuracy::AccuracyConfig;
use experiment::inits::InitsConfig;
use experiment::planar::PlanarConfig;

use cmdline::optimize::{BiasCorrectionArgs, IterationArgs};

#[derive(Args)]
#[command(mut_arg(
    "out",
    cmdline::groups::default_and_help(
        AccuracyConfig::default().out.display().to_string(),
        "Output folder (datasets in OUT/data, runs in OUT/runs; reused by a later run)"
    )
))]
#[command(mut_arg(
    "seed",
    cmdline::groups::help("Seed of the media, the renders and the runs")
))]
#[command(mut_arg("views", cmdline::groups::default_and_help(AccuracyConfig::default().views.to_string(), "Views per dataset")))]
#[command(mut_arg(
    "res",
    cmdline::groups::default_and_help(AccuracyConfig::default().res.to_string(), "Image width and height")
))]
pub struct AccuracyArgs {
    #[command(flatten)]
    pub out: cmdline::Output,
    /// Built-in shapes (comma-separated: sphere, cone, torus, rounded-box, blob), each with
    /// optional parameters as NAME[:KEY=VALUE]… (the keys of a scene file's `shape` table, e.g.
    /// `blob:amplitude=0.05`; its cases are named `blob-amplitude-0.05-m0`, …).
    #[arg(long, default_value = AccuracyConfig::default().shapes.join(","), value_delimiter = ',')]
    pub shapes: Vec<String>,
    /// The shapes at a smoke test's resolution (icosphere subdivisions at most 4, at most 32
    /// segments): a quick check of the pipeline, not a measurement.
    #[arg(long)]
    pub coarse_meshes: bool,
    /// Hidden media per shape, drawn from the paper's ranges.
    #[arg(long, default_value_t = AccuracyConfig::default().media)]
    pub media: u64,
    #[command(flatten)]
    pub views: cmdline::Views,
    #[command(flatten)]
    pub res: cmdline::Resolution,
    /// Samples per pixel of the volumetric target renders.
    #[arg(long, default_value_t = AccuracyConfig::default().target_spp)]
    pub target_spp: u32,
    /// Optimisation methods (comma-separated).
    #[arg(long, default_value = AccuracyConfig::default().methods.join(","), value_delimiter = ',')]
    pub methods: Vec<String>,
    #[command(flatten)]
    pub budget: IterationArgs,
    /// Optimise σ_t/100 (the paper's parameterisation) instead of ln σ_t (as `optimize`).
    #[arg(long)]
    pub scaled_sigma_t: bool,
    /// Albedo first: σ_t stays at its initial value for this many initial iterations (as
    /// `optimize`).
    #[arg(long, default_value_t = AccuracyConfig::default().albedo_warmup)]
    pub albedo_warmup: u32,
    /// Random initialisations on one case (`--inits-case`) with the first method (0: none).
    #[arg(long, default_value_t = AccuracyConfig::default().inits)]
    pub inits: u32,
    /// The case of the random initialisations (e.g. `torus-m0`; default: the first case).
    #[arg(long)]
    pub inits_case: Option<String>,
    #[command(flatten)]
    pub seed: cmdline::Seed,
    /// Bias correction (as `optimize --bias-correction`): after each run the case's dataset is
    /// rendered again at the recovered medium and recovered with the same settings; the rows
    /// `<method>+bc` (step 1) and `<method>+bc<k>` report θ_k.
    #[command(flatten)]
    pub bc: BiasCorrectionArgs,
    #[command(flatten)]
    pub learned: cmdline::LearnedArgs,
    #[command(flatten)]
    pub jobs: super::JobArgs,
}

impl AccuracyArgs {
    /// The experiment's settings.
    pub fn config(&self) -> AccuracyConfig {
        AccuracyConfig {
            out: self.out.to_path_buf(),
            shapes: self.shapes.clone(),
            coarse_meshes: self.coarse_meshes,
            media: self.media,
            views: *self.views,
            res: *self.res,
            target_spp: self.target_spp,
            methods: self.methods.clone(),
            budget: self.budget.budget(),
            scaled_sigma_t: self.scaled_sigma_t,
            albedo_warmup: self.albedo_warmup,
            inits: self.inits,
            inits_case: self.inits_case.clone(),
            seed: *self.seed,
            bc: self.bc.settings().correction,
            learned: self.learned.learned(),
            jobs: self.jobs.jobs(),
        }
    }
}

#[derive(Args)]
#[command(mut_arg(
    "out",
    cmdline::groups::default_and_help(
        InitsConfig::default().out.display().to_string(),
        "Output folder (datasets in OUT/data, runs in OUT/runs; reused by a later run)"
    )
))]
#[command(mut_arg(
    "seed",
    cmdline::groups::help("Seed of the medium, the renders, the starts and the runs")
))]
#[command(mut_arg(
    "quick",
    cmdline::groups::help(
        "A smoke test in seconds (4 views of 32², 6 iterations, 3 starts, coarse meshes): not a measurement"
    )
))]
pub struct InitsArgs {
    #[command(flatten)]
    pub out: cmdline::Output,
    /// The built-in shape of the case (as `experiment accuracy --shapes`).
    #[arg(long, default_value = InitsConfig::default().shape)]
    pub shape: String,
    /// Random initialisations.
    #[arg(long, default_value_t = InitsConfig::default().inits)]
    pub inits: u32,
    #[command(flatten)]
    pub budget: IterationArgs,
    #[command(flatten)]
    pub seed: cmdline::Seed,
    #[command(flatten)]
    pub quick: cmdline::Quick,
    #[command(flatten)]
    pub jobs: super::JobArgs,
}

impl InitsArgs {
    /// The experiment's settings.
    pub fn config(&self) -> InitsConfig {
        InitsConfig {
            out: self.out.to_path_buf(),
            shape: self.shape.clone(),
            inits: self.inits,
            budget: self.budget.budget(),
            seed: *self.seed,
            quick: *self.quick,
            jobs: self.jobs.jobs(),
        }
    }
}

#[derive(Args)]
#[command(mut_arg(
    "out",
    cmdline::groups::default_and_help(
        PlanarConfig::default().out.display().to_string(),
        "Output folder (datasets in OUT/data, runs in OUT/runs; reused by a later run)"
    )
))]
#[command(mut_arg(
    "seed",
    cmdline::groups::help("Seed of the media, the renders and the runs")
))]
#[command(mut_arg(
    "quick",
    cmdline::groups::help(
        "A smoke test in seconds (4 views of 32², 6 iterations, one medium, coarse meshes): not a measurement"
    )
))]
pub struct PlanarArgs {
    #[command(flatten)]
    pub out: cmdline::Output,
    /// Built-in shapes (comma-separated, as `experiment accuracy --shapes`).
    #[arg(long, default_value = PlanarConfig::default().shapes.join(","), value_delimiter = ',')]
    pub shapes: Vec<String>,
    /// Hidden media per shape, drawn from the paper's ranges.
    #[arg(long, default_value_t = PlanarConfig::default().media)]
    pub media: u64,
    #[command(flatten)]
    pub budget: IterationArgs,
    #[command(flatten)]
    pub seed: cmdline::Seed,
    #[command(flatten)]
    pub quick: cmdline::Quick,
    /// Samples per pixel of the re-renders of the first view (truth and each estimate, by the
    /// volumetric path tracer; module docs).
    #[arg(long, default_value_t = PlanarConfig::default().rerender_spp)]
    pub rerender_spp: u32,
    #[command(flatten)]
    pub jobs: super::JobArgs,
}

impl PlanarArgs {
    /// The experiment's settings.
    pub fn config(&self) -> PlanarConfig {
        PlanarConfig {
            out: self.out.to_path_buf(),
            shapes: self.shapes.clone(),
            media: self.media,
            budget: self.budget.budget(),
            seed: *self.seed,
            quick: *self.quick,
            rerender_spp: self.rerender_spp,
            jobs: self.jobs.jobs(),
        }
    }
}
