//! Adding an estimator is one file implementing [`SampleEstimator`] over the shared row: shown
//! with a stand-in that differentiates σ_t as `ours` does and leaves α alone (∂/∂α = 0), run
//! through the same row loop, accumulation and loss as the real ones.

use geometry::{Accel, Shape};
use glam::Vec3;
use scene::{Camera, Medium, PointLight};

use super::ours::Ours;
use super::row::{Sample, SampleEstimator, offset_row};
use super::{DiffSettings, Estimator, run};
use crate::render::{LearnedScene, LearnedSettings, RenderSettings, VertexFeatures, ViewRays};

/// σ_t by `ours`' offset pair; α held fixed.
struct SigmaOnly;

impl SampleEstimator for SigmaOnly {
    const PAIR: bool = true;

    fn offset_sets(moving: bool) -> usize {
        Ours::offset_sets(moving)
    }

    fn d_sigma_t(s: &Sample) -> f32 {
        Ours::d_sigma_t(s)
    }

    fn d_albedo(_: &Sample) -> Option<f32> {
        Some(0.0)
    }
}

/// The stand-in's value and ∂/∂σ_t images are `ours`' bit for bit (same row, same samples), its
/// ∂/∂α image is zero where `ours`' is not.
#[test]
fn a_new_estimator_is_one_file_over_the_shared_row() {
    let accel = Accel::new(
        Shape::Sphere {
            radius: 0.5,
            subdivisions: 3,
        }
        .build()
        .unwrap(),
    );
    let model = crate::model::shipped().unwrap();
    let medium = Medium {
        sigma_t: [20.0, 30.0, 40.0],
        albedo: [0.9, 0.8, 0.95],
        g: scene::Anisotropy::uniform(0.0),
        eta: 1.0,
        roughness: 0.0,
    };
    let features = VertexFeatures::fit(&accel, &medium, model.info().c19_quirk, 0).unwrap();
    let settings = LearnedSettings::default();
    let scene = LearnedScene::new(&accel, &model, &features, medium, settings).unwrap();
    let camera = Camera::look_at(Vec3::new(0.0, 0.3, 2.0), Vec3::ZERO, Vec3::Y, 32.0, 12, 12);
    let light = PointLight {
        position: Vec3::new(1.5, 0.5, 0.3),
        intensity: [2.0; 3],
    };
    let view = ViewRays::new(&scene, &camera, &light);
    let rs = RenderSettings {
        spp: 4,
        seed: 7,
        view: 0,
    };
    let ds = DiffSettings::default();
    assert_eq!(ds.estimator, Estimator::Ours);
    let images = |row| {
        run(&scene, &view, &rs, &ds, row, None, true, None)
            .unwrap()
            .images
            .unwrap()
    };
    let ours = images(Estimator::Ours.row());
    let toy = images(offset_row::<SigmaOnly>);
    assert_eq!(toy.value, ours.value);
    assert_eq!(toy.d_sigma_t, ours.d_sigma_t);
    assert!(toy.d_albedo.data.iter().flatten().all(|v| *v == 0.0));
    assert!(ours.d_albedo.data.iter().flatten().any(|v| *v != 0.0));
    assert!(ours.d_sigma_t.data.iter().flatten().any(|v| *v != 0.0));
}
