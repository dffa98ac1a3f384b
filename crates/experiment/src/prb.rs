//! `translucent experiment prb` (Son et al. 2024, Fig. 9: with RGB σ_t and α, ours converges
//! about six times sooner than Mitsuba 3's PRB): one RGB dataset (a blob, 40 views of 256², one
//! fixed light, a medium of the paper's ranges, targets by our volumetric path tracer at 128
//! spp), recovered from σ_t = 50, α = 0.5 at 32 spp and one view per iteration by the learned
//! model (`ours`), by our volumetric baseline (`optimize --model volpath`) and, with
//! `--mitsuba-python`, by Mitsuba 3's `prbvolpath` (`tools/mitsuba/prb_optimize.py`, its own
//! Adam on ln σ_t and α). `optimize`'s defaults otherwise, without refinement or bias correction. Reports the
//! σ_t and α errors (RMS over the channels) against iterations and against seconds
//! (`OUT/prb.png`, `.svg`), and per run the final errors, s/it, and the first iteration after
//! which the σ_t error stays within 10 % (`OUT/prb.md`, `prb.csv`). Runs resume and are reused.

use inverse::forward::ModelKind;
use recovery::Observer;
use std::path::{Path, PathBuf};

use crate::error::{Context, Result};
use plot::{Figure, Panel, Series};

use super::report::{Step, read_steps};

use crate::run::Run;
use inverse::views::random_medium;

/// The PRB comparison's settings.
#[derive(Clone, Debug, PartialEq)]
pub struct PrbConfig {
    /// The output folder (the dataset in `OUT/data`, runs in `OUT/runs`).
    pub out: PathBuf,
    /// Iterations per run.
    pub iterations: u32,
    /// Seed of the medium, the renders and the runs.
    pub seed: u64,
    /// A Python with Mitsuba 3: adds the PRB run.
    pub mitsuba_python: Option<PathBuf>,
    /// A smoke test in seconds (4 views of 32², 6 iterations, 2 spp, coarse meshes): not a measurement.
    pub quick: bool,
    pub jobs: super::jobs::Jobs,
}

impl Default for PrbConfig {
    fn default() -> Self {
        PrbConfig {
            out: PathBuf::from("out/experiment-prb"),
            iterations: 300,
            seed: 1,
            mitsuba_python: None,
            quick: false,
            jobs: super::jobs::Jobs::default(),
        }
    }
}

/// σ_t within this relative error (RMS over the channels) counts as converged.
const CONVERGED: f64 = 0.10;

/// A run's row of the table and the CSV: its final errors, seconds per iteration, and the first
/// iteration from which every later one has σ_t within [`CONVERGED`].
fn table_row(
    name: &str,
    steps: &[Step],
    err_t: &dyn Fn(&Step) -> f64,
    err_a: &dyn Fn(&Step) -> f64,
    md: &mut String,
    csv: &mut String,
) -> Result<()> {
    let last = steps.last().context("a run without iterations")?;
    // The first iteration from which every later one is within the bound.
    let from = steps
        .iter()
        .rposition(|p| err_t(p) > CONVERGED)
        .map_or(Some(0), |i| (i + 1 < steps.len()).then_some(i + 1));
    let spi = if steps.len() > 1 {
        (last.seconds - steps[0].seconds) / (steps.len() - 1) as f64
    } else {
        last.seconds
    };
    let (it, secs) = match from {
        Some(i) => (
            format!("{}", steps[i].iteration),
            format!("{:.0}", steps[i].seconds),
        ),
        None => ("not reached".into(), "—".into()),
    };
    md.push_str(&format!(
        "| {name} | {:.1} % | {:.4} | {spi:.3} | {it} | {secs} |\n",
        100.0 * err_t(last),
        err_a(last)
    ));
    csv.push_str(&format!(
        "{name},{},{},{spi},{it},{secs}\n",
        err_t(last),
        err_a(last)
    ));
    Ok(())
}

/// The runs' σ_t and α errors by iteration and by time.
fn figure(
    runs: &[(String, Vec<Step>)],
    err_t: &dyn Fn(&Step) -> f64,
    err_a: &dyn Fn(&Step) -> f64,
) -> Figure {
    let panel = |title: &str, x: &str, y: &str, f: &dyn Fn(&Step) -> f64, by_time: bool| Panel {
        title: title.into(),
        x_label: x.into(),
        y_label: y.into(),
        log_y: true,
        series: runs
            .iter()
            .map(|(name, steps)| {
                let at = |p: &Step| if by_time { p.seconds } else { p.iteration };
                Series::new(name.clone(), steps.iter().map(|p| (at(p), f(p))).collect())
            })
            .collect(),
        reference_lines: Vec::new(),
        bands: Vec::new(),
    };
    let pct = |p: &Step| 100.0 * err_t(p);
    Figure::new(
        vec![
            panel(
                "σ_t error",
                "iteration",
                "RMS over channels, %",
                &pct,
                false,
            ),
            panel("σ_t error", "seconds", "RMS over channels, %", &pct, true),
            panel("α error", "iteration", "RMS over channels", &err_a, false),
            panel("α error", "seconds", "RMS over channels", &err_a, true),
        ],
        2,
    )
}

pub fn run(a: &PrbConfig, obs: &dyn Observer) -> Result<()> {
    let (targets, iterations, spp) = super::workload(a.quick, a.iterations);
    let (views, res) = (targets.views, targets.res);
    let mut cases = vec!["ours".to_string(), "volumetric".to_string()];
    if a.mitsuba_python.is_some() {
        cases.push("mitsuba-prb".into());
    }
    if a.jobs.listed(&cases, obs)? {
        return Ok(());
    }
    let _lock = a.jobs.lock(&a.out)?;
    let data = a.out.join("data");
    let truth = random_medium(a.seed);
    a.jobs.shared_input(&a.out, "data", || {
        super::blob_dataset(&data, targets, truth, a.seed, obs)
    })?;
    let mut runs: Vec<(String, Vec<Step>)> = Vec::new();
    let mut missing = Vec::new();
    for (name, model) in [("ours", None), ("volumetric", Some(ModelKind::Volpath))] {
        let dir = a.out.join("runs").join(name);
        let mut o = Run::defaults(&data, &dir);
        let s = &mut o.settings;
        s.model.kind = model.unwrap_or_default();
        (s.schedule.iterations, s.schedule.spp) = (iterations, spp);
        s.schedule.seed = a.seed;
        s.checks.final_spp = 16;
        s.bias_correction.correction.enabled = false;
        // The paper's method is the learned model alone: no volumetric refinement.
        s.tracer.refine = Some(0);
        if a.jobs.runs(name) {
            o.run_or_reuse(obs, name)?;
        } else if o.finished()?.is_none() {
            missing.push(name.to_string());
            continue;
        }
        runs.push((name.into(), read_steps(&dir.join("iterations.csv"))?));
    }
    if let Some(py) = &a.mitsuba_python {
        let dir = a.out.join("runs").join("mitsuba-prb");
        if a.jobs.runs("mitsuba-prb") {
            if prb_finished(&dir, iterations, spp) {
                obs.say(&format!("run Mitsuba PRB: reusing {}", dir.display()));
            } else {
                super::run_prb(py, (&data, None), &dir, iterations, spp, a.seed, None)?;
            }
        }
        if prb_finished(&dir, iterations, spp) {
            runs.push((
                "Mitsuba PRB".into(),
                read_steps(&dir.join("iterations.csv"))?,
            ));
        } else {
            missing.push("mitsuba-prb".into());
        }
    }
    a.jobs.report_missing(&missing, obs);
    let err_t = |p: &Step| rms(|c| p.sigma_t[c] / truth.sigma_t[c] as f64 - 1.0);
    let err_a = |p: &Step| rms(|c| p.albedo[c] - truth.albedo[c] as f64);
    let mut md = format!(
        "RGB σ_t and α, blob, {views} views {res}², {iterations} iterations × {spp} spp from σ_t = \
         50, α = 0.5; truth σ_t = {:.1?}, α = {:.3?}{}\n\n| run | σ_t error (RMS) | α error (RMS) \
         | s/it | σ_t within 10 % from iteration | seconds to that |\n|---|---|---|---|---|---|\n",
        truth.sigma_t,
        truth.albedo,
        if a.quick {
            " — QUICK: a smoke test, not a measurement"
        } else {
            ""
        }
    );
    let mut csv = String::from(
        "run,sigma_t_rms_error,albedo_rms_error,seconds_per_iteration,converged_iteration,converged_seconds\n",
    );
    for (name, steps) in &runs {
        table_row(name, steps, &err_t, &err_a, &mut md, &mut csv)?;
    }
    let fig = figure(&runs, &err_t, &err_a);
    fig.write_png(&a.out.join("prb.png"), true)?;
    fig.write_svg(&a.out.join("prb.svg"), true)?;
    super::write_tables(&a.out, "prb", &md, &csv, ", prb.png/.svg", obs)
}

/// √(mean over the channels of f(c)²).
fn rms(f: impl Fn(usize) -> f64) -> f64 {
    ((0..3).map(|c| f(c).powi(2)).sum::<f64>() / 3.0).sqrt()
}

/// Whether Mitsuba's PRB finished in `out` with these settings.
fn prb_finished(out: &Path, iterations: u32, spp: u32) -> bool {
    std::fs::read(out.join("result.json"))
        .ok()
        .and_then(|bytes| serde_json::from_slice::<serde_json::Value>(&bytes).ok())
        .is_some_and(|v| {
            v["iterations"].as_u64() == Some(iterations as u64)
                && v["spp"].as_u64() == Some(spp as u64)
        })
}
