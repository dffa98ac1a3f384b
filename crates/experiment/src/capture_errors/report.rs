//! The capture-errors table (`OUT/capture-errors.md`, `OUT/capture-errors.csv`): per case and
//! perturbation the errors, their shift from the unperturbed run, the intervals' hold, status
//! and verdict; then per perturbation the verdicts over the cases.

use std::fmt::Write as _;

use super::{CaptureErrorsConfig, Perturbation, Row};
use inverse::params::OneOrRgb;

/// What a run's figures say about a perturbation (module docs of [`super`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Verdict {
    /// Every 95 % interval (σ_t and α, each channel, and the light's scale where it is
    /// recovered) holds the truth.
    Holds,
    /// An interval misses the truth and the run's status is not `ok`.
    Flagged,
    /// An interval misses the truth and the run says `ok`.
    Wrong,
}

impl Verdict {
    pub fn of(row: &Row) -> Verdict {
        let o = &row.outcome;
        let truth = row.perturbation.true_light_scale();
        let holds = o.covered().iter().flatten().all(|&c| c)
            && o.light_scale.is_none_or(|l| match l {
                // One factor's truth: the channels' (equal but for a white-balance error,
                // which one factor cannot hold: its interval then holds their mean).
                OneOrRgb::One(k) => k.covers(truth.iter().sum::<f64>() / 3.0),
                OneOrRgb::Rgb(k) => (0..3).all(|c| k[c].covers(truth[c])),
            });
        match (holds, o.status == "ok") {
            (true, _) => Verdict::Holds,
            (false, false) => Verdict::Flagged,
            (false, true) => Verdict::Wrong,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Verdict::Holds => "holds",
            Verdict::Flagged => "flagged",
            Verdict::Wrong => "wrong",
        }
    }
}

const CSV_HEADER: &str = "case,perturbation,channel,sigma_t_true,sigma_t_est,sigma_t_err,sigma_t_shift,sigma_t_lo,sigma_t_hi,sigma_t_covered,sigma_t_determined,albedo_true,albedo_est,albedo_err,albedo_shift,albedo_lo,albedo_hi,albedo_covered,light_scale_true,light_scale,light_scale_lo,light_scale_hi,status,verdict";

/// The unperturbed run of `row`'s case.
fn baseline<'a>(rows: &'a [Row], row: &Row) -> Option<&'a Row> {
    rows.iter().find(|r| {
        r.perturbation == Perturbation::None && r.outcome.case.name == row.outcome.case.name
    })
}

/// The estimate's shift from the unperturbed run's: σ_t relative, α absolute, per channel.
fn shift(rows: &[Row], row: &Row) -> ([f64; 3], [f64; 3]) {
    match baseline(rows, row) {
        Some(b) => {
            let (e, f) = (&row.outcome.estimate, &b.outcome.estimate);
            (
                std::array::from_fn(|c| e[0][c] / f[0][c] - 1.0),
                std::array::from_fn(|c| e[1][c] - f[1][c]),
            )
        }
        None => ([f64::NAN; 3], [f64::NAN; 3]),
    }
}

/// The entry of largest magnitude, with its sign.
fn largest(v: [f64; 3]) -> f64 {
    v.into_iter()
        .fold(0.0f64, |m, x| if x.abs() > m.abs() { x } else { m })
}

pub(super) fn report(a: &CaptureErrorsConfig, rows: &[Row]) -> (String, String) {
    let mut md = String::new();
    let w = a.suite().workload();
    let (views, res, spp, iterations) = (w.views, w.res, w.target_spp, w.iterations);
    let _ = writeln!(
        md,
        "Capture errors: {views} views {res}² (targets at {spp} spp by the volumetric path tracer), \
         `optimize`'s defaults ({iterations} iterations{}{}), seed {}{}\n",
        match (a.free_light_scale, a.light_scale_per_channel) {
            (false, _) => "",
            (true, false) => ", the light scale free",
            (true, true) => ", the light scale free per channel",
        },
        a.mesh_error
            .map(|f| format!(", intervals with a mesh error of {} %", 100.0 * f))
            .unwrap_or_default(),
        a.seed,
        if a.quick {
            " (quick: a smoke test, not a measurement)"
        } else {
            ""
        }
    );
    let _ = writeln!(
        md,
        "σ_t error per channel against the truth; shift: the largest change of the estimate from \
         the unperturbed run's (σ_t relative, α absolute); in 95 %: channels whose interval holds \
         the truth; verdict: `holds` (every interval holds the truth), `flagged` (one misses and \
         the run is not `ok`), `wrong` (one misses and the run says `ok`).\n"
    );
    let mut csv = String::from(CSV_HEADER);
    csv.push('\n');
    let mut cases: Vec<&str> = rows.iter().map(|r| r.outcome.case.name.as_str()).collect();
    cases.dedup();
    // Runs that recover the light's scale get its column: estimate, interval and truth.
    let with_k = rows.iter().any(|r| r.outcome.light_scale.is_some());
    for case in cases {
        let _ = writeln!(md, "### {case}\n");
        let _ = writeln!(
            md,
            "| perturbation | σ_t error R, G, B | σ_t shift | α error (largest) | α shift | in 95 % σ_t; α | σ_t determined | {}status | verdict |\n|---|---|---|---|---|---|---|{}---|---|",
            if with_k {
                "light scale [95 %] (truth) | "
            } else {
                ""
            },
            if with_k { "---|" } else { "" }
        );
        for row in rows.iter().filter(|r| r.outcome.case.name == case) {
            let o = &row.outcome;
            let err = o.sigma_t_error(true);
            let (s_sigma, s_alpha) = shift(rows, row);
            let cov = o.covered();
            let count = |v: &[bool; 3]| v.iter().filter(|&&b| b).count();
            let verdict = Verdict::of(row);
            let _ = writeln!(
                md,
                "| {} | {:+.1}, {:+.1}, {:+.1} % | {} | {:+.3} | {} | {}/3; {}/3 | {}/3 | {}{} | {} |",
                row.perturbation.describe(),
                100.0 * err[0],
                100.0 * err[1],
                100.0 * err[2],
                if row.perturbation == Perturbation::None {
                    "—".to_string()
                } else {
                    format!("{:+.1} %", 100.0 * largest(s_sigma))
                },
                largest(o.albedo_error()),
                if row.perturbation == Perturbation::None {
                    "—".to_string()
                } else {
                    format!("{:+.3}", largest(s_alpha))
                },
                count(&cov[0]),
                count(&cov[1]),
                count(&o.determined_sigma_t),
                match o.light_scale {
                    Some(OneOrRgb::One(k)) => format!(
                        "{:.3} [{:.3}, {:.3}] ({:.3}) | ",
                        k.estimate,
                        k.interval[0],
                        k.interval[1],
                        row.perturbation.true_light_scale().iter().sum::<f64>() / 3.0
                    ),
                    Some(OneOrRgb::Rgb(k)) => {
                        let t = row.perturbation.true_light_scale();
                        format!(
                            "{:.3}, {:.3}, {:.3}; {}/3 in 95 % ({:.3}, {:.3}, {:.3}) | ",
                            k[0].estimate,
                            k[1].estimate,
                            k[2].estimate,
                            (0..3).filter(|&c| k[c].covers(t[c])).count(),
                            t[0],
                            t[1],
                            t[2]
                        )
                    }
                    None if with_k => "— | ".to_string(),
                    None => String::new(),
                },
                o.status,
                match verdict {
                    Verdict::Wrong => "**wrong**",
                    v => v.name(),
                }
            );
            csv_rows(&mut csv, row, (s_sigma, s_alpha), verdict);
        }
        md.push('\n');
    }
    summary(&mut md, rows);
    (md, csv)
}

fn csv_rows(csv: &mut String, row: &Row, shift: ([f64; 3], [f64; 3]), verdict: Verdict) {
    let o = &row.outcome;
    let cov = o.covered();
    let err = [o.sigma_t_error(true), o.albedo_error()];
    let truth = [o.case.medium.sigma_t, o.case.medium.albedo];
    let intervals = [o.interval_sigma_t, o.interval_albedo];
    let shifts = [shift.0, shift.1];
    // Parameter k's columns of channel c: truth, estimate, error, shift, interval, covered.
    let param = |k: usize, c: usize| {
        let [lo, hi] = intervals[k][c].unwrap_or([f64::NAN; 2]);
        format!(
            "{},{},{},{},{lo},{hi},{}",
            truth[k][c], o.estimate[k][c], err[k][c], shifts[k][c], cov[k][c]
        )
    };
    // The light scale's columns of channel c (a single factor's in every row).
    let k = |c: usize| {
        o.light_scale.map_or("NaN,NaN,NaN".to_string(), |l| {
            let l = l.channel(c);
            format!("{},{},{}", l.estimate, l.interval[0], l.interval[1])
        })
    };
    for c in 0..3 {
        let k = k(c);
        let _ = writeln!(
            csv,
            "{},{},{},{},{},{},{},{k},{},{}",
            o.case.name,
            row.perturbation.name(),
            ["R", "G", "B"][c],
            param(0, c),
            o.determined_sigma_t[c],
            param(1, c),
            row.perturbation.true_light_scale()[c],
            o.status,
            verdict.name()
        );
    }
}

/// Per perturbation, its verdicts over the cases; then the count of confident wrong numbers.
fn summary(md: &mut String, rows: &[Row]) {
    let _ = writeln!(
        md,
        "### Over the cases\n\n| perturbation | holds | flagged | wrong | largest σ_t shift | largest α shift |\n|---|---|---|---|---|---|"
    );
    let mut seen: Vec<Perturbation> = Vec::new();
    for row in rows {
        if !seen.contains(&row.perturbation) {
            seen.push(row.perturbation);
        }
    }
    let mut wrong = 0;
    for p in &seen {
        let of: Vec<&Row> = rows.iter().filter(|r| r.perturbation == *p).collect();
        let n = |v: Verdict| of.iter().filter(|r| Verdict::of(r) == v).count();
        wrong += n(Verdict::Wrong);
        let (s_sigma, s_alpha) = of.iter().fold((0.0f64, 0.0f64), |(a, b), r| {
            let (s, t) = shift(rows, r);
            let (s, t) = (largest(s), largest(t));
            (
                if s.abs() > a.abs() { s } else { a },
                if t.abs() > b.abs() { t } else { b },
            )
        });
        let none = *p == Perturbation::None;
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {} | {} |",
            p.describe(),
            n(Verdict::Holds),
            n(Verdict::Flagged),
            n(Verdict::Wrong),
            if none {
                "—".into()
            } else {
                format!("{:+.1} %", 100.0 * s_sigma)
            },
            if none {
                "—".into()
            } else {
                format!("{:+.3}", s_alpha)
            }
        );
    }
    let _ = writeln!(
        md,
        "\nConfident wrong numbers (an interval misses the truth, the run says `ok`): {wrong} of {} runs.",
        rows.len()
    );
}
