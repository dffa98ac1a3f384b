//! Training: data, fit, resume, the shipped model.

use super::helpers::*;

// ---------------------------------------------------------------------------------------------
// Training: data, fit, resume, the shipped model.

#[test]
fn train_data_fit_resume_and_use_the_model() {
    let t = tmp();
    let d = t.path();
    let data_args = [
        "train",
        "data",
        "--out",
        "data",
        "--meshes",
        "1",
        "--val-meshes",
        "1",
        "--configs-per-mesh",
        "20",
        "--path-attempts",
        "64",
        "--seed",
        "1",
    ];
    let r = ok(d, &data_args);
    assert_stdout_has(&r, &["train: 320 samples"]);
    let first = read(&d.join("data/train.tlsamples"));
    // Same seed, same bytes; existing files are protected.
    let again = fails(d, &data_args);
    assert_stderr_has(&again, &["train.tlsamples", "--overwrite"]);
    let mut with_overwrite = data_args.to_vec();
    with_overwrite.push("--overwrite");
    ok(d, &with_overwrite);
    // Same records (the JSON header also holds the creation time, so compare after it:
    // magic 8 bytes, version u32, header length u32, header, records).
    let records = |b: &[u8]| {
        let n = u32::from_le_bytes(b[12..16].try_into().unwrap()) as usize;
        b[16 + n..].to_vec()
    };
    assert_eq!(
        records(&read(&d.join("data/train.tlsamples"))),
        records(&first)
    );

    let fit = [
        "train",
        "fit",
        "--data",
        "data",
        "--out",
        "m",
        "--steps",
        "40",
        "--batch",
        "32",
        "--eval-every",
        "20",
        "--checkpoint-every",
        "20",
        "--widths",
        "F=8,8;A=4;D=8;E=8",
    ];
    ok(d, &fit);
    for f in [
        "model.safetensors",
        "checkpoint.bin",
        "history.csv",
        "loss.png",
        "train.json",
    ] {
        assert!(d.join("m").join(f).exists(), "missing {f}");
    }
    let history = String::from_utf8(read(&d.join("m/history.csv"))).unwrap();
    assert_eq!(history.lines().count(), 1 + 3, "{history}");
    // A second fit into the same folder needs --resume or --overwrite.
    let r = fails(d, &fit);
    assert_stderr_has(&r, &["--resume", "--overwrite"]);
    let mut resume: Vec<&str> = fit.to_vec();
    resume[7] = "60"; // --steps 60
    resume.push("--resume");
    let r = ok(d, &resume);
    assert_stdout_has(&r, &["trained 60 steps (20 this run)"]);
    let info = ok(d, &["model", "info", "m/model.safetensors"]);
    assert_stdout_has(&info, &["translucent train fit"]);

    // Fine-tuning with the energy score from that model (the second stage of `train all`).
    let energy = [
        "train",
        "fit",
        "--data",
        "data",
        "--out",
        "e",
        "--init",
        "m/model.safetensors",
        "--objective",
        "energy",
        "--draws",
        "4",
        "--steps",
        "20",
        "--batch",
        "16",
        "--eval-every",
        "10",
    ];
    let r = ok(d, &energy);
    assert_stdout_has(&r, &["trained 20 steps", "energy_score"]);
    let info = ok(d, &["model", "info", "e/model.safetensors"]);
    assert_stdout_has(
        &info,
        &["energy-score", "m/model.safetensors", "8 -> 4 -> 1"],
    );
    let history = String::from_utf8(read(&d.join("e/history.csv"))).unwrap();
    assert!(
        history
            .lines()
            .next()
            .unwrap()
            .ends_with("val_energy_score")
    );
    // A model that cannot start a fine-tuning, and data made with the other c_19 convention.
    write(&d.join("bad.safetensors"), b"not a model");
    let mut bad = energy.to_vec();
    bad[5] = "e2";
    bad[7] = "bad.safetensors";
    let r = fails(d, &bad);
    assert_stderr_has(&r, &["--init bad.safetensors"]);
    let mut other = data_args.to_vec();
    other[3] = "data-noquirk";
    other.push("--no-c19-quirk");
    ok(d, &other);
    let mut mismatch = energy.to_vec();
    mismatch[3] = "data-noquirk";
    mismatch[5] = "e3";
    let r = fails(d, &mismatch);
    assert_stderr_has(
        &r,
        &["--init m/model.safetensors", "c_19", "--no-c19-quirk"],
    );
}

#[test]
fn train_fit_without_data_and_damaged_models_are_clear_errors() {
    let t = tmp();
    let d = t.path();
    let r = fails(d, &["train", "fit", "--data", "nothing", "--out", "m"]);
    assert_stderr_has(&r, &["nothing/train.tlsamples", "translucent train data"]);
    write(&d.join("bad.safetensors"), b"not a model at all");
    let r = fails(d, &["model", "info", "bad.safetensors"]);
    assert_stderr_has(&r, &["bad.safetensors"]);
    let r = fails(d, &["model", "info", "missing.safetensors"]);
    assert_stderr_has(&r, &["missing.safetensors", "does not exist"]);
}

#[test]
fn shipped_model_is_built_in_and_valid() {
    let t = tmp();
    let r = ok(t.path(), &["model", "info", "shipped"]);
    assert_stdout_has(&r, &["translucent train fit"]);
}
