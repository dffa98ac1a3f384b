//! Area-uniform surface point sampling (alias-free: binary search in the triangle-area CDF, then
//! the uniform triangle map (1 − √u₁, u₂√u₁)).
//!
//! SKELETON: helper H2 owns this file.

use glam::Vec3;

use crate::Mesh;

/// A sampled surface point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceSample {
    pub p: Vec3,
    /// Unit geometric normal (outward).
    pub ng: Vec3,
    /// Unit shading normal.
    pub ns: Vec3,
    pub tri: u32,
    /// Area density 1/A.
    pub pdf: f32,
}

/// Samples points uniformly by area.
pub struct AreaSampler {
    cdf: Vec<f64>,
    total_area: f64,
}

impl AreaSampler {
    pub fn new(mesh: &Mesh) -> Self {
        todo!()
    }
    pub fn total_area(&self) -> f64 {
        self.total_area
    }
    /// Map three uniforms in [0,1) to a surface point.
    pub fn sample(&self, mesh: &Mesh, u: [f32; 3]) -> SurfaceSample {
        todo!()
    }
}
