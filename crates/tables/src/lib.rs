//! The light-side walk tables of the learned BSSRDF: what random walks in a half-space (and in
//! balls of the surface's curvature) say about where light that entered leaves, which the
//! learned model's renderer looks up instead of walking. Each is simulated from a medium's g and
//! η, stored as JSON, and shipped for g = 0, η = 1 (`data/`):
//!
//! - [`exit`]: the exit law f(α; μ_cam, μ_l), light leaving toward the camera;
//! - [`incidence`]: the incidence factor A(α; μ_l, ρ, ψ), where light that entered obliquely
//!   leaves relative to its direction;
//! - [`curvature`]: the correction of both on a curved surface, from walks in balls.
//!
//! They depend on the medium alone (not on a network), so they sit below the learned model and
//! its renderer, which re-export them (`bssrdf::exit`, …).

pub mod curvature;
pub mod disk;
pub mod exit;
pub mod incidence;
pub mod table;
