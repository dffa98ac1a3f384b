//! The paper's experiments and the robustness suite (`translucent experiment …`): each one a set
//! of named cases (datasets and recoveries) that runs, resumes after an interruption, reuses what
//! a previous run left in its output folder, hands its cases to a cluster's scheduler
//! ([`jobs`]), and writes its tables (Markdown and CSV) and plots (PNG and SVG).
//!
//! | experiment | module | the paper |
//! |---|---|---|
//! | `accuracy` | [`accuracy`] | Table 1, Fig. 7 |
//! | `robustness` | [`robustness`] | (ours: captures we did not tune on) |
//! | `capture-errors` | [`capture_errors`] | (ours: what a real capture's errors do) |
//! | `timing` | [`timing`] | Table 1 |
//! | `gradients` | [`gradients`] | Fig. 3, 5 |
//! | `planar` | [`planar`] | Fig. 6 |
//! | `inits` | [`inits`] | Fig. 7 |
//! | `volumetric` | [`volumetric`] | Fig. 8 |
//! | `prb` | [`prb`] | Fig. 9 |
//!
//! The runs are `optimize`'s own ([`run::Run`]: the library's [`recovery::RecoverySettings`],
//! each field one of `optimize`'s options), with the defaults a user gets unless a row says
//! otherwise. The library prints nothing: its lines and progress bars go
//! to an [`Observer`]. Errors are typed ([`ExperimentError`]).

use scene::setting::Setting;
use std::path::Path;

use inverse::forward::ModelKind;
use inverse::views::{RenderOpts, make_dataset};
use recovery::Observer;
use scene::rig::paper_rig;
use scene::{Dataset, Medium, MeshSource};

pub mod accuracy;
pub mod capture_errors;
mod error;
pub mod gradients;
pub mod inits;
pub mod jobs;
pub mod planar;
pub mod prb;
pub mod report;
pub mod robustness;
pub mod run;
pub mod timing;
pub mod volumetric;

pub use error::{Context, ExperimentError, Result};

use accuracy::AccuracyConfig;

/// One experiment with its settings.
#[derive(Clone, Debug)]
pub enum Experiment {
    /// Accuracy of the recovered σ_t and α on volumetric-path-traced datasets (paper Table 1,
    /// Fig. 7): shapes × media, methods, random initialisations.
    Accuracy(Box<AccuracyConfig>),
    /// `optimize`'s defaults on cases we did not tune on: twelve index-matched, isotropic ones
    /// (flash, fixed light, turntable, back-lit; 5, 15, 50 mean free paths; blob, torus, a mesh
    /// file) and nine with a smooth or rough dielectric boundary around a forward-scattering
    /// medium (up to 300 mean free paths): errors, 95 % intervals and their calibration,
    /// whether σ_t is determined, consistency, status.
    Robustness(Box<robustness::RobustnessConfig>),
    /// What a real capture's errors (camera and light poses, the light's intensity, a scanned
    /// mesh, 8-bit photos, sensor noise) do to a recovery with the defaults: shifts, intervals,
    /// status, and whether any run gives a confident wrong number.
    CaptureErrors(Box<capture_errors::CaptureErrorsConfig>),
    /// Seconds per iteration of every forward model × estimator at the paper's workload
    /// (256² × 32 spp; paper Table 1), beside the paper's figures; Mitsuba 3's PRB with
    /// `--mitsuba-python`.
    Timing(timing::TimingConfig),
    /// Derivative images of the learned renderer's estimators (ours, naive) against central
    /// differences on a cone and a blob (paper Fig. 3 and 5): relative error of the summed
    /// derivative and per-pixel correlation.
    Gradients(gradients::GradientsConfig),
    /// The paper's comparison with the planar dipole (Fig. 6): ours, naive and the dipole on
    /// three shapes × two media; errors over iterations and re-renders side by side.
    Planar(planar::PlanarConfig),
    /// Random initialisations on one case (paper Fig. 7): the mean ± s.d. of the errors over
    /// the iterations, and every start's curve.
    Inits(inits::InitsConfig),
    /// σ_t alone with α fixed, grey medium (paper Fig. 8): ours at 32 spp against the
    /// volumetric baseline at 32 and 128 spp, at equal iterations and at equal time.
    Volumetric(volumetric::VolumetricConfig),
    /// RGB σ_t and α (paper Fig. 9): ours against the volumetric baseline and, with
    /// `--mitsuba-python`, Mitsuba 3's PRB, by iterations and by time.
    Prb(prb::PrbConfig),
}

/// Runs the experiment, reporting to `obs`.
pub fn run(cmd: &Experiment, obs: &dyn Observer) -> Result<()> {
    match cmd {
        Experiment::Accuracy(a) => accuracy::accuracy(a, obs).map(|_| ()),
        Experiment::Robustness(a) => robustness::run(a, obs),
        Experiment::CaptureErrors(a) => capture_errors::run(a, obs).map(|_| ()),
        Experiment::Timing(a) => timing::run(a, obs),
        Experiment::Gradients(a) => gradients::run(a, obs),
        Experiment::Planar(a) => planar::run(a, obs),
        Experiment::Inits(a) => inits::run(a, obs),
        Experiment::Volumetric(a) => volumetric::run(a, obs),
        Experiment::Prb(a) => prb::run(a, obs),
    }
}

/// The size of a single-dataset experiment's targets: `views` views of `res`² at `spp`, of the
/// blob at a smoke test's resolution ([`geometry::Shape::coarse`]) with `quick`.
#[derive(Clone, Copy, Debug)]
pub struct Targets {
    pub views: usize,
    pub res: u32,
    pub spp: u32,
    pub quick: bool,
}

/// The blob dataset of the single-dataset experiments in `dir`: `t.views` views of `t.res`² on
/// the paper's rig (one fixed light), `medium`, targets by the volumetric path tracer at `t.spp`
/// (depth 32, seed `seed`); rendered unless `dir` holds it already.
pub fn blob_dataset(
    dir: &Path,
    t: Targets,
    medium: Medium,
    seed: u64,
    obs: &dyn Observer,
) -> Result<Dataset> {
    if dir.join("dataset.json").exists() {
        return Ok(Dataset::load(dir)?);
    }
    let Targets {
        views,
        res,
        spp,
        quick,
    } = t;
    obs.say(&format!(
        "dataset: blob{}, {views} views {res}² at {spp} spp, σ_t = {:.1?}, α = {:.3?}",
        if quick { " (coarse mesh)" } else { "" },
        medium.sigma_t,
        medium.albedo
    ));
    let blob = geometry::Shape::from_name("blob")?;
    Ok(make_dataset(
        &paper_rig(views, res),
        MeshSource::Shape(if quick { blob.coarse() } else { blob }),
        medium,
        RenderOpts {
            spp,
            seed,
            max_depth: 32,
            shadow: Default::default(),
        },
        dir,
        false,
        obs,
    )?)
}

/// The refusal of a dataset folder that holds a dataset made with other settings than the
/// experiment's (reusing it would mix two experiments).
fn other_dataset(dir: &Path) -> ExperimentError {
    ExperimentError::Invalid(format!(
        "{} holds a dataset made with other settings; remove it or choose another {}",
        dir.display(),
        Setting::Out
    ))
}

/// Prints the table `md` and writes it as `OUT/<stem>.md` beside `OUT/<stem>.csv`, then says
/// what the folder holds (`extra`: the further files, e.g. `, <stem>.png/.svg`).
fn write_tables(
    out: &Path,
    stem: &str,
    md: &str,
    csv: &str,
    extra: &str,
    obs: &dyn Observer,
) -> Result<()> {
    obs.say(md.trim_end_matches('\n'));
    std::fs::write(out.join(format!("{stem}.md")), md)?;
    std::fs::write(out.join(format!("{stem}.csv")), csv)?;
    obs.say(&format!(
        "wrote {} ({stem}.md, {stem}.csv{extra})",
        out.display()
    ));
    Ok(())
}

/// Mitsuba 3's PRB (`tools/mitsuba/prb_optimize.py`, run by `python`) on the dataset `data`
/// (its object's mesh from the file `mesh` where given) into `out`: `iterations` × `spp`, one
/// view per iteration, seed `seed`, both learning rates × `decay.0` every `decay.1` iterations
/// where `decay` is given (constant otherwise). Returns its mean
/// seconds per iteration after the first (from its `result.json`).
pub fn run_prb(
    python: &Path,
    (data, mesh): (&Path, Option<&Path>),
    out: &Path,
    iterations: u32,
    spp: u32,
    seed: u64,
    decay: Option<(f32, u32)>,
) -> Result<f64> {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tools/mitsuba/prb_optimize.py");
    let status = std::process::Command::new(python)
        .arg(&script)
        .arg(data)
        .args(["--iterations", &iterations.to_string()])
        .args(["--spp", &spp.to_string()])
        .args(["--seed", &seed.to_string()])
        .args(["--views-per-iter", "1", "--print-every", "50"])
        .args(
            mesh.iter()
                .flat_map(|m| [std::ffi::OsStr::new("--mesh"), m.as_os_str()]),
        )
        .args(decay.iter().flat_map(|(f, n)| {
            [
                "--decay".to_string(),
                f.to_string(),
                "--decay-every".to_string(),
                n.to_string(),
            ]
        }))
        .args(["--overwrite", "--out"])
        .arg(out)
        .status()
        .with_context(|| format!("running {}", python.display()))?;
    if !status.success() {
        bail!(
            "{} {} failed ({status})",
            python.display(),
            script.display()
        );
    }
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("result.json"))?)?;
    v["seconds_per_iteration"]
        .as_f64()
        .context("PRB's result.json has no seconds_per_iteration")
}

/// The workload of the single-dataset experiments (targets, iterations, spp): the paper's (40
/// views of 256², targets at 128 spp, `iterations` × 32 spp), or the smoke test's with `quick`
/// (4 views of 32² of the coarse blob, 4 spp, 6 iterations × 2 spp).
pub fn workload(quick: bool, iterations: u32) -> (Targets, u32, u32) {
    let (views, res, spp) = if quick { (4, 32, 4) } else { (40, 256, 128) };
    let targets = Targets {
        views,
        res,
        spp,
        quick,
    };
    if quick {
        (targets, 6, 2)
    } else {
        (targets, iterations, 32)
    }
}

/// The baseline model a `--methods` entry names (`dipole`, `volpath`), if it names one.
pub fn baseline_model(method: &str) -> Option<ModelKind> {
    method
        .parse::<ModelKind>()
        .ok()
        .filter(|m| *m != ModelKind::Learned)
}
