//! The forward models behind [`inverse::forward`]: each model accepts only its own estimators,
//! with an error naming them; the volumetric path tracer and the planar dipole as the model of
//! the loop (the baselines), with each of their estimators, give a loss gradient that points
//! back to the truth on targets they rendered, and their view renderers' images are their
//! plain renders.

use crate::common;

use std::path::Path;

use bssrdf::nn::ShapeAdaptiveModel;
use bssrdf::render::RenderSettings;
use dipole::{DipoleScene, DipoleView};
use geometry::Vec3;
use inverse::forward::{ModelChoice, ModelKind, ModelSpec, TracerEstimator};
use inverse::optimize::{OptimizeConfig, Optimizer, TargetView};
use inverse::params::Params;
use scene::{Camera, Image, Medium, PointLight};
use volpath::{VolpathScene, VolpathSettings};

fn shipped() -> ShapeAdaptiveModel {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models/translucent-v2.safetensors");
    bssrdf::model::load(&p).unwrap()
}

#[test]
fn each_model_accepts_only_its_own_estimators() {
    for model in ModelKind::ALL {
        for name in model.estimators() {
            let c = OptimizeConfig {
                model: ModelChoice::new(model, Some(name)).unwrap(),
                refine_iterations: 0,
                ..OptimizeConfig::default()
            };
            assert!(c.check().is_ok(), "{model} × {name}");
            // The pair reads back from the configuration's JSON.
            let back: OptimizeConfig =
                serde_json::from_value(serde_json::to_value(&c).unwrap()).unwrap();
            assert_eq!(back.model, c.model);
        }
    }
    let e = ModelChoice::new(ModelKind::Learned, Some("ad"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("learned") && e.contains("ours, ours-alpha-offsets, naive, fd"),
        "{e}"
    );
    for model in [ModelKind::Volpath, ModelKind::Dipole] {
        for m in ["ours", "naive"] {
            let e = ModelChoice::new(model, Some(m)).unwrap_err().to_string();
            assert!(e.contains(model.name()) && e.contains("ad, fd"), "{e}");
        }
    }
    // A configuration file pairing a model with another's estimator is refused on reading.
    let mut json = serde_json::to_value(OptimizeConfig::default()).unwrap();
    json["model"] = "volpath".into();
    let e = serde_json::from_value::<OptimizeConfig>(json)
        .unwrap_err()
        .to_string();
    assert!(e.contains("volpath model has no estimator \"ours\""), "{e}");
    // Files written before the option read as the learned model, and the learned model's
    // settings serialise as before (no `model` key).
    let json = serde_json::to_value(OptimizeConfig::default()).unwrap();
    assert!(json.get("model").is_none() && json.get("volpath_max_depth").is_none());
    assert_eq!("volpath".parse::<ModelKind>().unwrap(), ModelKind::Volpath);
    assert_eq!("dipole".parse::<ModelKind>().unwrap(), ModelKind::Dipole);
    let e = "photon".parse::<ModelKind>().unwrap_err();
    assert!(e.contains("learned, volpath, dipole"), "{e}");
}

struct Setup {
    accel: geometry::Accel,
    views: Vec<(Camera, PointLight)>,
    targets: Vec<Image>,
    truth: Medium,
}

fn setup(model: ModelKind) -> Setup {
    let accel = common::sphere(0.5);
    let truth = Medium {
        sigma_t: [3.0, 4.0, 6.0],
        albedo: [0.9, 0.85, 0.8],
        g: scene::Anisotropy::uniform(0.0),
        eta: 1.0,
        roughness: 0.0,
    };
    let views: Vec<(Camera, PointLight)> = [Vec3::new(0.0, 0.3, 2.0), Vec3::new(1.5, 0.5, -1.2)]
        .into_iter()
        .map(|o| {
            (
                Camera::look_at(o, Vec3::ZERO, Vec3::Y, 30.0, 20, 20),
                PointLight {
                    position: Vec3::new(0.4, 0.3, -1.4),
                    intensity: [10.0; 3],
                },
            )
        })
        .collect();
    let settings = VolpathSettings::default();
    let targets = views
        .iter()
        .enumerate()
        .map(|(i, (c, l))| {
            let rs = RenderSettings {
                spp: 512,
                seed: 99,
                view: i as u64,
            };
            if model == ModelKind::Dipole {
                let scene = DipoleScene::new(&accel, truth).unwrap();
                return dipole::render_image(&scene, &DipoleView::new(&accel, c, l), &rs);
            }
            let scene = VolpathScene {
                accel: &accel,
                medium: truth,
                light: Some(*l),
                environment: None,
                light_bins: None,
            };
            volpath::render_image(&scene, &settings, c, &rs, None)
        })
        .collect();
    Setup {
        accel,
        views,
        targets,
        truth,
    }
}

/// On a sphere of 1.5–3 mean free paths radius, lit from behind one of the two views, with α at
/// the truth and σ_t twice too high (half too low), the model's loss gradient in σ_t on targets
/// it rendered is positive (negative) in every channel, by more than 4 standard errors of its
/// mean over `iterations` iterations (each its own view and random numbers); and the loop's
/// re-render is the model's plain image.
fn gradient_points_to_the_truth(choice: ModelChoice, iterations: u32) {
    let model_kind = choice.kind();
    let s = setup(model_kind);
    let model = shipped();
    let targets: Vec<TargetView> = s
        .views
        .iter()
        .zip(&s.targets)
        .map(|((c, l), img)| TargetView {
            camera: c,
            light: l,
            image: img,
        })
        .collect();
    let config = OptimizeConfig {
        model: choice,
        spp: 16,
        refine_iterations: 0,
        ..OptimizeConfig::default()
    };
    let truth = Params::of(&s.truth);
    let opt = Optimizer::new(config, &s.accel, Some(&model), s.truth, targets).unwrap();
    for (factor, sign) in [(2.0, 1.0), (0.5, -1.0)] {
        let p = Params {
            sigma_t: truth.sigma_t.map(|v| v * factor),
            ..truth
        };
        let g: Vec<[f64; 3]> = (0..iterations)
            .map(|k| opt.gradient(k, &p).unwrap().d_sigma_t)
            .collect();
        for c in 0..3 {
            let n = g.len() as f64;
            let m = g.iter().map(|v| v[c]).sum::<f64>() / n;
            let se = (g.iter().map(|v| (v[c] - m).powi(2)).sum::<f64>() / (n - 1.0) / n).sqrt();
            assert!(
                sign * m > 4.0 * se,
                "{model_kind} × {}: σ_t × {factor}: ∂ℓ/∂σ_t of channel {c} = {m} ± {se}",
                choice.estimator_name()
            );
        }
    }
    // The loop's re-render is the model's plain image.
    let rs = RenderSettings {
        spp: 4,
        seed: 5,
        view: 1,
    };
    let (c, l) = &s.views[1];
    let img = opt.render(&truth, c, l, &rs).unwrap();
    let plain = if model_kind == ModelKind::Dipole {
        let scene = DipoleScene::new(&s.accel, s.truth).unwrap();
        dipole::render_image(&scene, &DipoleView::new(&s.accel, c, l), &rs)
    } else {
        let scene = VolpathScene {
            accel: &s.accel,
            medium: s.truth,
            light: Some(*l),
            environment: None,
            light_bins: None,
        };
        volpath::render_image(&scene, &VolpathSettings::default(), c, &rs, None)
    };
    assert_eq!(img.data, plain.data);
}

#[test]
fn the_volumetric_model_s_gradient_points_to_the_truth() {
    gradient_points_to_the_truth(ModelChoice::Volpath(TracerEstimator::Ad), 40);
}

#[test]
fn the_volumetric_model_s_differences_point_to_the_truth() {
    gradient_points_to_the_truth(ModelChoice::Volpath(TracerEstimator::Fd), 40);
}

#[test]
fn the_dipole_s_gradient_points_to_the_truth() {
    gradient_points_to_the_truth(ModelChoice::Dipole(TracerEstimator::Ad), 40);
}

#[test]
fn the_dipole_s_differences_point_to_the_truth() {
    // The differences move the probe positions with σ_t: noisier than `ad` per iteration.
    gradient_points_to_the_truth(ModelChoice::Dipole(TracerEstimator::Fd), 120);
}

/// A pixel left out of the measurement (a photo's saturated or masked-out pixel): every model
/// renders it black and its derivatives zero, and renders every other pixel as without the mask
/// (the tracer and the dipole bit for bit); so whatever the target holds there, the loss
/// gradient is the same.
#[test]
fn every_model_leaves_unmeasured_pixels_out() {
    let model = shipped();
    for choice in [
        ModelChoice::default(),
        ModelChoice::Volpath(TracerEstimator::Ad),
        ModelChoice::Dipole(TracerEstimator::Ad),
    ] {
        let kind = choice.kind();
        let s = setup(kind);
        let (w, h) = (20u32, 20u32);
        // Out: a block over the object's middle and every 7th pixel.
        let bits = (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                !((6..12).contains(&x) && (8..14).contains(&y)) && i % 7 != 0
            })
            .collect();
        let mask = std::sync::Arc::new(scene::image::PixelMask {
            width: w,
            height: h,
            bits,
        });
        let masked: Vec<Camera> = s
            .views
            .iter()
            .map(|(c, _)| Camera {
                mask: Some(mask.clone()),
                ..c.clone()
            })
            .collect();
        // Targets: the renders, with a bright background where the mask leaves pixels out,
        // and the same with zeros there.
        let garbage: Vec<Image> = s
            .targets
            .iter()
            .map(|t| {
                let mut g = t.clone();
                for (i, p) in g.data.iter_mut().enumerate() {
                    if !mask.bits[i] {
                        *p = [5.0, 0.3, 2.0];
                    }
                }
                g
            })
            .collect();
        let zeroed: Vec<Image> = s
            .targets
            .iter()
            .map(|t| {
                let mut z = t.clone();
                z.apply_mask(&mask);
                z
            })
            .collect();
        let config = OptimizeConfig {
            model: choice,
            spp: 8,
            refine_iterations: 0,
            ..OptimizeConfig::default()
        };
        fn views<'a>(
            cams: &'a [Camera],
            views: &'a [(Camera, PointLight)],
            targets: &'a [Image],
        ) -> Vec<TargetView<'a>> {
            cams.iter()
                .zip(views)
                .zip(targets)
                .map(|((c, (_, l)), img)| TargetView {
                    camera: c,
                    light: l,
                    image: img,
                })
                .collect()
        }
        let a = Optimizer::new(
            config.clone(),
            &s.accel,
            Some(&model),
            s.truth,
            views(&masked, &s.views, &garbage),
        );
        let b = Optimizer::new(
            config.clone(),
            &s.accel,
            Some(&model),
            s.truth,
            views(&masked, &s.views, &zeroed),
        );
        let (a, b) = (a.unwrap(), b.unwrap());
        let p = Params::of(&Medium {
            sigma_t: s.truth.sigma_t.map(|v| v * 2.0),
            ..s.truth
        });
        for k in 0..3 {
            let (ga, gb) = (a.gradient(k, &p).unwrap(), b.gradient(k, &p).unwrap());
            assert_eq!(
                (ga.d_sigma_t, ga.d_albedo),
                (gb.d_sigma_t, gb.d_albedo),
                "{kind}"
            );
            assert!(
                ga.d_sigma_t.iter().all(|g| *g != 0.0),
                "{kind}: {:?}",
                ga.d_sigma_t
            );
        }
        let rs = RenderSettings {
            spp: 16,
            seed: 5,
            view: 0,
        };
        let (c, l) = &s.views[0];
        let full = a.render(&p, c, l, &rs).unwrap();
        let part = a.render(&p, &masked[0], l, &rs).unwrap();
        let lit = full
            .data
            .iter()
            .filter(|v| v.iter().any(|c| *c > 0.0))
            .count();
        assert!(lit > 40, "{kind}: {lit} lit pixels");
        for (i, (f, m)) in full.data.iter().zip(&part.data).enumerate() {
            if !mask.bits[i] {
                assert_eq!(*m, [0.0; 3], "{kind}: pixel {i}");
            } else if kind == ModelKind::Learned {
                // The network evaluates a row's samples as one batch: a smaller batch rounds
                // its sums in another order (the last bits only).
                for c in 0..3 {
                    assert!(
                        (m[c] - f[c]).abs() <= 1e-5 * f[c].abs(),
                        "pixel {i}: {m:?} {f:?}"
                    );
                }
            } else {
                assert_eq!(m, f, "{kind}: pixel {i}");
            }
        }
    }
}

/// A rough boundary's highlight: the learned renderer's surface term
/// (`bssrdf::render::Surface`, which it adds to every camera sample that meets the object) is
/// the tracer's. On a sphere of black medium (α = 0: nothing comes back from inside) behind a
/// rough dielectric (η 1.5, GGX α 0.3) lit from beside the camera, the tracer's image is the
/// surface's reflection alone; the surface term averaged over a 6 × 6 grid in every pixel
/// gives the same image up to the film's sampling (the tracer's 256 jittered samples): the
/// image sums within 0.5 % per channel (measured: 0.07 %).
#[test]
fn the_learned_model_reflects_a_rough_boundary_as_the_tracer_does() {
    let accel = common::sphere(0.5);
    let black = Medium {
        sigma_t: [10.0; 3],
        albedo: [0.0; 3],
        g: scene::Anisotropy::uniform(0.0),
        eta: 1.5,
        roughness: 0.3,
    };
    let camera = Camera::look_at(Vec3::new(0.0, 0.2, 2.0), Vec3::ZERO, Vec3::Y, 35.0, 24, 24);
    let light = PointLight {
        position: Vec3::new(0.8, 0.6, 1.6),
        intensity: [10.0, 5.0, 2.0],
    };
    let views = vec![scene::ViewDesc {
        camera: camera.clone(),
        light,
    }];
    let job = inverse::views::Job {
        accel: &accel,
        medium: &black,
        views: &views,
        spp: 256,
        seed: 3,
    };
    let pb = indicatif::ProgressBar::hidden();
    let tracer = ModelSpec::tracer(VolpathSettings::default());
    let traced = inverse::views::render(tracer, &job, false, &pb)
        .unwrap()
        .images
        .remove(0);

    let surface = bssrdf::render::Surface::of(&black).unwrap();
    let rays = camera.ray_gen();
    let n = 6;
    let mut sum = 0.0f64;
    for y in 0..camera.height {
        for x in 0..camera.width {
            for k in 0..n * n {
                let fx = x as f32 + ((k % n) as f32 + 0.5) / n as f32;
                let fy = y as f32 + ((k / n) as f32 + 0.5) / n as f32;
                let (o, d) = rays.ray(fx, fy);
                if let Some(hit) = accel.closest(o, d, 0.0, f32::INFINITY) {
                    sum += surface.reflection(&accel, &light, &hit, d) as f64;
                }
            }
        }
    }
    let sum = sum / (n * n) as f64;
    for c in 0..3 {
        let b = traced.data.iter().map(|p| p[c] as f64).sum::<f64>();
        let a = sum * light.intensity[c] as f64;
        assert!(b > 0.0, "the tracer's image is black in channel {c}");
        assert!(
            (a / b - 1.0).abs() < 5e-3,
            "channel {c}: the surface term's {a} against the tracer's {b}"
        );
    }
}
