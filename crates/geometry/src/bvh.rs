//! Ray queries over a triangle mesh: an obvhs CWBVH (8-wide) with the watertight triangle test of
//! [`crate::triangle`]. Triangles are stored reordered in BVH order for locality; every result
//! reports the ORIGINAL triangle index.
//!
//! SKELETON: helper H2 owns this file (keep the public signatures; add what you need).

use glam::{Vec2, Vec3};

use crate::Mesh;

/// A ray/surface intersection.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Distance along the (unit) ray direction.
    pub t: f32,
    /// Original triangle index in the mesh.
    pub tri: u32,
    /// Barycentrics (b1, b2) of v1 and v2.
    pub bary: Vec2,
    /// Hit position.
    pub p: Vec3,
    /// Unit geometric normal, pointing OUT of the medium (CCW convention).
    pub ng: Vec3,
    /// Unit shading normal (interpolated vertex normals, or `ng` when the mesh has none), made to
    /// lie in the same hemisphere as `ng`.
    pub ns: Vec3,
}

impl Hit {
    /// True when the ray arrived from outside the medium (`dir · ng < 0`).
    #[inline]
    pub fn entering(&self, dir: Vec3) -> bool {
        dir.dot(self.ng) < 0.0
    }
}

/// Acceleration structure over one mesh. `Send + Sync`; build once, query from many threads.
pub struct Accel {
    mesh: Mesh,
}

impl Accel {
    /// Build the BVH (parallel) over a validated mesh.
    pub fn new(mesh: Mesh) -> Self {
        todo!()
    }
    /// The mesh this accel was built over (original triangle order).
    pub fn mesh(&self) -> &Mesh {
        &self.mesh
    }
    /// Closest hit with `tmin < t < tmax` along `origin + t·dir` (`dir` unit length).
    pub fn closest(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> Option<Hit> {
        todo!()
    }
    /// True when anything is hit with `tmin < t < tmax`.
    pub fn occluded(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> bool {
        todo!()
    }
    /// All hits with `tmin < t < tmax`, appended to `out` sorted by `t` (`out` is cleared first;
    /// pass a reused buffer to stay allocation-free).
    pub fn all_hits(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32, out: &mut Vec<Hit>) {
        todo!()
    }
    /// Total length of the segment `a → b` that lies inside the closed mesh. Whether `a` is inside
    /// is decided by the facing of the first hit along the ray from `a` through `b` (a back-face
    /// hit means inside); every crossing toggles.
    pub fn inside_length(&self, a: Vec3, b: Vec3) -> f32 {
        todo!()
    }
    /// True when `p` is inside the closed mesh (facing of the first hit along a fixed direction).
    pub fn contains(&self, p: Vec3) -> bool {
        todo!()
    }
}
