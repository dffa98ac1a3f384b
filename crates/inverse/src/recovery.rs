//! A recovery from a dataset folder into an output folder: the whole of `translucent optimize`
//! behind one typed configuration ([`RecoveryConfig`]).
//!
//! [`run`] loads the dataset, runs the Adam loop ([`crate::optimize::Optimizer`]) with atomic
//! checkpoints, and writes:
//!
//! | file | content |
//! |---|---|
//! | `OUT/iterations.csv` | every iteration ([`crate::report::write_csv`]) |
//! | `OUT/checkpoint.json` | every `checkpoint_every` iterations, atomically; a resumed run continues bit-identically |
//! | `OUT/result.json` | the estimate, its 95 % intervals, the checks and the status |
//! | `OUT/convergence.png`/`.svg` | the parameters over the iterations |
//! | `OUT/final/` | re-renders beside the targets, false-colour differences, a contact sheet |
//!
//! After the loop: the intervals ([`crate::uncertainty`]), the bias correction of a learned-model
//! run without refinement ([`bias_correction`]), the consistency check by the volumetric path
//! tracer ([`crate::consistency`]), the tracer's sensitivity along the σ_t valley
//! ([`crate::sensitivity`]) and the health checks ([`crate::health`]). Several initialisations
//! first with `starts > 1` ([`multi_start`]). [`reuse::run_or_reuse`] is the step of multi-run
//! commands (experiments, the correction's own recoveries, the starts) that runs, resumes or
//! reuses a run folder.
//!
//! What a user would read is given line by line to an [`Observer`], which also supplies the
//! progress bars; the library itself prints nothing.

use std::path::{Path, PathBuf};
use std::time::Instant;

use bssrdf::render::RenderSettings;
use indicatif::ProgressBar;
use scene::{Dataset, Image, Medium};
use serde_json::json;

use crate::consistency::CheckView;
use crate::forward::ModelKind;
use crate::optimize::{Checkpoint, InverseError, OptimizeConfig, Optimizer, TargetView};
use crate::params::Params;
use crate::report;
use crate::uncertainty::UncertaintySettings;
use crate::views::build_accel;

pub mod bias_correction;
pub mod multi_start;
pub mod reuse;

pub use bias_correction::BiasCorrection;
pub use reuse::{RunResult, run_or_reuse};

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
    /// The library's defaults ([`OptimizeConfig::default`]) for `dataset` into `out`, with the
    /// dataset's own tracer depth `depth` for the refinement.
    pub fn new(dataset: PathBuf, out: PathBuf, depth: Option<u32>) -> Self {
        let mut optimize = OptimizeConfig::default();
        if optimize.refine_iterations > 0 {
            optimize.volpath_max_depth = depth;
        }
        RecoveryConfig {
            dataset,
            out,
            optimize,
            model_file: None,
            max_depth: None,
            refine_given: false,
            checkpoint_every: 10,
            final_spp: 64,
            uncertainty: UncertaintySettings::default(),
            consistency_views: 4,
            starts: 1,
            resume: false,
            overwrite: false,
            bias_correction: BiasCorrection::default(),
        }
    }

    /// The estimator's name (`ours`, `ad`, …).
    pub fn estimator(&self) -> &'static str {
        self.optimize.method.name()
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
         written before (resume from it with --resume)",
        .checkpoint.display()
    )]
    Stopped {
        iteration: usize,
        checkpoint: PathBuf,
        #[source]
        source: Box<InverseError>,
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

/// Where a recovery reports to: the lines a user reads and the progress bars.
pub trait Observer: Sync {
    /// A progress bar of `len` steps (0: no length) labelled `label`.
    fn progress(&self, len: u64, label: &str) -> ProgressBar;
    /// One line of the report.
    fn say(&self, line: &str);
}

/// An observer that shows nothing.
pub struct Silent;

impl Observer for Silent {
    fn progress(&self, _len: u64, _label: &str) -> ProgressBar {
        ProgressBar::hidden()
    }
    fn say(&self, _line: &str) {}
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
            "--resume: the settings differ from those of the run in {} ({}); repeat the run's \
             own options (only --iterations may change), or start a new run with --overwrite",
            ckpt.display(),
            diffs.join("; ")
        )));
    }
    Ok(())
}

/// The views of `ds` named by `subset` (indices into the dataset), in that order: a clear error
/// for an empty list, an index past the last view or an index given twice.
pub fn select_views(ds: &mut Dataset, subset: &[usize], what: &Path) -> Result<(), RecoveryError> {
    let n = ds.views.len();
    if subset.is_empty() {
        return Err(RecoveryError::Invalid(
            "--view-subset: give at least one view index".into(),
        ));
    }
    for (k, &i) in subset.iter().enumerate() {
        if i >= n {
            return Err(RecoveryError::Invalid(format!(
                "--view-subset: {} has {n} views (0 … {}); there is no view {i}",
                what.display(),
                n.saturating_sub(1)
            )));
        }
        if subset[..k].contains(&i) {
            return Err(RecoveryError::Invalid(format!(
                "--view-subset: view {i} is named twice"
            )));
        }
    }
    ds.views = subset.iter().map(|&i| ds.views[i].clone()).collect();
    Ok(())
}

/// The learned model of `cfg` (the shipped one unless a file is named). The volumetric and
/// dipole models have no networks; the optimiser's interface still takes one, unused.
fn load_model(cfg: &RecoveryConfig) -> Result<bssrdf::nn::ShapeAdaptiveModel, RecoveryError> {
    Ok(match (&cfg.model_file, cfg.optimize.model) {
        (Some(path), ModelKind::Learned) => bssrdf::model::load(path)?,
        _ => bssrdf::model::shipped()?,
    })
}

/// Run the recovery `cfg` (module docs).
pub fn run(cfg: &RecoveryConfig, obs: &dyn Observer) -> Result<(), RecoveryError> {
    if cfg.starts > 1 {
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
        };
        run(&b, obs)?;
        // The starts go into the run's record.
        let mut result = reuse::read_json(&cfg.out.join("result.json"))?;
        result["starts"] = json!({ "starts": starts, "chosen": best });
        return write_result(&cfg.out, &result);
    }
    let mut ds = Dataset::load(&cfg.dataset)?;
    // One run per output folder; released when this function returns (or the process dies).
    let _lock = scene::fsutil::lock_folder(&cfg.out)?;
    let ckpt = cfg.out.join("checkpoint.json");
    let checkpoint = if cfg.resume {
        let c = Checkpoint::read(&ckpt)?;
        check_resume_settings(&cfg.optimize, &c.config, &ckpt)?;
        Some(c)
    } else {
        None
    };
    // A resumed run fits the views it started with.
    let subset = match &checkpoint {
        Some(c) => {
            let given = &cfg.optimize.view_subset;
            if given.is_some() && *given != c.config.view_subset {
                return Err(RecoveryError::Invalid(format!(
                    "--view-subset {:?} differs from the views of the run in {} ({:?}); resume \
                     without --view-subset or start a new run",
                    given.as_deref().unwrap_or_default(),
                    cfg.out.display(),
                    c.config
                        .view_subset
                        .as_deref()
                        .map_or("all".into(), |v| format!("{v:?}"))
                )));
            }
            c.config.view_subset.clone()
        }
        None => cfg.optimize.view_subset.clone(),
    };
    if let Some(s) = &subset {
        select_views(&mut ds, s, &cfg.dataset)?;
    }
    let (mesh, warnings) = ds.load_mesh()?;
    let accel = build_accel(mesh, &warnings, &cfg.dataset.display().to_string());
    // Every iteration's light term asks for them; decide them once, in parallel, before the
    // first iteration rather than lazily in the first iterations.
    let t0 = Instant::now();
    let supporting = accel.decide_all_supporting();
    tracing::debug!(
        "supporting planes: {supporting} of {} triangles in {:.0} ms",
        accel.mesh().triangle_count(),
        t0.elapsed().as_secs_f64() * 1e3
    );
    if cfg.optimize.model == ModelKind::Volpath {
        let depth = cfg.max_depth.unwrap_or(32);
        if let Some(d) = ds
            .render
            .max_depth
            .filter(|d| cfg.max_depth.is_some() && *d != depth)
        {
            tracing::warn!(
                "the dataset was rendered with maximum depth {d}, the model traces to \
                 --max-depth {depth}"
            );
        }
    }
    let model = load_model(cfg)?;
    let targets = TargetView::of_dataset(&ds, &cfg.dataset.display().to_string())?;
    let images: Vec<&Image> = targets.iter().map(|t| t.image).collect();
    let base = ds.truth.unwrap_or(Medium {
        sigma_t: [50.0; 3],
        albedo: [0.5; 3],
        g: 0.0,
        eta: 1.0,
    });
    let truth = ds.truth.as_ref().map(Params::of);
    std::fs::create_dir_all(&cfg.out).map_err(|source| RecoveryError::CreateDir {
        path: cfg.out.clone(),
        source,
    })?;
    let mut opt = if let Some(c) = checkpoint {
        let budget = resume_budget(cfg, &c);
        Optimizer::resume(c, Some(budget), &accel, &model, base, targets)?
    } else {
        if ckpt.exists() && !cfg.overwrite {
            return Err(RecoveryError::Invalid(format!(
                "{} already holds an optimisation run; pass --resume to continue it or \
                 --overwrite to start again",
                cfg.out.display()
            )));
        }
        // The bootstrap folders belong to the run being replaced.
        let boot = cfg.out.join("bootstrap");
        if cfg.overwrite && boot.is_dir() {
            std::fs::remove_dir_all(&boot)
                .map_err(|source| RecoveryError::RemoveDir { path: boot, source })?;
        }
        Optimizer::new(cfg.optimize.clone(), &accel, &model, base, targets)?
    };
    let t0 = Instant::now();
    let pb = obs.progress(opt.config().iterations as u64, "optimize");
    pb.set_position(opt.iteration() as u64);
    let csv = cfg.out.join("iterations.csv");
    let ran = opt.run(Some((&ckpt, cfg.checkpoint_every)), |r, p| {
        pb.set_position(r.iteration as u64 + 1);
        pb.set_message(format!(
            "loss {:.3e} σ_t ({:.1}, {:.1}, {:.1}) α ({:.3}, {:.3}, {:.3})",
            r.loss, p.sigma_t[0], p.sigma_t[1], p.sigma_t[2], p.albedo[0], p.albedo[1], p.albedo[2]
        ));
    });
    pb.finish_and_clear();
    if let Err(e) = ran {
        if !matches!(e, InverseError::NonFinite { .. }) {
            // A failed write (disk full, permissions) or render: the outputs on disk stay as
            // they were (the last checkpoint included, written atomically); say what failed.
            return Err(RecoveryError::Stopped {
                iteration: opt.history().len(),
                checkpoint: ckpt,
                source: Box::new(e),
            });
        }
        // A run that broke down numerically still leaves its record: the history so far and a
        // failed status (the last good checkpoint stays as it was).
        report::write_csv(opt.history(), &csv)?;
        let failed = json!({
            "status": "failed",
            "problems": [crate::health::Problem::NonFinite { detail: e.to_string() }],
            "iterations": opt.history().len(),
            "config": opt.config(),
        });
        write_result(&cfg.out, &failed)?;
        return Err(RecoveryError::Failed {
            iterations: opt.history().len(),
            result: cfg.out.join("result.json"),
            source: Box::new(e),
        });
    }
    let seconds_total = t0.elapsed().as_secs_f64();
    report::write_csv(opt.history(), &csv)?;
    let estimate = opt.params();
    let uncertainty = if cfg.uncertainty.views > 0 {
        let pb = obs.progress(0, "95 % intervals");
        let u = opt.uncertainty(&cfg.uncertainty)?;
        pb.finish_and_clear();
        Some(u)
    } else {
        None
    };
    let mut result = report::result_json(
        opt.config(),
        opt.history(),
        &estimate,
        truth.as_ref(),
        seconds_total,
    );
    report::add_assessment(&mut result, &[], uncertainty.as_ref());
    // Not final until the correction and the checks below are in: an interrupted command is
    // resumed rather than reused (`run_or_reuse`).
    result["complete"] = json!(false);
    write_result(&cfg.out, &result)?;
    report::write_plots(
        opt.history(),
        &estimate,
        truth.as_ref(),
        uncertainty.as_ref(),
        &cfg.out.join("convergence.png"),
    )?;
    rerender(cfg, &opt, &ds, &estimate, obs)?;
    let spi = result["seconds_per_iteration"].as_f64().unwrap_or(f64::NAN);
    obs.say(&format!(
        "after {} iterations ({spi:.2} s/iteration):",
        opt.history().len()
    ));
    for line in estimate_lines(&estimate, truth.as_ref()) {
        obs.say(&line);
    }
    let (mut shown, mut shown_u) = (estimate, uncertainty.clone());
    // The volumetric model is the simulator the correction would use: it has no bias of its own
    // to measure, and a correction would only add a second recovery's noise. The same holds
    // after a volumetric refinement.
    if cfg.bias_correction.enabled && opt.config().final_model() == ModelKind::Learned {
        // The model's own fit stays in convergence.png and final/; result.json reports the
        // corrected medium.
        let c = bias_correction::correct(cfg, &ds, &estimate, &base, obs)?;
        result =
            bias_correction::corrected_result(result, &c, truth.as_ref(), uncertainty.as_ref());
        if let Some(last) = c.steps.last() {
            obs.say(&format!(
                "bias-corrected ({} step{}, simulations at {} spp):",
                c.steps.len(),
                if c.steps.len() == 1 { "" } else { "s" },
                c.spp
            ));
            for line in estimate_lines(&last.corrected, truth.as_ref()) {
                obs.say(&line);
            }
            shown = last.corrected;
            shown_u = uncertainty.as_ref().map(|u| u.corrected(&estimate, &shown));
        }
    }
    // The reported medium, rendered by the volumetric path tracer, against the targets; and
    // the tracer's own sensitivity along the σ_t valley on the same views.
    let n = ds.views.len();
    let k = cfg.consistency_views.min(n);
    let check_views: Vec<(usize, CheckView)> = (0..k)
        .map(|i| i * n / k)
        .map(|v| {
            let view = CheckView {
                camera: &ds.views[v].camera,
                light: &ds.views[v].light,
                target: images[v],
                index: opt.config().view_subset.as_ref().map_or(v, |s| s[v]),
            };
            (v, view)
        })
        .collect();
    let check_spp = ds.render.spp.unwrap_or(64);
    // The tracer renders the checks at the targets' own path depth.
    let check_depth = ds.render.max_depth.unwrap_or(32);
    let consistency = (k > 0).then(|| {
        let views: Vec<_> = check_views.iter().map(|(_, v)| *v).collect();
        let pb = obs.progress(0, "consistency (volumetric path tracer)");
        let c = crate::consistency::check(
            &accel,
            &shown.medium(&base),
            &views,
            check_spp,
            check_depth,
            cfg.optimize.seed ^ 0xC0_5157,
        );
        pb.finish_and_clear();
        c
    });
    // The tracer's own curvature against the learned model's: nothing to check when the
    // tracer is the model.
    let learned_model = opt.config().final_model() == ModelKind::Learned;
    let sensitivity = uncertainty
        .as_ref()
        // With σ_t fixed there is no interval of σ_t to widen.
        .filter(|u| learned_model && !u.fixed[0])
        .and_then(|u| {
            // The checked views whose learned bread the intervals measured.
            let (views, breads): (Vec<_>, Vec<_>) = check_views
                .iter()
                .filter_map(|(v, view)| {
                    let bread = u.view_bread.iter().find(|(i, _)| i == v)?.1;
                    Some((*view, bread))
                })
                .unzip();
            if views.is_empty() {
                return None;
            }
            let pb = obs.progress(
                0,
                "sensitivity along the σ_t valley (volumetric path tracer)",
            );
            let s = crate::sensitivity::measure(
                &accel,
                &shown.medium(&base),
                &views,
                &breads,
                // With α fixed there is no valley: the direction is σ_t alone.
                if u.fixed[1] {
                    [0.0; 3]
                } else {
                    crate::sensitivity::valley_slope(&u.bread())
                },
                check_spp,
                check_depth,
                cfg.optimize.seed ^ 0x5E_4517,
            );
            pb.finish_and_clear();
            Some(s)
        });
    if let (Some(u), Some(s)) = (&shown_u, &sensitivity) {
        let widened = u.with_sensitivity(&shown, s);
        if let serde_json::Value::Object(m) = widened.to_json() {
            result
                .as_object_mut()
                .expect("result.json is an object")
                .extend(m);
        }
        result["sensitivity"] = serde_json::to_value(s)?;
        shown_u = Some(widened);
    }
    let c = &cfg.optimize;
    let final_from = match c.refine_iterations {
        0 => 0,
        r => c.iterations.saturating_sub(r) as usize,
    };
    let mut problems = crate::health::assess(
        opt.history(),
        final_from,
        &shown,
        &opt.config().params,
        base.g as f64,
        consistency.as_ref(),
    );
    if !learned_model {
        // The training range is the learned model's; the tracer has none.
        problems.retain(|p| !matches!(p, crate::health::Problem::OutsideTrainingRange { .. }));
    }
    report::add_assessment(&mut result, &problems, None);
    if let Some(c) = &consistency {
        result["consistency"] = serde_json::to_value(c)?;
    }
    result["complete"] = json!(true);
    write_result(&cfg.out, &result)?;
    if let Some(u) = &shown_u {
        for line in report::interval_lines(&shown, u) {
            obs.say(&format!("  {line}"));
        }
    }
    if let Some(s) = &sensitivity {
        let rel = |c: usize| {
            format!(
                "{:.2} ± {:.2}",
                s.volpath[c] / s.learned[c],
                (2.0 * s.volpath_se[c] / s.learned[c]).abs()
            )
        };
        let along = if cfg.optimize.params.fix_albedo {
            "σ_t (α fixed)"
        } else {
            "σ_t along the σ_t–α valley"
        };
        obs.say(&format!(
            "  sensitivity to {along} (volumetric path tracer, {} views): the images curve ({}, \
             {}, {})× as much as the learned model says (± two standard errors); the intervals \
             widen by up to √ρ = ({:.2}, {:.2}, {:.2}) from the lower end, to at most a factor \
             10 either way",
            s.views.len(),
            rel(0),
            rel(1),
            rel(2),
            s.ratio[0].sqrt(),
            s.ratio[1].sqrt(),
            s.ratio[2].sqrt()
        ));
    }
    if let Some(c) = &consistency {
        obs.say(&format!(
            "  consistency (the estimate rendered by the volumetric path tracer, {} views): \
             brightness ratio ({:.3}, {:.3}, {:.3}), L2 ({:.2}, {:.2}, {:.2})× the noise floor \
             (the targets' own pixel variance {:.1}, {:.1}, {:.1}× our renders')",
            c.views.len(),
            c.mean_ratio[0],
            c.mean_ratio[1],
            c.mean_ratio[2],
            c.l2_over_noise[0],
            c.l2_over_noise[1],
            c.l2_over_noise[2],
            c.target_noise_ratio[0],
            c.target_noise_ratio[1],
            c.target_noise_ratio[2]
        ));
    }
    if problems.is_empty() {
        obs.say("  status: ok");
    }
    for p in &problems {
        obs.say(&format!("  FAILED: {}", p.message()));
    }
    obs.say(&format!(
        "wrote {} (result.json, convergence.png/.svg, final/contact-sheet.png: every target \
         beside its re-render and difference)",
        cfg.out.display()
    ));
    Ok(())
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
    let mut out = vec![format!(
        "  estimate  σ_t = {}  α = {}",
        f3(est.sigma_t, 2),
        f3(est.albedo, 4)
    )];
    if let Some(t) = truth {
        out.push(format!(
            "  truth     σ_t = {}  α = {}",
            f3(t.sigma_t, 2),
            f3(t.albedo, 4)
        ));
        let rel: [f64; 3] = std::array::from_fn(|c| 100.0 * (est.sigma_t[c] / t.sigma_t[c] - 1.0));
        let abs: [f64; 3] = std::array::from_fn(|c| est.albedo[c] - t.albedo[c]);
        out.push(format!(
            "  error     σ_t {} %  α {}",
            f3(rel, 1),
            f3(abs, 4)
        ));
    }
    out
}

/// Views re-rendered at the end of a run, at most: evenly spread over larger datasets.
const RERENDER_VIEWS: usize = 48;

/// Re-renders the views at the estimate next to their targets, with error images, and the
/// contact sheet of them all (`final/contact-sheet.png`).
fn rerender(
    cfg: &RecoveryConfig,
    opt: &Optimizer,
    ds: &Dataset,
    est: &Params,
    obs: &dyn Observer,
) -> Result<(), RecoveryError> {
    let dir = cfg.out.join("final");
    std::fs::create_dir_all(&dir).map_err(|source| RecoveryError::CreateDir {
        path: dir.clone(),
        source,
    })?;
    let n = ds.views.len();
    let k = n.min(RERENDER_VIEWS);
    let chosen: Vec<usize> = (0..k).map(|i| i * n / k).collect();
    let pb = obs.progress(k as u64, "re-renders");
    let mut imgs = Vec::new();
    for &i in &chosen {
        let v = &ds.views[i];
        let rs = RenderSettings {
            spp: cfg.final_spp,
            seed: cfg.optimize.seed ^ 0xF1AA_1000,
            view: i as u64,
        };
        imgs.push(opt.render(est, &v.camera, &v.light, &rs)?);
        pb.inc(1);
    }
    pb.finish_and_clear();
    let targets: Vec<&Image> = chosen
        .iter()
        .filter_map(|&i| ds.views[i].image.as_ref())
        .collect();
    let exposure = scene::image::auto_exposure(
        &targets
            .iter()
            .take(8)
            .map(|&t| t.clone())
            .collect::<Vec<_>>(),
    );
    for ((img, t), &i) in imgs.iter().zip(&targets).zip(&chosen) {
        // Named by the view's index in the dataset (the same as i without a view subset).
        let index = opt.config().view_subset.as_ref().map_or(i, |s| s[i]);
        write_view(&dir, &format!("view_{index:03}"), img, t, exposure)?;
    }
    // The first four views at a glance: targets above, re-renders below.
    let m = imgs.len().min(targets.len()).min(4);
    let overview = Image::grid(&[targets[..m].to_vec(), imgs[..m].iter().collect()], 2);
    overview.write_png(&dir.join("overview.png"), exposure, true)?;
    let renders: Vec<&Image> = imgs.iter().collect();
    report::contact_sheet(&targets, &renders, exposure)?.write_png(
        &dir.join("contact-sheet.png"),
        1.0,
        true,
    )?;
    Ok(())
}

fn write_view(
    dir: &Path,
    name: &str,
    img: &Image,
    target: &Image,
    exposure: f32,
) -> Result<(), RecoveryError> {
    img.write_exr(&dir.join(format!("{name}.exr")), true)?;
    img.write_png(&dir.join(format!("{name}.png")), exposure, true)?;
    target.write_png(&dir.join(format!("{name}_target.png")), exposure, true)?;
    Image::false_colour_diff(img, target)?.write_png(
        &dir.join(format!("{name}_diff.png")),
        1.0,
        true,
    )?;
    Ok(())
}
