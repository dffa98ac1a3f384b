//! Outputs of an inverse run: the per-iteration CSV, the result JSON and the convergence plots.

use std::fmt::Write as _;
use std::path::Path;

use plot::{Figure, Panel, Series};
use serde_json::json;

use crate::optimize::{InverseError, IterationRecord, OptimizeConfig};
use crate::params::Params;

const CHANNELS: [&str; 3] = ["R", "G", "B"];

/// `iterations.csv`: one row per iteration (parameters before the step, loss, gradient).
pub fn write_csv(history: &[IterationRecord], path: &Path) -> Result<(), InverseError> {
    let mut s = String::from(
        "iteration,loss,sigma_t_r,sigma_t_g,sigma_t_b,albedo_r,albedo_g,albedo_b,\
         d_sigma_t_r,d_sigma_t_g,d_sigma_t_b,d_albedo_r,d_albedo_g,d_albedo_b,views,seconds,crops\n",
    );
    for r in history {
        let _ = write!(s, "{},{:.6e}", r.iteration, r.loss);
        for v in r.params.sigma_t.iter().chain(&r.params.albedo) {
            let _ = write!(s, ",{v:.6}");
        }
        for v in r.d_sigma_t.iter().chain(&r.d_albedo) {
            let _ = write!(s, ",{v:.6e}");
        }
        let views: Vec<String> = r.views.iter().map(|v| v.to_string()).collect();
        // Crop origins as `x0:y0`, one per view, space-separated (empty without `--crop`).
        let crops: Vec<String> = r
            .crop_origins
            .iter()
            .map(|[x, y]| format!("{x}:{y}"))
            .collect();
        let _ = writeln!(
            s,
            ",{},{:.4},{}",
            views.join(" "),
            r.seconds,
            crops.join(" ")
        );
    }
    scene::fsutil::atomic_write(path, s.as_bytes(), true)?;
    Ok(())
}

/// Relative σ_t error and absolute α error per channel, and the paper-style RMSEs (σ_t in units
/// of 100, over the channels).
pub fn errors(est: &Params, truth: &Params) -> serde_json::Value {
    let rel: Vec<f64> = (0..3)
        .map(|c| est.sigma_t[c] / truth.sigma_t[c] - 1.0)
        .collect();
    let abs: Vec<f64> = (0..3).map(|c| est.albedo[c] - truth.albedo[c]).collect();
    let rmse = |v: &[f64]| (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt();
    let d100: Vec<f64> = (0..3)
        .map(|c| (est.sigma_t[c] - truth.sigma_t[c]) / 100.0)
        .collect();
    json!({
        "sigma_t_relative": rel,
        "albedo_absolute": abs,
        "sigma_t_rmse_units_of_100": rmse(&d100),
        "sigma_t_rmse": 100.0 * rmse(&d100),
        "albedo_rmse": rmse(&abs),
    })
}

/// `result.json` (issue #5's fields and more).
pub fn result_json(
    config: &OptimizeConfig,
    history: &[IterationRecord],
    estimate: &Params,
    truth: Option<&Params>,
    seconds_total: f64,
) -> serde_json::Value {
    let iters = history.len().max(1) as f64;
    let per_iter: f64 = history.iter().map(|r| r.seconds).sum::<f64>() / iters;
    json!({
        "estimate": { "sigma_t": estimate.sigma_t, "albedo": estimate.albedo },
        "truth": truth.map(|t| json!({ "sigma_t": t.sigma_t, "albedo": t.albedo })),
        "errors": truth.map(|t| errors(estimate, t)),
        "initial": { "sigma_t": config.init.sigma_t, "albedo": config.init.albedo },
        "iterations": history.len(),
        "spp": config.spp,
        "views_per_iteration": config.views_per_iter,
        "seconds_per_iteration": per_iter,
        "seconds_total": seconds_total,
        "method": config.method.name(),
        "seed": config.seed,
        "final_loss": history.last().map(|r| r.loss),
        "config": config,
    })
}

/// Adds `status` ("ok" or "failed"), `problems` and, when computed, `interval95`,
/// `determined` and `uncertainty` to a `result.json` value.
pub fn add_assessment(
    result: &mut serde_json::Value,
    problems: &[crate::health::Problem],
    uncertainty: Option<&crate::uncertainty::Uncertainty>,
) {
    let obj = result.as_object_mut().expect("result.json is an object");
    obj.insert(
        "status".into(),
        json!(if problems.is_empty() { "ok" } else { "failed" }),
    );
    obj.insert("problems".into(), json!(problems));
    if let Some(serde_json::Value::Object(m)) = uncertainty.map(|u| u.to_json()) {
        obj.extend(m);
    }
}

/// The printed intervals: `σ_t = 72.1 [65.0, 80.2]` per channel, and in plain words what the
/// images leave open and which capture would settle it.
pub fn interval_lines(est: &Params, u: &crate::uncertainty::Uncertainty) -> Vec<String> {
    const CH: [&str; 3] = ["R", "G", "B"];
    let fmt = |v: f64, i: Option<[f64; 2]>, p: usize| match i {
        Some([lo, hi]) => format!("{v:.p$} [{lo:.p$}, {hi:.p$}]"),
        None => format!("{v:.p$} [no finite interval]"),
    };
    let mut out = vec!["95 % intervals (from the images):".to_string()];
    for c in 0..3 {
        out.push(format!(
            "  {}: σ_t = {}  α = {}",
            CH[c],
            fmt(est.sigma_t[c], u.sigma_t[c], 1),
            fmt(est.albedo[c], u.albedo[c], 4)
        ));
    }
    let open_t: Vec<&str> = (0..3)
        .filter(|&c| !u.determined_sigma_t[c])
        .map(|c| CH[c])
        .collect();
    let open_a: Vec<&str> = (0..3)
        .filter(|&c| !u.determined_albedo[c])
        .map(|c| CH[c])
        .collect();
    if !open_t.is_empty() {
        out.push(format!(
            "σ_t is NOT determined by these images in {} (from the images alone its interval \
             spans more than ±{:.0} %): their brightness trades σ_t against α. Views with the \
             light beside or behind the object (light that crossed it) constrain σ_t most; a \
             light at the camera barely does, however many views. More views, or more samples \
             per iteration, narrow the interval of any capture.",
            open_t.join(", "),
            50.0 * (crate::uncertainty::DETERMINED_SIGMA_T_RATIO - 1.0)
        ));
    }
    if !open_a.is_empty() {
        out.push(format!(
            "α is NOT determined by these images in {} (its interval is wider than ±{}).",
            open_a.join(", "),
            crate::uncertainty::DETERMINED_ALBEDO_HALF_WIDTH
        ));
    }
    out
}

/// `convergence.png`: σ_t and α per channel against the iteration (truth dashed) and the loss.
pub fn write_plots(
    history: &[IterationRecord],
    final_params: &Params,
    truth: Option<&Params>,
    path: &Path,
) -> Result<(), InverseError> {
    let n = history.len();
    let series = |f: &dyn Fn(&Params, usize) -> f64| -> Vec<Series> {
        (0..3)
            .map(|c| {
                let mut pts: Vec<(f64, f64)> = history
                    .iter()
                    .map(|r| (r.iteration as f64, f(&r.params, c)))
                    .collect();
                pts.push((n as f64, f(final_params, c)));
                Series::new(format!("estimate {}", CHANNELS[c]), pts)
            })
            .collect()
    };
    let refs = |f: &dyn Fn(&Params, usize) -> f64| -> Vec<(String, f64)> {
        truth
            .map(|t| {
                (0..3)
                    .map(|c| (format!("truth {}", CHANNELS[c]), f(t, c)))
                    .collect()
            })
            .unwrap_or_default()
    };
    let sig = |p: &Params, c: usize| p.sigma_t[c];
    let alb = |p: &Params, c: usize| p.albedo[c];
    let fig = Figure::new(
        vec![
            Panel {
                title: "extinction σ_t".into(),
                x_label: "iteration".into(),
                y_label: "σ_t (1/unit)".into(),
                log_y: false,
                series: series(&sig),
                reference_lines: refs(&sig),
            },
            Panel {
                title: "albedo α".into(),
                x_label: "iteration".into(),
                y_label: "α".into(),
                log_y: false,
                series: series(&alb),
                reference_lines: refs(&alb),
            },
            Panel {
                title: "image loss".into(),
                x_label: "iteration".into(),
                y_label: "loss".into(),
                log_y: true,
                series: vec![Series::new(
                    "loss",
                    history
                        .iter()
                        .map(|r| (r.iteration as f64, r.loss))
                        .collect(),
                )],
                reference_lines: vec![],
            },
        ],
        3,
    );
    fig.write_png(path, true)
        .map_err(|e| InverseError::Invalid(format!("cannot draw {}: {e}", path.display())))
}
