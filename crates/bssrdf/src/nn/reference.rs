//! Naive f64 reference implementation (plain loops, one row at a time), for tests.

use super::{Dense, LATENT_DIM, Mlp, POSITION_DIM, ShapeAdaptiveModel};

/// `act(W x + b)` in f64.
pub fn dense(layer: &Dense, x: &[f64], relu: bool) -> Vec<f64> {
    (0..layer.n_out())
        .map(|o| {
            let row = &layer.weights()[o * layer.n_in()..(o + 1) * layer.n_in()];
            let s = row.iter().zip(x).map(|(&w, &v)| w as f64 * v).sum::<f64>()
                + layer.bias()[o] as f64;
            if relu { s.max(0.0) } else { s }
        })
        .collect()
}

/// An MLP on one row in f64.
pub fn mlp(net: &Mlp, x: &[f64]) -> Vec<f64> {
    let n = net.layers().len();
    let mut h = x.to_vec();
    for (i, l) in net.layers().iter().enumerate() {
        h = dense(l, &h, i + 1 < n || net.relu_output());
    }
    h
}

/// Feature vector of one normalised input row.
pub fn features(model: &ShapeAdaptiveModel, input: &[f32]) -> Vec<f64> {
    let x: Vec<f64> = input.iter().map(|&v| v as f64).collect();
    mlp(model.feature_mlp(), &x)
}

/// Absorb of one feature vector.
pub fn absorb(model: &ShapeAdaptiveModel, features: &[f64]) -> f64 {
    let a = mlp(model.absorption_mlp(), features)[0];
    1.0 / (1.0 + (-a).exp())
}

/// Decoder output for one feature vector and one latent sample.
pub fn decode(
    model: &ShapeAdaptiveModel,
    features: &[f64],
    z: &[f32; LATENT_DIM],
) -> [f64; POSITION_DIM] {
    let x: Vec<f64> = z
        .iter()
        .map(|&v| v as f64)
        .chain(features.iter().copied())
        .collect();
    let y = mlp(model.decoder(), &x);
    [y[0], y[1], y[2]]
}

/// Encoder output (μ, log σ²) for one feature vector and one position; `None` without an
/// encoder.
pub fn encode(
    model: &ShapeAdaptiveModel,
    features: &[f64],
    x: &[f32; POSITION_DIM],
) -> Option<([f64; LATENT_DIM], [f64; LATENT_DIM])> {
    let enc = model.encoder()?;
    let inp: Vec<f64> = x
        .iter()
        .map(|&v| v as f64)
        .chain(features.iter().copied())
        .collect();
    let h = mlp(enc.hidden(), &inp);
    let m = dense(enc.mean(), &h, false);
    let l = dense(enc.logvar(), &h, false);
    Some(([m[0], m[1], m[2], m[3]], [l[0], l[1], l[2], l[3]]))
}
