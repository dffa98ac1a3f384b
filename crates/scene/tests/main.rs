//! The integration tests of this crate, one module per file, in one test binary (one link
//! instead of one per file): `cargo test -p translucent-scene --test integration NAME`
//! runs the tests whose path contains NAME (a file's module, e.g. `pixel_bins::`).

mod pixel_bins;
mod properties;
mod scene_units;
