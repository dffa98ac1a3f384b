//! The energy-score objective of the decoder ("engression"): the learned exit distribution
//! fitted as a distribution, not through the VAE's reconstruction bound.
//!
//! The CVAE objective of docs/model.md §6 trains the decoder through the encoder: its position term
//! asks the decoder to reconstruct the target from the target's own latent code. At render time
//! the decoder is fed z ~ N(0, I₄) instead, and nothing in that objective compares the pushforward
//! of N(0, I₄) with the walks' exit distribution directly. Ours measured too wide in the core and
//! short in the tail on its own held-out data (docs/notes/decoder-training.md, "The decoder is
//! the cause").
//!
//! This objective compares the two distributions directly, with the same decoder D(z, f) and
//! z ~ N(0, I₄) as at render time. For a training row with features f and exit x, it draws m ≥ 2
//! latent samples z_j and scores Y_j = D(z_j, f) with the **energy score** (Gneiting & Raftery
//! 2007, eq. 22 with β = 1; its use to train a generative regression is Shen & Meinshausen 2024,
//! "Engression", eq. 2.3):
//!
//! ES_i = (1/m) Σ_j |Y_j − x| − 1/(m(m−1)) Σ_{j<k} |Y_j − Y_k|,
//!
//! an unbiased estimate of E|Y − x| − ½E|Y − Y'|. The energy score is strictly proper: its
//! expectation over x ~ p(· | f) is minimised only by the decoder whose pushforward IS p(· | f).
//! So the core and the tail are both matched, each as far as the network can.
//!
//! The loss of a batch is the mean of w_es·ES_i + w_abs·(A_i − p_i)² (the absorption term of
//! docs/model.md §6, so the shared feature MLP keeps serving the absorption network). The encoder
//! is not used; its parameters receive zero gradient and stay in the model file.
//!
//! **Gradient.** With δ = ∂L/∂·, B rows, u(v) = v/|v|:
//! δY_j = (w_es/B)·[u(Y_j − x)/m − Σ_{k≠j} u(Y_j − Y_k)/(m(m−1))]; the decoder backward gives
//! δ(z_j ⊕ f), whose f part is summed over the draws into δf; the absorption term adds its part
//! as in [`crate::cvae`]; then the feature MLP backward. |v| is floored at 10⁻¹² (a tie of two
//! proposals has measure zero; the floor only keeps the division finite).
//!
//! Flat parameter order, sub-batches and determinism as in [`crate::cvae`].

use std::ops::Range;

use bssrdf::model::ModelError;
use bssrdf::nn::{INPUT_DIM, LATENT_DIM, POSITION_DIM, ShapeAdaptiveModel};
use serde::{Deserialize, Serialize};

use crate::cvae::{
    Gradients, LossParts, Tapes, absorption_and_feature_backward, batched, sigmoid, sized,
};

/// Loss weights of the energy objective.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct EnergyWeights {
    /// Weight of the energy score (units of σ_n).
    pub energy: f32,
    /// Weight of the squared absorption error (docs/model.md §6: 5000).
    pub absorption: f32,
}

/// A training batch of the energy objective (row-major flat arrays).
#[derive(Clone, Copy, Debug)]
pub struct EnergyBatch<'a> {
    /// `rows × 23` normalised inputs.
    pub inputs: &'a [f32],
    /// `rows × 3` targets x_LS.
    pub targets: &'a [f32],
    /// `rows` absorption probabilities.
    pub absorption: &'a [f32],
    /// `rows × draws × 4` latent samples z ~ N(0, I₄).
    pub z: &'a [f32],
    /// Latent samples per row (m ≥ 2).
    pub draws: usize,
}

fn check(b: &EnergyBatch) -> Result<usize, ModelError> {
    let rows = b.absorption.len();
    if b.draws < 2 {
        return Err(ModelError::Batch(format!(
            "the energy score needs at least 2 latent draws per row, got {}",
            b.draws
        )));
    }
    if b.inputs.len() != rows * INPUT_DIM
        || b.targets.len() != rows * POSITION_DIM
        || b.z.len() != rows * b.draws * LATENT_DIM
    {
        return Err(ModelError::Batch(format!(
            "energy batch of {rows} rows × {} draws has {} inputs, {} targets and {} latent values",
            b.draws,
            b.inputs.len(),
            b.targets.len(),
            b.z.len()
        )));
    }
    Ok(rows)
}

/// Loss and gradient of `batch` (means over its rows); the gradient overwrites `grads`.
pub fn loss_and_grad(
    model: &ShapeAdaptiveModel,
    batch: &EnergyBatch,
    weights: &EnergyWeights,
    grads: &mut Gradients,
) -> Result<LossParts, ModelError> {
    let rows = check(batch)?;
    let inv = 1.0 / rows.max(1) as f32;
    Ok(batched(model, rows, Some(grads), |r, g, t| {
        run(model, batch, r, weights, inv, g, t)
    }))
}

/// The loss of `batch` without gradients (validation).
pub fn loss_only(
    model: &ShapeAdaptiveModel,
    batch: &EnergyBatch,
    weights: &EnergyWeights,
) -> Result<LossParts, ModelError> {
    let rows = check(batch)?;
    let inv = 1.0 / rows.max(1) as f32;
    Ok(batched(model, rows, None, |r, g, t| {
        run(model, batch, r, weights, inv, g, t)
    }))
}

/// Euclidean distance of two 3-vectors and the unit vector from `b` to `a` (floored length).
fn dist_dir(a: &[f32], b: &[f32]) -> (f32, [f32; 3]) {
    let d = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    let s = 1.0 / n.max(1e-12);
    (n, [d[0] * s, d[1] * s, d[2] * s])
}

/// Loss parts of rows `r` (each divided by the batch size via `inv`); parameter gradients are
/// added to `grad` (flat order of [`crate::cvae`]) when given.
fn run(
    model: &ShapeAdaptiveModel,
    b: &EnergyBatch,
    r: Range<usize>,
    w: &EnergyWeights,
    inv: f32,
    grad: Option<&mut [f32]>,
    t: &mut Tapes,
) -> LossParts {
    let (rows, m) = (r.len(), b.draws);
    let (feat_mlp, abs_mlp, dec_mlp) =
        (model.feature_mlp(), model.absorption_mlp(), model.decoder());
    let f_dim = feat_mlp.n_out();
    let x_in = &b.inputs[r.start * INPUT_DIM..r.end * INPUT_DIM];
    let target = &b.targets[r.start * POSITION_DIM..r.end * POSITION_DIM];
    let p_abs = &b.absorption[r.clone()];
    let z = &b.z[r.start * m * LATENT_DIM..r.end * m * LATENT_DIM];

    // Forward: features once per row, the decoder once per draw.
    t.feat.forward(feat_mlp, x_in, rows);
    let f = t.feat.output();
    t.abs.forward(abs_mlp, f, rows);
    let d_in_w = LATENT_DIM + f_dim;
    {
        let di = sized(&mut t.dec_in, rows * m * d_in_w);
        for (q, row) in di.chunks_exact_mut(d_in_w).enumerate() {
            let i = q / m;
            row[..LATENT_DIM].copy_from_slice(&z[q * LATENT_DIM..(q + 1) * LATENT_DIM]);
            row[LATENT_DIM..].copy_from_slice(&f[i * f_dim..(i + 1) * f_dim]);
        }
    }
    t.dec.forward(dec_mlp, &t.dec_in, rows * m);

    // Loss and ∂L/∂Y.
    let y = t.dec.output();
    let logits = t.abs.output();
    let d_y = sized(&mut t.d_out, rows * m * POSITION_DIM);
    d_y.fill(0.0);
    let (ca, cb) = (1.0 / m as f32, 1.0 / (m * (m - 1)) as f32);
    let g_es = w.energy * inv;
    let mut parts = LossParts::default();
    let inv64 = inv as f64;
    for i in 0..rows {
        let x = &target[i * 3..i * 3 + 3];
        let yi = &y[i * m * 3..(i + 1) * m * 3];
        let di = &mut d_y[i * m * 3..(i + 1) * m * 3];
        let (mut near, mut spread) = (0.0f64, 0.0f64);
        for j in 0..m {
            let (n, u) = dist_dir(&yi[j * 3..j * 3 + 3], x);
            near += n as f64;
            for k in 0..3 {
                di[j * 3 + k] += g_es * ca * u[k];
            }
            for l in j + 1..m {
                let (n, u) = dist_dir(&yi[j * 3..j * 3 + 3], &yi[l * 3..l * 3 + 3]);
                spread += n as f64;
                for k in 0..3 {
                    di[j * 3 + k] -= g_es * cb * u[k];
                    di[l * 3 + k] += g_es * cb * u[k];
                }
            }
        }
        let es = near * ca as f64 - spread * cb as f64;
        let ae = (sigmoid(logits[i]) as f64 - p_abs[i] as f64).powi(2);
        parts.energy_score += es * inv64;
        parts.energy += w.energy as f64 * es * inv64;
        parts.absorption_mse += ae * inv64;
        parts.absorption += w.absorption as f64 * ae * inv64;
    }
    parts.total = parts.energy + parts.absorption;
    let Some(grad) = grad else {
        return parts;
    };

    // Backward. Offsets of the blocks in the flat gradient (the encoder's stay zero).
    let (n_feat, n_abs, n_dec) = (feat_mlp.n_params(), abs_mlp.n_params(), dec_mlp.n_params());
    let (g_feat, rest) = grad.split_at_mut(n_feat);
    let (g_abs, rest) = rest.split_at_mut(n_abs);
    let g_dec = &mut rest[..n_dec];

    let d_f = sized(&mut t.d_f, rows * f_dim);
    d_f.fill(0.0);
    let d_in = sized(&mut t.d_in, rows * m * d_in_w);
    t.dec.backward(dec_mlp, &t.d_out, g_dec, Some(d_in));
    for (q, row) in t.d_in.chunks_exact(d_in_w).enumerate() {
        let i = q / m;
        d_f[i * f_dim..(i + 1) * f_dim]
            .iter_mut()
            .zip(&row[LATENT_DIM..])
            .for_each(|(a, b)| *a += b);
    }
    // Absorption and feature MLP.
    absorption_and_feature_backward(model, t, p_abs, w.absorption, inv, g_feat, g_abs);
    parts
}
