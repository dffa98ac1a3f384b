//! # translucent-base
//!
//! What the renderers, the training and the inverse loop share, so that they depend on this
//! crate rather than on each other:
//!
//! * [`rng`]: reproducible random streams keyed by (seed, view, pixel, purpose).
//! * [`pixel`]: per-render settings and the pixel samples (Owen-scrambled Sobol jitter).
//! * [`fresnel`]: exact dielectric Fresnel, reflection, refraction.
//! * [`boundary`]: the boundary factors of the BSSRDF estimators: Fresnel transmittance, FM1 and
//!   the light-side factor Sw.
//! * [`phase`]: Henyey–Greenstein sampling and evaluation.
//! * [`optim`]: Adam with per-parameter rates and step decay.

pub mod boundary;
pub mod fresnel;
pub mod optim;
pub mod phase;
pub mod pixel;
pub mod rng;
