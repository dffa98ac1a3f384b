//! `translucent experiment accuracy`: the paper's accuracy experiment (Son et al. 2024 §5,
//! Table 1 and Fig. 7) as one command.
//!
//! 1. Datasets: each built-in shape of `--shapes` × `--media` hidden media drawn from the paper's
//!    ranges (σ_t ~ U[30, 100], α ~ U[0.8, 0.98] per channel; medium k is the same for every shape),
//!    rendered by our volumetric path tracer: `--views` cameras on a sphere of radius 2 around the
//!    object, one fixed point light for all views (the paper's data, docs/model.md §8.3).
//! 2. Recovery: `translucent optimize` with each method of `--methods` from σ_t = 50, α = 0.5
//!    (`--iterations`, `--spp`), and `--inits` random initialisations on one case
//!    (`--inits-case`, default the first; Fig. 7). With `--bias-correction` every run, the
//!    random starts included, is corrected by the parametric bootstrap (`bias_corrected_row`);
//!    a start's bootstrap recovery starts from that start, so it is the same estimator.
//! 3. Report: per case and method σ_t relative error and α absolute error per channel, the
//!    paper-style RMSE over the channels (σ_t in 1/unit), seconds per iteration; per method the
//!    medians against the goal (σ_t ≤ 5 %, α ≤ 0.01). Printed, and written as `OUT/table.md` and
//!    `OUT/results.csv`; `OUT/inits.png` draws the trajectories of the random initialisations.
//!
//! Every step reuses what a previous run of the same command left in `OUT` (datasets with the
//! same settings, finished runs; unfinished runs resume from their checkpoints), so an interrupted
//! experiment continues where it stopped.

use std::path::{Path, PathBuf};

use geometry::Shape;
use inverse::forward::ModelKind;
use inverse::params::Params;
use inverse::views::{RenderOpts, make_dataset, random_medium};
use recovery::Observer;
use scene::rig::{Rig, paper_rig};
use scene::{Dataset, Medium, MeshSource, ShapeSpec};
use volpath::rng::Sampler;

pub(crate) mod config;

pub use config::AccuracyConfig;

use crate::error::{Context, Result};
use crate::report::{Row, inits_plot, report, results_csv};
use crate::run::Run;
use crate::{bail, baseline_model};
use scene::setting::Setting;

/// Runs the accuracy experiment; returns every row: the cases', then the random starts' (case
/// `<name> init <i>`).
pub fn accuracy(a: &AccuracyConfig, obs: &dyn Observer) -> Result<Vec<Row>> {
    check_methods(a)?;
    let shapes: Vec<Shape> = a
        .shapes
        .iter()
        .map(|s| {
            let shape = ShapeSpec::parse_compact(s, &Setting::Shapes.to_string())?
                .to_shape(&Setting::Shapes.to_string())?;
            Ok(if a.coarse_meshes {
                shape.coarse()
            } else {
                shape
            })
        })
        .collect::<Result<_>>()?;
    // The cases: every shape × medium, named `<shape>-m<k>`.
    let specs: Vec<(String, &Shape, u64)> = a
        .shapes
        .iter()
        .zip(&shapes)
        .flat_map(|(shape, built)| {
            (0..a.media)
                .map(move |k| (format!("{}-m{k}", shape.replace([':', '='], "-")), built, k))
        })
        .collect();
    let names: Vec<String> = specs.iter().map(|(n, ..)| n.clone()).collect();
    let init_name = match &a.inits_case {
        Some(want) if !names.contains(want) => bail!(
            "{}: no case named {want:?}; the cases are {}",
            Setting::InitsCase,
            names.join(", ")
        ),
        Some(want) => want.clone(),
        None => names[0].clone(),
    };
    let init_jobs: Vec<String> = (0..a.inits)
        .map(|i| format!("{init_name}-init{i}"))
        .collect();
    let jobs: Vec<String> = names.iter().chain(&init_jobs).cloned().collect();
    if a.jobs.listed(&jobs, obs)? {
        return Ok(Vec::new());
    }
    let _lock = a.jobs.lock(&a.out)?;
    std::fs::create_dir_all(a.out.join("data"))?;
    std::fs::create_dir_all(a.out.join("runs"))?;
    let x = Experiment {
        a,
        rig: paper_rig(a.views, a.res),
        obs,
    };
    x.rig.validate("experiment")?;

    let mut cases: Vec<Case> = Vec::new();
    for &(ref name, built, k) in &specs {
        let medium = random_medium(a.seed.wrapping_mul(1000).wrapping_add(k));
        if a.jobs.runs(name) {
            x.dataset(name, built, medium)?;
        }
        let dir = a.out.join("data").join(name);
        cases.push((name.clone(), dir, medium, built));
    }
    let mut missing: Vec<String> = Vec::new();
    let rows = x.case_rows(&cases, &mut missing)?;
    let init_case = cases
        .iter()
        .find(|(n, ..)| *n == init_name)
        .filter(|_| a.inits > 0);
    let (init_rows, init_bc_rows) = match init_case {
        Some(case) => x.start_rows(case, &init_jobs, &mut missing)?,
        None => (Vec::new(), Vec::new()),
    };
    missing.dedup();
    a.jobs.report_missing(&missing, obs);
    write_outputs(a, &rows, &init_rows, &init_bc_rows, obs)?;
    Ok(rows
        .into_iter()
        .chain(init_rows)
        .chain(init_bc_rows)
        .collect())
}

/// Every method names an estimator of the learned model or a baseline model.
fn check_methods(a: &AccuracyConfig) -> Result<()> {
    if a.shapes.is_empty() || a.methods.is_empty() || a.media == 0 {
        bail!(
            "{}, {} and {} must name at least one of each",
            Setting::Shapes,
            Setting::Methods,
            Setting::Media
        );
    }
    for m in &a.methods {
        if baseline_model(m).is_none() {
            m.parse::<bssrdf::diff::Estimator>().ok().ok_or_else(|| {
                let names =
                    |it: &mut dyn Iterator<Item = &'static str>| it.collect::<Vec<_>>().join(", ");
                crate::ExperimentError::Invalid(format!(
                    "{}: unknown method {m:?} (expected an estimator of the learned \
                         model: {}, or a baseline model: {})",
                    Setting::Methods,
                    names(&mut ModelKind::Learned.estimators().iter().copied()),
                    names(&mut ModelKind::ALL[1..].iter().map(|k| k.name()))
                ))
            })?;
        }
    }
    Ok(())
}

/// A case: its name, its dataset folder, its hidden medium and its shape.
type Case<'s> = (String, PathBuf, Medium, &'s Shape);

/// What every stage of the experiment shares: its options, the rig and the observer.
struct Experiment<'a> {
    a: &'a AccuracyConfig,
    rig: Rig,
    obs: &'a dyn Observer,
}

impl Experiment<'_> {
    /// Makes the dataset of case `name`: the first job that needs it (its own case's, or a
    /// random start's on it) renders it, the others wait for it.
    fn dataset(&self, name: &str, built: &Shape, medium: Medium) -> Result<()> {
        let a = self.a;
        let dir = a.out.join("data").join(name);
        a.jobs.shared_input(&a.out, name, || {
            ensure_dataset(
                a,
                &self.rig,
                built.clone(),
                medium,
                a.target_spp,
                &dir,
                name,
                self.obs,
            )
        })?;
        Ok(())
    }

    /// Every case × method from the paper's start, each followed by its bias-corrected rows
    /// (learned-model estimators only); the cases not finished go to `missing`.
    fn case_rows(&self, cases: &[Case], missing: &mut Vec<String>) -> Result<Vec<Row>> {
        let (a, obs) = (self.a, self.obs);
        let default_init = Params {
            sigma_t: [50.0; 3],
            albedo: [0.5; 3],
            g: None,
            light_scale: None,
        };
        let mut rows = Vec::new();
        for (name, dir, medium, shape) in cases {
            let run = a.jobs.runs(name);
            for method in &a.methods {
                let run_dir = a.out.join("runs").join(format!("{name}-{method}"));
                let Some(row) = optimize(
                    a,
                    run,
                    dir,
                    &run_dir,
                    method,
                    default_init,
                    medium,
                    name,
                    obs,
                )?
                else {
                    missing.push(name.clone());
                    continue;
                };
                let mut corrected = Vec::new();
                if a.bc.enabled && baseline_model(method).is_none() {
                    for step in 1..=a.bc.steps {
                        let current = corrected.last().unwrap_or(&row);
                        match bias_corrected_row(
                            a, run, &self.rig, shape, name, medium, &row, current, step, obs,
                        )? {
                            Some(next) => corrected.push(next),
                            None => {
                                missing.push(name.clone());
                                break;
                            }
                        }
                    }
                }
                rows.push(row);
                rows.extend(corrected);
            }
        }
        Ok(rows)
    }

    /// The random starts on `case` with the first method, and their last bias-corrected rows.
    fn start_rows(
        &self,
        (name, dir, medium, shape): &Case,
        init_jobs: &[String],
        missing: &mut Vec<String>,
    ) -> Result<(Vec<Row>, Vec<Row>)> {
        let (a, obs) = (self.a, self.obs);
        let mut init_rows = Vec::new();
        let mut init_bc_rows = Vec::new();
        let mut s = Sampler::new(a.seed, u64::MAX - 1, 0, 0x696e_6974);
        for (i, job) in init_jobs.iter().enumerate() {
            let init = Params {
                sigma_t: [0; 3].map(|_| 20.0 + 130.0 * s.next_f32() as f64),
                albedo: [0; 3].map(|_| 0.3 + 0.65 * s.next_f32() as f64),
                g: None,
                light_scale: None,
            };
            let run = a.jobs.runs(job);
            if run && !a.jobs.runs(name) {
                // A start's job makes (or waits for) the dataset it starts on.
                self.dataset(name, shape, *medium)?;
            }
            let run_dir = a.out.join("runs").join(job);
            let label = format!("{name} init {i}");
            let Some(row) = optimize(
                a,
                run,
                dir,
                &run_dir,
                &a.methods[0],
                init,
                medium,
                &label,
                obs,
            )?
            else {
                missing.push(job.clone());
                continue;
            };
            // The correction of a random start: the bootstrap recovery starts where this run
            // started (same estimator F), so the bias it measures includes the start's side.
            let mut current = Some(row.clone());
            let steps = if a.bc.enabled { a.bc.steps } else { 0 };
            for step in 1..=steps {
                let Some(c) = &current else { break };
                current =
                    bias_corrected_row(a, run, &self.rig, shape, job, medium, &row, c, step, obs)?;
            }
            if a.bc.enabled {
                match current {
                    Some(c) => init_bc_rows.push(c),
                    None => missing.push(job.clone()),
                }
            }
            init_rows.push(row);
        }
        Ok((init_rows, init_bc_rows))
    }
}

/// `OUT/table.md`, `OUT/results.csv` and, with random starts, `OUT/inits.png`.
fn write_outputs(
    a: &AccuracyConfig,
    rows: &[Row],
    init_rows: &[Row],
    init_bc_rows: &[Row],
    obs: &dyn Observer,
) -> Result<()> {
    let table = report(a, rows, init_rows, init_bc_rows);
    obs.say(table.trim_end_matches('\n'));
    std::fs::write(a.out.join("table.md"), &table)?;
    std::fs::write(
        a.out.join("results.csv"),
        results_csv(rows.iter().chain(init_rows).chain(init_bc_rows)),
    )?;
    if !init_rows.is_empty() {
        inits_plot(init_rows, &a.out.join("inits.png"))?;
    }
    obs.say(&format!(
        "wrote {} (table.md, results.csv{})",
        a.out.display(),
        if init_rows.is_empty() {
            ""
        } else {
            ", inits.png"
        }
    ));
    Ok(())
}

/// Step `step` of the parametric-bootstrap correction of `row` (`inverse::bootstrap`): the
/// case's dataset is rendered again at the medium of `current` (the estimate for step 1, the
/// previous step's correction after that) into `OUT/data/<case>-boot[<step>]-<method>`, recovered
/// with the same settings from the same initial values (`OUT/runs/<case>-<method>-boot[<step>]`;
/// no suffix for step 1), and the row of method `<method>+bc[<step>]` holds
/// θ_step = θ_current + θ̂ − θ̂_step (step 1: 2θ̂ − θ̂₂). Its s/it covers all recoveries so far.
#[allow(clippy::too_many_arguments)]
fn bias_corrected_row(
    a: &AccuracyConfig,
    run: bool,
    rig: &Rig,
    shape: &Shape,
    name: &str,
    truth: &Medium,
    row: &Row,
    current: &Row,
    step: u32,
    obs: &dyn Observer,
) -> Result<Option<Row>> {
    let at = current.estimate.medium(truth);
    let suffix = if step == 1 {
        String::new()
    } else {
        step.to_string()
    };
    let boot = format!("{name}-boot{suffix}-{}", row.method);
    let data = a.out.join("data").join(&boot);
    let spp = a.bc.spp.unwrap_or(a.target_spp);
    if run {
        ensure_dataset(a, rig, shape.clone(), at, spp, &data, &boot, obs)?;
    }
    let run_dir = a
        .out
        .join("runs")
        .join(format!("{name}-{}-boot{suffix}", row.method));
    let Some(refit) = optimize(
        a,
        run,
        &data,
        &run_dir,
        &row.method,
        row.init,
        &at,
        &format!("{name} bootstrap {step}"),
        obs,
    )?
    else {
        return Ok(None);
    };
    let corrected =
        inverse::bootstrap::bootstrap_step(&current.estimate, &row.estimate, &refit.estimate)
            .with_context(|| {
                format!(
                    "{}: the bootstrap recovery is not a valid medium ({:?})",
                    run_dir.display(),
                    refit.estimate
                )
            })?;
    let (bs, ba) = inverse::bootstrap::estimated_bias(&current.estimate, &refit.estimate);
    if run {
        obs.say(&format!(
            "bias of {} on {name} at step {step}'s medium: σ_t {:+.1?} %, α {:+.4?}",
            row.method,
            bs.map(|v| 100.0 * v),
            ba
        ));
    }
    Ok(Some(Row {
        method: format!("{}+bc{suffix}", row.method),
        estimate: corrected,
        seconds_per_iteration: current.seconds_per_iteration + refit.seconds_per_iteration,
        run_dir,
        ..row.clone()
    }))
}

/// Render the dataset unless `dir` already holds one with these settings.
#[allow(clippy::too_many_arguments)]
fn ensure_dataset(
    a: &AccuracyConfig,
    rig: &Rig,
    shape: Shape,
    medium: Medium,
    spp: u32,
    dir: &Path,
    name: &str,
    obs: &dyn Observer,
) -> Result<()> {
    if dir.join("dataset.json").exists() {
        let ds = Dataset::load(dir)?;
        let same = ds.truth == Some(medium)
            && ds.views.len() == a.views
            && ds
                .views
                .first()
                .is_some_and(|v| v.camera.width == a.res && v.camera.height == a.res)
            && ds.render.spp == Some(spp);
        if same {
            obs.say(&format!("dataset {name}: reusing {}", dir.display()));
            return Ok(());
        }
        return Err(crate::other_dataset(dir));
    }
    obs.say(&format!(
        "dataset {name}: {} views {}×{} at {} spp, σ_t = {:.1?}, α = {:.3?}",
        a.views, a.res, a.res, spp, medium.sigma_t, medium.albedo
    ));
    make_dataset(
        rig,
        MeshSource::Shape(shape),
        medium,
        RenderOpts {
            spp,
            seed: a.seed,
            max_depth: 32,
            shadow: Default::default(),
        },
        dir,
        false,
        obs,
    )?;
    Ok(())
}

/// The `optimize` settings of one run: its defaults with the experiment's budget, method, start
/// and learned-renderer options.
pub fn run_args(
    a: &AccuracyConfig,
    dataset: &Path,
    run_dir: &Path,
    method: &str,
    init: Params,
) -> Run {
    let mut r = Run::defaults(dataset, run_dir);
    let s = &mut r.settings;
    a.learned.apply(s);
    match baseline_model(method) {
        // A baseline model with its default estimator.
        Some(m) => s.model.kind = m,
        None => s.model.estimator = Some(method.to_string()),
    }
    a.budget.apply(&mut s.schedule);
    if a.scaled_sigma_t {
        s.schedule.params.parameterisation = inverse::params::Parameterisation::Scaled;
    }
    s.schedule.albedo_warmup = a.albedo_warmup;
    // As `--init-sigma-t` and `--init-albedo` read them: in single precision.
    let single = |v: [f64; 3]| v.map(|x| f64::from(x as f32));
    s.start.sigma_t_from_units = false;
    s.start.init = Params {
        sigma_t: single(init.sigma_t),
        albedo: single(init.albedo),
        g: None,
        light_scale: None,
    };
    s.schedule.seed = a.seed;
    s.checks.final_spp = 16;
    // The experiment corrects its runs itself (rows `<method>+bc`), and compares the learned
    // model's estimators on the learned model alone: no volumetric refinement.
    s.bias_correction.correction.enabled = false;
    s.tracer.refine = Some(0);
    r
}

/// Run (or resume, or reuse) one optimisation and read its result; with `run` false, only read
/// it if it has finished (`None` otherwise).
#[allow(clippy::too_many_arguments)]
fn optimize(
    a: &AccuracyConfig,
    run: bool,
    dataset: &Path,
    run_dir: &Path,
    method: &str,
    init: Params,
    truth: &Medium,
    label: &str,
    obs: &dyn Observer,
) -> Result<Option<Row>> {
    let o = run_args(a, dataset, run_dir, method, init);
    let done = if run {
        Some(o.run_or_reuse(obs, label)?)
    } else {
        o.finished()?
    };
    Ok(done.map(|done| Row {
        case: label.to_string(),
        method: method.to_string(),
        init,
        truth: Params::of(truth),
        estimate: done.estimate,
        seconds_per_iteration: done.seconds_per_iteration,
        run_dir: run_dir.to_path_buf(),
    }))
}
