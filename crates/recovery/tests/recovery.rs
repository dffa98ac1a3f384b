//! The recovery behind `optimize` as library code ([`recovery`]): a dataset folder
//! rendered by [`inverse::views::render_dataset`] in, `result.json` and the re-renders out; a
//! second call reuses the finished run; [`recovery::reuse::finished`] reads it without
//! running, and only for the settings it was made with; a folder holding a run made with other
//! settings is refused, naming the setting.

use geometry::{Shape, Vec3};
use indicatif::ProgressBar;
use inverse::views::{RenderOpts, render_dataset};
use recovery::{self, RecoveryConfig, RecoveryError, Silent};
use scene::scene_file::{RenderInfo, SceneDesc, ViewDesc};
use scene::{Camera, Medium, MeshSource, PointLight};

fn tiny_dataset(dir: &std::path::Path) {
    let views = [Vec3::new(0.0, 0.3, 2.0), Vec3::new(1.5, 0.5, -1.2)]
        .into_iter()
        .map(|o| ViewDesc {
            camera: Camera::look_at(o, Vec3::ZERO, Vec3::Y, 30.0, 12, 12),
            light: PointLight {
                position: o + Vec3::new(0.8, 0.8, 0.0),
                intensity: [10.0; 3],
            },
        })
        .collect();
    let desc = SceneDesc {
        mesh: MeshSource::Shape(Shape::Sphere {
            radius: 0.5,
            subdivisions: 3,
        }),
        medium: Medium {
            sigma_t: [60.0; 3],
            albedo: [0.9, 0.85, 0.8],
            g: scene::Anisotropy::uniform(0.0),
            eta: 1.0,
            roughness: 0.0,
        },
        views,
        render: RenderInfo::default(),
        path: dir.join("dataset.json"),
        length_unit: None,
    };
    let opts = RenderOpts {
        spp: 4,
        seed: 1,
        max_depth: 16,
        shadow: Default::default(),
    };
    render_dataset(desc, opts, dir, false, &ProgressBar::hidden()).unwrap();
}

#[test]
fn a_recovery_runs_from_its_config_and_is_reused_only_with_its_settings() {
    let t = tempfile::tempdir().unwrap();
    let data = t.path().join("data");
    tiny_dataset(&data);
    let mut cfg = RecoveryConfig::new(
        data.clone(),
        t.path().join("run"),
        recovery::settings::DatasetFacts::at_depth(16),
    );
    cfg.optimize = cfg.optimize.with_iterations(4);
    cfg.optimize.spp = 2;
    cfg.final_spp = 1;
    cfg.uncertainty.views = 0;
    cfg.consistency_views = 0;
    // The defaults refine: the tracer at the dataset's depth for the last half.
    assert_eq!(cfg.optimize.refine_iterations, 2);
    assert_eq!(cfg.optimize.volpath_max_depth, Some(16));
    assert!(recovery::reuse::finished(&cfg).is_none());

    let first = recovery::run_or_reuse(&cfg, &Silent, "tiny").unwrap();
    let result = recovery::reuse::read_json(&cfg.out.join("result.json")).unwrap();
    assert_eq!(result["status"], "ok");
    assert_eq!(result["iterations"], 4);
    assert!(cfg.out.join("final/contact-sheet.png").is_file());
    assert!(
        first
            .estimate
            .sigma_t
            .iter()
            .all(|s| s.is_finite() && *s > 0.0)
    );

    let again = recovery::run_or_reuse(&cfg, &Silent, "tiny").unwrap();
    assert_eq!(again.estimate.sigma_t, first.estimate.sigma_t);
    let read = recovery::reuse::finished(&cfg).expect("finished");
    assert_eq!(read.estimate.albedo, first.estimate.albedo);

    let mut other = cfg.clone();
    other.optimize.seed += 1;
    assert!(recovery::reuse::finished(&other).is_none());
    match recovery::run_or_reuse(&other, &Silent, "tiny") {
        Err(RecoveryError::Invalid(msg)) => {
            assert!(
                msg.contains("other settings") && msg.contains("seed"),
                "{msg}"
            )
        }
        r => panic!("a run with another seed in the same folder: {r:?}"),
    }
}
