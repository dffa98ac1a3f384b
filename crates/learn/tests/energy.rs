//! The energy-score objective (`learn::energy`): its gradient against an independent f64
//! reference (tolerances as in `gradients.rs`), the consistency of its reported parts, the
//! encoder untouched, determinism across thread counts, and a tiny training run that fits a
//! known conditional distribution with a sharp core and a long tail, where the CVAE's
//! reconstruction objective is not asked to.

use crate::common;
use common::*;

use base::rng::Sampler;
use bssrdf::model::ModelInfo;
use bssrdf::nn::{INPUT_DIM, LATENT_DIM, Normalisation, POSITION_DIM, ShapeAdaptiveModel};
use learn::cvae::{Gradients, Widths, init_model, params_to_flat};
use learn::energy::{EnergyBatch, EnergyWeights, loss_and_grad, loss_only};
use learn::optim::AdamConfig;
use learn::train::{Objective, Prepared, TrainConfig, Trainer};

const DRAWS: usize = 5;

/// `rows × DRAWS × 4` latent values.
fn latents(rows: usize, seed: u64) -> Vec<f32> {
    let mut s = Sampler::new(seed, 3, 3, 3);
    uniform(&mut s, rows * DRAWS * LATENT_DIM, 1.7)
}

fn batch<'a>(d: &'a Data, z: &'a [f32]) -> EnergyBatch<'a> {
    EnergyBatch {
        inputs: &d.inputs,
        targets: &d.targets,
        absorption: &d.absorption,
        z,
        draws: DRAWS,
    }
}

/// The energy objective in f64 (batch mean) and the smallest ReLU margin.
fn loss64(r: &Model64, p: &[f64], d: &Data, z: &[f32], w: &EnergyWeights) -> (f64, f64) {
    let off = r.offsets();
    let rows = d.absorption.len();
    let mut margin = f64::INFINITY;
    let mut total = 0.0;
    let dist = |a: &[f64], b: &[f64]| (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt();
    for i in 0..rows {
        let (x, f, s) = r.row(p, d, i, &mut margin);
        let y: Vec<Vec<f64>> = (0..DRAWS)
            .map(|j| {
                let q = (i * DRAWS + j) * LATENT_DIM;
                let dec_in: Vec<f64> = z[q..q + LATENT_DIM]
                    .iter()
                    .map(|&v| v as f64)
                    .chain(f.iter().copied())
                    .collect();
                forward64(p, off[2].start, &r.blocks[2], &dec_in, &mut margin)
            })
            .collect();
        let m = DRAWS as f64;
        let near: f64 = y.iter().map(|yj| dist(yj, &x)).sum::<f64>() / m;
        let mut spread = 0.0;
        for j in 0..DRAWS {
            for l in j + 1..DRAWS {
                spread += dist(&y[j], &y[l]);
            }
        }
        let es = near - spread / (m * (m - 1.0));
        let a = 1.0 / (1.0 + (-s).exp());
        total += w.energy as f64 * es + w.absorption as f64 * (a - d.absorption[i] as f64).powi(2);
    }
    (total / rows as f64, margin)
}

/// Every block's parameters (10 each) for the total and for each term alone; 70 rows so that
/// two sub-batches are summed. The encoder's gradient is exactly zero.
#[test]
fn energy_gradient_matches_f64_reference() {
    let d = data(70, 11);
    let z = latents(70, 1);
    let m = small_model(4);
    let r = Model64::new(&m);
    let idx = indices_per_block(&r, 10, 7);
    let p0: Vec<f64> = params_to_flat(&m).iter().map(|&v| v as f64).collect();
    for (label, w) in [
        ("total", (100.0, 5000.0)),
        ("energy term", (1.0, 0.0)),
        ("absorption term", (0.0, 1.0)),
    ] {
        let w = EnergyWeights {
            energy: w.0,
            absorption: w.1,
        };
        let mut g = Gradients::zeros_like(&m);
        let parts = loss_and_grad(&m, &batch(&d, &z), &w, &mut g).unwrap();
        check_gradient(label, &r, g.as_flat(), parts.total, &p0, &idx, |p| {
            loss64(&r, p, &d, &z, &w)
        });
        let enc = r.offsets()[3].start;
        assert!(
            g.as_flat()[enc..].iter().all(|&v| v == 0.0),
            "{label}: the encoder got a gradient"
        );
    }
}

/// `loss_only` equals `loss_and_grad`'s parts; weighted = weight × unweighted; total = sum;
/// the energy score of a batch is at most the mean distance of the proposals to the targets.
/// The gradient is bit-identical on 1 and 3 threads.
#[test]
fn energy_parts_are_consistent_and_deterministic() {
    let d = data(200, 3);
    let z = latents(200, 2);
    let m = small_model(5);
    let w = EnergyWeights {
        energy: 100.0,
        absorption: 5000.0,
    };
    let run = |threads: usize| {
        on_threads(threads, || {
            let mut g = Gradients::zeros_like(&m);
            let p = loss_and_grad(&m, &batch(&d, &z), &w, &mut g).unwrap();
            (p, g.as_flat().to_vec())
        })
    };
    let (a, g1) = run(1);
    let (a3, g3) = run(3);
    assert_eq!(a.total.to_bits(), a3.total.to_bits());
    assert_eq!(g1, g3);
    let b = loss_only(&m, &batch(&d, &z), &w).unwrap();
    let close = |x: f64, y: f64| (x - y).abs() <= 1e-6 * x.abs().max(1.0);
    assert!(
        close(a.total, b.total) && close(a.energy, b.energy),
        "{a:?} vs {b:?}"
    );
    assert!(close(a.energy, 100.0 * a.energy_score));
    assert!(close(a.absorption, 5000.0 * a.absorption_mse));
    assert!(close(a.total, a.energy + a.absorption));
    assert!(a.kl == 0.0 && a.position == 0.0);
    // Bad batches.
    let one = EnergyBatch {
        draws: 1,
        z: &z[..200 * LATENT_DIM],
        ..batch(&d, &z)
    };
    let mut g = Gradients::zeros_like(&m);
    assert!(loss_and_grad(&m, &one, &w, &mut g).is_err());
    let short = EnergyBatch {
        z: &z[..10],
        ..batch(&d, &z)
    };
    assert!(loss_only(&m, &short, &w).is_err());
}

// ---------------------------------------------------------------------------------------------
// Fitting a known distribution

/// The exit distance of the synthetic data: r = s(u₀)·E with E ~ Exp(1) (a sharp core at the
/// entry point and an exponential tail), in the tangent plane at a uniform angle; the scale
/// s(u₀) = exp(u₀/2) follows the first network input u₀ ∈ [−1, 1] (the other inputs are 0).
fn scale(u0: f32) -> f32 {
    (0.5 * u0).exp()
}

fn synthetic(rows: usize, seed: u64) -> Prepared {
    let mut s = Sampler::new(seed, 11, 11, 11);
    let mut p = Prepared::default();
    for _ in 0..rows {
        let mut u = vec![0.0f32; INPUT_DIM];
        u[0] = 2.0 * s.next_f32() - 1.0;
        let r = -scale(u[0]) * (1.0 - s.next_f32()).ln();
        let phi = std::f32::consts::TAU * s.next_f32();
        p.inputs.extend_from_slice(&u);
        p.targets
            .extend_from_slice(&[r * phi.cos(), r * phi.sin(), 0.0][..POSITION_DIM]);
        p.absorption.push(0.5);
    }
    p
}

/// Quantiles `qs` of the proposals' distance from the entry point for input `u0` (the other
/// inputs 0), from `n` latent draws.
fn proposal_quantiles(m: &ShapeAdaptiveModel, u0: f32, qs: &[f64], n: usize) -> Vec<f64> {
    let mut u = [0.0f32; INPUT_DIM];
    u[0] = u0;
    let inputs: Vec<f32> = (0..n).flat_map(|_| u.iter().copied()).collect();
    let mut s = Sampler::new(9, 9, 9, 9);
    let z: Vec<f32> = (0..n * LATENT_DIM)
        .map(|_| {
            // Standard normal by Box–Muller (one value per pair of uniforms).
            let (a, b) = (s.next_f32().max(1e-9), s.next_f32());
            (-2.0 * a.ln()).sqrt() * (std::f32::consts::TAU * b).cos()
        })
        .collect();
    let mut tape = learn::mlp_grad::MlpTape::default();
    tape.forward(m.feature_mlp(), &inputs, n);
    let fd = m.feature_mlp().n_out();
    let dec_in: Vec<f32> = (0..n)
        .flat_map(|i| {
            z[i * LATENT_DIM..(i + 1) * LATENT_DIM]
                .iter()
                .chain(&tape.output()[i * fd..(i + 1) * fd])
                .copied()
                .collect::<Vec<_>>()
        })
        .collect();
    let mut dec = learn::mlp_grad::MlpTape::default();
    dec.forward(m.decoder(), &dec_in, n);
    let mut r: Vec<f64> = dec
        .output()
        .chunks_exact(3)
        .map(|y| ((y[0] * y[0] + y[1] * y[1] + y[2] * y[2]) as f64).sqrt())
        .collect();
    r.sort_by(f64::total_cmp);
    qs.iter().map(|&q| r[(q * n as f64) as usize]).collect()
}

/// Worst relative error of the proposals' distance quantiles `QS` against Exp(1)'s, −ln(1 − q)
/// times the scale, at three inputs; separately for q ≤ 0.9 and for q = 0.99.
const QS: [f64; 4] = [0.25, 0.5, 0.9, 0.99];

fn worst_quantile_errors(m: &ShapeAdaptiveModel, label: &str) -> (f64, f64) {
    let (mut body, mut tail) = (0.0f64, 0.0f64);
    for u0 in [-1.0f32, 0.0, 1.0] {
        let got = proposal_quantiles(m, u0, &QS, 40_000);
        for (&q, &g) in QS.iter().zip(&got) {
            let want = -(scale(u0) as f64) * (1.0 - q).ln();
            let rel = (g / want - 1.0).abs();
            eprintln!(
                "{label}: u0 = {u0}, q = {q}: {g:.3} vs {want:.3} ({:.1} %)",
                100.0 * rel
            );
            if q < 0.95 {
                body = body.max(rel);
            } else {
                tail = tail.max(rel);
            }
        }
    }
    (body, tail)
}

/// A small model trained on the synthetic data with the energy objective from a fresh
/// initialisation matches the distribution's quantiles of distance at three inputs, and the
/// same model trained for the same steps with the CVAE objective does not.
///
/// The sample quantiles of 40,000 proposals have relative standard errors of 0.5–1.1 % at
/// q = 0.25–0.99 (for Exp(1): √(q(1−q)/n) / ((1−q)·(−ln(1−q)))), so the tolerances are the
/// network's approximation error after 8,000 steps: 12 % up to q = 0.9 and 30 % at q = 0.99,
/// where the exponential tail is thinnest in the data. A model with the wrong scale law (the
/// quantiles of an input ±1 away: a factor 0.61 or 1.65) fails both. The CVAE misses by far more
/// (core too wide, tail too short, as the shipped model did on the walks:
/// docs/notes/decoder-training.md, "The decoder is the cause"): the assertion is that the energy
/// objective's worst error is under half of it.
#[test]
fn energy_training_fits_the_core_and_the_tail() {
    let config = TrainConfig {
        widths: Widths {
            feature: vec![16, 16],
            absorption_hidden: vec![4],
            decoder_hidden: vec![32, 32],
            encoder_hidden: vec![16],
        },
        batch_size: 64,
        steps: 8_000,
        adam: AdamConfig {
            lr: 3e-3,
            decay: 0.5,
            decay_every: 3_000,
            ..AdamConfig::default()
        },
        seed: 1,
        eval_every: 1_000,
        objective: Objective::EnergyScore {
            draws: 8,
            weight: 1.0,
        },
        ..TrainConfig::default()
    };
    let train = |objective| {
        let c = TrainConfig {
            objective,
            ..config.clone()
        };
        let (t, v) = (synthetic(20_000, 1), synthetic(2_000, 2));
        let mut tr =
            Trainer::new(c, Normalisation::identity(), ModelInfo::default(), t, v).unwrap();
        tr.run(None, |_| {}).unwrap();
        tr
    };
    let es = train(config.objective);
    let h = es.history();
    let (first, last) = (h[0].val.energy_score, h.last().unwrap().val.energy_score);
    assert!(last < first, "energy score did not fall: {first} -> {last}");
    let (body, tail) = worst_quantile_errors(es.model(), "energy");
    assert!(
        body < 0.12 && tail < 0.30,
        "energy objective: worst errors {body:.3} (q ≤ 0.9), {tail:.3} (q = 0.99)"
    );
    let cvae = train(Objective::Cvae);
    let (cb, ct) = worst_quantile_errors(cvae.model(), "cvae");
    assert!(
        body.max(tail) < 0.5 * cb.max(ct),
        "the energy objective ({:.3}) is not clearly closer than the CVAE ({:.3})",
        body.max(tail),
        cb.max(ct)
    );
}

/// Fine-tuning: a run started from a model keeps its normalisation and widths, refuses a model
/// without an encoder, and resumes bit-identically under the energy objective.
#[test]
fn energy_fine_tuning_starts_from_a_model_and_resumes() {
    let train = synthetic(2_000, 3);
    let w = Widths {
        feature: vec![8],
        absorption_hidden: vec![4],
        decoder_hidden: vec![8],
        encoder_hidden: vec![8],
    };
    let base = init_model(&w, Normalisation::identity(), ModelInfo::default(), 5).unwrap();
    let config = |steps| TrainConfig {
        batch_size: 16,
        steps,
        eval_every: 10,
        checkpoint_every: 10,
        objective: Objective::EnergyScore {
            draws: 4,
            weight: 1.0,
        },
        ..TrainConfig::default()
    };
    let full = {
        let mut t =
            Trainer::from_model(config(30), base.clone(), train.clone(), Prepared::default())
                .unwrap();
        assert_eq!(t.config().widths, w);
        t.run(None, |_| {}).unwrap();
        t.params().to_vec()
    };
    let dir = tempfile::tempdir().unwrap();
    let ckpt = dir.path().join("checkpoint.bin");
    let mut part =
        Trainer::from_model(config(10), base.clone(), train.clone(), Prepared::default()).unwrap();
    part.run(Some(&ckpt), |_| {}).unwrap();
    let mut resumed = Trainer::resume(&ckpt, Some(30), train.clone(), Prepared::default()).unwrap();
    resumed.run(None, |_| {}).unwrap();
    assert_eq!(resumed.params(), &full[..]);

    let render_only = ShapeAdaptiveModel::new(
        base.feature_mlp().layers().to_vec(),
        base.absorption_mlp().layers().to_vec(),
        base.decoder().layers().to_vec(),
        None,
        Normalisation::identity(),
        ModelInfo::default(),
    )
    .unwrap();
    let e = Trainer::from_model(config(1), render_only, train, Prepared::default())
        .err()
        .expect("a model without an encoder cannot be fine-tuned");
    assert!(e.to_string().contains("no encoder"), "{e}");
}
