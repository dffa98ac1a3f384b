//! `translucent optimize`: recover σ_t and α from a dataset's images by differentiable rendering
//! (Son et al. 2024 §5). The options ([`cmdline::optimize::OptimizeArgs`]) become an
//! [`recovery::RecoveryConfig`]; the recovery itself, its outputs and its checks are the
//! library's ([`recovery`]).

use anyhow::Result;
use cmdline::optimize::{OptimizeArgs, recovery_config};

pub fn run(a: &OptimizeArgs) -> Result<()> {
    Ok(recovery::run(&recovery_config(a)?, &cmdline::Terminal)?)
}

#[cfg(test)]
mod tests {
    use std::path::PathBuf;

    use inverse::optimize::OptimizeConfig;
    use inverse::params::Params;
    use recovery::RecoverySettings;

    use super::*;

    /// `optimize --dataset D` runs the library's defaults ([`RecoverySettings::default`],
    /// [`OptimizeConfig::default`]), and so
    /// do `demo` and `experiment accuracy`: every number they publish comes from the settings a
    /// user gets.
    #[test]
    fn optimize_demo_and_experiment_share_the_library_defaults() {
        let d = PathBuf::from("d");
        let o = OptimizeArgs::with_defaults(d.clone(), PathBuf::from("o"));
        let config_for =
            |s: &RecoverySettings| s.optimize_config(|| Ok(Default::default())).unwrap();
        // Every option's default is the library's.
        assert_eq!(o.settings(), RecoverySettings::default());
        assert_eq!(config_for(&o.settings()), OptimizeConfig::default());
        let demo = crate::demo::recovery_args(&cmdline::arg_defaults::<crate::demo::DemoArgs>(&[]));
        let expected = OptimizeConfig {
            seed: *demo.seed,
            ..OptimizeConfig::default().with_iterations(demo.budget.iterations)
        };
        assert_eq!(config_for(&demo.settings()), expected);
        let exp = experiment::accuracy::AccuracyConfig::default();
        let init = Params {
            sigma_t: [50.0; 3],
            albedo: [0.5; 3],
            g: None,
            light_scale: None,
        };
        // The estimator comparison runs the learned model alone (`--refine 0`), the rest as
        // the defaults.
        let run = experiment::accuracy::run_args(&exp, &d, &d, "ours", init);
        let expected = OptimizeConfig {
            seed: exp.seed,
            refine_iterations: 0,
            refine_restarts_moments: false,
            ..OptimizeConfig::default()
        };
        assert_eq!(config_for(&run.settings), expected);
        // The robustness suite, which measures the defaults, runs them unchanged.
        let suite = experiment::robustness::RobustnessConfig::default();
        let run = experiment::robustness::run_args(&suite, &d, &d, 0);
        let expected = OptimizeConfig {
            seed: suite.seed,
            ..OptimizeConfig::default()
        };
        assert_eq!(config_for(&run.settings), expected);
    }
}
