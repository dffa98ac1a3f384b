//! One recovery of an experiment: the library's settings ([`RecoverySettings`]) for a dataset
//! and a run folder, which start as the defaults a user gets ([`Run::defaults`]) and change only
//! where the experiment says so. Each field is one of `optimize`'s options, so every run is one
//! a user can type.

use std::path::{Path, PathBuf};

use recovery::{self, Observer, RecoveryConfig, RecoverySettings, RunResult};

use crate::Result;

/// A recovery of `dataset` into `out` with `settings`.
#[derive(Clone, Debug)]
pub struct Run {
    pub dataset: PathBuf,
    pub out: PathBuf,
    pub settings: RecoverySettings,
}

impl Run {
    /// `optimize --dataset DATASET --out OUT` with every other option at its default.
    pub fn defaults(dataset: &Path, out: &Path) -> Self {
        Run {
            dataset: dataset.to_path_buf(),
            out: out.to_path_buf(),
            settings: RecoverySettings::default(),
        }
    }

    /// The resolved recovery (reads the dataset's depth when the tracer needs it).
    pub fn config(&self) -> Result<RecoveryConfig> {
        Ok(self
            .settings
            .resolve_for(self.dataset.clone(), self.out.clone())?)
    }

    /// Runs the recovery into its folder, resumes it, or reuses it when it has finished
    /// ([`recovery::run_or_reuse`]).
    pub fn run_or_reuse(&self, obs: &dyn Observer, label: &str) -> Result<RunResult> {
        Ok(recovery::run_or_reuse(&self.config()?, obs, label)?)
    }

    /// The result if the folder holds the run finished ([`recovery::reuse::finished`]); runs
    /// nothing.
    pub fn finished(&self) -> Result<Option<RunResult>> {
        if !self.out.join("result.json").exists() {
            // Nothing to read (and its dataset, which the settings may need, may not exist yet).
            return Ok(None);
        }
        Ok(recovery::reuse::finished(&self.config()?))
    }

    /// The learned model's networks of the run: its model file, or the shipped model.
    pub fn networks(&self) -> Result<bssrdf::nn::ShapeAdaptiveModel> {
        Ok(match self.settings.model_file()? {
            Some(path) => bssrdf::model::load(&path)?,
            None => bssrdf::model::shipped()?,
        })
    }
}
