//! Handing an experiment's cases to a scheduler instead of running them in one loop.
//!
//! An experiment is a set of named cases (a dataset and its runs, one random start, one
//! repetition of a capture). `--list-jobs` prints one self-contained command per case: the
//! command as given, with `--case NAME`. Each such command runs exactly its case into the shared
//! output folder (its dataset and run folders are its own; a dataset shared with other cases is
//! made under a lock that waits) and then tabulates every case that has finished so far;
//! `--assemble` only tabulates. Cases run on any machine that sees the output folder, in any
//! order, at the same time: Slurm and HyperQueue examples are in docs/commands.md.

use recovery::Observer;
use std::path::Path;

use crate::bail;
use crate::error::Result;
use scene::fsutil::FolderLock;
use scene::setting::Setting;

/// Which of an experiment's cases an invocation runs, or whether it lists them as jobs.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Jobs {
    /// List one self-contained command per case and run nothing: the words of the command
    /// that ran the experiment, to which each listed job adds its case ([`Setting::Case`]).
    pub list: Option<Vec<String>>,
    /// Run only this case into the output folder, then tabulate every case finished so far.
    pub case: Option<String>,
    /// Run nothing: tabulate the cases finished so far in the output folder.
    pub assemble: bool,
}

impl Jobs {
    /// Whether this invocation runs `case`.
    pub fn runs(&self, case: &str) -> bool {
        !self.assemble && self.case.as_deref().is_none_or(|c| c == case)
    }

    /// Whether this invocation runs every case (no `--case`, no `--assemble`).
    pub fn runs_all(&self) -> bool {
        !self.assemble && self.case.is_none()
    }

    /// Checks `--case` against the experiment's `cases`; with `--list-jobs` prints one command
    /// per case and returns true (the caller stops there).
    pub fn listed(&self, cases: &[String], obs: &dyn Observer) -> Result<bool> {
        if let Some(c) = &self.case
            && !cases.contains(c)
        {
            bail!(
                "{}: no case {c:?} in this experiment (its cases: {}); {} prints the command of \
                 each",
                Setting::Case,
                cases.join(", "),
                Setting::ListJobs
            );
        }
        let Some(argv) = &self.list else {
            return Ok(false);
        };
        let case_flag = Setting::Case.to_string();
        for case in cases {
            let words = argv
                .iter()
                .map(String::as_str)
                .chain([case_flag.as_str(), case.as_str()]);
            obs.say(&shlex::try_join(words).map_err(|e| {
                crate::ExperimentError::Invalid(format!("{}: {e}", Setting::ListJobs))
            })?);
        }
        Ok(true)
    }

    /// The claim on the output folder (created if needed): the whole folder when this
    /// invocation runs every case; none for a job or an assembly, whose runs lock their own
    /// folders.
    pub fn lock(&self, out: &Path) -> Result<Option<FolderLock>> {
        Ok(if self.runs_all() {
            Some(scene::fsutil::lock_folder(out)?)
        } else {
            std::fs::create_dir_all(out).map_err(|e| {
                crate::ExperimentError::Invalid(format!("cannot create {}: {e}", out.display()))
            })?;
            None
        })
    }

    /// Says which cases the tables leave out because they have not finished.
    pub fn report_missing(&self, missing: &[String], obs: &dyn Observer) {
        if !missing.is_empty() {
            obs.say(&format!(
                "not finished yet, left out of the tables: {}",
                missing.join(", ")
            ));
        }
    }
}

impl Jobs {
    /// Makes (or checks) an input that several cases share with `make`, unless this invocation
    /// only assembles: under the lock `out/locks/<name>` when cases may run side by side, so
    /// one job makes it and the others wait and then reuse it.
    pub fn shared_input<T>(
        &self,
        out: &Path,
        name: &str,
        make: impl FnOnce() -> Result<T>,
    ) -> Result<Option<T>> {
        if self.assemble {
            return Ok(None);
        }
        let _shared = if self.runs_all() {
            None
        } else {
            Some(shared_input_lock(out, name)?)
        };
        make().map(Some)
    }
}

/// Holds `out/locks/<name>` while a shared input (a dataset several cases use) is made or
/// checked, waiting for another job that holds it.
fn shared_input_lock(out: &Path, name: &str) -> Result<FolderLock> {
    Ok(scene::fsutil::lock_folder_waiting(
        &out.join("locks").join(name),
    )?)
}
