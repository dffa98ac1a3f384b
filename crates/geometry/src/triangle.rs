//! Watertight ray/triangle intersection: Woop, Benthin, Wald, "Watertight Ray/Triangle
//! Intersection", JCGT 2(1), 2013. No back-face culling (rays leave closed meshes from inside).
//!
//! SKELETON: helper H2 owns this file.

use glam::Vec3A;

/// Precomputed per-ray data of the watertight test (shear constants and axis permutation).
#[derive(Clone, Copy, Debug)]
pub struct WatertightRay {
    pub org: Vec3A,
    pub kx: usize,
    pub ky: usize,
    pub kz: usize,
    pub sx: f32,
    pub sy: f32,
    pub sz: f32,
}

impl WatertightRay {
    pub fn new(org: Vec3A, dir: Vec3A) -> Self {
        todo!()
    }

    /// Returns `(t, b1, b2)` (hit point = (1 − b1 − b2)·v0 + b1·v1 + b2·v2) when the ray hits the
    /// triangle with `tmin < t < tmax`.
    #[inline]
    pub fn intersect(&self, v0: Vec3A, v1: Vec3A, v2: Vec3A, tmin: f32, tmax: f32) -> Option<(f32, f32, f32)> {
        todo!()
    }
}
