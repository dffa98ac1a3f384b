//! # translucent-volpath
//!
//! The volumetric path tracer: ground truth for the learned BSSRDF, generator of datasets and a
//! baseline of the inverse problem. Conventions follow Mitsuba 3's `volpath` (CONVENTIONS.md)
//! so that its images can be compared with Mitsuba's directly.
//!
//! * [`integrator`]: radiance along a ray (free flights, NEE, dielectric boundary, roulette).
//! * [`derivative`]: ∂I/∂σ_t and ∂I/∂α of the same paths, from each path's throughput.
//! * [`spectral`]: hero-channel spectral MIS for RGB extinction.
//! * [`guided`]: Dwivedi-guided walks (directions and free flights towards the surface).
//! * [`phase`], [`fresnel`], [`rng`]: from the `base` crate.
//! * [`manifold`]: next-event estimation through one refraction (η > 1 with point lights).
//! * [`rough`]: the rough dielectric boundary (GGX): its sampling and its vertices' NEE.
//! * [`render`]: parallel, reproducible image rendering.
//! * [`shadow`]: transmittance of the shadow rays (exact or tracked).

pub mod derivative;
/// Fresnel, the phase function and the random streams live in `base`, shared with the other
/// renderers; re-exported here under their old paths.
pub use base::{fresnel, phase, rng};
pub mod guided;
pub mod integrator;
pub mod manifold;
pub mod render;
pub mod rough;
pub mod settings;
pub mod setup;
pub mod shadow;
pub mod spectral;
mod steps;
pub mod tally;
mod vertex;

pub use derivative::{DerivativeImages, PathDerivatives};
pub use guided::WalkSampling;
pub use integrator::{
    CameraLine, ChannelSampling, DEFAULT_MAX_DEPTH, PathScore, SpawnOffset, Tally, VolpathScene,
    VolpathSettings, radiance, radiance_primary, trace,
};
pub use render::{Progressive, RenderSettings, render_derivatives, render_image, shadow_lists};
pub use setup::{Lit, SharedLists};
pub use shadow::ShadowTransmittance;
