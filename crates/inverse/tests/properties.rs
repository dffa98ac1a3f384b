//! Property tests (proptest): every setting of a run survives its JSON form (the form
//! `result.json` and the checkpoints record, and that a resumed run is compared against).

use bssrdf::diff::{Estimator, Loss};
use inverse::forward::ModelChoice;
use inverse::optimize::OptimizeConfig;
use inverse::params::{Parameterisation, Params};
use proptest::prelude::*;

fn config() -> impl Strategy<Value = OptimizeConfig> {
    (
        (
            prop::sample::select(vec![
                Estimator::Ours,
                Estimator::OursAlphaOffsets,
                Estimator::Naive,
                Estimator::Fd,
            ]),
            1u32..100_000,
            1u32..4096,
            1usize..64,
            prop::option::of(1u32..2048),
            prop::sample::select(vec![Loss::L2, Loss::L1]),
            any::<(bool, bool, bool, bool)>(),
        ),
        (
            1e-6f32..1.0,
            1e-6f32..1.0,
            0.1f32..1.0,
            0u32..1000,
            0u32..100,
            1e-4f32..0.2,
            any::<u64>(),
            0u32..1000,
        ),
        (
            prop::array::uniform3(1e-3f64..1e4),
            prop::array::uniform3(0.0f64..0.99995),
            any::<(bool, bool, bool, bool)>(),
            1e-4f64..1.0,
            prop::option::of(prop::collection::vec(0usize..1000, 1..8)),
        ),
    )
        .prop_map(|(a, b, c)| {
            let mut o = OptimizeConfig {
                model: ModelChoice::Learned(a.0),
                ..OptimizeConfig::default()
            };
            (o.iterations, o.spp, o.views_per_iter, o.crop, o.loss) = (a.1, a.2, a.3, a.4, a.5);
            (
                o.two_renders,
                o.split_samples,
                o.fit_derivative,
                o.normalize_views,
            ) = a.6;
            (
                o.lr_sigma_t,
                o.lr_albedo,
                o.decay,
                o.decay_every,
                o.refit_every,
            ) = (b.0, b.1, b.2, b.3, b.4);
            (o.delta_rel, o.seed, o.albedo_warmup) = (b.5, b.6, b.7);
            o.init = Params {
                sigma_t: c.0,
                albedo: c.1,
                g: None,
                light_scale: None,
            };
            let (log, mono, fix_t, fix_a) = c.2;
            o.params.parameterisation = if log {
                Parameterisation::Log
            } else {
                Parameterisation::Scaled
            };
            (
                o.params.monochrome,
                o.params.fix_sigma_t,
                o.params.fix_albedo,
            ) = (mono, fix_t, fix_a);
            o.view_weight_floor = c.3;
            o.view_subset = c.4;
            o
        })
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 512,
        failure_persistence: None,
        // A fixed seed: the same inputs on every run (the tests are deterministic).
        rng_seed: proptest::test_runner::RngSeed::Fixed(4),
        ..ProptestConfig::default()
    })]

    /// JSON → value → JSON: the same settings, field for field.
    #[test]
    fn optimize_config_json_round_trip(cfg in config()) {
        let text = serde_json::to_string(&cfg).unwrap();
        let back: OptimizeConfig = serde_json::from_str(&text).unwrap();
        prop_assert_eq!(&back, &cfg);
        let pretty = serde_json::to_string_pretty(&cfg).unwrap();
        let back: OptimizeConfig = serde_json::from_str(&pretty).unwrap();
        prop_assert_eq!(back, cfg);
    }
}
