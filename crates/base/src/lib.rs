//! # translucent-base
//!
//! What the renderers, the training and the inverse loop share, so that they depend on this
//! crate rather than on each other:
//!
//! * [`rng`]: reproducible random streams keyed by (seed, view, pixel, purpose).
//! * [`pixel`]: per-render settings and the pixel samples (Owen-scrambled Sobol jitter).
//! * [`fresnel`]: exact dielectric Fresnel, reflection, refraction.
//! * [`microfacet`]: the rough dielectric boundary (GGX, Walter et al. 2007), its sampling of
//!   visible normals (Heitz 2018) and evaluation.
//! * [`boundary`]: the boundary factors of the BSSRDF estimators: Fresnel transmittance, FM1 and
//!   the light-side factor Sw.
//! * [`phase`]: Henyey–Greenstein sampling and evaluation.
//! * [`optim`]: Adam with per-parameter rates and step decay.

pub mod boundary;
pub mod fresnel;
pub mod microfacet;
pub mod optim;
pub mod phase;
pub mod pixel;
pub mod rng;
