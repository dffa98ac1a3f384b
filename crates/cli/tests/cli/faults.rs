//! Faults during long runs: two runs on one output folder, `kill -9` at random moments, a write
//! that fails (a file-size limit standing in for a full disk), and `--resume` with other settings.
//! Each test is deterministic in what it asserts; the kill times come from a fixed list.

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use super::helpers::*;

/// `optimize` of the dataset `ds` into `out` for `iterations` iterations at 1 spp, a checkpoint
/// after every iteration, without the work after the loop.
fn optimize_args<'a>(out: &'a str, iterations: &'a str) -> Vec<&'a str> {
    vec![
        "-q",
        "optimize",
        "--dataset",
        "ds",
        "--out",
        out,
        "--iterations",
        iterations,
        "--spp",
        "1",
        "--checkpoint-every",
        "1",
        "--final-spp",
        "1",
        "--no-bias-correction",
        "--uncertainty-views",
        "0",
        "--consistency-views",
        "0",
    ]
}

fn dataset() -> tempfile::TempDir {
    let t = tmp();
    make_dataset(
        t.path(),
        "ds",
        "2",
        "12",
        &["--sigma-t", "60", "--albedo", "0.9"],
    );
    t
}

fn spawn(dir: &Path, args: &[&str]) -> Child {
    Command::new(env!("CARGO_BIN_EXE_translucent"))
        .args(args)
        .current_dir(dir)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("cannot start the translucent binary")
}

/// Wait (at most 120 s) until `path` exists.
fn wait_for(path: &Path) {
    let t0 = Instant::now();
    while !path.exists() {
        assert!(
            t0.elapsed() < Duration::from_secs(120),
            "{} did not appear",
            path.display()
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Iterations recorded in a checkpoint (which must parse).
fn checkpoint_iterations(path: &Path) -> usize {
    read_json(path)["history"]
        .as_array()
        .unwrap_or_else(|| panic!("{}: no history", path.display()))
        .len()
}

/// A second run on a folder that a run is using is refused, naming the owner; after that run
/// is killed with SIGKILL (no chance to clean up) the folder is free and the run resumes.
#[test]
fn a_busy_folder_is_refused_and_a_killed_run_resumes() {
    let t = dataset();
    let d = t.path();
    let mut first = spawn(d, &optimize_args("o", "1000000"));
    wait_for(&d.join("o/checkpoint.json"));
    let second = fails(d, &optimize_args("o", "1000000"));
    assert_stderr_has(
        &second,
        &["in use by another translucent run", &first.id().to_string()],
    );
    first.kill().unwrap(); // SIGKILL
    first.wait().unwrap();
    let k = checkpoint_iterations(&d.join("o/checkpoint.json"));
    assert!(k >= 1);
    let more = (k + 2).to_string();
    let resume = [&optimize_args("o", "1000000")[..], &["--resume"]].concat();
    let mut resume: Vec<&str> = resume;
    resume[7] = &more;
    ok(d, &resume);
    assert_eq!(read_json(&d.join("o/result.json"))["iterations"], k + 2);
}

/// `kill -9` at twelve moments spread over a run never leaves a checkpoint that cannot be read:
/// after each kill, either there is none yet or `--resume` continues from it.
#[test]
fn kill_9_at_random_moments_leaves_a_readable_checkpoint() {
    let t = dataset();
    let d = t.path();
    let waits_ms = [0u64, 35, 70, 110, 160, 220, 290, 370, 460, 560, 680, 820];
    for (i, ms) in waits_ms.iter().enumerate() {
        let out = format!("k{i}");
        let mut child = spawn(d, &optimize_args(&out, "1000000"));
        std::thread::sleep(Duration::from_millis(*ms));
        child.kill().unwrap();
        child.wait().unwrap();
        let ck = d.join(&out).join("checkpoint.json");
        if !ck.exists() {
            continue;
        }
        let k = checkpoint_iterations(&ck);
        let more = (k + 1).to_string();
        let mut resume = [&optimize_args(&out, "1000000")[..], &["--resume"]].concat();
        resume[7] = &more;
        ok(d, &resume);
        // No temporary file of the atomic writes is left where a reader would take it.
        let names: Vec<String> = std::fs::read_dir(d.join(&out))
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        assert!(names.contains(&"checkpoint.json".to_string()), "{names:?}");
    }
}

/// A write that fails mid-run (a 2 KiB file-size limit, so the checkpoint's write fails with
/// EFBIG as on a full disk) stops the run with an error naming the file; the previous
/// checkpoint and result stay byte for byte; once writes work again the run resumes.
#[test]
fn a_failed_write_keeps_the_previous_checkpoint() {
    let t = dataset();
    let d = t.path();
    ok(d, &optimize_args("o", "3"));
    let ck = d.join("o/checkpoint.json");
    let before = read(&ck);
    let result_before = read(&d.join("o/result.json"));
    assert!(before.len() > 2048, "the checkpoint must exceed the limit");
    let mut args = [&optimize_args("o", "6")[..], &["--resume"]].concat();
    args.retain(|a| *a != "-q");
    let out = Command::new("bash")
        .arg("-c")
        .arg("trap '' XFSZ; ulimit -f 2; exec \"$0\" \"$@\"")
        .arg(env!("CARGO_BIN_EXE_translucent"))
        .args(&args)
        .current_dir(d)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(stderr.contains("checkpoint.json"), "{stderr}");
    assert!(
        stderr.contains("File too large") || stderr.contains("too large"),
        "{stderr}"
    );
    assert_eq!(read(&ck), before, "the previous checkpoint changed");
    assert_eq!(read(&d.join("o/result.json")), result_before);
    ok(d, &[&optimize_args("o", "6")[..], &["--resume"]].concat());
    assert_eq!(read_json(&d.join("o/result.json"))["iterations"], 6);
}

/// `--resume` with settings other than the run's is refused, naming each difference with both
/// values; only `--iterations` may change.
#[test]
fn resume_with_other_settings_is_refused() {
    let t = dataset();
    let d = t.path();
    ok(d, &optimize_args("o", "2"));
    let mut other = [&optimize_args("o", "4")[..], &["--resume", "--seed", "9"]].concat();
    other[9] = "2"; // --spp 2
    let r = fails(d, &other);
    assert_stderr_has(
        &r,
        &[
            "--resume",
            "settings differ",
            "spp: the run has 1, this command gives 2",
            "seed",
        ],
    );
    ok(d, &[&optimize_args("o", "4")[..], &["--resume"]].concat());
}
