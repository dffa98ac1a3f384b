//! Emitters. A [`PointLight`] has radiant intensity I per RGB channel: the irradiance at distance
//! r facing the light is I/r² (CONVENTIONS.md; psdr-cuda's `power` equals 4π·I).
//! An [`Environment`] is constant radiance from every direction (energy tests, furnace).

use glam::Vec3;
use serde::{Deserialize, Serialize};

/// Isotropic point light.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct PointLight {
    pub position: Vec3,
    /// Radiant intensity per channel [W/sr].
    pub intensity: [f32; 3],
}

/// Constant environment radiance (infinitely far away, all directions).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Environment {
    pub radiance: [f32; 3],
}
