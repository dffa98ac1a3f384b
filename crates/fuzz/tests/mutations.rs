//! The deterministic mutation pass over every reader of outside data (`fuzz::pass`): per reader
//! the seed corpus of `fuzz/corpus/<reader>/` (every file must be accepted) and 10,000 seeded
//! mutations of it, each read through the reader's public entry point. An input fails the test
//! when the reader panics, takes longer than 2 s, or returns an error that does not name the
//! file; this binary's global allocator aborts, naming the input, on any single allocation above
//! 512 MiB (a header field driving an unbounded allocation).
//!
//! The pass is deterministic: case `n` of a reader is always the same input. Environment:
//! `FUZZ_INPUTS` (mutated inputs per reader, default 10,000) for longer runs, `FUZZ_CASE=n` to
//! replay case `n` alone (e.g. `FUZZ_CASE=1234 cargo test -p translucent-fuzz --test mutations
//! -- ply`). Failing inputs are saved under `target/fuzz-failures/`.

use fuzz::pass::{Settings, run};
use fuzz::readers::Reader;

#[global_allocator]
static ALLOC: fuzz::alloc::LimitAlloc = fuzz::alloc::LimitAlloc::new(512 << 20);

fn env_u64(name: &str) -> Option<u64> {
    std::env::var(name).ok().map(|v| {
        v.parse()
            .unwrap_or_else(|_| panic!("{name}={v} is not a number"))
    })
}

fn pass(reader: Reader) {
    let mut settings = Settings::default();
    if let Some(n) = env_u64("FUZZ_INPUTS") {
        settings.inputs = n;
    }
    if let Some(case) = env_u64("FUZZ_CASE") {
        settings.first_case = case;
        settings.inputs = 1;
    }
    let scratch = tempfile_dir(reader);
    let report = run(reader, &settings, &scratch);
    let _ = std::fs::remove_dir_all(&scratch);
    println!("{report}");
    assert!(report.failures.is_empty(), "{report}");
    assert_eq!(
        report.inputs,
        settings.inputs
            + if settings.first_case == 0 {
                reader.corpus().map(|c| c.len() as u64).unwrap_or(0)
            } else {
                0
            }
    );
}

/// A fresh scratch folder for one reader's pass.
fn tempfile_dir(reader: Reader) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!(
        "translucent-fuzz-{}-{}",
        std::process::id(),
        reader.name()
    ));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

#[test]
fn ply() {
    pass(Reader::Ply);
}

#[test]
fn obj() {
    pass(Reader::Obj);
}

#[test]
fn scene_toml() {
    pass(Reader::SceneToml);
}

#[test]
fn scene_json() {
    pass(Reader::SceneJson);
}

#[test]
fn scene_xml() {
    pass(Reader::SceneXml);
}

#[test]
fn dataset() {
    pass(Reader::Dataset);
}

#[test]
fn reference() {
    pass(Reader::Reference);
}

#[test]
fn exr() {
    pass(Reader::Exr);
}

#[test]
fn model() {
    pass(Reader::Model);
}

#[test]
fn optimize_checkpoint() {
    pass(Reader::OptimizeCheckpoint);
}

#[test]
fn train_checkpoint() {
    pass(Reader::TrainCheckpoint);
}

#[test]
fn samples() {
    pass(Reader::Samples);
}

#[test]
fn tables() {
    pass(Reader::Tables);
}

#[test]
fn son24_bin() {
    pass(Reader::Son24Bin);
}

#[test]
fn colmap_cameras_txt() {
    pass(Reader::ColmapCamerasTxt);
}

#[test]
fn colmap_images_txt() {
    pass(Reader::ColmapImagesTxt);
}

#[test]
fn colmap_cameras_bin() {
    pass(Reader::ColmapCamerasBin);
}

#[test]
fn colmap_images_bin() {
    pass(Reader::ColmapImagesBin);
}

#[test]
fn photo() {
    pass(Reader::Photo);
}

#[test]
fn transforms_json() {
    pass(Reader::NerfTransforms);
}
