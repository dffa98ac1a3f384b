//! The planar dipole baseline ([`dipole`]): its probe sampler against its density (χ²
//! and the closed-form total reflectance of a half-space) and its derivative images against
//! central differences of its renders.

use base::pixel::RenderSettings;
use base::rng::Sampler;
use dipole::{DipoleScene, DipoleView, ProbeSampler, render_derivatives, render_image};
use geometry::{Accel, Frame, Shape};
use glam::Vec3;
use scene::{Camera, Image, Medium, PointLight};
use testkit::{MeanEstimate, chi2_test};

fn uniforms(s: &mut Sampler) -> [f32; 5] {
    std::array::from_fn(|_| s.next_f32())
}

/// On a half-space the probes estimate ∫ R_d dA, whose closed form is the total diffuse
/// reflectance (α'/2)(e^{−μ_tr z_r} + e^{−μ_tr z_v}): the estimate R_d(r)/p of each sample
/// (0 for a miss) must average to it within 4.5 standard errors. The half-space is the top face
/// of a box 14 × 14 × 8, its other faces beyond every channel's probe reach (r_max ≤ 3).
#[test]
fn half_space_estimate_is_the_total_diffuse_reflectance() {
    let m = Medium {
        sigma_t: [50.0, 80.0, 30.0],
        albedo: [0.9, 0.6, 0.99],
        g: scene::Anisotropy::uniform(0.2),
        eta: 1.3,
        roughness: 0.0,
    };
    let accel = Accel::new(
        Shape::RoundedBox {
            size: [14.0, 14.0, 8.0],
            radius: 0.1,
            segments: 8,
        }
        .build()
        .unwrap(),
    );
    let scene = DipoleScene::new(&accel, m).unwrap();
    let frame = Frame::from_normal(Vec3::Z);
    let x_o = Vec3::new(0.01, -0.02, 4.0);
    assert!(scene.sampler().r_max.iter().all(|&r| r < 3.0));
    let mut est = [
        MeanEstimate::default(),
        MeanEstimate::default(),
        MeanEstimate::default(),
    ];
    let mut s = Sampler::new(3, 0, 0, 0);
    let mut buf = Vec::new();
    for _ in 0..200_000 {
        let sample = scene
            .sampler()
            .sample(&accel, x_o, &frame, uniforms(&mut s), &mut buf);
        for (c, e) in est.iter_mut().enumerate() {
            e.push(sample.map_or(0.0, |p| {
                scene.profiles()[c].value((p.hit.p - x_o).length() as f64) / p.pdf
            }));
        }
    }
    for (c, e) in est.iter().enumerate() {
        let want = scene.profiles()[c].total_reflectance();
        eprintln!(
            "channel {c}: {} ± {} against {want}",
            e.mean(),
            e.std_error()
        );
        assert!(
            e.z_score(want).abs() < 4.5,
            "channel {c}: {} ± {} vs the closed form {want}",
            e.mean(),
            e.std_error()
        );
    }
}

/// χ² test of the probe sampler on a sphere small enough that the probes cross it twice (the
/// red channel's r_max is twice the diameter, the blue one's a quarter of it): the histogram of
/// the entry points over cells of polar angle (about x_o's direction from the centre) and
/// azimuth against the integral of [`ProbeSampler::pdf`] over each cell (midpoint rule on
/// subdivided triangles, finer near x_o). The cap within 4° of x_o, where the density's 1/r
/// singularity defeats the quadrature, is pooled with the misses into one cell whose expected
/// count is the rest.
#[test]
fn probe_sampler_passes_chi2_on_a_sphere() {
    let radius = 0.3f32;
    let accel = Accel::new(
        Shape::Sphere {
            radius,
            subdivisions: 4,
        }
        .build()
        .unwrap(),
    );
    let m = Medium {
        sigma_t: [30.0, 60.0, 120.0],
        albedo: [0.95, 0.9, 0.8],
        g: scene::Anisotropy::uniform(0.0),
        eta: 1.0,
        roughness: 0.0,
    };
    let scene = DipoleScene::new(&accel, m).unwrap();
    let sampler: &ProbeSampler = scene.sampler();
    let aim = Vec3::new(0.55, 0.7, 0.45).normalize();
    let hit = accel.closest(aim * 2.0, -aim, 0.0, f32::INFINITY).unwrap();
    let (x_o, frame) = (hit.p, Frame::from_normal(hit.ns));
    let pole = x_o.normalize();
    let theta_edges_deg = [
        4.0, 7.0, 10.0, 15.0, 20.0, 30.0, 40.0, 55.0, 70.0, 90.0, 120.0, 150.0, 180.01,
    ];
    let azimuths = 6usize;
    let cells = (theta_edges_deg.len() - 1) * azimuths;
    // Cell of a point (the pooled cell `cells` for the cap).
    let cell = |p: Vec3| -> usize {
        let d = p.normalize();
        let theta = d.dot(pole).clamp(-1.0, 1.0).acos().to_degrees();
        if theta < theta_edges_deg[0] {
            return cells;
        }
        let ring = theta_edges_deg.iter().rposition(|&e| theta >= e).unwrap();
        let ring = ring.min(theta_edges_deg.len() - 2);
        let l = frame.to_local(d - pole * d.dot(pole));
        let psi = l.y.atan2(l.x) + std::f32::consts::PI;
        let k = ((psi / std::f32::consts::TAU * azimuths as f32) as usize).min(azimuths - 1);
        ring * azimuths + k
    };
    let n = 300_000usize;
    let mut observed = vec![0.0; cells + 1];
    let mut s = Sampler::new(11, 0, 0, 0);
    let mut buf = Vec::new();
    for _ in 0..n {
        match sampler.sample(&accel, x_o, &frame, uniforms(&mut s), &mut buf) {
            Some(p) => observed[cell(p.hit.p)] += 1.0,
            None => observed[cells] += 1.0,
        }
    }
    let mesh = accel.mesh();
    let mut expected = vec![0.0; cells + 1];
    for tri in &mesh.indices {
        let [a, b, c] = tri.map(|i| mesh.positions[i as usize]);
        let ng = (b - a).cross(c - a).normalize();
        let centre = (a + b + c) / 3.0;
        let k = if (centre - x_o).length() < 0.12 {
            32
        } else {
            6
        };
        let area = 0.5 * (b - a).cross(c - a).length() as f64 / (k * k) as f64;
        // The k² sub-triangles of a barycentric grid, by their centroids.
        for i in 0..k {
            for j in 0..k - i {
                let f = |u: f32, v: f32| a + (b - a) * (u / k as f32) + (c - a) * (v / k as f32);
                let (u, v) = (i as f32, j as f32);
                let mut tris = vec![[f(u, v), f(u + 1.0, v), f(u, v + 1.0)]];
                if i + j + 1 < k {
                    tris.push([f(u + 1.0, v), f(u + 1.0, v + 1.0), f(u, v + 1.0)]);
                }
                for t in tris {
                    let p = (t[0] + t[1] + t[2]) / 3.0;
                    let q = cell(p);
                    if q < cells {
                        let pdf = sampler.pdf(&accel, x_o, &frame, p, ng, &mut buf);
                        expected[q] += pdf * area * n as f64;
                    }
                }
            }
        }
    }
    let rest: f64 = expected[..cells].iter().sum();
    assert!(rest < n as f64, "the density integrates to more than 1");
    expected[cells] = n as f64 - rest;
    let r = chi2_test(&observed, &expected, 5.0);
    eprintln!(
        "χ² = {:.1} on {} dof, p = {:.3}",
        r.statistic, r.dof, r.p_value
    );
    assert!(
        r.p_value > 1e-3,
        "χ² = {:.1} on {} dof, p = {:.2e}\nobserved {observed:?}\nexpected {expected:?}",
        r.statistic,
        r.dof,
        r.p_value
    );
    // The ring nearest the pole and the far side both hold samples: a real test of the
    // multi-crossing density.
    assert!(observed[..azimuths].iter().sum::<f64>() > 1000.0);
    assert!(
        observed[(theta_edges_deg.len() - 3) * azimuths..cells]
            .iter()
            .sum::<f64>()
            > 100.0
    );
}

fn blob_view() -> (Accel, Camera, PointLight) {
    let accel = Accel::new(
        Shape::Sphere {
            radius: 0.4,
            subdivisions: 4,
        }
        .build()
        .unwrap(),
    );
    let camera = Camera::look_at(Vec3::new(0.0, 0.3, 2.0), Vec3::ZERO, Vec3::Y, 32.0, 20, 20);
    let light = PointLight {
        position: Vec3::new(1.2, 0.8, 1.0),
        intensity: [2.0, 1.5, 1.0],
    };
    (accel, camera, light)
}

fn sums(img: &Image) -> [f64; 3] {
    let mut s = [0.0; 3];
    for px in &img.data {
        for c in 0..3 {
            s[c] += px[c] as f64;
        }
    }
    s
}

/// Σ_pixels w_c·I_c with fixed weights `w` per pixel and channel.
fn weighted(img: &Image, w: &[[f64; 3]]) -> [f64; 3] {
    let mut s = [0.0; 3];
    for (px, w) in img.data.iter().zip(w) {
        for c in 0..3 {
            s[c] += w[c] * px[c] as f64;
        }
    }
    s
}

/// The signs of a derivative image: weights under which the weighted sum of that derivative is
/// large (the plain image sum barely moves with σ_t: the total diffuse reflectance depends on
/// α' only; the spread of light across the object does).
fn signs(img: &Image) -> Vec<[f64; 3]> {
    img.data
        .iter()
        .map(|px| px.map(|v| v.signum() as f64))
        .collect()
}

/// The derivative images against central differences of renders with the same random numbers,
/// per parameter and channel, of a weighted image sum ([`weighted`], with the signs of a pilot
/// derivative render of another seed as the weights): over independent seeds k,
/// Y_k = Σ_pixels w·∂I/∂θ_c (one derivative render) and D_k = Σ_pixels w·(I(θ + h) − I(θ − h))/2h (every channel's parameter moved at once,
/// which leaves each channel's expectation a function of its own parameter). The test:
/// |mean Y − mean D| ≤ 4.5·√(se_Y² + se_D²) + the difference's truncation error, estimated by
/// Richardson from the difference at 2h (|D̄_2h − D̄_h|/3).
#[test]
fn derivative_images_match_central_differences() {
    let (accel, camera, light) = blob_view();
    let m = Medium {
        sigma_t: [6.0, 10.0, 16.0],
        albedo: [0.95, 0.85, 0.7],
        g: scene::Anisotropy::uniform(0.0),
        eta: 1.3,
        roughness: 0.0,
    };
    let view = DipoleView::new(&accel, &camera, &light);
    let pilot = render_derivatives(
        &DipoleScene::new(&accel, m).unwrap(),
        &view,
        &RenderSettings {
            spp: 256,
            seed: 1000,
            view: 0,
        },
    );
    let w = [signs(&pilot.d_sigma_t), signs(&pilot.d_albedo)];
    let render_at = |m: Medium, seed: u64, p: usize| {
        let scene = DipoleScene::new(&accel, m).unwrap();
        let rs = RenderSettings {
            spp: 8,
            seed,
            view: 0,
        };
        weighted(&render_image(&scene, &view, &rs), &w[p])
    };
    let moved = |sigma: f32, albedo: f32| Medium {
        sigma_t: m.sigma_t.map(|s| s * (1.0 + sigma)),
        albedo: m.albedo.map(|a| a + albedo),
        ..m
    };
    let (hs, ha) = (0.02f32, 0.01f32);
    // [parameter][channel]: ad, fd at h, fd at 2h.
    let mut est: Vec<[[MeanEstimate; 3]; 3]> = (0..2).map(|_| Default::default()).collect();
    for seed in 0..24u64 {
        let scene = DipoleScene::new(&accel, m).unwrap();
        let rs = RenderSettings {
            spp: 8,
            seed,
            view: 0,
        };
        let d = render_derivatives(&scene, &view, &rs);
        let plain = render_image(&scene, &view, &rs);
        assert_eq!(
            d.value, plain,
            "the derivative render's value is the plain render"
        );
        let ad = [weighted(&d.d_sigma_t, &w[0]), weighted(&d.d_albedo, &w[1])];
        for (p, (step, moved_by)) in [
            (hs, &(|k: f32| moved(k, 0.0)) as &dyn Fn(f32) -> Medium),
            (ha, &(|k: f32| moved(0.0, k)) as &dyn Fn(f32) -> Medium),
        ]
        .into_iter()
        .enumerate()
        {
            let fd = |k: f32| {
                let (a, b) = (
                    render_at(moved_by(k), seed, p),
                    render_at(moved_by(-k), seed, p),
                );
                std::array::from_fn::<f64, 3, _>(|c| {
                    let h = if p == 0 { m.sigma_t[c] * k } else { k };
                    (a[c] - b[c]) / (2.0 * h as f64)
                })
            };
            let (f1, f2) = (fd(step), fd(2.0 * step));
            for c in 0..3 {
                est[p][0][c].push(ad[p][c]);
                est[p][1][c].push(f1[c]);
                est[p][2][c].push(f2[c]);
            }
        }
    }
    for (p, name) in ["σ_t", "α"].iter().enumerate() {
        for c in 0..3 {
            let [ad, f1, f2] = [&est[p][0][c], &est[p][1][c], &est[p][2][c]];
            let se = (ad.std_error().powi(2) + f1.std_error().powi(2)).sqrt();
            let trunc = (f2.mean() - f1.mean()).abs() / 3.0;
            let diff = (ad.mean() - f1.mean()).abs();
            assert!(
                diff <= 4.5 * se + trunc,
                "∂/∂{name} channel {c}: ad {} ± {}, fd {} ± {} (truncation {trunc})",
                ad.mean(),
                ad.std_error(),
                f1.mean(),
                f1.std_error()
            );
            eprintln!(
                "∂/∂{name} {c}: ad {} ± {} fd {} ± {} fd2 {} ± {}",
                ad.mean(),
                ad.std_error(),
                f1.mean(),
                f1.std_error(),
                f2.mean(),
                f2.std_error()
            );
            assert!(
                ad.mean().abs() > 3.0 * ad.std_error(),
                "∂/∂{name} {c} is resolved"
            );
        }
    }
}

/// Same seed, same image, whatever the thread count; another seed, another image.
#[test]
fn renders_are_reproducible() {
    let (accel, camera, light) = blob_view();
    let m = Medium {
        sigma_t: [40.0, 70.0, 110.0],
        albedo: [0.95, 0.85, 0.7],
        g: scene::Anisotropy::uniform(0.0),
        eta: 1.0,
        roughness: 0.0,
    };
    let scene = DipoleScene::new(&accel, m).unwrap();
    let view = DipoleView::new(&accel, &camera, &light);
    let rs = RenderSettings {
        spp: 4,
        seed: 5,
        view: 2,
    };
    let a = render_derivatives(&scene, &view, &rs);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let b = pool.install(|| render_derivatives(&scene, &view, &rs));
    assert_eq!(a, b);
    let c = render_image(&scene, &view, &RenderSettings { seed: 6, ..rs });
    assert_ne!(a.value, c);
    assert!(sums(&a.value).iter().all(|&v| v > 0.0 && v.is_finite()));
}

/// Bad media are errors, not NaN images.
#[test]
fn invalid_media_are_errors() {
    let (accel, _, _) = blob_view();
    let m = Medium {
        sigma_t: [40.0, -1.0, 110.0],
        albedo: [0.95, 0.85, 0.7],
        g: scene::Anisotropy::uniform(0.0),
        eta: 1.0,
        roughness: 0.0,
    };
    let e = DipoleScene::new(&accel, m).err().expect("an error");
    assert!(e.to_string().contains("sigma_t[1]"), "{e}");
}
