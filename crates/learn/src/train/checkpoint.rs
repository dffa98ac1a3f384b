//! Checkpoints of a training run (format in the parent module's doc) and resume.

use std::path::Path;

use bssrdf::model::ModelInfo;
use bssrdf::nn::Normalisation;
use serde::{Deserialize, Serialize};

use super::{HistoryRow, Prepared, TrainConfig, TrainError, Trainer};
use crate::cvae::{self as vae, Gradients};
use crate::optim::{Adam, AdamState};

/// First bytes of a checkpoint file.
pub const CHECKPOINT_MAGIC: &[u8; 8] = b"TLCKPT01";
const VERSION: u32 = 1;

#[derive(Serialize, Deserialize)]
struct Header {
    format: String,
    version: u32,
    step: u64,
    seconds: f64,
    config: TrainConfig,
    history: Vec<HistoryRow>,
    normalisation: Normalisation,
    info: ModelInfo,
    adam_step: u64,
    n_params: usize,
    train_rows: usize,
    train_fingerprint: u64,
    since_row: (f64, u64),
}

fn err(path: &Path, reason: impl Into<String>) -> TrainError {
    TrainError::Checkpoint {
        path: path.to_path_buf(),
        reason: reason.into(),
    }
}

impl Trainer {
    /// Writes a checkpoint (atomically, replacing the previous one).
    pub fn save_checkpoint(&self, path: &Path) -> Result<(), TrainError> {
        let state: AdamState = self.adam.state();
        let header = Header {
            format: "translucent-train-checkpoint".into(),
            version: VERSION,
            step: self.step,
            seconds: self.seconds,
            config: self.config.clone(),
            history: self.history.clone(),
            normalisation: self.model.normalisation().clone(),
            info: self.model.info().clone(),
            adam_step: state.step,
            n_params: self.params.len(),
            train_rows: self.train.len(),
            train_fingerprint: fingerprint(&self.train),
            since_row: self.since_row,
        };
        let json = serde_json::to_vec(&header).map_err(|e| err(path, e.to_string()))?;
        let mut bytes = Vec::with_capacity(16 + json.len() + 12 * self.params.len());
        bytes.extend_from_slice(CHECKPOINT_MAGIC);
        bytes.extend_from_slice(&(json.len() as u64).to_le_bytes());
        bytes.extend_from_slice(&json);
        for arr in [&self.params, &state.m, &state.v] {
            for v in arr.iter() {
                bytes.extend_from_slice(&v.to_le_bytes());
            }
        }
        scene::fsutil::atomic_write(path, &bytes, true)?;
        Ok(())
    }

    /// Resumes the run saved in `path` on the same data. `steps` (if given) replaces the
    /// configured number of steps (to extend a finished run); every other setting comes from
    /// the checkpoint.
    pub fn resume(
        path: &Path,
        steps: Option<u64>,
        train: Prepared,
        val: Prepared,
    ) -> Result<Self, TrainError> {
        let bytes = std::fs::read(path).map_err(|source| TrainError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        if bytes.len() < 16 || &bytes[..8] != CHECKPOINT_MAGIC {
            return Err(err(
                path,
                "not a translucent training checkpoint (bad magic)",
            ));
        }
        let len = u64::from_le_bytes(bytes[8..16].try_into().expect("8 bytes")) as usize;
        let json = bytes
            .get(16..16usize.saturating_add(len))
            .ok_or_else(|| err(path, "truncated header; the file is damaged"))?;
        let h: Header = serde_json::from_slice(json)
            .map_err(|e| err(path, format!("malformed header: {e}")))?;
        if h.version != VERSION {
            return Err(err(
                path,
                format!("version {} (this build reads {VERSION})", h.version),
            ));
        }
        let body = &bytes[16 + len..];
        // Parameters, Adam's m and v: 12 bytes per parameter.
        if h.n_params.checked_mul(12) != Some(body.len()) {
            return Err(err(
                path,
                format!(
                    "holds {} bytes of tensors, expected 12 per parameter for n_params = {}; the \
                     file is damaged",
                    body.len(),
                    h.n_params
                ),
            ));
        }
        // The widths must describe exactly those parameters before a model of these widths is
        // allocated (a damaged width would otherwise ask for any amount of memory).
        if h.config.widths.n_params() != Some(h.n_params) {
            return Err(err(
                path,
                format!(
                    "config.widths {:?} do not describe the n_params = {} parameters the file \
                     holds; the file is damaged",
                    h.config.widths, h.n_params
                ),
            ));
        }
        super::check_run(&h.config, &train).map_err(|e| err(path, format!("config: {e}")))?;
        // A run stops at config.steps and takes one Adam step per step.
        if h.step > h.config.steps || h.adam_step > h.step {
            return Err(err(
                path,
                format!(
                    "step = {}, adam_step = {} and config.steps = {} are inconsistent (a run \
                     takes one optimiser step per step and stops at config.steps); the file is \
                     damaged",
                    h.step, h.adam_step, h.config.steps
                ),
            ));
        }
        if h.train_rows != train.len() || h.train_fingerprint != fingerprint(&train) {
            return Err(err(
                path,
                "was written for other training data (row count or content differ); pass the \
                 same samples file, or start a new run in another folder",
            ));
        }
        let floats: Vec<f32> = body
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes(b.try_into().expect("4 bytes")))
            .collect();
        let (params, rest) = floats.split_at(h.n_params);
        let (m, v) = rest.split_at(h.n_params);
        if let Some(i) = params.iter().position(|x| !x.is_finite()) {
            return Err(err(path, format!("parameter {i} is not finite")));
        }
        let mut config = h.config;
        if let Some(s) = steps {
            config.steps = s;
        }
        let mut model = vae::init_model(&config.widths, h.normalisation, h.info, config.seed)?;
        if vae::params_to_flat(&model).len() != h.n_params {
            return Err(err(path, "parameter count does not match its architecture"));
        }
        vae::flat_to_params(&mut model, params);
        let adam = Adam::from_state(
            config.adam.clone(),
            AdamState {
                step: h.adam_step,
                m: m.to_vec(),
                v: v.to_vec(),
                moments_from: 0,
            },
        );
        let grads = Gradients::zeros_like(&model);
        Ok(Self {
            config,
            model,
            params: params.to_vec(),
            grads,
            adam,
            step: h.step,
            history: h.history,
            seconds: h.seconds,
            train,
            val,
            perm: Vec::new(),
            perm_epoch: u64::MAX,
            batch: Default::default(),
            since_row: h.since_row,
        })
    }
}

/// Fingerprint of a prepared data set (mix64 over the bits of every value), stored in
/// checkpoints so that a resume on other data is refused.
pub fn fingerprint(p: &Prepared) -> u64 {
    let mut h = base::rng::hash_key(&[p.len() as u64]);
    for v in p.inputs.iter().chain(&p.targets).chain(&p.absorption) {
        h = base::rng::mix64(h ^ v.to_bits() as u64);
    }
    h
}
