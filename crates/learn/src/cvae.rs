//! The training objective of the shape-adaptive BSSRDF (docs/model.md §6) and its exact gradient
//! with respect to every parameter of the model: feature MLP (shared), absorption MLP, decoder
//! and encoder.
//!
//! For a sample with normalised inputs u, target x = x_LS (units of σ_n), absorption probability
//! p and noise ε ~ N(0, I₄):
//!
//! * f = Feature(u); A = sigmoid(Absorption(f));
//! * (μ, log σ²) = Encoder(x ⊕ f); z = μ + exp(½ log σ²)·ε (reparameterisation);
//! * x̂ = Decoder(z ⊕ f);
//! * L = w_pos · ⅓Σ₃(x − x̂)² + w_kl · ½Σ₄(μ² + σ² − log σ² − 1) + w_abs · (A − p)²,
//!
//! averaged over the batch, with VKJ19's weights w_pos = 100, w_kl = 1, w_abs = 5000. The
//! gradient flows into f from the decoder, the encoder and the absorption network.
//!
//! **Flat parameter order** (also the order of [`Gradients`]): feature layers, absorption
//! layers, decoder layers, encoder hidden layers, encoder mean head, encoder log-variance head;
//! for each layer its weights (`[n_out × n_in]` row-major) then its biases.
//!
//! **Determinism.** A batch is cut into sub-batches of [`SUB_BATCH`] rows (independent of the
//! thread count); each sub-batch's gradient is computed on its own and the results are summed in
//! sub-batch order, so the gradient is bit-identical for any number of threads.

use std::cell::RefCell;
use std::ops::Range;

use base::rng::Sampler;
use bssrdf::model::{ModelError, ModelInfo};
use bssrdf::nn::ShapeAdaptiveModel;
use bssrdf::nn::{Dense, Encoder, INPUT_DIM, LATENT_DIM, Normalisation, POSITION_DIM};
use rayon::prelude::*;
use scene::setting::Setting;
use serde::{Deserialize, Serialize};

use crate::mlp_grad::MlpTape;

/// Rows per sub-batch of the gradient computation.
pub const SUB_BATCH: usize = 64;

/// Layer widths of a model.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Widths {
    /// Feature MLP layer widths (the last is the feature dimension F).
    pub feature: Vec<usize>,
    /// Hidden widths of the absorption MLP (output 1).
    pub absorption_hidden: Vec<usize>,
    /// Hidden widths of the decoder (output 3).
    pub decoder_hidden: Vec<usize>,
    /// Hidden widths of the encoder (then two heads of 4).
    pub encoder_hidden: Vec<usize>,
}

impl Widths {
    /// Son et al.'s light model (docs/model.md §4.2): F = 32,32; A 16; D 32,32; E 32,32.
    pub fn son24() -> Self {
        Self {
            feature: vec![32, 32],
            absorption_hidden: vec![16],
            decoder_hidden: vec![32, 32],
            encoder_hidden: vec![32, 32],
        }
    }

    /// The widths of `model`, `None` when it has no encoder (a render-only model such as the
    /// imported reference weights cannot be trained further).
    pub fn of(model: &ShapeAdaptiveModel) -> Option<Self> {
        let outs = |m: &bssrdf::nn::Mlp| m.layers().iter().map(|l| l.n_out()).collect::<Vec<_>>();
        let hidden = |m: &bssrdf::nn::Mlp| {
            let mut v = outs(m);
            v.pop();
            v
        };
        let enc = model.encoder()?;
        Some(Self {
            feature: outs(model.feature_mlp()),
            absorption_hidden: hidden(model.absorption_mlp()),
            decoder_hidden: hidden(model.decoder()),
            encoder_hidden: outs(enc.hidden()),
        })
    }

    /// VKJ19's model (docs/model.md §4.1): F = 64,64,64; A 32; D 64,64,64; E 64,64,64.
    pub fn vkj19() -> Self {
        Self {
            feature: vec![64, 64, 64],
            absorption_hidden: vec![32],
            decoder_hidden: vec![64, 64, 64],
            encoder_hidden: vec![64, 64, 64],
        }
    }
}

impl Widths {
    /// The number of trainable parameters of a model with these widths (the layers of
    /// [`init_model`]), computed without building it; `None` when the feature or encoder widths
    /// are empty or the count overflows. A reader compares it with the parameters a file holds
    /// before it allocates a model of widths read from that file.
    pub fn n_params(&self) -> Option<usize> {
        fn stack(n_in: usize, widths: impl IntoIterator<Item = usize>) -> Option<usize> {
            let mut prev = n_in;
            let mut total = 0usize;
            for w in widths {
                total = total.checked_add(prev.checked_mul(w)?.checked_add(w)?)?;
                prev = w;
            }
            Some(total)
        }
        let f = *self.feature.last()?;
        let h = *self.encoder_hidden.last()?;
        let parts = [
            stack(INPUT_DIM, self.feature.iter().copied())?,
            stack(f, self.absorption_hidden.iter().copied().chain([1]))?,
            stack(
                LATENT_DIM.checked_add(f)?,
                self.decoder_hidden.iter().copied().chain([POSITION_DIM]),
            )?,
            stack(
                POSITION_DIM.checked_add(f)?,
                self.encoder_hidden.iter().copied(),
            )?,
            stack(h, [LATENT_DIM])?.checked_mul(2)?,
        ];
        parts.into_iter().try_fold(0usize, usize::checked_add)
    }
}

/// Loss weights (docs/model.md §6).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct LossWeights {
    /// Weight of the mean (over 3 dimensions) squared position error.
    pub position: f32,
    /// Weight of the KL term ½Σ(μ² + σ² − log σ² − 1).
    pub kl: f32,
    /// Weight of the squared absorption error.
    pub absorption: f32,
}

impl Default for LossWeights {
    fn default() -> Self {
        Self {
            position: 100.0,
            kl: 1.0,
            absorption: 5000.0,
        }
    }
}

/// Batch means of the loss and its parts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct LossParts {
    /// The loss.
    pub total: f64,
    /// Weighted position term.
    pub position: f64,
    /// Weighted KL term.
    pub kl: f64,
    /// Weighted absorption term.
    pub absorption: f64,
    /// Unweighted mean squared position error (units of σ_n², per dimension).
    pub position_mse: f64,
    /// Unweighted mean squared absorption error.
    pub absorption_mse: f64,
    /// Weighted energy-score term ([`crate::energy`]; 0 under the CVAE objective).
    #[serde(default)]
    pub energy: f64,
    /// Unweighted energy score (units of σ_n; 0 under the CVAE objective).
    #[serde(default)]
    pub energy_score: f64,
}

impl LossParts {
    fn add(&mut self, o: &LossParts) {
        self.total += o.total;
        self.position += o.position;
        self.kl += o.kl;
        self.absorption += o.absorption;
        self.position_mse += o.position_mse;
        self.absorption_mse += o.absorption_mse;
        self.energy += o.energy;
        self.energy_score += o.energy_score;
    }
}

/// A training batch (row-major flat arrays).
#[derive(Clone, Copy, Debug)]
pub struct Batch<'a> {
    /// `rows × 23` normalised inputs.
    pub inputs: &'a [f32],
    /// `rows × 3` targets x_LS.
    pub targets: &'a [f32],
    /// `rows` absorption probabilities.
    pub absorption: &'a [f32],
    /// `rows × 4` reparameterisation noise.
    pub eps: &'a [f32],
}

/// The gradient of the loss, flat in the parameter order of the module doc.
#[derive(Clone, Debug, PartialEq)]
pub struct Gradients {
    flat: Vec<f32>,
}

impl Gradients {
    /// Zeros for `model`'s parameters.
    pub fn zeros_like(model: &ShapeAdaptiveModel) -> Self {
        Self {
            flat: vec![0.0; n_params(model)],
        }
    }

    /// No values (a placeholder while the gradient buffer is lent out).
    pub fn empty() -> Self {
        Self { flat: Vec::new() }
    }

    /// The flat values.
    pub fn as_flat(&self) -> &[f32] {
        &self.flat
    }

    /// The flat values, mutable (Adam clips them in place).
    pub fn as_flat_mut(&mut self) -> &mut [f32] {
        &mut self.flat
    }
}

/// The layers of a model in the flat order; panics if the model has no encoder.
fn layers(model: &ShapeAdaptiveModel) -> Vec<&Dense> {
    let mut v: Vec<&Dense> = Vec::new();
    v.extend(model.feature_mlp().layers());
    v.extend(model.absorption_mlp().layers());
    v.extend(model.decoder().layers());
    if let Some(e) = model.encoder() {
        v.extend(e.hidden().layers());
        v.push(e.mean());
        v.push(e.logvar());
    }
    v
}

/// Number of trainable parameters (all blocks, encoder included).
pub fn n_params(model: &ShapeAdaptiveModel) -> usize {
    layers(model).iter().map(|l| l.n_params()).sum()
}

/// The parameters as one flat vector.
pub fn params_to_flat(model: &ShapeAdaptiveModel) -> Vec<f32> {
    let mut out = Vec::with_capacity(n_params(model));
    for l in layers(model) {
        out.extend_from_slice(l.weights());
        out.extend_from_slice(l.bias());
    }
    out
}

/// Sets the parameters from a flat vector.
///
/// # Panics
/// If `flat` does not have [`n_params`] values.
pub fn flat_to_params(model: &mut ShapeAdaptiveModel, flat: &[f32]) {
    assert_eq!(flat.len(), n_params(model), "flat parameter count");
    let mut rest = flat;
    let mut set = |l: &mut Dense| {
        let (w, r) = rest.split_at(l.weights().len());
        l.weights_mut().copy_from_slice(w);
        let (b, r) = r.split_at(l.bias().len());
        l.bias_mut().copy_from_slice(b);
        rest = r;
    };
    let (feat, abs, dec, enc) = model.networks_mut();
    feat.layers_mut().iter_mut().for_each(&mut set);
    abs.layers_mut().iter_mut().for_each(&mut set);
    dec.layers_mut().iter_mut().for_each(&mut set);
    if let Some(e) = enc {
        let (hidden, mean, logvar) = e.parts_mut();
        hidden.layers_mut().iter_mut().for_each(&mut set);
        set(mean);
        set(logvar);
    }
}

/// A layer with uniform random weights in ±sqrt(6/n_in) (He, for ReLU layers) or
/// ±sqrt(6/(n_in + n_out)) (Glorot, for linear outputs), biases 0.
fn init_layer(
    n_in: usize,
    n_out: usize,
    relu: bool,
    rng: &mut Sampler,
) -> Result<Dense, ModelError> {
    let a = if relu {
        (6.0 / n_in as f32).sqrt()
    } else {
        (6.0 / (n_in + n_out) as f32).sqrt()
    };
    let w = (0..n_in * n_out)
        .map(|_| a * (2.0 * rng.next_f32() - 1.0))
        .collect();
    Dense::new(n_in, n_out, w, vec![0.0; n_out])
}

fn init_stack(
    n_in: usize,
    widths: &[usize],
    relu_last: bool,
    rng: &mut Sampler,
) -> Result<Vec<Dense>, ModelError> {
    let mut v = Vec::new();
    let mut prev = n_in;
    for (i, &w) in widths.iter().enumerate() {
        v.push(init_layer(prev, w, i + 1 < widths.len() || relu_last, rng)?);
        prev = w;
    }
    Ok(v)
}

/// A freshly initialised model with an encoder (seeded, deterministic).
pub fn init_model(
    widths: &Widths,
    normalisation: Normalisation,
    info: ModelInfo,
    seed: u64,
) -> Result<ShapeAdaptiveModel, ModelError> {
    if widths.feature.is_empty() || widths.encoder_hidden.is_empty() {
        return Err(ModelError::Architecture(
            "the feature MLP and the encoder need at least one layer".into(),
        ));
    }
    let mut rng = Sampler::new(seed, 0x1417, 0, 0);
    let f = *widths.feature.last().expect("non-empty");
    let feature = init_stack(INPUT_DIM, &widths.feature, true, &mut rng)?;
    let mut abs_w = widths.absorption_hidden.clone();
    abs_w.push(1);
    let absorption = init_stack(f, &abs_w, false, &mut rng)?;
    let mut dec_w = widths.decoder_hidden.clone();
    dec_w.push(POSITION_DIM);
    let decoder = init_stack(LATENT_DIM + f, &dec_w, false, &mut rng)?;
    let hidden = init_stack(POSITION_DIM + f, &widths.encoder_hidden, true, &mut rng)?;
    let h = *widths.encoder_hidden.last().expect("non-empty");
    let mean = init_layer(h, LATENT_DIM, false, &mut rng)?;
    let logvar = init_layer(h, LATENT_DIM, false, &mut rng)?;
    let encoder = Encoder::new(hidden, mean, logvar)?;
    ShapeAdaptiveModel::new(
        feature,
        absorption,
        decoder,
        Some(encoder),
        normalisation,
        info,
    )
}

/// Per-thread activations and scratch buffers of one pass.
#[derive(Default)]
pub(crate) struct Tapes {
    pub(crate) feat: MlpTape,
    pub(crate) abs: MlpTape,
    pub(crate) enc: MlpTape,
    pub(crate) dec: MlpTape,
    pub(crate) enc_in: Vec<f32>,
    pub(crate) dec_in: Vec<f32>,
    pub(crate) mu: Vec<f32>,
    pub(crate) lv: Vec<f32>,
    pub(crate) d_out: Vec<f32>,
    pub(crate) d_in: Vec<f32>,
    pub(crate) d_f: Vec<f32>,
    pub(crate) d_mu: Vec<f32>,
    pub(crate) d_lv: Vec<f32>,
    pub(crate) d_h: Vec<f32>,
    pub(crate) d_h2: Vec<f32>,
}

thread_local! {
    static TAPES: RefCell<Tapes> = RefCell::new(Tapes::default());
}

/// `v` resized to `n` values, as a slice.
pub(crate) fn sized(v: &mut Vec<f32>, n: usize) -> &mut [f32] {
    v.resize(n, 0.0);
    &mut v[..n]
}

/// The logistic function.
pub(crate) fn sigmoid(x: f32) -> f32 {
    1.0 / (1.0 + (-x).exp())
}

/// The last part of every objective's backward pass: adds the absorption term's gradient
/// δs = w_abs·2(A − p)·A(1 − A)/B (B = 1/`inv` rows) at the absorption logits, back through the
/// absorption MLP into `g_abs` and into ∂L/∂f, which `t.d_f` (rows × F) already holds from the
/// other terms; then back through the feature MLP into `g_feat`.
pub(crate) fn absorption_and_feature_backward(
    model: &ShapeAdaptiveModel,
    t: &mut Tapes,
    p_abs: &[f32],
    w_abs: f32,
    inv: f32,
    g_feat: &mut [f32],
    g_abs: &mut [f32],
) {
    let rows = p_abs.len();
    let f_dim = model.feature_mlp().n_out();
    let Tapes {
        feat,
        abs,
        d_out,
        d_in,
        d_f,
        ..
    } = t;
    let d_s = sized(d_out, rows);
    for ((d, &s), &p) in d_s.iter_mut().zip(abs.output()).zip(p_abs) {
        let a = sigmoid(s);
        *d = w_abs * 2.0 * (a - p) * a * (1.0 - a) * inv;
    }
    let d_abs_in = sized(d_in, rows * f_dim);
    abs.backward(model.absorption_mlp(), d_out, g_abs, Some(d_abs_in));
    let d_f = &mut d_f[..rows * f_dim];
    d_f.iter_mut().zip(d_in.iter()).for_each(|(a, b)| *a += b);
    feat.backward(model.feature_mlp(), d_f, g_feat, None);
}

mod pass;

/// Runs `pass` over the sub-batches of `rows` rows in parallel and sums their loss parts (and,
/// when `grads` is given, their gradients, which overwrite `grads`) in sub-batch order: the
/// result is bit-identical for any thread count. Sub-batches have [`SUB_BATCH`] rows with
/// gradients, 1024 without.
pub(crate) fn batched(
    model: &ShapeAdaptiveModel,
    rows: usize,
    grads: Option<&mut Gradients>,
    pass: impl Fn(Range<usize>, Option<&mut [f32]>, &mut Tapes) -> LossParts + Sync,
) -> LossParts {
    let n = n_params(model);
    let with_grad = grads.is_some();
    let chunk = if with_grad { SUB_BATCH } else { 1024 };
    let subs: Vec<(LossParts, Vec<f32>)> = (0..rows.div_ceil(chunk))
        .into_par_iter()
        .map(|i| {
            let r = i * chunk..((i + 1) * chunk).min(rows);
            let mut g = if with_grad {
                vec![0.0f32; n]
            } else {
                Vec::new()
            };
            let parts = TAPES.with(|t| {
                pass(
                    r,
                    with_grad.then_some(g.as_mut_slice()),
                    &mut t.borrow_mut(),
                )
            });
            (parts, g)
        })
        .collect();
    let mut total = LossParts::default();
    subs.iter().for_each(|(p, _)| total.add(p));
    if let Some(grads) = grads {
        grads.flat.resize(n, 0.0);
        grads.flat.fill(0.0);
        for (_, g) in &subs {
            grads.flat.iter_mut().zip(g).for_each(|(a, b)| *a += b);
        }
    }
    total
}

fn check(model: &ShapeAdaptiveModel, b: &Batch) -> Result<usize, ModelError> {
    let rows = b.absorption.len();
    if b.inputs.len() != rows * INPUT_DIM
        || b.targets.len() != rows * POSITION_DIM
        || b.eps.len() != rows * LATENT_DIM
    {
        return Err(ModelError::Batch(format!(
            "training batch of {rows} rows has {} inputs, {} targets and {} noise values",
            b.inputs.len(),
            b.targets.len(),
            b.eps.len()
        )));
    }
    if model.encoder().is_none() {
        return Err(ModelError::Batch(
            "training needs a model with an encoder".into(),
        ));
    }
    Ok(rows)
}

/// Loss and gradient of `batch` (means over its rows); the gradient overwrites `grads`.
pub fn loss_and_grad(
    model: &ShapeAdaptiveModel,
    batch: &Batch,
    weights: &LossWeights,
    grads: &mut Gradients,
) -> Result<LossParts, ModelError> {
    let rows = check(model, batch)?;
    let inv = 1.0 / rows.max(1) as f32;
    Ok(batched(model, rows, Some(grads), |r, g, t| {
        pass::run(model, batch, r, weights, inv, g, t)
    }))
}

/// The loss of `batch` without gradients (validation), in chunks of 1024 rows over the pool.
pub fn loss_only(
    model: &ShapeAdaptiveModel,
    batch: &Batch,
    weights: &LossWeights,
) -> Result<LossParts, ModelError> {
    let rows = check(model, batch)?;
    let inv = 1.0 / rows.max(1) as f32;
    Ok(batched(model, rows, None, |r, g, t| {
        pass::run(model, batch, r, weights, inv, g, t)
    }))
}

impl std::str::FromStr for Widths {
    type Err = String;

    /// Parses `son24`, `vkj19` or `F=..;A=..;D=..;E=..` (the `--widths` of `train fit`).
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "son24" => return Ok(Self::son24()),
            "vkj19" => return Ok(Self::vkj19()),
            _ => {}
        }
        let mut w = Self::son24();
        for part in s.split(';').filter(|p| !p.trim().is_empty()) {
            let (k, v) = part
                .split_once('=')
                .ok_or_else(|| format!("{}: '{part}' is not KEY=w1,w2,…", Setting::Widths))?;
            let list: Vec<usize> = v
                .split(',')
                .map(|x| x.trim().parse::<usize>())
                .collect::<Result<_, _>>()
                .map_err(|_| format!("{}: '{v}' is not a list of integers", Setting::Widths))?;
            if list.contains(&0) {
                return Err(format!("{}: widths must be ≥ 1", Setting::Widths));
            }
            match k.trim() {
                "F" => w.feature = list,
                "A" => w.absorption_hidden = list,
                "D" => w.decoder_hidden = list,
                "E" => w.encoder_hidden = list,
                other => {
                    return Err(format!(
                        "{}: unknown block '{other}' (use F, A, D, E)",
                        Setting::Widths
                    ));
                }
            }
        }
        if w.feature.is_empty() {
            return Err(format!("{}: F needs at least one layer", Setting::Widths));
        }
        Ok(w)
    }
}
