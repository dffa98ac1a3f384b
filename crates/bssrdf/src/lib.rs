//! # translucent-bssrdf
//!
//! The learned shape-adaptive BSSRDF of Vicini, Koltun and Jakob 2019 (VKJ19) as used by Son et
//! al. 2024 (SON24), following `docs/model.md` of this repository (cited below as §N):
//!
//! * [`medium`]: reduced parameters, effective albedo, the kernel scale σ_n (§2).
//! * [`polynomial`]: the cubic implicit polynomial (20 monomials), its evaluation, gradient and
//!   exact rotation into another frame (§3.1, §3.3).
//! * [`fit`]: the surface point cloud with its k-d tree and the weighted least-squares cubic fit
//!   per vertex (§3.2, §3.4).
//! * [`nn`]: batched, allocation-free MLP inference (feature MLP, absorption MLP, decoder) and the
//!   input derivative of the absorption output (§4).
//! * [`model`]: our model file format (safetensors + JSON metadata) and its validation.
//! * [`projection`]: the projection Π of proposed points onto the mesh (§7, A5).
//! * the boundary factors (Fresnel transmittance, FM1, the light-side factor Sw, §1) are
//!   `base::boundary`, shared with the dipole.
//! * [`exit`], [`incidence`], [`curvature`] (the `tables` crate, re-exported): the light-side
//!   exit law from half-space walks, conditioned on the camera side (replaces the cosine law of
//!   Sw by default); where obliquely entering light leaves, relative to its direction; and the
//!   curvature correction from exact walks in balls, applied at the camera point.
//! * [`render`]: the forward renderer with the learned BSSRDF (§7.3).
//! * [`diff`]: the differentiable renderer: values and ∂/∂σ_t, ∂/∂α by the paper's estimators
//!   (`ours`, `ours-alpha-offsets`, `naive`, `fd`) and the loss gradient (§8; Son et al. eq. 15–17).
//! * [`gaussian`]: standard normal samples by inversion.
//! * [`son24`]: the importer of the reference weights of Son et al. (a yardstick, never a runtime
//!   dependency).

pub mod diff;
pub mod fit;
pub mod gaussian;
pub mod medium;
pub mod model;
pub mod nn;
pub mod polynomial;
pub mod projection;
pub mod render;
pub mod son24;
pub mod walk;

pub use tables::{curvature, exit, incidence};
