//! A tiny end-to-end training run: data from our generator, a few hundred
//! steps, the loss decreases, and a run interrupted by a checkpoint and resumed ends bit for bit
//! where the uninterrupted run ends.

use bssrdf::model::ModelInfo;
use learn::cvae::Widths;
use learn::datagen::{DataConfig, generate};
use learn::optim::AdamConfig;
use learn::sample::Sample;
use learn::train::{Objective, Prepared, TrainConfig, Trainer, normalisation_of, prepare};

fn data() -> (Vec<Sample>, Vec<Sample>) {
    let base = DataConfig {
        meshes: 2,
        configs_per_mesh: 60,
        samples_per_config: 8,
        path_attempts: 128,
        seed: 7,
        ..DataConfig::default()
    };
    let (train, _) = generate(&base, None).unwrap();
    let (val, _) = generate(
        &DataConfig {
            meshes: 1,
            first_mesh: 2,
            ..base
        },
        None,
    )
    .unwrap();
    (train, val)
}

fn config(steps: u64) -> TrainConfig {
    TrainConfig {
        widths: Widths {
            feature: vec![16, 16],
            absorption_hidden: vec![8],
            decoder_hidden: vec![16],
            encoder_hidden: vec![16],
        },
        batch_size: 32,
        steps,
        adam: AdamConfig {
            lr: 3e-3,
            ..AdamConfig::default()
        },
        weights: Default::default(),
        seed: 3,
        eval_every: 50,
        checkpoint_every: 100,
        objective: Objective::Cvae,
    }
}

fn prepared() -> (bssrdf::nn::Normalisation, Prepared, Prepared) {
    let (train, val) = data();
    let norm = normalisation_of(&train).unwrap();
    let t = prepare(&train, &norm).unwrap();
    let v = prepare(&val, &norm).unwrap();
    (norm, t, v)
}

#[test]
fn tiny_training_reduces_the_loss_and_resumes_bit_identically() {
    let (norm, t, v) = prepared();
    let dir = tempfile::tempdir().unwrap();
    let ckpt = dir.path().join("checkpoint.bin");

    // Uninterrupted run of 300 steps.
    let mut full = Trainer::new(
        config(300),
        norm.clone(),
        ModelInfo::default(),
        t.clone(),
        v.clone(),
    )
    .unwrap();
    full.run(None, |_| {}).unwrap();
    let h = full.history();
    let first = h.first().unwrap().val.total;
    let last = h.last().unwrap().val.total;
    // The untrained model's validation loss is dominated by the absorption term (weight 5000 on
    // a squared error of order 0.1); a model that learned anything halves it.
    assert!(
        last < 0.5 * first,
        "validation loss did not fall: {first} -> {last}"
    );
    assert!(h.iter().all(|r| r.val.total.is_finite()));

    // The same run, stopped at step 100 (checkpoint), resumed from the file to 300.
    let mut part = Trainer::new(
        config(100),
        norm,
        ModelInfo::default(),
        t.clone(),
        v.clone(),
    )
    .unwrap();
    part.run(Some(&ckpt), |_| {}).unwrap();
    drop(part);
    let mut resumed = Trainer::resume(&ckpt, Some(300), t.clone(), v).unwrap();
    assert_eq!(resumed.step(), 100);
    resumed.run(Some(&ckpt), |_| {}).unwrap();
    assert_eq!(resumed.params(), full.params(), "resumed parameters differ");
    let losses = |tr: &Trainer| tr.history().iter().map(|r| r.val.total).collect::<Vec<_>>();
    assert_eq!(losses(&resumed), losses(&full));

    // A checkpoint refuses other data.
    let mut other = t;
    other.absorption[0] = 1.0 - other.absorption[0];
    let err = Trainer::resume(&ckpt, None, other, Prepared::default())
        .err()
        .expect("resume on other data must fail");
    assert!(err.to_string().contains("other training data"), "{err}");
}

#[test]
fn damaged_checkpoints_are_refused_with_their_path() {
    let (norm, t, v) = prepared();
    let dir = tempfile::tempdir().unwrap();
    let ckpt = dir.path().join("checkpoint.bin");
    let mut tr =
        Trainer::new(config(10), norm, ModelInfo::default(), t.clone(), v.clone()).unwrap();
    tr.run(Some(&ckpt), |_| {}).unwrap();
    let bytes = std::fs::read(&ckpt).unwrap();
    // Truncated tensors.
    std::fs::write(&ckpt, &bytes[..bytes.len() - 4]).unwrap();
    let e = Trainer::resume(&ckpt, None, t.clone(), v.clone())
        .err()
        .unwrap();
    assert!(
        e.to_string().contains("checkpoint.bin") && e.to_string().contains("damaged"),
        "{e}"
    );
    // Not a checkpoint.
    std::fs::write(&ckpt, b"hello world, not a checkpoint").unwrap();
    let e = Trainer::resume(&ckpt, None, t, v).err().unwrap();
    assert!(e.to_string().contains("bad magic"), "{e}");
}

/// Rewrites the JSON header of a training checkpoint through `edit`, keeping the length prefix
/// consistent.
fn edit_checkpoint_header(path: &std::path::Path, edit: impl FnOnce(&mut serde_json::Value)) {
    let bytes = std::fs::read(path).unwrap();
    let len = u64::from_le_bytes(bytes[8..16].try_into().unwrap()) as usize;
    let mut header: serde_json::Value = serde_json::from_slice(&bytes[16..16 + len]).unwrap();
    edit(&mut header);
    let json = serde_json::to_vec(&header).unwrap();
    let mut out = bytes[..8].to_vec();
    out.extend_from_slice(&(json.len() as u64).to_le_bytes());
    out.extend_from_slice(&json);
    out.extend_from_slice(&bytes[16 + len..]);
    std::fs::write(path, out).unwrap();
}

/// Header fields of a checkpoint that size allocations or count steps are checked before
/// anything is allocated (found by the mutation pass of `crates/fuzz`: a feature width of 10⁹
/// made `resume` allocate 56 GB for the model before it compared the parameter count with the
/// file). Each damaged field is an error naming the file and the field.
#[test]
fn checkpoint_fields_that_size_allocations_are_checked_first() {
    let (norm, t, v) = prepared();
    let dir = tempfile::tempdir().unwrap();
    let ckpt = dir.path().join("checkpoint.bin");
    let mut tr = Trainer::new(config(2), norm, ModelInfo::default(), t.clone(), v.clone()).unwrap();
    tr.run(Some(&ckpt), |_| {}).unwrap();
    let good = std::fs::read(&ckpt).unwrap();
    let refused = |edit: &dyn Fn(&mut serde_json::Value), expect: &str| {
        std::fs::write(&ckpt, &good).unwrap();
        edit_checkpoint_header(&ckpt, edit);
        let e = Trainer::resume(&ckpt, None, t.clone(), v.clone())
            .err()
            .expect("a damaged checkpoint must be refused")
            .to_string();
        assert!(e.contains("checkpoint.bin") && e.contains(expect), "{e}");
    };
    refused(
        &|h| h["config"]["widths"]["feature"] = serde_json::json!([1_000_000_000u64, 16]),
        "config.widths",
    );
    refused(
        &|h| h["n_params"] = serde_json::json!(u64::MAX / 4),
        "12 per parameter",
    );
    refused(
        &|h| h["config"]["batch_size"] = serde_json::json!(1u64 << 40),
        "batch size",
    );
    refused(
        &|h| {
            h["config"]["objective"] =
                serde_json::json!({"kind": "energy-score", "draws": 1u64 << 40, "weight": 1.0})
        },
        "draws",
    );
    // Step counters: a run stops at config.steps and takes one Adam step per step (found by
    // the mutation pass in the test profile: step = 2⁶⁴ − 1 overflowed at the next step).
    refused(&|h| h["step"] = serde_json::json!(u64::MAX), "inconsistent");
    refused(&|h| h["adam_step"] = serde_json::json!(3), "inconsistent");
    // The untouched file still resumes.
    std::fs::write(&ckpt, &good).unwrap();
    assert!(Trainer::resume(&ckpt, None, t, v).is_ok());
}

/// `Widths::n_params` counts the parameters of the model `init_model` builds.
#[test]
fn widths_count_the_parameters_of_their_model() {
    for w in [
        Widths::son24(),
        Widths::vkj19(),
        config(1).widths,
        Widths {
            feature: vec![3],
            absorption_hidden: vec![],
            decoder_hidden: vec![2, 5],
            encoder_hidden: vec![1],
        },
    ] {
        let m = learn::cvae::init_model(
            &w,
            bssrdf::nn::Normalisation::identity(),
            ModelInfo::default(),
            0,
        )
        .unwrap();
        assert_eq!(w.n_params(), Some(learn::cvae::n_params(&m)), "{w:?}");
    }
    let huge = Widths {
        feature: vec![usize::MAX / 2, 2],
        ..Widths::son24()
    };
    assert_eq!(huge.n_params(), None);
}
