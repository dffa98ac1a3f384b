//! The integration tests of this crate, one module per file, in one test binary (one link
//! instead of one per file): `cargo test -p translucent-bssrdf --test integration NAME`
//! runs the tests whose path contains NAME (a file's module, e.g. `diff::`).

mod common;
mod diff;
mod fit;
mod model;
mod nn;
mod polynomial;
mod render;
mod walk_sampler;
