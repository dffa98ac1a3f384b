//! The differentiable learned renderer against brute-force finite differences
//! (ARCHITECTURE.md, "Gradient estimators": every estimator is checked against FD; docs/model.md §8).
//!
//! The model is a small deterministic random network built here (no model files). Its decoder
//! ignores the shape features (their input weights are zero), so y depends on z only and the
//! α-dependence of the render is exactly S_abs(α) plus σ_n(α): the offset estimators then have
//! the same expectation as FD of full renders (up to O(Δ²)).
//!
//! Standard errors come from R independent replicate renders (different `view` streams): the
//! image sums of the replicates are i.i.d., so se = sd/√R. Statistical comparisons use
//! |a − b| < 4·√(se_a² + se_b²).

use crate::common;

use bssrdf::diff::{
    DiffImages, DiffSettings, Estimator, Loss, Primal, render_diff, render_loss_gradient,
};
use bssrdf::nn::ShapeAdaptiveModel;
use bssrdf::render::{
    EntrySampler, LearnedScene, LearnedSettings, RenderSettings, VertexFeatures, render_image,
};
use common::{layer, slab};
use geometry::{Accel, Shape, Vec3};
use scene::{Camera, Image, Medium, PointLight};

mod boundary;

/// Random feature and absorption MLPs; a decoder of z only with outputs of order one (samples
/// spread over about σ_n).
fn model() -> ShapeAdaptiveModel {
    model_with_decoder_features(false)
}

/// As [`model`]; with `uses_features` the decoder also reads the shape features (y depends on
/// the descriptor, hence on σ_t when the descriptor is rescaled).
fn model_with_decoder_features(uses_features: bool) -> ShapeAdaptiveModel {
    let f = 8;
    let mut f0 = layer(23, 16, 0.5, 1);
    if uses_features {
        // Curvature-sensitive features: amplify the quadratic and cubic coefficients' weights
        // (inputs 4..20), which carry the σ_n dependence of a rescaled descriptor.
        for (i, w) in f0.weights_mut().iter_mut().enumerate() {
            if (4..20).contains(&(i % 23)) {
                *w *= 8.0;
            }
        }
    }
    let feature = vec![f0, layer(16, f, 0.5, 2)];
    let absorption = vec![layer(f, 8, 0.7, 3), layer(8, 1, 0.7, 4)];
    let mut d0 = layer(4 + f, 16, 0.8, 5);
    let n_in = d0.n_in();
    for (i, w) in d0.weights_mut().iter_mut().enumerate() {
        if i % n_in >= 4 {
            *w = if uses_features { *w } else { 0.0 };
        }
    }
    // The depth output y₃ (along e₃, into the medium) is kept small: proposals stay within the
    // projection bound of a flat or gently curved surface, so the only discontinuities are the
    // ones a configuration builds in.
    let mut d1 = layer(16, 3, 1.2, 6);
    for w in &mut d1.weights_mut()[2 * 16..] {
        *w *= 0.05;
    }
    let decoder = vec![d0, d1];
    common::assemble(feature, absorption, decoder)
}

fn sphere() -> Accel {
    Accel::new(
        Shape::Sphere {
            radius: 0.5,
            subdivisions: 3,
        }
        .build()
        .unwrap(),
    )
}

const PLANAR: LearnedSettings = LearnedSettings {
    projection: bssrdf::projection::ProjectionRule::Son24 {
        max_dist_scale: 2.0,
        origin_offset: 0.01,
    },
    planar_features: true,
    frames: None,
    frozen_descriptor: false,
    bvh_camera_rays: false,
    exit: bssrdf::exit::ExitLaw::HalfSpace,
    incidence: bssrdf::render::Incidence::Directional,
    entry: EntrySampler::Decoder,
    light_curvature: bssrdf::render::LightCurvature::None,
    sampling: bssrdf::render::PixelSampling::Stratified,
};

fn rgb_medium() -> Medium {
    Medium {
        sigma_t: [30.0, 40.0, 50.0],
        albedo: [0.8, 0.9, 0.95],
        g: scene::Anisotropy::uniform(0.0),
        eta: 1.0,
        roughness: 0.0,
    }
}

struct Setup {
    accel: Accel,
    model: ShapeAdaptiveModel,
    features: VertexFeatures,
    medium: Medium,
    camera: Camera,
    light: PointLight,
    settings: LearnedSettings,
}

impl Setup {
    /// The scene with the shipped test model and features fitted at `medium`.
    fn new(
        accel: Accel,
        medium: Medium,
        camera: Camera,
        light: PointLight,
        settings: LearnedSettings,
    ) -> Self {
        let features = VertexFeatures::fit(&accel, &medium, true, 0).unwrap();
        Setup {
            accel,
            model: model(),
            features,
            medium,
            camera,
            light,
            settings,
        }
    }

    fn scene(&self) -> LearnedScene<'_> {
        LearnedScene::new(
            &self.accel,
            &self.model,
            &self.features,
            self.medium,
            self.settings,
        )
        .unwrap()
    }
}

/// Sphere lit from the side, its terminator and shadowed half in view.
fn sphere_setup(medium: Medium) -> Setup {
    Setup::new(
        sphere(),
        medium,
        Camera::look_at(Vec3::new(0.0, 0.3, 2.0), Vec3::ZERO, Vec3::Y, 32.0, 16, 16),
        PointLight {
            position: Vec3::new(1.5, 0.5, 0.3),
            intensity: [2.0; 3],
        },
        LearnedSettings::default(),
    )
}

/// The sharp edge x = 0.5 of a slab lit from straight above: the side face gets no light, so
/// samples crossing the edge are lost; the footprint of every pixel straddles the edge.
fn edge_setup() -> Setup {
    slab_setup(
        0.485,
        1.4,
        PointLight {
            position: Vec3::new(0.0, 50.0, 0.0),
            intensity: [2500.0; 3],
        },
    )
}

/// The slab seen from straight above the point (x, 0, 0) with horizontal field of view `fov`
/// (degrees), 16×16. The slab's vertices are its corners: per-vertex polynomials say nothing
/// about the flat faces, so the planar descriptor (projection along −n(x_o)) is used.
fn slab_setup(x: f32, fov: f32, light: PointLight) -> Setup {
    Setup::new(
        slab(),
        rgb_medium(),
        Camera::look_at(
            Vec3::new(x, 2.0, 0.0),
            Vec3::new(x, 0.0, 0.0),
            Vec3::Z,
            fov,
            16,
            16,
        ),
        light,
        PLANAR,
    )
}

fn rs(spp: u32, view: u64) -> RenderSettings {
    RenderSettings { spp, seed: 7, view }
}

fn ds(estimator: Estimator) -> DiffSettings {
    DiffSettings {
        estimator,
        ..Default::default()
    }
}

/// Per-channel image sums of the value and the two derivative images, then the sums of the
/// absolute values of the derivative images.
fn sums(im: &DiffImages) -> [[f64; 3]; N_SUMS] {
    let s = |i: &Image, f: fn(f64) -> f64| {
        let mut a = [0.0f64; 3];
        for p in &i.data {
            for c in 0..3 {
                a[c] += f(p[c] as f64);
            }
        }
        a
    };
    let id = |v| v;
    [
        s(&im.value, id),
        s(&im.d_sigma_t, id),
        s(&im.d_albedo, id),
        s(&im.d_sigma_t, f64::abs),
        s(&im.d_albedo, f64::abs),
    ]
}

const N_SUMS: usize = 5;

/// Mean and standard error over replicates, per (image, channel).
#[derive(Debug, Clone, Copy)]
struct Est {
    mean: [[f64; 3]; N_SUMS],
    se: [[f64; 3]; N_SUMS],
}

fn replicate(
    s: &Setup,
    scene: &LearnedScene,
    d: &DiffSettings,
    spp: u32,
    views: std::ops::Range<u64>,
) -> Est {
    let runs: Vec<[[f64; 3]; N_SUMS]> = views
        .map(|v| sums(&render_diff(scene, &s.camera, &s.light, &rs(spp, v), d, None).unwrap()))
        .collect();
    let r = runs.len() as f64;
    let mut e = Est {
        mean: [[0.0; 3]; N_SUMS],
        se: [[0.0; 3]; N_SUMS],
    };
    for i in 0..N_SUMS {
        for c in 0..3 {
            let m = runs.iter().map(|x| x[i][c]).sum::<f64>() / r;
            let var = runs.iter().map(|x| (x[i][c] - m).powi(2)).sum::<f64>() / (r - 1.0);
            e.mean[i][c] = m;
            e.se[i][c] = (var / r).sqrt();
        }
    }
    e
}

/// |a − b| in units of the combined standard error.
fn z(a: &Est, b: &Est, i: usize, c: usize) -> f64 {
    (a.mean[i][c] - b.mean[i][c]).abs() / (a.se[i][c].powi(2) + b.se[i][c].powi(2)).sqrt()
}

const D_T: usize = 1;

/// `ours` and the same-seed FD renders agree on Σ∂I/∂σ_t to 1e-3 relative, per channel: with
/// identical random numbers the offset samples ARE the FD renders, so only rounding separates them.
fn assert_same_seed_fd(label: &str, ours: &Est, fd_same: &Est) {
    for c in 0..3 {
        let (a, b) = (ours.mean[D_T][c], fd_same.mean[D_T][c]);
        let rel = (a - b).abs() / a.abs();
        eprintln!("{label} channel {c}: ours {a:.5e}, same-seed fd {b:.5e}, rel {rel:.2e}");
        assert!(rel < 1e-3, "{label} channel {c}: {rel:.2e}");
    }
}
const D_A: usize = 2;
const ABS_D_A: usize = 4;

fn report(name: &str, e: &Est, i: usize) {
    for c in 0..3 {
        eprintln!("{name} ch{c}: {:.5e} ± {:.2e}", e.mean[i][c], e.se[i][c]);
    }
}

#[test]
fn ours_sigma_t_matches_finite_differences() {
    let s = sphere_setup(rgb_medium());
    let scene = s.scene();
    let (spp, r) = (32, 16);
    let ours = replicate(&s, &scene, &ds(Estimator::Ours), spp, 0..r);
    let fd = replicate(&s, &scene, &ds(Estimator::Fd), spp, r..2 * r);
    // Same random numbers: the offset samples ARE the samples of the FD renders (same z; the
    // descriptor rescaled to σ_n(σ_t ± Δ) in both), equal up to rounding.
    let fd_same = replicate(&s, &scene, &ds(Estimator::Fd), spp, 0..r);
    report("sphere ours dσ_t", &ours, D_T);
    report("sphere fd dσ_t", &fd, D_T);
    report("sphere fd(same seeds) dσ_t", &fd_same, D_T);
    for c in 0..3 {
        let zc = z(&ours, &fd, D_T, c);
        eprintln!("channel {c}: z = {zc:.2}");
        assert!(
            fd.mean[D_T][c].abs() > 6.0 * fd.se[D_T][c],
            "channel {c}: the derivative sum should be clearly non-zero"
        );
        assert!(zc < 4.0, "channel {c}: ours vs fd, z = {zc:.2}");
    }
    assert_same_seed_fd("sphere", &ours, &fd_same);
}

/// The sphere with a decoder that reads the shape features. The subject is the descriptor
/// term: the light side is the cosine law, whose weights do not depend on the camera direction,
/// so the comparison with the frozen descriptor is the one the test was designed on.
fn moved_descriptor_setup() -> Setup {
    let mut s = sphere_setup(rgb_medium());
    s.model = model_with_decoder_features(true);
    s.settings.exit = bssrdf::exit::ExitLaw::Cosine;
    s
}

/// The medium the features are fitted at (k = σ_n/σ_n,fit ≠ 1 at [`rgb_medium`]).
fn descriptor_fit_medium() -> Medium {
    Medium {
        sigma_t: [21.0, 28.0, 35.0],
        ..rgb_medium()
    }
}

/// The descriptor moves with σ_t (features fitted at another medium, k = σ_n/σ_n,fit ≠ 1, and a
/// decoder that reads them): the offset samples re-run the networks at the offset descriptor and
/// equal the FD renders sample for sample; with a frozen descriptor both drop that term, and the
/// term is clearly non-zero.
#[test]
fn offset_samples_follow_the_descriptor() {
    let mut s = moved_descriptor_setup();
    s.features = VertexFeatures::fit(&s.accel, &descriptor_fit_medium(), true, 0).unwrap();
    let (spp, r) = (32, 16);
    let mut results = Vec::new();
    for frozen in [false, true] {
        s.settings.frozen_descriptor = frozen;
        let scene = s.scene();
        let ours = replicate(&s, &scene, &ds(Estimator::Ours), spp, 0..r);
        let fd_same = replicate(&s, &scene, &ds(Estimator::Fd), spp, 0..r);
        assert_same_seed_fd(&format!("frozen {frozen}"), &ours, &fd_same);
        results.push(ours);
    }
    // Same random numbers in both: the difference is the descriptor term, not noise; it must
    // stand far above the 1e-3 agreement asserted above.
    for c in 0..3 {
        let (a, b) = (results[0].mean[D_T][c], results[1].mean[D_T][c]);
        let rel = (a - b).abs() / a.abs().max(b.abs());
        eprintln!("channel {c}: rescaled {a:.5e} vs frozen {b:.5e}: {rel:.2e}");
        assert!(
            rel > 2e-2,
            "channel {c}: the descriptor term should matter ({rel:.2e})"
        );
    }
}

/// With the fit's σ_n-derivative (`VertexFeatures::fit_with_derivative`, features fitted at
/// another medium) the descriptor at σ_n is G.rescaled(k) + ln k · dfit, in the value and in the
/// offset samples alike: `ours` still equals the same-seed FD renders sample for sample.
#[test]
fn offset_samples_follow_the_fit_derivative() {
    let mut s = moved_descriptor_setup();
    s.features =
        VertexFeatures::fit_with_derivative(&s.accel, &descriptor_fit_medium(), true, 0).unwrap();
    assert!(
        s.features.dfit.as_ref().unwrap()[0]
            .iter()
            .all(|p| p.0.iter().all(|c| c.is_finite()))
    );
    let scene = s.scene();
    let (spp, r) = (32, 8);
    let ours = replicate(&s, &scene, &ds(Estimator::Ours), spp, 0..r);
    let fd_same = replicate(&s, &scene, &ds(Estimator::Fd), spp, 0..r);
    assert_same_seed_fd("dfit", &ours, &fd_same);
}

/// The walk sampler ([`EntrySampler::Walks`]: the decoder's proposals replaced by exits of walks
/// in the same descriptor). Each sample keeps its random stream, so the offset samples repeat
/// its walks at σ_n(σ_t ± Δ) in the rescaled descriptor (features fitted at another medium) and
/// at α ± Δα: `ours` and `ours-alpha-offsets` equal the same-seed FD renders sample for sample as
/// with the decoder, and `ours` agrees with FD on independent random numbers. `naive`, which
/// differentiates the decoder's output, is refused with a message naming the fix.
#[test]
fn walk_sampler_offsets_equal_finite_differences() {
    let mut s = sphere_setup(rgb_medium());
    s.features = VertexFeatures::fit(&s.accel, &descriptor_fit_medium(), true, 0).unwrap();
    s.settings.entry = EntrySampler::Walks;
    let scene = s.scene();
    let (spp, r) = (32, 24);
    let ours = replicate(&s, &scene, &ds(Estimator::Ours), spp, 0..r);
    let fd_same = replicate(&s, &scene, &ds(Estimator::Fd), spp, 0..r);
    assert_same_seed_fd("walks", &ours, &fd_same);
    // A walk that leaves in one descriptor may not in the other: the derivative is noisier
    // than the decoder's, hence more samples than the decoder's tests use.
    let fd = replicate(&s, &scene, &ds(Estimator::Fd), spp, r..2 * r);
    for c in 0..3 {
        let zc = z(&ours, &fd, D_T, c);
        eprintln!("walks channel {c}: ours vs fd z = {zc:.2}");
        assert!(zc < 4.0, "channel {c}: z = {zc:.2}");
    }
    // The compared derivative is clearly non-zero: over the three channels (independent
    // replicates per channel sum), more than 6 standard errors from 0.
    let total: f64 = fd.mean[D_T].iter().sum();
    let se = fd.se[D_T].iter().map(|e| e * e).sum::<f64>().sqrt();
    eprintln!("walks Σ_c Σ∂I/∂σ_t = {total:.4e} ± {se:.2e}");
    assert!(total.abs() > 6.0 * se, "{total:.4e} ± {se:.2e}");
    let offs = replicate(&s, &scene, &ds(Estimator::OursAlphaOffsets), spp, 0..r);
    for c in 0..3 {
        let rel = (offs.mean[D_A][c] - fd_same.mean[D_A][c]).abs() / offs.mean[ABS_D_A][c];
        eprintln!("walks channel {c}: α offsets vs same-seed FD, difference / Σ|D| = {rel:.2e}");
        assert!(rel < 1e-3, "channel {c}: relative difference {rel:.2e}");
    }
    let err = render_diff(
        &scene,
        &s.camera,
        &s.light,
        &rs(4, 0),
        &ds(Estimator::Naive),
        None,
    )
    .expect_err("naive with walks must be refused")
    .to_string();
    assert!(
        err.contains("use entry_sampler decoder with estimator naive"),
        "{err}"
    );
}

/// FD through S_abs and the light side only: σ_n held fixed, Δα small enough for the tangent.
fn fd_sabs() -> DiffSettings {
    DiffSettings {
        estimator: Estimator::Fd,
        fd_fixed_sigma_n: true,
        delta_albedo: 2e-4,
        ..Default::default()
    }
}

/// With the light side's curvature correction (`LightCurvature::Ball`) the image changes, and
/// the estimators keep their properties: `ours` equals the same-seed FD for σ_t (C depends on σ_t
/// through κ/σ_t, and the offsets evaluate it at σ_t ± Δ), and its ∂I/∂α (through S_abs, the exit
/// law, the incidence factor and now ∂C/∂α) equals the FD through those with σ_n held fixed.
#[test]
fn curvature_correction_keeps_the_estimators_exact() {
    let mut s = sphere_setup(rgb_medium());
    s.settings.light_curvature = bssrdf::render::LightCurvature::None;
    let plain = replicate(&s, &s.scene(), &ds(Estimator::Ours), 16, 0..4);
    s.settings.light_curvature = bssrdf::render::LightCurvature::Ball;
    let scene = s.scene();
    let (spp, r) = (16, 8);
    let ours = replicate(&s, &scene, &ds(Estimator::Ours), spp, 0..r);
    let same = replicate(&s, &scene, &ds(Estimator::Ours), 16, 0..4);
    for c in 0..3 {
        let (a, b) = (plain.mean[0][c], same.mean[0][c]);
        eprintln!("channel {c}: image sum {a:.5e} without, {b:.5e} with the correction");
        assert!(
            (a - b).abs() > 1e-3 * a.abs(),
            "channel {c}: the correction does nothing"
        );
    }
    let fd_same = replicate(&s, &scene, &ds(Estimator::Fd), spp, 0..r);
    assert_same_seed_fd("curvature", &ours, &fd_same);
    let fd_sabs = replicate(&s, &scene, &fd_sabs(), spp, 0..r);
    for c in 0..3 {
        let rel = (ours.mean[D_A][c] - fd_sabs.mean[D_A][c]).abs() / ours.mean[ABS_D_A][c];
        eprintln!("curvature channel {c}: ours vs S_abs-only FD dα, difference / Σ|D| = {rel:.2e}");
        // As in `alpha_derivatives` (a): O(Δα²) and ReLU sign changes within ±Δα.
        assert!(rel < 3e-3, "channel {c}: relative difference {rel:.2e}");
    }
}

/// A slab lit by a near light, seen around the point under the light, away from every edge:
/// no visibility change in any footprint, so the interior term is the whole derivative.
fn interior_setup() -> Setup {
    slab_setup(
        0.05,
        4.0,
        PointLight {
            position: Vec3::new(0.0, 0.25, 0.0),
            intensity: [0.1; 3],
        },
    )
}

#[test]
fn alpha_derivatives() {
    let s = sphere_setup(rgb_medium());
    let scene = s.scene();
    let (spp, r) = (16, 16);
    // (a) Ours = FD through S_abs only (σ_n held fixed), same random numbers: the per-sample
    // estimates differ by the O(Δα²) error of the central difference and rounding only.
    let ours = replicate(&s, &scene, &ds(Estimator::Ours), spp, 0..r);
    let fd_sabs = replicate(&s, &scene, &fd_sabs(), spp, 0..r);
    report("sphere ours dα", &ours, D_A);
    report("sphere fd(σ_n fixed, same seeds) dα", &fd_sabs, D_A);
    for c in 0..3 {
        // Relative to the L1 norm of the derivative image (a channel's sum may be near 0).
        let rel = (ours.mean[D_A][c] - fd_sabs.mean[D_A][c]).abs() / ours.mean[ABS_D_A][c];
        eprintln!("channel {c}: ours vs S_abs-only FD, difference / Σ|D| = {rel:.2e}");
        // Central difference vs tangent: O(Δα²), plus O(Δα) from samples whose ReLU
        // pre-activations change sign within ±Δα.
        assert!(rel < 3e-3, "channel {c}: relative difference {rel:.2e}");
    }
    // (b) OursAlphaOffsets vs the full FD (σ_n(α) included), independent random numbers.
    let offs = replicate(&s, &scene, &ds(Estimator::OursAlphaOffsets), spp, 0..r);
    let fd = replicate(&s, &scene, &ds(Estimator::Fd), spp, r..2 * r);
    report("sphere ours-alpha-offsets dα", &offs, D_A);
    report("sphere fd dα", &fd, D_A);
    for c in 0..3 {
        let zc = z(&offs, &fd, D_A, c);
        let z_ours = z(&ours, &fd, D_A, c);
        eprintln!(
            "channel {c}: offsets vs fd z = {zc:.2}; ours (S_abs only) vs fd z = {z_ours:.2}"
        );
        assert!(zc < 4.0, "channel {c}: z = {zc:.2}");
    }
    // (c) OursAlphaOffsets is the full FD sample for sample: with the same random numbers and
    // the same Δα, both difference the same samples (networks, positions and light side at
    // α ± Δα), so they differ by f32 rounding of the per-sample differences only (about 1e-5 of
    // Σ|D|; tolerance 1e-3).
    let fd_same = replicate(&s, &scene, &ds(Estimator::Fd), spp, 0..r);
    for c in 0..3 {
        let rel = (offs.mean[D_A][c] - fd_same.mean[D_A][c]).abs() / offs.mean[ABS_D_A][c];
        eprintln!(
            "channel {c}: ours-alpha-offsets vs FD (same seeds), difference / Σ|D| = {rel:.2e}"
        );
        assert!(rel < 1e-3, "channel {c}: relative difference {rel:.2e}");
    }
}

/// `ours`, `naive` and `fd` on independent random numbers, with their z scores against `fd` per
/// channel (ours, naive).
fn ours_naive_fd(s: &Setup, label: &str, spp: u32, r: u64) -> (Est, [(f64, f64); 3]) {
    let scene = s.scene();
    let ours = replicate(s, &scene, &ds(Estimator::Ours), spp, 0..r);
    let naive = replicate(s, &scene, &ds(Estimator::Naive), spp, r..2 * r);
    let fd = replicate(s, &scene, &ds(Estimator::Fd), spp, 2 * r..3 * r);
    for (name, e) in [("ours", &ours), ("naive", &naive), ("fd", &fd)] {
        report(&format!("{label} {name} dσ_t"), e, D_T);
    }
    let zs = std::array::from_fn(|c| {
        let (zo, zn) = (z(&ours, &fd, D_T, c), z(&naive, &fd, D_T, c));
        eprintln!("{label} channel {c}: z(ours, fd) = {zo:.2}, z(naive, fd) = {zn:.2}");
        (zo, zn)
    });
    (fd, zs)
}

#[test]
fn naive_misses_the_boundary_term_and_ours_does_not() {
    // Interior only: all three agree.
    let (fd, zs) = ours_naive_fd(&interior_setup(), "interior", 16, 16);
    for (c, (zo, zn)) in zs.into_iter().enumerate() {
        assert!(fd.mean[D_T][c].abs() > 6.0 * fd.se[D_T][c]);
        assert!(zo < 4.0 && zn < 4.0);
    }
    // A sharp edge in every footprint: the boundary term dominates.
    let (_, zs) = ours_naive_fd(&edge_setup(), "edge", 64, 16);
    for (c, (zo, zn)) in zs.into_iter().enumerate() {
        assert!(zo < 4.0, "channel {c}: ours vs fd z = {zo:.2}");
        assert!(zn > 6.0, "channel {c}: naive vs fd z = {zn:.2}");
    }
}

/// The offset-mean primal (the mean of the two σ_t offset samples) estimates the same image as
/// the unperturbed sample: with identical random numbers, the summed difference of the two value
/// images lies within 4 standard errors (from the per-pixel differences, pixels independent)
/// plus the central-difference bias (Δ²/2)·∂²I/∂σ_t², bounded by 2.5·(Δ/σ_t)²·I (|∂ ln I/∂ ln
/// σ_t| ≤ 2 on this scene); and the derivative images do not depend on the primal.
#[test]
fn offset_mean_primal_estimates_the_forward_render() {
    let s = sphere_setup(Medium {
        eta: 1.3,
        ..rgb_medium()
    });
    let scene = s.scene();
    let r = rs(64, 5);
    let render = |primal| {
        let d = DiffSettings {
            primal,
            ..ds(Estimator::Ours)
        };
        render_diff(&scene, &s.camera, &s.light, &r, &d, None).unwrap()
    };
    let (pair, single) = (render(Primal::OffsetMean), render(Primal::Sample));
    assert_eq!(pair.d_sigma_t, single.d_sigma_t);
    let delta_rel = DiffSettings::default().delta_rel as f64;
    for c in 0..3 {
        let (mut sum_i, mut sum_d, mut sum_d2) = (0.0f64, 0.0f64, 0.0f64);
        for (a, b) in pair.value.data.iter().zip(&single.value.data) {
            let d = a[c] as f64 - b[c] as f64;
            sum_i += b[c] as f64;
            sum_d += d;
            sum_d2 += d * d;
        }
        assert!(sum_i > 0.0);
        let tol = 4.0 * sum_d2.sqrt() + 2.5 * delta_rel * delta_rel * sum_i;
        println!(
            "channel {c}: Σ I = {sum_i:.5}, Σ (pair − single) = {sum_d:.3e}, tolerance {tol:.3e}"
        );
        assert!(sum_d.abs() <= tol, "channel {c}: {sum_d} vs {tol}");
    }
}

#[test]
fn value_equals_the_forward_render_and_thread_count_does_not_matter() {
    // Grey, coloured, and coloured behind a rough boundary (its highlight is part of every
    // estimator's value; the cosine exit law keeps its walk tables out of the test's time).
    for (grey, roughness) in [(false, 0.0), (true, 0.0), (false, 0.2)] {
        let medium = if grey {
            Medium {
                sigma_t: [40.0; 3],
                albedo: [0.9; 3],
                g: scene::Anisotropy::uniform(0.0),
                eta: 1.3,
                roughness: 0.0,
            }
        } else {
            Medium {
                eta: 1.3,
                roughness,
                ..rgb_medium()
            }
        };
        let mut s = sphere_setup(medium);
        if roughness > 0.0 {
            s.settings.exit = bssrdf::exit::ExitLaw::Cosine;
        }
        let scene = s.scene();
        let r = rs(8, 3);
        let img = render_image(&scene, &s.camera, &s.light, &r, None).unwrap();
        assert!(img.mean()[0] > 0.0);
        for (method, primal) in Estimator::ALL
            .into_iter()
            .flat_map(|m| Primal::ALL.map(|p| (m, p)))
        {
            let d = DiffSettings {
                primal,
                ..ds(method)
            };
            let run = |threads: usize| {
                rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap()
                    .install(|| render_diff(&scene, &s.camera, &s.light, &r, &d, None).unwrap())
            };
            let (one, three) = (run(1), run(3));
            // The offset-mean primal of Ours is another estimator (next test).
            let pair = primal == Primal::OffsetMean
                && matches!(method, Estimator::Ours | Estimator::OursAlphaOffsets);
            if !pair {
                assert_eq!(
                    one.value, img,
                    "{method} {primal} (grey {grey}): value differs from render_image"
                );
            }
            assert_eq!(
                one, three,
                "{method} (grey {grey}): thread count changes the result"
            );
            assert!(one.d_sigma_t.data.iter().any(|p| p[0] != 0.0));
            assert!(one.d_albedo.data.iter().any(|p| p[0] != 0.0));
        }
    }
}

/// The per-pixel triangle lists of the camera (the default) and the BVH (the reference path)
/// give the same camera hits, so every image and derivative image is bit-identical.
#[test]
fn camera_ray_lists_and_the_bvh_render_identically() {
    let s = sphere_setup(Medium {
        eta: 1.3,
        ..rgb_medium()
    });
    let mut reference = sphere_setup(s.medium);
    reference.settings.bvh_camera_rays = true;
    let (scene, bvh) = (s.scene(), reference.scene());
    let r = rs(8, 5);
    let img = render_image(&scene, &s.camera, &s.light, &r, None).unwrap();
    assert!(img.mean()[0] > 0.0);
    assert_eq!(
        img,
        render_image(&bvh, &s.camera, &s.light, &r, None).unwrap()
    );
    for method in Estimator::ALL {
        let d = ds(method);
        assert_eq!(
            render_diff(&scene, &s.camera, &s.light, &r, &d, None).unwrap(),
            render_diff(&bvh, &s.camera, &s.light, &r, &d, None).unwrap(),
            "{method}"
        );
    }
}

#[test]
fn loss_gradient_equals_the_sum_over_derivative_images() {
    let s = sphere_setup(rgb_medium());
    let scene = s.scene();
    let r = rs(8, 1);
    for method in [Estimator::Ours, Estimator::Naive] {
        let d = ds(method);
        let images = render_diff(&scene, &s.camera, &s.light, &r, &d, None).unwrap();
        // Target: a blurred-ish, rescaled copy so residuals of both signs occur.
        let mut target = images.value.clone();
        for (i, p) in target.data.iter_mut().enumerate() {
            for c in 0..3 {
                p[c] = p[c] * 0.8 + 0.01 * ((i * 7 + c * 3) % 5) as f32;
            }
        }
        for loss in [Loss::L2, Loss::L1] {
            let g = render_loss_gradient(
                &scene, &s.camera, &s.light, &r, &d, &target, loss, false, None,
            )
            .unwrap();
            assert!(g.images.is_none());
            let n = 3.0 * images.value.data.len() as f64;
            let (mut l, mut gt, mut ga) = (0.0, [0.0f64; 3], [0.0f64; 3]);
            for i in 0..images.value.data.len() {
                for c in 0..3 {
                    let (li, dl) = loss.element(images.value.data[i][c], target.data[i][c]);
                    l += li / n;
                    gt[c] += dl / n * images.d_sigma_t.data[i][c] as f64;
                    ga[c] += dl / n * images.d_albedo.data[i][c] as f64;
                }
            }
            let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * a.abs().max(b.abs()).max(1e-300);
            eprintln!(
                "{method} {loss:?}: loss {:.6e}, dσ_t {:?}, dα {:?}",
                g.loss, g.d_sigma_t, g.d_albedo
            );
            assert!(
                close(g.loss, l),
                "{method} {loss:?}: loss {} vs {l}",
                g.loss
            );
            for c in 0..3 {
                assert!(gt[c] != 0.0 && ga[c] != 0.0);
                assert!(
                    close(g.d_sigma_t[c], gt[c]),
                    "{method} {loss:?} dσ_t[{c}]: {} vs {}",
                    g.d_sigma_t[c],
                    gt[c]
                );
                assert!(
                    close(g.d_albedo[c], ga[c]),
                    "{method} {loss:?} dα[{c}]: {} vs {}",
                    g.d_albedo[c],
                    ga[c]
                );
            }
            let kept = render_loss_gradient(
                &scene, &s.camera, &s.light, &r, &d, &target, loss, true, None,
            )
            .unwrap();
            assert_eq!(kept.images.as_ref(), Some(&images));
            assert_eq!(kept.d_sigma_t, g.d_sigma_t);
        }
    }
}

#[test]
fn estimator_names_round_trip() {
    for m in Estimator::ALL {
        assert_eq!(m.name().parse::<Estimator>().unwrap(), m);
    }
    assert_eq!(
        "OURS_ALPHA_OFFSETS".parse::<Estimator>().unwrap(),
        Estimator::OursAlphaOffsets
    );
    let err = "ad".parse::<Estimator>().unwrap_err().to_string();
    assert!(
        err.contains("\"ad\"") && err.contains("ours, ours-alpha-offsets, naive or fd"),
        "{err}"
    );
    assert_eq!(DiffSettings::default().estimator, Estimator::Ours);
    for p in Primal::ALL {
        assert_eq!(p.name().parse::<Primal>().unwrap(), p);
    }
    assert_eq!("Offset_Mean".parse::<Primal>().unwrap(), Primal::OffsetMean);
    let err = "main".parse::<Primal>().unwrap_err().to_string();
    assert!(
        err.contains("\"main\"") && err.contains("offset-mean"),
        "{err}"
    );
    assert_eq!(DiffSettings::default().primal, Primal::OffsetMean);
}

/// Timing of a 64×64 view at 32 spp (run with `--release --ignored --nocapture`).
#[test]
#[ignore]
fn timing_64x64_32spp() {
    let mut s = sphere_setup(rgb_medium());
    s.camera = Camera::look_at(Vec3::new(0.0, 0.3, 2.0), Vec3::ZERO, Vec3::Y, 32.0, 64, 64);
    let scene = s.scene();
    let r = rs(32, 0);
    for _ in 0..2 {
        let t = std::time::Instant::now();
        render_image(&scene, &s.camera, &s.light, &r, None).unwrap();
        let fwd = t.elapsed().as_secs_f64();
        for m in Estimator::ALL {
            let t = std::time::Instant::now();
            render_diff(&scene, &s.camera, &s.light, &r, &ds(m), None).unwrap();
            eprintln!("forward {fwd:.3} s, {m} {:.3} s", t.elapsed().as_secs_f64());
        }
    }
}
