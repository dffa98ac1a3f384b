//! `translucent experiment robustness`: recovery with `optimize`'s defaults on data we did not
//! tune on, crossing the capture, the object's size in mean free paths and the shape.
//!
//! Two sets of cases ([`Suite`]): twelve index-matched, isotropic ones, each of four captures at
//! each of three optical sizes, the shapes taking turns; and nine of a real object's physics, a
//! dielectric boundary (smooth η 1.5; rough η 1.33, GGX α 0.1; rough η 1.5, α 0.3) around a
//! forward-scattering medium (HG g 0.3, 0.7, 0.9), at 15, 50 and 300 mean free paths (two
//! orthogonal Latin squares: every boundary meets every g and every size once), the shapes
//! taking turns and every capture at least twice, a back light only at 15 and 50 (at 300 it
//! lights nothing the cameras see). The datasets state the boundary and the phase function, which the
//! recoveries read; the learned model renders neither (its runs say so, and the tracer's
//! refinement carries them).
//! * Captures: `flash` (a light 0.14 units from each camera, about 4° off its axis: the light
//!   moves with the camera); `fixed` (one point light for every view, the paper's data: some
//!   views are lit from behind); `turntable` (camera and lamp fixed, the object turning: the
//!   light 60° from every camera about the object); `backlit` (the light 150° from every camera:
//!   every view sees light that crossed the object).
//! * Optical sizes: object radius × mean σ_t ≈ 5, 15 and 50 mean free paths. The medium comes
//!   from the paper's ranges (α ~ U[0.8, 0.98]; σ_t ~ U[30, 50], U[30, 100], U[70, 100] for the
//!   three sizes), and the whole scene (object, cameras, lights) is scaled to reach the size;
//!   the light's intensity scales with the square of the distances, so every case is exposed
//!   alike.
//! * Shapes: the blob, the torus, and `data/meshes/spot.obj` (Keenan Crane's cow, a mesh our
//!   generator did not make: legs, ears and horns).
//!
//! Every case is rendered by the volumetric path tracer and recovered by `optimize` with its
//! defaults (the volumetric refinement included), `--seeds` times with independent renders and
//! runs.
//! The table gives, per case and channel, the σ_t error (corrected and uncorrected), whether the
//! 95 % interval holds the truth, whether the images determine σ_t, the α error, the
//! consistency (the uncorrected estimate re-rendered by the volumetric path tracer against the
//! targets), the status, the seconds per iteration and the time to an accurate answer
//! ([`settle`]); the summary the calibration (how often the intervals hold the truth), the
//! accuracy where σ_t is determined and how soon those runs got there, one table per set.
//! `OUT/robustness.md` and `OUT/robustness.csv`; an interrupted run continues where it stopped.

use recovery::Observer;
use scene::setting::Setting;
use std::path::{Path, PathBuf};

use crate::bail;
use crate::error::{Context, Result};
use crate::run::Run;
use recovery::settings::Budget;
use scene::Dataset;

use inverse::forward::ModelKind;
use inverse::forward::learned::LearnedSpec;
use inverse::params::OneOrRgb;
use inverse::views::build_accel;
use recovery::reuse::read_json;

mod cases;
mod prb;
mod report;
mod settle;
mod targets;

pub use cases::{Capture, Case, Suite, Targets, cases, dielectric_cases};
use report::report;
pub(crate) use targets::ensure_dataset;
use targets::target_renderers;

/// The robustness suite's settings; [`Default`] is the command's defaults.
#[derive(Clone, Debug, PartialEq)]
pub struct RobustnessConfig {
    /// The output folder (datasets, runs, tables).
    pub out: PathBuf,
    /// Views per dataset.
    pub views: usize,
    /// Image width and height.
    pub res: u32,
    /// Samples per pixel of the volumetric target renders.
    pub target_spp: u32,
    /// The forward model of the recoveries.
    pub model: ModelKind,
    pub budget: Budget,
    /// The tracer's refinement of every run: its last N iterations (`None`: the recovery's
    /// default).
    pub refine: Option<u32>,
    /// Samples per pixel of the refinement's iterations (`None`: the recovery's default).
    pub refine_spp: Option<u32>,
    /// Recover the phase function's g besides σ_t and α in every run (its own table).
    pub free_g: bool,
    /// Recover a factor on the lights (whose truth here is 1: the datasets state their lights)
    /// in every run (its own table).
    pub free_light_scale: bool,
    /// With a free light scale, one factor per channel (a table per channel).
    pub light_scale_per_channel: bool,
    /// The starting g of runs that free it (`None`: the dataset's stated g, the case's own).
    pub init_g: Option<f64>,
    /// The mesh's stated error that every run's intervals include (`optimize --mesh-error`).
    pub mesh_error: Option<f64>,
    /// The starting light scale of runs that free it (`None`: 1, the truth).
    pub init_light_scale: Option<f64>,
    /// Independent repetitions of every case (renders and runs; at least 1).
    pub seeds: u64,
    /// Which cases.
    pub suite: Suite,
    /// Only these cases of the suite (names as in the table, e.g. `flash-15-blob`).
    pub cases: Option<Vec<String>>,
    /// The mesh file of the third shape.
    pub mesh: PathBuf,
    /// A small scale that finishes in seconds (6 views of 24², 8 spp targets, 12 iterations,
    /// coarse meshes):
    /// a smoke test of the pipeline, not a measurement.
    pub quick: bool,
    /// Seed of the media (renders and runs use seed + repetition).
    pub seed: u64,
    /// Who renders the targets (`None`: ours, and Mitsuba's too when the script finds
    /// Mitsuba 3, not in a quick run).
    pub targets: Option<Vec<Targets>>,
    /// The script that renders a dataset's views with Mitsuba 3.
    pub mitsuba_script: PathBuf,
    /// The Python interpreter (with Mitsuba 3) that runs the script.
    pub python: PathBuf,
    /// Recover every case also with Mitsuba 3's PRB for this many iterations, run by `python`,
    /// and set its time to an accurate answer beside the defaults' ([`prb`]).
    pub prb_iterations: Option<u32>,
    /// PRB's learning rates decay as the defaults' do (×0.85 every 50 iterations) rather than
    /// staying constant (Mitsuba's own examples).
    pub prb_decay: bool,
    pub jobs: super::jobs::Jobs,
}

impl Default for RobustnessConfig {
    fn default() -> Self {
        RobustnessConfig {
            out: PathBuf::from("out/robustness"),
            views: 24,
            res: 128,
            target_spp: 128,
            model: ModelKind::Learned,
            budget: Budget::default(),
            refine: None,
            refine_spp: None,
            free_g: false,
            free_light_scale: false,
            mesh_error: None,
            light_scale_per_channel: false,
            init_g: None,
            init_light_scale: None,
            seeds: 1,
            suite: Suite::default(),
            cases: None,
            mesh: PathBuf::from("data/meshes/spot.obj"),
            quick: false,
            seed: 0,
            targets: None,
            mitsuba_script: PathBuf::from("tools/mitsuba/render_dataset.py"),
            python: PathBuf::from("python3"),
            prb_iterations: None,
            prb_decay: false,
            jobs: super::jobs::Jobs::default(),
        }
    }
}

/// What a suite run renders and iterates: its datasets' views, resolution and target samples,
/// and its runs' iterations and samples per iteration (the quick scale's with `quick`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Workload {
    pub views: usize,
    pub res: u32,
    pub target_spp: u32,
    pub iterations: u32,
    pub spp: u32,
}

impl RobustnessConfig {
    /// The workload these settings give: [`RobustnessConfig::quick`]'s 6 views of 24², 8 spp
    /// targets and 12 iterations × 4 spp, or the settings' own.
    pub fn workload(&self) -> Workload {
        if self.quick {
            Workload {
                views: 6,
                res: 24,
                target_spp: 8,
                iterations: 12,
                spp: 4,
            }
        } else {
            Workload {
                views: self.views,
                res: self.res,
                target_spp: self.target_spp,
                iterations: self.budget.iterations,
                spp: self.budget.spp,
            }
        }
    }
}

/// One recovery's figures, read from its `result.json`.
#[derive(Clone, Debug)]
pub struct Outcome {
    pub case: Case,
    pub rep: u64,
    pub targets: Targets,
    pub estimate: [[f64; 3]; 2],
    pub uncorrected: [[f64; 3]; 2],
    pub interval_sigma_t: [Option<[f64; 2]>; 3],
    pub interval_albedo: [Option<[f64; 2]>; 3],
    pub determined_sigma_t: [bool; 3],
    pub consistency_ratio: [f64; 3],
    pub consistency_l2: [f64; 3],
    /// The volumetric path tracer's curvature along the σ_t–α valley over the learned model's,
    /// per channel (`result.json`'s `sensitivity`; below 1 the model is surer than the images).
    pub valley_curvature: [f64; 3],
    pub status: String,
    pub seconds_per_iteration: f64,
    /// The learned model's own error on this case: its render of the truth against the
    /// targets, pooled brightness ratio per channel (`model_ratio`).
    pub model_ratio: [f64; 3],
    /// The recovered g, its 95 % interval and whether it is determined, in runs that free g.
    pub g: Option<Recovered>,
    /// The recovered light scale likewise, one or one per channel (its truth is 1).
    pub light_scale: Option<OneOrRgb<Recovered>>,
    /// Per channel, when the run's estimate entered σ_t ± 5 % and α ± 0.01 for good
    /// ([`settle`]; `None`: never, or no trajectory), and the loop's total seconds.
    pub settled: ([Option<settle::Settled>; 3], f64),
    /// Mitsuba 3's PRB on the same case, where it ran.
    pub prb: Option<prb::PrbOutcome>,
}

/// A run's recovered g or light scale.
#[derive(Clone, Copy, Debug)]
pub struct Recovered {
    pub estimate: f64,
    /// The 95 % interval (the whole range where the images give none).
    pub interval: [f64; 2],
    pub determined: bool,
}

impl Recovered {
    /// The estimate's error against `truth`.
    pub fn error(&self, truth: f64) -> f64 {
        self.estimate - truth
    }

    /// Whether the interval holds `truth`.
    pub fn covers(&self, truth: f64) -> bool {
        self.interval[0] <= truth && truth <= self.interval[1]
    }

    /// `result.json`'s `key` (estimate, interval and determined flag), where the run has it;
    /// `whole` where the images give no interval.
    fn of(v: &serde_json::Value, key: &str, whole: [f64; 2]) -> Option<Self> {
        Self::from_parts(
            &v["estimate"][key],
            &v["interval95"][key],
            &v["determined"][key],
            whole,
        )
    }

    /// One value's estimate, interval and flag from their JSON values.
    fn from_parts(
        estimate: &serde_json::Value,
        interval: &serde_json::Value,
        determined: &serde_json::Value,
        whole: [f64; 2],
    ) -> Option<Self> {
        estimate.as_f64().map(|estimate| Recovered {
            estimate,
            interval: match (interval[0].as_f64(), interval[1].as_f64()) {
                (Some(lo), Some(hi)) => [lo, hi],
                _ => whole,
            },
            determined: determined.as_bool().unwrap_or(false),
        })
    }

    /// `result.json`'s light scale: one value, or an array of three (one per channel).
    fn light_scale(v: &serde_json::Value) -> Option<OneOrRgb<Self>> {
        let key = "light_scale";
        let whole = [0.0, f64::INFINITY];
        if v["estimate"][key].is_array() {
            let c: [Option<Self>; 3] = std::array::from_fn(|c| {
                Self::from_parts(
                    &v["estimate"][key][c],
                    &v["interval95"][key][c],
                    &v["determined"][key][c],
                    whole,
                )
            });
            Some(OneOrRgb::Rgb([c[0]?, c[1]?, c[2]?]))
        } else {
            Self::of(v, key, whole).map(OneOrRgb::One)
        }
    }
}

impl Outcome {
    pub(crate) fn sigma_t_error(&self, corrected: bool) -> [f64; 3] {
        let e = if corrected {
            &self.estimate
        } else {
            &self.uncorrected
        };
        std::array::from_fn(|c| e[0][c] / self.case.medium.sigma_t[c] as f64 - 1.0)
    }

    pub(crate) fn albedo_error(&self) -> [f64; 3] {
        std::array::from_fn(|c| self.estimate[1][c] - self.case.medium.albedo[c] as f64)
    }

    pub(crate) fn covered(&self) -> [[bool; 3]; 2] {
        let inside = |i: Option<[f64; 2]>, t: f32| {
            i.is_some_and(|[lo, hi]| lo <= t as f64 && t as f64 <= hi)
        };
        [
            std::array::from_fn(|c| inside(self.interval_sigma_t[c], self.case.medium.sigma_t[c])),
            std::array::from_fn(|c| inside(self.interval_albedo[c], self.case.medium.albedo[c])),
        ]
    }
}

fn rgb(v: &serde_json::Value) -> [f64; 3] {
    std::array::from_fn(|c| v[c].as_f64().unwrap_or(f64::NAN))
}

/// The 95 % intervals of `v` (`interval95.sigma_t` or `.albedo`). Where the run measured its
/// uncertainty (`measured`) but the images give a channel no finite interval, the interval is
/// the parameter's whole range `whole` (which holds the truth: the run claims nothing there).
fn intervals(v: &serde_json::Value, measured: bool, whole: [f64; 2]) -> [Option<[f64; 2]>; 3] {
    std::array::from_fn(|c| {
        let i = &v[c];
        match (i[0].as_f64(), i[1].as_f64()) {
            (Some(lo), Some(hi)) => Some([lo, hi]),
            _ if measured => Some(whole),
            _ => None,
        }
    })
}

pub(crate) fn outcome(case: &Case, rep: u64, targets: Targets, result: &Path) -> Result<Outcome> {
    let v = read_json(result)?;
    let pair = |p: &serde_json::Value| [rgb(&p["sigma_t"]), rgb(&p["albedo"])];
    let estimate = pair(&v["estimate"]);
    let uncorrected = if v["estimate_uncorrected"].is_object() {
        pair(&v["estimate_uncorrected"])
    } else {
        estimate
    };
    let determined = &v["determined"]["sigma_t"];
    let measured = v["uncertainty"].is_object() && estimate.iter().flatten().all(|x| x.is_finite());
    Ok(Outcome {
        case: case.clone(),
        rep,
        targets,
        estimate,
        uncorrected,
        interval_sigma_t: intervals(&v["interval95"]["sigma_t"], measured, [0.0, f64::INFINITY]),
        interval_albedo: intervals(&v["interval95"]["albedo"], measured, [0.0, 1.0]),
        determined_sigma_t: std::array::from_fn(|c| determined[c].as_bool().unwrap_or(false)),
        consistency_ratio: rgb(&v["consistency"]["mean_ratio"]),
        consistency_l2: rgb(&v["consistency"]["l2_over_noise"]),
        valley_curvature: {
            let (t, m) = (
                rgb(&v["sensitivity"]["volpath"]),
                rgb(&v["sensitivity"]["learned"]),
            );
            // No learned curvature in the checked views: nothing to compare.
            std::array::from_fn(|c| if m[c] > 0.0 { t[c] / m[c] } else { f64::NAN })
        },
        status: v["status"].as_str().unwrap_or("?").to_string(),
        seconds_per_iteration: v["seconds_per_iteration"].as_f64().unwrap_or(f64::NAN),
        model_ratio: [f64::NAN; 3],
        g: Recovered::of(&v, "g", [-1.0, 1.0]),
        light_scale: Recovered::light_scale(&v),
        settled: settle::of_run(&case.medium, &v, result)?,
        prb: None,
    })
}

/// The model's error at the truth: every third view of the dataset rendered by the run's
/// model (the learned BSSRDF with the run's model and settings, or the dipole) with the true
/// medium at 32 spp, and the pooled brightness ratio Σ_views Σ_pixels render / Σ_views
/// Σ_pixels target per channel. An estimate can be no better than this allows: a model that
/// renders the truth 10 % too dark must move σ_t or α to match the images. Cached in
/// `RUN/model-ratio.json`.
fn model_ratio(
    o: &Run,
    data: &Path,
    run_dir: &Path,
    quick: bool,
    obs: &dyn Observer,
) -> Result<[f64; 3]> {
    let kind = o.settings.model.kind;
    let seed = o.settings.schedule.seed;
    if kind == inverse::forward::ModelKind::Volpath {
        // The volumetric model is the targets' own renderer (or Mitsuba's, which it matches).
        return Ok([f64::NAN; 3]);
    }
    let cache = run_dir.join("model-ratio.json");
    if let Ok(v) = read_json(&cache) {
        return Ok(rgb(&v["ratio"]));
    }
    let ds = Dataset::load(data)?;
    let truth = ds
        .truth
        .with_context(|| format!("{}: no truth", data.display()))?;
    let (mesh, warnings) = ds.load_mesh()?;
    let accel = build_accel(mesh, &warnings, &data.display().to_string());
    let picked: Vec<usize> = (0..ds.views.len()).step_by(3).collect();
    let scene = ds.scene(truth);
    let views: Vec<_> = picked.iter().map(|&i| scene.views[i].clone()).collect();
    let spp = if quick { 4 } else { 32 };
    let job = inverse::views::Job {
        accel: &accel,
        medium: &truth,
        views: &views,
        spp,
        seed,
    };
    let networks = match kind {
        inverse::forward::ModelKind::Learned => Some(o.networks()?),
        _ => None,
    };
    let spec = match &networks {
        Some(n) => inverse::forward::ModelSpec::Learned(LearnedSpec::new(
            n,
            o.settings.learned.renderer,
            seed,
        )),
        None => inverse::forward::ModelSpec::Dipole {
            estimator: Default::default(),
        },
    };
    let pb = obs.progress(inverse::views::total_rows(&views), kind.name());
    let rep = inverse::views::render(spec, &job, false, &pb)?;
    pb.finish_and_clear();
    let (mut num, mut den) = ([0.0f64; 3], [0.0f64; 3]);
    for (img, &i) in rep.images.iter().zip(&picked) {
        let target = ds.views[i]
            .image
            .as_ref()
            .with_context(|| format!("{}: view {i} has no image", data.display()))?;
        let (a, b) = (img.mean(), target.mean());
        for c in 0..3 {
            num[c] += a[c];
            den[c] += b[c];
        }
    }
    let ratio: [f64; 3] = std::array::from_fn(|c| num[c] / den[c]);
    let json = serde_json::json!({
        "ratio": ratio,
        "views": picked,
        "spp": spp,
        "what": format!("{kind} render of the true medium ÷ targets, pooled over the views"),
    });
    scene::fsutil::atomic_write(
        &cache,
        serde_json::to_string_pretty(&json)?.as_bytes(),
        true,
    )?;
    Ok(ratio)
}

/// The `optimize` run of one case: the command's defaults, with the experiment's budget and seed.
pub fn run_args(a: &RobustnessConfig, dataset: &Path, run_dir: &Path, rep: u64) -> Run {
    let mut r = Run::defaults(dataset, run_dir);
    let s = &mut r.settings;
    s.model.kind = a.model;
    a.budget.apply(&mut s.schedule);
    s.schedule.seed = a.seed + rep;
    s.checks.final_spp = 16;
    s.tracer.refine = a.refine;
    s.tracer.refine_spp = a.refine_spp;
    s.schedule.params.free_g = a.free_g;
    s.schedule.params.free_light_scale = a.free_light_scale;
    s.schedule.params.light_scale_per_channel = a.light_scale_per_channel;
    s.start.init.g = a.init_g.map(inverse::params::OneOrRgb::One);
    s.checks.uncertainty.mesh_error = a.mesh_error;
    s.start.init.light_scale = a.init_light_scale.map(inverse::params::OneOrRgb::One);
    if a.quick {
        s.schedule.iterations = a.workload().iterations;
        s.schedule.spp = a.workload().spp;
        s.checks.uncertainty.views = 3;
        s.checks.uncertainty.spp = 4;
        s.checks.consistency_views = 2;
        let half = s.schedule.iterations / 2;
        s.tracer.refine = s.tracer.refine.map(|r| r.min(half));
    }
    r
}

pub fn run(a: &RobustnessConfig, obs: &dyn Observer) -> Result<()> {
    let mut all = a.suite.cases(a.seed);
    if let Some(want) = &a.cases {
        for w in want {
            if !all.iter().any(|c| &c.name == w) {
                bail!(
                    "{}: no case '{w}' (the cases: {})",
                    Setting::Cases,
                    all.iter()
                        .map(|c| c.name.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                );
            }
        }
        all.retain(|c| want.contains(&c.name));
    }
    crate::ensure!(a.seeds >= 1, "{} must be at least 1", Setting::Seeds);
    let renderers = target_renderers(a, obs)?;
    // Repetition by repetition, so that an interrupted run has every renderer's first ones.
    let mut jobs: Vec<(u64, Targets, &Case)> = Vec::new();
    for rep in 0..a.seeds {
        for &t in &renderers {
            jobs.extend(all.iter().filter(|c| t.renders(c)).map(|c| (rep, t, c)));
        }
    }
    let unrendered: Vec<&str> = renderers
        .iter()
        .flat_map(|&t| all.iter().filter(move |c| !t.renders(c)))
        .map(|c| c.name.as_str())
        .collect();
    if !unrendered.is_empty() && a.jobs.list.is_none() {
        obs.say(&format!(
            "Mitsuba 3 targets: none for {} (a smooth dielectric lit by a point light is black \
             in Mitsuba's volpath: no path reaches the light through the smooth surface)",
            unrendered.join(", ")
        ));
    }
    let tags: Vec<String> = jobs
        .iter()
        .map(|(rep, t, c)| t.tag(&c.name, *rep))
        .collect();
    if a.jobs.listed(&tags, obs)? {
        return Ok(());
    }
    let _lock = a.jobs.lock(&a.out)?;
    let mut outcomes = Vec::new();
    let mut missing = Vec::new();
    for (&(rep, targets, case), tag) in jobs.iter().zip(&tags) {
        let data = a.out.join("data").join(tag);
        let run_dir = a.out.join("runs").join(tag);
        let o = run_args(a, &data, &run_dir, rep);
        let run = a.jobs.runs(tag);
        if run {
            ensure_dataset(a, case, rep, targets, &data, obs)?;
            o.run_or_reuse(obs, tag)?;
        } else if o.finished()?.is_none() {
            missing.push(tag.clone());
            continue;
        }
        let mut out = outcome(case, rep, targets, &run_dir.join("result.json"))?;
        out.model_ratio = if run {
            model_ratio(&o, &data, &run_dir, a.quick, obs)?
        } else {
            // A finished job measured it; a table assembled here only reads it.
            read_json(&run_dir.join("model-ratio.json")).map_or([f64::NAN; 3], |v| rgb(&v["ratio"]))
        };
        out.prb = prb::of_case(a, case, (rep, tag), &data, run, obs)?;
        outcomes.push(out);
    }
    a.jobs.report_missing(&missing, obs);
    let (table, csv) = report(a, &outcomes);
    obs.say(&table);
    std::fs::create_dir_all(&a.out)?;
    scene::fsutil::atomic_write(&a.out.join("robustness.md"), table.as_bytes(), true)?;
    scene::fsutil::atomic_write(&a.out.join("robustness.csv"), csv.as_bytes(), true)?;
    obs.say(&format!(
        "wrote {} and {}",
        a.out.join("robustness.md").display(),
        a.out.join("robustness.csv").display()
    ));
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A channel without a finite interval in a run that measured its uncertainty is the
    /// parameter's whole range (it holds the truth: the run claims nothing); a run without an
    /// uncertainty has no interval at all, which holds nothing.
    #[test]
    fn a_channel_without_a_finite_interval_is_the_whole_range() {
        let v = serde_json::json!([[1.0, 2.0], [null, null], null]);
        let whole = [0.0, f64::INFINITY];
        assert_eq!(
            intervals(&v, true, whole),
            [Some([1.0, 2.0]), Some(whole), Some(whole)]
        );
        assert_eq!(intervals(&v, false, whole), [Some([1.0, 2.0]), None, None]);
    }
}
