//! The learned renderer's estimator on a configuration with a closed-form expectation.
//!
//! A large flat slab lit by a distant point light (uniform irradiance E = I/r² at normal
//! incidence) and seen from above: with planar features every sample lands on the top face near
//! x_o, so each pixel's expectation is exactly
//!   E[C_c] = S_abs,c · (1 − F(cos θ_cam)) · D(w_l) · cos θ_l · E
//! whatever the decoder proposes, with D = Sw for the cosine exit law and D = f(α_c; 1, 1)/π for
//! the half-space law (camera and light both along the normal; `bssrdf::exit`) (the 3× one-hot channel weighting averages to one). S_abs,c is
//! computed directly from the model for the plane inputs, so the test checks the assembly of the
//! estimator (channel selection and weighting, absorption scale, Fresnel and Sw factors,
//! projection, shadow rays) for an arbitrary network. The same holds with the walk sampler
//! (`EntrySampler::Walks`): its exits lie on the plane, and S_abs still comes from the network. Tolerance: 4.5 standard errors of the
//! per-sample values (the one-hot channel choice makes each value 3v or 0; the stratified scheme
//! gives channel c exactly n_c samples of weight spp/n_c, and a grey medium serves all channels
//! with every sample, so both have the value v in every pixel).
//!
//! [`rgb_render_matches_three_grey_renders`]: the per-channel mean of a coloured render equals
//! that of a grey render at each channel's medium (the same vertex fits), for both pixel-sampling
//! schemes, within the standard errors of both estimates over independent seeds.

use crate::common;

use base::boundary::{sw, transmittance};
use bssrdf::exit::{ExitLaw, ExitTable};
use bssrdf::medium::{ReducedMedium, effective_albedo};
use bssrdf::nn::ShapeAdaptiveModel;
use bssrdf::polynomial::Poly3;
use bssrdf::render::{
    EntrySampler, LearnedScene, LearnedSettings, PixelSampling, RenderSettings, VertexFeatures,
    render_image,
};
use common::{layer, slab};
use geometry::{Accel, Vec3};
use scene::{Camera, Medium, PointLight};

/// A small random model; the decoder's last layer is tiny so samples stay within the
/// projection bound.
fn model() -> ShapeAdaptiveModel {
    let f = 8;
    let feature = vec![layer(23, 16, 0.5, 1), layer(16, f, 0.5, 2)];
    let absorption = vec![layer(f, 8, 0.7, 3), layer(8, 1, 0.7, 4)];
    let decoder = vec![layer(4 + f, 8, 0.5, 5), layer(8, 3, 0.02, 6)];
    common::assemble(feature, absorption, decoder)
}

#[test]
fn planar_estimator_matches_closed_form_on_a_lit_slab() {
    let accel = slab();
    let model = model();
    let cases = [
        (1.0f32, false, ExitLaw::Cosine, EntrySampler::Decoder),
        (1.4, false, ExitLaw::Cosine, EntrySampler::Decoder),
        (1.0, true, ExitLaw::Cosine, EntrySampler::Decoder),
        (1.0, false, ExitLaw::HalfSpace, EntrySampler::Decoder),
        (1.4, false, ExitLaw::HalfSpace, EntrySampler::Decoder),
        (1.0, true, ExitLaw::HalfSpace, EntrySampler::Decoder),
        (1.4, false, ExitLaw::HalfSpace, EntrySampler::Walks),
        (1.0, true, ExitLaw::HalfSpace, EntrySampler::Walks),
    ];
    let schemes = [PixelSampling::Stratified, PixelSampling::OneHot];
    for (sampling, (eta, grey, law, entry)) in schemes
        .into_iter()
        .flat_map(|s| cases.into_iter().map(move |c| (s, c)))
    {
        let medium = if grey {
            Medium {
                sigma_t: [60.0; 3],
                albedo: [0.8; 3],
                g: scene::Anisotropy::uniform(0.0),
                eta,
                roughness: 0.0,
            }
        } else {
            Medium {
                sigma_t: [50.0, 60.0, 70.0],
                albedo: [0.5, 0.8, 0.95],
                g: scene::Anisotropy::uniform(0.0),
                eta,
                roughness: 0.0,
            }
        };
        let features = VertexFeatures::fit(&accel, &medium, true, 0).unwrap();
        // The closed form is the half-space model's: no curvature correction.
        let settings = LearnedSettings {
            planar_features: true,
            exit: law,
            entry,
            light_curvature: bssrdf::render::LightCurvature::None,
            sampling,
            ..Default::default()
        };
        let scene = LearnedScene::new(&accel, &model, &features, medium, settings).unwrap();
        // Camera straight above the centre (narrow fov), light far above: E = I/r² ≈ 1.
        let cam = Camera::look_at(Vec3::new(0.0, 2.0, 0.0), Vec3::ZERO, Vec3::Z, 4.0, 12, 12);
        let light = PointLight {
            position: Vec3::new(0.0, 1000.0, 0.0),
            intensity: [1e6; 3],
        };
        let spp = 256;
        let img = render_image(
            &scene,
            &cam,
            &light,
            &RenderSettings {
                spp,
                seed: 3,
                view: 0,
            },
            None,
        )
        .unwrap();
        let n = (img.data.len() as u32 * spp) as f64;
        let m = img.mean();
        for c in 0..3 {
            let r = ReducedMedium::new(medium.sigma_t[c] as f64, medium.albedo[c] as f64, 0.0);
            let x = model.normalisation().inputs(
                &Poly3::plane(Vec3::Z).0,
                effective_albedo(r.albedo_red) as f32,
                0.0,
                eta,
            );
            let mut f = vec![0.0; model.feature_dim()];
            model.features(&[x], &mut f).unwrap();
            let mut absorb = [0.0];
            model.absorb(&f, &mut absorb).unwrap();
            let d = match law {
                ExitLaw::Cosine => sw(1.0, eta),
                ExitLaw::HalfSpace => {
                    let table = ExitTable::for_medium(0.0, eta, 0.0);
                    table.slice(medium.albedo[c]).eval(1.0, 1.0).0 / std::f32::consts::PI
                }
            };
            let v = (1.0 - absorb[0]) as f64 * transmittance(1.0, eta) as f64 * d as f64;
            // One-hot: each sample is 3v with probability 1/3, else 0: variance 2v². Grey and
            // stratified: every pixel's value is v (zero variance here: uniform light, every
            // sample hits), up to float rounding.
            let one_hot = sampling == PixelSampling::OneHot && !grey;
            let se = if one_hot {
                v * (2.0 / n).sqrt()
            } else {
                1e-5 * v
            };
            let z = (m[c] - v).abs() / se;
            assert!(
                z < 4.5,
                "{sampling:?} η={eta} {law:?} {entry:?} channel {c}: pixel mean {} vs closed form {v} (z = {z:.2})",
                m[c]
            );
        }
    }
}

#[test]
fn images_do_not_depend_on_the_thread_count_with_either_entry_sampler() {
    let accel = slab();
    let model = model();
    let medium = Medium {
        sigma_t: [30.0; 3],
        albedo: [0.9; 3],
        g: scene::Anisotropy::uniform(0.0),
        eta: 1.0,
        roughness: 0.0,
    };
    let features = VertexFeatures::fit(&accel, &medium, true, 0).unwrap();
    let cam = Camera::look_at(Vec3::new(0.5, 1.5, 1.0), Vec3::ZERO, Vec3::Y, 40.0, 16, 16);
    let light = PointLight {
        position: Vec3::new(1.0, 2.0, 0.0),
        intensity: [3.0; 3],
    };
    let rs = RenderSettings {
        spp: 8,
        seed: 1,
        view: 2,
    };
    let mut images = Vec::new();
    for entry in EntrySampler::ALL {
        let settings = LearnedSettings {
            entry,
            ..Default::default()
        };
        let scene = LearnedScene::new(&accel, &model, &features, medium, settings).unwrap();
        let render = |threads: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| render_image(&scene, &cam, &light, &rs, None).unwrap())
        };
        let (one, two) = (render(1), render(2));
        assert_eq!(one, two, "{entry:?}");
        assert!(one.mean()[0] > 0.0);
        images.push(one);
    }
    // The walk sampler is not the decoder.
    assert_ne!(images[0], images[1]);
}

/// The per-channel image mean of a coloured medium against grey media at each channel's σ_t, α
/// (whose vertex fits are the coloured medium's channel fits: the fit depends only on σ_n and
/// the seed). Each estimate is the mean over `SEEDS` independent renders; the tolerance is 4.5
/// standard errors of the difference, from the spread over seeds (a two-sided z-test with a
/// false-alarm rate of 7·10⁻⁶ per comparison, 9 comparisons).
#[test]
fn rgb_render_matches_three_grey_renders() {
    const SEEDS: u64 = 24;
    let accel = Accel::new(
        geometry::Shape::Sphere {
            radius: 0.5,
            subdivisions: 3,
        }
        .build()
        .unwrap(),
    );
    let model = model();
    let rgb = Medium {
        sigma_t: [30.0, 45.0, 70.0],
        albedo: [0.95, 0.85, 0.6],
        g: scene::Anisotropy::uniform(0.0),
        eta: 1.0,
        roughness: 0.0,
    };
    let cam = Camera::look_at(Vec3::new(0.5, 1.5, 1.0), Vec3::ZERO, Vec3::Y, 40.0, 12, 12);
    let light = PointLight {
        position: Vec3::new(1.0, 2.0, 0.0),
        intensity: [3.0; 3],
    };
    // Mean and standard error over seeds of the image mean, per channel.
    let stats = |medium: Medium, sampling: PixelSampling| -> ([f64; 3], [f64; 3]) {
        let features = VertexFeatures::fit(&accel, &medium, true, 0).unwrap();
        let settings = LearnedSettings {
            sampling,
            ..Default::default()
        };
        let scene = LearnedScene::new(&accel, &model, &features, medium, settings).unwrap();
        let means: Vec<[f64; 3]> = (0..SEEDS)
            .map(|seed| {
                let rs = RenderSettings {
                    spp: 7,
                    seed,
                    view: 0,
                };
                render_image(&scene, &cam, &light, &rs, None)
                    .unwrap()
                    .mean()
            })
            .collect();
        let n = SEEDS as f64;
        let mean: [f64; 3] = std::array::from_fn(|c| means.iter().map(|m| m[c]).sum::<f64>() / n);
        let se = std::array::from_fn(|c| {
            let var = means.iter().map(|m| (m[c] - mean[c]).powi(2)).sum::<f64>() / (n - 1.0);
            (var / n).sqrt()
        });
        (mean, se)
    };
    for sampling in [PixelSampling::Stratified, PixelSampling::OneHot] {
        let (m, se) = stats(rgb, sampling);
        for c in 0..3 {
            let grey = Medium {
                sigma_t: [rgb.sigma_t[c]; 3],
                albedo: [rgb.albedo[c]; 3],
                ..rgb
            };
            let (g, gse) = stats(grey, sampling);
            assert!(m[c] > 0.0 && g[c] > 0.0);
            let z = (m[c] - g[c]) / (se[c].powi(2) + gse[c].powi(2)).sqrt();
            assert!(
                z.abs() < 4.5,
                "{sampling:?} channel {c}: RGB mean {} ± {}, grey {} ± {} (z = {z:.2})",
                m[c],
                se[c],
                g[c],
                gse[c]
            );
        }
    }
}
