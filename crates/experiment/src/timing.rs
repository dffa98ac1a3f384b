//! `translucent experiment timing`: seconds per iteration of every forward model × estimator at
//! the paper's workload (Son et al. 2024, Table 1: 256² × 32 spp, one view per iteration), in
//! one run on this machine, beside the paper's figures (RTX 4090). The workload: a blob 0.8
//! across, four views with one fixed light, a random medium, targets rendered by the volumetric
//! path tracer ([`inverse::timing`] times the loop). With `--mitsuba-python`, Mitsuba 3's PRB
//! (`tools/mitsuba/prb_optimize.py`) runs on the same dataset, views, samples and iterations.
//!
//! Rows are kept in `OUT/timing.json` as they finish: an interrupted run continues with the
//! missing ones, and a finished one prints its table again; other settings need another `--out`.

use recovery::Observer;
use scene::setting::Setting;
use std::path::{Path, PathBuf};

use crate::bail;
use crate::error::{Context, Result};
use inverse::forward::{ModelChoice, ModelKind};
use inverse::optimize::TargetView;
use inverse::timing::{DEFAULTS, TimingRow, TimingSettings, all_pairs, measure, measure_defaults};
use serde::{Deserialize, Serialize};

use inverse::views::random_medium;

/// The timing experiment's settings.
#[derive(Clone, Debug, PartialEq)]
pub struct TimingConfig {
    /// The output folder (the dataset in `OUT/data`; timing.json, timing.md, timing.csv).
    pub out: PathBuf,
    /// Iterations per model × estimator (the first is not counted; at least 2).
    pub iterations: u32,
    /// Samples per pixel per iteration (the paper: 32).
    pub spp: u32,
    /// Image width and height (the paper: 256).
    pub res: u32,
    /// Seed of the medium, the targets and the runs.
    pub seed: u64,
    /// A Python with Mitsuba 3: adds the PRB row.
    pub mitsuba_python: Option<PathBuf>,
    /// A smoke test in seconds (32², 4 spp, 3 iterations, coarse meshes): not a measurement.
    pub quick: bool,
    /// All rows are one case (`timing`): their times compare only when measured on one machine.
    pub jobs: super::jobs::Jobs,
}

impl Default for TimingConfig {
    /// The paper's workload: 256² × 32 spp, 16 iterations, seed 3.
    fn default() -> Self {
        TimingConfig {
            out: PathBuf::from("out/experiment-timing"),
            iterations: 16,
            spp: 32,
            res: 256,
            seed: 3,
            mitsuba_python: None,
            quick: false,
            jobs: super::jobs::Jobs::default(),
        }
    }
}

/// What `OUT/timing.json` holds.
#[derive(Serialize, Deserialize)]
struct Record {
    settings: TimingSettings,
    res: u32,
    rows: Vec<TimingRow>,
    /// Mitsuba's PRB, seconds per iteration after the first.
    prb: Option<f64>,
}

/// The paper's seconds per iteration (RTX 4090, its Head scene, 32 spp) of the method a row
/// corresponds to.
fn paper_figure(model: ModelKind, method: &str, spp_factor: u32) -> &'static str {
    match (model, method, spp_factor) {
        (ModelKind::Learned, "ours" | DEFAULTS, 1) => "1.40 (ours)",
        (ModelKind::Learned, "ours", 2) => "2.80 (ours)",
        (ModelKind::Volpath, "ad", 1) => "2.28 (PSDR-VOL, depth 6)",
        _ => "—",
    }
}

/// Tabulates the record the output folder holds, if any (runs nothing).
fn assemble(a: &TimingConfig, obs: &dyn Observer) -> Result<()> {
    let path = a.out.join("timing.json");
    let Ok(bytes) = std::fs::read(&path) else {
        a.jobs.report_missing(&["timing".to_string()], obs);
        return Ok(());
    };
    let record: Record = serde_json::from_slice(&bytes)
        .with_context(|| format!("{}: not a timing record", path.display()))?;
    let (md, csv) = tables(&record, a.quick);
    super::write_tables(&a.out, "timing", &md, &csv, "", obs)
}

pub fn run(a: &TimingConfig, obs: &dyn Observer) -> Result<()> {
    let (res, spp, iterations, views, target_spp) = if a.quick {
        (32, 4, 3, 2, 4)
    } else {
        (a.res, a.spp, a.iterations, 4, 8)
    };
    if iterations < 2 {
        bail!(
            "{} must be at least 2 (the first iteration is not counted)",
            Setting::Iterations
        );
    }
    if a.jobs.listed(&["timing".to_string()], obs)? {
        return Ok(());
    }
    if a.jobs.assemble {
        return assemble(a, obs);
    }
    let _lock = a.jobs.lock(&a.out)?;
    let data = a.out.join("data");
    let targets = super::Targets {
        views,
        res,
        spp: target_spp,
        quick: a.quick,
    };
    let ds = super::blob_dataset(&data, targets, random_medium(a.seed), a.seed, obs)?;
    if ds.views.first().map(|v| v.camera.width) != Some(res) {
        bail!(
            "{} holds a dataset of another resolution; use another {}",
            data.display(),
            Setting::Out
        );
    }
    let settings = TimingSettings {
        iterations,
        spp,
        seed: a.seed,
        volpath_max_depth: ds.render.max_depth.unwrap_or(volpath::DEFAULT_MAX_DEPTH),
    };
    let path = a.out.join("timing.json");
    let mut record = match std::fs::read(&path) {
        Ok(bytes) => {
            let r: Record = serde_json::from_slice(&bytes)
                .with_context(|| format!("{}: not a timing record", path.display()))?;
            if r.settings != settings || r.res != res {
                bail!(
                    "{} holds a timing run with other settings; use another {}",
                    a.out.display(),
                    Setting::Out
                );
            }
            r
        }
        Err(_) => Record {
            settings,
            res,
            rows: Vec::new(),
            prb: None,
        },
    };
    let (mesh, warnings) = ds.load_mesh()?;
    let accel = inverse::views::build_accel(mesh, &warnings, "the timing dataset's mesh");
    accel.decide_all_supporting();
    let targets = TargetView::of_dataset(&ds, "the timing dataset")?;
    // The boundary and phase function the dataset states (the parameters come from the runs).
    let base = ds
        .object
        .context("the timing dataset states no object (boundary, phase function)")?
        .medium([50.0; 3], [0.5; 3]);
    let nets = bssrdf::model::shipped()?;
    // Every pair at the workload's spp, and the paper's method at twice that (its Table 1).
    let runs = all_pairs()
        .into_iter()
        .map(|c| (c, spp))
        .chain([(ModelChoice::default(), 2 * spp)]);
    for (choice, spp) in runs {
        let (model, method) = (choice.kind(), choice.estimator_name());
        let done = |r: &TimingRow| r.model == model && r.method == method && r.spp == spp;
        if record.rows.iter().any(done) {
            continue;
        }
        let label = format!("{model} × {method}, {spp} spp");
        let pb = obs.progress(0, &label);
        let row = measure(&accel, &nets, base, &targets, choice, spp, &settings)?;
        pb.finish_and_clear();
        keep_row(&mut record, row, &label, &path, obs)?;
    }
    // What `optimize` runs: the learned model, then the volumetric refinement.
    if !record.rows.iter().any(|r| r.method == DEFAULTS) {
        let pb = obs.progress(0, "optimize's defaults");
        let row = measure_defaults(&accel, &nets, base, &targets, spp, &settings)?;
        pb.finish_and_clear();
        let label =
            format!("optimize's defaults (learned, then the volumetric refinement), {spp} spp");
        keep_row(&mut record, row, &label, &path, obs)?;
    }
    if let (Some(py), None) = (&a.mitsuba_python, record.prb) {
        record.prb = Some(super::run_prb(
            py,
            (&data, None),
            &a.out.join("prb"),
            settings.iterations,
            settings.spp,
            0,
            None,
        )?);
        scene::fsutil::atomic_write(&path, &serde_json::to_vec_pretty(&record)?, true)?;
    }
    let (md, csv) = tables(&record, a.quick);
    super::write_tables(&a.out, "timing", &md, &csv, "", obs)
}

/// The Markdown and CSV tables.
/// Says the row's mean seconds per iteration, adds it to the record and saves the record at
/// `path` (atomically), so that an interrupted run keeps every row it measured.
fn keep_row(
    record: &mut Record,
    row: TimingRow,
    label: &str,
    path: &Path,
    obs: &dyn Observer,
) -> Result<()> {
    obs.say(&format!("{label}: {:.3} s/it", row.mean()));
    record.rows.push(row);
    scene::fsutil::atomic_write(path, &serde_json::to_vec_pretty(record)?, true)?;
    Ok(())
}

fn tables(r: &Record, quick: bool) -> (String, String) {
    let s = &r.settings;
    let mut md = format!(
        "Seconds per iteration, {res}² × {spp} spp, one view per iteration, iterations 1–{last} \
         of {n} (mean ± standard error){quick}\n\n\
         | model | estimator | spp | s/it | paper (RTX 4090) |\n|---|---|---|---|---|\n",
        res = r.res,
        spp = s.spp,
        last = s.iterations - 1,
        n = s.iterations,
        quick = if quick {
            " — QUICK: a smoke test, not a measurement"
        } else {
            ""
        },
    );
    let mut csv = String::from("model,estimator,spp,seconds_per_iteration,std_error,iterations\n");
    for row in &r.rows {
        let (model, method) = if row.method == DEFAULTS {
            (
                "**`optimize`'s defaults**: learned, then volpath".to_string(),
                "ours, then ad (last half)".to_string(),
            )
        } else {
            (row.model.to_string(), row.method.clone())
        };
        md.push_str(&format!(
            "| {model} | {method} | {} | {:.3} ± {:.3} | {} |\n",
            row.spp,
            row.mean(),
            row.std_error(),
            paper_figure(row.model, &row.method, row.spp / s.spp.max(1))
        ));
        csv.push_str(&format!(
            "{},{},{},{},{},{}\n",
            row.model,
            row.method,
            row.spp,
            row.mean(),
            row.std_error(),
            row.seconds.len()
        ));
    }
    if let Some(p) = r.prb {
        md.push_str(&format!(
            "| Mitsuba 3 PRB (`prbvolpath`) | — | {} | {p:.3} | not given |\n",
            s.spp
        ));
        csv.push_str(&format!("mitsuba-prb,,{},{p},,{}\n", s.spp, s.iterations));
    }
    (md, csv)
}
