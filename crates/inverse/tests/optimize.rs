//! A tiny end-to-end optimisation: targets rendered by the learned
//! renderer with the shipped model at known parameters, the inverse loop started far away must
//! bring the error down substantially; a checkpointed run resumes bit-identically.

use crate::common;

use std::path::Path;

use bssrdf::nn::ShapeAdaptiveModel;
use bssrdf::render::{LearnedScene, LearnedSettings, RenderSettings, VertexFeatures, render_image};
use geometry::{Accel, Vec3};
use inverse::optimize::{Checkpoint, OptimizeConfig, Optimizer, TargetView};
use inverse::params::Params;
use scene::{Camera, Image, Medium, PointLight};

fn shipped() -> ShapeAdaptiveModel {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models/translucent-v2.safetensors");
    bssrdf::model::load(&p).unwrap()
}

struct Setup {
    accel: Accel,
    model: ShapeAdaptiveModel,
    views: Vec<(Camera, PointLight)>,
    targets: Vec<Image>,
    truth: Medium,
}

fn setup() -> Setup {
    let accel = common::sphere(0.5);
    let model = shipped();
    let truth = Medium {
        sigma_t: [60.0; 3],
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
                    position: o + Vec3::new(0.8, 0.8, 0.0),
                    intensity: [10.0; 3],
                },
            )
        })
        .collect();
    let features = VertexFeatures::fit(&accel, &truth, model.info().c19_quirk, 0).unwrap();
    let scene =
        LearnedScene::new(&accel, &model, &features, truth, LearnedSettings::default()).unwrap();
    let targets = views
        .iter()
        .enumerate()
        .map(|(i, (c, l))| {
            let rs = RenderSettings {
                spp: 256,
                seed: 99,
                view: i as u64,
            };
            render_image(&scene, c, l, &rs, None).unwrap()
        })
        .collect();
    Setup {
        accel,
        model,
        views,
        targets,
        truth,
    }
}

fn targets(s: &Setup) -> Vec<TargetView<'_>> {
    s.views
        .iter()
        .zip(&s.targets)
        .map(|((c, l), img)| TargetView {
            camera: c,
            light: l,
            image: img,
        })
        .collect()
}

fn config(iterations: u32) -> OptimizeConfig {
    let mut c = OptimizeConfig::new(Params {
        sigma_t: [60.0; 3],
        albedo: [0.5; 3],
        g: None,
        light_scale: None,
    });
    c.iterations = iterations;
    c.refine_iterations = 0;
    c.spp = 8;
    c.views_per_iter = 2;
    c.lr_albedo = 0.03;
    c.params.fix_sigma_t = true;
    c.two_renders = true;
    c.seed = 5;
    c
}

#[test]
fn albedo_error_falls_and_resume_is_bit_identical() {
    let s = setup();
    let truth = Params::of(&s.truth);
    let err = |p: &Params| {
        (0..3)
            .map(|c| (p.albedo[c] - truth.albedo[c]).abs())
            .fold(0.0, f64::max)
    };
    let mut full =
        Optimizer::new(config(40), &s.accel, Some(&s.model), s.truth, targets(&s)).unwrap();
    let start = err(&full.params());
    full.run(None, |_, _| {}).unwrap();
    let end = err(&full.params());
    assert!(
        end < 0.2 * start,
        "α error did not fall substantially: {start:.3} -> {end:.3} ({:?})",
        full.params().albedo
    );
    assert!(full.history().iter().all(|r| r.loss.is_finite()));

    // Interrupted at 20 by a checkpoint, resumed to 40: same parameters.
    let dir = tempfile::tempdir().unwrap();
    let ck = dir.path().join("checkpoint.json");
    let mut part =
        Optimizer::new(config(20), &s.accel, Some(&s.model), s.truth, targets(&s)).unwrap();
    part.run(Some((&ck, 10)), |_, _| {}).unwrap();
    let mut resumed = Optimizer::resume(
        Checkpoint::read(&ck).unwrap(),
        Some((40, 0)),
        &s.accel,
        Some(&s.model),
        s.truth,
        targets(&s),
    )
    .unwrap();
    resumed.run(None, |_, _| {}).unwrap();
    // The resumed run follows the uninterrupted one. (Two runs of the differentiable renderer
    // in one process can differ in the last bits of the f64 gradient sums — an open finding — so this compares to 1e-9 instead of bit for bit.)
    let (a, b) = (resumed.params(), full.params());
    for c in 0..3 {
        assert!((a.albedo[c] - b.albedo[c]).abs() < 1e-9, "{a:?} vs {b:?}");
        assert!((a.sigma_t[c] - b.sigma_t[c]).abs() < 1e-9, "{a:?} vs {b:?}");
    }
    assert_eq!(resumed.history().len(), 40);
    for (r, f) in resumed.history().iter().zip(full.history()) {
        assert_eq!(r.views, f.views);
        assert!(
            (r.loss - f.loss).abs() <= 1e-9 * f.loss.abs(),
            "{} vs {}",
            r.loss,
            f.loss
        );
    }
}

/// Albedo first: σ_t keeps its initial value exactly for the warm-up iterations while α moves,
/// and moves afterwards (16 iterations: the warm-up is at most a third of the run).
#[test]
fn albedo_warmup_holds_sigma_t_then_releases_it() {
    let s = setup();
    let mut c = config(16);
    c.params.fix_sigma_t = false;
    c.lr_sigma_t = 0.05;
    c.albedo_warmup = 5;
    let mut o = Optimizer::new(c, &s.accel, Some(&s.model), s.truth, targets(&s)).unwrap();
    o.run(None, |_, _| {}).unwrap();
    let h = o.history();
    let init = h[0].params.sigma_t;
    for r in &h[..6] {
        // Record k holds the parameters before step k: steps 0..4 are the warm-up.
        assert_eq!(r.params.sigma_t, init, "iteration {}", r.iteration);
    }
    assert!(h[5].params.albedo != h[0].params.albedo, "α did not move");
    let end = o.params();
    assert!(
        (0..3).all(|ch| end.sigma_t[ch] != init[ch]),
        "σ_t did not move after the warm-up: {:?}",
        end.sigma_t
    );
}

/// Random crops (the paper's released optimiser): a crop as large as the image is the whole
/// image (same iterations), and 12×12 crops of the 20×20 views still recover α.
#[test]
fn crops_are_windows_and_still_recover_albedo() {
    let s = setup();
    let run = |crop: Option<u32>, iterations: u32| {
        let mut c = config(iterations);
        c.crop = crop;
        let mut o = Optimizer::new(c, &s.accel, Some(&s.model), s.truth, targets(&s)).unwrap();
        o.run(None, |_, _| {}).unwrap();
        o
    };
    let (whole, covering) = (run(None, 4), run(Some(64), 4));
    for (a, b) in whole.history().iter().zip(covering.history()) {
        assert!(
            (a.loss - b.loss).abs() <= 1e-9 * a.loss.abs(),
            "{} vs {}",
            a.loss,
            b.loss
        );
    }
    let truth = Params::of(&s.truth);
    let err = |p: &Params| {
        (0..3)
            .map(|c| (p.albedo[c] - truth.albedo[c]).abs())
            .fold(0.0, f64::max)
    };
    let cropped = run(Some(12), 40);
    // Every iteration records one crop origin per view, inside the 20×20 image, and the
    // windows move (a fixed window would be a bug of the stream).
    let origins: Vec<[u32; 2]> = cropped
        .history()
        .iter()
        .flat_map(|r| {
            assert_eq!(r.crop_origins.len(), r.views.len());
            r.crop_origins.clone()
        })
        .collect();
    assert!(
        origins.iter().all(|&[x, y]| x <= 8 && y <= 8),
        "{origins:?}"
    );
    assert!(origins.iter().any(|o| *o != origins[0]), "{origins:?}");
    assert!(whole.history().iter().all(|r| r.crop_origins.is_empty()));
    let (start, end) = (err(&config(1).init), err(&cropped.params()));
    assert!(
        end < 0.25 * start,
        "α error with crops did not fall substantially: {start:.3} -> {end:.3}"
    );
}

#[test]
fn damaged_checkpoint_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let ck = dir.path().join("checkpoint.json");
    std::fs::write(&ck, "{ not json").unwrap();
    let e = Checkpoint::read(&ck).err().unwrap().to_string();
    assert!(
        e.contains("checkpoint.json") && e.contains("damaged"),
        "{e}"
    );
}

/// A checkpoint's configuration is checked when it is read (`OptimizeConfig::check`), as a new
/// run's is: a damaged setting (no views per iteration, 10¹² of them, a zero offset
/// `delta_rel`, a negative σ_t, an empty crop, a view named twice) is refused naming the file
/// and the field, instead of failing or allocating later in the resumed run (before, `read`
/// checked the format and the variables only, and `resume` trusted the settings).
#[test]
fn checkpoint_settings_are_checked_when_read() {
    let s = setup();
    let dir = tempfile::tempdir().unwrap();
    let ck = dir.path().join("checkpoint.json");
    let mut o = Optimizer::new(config(1), &s.accel, Some(&s.model), s.truth, targets(&s)).unwrap();
    o.run(Some((&ck, 1)), |_, _| {}).unwrap();
    let good: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&ck).unwrap()).unwrap();
    assert!(Checkpoint::read(&ck).is_ok());
    let cases: [(&str, serde_json::Value, &str); 6] = [
        ("views_per_iter", 0.into(), "views per iteration"),
        (
            "views_per_iter",
            1_000_000_000_000u64.into(),
            "views_per_iter",
        ),
        ("delta_rel", serde_json::json!(0.0), "delta_rel"),
        (
            "init",
            serde_json::json!({"sigma_t": [-1.0, 50.0, 50.0], "albedo": [0.5, 0.5, 0.5]}),
            "init.sigma_t",
        ),
        ("crop", 0.into(), "crop"),
        ("view_subset", serde_json::json!([1, 0, 1]), "view_subset"),
    ];
    for (field, value, expect) in cases {
        let mut v = good.clone();
        v["config"][field] = value;
        std::fs::write(&ck, v.to_string()).unwrap();
        let e = Checkpoint::read(&ck)
            .err()
            .unwrap_or_else(|| panic!("{field} must be refused"))
            .to_string();
        assert!(e.contains("checkpoint.json") && e.contains(expect), "{e}");
    }
    // One Adam step per recorded iteration at most.
    let mut v = good.clone();
    v["adam_step"] = u64::MAX.into();
    std::fs::write(&ck, v.to_string()).unwrap();
    let e = Checkpoint::read(&ck).err().unwrap().to_string();
    assert!(
        e.contains("checkpoint.json") && e.contains("adam_step"),
        "{e}"
    );
}

/// `view_weights`: a view 10× brighter gets 1/100 of the L2 weight (1/10 for L1), so every view's
/// black-image loss weighs the same; a view dimmer than the floor is capped at 1/floor times the
/// mean; without normalisation all weights are 1.
#[test]
fn view_weights_equalise_black_losses_with_a_floor() {
    use bssrdf::diff::Loss;
    use inverse::optimize::view_weights;
    let s = setup();
    let a = &s.targets[0];
    let scaled = |k: f32| {
        let mut im = a.clone();
        im.data.iter_mut().for_each(|p| *p = p.map(|v| v * k));
        im
    };
    let (b, dim) = (scaled(10.0), scaled(1e-3));
    assert!(
        view_weights(&[a, &b], Loss::L2, false, 0.01)
            .iter()
            .all(|w| *w == [1.0; 3])
    );
    for (loss, power) in [(Loss::L2, 2), (Loss::L1, 1)] {
        let w = view_weights(&[a, &b], loss, true, 1e-6);
        for c in 0..3 {
            let ratio = w[0][c] / w[1][c];
            let want = 10f64.powi(power);
            assert!((ratio / want - 1.0).abs() < 1e-5, "{loss:?} c{c}: {ratio}");
        }
        // With a floor of 0.1 the dim view's normaliser is 0.1 of the mean: weight 10.
        let w = view_weights(&[a, &b, &dim], loss, true, 0.1);
        for c in 0..3 {
            assert!((w[2][c] - 10.0).abs() < 1e-9, "{loss:?} c{c}: {}", w[2][c]);
        }
    }
}

/// The optimiser applies the weights: one iteration with `normalize_views` has the gradient of
/// the same iteration without it times the drawn view's weight (same seed, same renders).
#[test]
fn normalized_views_scale_the_drawn_views_gradient() {
    use inverse::optimize::view_weights;
    let s = setup();
    let mut c = config(1);
    c.views_per_iter = 1;
    let mut plain =
        Optimizer::new(c.clone(), &s.accel, Some(&s.model), s.truth, targets(&s)).unwrap();
    c.normalize_views = true;
    let mut weighted =
        Optimizer::new(c.clone(), &s.accel, Some(&s.model), s.truth, targets(&s)).unwrap();
    let (p, w) = (
        plain.step().unwrap().clone(),
        weighted.step().unwrap().clone(),
    );
    assert_eq!(p.views, w.views);
    let v = p.views[0];
    let images: Vec<&Image> = s.targets.iter().collect();
    let weights = view_weights(&images, c.loss, true, c.view_weight_floor);
    assert!(
        weights.iter().any(|w| (w[0] - 1.0).abs() > 0.05),
        "{weights:?}"
    );
    for ch in 0..3 {
        let want = p.d_albedo[ch] * weights[v][ch];
        assert!(
            (w.d_albedo[ch] - want).abs() <= 1e-12 * want.abs().max(1e-30),
            "c{ch}: {} vs {want}",
            w.d_albedo[ch]
        );
        assert!(p.d_albedo[ch] != 0.0);
    }
    // A floor outside (0, 1] is refused with its name.
    c.view_weight_floor = 0.0;
    let err = Optimizer::new(c, &s.accel, Some(&s.model), s.truth, targets(&s))
        .err()
        .expect("a zero floor is refused");
    assert!(err.to_string().contains("view_weight_floor"), "{err}");
}

/// Options added after runs were written stay out of the configuration's JSON at their defaults,
/// so `experiment` and `--resume` still recognise those runs as made with the same settings.
#[test]
fn config_json_leaves_out_default_view_normalisation() {
    let mut c = config(3);
    let v = serde_json::to_value(&c).unwrap();
    assert!(v.get("normalize_views").is_none(), "{v}");
    assert!(v.get("view_weight_floor").is_none(), "{v}");
    let back: OptimizeConfig = serde_json::from_value(v).unwrap();
    assert_eq!(back, c);
    c.normalize_views = true;
    c.view_weight_floor = 0.2;
    let v = serde_json::to_value(&c).unwrap();
    assert_eq!(v["normalize_views"], true);
    assert_eq!(v["view_weight_floor"], 0.2);
    assert_eq!(serde_json::from_value::<OptimizeConfig>(v).unwrap(), c);
}

/// The 95 % intervals ([`inverse::uncertainty`]) on a case where the model is exact: targets
/// rendered by the learned renderer itself at the truth (each seed its own target noise), the
/// run started at the truth with the default settings, the interval without the allowance for
/// the model's brightness error (there is none). Over 12 seeds × 6 parameters the truth
/// must lie inside the interval at least as often as a 95 % interval allows: 72 pairs, binomial
/// s.d. √(0.95·0.05/72) = 0.026, so coverage ≥ 0.95 − 3·0.026 ≈ 0.87 (the pairs of one seed
/// share a run, so this is a lenient bound rather than an exact one). Six 32² views with the
/// light beside the object give every parameter a finite interval around its estimate.
#[test]
fn intervals_cover_the_truth_where_the_model_is_exact() {
    let s = setup();
    let truth = Params::of(&s.truth);
    let views: Vec<(Camera, PointLight)> = (0..6)
        .map(|i| {
            let t = i as f32 * std::f32::consts::TAU / 6.0;
            let o = Vec3::new(2.0 * t.cos(), 0.4 * (i as f32 - 2.5), 2.0 * t.sin());
            (
                Camera::look_at(o, Vec3::ZERO, Vec3::Y, 30.0, 32, 32),
                // The light 90° from the camera about the object: light that crossed it.
                PointLight {
                    position: 2.0 * o.cross(Vec3::Y).normalize(),
                    intensity: [10.0; 3],
                },
            )
        })
        .collect();
    let features = VertexFeatures::fit(&s.accel, &s.truth, s.model.info().c19_quirk, 0).unwrap();
    let scene = LearnedScene::new(
        &s.accel,
        &s.model,
        &features,
        s.truth,
        LearnedSettings::default(),
    )
    .unwrap();
    let (mut covered, mut pairs) = (0, 0);
    for seed in 0..12u64 {
        let images: Vec<Image> = views
            .iter()
            .enumerate()
            .map(|(i, (c, l))| {
                let rs = RenderSettings {
                    spp: 64,
                    seed: 1000 + seed,
                    view: i as u64,
                };
                render_image(&scene, c, l, &rs, None).unwrap()
            })
            .collect();
        let targets: Vec<TargetView> = views
            .iter()
            .zip(&images)
            .map(|((c, l), img)| TargetView {
                camera: c,
                light: l,
                image: img,
            })
            .collect();
        let mut c = OptimizeConfig::new(truth).with_iterations(30);
        c.refine_iterations = 0;
        c.spp = 8;
        c.seed = seed;
        let mut o = Optimizer::new(c, &s.accel, Some(&s.model), s.truth, targets).unwrap();
        o.run(None, |_, _| {}).unwrap();
        let u = o
            .uncertainty(
                &inverse::uncertainty::UncertaintySettings {
                    views: 6,
                    spp: 64,
                    // The model is exact here: no allowance for its brightness error.
                    model_brightness_sd: 0.0,
                    ..Default::default()
                },
                &[],
            )
            .unwrap();
        let est = o.params();
        for ch in 0..3 {
            let [lo, hi] = u.sigma_t[ch].expect("finite σ_t interval");
            assert!(lo < est.sigma_t[ch] && est.sigma_t[ch] < hi);
            let [alo, ahi] = u.albedo[ch].expect("finite α interval");
            assert!(alo < est.albedo[ch] && est.albedo[ch] < ahi);
            covered += usize::from(lo <= truth.sigma_t[ch] && truth.sigma_t[ch] <= hi);
            covered += usize::from(alo <= truth.albedo[ch] && truth.albedo[ch] <= ahi);
            pairs += 2;
        }
    }
    let f = covered as f64 / pairs as f64;
    eprintln!("coverage {covered}/{pairs} = {f:.3}");
    assert!(f >= 0.87, "coverage {covered}/{pairs} = {f:.3}");
}

/// The split-sample gradient (two derivative renders at half the samples each, the default)
/// has the expectation of the two-full-renders gradient: both are unbiased estimates of the
/// loss gradient without the covariance term of a single render. Per parameter, the means over
/// 24 iterations (each its own random numbers) agree within 4.5 standard errors of their
/// difference (a two-sided z-test, false alarm 7·10⁻⁶ per parameter).
#[test]
fn split_sample_gradient_has_the_two_render_expectation() {
    let s = setup();
    let at = Params {
        sigma_t: [72.0, 66.0, 54.0],
        albedo: [0.86, 0.82, 0.83],
        g: None,
        light_scale: None,
    };
    let grads = |split: bool| -> Vec<[f64; 6]> {
        let mut c = OptimizeConfig::new(at);
        c.spp = 8;
        c.views_per_iter = 2;
        c.split_samples = split;
        let o = Optimizer::new(c, &s.accel, Some(&s.model), s.truth, targets(&s)).unwrap();
        (0..24)
            .map(|k| {
                let g = o.gradient(k, &at).unwrap();
                [
                    g.d_sigma_t[0],
                    g.d_sigma_t[1],
                    g.d_sigma_t[2],
                    g.d_albedo[0],
                    g.d_albedo[1],
                    g.d_albedo[2],
                ]
            })
            .collect()
    };
    let stats = |g: &[[f64; 6]], i: usize| {
        let n = g.len() as f64;
        let m = g.iter().map(|v| v[i]).sum::<f64>() / n;
        let var = g.iter().map(|v| (v[i] - m).powi(2)).sum::<f64>() / (n - 1.0);
        (m, var / n)
    };
    let (a, b) = (grads(true), grads(false));
    for i in 0..6 {
        let ((ma, va), (mb, vb)) = (stats(&a, i), stats(&b, i));
        let z = (ma - mb) / (va + vb).sqrt();
        assert!(
            z.abs() < 4.5,
            "parameter {i}: split {ma:.4e} ± {:.2e}, full {mb:.4e} ± {:.2e} (z = {z:.2})",
            va.sqrt(),
            vb.sqrt()
        );
        // Away from the minimum the gradient is resolved, not noise.
        assert!(
            ma.abs() > 3.0 * va.sqrt() || i < 3,
            "parameter {i}: {ma:.3e} ± {:.2e}",
            va.sqrt()
        );
    }
}

/// A NaN that reaches the optimiser (here a NaN pixel in target view 1, which the command line
/// refuses up front but a library caller might pass) is caught in the iteration and view where it
/// first appears; the optimiser keeps its last finite parameters and a checkpoint written
/// afterwards holds no NaN.
#[test]
fn non_finite_gradient_names_iteration_and_view_and_keeps_the_last_good_state() {
    let mut s = setup();
    s.targets[1].data[7] = [f32::NAN, 0.0, 0.0];
    let mut c = config(20);
    c.views_per_iter = 1;
    let mut opt = Optimizer::new(c, &s.accel, Some(&s.model), s.truth, targets(&s)).unwrap();
    let err = loop {
        match opt.step() {
            Ok(_) => continue,
            Err(e) => break e,
        }
    };
    let k = opt.history().len();
    match &err {
        inverse::optimize::InverseError::NonFinite {
            iteration, view, ..
        } => {
            assert_eq!(*iteration as usize, k, "{err}");
            assert_eq!(*view, Some(1), "{err}");
        }
        other => panic!("expected NonFinite, got {other}"),
    }
    let msg = err.to_string();
    assert!(msg.contains(&format!("iteration {k}, view 1")), "{msg}");
    let p = opt.params();
    assert!(
        p.sigma_t.iter().chain(&p.albedo).all(|v| v.is_finite()),
        "{p:?}"
    );
    assert!(opt.history().iter().all(|r| r.loss.is_finite()));
    let dir = tempfile::tempdir().unwrap();
    let ck = dir.path().join("checkpoint.json");
    opt.save_checkpoint(&ck).unwrap();
    // (serde_json writes a NaN as null; the reader refuses non-finite variables.)
    let back = Checkpoint::read(&ck).unwrap();
    assert_eq!(back.history.len(), k);
    for r in &back.history {
        let p = &r.params;
        assert!(r.loss.is_finite());
        assert!(p.sigma_t.iter().chain(&p.albedo).all(|v| v.is_finite()));
        assert!(r.d_sigma_t.iter().chain(&r.d_albedo).all(|v| v.is_finite()));
    }
}

/// Six iterations, the last two refined by the volumetric path tracer at depth 8.
fn refined_config() -> OptimizeConfig {
    let mut c = config(6);
    c.refine_iterations = 2;
    c.volpath_max_depth = Some(8);
    c
}

/// `refine_iterations`: the last iterations of a run use the volumetric path tracer. After the
/// run, the optimiser renders exactly as a run of the tracer itself does (and not as the
/// learned model does), a run resumed from a checkpoint inside the refinement ends where the
/// uninterrupted one does, the setting is left out of the JSON when 0, and impossible settings
/// are refused.
#[test]
fn refinement_switches_to_the_volumetric_tracer_for_the_last_iterations() {
    use inverse::forward::{ModelChoice, ModelKind, TracerEstimator};
    let s = setup();
    let c = refined_config();
    assert_eq!(c.model_at(3).kind(), ModelKind::Learned);
    assert_eq!(c.model_at(4), ModelChoice::Volpath(TracerEstimator::Ad));
    assert_eq!(c.final_model(), ModelKind::Volpath);
    assert_eq!(serde_json::to_value(&c).unwrap()["refine_iterations"], 2);
    assert!(
        serde_json::to_value(config(6))
            .unwrap()
            .get("refine_iterations")
            .is_none()
    );

    let mut full =
        Optimizer::new(c.clone(), &s.accel, Some(&s.model), s.truth, targets(&s)).unwrap();
    full.run(None, |_, _| {}).unwrap();
    let p = full.params();
    let (camera, light) = &s.views[0];
    let rs = RenderSettings {
        spp: 4,
        seed: 3,
        view: 0,
    };
    let refined = full.render(&p, camera, light, &rs).unwrap();
    let mut tracer = c.clone();
    (tracer.model, tracer.refine_iterations) = (ModelChoice::Volpath(TracerEstimator::Ad), 0);
    let by_tracer = Optimizer::new(tracer, &s.accel, Some(&s.model), s.truth, targets(&s))
        .unwrap()
        .render(&p, camera, light, &rs)
        .unwrap();
    assert_eq!(
        refined.data, by_tracer.data,
        "the refinement renders with the tracer"
    );
    let mut learned = c.clone();
    learned.refine_iterations = 0;
    let by_model = Optimizer::new(learned, &s.accel, Some(&s.model), s.truth, targets(&s))
        .unwrap()
        .render(&p, camera, light, &rs)
        .unwrap();
    assert_ne!(refined.data, by_model.data);

    // Interrupted inside the refinement and resumed: the same end.
    let dir = tempfile::tempdir().unwrap();
    let ck = dir.path().join("checkpoint.json");
    let mut part = c.clone();
    part.iterations = 5;
    part.refine_iterations = 1;
    let mut part = Optimizer::new(part, &s.accel, Some(&s.model), s.truth, targets(&s)).unwrap();
    part.run(Some((&ck, 1)), |_, _| {}).unwrap();
    // The checkpoint of iteration 5 of the full run's settings (its first four iterations are
    // those of `full`, its fifth the first of the refinement).
    let mut ckpt = Checkpoint::read(&ck).unwrap();
    (ckpt.config.iterations, ckpt.config.refine_iterations) = (6, 2);
    let longer = || Checkpoint::read(&ck).unwrap();
    let e = Optimizer::resume(
        longer(),
        Some((6, 1)),
        &s.accel,
        Some(&s.model),
        s.truth,
        targets(&s),
    )
    .err()
    .expect("extending a refined run with the same refinement would move it");
    assert!(e.to_string().contains("(refine 2)"), "{e}");
    // The same length with the refinement kept where it began is the full run.
    assert!(
        Optimizer::resume(
            longer(),
            Some((6, 2)),
            &s.accel,
            Some(&s.model),
            s.truth,
            targets(&s)
        )
        .is_ok()
    );
    let mut resumed =
        Optimizer::resume(ckpt, None, &s.accel, Some(&s.model), s.truth, targets(&s)).unwrap();
    resumed.run(None, |_, _| {}).unwrap();
    let (a, b) = (resumed.params(), full.params());
    for ch in 0..3 {
        assert!((a.albedo[ch] - b.albedo[ch]).abs() < 1e-9, "{a:?} vs {b:?}");
    }

    let mut bad = c.clone();
    bad.refine_iterations = 7;
    assert!(bad.check().unwrap_err().contains("refine_iterations"));
    let mut bad = c;
    bad.model = ModelChoice::Volpath(TracerEstimator::Ad);
    assert!(bad.check().unwrap_err().contains("refine_iterations"));
}

/// `refine_spp`: the refinement's iterations render at their own samples per pixel and the
/// others at `spp`. A run with `refine_spp = spp` is the run without it, bit for bit; with fewer
/// samples the iterations before the refinement are unchanged and the refinement's gradients
/// differ. It is left out of the JSON when unset, and refused at 0 or without a refinement.
#[test]
fn refine_spp_sets_the_samples_of_the_refinement_alone() {
    let s = setup();
    let c = refined_config();
    assert!(
        serde_json::to_value(&c)
            .unwrap()
            .get("refine_spp")
            .is_none()
    );
    let history = |c: &OptimizeConfig| {
        let mut o =
            Optimizer::new(c.clone(), &s.accel, Some(&s.model), s.truth, targets(&s)).unwrap();
        o.run(None, |_, _| {}).unwrap();
        o.history()
            .iter()
            .map(|r| (r.loss, r.d_albedo, r.params.albedo))
            .collect::<Vec<_>>()
    };
    let plain = history(&c);
    let mut same = c.clone();
    same.refine_spp = Some(c.spp);
    assert_eq!(history(&same), plain);
    let mut fewer = c.clone();
    fewer.refine_spp = Some(2);
    assert_eq!(
        (fewer.spp_at(3), fewer.spp_at(4), fewer.spp_at(5)),
        (8, 2, 2)
    );
    assert_eq!(serde_json::to_value(&fewer).unwrap()["refine_spp"], 2);
    let back: OptimizeConfig =
        serde_json::from_value(serde_json::to_value(&fewer).unwrap()).unwrap();
    assert_eq!(back, fewer);
    let cheap = history(&fewer);
    assert_eq!(
        cheap[..4],
        plain[..4],
        "the learned iterations are unchanged"
    );
    assert_ne!(
        cheap[4].1, plain[4].1,
        "the refinement renders fewer samples"
    );

    let mut bad = fewer.clone();
    bad.refine_spp = Some(0);
    assert!(bad.check().unwrap_err().contains("refine_spp"));
    let mut bad = fewer;
    bad.refine_iterations = 0;
    assert!(bad.check().unwrap_err().contains("refine_spp"));
}
