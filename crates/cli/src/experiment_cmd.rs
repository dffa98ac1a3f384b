//! The options of `translucent experiment …`: one subcommand per experiment, each turned into
//! the experiment library's settings in one conversion ([`ExperimentCommand::experiment`]).

use clap::{Args, Subcommand};
use experiment::Experiment;
use experiment::jobs::Jobs;

pub mod accuracy;
pub mod capture_errors;
pub mod renderers;
pub mod robustness;

/// `--quick`'s help in the suites' commands (robustness, capture errors), whose quick scale is
/// `RobustnessConfig::workload`'s.
const SUITE_QUICK_HELP: &str = "A small scale that finishes in seconds (6 views of 24², 8 spp targets, 12 iterations, coarse meshes): a smoke test of the pipeline, not a measurement";

/// The `--help` heading of the scheduler options.
const JOB_OPTIONS: &str = "Running the cases as separate jobs (a cluster's scheduler)";

/// `--list-jobs`, `--case`, `--assemble`.
#[derive(Args, Clone, Debug, Default)]
pub struct JobArgs {
    /// Print one self-contained command per case (this command with `--case NAME`) for a
    /// scheduler, e.g. a Slurm job array or HyperQueue, and run nothing.
    #[arg(help_heading = JOB_OPTIONS, long, conflicts_with_all = ["case", "assemble"])]
    pub list_jobs: bool,
    /// Run only the case NAME (as `--list-jobs` prints it) into the output folder, then
    /// tabulate every case finished so far.
    #[arg(help_heading = JOB_OPTIONS, long, value_name = "NAME")]
    pub case: Option<String>,
    /// Run nothing: tabulate the cases finished so far in the output folder.
    #[arg(help_heading = JOB_OPTIONS, long, conflicts_with = "case")]
    pub assemble: bool,
}

impl JobArgs {
    /// Which cases this invocation runs; a listing repeats the command as it was given.
    pub fn jobs(&self) -> Jobs {
        Jobs {
            list: self
                .list_jobs
                .then(|| std::env::args().filter(|a| a != "--list-jobs").collect()),
            case: self.case.clone(),
            assemble: self.assemble,
        }
    }
}

#[derive(Subcommand)]
pub enum ExperimentCommand {
    /// Accuracy of the recovered σ_t and α on volumetric-path-traced datasets (paper Table 1,
    /// Fig. 7): shapes × media, methods, random initialisations.
    Accuracy(Box<accuracy::AccuracyArgs>),
    /// `optimize`'s defaults on cases we did not tune on: twelve index-matched, isotropic ones
    /// (flash, fixed light, turntable, back-lit; 5, 15, 50 mean free paths; blob, torus, a mesh
    /// file) and nine with a smooth or rough dielectric boundary around a forward-scattering
    /// medium (up to 300 mean free paths): errors, 95 % intervals and their calibration,
    /// whether σ_t is determined, consistency, status.
    Robustness(Box<robustness::RobustnessArgs>),
    /// What a real capture's errors (camera and light poses, the light's intensity, a scanned
    /// mesh, 8-bit photos, sensor noise) do to a recovery with the defaults: shifts, intervals,
    /// status, and whether any run gives a confident wrong number.
    CaptureErrors(Box<capture_errors::CaptureErrorsArgs>),
    /// Seconds per iteration of every forward model × estimator at the paper's workload
    /// (256² × 32 spp; paper Table 1), beside the paper's figures; Mitsuba 3's PRB with
    /// `--mitsuba-python`.
    Timing(renderers::TimingArgs),
    /// Derivative images of the learned renderer's estimators (ours, naive) against central
    /// differences on a cone and a blob (paper Fig. 3 and 5): relative error of the summed
    /// derivative and per-pixel correlation.
    Gradients(renderers::GradientsArgs),
    /// The paper's comparison with the planar dipole (Fig. 6): ours, naive and the dipole on
    /// three shapes × two media; errors over iterations and re-renders side by side.
    Planar(accuracy::PlanarArgs),
    /// Random initialisations on one case (paper Fig. 7): the mean ± s.d. of the errors over
    /// the iterations, and every start's curve.
    Inits(accuracy::InitsArgs),
    /// σ_t alone with α fixed, grey medium (paper Fig. 8): ours at 32 spp against the
    /// volumetric baseline at 32 and 128 spp, at equal iterations and at equal time.
    Volumetric(renderers::VolumetricArgs),
    /// RGB σ_t and α (paper Fig. 9): ours against the volumetric baseline and, with
    /// `--mitsuba-python`, Mitsuba 3's PRB, by iterations and by time.
    Prb(renderers::PrbArgs),
}

impl ExperimentCommand {
    /// The experiment with its settings.
    pub fn experiment(&self) -> Experiment {
        match self {
            ExperimentCommand::Accuracy(a) => Experiment::Accuracy(Box::new(a.config())),
            ExperimentCommand::Robustness(a) => Experiment::Robustness(Box::new(a.config())),
            ExperimentCommand::CaptureErrors(a) => Experiment::CaptureErrors(Box::new(a.config())),
            ExperimentCommand::Timing(a) => Experiment::Timing(a.config()),
            ExperimentCommand::Gradients(a) => Experiment::Gradients(a.config()),
            ExperimentCommand::Planar(a) => Experiment::Planar(a.config()),
            ExperimentCommand::Inits(a) => Experiment::Inits(a.config()),
            ExperimentCommand::Volumetric(a) => Experiment::Volumetric(a.config()),
            ExperimentCommand::Prb(a) => Experiment::Prb(a.config()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::{accuracy, capture_errors, renderers, robustness};
    use ::experiment as lib;
    use cmdline::arg_defaults;

    /// Every experiment's options default to its library settings' `Default`, the one place
    /// the defaults are written.
    #[test]
    fn every_experiment_defaults_to_its_library_settings() {
        assert_eq!(
            arg_defaults::<accuracy::AccuracyArgs>(&[]).config(),
            lib::accuracy::AccuracyConfig::default()
        );
        assert_eq!(
            arg_defaults::<accuracy::InitsArgs>(&[]).config(),
            lib::inits::InitsConfig::default()
        );
        assert_eq!(
            arg_defaults::<accuracy::PlanarArgs>(&[]).config(),
            lib::planar::PlanarConfig::default()
        );
        assert_eq!(
            arg_defaults::<robustness::RobustnessArgs>(&[]).config(),
            lib::robustness::RobustnessConfig::default()
        );
        assert_eq!(
            arg_defaults::<capture_errors::CaptureErrorsArgs>(&[]).config(),
            lib::capture_errors::CaptureErrorsConfig::default()
        );
        assert_eq!(
            arg_defaults::<renderers::TimingArgs>(&[]).config(),
            lib::timing::TimingConfig::default()
        );
        assert_eq!(
            arg_defaults::<renderers::GradientsArgs>(&[]).config(),
            lib::gradients::GradientsConfig::default()
        );
        assert_eq!(
            arg_defaults::<renderers::VolumetricArgs>(&[]).config(),
            lib::volumetric::VolumetricConfig::default()
        );
        assert_eq!(
            arg_defaults::<renderers::PrbArgs>(&[]).config(),
            lib::prb::PrbConfig::default()
        );
    }
}
