//! End-to-end tests of the `translucent` binary: every command on tiny images (8×8 … 16×16, a few
//! views, a few samples per pixel), determinism of the outputs, and the error messages for bad
//! input (exit code ≠ 0, the file and field named, never a panic).
//!
//! Each test works in its own temporary folder (the binary runs with that folder as its current
//! directory, so relative paths in the messages are short and nothing leaks into the repository).

mod helpers;

mod bad_input;
mod capture_errors;
mod dataset_render_compare;
mod demo_validate;
mod faults;
mod import;
mod inverse;
mod train;
