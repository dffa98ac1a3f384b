//! The Mitsuba 3 `perspective` camera (architecture.md §3, fixed convention).
//!
//! `to_world = look_at(origin, target, up)`: z = normalize(target − origin) (view direction),
//! x = normalize(cross(up, z)) (image LEFT), y = cross(z, x) (image up). With t = tan(fov_x/2),
//! film coordinates (px, py) in pixels (py down):
//! d_cam = ((1 − 2px/W)·t, (1 − 2py/H)·t·H/W, 1), d_world = normalize(R·d_cam).

use glam::{Mat3, Vec3};
use serde::{Deserialize, Serialize};

/// A pinhole perspective camera.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Camera {
    /// Camera position.
    pub origin: Vec3,
    /// Rotation columns [x (image left), y (image up), z (view direction)].
    pub rotation: Mat3,
    /// Horizontal field of view in degrees (Mitsuba `fov_axis = "x"`).
    pub fov_x_deg: f32,
    pub width: u32,
    pub height: u32,
}

impl Camera {
    /// Mitsuba `look_at`. `up` must not be parallel to `target − origin` (checked by the scene
    /// validation, which reports it as an error).
    pub fn look_at(origin: Vec3, target: Vec3, up: Vec3, fov_x_deg: f32, width: u32, height: u32) -> Self {
        let z = (target - origin).normalize();
        let x = up.cross(z).normalize();
        let y = z.cross(x);
        Camera { origin, rotation: Mat3::from_cols(x, y, z), fov_x_deg, width, height }
    }

    /// Primary ray through film position (px, py) (pixels, py down): (origin, unit direction).
    #[inline]
    pub fn ray(&self, px: f32, py: f32) -> (Vec3, Vec3) {
        let t = (0.5 * self.fov_x_deg.to_radians()).tan();
        let w = self.width as f32;
        let h = self.height as f32;
        let d = Vec3::new((1.0 - 2.0 * px / w) * t, (1.0 - 2.0 * py / h) * t * h / w, 1.0);
        (self.origin, (self.rotation * d).normalize())
    }

    /// Project a world point to film coordinates (px, py), or `None` behind the camera.
    pub fn project(&self, p: Vec3) -> Option<(f32, f32)> {
        let d = self.rotation.transpose() * (p - self.origin);
        if d.z <= 0.0 {
            return None;
        }
        let t = (0.5 * self.fov_x_deg.to_radians()).tan();
        let w = self.width as f32;
        let h = self.height as f32;
        let px = (1.0 - d.x / d.z / t) * 0.5 * w;
        let py = (1.0 - d.y / d.z / (t * h / w)) * 0.5 * h;
        Some((px, py))
    }
}
