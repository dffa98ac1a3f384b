//! The options of the experiments that time and compare renderers: `timing`, `gradients`,
//! `volumetric` and `prb`.

use std::path::PathBuf;

use clap::Args;
use experiment::gradients::GradientsConfig;
use experiment::prb::PrbConfig;
use experiment::timing::TimingConfig;
use experiment::volumetric::VolumetricConfig;

#[derive(Args)]
#[command(mut_arg(
    "out",
    cmdline::groups::default_and_help(
        TimingConfig::default().out.display().to_string(),
        "Output folder (the dataset in OUT/data; timing.json, timing.md, timing.csv)"
    )
))]
#[command(mut_arg(
    "seed",
    cmdline::groups::default_and_help(TimingConfig::default().seed.to_string(), "Seed of the medium, the targets and the runs")
))]
#[command(mut_arg(
    "spp",
    cmdline::groups::default_and_help(TimingConfig::default().spp.to_string(), "Samples per pixel per iteration (the paper: 32)")
))]
#[command(mut_arg(
    "res",
    cmdline::groups::default_and_help(TimingConfig::default().res.to_string(), "Image width and height (the paper: 256)")
))]
#[command(mut_arg(
    "quick",
    cmdline::groups::help(
        "A smoke test in seconds (32², 4 spp, 3 iterations, coarse meshes): not a measurement"
    )
))]
pub struct TimingArgs {
    #[command(flatten)]
    pub out: cmdline::Output,
    /// Iterations per model × estimator (the first is not counted).
    #[arg(long, default_value_t = TimingConfig::default().iterations)]
    pub iterations: u32,
    #[command(flatten)]
    pub spp: cmdline::Spp,
    #[command(flatten)]
    pub res: cmdline::Resolution,
    #[command(flatten)]
    pub seed: cmdline::Seed,
    /// A Python with Mitsuba 3 (e.g. `.mi/bin/python`): adds the PRB row.
    #[arg(long)]
    pub mitsuba_python: Option<PathBuf>,
    #[command(flatten)]
    pub quick: cmdline::Quick,
    /// All rows are one case (`timing`): their times compare only when measured on one machine.
    #[command(flatten)]
    pub jobs: super::JobArgs,
}

impl TimingArgs {
    /// The experiment's settings.
    pub fn config(&self) -> TimingConfig {
        TimingConfig {
            out: self.out.to_path_buf(),
            iterations: self.iterations,
            spp: *self.spp,
            res: *self.res,
            seed: *self.seed,
            mitsuba_python: self.mitsuba_python.clone(),
            quick: *self.quick,
            jobs: self.jobs.jobs(),
        }
    }
}

#[derive(Args)]
#[command(mut_arg("out", cmdline::groups::default(GradientsConfig::default().out.display().to_string())))]
#[command(mut_arg("seed", cmdline::groups::help("Seed of the renders")))]
#[command(mut_arg(
    "res",
    cmdline::groups::default_and_help(GradientsConfig::default().res.to_string(), "Image width and height")
))]
#[command(mut_arg(
    "spp",
    cmdline::groups::default_and_help(
        GradientsConfig::default().spp.to_string(),
        "Samples per pixel of the estimators' derivative renders (the differences: four times)"
    )
))]
#[command(mut_arg(
    "quick",
    cmdline::groups::help(
        "A smoke test in seconds (32², 4 spp, coarse meshes): not a measurement"
    )
))]
pub struct GradientsArgs {
    #[command(flatten)]
    pub out: cmdline::Output,
    #[command(flatten)]
    pub res: cmdline::Resolution,
    #[command(flatten)]
    pub spp: cmdline::Spp,
    #[command(flatten)]
    pub seed: cmdline::Seed,
    #[command(flatten)]
    pub quick: cmdline::Quick,
    #[command(flatten)]
    pub jobs: super::JobArgs,
}

impl GradientsArgs {
    /// The experiment's settings.
    pub fn config(&self) -> GradientsConfig {
        GradientsConfig {
            out: self.out.to_path_buf(),
            res: *self.res,
            spp: *self.spp,
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
        VolumetricConfig::default().out.display().to_string(),
        "Output folder (the dataset in OUT/data, runs in OUT/runs)"
    )
))]
#[command(mut_arg("seed", cmdline::groups::help("Seed of the renders and the runs")))]
#[command(mut_arg(
    "quick",
    cmdline::groups::help(
        "A smoke test in seconds (4 views of 32², 6 iterations, 2 and 8 spp, coarse meshes): not a measurement"
    )
))]
pub struct VolumetricArgs {
    #[command(flatten)]
    pub out: cmdline::Output,
    /// Iterations per run.
    #[arg(long, default_value_t = VolumetricConfig::default().iterations)]
    pub iterations: u32,
    #[command(flatten)]
    pub seed: cmdline::Seed,
    #[command(flatten)]
    pub quick: cmdline::Quick,
    #[command(flatten)]
    pub jobs: super::JobArgs,
}

impl VolumetricArgs {
    /// The experiment's settings.
    pub fn config(&self) -> VolumetricConfig {
        VolumetricConfig {
            out: self.out.to_path_buf(),
            iterations: self.iterations,
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
        PrbConfig::default().out.display().to_string(),
        "Output folder (the dataset in OUT/data, runs in OUT/runs)"
    )
))]
#[command(mut_arg(
    "seed",
    cmdline::groups::default_and_help(PrbConfig::default().seed.to_string(), "Seed of the medium, the renders and the runs")
))]
#[command(mut_arg(
    "quick",
    cmdline::groups::help(
        "A smoke test in seconds (4 views of 32², 6 iterations, 2 spp, coarse meshes): not a measurement"
    )
))]
pub struct PrbArgs {
    #[command(flatten)]
    pub out: cmdline::Output,
    /// Iterations per run.
    #[arg(long, default_value_t = PrbConfig::default().iterations)]
    pub iterations: u32,
    #[command(flatten)]
    pub seed: cmdline::Seed,
    /// A Python with Mitsuba 3 (e.g. `.mi/bin/python`): adds the PRB run.
    #[arg(long)]
    pub mitsuba_python: Option<PathBuf>,
    #[command(flatten)]
    pub quick: cmdline::Quick,
    #[command(flatten)]
    pub jobs: super::JobArgs,
}

impl PrbArgs {
    /// The experiment's settings.
    pub fn config(&self) -> PrbConfig {
        PrbConfig {
            out: self.out.to_path_buf(),
            iterations: self.iterations,
            seed: *self.seed,
            mitsuba_python: self.mitsuba_python.clone(),
            quick: *self.quick,
            jobs: self.jobs.jobs(),
        }
    }
}
