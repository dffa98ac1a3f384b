//! Gradients of the training code (docs/model.md §6) against an independent **f64** reference.
//!
//! The reference is a separate f64
//! implementation written with plain loops that reads the model's parameters through the flat
//! vector of [`params_to_flat`] in its documented order (so the order is tested too), and the
//! finite differences are central differences in f64:
//!
//! * truncation error O(h²·L''') ≈ 1e-12 with h = 1e-6 on O(1) parameters;
//! * rounding error ≈ 2⁻⁵²·|L|/h ≈ 2e-10·|L| (|L| ≲ 10³ with the default weights ⇒ ≲ 2e-7);
//! * the analytic gradient is computed in f32 (relative error ~1e-6 per product, a few hundred
//!   terms per component), so the tolerance is `1e-4·|g| + 1e-5·max|g| + 1e-6`.
//!
//! A ReLU kink between θ − h and θ + h would break a central difference; every test asserts
//! that the smallest |pre-activation| of every ReLU unit over the batch is larger than the
//! largest change h can cause (inputs are O(1), so a margin of 1e-4 ≫ 1e-6·|x| suffices).
//!
//! Also here: the training forward pass ([`MlpTape`], i.e. `Dense::forward_rows`) against the
//! inference entry points, gradients bit-identical for any thread count, bad batches, Adam
//! resuming bit-identically from its state, and (ignored) a
//! throughput measurement: `cargo test --release -p translucent-learn --test integration
//! gradients:: -- --ignored --nocapture`.

use crate::common;
use common::*;

use base::rng::Sampler;
use bssrdf::model::ModelInfo;
use bssrdf::nn::{Dense, INPUT_DIM, LATENT_DIM, Mlp, Normalisation, ShapeAdaptiveModel, Workspace};
use learn::cvae::{
    Batch, Gradients, LossWeights, Widths, flat_to_params, init_model, loss_and_grad, loss_only,
    n_params, params_to_flat,
};
use learn::mlp_grad::{MlpTape, dense_backward};
use learn::optim::{Adam, AdamConfig, AdamState};

fn assert_close(label: &str, analytic: &[f32], fd: &[f64]) {
    let gmax = analytic.iter().fold(0.0f32, |a, b| a.max(b.abs())) as f64;
    for (i, (&g, &f)) in analytic.iter().zip(fd).enumerate() {
        let tol = 1e-4 * (g as f64).abs() + 1e-5 * gmax + 1e-6;
        assert!(
            (g as f64 - f).abs() <= tol,
            "{label}[{i}]: analytic {g} vs f64 FD {f} (tol {tol:.3e})"
        );
    }
}

// ---------------------------------------------------------------------------------------------
// f64 reference networks over a flat parameter vector

/// Central differences of ⟨c, MLP(x)⟩ (summed over `rows` rows) with respect to every parameter
/// `p0` and every input `x0` of the f64 reference network `shapes`; asserts that no ReLU kink
/// lies within [`MARGIN`] of the evaluation point.
fn fd_linear_functional(
    shapes: &[Shape],
    p0: &[f64],
    x0: &[f64],
    c: &[f32],
    rows: usize,
) -> (Vec<f64>, Vec<f64>) {
    let (n_in, n_out) = (shapes[0].0, shapes[shapes.len() - 1].1);
    let loss = |p: &[f64], x: &[f64]| {
        let mut margin = f64::INFINITY;
        let mut l = 0.0;
        for r in 0..rows {
            let y = forward64(p, 0, shapes, &x[r * n_in..(r + 1) * n_in], &mut margin);
            l += (0..n_out)
                .map(|j| c[r * n_out + j] as f64 * y[j])
                .sum::<f64>();
        }
        (l, margin)
    };
    assert!(loss(p0, x0).1 > MARGIN, "ReLU kink too close");
    let fd = |i: usize, wrt_x: bool| {
        let (mut pa, mut pb, mut xa, mut xb) = (p0.to_vec(), p0.to_vec(), x0.to_vec(), x0.to_vec());
        if wrt_x {
            xa[i] += H;
            xb[i] -= H;
        } else {
            pa[i] += H;
            pb[i] -= H;
        }
        (loss(&pa, &xa).0 - loss(&pb, &xb).0) / (2.0 * H)
    };
    (
        (0..p0.len()).map(|i| fd(i, false)).collect(),
        (0..x0.len()).map(|i| fd(i, true)).collect(),
    )
}

impl Model64 {
    /// Batch mean of the §6 loss in f64 and the smallest ReLU margin.
    fn loss(&self, p: &[f64], d: &Data, w: &LossWeights) -> (f64, f64) {
        let off = self.offsets();
        let rows = d.absorption.len();
        let mut margin = f64::INFINITY;
        let mut total = 0.0;
        for r in 0..rows {
            let (x, f, s) = self.row(p, d, r, &mut margin);
            let enc_in: Vec<f64> = x.iter().chain(&f).copied().collect();
            let h = forward64(p, off[3].start, &self.blocks[3], &enc_in, &mut margin);
            let mu = forward64(p, off[4].start, &self.blocks[4], &h, &mut margin);
            let lv = forward64(p, off[5].start, &self.blocks[5], &h, &mut margin);
            let z: Vec<f64> = (0..LATENT_DIM)
                .map(|k| mu[k] + (0.5 * lv[k]).exp() * d.eps[r * LATENT_DIM + k] as f64)
                .collect();
            let dec_in: Vec<f64> = z.iter().chain(&f).copied().collect();
            let xhat = forward64(p, off[2].start, &self.blocks[2], &dec_in, &mut margin);
            let pos = (0..3).map(|k| (xhat[k] - x[k]).powi(2)).sum::<f64>() / 3.0;
            let kl = 0.5
                * (0..LATENT_DIM)
                    .map(|k| mu[k] * mu[k] + lv[k].exp() - lv[k] - 1.0)
                    .sum::<f64>();
            let a = 1.0 / (1.0 + (-s).exp());
            let ab = (a - d.absorption[r] as f64).powi(2);
            total += w.position as f64 * pos + w.kl as f64 * kl + w.absorption as f64 * ab;
        }
        (total / rows as f64, margin)
    }
}

// ---------------------------------------------------------------------------------------------
// Fixtures

fn batch(d: &Data) -> Batch<'_> {
    Batch {
        inputs: &d.inputs,
        targets: &d.targets,
        absorption: &d.absorption,
        eps: &d.eps,
    }
}

fn random_dense(n_in: usize, n_out: usize, s: &mut Sampler) -> Dense {
    Dense::new(
        n_in,
        n_out,
        uniform(s, n_in * n_out, 0.6),
        uniform(s, n_out, 0.3),
    )
    .unwrap()
}

// ---------------------------------------------------------------------------------------------
// Dense layer and MLP

/// L = Σ c ⊙ y for a fixed random c, so ∂L/∂y = c; checks ∂L/∂W = δᵀX, ∂L/∂b = Σδ, ∂L/∂X = δW
/// (δ = c masked by the ReLU) for every entry.
#[test]
fn dense_layer_gradient_matches_f64_finite_differences() {
    let (rows, n_in, n_out) = (9, 7, 5);
    for relu in [false, true] {
        let mut s = Sampler::new(relu as u64, 1, 1, 1);
        let layer = random_dense(n_in, n_out, &mut s);
        let x = uniform(&mut s, rows * n_in, 1.0);
        let c = uniform(&mut s, rows * n_out, 1.0);
        let mut y = vec![0.0f32; rows * n_out];
        layer.forward_rows(&x, rows, &mut y, relu);
        let mut delta = c.clone();
        let mut grad = vec![0.0f32; layer.n_params()];
        let mut dx = vec![0.0f32; rows * n_in];
        dense_backward(
            &layer,
            &x,
            &y,
            relu,
            rows,
            &mut delta,
            &mut grad,
            Some(&mut dx),
        );

        let shapes = [(n_in, n_out, relu)];
        let p0: Vec<f64> = layer
            .weights()
            .iter()
            .chain(layer.bias())
            .map(|&v| v as f64)
            .collect();
        let x0: Vec<f64> = x.iter().map(|&v| v as f64).collect();
        let (fd_p, fd_x) = fd_linear_functional(&shapes, &p0, &x0, &c, rows);
        assert_close(&format!("dense relu={relu} dW,db"), &grad, &fd_p);
        assert_close(&format!("dense relu={relu} dX"), &dx, &fd_x);
    }
}

/// An MLP through [`MlpTape`] (linear and ReLU output), all parameters and the input gradient;
/// the gradient is ADDED to the buffer (checked by starting from a non-zero buffer).
#[test]
fn mlp_gradient_matches_f64_finite_differences() {
    let (rows, widths) = (11, [6usize, 9, 7, 4]);
    for relu_output in [false, true] {
        let mut s = Sampler::new(10 + relu_output as u64, 2, 2, 2);
        let layers = widths
            .windows(2)
            .map(|w| random_dense(w[0], w[1], &mut s))
            .collect();
        let mlp = Mlp::new(layers, relu_output).unwrap();
        let x = uniform(&mut s, rows * widths[0], 1.0);
        let c = uniform(&mut s, rows * 4, 1.0);
        let mut tape = MlpTape::default();
        // Run twice: the second pass reuses the tape's buffers (warm) and must give the same.
        let mut results = Vec::new();
        for _ in 0..2 {
            tape.forward(&mlp, &x, rows);
            let offset = 0.25f32;
            let mut grad = vec![offset; mlp.n_params()];
            let mut dx = vec![0.0f32; rows * widths[0]];
            tape.backward(&mlp, &c, &mut grad, Some(&mut dx));
            grad.iter_mut().for_each(|g| *g -= offset);
            results.push((grad, dx));
        }
        assert_eq!(results[0], results[1], "warm tape differs from cold tape");
        let (grad, dx) = &results[0];

        let shapes = mlp_shapes(&mlp);
        let p0: Vec<f64> = mlp
            .layers()
            .iter()
            .flat_map(|l| l.weights().iter().chain(l.bias()))
            .map(|&v| v as f64)
            .collect();
        let x0: Vec<f64> = x.iter().map(|&v| v as f64).collect();
        let (fd_p, fd_x) = fd_linear_functional(&shapes, &p0, &x0, &c, rows);
        assert_close(
            &format!("mlp relu_output={relu_output} params"),
            grad,
            &fd_p,
        );
        assert_close(&format!("mlp relu_output={relu_output} dX"), dx, &fd_x);
    }
}

// ---------------------------------------------------------------------------------------------
// Whole objective

/// Analytic gradient of `weights` vs f64 FD of the reference objective for the parameters `idx`.
fn check_objective(
    m: &ShapeAdaptiveModel,
    d: &Data,
    weights: LossWeights,
    label: &str,
    idx: &[usize],
) {
    let mut g = Gradients::zeros_like(m);
    let parts = loss_and_grad(m, &batch(d), &weights, &mut g).unwrap();
    let r = Model64::new(m);
    let p0: Vec<f64> = params_to_flat(m).iter().map(|&v| v as f64).collect();
    check_gradient(label, &r, g.as_flat(), parts.total, &p0, idx, |p| {
        r.loss(p, d, &weights)
    });
}

/// 10 random parameters of every block (feature, absorption, decoder, encoder hidden, mean
/// head, log-variance head), for the total loss and for each term alone; batch of 70 rows so
/// that two sub-batches (64 + 6) are summed.
#[test]
fn objective_gradient_matches_f64_reference_for_every_block_and_term() {
    let d = data(70, 1);
    let m = small_model(21);
    let idx = indices_per_block(&Model64::new(&m), 10, 5);
    let term = |p: f32, k: f32, a: f32| LossWeights {
        position: p,
        kl: k,
        absorption: a,
    };
    check_objective(&m, &d, LossWeights::default(), "total", &idx);
    check_objective(&m, &d, term(1.0, 0.0, 0.0), "position term", &idx);
    check_objective(&m, &d, term(0.0, 1.0, 0.0), "KL term", &idx);
    check_objective(&m, &d, term(0.0, 0.0, 1.0), "absorption term", &idx);
}

/// The sigmoid absorption head: with only the absorption term, EVERY feature and absorption
/// parameter matches the f64 reference and the decoder/encoder gradients are exactly zero.
#[test]
fn absorption_head_gradient_matches_f64_reference() {
    let d = data(20, 4);
    let m = small_model(8);
    let w = LossWeights {
        position: 0.0,
        kl: 0.0,
        absorption: 5000.0,
    };
    let off = Model64::new(&m).offsets();
    let idx: Vec<usize> = (0..off[1].end).collect();
    check_objective(&m, &d, w, "absorption only", &idx);
    let mut g = Gradients::zeros_like(&m);
    loss_and_grad(&m, &batch(&d), &w, &mut g).unwrap();
    assert!(g.as_flat()[off[2].start..].iter().all(|&v| v == 0.0));
}

// ---------------------------------------------------------------------------------------------
// Flat order, forward equivalence, reporting values

/// `params_to_flat` is the concatenation feature, absorption, decoder, encoder hidden, mean,
/// logvar (each layer W then b); `flat_to_params` is its inverse; `n_params` its length.
#[test]
fn flat_parameter_order_is_canonical() {
    let m = small_model(2);
    let e = m.encoder().unwrap();
    let mut want = Vec::new();
    let layers = m
        .feature_mlp()
        .layers()
        .iter()
        .chain(m.absorption_mlp().layers())
        .chain(m.decoder().layers())
        .chain(e.hidden().layers())
        .chain([e.mean(), e.logvar()]);
    for l in layers {
        want.extend_from_slice(l.weights());
        want.extend_from_slice(l.bias());
    }
    let flat = params_to_flat(&m);
    assert_eq!(flat, want);
    assert_eq!(n_params(&m), flat.len());
    let mut m2 = small_model(3);
    flat_to_params(&mut m2, &flat);
    assert_eq!(params_to_flat(&m2), flat);
    assert_eq!(Gradients::zeros_like(&m).as_flat().len(), flat.len());
}

/// The training forward pass (MlpTape = `Dense::forward_rows` layer by layer) equals the
/// inference entry points bit for bit for the features, Absorb and the encoder; the decoder
/// (inference splits its first layer into W_z z + (W_f f + b)) to 1e-6 relative.
#[test]
fn training_forward_equals_inference() {
    let rows = 50;
    let d = data(rows, 6);
    let m = small_model(5);
    let e = m.encoder().unwrap();
    let mut ws = Workspace::default();
    let inputs: Vec<[f32; INPUT_DIM]> = d
        .inputs
        .chunks_exact(INPUT_DIM)
        .map(|c| c.try_into().unwrap())
        .collect();
    let fd = m.feature_dim();
    let mut f = vec![0.0; rows * fd];
    m.features_with(&inputs, &mut f, &mut ws).unwrap();
    let mut tape = MlpTape::default();
    tape.forward(m.feature_mlp(), &d.inputs, rows);
    assert_eq!(tape.output(), &f[..], "features");

    let mut a = vec![0.0; rows];
    m.absorb_with(&f, &mut a, &mut ws).unwrap();
    tape.forward(m.absorption_mlp(), &f, rows);
    let a_train: Vec<f32> = tape
        .output()
        .iter()
        .map(|&s| 1.0 / (1.0 + (-s).exp()))
        .collect();
    assert_eq!(a_train, a, "Absorb");

    let x: Vec<[f32; 3]> = d
        .targets
        .chunks_exact(3)
        .map(|c| c.try_into().unwrap())
        .collect();
    let idx: Vec<u32> = (0..rows as u32).collect();
    let (mut mu, mut lv) = (vec![[0.0; 4]; rows], vec![[0.0; 4]; rows]);
    m.encode_with(&f, &x, &idx, &mut mu, &mut lv, &mut ws)
        .unwrap();
    let enc_in: Vec<f32> = (0..rows)
        .flat_map(|r| x[r].iter().chain(&f[r * fd..(r + 1) * fd]).copied())
        .collect();
    tape.forward(e.hidden(), &enc_in, rows);
    let (mut mu_t, mut lv_t) = (vec![0.0; rows * 4], vec![0.0; rows * 4]);
    e.mean().forward_rows(tape.output(), rows, &mut mu_t, false);
    e.logvar()
        .forward_rows(tape.output(), rows, &mut lv_t, false);
    assert_eq!(mu_t, mu.as_flattened(), "encoder mean");
    assert_eq!(lv_t, lv.as_flattened(), "encoder log-variance");

    let z: Vec<[f32; 4]> = d
        .eps
        .chunks_exact(4)
        .map(|c| c.try_into().unwrap())
        .collect();
    let mut xhat = vec![[0.0; 3]; rows];
    m.decode_with(&f, &z, &idx, &mut xhat, &mut ws).unwrap();
    let dec_in: Vec<f32> = (0..rows)
        .flat_map(|r| z[r].iter().chain(&f[r * fd..(r + 1) * fd]).copied())
        .collect();
    tape.forward(m.decoder(), &dec_in, rows);
    for (i, (&t, &q)) in tape.output().iter().zip(xhat.as_flattened()).enumerate() {
        assert!(
            (t - q).abs() <= 1e-6 * q.abs().max(1.0),
            "decoder {i}: {t} vs {q}"
        );
    }
}

/// The reporting values: `loss_only` equals `loss_and_grad`'s parts; the unweighted MSEs times
/// the weights are the weighted terms; total = sum of the terms.
#[test]
fn loss_parts_are_consistent() {
    let d = data(200, 9);
    let m = small_model(6);
    let w = LossWeights::default();
    let mut g = Gradients::zeros_like(&m);
    let a = loss_and_grad(&m, &batch(&d), &w, &mut g).unwrap();
    let b = loss_only(&m, &batch(&d), &w).unwrap();
    let close = |x: f64, y: f64| (x - y).abs() <= 1e-6 * x.abs().max(1.0);
    assert!(
        close(a.total, b.total) && close(a.kl, b.kl),
        "{a:?} vs {b:?}"
    );
    assert!(close(a.position, 100.0 * a.position_mse));
    assert!(close(a.absorption, 5000.0 * a.absorption_mse));
    assert!(close(a.total, a.position + a.kl + a.absorption));
}

// ---------------------------------------------------------------------------------------------
// Adam

/// A checkpoint stores `AdamState` (step, m, v as flat vectors): 6 + 6 steps resumed from the
/// state equal 12 uninterrupted steps bit for bit (schedule boundary and clipping included).
#[test]
fn adam_resumes_bit_identically_from_its_state() {
    let cfg = AdamConfig {
        lr: 0.1,
        decay: 0.5,
        decay_every: 4,
        floor_fraction: 0.3,
        clip_norm: 2.0,
        ..AdamConfig::default()
    };
    let grad = |p: &[f32]| -> Vec<f32> {
        p.iter()
            .enumerate()
            .map(|(i, v)| (i as f32 + 1.0) * (v - 1.0))
            .collect()
    };
    let mut p_ref = vec![0.0f32, 3.0, -2.0];
    let mut adam = Adam::new(3, cfg.clone());
    for _ in 0..12 {
        let mut g = grad(&p_ref);
        adam.step(&mut p_ref, &mut g);
    }
    let mut p = vec![0.0f32, 3.0, -2.0];
    let mut first = Adam::new(3, cfg.clone());
    for _ in 0..6 {
        let mut g = grad(&p);
        first.step(&mut p, &mut g);
    }
    let AdamState {
        step,
        m,
        v,
        moments_from,
    } = first.state();
    let mut resumed = Adam::from_state(
        cfg,
        AdamState {
            step,
            m,
            v,
            moments_from,
        },
    );
    for _ in 0..6 {
        let mut g = grad(&p);
        resumed.step(&mut p, &mut g);
    }
    assert_eq!(p, p_ref);
    assert_eq!(resumed.state(), adam.state());
}

// ---------------------------------------------------------------------------------------------
// Throughput (not asserted)

/// Samples/s of `loss_and_grad` with the SON24 (and VKJ19) widths, batch 256, on 1 thread and
/// on the global pool.
#[test]
#[ignore = "benchmark; run in release with --ignored --nocapture"]
fn training_throughput() {
    let rows = 256;
    let d = data(rows, 1);
    for (name, w) in [("son24", Widths::son24()), ("vkj19", Widths::vkj19())] {
        let m = init_model(&w, Normalisation::identity(), ModelInfo::default(), 1).unwrap();
        let mut g = Gradients::zeros_like(&m);
        for threads in [1, rayon::current_num_threads()] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| {
                for _ in 0..50 {
                    loss_and_grad(&m, &batch(&d), &LossWeights::default(), &mut g).unwrap();
                }
                let iters = 2000;
                let t = std::time::Instant::now();
                for _ in 0..iters {
                    loss_and_grad(&m, &batch(&d), &LossWeights::default(), &mut g).unwrap();
                }
                let s = t.elapsed().as_secs_f64();
                println!(
                    "{name} ({} params), batch {rows}, {threads} thread(s): {:.0} samples/s ({:.1} µs/batch)",
                    n_params(&m),
                    (iters * rows) as f64 / s,
                    1e6 * s / iters as f64
                );
            });
        }
    }
}

#[test]
fn gradient_is_bit_identical_for_any_thread_count() {
    let d = data(300, 2);
    let m = small_model(1);
    let w = LossWeights::default();
    let run = |threads: usize| {
        on_threads(threads, || {
            let mut g = Gradients::zeros_like(&m);
            let p = loss_and_grad(&m, &batch(&d), &w, &mut g).unwrap();
            (p.total, g.as_flat().to_vec())
        })
    };
    let (l1, g1) = run(1);
    let (l3, g3) = run(3);
    assert_eq!(l1.to_bits(), l3.to_bits());
    assert_eq!(g1, g3);
}

#[test]
fn bad_batches_are_errors() {
    let d = data(4, 1);
    let m = small_model(1);
    let bad = Batch {
        targets: &d.targets[..5],
        ..batch(&d)
    };
    let mut g = Gradients::zeros_like(&m);
    assert!(loss_and_grad(&m, &bad, &LossWeights::default(), &mut g).is_err());
}
