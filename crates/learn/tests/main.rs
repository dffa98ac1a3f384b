//! The integration tests of this crate, one module per file, in one test binary (one link
//! instead of one per file): `cargo test -p translucent-learn --test integration NAME`
//! runs the tests whose path contains NAME (a file's module, e.g. `datagen::`).

mod common;
mod datagen;
mod energy;
mod exit_walks;
mod gradients;
mod train;
