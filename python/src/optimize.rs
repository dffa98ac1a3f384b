//! `translucent.optimize`: the recovery of `translucent optimize` (`recovery::run`) from a
//! dataset folder into an output folder, with the product's defaults
//! (`recovery::RecoverySettings::default`) changed by keyword ([`crate::options`]).
//!
//! The recovery runs on a worker thread without the GIL while the calling thread waits, checking
//! for Ctrl-C every 100 ms; an interrupt, or a callback that returns `False`, stops the loop
//! after its current iteration with a checkpoint (`result.json` then says `interrupted`, and
//! `resume=True` continues the run). The callback is called after every iteration with
//! (iteration, parameters, loss) while the worker waits for it.

use std::ops::ControlFlow;
use std::path::PathBuf;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::time::Duration;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use inverse::optimize::IterationRecord;
use inverse::params::{OneOrRgb, Params};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use recovery::{Observer, RecoveryError};

use crate::{errors, options};

/// Reports to Python: lines through `print`, progress bars on stderr, each iteration to the
/// callback.
struct PyObserver {
    callback: Option<Py<PyAny>>,
    verbose: bool,
    /// Set by the waiting thread on Ctrl-C.
    interrupt: AtomicBool,
    /// The callback's own exception, raised again once the run has stopped.
    raised: Mutex<Option<PyErr>>,
}

/// The parameters as the callback sees them: σ_t and albedo as 3-tuples, g and the light
/// scale where recovered.
fn params_dict<'py>(py: Python<'py>, p: &Params) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("sigma_t", (p.sigma_t[0], p.sigma_t[1], p.sigma_t[2]))?;
    d.set_item("albedo", (p.albedo[0], p.albedo[1], p.albedo[2]))?;
    match p.g {
        Some(OneOrRgb::One(g)) => d.set_item("g", g)?,
        Some(OneOrRgb::Rgb(g)) => d.set_item("g", (g[0], g[1], g[2]))?,
        None => {}
    }
    match p.light_scale {
        Some(OneOrRgb::One(k)) => d.set_item("light_scale", k)?,
        Some(OneOrRgb::Rgb(k)) => d.set_item("light_scale", (k[0], k[1], k[2]))?,
        None => {}
    }
    Ok(d)
}

impl Observer for PyObserver {
    fn progress(&self, len: u64, label: &str) -> ProgressBar {
        if !self.verbose {
            return ProgressBar::hidden();
        }
        let pb = ProgressBar::with_draw_target(Some(len), ProgressDrawTarget::stderr());
        if let Ok(style) = ProgressStyle::with_template(
            "{msg:>12} [{elapsed_precise}] {wide_bar} {pos}/{len} ({eta} left)",
        ) {
            pb.set_style(style);
        }
        pb.set_message(label.to_string());
        pb
    }

    fn say(&self, line: &str) {
        if self.verbose {
            Python::attach(|py| {
                let _ = py
                    .import("builtins")
                    .and_then(|b| b.getattr("print"))
                    .and_then(|p| p.call1((line,)));
            });
        }
    }

    fn iteration(&self, record: &IterationRecord, params: &Params) -> ControlFlow<()> {
        if self.interrupt.load(Ordering::SeqCst) {
            return ControlFlow::Break(());
        }
        let Some(cb) = &self.callback else {
            return ControlFlow::Continue(());
        };
        Python::attach(|py| {
            let called = params_dict(py, params)
                .and_then(|p| cb.call1(py, (record.iteration, p, record.loss)));
            match called {
                // `False` stops; None (no return) and anything else go on.
                Ok(r) if r.bind(py).is(&*pyo3::types::PyBool::new(py, false)) => {
                    ControlFlow::Break(())
                }
                Ok(_) => ControlFlow::Continue(()),
                Err(e) => {
                    *self.raised.lock().unwrap_or_else(|p| p.into_inner()) = Some(e);
                    ControlFlow::Break(())
                }
            }
        })
    }
}

/// Runs the recovery of `dataset` into `out` with the product's defaults changed by `options`
/// (a dict of keyword arguments, [`options::OPTIONS`]). Returns normally when the run ends,
/// also when it failed (`result.json` says so) or the callback stopped it; raises on bad
/// settings or data, on Ctrl-C (`KeyboardInterrupt`, after the checkpoint) and with the
/// callback's own exception.
#[pyfunction]
#[pyo3(signature = (dataset, out, options = None, callback = None, verbose = true, threads = None))]
pub fn optimize(
    py: Python<'_>,
    dataset: PathBuf,
    out: PathBuf,
    options: Option<Bound<'_, PyDict>>,
    callback: Option<Py<PyAny>>,
    verbose: bool,
    threads: Option<usize>,
) -> PyResult<()> {
    let settings = options::settings(options.as_ref())?;
    let pool = crate::pool(threads)?;
    let cfg = {
        let (d, o) = (dataset.clone(), out.clone());
        py.detach(move || settings.resolve_for(d, o))
            .map_err(errors::recovery)?
    };
    let obs = PyObserver {
        callback,
        verbose,
        interrupt: AtomicBool::new(false),
        raised: Mutex::new(None),
    };
    let mut keyboard: Option<PyErr> = None;
    let ran = std::thread::scope(|scope| {
        let (tx, rx) = mpsc::channel();
        let rx = Mutex::new(rx);
        let (cfg, obs, pool) = (&cfg, &obs, pool.as_ref());
        scope.spawn(move || {
            let r = match pool {
                Some(p) => p.install(|| recovery::run(cfg, obs)),
                None => recovery::run(cfg, obs),
            };
            let _ = tx.send(r);
        });
        loop {
            match py.detach(|| {
                rx.lock()
                    .unwrap_or_else(|p| p.into_inner())
                    .recv_timeout(Duration::from_millis(100))
            }) {
                Ok(r) => break Some(r),
                Err(mpsc::RecvTimeoutError::Timeout) => {
                    if keyboard.is_none()
                        && let Err(e) = py.check_signals()
                    {
                        obs.interrupt.store(true, Ordering::SeqCst);
                        keyboard = Some(e);
                    }
                }
                // The worker panicked: the scope raises its panic on return.
                Err(mpsc::RecvTimeoutError::Disconnected) => break None,
            }
        }
    });
    let Some(ran) = ran else {
        return Err(errors::Error::new_err("the recovery stopped unexpectedly"));
    };
    if let Some(e) = obs.raised.lock().unwrap_or_else(|p| p.into_inner()).take() {
        return Err(e);
    }
    match ran {
        Ok(()) => Ok(()),
        Err(e @ RecoveryError::Interrupted { .. }) => match keyboard {
            Some(k) => {
                if verbose {
                    obs.say(&errors::chain(&e));
                }
                Err(k)
            }
            // Stopped by the callback: the run's record says so, unless the stop came in a
            // run of its own (a start of several), whose folder the message names.
            None if cfg.out.join("result.json").is_file() => Ok(()),
            None => Err(errors::Error::new_err(errors::chain(&e))),
        },
        // A numerical breakdown leaves a failed result.json: a result, not an exception.
        Err(RecoveryError::Failed { .. }) => Ok(()),
        Err(e) => Err(errors::recovery(e)),
    }
}

/// The product's default of every `optimize` option, with what it sets: {name: (default,
/// description)}.
#[pyfunction]
pub fn default_options(py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
    let d = PyDict::new(py);
    for (name, help) in options::OPTIONS {
        d.set_item(*name, (options::default_of(py, name)?, *help))?;
    }
    Ok(d)
}
