//! Mitsuba 3's PRB on the suite's cases: every case recovered also by Mitsuba 3's differentiable
//! `prbvolpath` (`tools/mitsuba/prb_optimize.py`: its own Adam on ln σ_t and α with the
//! defaults' learning rates, 0.015 and 0.02, from the same start σ_t = 50, α = 0.5, one random
//! view per iteration at the suite's samples per pixel, L2 loss), and its time to an accurate
//! answer ([`super::settle`]) set beside the defaults'.
//!
//! Both times are wall clock of the optimisation loop alone (PRB's first iteration includes
//! compiling its kernels, about a second). The table gives, per case and channel, the iteration
//! from which each run stays within σ_t ± 5 % and α ± 0.01 and the seconds until then; the
//! summary, on the pairs whose σ_t the defaults determine, the median of each and of PRB's
//! seconds over the defaults' (a pair PRB never settles on counts with PRB's whole loop: a
//! lower bound).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use recovery::Observer;
use recovery::reuse::read_json;

use super::settle::{self, Settled};
use super::{Case, Outcome, RobustnessConfig};
use crate::error::Result;

/// Where the defaults start, and so PRB too (`prb_optimize.py`'s defaults).
const START: ([f64; 3], [f64; 3]) = ([50.0; 3], [0.5; 3]);

/// PRB's recovery of one case.
#[derive(Clone, Debug)]
pub struct PrbOutcome {
    /// Its iterations.
    pub iterations: u32,
    /// Its learning rates' decay (factor, every so many iterations), `None`: constant.
    pub decay: Option<(f32, u32)>,
    /// Its final estimate (σ_t, α).
    pub estimate: [[f64; 3]; 2],
    /// Mean seconds per iteration over iterations 1 … N − 1 (after the kernels' compilation).
    pub seconds_per_iteration: f64,
    /// Per channel, when its estimate entered the band for good, and the loop's total seconds.
    pub settled: ([Option<Settled>; 3], f64),
}

/// PRB's settings: iterations, samples per pixel, seed, and its learning rates' decay (factor,
/// every so many iterations; `None`: constant).
pub(super) type PrbSettings = (u32, u32, u64, Option<(f32, u32)>);

/// Whether PRB finished in `dir` with these settings.
fn finished(dir: &Path, (iterations, spp, _, decay): PrbSettings) -> bool {
    let factor = decay.map_or(1.0, |d| d.0 as f64);
    read_json(&dir.join("result.json")).is_ok_and(|v| {
        v["iterations"].as_u64() == Some(iterations as u64)
            && v["spp"].as_u64() == Some(spp as u64)
            // The factor went through its decimal form (an f32 printed, read as f64).
            && (v["lr_decay"]["factor"].as_f64().unwrap_or(1.0) - factor).abs() < 1e-6
    })
}

/// PRB's recovery of `case` (repetition `rep`, the run `tag`, its dataset `data`) where the
/// suite's settings `a` ask for one: run (where `run`) or read, in `RUNS/{tag}-prb` (constant
/// learning rates) or `RUNS/{tag}-prb-decay` (decayed as the defaults' are).
pub(super) fn of_case(
    a: &RobustnessConfig,
    case: &Case,
    (rep, tag): (u64, &str),
    data: &Path,
    run: bool,
    obs: &dyn Observer,
) -> Result<Option<PrbOutcome>> {
    let Some(n) = a.prb_iterations else {
        return Ok(None);
    };
    let decay = a.prb_decay.then(|| {
        let d = inverse::optimize::OptimizeConfig::default();
        (d.decay, d.decay_every)
    });
    let suffix = if decay.is_some() {
        "-prb-decay"
    } else {
        "-prb"
    };
    let dir = a.out.join("runs").join(format!("{tag}{suffix}"));
    let settings = (n, a.workload().spp, a.seed + rep, decay);
    // The object's mesh as a file: the script rebuilds only some built-in shapes.
    let mesh = || match super::cases::mesh_source(case, &a.mesh, &dir, (true, a.quick))? {
        scene::scene_file::MeshSource::File(p) => Ok(p),
        _ => crate::bail!("{}: no mesh file for Mitsuba 3", case.name),
    };
    run_or_read(
        &a.python,
        (data, &mesh),
        &dir,
        settings,
        &case.medium,
        run,
        obs,
    )
}

/// PRB's recovery of the case whose dataset is `data` and whose truth is `truth`, in `dir`:
/// run with `python` on the object's mesh written by `mesh` (unless it finished there with
/// these settings, or `run` is false), then read. `None` where it has not run.
#[allow(clippy::too_many_arguments)]
fn run_or_read(
    python: &Path,
    (data, mesh): (&Path, &dyn Fn() -> Result<PathBuf>),
    dir: &Path,
    settings: PrbSettings,
    truth: &scene::Medium,
    run: bool,
    obs: &dyn Observer,
) -> Result<Option<PrbOutcome>> {
    let (iterations, spp, seed, decay) = settings;
    if finished(dir, settings) {
        if run {
            obs.say(&format!("run Mitsuba PRB: reusing {}", dir.display()));
        }
    } else if run {
        obs.say(&format!(
            "run Mitsuba PRB on {}: {iterations} iterations × {spp} spp",
            data.display()
        ));
        let mesh = mesh()?;
        super::super::run_prb(
            python,
            (data, Some(&mesh)),
            dir,
            iterations,
            spp,
            seed,
            decay,
        )?;
    } else {
        return Ok(None);
    }
    let v = read_json(&dir.join("result.json"))?;
    let rgb = |x: &serde_json::Value| -> [f64; 3] {
        std::array::from_fn(|c| x[c].as_f64().unwrap_or(f64::NAN))
    };
    Ok(Some(PrbOutcome {
        iterations,
        decay,
        estimate: [
            rgb(&v["estimate"]["sigma_t"]),
            rgb(&v["estimate"]["albedo"]),
        ],
        seconds_per_iteration: v["seconds_per_iteration"].as_f64().unwrap_or(f64::NAN),
        settled: settle::settled_from_csv(
            &dir.join("iterations.csv"),
            settle::Rows::After(START),
            truth.sigma_t.map(f64::from),
            truth.albedo.map(f64::from),
        )?,
    }))
}

fn when(s: Option<Settled>, total: f64) -> String {
    s.map_or(format!("never ({total:.0} s)"), |s| {
        format!("{} ({:.0} s)", s.iteration, s.seconds)
    })
}

/// The table and summary of the runs that have PRB's beside them (nothing when none has).
pub(super) fn table(md: &mut String, outcomes: &[Outcome]) {
    let with: Vec<(&Outcome, &PrbOutcome)> = outcomes
        .iter()
        .filter_map(|o| o.prb.as_ref().map(|p| (o, p)))
        .collect();
    let Some((_, first)) = with.first() else {
        return;
    };
    let _ = writeln!(
        md,
        "\n### Time to σ_t within {:.0} % and α within {}: the defaults against Mitsuba 3 PRB\n\n\
         PRB: `prbvolpath`, its own Adam on ln σ_t and α (learning rates 0.015, 0.02{}), from \
         the same start, {} iterations, one random view per iteration at the suite's spp. Per \
         channel: the iteration from which the run stays in the band (seconds of the loop until \
         then); `never`: not within the run (its whole loop's seconds).\n\n\
         | case | rep | σ_t determined | defaults: R, G, B | defaults s/it | PRB: R, G, B | PRB s/it | PRB σ_t error % | PRB α error |\n\
         |---|---|---|---|---|---|---|---|---|",
        100.0 * settle::SIGMA_T_BAND,
        settle::ALBEDO_BAND,
        first
            .decay
            .map_or(", constant".to_string(), |(f, n)| format!(
                ", ×{f} every {n} iterations as the defaults'"
            )),
        first.iterations
    );
    let yn = |b: bool| if b { 'y' } else { 'n' };
    for (o, p) in &with {
        let m = &o.case.medium;
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {:.2} | {} | {:.2} | {} | {} |",
            o.case.name,
            o.rep,
            o.determined_sigma_t.map(yn).iter().collect::<String>(),
            (0..3)
                .map(|c| when(o.settled.0[c], o.settled.1))
                .collect::<Vec<_>>()
                .join(", "),
            o.seconds_per_iteration,
            (0..3)
                .map(|c| when(p.settled.0[c], p.settled.1))
                .collect::<Vec<_>>()
                .join(", "),
            p.seconds_per_iteration,
            (0..3)
                .map(|c| format!(
                    "{:+.1}",
                    100.0 * (p.estimate[0][c] / m.sigma_t[c] as f64 - 1.0)
                ))
                .collect::<Vec<_>>()
                .join(", "),
            (0..3)
                .map(|c| format!("{:+.4}", p.estimate[1][c] - m.albedo[c] as f64))
                .collect::<Vec<_>>()
                .join(", "),
        );
    }
    summary(md, &with);
}

/// On the determined pairs: how many settle in each run, the median seconds to accuracy of
/// each, and the median of PRB's seconds over the defaults'.
fn summary(md: &mut String, with: &[(&Outcome, &PrbOutcome)]) {
    // (defaults' seconds, PRB's seconds or its whole loop, whether PRB settled).
    let mut pairs: Vec<(f64, f64, bool)> = Vec::new();
    let mut unsettled_ours = 0;
    for (o, p) in with {
        for c in (0..3).filter(|&c| o.determined_sigma_t[c]) {
            let Some(ours) = o.settled.0[c] else {
                unsettled_ours += 1;
                continue;
            };
            let theirs = p.settled.0[c];
            pairs.push((
                ours.seconds,
                theirs.map_or(p.settled.1, |s| s.seconds),
                theirs.is_some(),
            ));
        }
    }
    if pairs.is_empty() {
        let _ = writeln!(
            md,
            "\n- no pair whose σ_t the defaults determine and settle on"
        );
        return;
    }
    let med =
        |f: &dyn Fn(&(f64, f64, bool)) -> f64| super::report::median(pairs.iter().map(f).collect());
    let prb_settled = pairs.iter().filter(|p| p.2).count();
    let _ = writeln!(
        md,
        "\n- on the {} pairs whose σ_t the defaults determine and settle on ({} determined pairs \
         never settle): the defaults are accurate after a median {:.0} s; PRB settles on {} of \
         them, after a median {:.0} s (a pair it never settles on counts its whole loop); PRB's \
         seconds ÷ the defaults': median {:.1}×, smallest {:.1}×{}",
        pairs.len(),
        unsettled_ours,
        med(&|p| p.0),
        prb_settled,
        med(&|p| p.1),
        med(&|p| p.1 / p.0),
        pairs
            .iter()
            .map(|p| p.1 / p.0)
            .fold(f64::INFINITY, f64::min),
        if prb_settled < pairs.len() {
            " (lower bounds where PRB never settles)"
        } else {
            ""
        }
    );
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::robustness::{Targets, cases, outcome};

    /// A run's `iterations.csv` with the parameters `f` × the truth per row (`secs` each).
    fn trajectory(truth: &scene::Medium, rows: &[f64], secs: f64) -> String {
        let mut csv = String::from(
            "iteration,sigma_t_r,sigma_t_g,sigma_t_b,albedo_r,albedo_g,albedo_b,seconds\n",
        );
        for (i, f) in rows.iter().enumerate() {
            let s = truth.sigma_t.map(|s| s as f64 * f);
            let a = truth.albedo;
            let _ = writeln!(
                csv,
                "{i},{},{},{},{},{},{},{secs}",
                s[0], s[1], s[2], a[0], a[1], a[2]
            );
        }
        csv
    }

    /// PRB's finished folder is read (its trajectory after each step, from the start), and the
    /// table sets its time to accuracy beside the defaults' on the determined pairs; a folder
    /// without a finished run reads as none.
    #[test]
    fn prbs_time_to_accuracy_is_read_and_compared() {
        let dir = tempfile::tempdir().expect("tmp");
        let case = cases(0).remove(0);
        let m = case.medium;
        // The defaults: in the band from the third row on, 1 s per iteration; the final
        // estimate is the truth.
        let ours = dir.path().join("ours");
        std::fs::create_dir_all(&ours).expect("mkdir");
        std::fs::write(
            ours.join("iterations.csv"),
            trajectory(&m, &[2.0, 1.5, 1.01, 1.0], 1.0),
        )
        .expect("write");
        let est = serde_json::json!({"sigma_t": m.sigma_t, "albedo": m.albedo});
        let result = serde_json::json!({
            "estimate": est, "determined": {"sigma_t": [true, true, false]},
            "status": "ok", "seconds_per_iteration": 1.0,
        });
        std::fs::write(ours.join("result.json"), result.to_string()).expect("write");
        let mut o = outcome(&case, 0, Targets::Volpath, &ours.join("result.json")).expect("read");
        assert_eq!(
            o.settled.0[0].map(|s| (s.iteration, s.seconds)),
            Some((2, 2.0))
        );

        // PRB: 4 iterations of 3 s after which it is in the band from its third step on.
        let prb = dir.path().join("prb");
        let no_mesh = || -> Result<PathBuf> { unreachable!("not run") };
        // Read (never run) PRB's folder with these settings.
        let read = |settings: PrbSettings| {
            let at = Path::new("/nonexistent");
            run_or_read(
                at,
                (&ours, &no_mesh),
                &prb,
                settings,
                &m,
                false,
                &recovery::Silent,
            )
            .expect("read")
        };
        assert!(read((4, 32, 0, None)).is_none());
        std::fs::create_dir_all(&prb).expect("mkdir");
        std::fs::write(
            prb.join("iterations.csv"),
            trajectory(&m, &[1.8, 1.3, 1.02, 0.99], 3.0),
        )
        .expect("write");
        let mut r = result.clone();
        r["iterations"] = 4.into();
        r["spp"] = 32.into();
        r["seconds_per_iteration"] = 3.0.into();
        std::fs::write(prb.join("result.json"), r.to_string()).expect("write");
        let p = read((4, 32, 0, None)).expect("finished");
        // The start, then rows 0, 1, 2: in the band from row 2 (the trajectory's index 3).
        assert_eq!(
            p.settled.0[1].map(|s| (s.iteration, s.seconds)),
            Some((3, 9.0))
        );
        assert_eq!(p.settled.1, 12.0);
        // Other settings: not this run.
        assert!(read((5, 32, 0, None)).is_none());
        // The same run with a decay, as the script records it: reused only with that decay.
        r["lr_decay"] = serde_json::json!({"factor": 0.85, "every": 50});
        std::fs::write(prb.join("result.json"), r.to_string()).expect("write");
        assert!(read((4, 32, 0, Some((0.85, 50)))).is_some());
        assert!(read((4, 32, 0, None)).is_none());

        o.prb = Some(p);
        let mut md = String::new();
        table(&mut md, &[o]);
        assert!(md.contains("| 2 (2 s), 2 (2 s), 2 (2 s) |"), "{md}");
        assert!(md.contains("| 3 (9 s), 3 (9 s), 3 (9 s) |"), "{md}");
        // Two determined pairs, PRB 9 s against 2 s on each.
        assert!(md.contains("on the 2 pairs"), "{md}");
        assert!(md.contains("median 4.5×"), "{md}");
    }
}
