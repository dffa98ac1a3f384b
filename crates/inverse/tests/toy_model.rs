//! A model added from outside the library goes through `optimize`'s loop: a forward model is a
//! type implementing the three traits of [`inverse::forward`], handed to
//! [`Optimizer::with_forward`]. The stand-in here is a Lambertian slab of constant albedo seen
//! through an absorbing layer whose optical depth grows across the image,
//!
//!   I_c(x) = L_c · α_c · s(x) · (1 − e^{−σ_t,c·d(x)}) · (1 + g·u(x)),
//!   s(x) = 1/2 + y/(2H),  d(x) = 0.01 + 0.03·x/W,  u(x) = (x + y)/(W + H) − 1/2,
//!
//! L_c the light's intensity, with its exact derivatives (g tilts the image along its
//! diagonal); the loop recovers α and σ_t from its own images, and g or the light's scale as
//! well where they are free.

use crate::common;

use std::ops::ControlFlow;

use bssrdf::diff::DiffImages;
use bssrdf::render::RenderSettings;
use geometry::Vec3;
use inverse::forward::{ForwardModel, MediumRenderer, Progress, ViewRenderer};
use inverse::optimize::{InverseError, OptimizeConfig, Optimizer, Ran, TargetView};
use inverse::params::{OneOrRgb, Params};
use scene::{Camera, Image, Medium, PointLight};

/// The stand-in model: nothing to prepare, every view alike.
struct Lambertian;

struct At(Medium);

struct View<'v> {
    medium: &'v Medium,
    camera: &'v Camera,
    light: &'v PointLight,
}

impl ForwardModel for Lambertian {
    fn prepare(&mut self, _medium: &Medium) -> Result<(), InverseError> {
        Ok(())
    }

    fn at<'s>(&'s self, medium: Medium) -> Result<Box<dyn MediumRenderer + 's>, InverseError> {
        Ok(Box::new(At(medium)))
    }
}

impl MediumRenderer for At {
    fn view<'v>(&'v self, camera: &'v Camera, light: &'v PointLight) -> Box<dyn ViewRenderer + 'v> {
        Box::new(View {
            medium: &self.0,
            camera,
            light,
        })
    }
}

impl View<'_> {
    /// Per pixel and channel: (I, ∂I/∂σ_t, ∂I/∂α, ∂I/∂g).
    fn pixels(&self) -> [Image; 4] {
        let (w, h) = (self.camera.width, self.camera.height);
        let mut out = [(); 4].map(|_| Image::new(w, h));
        let g = self.medium.g.channels();
        for y in 0..h {
            for x in 0..w {
                let s = 0.5 + y as f32 / (2.0 * h as f32);
                let d = 0.01 + 0.03 * x as f32 / w as f32;
                let u = (x + y) as f32 / (w + h) as f32 - 0.5;
                let i = (y * w + x) as usize;
                for c in 0..3 {
                    let (a, st) = (self.medium.albedo[c], self.medium.sigma_t[c]);
                    let e = (-st * d).exp();
                    let tilt = (1.0 + g[c] * u) * self.light.intensity[c];
                    out[0].data[i][c] = a * s * (1.0 - e) * tilt;
                    out[1].data[i][c] = a * s * d * e * tilt;
                    out[2].data[i][c] = s * (1.0 - e) * tilt;
                    out[3].data[i][c] = a * s * (1.0 - e) * u * self.light.intensity[c];
                }
            }
        }
        out
    }
}

impl ViewRenderer for View<'_> {
    fn value(&self, _rs: &RenderSettings, _progress: Progress) -> Result<Image, InverseError> {
        let [value, ..] = self.pixels();
        Ok(value)
    }

    fn derivatives(
        &self,
        _rs: &RenderSettings,
        _progress: Progress,
    ) -> Result<DiffImages, InverseError> {
        let [value, d_sigma_t, d_albedo, d_g] = self.pixels();
        Ok(DiffImages {
            value,
            d_sigma_t,
            d_albedo,
            d_g: Some(d_g),
        })
    }
}

/// The medium of the toy runs (g and the light as each test sets them).
const TRUTH: Medium = Medium {
    sigma_t: [40.0, 70.0, 100.0],
    albedo: [0.7, 0.8, 0.9],
    g: scene::Anisotropy::uniform(0.0),
    eta: 1.0,
    roughness: 0.0,
};

/// The toy runs' camera and light (of intensity `intensity`).
fn view(intensity: f32) -> (Camera, PointLight) {
    let camera = Camera::look_at(Vec3::new(0.0, 0.0, 3.0), Vec3::ZERO, Vec3::Y, 30.0, 16, 16);
    let light = PointLight {
        position: Vec3::new(0.0, 2.0, 2.0),
        intensity: [intensity; 3],
    };
    (camera, light)
}

/// The stand-in's image of `medium` in the view.
fn target(medium: Medium, camera: &Camera, light: &PointLight) -> Image {
    let rs = RenderSettings {
        spp: 1,
        seed: 0,
        view: 0,
    };
    Lambertian
        .at(medium)
        .unwrap()
        .view(camera, light)
        .value(&rs, None)
        .unwrap()
}

/// The optimiser of the toy model on one view: `camera`, `light` (as stated) and `target`.
fn lambertian<'a>(
    config: OptimizeConfig,
    accel: &'a geometry::Accel,
    (camera, light, target): (&'a Camera, &'a PointLight, &'a Image),
    base: Medium,
) -> Optimizer<'a> {
    let targets = vec![TargetView {
        camera,
        light,
        image: target,
    }];
    Optimizer::with_forward(config, accel, Box::new(Lambertian), None, base, targets).unwrap()
}

/// A caller that breaks ends the run after that iteration with a checkpoint of it; the run then
/// goes on to its end where it stopped.
#[test]
fn a_caller_stops_the_loop_after_an_iteration_with_a_checkpoint() {
    let accel = common::sphere(0.5);
    let (camera, light) = view(1.0);
    let target = target(TRUTH, &camera, &light);
    let config = OptimizeConfig {
        iterations: 6,
        refine_iterations: 0,
        ..OptimizeConfig::default()
    };
    let mut opt = lambertian(config.clone(), &accel, (&camera, &light, &target), TRUTH);
    let dir = tempfile::tempdir().unwrap();
    let ck = dir.path().join("checkpoint.json");
    let mut seen = Vec::new();
    let ran = opt
        .run_until(Some((&ck, 100)), |r, _| {
            seen.push(r.iteration);
            if r.iteration == 2 {
                ControlFlow::Break(())
            } else {
                ControlFlow::Continue(())
            }
        })
        .unwrap();
    assert_eq!(ran, Ran::Stopped);
    assert_eq!(seen, [0, 1, 2]);
    assert_eq!(opt.history().len(), 3);
    let saved = inverse::optimize::Checkpoint::read(&ck).unwrap();
    assert_eq!(
        saved.history.len(),
        3,
        "the checkpoint holds the iterations run"
    );
    let ran = opt
        .run_until(None, |_, _| ControlFlow::Continue(()))
        .unwrap();
    assert_eq!(ran, Ran::Completed);
    assert_eq!(opt.history().len(), 6);
    // A break in the first iteration stops the run after it.
    let mut last = lambertian(config, &accel, (&camera, &light, &target), TRUTH);
    let ran = last.run_until(None, |_, _| ControlFlow::Break(())).unwrap();
    assert_eq!((ran, last.history().len()), (Ran::Stopped, 1));
}

#[test]
fn a_model_from_outside_the_library_runs_through_the_loop() {
    let accel = common::sphere(0.5);
    let truth = TRUTH;
    let (camera, light) = view(1.0);
    let target = target(truth, &camera, &light);
    let config = OptimizeConfig {
        iterations: 400,
        refine_iterations: 0,
        albedo_warmup: 0,
        lr_sigma_t: 0.03,
        lr_albedo: 0.02,
        ..OptimizeConfig::default()
    };
    let mut opt = lambertian(config, &accel, (&camera, &light, &target), truth);
    opt.run(None, |_, _| {}).unwrap();
    let p = opt.params();
    for c in 0..3 {
        let (st, a) = (truth.sigma_t[c] as f64, truth.albedo[c] as f64);
        assert!(
            (p.sigma_t[c] / st - 1.0).abs() < 0.02 && (p.albedo[c] - a).abs() < 0.01,
            "channel {c}: σ_t {} (truth {st}), α {} (truth {a})",
            p.sigma_t[c],
            p.albedo[c]
        );
    }
    // The history starts at the configuration's initial parameters, 50 and 0.5 (σ_t through
    // its logarithm, to rounding).
    let Params {
        sigma_t, albedo, ..
    } = opt.history()[0].params;
    assert!(
        sigma_t.iter().all(|s| (s / 50.0 - 1.0).abs() < 1e-6),
        "{sigma_t:?}"
    );
    assert_eq!(albedo, [0.5; 3]);
}

/// With g free the same loop recovers g as a seventh variable (`per_channel`: three, one per
/// channel, for a medium of a g per channel): each loss gradient is the exact derivative of
/// the loss (central differences of the noise-free model), the run lands on the truth, and the
/// intervals give each g its own.
fn recovers_g(truth_g: [f32; 3], per_channel: bool) {
    let accel = common::sphere(0.5);
    let truth = Medium {
        g: scene::Anisotropy(truth_g),
        ..TRUTH
    };
    let (camera, light) = view(1.0);
    let target = target(truth, &camera, &light);
    let mut config = OptimizeConfig {
        // Each channel's g, σ_t and α share one channel's images: their valley is flatter
        // than one g's, which all three channels set.
        iterations: if per_channel { 800 } else { 400 },
        refine_iterations: 0,
        albedo_warmup: 0,
        lr_sigma_t: 0.03,
        lr_albedo: 0.02,
        lr_g: 0.02,
        model: inverse::forward::ModelChoice::Volpath(inverse::forward::TracerEstimator::Ad),
        ..OptimizeConfig::default()
    };
    config.params.free_g = true;
    config.params.g_per_channel = per_channel;
    let targets = || {
        (0..3)
            .map(|_| TargetView {
                camera: &camera,
                light: &light,
                image: &target,
            })
            .collect::<Vec<_>>()
    };
    // The object states g = 0: the run starts there.
    let base = Medium {
        g: scene::Anisotropy::ISOTROPIC,
        ..truth
    };
    let mut opt =
        Optimizer::with_forward(config, &accel, Box::new(Lambertian), None, base, targets())
            .unwrap();
    let p0 = opt.params();
    let start = if per_channel {
        OneOrRgb::Rgb([0.0; 3])
    } else {
        OneOrRgb::One(0.0)
    };
    assert_eq!(p0.g, Some(start));
    let grad = opt.gradient(0, &p0).unwrap();
    let d_g = grad.d_g.expect("the model gives ∂I/∂g");
    let h = 1e-3;
    let loss = |g: OneOrRgb<f64>| opt.gradient(0, &Params { g: Some(g), ..p0 }).unwrap().loss;
    let moved = |c: usize, h: f64| match start {
        OneOrRgb::One(_) => OneOrRgb::One(h),
        OneOrRgb::Rgb(_) => OneOrRgb::Rgb(std::array::from_fn(|k| if k == c { h } else { 0.0 })),
    };
    let variables = if per_channel { 3 } else { 1 };
    for c in 0..variables {
        let fd = (loss(moved(c, h)) - loss(moved(c, -h))) / (2.0 * h);
        // One g's derivative is the sum of the channels' terms.
        let ad = if per_channel {
            d_g[c]
        } else {
            d_g.iter().sum()
        };
        assert!(
            (ad / fd - 1.0).abs() < 1e-3,
            "∂ℓ/∂g (variable {c}) {ad} against differences {fd}"
        );
    }

    opt.run(None, |_, _| {}).unwrap();
    let p = opt.params();
    let g = p.g.unwrap();
    assert_eq!(g.values().len(), variables);
    for c in 0..3 {
        let (st, a) = (truth.sigma_t[c] as f64, truth.albedo[c] as f64);
        assert!(
            (g.channel(c) - truth_g[c] as f64).abs() < 0.01,
            "channel {c}: g {} (truth {})",
            g.channel(c),
            truth_g[c]
        );
        assert!(
            (p.sigma_t[c] / st - 1.0).abs() < 0.03 && (p.albedo[c] - a).abs() < 0.015,
            "channel {c}: σ_t {} (truth {st}), α {} (truth {a})",
            p.sigma_t[c],
            p.albedo[c]
        );
    }
    assert!(opt.history().iter().skip(1).all(|r| r.d_g.is_some()));
    let u = opt
        .uncertainty(
            &inverse::uncertainty::UncertaintySettings {
                views: 3,
                ..Default::default()
            },
            &[],
        )
        .unwrap();
    let gu = u.g.expect("g has its interval");
    assert_eq!(gu.values().len(), variables);
    for c in 0..3 {
        let [lo, hi] = gu.channel(c).interval.expect("a finite interval");
        let g = g.channel(c);
        assert!(lo <= g && g <= hi && hi - lo < 0.2, "g {g} in [{lo}, {hi}]");
    }
    let json = u.to_json();
    let interval = &json["interval95"]["g"];
    if per_channel {
        assert_eq!(interval.as_array().map(Vec::len), Some(3));
        assert!(interval[2].is_array(), "{interval}");
    } else {
        assert!(interval.is_array() && interval[0].is_number(), "{interval}");
    }
}

#[test]
fn a_free_g_is_recovered_through_the_same_loop() {
    recovers_g([0.4; 3], false);
}

#[test]
fn a_g_per_channel_is_recovered_through_the_same_loop() {
    recovers_g([0.2, 0.4, 0.6], true);
}

/// A light of unknown strength: the targets were made with a light `factor` times the stated
/// one per channel, and the run, with the light scale free (`per_channel`: one factor per
/// channel) and α held at its truth (in this model α and the light multiply alike, so the
/// images cannot tell them apart), recovers k and σ_t; its loss gradient in each ln k is the
/// derivative of the loss. Each channel's σ_t then rests on the curvature of 1 − e^(−σ_t·d)
/// alone, a shallow valley in blue (σ_t·d up to 4), so the steps do not decay; k moves in
/// the second half of the run.
fn recovers_light_scale(factor: [f32; 3], per_channel: bool) {
    let accel = common::sphere(0.5);
    let truth = TRUTH;
    let (camera, stated) = view(1.0);
    let bright = PointLight {
        intensity: factor,
        ..stated
    };
    let target = target(truth, &camera, &bright);
    let mut config = OptimizeConfig {
        iterations: 2000,
        refine_iterations: 0,
        albedo_warmup: 0,
        lr_sigma_t: 0.03,
        init: Params::new(
            truth.sigma_t.map(|s| 0.8 * s as f64),
            truth.albedo.map(f64::from),
        ),
        decay: 1.0,
        ..OptimizeConfig::default()
    };
    config.params.free_light_scale = true;
    config.params.light_scale_per_channel = per_channel;
    config.params.fix_albedo = true;
    let mut opt = lambertian(config, &accel, (&camera, &stated, &target), truth);
    let p0 = opt.params();
    assert_eq!((0..3).map(|c| p0.light_scale_of(c)).sum::<f64>(), 3.0);
    let grad = opt.gradient(0, &p0).unwrap();
    let d = grad
        .d_ln_light_scale
        .expect("every model's gradient has ∂ℓ/∂ln k");
    let h = 1e-3;
    for c in 0..3 {
        let loss = |ln_k: f64| {
            let mut k = [1.0; 3];
            k[c] = ln_k.exp();
            let p = Params {
                light_scale: Some(OneOrRgb::Rgb(k)),
                ..p0
            };
            opt.gradient(0, &p).unwrap().loss
        };
        let fd = (loss(h) - loss(-h)) / (2.0 * h);
        assert!(
            (d[c] / fd - 1.0).abs() < 1e-3,
            "∂ℓ/∂ln k_{c} {} against differences {fd}",
            d[c]
        );
    }
    opt.run(None, |_, _| {}).unwrap();
    let p = opt.params();
    for c in 0..3 {
        let (k, st) = (p.light_scale_of(c), truth.sigma_t[c] as f64);
        assert!(
            (k / factor[c] as f64 - 1.0).abs() < 0.01,
            "channel {c}: k {k}"
        );
        assert!(
            (p.sigma_t[c] / st - 1.0).abs() < 0.03,
            "channel {c}: σ_t {}",
            p.sigma_t[c]
        );
    }
    assert_eq!(
        p.light_scale.unwrap().values().len(),
        if per_channel { 3 } else { 1 }
    );
}

/// The light scale holds still while σ_t and α fit the images under the lights as stated (no
/// gradient, no step): without a refinement, the first half of the run, and never inside the
/// α-first iterations; then it moves.
#[test]
fn a_free_light_scale_waits_for_the_albedo() {
    let accel = common::sphere(0.5);
    let (camera, stated) = view(1.0);
    let target = target(
        TRUTH,
        &camera,
        &PointLight {
            intensity: [2.0; 3],
            ..stated
        },
    );
    let mut config = OptimizeConfig {
        iterations: 12,
        refine_iterations: 0,
        albedo_warmup: 4,
        init: Params::new([50.0; 3], [0.5; 3]),
        ..OptimizeConfig::default()
    };
    config.params.free_light_scale = true;
    let mut opt = lambertian(config, &accel, (&camera, &stated, &target), TRUTH);
    opt.run(None, |_, _| {}).unwrap();
    let h = opt.history();
    assert_eq!(opt.config().light_scale_start(), 6);
    for r in &h[..6] {
        assert_eq!(r.params.light_scale_of(0), 1.0, "iteration {}", r.iteration);
        assert!(r.d_ln_light_scale.is_none(), "iteration {}", r.iteration);
    }
    assert_ne!(h[6].params.albedo, h[0].params.albedo, "α moves meanwhile");
    assert!(h[6..].iter().all(|r| r.d_ln_light_scale.is_some()));
    assert!(
        opt.params().light_scale_of(0) > 1.0,
        "k moves towards 2 after the warm-up"
    );
    // With a refinement, k moves in it; α-first iterations beyond it hold k too.
    let refined = OptimizeConfig {
        iterations: 300,
        refine_iterations: 100,
        albedo_warmup: 30,
        ..OptimizeConfig::default()
    };
    assert_eq!(refined.light_scale_start(), 200);
    let long_warmup = OptimizeConfig {
        iterations: 12,
        refine_iterations: 0,
        albedo_warmup: 100,
        ..OptimizeConfig::default()
    };
    assert_eq!(long_warmup.light_scale_start(), 6);
}

#[test]
fn a_free_light_scale_is_recovered_through_the_same_loop() {
    recovers_light_scale([2.0; 3], false);
}

/// One factor per channel: the light's strength and the camera's white balance both unknown.
#[test]
fn a_per_channel_light_scale_is_recovered_through_the_same_loop() {
    recovers_light_scale([2.0, 1.0, 0.5], true);
}
