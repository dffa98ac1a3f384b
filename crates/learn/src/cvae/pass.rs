//! One forward (and optionally backward) pass of the objective of the parent module over a
//! range of rows.
//!
//! Backward (δ = ∂L/∂·, B = batch size):
//! δx̂ = w_pos·⅔(x̂ − x)/B; decoder backward gives δz and a part of δf;
//! δμ = δz + w_kl·μ/B; δlog σ² = δz·ε·½e^{½ log σ²} + w_kl·½(e^{log σ²} − 1)/B;
//! heads and encoder backward give another part of δf; δs = w_abs·2(A − p)·A(1 − A)/B for the
//! absorption logit s gives the last part; then the feature MLP backward.

use std::ops::Range;

use bssrdf::nn::ShapeAdaptiveModel;
use bssrdf::nn::{INPUT_DIM, LATENT_DIM, POSITION_DIM};

use super::{
    Batch, LossParts, LossWeights, Tapes, absorption_and_feature_backward, sigmoid, sized,
};
use crate::mlp_grad::dense_backward;

/// The loss of `rows` samples, each term weighted by `w` and scaled by `inv`: the mean squared
/// error of the decoded exit position `xhat` against `target`, the KL divergence of the
/// encoder's posterior N(μ, e^{log σ²}) from N(0, I), and the squared error of the absorption
/// probability sigmoid(logit) against `p_abs`.
fn loss_parts(
    rows: usize,
    (xhat, target): (&[f32], &[f32]),
    (mu, lv): (&[f32], &[f32]),
    (logits, p_abs): (&[f32], &[f32]),
    w: &LossWeights,
    inv: f32,
) -> LossParts {
    let mut parts = LossParts::default();
    let inv64 = inv as f64;
    for i in 0..rows {
        let se: f64 = (0..POSITION_DIM)
            .map(|k| ((xhat[i * 3 + k] - target[i * 3 + k]) as f64).powi(2))
            .sum::<f64>()
            / 3.0;
        let kl: f64 = (0..LATENT_DIM)
            .map(|k| {
                let (m, l) = (mu[i * 4 + k] as f64, lv[i * 4 + k] as f64);
                0.5 * (m * m + l.exp() - l - 1.0)
            })
            .sum();
        let ae = (sigmoid(logits[i]) as f64 - p_abs[i] as f64).powi(2);
        parts.position_mse += se * inv64;
        parts.absorption_mse += ae * inv64;
        parts.position += w.position as f64 * se * inv64;
        parts.kl += w.kl as f64 * kl * inv64;
        parts.absorption += w.absorption as f64 * ae * inv64;
    }
    parts.total = parts.position + parts.kl + parts.absorption;
    parts
}

/// Loss parts of rows `r` (each divided by the batch size via `inv`); parameter gradients are
/// added to `grad` (flat order) when given.
pub(super) fn run(
    model: &ShapeAdaptiveModel,
    b: &Batch,
    r: Range<usize>,
    w: &LossWeights,
    inv: f32,
    grad: Option<&mut [f32]>,
    t: &mut Tapes,
) -> LossParts {
    let rows = r.len();
    let enc = model.encoder().expect("checked by the caller");
    let (feat_mlp, abs_mlp, dec_mlp) =
        (model.feature_mlp(), model.absorption_mlp(), model.decoder());
    let f_dim = feat_mlp.n_out();
    let x_in = &b.inputs[r.start * INPUT_DIM..r.end * INPUT_DIM];
    let target = &b.targets[r.start * POSITION_DIM..r.end * POSITION_DIM];
    let p_abs = &b.absorption[r.clone()];
    let eps = &b.eps[r.start * LATENT_DIM..r.end * LATENT_DIM];

    // Forward.
    t.feat.forward(feat_mlp, x_in, rows);
    let f = t.feat.output();
    t.abs.forward(abs_mlp, f, rows);
    let e_in = POSITION_DIM + f_dim;
    {
        let ei = sized(&mut t.enc_in, rows * e_in);
        for (i, row) in ei.chunks_exact_mut(e_in).enumerate() {
            row[..POSITION_DIM].copy_from_slice(&target[i * POSITION_DIM..(i + 1) * POSITION_DIM]);
            row[POSITION_DIM..].copy_from_slice(&f[i * f_dim..(i + 1) * f_dim]);
        }
    }
    t.enc.forward(enc.hidden(), &t.enc_in, rows);
    let h = t.enc.output();
    enc.mean()
        .forward_rows(h, rows, sized(&mut t.mu, rows * LATENT_DIM), false);
    enc.logvar()
        .forward_rows(h, rows, sized(&mut t.lv, rows * LATENT_DIM), false);
    let d_in_w = LATENT_DIM + f_dim;
    {
        let di = sized(&mut t.dec_in, rows * d_in_w);
        for (i, row) in di.chunks_exact_mut(d_in_w).enumerate() {
            for k in 0..LATENT_DIM {
                let j = i * LATENT_DIM + k;
                row[k] = t.mu[j] + (0.5 * t.lv[j]).exp() * eps[j];
            }
            row[LATENT_DIM..].copy_from_slice(&f[i * f_dim..(i + 1) * f_dim]);
        }
    }
    t.dec.forward(dec_mlp, &t.dec_in, rows);

    // Loss.
    let xhat = t.dec.output();
    let logits = t.abs.output();
    let (latent, absorption) = ((&t.mu[..], &t.lv[..]), (logits, p_abs));
    let parts = loss_parts(rows, (xhat, target), latent, absorption, w, inv);
    let Some(grad) = grad else {
        return parts;
    };

    // Backward. Offsets of the blocks in the flat gradient.
    let n_feat = feat_mlp.n_params();
    let n_abs = abs_mlp.n_params();
    let n_dec = dec_mlp.n_params();
    let n_enc = enc.hidden().n_params();
    let n_mean = enc.mean().n_params();
    let (g_feat, rest) = grad.split_at_mut(n_feat);
    let (g_abs, rest) = rest.split_at_mut(n_abs);
    let (g_dec, rest) = rest.split_at_mut(n_dec);
    let (g_enc, rest) = rest.split_at_mut(n_enc);
    let (g_mean, g_lv) = rest.split_at_mut(n_mean);

    let d_f = sized(&mut t.d_f, rows * f_dim);
    d_f.fill(0.0);
    // Decoder.
    {
        let d_out = sized(&mut t.d_out, rows * POSITION_DIM);
        let c = w.position * (2.0 / 3.0) * inv;
        for (d, (&a, &b)) in d_out.iter_mut().zip(xhat.iter().zip(target)) {
            *d = c * (a - b);
        }
    }
    let d_in = sized(&mut t.d_in, rows * d_in_w);
    t.dec.backward(dec_mlp, &t.d_out, g_dec, Some(d_in));
    let d_mu = sized(&mut t.d_mu, rows * LATENT_DIM);
    let d_lv = sized(&mut t.d_lv, rows * LATENT_DIM);
    for i in 0..rows {
        for k in 0..LATENT_DIM {
            let j = i * LATENT_DIM + k;
            let dz = t.d_in[i * d_in_w + k];
            let s = (0.5 * t.lv[j]).exp();
            d_mu[j] = dz + w.kl * t.mu[j] * inv;
            d_lv[j] = dz * eps[j] * 0.5 * s + w.kl * 0.5 * (s * s - 1.0) * inv;
        }
        for k in 0..f_dim {
            d_f[i * f_dim + k] += t.d_in[i * d_in_w + LATENT_DIM + k];
        }
    }
    // Encoder heads and hidden layers.
    let h = t.enc.output();
    let hw = enc.hidden().n_out();
    let d_h = sized(&mut t.d_h, rows * hw);
    let d_h2 = sized(&mut t.d_h2, rows * hw);
    dense_backward(enc.mean(), h, &t.mu, false, rows, d_mu, g_mean, Some(d_h));
    dense_backward(enc.logvar(), h, &t.lv, false, rows, d_lv, g_lv, Some(d_h2));
    d_h.iter_mut().zip(d_h2.iter()).for_each(|(a, b)| *a += b);
    let d_enc_in = sized(&mut t.d_in, rows * e_in);
    t.enc.backward(enc.hidden(), d_h, g_enc, Some(d_enc_in));
    for i in 0..rows {
        for k in 0..f_dim {
            d_f[i * f_dim + k] += t.d_in[i * e_in + POSITION_DIM + k];
        }
    }
    // Absorption and feature MLP.
    absorption_and_feature_backward(model, t, p_abs, w.absorption, inv, g_feat, g_abs);
    parts
}
