//! `translucent experiment planar` (Son et al. 2024, Fig. 6: ours beats naive differentiation and
//! the planar dipole, with sharper re-renders): the accuracy experiment
//! ([`super::accuracy`]) with the methods `ours`, `naive` and the planar dipole baseline
//! (`optimize --model dipole`), on three shapes × two media, without random initialisations or
//! bias correction (the paper compares the plain methods). Besides
//! its table (`OUT/table.md`, `results.csv`), per case a figure of the σ_t and α errors over the
//! iterations, one line per method (`OUT/planar-<case>.png` and `.svg`), and the re-renders of
//! the first view (below, "Re-renders").
//!
//! # Re-renders
//! The paper shows each method's estimate re-rendered beside the truth ("planar blurrier"). Here
//! the truth and every estimate are rendered by the volumetric path tracer in the first view,
//! all at `--rerender-spp` with one seed, so that they differ by their media alone and their
//! noise is well below the targets': `OUT/renders-<case>.png` (truth, then each method, one
//! exposure), the EXRs in `OUT/rerenders/`, and per method and channel, against the truth's
//! re-render I_T:
//!
//! * brightness ratio  Σ_p I_p / Σ_p I_T,p;
//! * relative RMS difference  √(Σ_p (I_p − I_T,p)² / Σ_p I_T,p²);
//! * the same at equal brightness, with I_p divided by the brightness ratio: what differs
//!   besides the overall brightness (how far the light spreads, the contrast), plus noise;
//!
//! with a noise-floor row: the truth rendered again with another seed. A render is kept (and
//! reused by a later assembly) beside a JSON file of the medium, spp, seed and depth it was made
//! with.

pub mod rerender;

use recovery::Observer;

use crate::error::Result;
use plot::{Figure, Panel, Series};
use recovery::BiasCorrection;
use std::path::PathBuf;

use super::report::{Row, read_trajectory};
use crate::accuracy::{AccuracyConfig, accuracy};
use recovery::settings::Budget;

/// The planar-dipole comparison's settings.
#[derive(Clone, Debug, PartialEq)]
pub struct PlanarConfig {
    /// The output folder (datasets in `OUT/data`, runs in `OUT/runs`; reused by a later run).
    pub out: PathBuf,
    /// Built-in shapes (as the accuracy experiment's shapes).
    pub shapes: Vec<String>,
    /// Hidden media per shape, drawn from the paper's ranges.
    pub media: u64,
    pub budget: Budget,
    /// Seed of the media, the renders and the runs.
    pub seed: u64,
    /// A smoke test in seconds (4 views of 32², 6 iterations, one medium, coarse meshes): not a measurement.
    pub quick: bool,
    /// Samples per pixel of the re-renders of the first view (truth and each estimate, by the
    /// volumetric path tracer; module docs).
    pub rerender_spp: u32,
    pub jobs: super::jobs::Jobs,
}

impl Default for PlanarConfig {
    fn default() -> Self {
        PlanarConfig {
            out: PathBuf::from("out/experiment-planar"),
            shapes: ["blob", "torus", "cone"].map(String::from).to_vec(),
            media: 2,
            budget: Budget::default(),
            seed: 0,
            quick: false,
            rerender_spp: 512,
            jobs: super::jobs::Jobs::default(),
        }
    }
}

/// The methods compared (paper Fig. 6).
const METHODS: [&str; 3] = ["ours", "naive", "dipole"];

pub fn run(a: &PlanarConfig, obs: &dyn Observer) -> Result<()> {
    let mut acc = AccuracyConfig {
        out: a.out.clone(),
        ..AccuracyConfig::default()
    };
    acc.shapes = a.shapes.clone();
    acc.media = a.media;
    acc.budget = a.budget;
    acc.seed = a.seed;
    acc.methods = METHODS.map(String::from).to_vec();
    acc.inits = 0;
    // The paper compares the plain methods.
    acc.bc = BiasCorrection::off();
    if a.quick {
        (acc.views, acc.res, acc.target_spp, acc.media) = (4, 32, 4, 1);
        acc.coarse_meshes = true;
        (acc.budget.iterations, acc.budget.spp) = (6, 2);
    }
    acc.jobs = a.jobs.clone();
    let rows = accuracy(&acc, obs)?;
    if a.jobs.list.is_some() {
        return Ok(());
    }
    let mut cases: Vec<&str> = rows.iter().map(|r| r.case.as_str()).collect();
    cases.dedup();
    let spp = if a.quick { 4 } else { a.rerender_spp };
    let mut compared = Vec::new();
    for case in cases {
        let of_case: Vec<&Row> = rows.iter().filter(|r| r.case == case).collect();
        let fig = error_figure(case, &of_case)?;
        fig.write_png(&a.out.join(format!("planar-{case}.png")), true)?;
        fig.write_svg(&a.out.join(format!("planar-{case}.svg")), true)?;
        let r = rerender::case(&a.out, case, &of_case, spp, a.seed, obs)?;
        r.figure
            .write_png(&a.out.join(format!("renders-{case}.png")), r.exposure, true)?;
        compared.extend(r.rows);
    }
    if !compared.is_empty() {
        let table = rerender::table(&compared, spp);
        obs.say(&table);
        scene::fsutil::atomic_write(&a.out.join("rerenders.md"), table.as_bytes(), true)?;
        let csv = rerender::csv(&compared, spp);
        scene::fsutil::atomic_write(&a.out.join("rerenders.csv"), csv.as_bytes(), true)?;
    }
    obs.say(&format!(
        "wrote {} (planar-<case>.png/.svg: errors over iterations; renders-<case>.png: the first \
         view re-rendered at {spp} spp by the volumetric path tracer: truth, {}; rerenders.md/.csv: \
         each re-render against the truth's)",
        a.out.display(),
        METHODS.join(", ")
    ));
    Ok(())
}

/// σ_t relative error (%, RMS over the channels) and α absolute error (RMS) over the
/// iterations, one line per method.
fn error_figure(case: &str, rows: &[&Row]) -> Result<Figure> {
    let mut sigma = Vec::new();
    let mut albedo = Vec::new();
    for r in rows {
        let t = read_trajectory(&r.run_dir.join("iterations.csv"))?;
        let rms = |f: &dyn Fn(usize, &[f64; 7]) -> f64, p: &[f64; 7]| {
            ((0..3).map(|c| f(c, p).powi(2)).sum::<f64>() / 3.0).sqrt()
        };
        let s = |c: usize, p: &[f64; 7]| 100.0 * (p[1 + c] / r.truth.sigma_t[c] - 1.0);
        let al = |c: usize, p: &[f64; 7]| p[4 + c] - r.truth.albedo[c];
        sigma.push(Series::new(
            r.method.clone(),
            t.iter().map(|p| (p[0], rms(&s, p))).collect(),
        ));
        albedo.push(Series::new(
            r.method.clone(),
            t.iter().map(|p| (p[0], rms(&al, p))).collect(),
        ));
    }
    let panel = |title: String, y_label: &str, series| Panel {
        title,
        x_label: "iteration".into(),
        y_label: y_label.into(),
        log_y: true,
        series,
        reference_lines: Vec::new(),
        bands: Vec::new(),
    };
    Ok(Figure::new(
        vec![
            panel(format!("{case}: σ_t error"), "RMS over channels, %", sigma),
            panel(format!("{case}: α error"), "RMS over channels", albedo),
        ],
        2,
    ))
}
