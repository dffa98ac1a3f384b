//! The integration tests of this crate, one module per file, in one test binary (one link
//! instead of one per file): `cargo test -p translucent-volpath --test integration NAME`
//! runs the tests whose path contains NAME (a file's module, e.g. `derivatives::`).

mod chromatic;
mod derivatives;
mod energy;
mod guided;
mod properties;
mod sampling;
mod shadow;
mod spawn_offset;
