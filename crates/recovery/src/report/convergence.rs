//! The convergence plot of a run (`convergence.png` and `.svg`): the parameters per iteration
//! against the truth with this fit's interval, and the loss relative to each view's final level.

use std::path::Path;

use plot::{Band, Figure, Panel, Series};

use super::CHANNELS;
use inverse::optimize::{InverseError, IterationRecord};
use inverse::params::{OneOrRgb, Params};
use inverse::uncertainty::SharedUncertainty;

/// `convergence.png` and `.svg` beside it: σ_t and α per channel against the iteration, with
/// the truth dashed and the 95 % interval of this fit shaded when they are known, and the loss
/// relative to each view's final level (raw values faint, their running median solid). The
/// interval is the fit's own (`uncertainty`): the one `result.json` reports also carries the
/// bias correction and the tracer's sensitivity check.
pub fn write_plots(
    history: &[IterationRecord],
    final_params: &Params,
    truth: Option<&Params>,
    uncertainty: Option<&inverse::uncertainty::Uncertainty>,
    path: &Path,
) -> Result<(), InverseError> {
    let n = history.len();
    let bands = |intervals: Option<[Option<[f64; 2]>; 3]>| -> Vec<Band> {
        let Some(iv) = intervals else {
            return Vec::new();
        };
        (0..3)
            .filter_map(|c| {
                iv[c].map(|[lo, hi]| {
                    Band::constant(
                        format!("95 % interval of this fit {}", CHANNELS[c]),
                        0.0,
                        n as f64,
                        lo,
                        hi,
                    )
                    .coloured(c)
                })
            })
            .collect()
    };
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
    let mut panels = vec![
        Panel {
            title: "extinction σ_t".into(),
            x_label: "iteration".into(),
            y_label: "σ_t (1/unit)".into(),
            log_y: false,
            series: series(&sig),
            reference_lines: refs(&sig),
            bands: bands(uncertainty.map(|u| u.sigma_t)),
        },
        Panel {
            title: "albedo α".into(),
            x_label: "iteration".into(),
            y_label: "α".into(),
            log_y: false,
            series: series(&alb),
            reference_lines: refs(&alb),
            bands: bands(uncertainty.map(|u| u.albedo)),
        },
        Panel {
            title: "loss ÷ the view's final level (1: converged)".into(),
            x_label: "iteration".into(),
            y_label: "relative loss".into(),
            log_y: true,
            series: relative_loss_series(history),
            reference_lines: vec![("final level".into(), 1.0)],
            bands: Vec::new(),
        },
    ];
    let shared = shared_panels(history, final_params, truth, uncertainty);
    let loss = panels.pop().expect("the loss panel");
    panels.extend(shared);
    panels.push(loss);
    let columns = if panels.len() == 4 { 2 } else { 3 };
    let fig = Figure::new(panels, columns);
    let draw_err = |e: plot::PlotError| InverseError::Invalid(e.to_string());
    fig.write_png(path, true).map_err(draw_err)?;
    fig.write_svg(&path.with_extension("svg"), true)
        .map_err(draw_err)
}

/// The loss of each iteration over its views' final level, and its running median.
///
/// One view per iteration makes the raw loss jump with the view's brightness (orders of
/// magnitude between a lit and a back-lit view). Dividing by the level each view settles at
/// (the median of its losses over the run's last third; its smallest loss when it was not drawn
/// then) leaves what the optimisation did: falling towards 1 while it converges, then noise
/// around 1. The running median over 25 iterations shows the trend.
pub fn relative_loss(history: &[IterationRecord]) -> Vec<(f64, f64)> {
    use std::collections::BTreeMap;
    let tail_start = history.len() - history.len() / 3;
    let mut per_view: BTreeMap<usize, (Vec<f64>, f64)> = BTreeMap::new();
    for (i, r) in history.iter().enumerate() {
        for &v in &r.views {
            let e = per_view.entry(v).or_insert((Vec::new(), f64::INFINITY));
            if i >= tail_start {
                e.0.push(r.loss);
            }
            e.1 = e.1.min(r.loss);
        }
    }
    let level: BTreeMap<usize, f64> = per_view
        .into_iter()
        .map(|(v, (mut tail, min))| {
            let l = if tail.is_empty() {
                min
            } else {
                tail.sort_by(f64::total_cmp);
                tail[tail.len() / 2]
            };
            (v, l)
        })
        .collect();
    history
        .iter()
        .filter_map(|r| {
            let n = r.views.len();
            let l = r.views.iter().map(|v| level[v]).sum::<f64>() / n.max(1) as f64;
            let q = r.loss / l;
            (n > 0 && q.is_finite() && q > 0.0).then_some((r.iteration as f64, q))
        })
        .collect()
}

pub(super) fn relative_loss_series(history: &[IterationRecord]) -> Vec<Series> {
    const WINDOW: usize = 25;
    let pts = relative_loss(history);
    let median: Vec<(f64, f64)> = (0..pts.len())
        .map(|i| {
            let lo = i.saturating_sub(WINDOW / 2);
            let hi = (i + WINDOW / 2 + 1).min(pts.len());
            let mut w: Vec<f64> = pts[lo..hi].iter().map(|p| p.1).collect();
            w.sort_by(f64::total_cmp);
            (pts[i].0, w[w.len() / 2])
        })
        .collect();
    vec![
        Series::faint("per iteration", pts),
        Series::new(format!("running median of {WINDOW}"), median),
    ]
}

/// The panels of a recovered g and light scale: one series each (the channels share them; a
/// light scale per channel has a panel per channel), the truth dashed and this fit's interval
/// shaded where known.
fn shared_panels(
    history: &[IterationRecord],
    final_params: &Params,
    truth: Option<&Params>,
    uncertainty: Option<&inverse::uncertainty::Uncertainty>,
) -> Vec<Panel> {
    type Of = Box<dyn Fn(&Params) -> Option<f64>>;
    let n = history.len();
    // One panel per variable of an unknown that is one value or one per channel: (title and
    // label with `{}` for the channel's suffix, the unknown of a Params, its intervals).
    let per_variable = |title: &str,
                        label: &str,
                        of: fn(&Params) -> Option<OneOrRgb<f64>>,
                        u: Option<OneOrRgb<SharedUncertainty>>|
     -> Vec<(String, String, Of, Option<SharedUncertainty>)> {
        let channels: &[(usize, &str)] = match of(final_params) {
            Some(OneOrRgb::Rgb(_)) => &[(0, "_R"), (1, "_G"), (2, "_B")],
            _ => &[(0, "")],
        };
        (channels.iter())
            .map(|&(c, suffix)| -> (_, _, Of, _) {
                (
                    title.replace("{}", suffix),
                    label.replace("{}", suffix),
                    Box::new(move |p| of(p).map(|v| v.channel(c))),
                    u.map(|u| u.channel(c)),
                )
            })
            .collect()
    };
    let mut shared = per_variable(
        "phase function g{}",
        "g{}",
        |p| p.g,
        uncertainty.and_then(|u| u.g),
    );
    shared.extend(per_variable(
        "light scale k{} (× the stated intensity)",
        "k{}",
        |p| p.light_scale,
        uncertainty.and_then(|u| u.light_scale),
    ));
    let mut out = Vec::new();
    for (title, label, of, u) in shared {
        let Some(last) = of(final_params) else {
            continue;
        };
        let mut pts: Vec<(f64, f64)> = history
            .iter()
            .filter_map(|r| of(&r.params).map(|v| (r.iteration as f64, v)))
            .collect();
        pts.push((n as f64, last));
        let band = u
            .and_then(|u| u.interval)
            .map(|[lo, hi]| Band::constant("95 % interval of this fit", 0.0, n as f64, lo, hi));
        out.push(Panel {
            title,
            x_label: "iteration".into(),
            y_label: label,
            log_y: false,
            series: vec![Series::new("estimate", pts)],
            reference_lines: truth
                .and_then(&of)
                .map(|t| vec![("truth".to_string(), t)])
                .unwrap_or_default(),
            bands: band.into_iter().collect(),
        });
    }
    out
}
