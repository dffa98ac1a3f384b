//! `translucent experiment inits` (Son et al. 2024, Fig. 7: eight random initialisations
//! converge together): the accuracy experiment ([`super::accuracy`]) on one case with `ours` and
//! `--inits` random starts (σ_t ~ U[20, 150], α ~ U[0.3, 0.95] per channel), without bias
//! correction. Besides its table (`OUT/table.md`, `results.csv`) and the trajectories
//! (`OUT/inits.png`): the σ_t and α errors over the iterations, the mean over the starts with
//! the mean ± one standard deviation and every start's curve (`OUT/inits-band.png` and `.svg`).

use recovery::Observer;

use crate::bail;
use crate::error::Result;
use plot::{Band, Figure, Panel, Series};

use super::report::{Row, read_trajectory};
use crate::accuracy::{AccuracyConfig, accuracy};
use recovery::BiasCorrection;
use recovery::settings::Budget;
use scene::setting::Setting;
use std::path::PathBuf;

/// The initialisations experiment's settings.
#[derive(Clone, Debug, PartialEq)]
pub struct InitsConfig {
    /// The output folder (datasets in `OUT/data`, runs in `OUT/runs`; reused by a later run).
    pub out: PathBuf,
    /// The built-in shape of the case (as the accuracy experiment's shapes).
    pub shape: String,
    /// Random initialisations (at least 2).
    pub inits: u32,
    pub budget: Budget,
    /// Seed of the medium, the renders, the starts and the runs.
    pub seed: u64,
    /// A smoke test in seconds (4 views of 32², 6 iterations, 3 starts, coarse meshes): not a measurement.
    pub quick: bool,
    pub jobs: super::jobs::Jobs,
}

impl Default for InitsConfig {
    fn default() -> Self {
        InitsConfig {
            out: PathBuf::from("out/experiment-inits"),
            shape: "blob".into(),
            inits: 8,
            budget: Budget::default(),
            seed: 0,
            quick: false,
            jobs: super::jobs::Jobs::default(),
        }
    }
}

pub fn run(a: &InitsConfig, obs: &dyn Observer) -> Result<()> {
    if a.inits < 2 {
        bail!(
            "{} must be at least 2 (a spread needs two starts)",
            Setting::Inits
        );
    }
    let mut acc = AccuracyConfig {
        out: a.out.clone(),
        ..AccuracyConfig::default()
    };
    acc.shapes = vec![a.shape.clone()];
    acc.media = 1;
    acc.budget = a.budget;
    acc.seed = a.seed;
    acc.methods = vec!["ours".into()];
    acc.inits = a.inits;
    acc.bc = BiasCorrection::off();
    if a.quick {
        (acc.views, acc.res, acc.target_spp, acc.inits) = (4, 32, 4, 3);
        acc.coarse_meshes = true;
        (acc.budget.iterations, acc.budget.spp) = (6, 2);
    }
    acc.jobs = a.jobs.clone();
    let rows = accuracy(&acc, obs)?;
    if a.jobs.list.is_some() {
        return Ok(());
    }
    let starts: Vec<&Row> = rows.iter().filter(|r| r.case.contains(" init ")).collect();
    if starts.len() < 2 {
        obs.say(&format!(
            "{} of the starts finished so far: the band needs two",
            starts.len()
        ));
        return Ok(());
    }
    let fig = band_figure(&starts)?;
    fig.write_png(&a.out.join("inits-band.png"), true)?;
    fig.write_svg(&a.out.join("inits-band.svg"), true)?;
    obs.say(&format!(
        "wrote {} (inits-band.png/.svg: mean ± s.d. of the errors over the starts)",
        a.out.display()
    ));
    Ok(())
}

/// Per iteration, each start's σ_t relative error (%, RMS over the channels) and α absolute
/// error (RMS); their mean, mean ± one standard deviation, and each start's curve.
fn band_figure(starts: &[&Row]) -> Result<Figure> {
    let mut curves: [Vec<Vec<(f64, f64)>>; 2] = [Vec::new(), Vec::new()];
    for r in starts {
        let t = read_trajectory(&r.run_dir.join("iterations.csv"))?;
        let rms =
            |f: &dyn Fn(usize) -> f64| ((0..3).map(|c| f(c).powi(2)).sum::<f64>() / 3.0).sqrt();
        curves[0].push(
            t.iter()
                .map(|p| {
                    (
                        p[0],
                        rms(&|c| 100.0 * (p[1 + c] / r.truth.sigma_t[c] - 1.0)),
                    )
                })
                .collect(),
        );
        curves[1].push(
            t.iter()
                .map(|p| (p[0], rms(&|c| p[4 + c] - r.truth.albedo[c])))
                .collect(),
        );
    }
    let panels = curves
        .iter()
        .zip([
            ("σ_t error", "RMS over channels, %"),
            ("α error", "RMS over channels"),
        ])
        .map(|(c, (title, y))| {
            let n = c.iter().map(Vec::len).min().unwrap_or(0);
            let stat = |k: usize| {
                let v: Vec<f64> = c.iter().map(|s| s[k].1).collect();
                let m = v.iter().sum::<f64>() / v.len() as f64;
                let sd = (v.iter().map(|x| (x - m).powi(2)).sum::<f64>()
                    / (v.len() as f64 - 1.0).max(1.0))
                .sqrt();
                (c[0][k].0, m, sd)
            };
            let s: Vec<(f64, f64, f64)> = (0..n).map(stat).collect();
            let mut series = vec![Series::new("mean", s.iter().map(|p| (p.0, p.1)).collect())];
            series.extend(
                c.iter()
                    .enumerate()
                    .map(|(i, pts)| Series::faint(format!("start {i}"), pts.clone())),
            );
            let band = Band {
                label: "mean ± s.d.".into(),
                points: s.iter().map(|p| (p.0, p.1 - p.2, p.1 + p.2)).collect(),
                colour: 0,
            };
            Panel {
                title: format!("{title} over {} random starts", c.len()),
                x_label: "iteration".into(),
                y_label: y.into(),
                log_y: false,
                series,
                reference_lines: Vec::new(),
                bands: vec![band],
            }
        })
        .collect();
    Ok(Figure::new(panels, 2))
}
