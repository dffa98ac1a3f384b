//! The integration tests of this crate, one module per file, in one test binary (one link
//! instead of one per file): `cargo test -p translucent-geometry --test integration NAME`
//! runs the tests whose path contains NAME (a file's module, e.g. `bvh::`).

mod bvh;
mod common;
mod light_bins;
mod mesh_io;
mod properties;
mod shapes;
mod support_planes;
