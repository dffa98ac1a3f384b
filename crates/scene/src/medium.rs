//! The homogeneous medium (architecture.md §3): per RGB channel extinction σ_t [1/unit] and
//! single-scattering albedo α (σ_s = α σ_t), Henyey–Greenstein g, relative IOR η = n_in/n_out.
//!
//! SKELETON: helper H3 owns `validate`.

use serde::{Deserialize, Serialize};

use crate::SceneError;

/// Homogeneous medium parameters.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Medium {
    pub sigma_t: [f32; 3],
    pub albedo: [f32; 3],
    /// Henyey–Greenstein anisotropy, (−1, 1); 0 = isotropic (the paper's setting).
    #[serde(default)]
    pub g: f32,
    /// Relative index of refraction η ≥ 1; 1 = index-matched (null) boundary (the paper's data).
    #[serde(default = "one")]
    pub eta: f32,
}

fn one() -> f32 {
    1.0
}

impl Medium {
    /// Check ranges: σ_t > 0 and finite, α ∈ [0, 1), g ∈ (−1, 1), η ≥ 1. `context` (file and
    /// field path, e.g. "scene.toml: medium") goes into the error.
    pub fn validate(&self, context: &str) -> Result<(), SceneError> {
        todo!()
    }
    /// σ_s per channel.
    pub fn sigma_s(&self) -> [f32; 3] {
        [0, 1, 2].map(|c| self.sigma_t[c] * self.albedo[c])
    }
}
