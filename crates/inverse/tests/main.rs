//! The integration tests of this crate, one module per file, in one test binary (one link
//! instead of one per file): `cargo test -p translucent-inverse --test integration NAME`
//! runs the tests whose path contains NAME (a file's module, e.g. `boundary::`).

mod common;
mod forward;
mod optimize;
mod properties;
mod sensitivity;
mod toy_model;
