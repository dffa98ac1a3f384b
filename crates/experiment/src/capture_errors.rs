//! `translucent experiment capture-errors`: what the errors of a real capture do to a recovery
//! with `optimize`'s defaults.
//!
//! A few cases of the robustness suite ([`crate::robustness`]) are rendered once by the
//! volumetric path tracer; then each [`Perturbation`] makes a dataset whose images are still
//! the true object's while what the recovery is told departs from it the way a capture does
//! (cameras turned by 0.1° and 0.5°, moved by 0.5 % and 2 % of their distance; lights moved by
//! 1 % and 5 %; the light's intensity ±5 % and ±10 %; the mesh decimated ×10 and ×50, noisy by
//! 0.2 % of its size or smoothed; the images quantised to 8-bit sRGB or given the sensor noise
//! of ISO 100 and ISO 3200), and `optimize` recovers each with its defaults.
//!
//! The table gives, per case and perturbation, the σ_t and α errors against the truth and
//! their shift from the unperturbed run, whether every 95 % interval holds the truth, whether
//! σ_t is determined, and the run's status (a run whose estimate the tracer cannot reproduce
//! is `failed`, `inconsistent`). The verdict: `holds` (every interval holds the truth),
//! `flagged` (an interval misses, and the run says it failed), or `wrong` (an interval misses
//! and the run says `ok`: a confident wrong number, which the experiment exists to find).
//! `OUT/capture-errors.md` and `.csv`; an interrupted run continues where it stopped.

use std::path::{Path, PathBuf};

use recovery::Observer;
use recovery::settings::Budget;
use scene::setting::Setting;
use scene::{Dataset, MeshSource};

use crate::bail;
use crate::error::Result;
use crate::robustness::{self, Case, RobustnessConfig, Suite, Targets};

pub mod perturb;
mod report;

pub use perturb::Perturbation;

/// The capture-errors experiment's settings; [`Default`] is the command's defaults.
#[derive(Clone, Debug, PartialEq)]
pub struct CaptureErrorsConfig {
    /// The output folder (datasets, runs, tables).
    pub out: PathBuf,
    /// Views per dataset.
    pub views: usize,
    /// Image width and height.
    pub res: u32,
    /// Samples per pixel of the volumetric target renders.
    pub target_spp: u32,
    pub budget: Budget,
    /// The robustness suite's cases to perturb (names as in its table).
    pub cases: Vec<String>,
    /// Only these perturbations (names as in the table; `None`: all). The unperturbed run is
    /// always made: every shift is measured from it.
    pub perturbations: Option<Vec<String>>,
    /// Recover a factor on the lights besides σ_t and α in every run (the remedy for an
    /// unknown intensity).
    pub free_light_scale: bool,
    /// With a free light scale, one factor per channel (the remedy for an unknown white
    /// balance).
    pub light_scale_per_channel: bool,
    /// The mesh's stated error that every run's intervals include (the remedy for a scanned
    /// mesh: `optimize --mesh-error`).
    pub mesh_error: Option<f64>,
    /// The mesh file of the suite's third shape.
    pub mesh: PathBuf,
    /// A small scale that finishes in seconds (6 views of 24², 8 spp targets, 12 iterations,
    /// coarse meshes):
    /// a smoke test of the pipeline, not a measurement.
    pub quick: bool,
    /// Seed of the media, renders, perturbations and runs.
    pub seed: u64,
    pub jobs: crate::jobs::Jobs,
}

impl Default for CaptureErrorsConfig {
    fn default() -> Self {
        CaptureErrorsConfig {
            out: PathBuf::from("out/capture-errors"),
            views: 24,
            res: 128,
            target_spp: 128,
            budget: Budget::default(),
            cases: vec!["flash-15-torus".into(), "turntable-15-blob".into()],
            perturbations: None,
            free_light_scale: false,
            light_scale_per_channel: false,
            mesh_error: None,
            mesh: PathBuf::from("data/meshes/spot.obj"),
            quick: false,
            seed: 0,
            jobs: Default::default(),
        }
    }
}

impl CaptureErrorsConfig {
    /// The robustness suite's settings that render this experiment's datasets and make its
    /// runs (the same workload, budget, seed and mesh).
    fn suite(&self) -> RobustnessConfig {
        RobustnessConfig {
            out: self.out.clone(),
            views: self.views,
            res: self.res,
            target_spp: self.target_spp,
            budget: self.budget,
            free_light_scale: self.free_light_scale,
            light_scale_per_channel: self.light_scale_per_channel,
            mesh_error: self.mesh_error,
            mesh: self.mesh.clone(),
            quick: self.quick,
            seed: self.seed,
            suite: Suite::All,
            ..RobustnessConfig::default()
        }
    }

    /// The perturbations to run, the unperturbed one first.
    fn perturbations(&self) -> Result<Vec<Perturbation>> {
        let all = perturb::all();
        let Some(want) = &self.perturbations else {
            return Ok(all);
        };
        for w in want {
            if !all.iter().any(|p| &p.name() == w) {
                bail!(
                    "{}: no perturbation '{w}' (the perturbations: {})",
                    Setting::Perturbations,
                    all.iter().map(|p| p.name()).collect::<Vec<_>>().join(", ")
                );
            }
        }
        Ok(all
            .into_iter()
            .filter(|p| *p == Perturbation::None || want.contains(&p.name()))
            .collect())
    }

    /// The cases to perturb, from the robustness suite's.
    fn cases(&self) -> Result<Vec<Case>> {
        let all = Suite::All.cases(self.seed);
        self.cases
            .iter()
            .map(|w| {
                all.iter().find(|c| &c.name == w).cloned().ok_or_else(|| {
                    crate::ExperimentError::Invalid(format!(
                        "{}: no case '{w}' in the robustness suite (its cases: {})",
                        Setting::Cases,
                        all.iter()
                            .map(|c| c.name.as_str())
                            .collect::<Vec<_>>()
                            .join(", ")
                    ))
                })
            })
            .collect()
    }
}

/// One recovery of the table: its case, perturbation and figures.
#[derive(Clone, Debug)]
pub struct Row {
    pub perturbation: Perturbation,
    pub outcome: robustness::Outcome,
}

/// Makes the perturbed dataset `dir` from the unperturbed one `clean`, unless it exists.
fn ensure_perturbed(
    clean: &Path,
    dir: &Path,
    p: Perturbation,
    seed: u64,
    obs: &dyn Observer,
) -> Result<()> {
    if dir.join("dataset.json").exists() {
        return Ok(());
    }
    obs.say(&format!("dataset {}: {}", dir.display(), p.describe()));
    let mut ds = Dataset::load(clean)?;
    if p.changes_mesh() {
        let (mesh, _) = ds.load_mesh()?;
        let changed = p.mesh(&mesh, seed);
        std::fs::create_dir_all(dir)?;
        let path = dir.join("mesh-perturbed.ply");
        geometry::io::save_ply(&changed, &path)?;
        ds.mesh = MeshSource::File(path);
    }
    p.apply(&mut ds, seed);
    ds.metadata.notes = Some(serde_json::json!({
        "capture_error": p.describe(),
        "images_of": clean.display().to_string(),
    }));
    ds.save(dir, false)?;
    Ok(())
}

pub fn run(a: &CaptureErrorsConfig, obs: &dyn Observer) -> Result<Vec<Row>> {
    let cases = a.cases()?;
    let perturbations = a.perturbations()?;
    let suite = a.suite();
    let jobs: Vec<(&Case, Perturbation)> = cases
        .iter()
        .flat_map(|c| perturbations.iter().map(move |&p| (c, p)))
        .collect();
    let tags: Vec<String> = jobs
        .iter()
        .map(|(c, p)| format!("{}-{}", c.name, p.name()))
        .collect();
    if a.jobs.listed(&tags, obs)? {
        return Ok(Vec::new());
    }
    let _lock = a.jobs.lock(&a.out)?;
    let mut rows = Vec::new();
    let mut missing = Vec::new();
    for (&(case, p), tag) in jobs.iter().zip(&tags) {
        let clean = a.out.join("data").join(&case.name);
        let data = match p {
            Perturbation::None => clean.clone(),
            _ => a.out.join("data").join(tag),
        };
        let run_dir = a.out.join("runs").join(tag);
        let r = robustness::run_args(&suite, &data, &run_dir, 0);
        if a.jobs.runs(tag) {
            robustness::ensure_dataset(&suite, case, 0, Targets::Volpath, &clean, obs)?;
            ensure_perturbed(&clean, &data, p, a.seed, obs)?;
            r.run_or_reuse(obs, tag)?;
        } else if r.finished()?.is_none() {
            missing.push(tag.clone());
            continue;
        }
        let outcome = robustness::outcome(case, 0, Targets::Volpath, &run_dir.join("result.json"))?;
        rows.push(Row {
            perturbation: p,
            outcome,
        });
    }
    a.jobs.report_missing(&missing, obs);
    let (md, csv) = report::report(a, &rows);
    std::fs::create_dir_all(&a.out)?;
    crate::write_tables(&a.out, "capture-errors", &md, &csv, "", obs)?;
    Ok(rows)
}
