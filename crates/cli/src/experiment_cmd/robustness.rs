//! The options of the robustness suite.

use std::path::PathBuf;

use clap::Args;
use experiment::robustness::{RobustnessConfig, Suite, Targets};

use cmdline::optimize::{FreeParam, IterationArgs};

#[derive(Args)]
#[command(mut_arg(
    "out",
    cmdline::groups::default_and_help(RobustnessConfig::default().out.display().to_string(), "Output folder (datasets, runs, tables)")
))]
#[command(mut_arg(
    "seed",
    cmdline::groups::help("Seed of the media (renders and runs use seed + repetition)")
))]
#[command(mut_arg("views", cmdline::groups::default_and_help(RobustnessConfig::default().views.to_string(), "Views per dataset")))]
#[command(mut_arg(
    "res",
    cmdline::groups::default_and_help(RobustnessConfig::default().res.to_string(), "Image width and height")
))]
#[command(mut_arg("quick", cmdline::groups::help(super::SUITE_QUICK_HELP)))]
pub struct RobustnessArgs {
    #[command(flatten)]
    pub out: cmdline::Output,
    #[command(flatten)]
    pub views: cmdline::Views,
    #[command(flatten)]
    pub res: cmdline::Resolution,
    /// Samples per pixel of the volumetric target renders.
    #[arg(long, default_value_t = RobustnessConfig::default().target_spp)]
    pub target_spp: u32,
    /// The forward model of the recoveries: `learned` (the default), `volpath` (the volumetric
    /// baseline, `optimize --model volpath`) or `dipole` (the planar dipole baseline).
    #[arg(long, default_value_t = RobustnessConfig::default().model)]
    pub model: inverse::forward::ModelKind,
    #[command(flatten)]
    pub budget: IterationArgs,
    /// The volumetric refinement of every run (`optimize --refine`): its last N iterations with
    /// the volumetric path tracer. Default: `optimize`'s.
    #[arg(help_heading = cmdline::RESEARCH_OPTIONS, long, value_name = "N")]
    pub refine: Option<u32>,
    /// Samples per pixel of the refinement's iterations (`optimize --refine-spp`). Default:
    /// `optimize`'s (--spp).
    #[arg(help_heading = cmdline::RESEARCH_OPTIONS, long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..))]
    pub refine_spp: Option<u32>,
    /// Recover these besides σ_t and α in every run (`optimize --free`): `g`, the phase
    /// function's anisotropy; `light-scale`, a factor on the lights (whose truth here is 1:
    /// the datasets state their lights), or `light-scale-rgb`, one per channel. Each gets its
    /// own table (one per channel for `light-scale-rgb`).
    #[arg(long, value_enum, value_delimiter = ',', value_name = "PARAM")]
    pub free: Vec<cmdline::optimize::FreeParam>,
    /// The starting g of runs that free it (`optimize --init-g`). Default: the dataset's
    /// stated g, which here is the case's own.
    #[arg(long, allow_negative_numbers = true, requires = "free")]
    pub init_g: Option<f64>,
    /// The starting light scale of runs that free it (`optimize --init-light-scale`; default
    /// 1, the truth).
    #[arg(long, requires = "free")]
    pub init_light_scale: Option<f64>,
    /// Independent repetitions of every case (renders and runs).
    #[arg(long, default_value_t = RobustnessConfig::default().seeds)]
    pub seeds: u64,
    /// Which cases: the twelve index-matched, isotropic ones (the default), the nine with a
    /// dielectric boundary and a forward-scattering medium, or all.
    #[arg(long, value_enum, default_value_t = RobustnessConfig::default().suite)]
    pub suite: Suite,
    /// Only these cases of the suite (names as in the table, e.g. `flash-15-blob`).
    #[arg(long, value_delimiter = ',')]
    pub cases: Option<Vec<String>>,
    /// The mesh file of the third shape.
    #[arg(long, default_value_os_t = RobustnessConfig::default().mesh)]
    pub mesh: PathBuf,
    #[command(flatten)]
    pub quick: cmdline::Quick,
    #[command(flatten)]
    pub seed: cmdline::Seed,
    /// Who renders the targets: `volpath` (ours), `mitsuba` (Mitsuba 3's volpath through
    /// `--mitsuba-script`, an independent renderer), or both (`volpath,mitsuba`). Default: ours,
    /// and Mitsuba's too when the script finds Mitsuba 3 (not with `--quick`).
    #[arg(long, value_delimiter = ',')]
    pub targets: Option<Vec<Targets>>,
    /// The script that renders a dataset's views with Mitsuba 3 (`pip install mitsuba numpy`;
    /// on Debian also `apt-get install libllvm19`).
    #[arg(long, default_value_os_t = RobustnessConfig::default().mitsuba_script)]
    pub mitsuba_script: PathBuf,
    /// The Python interpreter (with Mitsuba 3) that runs `--mitsuba-script`.
    #[arg(long = "mitsuba-python", default_value_os_t = RobustnessConfig::default().python)]
    pub python: PathBuf,
    /// Recover every case also with Mitsuba 3's differentiable `prbvolpath`
    /// (`tools/mitsuba/prb_optimize.py`, run by --mitsuba-python) for N iterations from the same
    /// start at the same samples per pixel, and set its time to an accurate answer beside the
    /// defaults'.
    #[arg(help_heading = cmdline::RESEARCH_OPTIONS, long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..))]
    pub prb_iterations: Option<u32>,
    /// PRB's learning rates decay as `optimize`'s do (×0.85 every 50 iterations) instead of
    /// staying constant.
    #[arg(help_heading = cmdline::RESEARCH_OPTIONS, long, requires = "prb_iterations")]
    pub prb_decay: bool,
    #[command(flatten)]
    pub jobs: super::JobArgs,
}

impl RobustnessArgs {
    /// The suite's settings.
    pub fn config(&self) -> RobustnessConfig {
        RobustnessConfig {
            out: self.out.to_path_buf(),
            views: *self.views,
            res: *self.res,
            target_spp: self.target_spp,
            model: self.model,
            budget: self.budget.budget(),
            refine: self.refine,
            refine_spp: self.refine_spp,
            free_g: self.free.contains(&FreeParam::G),
            free_light_scale: self.free.contains(&FreeParam::LightScale)
                || self.free.contains(&FreeParam::LightScaleRgb),
            light_scale_per_channel: self.free.contains(&FreeParam::LightScaleRgb),
            init_g: self.init_g,
            init_light_scale: self.init_light_scale,
            // The suite's meshes are exact.
            mesh_error: None,
            seeds: self.seeds,
            suite: self.suite,
            cases: self.cases.clone(),
            mesh: self.mesh.clone(),
            quick: *self.quick,
            seed: *self.seed,
            targets: self.targets.clone(),
            mitsuba_script: self.mitsuba_script.clone(),
            python: self.python.clone(),
            prb_iterations: self.prb_iterations,
            prb_decay: self.prb_decay,
            jobs: self.jobs.jobs(),
        }
    }
}
