//! Reporting of `translucent experiment accuracy`: the per-run rows (σ_t relative error, α
//! absolute error, the paper-style RMSE over the channels, Son et al. 2024 Table 1), the Markdown
//! table with the per-method medians against the goal, the CSV and the plot of the random
//! initialisations' trajectories (Fig. 7).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use crate::bail;
use crate::error::{Context, Result};
use inverse::params::Params;
use plot::{Figure, Panel, Series};

use crate::accuracy::config::AccuracyConfig;

/// One finished run.
#[derive(Clone)]
pub struct Row {
    pub case: String,
    pub method: String,
    pub init: Params,
    pub truth: Params,
    pub estimate: Params,
    pub seconds_per_iteration: f64,
    pub run_dir: PathBuf,
}

impl Row {
    fn sigma_rel(&self) -> [f64; 3] {
        std::array::from_fn(|c| {
            (self.estimate.sigma_t[c] - self.truth.sigma_t[c]) / self.truth.sigma_t[c]
        })
    }
    fn albedo_err(&self) -> [f64; 3] {
        std::array::from_fn(|c| self.estimate.albedo[c] - self.truth.albedo[c])
    }
    /// RMSE over the channels (paper Table 1).
    fn rmse(a: &[f64; 3], b: &[f64; 3]) -> f64 {
        ((0..3).map(|c| (a[c] - b[c]).powi(2)).sum::<f64>() / 3.0).sqrt()
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    match v.len() {
        0 => f64::NAN,
        n if n % 2 == 1 => v[n / 2],
        n => 0.5 * (v[n / 2 - 1] + v[n / 2]),
    }
}

/// The Markdown table and the per-method summary.
/// The Markdown report: every row, then the per-group summary (each method of `rows`, the random
/// initialisations `init_rows` and, when bias-corrected, their corrections `init_bc_rows`).
pub fn report(a: &AccuracyConfig, rows: &[Row], init_rows: &[Row], init_bc_rows: &[Row]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "Accuracy: {} views {}×{} (targets {} spp, volpath), {} iterations × {} spp × {} view(s){}, {}, α first for {} iterations, seed {}; {}\n",
        a.views,
        a.res,
        a.res,
        a.target_spp,
        a.budget.iterations,
        a.budget.spp,
        a.budget.views_per_iter,
        a.budget
            .crop
            .map_or(String::new(), |n| format!(" (random {n}×{n} crops)")),
        if a.scaled_sigma_t {
            "Adam on σ_t/100"
        } else {
            "Adam on ln σ_t"
        },
        a.albedo_warmup,
        a.seed,
        a.learned.describe()
    );
    let _ = writeln!(
        s,
        "| case | method | init σ_t / α | truth σ_t (R,G,B) | estimate σ_t | σ_t rel. err. % | σ_t RMSE | truth α | estimate α | α err. | α RMSE | s/it |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|---|---|---|");
    let f = |v: &[f64; 3], p: usize| {
        v.iter()
            .map(|x| format!("{x:.p$}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    for r in rows.iter().chain(init_rows).chain(init_bc_rows) {
        let rel = r.sigma_rel().map(|x| 100.0 * x);
        let _ = writeln!(
            s,
            "| {} | {} | {:.0}/{:.2} | {} | {} | {} | {:.2} | {} | {} | {} | {:.4} | {:.2} |",
            r.case,
            r.method,
            r.init.sigma_t[0],
            r.init.albedo[0],
            f(&r.truth.sigma_t, 1),
            f(&r.estimate.sigma_t, 1),
            f(&rel, 1),
            Row::rmse(&r.estimate.sigma_t, &r.truth.sigma_t),
            f(&r.truth.albedo, 3),
            f(&r.estimate.albedo, 3),
            f(&r.albedo_err(), 4),
            Row::rmse(&r.estimate.albedo, &r.truth.albedo),
            r.seconds_per_iteration,
        );
    }
    let _ = writeln!(
        s,
        "\n| method | runs | median abs. σ_t rel. err. % | median abs. α err. | mean σ_t RMSE | mean α RMSE | goal (≤ 5 %, ≤ 0.01) |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|");
    let mut groups: Vec<(&str, Vec<&Row>)> = Vec::new();
    // Methods in the order their rows appear (`ours`, then `ours+bc` when bias-corrected, …).
    for r in rows {
        if !groups.iter().any(|(m, _)| *m == r.method) {
            groups.push((
                r.method.as_str(),
                rows.iter().filter(|x| x.method == r.method).collect(),
            ));
        }
    }
    if !init_rows.is_empty() {
        groups.push(("random inits", init_rows.iter().collect()));
    }
    if !init_bc_rows.is_empty() {
        groups.push(("random inits+bc", init_bc_rows.iter().collect()));
    }
    for (name, g) in groups {
        if g.is_empty() {
            continue;
        }
        let ms = median(
            g.iter()
                .flat_map(|r| r.sigma_rel().map(|x| 100.0 * x.abs()))
                .collect(),
        );
        let ma = median(
            g.iter()
                .flat_map(|r| r.albedo_err().map(f64::abs))
                .collect(),
        );
        let n = g.len() as f64;
        let rs = g
            .iter()
            .map(|r| Row::rmse(&r.estimate.sigma_t, &r.truth.sigma_t))
            .sum::<f64>()
            / n;
        let ra = g
            .iter()
            .map(|r| Row::rmse(&r.estimate.albedo, &r.truth.albedo))
            .sum::<f64>()
            / n;
        let met = if ms <= 5.0 && ma <= 0.01 {
            "met"
        } else {
            "not met"
        };
        let _ = writeln!(
            s,
            "| {name} | {} | {ms:.1} | {ma:.4} | {rs:.2} | {ra:.4} | {met} |",
            g.len()
        );
    }
    s
}

pub fn results_csv<'a>(rows: impl Iterator<Item = &'a Row>) -> String {
    let mut s = String::from(
        "case,method,init_sigma_t_r,init_sigma_t_g,init_sigma_t_b,init_albedo_r,init_albedo_g,init_albedo_b,\
         truth_sigma_t_r,truth_sigma_t_g,truth_sigma_t_b,truth_albedo_r,truth_albedo_g,truth_albedo_b,\
         sigma_t_r,sigma_t_g,sigma_t_b,albedo_r,albedo_g,albedo_b,seconds_per_iteration,run\n",
    );
    for r in rows {
        let mut v: Vec<String> = vec![r.case.clone(), r.method.clone()];
        for arr in [
            r.init.sigma_t,
            r.init.albedo,
            r.truth.sigma_t,
            r.truth.albedo,
            r.estimate.sigma_t,
            r.estimate.albedo,
        ] {
            v.extend(arr.iter().map(|x| format!("{x}")));
        }
        v.push(format!("{}", r.seconds_per_iteration));
        v.push(r.run_dir.display().to_string());
        s += &v.join(",");
        s.push('\n');
    }
    s
}

/// σ_t and α of every random initialisation against the iteration (from the runs'
/// iterations.csv), truth dashed: paper Fig. 7.
pub fn inits_plot(rows: &[Row], path: &Path) -> Result<()> {
    const CH: [&str; 3] = ["R", "G", "B"];
    let traj: Vec<Vec<[f64; 7]>> = rows
        .iter()
        .map(|r| read_trajectory(&r.run_dir.join("iterations.csv")))
        .collect::<Result<_>>()?;
    let mut panels = Vec::new();
    for (what, off) in [("σ_t", 1usize), ("α", 4)] {
        for c in 0..3 {
            let truth = if off == 1 {
                rows[0].truth.sigma_t[c]
            } else {
                rows[0].truth.albedo[c]
            };
            panels.push(Panel {
                title: format!("{what} {} (random initialisations)", CH[c]),
                x_label: "iteration".into(),
                y_label: what.into(),
                log_y: false,
                series: traj
                    .iter()
                    .enumerate()
                    .map(|(i, t)| {
                        Series::new(
                            format!("init {i}"),
                            t.iter().map(|p| (p[0], p[off + c])).collect(),
                        )
                    })
                    .collect(),
                reference_lines: vec![(format!("truth {}", CH[c]), truth)],
                bands: Vec::new(),
            });
        }
    }
    Figure::new(panels, 3).write_png(path, true)?;
    Ok(())
}

/// (iteration, σ_t R/G/B, α R/G/B) per row of an `iterations.csv`.
pub fn read_trajectory(path: &Path) -> Result<Vec<[f64; 7]>> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    text.lines()
        .skip(1)
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            let f: Vec<f64> = l
                .split(',')
                .take(8)
                .map(|x| x.trim().parse::<f64>().unwrap_or(f64::NAN))
                .collect();
            if f.len() < 8 {
                bail!("{}: short row {l:?}", path.display());
            }
            // Columns: iteration, loss, σ_t ×3, α ×3.
            Ok([f[0], f[2], f[3], f[4], f[5], f[6], f[7]])
        })
        .collect()
}

/// One iteration of a run, read by column name from an `iterations.csv` (ours or
/// `tools/mitsuba/prb_optimize.py`'s): iteration, cumulative seconds at its end, σ_t and α.
#[derive(Clone, Copy, Debug)]
pub struct Step {
    pub iteration: f64,
    pub seconds: f64,
    pub sigma_t: [f64; 3],
    pub albedo: [f64; 3],
}

/// The steps of `path` (module docs of [`Step`]).
pub fn read_steps(path: &Path) -> Result<Vec<Step>> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    let header: Vec<&str> = text.lines().next().unwrap_or("").split(',').collect();
    let col = |name: &str| {
        header
            .iter()
            .position(|h| h.trim() == name)
            .with_context(|| format!("{}: no column {name}", path.display()))
    };
    let names = [
        "iteration",
        "seconds",
        "sigma_t_r",
        "sigma_t_g",
        "sigma_t_b",
        "albedo_r",
        "albedo_g",
        "albedo_b",
    ];
    let cols: Vec<usize> = names.iter().map(|n| col(n)).collect::<Result<_>>()?;
    let mut total = 0.0;
    text.lines()
        .skip(1)
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            let v: Vec<f64> = cols
                .iter()
                .map(|&i| {
                    f.get(i)
                        .and_then(|x| x.trim().parse().ok())
                        .unwrap_or(f64::NAN)
                })
                .collect();
            total += v[1];
            Ok(Step {
                iteration: v[0],
                seconds: total,
                sigma_t: [v[2], v[3], v[4]],
                albedo: [v[5], v[6], v[7]],
            })
        })
        .collect()
}
