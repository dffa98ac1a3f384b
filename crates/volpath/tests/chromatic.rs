//! A medium with a Henyey–Greenstein g per channel (a chromatic phase function) against three
//! renders of one g each.
//!
//! Channel c's radiance depends on the medium's channel c alone: on σ_t,c, α_c and g_c. So the
//! channel c of a render with g = (g_R, g_G, g_B) has the expectation of channel c of a render
//! whose every channel has g_c. The two are drawn differently: the chromatic render samples each
//! path's directions with its hero channel's g and weighs the other channels by the ratio of
//! their phase functions' densities (within the spectral MIS of the free flights), while the
//! uniform one samples every channel's directions from g_c. Each pair is compared through the
//! means over independent camera rays, within 4.5 combined standard errors, for every way the
//! tracer reaches the light: shadow rays through an index-matched boundary (classical and
//! guided walks), manifold NEE through a smooth dielectric, and the rough boundary's own
//! next-event estimates with the guided connection, whose MIS weights the directions' channel
//! densities enter.

use glam::Vec3;
use scene::{Anisotropy, Environment, Medium, PointLight};
use testkit::MeanEstimate;
use volpath::guided::WalkSampling;
use volpath::rng::Sampler;
use volpath::{VolpathScene, VolpathSettings, radiance};

use crate::derivatives::sphere;

const SAMPLES: u64 = 60_000;
const G: [f32; 3] = [0.0, 0.5, 0.85];

/// The mean radiance per channel over `SAMPLES` camera rays from (0, 0, 3) towards the disk of
/// radius 0.6 at z = 0, with the streams of `stream`.
fn means(scene: &VolpathScene, settings: &VolpathSettings, stream: u64) -> [MeanEstimate; 3] {
    let mut m: [MeanEstimate; 3] = Default::default();
    for i in 0..SAMPLES {
        let mut s = Sampler::new(11, stream, i, 0);
        let (u, v) = (s.next_f32(), s.next_f32());
        let r = 0.6 * u.sqrt();
        let phi = std::f32::consts::TAU * v;
        let o = Vec3::new(0.0, 0.0, 3.0);
        let d = (Vec3::new(r * phi.cos(), r * phi.sin(), 0.0) - o).normalize();
        let l = radiance(scene, settings, o, d, &mut s);
        for c in 0..3 {
            m[c].push(l[c] as f64);
        }
    }
    m
}

/// Channel c of the chromatic medium `m` against channel c of `m` with g_c in every channel.
fn compare(name: &str, m: Medium, environment: Option<Environment>, settings: &VolpathSettings) {
    let accel = sphere();
    let scene = |medium: Medium| VolpathScene {
        accel: &accel,
        medium,
        light: Some(PointLight {
            position: Vec3::new(1.2, 0.5, 1.5),
            intensity: [10.0, 8.0, 6.0],
        }),
        environment,
        light_bins: None,
    };
    let chromatic = means(
        &scene(Medium {
            g: Anisotropy(G),
            ..m
        }),
        settings,
        0,
    );
    for c in 0..3 {
        let uniform = Medium {
            g: Anisotropy::uniform(G[c]),
            ..m
        };
        let one = &means(&scene(uniform), settings, 1 + c as u64)[c];
        let ours = &chromatic[c];
        let se = (ours.std_error().powi(2) + one.std_error().powi(2)).sqrt();
        eprintln!(
            "{name}, channel {c} (g {}): chromatic {:.5e} ± {:.1e}, uniform {:.5e} ± {:.1e}",
            G[c],
            ours.mean(),
            ours.std_error(),
            one.mean(),
            one.std_error()
        );
        assert!(
            one.mean() > 10.0 * one.std_error(),
            "{name}: channel {c} unresolved"
        );
        assert!(
            (ours.mean() - one.mean()).abs() <= 4.5 * se,
            "{name}, channel {c}: chromatic {} against uniform {} (se {se})",
            ours.mean(),
            one.mean()
        );
    }
}

fn medium(eta: f32, roughness: f32) -> Medium {
    Medium {
        sigma_t: [6.0, 12.0, 24.0],
        albedo: [0.8, 0.9, 0.95],
        g: Anisotropy::ISOTROPIC,
        eta,
        roughness,
    }
}

#[test]
fn index_matched_channels_match_their_own_g() {
    compare(
        "classical walks",
        medium(1.0, 0.0),
        None,
        &VolpathSettings::default(),
    );
    let guided = VolpathSettings {
        walks: WalkSampling::Guided { probability: 0.5 },
        ..VolpathSettings::default()
    };
    compare("guided walks", medium(1.0, 0.0), None, &guided);
}

#[test]
fn dielectric_channels_match_their_own_g() {
    let environment = Some(Environment {
        radiance: [0.3, 0.5, 0.7],
    });
    compare(
        "smooth dielectric",
        medium(1.5, 0.0),
        environment,
        &VolpathSettings::default(),
    );
    compare(
        "rough dielectric",
        medium(1.5, 0.3),
        environment,
        &VolpathSettings::default(),
    );
}
