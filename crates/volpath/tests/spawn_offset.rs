//! Mitsuba 3's spawn offset ([`SpawnOffset::Mitsuba`]) and what it does to an image.
//!
//! 1. The offset itself: (1 + max_i |p_i|)·1500·2⁻²⁴ along the geometric normal, on the side the
//!    new ray points to; measured in Mitsuba 3.9.1 at a hit of the reference sphere
//!    (p = (0.117387, 0.0382613, 0.0191307)): |o − p| = 9.990·10⁻⁵.
//! 2. Its effect, derived: a camera ray entering a medium skips the sliver δ = (1 + max|p|)·ε of
//!    the medium, so with the same random numbers every vertex of the path lies δ deeper along
//!    the normal. Looking straight down at the flat top face (z = 1, so max|p| = 1 and δ = 2ε)
//!    of a thick box of medium, lit by a distant point light straight above, single scattering
//!    (max_depth 2: one NEE per path) then loses exactly exp(−σ_t,c·(δ − δ_robust)/cos θ_l) per
//!    path, where δ_robust is the robust offset (256 ulps of the floats below 1: 1.5·10⁻⁵) and
//!    cos θ_l ≥ 0.99999 in this set-up. Both renders use identical random numbers, so the
//!    ratio of their image sums is that factor up to the 1/r² change (≤ 2·δ/9 relative) and
//!    rounding (5·10⁻⁶ allowed), not up to Monte Carlo noise: no noise term.

use geometry::{Accel, Shape};
use glam::Vec3;
use scene::{Camera, Medium, PointLight};
use volpath::render::pixel_jitter;
use volpath::rng::{Sampler, hash_key};
use volpath::{SpawnOffset, VolpathScene, VolpathSettings, radiance};

const EPS: f32 = 1500.0 / 16_777_216.0;

#[test]
fn mitsuba_offset_matches_mitsubas_spawn_ray() {
    let p = Vec3::new(0.117387, 0.0382613, 0.0191307);
    let n = Vec3::new(0.935576, 0.313597, 0.162339);
    let inward = -n;
    let o = SpawnOffset::Mitsuba.spawn(p, n, inward);
    let off = o - p;
    // Mitsuba 3.9.1 (scalar_rgb), `si.spawn_ray(d)` at this hit: |o − p| = 9.990372659e-5.
    assert!(
        ((off.length() as f64) - 9.990372659e-5).abs() < 2e-9,
        "{off}"
    );
    assert!(off.normalize().dot(inward) > 0.999_999, "{off}");
    // Either orientation of the stored normal gives the same point.
    assert_eq!(SpawnOffset::Mitsuba.spawn(p, -n, inward), o);
    // The robust offset stays far below it.
    let r = SpawnOffset::Robust.spawn(p, n, inward) - p;
    assert!(r.length() < 5e-6 && r.dot(inward) > 0.0, "{r}");
}

#[test]
fn mitsuba_offset_darkens_single_scattering_by_the_skipped_sliver() {
    let accel = Accel::new(
        Shape::RoundedBox {
            size: [2.0, 2.0, 2.0],
            radius: 0.2,
            segments: 8,
        }
        .build()
        .expect("box"),
    );
    let sigma_t = [30.0f32, 50.0, 70.0];
    let scene = VolpathScene {
        accel: &accel,
        medium: Medium {
            sigma_t,
            albedo: [0.9, 0.8, 0.7],
            g: scene::Anisotropy::uniform(0.0),
            eta: 1.0,
            roughness: 0.0,
        },
        light: Some(PointLight {
            position: Vec3::new(0.0, 0.0, 10.0),
            intensity: [1.0; 3],
        }),
        environment: None,
        light_bins: None,
    };
    // Straight down at the centre of the top face; the footprint is about 0.05 across.
    let cam = Camera::look_at(Vec3::new(0.0, 0.0, 3.0), Vec3::ZERO, Vec3::Y, 1.5, 8, 8);
    let render = |spawn_offset: SpawnOffset| {
        let settings = VolpathSettings {
            max_depth: 2,
            spawn_offset,
            ..Default::default()
        };
        let mut sum = [0.0f64; 3];
        for pixel in 0..64u64 {
            let mut s = Sampler::new(7, 0, pixel, 0);
            let key = hash_key(&[7, 0, pixel, 1]);
            for i in 0..64 {
                let (jx, jy) = pixel_jitter(i, key, &mut s);
                let (o, d) = cam.ray((pixel % 8) as f32 + jx, (pixel / 8) as f32 + jy);
                let l = radiance(&scene, &settings, o, d, &mut s);
                for c in 0..3 {
                    sum[c] += l[c] as f64;
                }
            }
        }
        sum
    };
    let robust = render(SpawnOffset::Robust);
    let mitsuba = render(SpawnOffset::Mitsuba);
    let delta = 2.0 * EPS as f64;
    // The robust offset on the flat top face: the normal is +z exactly, so only z moves, by 256
    // ulps of the floats just below 1 (2⁻²⁴ each).
    let delta_robust = 256.0 / 16_777_216.0;
    for c in 0..3 {
        assert!(robust[c] > 0.0);
        let ratio = mitsuba[c] / robust[c];
        let st = sigma_t[c] as f64;
        // Bounds of exp(−σ_t (δ − δ_r)/cos θ_l) · (r/r')², see the module docs.
        let hi = (-st * (delta - delta_robust)).exp() * (1.0 + 5e-6);
        let lo = (-st * (delta - delta_robust) / 0.99999).exp()
            * (1.0 - 2.0 * delta / 9.0)
            * (1.0 - 5e-6);
        eprintln!("channel {c}: ratio {ratio:.6} in [{lo:.6}, {hi:.6}]");
        assert!(
            (lo..=hi).contains(&ratio),
            "channel {c}: ratio {ratio} outside [{lo}, {hi}]"
        );
    }
}
