//! The robustness suite's table and summary (`OUT/robustness.md`, `OUT/robustness.csv`): per
//! case and channel the errors, the intervals' hold, whether σ_t is determined, consistency and
//! status; the calibration and the accuracy where σ_t is determined.

use std::fmt::Write as _;

use inverse::optimize::OptimizeConfig;
use inverse::params::OneOrRgb;

use super::{Outcome, RobustnessConfig, Targets};

pub(super) fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// The CSV's columns: one row per case, repetition and channel.
const CSV_HEADER: &str = "case,capture,mfp,shape,targets,rep,channel,sigma_t_true,sigma_t_est,sigma_t_err,sigma_t_err_uncorrected,sigma_t_lo,sigma_t_hi,sigma_t_covered,sigma_t_determined,albedo_true,albedo_est,albedo_err,albedo_lo,albedo_hi,albedo_covered,consistency_ratio,consistency_l2,valley_curvature,model_ratio,status,seconds_per_iteration,eta,roughness,g,settled_iteration,settled_seconds,loop_seconds,prb_settled_iteration,prb_settled_seconds,prb_loop_seconds";

/// The Markdown header, then a table with its summary per set of cases (index-matched or
/// dielectric; a heading each when both ran), and the CSV.
pub(super) fn report(a: &RobustnessConfig, outcomes: &[Outcome]) -> (String, String) {
    let mut md = String::new();
    let w = a.workload();
    let (views, res, spp) = (w.views, w.res, w.target_spp);
    let _ = writeln!(
        md,
        "Robustness: {views} views {res}² (targets rendered at {spp} spp by {}), `optimize` defaults ({}{} iterations × {} spp from σ_t = 50, α = 0.5{}), {} repetition(s), seed {}{}\n",
        renderers_named(outcomes),
        match a.model {
            inverse::forward::ModelKind::Learned => String::new(),
            m => format!("the {m} model, "),
        },
        w.iterations,
        w.spp,
        {
            let iterations = w.iterations;
            let default = OptimizeConfig::default_refinement(a.model, iterations);
            match a.refine.unwrap_or(default) {
                0 if a.model == inverse::forward::ModelKind::Learned => {
                    ", bias correction".to_string()
                }
                0 => String::new(),
                r => format!(
                    ", the last {r} by the volumetric path tracer{}",
                    a.refine_spp
                        .map_or(String::new(), |s| format!(" at {s} spp"))
                ),
            }
        },
        a.seeds,
        a.seed,
        if a.quick {
            " — QUICK: a smoke test, not a measurement"
        } else {
            ""
        }
    );
    // The shared parameters some run recovered: their columns and tables.
    let free: Vec<&SharedColumn> = SHARED
        .iter()
        .filter(|c| outcomes.iter().any(|o| (c.of)(o).is_some()))
        .collect();
    for c in &free {
        let from = match c.name {
            "g" => a
                .init_g
                .map_or("the dataset's stated g (the case's own)".to_string(), |g| {
                    format!("g = {g}")
                }),
            _ => format!("k = {} (the truth is 1)", a.init_light_scale.unwrap_or(1.0)),
        };
        let _ = writeln!(
            md,
            "The {} is recovered in every run, from {from}.\n",
            c.name
        );
    }
    let mut csv = String::from(CSV_HEADER);
    for c in &free {
        let key = c.name.replace(' ', "_");
        let _ = write!(
            csv,
            ",{key}_est,{key}_lo,{key}_hi,{key}_covered,{key}_determined"
        );
    }
    csv.push('\n');
    let (index_matched, dielectric): (Vec<Outcome>, Vec<Outcome>) = outcomes
        .iter()
        .cloned()
        .partition(|o| o.case.medium.eta == 1.0 && o.case.medium.g.is_isotropic());
    let both = !index_matched.is_empty() && !dielectric.is_empty();
    for (title, set) in [
        ("Index-matched boundary, isotropic medium", index_matched),
        (
            "Dielectric boundary (smooth or rough), forward-scattering medium",
            dielectric,
        ),
    ] {
        if set.is_empty() {
            continue;
        }
        if both {
            let _ = writeln!(md, "### {title}\n");
        }
        table(&mut md, &mut csv, &set, &free);
        for col in SHARED
            .iter()
            .filter(|c| set.iter().any(|o| (c.of)(o).is_some()))
        {
            shared_table(&mut md, &set, col);
        }
    }
    super::prb::table(&mut md, outcomes);
    (md, csv)
}

/// A parameter the runs may recover besides σ_t and α: its name, its value in a run and its
/// truth in a case, and the goal on its error.
struct SharedColumn {
    name: &'static str,
    of: fn(&Outcome) -> Option<super::Recovered>,
    truth: fn(&Outcome) -> f64,
    goal: &'static str,
}

/// The light scale of channel `c` where the run recovered one per channel.
fn light_scale_of(o: &Outcome, c: usize) -> Option<super::Recovered> {
    match o.light_scale {
        Some(OneOrRgb::Rgb(k)) => Some(k[c]),
        _ => None,
    }
}

// The suite's datasets state their lights as rendered: every light scale's truth is 1.
const SHARED: [SharedColumn; 5] = [
    SharedColumn {
        name: "g",
        of: |o| o.g,
        truth: |o| o.case.medium.g.mean() as f64,
        goal: "|error| ≤ 0.05",
    },
    SharedColumn {
        name: "light scale",
        of: |o| match o.light_scale {
            Some(OneOrRgb::One(k)) => Some(k),
            _ => None,
        },
        truth: |_| 1.0,
        goal: "|error| ≤ 0.05",
    },
    SharedColumn {
        name: "light scale R",
        of: |o| light_scale_of(o, 0),
        truth: |_| 1.0,
        goal: "|error| ≤ 0.05",
    },
    SharedColumn {
        name: "light scale G",
        of: |o| light_scale_of(o, 1),
        truth: |_| 1.0,
        goal: "|error| ≤ 0.05",
    },
    SharedColumn {
        name: "light scale B",
        of: |o| light_scale_of(o, 2),
        truth: |_| 1.0,
        goal: "|error| ≤ 0.05",
    },
];

/// The recovered g or light scale of each run and their summary.
fn shared_table(md: &mut String, outcomes: &[Outcome], col: &SharedColumn) {
    let name = col.name;
    let _ = writeln!(
        md,
        "\n| case | targets | rep | {name} truth | {name} estimate [95 % interval] | error | in interval | determined |"
    );
    let _ = writeln!(md, "|---|---|---|---|---|---|---|---|");
    let mut det_err = Vec::new();
    let (mut covered, mut n) = (0, 0);
    for o in outcomes {
        let Some(r) = (col.of)(o) else { continue };
        let truth = (col.truth)(o);
        let _ = writeln!(
            md,
            "| {} | {} | {} | {truth:.3} | {:.3} [{:.3}, {:.3}] | {:+.3} | {} | {} |",
            o.case.name,
            o.targets.name(),
            o.rep,
            r.estimate,
            r.interval[0],
            r.interval[1],
            r.error(truth),
            if r.covers(truth) { "y" } else { "n" },
            if r.determined { "y" } else { "n" }
        );
        n += 1;
        covered += r.covers(truth) as usize;
        if r.determined {
            det_err.push(r.error(truth).abs());
        }
    }
    let _ = writeln!(
        md,
        "\n- {name}: the truth inside the 95 % interval in {covered} of {n} runs; determined in {} of {n}{}",
        det_err.len(),
        if det_err.is_empty() {
            String::new()
        } else {
            format!(
                ", where the largest |error| is {:.3} (goal: {})",
                det_err.iter().copied().fold(0.0, f64::max),
                col.goal
            )
        }
    );
}

/// The table of `outcomes` with its summary (Markdown), and their CSV rows.
fn table(md: &mut String, csv: &mut String, outcomes: &[Outcome], free: &[&SharedColumn]) {
    let _ = writeln!(
        md,
        "| case | targets | rep | σ_t truth | σ_t error % (uncorrected) | in 95 % interval σ_t / α | σ_t determined | α error | consistency ratio / L2÷noise | valley curvature, tracer ÷ model | model at truth ÷ targets | status | s/it | within 5 % / 0.01 from, R, G, B: iteration (s of the loop's) |"
    );
    let _ = writeln!(
        md,
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
    );
    let f3 = |v: [f64; 3], s: f64, p: usize| {
        format!(
            "{:+.p$}, {:+.p$}, {:+.p$}",
            s * v[0],
            s * v[1],
            s * v[2],
            p = p
        )
    };
    let yn = |v: [bool; 3]| v.map(|b| if b { "y" } else { "n" }).join("");
    for o in outcomes {
        let cov = o.covered();
        let _ = writeln!(
            md,
            "| {} | {} | {} | {:.1}, {:.1}, {:.1} | {} ({}) | {} / {} | {} | {} | {:.3}, {:.3}, {:.3} / {:.2}, {:.2}, {:.2} | {:.2}, {:.2}, {:.2} | {:.3}, {:.3}, {:.3} | {} | {:.2} | {} |",
            o.case.name,
            o.targets.name(),
            o.rep,
            o.case.medium.sigma_t[0],
            o.case.medium.sigma_t[1],
            o.case.medium.sigma_t[2],
            f3(o.sigma_t_error(true), 100.0, 1),
            f3(o.sigma_t_error(false), 100.0, 1),
            yn(cov[0]),
            yn(cov[1]),
            yn(o.determined_sigma_t),
            f3(o.albedo_error(), 1.0, 4),
            o.consistency_ratio[0],
            o.consistency_ratio[1],
            o.consistency_ratio[2],
            o.consistency_l2[0],
            o.consistency_l2[1],
            o.consistency_l2[2],
            o.valley_curvature[0],
            o.valley_curvature[1],
            o.valley_curvature[2],
            o.model_ratio[0],
            o.model_ratio[1],
            o.model_ratio[2],
            o.status,
            o.seconds_per_iteration,
            o.settled
                .0
                .map(|s| match s {
                    Some(s) => format!("{} ({:.0} of {:.0})", s.iteration, s.seconds, o.settled.1),
                    None => "never".to_string(),
                })
                .join(", ")
        );
        csv_rows(csv, o, free);
    }
    let _ = writeln!(md);
    let mut names: Vec<Targets> = outcomes.iter().map(|o| o.targets).collect();
    names.dedup();
    if names.len() > 1 {
        summary(md, "all targets", outcomes);
        for t in names {
            let only: Vec<Outcome> = outcomes
                .iter()
                .filter(|o| o.targets == t)
                .cloned()
                .collect();
            summary(md, &format!("{} targets", t.name()), &only);
        }
    } else {
        summary(md, "", outcomes);
    }
}

/// The CSV rows of one run, one per channel.
fn csv_rows(csv: &mut String, o: &Outcome, free: &[&SharedColumn]) {
    let cov = o.covered();
    for c in 0..3 {
        let i = |v: Option<[f64; 2]>, k: usize| v.map_or(f64::NAN, |x| x[k]);
        let _ = write!(
            csv,
            "{},{},{},{},{},{},{},{},{},{:.5},{:.5},{},{},{},{},{},{},{:.5},{},{},{},{:.4},{:.4},{:.4},{:.4},{},{:.4},{},{},{}",
            o.case.name,
            o.case.capture.name(),
            o.case.mfp,
            o.case.shape,
            o.targets.name(),
            o.rep,
            ["R", "G", "B"][c],
            o.case.medium.sigma_t[c],
            o.estimate[0][c],
            o.sigma_t_error(true)[c],
            o.sigma_t_error(false)[c],
            i(o.interval_sigma_t[c], 0),
            i(o.interval_sigma_t[c], 1),
            cov[0][c],
            o.determined_sigma_t[c],
            o.case.medium.albedo[c],
            o.estimate[1][c],
            o.albedo_error()[c],
            i(o.interval_albedo[c], 0),
            i(o.interval_albedo[c], 1),
            cov[1][c],
            o.consistency_ratio[c],
            o.consistency_l2[c],
            o.valley_curvature[c],
            o.model_ratio[c],
            o.status,
            o.seconds_per_iteration,
            o.case.medium.eta,
            o.case.medium.roughness,
            o.case.medium.g
        );
        let mut settled = vec![o.settled];
        settled.extend(o.prb.as_ref().map(|p| p.settled));
        settled.resize(2, ([None; 3], f64::NAN));
        for (settled, total) in settled {
            match settled[c] {
                Some(s) => {
                    let _ = write!(csv, ",{},{:.2},{total:.2}", s.iteration, s.seconds);
                }
                None => {
                    let _ = write!(csv, ",,,{total:.2}");
                }
            }
        }
        // The shared parameters' columns (the same on the three channel rows).
        for col in free {
            match (col.of)(o) {
                Some(r) => {
                    let _ = write!(
                        csv,
                        ",{:.5},{:.5},{:.5},{},{}",
                        r.estimate,
                        r.interval[0],
                        r.interval[1],
                        r.covers((col.truth)(o)),
                        r.determined
                    );
                }
                None => csv.push_str(",,,,,"),
            }
        }
        csv.push('\n');
    }
}

/// The summary lines of `outcomes` (under the heading `label`, when given).
fn summary(md: &mut String, label: &str, outcomes: &[Outcome]) {
    let (head, ind) = if label.is_empty() {
        (String::new(), "")
    } else {
        (format!("- {label}:\n  "), "  ")
    };
    let pairs = outcomes.len() * 3;
    let covered_t: usize = outcomes
        .iter()
        .map(|o| o.covered()[0].iter().filter(|&&b| b).count())
        .sum();
    let covered_a: usize = outcomes
        .iter()
        .map(|o| o.covered()[1].iter().filter(|&&b| b).count())
        .sum();
    let det: Vec<f64> = outcomes
        .iter()
        .flat_map(|o| {
            let e = o.sigma_t_error(true);
            (0..3)
                .filter(move |&c| o.determined_sigma_t[c])
                .map(move |c| e[c].abs())
        })
        .collect();
    let all_t: Vec<f64> = outcomes
        .iter()
        .flat_map(|o| o.sigma_t_error(true).map(f64::abs))
        .collect();
    let all_t_unc: Vec<f64> = outcomes
        .iter()
        .flat_map(|o| o.sigma_t_error(false).map(f64::abs))
        .collect();
    let max_a = outcomes
        .iter()
        .flat_map(|o| o.albedo_error().map(f64::abs))
        .fold(0.0, f64::max);
    let failed = outcomes.iter().filter(|o| o.status != "ok").count();
    let unbounded = outcomes
        .iter()
        .flat_map(|o| o.interval_sigma_t)
        .filter(|i| i.is_some_and(|[_, hi]| hi.is_infinite()))
        .count();
    let _ = writeln!(
        md,
        "{head}- calibration: the truth inside the 95 % interval for σ_t in {covered_t} of {pairs} (case, channel) pairs ({:.0} %), for α in {covered_a} of {pairs} ({:.0} %); together {:.0} % (goal ≥ 90 %){}",
        100.0 * covered_t as f64 / pairs.max(1) as f64,
        100.0 * covered_a as f64 / pairs.max(1) as f64,
        100.0 * (covered_t + covered_a) as f64 / (2 * pairs).max(1) as f64,
        match unbounded {
            0 => String::new(),
            k => format!(
                "; σ_t in {k} of them has no finite interval (the images bound neither σ_t nor \
                 α there), counted as holding the truth"
            ),
        }
    );
    if det.is_empty() {
        let _ = writeln!(md, "{ind}- σ_t determined in none of the {pairs} pairs");
    } else {
        let _ = writeln!(
            md,
            "{ind}- σ_t determined in {} of {pairs} pairs: median |error| {:.1} %, largest {:.1} % (goal: median ≤ 3 %, every channel ≤ 10 %)",
            det.len(),
            100.0 * median(det.clone()),
            100.0 * det.iter().copied().fold(0.0, f64::max)
        );
    }
    let _ = writeln!(
        md,
        "{ind}- all pairs: median |σ_t error| {:.1} % (uncorrected {:.1} %); largest |α error| {:.4} (goal ≤ 0.01)",
        100.0 * median(all_t),
        100.0 * median(all_t_unc),
        max_a
    );
    let _ = writeln!(
        md,
        "{ind}- runs whose status is not ok: {failed} of {}",
        outcomes.len()
    );
    time_to_accuracy(md, ind, outcomes);
    // Where the model itself is off at the truth, and the calibration of the runs that
    // did not report a failure (a failed run's interval is not meant to be trusted).
    let off = |o: &Outcome| {
        o.model_ratio
            .iter()
            .any(|r| r.is_finite() && (r - 1.0).abs() > MODEL_RATIO_OFF)
    };
    let model_off: Vec<&Outcome> = outcomes.iter().filter(|o| off(o)).collect();
    let big_alpha = |o: &Outcome| o.albedo_error().iter().any(|e| e.abs() > 0.01);
    let _ = writeln!(
        md,
        "{ind}- the model renders the truth more than {:.0} % off the targets (a channel) in {} of {} runs; of the {} runs with an α error above 0.01, {} are among them",
        100.0 * MODEL_RATIO_OFF,
        model_off.len(),
        outcomes.len(),
        outcomes.iter().filter(|o| big_alpha(o)).count(),
        model_off.iter().filter(|o| big_alpha(o)).count()
    );
    let ok: Vec<&Outcome> = outcomes.iter().filter(|o| o.status == "ok").collect();
    let covered_ok: usize = ok
        .iter()
        .map(|o| o.covered().iter().flatten().filter(|&&b| b).count())
        .sum();
    let _ = writeln!(
        md,
        "{ind}- calibration of the {} runs whose status is ok: {covered_ok} of {} (parameter, channel) pairs ({:.0} %)",
        ok.len(),
        6 * ok.len(),
        100.0 * covered_ok as f64 / (6 * ok.len()).max(1) as f64
    );
}

/// The summary line of the time to an accurate answer ([`super::settle`]) on the (run, channel)
/// pairs whose σ_t is determined.
fn time_to_accuracy(md: &mut String, ind: &str, outcomes: &[Outcome]) {
    let pairs: Vec<Option<(f64, f64)>> = outcomes
        .iter()
        .flat_map(|o| {
            (0..3)
                .filter(|&c| o.determined_sigma_t[c])
                .map(move |c| o.settled.0[c].map(|s| (s.iteration as f64, s.seconds / o.settled.1)))
        })
        .collect();
    if pairs.is_empty() {
        return;
    }
    let settled: Vec<(f64, f64)> = pairs.iter().flatten().copied().collect();
    let _ = writeln!(
        md,
        "{ind}- time to σ_t within {:.0} % and α within {} for good, on the {} determined pairs: {} settle, at a median iteration {:.0} ({:.0} % of the loop's seconds; latest {:.0}); {} never do",
        100.0 * super::settle::SIGMA_T_BAND,
        super::settle::ALBEDO_BAND,
        pairs.len(),
        settled.len(),
        median(settled.iter().map(|s| s.0).collect()),
        100.0 * median(settled.iter().map(|s| s.1).collect()),
        settled.iter().map(|s| s.0).fold(f64::NAN, f64::max),
        pairs.len() - settled.len()
    );
}

/// A channel whose learned render of the truth differs from the targets by more than this
/// (relative) counts as the model's own error in the summary.
const MODEL_RATIO_OFF: f64 = 0.05;

/// "our volumetric path tracer", "Mitsuba 3's volpath" or both.
fn renderers_named(outcomes: &[Outcome]) -> String {
    let mut names: Vec<&str> = Vec::new();
    for o in outcomes {
        let n = match o.targets {
            Targets::Volpath => "our volumetric path tracer",
            Targets::Mitsuba => "Mitsuba 3's volpath",
        };
        if !names.contains(&n) {
            names.push(n);
        }
    }
    names.join(" and ")
}
