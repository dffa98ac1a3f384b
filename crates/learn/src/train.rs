//! The training loop of the learned BSSRDF (docs/model.md §6): data preparation and input
//! normalisation, deterministic mini-batches, Adam steps, validation, atomic checkpoints and
//! bit-identical resume.
//!
//! **Inputs** (§4.1): the 23 network inputs `normalise(c_LS, α', g, η)` with the statistics
//! ([`Normalisation::from_samples`]) of the TRAINING set. Unlike VKJ19, whose albedo statistic was
//! taken over α_eff of the raw albedo α while the network was fed α_eff(α'), ours is taken over
//! α_eff(α') — the quantity the network sees. **Targets**: `x_LS` (the sample's `out_ls`, units of
//! σ_n) and the configuration's absorption probability.
//!
//! **Determinism.** Step `s` uses the rows `perm_e[(s·B + i) mod N]` of the epoch permutation
//! `perm_e` (Fisher–Yates from `hash(seed, e)`), and the reparameterisation noise
//! `ε = BoxMuller(hash(seed, s, i))`; the gradient is summed in a fixed order by
//! [`crate::cvae::loss_and_grad`]. Nothing depends on the thread count or on whether the run was
//! interrupted: a resumed run reproduces the uninterrupted one bit for bit.
//!
//! **Checkpoint file** (`checkpoint.bin`): magic `TLCKPT01`, u64 LE length of a JSON document
//! (format version, step, configuration, history, model metadata), the JSON, then f32 LE
//! arrays: parameters, Adam first moments, Adam second moments (each of the length given in the
//! JSON). Written atomically (temporary file + rename).

use std::path::{Path, PathBuf};
use std::time::Instant;

use base::rng::Sampler;
use bssrdf::medium::{ReducedMedium, StatSample};
use bssrdf::model::ModelInfo;
use bssrdf::nn::ShapeAdaptiveModel;
use bssrdf::nn::{INPUT_DIM, LATENT_DIM, Normalisation, POSITION_DIM};
use scene::setting::Setting;
use serde::{Deserialize, Serialize};

use crate::cvae::{self as vae, Batch, Gradients, LossParts, LossWeights, Widths};
use crate::energy::{self, EnergyBatch, EnergyWeights};
use crate::optim::{Adam, AdamConfig};
use crate::sample::Sample;

/// Errors of training.
#[derive(Debug, thiserror::Error)]
pub enum TrainError {
    /// The training or validation set is unusable.
    #[error("training data: {0}")]
    Data(String),
    /// A checkpoint cannot be read or does not match this run.
    #[error("checkpoint {}: {reason}", .path.display())]
    Checkpoint {
        /// The checkpoint file.
        path: PathBuf,
        /// What is wrong and how to fix it.
        reason: String,
    },
    /// The loss became NaN or infinite.
    #[error(
        "the training loss became non-finite at step {step}; lower the learning rate ({}) or \
         the gradient clipping threshold ({})",
        Setting::Lr,
        Setting::Clip
    )]
    Diverged {
        /// Step at which it happened.
        step: u64,
    },
    /// Model construction, saving or inference failed.
    #[error(transparent)]
    Model(#[from] bssrdf::model::ModelError),
    /// Writing a file failed.
    #[error(transparent)]
    Write(#[from] scene::SceneError),
    /// Reading a file failed.
    #[error("{}: {source}", .path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
}

/// Hyper-parameters of a training run (defaults: see [`TrainConfig::default`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TrainConfig {
    /// Network widths.
    pub widths: Widths,
    /// Samples per step.
    pub batch_size: usize,
    /// Number of optimisation steps.
    pub steps: u64,
    /// Adam optimiser and learning-rate schedule.
    pub adam: AdamConfig,
    /// Loss weights (docs/model.md §6).
    pub weights: LossWeights,
    /// Seed of the initialisation, the batch order and the VAE noise.
    pub seed: u64,
    /// Validate (and record a history row) every this many steps.
    pub eval_every: u64,
    /// Write a checkpoint every this many steps.
    pub checkpoint_every: u64,
    /// The objective (the CVAE of docs/model.md §6, or the energy score of [`crate::energy`]).
    #[serde(default)]
    pub objective: Objective,
}

/// A training objective by name (the settings of [`Objective`] aside).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum ObjectiveKind {
    /// The conditional VAE (default).
    #[default]
    Cvae,
    /// The energy score of the decoder's proposals against the exits: a fine-tuning stage.
    Energy,
}

/// What a training run minimises.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", tag = "kind")]
pub enum Objective {
    /// The conditional VAE of docs/model.md §6 (weights: [`TrainConfig::weights`]).
    #[default]
    Cvae,
    /// The energy score of the decoder's proposals against the exits plus the absorption term
    /// of [`TrainConfig::weights`] ([`crate::energy`]).
    EnergyScore {
        /// Latent draws per row (m ≥ 2).
        draws: usize,
        /// Weight of the energy score.
        weight: f32,
    },
}

impl Objective {
    /// Standard-normal values drawn per training row: the VAE's reparameterisation noise, or
    /// the energy score's latent samples.
    fn noise_per_row(&self) -> usize {
        match self {
            Objective::Cvae => LATENT_DIM,
            Objective::EnergyScore { draws, .. } => draws * LATENT_DIM,
        }
    }
}

impl Default for TrainConfig {
    fn default() -> Self {
        Self {
            widths: Widths::son24(),
            batch_size: 256,
            steps: 100_000,
            adam: AdamConfig::default(),
            weights: LossWeights::default(),
            seed: 0,
            eval_every: 1000,
            checkpoint_every: 5000,
            objective: Objective::Cvae,
        }
    }
}

/// Network inputs and targets of a sample set, as flat row-major arrays.
#[derive(Clone, Debug, Default)]
pub struct Prepared {
    /// `n × 23` normalised inputs.
    pub inputs: Vec<f32>,
    /// `n × 3` targets `x_LS`.
    pub targets: Vec<f32>,
    /// `n` absorption probabilities.
    pub absorption: Vec<f32>,
}

impl Prepared {
    /// Number of rows.
    pub fn len(&self) -> usize {
        self.absorption.len()
    }

    /// Whether there are no rows.
    pub fn is_empty(&self) -> bool {
        self.absorption.is_empty()
    }
}

/// Reduced albedo α' of a sample (the network's albedo input is α_eff(α')).
fn reduced_albedo(s: &Sample) -> f64 {
    ReducedMedium::new(s.sigma_t as f64, s.albedo as f64, s.g as f64).albedo_red
}

/// Input statistics of a training set (docs/model.md §4.1, over α_eff(α'); see the module doc).
pub fn normalisation_of(samples: &[Sample]) -> Result<Normalisation, TrainError> {
    let stats: Vec<StatSample> = samples
        .iter()
        .map(|s| StatSample {
            coeffs_ls: s.poly_ls,
            albedo: reduced_albedo(s),
            g: s.g as f64,
        })
        .collect();
    Normalisation::from_samples(&stats).map_err(|e| TrainError::Data(e.to_string()))
}

/// Network inputs and targets of `samples` under `norm`.
pub fn prepare(samples: &[Sample], norm: &Normalisation) -> Result<Prepared, TrainError> {
    let mut p = Prepared {
        inputs: Vec::with_capacity(samples.len() * INPUT_DIM),
        targets: Vec::with_capacity(samples.len() * POSITION_DIM),
        absorption: Vec::with_capacity(samples.len()),
    };
    for (i, s) in samples.iter().enumerate() {
        let x = norm.normalise(&s.poly_ls, reduced_albedo(s), s.g as f64, s.eta as f64);
        if x.iter().chain(&s.out_ls).any(|v| !v.is_finite())
            || !(0.0..=1.0).contains(&s.absorption_prob)
        {
            return Err(TrainError::Data(format!(
                "sample {i} has a non-finite input or target, or an absorption probability \
                 outside [0, 1]; regenerate the data"
            )));
        }
        p.inputs.extend_from_slice(&x);
        p.targets.extend_from_slice(&s.out_ls);
        p.absorption.push(s.absorption_prob);
    }
    Ok(p)
}

/// One row of the training history.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct HistoryRow {
    /// Steps done.
    pub step: u64,
    /// Learning rate of the last step.
    pub lr: f32,
    /// Mean training loss over the steps since the previous row (none before the first step).
    pub train_loss: Option<f64>,
    /// Validation loss parts (fixed noise).
    pub val: LossParts,
    /// Wall time spent training so far (seconds, summed over resumed runs).
    pub seconds: f64,
}

/// Per-step statistics for progress display.
#[derive(Clone, Copy, Debug)]
pub struct StepInfo {
    /// Steps done.
    pub step: u64,
    /// Loss of this step.
    pub loss: f64,
    /// Latest validation row, if any yet.
    pub last_val: Option<f64>,
}

/// A training run: model, optimiser, data and history.
pub struct Trainer {
    config: TrainConfig,
    model: ShapeAdaptiveModel,
    params: Vec<f32>,
    grads: Gradients,
    adam: Adam,
    step: u64,
    history: Vec<HistoryRow>,
    seconds: f64,
    train: Prepared,
    val: Prepared,
    perm: Vec<u32>,
    perm_epoch: u64,
    batch: BatchBuffers,
    since_row: (f64, u64),
}

#[derive(Default)]
struct BatchBuffers {
    inputs: Vec<f32>,
    targets: Vec<f32>,
    absorption: Vec<f32>,
    eps: Vec<f32>,
}

/// Standard normal pair from two uniforms (Box–Muller).
fn box_muller(u1: f32, u2: f32) -> (f32, f32) {
    let r = (-2.0 * (1.0 - u1).ln()).sqrt();
    let phi = std::f32::consts::TAU * u2;
    (r * phi.cos(), r * phi.sin())
}

/// Fills `eps` (`rows × width`, `width` even) with N(0, 1) values from `hash(seed, step, row)`.
fn fill_noise(eps: &mut [f32], width: usize, seed: u64, step: u64) {
    for (row, e) in eps.chunks_exact_mut(width).enumerate() {
        let mut s = Sampler::new(seed, step, row as u64, 0x05EE_DE95);
        for pair in e.chunks_exact_mut(2) {
            let (a, b) = box_muller(s.next_f32(), s.next_f32());
            pair[0] = a;
            pair[1] = b;
        }
    }
}

impl Trainer {
    /// A fresh run on prepared data with a freshly initialised model.
    pub fn new(
        config: TrainConfig,
        norm: Normalisation,
        info: ModelInfo,
        train: Prepared,
        val: Prepared,
    ) -> Result<Self, TrainError> {
        let model = vae::init_model(&config.widths, norm, info, config.seed)?;
        Self::with_model(config, model, train, val)
    }

    /// A fresh run that starts from `model` (fine-tuning, e.g. with
    /// [`Objective::EnergyScore`] after the CVAE): its parameters, normalisation and metadata
    /// are kept and `config.widths` is replaced by its widths. `train` and `val` must be prepared
    /// with the model's normalisation ([`prepare`]).
    pub fn from_model(
        mut config: TrainConfig,
        model: ShapeAdaptiveModel,
        train: Prepared,
        val: Prepared,
    ) -> Result<Self, TrainError> {
        config.widths = Widths::of(&model).ok_or_else(|| {
            TrainError::Data(
                "the initial model has no encoder (a render-only model, e.g. imported reference \
                 weights); start from a model written by `translucent train fit`"
                    .into(),
            )
        })?;
        Self::with_model(config, model, train, val)
    }

    fn with_model(
        config: TrainConfig,
        model: ShapeAdaptiveModel,
        train: Prepared,
        val: Prepared,
    ) -> Result<Self, TrainError> {
        check_run(&config, &train)?;
        let params = vae::params_to_flat(&model);
        let adam = Adam::new(params.len(), config.adam.clone());
        let grads = Gradients::zeros_like(&model);
        Ok(Self {
            config,
            model,
            params,
            grads,
            adam,
            step: 0,
            history: Vec::new(),
            seconds: 0.0,
            train,
            val,
            perm: Vec::new(),
            perm_epoch: u64::MAX,
            batch: BatchBuffers::default(),
            since_row: (0.0, 0),
        })
    }

    /// Steps done.
    pub fn step(&self) -> u64 {
        self.step
    }

    /// The configuration.
    pub fn config(&self) -> &TrainConfig {
        &self.config
    }

    /// The history rows so far.
    pub fn history(&self) -> &[HistoryRow] {
        &self.history
    }

    /// Training seconds so far (over resumed runs).
    pub fn seconds(&self) -> f64 {
        self.seconds
    }

    /// The current model.
    pub fn model(&self) -> &ShapeAdaptiveModel {
        &self.model
    }

    /// Mutable access to the model's metadata (provenance before saving).
    pub fn model_info_mut(&mut self) -> &mut ModelInfo {
        self.model.info_mut()
    }

    /// The flat parameters (for tests).
    pub fn params(&self) -> &[f32] {
        &self.params
    }

    /// Row `i` of the epoch permutation of training step rows.
    fn row_of(&mut self, global: u64) -> usize {
        let n = self.train.len() as u64;
        let epoch = global / n;
        if epoch != self.perm_epoch {
            self.perm.clear();
            self.perm.extend(0..n as u32);
            let mut s = Sampler::new(self.config.seed, epoch, 0, 0x05E0_FF1E);
            for i in (1..self.perm.len()).rev() {
                let j = s.next_below(i as u32 + 1) as usize;
                self.perm.swap(i, j);
            }
            self.perm_epoch = epoch;
        }
        self.perm[(global % n) as usize] as usize
    }

    fn gather_batch(&mut self) {
        let b = self.config.batch_size;
        let mut buf = std::mem::take(&mut self.batch);
        buf.inputs.clear();
        buf.targets.clear();
        buf.absorption.clear();
        let width = self.config.objective.noise_per_row();
        buf.eps.resize(b * width, 0.0);
        for i in 0..b {
            let r = self.row_of(self.step * b as u64 + i as u64);
            buf.inputs
                .extend_from_slice(&self.train.inputs[r * INPUT_DIM..(r + 1) * INPUT_DIM]);
            buf.targets
                .extend_from_slice(&self.train.targets[r * POSITION_DIM..(r + 1) * POSITION_DIM]);
            buf.absorption.push(self.train.absorption[r]);
        }
        fill_noise(&mut buf.eps, width, self.config.seed, self.step);
        self.batch = buf;
    }

    /// Loss parts of `data` (inputs, targets, absorption) under the run's objective with the
    /// noise `eps`, and the gradient into `grads` when given.
    fn objective(
        &self,
        data: (&[f32], &[f32], &[f32]),
        eps: &[f32],
        grads: Option<&mut Gradients>,
    ) -> Result<LossParts, TrainError> {
        let (inputs, targets, absorption) = data;
        let parts = match self.config.objective {
            Objective::Cvae => {
                let batch = Batch {
                    inputs,
                    targets,
                    absorption,
                    eps,
                };
                match grads {
                    Some(g) => vae::loss_and_grad(&self.model, &batch, &self.config.weights, g),
                    None => vae::loss_only(&self.model, &batch, &self.config.weights),
                }
            }
            Objective::EnergyScore { draws, weight } => {
                let batch = EnergyBatch {
                    inputs,
                    targets,
                    absorption,
                    z: eps,
                    draws,
                };
                let w = EnergyWeights {
                    energy: weight,
                    absorption: self.config.weights.absorption,
                };
                match grads {
                    Some(g) => energy::loss_and_grad(&self.model, &batch, &w, g),
                    None => energy::loss_only(&self.model, &batch, &w),
                }
            }
        };
        Ok(parts?)
    }

    /// One optimisation step; returns its loss.
    pub fn train_step(&mut self) -> Result<f64, TrainError> {
        self.gather_batch();
        let mut grads = std::mem::replace(&mut self.grads, Gradients::empty());
        let b = &self.batch;
        let parts = self.objective(
            (&b.inputs, &b.targets, &b.absorption),
            &b.eps,
            Some(&mut grads),
        );
        self.grads = grads;
        let parts = parts?;
        if !parts.total.is_finite() {
            return Err(TrainError::Diverged { step: self.step });
        }
        self.adam.step(&mut self.params, self.grads.as_flat_mut());
        vae::flat_to_params(&mut self.model, &self.params);
        self.step += 1;
        self.since_row.0 += parts.total;
        self.since_row.1 += 1;
        Ok(parts.total)
    }

    /// Validation loss parts with fixed noise (`hash(seed, u64::MAX, row)`).
    pub fn validate(&self) -> Result<LossParts, TrainError> {
        let data = if self.val.is_empty() {
            &self.train
        } else {
            &self.val
        };
        let width = self.config.objective.noise_per_row();
        let mut eps = vec![0.0f32; data.len() * width];
        fill_noise(&mut eps, width, self.config.seed, u64::MAX);
        self.objective((&data.inputs, &data.targets, &data.absorption), &eps, None)
    }

    fn record_row(&mut self) -> Result<(), TrainError> {
        let val = self.validate()?;
        let (sum, n) = self.since_row;
        self.history.push(HistoryRow {
            step: self.step,
            lr: self.adam.learning_rate(self.step.saturating_sub(1)),
            train_loss: (n > 0).then(|| sum / n as f64),
            val,
            seconds: self.seconds,
        });
        self.since_row = (0.0, 0);
        Ok(())
    }

    /// Trains until `config.steps`, validating every `eval_every` steps and writing a
    /// checkpoint to `checkpoint` every `checkpoint_every` steps and at the end. `on_step` is
    /// called after every step (progress display).
    pub fn run(
        &mut self,
        checkpoint: Option<&Path>,
        mut on_step: impl FnMut(StepInfo),
    ) -> Result<(), TrainError> {
        if self.history.is_empty() && self.step == 0 {
            self.record_row()?;
        }
        while self.step < self.config.steps {
            let t0 = Instant::now();
            let loss = self.train_step()?;
            self.seconds += t0.elapsed().as_secs_f64();
            if self.step.is_multiple_of(self.config.eval_every) || self.step == self.config.steps {
                let t1 = Instant::now();
                self.record_row()?;
                self.seconds += t1.elapsed().as_secs_f64();
            }
            if let Some(path) = checkpoint
                && (self.step.is_multiple_of(self.config.checkpoint_every)
                    || self.step == self.config.steps)
            {
                self.save_checkpoint(path)?;
            }
            on_step(StepInfo {
                step: self.step,
                loss,
                last_val: self.history.last().map(|r| r.val.total),
            });
        }
        Ok(())
    }
}

/// Largest batch (rows per step): the batch buffers hold 23 inputs and the noise of each row,
/// so a bound on the rows bounds what a step allocates.
pub const MAX_BATCH: usize = 1 << 20;
/// Largest number of latent draws per row of the energy objective (it is used with a handful).
pub const MAX_DRAWS: usize = 1024;

/// The checks of a run's settings against its data, shared by a fresh run and a resumed one
/// (whose settings come from a checkpoint file, so that a damaged field is an error and not a
/// huge allocation at the first step): a non-empty training set of at most 2³² rows, a batch of
/// 1 to [`MAX_BATCH`] rows, and an energy objective with 2 to [`MAX_DRAWS`] draws and a positive
/// weight.
fn check_run(config: &TrainConfig, train: &Prepared) -> Result<(), TrainError> {
    if train.is_empty() {
        return Err(TrainError::Data("the training set is empty".into()));
    }
    if train.len() > u32::MAX as usize {
        return Err(TrainError::Data("more than 2^32 training samples".into()));
    }
    if config.batch_size == 0 {
        return Err(TrainError::Data("the batch size must be at least 1".into()));
    }
    if config.batch_size > MAX_BATCH {
        return Err(TrainError::Data(format!(
            "the batch size {} is above the limit of {MAX_BATCH} rows",
            config.batch_size
        )));
    }
    if let Objective::EnergyScore { draws, weight } = config.objective
        && !((2..=MAX_DRAWS).contains(&draws) && weight.is_finite() && weight > 0.0)
    {
        return Err(TrainError::Data(format!(
            "the energy objective needs 2 to {MAX_DRAWS} draws and a positive weight, got \
                 {draws} draws and weight {weight}"
        )));
    }
    Ok(())
}

mod checkpoint;
pub use checkpoint::{CHECKPOINT_MAGIC, fingerprint};

#[cfg(test)]
mod tests;
