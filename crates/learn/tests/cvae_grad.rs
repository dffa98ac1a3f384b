//! The analytic gradient of the training objective (model-spec §6) against central finite
//! differences, for parameters of every block and for each loss term alone; the training
//! forward pass against the inference code; determinism over thread counts.

use bssrdf::model::ModelInfo;
use bssrdf::nn::{INPUT_DIM, LATENT_DIM, Normalisation, POSITION_DIM, ShapeAdaptiveModel};
use learn::cvae::{
    Batch, Gradients, LossWeights, Widths, flat_to_params, init_model, loss_and_grad, loss_only,
    params_to_flat,
};
use volpath::rng::Sampler;

struct Data {
    inputs: Vec<f32>,
    targets: Vec<f32>,
    absorption: Vec<f32>,
    eps: Vec<f32>,
}

fn data(rows: usize, seed: u64) -> Data {
    let mut s = Sampler::new(seed, 1, 2, 3);
    let mut u = |a: f32| a * (2.0 * s.next_f32() - 1.0);
    Data {
        inputs: (0..rows * INPUT_DIM).map(|_| u(1.5)).collect(),
        targets: (0..rows * POSITION_DIM).map(|_| u(2.0)).collect(),
        absorption: (0..rows).map(|_| 0.5 + u(0.45)).collect(),
        eps: (0..rows * LATENT_DIM).map(|_| u(1.7)).collect(),
    }
}

fn batch(d: &Data) -> Batch<'_> {
    Batch {
        inputs: &d.inputs,
        targets: &d.targets,
        absorption: &d.absorption,
        eps: &d.eps,
    }
}

fn model(seed: u64) -> ShapeAdaptiveModel {
    let w = Widths {
        feature: vec![12, 10],
        absorption_hidden: vec![6],
        decoder_hidden: vec![9, 7],
        encoder_hidden: vec![8, 5],
    };
    let mut m = init_model(&w, Normalisation::identity(), ModelInfo::default(), seed).unwrap();
    // Non-zero biases so that the bias gradients are exercised away from the init point.
    let mut p = params_to_flat(&m);
    let mut s = Sampler::new(seed, 9, 9, 9);
    p.iter_mut()
        .for_each(|v| *v += 0.05 * (2.0 * s.next_f32() - 1.0));
    flat_to_params(&mut m, &p);
    m
}

/// Block boundaries in the flat order: feature, absorption, decoder, encoder hidden, mean, logvar.
fn blocks(m: &ShapeAdaptiveModel) -> Vec<(&'static str, std::ops::Range<usize>)> {
    let e = m.encoder().unwrap();
    let sizes = [
        ("feature", m.feature_mlp().n_params()),
        ("absorption", m.absorption_mlp().n_params()),
        ("decoder", m.decoder().n_params()),
        ("encoder", e.hidden().n_params()),
        ("mean head", e.mean().n_params()),
        ("logvar head", e.logvar().n_params()),
    ];
    let mut o = 0;
    sizes
        .iter()
        .map(|&(n, s)| {
            o += s;
            (n, o - s..o)
        })
        .collect()
}

fn check_fd(weights: LossWeights, label: &str) {
    let d = data(24, 5);
    let mut m = model(11);
    let mut g = Gradients::zeros_like(&m);
    loss_and_grad(&m, &batch(&d), &weights, &mut g).unwrap();
    let g = g.as_flat().to_vec();
    let p0 = params_to_flat(&m);
    let gmax = g.iter().fold(0.0f32, |a, b| a.max(b.abs()));
    let h = 2e-3f32;
    let mut s = Sampler::new(3, 3, 3, 3);
    for (block, range) in blocks(&m) {
        let mut checked = 0;
        for _ in 0..12 {
            let i = range.start + s.next_below(range.len() as u32) as usize;
            let mut p = p0.clone();
            p[i] = p0[i] + h;
            flat_to_params(&mut m, &p);
            let lp = loss_only(&m, &batch(&d), &weights).unwrap().total;
            p[i] = p0[i] - h;
            flat_to_params(&mut m, &p);
            let lm = loss_only(&m, &batch(&d), &weights).unwrap().total;
            let fd = ((lp - lm) / (2.0 * h as f64)) as f32;
            // f32 forward pass: the FD error is O(h²·L''') + O(ε_f32·L/h); 1 % of the largest
            // gradient component bounds both here.
            let tol = 0.02 * g[i].abs() + 0.01 * gmax;
            assert!(
                (fd - g[i]).abs() <= tol,
                "{label}: {block} parameter {i}: analytic {} vs FD {fd} (tol {tol})",
                g[i]
            );
            checked += 1;
        }
        assert_eq!(checked, 12);
    }
    flat_to_params(&mut m, &p0);
}

#[test]
fn gradient_matches_finite_differences_for_every_block_and_term() {
    let w = LossWeights::default();
    check_fd(w, "total");
    check_fd(
        LossWeights {
            position: 1.0,
            kl: 0.0,
            absorption: 0.0,
        },
        "position term",
    );
    check_fd(
        LossWeights {
            position: 0.0,
            kl: 1.0,
            absorption: 0.0,
        },
        "KL term",
    );
    check_fd(
        LossWeights {
            position: 0.0,
            kl: 0.0,
            absorption: 1.0,
        },
        "absorption term",
    );
}

#[test]
fn training_forward_equals_inference() {
    let d = data(40, 8);
    let m = model(4);
    let w = LossWeights::default();
    let parts = loss_only(&m, &batch(&d), &w).unwrap();
    // Recompute with the inference entry points of bssrdf.
    let rows = d.absorption.len();
    let inputs: Vec<[f32; INPUT_DIM]> = d
        .inputs
        .chunks_exact(INPUT_DIM)
        .map(|c| c.try_into().unwrap())
        .collect();
    let f_dim = m.feature_dim();
    let mut f = vec![0.0; rows * f_dim];
    m.features(&inputs, &mut f).unwrap();
    let mut a = vec![0.0; rows];
    m.absorb(&f, &mut a).unwrap();
    let idx: Vec<u32> = (0..rows as u32).collect();
    let x: Vec<[f32; 3]> = d
        .targets
        .chunks_exact(3)
        .map(|c| c.try_into().unwrap())
        .collect();
    let mut mu = vec![[0.0; LATENT_DIM]; rows];
    let mut lv = vec![[0.0; LATENT_DIM]; rows];
    m.encode_with(&f, &x, &idx, &mut mu, &mut lv, &mut Default::default())
        .unwrap();
    let z: Vec<[f32; LATENT_DIM]> = (0..rows)
        .map(|i| std::array::from_fn(|k| mu[i][k] + (0.5 * lv[i][k]).exp() * d.eps[i * 4 + k]))
        .collect();
    let mut xhat = vec![[0.0; 3]; rows];
    m.decode(&f, &z, &idx, &mut xhat).unwrap();
    let mut pos = 0.0f64;
    let mut abs = 0.0f64;
    for i in 0..rows {
        pos += (0..3)
            .map(|k| ((xhat[i][k] - x[i][k]) as f64).powi(2))
            .sum::<f64>()
            / 3.0;
        abs += ((a[i] - d.absorption[i]) as f64).powi(2);
    }
    pos /= rows as f64;
    abs /= rows as f64;
    assert!(
        (parts.position_mse - pos).abs() <= 1e-5 * pos.max(1.0),
        "{} vs {pos}",
        parts.position_mse
    );
    assert!(
        (parts.absorption_mse - abs).abs() <= 1e-6,
        "{} vs {abs}",
        parts.absorption_mse
    );
}

#[test]
fn gradient_is_bit_identical_for_any_thread_count() {
    let d = data(300, 2);
    let m = model(1);
    let w = LossWeights::default();
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
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
    let m = model(1);
    let bad = Batch {
        targets: &d.targets[..5],
        ..batch(&d)
    };
    let mut g = Gradients::zeros_like(&m);
    assert!(loss_and_grad(&m, &bad, &LossWeights::default(), &mut g).is_err());
}
