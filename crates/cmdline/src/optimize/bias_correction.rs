//! The options of the parametric-bootstrap bias correction (`recovery::bias_correction`).

use clap::Args;

#[derive(Args, Clone, Copy, Debug)]
pub struct BiasCorrectionArgs {
    /// Skip the parametric-bootstrap bias correction of a learned-model run without refinement
    /// (`--refine 0`): the dataset is rendered again with the volumetric path tracer at the
    /// estimate (same views, lights, spp and seed), recovered with the same settings, and
    /// 2θ̂ − θ̂₂ in (ln σ_t, α) is reported, with the correction's size added to the 95 %
    /// intervals. It doubles the cost. (Not after a refinement, nor with `--model volpath`: the
    /// tracer is the simulator itself, with no bias to correct.)
    #[arg(help_heading = crate::RESEARCH_OPTIONS, long)]
    pub no_bias_correction: bool,
    /// The learned model alone with the parametric-bootstrap bias correction, instead of the
    /// volumetric refinement (`--refine 0`, whose correction is on unless
    /// --no-bias-correction).
    #[arg(help_heading = crate::RESEARCH_OPTIONS, long, conflicts_with = "no_bias_correction")]
    pub bias_correction: bool,
    /// Steps of the iterated correction: step k renders at the previous corrected medium
    /// θ_{k−1}, recovers θ̂_k from it and moves to θ_k = θ_{k−1} + θ̂ − θ̂_k; a bias of constant
    /// slope s shrinks by −s per step. Each step costs one volumetric render and one recovery.
    #[arg(help_heading = crate::RESEARCH_OPTIONS, long, default_value_t = inverse::bootstrap::DEFAULT_STEPS, value_parser = clap::value_parser!(u32).range(1..=8))]
    pub bias_correction_steps: u32,
    /// Samples per pixel of the simulated images (default: the dataset's own, else 64).
    #[arg(help_heading = crate::RESEARCH_OPTIONS, long, value_parser = clap::value_parser!(u32).range(1..))]
    pub bias_correction_spp: Option<u32>,
}

impl Default for BiasCorrectionArgs {
    fn default() -> Self {
        Self {
            no_bias_correction: false,
            bias_correction: false,
            bias_correction_steps: inverse::bootstrap::DEFAULT_STEPS,
            bias_correction_spp: None,
        }
    }
}

impl BiasCorrectionArgs {
    /// Whether the correction runs.
    pub fn enabled(&self) -> bool {
        !self.no_bias_correction
    }

    /// No correction (runs whose caller corrects).
    pub fn off() -> Self {
        Self {
            no_bias_correction: true,
            ..Self::default()
        }
    }

    /// The library's settings of the correction.
    pub fn settings(&self) -> recovery::settings::BiasCorrectionSettings {
        recovery::settings::BiasCorrectionSettings {
            correction: recovery::BiasCorrection {
                enabled: self.enabled(),
                steps: self.bias_correction_steps,
                spp: self.bias_correction_spp,
            },
            instead_of_refinement: self.bias_correction,
        }
    }
}
