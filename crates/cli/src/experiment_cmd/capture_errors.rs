//! The options of the capture-errors experiment.

use std::path::PathBuf;

use clap::Args;
use experiment::capture_errors::CaptureErrorsConfig;

use cmdline::optimize::IterationArgs;

#[derive(Args)]
#[command(mut_arg(
    "out",
    cmdline::groups::default_and_help(CaptureErrorsConfig::default().out.display().to_string(), "Output folder (datasets, runs, tables)")
))]
#[command(mut_arg(
    "seed",
    cmdline::groups::help("Seed of the media, renders, perturbations and runs")
))]
#[command(mut_arg("views", cmdline::groups::default_and_help(CaptureErrorsConfig::default().views.to_string(), "Views per dataset")))]
#[command(mut_arg(
    "res",
    cmdline::groups::default_and_help(CaptureErrorsConfig::default().res.to_string(), "Image width and height")
))]
#[command(mut_arg("quick", cmdline::groups::help(super::SUITE_QUICK_HELP)))]
pub struct CaptureErrorsArgs {
    #[command(flatten)]
    pub out: cmdline::Output,
    #[command(flatten)]
    pub views: cmdline::Views,
    #[command(flatten)]
    pub res: cmdline::Resolution,
    /// Samples per pixel of the volumetric target renders.
    #[arg(long, default_value_t = CaptureErrorsConfig::default().target_spp)]
    pub target_spp: u32,
    #[command(flatten)]
    pub budget: IterationArgs,
    /// The robustness suite's cases to perturb (names as in its table, e.g. `flash-15-torus`).
    #[arg(long, value_delimiter = ',', default_values_t = CaptureErrorsConfig::default().cases)]
    pub cases: Vec<String>,
    /// Only these perturbations (names as in the CSV, e.g. `camera-rotation-0.5deg`,
    /// `light-intensity-x0.9`, `white-balance-r1.1-b0.9`, `mesh-decimated-x50`, `srgb-8bit`,
    /// `sensor-noise-iso3200`);
    /// default: all. The unperturbed run is always made.
    #[arg(long, value_delimiter = ',')]
    pub perturbations: Option<Vec<String>>,
    /// Recover a factor on the lights besides σ_t and α in every run (`optimize --free
    /// light-scale`), the remedy for an intensity the capture does not know.
    #[arg(long)]
    pub free_light_scale: bool,
    /// Recover one factor per channel on the lights in every run (`optimize --free
    /// light-scale-rgb`), the remedy for a white balance the capture does not know.
    #[arg(long)]
    pub free_light_scale_rgb: bool,
    /// State the mesh's accuracy in every run (`optimize --mesh-error`): the intervals include
    /// what a mesh error of that size moves the estimate by, to first order (on a mesh with
    /// 0.2 % noise, a third to a half of its actual effect).
    #[arg(long, value_name = "FRACTION", value_parser = cmdline::optimize::parse_mesh_error)]
    pub mesh_error: Option<f64>,
    /// The mesh file of the robustness suite's third shape.
    #[arg(long, default_value_os_t = CaptureErrorsConfig::default().mesh)]
    pub mesh: PathBuf,
    #[command(flatten)]
    pub quick: cmdline::Quick,
    #[command(flatten)]
    pub seed: cmdline::Seed,
    #[command(flatten)]
    pub jobs: super::JobArgs,
}

impl CaptureErrorsArgs {
    /// The experiment's settings.
    pub fn config(&self) -> CaptureErrorsConfig {
        CaptureErrorsConfig {
            out: self.out.to_path_buf(),
            views: *self.views,
            res: *self.res,
            target_spp: self.target_spp,
            budget: self.budget.budget(),
            cases: self.cases.clone(),
            perturbations: self.perturbations.clone(),
            free_light_scale: self.free_light_scale || self.free_light_scale_rgb,
            light_scale_per_channel: self.free_light_scale_rgb,
            mesh_error: self.mesh_error,
            mesh: self.mesh.clone(),
            quick: *self.quick,
            seed: *self.seed,
            jobs: self.jobs.jobs(),
        }
    }
}
