//! # translucent-fuzz
//!
//! Fuzzing of every reader of outside data (files a user, another tool or an earlier run hands
//! to translucent):
//!
//! * [`readers`]: each reader behind one interface, [`readers::Target::read`]: bytes in, the
//!   reader's verdict out (accepted, or its error message). The readers are the library's own
//!   entry points (`geometry::io::load_mesh`, `scene::SceneDesc::load`, `scene::Dataset::load`,
//!   `scene::Dataset::load_reference`, `scene::Image::read_exr`, `bssrdf::model::load`,
//!   `bssrdf::exit::TableFile::from_json`, `bssrdf::son24::read_bin`,
//!   `inverse::optimize::Checkpoint::read`, `learn::train::Trainer::resume`,
//!   `learn::samplefile::read_samples`), fed through a file as the command line feeds them.
//! * [`mutate`]: a seeded mutator of the seed corpus (`fuzz/corpus/<reader>/`, made by the
//!   `make-corpus` binary of this crate with the project's own writers): bit flips, interesting
//!   bytes and little/big-endian counts, truncation, deleted/duplicated chunks, splices between
//!   corpus files, and for text (and the JSON headers inside binary containers, with their length
//!   prefix kept consistent) number, string, line and punctuation mutations.
//! * [`alloc`]: a global allocator that refuses any single allocation above a limit and says
//!   which input asked for it, so that a header field cannot drive an unbounded allocation
//!   unnoticed.
//! * [`pass`]: the deterministic mutation pass that the test suite runs (`tests/mutations.rs`):
//!   per reader the corpus itself (which must be accepted) and then ≥ 10⁴ mutated inputs, each
//!   checked for panics, time and an error that names the file.
//!
//! The coverage-guided long runs (AFL++ through `cargo afl`) live in the `fuzz/` folder at the
//! repository root, outside the workspace, and call the same [`readers::Target`]; see
//! `fuzz/README.md`.

pub mod alloc;
pub mod mutate;
pub mod pass;
pub mod readers;
pub mod rng;

use std::path::PathBuf;

/// The `fuzz/` folder at the repository root (corpus, support files, AFL targets).
pub fn fuzz_dir() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fuzz"))
}

/// The workspace's `target/` folder (failing inputs are saved under `target/fuzz-failures/`).
pub fn target_dir() -> PathBuf {
    std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../target")))
}
