//! The walk tables' integration tests, one binary: each shipped table against its generator,
//! its interpolation and its reader.

mod exit;
mod incidence;
mod rough;
