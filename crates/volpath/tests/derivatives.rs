//! The tracer's derivatives ∂I/∂σ_t, ∂I/∂α and ∂I/∂g ([`volpath::derivative`]) against
//! finite differences, per parameter and channel.
//!
//! The quantity is the mean radiance over camera rays aimed uniformly at a disk that covers a
//! sphere of medium (rays that miss count 0). Per sample i, one derivative path gives
//! Y_i = ∂L/∂θ_c, and the same random numbers at θ ± h give the central difference
//! D_i = (L_i(θ + h) − L_i(θ − h)) / 2h (common random numbers; every channel's parameter is
//! moved at once, which leaves each channel's expectation a function of its own parameter).
//! Both are i.i.d. over i, so the means and standard errors come from the samples themselves.
//! The test: |mean Y − mean D| ≤ 4.5·√(se_Y² + se_D²) + the truncation error of the central
//! difference, estimated by Richardson from the difference at 2h: |D̄_2h − D̄_h|/3, itself
//! with its standard error. The set-ups: an index-matched boundary with exact shadow
//! transmittance, the same with the tracked (Mitsuba) shadow estimator and with guided walks
//! (the walks' densities depend on σ_t and α; the common random numbers follow them), a smooth dielectric
//! boundary (η = 1.5, manifold next-event estimation) and a rough one (η = 1.5, GGX α 0.3,
//! next-event estimation at the boundary's vertices), under a point light and an environment.

use geometry::{Accel, Shape};
use glam::Vec3;
use scene::{Camera, Environment, Medium, PointLight};
use testkit::MeanEstimate;
use volpath::rng::Sampler;
use volpath::{
    PathDerivatives, RenderSettings, ShadowTransmittance, VolpathScene, VolpathSettings,
    WalkSampling, radiance, render_derivatives, render_image, trace,
};

const SAMPLES: u64 = 40_000;
/// Relative step in σ_t, absolute steps in α and g.
const H_SIGMA_T: f32 = 0.02;
const H_ALBEDO: f32 = 0.01;
const H_G: f32 = 0.02;

/// The sphere of radius 0.5 the derivative and chromatic tests render.
pub(crate) fn sphere() -> Accel {
    Accel::new(
        Shape::Sphere {
            radius: 0.5,
            subdivisions: 4,
        }
        .build()
        .expect("sphere"),
    )
}

fn medium(eta: f32) -> Medium {
    Medium {
        sigma_t: [6.0, 12.0, 24.0],
        albedo: [0.7, 0.9, 0.95],
        g: scene::Anisotropy::uniform(0.3),
        eta,
        roughness: 0.0,
    }
}

/// Camera ray i: from (0, 0, 3) towards a uniform point of the disk of radius 0.6 at z = 0.
fn camera_ray(s: &mut Sampler) -> (Vec3, Vec3) {
    let (u, v) = (s.next_f32(), s.next_f32());
    let r = 0.6 * u.sqrt();
    let phi = std::f32::consts::TAU * v;
    let o = Vec3::new(0.0, 0.0, 3.0);
    let target = Vec3::new(r * phi.cos(), r * phi.sin(), 0.0);
    (o, (target - o).normalize())
}

/// The radiance of sample `i` of a scene with medium `m` (the sample's own stream).
fn value(
    accel: &Accel,
    base: &VolpathScene,
    settings: &VolpathSettings,
    m: Medium,
    i: u64,
) -> [f32; 3] {
    let scene = VolpathScene {
        accel,
        medium: m,
        ..*base
    };
    let mut s = Sampler::new(7, 0, i, 0);
    let (o, d) = camera_ray(&mut s);
    radiance(&scene, settings, o, d, &mut s)
}

struct Comparison {
    ad: [MeanEstimate; 3],
    fd_h: [MeanEstimate; 3],
    fd_2h: [MeanEstimate; 3],
}

fn compare(name: &str, accel: &Accel, scene: &VolpathScene, settings: &VolpathSettings) {
    let m = scene.medium;
    let mut sigma_t = Comparison {
        ad: Default::default(),
        fd_h: Default::default(),
        fd_2h: Default::default(),
    };
    let mut albedo = Comparison {
        ad: Default::default(),
        fd_h: Default::default(),
        fd_2h: Default::default(),
    };
    let mut g = Comparison {
        ad: Default::default(),
        fd_h: Default::default(),
        fd_2h: Default::default(),
    };
    let moved = |f: &dyn Fn(&mut Medium)| {
        let mut m = m;
        f(&mut m);
        m
    };
    for i in 0..SAMPLES {
        let mut s = Sampler::new(7, 0, i, 0);
        let (o, d) = camera_ray(&mut s);
        let p: PathDerivatives = trace(scene, settings, o, d, None, &mut s);
        for (k, step) in [1.0f32, 2.0].into_iter().enumerate() {
            let ht = H_SIGMA_T * step;
            let up = value(
                accel,
                scene,
                settings,
                moved(&|m| m.sigma_t = m.sigma_t.map(|v| v * (1.0 + ht))),
                i,
            );
            let down = value(
                accel,
                scene,
                settings,
                moved(&|m| m.sigma_t = m.sigma_t.map(|v| v * (1.0 - ht))),
                i,
            );
            let ha = H_ALBEDO * step;
            let a_up = value(
                accel,
                scene,
                settings,
                moved(&|m| m.albedo = m.albedo.map(|v| v + ha)),
                i,
            );
            let a_down = value(
                accel,
                scene,
                settings,
                moved(&|m| m.albedo = m.albedo.map(|v| v - ha)),
                i,
            );
            let hg = H_G * step;
            // Every channel's g moves: channel c's image depends on its own g_c alone, so the
            // difference of channel c is ∂I_c/∂g_c.
            let shift = |m: &mut Medium, h: f32| m.g = scene::Anisotropy(m.g.0.map(|g| g + h));
            let g_up = value(accel, scene, settings, moved(&|m| shift(m, hg)), i);
            let g_down = value(accel, scene, settings, moved(&|m| shift(m, -hg)), i);
            for c in 0..3 {
                let dt = (up[c] - down[c]) as f64 / (2.0 * (m.sigma_t[c] * ht) as f64);
                let da = (a_up[c] - a_down[c]) as f64 / (2.0 * ha as f64);
                let dg = (g_up[c] - g_down[c]) as f64 / (2.0 * hg as f64);
                let (ft, fa, fg) = if k == 0 {
                    (&mut sigma_t.fd_h[c], &mut albedo.fd_h[c], &mut g.fd_h[c])
                } else {
                    (&mut sigma_t.fd_2h[c], &mut albedo.fd_2h[c], &mut g.fd_2h[c])
                };
                ft.push(dt);
                fa.push(da);
                fg.push(dg);
            }
        }
        for c in 0..3 {
            sigma_t.ad[c].push(p.d_sigma_t[c] as f64);
            albedo.ad[c].push(p.d_albedo[c] as f64);
            g.ad[c].push(p.d_g[c] as f64);
        }
    }
    for (param, cmp) in [("σ_t", &sigma_t), ("α", &albedo), ("g", &g)] {
        let mut resolved = [false; 3];
        for c in 0..3 {
            let (ad, fd, fd2) = (&cmp.ad[c], &cmp.fd_h[c], &cmp.fd_2h[c]);
            let trunc = (fd2.mean() - fd.mean()).abs() / 3.0
                + (fd2.std_error().powi(2) + fd.std_error().powi(2)).sqrt() / 3.0;
            let se = (ad.std_error().powi(2) + fd.std_error().powi(2)).sqrt();
            let diff = (ad.mean() - fd.mean()).abs();
            eprintln!(
                "{name} ∂/∂{param} channel {c}: AD {:.5e} ± {:.1e}, FD {:.5e} ± {:.1e} (2h {:.5e}), |Δ|/se {:.2}",
                ad.mean(),
                ad.std_error(),
                fd.mean(),
                fd.std_error(),
                fd2.mean(),
                diff / se
            );
            assert!(
                diff <= 4.5 * se + trunc,
                "{name}: ∂/∂{param} of channel {c}: AD {} against FD {} (se {se}, truncation {trunc})",
                ad.mean(),
                fd.mean()
            );
            // The derivative is not trivially zero: it is resolved by the samples.
            let z = if param == "g" { 3.0 } else { 4.5 };
            resolved[c] = ad.mean().abs() > z * ad.std_error();
        }
        // In every channel for σ_t and α; for g in one channel at least, and at 3 standard
        // errors: its effects (more light forward, less sideways) partly cancel over the disk of
        // rays, and each phase-function factor adds to the score's spread, so that at these
        // samples ∂I/∂g is resolved only at 3–8 standard errors (a run with 300 000 samples and
        // independent streams agreed with differences within 1.3 standard errors, rough case).
        if param == "g" {
            assert!(
                resolved.contains(&true),
                "{name}: ∂/∂g unresolved in every channel"
            );
        } else {
            assert!(
                resolved == [true; 3],
                "{name}: ∂/∂{param} unresolved: {resolved:?}"
            );
        }
    }
}

fn light() -> PointLight {
    PointLight {
        position: Vec3::new(1.2, 0.5, -1.5),
        intensity: [10.0, 8.0, 6.0],
    }
}

/// The sphere of medium with boundary `eta` under [`light`] and `environment`.
fn scene(accel: &Accel, eta: f32, environment: Option<Environment>) -> VolpathScene<'_> {
    VolpathScene {
        accel,
        medium: medium(eta),
        light: Some(light()),
        environment,
        light_bins: None,
    }
}

#[test]
fn derivatives_match_finite_differences_index_matched() {
    let accel = sphere();
    let scene = scene(&accel, 1.0, None);
    compare("exact shadows", &accel, &scene, &VolpathSettings::default());
    let tracked = VolpathSettings {
        shadow: ShadowTransmittance::Tracked,
        ..VolpathSettings::default()
    };
    compare("tracked shadows", &accel, &scene, &tracked);
    let guided = VolpathSettings {
        walks: WalkSampling::Guided { probability: 0.5 },
        ..VolpathSettings::default()
    };
    compare("guided walks", &accel, &scene, &guided);
}

#[test]
fn derivatives_match_finite_differences_dielectric() {
    let accel = sphere();
    let environment = Environment {
        radiance: [0.3, 0.5, 0.7],
    };
    let scene = scene(&accel, 1.5, Some(environment));
    compare("dielectric", &accel, &scene, &VolpathSettings::default());
}

#[test]
fn derivatives_match_finite_differences_rough_dielectric() {
    let accel = sphere();
    let environment = Environment {
        radiance: [0.3, 0.5, 0.7],
    };
    let mut scene = scene(&accel, 1.5, Some(environment));
    scene.medium.roughness = 0.3;
    compare(
        "rough dielectric",
        &accel,
        &scene,
        &VolpathSettings::default(),
    );
}

/// A chromatic medium (a g per channel): each channel's ∂I_c/∂g_c, with the classical walk
/// (whose directions weigh the channels by their phase functions), guided walks, and behind a
/// rough boundary (whose guided connection weighs them too).
#[test]
fn derivatives_match_finite_differences_chromatic_phase() {
    let accel = sphere();
    let mut scene = scene(&accel, 1.0, None);
    scene.medium.g = scene::Anisotropy([0.1, 0.4, 0.7]);
    compare("chromatic g", &accel, &scene, &VolpathSettings::default());
    let guided = VolpathSettings {
        walks: WalkSampling::Guided { probability: 0.5 },
        ..VolpathSettings::default()
    };
    compare("chromatic g, guided walks", &accel, &scene, &guided);
    let environment = Environment {
        radiance: [0.3, 0.5, 0.7],
    };
    let mut rough = self::scene(&accel, 1.5, Some(environment));
    rough.medium.g = scene::Anisotropy([0.1, 0.4, 0.7]);
    rough.medium.roughness = 0.3;
    compare(
        "chromatic g, rough dielectric",
        &accel,
        &rough,
        &VolpathSettings::default(),
    );
}

/// The value image of a render with derivatives is the plain render, bit for bit.
#[test]
fn derivative_render_has_the_plain_image() {
    let accel = sphere();
    let scene = scene(&accel, 1.0, None);
    let camera = Camera::look_at(Vec3::new(0.0, 0.0, 3.0), Vec3::ZERO, Vec3::Y, 30.0, 24, 20);
    let rs = RenderSettings {
        spp: 8,
        seed: 3,
        view: 1,
    };
    let settings = VolpathSettings::default();
    let plain = render_image(&scene, &settings, &camera, &rs, None);
    let d = render_derivatives(&scene, &settings, &camera, &rs, None);
    assert_eq!(plain.data, d.value.data);
    assert!(d.d_sigma_t.data.iter().any(|p| p.iter().any(|v| *v != 0.0)));
    assert!(
        d.d_albedo
            .data
            .iter()
            .all(|p| p.iter().all(|v| v.is_finite() && *v >= 0.0))
    );
}
