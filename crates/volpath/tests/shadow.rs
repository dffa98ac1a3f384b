//! The shadow-ray transmittance estimators ([`volpath::shadow`]).
//!
//! 1. With an unlimited budget the tracked walk returns the exact inside length of the segment
//!    (the all-hits reduction [`geometry::Accel::inside_length`]) on a torus, where segments
//!    leave the medium and re-enter it across the hole.
//! 2. The tracked estimator is unbiased: for fixed segments (with and without a re-entry), the
//!    mean of T̂_c over many draws matches exp(−σ_t,c ℓ) within 4.5 standard errors computed
//!    from the draws; its survival rate matches exp(−min σ_t · ℓ) by a binomial z-test.
//! 3. The exact estimator is the closed form.
//! 4. `render_image` (camera rays through the per-pixel triangle lists, exact shadow rays
//!    through the light's per-direction lists) equals the plain BVH loop over
//!    [`volpath::radiance`] bit for bit, with either estimator.

use geometry::{Accel, Shape};
use glam::Vec3;
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg32;
use testkit::MeanEstimate;
use volpath::ShadowTransmittance;
use volpath::rng::Sampler;
use volpath::shadow::tracked_inside_length;

const Z_MAX: f64 = 4.5;

fn torus() -> Accel {
    Accel::new(
        Shape::Torus {
            major: 0.35,
            minor: 0.15,
            segments: 64,
        }
        .build()
        .expect("torus"),
    )
}

/// The torus's medium (index-matched, g as given) lit by a point light of intensity 2 at `light`.
fn lit_scene(
    accel: &Accel,
    sigma_t: [f32; 3],
    albedo: [f32; 3],
    g: f32,
    light: Vec3,
) -> volpath::VolpathScene<'_> {
    volpath::VolpathScene {
        accel,
        medium: scene::Medium {
            sigma_t,
            albedo,
            g: g.into(),
            eta: 1.0,
            roughness: 0.0,
        },
        light: Some(scene::PointLight {
            position: light,
            intensity: [2.0; 3],
        }),
        environment: None,
        light_bins: None,
    }
}

/// A point inside the torus tube: angle φ around the Y axis, offset (r, θ) in the tube.
fn inside_point(phi: f32, r: f32, theta: f32) -> Vec3 {
    let radial = 0.35 + r * theta.cos();
    Vec3::new(radial * phi.cos(), r * theta.sin(), radial * phi.sin())
}

#[test]
fn unlimited_budget_gives_the_exact_inside_length() {
    let accel = torus();
    let mut rng = Pcg32::seed_from_u64(5);
    let mut reentries = 0;
    for _ in 0..2000 {
        let p = inside_point(
            rng.random::<f32>() * std::f32::consts::TAU,
            0.12 * rng.random::<f32>().sqrt(),
            rng.random::<f32>() * std::f32::consts::TAU,
        );
        assert!(accel.contains(p));
        // Lights around the torus, many of them across the hole from p.
        let light = Vec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-0.4..0.4),
            rng.random_range(-1.0..1.0),
        ) * 1.5;
        if accel.contains(light) {
            continue;
        }
        let exact = accel.inside_length(p, light);
        let tracked = tracked_inside_length(&accel, p, light, f32::INFINITY)
            .expect("an unlimited budget never runs out");
        let dir = (light - p).normalize();
        let mut hits = Vec::new();
        accel.all_hits(p, dir, 0.0, (light - p).length(), &mut hits);
        // The walk restarts each query from an origin pushed off the surface along the normal
        // (`offset_origin`: at most ~3e-5 relative to the coordinates, |p| < 1.5 here), and
        // `inside_length` does not: allow that much per crossing. A grazing chord through the
        // curved tube changes by much more for such a shift (L = 2√(2Rh): dL/dh = √(2R/h)), so
        // segments with a crossing within ~6° of tangent are not compared.
        if hits.iter().any(|h| h.ng.dot(dir).abs() < 0.1) {
            continue;
        }
        reentries += (hits.len() > 1) as u32;
        let tol = 1e-6 + 5e-5 * hits.len() as f32;
        assert!(
            (exact - tracked).abs() <= tol,
            "p {p} light {light}: exact {exact} tracked {tracked} ({} crossings)",
            hits.len()
        );
    }
    assert!(reentries > 100, "only {reentries} segments re-enter");
}

#[test]
fn tracked_transmittance_is_unbiased() {
    let accel = torus();
    let sigma_t = [8.0f32, 12.0, 20.0];
    // One segment straight out of the tube, one across the hole (leaves, re-enters, leaves).
    let p = inside_point(0.0, 0.05, 0.3);
    let cases = [
        ("no re-entry", p, Vec3::new(1.5, 0.2, 0.1)),
        ("re-entry", p, Vec3::new(-1.5, 0.05, 0.0)),
    ];
    for (name, p, light) in cases {
        let len = accel.inside_length(p, light) as f64;
        let mut hits = Vec::new();
        accel.all_hits(
            p,
            (light - p).normalize(),
            0.0,
            (light - p).length(),
            &mut hits,
        );
        eprintln!("{name}: ℓ = {len:.4}, {} crossings", hits.len());
        assert_eq!(hits.len(), if name == "re-entry" { 3 } else { 1 });
        let n = 200_000u64;
        let mut est = [MeanEstimate::default(); 3];
        let mut survived = 0u64;
        for i in 0..n {
            let mut s = Sampler::new(9, 0, i, 0);
            let tr =
                ShadowTransmittance::Tracked.estimate(&accel, None, &sigma_t, p, light, &mut s);
            survived += (tr[0] > 0.0) as u64;
            for c in 0..3 {
                est[c].push(tr[c] as f64);
            }
        }
        let sigma_min = sigma_t[0] as f64;
        let q = (-sigma_min * len).exp();
        let z_surv = (survived as f64 - n as f64 * q).abs() / (n as f64 * q * (1.0 - q)).sqrt();
        assert!(
            z_surv < Z_MAX,
            "{name}: survival {survived}/{n}, expected rate {q:.5}"
        );
        for c in 0..3 {
            let expect = (-(sigma_t[c] as f64) * len).exp();
            eprintln!(
                "{name} channel {c}: {:.5} ± {:.5}, exp(−σ_t ℓ) = {expect:.5}",
                est[c].mean(),
                est[c].std_error()
            );
            assert!(
                est[c].z_score(expect) < Z_MAX,
                "{name} channel {c}: {} ± {} expected {expect}",
                est[c].mean(),
                est[c].std_error()
            );
        }
        let mut s = Sampler::new(9, 0, 0, 0);
        let exact = ShadowTransmittance::Exact.estimate(&accel, None, &sigma_t, p, light, &mut s);
        for c in 0..3 {
            let expect = (-(sigma_t[c] as f64) * len).exp();
            assert!((exact[c] as f64 - expect).abs() <= 1e-6 * expect.max(1e-3));
        }
        // The same value through the light's triangle lists.
        let bins = geometry::LightBins::build(&accel, light).expect("light outside the torus");
        let listed =
            ShadowTransmittance::Exact.estimate(&accel, Some(&bins), &sigma_t, p, light, &mut s);
        assert_eq!(listed.map(f32::to_bits), exact.map(f32::to_bits));
    }
}

/// `render_image` answers camera rays from the camera's per-pixel triangle lists and exact shadow
/// rays from the light's per-direction lists ([`geometry::LightBins`]); the reference is the plain
/// BVH path ([`volpath::radiance`] with no lists) with the same streams: identical images, bit for
/// bit, with both shadow estimators.
#[test]
fn render_image_matches_the_bvh_reference_loop() {
    use scene::Camera;
    use volpath::render::pixel_jitter;
    use volpath::rng::hash_key;
    use volpath::{RenderSettings, VolpathSettings, radiance, render_image, shadow_lists};

    let accel = torus();
    let cam = Camera::look_at(Vec3::new(0.3, 0.9, 1.4), Vec3::ZERO, Vec3::Y, 40.0, 24, 20);
    assert!(
        cam.pixel_bins(&accel).is_some(),
        "the bins path must be exercised"
    );
    let scene = lit_scene(
        &accel,
        [20.0, 30.0, 45.0],
        [0.95, 0.9, 0.85],
        0.0,
        Vec3::new(1.0, 1.5, 0.5),
    );
    let rs = RenderSettings {
        spp: 3,
        seed: 11,
        view: 2,
    };
    for shadow in [ShadowTransmittance::Exact, ShadowTransmittance::Tracked] {
        let settings = VolpathSettings {
            shadow,
            ..Default::default()
        };
        assert_eq!(
            shadow_lists(&scene, &settings).is_some(),
            shadow == ShadowTransmittance::Exact,
            "the light's lists must be exercised by the exact estimator"
        );
        let img = render_image(&scene, &settings, &cam, &rs, None);
        let mut nonzero = 0;
        for y in 0..cam.height {
            for x in 0..cam.width {
                let pixel = (y * cam.width + x) as u64;
                let mut s = Sampler::new(rs.seed, rs.view, pixel, 0);
                let key = hash_key(&[rs.seed, rs.view, pixel, 1]);
                let mut acc = [0.0f64; 3];
                for i in 0..rs.spp {
                    let (jx, jy) = pixel_jitter(i, key, &mut s);
                    let (o, d) = cam.ray(x as f32 + jx, y as f32 + jy);
                    let l = radiance(&scene, &settings, o, d, &mut s);
                    for c in 0..3 {
                        acc[c] += l[c] as f64;
                    }
                }
                let expect = acc.map(|v| (v / rs.spp as f64) as f32);
                let got = img.data[pixel as usize];
                assert_eq!(
                    got.map(f32::to_bits),
                    expect.map(f32::to_bits),
                    "{shadow:?} pixel ({x}, {y})"
                );
                nonzero += (expect[0] > 0.0) as u32;
            }
        }
        assert!(nonzero > 50, "{shadow:?}: only {nonzero} lit pixels");
    }
}

/// A [`volpath::Progressive`] render continues every pixel's streams from pass to pass: passes of
/// 1, 2 and 3 samples give bit for bit `render_image` at 6 spp, with the scene's own shadow lists
/// and with lists built by the progressive render itself; before any pass the image is black.
#[test]
fn progressive_passes_give_the_image_of_one_render() {
    use scene::Camera;
    use volpath::{Progressive, RenderSettings, VolpathSettings, render_image, shadow_lists};

    let accel = torus();
    let cam = Camera::look_at(Vec3::new(-0.4, 0.7, 1.5), Vec3::ZERO, Vec3::Y, 40.0, 20, 16);
    let mut scene = lit_scene(
        &accel,
        [25.0, 35.0, 50.0],
        [0.9, 0.95, 0.8],
        0.3,
        Vec3::new(-1.0, 1.2, 0.8),
    );
    let settings = VolpathSettings::default();
    let rs = RenderSettings {
        spp: 6,
        seed: 5,
        view: 3,
    };
    let whole = render_image(&scene, &settings, &cam, &rs, None);
    assert!(
        whole.data.iter().any(|p| p[0] > 0.0),
        "the view must see the lit torus"
    );
    let lists = shadow_lists(&scene, &settings).expect("exact shadows use the light's lists");
    for shared in [false, true] {
        scene.light_bins = shared.then_some(&lists);
        let mut p = Progressive::new(&scene, &settings, &cam, rs.seed, rs.view);
        assert!(p.image().data.iter().all(|px| *px == [0.0; 3]));
        for n in [1, 2, 3] {
            p.advance(n, None);
        }
        assert_eq!(p.spp(), rs.spp);
        for (i, (a, b)) in p.image().data.iter().zip(&whole.data).enumerate() {
            assert_eq!(
                a.map(f32::to_bits),
                b.map(f32::to_bits),
                "pixel {i}, lists shared: {shared}"
            );
        }
    }
}
