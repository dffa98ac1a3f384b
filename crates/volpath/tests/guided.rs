//! Guided walks ([`volpath::guided`]) against classical ones: the same expected image, and the
//! same derivatives.
//!
//! The quantity is the mean radiance over camera rays aimed uniformly at a disk that covers the
//! object (rays that miss count 0), estimated by each walk from its own independent streams.
//! Per channel the two means must agree within 4.5 standard errors of their difference (the
//! samples' own spread), and each must be resolved (more than 10 standard errors from 0), on a
//! sphere, the blob and a torus, at albedos from 0.8 to 0.99, behind each boundary (null, smooth,
//! rough) and with forward scattering.

use geometry::{Accel, Shape};
use glam::Vec3;
use scene::{Environment, Medium, PointLight};
use testkit::MeanEstimate;
use volpath::rng::Sampler;
use volpath::{PathDerivatives, VolpathScene, VolpathSettings, WalkSampling, radiance, trace};

/// The guided share the comparisons use (every strategy in use, none dominant).
const GUIDED: WalkSampling = WalkSampling::Guided { probability: 0.5 };

fn accel(shape: Shape) -> Accel {
    Accel::new(shape.build().expect("shape"))
}

/// Camera ray i: from (0, 0.4, 3) towards a uniform point of the disk of radius `r` at z = 0.
fn camera_ray(r: f32, s: &mut Sampler) -> (Vec3, Vec3) {
    let (u, v) = (s.next_f32(), s.next_f32());
    let rr = r * u.sqrt();
    let phi = std::f32::consts::TAU * v;
    let o = Vec3::new(0.0, 0.4, 3.0);
    let target = Vec3::new(rr * phi.cos(), rr * phi.sin(), 0.0);
    (o, (target - o).normalize())
}

/// The mean radiance per channel over `n` camera rays, with the walks of `settings`; stream
/// `stream` (independent between the two walks compared).
fn mean_radiance(
    scene: &VolpathScene,
    settings: &VolpathSettings,
    r: f32,
    n: u64,
    stream: u64,
) -> [MeanEstimate; 3] {
    let mut est: [MeanEstimate; 3] = Default::default();
    for i in 0..n {
        let mut s = Sampler::new(21, stream, i, 0);
        let (o, d) = camera_ray(r, &mut s);
        let l = radiance(scene, settings, o, d, &mut s);
        for c in 0..3 {
            est[c].push(l[c] as f64);
        }
    }
    est
}

struct Case {
    name: &'static str,
    shape: Shape,
    /// The disk the camera rays aim at.
    disk: f32,
    medium: Medium,
    light: Vec3,
    environment: bool,
}

fn compare(case: &Case, n: u64) {
    let accel = accel(case.shape.clone());
    let scene = VolpathScene {
        accel: &accel,
        medium: case.medium,
        light: Some(PointLight {
            position: case.light,
            intensity: [10.0, 8.0, 6.0],
        }),
        environment: case.environment.then_some(Environment {
            radiance: [0.3, 0.5, 0.7],
        }),
        light_bins: None,
    };
    let classical = VolpathSettings::default();
    let guided = VolpathSettings {
        walks: GUIDED,
        ..classical
    };
    let a = mean_radiance(&scene, &classical, case.disk, n, 0);
    let b = mean_radiance(&scene, &guided, case.disk, n, 1);
    for c in 0..3 {
        let se = (a[c].std_error().powi(2) + b[c].std_error().powi(2)).sqrt();
        let z = (a[c].mean() - b[c].mean()) / se;
        eprintln!(
            "{} channel {c}: classical {:.5e} ± {:.1e}, guided {:.5e} ± {:.1e}, z {z:.2}",
            case.name,
            a[c].mean(),
            a[c].std_error(),
            b[c].mean(),
            b[c].std_error()
        );
        assert!(
            z.abs() <= 4.5,
            "{}: channel {c}: classical {} against guided {} ({z:.2} standard errors)",
            case.name,
            a[c].mean(),
            b[c].mean()
        );
        for (walk, e) in [("classical", &a[c]), ("guided", &b[c])] {
            assert!(
                e.mean() > 10.0 * e.std_error(),
                "{}: channel {c}: the {walk} mean is not resolved",
                case.name
            );
        }
    }
}

fn medium(albedo: [f32; 3], g: f32, eta: f32, roughness: f32) -> Medium {
    Medium {
        sigma_t: [10.0, 15.0, 20.0],
        albedo,
        g: g.into(),
        eta,
        roughness,
    }
}

#[test]
fn guided_walks_render_the_classical_image_index_matched() {
    let sphere = Shape::Sphere {
        radius: 0.5,
        subdivisions: 3,
    };
    for (name, albedo, light) in [
        (
            "sphere α 0.8–0.9, front light",
            [0.8, 0.85, 0.9],
            Vec3::new(0.8, 0.8, 2.0),
        ),
        (
            "sphere α 0.95–0.99, front light",
            [0.95, 0.97, 0.99],
            Vec3::new(0.8, 0.8, 2.0),
        ),
        (
            "sphere α 0.95–0.99, back light",
            [0.95, 0.97, 0.99],
            Vec3::new(0.3, 0.5, -2.0),
        ),
    ] {
        let case = Case {
            name,
            shape: sphere.clone(),
            disk: 0.6,
            medium: medium(albedo, 0.0, 1.0, 0.0),
            light,
            environment: false,
        };
        compare(&case, 20_000);
    }
}

#[test]
fn guided_walks_render_the_classical_image_behind_boundaries() {
    let blob = Shape::Blob {
        radius: 0.5,
        amplitude: 0.15,
        bumps: 12,
        seed: 7,
        subdivisions: 4,
    };
    let torus = Shape::Torus {
        major: 0.4,
        minor: 0.18,
        segments: 32,
    };
    for case in [
        Case {
            name: "blob, rough η 1.5 α 0.3, g 0.7",
            shape: blob,
            disk: 0.7,
            medium: medium([0.95, 0.97, 0.99], 0.7, 1.5, 0.3),
            light: Vec3::new(0.8, 0.8, 2.0),
            environment: true,
        },
        Case {
            name: "torus, smooth η 1.33, g 0.3",
            shape: torus,
            disk: 0.6,
            medium: medium([0.8, 0.9, 0.95], 0.3, 1.33, 0.0),
            light: Vec3::new(0.8, 0.8, 2.0),
            environment: true,
        },
    ] {
        compare(&case, 10_000);
    }
}

/// Guided walks' derivative paths: ∂I/∂σ_t and ∂I/∂α per channel agree with the classical
/// walks' (which `derivatives::` checks against finite differences), from independent streams.
#[test]
fn guided_walks_have_the_classical_derivatives() {
    let accel = accel(Shape::Sphere {
        radius: 0.5,
        subdivisions: 3,
    });
    let scene = VolpathScene {
        accel: &accel,
        medium: Medium {
            sigma_t: [6.0, 12.0, 24.0],
            ..medium([0.7, 0.9, 0.95], 0.3, 1.0, 0.0)
        },
        light: Some(PointLight {
            position: Vec3::new(1.2, 0.5, -1.5),
            intensity: [10.0, 8.0, 6.0],
        }),
        environment: None,
        light_bins: None,
    };
    let classical = VolpathSettings::default();
    let guided = VolpathSettings {
        walks: GUIDED,
        ..classical
    };
    let n = 20_000u64;
    let run = |settings: &VolpathSettings, stream: u64| {
        let mut est: [[MeanEstimate; 3]; 3] = Default::default();
        for i in 0..n {
            let mut s = Sampler::new(23, stream, i, 0);
            let (o, d) = camera_ray(0.6, &mut s);
            let p: PathDerivatives = trace(&scene, settings, o, d, None, &mut s);
            for c in 0..3 {
                est[0][c].push(p.d_sigma_t[c] as f64);
                est[1][c].push(p.d_albedo[c] as f64);
                est[2][c].push(p.d_g[c] as f64);
            }
        }
        est
    };
    let a = run(&classical, 0);
    let b = run(&guided, 1);
    for (k, param) in ["σ_t", "α", "g"].into_iter().enumerate() {
        for c in 0..3 {
            let (x, y) = (&a[k][c], &b[k][c]);
            let se = (x.std_error().powi(2) + y.std_error().powi(2)).sqrt();
            let z = (x.mean() - y.mean()) / se;
            eprintln!(
                "∂/∂{param} channel {c}: classical {:.4e} ± {:.1e}, guided {:.4e} ± {:.1e}, z {z:.2}",
                x.mean(),
                x.std_error(),
                y.mean(),
                y.std_error()
            );
            assert!(z.abs() <= 4.5, "∂/∂{param} channel {c}: z {z}");
            if param != "g" {
                assert!(
                    y.mean().abs() > 5.0 * y.std_error(),
                    "∂/∂{param} {c} unresolved"
                );
            }
        }
    }
}
