//! The recovery application: a recovery from a dataset folder into an output folder, the whole
//! of `translucent optimize` behind one typed configuration ([`RecoveryConfig`]), over the
//! inverse core (`inverse`: the forward models, the loop, the intervals and the checks).
//!
//! [`run`] loads the dataset, runs the Adam loop ([`inverse::optimize::Optimizer`]) with atomic
//! checkpoints, and writes:
//!
//! | file | content |
//! |---|---|
//! | `OUT/iterations.csv` | every iteration ([`crate::report::write_csv`]) |
//! | `OUT/checkpoint.json` | every `checkpoint_every` iterations, atomically; a resumed run continues bit-identically |
//! | `OUT/result.json` | the estimate, its 95 % intervals, the checks and the status |
//! | `OUT/convergence.png`/`.svg` | the parameters over the iterations |
//! | `OUT/final/` | re-renders beside the targets, false-colour differences, a contact sheet |
//! | `OUT/mitsuba/` | the reported medium as Mitsuba 3 XML: `medium.xml` (boundary and interior), the dataset's scene with it, `object.ply` |
//!
//! After the loop: the intervals ([`inverse::uncertainty`]), the bias correction of a learned-model
//! run without refinement ([`bias_correction`]), the consistency check by the volumetric path
//! tracer ([`inverse::consistency`]), the tracer's sensitivity along the σ_t valley
//! ([`inverse::sensitivity`]) and the health checks ([`inverse::health`]). Several initialisations
//! first with `starts > 1` ([`multi_start`]). [`reuse::run_or_reuse`] is the step of multi-run
//! commands (experiments, the correction's own recoveries, the starts) that runs, resumes or
//! reuses a run folder.
//!
//! What a user would read is given line by line to an [`Observer`], which also supplies the
//! progress bars; the library itself prints nothing.

use std::path::{Path, PathBuf};

use scene::Dataset;
use scene::setting::Setting;
use serde_json::json;

use inverse::optimize::{Checkpoint, InverseError, OptimizeConfig};
use inverse::params::Params;
use inverse::uncertainty::UncertaintySettings;

pub mod bias_correction;
mod checks;
mod fit;
pub mod multi_start;
mod outputs;
mod prepare;
pub mod report;
pub mod reuse;
pub mod settings;

pub use bias_correction::BiasCorrection;
pub use inverse::observer::{Observer, Silent};
pub use reuse::{RunResult, run_or_reuse};
pub use settings::RecoverySettings;

/// Everything a recovery needs, resolved: what the binary makes of `optimize`'s options.
#[derive(Clone, Debug)]
pub struct RecoveryConfig {
    /// The dataset folder: ours (dataset.json) or a Mitsuba reference folder (scene.json).
    pub dataset: PathBuf,
    /// The output folder.
    pub out: PathBuf,
    /// The loop's settings (initialisation, model, estimator, budget, refinement, seed, …).
    pub optimize: OptimizeConfig,
    /// A learned model file; `None`: the shipped model ([`bssrdf::model::shipped`]).
    pub model_file: Option<PathBuf>,
    /// The tracer depth the user gave (`None`: the dataset's own, already in `optimize`); only
    /// used to warn when it differs from the dataset's.
    pub max_depth: Option<u32>,
    /// Whether the refinement's length was given: a resumed run without it keeps refining from
    /// where it began ([`resume_budget`]).
    pub refine_given: bool,
    /// Iterations between checkpoints.
    pub checkpoint_every: u32,
    /// Samples per pixel of the re-renders in `OUT/final/`.
    pub final_spp: u32,
    /// The 95 % intervals (`views` 0: none).
    pub uncertainty: UncertaintySettings,
    /// Views re-rendered by the volumetric path tracer at the estimate (0: no check).
    pub consistency_views: usize,
    /// Initialisations tried first (1: none; [`multi_start`]).
    pub starts: u32,
    /// Continue the run in `out` from its checkpoint.
    pub resume: bool,
    /// Replace a run in `out`.
    pub overwrite: bool,
    /// The bias correction of a learned-model run without refinement.
    pub bias_correction: BiasCorrection,
}

impl RecoveryConfig {
    /// The library's defaults ([`RecoverySettings::default`]) for `dataset` into `out`, with
    /// what they need of the dataset given (`facts`: its tracer depth, its object's size)
    /// instead of read ([`RecoverySettings::resolve_for`] reads them).
    pub fn new(dataset: PathBuf, out: PathBuf, facts: settings::DatasetFacts) -> Self {
        RecoverySettings::default()
            .resolve(dataset, out, || Ok(facts))
            .expect("the default settings resolve")
    }

    /// The estimator's name (`ours`, `ad`, …).
    pub fn estimator(&self) -> &'static str {
        self.optimize.model.estimator_name()
    }
}

/// Why a recovery stopped.
#[derive(Debug, thiserror::Error)]
pub enum RecoveryError {
    /// Settings or data that cannot be used; the message says how to fix them.
    #[error("{0}")]
    Invalid(String),
    /// The loop, a render or an output failed.
    #[error(transparent)]
    Inverse(#[from] InverseError),
    /// A dataset, mesh or file could not be read or written.
    #[error(transparent)]
    Scene(#[from] scene::SceneError),
    /// The learned model could not be loaded.
    #[error(transparent)]
    Model(#[from] bssrdf::model::ModelError),
    /// A folder could not be created.
    #[error("cannot create {}", .path.display())]
    CreateDir {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// A folder could not be removed.
    #[error("cannot remove {}", .path.display())]
    RemoveDir {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// A JSON file could not be read.
    #[error("reading {}", .path.display())]
    Read {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// A file is not JSON, or a value not serialisable.
    #[error("{}", .path.as_ref().map_or("JSON".into(), |p| format!("{} is not valid JSON", p.display())))]
    Json {
        path: Option<PathBuf>,
        #[source]
        source: serde_json::Error,
    },
    /// The loop stopped on an error other than a numerical breakdown (a failed write or render):
    /// the outputs stay as they were, the last checkpoint included.
    #[error(
        "the optimisation stopped in iteration {iteration}; {} holds the last checkpoint \
         written before (resume from it with {})",
        .checkpoint.display(),
        Setting::Resume
    )]
    Stopped {
        iteration: usize,
        checkpoint: PathBuf,
        #[source]
        source: Box<InverseError>,
    },
    /// The observer stopped the loop ([`Observer::iteration`]); `result.json` says
    /// `interrupted` and the checkpoint resumes the run.
    #[error(
        "the run was stopped after iteration {iteration} of {of}; {} holds it (continue it with \
         {})",
        .checkpoint.display(),
        Setting::Resume
    )]
    Interrupted {
        iteration: usize,
        of: usize,
        checkpoint: PathBuf,
    },
    /// The loop broke down numerically; `result.json` records the failure.
    #[error(
        "the optimisation failed after {iterations} iterations (status in {})",
        .result.display()
    )]
    Failed {
        iterations: usize,
        result: PathBuf,
        #[source]
        source: Box<InverseError>,
    },
}

impl From<serde_json::Error> for RecoveryError {
    fn from(source: serde_json::Error) -> Self {
        RecoveryError::Json { path: None, source }
    }
}

/// The (iterations, refinement) a resumed run goes on with: the configuration's iterations, and
/// its refinement when given; without it, a run already in its refinement keeps refining from
/// where it began (a longer run refines longer), and one that has not reached it takes the
/// default of its new length, begun no earlier than the iterations done.
pub fn resume_budget(cfg: &RecoveryConfig, c: &Checkpoint) -> (u32, u32) {
    let n = cfg.optimize.iterations;
    let saved = &c.config;
    let done = c.history.len() as u32;
    let start = saved.iterations - saved.refine_iterations;
    let refining = saved.refine_iterations > 0 && done > start;
    let r = if cfg.refine_given {
        cfg.optimize.refine_iterations
    } else if refining {
        n.saturating_sub(start)
    } else {
        cfg.optimize.refine_iterations.min(n.saturating_sub(done))
    };
    (n, r)
}

/// A resumed run continues with the settings it started with: every setting of `now` must
/// equal the checkpoint's ([`reuse::differing_settings`]), except the number of iterations and
/// its refinement (`Optimizer::resume` checks those) and the view subset (a resumed run may
/// leave it out). The error names each differing setting with both values.
fn check_resume_settings(
    now: &OptimizeConfig,
    saved: &OptimizeConfig,
    ckpt: &Path,
) -> Result<(), RecoveryError> {
    let json = |c: &OptimizeConfig| {
        let mut c = c.clone();
        c.view_subset = None;
        c.refine_iterations = 0;
        serde_json::to_value(&c)
    };
    let diffs: Vec<String> = reuse::differing_settings(&json(now)?, &json(saved)?)
        .into_iter()
        .map(|d| {
            format!(
                "{}: the run has {}, this command gives {}",
                d.key, d.recorded, d.expected
            )
        })
        .collect();
    if !diffs.is_empty() {
        return Err(RecoveryError::Invalid(format!(
            "{}: the settings differ from those of the run in {} ({}); repeat the run's \
             own options (only {} may change), or start a new run with {}",
            Setting::Resume,
            ckpt.display(),
            diffs.join("; "),
            Setting::Iterations,
            Setting::Overwrite
        )));
    }
    Ok(())
}

/// The views of `ds` named by `subset` (indices into the dataset), in that order: a clear error
/// for an empty list, an index past the last view or an index given twice.
pub fn select_views(ds: &mut Dataset, subset: &[usize], what: &Path) -> Result<(), RecoveryError> {
    let n = ds.views.len();
    if subset.is_empty() {
        return Err(RecoveryError::Invalid(format!(
            "{}: give at least one view index",
            Setting::ViewSubset
        )));
    }
    for (k, &i) in subset.iter().enumerate() {
        if i >= n {
            return Err(RecoveryError::Invalid(format!(
                "{}: {} has {n} views (0 … {}); there is no view {i}",
                Setting::ViewSubset,
                what.display(),
                n.saturating_sub(1)
            )));
        }
        if subset[..k].contains(&i) {
            return Err(RecoveryError::Invalid(format!(
                "{}: view {i} is named twice",
                Setting::ViewSubset
            )));
        }
    }
    ds.views = subset.iter().map(|&i| ds.views[i].clone()).collect();
    Ok(())
}

/// Run the recovery `cfg` (module docs), in named stages: prepare the data, fit, the intervals,
/// the correction, the checks.
pub fn run(cfg: &RecoveryConfig, obs: &dyn Observer) -> Result<(), RecoveryError> {
    if cfg.starts > 1 {
        return run_starts(cfg, obs);
    }
    let (prepared, checkpoint) = prepare::prepare(cfg)?;
    let mut opt = prepared.start(cfg, checkpoint)?;
    let seconds = fit::fit(cfg, &mut opt, &prepared, obs)?;
    let (estimate, uncertainty, mut result) = fit::intervals(cfg, &opt, &prepared, seconds, obs)?;
    let shown = fit::correct(
        cfg,
        &opt,
        &prepared,
        (&estimate, uncertainty.as_ref()),
        &mut result,
        obs,
    )?;
    checks::check(
        cfg,
        &opt,
        &prepared,
        shown,
        uncertainty.as_ref(),
        result,
        obs,
    )
}

/// Several initialisations ([`multi_start`]), then the run from the best one, with the starts in
/// its record.
fn run_starts(cfg: &RecoveryConfig, obs: &dyn Observer) -> Result<(), RecoveryError> {
    Dataset::load(&cfg.dataset)?;
    let (starts, best) = {
        let _lock = scene::fsutil::lock_folder(&cfg.out)?;
        multi_start::run_starts(cfg, obs)?
    };
    let mut b = cfg.clone();
    b.starts = 1;
    // At the precision of the command line's initialisation.
    b.optimize.init = Params {
        sigma_t: starts[best].estimate.sigma_t.map(|v| v as f32 as f64),
        albedo: starts[best].estimate.albedo.map(|v| v as f32 as f64),
        g: starts[best].estimate.g.map(|g| g.map(|v| v as f32 as f64)),
        light_scale: starts[best]
            .estimate
            .light_scale
            .map(|k| k.map(|v| v as f32 as f64)),
    };
    run(&b, obs)?;
    // The starts go into the run's record.
    let mut result = reuse::read_json(&cfg.out.join("result.json"))?;
    result["starts"] = json!({ "starts": starts, "chosen": best });
    write_result(&cfg.out, &result)
}

/// `OUT/result.json`, replaced atomically.
pub fn write_result(out: &Path, result: &serde_json::Value) -> Result<(), RecoveryError> {
    scene::fsutil::atomic_write(
        &out.join("result.json"),
        serde_json::to_string_pretty(result)?.as_bytes(),
        true,
    )?;
    Ok(())
}

/// The estimate, and the truth and the errors when known, as the summary's lines.
pub fn estimate_lines(est: &Params, truth: Option<&Params>) -> Vec<String> {
    let f3 = |v: [f64; 3], p: usize| format!("({:.p$}, {:.p$}, {:.p$})", v[0], v[1], v[2], p = p);
    // A recovered g and light scale, printed after α.
    let g = |p: &Params| {
        let g = p.g.map(|g| format!("  g = {g:.3}")).unwrap_or_default();
        let k = p
            .light_scale
            .map(|k| format!("  light ×{k:.4}"))
            .unwrap_or_default();
        g + &k
    };
    let mut out = vec![format!(
        "  estimate  σ_t = {}  α = {}{}",
        f3(est.sigma_t, 2),
        f3(est.albedo, 4),
        g(est)
    )];
    if let Some(t) = truth {
        out.push(format!(
            "  truth     σ_t = {}  α = {}{}",
            f3(t.sigma_t, 2),
            f3(t.albedo, 4),
            g(t)
        ));
        let rel: [f64; 3] = std::array::from_fn(|c| 100.0 * (est.sigma_t[c] / t.sigma_t[c] - 1.0));
        let abs: [f64; 3] = std::array::from_fn(|c| est.albedo[c] - t.albedo[c]);
        let g_err = match (est.g, t.g) {
            (Some(e), Some(t)) => format!("  g {:+.3}", e.zip_with(t, |e, t| e - t)),
            _ => String::new(),
        };
        out.push(format!(
            "  error     σ_t {} %  α {}{g_err}",
            f3(rel, 1),
            f3(abs, 4)
        ));
    }
    out
}
