//! Where a long computation reports to: the lines a user reads and the progress bars. The
//! binaries show them on the terminal; a test or a library caller passes [`Silent`].

use std::ops::ControlFlow;

use indicatif::ProgressBar;

use crate::optimize::IterationRecord;
use crate::params::Params;

/// Where a recovery reports to: the lines a user reads and the progress bars.
pub trait Observer: Sync {
    /// A progress bar of `len` steps (0: no length) labelled `label`.
    fn progress(&self, len: u64, label: &str) -> ProgressBar;
    /// One line of the report.
    fn say(&self, line: &str);
    /// Each iteration of an optimisation loop, after its step: the record and the parameters
    /// after the step. [`ControlFlow::Break`] stops the run cleanly after this iteration
    /// (checkpointed, resumable); the default never stops it.
    fn iteration(&self, _record: &IterationRecord, _params: &Params) -> ControlFlow<()> {
        ControlFlow::Continue(())
    }
}

/// An observer that shows nothing.
pub struct Silent;

impl Observer for Silent {
    fn progress(&self, _len: u64, _label: &str) -> ProgressBar {
        ProgressBar::hidden()
    }
    fn say(&self, _line: &str) {}
}
