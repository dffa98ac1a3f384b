//! Inverse rendering: optimize (with the bias correction), resume, gradcheck,
//! experiment accuracy.

use std::path::Path;

use serde_json::Value;

use super::helpers::*;

/// `optimize` of the dataset `ds` ([`tiny_optimize_dataset`]) into `o`: 3 iterations at
/// 2 spp.
const TINY_OPTIMIZE: [&str; 11] = [
    "optimize",
    "--dataset",
    "ds",
    "--out",
    "o",
    "--iterations",
    "3",
    "--spp",
    "2",
    "--final-spp",
    "2",
];

// ---------------------------------------------------------------------------------------------
// Inverse rendering: optimize, resume, gradcheck.

/// A temporary folder holding the dataset `ds` of [`TINY_OPTIMIZE`]: `views` views of 12² of
/// a sphere at σ_t = 60, α = 0.9.
fn tiny_optimize_dataset(views: &str) -> tempfile::TempDir {
    let t = tmp();
    make_dataset(
        t.path(),
        "ds",
        views,
        "12",
        &["--sigma-t", "60", "--albedo", "0.9"],
    );
    t
}

#[test]
fn optimize_writes_results_resumes_and_gradcheck_runs() {
    let t = tiny_optimize_dataset("2");
    let d = t.path();
    let opt = [&TINY_OPTIMIZE[..], &["--checkpoint-every", "2"]].concat();
    let r = ok(d, &opt);
    assert_stdout_has(&r, &["truth"]);
    let res = read_json(&d.join("o/result.json"));
    for k in [
        "estimate",
        "truth",
        "iterations",
        "spp",
        "seconds_per_iteration",
        "seconds_total",
        "method",
        "seed",
    ] {
        assert!(res.get(k).is_some(), "result.json lacks {k}: {res}");
    }
    assert_eq!(res["iterations"], 3);
    assert_eq!(res["method"], "ours");
    assert_eq!(res["estimate"]["sigma_t"].as_array().unwrap().len(), 3);
    for f in [
        "iterations.csv",
        "convergence.png",
        "convergence.svg",
        "checkpoint.json",
        "final/view_000.png",
        "final/view_000_diff.png",
        "final/overview.png",
        "final/contact-sheet.png",
    ] {
        assert!(d.join("o").join(f).exists(), "missing {f}");
    }
    // The estimate as Mitsuba 3 XML, which reads back as the estimate and renders.
    let xml: Vec<_> = std::fs::read_dir(d.join("o/mitsuba"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "xml") && !p.ends_with("medium.xml"))
        .collect();
    assert!(!xml.is_empty() && d.join("o/mitsuba/medium.xml").exists());
    let back = scene::SceneDesc::load(&xml[0]).unwrap();
    for c in 0..3 {
        let want = res["estimate"]["sigma_t"][c].as_f64().unwrap();
        assert!(
            (back.medium.sigma_t[c] as f64 / want - 1.0).abs() < 1e-5,
            "{back:?}"
        );
    }
    let r = ok(
        d,
        &[
            "render",
            xml[0].to_str().unwrap(),
            "--spp",
            "1",
            "--out",
            "rx",
        ],
    );
    assert_stdout_has(&r, &["rendered"]);
    assert!(d.join("rx/view_000.exr").exists());
    let again = fails(d, &opt);
    assert_stderr_has(&again, &["--resume", "--overwrite"]);
    let mut resume: Vec<&str> = opt.to_vec();
    resume[6] = "5"; // --iterations 5
    resume.push("--resume");
    ok(d, &resume);
    assert_eq!(read_json(&d.join("o/result.json"))["iterations"], 5);
    let bad = fails(
        d,
        &[
            "optimize",
            "--dataset",
            "ds",
            "--out",
            "o2",
            "--estimator",
            "magic",
        ],
    );
    assert_stderr_has(&bad, &["magic", "ours"]);

    let r = ok(
        d,
        &["gradcheck", "--dataset", "ds", "--spp", "2", "--out", "g"],
    );
    assert_stdout_has(&r, &["naive", "fd"]);
    for f in [
        "gradcheck.csv",
        "ours_d_sigma_t.png",
        "fd_d_albedo.png",
        "naive_d_sigma_t.exr",
    ] {
        assert!(d.join("g").join(f).exists(), "missing {f}");
    }
}

// ---------------------------------------------------------------------------------------------
// experiment accuracy

/// Channel `c` of `v[key]` (a medium as JSON: `{"sigma_t": [3], "albedo": [3]}`).
fn num(v: &Value, key: &str, c: usize) -> f64 {
    v[key][c].as_f64().unwrap()
}

/// The estimate (σ_t[3], α[3]) of the row of `case` and `method` in an experiment's
/// `results.csv`, as a medium in JSON.
fn csv_estimate(csv: &str, case: &str, method: &str) -> Value {
    let v: Vec<f64> = csv
        .lines()
        .find(|l| l.starts_with(&format!("{case},{method},")))
        .unwrap_or_else(|| panic!("no row {case},{method} in {csv}"))
        .split(',')
        .skip(14)
        .take(6)
        .map(|v| v.parse().unwrap())
        .collect();
    serde_json::json!({ "sigma_t": v[..3], "albedo": v[3..] })
}

/// Bootstrap step `step` from its files: its dataset was simulated at `current` (θ_{k−1}, the
/// dataset's `truth`: f32 precision), and `got` is θ_k = θ_{k−1} + θ̂ − θ̂_k in (ln σ_t, α) with
/// θ̂ = `est` and θ̂_k = `refit`, to the relative σ_t and absolute α tolerances `tol`.
fn assert_bootstrap_step(
    step: usize,
    truth: &Value,
    current: &Value,
    est: &Value,
    refit: &Value,
    got: &Value,
    tol: (f64, f64),
) {
    for c in 0..3 {
        for key in ["sigma_t", "albedo"] {
            let (a, b) = (num(truth, key, c), num(current, key, c));
            assert!(
                (a - b).abs() <= 1e-5 * b.abs(),
                "step {step} {key}[{c}]: {a} vs {b}"
            );
        }
        let s = (num(current, "sigma_t", c).ln() + num(est, "sigma_t", c).ln()
            - num(refit, "sigma_t", c).ln())
        .exp();
        let a = (num(current, "albedo", c) + num(est, "albedo", c) - num(refit, "albedo", c))
            .clamp(1e-4, 0.99995);
        let (gs, ga) = (num(got, "sigma_t", c), num(got, "albedo", c));
        assert!(
            (gs - s).abs() <= tol.0 * s,
            "step {step} σ_t[{c}]: {gs} vs {s}"
        );
        assert!((ga - a).abs() <= tol.1, "step {step} α[{c}]: {ga} vs {a}");
    }
}

/// `optimize --bias-correction --bias-correction-steps 2`: each step simulates the dataset at
/// the previous medium (θ̂, then θ₁) with the dataset's own spp, recovers from it with the same
/// settings, and `result.json` reports θ₂ = θ₁ + θ̂ − θ̂₂' as `estimate` beside the optimiser's
/// own; `--resume` reuses the steps, `--overwrite` drops them. `--bias-correction` means the
/// learned model alone, in the main run and in the steps' recoveries: with a refinement it is
/// refused, as is `--refine-spp` without a refinement.
#[test]
fn optimize_bias_correction_reports_the_iterated_correction() {
    let t = tmp();
    let d = t.path();
    make_dataset(d, "ds", "2", "12", &["--sigma-t", "60", "--albedo", "0.9"]);
    let both = [&TINY_OPTIMIZE[..], &["--bias-correction", "--refine", "1"]].concat();
    assert_stderr_has(
        &fails(d, &both),
        &["--bias-correction with --refine 1", "fix"],
    );
    let unrefined = [&TINY_OPTIMIZE[..], &["--refine", "0", "--refine-spp", "4"]].concat();
    assert_stderr_has(
        &fails(d, &unrefined),
        &["--refine-spp 4 without a refinement", "fix"],
    );
    let mut args = TINY_OPTIMIZE.to_vec();
    args.extend(["--bias-correction", "--bias-correction-steps", "2"]);
    let run = ok(d, &args);
    assert_stdout_has(
        &run,
        &[
            "bootstrap step 2:",
            "bias-corrected (2 steps, simulations at 4 spp)",
        ],
    );
    let r = read_json(&d.join("o/result.json"));
    let est = r["estimate_uncorrected"].clone();
    let steps = r["bias_correction"]["steps"].as_array().unwrap().clone();
    assert_eq!(steps.len(), 2);
    assert_eq!(r["bias_correction"]["simulation_spp"], 4);
    let mut current = est.clone();
    for (k, step) in steps.iter().enumerate() {
        let dir = d.join(format!("o/bootstrap/step-{}", k + 1));
        let sim = read_json(&dir.join("data/dataset.json"));
        let run = read_json(&dir.join("run/result.json"));
        // The recovery from the simulation is the learned model alone, as the main run.
        assert_eq!(
            run["config"]["refine_iterations"],
            r["config"]["refine_iterations"]
        );
        let refit = run["estimate"].clone();
        for c in 0..3 {
            for key in ["sigma_t", "albedo"] {
                assert_eq!(step["recovered"][key][c], refit[key][c]);
            }
        }
        let got = &step["corrected"];
        assert_bootstrap_step(k, &sim["truth"], &current, &est, &refit, got, (1e-9, 1e-9));
        current = step["corrected"].clone();
    }
    assert_eq!(r["estimate"], current);
    let rel = num(&r["errors"], "sigma_t_relative", 0);
    assert!((rel - (num(&current, "sigma_t", 0) / 60.0 - 1.0)).abs() < 1e-12);
    assert!(r["errors_uncorrected"]["sigma_t_relative"].is_array());

    // --resume reuses both steps and reports the same correction.
    args.push("--resume");
    let again = ok(d, &args);
    assert_stdout_has(
        &again,
        &[
            "bootstrap step 1: reusing",
            "run bootstrap step 2 (ours): reusing",
        ],
    );
    assert_eq!(
        read_json(&d.join("o/result.json"))["estimate"],
        r["estimate"]
    );
    // --overwrite starts again: one step now, and the second step's folder is gone.
    let one_step = [&args[..args.len() - 3], &["--overwrite"]].concat();
    assert_eq!(one_step[one_step.len() - 2], "--bias-correction");
    ok(d, &one_step);
    assert!(d.join("o/bootstrap/step-1/run/result.json").exists());
    assert!(!d.join("o/bootstrap/step-2").exists());
}

/// `experiment accuracy` on a tiny sphere case (2 views of 12², 3 iterations), quiet, into
/// `exp`, with `extra` arguments.
fn tiny_accuracy_args<'a>(extra: &[&'a str]) -> Vec<&'a str> {
    let mut args = vec![
        "experiment",
        "accuracy",
        "--out",
        "exp",
        "--shapes",
        "sphere",
        "--coarse-meshes",
        "--media",
        "1",
        "--views",
        "2",
        "--res",
        "12",
        "--target-spp",
        "4",
        "--iterations",
        "3",
        "--spp",
        "2",
        "-q",
    ];
    args.extend_from_slice(extra);
    args
}

/// Cases as jobs: `--list-jobs` prints one command per case (a dataset and its runs, each random
/// start); `--assemble` before any has run leaves them all out and says so; the printed commands
/// run at the same time as separate processes into one folder (the start's job waits for the
/// dataset the other makes); `--assemble` then tabulates both, with the same estimates as one
/// plain run of the whole experiment; an unknown `--case` is refused with the list.
#[test]
fn experiment_cases_run_as_separate_jobs_and_assemble() {
    let t = tmp();
    let d = t.path();
    let args = tiny_accuracy_args(&["--inits", "1", "--methods", "ours"]);
    let listed = ok(d, &[&args[..], &["--list-jobs"]].concat());
    let lines: Vec<&str> = listed.stdout.lines().collect();
    assert_eq!(lines.len(), 2, "{}", listed.stdout);
    assert!(lines[0].ends_with("--case sphere-m0"), "{}", lines[0]);
    assert!(lines[1].ends_with("--case sphere-m0-init0"), "{}", lines[1]);
    assert!(!listed.stdout.contains("--list-jobs"));
    assert!(!d.join("exp/runs").exists(), "--list-jobs runs nothing");

    let early = ok(d, &[&args[..], &["--assemble"]].concat());
    assert_stdout_has(
        &early,
        &["not finished yet, left out of the tables: sphere-m0, sphere-m0-init0"],
    );

    let jobs: Vec<_> = lines
        .iter()
        .map(|line| {
            std::process::Command::new("sh")
                .args(["-c", line])
                .current_dir(d)
                .stdout(std::process::Stdio::piped())
                .stderr(std::process::Stdio::piped())
                .spawn()
                .expect("the job starts")
        })
        .collect();
    for job in jobs {
        let out = job.wait_with_output().expect("the job ran");
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let table = ok(d, &[&args[..], &["--assemble"]].concat());
    assert_stdout_has(&table, &["| sphere-m0 | ours |", "sphere-m0 init 0"]);
    assert!(!table.stdout.contains("not finished"), "{}", table.stdout);

    let plain: Vec<&str> = args
        .iter()
        .map(|a| if *a == "exp" { "plain" } else { *a })
        .collect();
    ok(d, &plain);
    for run in ["sphere-m0-ours", "sphere-m0-init0"] {
        let est = |root: &str| {
            read_json(&d.join(root).join("runs").join(run).join("result.json"))["estimate"].clone()
        };
        assert_eq!(est("exp"), est("plain"), "{run}");
    }

    let unknown = fails(d, &[&args[..], &["--case", "nope"]].concat());
    assert_stderr_has(
        &unknown,
        &["no case \"nope\"", "sphere-m0-init0", "--list-jobs"],
    );
}

/// `--bias-correction --bias-correction-steps 2`: step 1 renders at the estimate θ̂ and reports
/// 2θ̂ − θ̂₂ (`ours+bc`); step 2 renders at that correction θ₁ and reports θ₁ + θ̂ − θ̂₂'
/// (`ours+bc2`), all in (ln σ_t, α).
#[test]
fn experiment_bias_correction_refits_at_the_estimate() {
    let d = tmp();
    let args = tiny_accuracy_args(&[
        "--inits",
        "0",
        "--methods",
        "ours",
        "--bias-correction",
        "--bias-correction-steps",
        "2",
    ]);
    let run = ok(d.path(), &args);
    assert_stdout_has(
        &run,
        &[
            "| sphere-m0 | ours |",
            "| sphere-m0 | ours+bc |",
            "| sphere-m0 | ours+bc2 |",
            "bias of ours on sphere-m0",
        ],
    );
    let exp = d.path().join("exp");
    let estimate =
        |run: &str| read_json(&exp.join("runs").join(run).join("result.json"))["estimate"].clone();
    let csv = String::from_utf8(read(&exp.join("results.csv"))).unwrap();
    let row = |method: &str| csv_estimate(&csv, "sphere-m0", method);
    let est = estimate("sphere-m0-ours");
    let mut current = est.clone();
    for (step, (data, run, method)) in [
        ("sphere-m0-boot-ours", "sphere-m0-ours-boot", "ours+bc"),
        ("sphere-m0-boot2-ours", "sphere-m0-ours-boot2", "ours+bc2"),
    ]
    .into_iter()
    .enumerate()
    {
        let boot = read_json(&exp.join("data").join(data).join("dataset.json"));
        let got = row(method);
        let refit = estimate(run);
        assert_bootstrap_step(
            step,
            &boot["truth"],
            &current,
            &est,
            &refit,
            &got,
            (1e-4, 1e-5),
        );
        current = got;
    }
}

/// `--inits N --bias-correction`: every random start is corrected too, by a bootstrap recovery
/// that starts where the start's own run started (the same estimator), and the summary has a
/// `random inits+bc` group.
#[test]
fn experiment_corrects_the_random_starts() {
    let d = tmp();
    let args = tiny_accuracy_args(&["--inits", "1", "--methods", "ours", "--bias-correction"]);
    let run = ok(d.path(), &args);
    assert_stdout_has(
        &run,
        &[
            "| sphere-m0 init 0 | ours+bc |",
            "| random inits | 1 |",
            "| random inits+bc | 1 |",
            "bias of ours on sphere-m0-init0",
        ],
    );
    let exp = d.path().join("exp");
    let result = |run: &str| read_json(&exp.join("runs").join(run).join("result.json"));
    let (start, boot) = (
        result("sphere-m0-init0"),
        result("sphere-m0-init0-ours-boot"),
    );
    assert_eq!(boot["initial"], start["initial"]);
    assert_ne!(start["initial"]["sigma_t"][0], 50.0);
    let csv = String::from_utf8(read(&exp.join("results.csv"))).unwrap();
    let got = csv_estimate(&csv, "sphere-m0 init 0", "ours+bc");
    let data = read_json(&exp.join("data/sphere-m0-init0-boot-ours/dataset.json"));
    let est = start["estimate"].clone();
    assert_bootstrap_step(
        0,
        &data["truth"],
        &est,
        &est,
        &boot["estimate"],
        &got,
        (1e-4, 1e-5),
    );
}

#[test]
fn experiment_accuracy_writes_table_and_reuses_its_runs() {
    let d = tmp();
    let args = tiny_accuracy_args(&["--inits", "2", "--methods", "ours,naive"]);
    let first = ok(d.path(), &args);
    // The bias correction is on by default, as in `optimize`: every run gets its `+bc` row.
    assert_stdout_has(
        &first,
        &[
            "| sphere-m0 | ours |",
            "| sphere-m0 | naive |",
            "| sphere-m0 | ours+bc |",
            "| random inits | 2 |",
        ],
    );
    let csv = String::from_utf8(read(&d.path().join("exp/results.csv"))).unwrap();
    assert_eq!(csv.lines().count(), 1 + 2 * (2 + 2), "{csv}");
    assert!(d.path().join("exp/inits.png").exists());
    for run in [
        "sphere-m0-ours",
        "sphere-m0-naive",
        "sphere-m0-init0",
        "sphere-m0-init1",
    ] {
        let r = read_json(&d.path().join("exp/runs").join(run).join("result.json"));
        assert_eq!(r["iterations"], 3, "{run}");
    }
    // A second run reuses the datasets and the finished runs and prints the same table.
    let second = ok(d.path(), &args);
    assert_stdout_has(&second, &["dataset sphere-m0: reusing", "reusing"]);
    let table = |s: &str| {
        s.lines()
            .filter(|l| l.starts_with('|'))
            .collect::<Vec<_>>()
            .join("\n")
    };
    assert_eq!(table(&first.stdout), table(&second.stdout));
    // Runs made with another schedule are not reused (nor continued): a clear error instead.
    let mut other = args.to_vec();
    other.extend(["--albedo-warmup", "1"]);
    let bad = fails(d.path(), &other);
    assert_stderr_has(&bad, &["other settings", "sphere-m0-ours"]);
    // So are runs made with another projection reach; the header names the learned settings.
    assert_stdout_has(
        &first,
        &["son24 projection (reach 8σ_n)", "half-space exit law"],
    );
    let mut other = args.to_vec();
    other.extend(["--max-dist-scale", "3"]);
    let bad = fails(d.path(), &other);
    assert_stderr_has(&bad, &["other settings", "learned"]);
    // The random initialisations go to the case named by --inits-case, which must exist.
    let mut other = args.to_vec();
    other.extend(["--inits-case", "sphere-m7"]);
    let bad = fails(d.path(), &other);
    assert_stderr_has(&bad, &["--inits-case", "sphere-m7", "sphere-m0"]);
    // Unknown shapes and methods are refused before any work.
    let bad = fails(
        d.path(),
        &["experiment", "accuracy", "--out", "x", "--shapes", "teapot"],
    );
    assert_stderr_has(&bad, &["teapot"]);
    let bad = fails(
        d.path(),
        &["experiment", "accuracy", "--out", "x", "--methods", "magic"],
    );
    assert_stderr_has(&bad, &["magic"]);
    let bad = fails(
        d.path(),
        &[
            "experiment",
            "accuracy",
            "--out",
            "x",
            "--shapes",
            "blob:colour=1",
        ],
    );
    assert_stderr_has(&bad, &["--shapes", "colour", "amplitude"]);
    assert!(!d.path().join("x").exists(), "refused before any work");
}

/// `--shapes NAME:KEY=VALUE`: the case is named after the parameters and its dataset is
/// rendered with them.
#[test]
fn experiment_takes_shape_parameters() {
    let d = tmp();
    let mut args = tiny_accuracy_args(&["--inits", "0", "--methods", "ours"]);
    let at = args.iter().position(|a| *a == "sphere").unwrap();
    args[at] = "sphere:radius=0.3:subdivisions=3";
    let out = ok(d.path(), &args);
    let case = "sphere-radius-0.3-subdivisions-3-m0";
    assert_stdout_has(&out, &[&format!("| {case} | ours |")]);
    let data = read_json(&d.path().join("exp/data").join(case).join("dataset.json"));
    assert_eq!(data["shape"]["radius"], 0.3, "{}", data["shape"]);
    assert_eq!(data["shape"]["subdivisions"], 3, "{}", data["shape"]);
}

/// `render --model learned --as-dataset` makes a dataset of the learned model's own images (its
/// truth the rendered medium, its renderer named), and refuses to replace it.
#[test]
fn learned_targets_as_a_dataset() {
    let t = tmp();
    let d = t.path();
    make_dataset(d, "ds", "2", "12", &["--sigma-t", "60", "--albedo", "0.9"]);
    let render = [
        "-q",
        "render",
        "ds",
        "--model",
        "learned",
        "--spp",
        "2",
        "--seed",
        "3",
        "--out",
        "lt",
        "--as-dataset",
    ];
    ok(d, &render);
    let j = read_json(&d.join("lt/dataset.json"));
    assert_eq!(j["truth"], read_json(&d.join("ds/dataset.json"))["truth"]);
    assert!(
        j["render"]["renderer"]
            .as_str()
            .unwrap()
            .contains("learned BSSRDF"),
        "{}",
        j["render"]
    );
    assert_eq!(j["views"].as_array().unwrap().len(), 2);
    let again = fails(d, &render);
    assert_stderr_has(&again, &["lt", "--overwrite"]);
}

/// `optimize --view-subset`: only the named views are fitted (renumbered for the optimiser,
/// named by their dataset index in `final/`), a resume keeps them, and bad lists are clear
/// errors.
#[test]
fn optimize_fits_a_subset_of_the_views() {
    let t = tiny_optimize_dataset("3");
    let d = t.path();
    let opt = [&TINY_OPTIMIZE[..], &["--view-subset", "2,0"]].concat();
    ok(d, &opt);
    let res = read_json(&d.join("o/result.json"));
    assert_eq!(
        res["config"]["view_subset"],
        serde_json::json!([2, 0]),
        "{res}"
    );
    assert!(d.join("o/final/view_002.png").exists());
    assert!(d.join("o/final/view_000.png").exists());
    assert!(!d.join("o/final/view_001.png").exists());
    let ckpt = read_json(&d.join("o/checkpoint.json"));
    for h in ckpt["history"].as_array().unwrap() {
        assert!(h["views"][0].as_u64().unwrap() < 2, "{h}");
    }
    let mut resume: Vec<&str> = TINY_OPTIMIZE.to_vec();
    resume[6] = "4"; // --iterations 4
    resume.push("--resume");
    ok(d, &resume);
    let res = read_json(&d.join("o/result.json"));
    assert_eq!(res["iterations"], 4);
    assert_eq!(res["config"]["view_subset"], serde_json::json!([2, 0]));
    let other = fails(d, &[&resume[..], &["--view-subset", "1"]].concat());
    assert_stderr_has(&other, &["--view-subset", "[2, 0]"]);
    for (list, msg) in [("3", "there is no view 3"), ("0,0", "named twice")] {
        let mut bad: Vec<&str> = TINY_OPTIMIZE.to_vec();
        bad[4] = "o2";
        bad.extend(["--view-subset", list]);
        assert_stderr_has(&fails(d, &bad), &[msg]);
    }
}

/// A flash capture (the light next to each camera): `optimize` reports 95 % intervals, a
/// status and the consistency check in `result.json`, and says in plain words that σ_t is not
/// determined and which capture would determine it.
#[test]
fn flash_capture_says_sigma_t_is_not_determined() {
    let t = tmp();
    let d = t.path();
    make_dataset(
        d,
        "ds",
        "4",
        "12",
        &[
            "--light",
            "attached",
            "--light-offset",
            "0.05,0.05,0",
            "--sigma-t",
            "60",
            "--albedo",
            "0.9",
        ],
    );
    let r = ok(d, &TINY_OPTIMIZE);
    assert_stdout_has(
        &r,
        &[
            "95 % intervals",
            "σ_t is NOT determined",
            "light beside or behind the object",
            "consistency",
        ],
    );
    let res = read_json(&d.join("o/result.json"));
    for key in ["sigma_t", "albedo"] {
        let i = res["interval95"][key].as_array().unwrap();
        assert_eq!(i.len(), 3, "{res}");
        let det = res["determined"][key].as_array().unwrap();
        assert_eq!(det.len(), 3, "{res}");
    }
    assert_eq!(
        res["determined"]["sigma_t"],
        serde_json::json!([false, false, false])
    );
    assert!(res["status"].is_string(), "{res}");
    assert!(res["consistency"]["mean_ratio"].is_array(), "{res}");
    assert_eq!(res["complete"], true);
    // The learned model alone also measures the tracer's own sensitivity along the valley,
    // which widens the interval where the model is surer than the images.
    let mut plain = TINY_OPTIMIZE.to_vec();
    plain[4] = "o2";
    plain.extend(["--refine", "0", "--no-bias-correction"]);
    let r = ok(d, &plain);
    assert_stdout_has(&r, &["sensitivity to σ_t along the σ_t–α valley"]);
    let res = read_json(&d.join("o2/result.json"));
    let ratio = res["sensitivity"]["ratio"].as_array().unwrap();
    assert!(ratio.iter().all(|r| r.as_f64().unwrap() >= 1.0), "{res}");
    // Long enough for finite intervals: the advice says which capture would determine σ_t. Every
    // view is a flash, so it renders a view lit from the side and one from behind at the
    // estimate, and counts the views of each kind that would.
    let mut longer = TINY_OPTIMIZE.to_vec();
    longer[4] = "o3";
    longer[6] = "40"; // --iterations
    longer[8] = "16"; // --spp
    let r = ok(d, &longer);
    assert_stdout_has(
        &r,
        &[
            "What would determine σ_t with this rig",
            "4 views with the light within 30° of the camera (a flash)",
            "with the light moved 90° round the object",
        ],
    );
    let res = read_json(&d.join("o3/result.json"));
    let advice = &res["advice"]["sigma_t"];
    assert_eq!(advice["groups"].as_array().unwrap().len(), 1, "{advice}");
    assert_eq!(
        advice["groups"][0]["views"],
        serde_json::json!([0, 1, 2, 3])
    );
    let angles: Vec<f64> = advice["candidates"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c["angle_deg"].as_f64().unwrap())
        .collect();
    assert_eq!(angles, [90.0, 150.0], "{advice}");
    for c in 0..3 {
        let need = advice["need"][c].as_f64().unwrap();
        assert!(need > 1.0, "{advice}");
    }
}

/// `-q experiment robustness --quick --suite SUITE --out rb`, then `rest`.
fn quick_robustness<'a>(suite: &'a str, rest: &[&'a str]) -> Vec<&'a str> {
    let head = [
        "-q",
        "experiment",
        "robustness",
        "--quick",
        "--suite",
        suite,
    ];
    [&head[..], &["--out", "rb"], rest].concat()
}

/// `experiment robustness --quick` (`--suite index-matched`, the default) on four of its twelve
/// cases, one per capture, covering its three sizes and three shapes: each is rendered,
/// recovered and tabulated (Markdown and CSV, with intervals, consistency and the learned
/// model's own error at the truth); a second invocation reuses the datasets and runs; Mitsuba
/// targets without a usable script are a clear error.
#[test]
fn experiment_robustness_quick_tabulates_every_case_and_resumes() {
    let t = tmp();
    let d = t.path();
    let spot = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../data/meshes/spot.obj");
    let spot = spot.to_str().unwrap();
    let cases = "flash-5-blob,fixed-15-spot,turntable-50-torus,backlit-50-spot";
    let args = quick_robustness("index-matched", &["--cases", cases, "--mesh", spot]);
    let r = ok(d, &args);
    assert_stdout_has(&r, &["calibration", "QUICK", "model at truth ÷ targets"]);
    let csv = testkit::CsvTable::read(d.join("rb/robustness.csv"));
    let rows: Vec<&str> = csv.text.lines().skip(1).collect();
    assert_eq!(csv.rows.len(), 4 * 3, "{}", csv.text);
    let col = |name: &str| csv.column(name);
    for (row, f) in rows.iter().zip(&csv.rows) {
        assert_eq!(f[col("targets")], "volpath", "{row}");
        for name in [
            "sigma_t_est",
            "albedo_est",
            "model_ratio",
            "consistency_ratio",
        ] {
            let v: f64 = f[col(name)].parse().unwrap();
            assert!(v.is_finite() && v > 0.0, "{name} in {row}");
        }
        // The tracer's curvature along the valley over the model's: not measured (NaN) where
        // the defaults' refinement made the tracer the final model.
        let v: f64 = f[col("valley_curvature")].parse().unwrap();
        assert!(v.is_nan(), "valley_curvature in {row}");
    }
    for capture in ["flash", "fixed", "turntable", "backlit"] {
        assert!(
            rows.iter().filter(|r| r.contains(capture)).count() == 3,
            "{capture}"
        );
    }
    assert!(d.join("rb/robustness.md").exists());
    let again = ok(d, &args);
    assert_eq!(
        again.stdout.matches("reusing").count(),
        4,
        "{}",
        again.stdout
    );
    let fails_ = fails(
        d,
        &[
            &args[..],
            &["--targets", "mitsuba", "--mitsuba-script", "no-such.py"],
        ]
        .concat(),
    );
    assert_stderr_has(
        &fails_,
        &["--targets mitsuba", "no-such.py", "pip install mitsuba"],
    );
}

/// `experiment robustness --suite dielectric`: a case with a smooth boundary and one with a rough
/// boundary at 300 mean free paths are rendered with the boundary and the phase function their
/// datasets state, recovered with them (not with an assumed index-matched, isotropic object),
/// and tabulated with their boundary and g. With the tracer as the model: the learned model
/// would first simulate its walk tables at each case's (g, η), one to two minutes per case.
#[test]
fn experiment_robustness_dielectric_cases_state_and_use_their_object() {
    let t = tmp();
    let d = t.path();
    let cases = "flash-15-blob-smooth1.5-g0.3,fixed-300-blob-rough1.33a0.1-g0.7";
    let args = quick_robustness("dielectric", &["--cases", cases, "--model", "volpath"]);
    ok(d, &args);
    let csv = testkit::CsvTable::read(d.join("rb/robustness.csv"));
    assert_eq!(csv.rows.len(), 2 * 3, "{}", csv.text);
    for f in &csv.rows {
        let rough = f[csv.column("case")].contains("rough");
        let (eta, roughness, g) = if rough {
            ("1.33", "0.1", "0.7")
        } else {
            ("1.5", "0", "0.3")
        };
        assert_eq!(f[csv.column("eta")], eta);
        assert_eq!(f[csv.column("roughness")], roughness);
        assert_eq!(f[csv.column("g")], g);
        assert_eq!(f[csv.column("mfp")], if rough { "300" } else { "15" });
    }
    let ds = read_json(&d.join("rb/data/fixed-300-blob-rough1.33a0.1-g0.7-r0/dataset.json"));
    assert_eq!(ds["object"]["boundary"]["type"], "dielectric", "{ds}");
    let f32_at = |v: &serde_json::Value| v.as_f64().map(|x| x as f32);
    assert_eq!(f32_at(&ds["object"]["boundary"]["roughness"]), Some(0.1));
    assert_eq!(f32_at(&ds["object"]["phase"]["g"]), Some(0.7));
    let res = read_json(&d.join("rb/runs/fixed-300-blob-rough1.33a0.1-g0.7-r0/result.json"));
    assert_eq!(res["object"]["source"], "dataset", "{res}");
    let boundary = serde_json::json!({ "type": "dielectric", "eta": 1.33, "roughness": 0.1 });
    assert_eq!(res["object"]["boundary"], boundary, "{res}");
    assert_eq!(res["object"]["phase"]["g"], 0.7, "{res}");
    assert_eq!(
        res["object"]["not_modelled"],
        serde_json::json!([]),
        "{res}"
    );
}

/// `--starts 3`: three short runs from σ_t = init/3, init, 3·init; the run starts from the
/// estimate of the one with the lowest loss, and result.json lists them all.
#[test]
fn multi_start_runs_from_the_best_start() {
    let t = tiny_optimize_dataset("2");
    let d = t.path();
    let r = ok(
        d,
        &[
            &TINY_OPTIMIZE[..],
            &[
                "--starts",
                "3",
                "--no-bias-correction",
                "--uncertainty-views",
                "0",
            ],
        ]
        .concat(),
    );
    assert_stdout_has(
        &r,
        &["start 0 of 3", "start 2 of 3", "loss over the last third"],
    );
    let res = read_json(&d.join("o/result.json"));
    let starts = res["starts"]["starts"].as_array().unwrap();
    assert_eq!(starts.len(), 3);
    let inits: Vec<f64> = starts
        .iter()
        .map(|s| s["init_sigma_t"][0].as_f64().unwrap())
        .collect();
    assert!(
        (inits[0] - 50.0 / 3.0).abs() < 1e-3 && inits[1] == 50.0 && (inits[2] - 150.0).abs() < 1e-3
    );
    let best = res["starts"]["chosen"].as_u64().unwrap() as usize;
    let losses: Vec<f64> = starts.iter().map(|s| s["loss"].as_f64().unwrap()).collect();
    assert!(losses.iter().all(|&l| l >= losses[best]), "{losses:?}");
    for c in 0..3 {
        let init = res["config"]["init"]["sigma_t"][c].as_f64().unwrap();
        let chosen = starts[best]["estimate"]["sigma_t"][c].as_f64().unwrap();
        assert!((init - chosen).abs() <= 1e-5 * chosen, "{init} vs {chosen}");
    }
    assert!(d.join("o/starts/starts.json").exists());
}

/// Negative numbers reach our own checks rather than the argument parser: a negative initial
/// σ_t is a domain error naming the field, and a negative anisotropy is accepted where it is
/// valid.
#[test]
fn negative_numbers_reach_the_domain_checks() {
    let t = tmp();
    let d = t.path();
    make_dataset(d, "ds", "2", "8", &["--g", "-0.3"]);
    let ds = read_json(&d.join("ds/dataset.json"));
    assert!(ds.to_string().contains("-0.3"), "{ds}");
    let bad = fails(d, &[&TINY_OPTIMIZE[..], &["--init-sigma-t", "-5"]].concat());
    assert_stderr_has(&bad, &["init.sigma_t", "-5", "must be positive"]);
}

/// `optimize --model volpath` runs the volumetric baseline through the same loop and reports:
/// its estimator is `ad`, the configuration records the model, the re-renders and intervals are
/// written, and no bias correction runs; a learned-model estimator with it (or `ad` with the
/// learned model) is refused, naming the model's estimators. The same for `--model dipole`.
#[test]
fn optimize_with_the_volumetric_model_and_invalid_pairs() {
    let t = tiny_optimize_dataset("2");
    let d = t.path();
    let args = [&TINY_OPTIMIZE[..], &["--model", "volpath"]].concat();
    let r = ok(d, &args);
    // No bias correction: the tracer is the correction's own simulator.
    assert!(!r.stdout.contains("bootstrap"));
    assert!(!d.join("o/bootstrap").exists());
    let res = read_json(&d.join("o/result.json"));
    assert_eq!(res["config"]["model"], "volpath");
    assert_eq!(res["config"]["method"], "ad");
    // The dataset's own depth (`make_dataset` renders at the default, 32).
    assert_eq!(res["config"]["volpath_max_depth"], 32);
    assert!(res["interval95"]["sigma_t"][0][0].as_f64().unwrap() > 0.0);
    assert!(res.get("sensitivity").is_none_or(Value::is_null));
    assert!(d.join("o/final/view_000.exr").is_file());
    // The same command into a fresh folder, with an invalid model × estimator pair.
    let mut fresh = TINY_OPTIMIZE.to_vec();
    fresh[4] = "o2";
    let bad = [&fresh[..], &["--model", "volpath", "--estimator", "ours"]].concat();
    assert_stderr_has(&fails(d, &bad), &["volpath", "no estimator \"ours\"", "ad"]);
    let bad = [&fresh[..], &["--estimator", "ad"]].concat();
    assert_stderr_has(
        &fails(d, &bad),
        &["learned", "ours, ours-alpha-offsets, naive, fd"],
    );
    // The planar dipole through the same loop.
    fresh[4] = "o3";
    ok(d, &[&fresh[..], &["--model", "dipole"]].concat());
    let res = read_json(&d.join("o3/result.json"));
    assert_eq!(res["config"]["model"], "dipole");
    assert_eq!(res["config"]["method"], "ad");
    assert!(res["interval95"]["sigma_t"][0][0].as_f64().unwrap() > 0.0);
    assert!(!d.join("o3/bootstrap").exists());
    assert!(d.join("o3/final/view_000.exr").is_file());
    fresh[4] = "o4";
    // `--method`, the option's former name, still parses (hidden from the help).
    let bad = [&fresh[..], &["--model", "dipole", "--method", "naive"]].concat();
    assert_stderr_has(
        &fails(d, &bad),
        &["dipole", "no estimator \"naive\"", "ad, fd"],
    );
    // A volumetric refinement of the learned fit: its last iteration with the tracer, and no
    // bias correction after it.
    fresh[4] = "o5";
    ok(d, &[&fresh[..], &["--refine", "1"]].concat());
    let res = read_json(&d.join("o5/result.json"));
    assert_eq!(res["config"]["refine_iterations"], 1);
    assert_eq!(
        res["config"]["model"],
        Value::Null,
        "the learned model is the run's model"
    );
    assert!(res["config"]["volpath_max_depth"].as_u64().unwrap() > 0);
    assert!(!d.join("o5/bootstrap").exists());
    assert!(res.get("sensitivity").is_none_or(Value::is_null));
    let bad = [&fresh[..], &["--refine", "4", "--overwrite"]].concat();
    assert_stderr_has(&fails(d, &bad), &["refine_iterations", "3 iterations"]);
}

/// `experiment timing --quick`: one row per model × estimator with a positive time, the paper's
/// method at twice the samples (as its Table 1) and `optimize`'s defaults; the paper's figures
/// beside ours and the PRB row absent without Mitsuba; the tables are written; a second run
/// measures nothing again; other settings in the same folder are refused.
#[test]
fn experiment_timing_quick_times_every_model_and_estimator() {
    let t = tmp();
    let d = t.path();
    let r = ok(d, &["-q", "experiment", "timing", "--quick", "--out", "tm"]);
    let csv = testkit::CsvTable::read(d.join("tm/timing.csv"));
    assert_eq!(
        csv.keys(3),
        [
            "learned ours 4",
            "learned ours-alpha-offsets 4",
            "learned naive 4",
            "learned fd 4",
            "volpath ad 4",
            "volpath fd 4",
            "dipole ad 4",
            "dipole fd 4",
            "learned ours 8",
            "learned defaults 4"
        ]
    );
    for l in &csv.rows {
        let s: f64 = l[3].parse().unwrap();
        assert!(s > 0.0 && s.is_finite(), "{l:?}");
    }
    assert!(r.stdout.contains("1.40 (ours)") && r.stdout.contains("QUICK"));
    assert!(
        r.stdout
            .contains("`optimize`'s defaults**: learned, then volpath")
    );
    assert!(!r.stdout.contains("PRB"));
    assert!(d.join("tm/timing.md").is_file());
    let again = ok(d, &["-q", "experiment", "timing", "--quick", "--out", "tm"]);
    assert!(!again.stdout.contains("s/it\n"), "{}", again.stdout);
    assert_eq!(
        std::fs::read_to_string(d.join("tm/timing.csv")).unwrap(),
        csv.text
    );
    let other = fails(d, &["-q", "experiment", "timing", "--out", "tm"]);
    assert_stderr_has(&other, &["another"]);
}

/// `experiment gradients --quick`: a row per scene × estimator (ours, naive, and the differences
/// as the reference, which agree with themselves), the derivative images in false colour, and a
/// second run that reuses the images.
#[test]
fn experiment_gradients_quick_compares_estimators_with_differences() {
    let t = tmp();
    let d = t.path();
    ok(
        d,
        &["-q", "experiment", "gradients", "--quick", "--out", "g"],
    );
    let csv = testkit::CsvTable::read(d.join("g/gradients.csv"));
    let rows = &csv.rows;
    assert_eq!(
        csv.keys(2),
        [
            "cone ours",
            "cone naive",
            "cone fd",
            "blob ours",
            "blob naive",
            "blob fd"
        ]
    );
    for r in rows {
        let v: Vec<f64> = r[2..6].iter().map(|x| x.parse().unwrap()).collect();
        assert!(v.iter().all(|x| x.is_finite()), "{r:?}");
        if r[1] == "fd" {
            assert_eq!(v, [0.0, 1.0, 0.0, 1.0]);
        }
    }
    for f in [
        "cone/ours_d_sigma_t.png",
        "blob/naive_d_albedo.exr",
        "gradients.md",
    ] {
        assert!(d.join("g").join(f).is_file(), "{f}");
    }
    let again = ok(
        d,
        &["-q", "experiment", "gradients", "--quick", "--out", "g"],
    );
    assert!(again.stdout.contains("reusing"), "{}", again.stdout);
}

/// `experiment planar --quick`: ours, naive and the dipole on three shapes, the table holding
/// every method, an error figure (PNG and SVG) and the side-by-side re-renders per case with
/// their comparison against the truth's, and the dipole's runs made with the dipole model.
#[test]
fn experiment_planar_quick_compares_ours_naive_and_the_dipole() {
    let t = tmp();
    let d = t.path();
    ok(d, &["-q", "experiment", "planar", "--quick", "--out", "p"]);
    let csv = std::fs::read_to_string(d.join("p/results.csv")).unwrap();
    for m in ["ours", "naive", "dipole"] {
        assert_eq!(
            csv.lines()
                .filter(|l| l.contains(&format!(",{m},")))
                .count(),
            3,
            "{m}:\n{csv}"
        );
    }
    assert!(!csv.contains("+bc"));
    for case in ["blob-m0", "torus-m0", "cone-m0"] {
        for f in [
            format!("planar-{case}.png"),
            format!("planar-{case}.svg"),
            format!("renders-{case}.png"),
        ] {
            assert!(d.join("p").join(&f).is_file(), "{f}");
        }
    }
    let res = read_json(&d.join("p/runs/cone-m0-dipole/result.json"));
    assert_eq!(res["config"]["model"], "dipole");
    // The re-renders: per case the noise floor and each method against the truth's, finite.
    let rr = testkit::CsvTable::read(d.join("p/rerenders.csv"));
    assert_eq!(rr.rows.len(), 3 * 4, "{}", rr.text);
    for case in ["blob-m0", "torus-m0", "cone-m0"] {
        for m in ["truth (another seed)", "ours", "naive", "dipole"] {
            let row = rr
                .rows
                .iter()
                .find(|r| r[0] == case && r[1] == m)
                .unwrap_or_else(|| panic!("{case} {m}:\n{}", rr.text));
            for v in &row[3..12] {
                let v: f64 = v.parse().unwrap();
                assert!(v.is_finite() && v >= 0.0, "{case} {m}: {v}");
            }
        }
    }
    assert!(d.join("p/rerenders/cone-m0-dipole.exr").is_file());
    assert!(d.join("p/rerenders/cone-m0-dipole.json").is_file());
}

/// `experiment inits --quick`: one case with `ours`, three random starts in the table, the
/// trajectories and the band figure (PNG and SVG).
#[test]
fn experiment_inits_quick_draws_the_band_of_the_starts() {
    let t = tmp();
    let d = t.path();
    ok(d, &["-q", "experiment", "inits", "--quick", "--out", "i"]);
    let csv = std::fs::read_to_string(d.join("i/results.csv")).unwrap();
    assert_eq!(
        csv.lines().filter(|l| l.contains(" init ")).count(),
        3,
        "{csv}"
    );
    for f in ["inits.png", "inits-band.png", "inits-band.svg", "table.md"] {
        assert!(d.join("i").join(f).is_file(), "{f}");
    }
    let svg = std::fs::read_to_string(d.join("i/inits-band.svg")).unwrap();
    assert!(svg.contains("start 2") && svg.contains("mean"));
}

/// `experiment volumetric --quick`: three runs (ours, the volumetric model at the base and at
/// four times the samples) of σ_t alone with α held at 0.9 and grey, the table and the figure.
#[test]
fn experiment_volumetric_quick_runs_sigma_t_alone() {
    let t = tmp();
    let d = t.path();
    ok(
        d,
        &["-q", "experiment", "volumetric", "--quick", "--out", "v"],
    );
    let csv = testkit::CsvTable::read(d.join("v/volumetric.csv"));
    assert_eq!(csv.keys(2), ["ours 2", "volumetric 2", "volumetric 8"]);
    for dir in ["ours-2spp", "volumetric-2spp", "volumetric-8spp"] {
        let res = read_json(&d.join("v/runs").join(dir).join("result.json"));
        let albedo = &res["estimate"]["albedo"];
        let sigma = &res["estimate"]["sigma_t"];
        for c in 0..3 {
            assert!(
                (albedo[c].as_f64().unwrap() - 0.9).abs() < 1e-6,
                "{dir}: {albedo}"
            );
            assert_eq!(sigma[c], sigma[0], "{dir}: grey");
        }
    }
    assert!(d.join("v/volumetric.png").is_file() && d.join("v/volumetric.svg").is_file());
}

/// `experiment prb --quick` without Mitsuba: ours and the volumetric baseline, the table with
/// their errors and s/it, the four-panel figure; a second run reuses both runs.
#[test]
fn experiment_prb_quick_compares_ours_with_the_volumetric_baseline() {
    let t = tmp();
    let d = t.path();
    ok(d, &["-q", "experiment", "prb", "--quick", "--out", "r"]);
    let csv = testkit::CsvTable::read(d.join("r/prb.csv"));
    assert_eq!(csv.keys(1), ["ours", "volumetric"]);
    for l in &csv.rows {
        let f: Vec<f64> = l[1..4].iter().map(|x| x.parse().unwrap()).collect();
        assert!(f.iter().all(|x| x.is_finite() && *x >= 0.0), "{l:?}");
    }
    assert!(d.join("r/prb.png").is_file() && d.join("r/prb.svg").is_file());
    let again = ok(d, &["-q", "experiment", "prb", "--quick", "--out", "r"]);
    assert_eq!(
        again.stdout.matches("reusing").count(),
        2,
        "{}",
        again.stdout
    );
}

/// A Mitsuba 3 scene folder (the scene file `optimize` exported, with the dataset's images) is a
/// dataset: a recovery from it renders with the boundary and phase function the scene states.
#[test]
fn a_mitsuba_scene_folder_is_recovered_with_its_stated_physics() {
    let t = tmp();
    let d = t.path();
    make_dataset(
        d,
        "ds",
        "2",
        "12",
        &[
            "--light",
            "fixed",
            "--eta",
            "1.3",
            "--roughness",
            "0.1",
            "--g",
            "0.5",
        ],
    );
    // The tracer as the model: the learned model's tables for this g and η would be simulated
    // first (tens of seconds), which is not what this test is about.
    let first = [&TINY_OPTIMIZE[..], &["--model", "volpath"]].concat();
    ok(d, &first);
    let mx = d.join("mx");
    std::fs::create_dir(&mx).unwrap();
    for f in ["scene.xml", "object.ply"] {
        std::fs::copy(d.join("o/mitsuba").join(f), mx.join(f)).unwrap();
    }
    for n in exr_names(2) {
        std::fs::copy(d.join("ds").join(&n), mx.join(&n)).unwrap();
    }
    let mut opt = first.clone();
    (opt[2], opt[4]) = ("mx", "o2");
    ok(d, &opt);
    let r = read_json(&d.join("o2/result.json"));
    let o = &r["object"];
    assert_eq!(o["source"], "dataset", "{o}");
    assert_eq!(o["boundary"]["eta"], 1.3, "{o}");
    assert_eq!(o["boundary"]["roughness"], 0.1, "{o}");
    assert_eq!(o["phase"]["g"], 0.5, "{o}");
    // The scene states no truth: the images are what σ_t and α come from.
    assert!(r.get("truth").is_none_or(|t| t.is_null()), "{r}");
}

/// `--free g` needs the tracer in the run's last iterations and says so with the flags to
/// change; `--init-g` needs `--free g`.
#[test]
fn optimize_free_g_is_refused_where_no_model_differentiates_g() {
    let t = tmp();
    let d = t.path();
    make_dataset(d, "ds", "2", "12", &["--sigma-t", "60", "--albedo", "0.9"]);
    let learned = [&TINY_OPTIMIZE[..], &["--free", "g", "--refine", "0"]].concat();
    assert_stderr_has(
        &fails(d, &learned),
        &[
            "--free g with model learned",
            "fix: keep the refinement (--refine above 0)",
        ],
    );
    let dipole = [&TINY_OPTIMIZE[..], &["--free", "g", "--model", "dipole"]].concat();
    assert_stderr_has(&fails(d, &dipole), &["the dipole does not differentiate g"]);
    let start = [&TINY_OPTIMIZE[..], &["--init-g", "0.5"]].concat();
    assert_stderr_has(
        &fails(d, &start),
        &[
            "--init-g 0.5 without --free g",
            "fix: add --free g or drop --init-g",
        ],
    );
}

/// `--free light-scale` is refused with the learned model's bias correction, naming the fix;
/// `--init-light-scale` needs it.
#[test]
fn optimize_free_light_scale_is_refused_with_the_bias_correction() {
    let t = tmp();
    let d = t.path();
    make_dataset(d, "ds", "2", "12", &["--sigma-t", "60", "--albedo", "0.9"]);
    let corrected = [
        &TINY_OPTIMIZE[..],
        &["--free", "light-scale", "--refine", "0"],
    ]
    .concat();
    assert_stderr_has(
        &fails(d, &corrected),
        &[
            "--free light-scale with the bias correction",
            "fix: keep the refinement (--refine above 0)",
        ],
    );
    let start = [&TINY_OPTIMIZE[..], &["--init-light-scale", "2"]].concat();
    assert_stderr_has(
        &fails(d, &start),
        &["--init-light-scale 2 without --free light-scale"],
    );
}

/// A measured medium in real units: `dataset --measured marble --units cm` renders Jensen et
/// al.'s marble (σ_t in 1/cm: the sphere is about 1 cm across), the dataset states its unit, and `optimize` reports the estimate
/// in mm⁻¹ with the nearest measured media; an unknown name lists the names.
#[test]
fn a_measured_medium_in_centimetres_is_reported_in_real_units() {
    let t = tmp();
    let d = t.path();
    // g = 0: the learned model's walk tables for another g would cost the test a minute.
    let r = ok(
        d,
        &[
            "dataset",
            "--shape",
            "sphere",
            "--views",
            "2",
            "--res",
            "12",
            "--spp",
            "4",
            "--out",
            "ds",
            "--measured",
            "marble",
            "--units",
            "cm",
            "--g",
            "0",
        ],
    );
    // Marble's σ_s' + σ_a at g = 0: σ_t = 10 × (2.19 + 0.0021) cm⁻¹, ….
    assert_stdout_has(&r, &["truth: σ_t = (21.921, 26.241, 30.071) 1/cm"]);
    let ds = read_json(&d.join("ds/dataset.json"));
    assert_eq!(ds["length_unit"], "cm");
    assert!(
        ds["units"].as_str().unwrap().starts_with("lengths in cm"),
        "{}",
        ds["units"]
    );
    let r = ok(d, &TINY_OPTIMIZE);
    // A dataset with a unit starts σ_t at a typical real material's: 1.50 mm⁻¹ = 15.0 cm⁻¹.
    assert_stderr_has(&r, &["σ_t starts at 15.009 per cm"]);
    let start = read_json(&d.join("o/result.json"))["config"]["init"]["sigma_t"].clone();
    assert!(
        (start[0].as_f64().unwrap() - 15.009).abs() < 1e-3,
        "{start}"
    );
    assert_stdout_has(
        &r,
        &[
            "in real units (lengths in cm): σ_t = (",
            "nearest measured media",
        ],
    );
    let res = read_json(&d.join("o/result.json"));
    assert_eq!(res["real_units"]["length_unit"], "cm");
    assert_eq!(
        res["real_units"]["nearest_measured"]
            .as_array()
            .unwrap()
            .len(),
        3
    );
    let e = fails(
        d,
        &[
            "dataset",
            "--shape",
            "sphere",
            "--measured",
            "jade",
            "--units",
            "mm",
            "--out",
            "x",
        ],
    );
    assert_stderr_has(&e, &["\"jade\"", "marble", "regular-milk"]);
    let e = fails(
        d,
        &[
            "dataset",
            "--shape",
            "sphere",
            "--measured",
            "marble",
            "--out",
            "x",
        ],
    );
    assert_stderr_has(&e, &["--units"]);
}

/// `--mesh-error`: the same run with the mesh's error stated has intervals at least as wide in
/// every channel (C_capture is added to the same covariance), says so in `result.json` and in
/// its summary; a fraction outside (0, 0.1] is refused naming the option.
#[test]
fn a_stated_mesh_error_widens_the_intervals() {
    let t = tiny_optimize_dataset("2");
    let d = t.path();
    let sd = |dir: &str| -> (Vec<f64>, serde_json::Value) {
        let res = read_json(&d.join(dir).join("result.json"));
        let sd = (0..3)
            .map(|c| res["uncertainty"]["sd_ln_sigma_t"][c].as_f64().unwrap())
            .collect();
        (sd, res["uncertainty"]["mesh_error"].clone())
    };
    ok(
        d,
        &[&TINY_OPTIMIZE[..], &["--uncertainty-views", "2"]].concat(),
    );
    let (plain, none) = sd("o");
    assert!(none.is_null(), "{none}");
    // The same run into `m` (TINY_OPTIMIZE's `--out o` replaced).
    let into_m: Vec<&str> = TINY_OPTIMIZE
        .iter()
        .map(|&a| if a == "o" { "m" } else { a })
        .collect();
    let r = ok(
        d,
        &[
            &into_m[..],
            &["--uncertainty-views", "2", "--mesh-error", "0.01"],
        ]
        .concat(),
    );
    assert_stdout_has(&r, &["a mesh error of 1.00 % of its diagonal"]);
    let (wide, stated) = sd("m");
    assert_eq!(stated["fraction"], 0.01);
    assert_eq!(stated["draws"], 8);
    for c in 0..3 {
        assert!(
            wide[c] >= plain[c],
            "channel {c}: {wide:?} against {plain:?}"
        );
    }
    assert!(
        wide.iter().zip(&plain).any(|(w, p)| w > p),
        "{wide:?} {plain:?}"
    );
    for bad in ["0", "0.5", "x"] {
        let e = fails(d, &[&TINY_OPTIMIZE[..], &["--mesh-error", bad]].concat());
        assert_stderr_has(&e, &["--mesh-error", "0.002"]);
    }
}
