//! A training run in an output folder (`translucent train fit`): the data files
//! `train.tlsamples` and `val.tlsamples`, a fresh start, a fine-tuning start from a model
//! (`init`) or a resume from `checkpoint.bin` (bit-identical to an uninterrupted run), and the
//! outputs: `model.safetensors` with its provenance (data, configuration, steps, validation),
//! the loss history (CSV and plots) and `train.json`. One run per folder (a folder lock).

use std::path::{Path, PathBuf};
use std::time::Instant;

use bssrdf::nn::ShapeAdaptiveModel;
use indicatif::ProgressBar;
use scene::setting::Setting;

use crate::samplefile::{SampleFileError, SampleFileHeader, read_samples};
use crate::train::{Prepared, TrainConfig, TrainError, Trainer, normalisation_of, prepare};

/// Why a training run could not start or finish.
#[derive(Debug, thiserror::Error)]
pub enum FitError {
    /// The folders or options do not allow the run; the message names the fix.
    #[error("{0}")]
    Invalid(String),
    #[error(transparent)]
    Train(#[from] TrainError),
    #[error(transparent)]
    Samples(#[from] SampleFileError),
    #[error(transparent)]
    Model(#[from] bssrdf::model::ModelError),
    #[error(transparent)]
    Scene(#[from] scene::SceneError),
    #[error(transparent)]
    Json(#[from] serde_json::Error),
}

/// A training run: where its data and outputs are, how it starts, and (for a new run) its
/// configuration.
#[derive(Clone, Debug)]
pub struct FitRun {
    /// The folder of `train.tlsamples` (and `val.tlsamples`; without it the run validates on
    /// the training set).
    pub data: PathBuf,
    /// The output folder.
    pub out: PathBuf,
    /// Fine-tune this model instead of starting from random weights.
    pub init: Option<PathBuf>,
    /// Continue from `out/checkpoint.bin` (to `config.steps`).
    pub resume: bool,
    /// Replace a run already in `out`.
    pub overwrite: bool,
    /// The configuration of a new run (a resumed one keeps its own, except the steps).
    pub config: TrainConfig,
}

/// What a finished run did.
#[derive(Clone, Debug)]
pub struct FitOutcome {
    /// Steps in all, and in this invocation.
    pub steps: u64,
    pub steps_this_run: u64,
    /// Wall time of this invocation.
    pub seconds: f64,
    /// Training samples per second in this invocation.
    pub samples_per_second: f64,
    /// The last validation record, as text.
    pub validation: Option<String>,
    /// The model written.
    pub model: PathBuf,
}

fn load_set(path: &Path) -> Result<(SampleFileHeader, Vec<crate::sample::Sample>), FitError> {
    if !path.exists() {
        return Err(FitError::Invalid(format!(
            "{} does not exist; create the data with `{} {}`",
            path.display(),
            Setting::MakeTrainingData,
            path.parent().unwrap_or(Path::new(".")).display()
        )));
    }
    Ok(read_samples(path)?)
}

/// Runs (or resumes) the training `run`; `pb` follows its steps.
/// A model to fine-tune (`run.init`) must have been fitted with the data's c_19 setting.
fn check_quirk(run: &FitRun, model: &ShapeAdaptiveModel, quirk: bool) -> Result<(), FitError> {
    if model.info().c19_quirk == quirk {
        return Ok(());
    }
    let path = run.init.as_ref().expect("the model of run.init is loaded");
    let with = |b: bool| if b { "with" } else { "without" };
    Err(FitError::Invalid(format!(
        "{} {}: the model was fitted {} VKJ19's c_19 = 0 quirk and the data \
         in {} {} it; fine-tune on data made with the same setting ({} when \
         making the data)",
        Setting::Init,
        path.display(),
        with(model.info().c19_quirk),
        run.data.display(),
        with(quirk),
        Setting::NoC19Quirk,
    )))
}

/// The provenance stored in the fitted model and in `train.json`: the data, the training
/// configuration, the starting model, the steps and seconds, and the last validation.
fn provenance(
    run: &FitRun,
    train_file: &Path,
    header: &SampleFileHeader,
    trainer: &Trainer,
) -> serde_json::Value {
    serde_json::json!({
        "source": "translucent train fit",
        "data": {
            "train_file": train_file.display().to_string(),
            "train_samples": header.sample_count,
            "generator": header.generator,
            "seed": header.seed,
            "config": header.config,
        },
        "training": trainer.config(),
        "init": run.init.as_ref().map(|p| p.display().to_string()),
        "steps": trainer.step(),
        "training_seconds": trainer.seconds(),
        "validation": trainer.history().last().map(|r| &r.val),
    })
}

pub fn run(run: &FitRun, pb: &ProgressBar) -> Result<FitOutcome, FitError> {
    let invalid = |m: String| Err(FitError::Invalid(m));
    let train_file = run.data.join("train.tlsamples");
    let (train_header, train) = load_set(&train_file)?;
    let val_path = run.data.join("val.tlsamples");
    let val = if val_path.exists() {
        read_samples(&val_path)?.1
    } else {
        tracing::warn!(
            "{} is missing: validating on the training set",
            val_path.display()
        );
        Vec::new()
    };
    // One run per output folder; released when this function returns (or the process dies).
    let _lock = scene::fsutil::lock_folder(&run.out)?;
    let ckpt = run.out.join("checkpoint.bin");
    let model_path = run.out.join("model.safetensors");
    let init =
        match &run.init {
            Some(p) => Some(ShapeAdaptiveModel::load(p).map_err(|e| {
                FitError::Invalid(format!("{} {}: {e}", Setting::Init, p.display()))
            })?),
            None => None,
        };
    let norm = match &init {
        Some(m) => m.normalisation().clone(),
        None => normalisation_of(&train)?,
    };
    let train_p: Prepared = prepare(&train, &norm)?;
    let val_p: Prepared = prepare(&val, &norm)?;
    drop(val);
    let Some(quirk) = train_header
        .config
        .get("quirk_c19")
        .and_then(|v| v.as_bool())
    else {
        return invalid(format!(
            "{}: the header has no boolean config.quirk_c19; regenerate the data",
            train_file.display()
        ));
    };
    let mut trainer = if run.resume {
        if !ckpt.exists() {
            return invalid(format!(
                "{}: {} does not exist",
                Setting::Resume,
                ckpt.display()
            ));
        }
        Trainer::resume(&ckpt, Some(run.config.steps), train_p, val_p)?
    } else {
        if (ckpt.exists() || model_path.exists()) && !run.overwrite {
            return invalid(format!(
                "{} already holds a training run; pass {} to continue it or {} to start again",
                run.out.display(),
                Setting::Resume,
                Setting::Overwrite
            ));
        }
        let info = bssrdf::model::ModelInfo {
            c19_quirk: quirk,
            frame_convention: bssrdf::model::FrameConvention::Vkj19,
            provenance: serde_json::Value::Null,
        };
        let w = run.config.weights.position;
        if !(w.is_finite() && w > 0.0) {
            return invalid(format!(
                "{} must be a positive number, got {w}",
                Setting::PositionWeight
            ));
        }
        let config = run.config.clone();
        match init {
            Some(model) => {
                check_quirk(run, &model, quirk)?;
                Trainer::from_model(config, model, train_p, val_p)?
            }
            None => Trainer::new(config, norm, info, train_p, val_p)?,
        }
    };
    pb.set_length(trainer.config().steps);
    pb.set_position(trainer.step());
    let start_step = trainer.step();
    let t0 = Instant::now();
    trainer.run(Some(&ckpt), |s| {
        if s.step % 100 == 0 {
            pb.set_position(s.step);
            if let Some(v) = s.last_val {
                pb.set_message(format!("loss {:.3} val {:.3}", s.loss, v));
            }
        }
    })?;
    pb.finish_and_clear();
    let seconds = t0.elapsed().as_secs_f64();
    let last = trainer.history().last().cloned();
    let provenance = provenance(run, &train_file, &train_header, &trainer);
    trainer.model_info_mut().provenance = provenance.clone();
    trainer.model().save(&model_path)?;
    crate::plot::write_history(trainer.history(), &run.out, true)?;
    scene::fsutil::atomic_write(
        &run.out.join("train.json"),
        serde_json::to_string_pretty(&provenance)?.as_bytes(),
        true,
    )?;
    let steps_this_run = trainer.step() - start_step;
    Ok(FitOutcome {
        steps: trainer.step(),
        steps_this_run,
        seconds,
        samples_per_second: steps_this_run as f64 * trainer.config().batch_size as f64
            / seconds.max(1e-9),
        validation: last.map(|r| format!("{:?}", r.val)),
        model: model_path,
    })
}
